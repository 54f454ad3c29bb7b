"""Candidates fitted on one split of a measurement's trials and scored on the other (steps 1
and 3 of :mod:`.diagnose`).

Split: trials alternate into a training and a held-out half within each drive signature (kind
and main axis; a drive type met only once goes to training). Each candidate extension
(:mod:`.candidates`) is fitted on the training half from the best of its starts (E, ζ and its
own parameters, ``CANDIDATE_ITERATIONS``), scored by its held-out error e_c and its training
ΔBIC = n·ln(RSS_c/RSS₀) + Δp·ln n. The ``LEADERS`` candidates with the lowest held-out error
among those that pass the training test (:func:`~.decision.trained`), and the one with the
lowest ΔBIC, continue their fits (``FINAL_ITERATIONS``) with the candidate's ``refine``
parameters added (drag: the quadratic C_d): a short fit can stop short of a strong effect,
letting a surrogate win, and a first fit without its refine parameter can fit the training
trials and still miss the held-out ones (linear drag fitted to one pulse mispredicts a
faster one when the drag is quadratic). A fit that ends worse on its training trials than the
model it extends (RSS_c > RSS₀: the optimiser stopped in another basin, from a start whose E
and ζ were matched to the data rather than to that model) is fitted again from that model's
optimum with the candidate's parameters at their null values
(:meth:`~.candidates.Candidate.nested_start`), and the better of the two fits kept. Paired held-out z of a candidate against the model
it extends: z = (Σr₀² − Σr_c²)/(2σ̂·|p₀ − p_c|) (r residuals, p predictions: the shared noise
cancels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.diagnosis.candidates import ABSORBS, Candidate, WhiskerScales
from pipeline.diagnosis.decision import trained
from pipeline.diagnosis.fitting import Fit, best_start, fit
from pipeline.diagnosis.nonlinear import correct
from pipeline.diagnosis.objective import RESIDUAL_UNIT_M, FeatureObjective, TrajectoryObjective
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.errors import SimulationError
from pipeline.measurements.timeseries import ReleaseDrive, TimeSeriesMeasurement

CANDIDATE_ITERATIONS = 10   # first fits on the training half: enough to rank candidates
LEADERS = 3                 # candidates whose fits then continue
FINAL_ITERATIONS = 40       # continued fits, and the refit of the named model on all trials


@dataclass
class CandidateScore:
    name: str
    fit: Fit
    heldout_error: float
    bic_delta: float
    heldout_residuals: np.ndarray
    fit_delta: float = float("nan")        # n·ln(RSS_c/RSS₀) on the training trials: ΔBIC without its p·ln n
    score: float = float("nan")
    z: float = float("nan")

    def as_dict(self) -> dict:
        return {"name": self.name, "params": self.fit.params(), "heldout_error": self.heldout_error,
                "score": self.score}


def signature(trial) -> tuple[str, int]:
    """Drive kind and main axis (rotation: largest angle column; release: the larger of the
    tip's y and z travel from the first tracked frames to its final rest)."""
    if isinstance(trial.drive, ReleaseDrive):
        tip = trial.positions_m[:, int(np.argmax(trial.arc_fraction))]
        tip = tip[~np.isnan(tip).any(axis=1)]
        if len(tip) < 2:
            return "release", 0
        travel = np.nanmean(tip[:5], axis=0) - np.nanmean(tip[-max(5, len(tip) // 10):], axis=0)
        return "release", int(np.argmax(np.nan_to_num(np.abs(travel[1:]))))
    return "rotation", int(np.argmax(np.abs(trial.drive.angles_rad).max(axis=0)))


def split_trials(measurement: TimeSeriesMeasurement) -> tuple[list[str], list[str]]:
    """(training, held-out) trial names: alternate within each drive signature."""
    groups: dict[tuple, list[str]] = {}
    for trial in measurement.trials:
        groups.setdefault(signature(trial), []).append(trial.name)
    train, test = [], []
    for names in groups.values():
        for i, name in enumerate(names):
            (train if i % 2 == 0 else test).append(name)
    return train, test


def _bic(residuals: np.ndarray, params: int) -> float:
    n = residuals.size
    return float(n * np.log(residuals @ residuals / n) + params * np.log(n))


class Session:
    """Objectives on the training, held-out and all trials of one measurement."""

    def __init__(self, measurement: TimeSeriesMeasurement, train: list[str], test: list[str], simulator=None):
        self.measurement, self.names = measurement, (train, test)
        self.train = TrajectoryObjective(measurement.subset(train), simulator)
        self.test = TrajectoryObjective(measurement.subset(test), simulator)
        self.train_features = FeatureObjective(measurement.subset(train))

    def heldout(self, spec: ModelSpec) -> np.ndarray:
        return self.test.residuals(spec)

    def flipped(self) -> "Session":
        """The same split with the halves' roles swapped (training ↔ held out)."""
        return Session(self.measurement, self.names[1], self.names[0], self.train.simulator)


def fit_candidate(session: Session, baseline: Fit, name: str, start: ModelSpec, names,
                  iterations: int, nested: ModelSpec | None = None) -> CandidateScore:
    """A candidate fitted from ``start`` on the training half; again from ``nested`` (the
    baseline with the candidate's parameters at their null values) when the first fit ends
    worse than the baseline, the better fit kept (module docstring)."""
    result = fit(session.train, start, names, max_iterations=iterations)
    if nested is not None and _rss(result) > _rss(baseline):
        restarted = fit(session.train, nested, names, max_iterations=iterations)
        if _rss(restarted) < _rss(result):
            result = restarted
    return score_fit(session, baseline, name, result)


def _rss(result: Fit) -> float:
    return float(result.residuals @ result.residuals)


def score_fit(session: Session, baseline: Fit, name: str, result: Fit) -> CandidateScore:
    """A candidate's fit scored against the baseline: held-out error on ``session`` and ΔBIC."""
    heldout = session.heldout(result.spec)
    bic_delta = _bic(result.residuals, len(result.names)) - _bic(baseline.residuals, len(baseline.names))
    return CandidateScore(name, result, session.test.error(heldout), bic_delta, heldout,
                          bic_delta - (len(result.names) - len(baseline.names)) * np.log(result.residuals.size))


def fit_candidates(session: Session, baseline: Fit, chosen: list[Candidate]) -> list[CandidateScore]:
    """Every candidate in ``chosen`` fitted on top of ``baseline`` on the training half, the leaders'
    fits continued (module docstring)."""
    scales = WhiskerScales.of(baseline.spec.physics(session.measurement.geometry))
    scores = []
    nested = {c.name: c.nested_start(baseline.spec, scales) for c in chosen}
    for c in chosen:
        start = best_start(session.train, session.train_features, c.on(baseline.spec), c.starts(scales))
        scores.append(fit_candidate(session, baseline, c.name, start, baseline.names + c.params,
                                    CANDIDATE_ITERATIONS, nested[c.name]))
    for lead in leaders(scores):
        refine = next(c.refine for c in chosen if c.name == lead.name)
        scores[scores.index(lead)] = fit_candidate(session, baseline, lead.name, lead.fit.spec.with_values(refine),
                                                   lead.fit.names + tuple(refine), FINAL_ITERATIONS,
                                                   nested[lead.name])
    return scores


def leaders(scores: list[CandidateScore]) -> list[CandidateScore]:
    """The ``LEADERS`` candidates that pass the training test (:func:`~.decision.trained`) with the lowest
    held-out errors, and the one with the strongest training evidence (lowest ΔBIC) if it is
    not among them."""
    strong = [s for s in scores if trained(s.name, s.bic_delta, s.fit_delta)]
    chosen = sorted(strong, key=lambda s: s.heldout_error)[:LEADERS]
    best_trained = min(strong, key=lambda s: s.bic_delta, default=None)
    if best_trained is not None and best_trained not in chosen:
        chosen.append(best_trained)
    return chosen


def corrected_leaders(session: Session, baseline: Fit, scores: list[CandidateScore]) -> dict:
    """Defect-correct the leading candidates' fits with their own defects, rescore them on the
    held-out trials; {name: corrected simulator}."""
    simulators = {}
    for lead in leaders(scores):
        try:
            corrected = correct(session.measurement, lead.fit, session.names[0], FINAL_ITERATIONS)
        except SimulationError:        # keeps the score with the baseline's defect
            continue
        own = Session(session.measurement, *session.names, corrected.simulator)
        scores[scores.index(lead)] = score_fit(own, baseline, lead.name, corrected.fit)
        simulators[lead.name] = corrected.simulator
    return simulators


def paired_z(r0: np.ndarray, noise: float, scores: list[CandidateScore]) -> None:
    """Each candidate's paired held-out z (residuals r in 0.1 mm units)."""
    sigma = noise / RESIDUAL_UNIT_M
    for s in scores:
        change = np.linalg.norm(r0 - s.heldout_residuals)
        s.z = float((r0 @ r0 - s.heldout_residuals @ s.heldout_residuals) / (2 * sigma * change)) \
            if change > 0 else 0.0


def evidence_of(e0: float, noise: float, amplitude_m: float, r0: np.ndarray, scores: list[CandidateScore]) -> dict:
    """The held-out evidence :func:`~.decision.decide` takes (baseline error e0 and residuals r0)."""
    return {"baseline_m": e0, "noise_m": noise, "amplitude_m": amplitude_m, "values": int(r0.size),
            "candidates": [{"name": c.name, "heldout_m": c.heldout_error, "bic_delta": c.bic_delta,
                            "fit_delta": c.fit_delta, "z": c.z, "absorbs": ABSORBS[c.name]} for c in scores]}
