"""What does the model get wrong on a measurement, and which extension explains it?

Time series (positions of tracked points):

1. Split the trials in two, stratified by drive (:func:`~.candidate_fits.split_trials`): a
   training half and a held-out half.
2. Baseline: fit E and ζ on the training trials (trajectory least squares from a start whose
   FRF and δ match the data); its error on the held-out trials is e₀. Every model fitted here
   has the two ``CONTINUUM`` corrections, which make the chain converge to the continuous
   whisker at second order in 1/N: the base segment
   (:class:`~pipeline.model.effects.base_segment.BaseSegment`; the chain's rigid base half-link would
   otherwise bias E by ≈ −1.2/N and the base-weighted parameters with it) and the integrated
   link density (:class:`~pipeline.model.effects.integrated_density.IntegratedDensity`; the paper's
   proximal-node density, ≈ −0.5 % on E at N = 20).
3. Each candidate (:mod:`.candidates`, damping laws included) fitted on the training trials on
   top of the baseline and scored on the held-out ones (:mod:`.candidate_fits`).
4. Evidence on the held-out trials: tracking noise σ̂ from the second differences of the
   best model's residuals (:mod:`.residuals`), the RMS deflection A of the held-out data
   (:mod:`.deflection`), each candidate's paired z.
5. Decision (:mod:`.decision`): "none", "unexplained" or a candidate. A named cause that still
   leaves a significant excess gets a note (a second effect?). Positions cannot tell a uniform
   density change from a change of E (eq. 3: only E/ρ sets the time scale): every diagnosis
   says so.
5b. Several causes (:mod:`.later_causes`): forward selection, each later round decided on both
   halves held out in turn, at a z threshold that counts every candidate tried; after an
   "unexplained" first round, one pair (the held-out leader and a round on top of it). Data scored
   with the nonlinear correction stop after the first round (a note says so). ``causes``
   lists the causes in the order named; the model refitted in step 6 holds all of them.
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
from pipeline.diagnosis.candidate_fits import (FINAL_ITERATIONS, CandidateScore, Session, corrected_leaders,
                                               evidence_of, fit_candidates, paired_z, split_trials)
from pipeline.diagnosis.candidates import CANDIDATES, DAMPING_LAWS
from pipeline.diagnosis.damping_laws import in_plane_modes
from pipeline.diagnosis.decision import FLOOR_FRACTION, beyond_floor, decide
from pipeline.diagnosis.deflection import amplitude, bend
from pipeline.diagnosis.discretisation import with_modulus_discretisation
from pipeline.diagnosis.fitting import Fit, block_sandwich_sd, fit, matched_start
from pipeline.diagnosis.later_causes import forward_selection, pair_after_unexplained
from pipeline.diagnosis.nonlinear import correct
from pipeline.diagnosis.objective import RESIDUAL_UNIT_M, TrajectoryObjective
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec
from pipeline.diagnosis.residuals import analyse, noise_estimate
from pipeline.diagnosis.threads import single_threaded_blas
from pipeline.engines.linear.chain import linearise
from pipeline.errors import SimulationError, UserError
from pipeline.measurements.timeseries import TimeSeriesMeasurement
from pipeline.model.effects.base_segment import BaseSegment
from pipeline.model.effects.integrated_density import IntegratedDensity

CONTINUUM = (BaseSegment(), IntegratedDensity())   # in every model diagnose fits (step 2)
METRIC = "heldout_rms_m"
LINEAR_BEND_MAX = 0.2       # largest tip deflection / S the linear fast simulator follows (§9)
BLOCK_S = 0.05              # residual blocks of the sandwich SDs (s)
SD_MODEL_FRACTION = 0.0014  # model-error term of the SDs / RMS deflection (benchmarks/calibrate_sd.py, §9)


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


E_DENSITY_NOTE = ("positions fix E/ρ only (a uniform density change is exactly a change of E): E is given "
                  "for the file's nominal density; a whisker k times denser has k times this E")


def diagnose(measurement: TimeSeriesMeasurement, material: MaterialConfig | None = None,
             candidates=None) -> Diagnosis:
    """Fit the baseline and every candidate (or those named in ``candidates``), name the cause
    (see the module docstring)."""
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
    session = Session(measurement, train, test)
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
            session = Session(measurement, train, test, nonlinear.simulator)
    r0 = session.heldout(baseline.spec)
    e0 = session.test.error(r0)
    scores = fit_candidates(session, baseline, chosen)
    if simulators:
        simulators.update(corrected_leaders(session, baseline, scores))
    best = min([(e0, baseline.spec)] + [(s.heldout_error, s.fit.spec) for s in scores], key=lambda p: p[0])[1]
    noise = noise_estimate(session.test.measurement, session.test.simulate(best))
    paired_z(r0, noise, scores)
    evidence = {**evidence_of(e0, noise, amplitude(session.test.measurement), r0, scores),
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
    causes, rounds = ([cause] if named else []), []
    if named and simulators:
        notes.append("the data need the nonlinear correction: only one cause is looked for")
    elif named:
        named, causes, rounds = forward_selection(session, named, chosen, len(scores), noise)
    elif cause == "unexplained" and not simulators:
        named, causes, rounds = pair_after_unexplained(session, scores, chosen, evidence, noise)
        if named:
            cause = causes[0]
            notes.append(f"no candidate explains the misfit alone: {causes[0]} and {causes[1]} pass the first "
                         "round's tests together")
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
    f, z = in_plane_modes(linearise(final.spec.physics(geometry)), 3)
    modes = ", ".join(f"{fi:.1f} Hz ζ {zi:.3f}" for fi, zi in zip(f, z) if np.isfinite(fi))
    return f"damping law {law} ({final.spec.material.damping_model} joints" + \
        (" + mass-proportional α·M" if final.spec.extension("mass_damping") else "") + f"): in-plane modes {modes}"
