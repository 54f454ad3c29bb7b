"""The rule that names a cause from held-out evidence (steps 4–5 of :mod:`.diagnose`).

The evidence (``Diagnosis.evidence``, a dict): the baseline's held-out RMS error e₀
(``baseline_m``), the tracking noise σ̂ (``noise_m``), the RMS deflection A of the held-out
data (``amplitude_m``), the number n of held-out values (``values``), and per candidate its
held-out error e_c, ΔBIC and n·ln(RSS_c/RSS₀) on its training trials, and its paired z.

- Model-error floor f = ``FLOOR_FRACTION``·A: a cap on the misfit a right model leaves because
  the chain is not the continuum (docs/measurements.md §9). The excess X = e₀² − σ̂² − f² is
  the misfit to explain, significant when it exceeds ``SIGNIFICANT`` times its standard
  error ≈ 1.5·σ̂²/√n (white noise).
- A candidate's gain g = e₀² − e_c², its share of the excess φ = g/X (X ≤ 0: 1 if g exceeds
  the candidate's own floor, else 0); its paired z beyond its own floor, z·(g − f_c²)/g, f_c =
  min(f, ``ABSORB_MARGIN``·κ_c·A), κ_c the most of the model error that candidate took for an
  effect on effect-free calibration draws (``Candidate.absorbs``).
- Training test (:func:`trained`): ΔBIC < −``BIC_MIN`` for an effect in the first round; a
  training fit no worse than the baseline's for a damping law, and for every candidate of a
  later round (on top of a named cause, :mod:`.later_causes`).
- Decision (:func:`decide`): the baseline is inadequate when X is significant or when a
  candidate that passes the training test has z beyond its floor > ``Z_MIN``; otherwise
  "none". Then the candidate with the lowest held-out error among those that pass the
  training test, with z beyond its floor > ``Z_MIN`` and that explain the misfit: φ ≥
  ``EXPLAINED_MIN``, or no significant excess left, e_c² − σ̂² − f² within ``SIGNIFICANT``
  standard errors (an excess that is itself within the noise has no share to take); none
  such → "unexplained".
- A pair after "unexplained" (:func:`pair_leader`, :func:`pair_passes`): two effects can each be
  too weak to pass alone while the other is left out. The candidate that leads on the held-out
  trials (z beyond its floor > ``Z_MIN``, lowest e_c) is then the start of a later round; the
  pair is named when it passes the first round's tests together: the leader's ΔBIC plus the
  second's on top of it (the same training trials) < −``BIC_MIN``, and the pair's held-out error
  explains the first round's excess as a single cause must.
"""

from __future__ import annotations

import numpy as np

from pipeline.diagnosis.candidates import ABSORBS, DAMPING_LAWS

BIC_MIN = 10.0             # "very strong" evidence on the Kass–Raftery scale
Z_MIN = 3.0
SIGNIFICANT = 3.0
EXPLAINED_MIN = 0.5
FLOOR_FRACTION = 0.03       # model-error floor / RMS deflection (docs/measurements.md §9)
ABSORB_MARGIN = 2.0         # a candidate's floor / the most it absorbed on calibration draws (§9)


def trained(name: str, bic_delta: float, fit_delta: float, later: bool = False) -> bool:
    """The training half's test of a candidate: an effect needs ΔBIC < −``BIC_MIN``; a damping
    law (:data:`~.candidates.DAMPING_LAWS`: an alternative to the baseline's law, not an
    effect added to it) needs only a training fit no worse than the baseline's
    (n·ln(RSS_c/RSS₀) < 0), its held-out z beyond its own floor being the test: a law's
    signature is the higher modes' decay, which some drives excite and others hardly, so one
    half of the trials can hold it and the other not. In a ``later`` round every candidate is
    tested as a law is: the named cause's parameters were fitted on the same training trials and
    took what they could of a second effect there (a stiffness gradient's γ absorbs a compliant
    follicle), so the two fits can end equally good on those trials and only the held-out
    trials, at the round's family threshold, tell them apart."""
    if name in DAMPING_LAWS or later:
        return fit_delta < 0
    return bic_delta < -BIC_MIN


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
    # imported here, not at the top: scipy.stats ≈0.7 CPU-s on every command that imports the diagnosis
    from scipy.stats import norm

    return float(norm.isf(norm.sf(Z_MIN) * first_round / max(tried, first_round)))


def decide(evidence: dict, floor_fraction: float = None, explained_min: float = None,
           notes: list[str] | None = None, z_min: float = Z_MIN, later: bool = False) -> tuple[str, dict[str, float]]:
    """(cause, each candidate's share φ of the excess) from the held-out evidence
    (``Diagnosis.evidence``) and the rule's thresholds (default: this module's); ``later``: a
    round on top of a named cause (its training test, :func:`trained`)."""
    floor_fraction = FLOOR_FRACTION if floor_fraction is None else floor_fraction
    explained_min = EXPLAINED_MIN if explained_min is None else explained_min
    e0, noise, n = evidence["baseline_m"], evidence["noise_m"], evidence["values"]
    floor = floor_fraction * evidence["amplitude_m"]
    excess = e0 ** 2 - noise ** 2 - floor ** 2
    z_beyond = beyond_floor(evidence, floor_fraction)
    shares = {c["name"]: (e0 ** 2 - c["heldout_m"] ** 2) / excess if excess > 0 else float(z_beyond[c["name"]] > 0)
              for c in evidence["candidates"]}
    beats = [c for c in evidence["candidates"]
             if trained(c["name"], c["bic_delta"], c.get("fit_delta", float("nan")), later) and z_beyond[c["name"]] > z_min]
    if significance(e0, noise, floor, n) <= SIGNIFICANT and not beats:
        return "none", shares
    supported = [c for c in beats if shares[c["name"]] >= explained_min
                 or significance(c["heldout_m"], noise, floor, n) <= SIGNIFICANT]
    if not supported:
        return "unexplained", shares
    best = min(supported, key=lambda c: c["heldout_m"])
    if notes is not None and significance(best["heldout_m"], noise, floor, n) > SIGNIFICANT:
        notes.append(f"{best['name']} leaves a significant misfit ({best['heldout_m'] * 1e3:.4f} mm held out vs "
                     f"noise {noise * 1e3:.4f} mm and model-error floor {floor * 1e3:.4f} mm): "
                     "a second effect may be present")
    return best["name"], shares


def pair_leader(evidence: dict, floor_fraction: float = None) -> str | None:
    """The candidate a pair starts from when :func:`decide` says "unexplained": the lowest
    held-out error among those with z beyond their floor > ``Z_MIN``, whatever their training
    test and share (None when no candidate has such z)."""
    z_beyond = beyond_floor(evidence, floor_fraction)
    ahead = [c for c in evidence["candidates"] if z_beyond[c["name"]] > Z_MIN]
    return min(ahead, key=lambda c: c["heldout_m"])["name"] if ahead else None


def pair_passes(evidence: dict, leader: str, pair_round: dict, second: str, floor_fraction: float = None) -> bool:
    """Does the pair (``leader`` of the first round's ``evidence``, ``second`` named in the round on
    top of it, whose ``first_fold`` holds the first round's held-out half) pass the first round's
    tests together: ΔBIC_leader + ΔBIC_second|leader < −``BIC_MIN`` on the training trials, and
    the pair's held-out error takes ≥ ``EXPLAINED_MIN`` of the first round's excess or leaves
    none that is significant."""
    floor_fraction = FLOOR_FRACTION if floor_fraction is None else floor_fraction
    first = next(c for c in evidence["candidates"] if c["name"] == leader)
    pair = next(c for c in pair_round["first_fold"]["candidates"] if c["name"] == second)
    if first["bic_delta"] + pair["bic_delta"] >= -BIC_MIN:
        return False
    e0, noise, n = evidence["baseline_m"], evidence["noise_m"], evidence["values"]
    floor = floor_fraction * evidence["amplitude_m"]
    excess = e0 ** 2 - noise ** 2 - floor ** 2
    share = (e0 ** 2 - pair["heldout_m"] ** 2) / excess if excess > 0 else 1.0
    return share >= EXPLAINED_MIN or significance(pair["heldout_m"], noise, floor, n) <= SIGNIFICANT
