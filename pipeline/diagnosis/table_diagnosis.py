"""Diagnose a resonance table (f1, δ per whisker): what fits, what does not, what can be told apart.

With m measured features and the baseline's two parameters (E, θ_ζ) there are m − 2 checks.
The baseline fit's χ² (residuals ln(sim/exp) over the measured log standard deviations) says
whether the model is inside the measured spread ("none") or not ("unexplained": a table of
f1 and δ alone cannot single out a cause). For every candidate parameter the sensitivity of
the log-features J_c is compared with those of E and θ_ζ: the share of J_c orthogonal to
their span tells whether the table could ever distinguish it ("confounded with E/θ_ζ" below
``CONFOUNDED``), "no effect" if J_c is negligible. Candidates that are distinguishable are
fitted in-sample; with three or more whiskers each is also scored leaving one whisker out.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2 as chi2_dist

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.calibrate import modal_summary
from pipeline.diagnosis.candidates import CANDIDATES, WhiskerScales
from pipeline.diagnosis.features import msa
from pipeline.diagnosis.fitting import FD_STEP, Fit, fit, matched_start
from pipeline.diagnosis.objective import TableObjective
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec, ParameterSpace
from pipeline.diagnosis.threads import single_threaded_blas
from pipeline.measurements.table import ResonanceTable

CONFOUNDED = 0.1           # orthogonal share of a sensitivity below which E/θ_ζ mimic it
NO_EFFECT = 1e-3           # |∂ ln feature/∂x| below this: the feature does not see the parameter
CHI2_LEVEL = 0.95
# assumed relative standard deviations where a table gives none: frequency, log decrement
# (ζ1: the two D-row methods differ by 10-35 % on the same whiskers, Hartmann et al. 2003)
DEFAULT_LOG_SD = {"hz": 0.01, "log_decrement": 0.25, "zeta1": 0.2}


@dataclass
class TableDiagnosis:
    baseline: Fit
    candidates: list[dict]
    cause: str
    final: Fit
    rows: list[dict]
    identifiability: list[dict]
    summary: str
    chi2: float
    dof: int
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"baseline": {"params": self.baseline.params(), "error": self.baseline.error},
                "candidates": [{k: c[k] for k in ("name", "params", "heldout_error", "score")}
                               for c in self.candidates],
                "cause": self.cause, "params": self.final.params(),
                "gain": {"metric": self.baseline.metric, "before": self.baseline.error,
                         "after": self.final.error}}


def _sensitivities(objective: TableObjective, spec: ModelSpec, names) -> np.ndarray:
    """[m, p] ∂ ln(features)/∂x at ``spec`` (forward differences in ParameterSpace coordinates)."""
    space = ParameterSpace(names)
    x = space.to_x({**spec.values(), **{n: p.neutral for n, p in zip(names, space.specs)
                                        if n not in spec.values()}})
    r0 = objective.residuals(spec.with_values(space.to_values(x)))
    columns = []
    for i in range(len(x)):
        step = FD_STEP * 10 * max(1.0, abs(x[i]))
        shifted = x.copy()
        shifted[i] += step
        columns.append((objective.residuals(spec.with_values(space.to_values(shifted))) - r0) / step)
    return np.stack(columns, axis=1)


def _verdict(jac: np.ndarray, weights: np.ndarray, dof_left: int) -> tuple[str, float]:
    j = jac * weights[:, None]
    base, own = j[:, :2], j[:, 2]
    if np.abs(jac[:, 2]).max() < NO_EFFECT:
        return "no effect on these features", 0.0
    q, _ = np.linalg.qr(base)
    orthogonal = float(np.linalg.norm(own - q @ (q.T @ own)) / np.linalg.norm(own))
    if orthogonal < CONFOUNDED:
        return f"confounded with E/θ_ζ (only {100 * orthogonal:.0f} % of its effect is distinct)", orthogonal
    if dof_left < 1:
        return f"distinct in principle ({100 * orthogonal:.0f} %), but the table has too few features", orthogonal
    return f"distinguishable ({100 * orthogonal:.0f} % distinct)", orthogonal


def diagnose_table(table: ResonanceTable, material: MaterialConfig | None = None) -> TableDiagnosis:
    with single_threaded_blas():
        return _diagnose_table(table, material or MaterialConfig())


def log_sd_with_defaults(objective: TableObjective) -> tuple[np.ndarray, str]:
    """Measured log standard deviations, defaults (DEFAULT_LOG_SD) where the table has none."""
    keys = [key for meas in objective.measured() for key in meas]
    sd = objective.log_sd()
    missing = ~(np.isfinite(sd) & (sd > 0))
    defaults = np.array([DEFAULT_LOG_SD["hz" if k.endswith("_hz") else k] for k in keys])
    sd = np.where(missing, defaults, sd)
    return sd, ", ".join(sorted({keys[i] for i in np.flatnonzero(missing)}))


def _leave_one_out(table: ResonanceTable, spec: ModelSpec, names) -> float:
    """MSA of each whisker's features predicted from a fit to the other whiskers."""
    ratios = []
    for k in range(len(table.records)):
        others = replace(table, records=table.records[:k] + table.records[k + 1:])
        model = fit(TableObjective(others), spec, names).spec
        ratios.extend(TableObjective(replace(table, records=(table.records[k],))).residuals(model))
    return msa(ratios)


def _diagnose_table(table: ResonanceTable, material: MaterialConfig) -> TableDiagnosis:
    objective = TableObjective(table)
    sd, assumed = log_sd_with_defaults(objective)
    weights = 1.0 / sd
    start = matched_start(objective, ModelSpec(material))
    baseline = fit(objective, start, BASELINE_NAMES, sigma=sd)
    m = baseline.residuals.size
    dof = m - len(BASELINE_NAMES)
    chi2 = float(baseline.residuals @ baseline.residuals)
    simulated = objective.record_features(baseline.spec)
    rows = []
    for record, meas, sim in zip(table.records, objective.measured(), simulated):
        rows.append({"whisker": record.whisker, "measured": meas, "simulated": sim,
                     "z": {k: float(np.log(sim[k] / v) / (s / v)) if s > 0 else float("nan")
                           for k, (v, s) in meas.items()}})
    scales = WhiskerScales.of(baseline.spec.physics(table.records[0].geometry))
    identifiability, candidates = [], []
    for cand in CANDIDATES:
        spec = baseline.spec.with_values(cand.starts(scales)[0])
        jac = _sensitivities(objective, spec, BASELINE_NAMES + cand.params)
        distinct = []
        for i, param in enumerate(cand.params):
            verdict, share = _verdict(jac[:, [0, 1, 2 + i]], weights, dof - len(cand.params))
            identifiability.append({"name": cand.name, "param": param, "verdict": verdict,
                                    "distinct_share": share})
            distinct.append(verdict.startswith("distinguishable"))
        if all(distinct):
            result = fit(objective, spec, BASELINE_NAMES + cand.params, sigma=sd)
            chi2_c = float(result.residuals @ result.residuals)
            heldout = (_leave_one_out(table, spec, BASELINE_NAMES + cand.params)
                       if len(table.records) >= 3 else None)
            candidates.append({"name": cand.name, "params": result.params(), "heldout_error": heldout,
                               "score": (chi2 - chi2_c) / chi2 if chi2 > 0 else 0.0, "fit": result})
        else:
            candidates.append({"name": cand.name, "params": {}, "heldout_error": None, "score": None})
    inside = dof <= 0 or chi2 <= chi2_dist.ppf(CHI2_LEVEL, dof)
    cause = "none" if inside else "unexplained"
    summary = _summary(table, baseline, rows, chi2, dof, identifiability, inside)
    notes = ["f2, f3 of the model are the linear chain's in-plane natural frequencies (damped)",
             "θ_ζ is the damping model's parameter, not the modal damping ratio"]
    if assumed:
        notes.append(f"standard deviations assumed where missing: {assumed}")
    return TableDiagnosis(baseline, candidates, cause, baseline, rows, identifiability, summary, chi2,
                          dof, notes)


def _summary(table, baseline: Fit, rows, chi2, dof, identifiability, inside) -> str:
    e = baseline.values["E"]
    parts = [f"Baseline E = {e / 1e9:.2f} ± {baseline.sd.get('E', np.nan) / 1e9:.2f} GPa, "
             f"θ_ζ = {baseline.values['zeta']:.3f} ± {baseline.sd.get('zeta', np.nan):.3f}: "
             f"MSA {baseline.error:.3f}, χ² = {chi2:.2f} on {dof} degree(s) of freedom "
             f"({'inside' if inside else 'outside'} the measured spread)."]
    own = [f"{r['whisker']} {e * (r['measured']['f1_hz'][0] / r['simulated']['f1_hz']) ** 2 / 1e9:.2f} GPa"
           for r in rows]
    parts.append("E matching each whisker's f1 alone: " + ", ".join(own) + ".")
    modes = [f"{rec.whisker} {modal_summary(baseline.spec, rec.geometry)['zeta1']:.3f}"
             + (f" (measured {rec.damping_ratio:.2f} ± {rec.damping_ratio_sd:.2f})"
                if np.isfinite(rec.damping_ratio) else "") for rec in table.records]
    parts.append("Modal damping ratio of mode 1: " + ", ".join(modes) + ".")
    groups: dict[str, list[str]] = {}
    for item in identifiability:
        key = item["verdict"].split(" (")[0].split(",")[0]
        groups.setdefault(key, []).append(item["param"])
    parts.append(" ".join(f"{k[0].upper() + k[1:]}: {', '.join(v)}." for k, v in groups.items()))
    return " ".join(parts)
