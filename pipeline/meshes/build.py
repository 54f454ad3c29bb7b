"""The ``build-meshes`` stage: every scan of a folder → ``<name>.obj`` (metres) + manifest entry.

Per scan (all internal lengths in mm): read in chunks with voxel down-sampling and unit
handling → statistical and radius outlier removal → oriented normals → Poisson (or ball
pivoting) → removal of unsupported surface (distance to the data, crop to its bounds) →
cleaning → quadric simplification → splitting of edges longer than ``max_edge_mm`` →
a last drop of any face still too far from the data → pieces with an open boundary closed into
shells ``shell_thickness_mm`` thick (:mod:`pipeline.meshes.shell`; the shell's back lies behind
the scanned surface, so the distance guarantee and the surface-to-data metrics are those of the
scanned faces) → plain OBJ in metres.

Scans whose input bytes and parameters are unchanged (and whose OBJ is intact) are
skipped. Several scans run in parallel processes, one thread each; a scan's failure is
recorded and the others still build. Results are deterministic: the same input and
parameters give the same OBJ bytes.
"""

from __future__ import annotations

import errno
import os
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Callable

import numpy as np
import open3d as o3d
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from scipy.spatial import cKDTree

from pipeline.config.loader import load_config
from pipeline.config.meshes import MeshConfig
from pipeline.config.project import find_config
from pipeline.datasets.manifest import refuse_complete_version
from pipeline.errors import UserError
from pipeline.meshes.clean import oriented_normals, remove_outliers
from pipeline.meshes.io import SUPPORTED_SUFFIXES, write_obj
from pipeline.meshes.load import read_scan
from pipeline.meshes.manifest import (is_current, load_manifest, parameters_key, scan_parameters, versions,
                                      write_manifest)
from pipeline.meshes.metrics import mesh_metrics, shape_metrics
from pipeline.meshes.reconstruct import drop_far_faces, reconstruct, trim_unsupported
from pipeline.meshes.refine import clean_mesh, limit_edges, simplify
from pipeline.meshes.shell import close_open_sheets
from pipeline.provenance import file_sha256

CONFIG_ENV_PREFIX = "PIPELINE_MESHES_"
CONFIG_NAME = "meshes.yaml"            # found as <project>/configs/meshes.yaml


@dataclass
class ScanResult:
    """Outcome of one scan: ``status`` is ``built``, ``skipped`` (unchanged) or ``failed``."""

    name: str
    status: str
    input: str
    output: str | None = None
    message: str = ""
    seconds: float = 0.0
    metrics: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


@dataclass
class BuildReport:
    """What ``build_meshes`` did. Output meshes are OBJ files with vertices in metres."""

    out_dir: str
    manifest: str
    scans: list[ScanResult]

    @property
    def failed(self) -> list[ScanResult]:
        return [s for s in self.scans if s.status == "failed"]

    def count(self, status: str) -> int:
        return sum(s.status == status for s in self.scans)

    def summary(self) -> dict[str, Any]:
        return {"built": self.count("built"), "skipped": self.count("skipped"),
                "failed": self.count("failed"), "manifest": self.manifest}

    def to_dict(self) -> dict[str, Any]:
        return {**self.summary(), "out_dir": self.out_dir,
                "scans": [asdict(s) for s in self.scans]}


# --------------------------------------------------------------------------- one scan

def build_scan(path: Path, name: str, out_dir: Path, config: MeshConfig) -> dict[str, Any]:
    """Build ``out_dir/<name>.obj`` from the scan at ``path``; the manifest entry's body.

    Raises :class:`UserError` for bad input. Vertices are written in metres.
    """
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(step: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[step] = round(now - clock, 3)
        clock = now

    start = clock
    scan = read_scan(path, name, config)
    voxel = scan.voxel_mm
    warnings = list(scan.warnings)
    lap("read_downsample")

    cleaned = remove_outliers(scan.points_mm, config.outliers, voxel)
    points = cleaned.points_mm
    if len(points) < config.read.min_points:
        raise UserError(f"{path}: only {len(points)} points left after outlier removal "
                        f"(read.min_points = {config.read.min_points})")
    _require_depth(path, points)
    tree = cKDTree(points)
    lap("outliers")

    normals = oriented_normals(points, config.normals, voxel)
    lap("normals")

    rec = reconstruct(points, normals, config.reconstruct, voxel)
    warnings += rec.warnings
    mesh = rec.mesh
    lap("reconstruct")

    mesh, removed_area = trim_unsupported(mesh, tree, points, config.reconstruct)
    lap("trim")
    mesh = clean_mesh(mesh, config.clean)
    lap("clean")
    mesh = simplify(mesh, config.simplify)
    mesh = clean_mesh(mesh, config.clean)
    lap("simplify")
    vertices, faces = limit_edges(np.asarray(mesh.vertices), np.asarray(mesh.triangles),
                                  config.max_edge_mm)
    vertices, faces, dropped = drop_far_faces(vertices, faces, tree,
                                              config.reconstruct.max_distance_mm)
    lap("max_edge")
    if len(faces) == 0:
        raise UserError(f"{path}: no surface left after removing what the data does not "
                        f"support (reconstruct.max_distance_mm = "
                        f"{config.reconstruct.max_distance_mm:g})")

    metrics = mesh_metrics(vertices, faces, tree, config.metric_samples, config.seed)
    scanned_triangles = len(faces)
    vertices, faces, shell = close_open_sheets(vertices, faces, config.shell_thickness_mm)
    if shell:
        vertices, faces = limit_edges(vertices, faces, config.max_edge_mm)
        metrics |= shape_metrics(vertices, faces)
    if metrics["max_edge_mm"] > config.max_edge_mm + 1e-9:
        raise RuntimeError(f"max edge {metrics['max_edge_mm']} mm exceeds {config.max_edge_mm}")
    lap("metrics")

    vertices_m = vertices / 1000.0
    obj = Path(out_dir) / f"{name}.obj"
    write_obj(obj, vertices_m, faces)
    lap("write")
    timings["total"] = round(time.perf_counter() - start, 3)

    metrics = {
        "points_in": scan.points_read,
        "nonfinite_dropped": scan.nonfinite_dropped,
        "points_after_downsample": int(len(scan.points_mm)),
        "outliers_removed": cleaned.statistical_removed + cleaned.radius_removed,
        "outliers_statistical": cleaned.statistical_removed,
        "outliers_radius": cleaned.radius_removed,
        "points_after_outliers": int(len(points)),
        **metrics,
        "unsupported_area_removed_mm2": round(float(removed_area), 3),
        "far_faces_dropped": dropped,
        "shell_triangles": int(metrics["triangles"] - scanned_triangles),
    }
    return {
        "units": {"input": scan.units, "source": scan.units_source, "output": "m"},
        "reconstruction": {"method": rec.method, "voxel_mm": voxel,
                           "poisson_depth": rec.poisson_depth,
                           "poisson_cell_mm": None if rec.poisson_cell_mm is None
                           else round(rec.poisson_cell_mm, 4)},
        "output": {"path": obj.name, "sha256": file_sha256(obj),
                   "bbox_min_m": [round(float(x), 7) for x in vertices_m.min(axis=0)],
                   "bbox_max_m": [round(float(x), 7) for x in vertices_m.max(axis=0)]},
        "metrics": metrics,
        "timings_s": timings,
        "warnings": warnings,
        "format": scan.file_format,
    }


FLAT_THICKNESS_FRACTION = 1e-6     # rms distance from the best plane, as a fraction of the extent


def _require_depth(path: Path, points_mm: np.ndarray) -> None:
    """UserError if the points lie in one plane (or on a line): reconstruction needs depth."""
    centred = points_mm - points_mm.mean(axis=0)
    spread = np.linalg.svd(centred, compute_uv=False) / np.sqrt(len(points_mm))
    if spread[-1] <= FLAT_THICKNESS_FRACTION * max(spread[0], 1e-300):
        raise UserError(f"{path}: all points lie in one plane (rms {spread[-1]:.3g} mm off it over "
                        f"{spread[0]:.3g} mm): no surface with depth to reconstruct")


def _job(path: str, name: str, out_dir: str, config_data: dict[str, Any]) -> dict[str, Any]:
    """Run one scan; never raises: returns ``{"status": "ok", ...}`` or a failure entry."""
    start = time.perf_counter()
    try:
        body = build_scan(Path(path), name, Path(out_dir), MeshConfig.model_validate(config_data))
        return {"status": "ok", **body}
    except UserError as exc:
        return {"status": "failed", "error": str(exc),
                "timings_s": {"total": round(time.perf_counter() - start, 3)}}
    except MemoryError:
        return {"status": "failed", "error": f"{path}: out of memory",
                "timings_s": {"total": round(time.perf_counter() - start, 3)}}
    except Exception as exc:  # a bug: keep the traceback in the manifest
        first_line = (str(exc).strip().splitlines() or [""])[0]
        return {"status": "failed", "error": f"{path}: internal error: {type(exc).__name__}: {first_line}",
                "traceback": traceback.format_exc(),
                "timings_s": {"total": round(time.perf_counter() - start, 3)}}


def _init_worker() -> None:
    """One thread per worker process (set before Open3D's OpenMP runtime starts)."""
    os.environ["OMP_NUM_THREADS"] = "1"


# --------------------------------------------------------------------------- the folder

def find_scans(scans_dir: Path) -> list[Path]:
    """The entries directly in ``scans_dir`` named like point files (sorted by name), also
    those that are not readable files (directories, dangling links): they fail by name."""
    scans_dir = Path(scans_dir)
    if not scans_dir.is_dir():
        raise UserError(f"scan folder not found: {scans_dir}")
    return sorted(p for p in scans_dir.iterdir() if p.suffix.lower() in SUPPORTED_SUFFIXES)


def _not_a_scan(path: Path) -> str | None:
    """Why ``path`` cannot be read as a scan file (one line), or None if it can be."""
    try:
        if path.is_dir():
            return f"{path}: a directory, not a scan file"
        with open(path, "rb"):
            return None
    except OSError as exc:
        reason = ("a symbolic link loop" if exc.errno == errno.ELOOP else "a dangling symbolic link"
                  if path.is_symlink() and not path.exists() else exc.strerror)
        return f"{path}: cannot be read ({reason})"


def build_meshes(scans_dir: str | Path, out_dir: str | Path, config: MeshConfig | None = None,
                 force: bool = False, *, progress: bool = False,
                 workers: int | None = None) -> BuildReport:
    """Build ``out_dir/<name>.obj`` for every ``.ply .pcd .xyz .pts`` in ``scans_dir``.

    Output OBJ files are plain ``v``/``f`` lines with vertices in **metres**;
    ``out_dir/manifest.json`` records input sha256, parameters, versions, units, timings,
    quality metrics and each mesh's bounding box in metres. Unchanged scans are skipped
    unless ``force``. Bad scans are reported (``status == "failed"``, one-line message)
    and do not stop the others. ``workers`` overrides ``config.workers``.
    """
    config = config or MeshConfig()
    scans_dir, out_dir = Path(scans_dir), Path(out_dir)
    refuse_complete_version(out_dir, "build-meshes output folder")
    paths = find_scans(scans_dir)
    if not paths:
        raise UserError(f"{scans_dir}: no scans ({' '.join(SUPPORTED_SUFFIXES)}) in the folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    manifest = load_manifest(out_dir)
    library = versions()
    old_entries: dict[str, Any] = manifest["scans"]
    entries: dict[str, Any] = {}
    results: dict[str, ScanResult] = {}
    jobs: list[tuple[str, Path]] = []

    by_name: dict[str, list[Path]] = {}
    for path in paths:
        by_name.setdefault(path.stem, []).append(path)
    for name, same in by_name.items():
        path = same[0]
        problem = _not_a_scan(path)
        if problem:
            entries[name] = {"status": "failed", "input": {"path": str(path)}, "error": problem}
            results[name] = ScanResult(name, "failed", str(path), message=problem)
            continue
        params = scan_parameters(config, name)
        key = parameters_key(params, library)
        base = {"input": {"path": str(path), "sha256": file_sha256(path),
                          "bytes": path.stat().st_size},
                "parameters": params, "parameters_sha256": key, "versions": library}
        if len(same) > 1:
            message = (f"{path}: name clash: {', '.join(p.name for p in same)} would all "
                       f"write {name}.obj; rename all but one")
            entries[name] = {"status": "failed", **base, "error": message}
            results[name] = ScanResult(name, "failed", str(path), message=message)
            continue
        old = old_entries.get(name)
        if not force and is_current(old, base["input"]["sha256"], key, out_dir):
            entries[name] = {**old, "input": base["input"]}
            results[name] = ScanResult(name, "skipped", str(path), str(out_dir / f"{name}.obj"),
                                       metrics=old.get("metrics", {}),
                                       warnings=old.get("warnings", []))
            continue
        entries[name] = base
        jobs.append((name, path))

    def record(name: str, path: Path, outcome: dict[str, Any]) -> None:
        entry = {**entries[name], **outcome}
        entry.setdefault("status", "failed")
        entries[name] = entry
        seconds = entry.get("timings_s", {}).get("total", 0.0)
        if entry["status"] == "ok":
            results[name] = ScanResult(name, "built", str(path),
                                       str(out_dir / entry["output"]["path"]), seconds=seconds,
                                       metrics=entry["metrics"], warnings=entry["warnings"])
        else:
            results[name] = ScanResult(name, "failed", str(path), message=entry["error"],
                                       seconds=seconds)
        write_manifest(out_dir, entries)

    write_manifest(out_dir, {n: e for n, e in entries.items() if n not in dict(jobs)})
    config_data = config.model_dump(mode="json")
    count = workers if workers is not None else (config.workers or os.cpu_count() or 1)
    count = max(1, min(count, len(jobs)))
    with _progress(progress, len(jobs)) as advance:
        if count == 1:
            for name, path in jobs:
                record(name, path, _job(str(path), name, str(out_dir), config_data))
                advance(name)
        else:
            with ProcessPoolExecutor(max_workers=count, mp_context=get_context("spawn"),
                                     initializer=_init_worker) as pool:
                futures = {pool.submit(_job, str(path), name, str(out_dir), config_data):
                           (name, path) for name, path in jobs}
                for future in as_completed(futures):
                    name, path = futures[future]
                    try:
                        outcome = future.result()
                    except Exception as exc:  # the worker process died (e.g. killed for memory)
                        outcome = {"status": "failed",
                                   "error": f"{path}: worker process failed: "
                                            f"{type(exc).__name__}: {exc}"}
                    record(name, path, outcome)
                    advance(name)
    manifest_path = write_manifest(out_dir, entries)
    return BuildReport(str(out_dir), str(manifest_path), [results[n] for n in sorted(results)])


class _progress:
    """Context manager yielding ``advance(name)``; a rich bar on stderr if asked and a terminal."""

    def __init__(self, enabled: bool, total: int) -> None:
        self.enabled, self.total, self.bar = enabled, total, None

    def __enter__(self) -> Callable[[str], None]:
        if self.enabled and self.total:
            console = Console(stderr=True)
            if console.is_terminal:
                self.bar = Progress(TextColumn("building meshes"), BarColumn(),
                                    MofNCompleteColumn(), TimeElapsedColumn(),
                                    TextColumn("{task.description}"), console=console)
                self.bar.start()
                self.task = self.bar.add_task("", total=self.total)
        return self.advance

    def advance(self, name: str) -> None:
        if self.bar is not None:
            self.bar.update(self.task, advance=1, description=f"last: {name}")

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()


# --------------------------------------------------------------------------- stage & config

def load_mesh_config(path: str | Path | None = None) -> MeshConfig:
    """Defaults < ``path`` (or the project's ``configs/meshes.yaml`` if it exists, see
    :mod:`pipeline.config.project`) < ``PIPELINE_MESHES_*``."""
    if path is None:
        path = find_config(CONFIG_NAME)
    config, _ = load_config(MeshConfig, path, env_prefix=CONFIG_ENV_PREFIX)
    return config


def run_stage(config_path: str | Path | None, scans: str = "scans", out: str = "outputs/meshes",
              force: bool = False) -> dict[str, Any]:
    """Workflow stage ``build-meshes``: summary dict; raises UserError if any scan failed."""
    report = build_meshes(scans, out, load_mesh_config(config_path), force=force)
    if report.failed:
        raise UserError(f"build-meshes: {len(report.failed)} of {len(report.scans)} scans failed "
                        f"(see {report.manifest}): "
                        + "; ".join(s.message for s in report.failed))
    return report.summary()
