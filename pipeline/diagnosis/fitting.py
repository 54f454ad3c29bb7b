"""Fit named parameters of a :class:`ModelSpec` to an objective; uncertainties; engine refinement.

- ``optimizer``: bounded least squares (scipy ``least_squares``, trust-region reflective)
  on the objective's residuals, in the order-one coordinates of :class:`ParameterSpace`,
  finite-difference Jacobian.
- ``grid``: the paper's brute force (§4.4.1): every combination of ``points`` values per
  parameter (36 × 36 = 1296 for two, as the paper), spanning a factor 4 either side of the
  start for scale parameters and the bounds otherwise; the minimum of the objective's error.
- ``scaling``: E and ζ of a resonance table from two facts of the chain: f ∝ √E at fixed
  geometry (k_n ∝ E and, through eq. 3, c_n ∝ √E, so the modal damping ratio does not depend
  on E), and the damping grows monotonically with θ_ζ. θ_ζ is a bounded 1-D search
  (Brent, tolerance ``SCALING_ZETA_TOLERANCE``, within ``SCALING_ZETA_RANGE``) on the sum of
  squared damping residuals at the start's E, then θ_E = E·exp(−2·mean of the frequency
  residuals ln(sim/exp)) in closed form: 15–20 simulations, however costly each is (the
  engine's refit, :mod:`.material_fit`). Unweighted, no Jacobian (no sd).

With known standard deviations σ of the measured values (resonance tables) the residuals
are divided by σ (a χ² fit) and cov = (JᵀJ)⁻¹; otherwise cov = s²·(JᵀJ)⁻¹ with
s² = |r|²/(m − p), J the Jacobian at the solution; or a bootstrap over trials
(:func:`bootstrap`). Trajectory residuals are correlated in time, so the Jacobian values are
lower bounds; the bootstrap is the honest one when there are enough trials, and
:func:`block_sandwich_sd` (residuals grouped into blocks of consecutive samples) the honest
one for a few trials: it follows the misfit, not the white-noise part alone.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np

from pipeline.diagnosis.parameters import ModelSpec, ParameterSpace
from pipeline.errors import SimulationError, UserError

FD_STEP = 1e-4
GRID_SPAN = np.log(4.0)
PAPER_GRID_EVALUATIONS = 1296
SCALING_ZETA_RANGE = (0.05, 0.6)
SCALING_ZETA_TOLERANCE = 5e-3


@dataclass
class Fit:
    spec: ModelSpec
    names: tuple[str, ...]
    values: dict[str, float]
    sd: dict[str, float]
    error: float
    metric: str
    residuals: np.ndarray
    jacobian: np.ndarray | None = None
    evaluations: int = 0
    notes: list[str] = field(default_factory=list)

    def params(self) -> dict:
        """{name: {value, sd, unit}} for reports and JSON."""
        units = ParameterSpace(self.names).units()
        return {n: {"value": self.values[n], "sd": self.sd.get(n, float("nan")), "unit": units[n]}
                for n in self.names}


class _Counted:
    """The residual function of x (divided by σ when given), counting its calls."""

    def __init__(self, objective, spec: ModelSpec, space: ParameterSpace, sigma: np.ndarray | None = None):
        self.objective, self.spec, self.space, self.calls = objective, spec, space, 0
        self.sigma = sigma

    def spec_at(self, x) -> ModelSpec:
        return self.spec.with_values(self.space.to_values(x))

    def __call__(self, x) -> np.ndarray:
        return self.at(self.spec_at(x))

    def at(self, spec: ModelSpec) -> np.ndarray:
        self.calls += 1
        r = self.objective.residuals(spec)
        return r if self.sigma is None else r / self.sigma

    def error(self, r: np.ndarray) -> float:
        return self.objective.error(r if self.sigma is None else r * self.sigma)


def jacobian(fun, x: np.ndarray, r0: np.ndarray, bounds) -> np.ndarray:
    """Forward differences of ``fun`` at x (steps away from a bound that is too close)."""
    lo, hi = bounds
    columns = []
    for i in range(len(x)):
        step = FD_STEP * max(1.0, abs(x[i]))
        if x[i] + step > hi[i]:
            step = -step
        shifted = x.copy()
        shifted[i] += step
        columns.append((fun(shifted) - r0) / step)
    return np.stack(columns, axis=1)


def _x_sd(jac: np.ndarray, residuals: np.ndarray, known_sigma: bool) -> np.ndarray:
    m, p = jac.shape
    if known_sigma:
        cov = np.linalg.pinv(jac.T @ jac)
    elif m > p:
        cov = np.linalg.pinv(jac.T @ jac) * float(residuals @ residuals) / (m - p)
    else:
        return np.full(p, np.nan)
    return np.sqrt(np.clip(np.diag(cov), 0, None))


def _result(counted: _Counted, x, residuals, jac, notes=None) -> Fit:
    space = counted.space
    values = space.to_values(x)
    sd = space.value_sd(x, _x_sd(jac, residuals, counted.sigma is not None)) if jac is not None else {}
    return Fit(counted.spec_at(x), space.names, values, sd, counted.error(residuals),
               counted.objective.metric, residuals, jac, counted.calls, list(notes or []))


def matched_start(feature_objective, spec: ModelSpec, rounds: int = 2, names=("E", "zeta")) -> ModelSpec:
    """``spec`` with E and ζ (those of them in ``names``) rescaled so the simulated FRF and δ
    match the measured ones (f1 ∝ √E; δ roughly ∝ ζ): a start inside the basin of the
    trajectory and MSA fits, which have many local minima one ringing period apart."""
    for _ in range(rounds):
        freq, dec = feature_objective.ratios(spec)
        values = spec.values()
        update = {"E": float(np.clip(values["E"] * freq ** 2, 0.3e9, 19e9)),
                  "zeta": float(np.clip(values["zeta"] * dec, 2e-3, 1.9))}
        spec = spec.with_values({k: v for k, v in update.items() if k in names})
    return spec


def best_start(objective, feature_objective, spec: ModelSpec, starts) -> ModelSpec:
    """Of ``spec`` set to each of ``starts`` (values of extension parameters) with E, ζ matched
    to the measured FRF and δ, the one with the lowest error of ``objective``."""
    best, best_error = spec, np.inf
    for start in starts:
        candidate = matched_start(feature_objective, spec.with_values(start), rounds=1)
        error = objective.error(objective.residuals(candidate))
        if error < best_error:
            best, best_error = candidate, error
    return best


def fit(objective, spec: ModelSpec, names, method: str = "optimizer", grid_points: int | None = None,
        max_iterations: int = 15, sigma: np.ndarray | None = None) -> Fit:
    """Fit ``names`` of ``spec`` (others fixed) to ``objective``, starting from ``spec``'s values;
    ``sigma``: standard deviations of the residuals when known (then a χ² fit; optimizer and grid)."""
    # imported here, not at the top: scipy.optimize ≈0.4 CPU-s
    from scipy.optimize import least_squares

    if method == "scaling":
        return _scaling(objective, spec, tuple(names))
    space = ParameterSpace(names)
    known = sigma is not None and np.all(np.isfinite(sigma)) and np.all(sigma > 0)
    counted = _Counted(objective, spec, space, sigma if known else None)
    start = {**spec.values(), **{n: p.neutral for n, p in zip(space.names, space.specs)
                                 if n not in spec.values()}}
    x0 = space.to_x(start)
    bounds = space.bounds()
    if method == "grid":
        x = _grid(counted, x0, bounds, grid_points)
        r = counted(x)
        return _result(counted, x, r, jacobian(counted, x, r, bounds),
                       [f"grid of {_points(grid_points, len(x0)) ** len(x0)} points"])
    if method != "optimizer":
        raise UserError(f"unknown fit method '{method}' (optimizer, grid or scaling)")
    loss, scale = (objective.loss, 1.0) if isinstance(objective.loss, str) else objective.loss
    solution = least_squares(counted, x0, bounds=bounds, method="trf", diff_step=FD_STEP, x_scale=1.0,
                             max_nfev=max_iterations, ftol=1e-6, xtol=1e-6, loss=loss, f_scale=scale)
    notes = [] if solution.success else [f"optimizer stopped: {solution.message}"]
    return _result(counted, solution.x, solution.fun, solution.jac, notes)


def _scaling(objective, spec: ModelSpec, names: tuple[str, ...]) -> Fit:
    """The ``scaling`` method (module docstring) on an objective with a ``damping_mask``."""
    # imported here, not at the top: scipy.optimize ≈0.4 CPU-s
    from scipy.optimize import minimize_scalar

    if sorted(names) != ["E", "zeta"]:
        raise UserError(f"the scaling fit takes E and zeta together, not {', '.join(names)}")
    counted = _Counted(objective, spec, ParameterSpace(names))
    damping = objective.damping_mask()

    def damping_error(zeta: float) -> float:
        return float(np.sum(counted.at(spec.with_values({"zeta": zeta}))[damping] ** 2))

    zeta = minimize_scalar(damping_error, bounds=SCALING_ZETA_RANGE, method="bounded",
                           options={"xatol": SCALING_ZETA_TOLERANCE}).x
    damped = spec.with_values({"zeta": zeta})
    frequency_ratio = -np.mean(counted.at(damped)[~damping])
    fitted = damped.with_values({"E": damped.values()["E"] * np.exp(2 * frequency_ratio)})
    residuals = counted.at(fitted)
    values = fitted.values()
    return Fit(fitted, names, {n: values[n] for n in names}, {}, objective.error(residuals), objective.metric,
               residuals, evaluations=counted.calls)


def _points(grid_points: int | None, dims: int) -> int:
    return grid_points or max(3, int(round(PAPER_GRID_EVALUATIONS ** (1.0 / dims))))


def _grid(counted: _Counted, x0, bounds, grid_points):
    axes = []
    for xi, lo, hi, p in zip(x0, bounds[0], bounds[1], counted.space.specs):
        span = (max(lo, xi - GRID_SPAN), min(hi, xi + GRID_SPAN)) if p.log else (lo, hi)
        axes.append(np.linspace(span[0], span[1], _points(grid_points, len(x0))))
    best, best_error = None, np.inf
    for point in itertools.product(*axes):
        x = np.array(point)
        error = counted.error(counted(x))
        if error < best_error:
            best, best_error = x, error
    return best


def block_sandwich_sd(result: Fit, blocks: np.ndarray, floor: float = 0.0) -> dict[str, float]:
    """Standard deviations of ``result``'s values: the cluster-robust ("sandwich") covariance
    B⁻¹·M·B⁻¹ · G/(G − 1), B = JᵀJ, M = Σ_b (J_bᵀr_b)(J_bᵀr_b)ᵀ over the G blocks b of residuals
    (``blocks``: one label per residual; residuals correlated within a block, a systematic
    misfit and not only noise, widen it), plus a model-error term floor²·m·B⁻¹: the shift of
    the values that a model error of RMS ``floor`` (residual units) over all m residuals,
    coherent like a change of the parameters, could cause."""
    jac, r = result.jacobian, result.residuals
    labels = np.unique(blocks, return_inverse=True)[1]
    count = labels.max() + 1
    scores = np.zeros((count, jac.shape[1]))
    np.add.at(scores, labels, jac * r[:, None])
    bread = np.linalg.pinv(jac.T @ jac)
    cov = bread @ (scores.T @ scores) @ bread * count / max(count - 1, 1) + floor ** 2 * len(r) * bread
    space = ParameterSpace(result.names)
    return space.value_sd(space.to_x(result.values), np.sqrt(np.clip(np.diag(cov), 0, None)))


def bootstrap(make_objective, measurement, spec: ModelSpec, names, samples: int, seed: int = 0,
              method: str = "optimizer") -> dict[str, float]:
    """Standard deviation of each fitted value over refits on trials resampled with replacement."""
    rng = np.random.default_rng(seed)
    count = len(measurement.trials)
    values = []
    for _ in range(samples):
        chosen = rng.choice(count, size=count, replace=True)
        resampled = replace(measurement, trials=tuple(measurement.trials[i] for i in chosen))
        refit = fit(make_objective(resampled), spec, names, method=method)
        values.append([refit.values[n] for n in names])
    spread = np.std(np.array(values), axis=0, ddof=1) if samples > 1 else np.full(len(names), np.nan)
    return dict(zip(names, spread.tolist()))


def engine_check(fitted: Fit, fast_objective, engine_objective, engine: str) -> dict:
    """JSON-ready engine check and refinement of ``fitted``; an engine that cannot simulate the
    model, or fails, is reported, not raised (the fast result stands)."""
    try:
        refined = refine_with_engine(fitted, fast_objective, engine_objective)
    except (UserError, SimulationError) as exc:
        return {"name": engine, "error": str(exc)}
    return {"name": engine, "error_before": refined["error_before"], "error_after": refined["error_after"],
            "params": refined["fit"].params(), "evaluations": refined["evaluations"]}


def refine_with_engine(result: Fit, fast_objective, engine_objective, iterations: int = 2) -> dict:
    """Correct a fast-simulator fit with an engine (defect correction, "output space mapping"):
    x ← x − J⁺·r_engine(x), J the fast model's Jacobian; keep a step only if the engine's
    error falls. Returns the engine's error before and after and the refined fit."""
    space = ParameterSpace(result.names)
    counted = _Counted(engine_objective, result.spec, space)
    x = space.to_x(result.values)
    r = counted(x)
    before = engine_objective.error(r)
    fast = _Counted(fast_objective, result.spec, space)
    refined, error = result, before
    for _ in range(iterations):
        jac = jacobian(fast, x, fast(x), space.bounds())
        candidate = np.clip(x - np.linalg.lstsq(jac, r, rcond=None)[0], *space.bounds())
        r_new = counted(candidate)
        if engine_objective.error(r_new) >= error:
            break
        x, r, error = candidate, r_new, engine_objective.error(r_new)
        refined = _result(counted, x, r, jac)
    return {"error_before": before, "error_after": error, "fit": refined, "evaluations": counted.calls}
