"""Several causes: forward selection after the first cause (step 5b of :mod:`.diagnose`).

Once a cause is named, the named model is the baseline of another round over the remaining
candidates, each fitted on top of it, until a round names nothing or ``MAX_CAUSES`` are named
(once a damping law is named no other law is tried: the laws exclude each other).

A round is decided on both halves of the split held out in turn (two folds), the first
round on one (:mod:`.decision`):

- fold 1: the candidates fitted on the training half on top of the named model's training fit,
  scored on the held-out half (as in the first round);
- fold 2: the named model refitted on the held-out half, the candidates that lowered fold 1's
  held-out error (paired z > 0) fitted on top of it there, and scored on the training half;
- combined: each residual is held out exactly once, so the two folds' held-out residuals,
  concatenated, give one held-out error per candidate and its share of the pooled excess (A
  the RMS deflection of all trials); its z is Stouffer's (z₁ + z₂)/√2 of the folds' paired z
  beyond their own floors (each fold's floor from its own held-out half: the floors
  are not a fixed share of the pooled gain, so pooling the gains first would let the half with
  the larger deflections set the floor of both). The training test asks a training fit no
  worse than the named model's (:func:`~.decision.trained`, ``later``) on at least one of the
  two halves: after the first cause the rest of the misfit can sit in the trials of one half
  only (a follicle behind a fitted stiffness gradient: held out z 23 with no training gain). ``first_fold`` and
  ``second_fold`` in the evidence are each fold alone, fold 1 as the first round scores it.

A first round that ends "unexplained" (no candidate passes its tests alone) tries one pair
(:func:`pair_after_unexplained`): a round on top of the candidate that leads on the held-out
trials, the pair named when it passes the first round's tests together
(:func:`~.decision.pair_passes`); the forward selection then goes on from the pair.

Many candidates tried: the z threshold of a later round is :func:`~.decision.family_z` over
every candidate tried so far (Bonferroni on the one-sided tail of ``Z_MIN``, which the first
round's candidates set); a fold-2 refit is part of the same test (one combined z per candidate),
and leaving out the candidates with fold-1 z ≤ 0 only removes tests, so the family's
false-alarm rate stays at most that of ``Z_MIN`` on the first round.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.diagnosis.candidate_fits import (FINAL_ITERATIONS, CandidateScore, Session, evidence_of,
                                               fit_candidates, paired_z)
from pipeline.diagnosis.candidates import DAMPING_LAWS, Candidate
from pipeline.diagnosis.decision import beyond_floor, decide, family_z, pair_leader, pair_passes
from pipeline.diagnosis.deflection import amplitude
from pipeline.diagnosis.fitting import fit

MAX_CAUSES = 3              # rounds of the forward selection


def forward_selection(session: Session, named: CandidateScore, chosen: list[Candidate], first_round: int,
                      noise: float, causes: list[str] | None = None,
                      tried: int | None = None) -> tuple[CandidateScore, list[str], list[dict]]:
    """The causes after the first one (``named``, from ``first_round`` candidates), or after
    ``causes`` already named with ``tried`` candidates tried: (the last named cause's score,
    every cause in the order named, each round's evidence)."""
    causes, rounds, tried = list(causes or [named.name]), [], tried or first_round
    while len(causes) < MAX_CAUSES:
        rest = _rest(chosen, causes)
        tried += len(rest)
        found, evidence = next_cause(session, named, rest, noise, family_z(tried, first_round))
        rounds.append(evidence)
        if found is None:
            break
        named = found
        causes.append(found.name)
    return named, causes, rounds


def pair_after_unexplained(session: Session, scores: list[CandidateScore], chosen: list[Candidate],
                           evidence: dict, noise: float) -> tuple[CandidateScore | None, list[str], list[dict]]:
    """After a first round (``scores``, its ``evidence``) that ends "unexplained": the round on top
    of its leader (:func:`~.decision.pair_leader`) at the family threshold; (the last named
    cause's score, every cause named, each round's evidence), nothing named when the pair
    fails the first round's tests (:func:`~.decision.pair_passes`)."""
    leader = next((s for s in scores if s.name == pair_leader(evidence)), None)
    if leader is None:
        return None, [], []
    rest = _rest(chosen, [leader.name])
    tried = len(scores) + len(rest)
    found, pair_round = next_cause(session, leader, rest, noise, family_z(tried, len(scores)))
    passes = found is not None and pair_passes(evidence, leader.name, pair_round, found.name)
    pair_round.update(pair_after_unexplained=True, pair_passes=passes)
    if not passes:
        return None, [], [pair_round]
    named, causes, rounds = forward_selection(session, found, chosen, len(scores), noise,
                                              [leader.name, found.name], tried)
    return named, causes, [pair_round] + rounds


def _rest(chosen: list[Candidate], causes: list[str]) -> list[Candidate]:
    """The candidates a round on top of ``causes`` tries (one damping law at most)."""
    return [c for c in chosen if c.name not in causes and not (c.law and set(causes) & set(DAMPING_LAWS))]


def next_cause(session: Session, named: CandidateScore, rest: list[Candidate], noise: float,
               z_min: float) -> tuple[CandidateScore | None, dict]:
    """One round: the ``rest`` candidates on top of the ``named`` model, decided at ``z_min`` on
    both folds (module docstring); (the new cause's fold-1 score or None, evidence)."""
    first = fit_candidates(session, named.fit, rest)
    paired_z(named.heldout_residuals, noise, first)
    evidence = {"first_fold": evidence_of(named.heldout_error, noise, amplitude(session.test.measurement),
                                          named.heldout_residuals, first)}
    carried = [c for c, s in zip(rest, first) if s.z > 0]
    if session.names[0] == session.names[1] or not carried:     # one fold (a single trial per drive type)
        pooled, r0 = first, named.heldout_residuals
    else:
        other = session.flipped()
        refit = fit(other.train, named.fit.spec, named.fit.names, max_iterations=FINAL_ITERATIONS)
        r0_other = other.heldout(refit.spec)
        second = fit_candidates(other, refit, carried)
        paired_z(r0_other, noise, second)
        evidence["second_fold"] = evidence_of(other.test.error(r0_other), noise, amplitude(other.test.measurement),
                                              r0_other, second)
        r0 = np.concatenate([named.heldout_residuals, r0_other])
        pooled = [_pooled(session, s, t) for s, t in zip([s for s in first if s.z > 0], second)]
    evidence.update(evidence_of(session.test.error(r0), noise, amplitude(session.measurement), r0, pooled))
    if "second_fold" in evidence:
        _combine(evidence)
    cause, _ = decide(evidence, z_min=z_min, later=True)
    evidence.update(z_min=z_min, on_top_of=named.fit.names, cause=cause)
    return next((s for s in first if s.name == cause), None), evidence


def _combine(evidence: dict) -> None:
    """Each candidate's z in the pooled ``evidence``: Stouffer's sum of its two folds' z beyond
    their own floors, (z₁ + z₂)/√2 (``absorbs`` 0: the floors are already out)."""
    beyond = [beyond_floor(evidence[fold]) for fold in ("first_fold", "second_fold")]
    for c in evidence["candidates"]:
        c.update(z=(beyond[0][c["name"]] + beyond[1][c["name"]]) / np.sqrt(2), absorbs=0.0)


def _pooled(session: Session, first: CandidateScore, second: CandidateScore) -> CandidateScore:
    """A candidate's two folds as one held-out score: all its held-out residuals, the better
    training evidence."""
    residuals = np.concatenate([first.heldout_residuals, second.heldout_residuals])
    return replace(first, heldout_error=session.test.error(residuals), heldout_residuals=residuals,
                   bic_delta=min(first.bic_delta, second.bic_delta), fit_delta=min(first.fit_delta, second.fit_delta))
