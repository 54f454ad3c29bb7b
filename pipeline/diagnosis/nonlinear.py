"""Follow large bends: the linear fast simulator corrected by a nonlinear engine.

The fast simulator LIN(p) (:mod:`.fastsim`) is exact in time but linear in the joint angles;
the MuJoCo engine NL(p) (:mod:`.engine`) integrates the same joints with the full nonlinear
multibody dynamics, at about the same cost per run but too slowly for every evaluation of
a fit. Output-space defect correction needs two engine runs per iteration: from a linear
fit p₀ to the data y,

    d_k = D(p_k; u) − D(p_k; s·u)/s,   D = NL − LIN   (per trial: tracked points, every frame, m)
    p_{k+1} = argmin_p |LIN(p) + d_k − y|²          (the usual fit, data shifted by d_k)

u the trial's drive (rotation angles, the release's probe displacement from rest, gravity),
scaled by s = ``LINEAR_PROBE`` in the second run. The engine and the fast simulator differ
also where both are linear: the engine's step (first order in dt) and its interpolation of
a sampled drive (a pulse's abrupt stop) give ≈ 1.5–2.5 % of the motion at any amplitude
(benchmarks/nonlinear_range.py). That part of D is linear in u and the second term removes
it, leaving the nonlinearity (its O(s) remainder is 5 % of it); the fast simulator, exact in
time, keeps the linear dynamics.

The iteration stops when p moves less than ``TOLERANCE`` in the optimiser's coordinates
(1 % for scale parameters) or the corrected misfit stops falling, after at most
``ITERATIONS`` defects. At a fixed point LIN(p) + d(p) is the nonlinear model (the linear
dynamics exact in time, the engine's nonlinearity): its residuals are scored, and the
parameters zero LIN's Jacobian times them (its own to first order in the defect).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.fitting import Fit, fit
from pipeline.engines.linear.chain import linearise
from pipeline.diagnosis.objective import TrajectoryObjective
from pipeline.diagnosis.parameters import ModelSpec, ParameterSpace
from pipeline.measurements.timeseries import ReleaseDrive, TimeSeriesMeasurement

ENGINE = "mujoco"
ENGINE_DT_S = 1e-4          # engine step (docs/measurements.md §9: the defect's convergence in dt)
LINEAR_PROBE = 0.05         # drive scale s of the run that measures the defect's linear part
ITERATIONS = 3
TOLERANCE = 0.01


class DefectSimulator(FastSimulator):
    """The fast simulator plus a fixed defect per trial (by trial name; [T, K, 3] m, rest frame)."""

    name = "fast+defect"

    def __init__(self, defects: dict[str, np.ndarray]):
        self.defects = defects

    def simulate(self, physics, prepared: list[PreparedTrial]) -> list[np.ndarray]:
        return [s + self.defects[p.trial.name] for s, p in zip(super().simulate(physics, prepared), prepared)]


def engine_minus_fast(spec: ModelSpec, measurement: TimeSeriesMeasurement, engine: str = ENGINE,
                      dt_s: float = ENGINE_DT_S) -> list[np.ndarray]:
    """D = NL(p) − LIN(p) of every trial of ``measurement`` at ``spec`` ([T, K, 3] m each)."""
    prepared = [PreparedTrial(t, measurement.gravity_direction) for t in measurement.trials]
    physics = spec.physics(measurement.geometry)
    nonlinear = EngineSimulator(engine, dt_s).simulate(physics, prepared)
    return [a - b for a, b in zip(nonlinear, FastSimulator().simulate(physics, prepared))]


def scaled(spec: ModelSpec, measurement: TimeSeriesMeasurement, s: float):
    """(spec, measurement) with every drive scaled by ``s``: rotation angles, the release
    probe's displacement from the rest point, gravity."""
    lin = linearise(spec.physics(measurement.geometry))
    trials = []
    for trial in measurement.trials:
        drive = trial.drive
        if isinstance(drive, ReleaseDrive):
            rest = lin.rest_points(np.array([drive.contact_fraction]))[0]
            drive = replace(drive, contact_position_m=rest + s * (np.asarray(drive.contact_position_m) - rest))
        else:
            drive = replace(drive, angles_rad=s * drive.angles_rad)
        trials.append(replace(trial, drive=drive))
    gravity = spec.extension("gravity")
    return (spec.with_values({"gravity.g": s * gravity.g}) if gravity else spec,
            replace(measurement, trials=tuple(trials)))


def defects(spec: ModelSpec, measurement: TimeSeriesMeasurement, engine: str = ENGINE,
            dt_s: float = ENGINE_DT_S) -> dict[str, np.ndarray]:
    """The nonlinear defect d = D(p; u) − D(p; s·u)/s of every trial at ``spec`` (by name)."""
    full = engine_minus_fast(spec, measurement, engine, dt_s)
    probe = engine_minus_fast(*scaled(spec, measurement, LINEAR_PROBE), engine, dt_s)
    return {t.name: a - b / LINEAR_PROBE for t, a, b in zip(measurement.trials, full, probe)}


@dataclass
class Correction:
    """A fit whose residuals are the nonlinear model's, and the simulator that reproduces them."""

    fit: Fit
    simulator: DefectSimulator
    iterations: int           # defects accepted (each one engine run of every trial)
    errors: list[float]       # corrected training misfit after each refit (m); [0]: the linear fit's

    def note(self) -> str:
        steps = " → ".join(f"{e * 1e3:.4f}" for e in self.errors)
        return (f"nonlinear correction: {ENGINE}, {self.iterations} iteration(s), "
                f"fitted RMS {steps} mm")


def correct(measurement: TimeSeriesMeasurement, fitted: Fit, trials: list[str] | None = None,
            max_iterations: int = 15) -> Correction:
    """Defect-correct ``fitted`` (a linear fit of ``fitted.names`` on ``trials`` of
    ``measurement``, all if None); defects are computed on every trial so that held-out
    trials are scored by the same corrected simulator."""
    data = measurement.subset(trials) if trials is not None else measurement
    space = ParameterSpace(fitted.names)
    errors, best, simulator = [fitted.error], fitted, None
    for k in range(ITERATIONS):
        candidate_simulator = DefectSimulator(defects(best.spec, measurement))
        refit = fit(TrajectoryObjective(data, candidate_simulator), best.spec, best.names,
                    max_iterations=max_iterations)
        if simulator is not None and refit.error >= errors[-1]:
            return Correction(best, simulator, k, errors)
        moved = np.abs(space.to_x(refit.values) - space.to_x(best.values)).max()
        best, simulator = refit, candidate_simulator
        errors.append(refit.error)
        if moved < TOLERANCE:
            break
    return Correction(best, simulator, k + 1, errors)
