"""What does the model get wrong on a measurement, and which extension explains it?

Time series (positions of tracked points):

1. Split the trials in two, stratified by drive (kind and main axis): a training half and a
   held-out half (a drive type met only once goes to training).
2. Baseline: fit E and ζ on the training trials (trajectory least squares from a start whose
   FRF and δ match the data); its error on the held-out trials is e₀. Every model fitted here
   has the two ``CONTINUUM`` corrections, which make the chain converge to the continuous
   whisker at second order in 1/N: the base segment
   (:class:`~pipeline.model.effects.base_segment.BaseSegment`; the chain's rigid base half-link would
   otherwise bias E by ≈ −1.2/N and the base-weighted parameters with it) and the integrated
   link density (:class:`~pipeline.model.effects.integrated_density.IntegratedDensity`; the paper's
   proximal-node density, ≈ −0.5 % on E at N = 20).
3. Each candidate extension (:mod:`.candidates`): fit E, ζ and its parameters on the training
   trials (best of a few starts), held-out error e_c, and BIC = n·ln(RSS/n) + p·ln(n) on the
   training residuals. The ``LEADERS`` candidates with the lowest held-out error among those
   that pass the training test (:func:`trained`: ΔBIC < −``BIC_MIN`` for an effect, a training
   fit no worse than the baseline's for a damping law), and the one with the lowest ΔBIC,
   continue their fits (a short
   fit can stop short of a strong effect, letting a surrogate win), with the candidate's
   ``refine`` parameters added (drag: the quadratic C_d). Damping laws are candidates like
   the others (:mod:`.candidates`: ``rayleigh``, ``eq3``, ``kelvin_voigt``, each fitted from
   the baseline's values with its own damping model), so a law is named on the same evidence. The lowest ΔBIC joins because a
   first fit without its refine parameter can fit the training trials and still miss the
   held-out ones: linear drag fitted to one pulse mispredicts a faster one when the drag is
   quadratic.
4. Evidence on the held-out trials: tracking noise σ̂ from the second differences of the
   best model's residuals (:mod:`.residuals`); a model-error floor f = ``FLOOR_FRACTION``·A,
   A the RMS deflection of the held-out data (:mod:`.deflection`): a cap on the misfit a right
   model leaves because the chain is not the continuum (the chain without the continuum
   corrections needed up to 0.03·A on effect-free draws of an independent simulator; with
   them none of 24 draws needs any, docs/measurements.md §9); the excess X = e₀² − σ̂² − f² is the
   misfit to explain, significant when it exceeds ``SIGNIFICANT`` times its standard error
   ≈ 1.5·σ̂²/√n (n held-out values, white noise). A candidate's gain g = e₀² − e_c², its
   share of the excess φ = g/X (X ≤ 0: 1 if g exceeds the candidate's own floor, else 0); its
   paired held-out z = (Σr₀² − Σr_c²)/(2σ̂·|p₀ − p_c|) (r residuals, p predictions: the shared
   noise cancels), and the same z beyond the candidate's own floor, z·(g − f_c²)/g: f_c =
   min(f, ``ABSORB_MARGIN``·κ_c·A), κ_c the most of the model error that candidate took for
   an effect on effect-free draws (``Candidate.absorbs``, 0.0002–0.0064 with the continuum
   corrections), so a weak effect stands out long before it exceeds f.
5. Decision (:func:`decide`): the baseline is inadequate when X is significant or when a
   candidate that passes the training test beats it on the held-out trials beyond its own
   floor (z beyond the floor > ``Z_MIN``); otherwise "none". Then the candidate with the lowest
   held-out error among those that pass the training test, with z beyond its floor > ``Z_MIN``
   and φ ≥ ``EXPLAINED_MIN``; none such → "unexplained". The training test of a damping law
   is only that its training fit is no worse than the baseline's: BIC's ln n penalty asks the
   training half alone for "very strong" evidence, and a law's signature (how the higher
   modes decay) sits in the trials that excite those modes, which the split may put in either
   half (a modal-law draw: training RSS −0.04 %, ΔBIC +4.6; held-out z 10.6); for an effect
   the training test stays ΔBIC < −``BIC_MIN``. A named cause that still leaves a
   significant excess gets a note (a second effect?). Positions cannot tell a uniform density
   change from a change of E (eq. 3: only E/ρ sets the time scale): every diagnosis says so.
5b. Several causes (forward selection, :func:`_next_cause`): once a cause is named, the named
   model is the baseline of another round over the remaining candidates (each fitted on top
   of it, steps 3–5 on the same split and noise), until a round names nothing or
   ``MAX_CAUSES`` are named. A later round's z threshold accounts for every candidate tried
   so far (:func:`family_z`: Bonferroni on the one-sided tail of ``Z_MIN``, which the first
   round's candidates set), so trying more candidates does not lower the bar. Data scored
   with the nonlinear correction stop after the first round (a note says so). ``causes``
   lists the causes in the order named; the model refitted in step 6 holds all of them. Once a
   damping law is named no other law is tried (the laws exclude each other).
6. The named model (or the baseline) is refitted on all trials for its parameters; their
   SDs are block-sandwich SDs over 50 ms stretches plus a model-error term of RMS
   ``SD_MODEL_FRACTION``·A (:func:`~.fitting.block_sandwich_sd`), calibrated so that ±1 SD
   holds the truth on 68 % of independent draws kept apart from the benchmark
   (benchmarks/calibrate_sd.py, docs/measurements.md §9); E's SD also holds the chain's
   discretisation error, which no residual shows (:mod:`.discretisation`: Richardson from N
   and 2N links).

Data that bend the whisker beyond ``LINEAR_BEND_MAX`` of its length (largest tip deflection
off the rigidly rotated rest shape), which the linear fast simulator does not follow, switch
to the nonlinear correction (:mod:`.nonlinear`, MuJoCo): the baseline fit of step 2 and the
leading candidates' fits of step 3 are defect-corrected, and every later fit and score
(held-out errors, BIC, the refits of step 6) uses each model's corrected simulator; the
notes and ``decision.simulator`` say so.

Resonance tables (f1, δ per whisker): see :func:`diagnose_table`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.candidates import ABSORBS, CANDIDATES, DAMPING_LAWS, Candidate, WhiskerScales
from pipeline.diagnosis.deflection import amplitude, bend
from pipeline.diagnosis.discretisation import with_modulus_discretisation
from pipeline.diagnosis.fitting import Fit, best_start, block_sandwich_sd, fit, matched_start
from pipeline.diagnosis.nonlinear import correct
from pipeline.diagnosis.objective import RESIDUAL_UNIT_M, FeatureObjective, TrajectoryObjective
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec
from pipeline.diagnosis.residuals import analyse, noise_estimate
from pipeline.errors import SimulationError, UserError
from pipeline.measurements.timeseries import ReleaseDrive, TimeSeriesMeasurement
from pipeline.model.effects.base_segment import BaseSegment
from pipeline.model.effects.integrated_density import IntegratedDensity

CONTINUUM = (BaseSegment(), IntegratedDensity())   # in every model diagnose fits (step 2)
BIC_MIN = 10.0             # "very strong" evidence on the Kass–Raftery scale
Z_MIN = 3.0
SIGNIFICANT = 3.0
EXPLAINED_MIN = 0.5
FLOOR_FRACTION = 0.03       # model-error floor / RMS deflection (docs/measurements.md §9)
ABSORB_MARGIN = 2.0         # a candidate's floor / the most it absorbed on calibration draws (§9)
LINEAR_BEND_MAX = 0.2       # largest tip deflection / S the linear fast simulator follows (§9)
BLOCK_S = 0.05              # residual blocks of the sandwich SDs (s)
SD_MODEL_FRACTION = 0.0014  # model-error term of the SDs / RMS deflection (benchmarks/calibrate_sd.py, §9)
METRIC = "heldout_rms_m"
CANDIDATE_ITERATIONS = 10   # first fits on the training half: enough to rank candidates
LEADERS = 3                 # candidates whose fits then continue
FINAL_ITERATIONS = 40       # continued fits, and the refit of the named model on all trials
MAX_CAUSES = 3              # rounds of the forward selection (step 5b)


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


@dataclass
class Diagnosis:
    baseline: Fit
    baseline_heldout: float
    candidates: list[CandidateScore]
    cause: str
    final: Fit
    gain_after: float
    noise_m: float
    metric: str = METRIC
    analysis: dict = field(default_factory=dict)       # residuals of the baseline (all trials)
    cause_analysis: dict = field(default_factory=dict)
    split: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    simulated: dict = field(default_factory=dict)     # "baseline"/"cause" → positions per trial
    evidence: dict = field(default_factory=dict)      # what the cause was decided on (see decide)
    floor_m: float = 0.0                              # model-error floor on the held-out trials (m)
    causes: list[str] = field(default_factory=list)   # every cause named, in order (step 5b)

    def as_dict(self) -> dict:
        """The JSON of ``pipeline diagnose --json`` (docs/measurements.md)."""
        return {"baseline": {"params": self.baseline.params(), "error": self.baseline_heldout},
                "candidates": [c.as_dict() for c in self.candidates],
                "cause": self.cause, "causes": self.causes, "params": self.final.params(),
                "gain": {"metric": self.metric, "before": self.baseline_heldout, "after": self.gain_after},
                "decision": self.evidence}


def _signature(trial) -> tuple[str, int]:
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
        groups.setdefault(_signature(trial), []).append(trial.name)
    train, test = [], []
    for names in groups.values():
        for i, name in enumerate(names):
            (train if i % 2 == 0 else test).append(name)
    return train, test


def _bic(residuals: np.ndarray, params: int) -> float:
    n = residuals.size
    return float(n * np.log(residuals @ residuals / n) + params * np.log(n))


def trained(name: str, bic_delta: float, fit_delta: float) -> bool:
    """The training half's test of a candidate: an effect needs ΔBIC < −``BIC_MIN``; a damping
    law (:data:`~.candidates.DAMPING_LAWS`: an alternative to the baseline's law, not an
    effect added to it) needs only a training fit no worse than the baseline's
    (n·ln(RSS_c/RSS₀) < 0), its held-out z beyond its own floor being the test: a law's
    signature is the higher modes' decay, which some drives excite and others hardly, so one
    half of the trials can hold it and the other not (module docstring, step 5)."""
    if name in DAMPING_LAWS:
        return fit_delta < 0
    return bic_delta < -BIC_MIN


class _Session:
    """Objectives on the training, held-out and all trials of one measurement."""

    def __init__(self, measurement: TimeSeriesMeasurement, train: list[str], test: list[str], simulator=None):
        self.measurement, self.names = measurement, (train, test)
        self.train = TrajectoryObjective(measurement.subset(train), simulator)
        self.test = TrajectoryObjective(measurement.subset(test), simulator)
        self.train_features = FeatureObjective(measurement.subset(train))

    def heldout(self, spec: ModelSpec) -> np.ndarray:
        return self.test.residuals(spec)


def _fit_candidate(session: _Session, baseline: Fit, name: str, start: ModelSpec, names,
                   iterations: int) -> CandidateScore:
    return _score(session, baseline, name, fit(session.train, start, names, max_iterations=iterations))


def _score(session: _Session, baseline: Fit, name: str, result: Fit) -> CandidateScore:
    """A candidate's fit scored against the baseline: held-out error on ``session`` and ΔBIC."""
    heldout = session.heldout(result.spec)
    bic_delta = _bic(result.residuals, len(result.names)) - _bic(baseline.residuals, len(baseline.names))
    return CandidateScore(name, result, session.test.error(heldout), bic_delta, heldout,
                          bic_delta - (len(result.names) - len(baseline.names)) * np.log(result.residuals.size))


def _candidates(session: _Session, baseline: Fit, chosen: list[Candidate]) -> list[CandidateScore]:
    scales = WhiskerScales.of(baseline.spec.physics(session.measurement.geometry))
    scores = []
    for c in chosen:
        start = best_start(session.train, session.train_features, c.on(baseline.spec), c.starts(scales))
        scores.append(_fit_candidate(session, baseline, c.name, start, baseline.names + c.params,
                                     CANDIDATE_ITERATIONS))
    for lead in _leaders(scores):
        refine = next(c.refine for c in chosen if c.name == lead.name)
        scores[scores.index(lead)] = _fit_candidate(session, baseline, lead.name, lead.fit.spec.with_values(refine),
                                                    lead.fit.names + tuple(refine), FINAL_ITERATIONS)
    return scores


def _leaders(scores: list[CandidateScore]) -> list[CandidateScore]:
    """The ``LEADERS`` candidates that pass the training test (:func:`trained`) with the lowest
    held-out errors, and the one with the strongest training evidence (lowest ΔBIC) if it is
    not among them."""
    strong = [s for s in scores if trained(s.name, s.bic_delta, s.fit_delta)]
    leaders = sorted(strong, key=lambda s: s.heldout_error)[:LEADERS]
    best_trained = min(strong, key=lambda s: s.bic_delta, default=None)
    if best_trained is not None and best_trained not in leaders:
        leaders.append(best_trained)
    return leaders


def _corrected_leaders(session: _Session, baseline: Fit, scores: list[CandidateScore]) -> dict:
    """Defect-correct the leading candidates' fits with their own defects, rescore them on the
    held-out trials; {name: corrected simulator}."""
    simulators = {}
    for lead in _leaders(scores):
        try:
            corrected = correct(session.measurement, lead.fit, session.names[0], FINAL_ITERATIONS)
        except SimulationError:        # keeps the score with the baseline's defect
            continue
        own = _Session(session.measurement, *session.names, corrected.simulator)
        scores[scores.index(lead)] = _score(own, baseline, lead.name, corrected.fit)
        simulators[lead.name] = corrected.simulator
    return simulators


def _paired_z(r0: np.ndarray, noise: float, scores: list[CandidateScore]) -> None:
    """Each candidate's paired held-out z (residuals r in 0.1 mm units)."""
    sigma = noise / RESIDUAL_UNIT_M
    for s in scores:
        change = np.linalg.norm(r0 - s.heldout_residuals)
        s.z = float((r0 @ r0 - s.heldout_residuals @ s.heldout_residuals) / (2 * sigma * change)) \
            if change > 0 else 0.0


def significance(error: float, noise: float, floor: float, n: int) -> float:
    """Excess e² − σ̂² − floor² in units of its standard error for white noise, 1.5·σ̂²/√n."""
    return float((error ** 2 - noise ** 2 - floor ** 2) / (1.5 * noise ** 2 / np.sqrt(n)))


def beyond_floor(evidence: dict, floor_fraction: float = None) -> dict[str, float]:
    """Each candidate's paired z for its held-out gain g = e₀² − e_c² beyond its own floor
    f_c² (the model error it can take for an effect): z·(g − f_c²)/g, f_c = min(κ,
    ``ABSORB_MARGIN``·absorbs)·A; a candidate without a gain keeps its z (≤ 0)."""
    floor_fraction = FLOOR_FRACTION if floor_fraction is None else floor_fraction
    e0, amplitude = evidence["baseline_m"], evidence["amplitude_m"]
    result = {}
    for c in evidence["candidates"]:
        gain = e0 ** 2 - c["heldout_m"] ** 2
        absorbed = (min(floor_fraction, ABSORB_MARGIN * c.get("absorbs", ABSORBS[c["name"]])) * amplitude) ** 2
        result[c["name"]] = float(c["z"] * (gain - absorbed) / gain) if gain > 0 else min(float(c["z"]), 0.0)
    return result


def family_z(tried: int, first_round: int) -> float:
    """The z threshold after ``tried`` candidates in all, ``first_round`` of them in the round that
    set ``Z_MIN``: the one-sided tail of ``Z_MIN`` shared out over all of them (Bonferroni)."""
    from scipy.stats import norm

    return float(norm.isf(norm.sf(Z_MIN) * first_round / max(tried, first_round)))


def decide(evidence: dict, floor_fraction: float = None, explained_min: float = None,
           notes: list[str] | None = None, z_min: float = Z_MIN) -> tuple[str, dict[str, float]]:
    """(cause, each candidate's share φ of the excess) from the held-out evidence
    (``Diagnosis.evidence``) and the rule's thresholds (default: this module's)."""
    floor_fraction = FLOOR_FRACTION if floor_fraction is None else floor_fraction
    explained_min = EXPLAINED_MIN if explained_min is None else explained_min
    e0, noise, n = evidence["baseline_m"], evidence["noise_m"], evidence["values"]
    floor = floor_fraction * evidence["amplitude_m"]
    excess = e0 ** 2 - noise ** 2 - floor ** 2
    z_beyond = beyond_floor(evidence, floor_fraction)
    shares = {c["name"]: (e0 ** 2 - c["heldout_m"] ** 2) / excess if excess > 0 else float(z_beyond[c["name"]] > 0)
              for c in evidence["candidates"]}
    beats = [c for c in evidence["candidates"]
             if trained(c["name"], c["bic_delta"], c.get("fit_delta", float("nan"))) and z_beyond[c["name"]] > z_min]
    if significance(e0, noise, floor, n) <= SIGNIFICANT and not beats:
        return "none", shares
    supported = [c for c in beats if shares[c["name"]] >= explained_min]
    if not supported:
        return "unexplained", shares
    best = min(supported, key=lambda c: c["heldout_m"])
    if notes is not None and significance(best["heldout_m"], noise, floor, n) > SIGNIFICANT:
        notes.append(f"{best['name']} leaves a significant misfit ({best['heldout_m'] * 1e3:.4f} mm held out vs "
                     f"noise {noise * 1e3:.4f} mm and model-error floor {floor * 1e3:.4f} mm): "
                     "a second effect may be present")
    return best["name"], shares


E_DENSITY_NOTE = ("positions fix E/ρ only (a uniform density change is exactly a change of E): E is given "
                  "for the file's nominal density; a whisker k times denser has k times this E")


def diagnose(measurement: TimeSeriesMeasurement, material: MaterialConfig | None = None,
             candidates=None) -> Diagnosis:
    """Fit the baseline and every candidate (or those named in ``candidates``), name the cause
    (see the module docstring)."""
    from pipeline.diagnosis.threads import single_threaded_blas

    with single_threaded_blas():
        return _diagnose(measurement, material or MaterialConfig(), candidates)


def _diagnose(measurement, material, candidates) -> Diagnosis:
    unknown = set(candidates or ()) - {c.name for c in CANDIDATES}
    if unknown:
        raise UserError(f"unknown candidate(s) {', '.join(sorted(unknown))} "
                        f"(known: {', '.join(c.name for c in CANDIDATES)})")
    chosen = [c for c in CANDIDATES if (candidates is None or c.name in candidates) and c.applies_to(material)]
    train, test = split_trials(measurement)
    notes = []
    if not test:
        notes.append("a single trial per drive type: held-out error = training error")
        test = train
    session = _Session(measurement, train, test)
    start = matched_start(session.train_features, ModelSpec(material, CONTINUUM))
    baseline = fit(session.train, start, BASELINE_NAMES)
    simulators, simulator_note, bent = {}, "fast (linear)", bend(measurement)
    if bent > LINEAR_BEND_MAX:
        try:
            nonlinear = correct(measurement, baseline, train)
        except (UserError, SimulationError) as exc:
            simulator_note = f"fast (linear); the nonlinear correction failed: {exc}"
        else:
            baseline, simulator_note = nonlinear.fit, nonlinear.note()
            simulators["baseline"] = nonlinear.simulator
            session = _Session(measurement, train, test, nonlinear.simulator)
    r0 = session.heldout(baseline.spec)
    e0 = session.test.error(r0)
    scores = _candidates(session, baseline, chosen)
    if simulators:
        simulators.update(_corrected_leaders(session, baseline, scores))
    best = min([(e0, baseline.spec)] + [(s.heldout_error, s.fit.spec) for s in scores], key=lambda p: p[0])[1]
    noise = noise_estimate(session.test.measurement, session.test.simulate(best))
    _paired_z(r0, noise, scores)
    evidence = {**_evidence(e0, noise, amplitude(session.test.measurement), r0, scores),
                "bend": bent, "simulator": simulator_note}
    cause, shares = decide(evidence, notes=notes)
    notes.append(E_DENSITY_NOTE)
    evidence["ambiguous"] = ["E", "density.scale"]
    for c, z in zip(evidence["candidates"], beyond_floor(evidence).values()):
        c["z_beyond_floor"] = z
    for c in scores:
        c.score = shares[c.name]
    if simulators:
        notes.append(f"the data bend the whisker by {100 * evidence['bend']:.0f} % of its length, beyond the "
                     f"{100 * LINEAR_BEND_MAX:.0f} % the linear fast simulator follows: baseline and leading "
                     f"candidates scored with the {simulator_note}")
    named = next((s for s in scores if s.name == cause), None)
    causes = [cause] if named else []
    if named and simulators:
        notes.append("the data need the nonlinear correction: only one cause is looked for")
    tried, rounds = len(scores), []
    while named and not simulators and len(causes) < MAX_CAUSES:
        rest = [c for c in chosen if c.name not in causes and not (c.law and set(causes) & set(DAMPING_LAWS))]
        found, round_evidence = _next_cause(session, named, rest, noise, evidence["amplitude_m"],
                                            family_z(tried + len(rest), len(scores)))
        tried += len(rest)
        rounds.append(round_evidence)
        if found is None:
            break
        named = found
        causes.append(found.name)
    evidence["rounds"] = rounds
    if len(causes) > 1:
        notes.append(f"{len(causes)} causes named, in order: {', '.join(causes)} (each on top of the ones before)")
    final_names = BASELINE_NAMES + (named.fit.names[2:] if named else ())
    whole = TrajectoryObjective(measurement, simulators.get(cause, simulators.get("baseline")))
    final = fit(whole, (named.fit if named else baseline).spec, final_names, max_iterations=FINAL_ITERATIONS)
    baseline_whole = TrajectoryObjective(measurement, simulators.get("baseline"))
    baseline_all = fit(baseline_whole, baseline.spec, BASELINE_NAMES, max_iterations=FINAL_ITERATIONS)
    blocks, model_error = whole.blocks(BLOCK_S), SD_MODEL_FRACTION * amplitude(measurement)
    for result in (final, baseline_all):
        result.sd = with_modulus_discretisation(block_sandwich_sd(result, blocks, model_error / RESIDUAL_UNIT_M),
                                                result, measurement.geometry)
    simulated = {"baseline": baseline_whole.simulate(baseline_all.spec), "cause": whole.simulate(final.spec)}
    law = next((c for c in causes if c in DAMPING_LAWS), None)
    if law:
        notes.append(_law_note(law, final, measurement.geometry))
    return Diagnosis(
        baseline=baseline_all, baseline_heldout=e0, candidates=scores, cause=cause, final=final,
        gain_after=named.heldout_error if named else e0, noise_m=noise,
        analysis=analyse(measurement, simulated["baseline"]),
        cause_analysis=analyse(measurement, simulated["cause"]),
        split={"train": train, "heldout": test}, notes=notes + final.notes, simulated=simulated,
        evidence=evidence, floor_m=FLOOR_FRACTION * evidence["amplitude_m"], causes=causes)


def _law_note(law: str, final: Fit, geometry) -> str:
    """The named damping law's first three in-plane modes (f, ζ) in the refitted model."""
    from pipeline.diagnosis.damping_laws import in_plane_modes
    from pipeline.engines.linear.chain import linearise

    f, z = in_plane_modes(linearise(final.spec.physics(geometry)), 3)
    modes = ", ".join(f"{fi:.1f} Hz ζ {zi:.3f}" for fi, zi in zip(f, z) if np.isfinite(fi))
    return f"damping law {law} ({final.spec.material.damping_model} joints" + \
        (" + mass-proportional α·M" if final.spec.extension("mass_damping") else "") + f"): in-plane modes {modes}"


def _evidence(e0: float, noise: float, amplitude_m: float, r0: np.ndarray, scores: list[CandidateScore]) -> dict:
    """The held-out evidence :func:`decide` takes (baseline error e0 and residuals r0)."""
    return {"baseline_m": e0, "noise_m": noise, "amplitude_m": amplitude_m, "values": int(r0.size),
            "candidates": [{"name": c.name, "heldout_m": c.heldout_error, "bic_delta": c.bic_delta,
                            "fit_delta": c.fit_delta, "z": c.z, "absorbs": ABSORBS[c.name]} for c in scores]}


def _next_cause(session: _Session, named: CandidateScore, rest: list[Candidate], noise: float,
                amplitude_m: float, z_min: float) -> tuple[CandidateScore | None, dict]:
    """One round of step 5b: the ``rest`` candidates fitted on top of the ``named`` model (its
    training fit the baseline), decided at ``z_min``; (the new cause's score or None, evidence)."""
    scores = _candidates(session, named.fit, rest)
    _paired_z(named.heldout_residuals, noise, scores)
    evidence = _evidence(named.heldout_error, noise, amplitude_m, named.heldout_residuals, scores)
    cause, _ = decide(evidence, z_min=z_min)
    evidence.update(z_min=z_min, on_top_of=named.fit.names, cause=cause)
    return next((s for s in scores if s.name == cause), None), evidence
