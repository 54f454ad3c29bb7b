"""Contact statics against the elastica: a whisker turned slowly into a thin peg.

One whisker of the model rat (default material, rigid follicle: the base is clamped as in the
elastica) lies in the head's x–y plane, concave toward +y, and the drive turns it about z
(:func:`pipeline.model.array.single_whisker`), so the problem is planar. A vertical peg of
radius :data:`PEG_RADIUS_M` stands on the +y side where the rest shape, turned by
:data:`TOUCH_ANGLE_DEG`, touches it at a fraction of the arc length S. The base turns at
:data:`SPEED_DEG_S` (linear ramp, quasi-static: see benchmarks/bench_contact_statics.py) to
:data:`SWEEP_DEG` past the touch, and each output sample's base wrench (whisker frame: Mz, Fy
transverse, Fx axial) is compared with the planar elastica of
:mod:`pipeline.references.elastica` at the same base angle.

Errors, over the samples where both are in contact (from the touch to the earlier slip-off):
RMS of the moment and of the transverse force in % of the elastica's largest |value|, RMS of
the axial force in % of the elastica's largest |F|; the slip-off angle difference (engine −
elastica, degrees; the engine slips off at its last sample in contact when none follows within
:data:`SLIP_HOLD_DEG`; where the elastica's tip turns parallel to the obstacle its path ends,
without a slip-off, and so does the comparison); pass-through: a point of the centre line
(sampled along the links) deeper than :data:`PASS_THROUGH_M` inside the peg.

The peg is a :class:`~pipeline.scenes.obstacles.Cylinder` (``facets`` 0), or a closed
:class:`~pipeline.scenes.obstacles.TriangleMesh` with ``facets`` flat sides round (vertices on
the circle, rings every :data:`MESH_RING_M` along the axis, capped): the engines' scan contact
(Bullet's own solver with a skin, MuJoCo's prism per face) against the same elastica.

A wall case (``wall``) puts a flat wall, normal −y, where the tip touches it at the touch angle:
a :class:`~pipeline.scenes.obstacles.Box` (``facets`` 0) or the same box as a triangle mesh
(12 faces); the tip then slides along it. Its elastica is a peg of radius :data:`WALL_RADIUS_M`
tangent to the wall there (≤ 0.02 mm from the plane over the tip's travel).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import get_args

import numpy as np
import trimesh

from pipeline.config.physics import EngineName, ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import single_whisker
from pipeline.model.effects.registry import model_parts
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import load_morphology
from pipeline.model.whisker import WhiskerGeometry, rest_nodes
from pipeline.references.elastica import Path, Peg, Rod, peg_touching, quasi_static_path, rest_shape, rotate
from pipeline.reports.checks import Section, check, rigid
from pipeline.reports.published import Published
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh, points_along

WHISKERS = ("RC1", "RC3", "RC5")
FRACTIONS = (0.30, 0.60, 0.85)
FRICTIONS = (0.0, 0.5)
ENGINES = get_args(EngineName)     # every engine (config/physics.py)
QUICK = {"whiskers": ("RC3",), "fractions": (0.60,), "frictions": (0.0,)}
PEG_RADIUS_M = 0.5e-3            # the library's 1 mm pegs
PEG_LENGTH_M = 0.02
TOUCH_ANGLE_DEG = 2.0
SWEEP_DEG = 30.0
SPEED_DEG_S = 10.0
REFERENCE_STEP_DEG = 0.25
ROD_GRID = 401
SLIP_HOLD_DEG = 1.0
PASS_THROUGH_M = 0.05e-3
MESH_FACETS = (16, 64, 256)      # meshed pegs: flat sides round
MESH_RING_M = 2e-3               # meshed pegs: spacing of the vertex rings along the axis
WALL_RADIUS_M = 1.0              # the elastica's stand-in for a flat wall
WALL_HALF_EXTENTS_M = (10e-3, 1e-3, 10e-3)    # the wall box: along x, thickness (y), height (z)


@dataclass(frozen=True)
class Case:
    whisker: str
    fraction: float
    friction: float
    engine: str
    facets: int = 0                 # 0: the analytic peg or Box wall; else meshed (module docstring)
    wall: bool = False              # a flat wall touched by the tip instead of a peg (``fraction`` 1)

    @property
    def obstacle(self) -> str:
        if self.wall:
            return "wall mesh" if self.facets else "wall box"
        return f"mesh {self.facets}" if self.facets else "cylinder"

    @property
    def label(self) -> str:
        shape = f" {self.obstacle}" if self.facets or self.wall else ""
        return f"{self.whisker} {self.fraction:.0%} μ={self.friction:g} {self.engine}{shape}"


@dataclass
class CaseResult:
    case: Case
    errors: dict                    # the numbers of the table (module docstring)
    angle_deg: np.ndarray = field(repr=False, default=None)        # [T] base angle of the samples
    engine_wrench: np.ndarray = field(repr=False, default=None)    # [T, 3] Mz, Fy, Fx
    reference_wrench: np.ndarray = field(repr=False, default=None)  # [T, 3] NaN outside contact


def geometry_of(config: ModelConfig, name: str) -> WhiskerGeometry:
    s = load_morphology(config.morphology)[name]
    return WhiskerGeometry(s.arc_length_m, s.base_radius_m, s.tip_radius_m, s.curvature_per_m)


def rod_of(geometry: WhiskerGeometry, youngs_modulus_pa: float, points: int = ROD_GRID) -> Rod:
    """The continuum whisker the model discretises: radius linear from base to tip, rest shape
    y = A·x² (κ0 = 2A / (1 + 4A²x²)^{3/2} at the x of each arc length)."""
    arc = geometry.arc_length_m * np.linspace(0.0, 1.0, points)
    x = rest_nodes(geometry, points - 1)[:, 0]
    a = geometry.curvature_per_m
    curvature = 2 * a / (1 + (2 * a * x) ** 2) ** 1.5
    radius = geometry.base_radius_m + (geometry.tip_radius_m - geometry.base_radius_m) * arc / geometry.arc_length_m
    return Rod.from_radius(arc, radius, youngs_modulus_pa, curvature)


def bench_config(config: ModelConfig, engine: str, friction: float) -> ModelConfig:
    """``config`` on ``engine`` (its default step) with friction μ and a clamped base."""
    bench = rigid(config)
    return bench.model_copy(update={"engine": bench.engine.model_copy(
        update={"name": engine, "contact_friction": friction})})


def reference_path(rod: Rod, peg: Peg, friction: float, sweep_deg: float = SWEEP_DEG) -> Path:
    angles = np.radians(np.arange(0.0, TOUCH_ANGLE_DEG + sweep_deg + 1e-9, REFERENCE_STEP_DEG))
    return quasi_static_path(rod, peg, angles, friction)


def peg_mesh(peg: Peg, facets: int, length_m: float = PEG_LENGTH_M) -> TriangleMesh:
    """The vertical peg as a closed triangle mesh: ``facets`` flat sides with their vertices on
    the circle, rings every :data:`MESH_RING_M` (at most) along z ∈ ±length/2, a fan per cap;
    faces wound outward."""
    rings = max(2, int(np.ceil(length_m / MESH_RING_M)) + 1)
    phi = 2 * np.pi * np.arange(facets) / facets
    z = np.linspace(-0.5 * length_m, 0.5 * length_m, rings)
    cx, cy = peg.centre_m
    side = np.stack([np.tile(cx + peg.radius_m * np.cos(phi), rings), np.tile(cy + peg.radius_m * np.sin(phi), rings),
                     np.repeat(z, facets)], axis=1)
    vertices = np.concatenate([side, [[cx, cy, z[0]], [cx, cy, z[-1]]]])
    bottom, top = len(side), len(side) + 1
    k = np.arange(facets)
    faces = []
    for r in range(rings - 1):
        a, b = r * facets + k, r * facets + (k + 1) % facets            # ring r, counter-clockwise
        faces += [np.stack([a, b, b + facets], axis=1), np.stack([a, b + facets, a + facets], axis=1)]
    last = (rings - 1) * facets
    faces += [np.stack([np.full(facets, bottom), (k + 1) % facets, k], axis=1),
              np.stack([np.full(facets, top), last + k, last + (k + 1) % facets], axis=1)]
    return TriangleMesh(vertices, np.concatenate(faces), source=f"peg-{facets}-{cx:.6g}-{cy:.6g}-{peg.radius_m:g}")


def wall_touching(rod: Rod, touch_angle_rad: float) -> Peg:
    """The elastica's wall: a circle of radius :data:`WALL_RADIUS_M` on the +y side of the rest
    shape's tip turned by ``touch_angle_rad``, touching it there with its lowest point."""
    tip = rotate(rest_shape(rod)[-1:], touch_angle_rad)[0]
    return Peg((float(tip[0]), float(tip[1] + rod.radius_m[-1] + WALL_RADIUS_M)), WALL_RADIUS_M)


def wall_obstacle(peg: Peg, meshed: bool):
    """The flat wall tangent to the elastica's ``peg`` at its lowest point: a Box, or the same
    box as a closed triangle mesh."""
    centre = (peg.centre_m[0], peg.centre_m[1] - peg.radius_m + WALL_HALF_EXTENTS_M[1], 0.0)
    if not meshed:
        return Box(WALL_HALF_EXTENTS_M, centre)
    box = trimesh.creation.box(2 * np.asarray(WALL_HALF_EXTENTS_M))
    return TriangleMesh(np.asarray(box.vertices) + centre, np.asarray(box.faces), source=f"wall-{centre}")


def peg_obstacle(peg: Peg, facets: int = 0, wall: bool = False):
    """The obstacle as the engines see it: a Cylinder (``facets`` 0) or :func:`peg_mesh`; for a
    wall :func:`wall_obstacle`."""
    if wall:
        return wall_obstacle(peg, bool(facets))
    return peg_mesh(peg, facets) if facets else Cylinder(peg.radius_m, PEG_LENGTH_M, (*peg.centre_m, 0.0))


def run_engine(config: ModelConfig, geometry: WhiskerGeometry, peg: Peg, speed_deg_s: float = SPEED_DEG_S,
               sweep_deg: float = SWEEP_DEG, facets: int = 0, wall: bool = False, obstacle=None):
    """(protraction angle per sample in degrees, TrialOutput) of one slow turn into the peg
    (``facets``, ``wall``: :func:`peg_obstacle`), or into ``obstacle`` if given."""
    end_deg = TOUCH_ANGLE_DEG + sweep_deg
    duration = end_deg / speed_deg_s
    drive = ProtractionDrive(np.array([0.0, duration]), np.radians([0.0, end_deg]), interpolation="linear")
    obstacle = obstacle if obstacle is not None else peg_obstacle(peg, facets, wall)
    scene = Scene(f"contact-statics-{facets}-{wall}", (obstacle,))
    material, extensions = model_parts(config)
    with create_engine(config, single_whisker(geometry, material, extensions=extensions)) as engine:
        output = engine.run(scene, Pose(), drive, duration)
    return np.degrees(drive(output.time_s)), output


def engine_slip_off_deg(angle_deg: np.ndarray, touching: np.ndarray) -> float:
    """Angle of the last sample in contact when no contact follows within SLIP_HOLD_DEG; NaN if
    the contact holds to the end (or never starts)."""
    if not touching.any():
        return float("nan")
    k = np.flatnonzero(touching)
    gaps = np.flatnonzero((angle_deg[k[1:]] - angle_deg[k[:-1]]) > SLIP_HOLD_DEG)
    last = k[gaps[0]] if gaps.size else k[-1]
    return float(angle_deg[last]) if angle_deg[-1] - angle_deg[last] > SLIP_HOLD_DEG else float("nan")


def deepest_m(output, peg: Peg) -> float:
    """Largest depth (m) of the whisker's centre line inside the peg (points along the links)."""
    nodes = output.node_positions_m[:, 0].astype(float)
    points = points_along(nodes, 0.1 * peg.radius_m)                  # [T, P, 3]
    distance = np.hypot(points[..., 0] - peg.centre_m[0], points[..., 1] - peg.centre_m[1])
    return float(np.max(peg.radius_m - distance))


def compare(case: Case, angle_deg: np.ndarray, output, path: Path, peg: Peg) -> CaseResult:
    """The errors of one engine run against the elastica path (module docstring)."""
    wrench = output.base_wrench[:, 0].astype(float)
    engine = np.stack([wrench[:, 5], wrench[:, 1], wrench[:, 0]], axis=1)
    ref_angle = np.degrees(path.series("base_angle_rad"))
    ref = np.stack([path.series(k) for k in ("base_moment_nm", "transverse_force_n", "axial_force_n")], axis=1)
    ref_slip = np.degrees(path.slip_off_angle_rad)
    engine_slip = engine_slip_off_deg(angle_deg, output.contact[:, 0].any(axis=1))
    end = np.nanmin([ref_slip, engine_slip, ref_angle[-1]])
    inside = (angle_deg > np.degrees(path.touch_angle_rad)) & (angle_deg <= end) & (angle_deg >= ref_angle[0])
    reference = np.full_like(engine, np.nan)
    for j in range(3):
        reference[inside, j] = np.interp(angle_deg[inside], ref_angle, ref[:, j])
    force_scale = np.max(np.hypot(ref[:, 1], ref[:, 2]))
    scales = (np.max(np.abs(ref[:, 0])), np.max(np.abs(ref[:, 1])), force_scale)
    difference = engine[inside] - reference[inside]
    rms = [float(100 * np.sqrt(np.mean(difference[:, j] ** 2)) / scales[j]) if inside.any() else float("nan")
           for j in range(3)]
    bias = [float(100 * np.mean(difference[:, j]) / scales[j]) if inside.any() else float("nan") for j in range(3)]
    deepest = deepest_m(output, peg)
    errors = {"moment_rms_pct": rms[0], "transverse_rms_pct": rms[1], "axial_rms_pct_of_f": rms[2],
              "moment_bias_pct": bias[0], "transverse_bias_pct": bias[1], "axial_bias_pct_of_f": bias[2],
              "slip_off_ref_deg": float(ref_slip), "slip_off_engine_deg": engine_slip,
              "slip_off_diff_deg": float(engine_slip - ref_slip),
              "tip_tangent_ref_deg": float(np.degrees(path.tip_tangent_angle_rad)),
              "end_deg": float(end), "sweep_end_deg": float(angle_deg[-1]), "samples": int(inside.sum()),
              "deepest_mm": deepest * 1e3, "pass_through": bool(deepest > PASS_THROUGH_M),
              "max_moment_nm": float(scales[0]), "max_force_n": float(force_scale),
              "cpu_s": float(output.metadata.get("cpu_seconds", float("nan")))}
    return CaseResult(case, errors, angle_deg, engine, reference)


def run_case(config: ModelConfig, case: Case, speed_deg_s: float = SPEED_DEG_S,
             path: Path | None = None, sweep_deg: float = SWEEP_DEG) -> CaseResult:
    """One whisker × contact position × friction × engine, the base turned ``sweep_deg`` past the
    touch (``path``: the elastica, if known)."""
    geometry = geometry_of(config, case.whisker)
    rod = rod_of(geometry, config.material.youngs_modulus_gpa * 1e9)
    peg = obstacle_circle(rod, case.fraction, case.wall)
    path = path or reference_path(rod, peg, case.friction, sweep_deg)
    angle, output = run_engine(bench_config(config, case.engine, case.friction), geometry, peg, speed_deg_s,
                               sweep_deg, case.facets, case.wall)
    return compare(case, angle, output, path, peg)


def obstacle_circle(rod: Rod, fraction: float, wall: bool) -> Peg:
    """The elastica's obstacle: the peg touched at ``fraction`` of S, or the wall's circle."""
    if wall:
        return wall_touching(rod, np.radians(TOUCH_ANGLE_DEG))
    return peg_touching(rod, fraction, np.radians(TOUCH_ANGLE_DEG), PEG_RADIUS_M)


def run_cases(config: ModelConfig, whiskers=WHISKERS, fractions=FRACTIONS, frictions=FRICTIONS,
              engines=ENGINES, progress=lambda _: None, sweep_deg: float = SWEEP_DEG,
              facets=(0,), wall: bool = False) -> list[CaseResult]:
    """Every case (``facets``: the pegs, 0 the analytic one; ``wall``: the walls instead of
    pegs, ``fractions`` ignored); the elastica is solved once per whisker × position × friction."""
    results = []
    for whisker in whiskers:
        geometry = geometry_of(config, whisker)
        rod = rod_of(geometry, config.material.youngs_modulus_gpa * 1e9)
        for fraction in (1.0,) if wall else fractions:
            peg = obstacle_circle(rod, fraction, wall)
            for friction in frictions:
                path = reference_path(rod, peg, friction, sweep_deg)
                for engine in engines:
                    for peg_facets in facets:
                        case = Case(whisker, fraction, friction, engine, peg_facets, wall)
                        progress(f"contact statics: {case.label}")
                        results.append(run_case(config, case, path=path, sweep_deg=sweep_deg))
    return results


TABLE_COLUMNS = ("whisker", "position", "μ", "engine", "peg", "M rms %", "F⊥ rms %", "F∥ rms % of |F|",
                 "M bias %", "slip-off elastica °", "slip-off engine °", "deepest mm", "pass-through")


def table_rows(results: list[CaseResult]) -> list[list[str]]:
    """One row per case, the columns of TABLE_COLUMNS."""
    def angle(value, tangent=float("nan")):
        if np.isfinite(tangent):
            return f"tip ∥ at {tangent:.2f}"
        return "held" if not np.isfinite(value) else f"{value:.2f}"

    rows = []
    for r in results:
        e, c = r.errors, r.case
        rows.append([c.whisker, f"{c.fraction:.0%}", f"{c.friction:g}", c.engine, c.obstacle,
                     f"{e['moment_rms_pct']:.1f}", f"{e['transverse_rms_pct']:.1f}", f"{e['axial_rms_pct_of_f']:.1f}",
                     f"{e['moment_bias_pct']:+.1f}", angle(e["slip_off_ref_deg"], e["tip_tangent_ref_deg"]),
                     angle(e["slip_off_engine_deg"]),
                     f"{e['deepest_mm']:.3f}", "yes" if e["pass_through"] else "no"])
    return rows


# -- `pipeline validate`: the section ------------------------------------------------------
ISSUE = "issue 24, done-when (against the elastica)"
TARGETS = {"moment": Published(3.0, None, ISSUE), "transverse": Published(3.0, None, ISSUE),
           "axial": Published(5.0, None, ISSUE), "axial_friction": Published(10.0, None, ISSUE),
           "slip_off": Published(0.5, None, ISSUE), "pass_through": Published(0, None, ISSUE)}
QUICK_SWEEP_DEG = 8.0


def slip_off_gap_deg(errors: dict) -> float:
    """|engine − elastica| slip-off angle (°): 0 if neither slips off within the sweep (or the
    engine not before the elastica's path ends with its tip along the obstacle); if only one
    does, its distance to the end of the comparison (a lower bound)."""
    engine, ref = errors["slip_off_engine_deg"], errors["slip_off_ref_deg"]
    tangent = errors["tip_tangent_ref_deg"]
    if np.isfinite(tangent) and not engine < tangent:      # the elastica's path ended first
        engine = float("nan")
    if np.isfinite(engine) and np.isfinite(ref):
        return abs(engine - ref)
    if np.isfinite(engine) or np.isfinite(ref):
        return abs(errors["sweep_end_deg"] - (engine if np.isfinite(engine) else ref))
    return 0.0


def contact_statics_section(config: ModelConfig, quick: bool, progress=lambda _: None) -> Section:
    """Section ``contact_statics``: the configured engine against the elastica, worst case of
    each error against the issue's targets; every case in the summary."""
    chosen = QUICK if quick else {"whiskers": WHISKERS, "fractions": FRACTIONS, "frictions": FRICTIONS}
    sweep = QUICK_SWEEP_DEG if quick else SWEEP_DEG
    results = run_cases(config, chosen["whiskers"], chosen["fractions"], chosen["frictions"],
                        (config.engine.name,), progress, sweep)

    def worst(name, frictions=(0.0, 0.5)):
        values = [r.errors[name] for r in results if r.case.friction in frictions]
        return float(np.nanmax(values)) if values else float("nan")

    slip = max(slip_off_gap_deg(r.errors) for r in results)
    through = sum(r.errors["pass_through"] for r in results)
    checks = [
        check("contact_moment_rms_pct", "base moment RMS error, worst case (% of the elastica's max)",
              TARGETS["moment"], worst("moment_rms_pct"), worst("moment_rms_pct") <= 3.0, "≤ 3 %"),
        check("contact_transverse_rms_pct", "transverse force RMS error, worst case (% of max)",
              TARGETS["transverse"], worst("transverse_rms_pct"), worst("transverse_rms_pct") <= 3.0, "≤ 3 %"),
        check("contact_axial_pct", "axial force RMS error, μ = 0, worst case (% of max |F|)", TARGETS["axial"],
              worst("axial_rms_pct_of_f", (0.0,)), worst("axial_rms_pct_of_f", (0.0,)) <= 5.0, "≤ 5 %"),
        check("contact_axial_friction_pct", "axial force RMS error, μ = 0.5, worst case (% of max |F|)",
              TARGETS["axial_friction"], worst("axial_rms_pct_of_f", (0.5,)),
              worst("axial_rms_pct_of_f", (0.5,)) <= 10.0, "≤ 10 %"),
        check("contact_slip_off_deg", "slip-off angle difference, worst case (°)", TARGETS["slip_off"], slip,
              slip <= 0.5, "≤ 0.5°"),
        check("contact_pass_through", "cases with the centre line > 0.05 mm inside the peg", TARGETS["pass_through"],
              through, through == 0, "none"),
    ]
    cases = [{"whisker": r.case.whisker, "fraction": r.case.fraction, "friction": r.case.friction,
              "engine": r.case.engine, **r.errors} for r in results]
    caption = (f"Contact statics: {', '.join(chosen['whiskers'])} turned about the base at {SPEED_DEG_S:g} °/s "
               f"into a peg of radius {PEG_RADIUS_M * 1e3:g} mm touched at "
               f"{', '.join(f'{f:.0%}' for f in chosen['fractions'])} of the arc, μ = "
               f"{', '.join(f'{f:g}' for f in chosen['frictions'])}, rigid follicle, compared with the planar "
               f"elastica (pipeline/references/elastica.py) over {sweep:g}° past the touch. Per case "
               "(whisker, position, μ: moment / transverse / axial RMS error %): " + "; ".join(
                   f"{r.case.whisker} {r.case.fraction:.0%} μ={r.case.friction:g}: "
                   f"{r.errors['moment_rms_pct']:.1f} / {r.errors['transverse_rms_pct']:.1f} / "
                   f"{r.errors['axial_rms_pct_of_f']:.1f}" for r in results) + ".")
    series = {r.case.label: (r.angle_deg, r.engine_wrench, r.reference_wrench) for r in results}
    return Section("contact_statics", "Contact statics against the elastica (issue 24)", checks,
                   {"sweep_deg": sweep, "speed_deg_s": SPEED_DEG_S, "peg_radius_m": PEG_RADIUS_M, "cases": cases},
                   series, caption)
