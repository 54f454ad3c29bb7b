"""Stick and slip of a whisker's tip on a flat face: the engines against the elastica.

One whisker of the model rat (default material, rigid follicle) turns slowly about z, as in
:mod:`pipeline.reports.contact_statics`, until its tip meets a flat face at an incline α to the
tip's rest tangent (:mod:`pipeline.references.tip_on_plane`: α = 90° head-on, small α grazing)
after :data:`~pipeline.reports.contact_statics.TOUCH_ANGLE_DEG`, and on for ``sweep_deg``. The
face is a :class:`~pipeline.scenes.obstacles.Box` (``meshed`` False) or the same box as a closed
triangle mesh (the engines' scan contact path). Compared with the frictional elastica at each
sample's base angle, over the samples where both touch and the elastica's path goes on: RMS of
the base moment and of the transverse force in % of the elastica's largest |value|, of the axial
force in % of its largest |F|. And the tip's slip: per sample, whether the tip's centre line
point moves along the face by more than :data:`SLIP_FRACTION` of what the rigid turn would move it
(the elastica: its states' stick or slide); the fraction of compared samples on which engine and
elastica disagree, and each one's first slip after a stick (the slip onset, degrees).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from pipeline.config.physics import ModelConfig
from pipeline.references.elastica import Path
from pipeline.references.tip_on_plane import face_touching, slip_onset_rad, tip_path
from pipeline.reports.contact_statics import (SPEED_DEG_S, TOUCH_ANGLE_DEG, bench_config,
                                              geometry_of, rod_of, run_engine)
from pipeline.scenes.obstacles import Box, TriangleMesh

FACE_HALF_EXTENTS_M = (10e-3, 1e-3, 10e-3)      # along the face, thickness, height (z)
SLIP_FRACTION = 0.1
SWEEP_DEG = 6.0
REFERENCE_STEP_DEG = 0.1          # the elastica's continuation step (a stick or slip onset to ±0.1°)


@dataclass(frozen=True)
class FaceCase:
    whisker: str
    incline_deg: float
    friction: float
    engine: str
    meshed: bool = False

    @property
    def label(self) -> str:
        return (f"{self.whisker} α={self.incline_deg:g}° μ={self.friction:g} {self.engine} "
                f"{'mesh' if self.meshed else 'box'}")


@dataclass
class FaceResult:
    case: FaceCase
    errors: dict
    angle_deg: np.ndarray = field(repr=False, default=None)
    engine_wrench: np.ndarray = field(repr=False, default=None)      # [T, 3] Mz, Fy, Fx
    reference_wrench: np.ndarray = field(repr=False, default=None)   # [T, 3], NaN outside
    engine_slip: np.ndarray = field(repr=False, default=None)        # [T] bool, compared samples
    reference_slip: np.ndarray = field(repr=False, default=None)


def face_obstacle(surface_m: np.ndarray, normal: np.ndarray, meshed: bool):
    """A box whose +y face (outward normal ``normal``, in the x–y plane) passes through
    ``surface_m``; or the same box as a closed triangle mesh."""
    along = np.array([normal[1], -normal[0], 0.0])
    rotation = np.stack([along, [normal[0], normal[1], 0.0], [0.0, 0.0, 1.0]], axis=1)
    centre = np.array([*(surface_m - FACE_HALF_EXTENTS_M[1] * normal), 0.0])
    if not meshed:
        return Box(FACE_HALF_EXTENTS_M, tuple(centre), tuple(map(tuple, rotation)))
    box = trimesh.creation.box(2 * np.asarray(FACE_HALF_EXTENTS_M))
    return TriangleMesh(np.asarray(box.vertices) @ rotation.T + centre, np.asarray(box.faces),
                        source=f"face-{centre}-{normal}")


def sawtooth_obstacle(surface_m: np.ndarray, normal: np.ndarray, amplitude_m: float, period_m: float) -> TriangleMesh:
    """The face of :func:`face_obstacle` made rough: a closed slab whose top is a sawtooth
    across the face (ridges on the face's plane through ``surface_m``, valleys ``amplitude_m``
    below it, ``period_m`` apart, straight along z), faces wound outward: a tip on a scan's
    facets, crossing ridges (convex edges) and valleys."""
    half, depth, height = FACE_HALF_EXTENTS_M[0], 2 * FACE_HALF_EXTENTS_M[1], FACE_HALF_EXTENTS_M[2]
    u = np.arange(-half, half + 1e-12, period_m / 2)
    top = np.where(np.arange(len(u)) % 2 == 0, 0.0, -amplitude_m)
    # vertex (k, level, side): level 0 the bottom, 1 the sawtooth; side 0 at −z, 1 at +z
    grid = np.stack(np.meshgrid(np.arange(len(u)), [0, 1], [0, 1], indexing="ij"), axis=-1).reshape(-1, 3)
    k, level, side = grid.T
    local = np.stack([u[k], np.where(level == 1, top[k], -depth), (2 * side - 1) * height], axis=1)
    index = np.arange(len(grid)).reshape(len(u), 2, 2)
    quads, outward = [], []
    for j in range(len(u) - 1):
        for lv in (0, 1):
            quads.append(index[[j, j + 1, j + 1, j], lv, [0, 0, 1, 1]])
            outward.append((0.0, 1.0 if lv else -1.0, 0.0))
        for sd in (0, 1):
            quads.append(index[[j, j + 1, j + 1, j], [0, 0, 1, 1], sd])
            outward.append((0.0, 0.0, 1.0 if sd else -1.0))
    for j, sign in ((0, -1.0), (len(u) - 1, 1.0)):
        quads.append(index[j, [0, 1, 1, 0], [0, 0, 1, 1]])
        outward.append((sign, 0.0, 0.0))
    faces = []
    for (a, b, c, d), out in zip(quads, outward):
        for tri in ((a, b, c), (a, c, d)):
            turn = np.cross(local[tri[1]] - local[tri[0]], local[tri[2]] - local[tri[0]])
            faces.append(tri if turn @ np.asarray(out) > 0 else tri[::-1])
    along = np.array([normal[1], -normal[0]])
    world = np.stack([surface_m[0] + local[:, 0] * along[0] + local[:, 1] * normal[0],
                      surface_m[1] + local[:, 0] * along[1] + local[:, 1] * normal[1], local[:, 2]], axis=1)
    return TriangleMesh(world, np.array(faces), source=f"sawtooth-{surface_m}-{normal}-{amplitude_m}-{period_m}")


def slipping(angle_deg: np.ndarray, tip_m: np.ndarray, along: np.ndarray, lever_m: float) -> np.ndarray:
    """[T] the tip moves along the face (unit ``along``) faster than SLIP_FRACTION of the rigid
    turn's rate ``lever_m`` per radian (central differences of the tip points [T, 2])."""
    position = tip_m @ along
    rate = np.gradient(position, np.radians(angle_deg))
    return np.abs(rate) > SLIP_FRACTION * lever_m


def first_slip_deg(angle_deg: np.ndarray, slip: np.ndarray) -> float:
    """The first slipping angle after a stuck one (NaN if none)."""
    stuck = np.flatnonzero(~slip)
    if not stuck.size:
        return float("nan")
    after = np.flatnonzero(slip[stuck[0]:])
    return float(angle_deg[stuck[0] + after[0]]) if after.size else float("nan")


def reference_of(config: ModelConfig, whisker: str, incline_deg: float, friction: float,
                 sweep_deg: float = SWEEP_DEG):
    """(rod, elastica path, face point, face normal) of one whisker, incline and μ."""
    rod = rod_of(geometry_of(config, whisker), config.material.youngs_modulus_gpa * 1e9)
    touch = np.radians(TOUCH_ANGLE_DEG)
    _, surface, normal = face_touching(rod, touch, np.radians(incline_deg))
    angles = np.radians(np.arange(TOUCH_ANGLE_DEG, TOUCH_ANGLE_DEG + sweep_deg + 1e-9, REFERENCE_STEP_DEG))
    path = tip_path(rod, touch, np.radians(incline_deg), angles, friction)
    return rod, path, surface, normal


def run_face_case(config: ModelConfig, case: FaceCase, sweep_deg: float = SWEEP_DEG, reference=None) -> FaceResult:
    """One whisker × incline × μ × engine × face (``reference``: :func:`reference_of`'s, if known)."""
    rod, path, surface, normal = reference or reference_of(config, case.whisker, case.incline_deg, case.friction,
                                                            sweep_deg)
    obstacle = face_obstacle(surface, normal, case.meshed)
    angle, output = run_engine(bench_config(config, case.engine, case.friction), geometry_of(config, case.whisker),
                               None, SPEED_DEG_S, sweep_deg, obstacle=obstacle)
    return compare_face(case, angle, output, path, rod.length_m, normal)


def compare_face(case: FaceCase, angle_deg: np.ndarray, output, path: Path, length_m: float,
                 normal: np.ndarray) -> FaceResult:
    """The errors of one engine run against the elastica (module docstring)."""
    wrench = output.base_wrench[:, 0].astype(float)
    engine = np.stack([wrench[:, 5], wrench[:, 1], wrench[:, 0]], axis=1)
    along = np.array([normal[1], -normal[0]])
    ref_angle = np.degrees(path.series("base_angle_rad"))
    ref = np.stack([path.series(k) for k in ("base_moment_nm", "transverse_force_n", "axial_force_n")], axis=1)
    ref_tip = np.array([s.shape_m[-1] for s in path.states])
    lever = float(np.linalg.norm(ref_tip[0]))
    ref_slip = slipping(ref_angle, ref_tip, along, lever)
    tip = output.node_positions_m[:, 0, -1, :2].astype(float)
    engine_slip = slipping(angle_deg, tip, along, lever)
    touching = output.contact[:, 0].any(axis=1)
    end = ref_angle[-1]
    inside = (angle_deg > ref_angle[0]) & (angle_deg <= end) & touching
    reference = np.full_like(engine, np.nan)
    for j in range(3):
        reference[inside, j] = np.interp(angle_deg[inside], ref_angle, ref[:, j])
    scales = (np.max(np.abs(ref[:, 0])), np.max(np.abs(ref[:, 1])), np.max(np.hypot(ref[:, 1], ref[:, 2])))
    difference = engine[inside] - reference[inside]
    rms = [float(100 * np.sqrt(np.mean(difference[:, j] ** 2)) / scales[j]) if inside.any() else float("nan")
           for j in range(3)]
    ref_slip_at = np.interp(angle_deg, ref_angle, ref_slip.astype(float)) > 0.5
    disagree = float(np.mean(engine_slip[inside] != ref_slip_at[inside])) if inside.any() else float("nan")
    ratio = path.series("tangential_force_n") / path.series("normal_force_n")
    errors = {"moment_rms_pct": rms[0], "transverse_rms_pct": rms[1], "axial_rms_pct_of_f": rms[2],
              "slip_disagree_pct": 100 * disagree, "samples": int(inside.sum()), "end_deg": float(end),
              "slip_onset_ref_deg": float(np.degrees(slip_onset_rad(path))),
              "slip_onset_engine_deg": first_slip_deg(angle_deg[inside], engine_slip[inside]),
              "ref_stick_pct": float(100 * np.mean(~ref_slip)), "ref_ratio_range": (float(ratio.min()), float(ratio.max())),
              "engine_stick_pct": float(100 * np.mean(~engine_slip[inside])) if inside.any() else float("nan"),
              "touch_engine_deg": float(angle_deg[np.argmax(touching)]) if touching.any() else float("nan"),
              "path_end": "tip along the face" if np.isfinite(path.tip_tangent_angle_rad) else
              ("no equilibrium" if np.isfinite(path.slip_off_angle_rad) else "sweep"),
              "length_m": length_m}
    return FaceResult(case, errors, angle_deg, engine, reference, engine_slip & inside, ref_slip_at & inside)
