"""Procedural natural objects "scanned" by a simulated depth sensor (example scans and tests).

Objects (meshes in mm): a drainpipe (open tube, slightly oval), a rock pile (lumpy
ellipsoids stacked) and a branch (tapering bent tube with a side twig). The sensor is a
pinhole depth camera seen from several viewpoints; each view has depth noise growing with
the square of the depth, flying pixels at depth edges (points smeared between the
foreground and what lies behind), dropouts (random pixels, grazing angles and a few
specular holes) and uniform outliers in the object's surroundings. Everything is driven by
one seed: the same seed gives the same points.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.meshes.io import write_pcd_points, write_ply_points, write_xyz_points
import open3d as o3d
import trimesh

# ---------------------------------------------------------------------------- objects


def _tube(path: np.ndarray, radii: np.ndarray, sections: int = 48,
          wobble: np.ndarray | None = None, caps: bool = True):
    """A swept tube along ``path`` (n, 3) with per-ring ``radii``; optional radial ``wobble``
    (n, sections) in mm. Returns (vertices, faces)."""
    tangent = np.gradient(path, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # rotation-minimising frames (double reflection would be overkill: small bends)
    ref = np.array([0.0, 0.0, 1.0]) if abs(tangent[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    normal = np.cross(tangent[0], ref)
    normal /= np.linalg.norm(normal)
    normals = []
    for t in tangent:
        normal = normal - t * np.dot(normal, t)
        normal /= np.linalg.norm(normal)
        normals.append(normal)
    normals = np.array(normals)
    binormals = np.cross(tangent, normals)
    angle = np.linspace(0, 2 * np.pi, sections, endpoint=False)
    r = radii[:, None] + (wobble if wobble is not None else 0.0)
    ring = (normals[:, None, :] * np.cos(angle)[None, :, None]
            + binormals[:, None, :] * np.sin(angle)[None, :, None])
    vertices = (path[:, None, :] + r[:, :, None] * ring).reshape(-1, 3)
    n = len(path)
    i = np.arange(n - 1)[:, None] * sections
    j = np.arange(sections)[None, :]
    a, b = i + j, i + (j + 1) % sections
    c, d = a + sections, b + sections
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)])
    if caps:
        start, end = len(vertices), len(vertices) + 1
        vertices = np.vstack([vertices, path[0], path[-1]])
        ring0 = np.arange(sections)
        ring1 = ring0 + (n - 1) * sections
        faces = np.concatenate([faces,
                                np.stack([np.full(sections, start), (ring0 + 1) % sections, ring0], -1),
                                np.stack([np.full(sections, end), ring1,
                                          (ring0 + 1) % sections + (n - 1) * sections], -1)])
    return vertices, faces


def _merge(parts):
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.vstack(vertices), np.vstack(faces)


def drainpipe(rng: np.random.Generator):
    """An open concrete drainpipe, 80 mm across, 240 mm long, walls 5 mm, lying along x."""
    length, outer, inner = 240.0, 40.0, 35.0
    x = np.linspace(-length / 2, length / 2, 61)
    path = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    angle = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    oval = 1.5 * np.cos(2 * angle + rng.uniform(0, np.pi))[None, :] * np.ones((len(x), 1))
    dents = 0.6 * np.sin(3 * angle[None, :] + x[:, None] / 25.0 + rng.uniform(0, np.pi))
    vo, fo = _tube(path, np.full(len(x), outer), 64, oval + dents, caps=False)
    vi, fi = _tube(path, np.full(len(x), inner), 64, oval, caps=False)
    fi = fi[:, ::-1]  # inner wall faces inward
    # end rings joining the walls
    n, s = len(x), 64
    ring = np.arange(s)
    rims = []
    for k in (0, n - 1):
        o, i_ = ring + k * s, ring + k * s + len(vo)
        o2, i2 = (ring + 1) % s + k * s, (ring + 1) % s + k * s + len(vo)
        tri = np.concatenate([np.stack([o, i_, o2], -1), np.stack([o2, i_, i2], -1)])
        rims.append(tri if k == 0 else tri[:, ::-1])
    vertices, faces = _merge([(vo, fo), (vi, fi)])
    return vertices, np.vstack([faces] + rims)


def _lumpy_sphere(rng: np.random.Generator, radius: float, subdivisions: int = 4):
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    directions = sphere.vertices
    bumps = np.zeros(len(directions))
    for _ in range(6):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        bumps += rng.uniform(0.03, 0.08) * np.sin(rng.uniform(1.5, 4.0) * directions @ axis
                                                  + rng.uniform(0, 2 * np.pi))
    scale = rng.uniform(0.7, 1.0, size=3) * radius
    vertices = directions * (1.0 + bumps)[:, None] * scale
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return vertices @ q.T, sphere.faces.copy()


def rock_pile(rng: np.random.Generator):
    """Six lumpy rocks of 25–60 mm, four on the ground and two resting on them."""
    parts = []
    centres = [(-45, -20), (15, -35), (40, 25), (-15, 35)]
    for cx, cy in centres:
        v, f = _lumpy_sphere(rng, rng.uniform(24, 32))
        v += [cx + rng.uniform(-5, 5), cy + rng.uniform(-5, 5), -v[:, 2].min()]
        parts.append((v, f))
    for cx, cy in ((-15, -5), (20, 5)):
        v, f = _lumpy_sphere(rng, rng.uniform(18, 24))
        v += [cx, cy, 40 + rng.uniform(0, 8)]
        parts.append((v, f))
    return _merge(parts)


def branch(rng: np.random.Generator):
    """A bent branch, 260 mm long, 18 → 8 mm across, with a 90 mm side twig."""
    t = np.linspace(0, 1, 90)
    bend = rng.uniform(20, 35)
    path = np.column_stack([260 * (t - 0.5), bend * np.sin(np.pi * t), 12 * np.sin(2 * np.pi * t)])
    radii = 9.0 - 5.0 * t
    bark = 0.25 * rng.standard_normal((len(t), 40))
    main = _tube(path, radii, 40, bark)
    k = 35
    direction = np.array([0.55, 0.8, 0.25])
    direction /= np.linalg.norm(direction)
    s = np.linspace(0, 90, 40)[:, None]
    twig_path = path[k] + s * direction + np.column_stack([np.zeros(40), np.zeros(40),
                                                          -0.002 * s[:, 0] ** 2])
    twig = _tube(twig_path, np.linspace(4.0, 2.0, 40), 24)
    return _merge([main, twig])


SCENES = {"drainpipe": drainpipe, "rock_pile": rock_pile, "branch": branch}


def scene_mesh(name: str, seed: int = 0):
    """The reference surface of scene ``name`` as a ``trimesh.Trimesh`` in mm."""
    rng = np.random.default_rng([seed, list(SCENES).index(name)])
    vertices, faces = SCENES[name](rng)
    return trimesh.Trimesh(vertices, faces, process=False)


# ---------------------------------------------------------------------------- the sensor


@dataclass(frozen=True)
class SensorModel:
    """A pinhole depth camera; lengths in mm."""

    width_px: int = 200
    height_px: int = 150
    fov_deg: float = 50.0
    distance_factor: float = 2.2       # camera distance / object size
    noise_mm_at_500: float = 0.6       # depth noise σ at 500 mm, grows with depth²
    dropout: float = 0.04              # random pixel dropouts
    grazing_cos: float = 0.2           # |cos| below this: dropped with ``grazing_drop``
    grazing_drop: float = 0.7
    holes_per_view: int = 3            # specular holes of ``hole_px`` radius
    hole_px: float = 5.0
    flying_fraction: float = 0.5       # of depth-edge pixels that become flying pixels
    edge_jump_mm: float = 15.0
    outlier_fraction: float = 0.008    # uniform in the 1.6× bounding box


def _look_at_rays(eye: np.ndarray, target: np.ndarray, sensor: SensorModel):
    forward = target - eye
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    if abs(forward @ up) > 0.95:
        up = np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    f = 0.5 * sensor.width_px / np.tan(np.radians(sensor.fov_deg) / 2)
    u = (np.arange(sensor.width_px) + 0.5 - sensor.width_px / 2) / f
    v = (np.arange(sensor.height_px) + 0.5 - sensor.height_px / 2) / f
    uu, vv = np.meshgrid(u, v)
    directions = forward + uu[..., None] * right + vv[..., None] * down  # depth = t
    return directions, forward


def scan_points(vertices: np.ndarray, faces: np.ndarray, seed: int = 0,
                views: int = 4, sensor: SensorModel = SensorModel()) -> np.ndarray:
    """Simulated multi-view depth scan of a mesh (mm) → points (n, 3) in mm."""
    rng = np.random.default_rng(seed)
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(np.asarray(vertices, dtype=np.float32))
    mesh.triangle.indices = o3d.core.Tensor(np.asarray(faces, dtype=np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    centre, size = (low + high) / 2, float(np.max(high - low))
    clouds = []
    for k in range(views):
        azimuth = 2 * np.pi * k / views + rng.uniform(-0.3, 0.3)
        elevation = rng.uniform(0.35, 0.8)
        eye = centre + sensor.distance_factor * size * np.array(
            [np.cos(azimuth) * np.cos(elevation), np.sin(azimuth) * np.cos(elevation),
             np.sin(elevation)])
        directions, forward = _look_at_rays(eye, centre, sensor)
        rays = np.concatenate([np.broadcast_to(eye, directions.shape), directions], axis=-1)
        hit = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
        valid = np.isfinite(hit["t_hit"].numpy())
        depth = np.where(valid, hit["t_hit"].numpy(), 0.0).astype(np.float64)
        normal = hit["primitive_normals"].numpy().astype(np.float64)
        unit = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
        cos = np.abs(np.einsum("ijk,ijk->ij", normal, unit))
        # flying pixels: at depth edges, smear towards what lies behind (a miss counts as a
        # background 30 % farther away)
        filled = np.where(valid, depth, np.inf)
        behind = np.max(np.stack([np.roll(filled, s, axis=a) for a in (0, 1) for s in (-1, 1)]),
                        axis=0)
        gap = np.zeros_like(depth)
        gap[valid] = np.where(np.isinf(behind[valid]), 0.3 * depth[valid],
                              behind[valid] - depth[valid])
        edge = valid & (gap > sensor.edge_jump_mm)
        fly = edge & (rng.random(depth.shape) < sensor.flying_fraction)
        depth = np.where(fly, depth + rng.uniform(0.1, 0.9, depth.shape) * gap, depth)
        # depth noise ∝ depth²
        sigma = sensor.noise_mm_at_500 * (depth / 500.0) ** 2
        depth = depth + rng.standard_normal(depth.shape) * sigma
        # dropouts
        keep = valid & (rng.random(depth.shape) >= sensor.dropout)
        keep &= ~((cos < sensor.grazing_cos) & (rng.random(depth.shape) < sensor.grazing_drop))
        rows, cols = np.indices(depth.shape)
        for _ in range(sensor.holes_per_view):
            r0, c0 = rng.integers(0, depth.shape[0]), rng.integers(0, depth.shape[1])
            keep &= (rows - r0) ** 2 + (cols - c0) ** 2 > sensor.hole_px ** 2
        clouds.append(eye + depth[keep][:, None] * directions[keep])
    points = np.vstack(clouds)
    count = int(sensor.outlier_fraction * len(points))
    span = (high - low) * 1.6
    outliers = centre + (rng.random((count, 3)) - 0.5) * span
    points = np.vstack([points, outliers])
    return points[rng.permutation(len(points))]


# ---------------------------------------------------------------------------- example files

EXAMPLES = {
    # name: (file name, units written, declared in the file?, sensor)
    "drainpipe": ("drainpipe.ply", "mm", True, SensorModel(width_px=400, height_px=300)),
    "rock_pile": ("rock_pile.pcd", "m", True, SensorModel(width_px=360, height_px=270)),
    "branch": ("branch.xyz", "m", False, SensorModel(width_px=640, height_px=480,
                                                     distance_factor=1.6)),
}


def write_example_scans(out_dir: str | Path, seed: int = 0,
                        truth_dir: str | Path | None = None) -> list[Path]:
    """Write the example scans (and optionally their reference meshes in mm) to ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for index, (name, (file_name, units, declared, sensor)) in enumerate(EXAMPLES.items()):
        mesh = scene_mesh(name, seed)
        points_mm = scan_points(mesh.vertices, mesh.faces, seed=seed * 100 + index,
                                sensor=sensor)
        points = points_mm / (1000.0 if units == "m" else 1.0)
        path = out_dir / file_name
        tag = units if declared else None
        if path.suffix == ".ply":
            write_ply_points(path, points, units=tag)
        elif path.suffix == ".pcd":
            write_pcd_points(path, points, units=tag)
        else:
            write_xyz_points(path, points, units=tag, fmt="%.6f" if units == "m" else "%.3f")
        written.append(path)
        if truth_dir is not None:
            Path(truth_dir).mkdir(parents=True, exist_ok=True)
            mesh.export(Path(truth_dir) / f"{name}.obj")
    return written
