"""Follow large bends: the linear fast simulator corrected by a nonlinear engine.

The fast simulator LIN(p) (:mod:`.fastsim`) is exact in time but linear in the joint angles;
the MuJoCo engine NL(p) (:mod:`.engine`) integrates the same joints with the full nonlinear
multibody dynamics, at about the same cost per run but too slowly for every evaluation of
a fit. Output-space defect correction uses one NL run per iteration: from a linear fit p₀
to the data y,

    d_k = NL(p_k) − LIN(p_k)                       (per trial: tracked points, every frame, m)
    p_{k+1} = argmin_p |LIN(p) + d_k − y|²          (the usual fit, data shifted by d_k)

stopping when p moves less than ``TOLERANCE`` in the optimiser's coordinates (1 % for scale
parameters) or the corrected misfit stops falling, after at most ``ITERATIONS`` defects.
At a fixed point LIN(p) + d = NL(p): the residuals are those of the nonlinear model, and
the parameters zero LIN's Jacobian times them (NL's to first order in the defect).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.fitting import Fit, fit
from pipeline.diagnosis.objective import TrajectoryObjective
from pipeline.diagnosis.parameters import ModelSpec, ParameterSpace
from pipeline.measurements.timeseries import TimeSeriesMeasurement

ENGINE = "mujoco"
ENGINE_DT_S = 5e-5          # engine step: the defect converges to a few µm (docs/measurements.md §9)
ITERATIONS = 3
TOLERANCE = 0.01


class DefectSimulator(FastSimulator):
    """The fast simulator plus a fixed defect per trial (by trial name; [T, K, 3] m, rest frame)."""

    name = "fast+defect"

    def __init__(self, defects: dict[str, np.ndarray]):
        self.defects = defects

    def simulate(self, physics, prepared: list[PreparedTrial]) -> list[np.ndarray]:
        return [s + self.defects[p.trial.name] for s, p in zip(super().simulate(physics, prepared), prepared)]


def defects(spec: ModelSpec, measurement: TimeSeriesMeasurement, engine: str = ENGINE,
            dt_s: float = ENGINE_DT_S) -> dict[str, np.ndarray]:
    """NL(p) − LIN(p) of every trial of ``measurement`` at ``spec``."""
    prepared = [PreparedTrial(t, measurement.gravity_direction) for t in measurement.trials]
    physics = spec.physics(measurement.geometry)
    nonlinear = EngineSimulator(engine, dt_s).simulate(physics, prepared)
    linear = FastSimulator().simulate(physics, prepared)
    return {t.name: a - b for t, a, b in zip(measurement.trials, nonlinear, linear)}


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
