"""``pipeline calibrate``: fit model parameters to a measurement, with uncertainties.

Objective: the paper's median symmetric accuracy, eq. 4a over FRF, δ and amplitude of
motor-driven trials and eq. 4b over FRF, y0 and y1 of release trials (resonance tables: f1
and δ, and f2/f3 when given); ``trajectory`` fits every tracked position instead (more
information, needed for most extensions). The start matches the measured FRF and δ
(:func:`~pipeline.diagnosis.fitting.matched_start`); the fast simulator does the fit and an
engine can check and refine it (:func:`~pipeline.diagnosis.fitting.refine_with_engine`).
"""

from __future__ import annotations

from typing import get_args

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.candidates import WhiskerScales, starts_for
from pipeline.diagnosis.choices import FitMethod, ObjectiveName
from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fitting import bootstrap as bootstrap_sd
from pipeline.diagnosis.fitting import best_start, engine_check, fit, matched_start
from pipeline.diagnosis.in_plane import first_damped_in_plane
from pipeline.diagnosis.objective import FeatureObjective, TableObjective, TrajectoryObjective
from pipeline.diagnosis.parameters import ModelSpec, parameter
from pipeline.diagnosis.threads import single_threaded_blas
from pipeline.engines.linear.chain import linearise
from pipeline.errors import UserError
from pipeline.measurements.table import ResonanceTable

OBJECTIVES = get_args(ObjectiveName)
MAX_ITERATIONS = 60


def _objective(measurement, kind: str, simulator=None):
    if isinstance(measurement, ResonanceTable):
        if kind != "msa":
            raise UserError("a resonance table has no trajectories: use --objective msa")
        return TableObjective(measurement, simulator)
    if kind not in OBJECTIVES:
        raise UserError(f"unknown objective '{kind}' ({' or '.join(OBJECTIVES)})")
    return (FeatureObjective if kind == "msa" else TrajectoryObjective)(measurement, simulator)


def _table_sigma(objective) -> np.ndarray | None:
    sigma = objective.log_sd() if isinstance(objective, TableObjective) else None
    return sigma if sigma is not None and np.all(np.isfinite(sigma)) and np.all(sigma > 0) else None


def modal_summary(spec: ModelSpec, geometry) -> dict:
    """First in-plane mode of the fitted whisker: damped frequency (Hz) and damping ratio (both
    NaN, null in the JSON, when the fitted whisker is overdamped in-plane)."""
    f1, zeta1 = first_damped_in_plane(linearise(spec.physics(geometry)))
    return {"f1_hz": f1, "zeta1": zeta1}


BOUND_TOLERANCE = 1e-6      # relative distance from a bound at which a fitted value is pinned to it


def pinned_notes(values: dict[str, float]) -> list[str]:
    """Warnings for fitted values at a bound of their range: their sd is not an uncertainty."""
    notes = []
    for name, value in values.items():
        spec = parameter(name)
        for side, bound in (("lower", spec.lower), ("upper", spec.upper)):
            if abs(value - bound) <= BOUND_TOLERANCE * max(abs(bound), abs(value), 1e-300):
                notes.append(f"warning: {name} = {value:.5g} is pinned at its {side} bound: the data do not "
                             "constrain it within its range, and its sd is not an uncertainty")
    return notes


def calibrate(measurement, names=("E", "zeta"), method: FitMethod = "optimizer", objective: ObjectiveName = "msa",
              material: MaterialConfig | None = None, engine: str | None = None, bootstrap: int = 0,
              grid_points: int | None = None) -> dict:
    """Fit ``names`` to ``measurement`` (time series or resonance table); JSON-ready result."""
    with single_threaded_blas():
        return _calibrate(measurement, tuple(names), method, objective, material or MaterialConfig(),
                          engine, bootstrap, grid_points)


def _calibrate(measurement, names, method, objective, material, engine, bootstrap, grid_points) -> dict:
    target = _objective(measurement, objective)
    starter = target if isinstance(target, (TableObjective, FeatureObjective)) else FeatureObjective(measurement)
    start = matched_start(starter, ModelSpec(material), names=names)
    geometry = measurement.records[0].geometry if isinstance(measurement, ResonanceTable) else measurement.geometry
    starts = starts_for(names, WhiskerScales.of(start.physics(geometry)))
    if starts and method == "optimizer":
        start = best_start(target, starter, start, starts)
    result = fit(target, start, names, method=method, grid_points=grid_points, sigma=_table_sigma(target),
                 max_iterations=MAX_ITERATIONS)
    out = {"params": result.params(), "error": result.error, "metric": result.metric, "method": method,
           "objective": objective, "evaluations": result.evaluations,
           "notes": list(result.notes) + pinned_notes(result.values)}
    if isinstance(measurement, ResonanceTable):
        out["modes"] = {r.whisker: modal_summary(result.spec, r.geometry) for r in measurement.records}
    else:
        out["modes"] = {measurement.whisker: modal_summary(result.spec, measurement.geometry)}
        if bootstrap:
            spread = bootstrap_sd(lambda m: _objective(m, objective), measurement, result.spec, names,
                                  bootstrap, method=method)
            for name, sd in spread.items():
                out["params"][name]["sd_bootstrap"] = sd
    out["notes"] += [f"the fitted {w} is overdamped in-plane (no oscillating first mode): f1 and ζ1 are null"
                     for w, m in out["modes"].items() if not np.isfinite(m["f1_hz"])]
    if engine:
        out["engine"] = engine_check(result, target, _objective(measurement, objective, EngineSimulator(engine)),
                                     engine)
    return out
