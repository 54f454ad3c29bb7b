"""Mesh stage on the real scans of ../shared/data/scans (mm), tested against truth/ meshes.

Done-criteria per scan: median distance from the output mesh to the reference surface
≤ 0.5 mm, p95 ≤ 2 mm, no surface farther than 3 mm from the scan data, max edge ≤ 3 mm.
Two scans run in the fast set, all six with ``-m slow``.
"""

from pathlib import Path

import numpy as np
import pytest

from pipeline.config.meshes import MeshConfig
from pipeline.meshes.build import build_meshes
from pipeline.meshes.io import read_obj
from pipeline.meshes.metrics import distance_to_surface

SCANS = Path(__file__).resolve().parents[3] / "shared" / "data" / "scans"
FAST = ("scan_14", "scan_82")
ALL = ("scan_14", "scan_24", "scan_43", "scan_57", "scan_80", "scan_82")


@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=pytest.mark.slow)
                                  for n in ALL])
def test_real_scan_against_truth(name, tmp_path):
    import trimesh
    from scipy.spatial import cKDTree

    from pipeline.meshes.io import open_point_file
    from pipeline.meshes.metrics import sample_surface

    scan, reference = SCANS / f"{name}.ply", SCANS / "truth" / f"{name}.obj"
    if not scan.is_file() or not reference.is_file():
        pytest.skip(f"real scans not available ({SCANS})")
    (tmp_path / "scans").mkdir()
    (tmp_path / "scans" / scan.name).symlink_to(scan)
    report = build_meshes(tmp_path / "scans", tmp_path / "meshes", MeshConfig(), workers=1)
    (result,) = report.scans
    assert result.status == "built", result.message
    vertices, faces = read_obj(result.output)
    vertices *= 1000.0                                      # the OBJ is in metres
    truth = trimesh.load(reference, process=False)
    truth_v, truth_f = np.asarray(truth.vertices), np.asarray(truth.faces)

    samples = np.vstack([sample_surface(vertices, faces, 200_000, seed=1), vertices])
    to_truth = distance_to_surface(samples, truth_v, truth_f)
    assert np.median(to_truth) <= 0.5
    assert np.percentile(to_truth, 95) <= 2.0

    # "the data": the scan's points on the scanned surface (its outliers excluded)
    raw = np.vstack(list(open_point_file(scan).chunks(1_000_000)))
    data = cKDTree(raw[distance_to_surface(raw, truth_v, truth_f) < 5.0])
    assert data.query(samples)[0].max() <= 3.0
    assert result.metrics["surface_to_data_max_mm"] <= 3.0
    assert result.metrics["max_edge_mm"] <= 3.0

    # the mesh covers what the data covers (no passing by deleting surface)
    truth_samples = sample_surface(truth_v, truth_f, 50_000, seed=2)
    seen = data.query(truth_samples)[0] < 2.0
    covered = distance_to_surface(truth_samples, vertices, faces) < 2.0
    assert covered.mean() >= seen.mean() - 0.05
