"""Contact statics against the elastica (issue 24): a whisker turned slowly into a thin peg.

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
:data:`SLIP_HOLD_DEG`); pass-through: a point of the centre line (sampled along the links)
deeper than :data:`PASS_THROUGH_M` inside the peg.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.model.array import single_whisker
from pipeline.model.extensions import model_parts
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import load_morphology
from pipeline.model.whisker import WhiskerGeometry, rest_nodes
from pipeline.references.elastica import Path, Peg, Rod, peg_touching, quasi_static_path
from pipeline.reports.checks import rigid
from pipeline.scenes.obstacles import Cylinder, Scene, points_along

WHISKERS = ("RC1", "RC3", "RC5")
FRACTIONS = (0.30, 0.60, 0.85)
FRICTIONS = (0.0, 0.5)
ENGINES = ("bullet", "mujoco")
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


@dataclass(frozen=True)
class Case:
    whisker: str
    fraction: float
    friction: float
    engine: str

    @property
    def label(self) -> str:
        return f"{self.whisker} {self.fraction:.0%} μ={self.friction:g} {self.engine}"


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


def reference_path(rod: Rod, peg: Peg, friction: float) -> Path:
    angles = np.radians(np.arange(0.0, TOUCH_ANGLE_DEG + SWEEP_DEG + 1e-9, REFERENCE_STEP_DEG))
    return quasi_static_path(rod, peg, angles, friction)


def run_engine(config: ModelConfig, geometry: WhiskerGeometry, peg: Peg, speed_deg_s: float = SPEED_DEG_S):
    """(protraction angle per sample in degrees, TrialOutput) of one slow turn into the peg."""
    from pipeline.engines import create_engine

    end_deg = TOUCH_ANGLE_DEG + SWEEP_DEG
    duration = end_deg / speed_deg_s
    drive = ProtractionDrive(np.array([0.0, duration]), np.radians([0.0, end_deg]), interpolation="linear")
    scene = Scene("contact-statics", (Cylinder(peg.radius_m, PEG_LENGTH_M, (*peg.centre_m, 0.0)),))
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
              "compared_to_deg": float(end), "samples": int(inside.sum()),
              "deepest_mm": deepest * 1e3, "pass_through": bool(deepest > PASS_THROUGH_M),
              "max_moment_nm": float(scales[0]), "max_force_n": float(force_scale),
              "cpu_s": float(output.metadata.get("cpu_seconds", float("nan")))}
    return CaseResult(case, errors, angle_deg, engine, reference)


def run_case(config: ModelConfig, case: Case, speed_deg_s: float = SPEED_DEG_S,
             path: Path | None = None) -> CaseResult:
    """One whisker × contact position × friction × engine (``path``: the elastica, if known)."""
    geometry = geometry_of(config, case.whisker)
    rod = rod_of(geometry, config.material.youngs_modulus_gpa * 1e9)
    peg = peg_touching(rod, case.fraction, np.radians(TOUCH_ANGLE_DEG), PEG_RADIUS_M)
    path = path or reference_path(rod, peg, case.friction)
    angle, output = run_engine(bench_config(config, case.engine, case.friction), geometry, peg, speed_deg_s)
    return compare(case, angle, output, path, peg)


def run_cases(config: ModelConfig, whiskers=WHISKERS, fractions=FRACTIONS, frictions=FRICTIONS,
              engines=ENGINES, progress=lambda _: None) -> list[CaseResult]:
    """Every case; the elastica is solved once per whisker × position × friction."""
    results = []
    for whisker in whiskers:
        geometry = geometry_of(config, whisker)
        rod = rod_of(geometry, config.material.youngs_modulus_gpa * 1e9)
        for fraction in fractions:
            peg = peg_touching(rod, fraction, np.radians(TOUCH_ANGLE_DEG), PEG_RADIUS_M)
            for friction in frictions:
                path = reference_path(rod, peg, friction)
                for engine in engines:
                    case = Case(whisker, fraction, friction, engine)
                    progress(f"contact statics: {case.label}")
                    results.append(run_case(config, case, path=path))
    return results


TABLE_COLUMNS = ("whisker", "position", "μ", "engine", "M rms %", "F⊥ rms %", "F∥ rms % of |F|",
                 "M bias %", "slip-off elastica °", "slip-off engine °", "deepest mm", "pass-through")


def table_rows(results: list[CaseResult]) -> list[list[str]]:
    """One row per case, the columns of TABLE_COLUMNS."""
    def angle(value):
        return "held" if not np.isfinite(value) else f"{value:.2f}"

    rows = []
    for r in results:
        e, c = r.errors, r.case
        rows.append([c.whisker, f"{c.fraction:.0%}", f"{c.friction:g}", c.engine,
                     f"{e['moment_rms_pct']:.1f}", f"{e['transverse_rms_pct']:.1f}", f"{e['axial_rms_pct_of_f']:.1f}",
                     f"{e['moment_bias_pct']:+.1f}", angle(e["slip_off_ref_deg"]), angle(e["slip_off_engine_deg"]),
                     f"{e['deepest_mm']:.3f}", "yes" if e["pass_through"] else "no"])
    return rows
