"""Mesh stage, reading side: file formats, units, validation messages, voxel grid, config."""

from pathlib import Path

import numpy as np
import pytest

from pipeline.config import load_config
from pipeline.config.meshes import MeshConfig
from pipeline.errors import UserError
from pipeline.meshes.clean import VoxelGrid
from pipeline.meshes.io import open_point_file, write_pcd_points, write_ply_points, write_xyz_points
from pipeline.meshes.load import read_scan
from pipeline.meshes.point_source import parse_units

REPO = Path(__file__).resolve().parents[2]


def _read_all(path, chunk=1000):
    return np.vstack(list(open_point_file(path).chunks(chunk)))


def _sphere(n=3000, radius=40.0, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    return radius * u / np.linalg.norm(u, axis=1, keepdims=True)


# ---------------------------------------------------------------------------- formats

@pytest.mark.parametrize("kind", ["ply_f4", "ply_f8", "ply_ascii", "pcd", "pcd_ascii", "xyz",
                                  "pts"])
def test_formats_round_trip_and_match_open3d(tmp_path, kind):
    import open3d as o3d

    points = _sphere(2500)
    suffix = {"ply_f4": ".ply", "ply_f8": ".ply", "ply_ascii": ".ply", "pcd": ".pcd",
              "pcd_ascii": ".pcd", "xyz": ".xyz", "pts": ".pts"}[kind]
    path = tmp_path / f"cloud{suffix}"
    if kind == "ply_f4":
        write_ply_points(path, points, units="mm")
    elif kind == "ply_f8":
        write_ply_points(path, points, dtype="<f8")
    elif kind == "ply_ascii":
        body = "\n".join(f"{x:.6f} {y:.6f} {z:.6f} 255" for x, y, z in points)
        path.write_text("ply\nformat ascii 1.0\ncomment units: mm\nelement vertex "
                        f"{len(points)}\nproperty float x\nproperty float y\nproperty float z\n"
                        f"property uchar intensity\nend_header\n{body}\n")
    elif kind == "pcd":
        write_pcd_points(path, points, units="mm")
    elif kind == "pcd_ascii":
        body = "\n".join(f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in points)
        path.write_text(f"# units mm\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                        f"COUNT 1 1 1\nWIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
                        f"POINTS {len(points)}\nDATA ascii\n{body}\n")
    elif kind == "xyz":
        write_xyz_points(path, points, units="mm")
    else:
        body = "\n".join(f"{x:.6f} {y:.6f} {z:.6f} 7 1 2 3" for x, y, z in points)
        path.write_text(f"{len(points)}\n{body}\n")
    mine = _read_all(path, chunk=700)  # several chunks
    assert mine.shape == points.shape
    assert np.allclose(mine, points, atol=1e-4)
    theirs = np.asarray(o3d.io.read_point_cloud(str(path)).points)
    assert np.allclose(mine, theirs, atol=1e-5)
    expected_units = None if kind in ("ply_f8", "pts") else "mm"
    assert open_point_file(path).declared_units == expected_units


def test_real_scan_read_matches_open3d():
    import open3d as o3d

    scan = Path(__file__).resolve().parents[3] / "shared" / "data" / "scans" / "scan_82.ply"
    if not scan.is_file():
        pytest.skip("shared real scans not available")
    assert np.array_equal(_read_all(scan, 10_000),
                          np.asarray(o3d.io.read_point_cloud(str(scan)).points))


@pytest.mark.parametrize("text, units", [("comment units mm", "mm"), ("comment unit: m", "m"),
                                         ("# units = millimetres", "mm"), ("# Units: meters", "m"),
                                         ("comment Created by Open3D", None)])
def test_parse_units(text, units):
    assert parse_units(text) == units


# ---------------------------------------------------------------------------- bad input

def _ply_header(count, extra=""):
    return (f"ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\n"
            f"property float y\nproperty float z\n{extra}end_header\n").encode()


BAD = {
    "empty.ply": (b"", "empty file"),
    "truncated.ply": (_ply_header(1000) + np.zeros((10, 3), "<f4").tobytes(),
                      "truncated: header declares 1000 points, file holds only 10"),
    "header_cut.ply": (b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nprop",
                       "truncated PLY header"),
    "mesh.ply": (_ply_header(3, "element face 1\nproperty list uchar int vertex_indices\n")
                 + np.eye(3, dtype="<f4").tobytes() + b"\x03" + np.arange(3, dtype="<i4").tobytes(),
                 "is a triangle mesh (1 face elements), expected a point cloud"),
    "obj_renamed.ply": (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not a PLY file"),
    "mesh.xyz": (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "looks like a mesh file"),
    "binary.xyz": (bytes(range(256)) * 10, "binary data"),
    "words.xyz": (b"1 2 3\n4 5 6\nhello world again\n", "line 3: expected 3 or more numbers"),
    "two_columns.xyz": (b"1 2 3\n4 5\n", "line 2"),
    "notpcd.pcd": (b"this is not a point cloud\n", "not a PCD file"),
    "noxyz.pcd": (b"VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\n"
                  b"HEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n", "no x, y, z fields"),
    "short.pts": (b"100\n1 2 3\n4 5 6\n", "truncated: header declares 100 points, file holds only 2"),
    "zero.ply": (_ply_header(0), "no points"),
    "few.xyz": (b"1 2 3\n4 5 6\n7 8 9\n", "only 3 points"),
    "nan.xyz": (b"".join(f"{i} {i % 7} {i % 3}\n".encode() for i in range(200)) + b"nan 1 2\n",
                "NaN or infinite coordinates (first at point 200)"),
    "inf.ply": (_ply_header(200) + np.vstack([_sphere(199), [[np.inf, 0, 0]]]).astype("<f4").tobytes(),
                "NaN or infinite coordinates"),
    "scan.txt": (b"1 2 3\n", "unsupported extension"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input_gives_one_line_naming_the_file(tmp_path, name):
    content, needle = BAD[name]
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(UserError) as info:
        read_scan(path, path.stem, MeshConfig())
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(str(path) + ":")
    assert needle in message


def test_nonfinite_drop_option(tmp_path):
    points = _sphere(3000)
    points[::100] = np.nan
    path = tmp_path / "holes.ply"
    write_ply_points(path, points, units="mm")
    config = MeshConfig.model_validate({"read": {"nonfinite": "drop"}})
    scan = read_scan(path, "holes", config)
    assert scan.nonfinite_dropped == 30 and scan.points_read == 2970


def test_five_km_object_is_wrong_units(tmp_path):
    # a 5 m scene written in mm but declared as metres → 5 km
    declared = tmp_path / "declared.ply"
    write_ply_points(declared, _sphere(5000, radius=2500.0), units="m")
    with pytest.raises(UserError, match=r"declared.ply: scan spans 49\d\d m .*max_extent_m = 20 m: "
                                        r"wrong units\?"):
        read_scan(declared, "declared", MeshConfig())
    # coordinates in mm of a 5 km object, undeclared (detected as mm from its spacing)
    detected = tmp_path / "detected.ply"
    write_ply_points(detected, _sphere(5000, radius=2.5e6))
    with pytest.raises(UserError, match="wrong units"):
        read_scan(detected, "detected", MeshConfig())


def test_tiny_object_is_wrong_units(tmp_path):
    path = tmp_path / "tiny.ply"
    write_ply_points(path, _sphere(3000, radius=40.0) / 1000.0, units="mm")  # 80 µm ball
    with pytest.raises(UserError, match="spans only .*min_extent_mm"):
        read_scan(path, "tiny", MeshConfig())


# ---------------------------------------------------------------------------- units

def test_units_detected_declared_and_configured(tmp_path):
    points_mm = _sphere(20_000, radius=50.0)
    write_ply_points(tmp_path / "in_m.ply", points_mm / 1000.0)
    write_ply_points(tmp_path / "in_mm.ply", points_mm)
    write_ply_points(tmp_path / "declared.ply", points_mm, units="mm")
    config = MeshConfig()
    in_m = read_scan(tmp_path / "in_m.ply", "in_m", config)
    in_mm = read_scan(tmp_path / "in_mm.ply", "in_mm", config)
    assert (in_m.units, in_mm.units) == ("m", "mm")
    assert in_m.units_source.startswith("detected") and not in_m.warnings
    assert np.allclose(in_m.points_mm, in_mm.points_mm, atol=1e-6)     # both end in mm
    assert 95 < in_m.extent_mm < 101
    declared = read_scan(tmp_path / "declared.ply", "declared", config)
    assert (declared.units, declared.units_source) == ("mm", "declared in file")
    # per-scan config beats the file, and a mismatch with the spacing is warned about
    forced = MeshConfig.model_validate({"units": {"per_scan": {"declared": "m"},
                                                  "max_extent_m": 1000}})
    wrong = read_scan(tmp_path / "declared.ply", "declared", forced)
    assert wrong.units == "m" and wrong.units_source == "config units.per_scan"
    assert "looks like 'mm'" in wrong.warnings[0]


def test_example_scans_units():
    config = MeshConfig()
    found = {p.stem: read_scan(p, p.stem, config) for p in sorted((REPO / "scans").iterdir())
             if p.suffix in (".ply", ".pcd", ".xyz", ".pts")}
    assert set(found) == {"drainpipe", "rock_pile", "branch"}
    assert found["drainpipe"].units == "mm" and found["rock_pile"].units == "m"
    assert found["branch"].units == "m" and found["branch"].units_source.startswith("detected")
    for scan in found.values():
        assert 100 < scan.extent_mm < 400


# ---------------------------------------------------------------------------- voxel grid

def test_voxel_grid_streaming_equals_one_pass_and_doubling_is_exact():
    rng = np.random.default_rng(1)
    points = rng.uniform(-20, 20, size=(50_000, 3))
    one = VoxelGrid(1.0, 10**9)
    one.add(points)
    streamed = VoxelGrid(1.0, 10**9)
    for part in np.array_split(points, 7):
        streamed.add(part)
    assert np.allclose(one.points(), streamed.points(), atol=1e-9)
    counts = np.unique(np.floor(points).astype(int), axis=0).shape[0]
    assert len(one.points()) == counts
    # capped: the voxel doubles until it fits, and equals a direct pass at that size
    capped = VoxelGrid(1.0, 5_000)   # ~35 000 voxels of 1 mm: doubles while streaming and after
    for part in np.array_split(points, 5):
        capped.add(part)
    result = capped.points()
    assert capped.doublings == 2 and capped.voxel_mm == 4.0 and len(result) <= 5_000
    direct = VoxelGrid(4.0, 10**9)
    direct.add(points)
    assert np.allclose(result, direct.points(), atol=1e-9)


# ---------------------------------------------------------------------------- config

def test_shipped_yaml_equals_model_defaults():
    config, _ = load_config(MeshConfig, REPO / "configs" / "meshes.yaml")
    assert config == MeshConfig()


@pytest.mark.parametrize("text, needle", [
    ("downsample:\n  voxel_mm: -1\n", "downsample.voxel_mm"),
    ("reconstruct:\n  method: marching\n", "reconstruct.method"),
    ("units:\n  per_scan: {rock: inches}\n", "units.per_scan.rock"),
    ("reconstruct:\n  poisson: {min_depth: 9, max_depth: 7}\n", "min_depth 9 > max_depth 7"),
    ("simplify:\n  target_edge: 2\n", "unknown field 'simplify.target_edge'"),
])
def test_bad_config_names_file_and_field(tmp_path, text, needle):
    path = tmp_path / "meshes.yaml"
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_config(MeshConfig, path, env_prefix="PIPELINE_MESHES_", environ={})
    assert str(path) in str(info.value) and needle in str(info.value)


def test_registry_knows_meshes_yaml():
    from pipeline.config.registry import CONFIG_FILES

    assert CONFIG_FILES["meshes.yaml"] == (MeshConfig, "PIPELINE_MESHES_")
