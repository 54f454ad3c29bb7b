"""Joint calibration over several resonance tables (``pipeline calibrate A.csv B.csv``, ``--library``).

The tables are combined into one (:func:`pipeline.measurements.table.combine`): every record
keeps its set's conditions, in particular how its damping was measured (the paper's two-peak δ
of the protocol, or the first mode's ζ1 of the linear chain; :class:`TableObjective`), and
shared parameters are fitted to all of them at once with the same least squares as
``pipeline calibrate`` (:func:`pipeline.diagnosis.fitting.fit`), each residual ln(sim/exp)
divided by its measured log standard deviation or, where a table gives none, by
:data:`~pipeline.diagnosis.table_diagnosis.DEFAULT_LOG_SD` (a χ² fit; parameter SDs from the
Jacobian, scaled by the Birge ratio √(χ²/dof) when the data scatter more than that). Reported: every set's misfit (MSA and χ²/n over its own residuals) and, for
records held out of the fit (:data:`pipeline.measurements.library.HELD_OUT`), the prediction
error: |f1 error| per whisker and its median, ζ1 against the range measured on those whiskers.
"""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.features import msa
from pipeline.diagnosis.fitting import fit, matched_start
from pipeline.diagnosis.objective import TableObjective
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.diagnosis.table_diagnosis import log_sd_with_defaults
from pipeline.diagnosis.threads import single_threaded_blas
from pipeline.measurements.library import split_held_out
from pipeline.measurements.table import CONDITIONS, combine

MAX_ITERATIONS = 60


def _per_set(objective: TableObjective, spec: ModelSpec, sd: np.ndarray) -> dict[str, dict]:
    """Misfit of each set at ``spec``: MSA and χ²/n of its own residuals."""
    residuals = objective.residuals(spec)
    owner = [r.source for r, meas in zip(objective.table.records, objective.measured()) for _ in meas]
    out = {}
    for name in dict.fromkeys(owner):
        mask = np.array([o == name for o in owner])
        out[name] = {"msa": msa(residuals[mask]), "chi2_per_value": float(np.mean((residuals[mask] / sd[mask]) ** 2)),
                     "values": int(mask.sum())}
    return out


def held_out_errors(table, spec: ModelSpec) -> dict:
    """Prediction of held-out records: f1 error per whisker (sim/exp − 1), its median |·|, and
    ζ1 (linear chain) against the range of the measured damping ratios."""
    objective = TableObjective(table)
    rows = {}
    for record, sim in zip(table.records, objective.record_features(spec)):
        rows[record.whisker] = {"f1_measured_hz": record.frequencies_hz[0], "f1_model_hz": sim["f1_hz"],
                                "f1_error": sim["f1_hz"] / record.frequencies_hz[0] - 1,
                                "zeta1_measured": record.damping_ratio, "zeta1_model": sim["zeta1"]}
    measured = [r["zeta1_measured"] for r in rows.values() if np.isfinite(r["zeta1_measured"])]
    model = [r["zeta1_model"] for r in rows.values()]
    span = (min(measured), max(measured)) if measured else (np.nan, np.nan)
    return {"whiskers": rows, "median_abs_f1_error": float(np.median([abs(r["f1_error"]) for r in rows.values()])),
            "zeta1_measured_range": span, "zeta1_model": (min(model), max(model)),
            "zeta1_inside": bool(measured) and span[0] <= min(model) and max(model) <= span[1]}


def calibrate_sets(tables, names=("E", "zeta"), material: MaterialConfig | None = None,
                   hold_out: bool = True, extensions=()) -> dict:
    """Fit ``names`` jointly to ``tables`` (records in ``HELD_OUT`` kept out when ``hold_out``);
    ``extensions``: model extensions present at their given values (fixed unless named)."""
    material = material or MaterialConfig()
    fitted, held = split_held_out(tables) if hold_out else (combine(tables), None)
    with single_threaded_blas():
        objective = TableObjective(fitted)
        sd, assumed = log_sd_with_defaults(objective)
        start = matched_start(objective, ModelSpec(material, tuple(extensions)), names=names)
        result = fit(objective, start, tuple(names), sigma=sd, max_iterations=MAX_ITERATIONS)
        sets = _per_set(objective, result.spec, sd)
        chi2 = float(np.sum(result.residuals ** 2))
        dof = result.residuals.size - len(names)
        birge = float(np.sqrt(chi2 / dof)) if dof > 0 else float("nan")
        params = result.params()
        if birge > 1:
            for p in params.values():
                p["sd"] *= birge
        for table in tables:
            name = table.path.stem if table.path else "table"
            if name in sets:
                sets[name]["conditions"] = table.conditions
        out = {"params": params, "error": result.error, "metric": result.metric, "chi2": chi2,
               "values": int(result.residuals.size), "birge_ratio": birge,
               "evaluations": result.evaluations, "sets": sets,
               "fitted_records": [r.whisker for r in fitted.records],
               "damping_model": material.damping_model, "links": material.links,
               "notes": result.notes + ([f"standard deviations assumed where missing: {assumed}"] if assumed else [])
               + ([f"parameter SDs scaled by the Birge ratio √(χ²/dof) = {birge:.2f}: the sets scatter "
                   "more than their stated (or assumed) SDs"] if birge > 1 else [])}
        if held is not None:
            out["held_out"] = held_out_errors(held, result.spec)
    return out


def _fit_chi2(tables, names, material: MaterialConfig) -> tuple[float, int, dict]:
    """(χ², number of values, fitted parameters) of ``names`` fitted to ``tables`` combined."""
    objective = TableObjective(combine(tables))
    sd, _ = log_sd_with_defaults(objective)
    start = matched_start(objective, ModelSpec(material), names=names)
    result = fit(objective, start, tuple(names), sigma=sd, max_iterations=MAX_ITERATIONS)
    return float(np.sum(result.residuals ** 2)), int(result.residuals.size), result.params()


def condition_splits(tables, names=("E", "zeta"), material: MaterialConfig | None = None) -> list[dict]:
    """For every condition that differs between the sets: χ² of one shared model against
    ``names`` fitted separately per value of that condition (all records, none held out), and
    ΔBIC = Δχ² − Δp·ln m (negative: the split is worth its extra parameters). Conditions that
    split the sets alike share their fits."""
    material = material or MaterialConfig()
    fits: dict[tuple, tuple[float, int, dict]] = {}

    def chi2_of(group) -> tuple[float, int, dict]:
        key = tuple(id(t) for t in group)
        if key not in fits:
            fits[key] = _fit_chi2(group, names, material)
        return fits[key]

    out = []
    with single_threaded_blas():
        shared, m, _ = chi2_of(tables)
        for key in CONDITIONS:
            groups: dict[str, list] = {}
            for table in tables:
                groups.setdefault(table.conditions[key], []).append(table)
            if len(groups) < 2:
                continue
            split_fits = {value: chi2_of(group) for value, group in groups.items()}
            split = sum(f[0] for f in split_fits.values())
            extra = len(names) * (len(groups) - 1)
            out.append({"condition": key, "chi2_shared": shared, "chi2_split": split,
                        "gain": (shared - split) / shared if shared > 0 else 0.0,
                        "delta_bic": split - shared + extra * np.log(m),
                        "params": {value: f[2] for value, f in split_fits.items()}})
    return sorted(out, key=lambda item: item["delta_bic"])
