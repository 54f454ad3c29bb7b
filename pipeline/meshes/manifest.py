"""``manifest.json`` of the mesh folder: what was built from what, and whether it is current.

One entry per scan (by name = file stem) holding the input path and sha256, the
parameters and their hash, library versions, units, timings, quality metrics and the
output's sha256 and bounding box in metres; failed scans hold their error message.
"""

from __future__ import annotations

import json
import os
from importlib import metadata
from pathlib import Path
from typing import Any

import pipeline
from pipeline.config.meshes import MeshConfig
from pipeline.provenance import file_sha256, json_sha256

MANIFEST_NAME = "manifest.json"
FORMAT = "whisker-pipeline meshes/1"


def versions() -> dict[str, str]:
    """Versions that change the output (read from package metadata, nothing imported)."""
    found = {"whisker-pipeline": pipeline.__version__}
    for name, key in (("open3d-cpu", "open3d"), ("open3d", "open3d"), ("trimesh", "trimesh"),
                      ("numpy", "numpy"), ("scipy", "scipy")):
        if key in found:
            continue
        try:
            found[key] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return found


def scan_parameters(config: MeshConfig, name: str) -> dict[str, Any]:
    """The parameters that can change scan ``name``'s mesh (not the worker count)."""
    params = config.model_dump(mode="json", exclude={"workers"})
    per_scan = params["units"].pop("per_scan")
    params["units"]["this_scan"] = per_scan.get(name)
    return params


def parameters_key(params: dict[str, Any], library_versions: dict[str, str]) -> str:
    return json_sha256({"parameters": params, "versions": library_versions})


def load_manifest(out_dir: Path) -> dict[str, Any]:
    """The manifest of ``out_dir`` (an empty one if missing or unreadable)."""
    path = Path(out_dir) / MANIFEST_NAME
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        data = {}
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        data = {}
    data.setdefault("scans", {})
    return data


def write_manifest(out_dir: Path, scans: dict[str, Any]) -> Path:
    """Write the manifest atomically (temporary name, then rename)."""
    path = Path(out_dir) / MANIFEST_NAME
    data = {
        "format": FORMAT,
        "units": "meshes (OBJ vertices) and bbox_*_m in metres; metrics in mm / mm² as named",
        "scans": {name: scans[name] for name in sorted(scans)},
    }
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
    os.replace(partial, path)
    return path


def is_current(entry: dict[str, Any] | None, input_sha: str, key: str, out_dir: Path) -> bool:
    """True if ``entry`` built this input with these parameters and its OBJ is intact."""
    if not entry or entry.get("status") != "ok":
        return False
    if entry.get("input", {}).get("sha256") != input_sha or entry.get("parameters_sha256") != key:
        return False
    output = entry.get("output", {})
    mesh = Path(out_dir) / output.get("path", "")
    return mesh.is_file() and file_sha256(mesh) == output.get("sha256")
