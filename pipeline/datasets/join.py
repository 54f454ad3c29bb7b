"""Join the shards of a scheduler-less run (``pipeline simulate --shard i/N``) into a new version.

The shard files move into ``v<k>/shards/`` (hard links, or copies across file systems) and
``v<k>/data.h5`` maps their blocks of trials through HDF5 virtual datasets, so nothing is
copied; the small trial table is merged for real. Recordings move to ``v<k>/recordings/``, the
shards' meshes (content-addressed, pipeline.runner.scenes) to ``v<k>/meshes/``.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import h5py

from pipeline.config.project import datasets_root
from pipeline.datasets.dimensions import SCALE_ATTRIBUTES, attach_dimensions
from pipeline.datasets.manifest import write_manifest
from pipeline.datasets.reader import decode_attr
from pipeline.datasets.schema import ARRAYS, CONFIG_FILE, DATA_FILE, FAILED, LIBVER, OK, PENDING, SAMPLES
from pipeline.datasets.shards import Shard
from pipeline.datasets.versions import MESHES_DIR, SHARDS_DIR, VersionLock, is_locked, new_version
from pipeline.datasets.writer import recover
from pipeline.errors import UserError


def _place(source: Path, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


def _run_folder(root: Path, name: str, run: str | None) -> Path:
    staging = Path(root) / name / SHARDS_DIR
    runs = sorted(p for p in staging.iterdir() if p.is_dir()) if staging.is_dir() else []
    if run:
        runs = [p for p in runs if p.name.startswith(run)]
    if not runs:
        raise UserError(f"no shards of dataset '{name}'{f' run {run}' if run else ''} in {staging}/ "
                        f"(write them with `pipeline simulate --shard i/N --name {name}`)")
    if len(runs) > 1:
        raise UserError(f"dataset '{name}' has shards of {len(runs)} runs ({', '.join(p.name for p in runs)}); "
                        "choose one with --run")
    return runs[0]


def _shards(run_folder: Path) -> list[tuple[Path, range]]:
    """(data file, trial block) per shard, checked complete, not being written, and all of one
    partition (same shard count and trials, each holding its own block)."""
    found, partitions = {}, set()
    for folder in sorted(run_folder.glob("shard_*_of_*")):
        data = folder / DATA_FILE
        if is_locked(folder):
            raise UserError(f"{folder} is still being written")
        if not data.is_file():
            continue
        try:
            h5py.File(data, "r").close()
        except OSError:           # its writer was killed after the last trial: clean copy first
            recover(data)
        with h5py.File(data, "r") as f:
            number, count = decode_attr(f.attrs["shard"])
            block = range(*decode_attr(f.attrs["trial_range"]))
            total = int(f.attrs["trials"])
            pending = int((f["trials/status"][block.start:block.stop] == PENDING.encode()).sum())
        partitions.add((count, total))
        if len(partitions) > 1:
            shown = " and ".join(f"{c} shards of {t} trials" for c, t in sorted(partitions))
            raise UserError(f"{run_folder}: shards of different partitions ({shown}); join the shards of "
                            "one partition only")
        if block != Shard(number, count).indices(total):
            raise UserError(f"{data}: shard {number}/{count} holds trials {block.start}-{block.stop - 1}, "
                            "not its block of the partition")
        if pending:
            raise UserError(f"shard {number}/{count} has {pending} trials pending; finish it with "
                            f"`pipeline simulate --shard {number}/{count}` and the same config")
        found[number] = (data, block)
    count = next(iter(partitions))[0] if partitions else 0
    missing = [f"{i}/{count}" for i in range(1, count + 1) if i not in found]
    if not found or missing:
        raise UserError(f"{run_folder}: shards missing: {', '.join(missing) or 'all'}")
    return [found[i] for i in sorted(found)]


def _write_joined(path: Path, label: str, shards: list[tuple[Path, range]]) -> None:
    partial = path.with_name(path.name + ".partial")
    with h5py.File(shards[0][0], "r") as first, h5py.File(partial, "w", libver=LIBVER) as out:
        out.attrs.update(first.attrs)
        del out.attrs["shard"]
        out.attrs.update(label=label, trial_range=[0, first["trials/status"].shape[0]],
                         joined_from=json.dumps([f"{SHARDS_DIR}/{p.name}" for p, _ in shards]))
        for key in first:                  # tables and coordinates; the arrays map into the shards
            if key != SAMPLES:
                first.copy(first[key], out, name=key)
        for key in first[SAMPLES]:
            if key not in ARRAYS:
                first.copy(first[SAMPLES][key], out.require_group(SAMPLES), name=key)
        for data, block in shards[1:]:
            with h5py.File(data, "r") as shard:
                for column, values in shard["trials"].items():
                    out["trials"][column][block.start:block.stop] = values[block.start:block.stop]
        for name in ARRAYS:
            if name not in first[SAMPLES]:
                continue
            source, inner = first[SAMPLES][name], f"{SAMPLES}/{name}"
            layout = h5py.VirtualLayout(shape=source.shape, dtype=source.dtype)
            for data, block in shards:
                virtual = h5py.VirtualSource(f"{SHARDS_DIR}/{data.name}", inner, shape=source.shape)
                layout[block.start:block.stop] = virtual[block.start:block.stop]
            out.create_virtual_dataset(inner, layout, fillvalue=source.fillvalue).attrs.update(
                {key: value for key, value in source.attrs.items() if key not in SCALE_ATTRIBUTES})
        attach_dimensions(out)
    os.replace(partial, path)


def join_shards(root: Path | None, name: str, run: str | None = None) -> Path:
    """Make a new version of ``name`` (under ``root``, default the project's datasets folder) from
    the complete shards of one run; returns its folder. The run's folder is locked while it is
    joined, so two joins at once make one version, not two sharing the same shard files."""
    root = datasets_root(root)
    run_folder = _run_folder(root, name, run)
    with VersionLock(run_folder, "joined"):  # a second `join` of the same run at once stops here
        return _join_locked(root, name, run_folder)


def _join_locked(root: Path, name: str, run_folder: Path) -> Path:
    shards = _shards(run_folder)
    version = new_version(root, name)
    with VersionLock(version):
        placed = []
        for data, block in shards:
            target = version / SHARDS_DIR / f"{data.parent.name}.h5"
            _place(data, target)
            placed.append((target, block))
            for recording in sorted((data.parent / "recordings").glob("*.rrd")):
                _place(recording, version / "recordings" / recording.name)
            for mesh in sorted((data.parent / MESHES_DIR).glob("*")):      # content-addressed: once each
                if not (version / MESHES_DIR / mesh.name).exists():
                    _place(mesh, version / MESHES_DIR / mesh.name)
        _place(shards[0][0].parent / CONFIG_FILE, version / CONFIG_FILE)
        _write_joined(version / DATA_FILE, f"{name}/{version.name}", placed)
        with h5py.File(version / DATA_FILE, "r") as f:
            status = f["trials/status"][()]
        write_manifest(version, {"trials": len(status), "ok": int((status == OK.encode()).sum()),
                                 "failed": int((status == FAILED.encode()).sum()),
                                 "joined_run": run_folder.name, "shards": len(shards)})
    shutil.rmtree(run_folder)
    if not any(run_folder.parent.iterdir()):
        run_folder.parent.rmdir()
    return version
