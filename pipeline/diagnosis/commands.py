"""One library function per command (``pipeline calibrate``, ``diagnose``, ``synth``): load the
inputs, run, and return (JSON-ready result, human-readable lines; synth: its summary alone).
The lines leave out the fitted parameters (the result's ``params``: value, sd, unit), which
the CLI shows as a table. Non-finite numbers become ``null`` in the JSON-ready result."""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path

from pipeline.diagnosis import saved_model
from pipeline.diagnosis.calibrate import calibrate, modal_summary
from pipeline.diagnosis.damping_evidence import c1_modes_hz, damping_law_evidence
from pipeline.diagnosis.diagnose import diagnose
from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fitting import engine_check
from pipeline.diagnosis.joint import calibrate_sets, condition_splits
from pipeline.diagnosis.objective import TableObjective, TrajectoryObjective
from pipeline.diagnosis.parameters import ModelSpec, parse_names
from pipeline.diagnosis.report import write_report, write_table_report
from pipeline.diagnosis.statics import static_vs_dynamic
from pipeline.diagnosis.synth import load_synth_config, synth
from pipeline.diagnosis.table_diagnosis import diagnose_table
from pipeline.diagnosis.threads import single_threaded_blas
from pipeline.errors import UserError
from pipeline.measurements import ResonanceTable, load_measurement
from pipeline.measurements.library import load_library
from pipeline.measurements.statics import static_records
from pipeline.measurements.table import CONDITIONS, combine


def _jsonable(value):
    """``value`` with numpy scalars as Python numbers and NaN/inf as None, recursively."""
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if hasattr(value, "item"):
        value = value.item()
    return None if isinstance(value, float) and not math.isfinite(value) else value


def run_calibrate(path: Path, names: str, method: str, objective: str, material, engine, bootstrap: int,
                  grid_points, save_model: Path | None = None) -> tuple[dict, list[str]]:
    measurement = load_measurement(path)
    if bootstrap and isinstance(measurement, ResonanceTable):
        raise UserError(f"--bootstrap {bootstrap}: refits over the trials of a time series (.h5); "
                        f"{path} is a resonance table, which has none")
    result = calibrate(measurement, parse_names(names), method, objective, material, engine,
                       bootstrap, grid_points)
    lines = [f"{path}: {result['metric']} = {result['error']:.4g} ({method}, {result['evaluations']} simulations)"]
    lines += [f"  mode 1 of {w}: {m['f1_hz']:.2f} Hz, ζ1 = {m['zeta1']:.4f}" for w, m in result["modes"].items()]
    if "engine" in result:
        e = result["engine"]
        lines.append(f"  {e['name']}: " + (e["error"] if "error" in e else
                                           f"{result['metric']} {e['error_before']:.4g} → {e['error_after']:.4g}"))
    lines += [f"  note: {n}" for n in result["notes"]]
    if save_model is not None:
        spec = _fitted_spec(material, result["params"])
        whisker, modes = next(iter(result["modes"].items()))
        summary = {"method": "calibrate", "metric": result["metric"], "error": result["error"],
                   "whisker": whisker, **modes}
        result["model_file"] = str(saved_model.save_model(save_model, spec, result["params"], [path], summary))
        lines.append(f"  model: {result['model_file']}")
    return _jsonable(result), lines


def _fitted_spec(material, params: dict) -> ModelSpec:
    """The model of ``material`` with the fitted ``params`` ({name: {value, sd, unit}})."""
    return ModelSpec(material).with_values({n: p["value"] for n, p in params.items()})


def parse_where(where: str | None) -> dict[str, str]:
    """The conditions of ``--where`` ('key=value;...', docs/measurements.md); UserError naming a
    term that is not one."""
    wanted = {}
    for item in filter(None, (part.strip() for part in (where or "").split(";"))):
        key, _, value = (x.strip() for x in item.partition("="))
        if key not in CONDITIONS or value not in CONDITIONS[key]:
            raise UserError(f"--where '{item}': not a condition (known: "
                            + "; ".join(f"{k}={'|'.join(v)}" for k, v in CONDITIONS.items()) + ")")
        wanted[key] = value
    return wanted


def _tables(paths, library: bool, where: str | None) -> list:
    """Resonance tables of ``paths`` plus the shipped library's, kept when they match ``where``
    ('key=value;...', conditions of docs/measurements.md)."""
    tables = [load_measurement(p) for p in paths] + (load_library() if library else [])
    for table, path in zip(tables, paths):
        if not isinstance(table, ResonanceTable):
            raise UserError(f"{path}: a joint fit takes resonance tables (.csv) only")
    wanted = parse_where(where)
    chosen = [t for t in tables if all(t.conditions[k] == v for k, v in wanted.items())]
    if not chosen:
        raise UserError(f"no measurement set matches --where '{where}'")
    return chosen


def run_calibrate_sets(paths, library: bool, where: str | None, hold_out: bool, names: str,
                       material, save_model: Path | None = None) -> tuple[dict, list[str]]:
    tables = _tables(paths, library, where)
    result = calibrate_sets(tables, parse_names(names), material, hold_out)
    lines = [f"joint fit of {result['values']} values ({len(result['fitted_records'])} whiskers): "
             f"{result['metric']} = {result['error']:.4g}, χ² = {result['chi2']:.1f}; "
             f"{material.damping_model} damping, {material.links} links"]
    lines.append(f"  {'set':<36} {'conditions':<58} {'MSA':>6} {'χ²/n':>7}")
    for name, s in result["sets"].items():
        c = s["conditions"]
        text = ", ".join(f"{k}={c[k]}" for k in ("trimmed", "base", "excitation", "preparation", "damping"))
        lines.append(f"  {name:<36} {text:<58} {s['msa']:>6.3f} {s['chi2_per_value']:>7.2f}")
    if "held_out" in result:
        h = result["held_out"]
        lines.append(f"  held out (not fitted): median |f1 error| {100 * h['median_abs_f1_error']:.1f} %; ζ1 model "
                     f"{h['zeta1_model'][0]:.3f}-{h['zeta1_model'][1]:.3f} vs measured "
                     f"{h['zeta1_measured_range'][0]:.2f}-{h['zeta1_measured_range'][1]:.2f}")
        lines += [f"    {w}: f1 {r['f1_model_hz']:.1f} Hz vs {r['f1_measured_hz']:.1f} Hz ({100 * r['f1_error']:+.1f} %), "
                  f"ζ1 {r['zeta1_model']:.3f} vs {r['zeta1_measured']:.2f}" for w, r in h["whiskers"].items()]
    lines += [f"  note: {n}" for n in result["notes"]]
    if library:
        _with_statics(result, lines, result["params"]["E"], f"the joint fit of {', '.join(result['sets'])}",
                      material)
        _with_damping_laws(result, lines, material)
    if save_model is not None:
        result["model_file"] = str(_save_joint_fit(save_model, result, tables, material))
        lines.append(f"  model: {result['model_file']}")
    return _jsonable(result), lines


def _save_joint_fit(out: Path, result: dict, tables, material) -> Path:
    """A joint fit's model (the material's law, its fitted parameters) to ``out``; its fit summary
    names the first fitted whisker and that whisker's first in-plane mode under the fit."""
    spec = _fitted_spec(material, result["params"])
    record = next(r for r in combine(tables).records if r.whisker == result["fitted_records"][0])
    summary = {"method": "calibrate", "metric": result["metric"], "error": result["error"],
               "whisker": record.whisker, **modal_summary(spec, record.geometry)}
    return saved_model.save_model(out, spec, result["params"], [t.path for t in tables], summary)


def _with_damping_laws(data: dict, lines: list[str], material) -> None:
    """Add which damping law the library supports (:func:`~.damping_evidence.damping_law_evidence`)."""
    evidence = damping_law_evidence(material)
    data["damping_laws"] = evidence
    lines.append(f"  damping law (untrimmed whiskers; C1 measured {' / '.join(f'{f:.0f}' for f in c1_modes_hz())} Hz):")
    for law, row in evidence["laws"].items():
        c1 = row["c1"]
        modes = " / ".join("overdamped" if not math.isfinite(f) else f"{f:.0f} Hz ζ {z:.3f}"
                           for f, z in zip(c1["f_hz"], c1["zeta"]))
        lines.append(f"    {law:<13} E {row['E_pa'] / 1e9:.2f} GPa, parameter {row['parameter']:.3f}, held-out error "
                     f"{row['held_out_error']:.3f}; C1 {modes}; multi-mode {'yes' if c1['multi_mode_consistent'] else 'no'}, "
                     f"f within 15 % {'yes' if c1['f_within_15pct'] else 'no'}, ζ1 in 0.11-0.17 "
                     f"{'yes' if c1['zeta1_in_range'] else 'no'}")
    tie = f" (tied on held-out error with {', '.join(evidence['tied'][1:])})" if len(evidence["tied"]) > 1 else ""
    engines = "" if evidence["engines_have_it"] else "; the engines have eq. 3, Kelvin–Voigt and Rayleigh only"
    lines.append(f"    the evidence picks: {evidence['picked']}{tie}{engines}")


def _with_statics(data: dict, lines: list[str], dynamic_e: dict, label: str, material) -> None:
    """Add the quasi-static measurements' E against the dynamic ``dynamic_e`` ({'value', 'sd'}, Pa)
    of the fit named by ``label`` (:func:`pipeline.diagnosis.statics.static_vs_dynamic`)."""
    s = static_vs_dynamic(static_records(), ModelSpec(material), dynamic_e["value"], dynamic_e["sd"])
    data["static"] = {**s, "dynamic_fit": label}
    lines.append("  quasi-static measurements (linear chain statics; E per source):")
    lines += [f"    {name:<20} {src['whisker']:<30} E {src['E_pa'] / 1e9:.2f} GPa"
              + (f" ± {src['sd_pa'] / 1e9:.2f}" if math.isfinite(src["sd_pa"]) else "")
              for name, src in s["sources"].items()]
    verdict = "one model explains both" if s["one_model_explains_both"] else "no single E explains both"
    lines.append(f"    static E {s['static_E_pa'] / 1e9:.2f} ± {s['static_se_pa'] / 1e9:.2f} GPa vs dynamic "
                 f"{s['dynamic_E_pa'] / 1e9:.2f} ± {s['dynamic_sd_pa'] / 1e9:.2f} GPa ({label}): z {s['z']:+.2f}, "
                 f"{verdict} (the resonances fix E/ρ: the static E fits them with the density × "
                 f"{s['density_factor']:.2f})")


def _candidates_need_a_series(candidates: str, what) -> UserError:
    return UserError(f"--candidates {candidates}: chooses the extensions fitted to a time series (.h5); "
                     f"{what} holds resonance tables, which are diagnosed without them")


def run_diagnose(path: Path | None, material, report: Path | None, engine: str | None,
                 candidates: str | None = None, library: bool = False,
                 save_model: Path | None = None) -> tuple[dict, list[str]]:
    if candidates and library:
        raise _candidates_need_a_series(candidates, "the library")
    if library:
        if save_model is not None:
            raise UserError("--save-model saves the diagnosis of one measurement FILE, not of the library")
        tables = _tables([], True, None)
        with single_threaded_blas():
            data, lines, _ = _diagnose_table(combine(tables), material, report, engine)
        return _with_condition_splits(data, lines, tables, material)
    measurement = load_measurement(path)
    with single_threaded_blas():
        if isinstance(measurement, ResonanceTable):
            if candidates:
                raise _candidates_need_a_series(candidates, path)
            data, lines, result = _diagnose_table(measurement, material, report, engine)
            geometry, whisker = measurement.records[0].geometry, measurement.records[0].whisker
        else:
            chosen = [c.strip() for c in candidates.split(",") if c.strip()] if candidates else None
            data, lines, result = _diagnose_series(measurement, material, report, engine, chosen)
            geometry, whisker = measurement.geometry, measurement.whisker
    if save_model is not None:
        data["model_file"] = str(_save_diagnosis(save_model, result, path, geometry, whisker))
        lines.append(f"  model: {data['model_file']}")
    return data, lines


def _save_diagnosis(out: Path, result, path: Path, geometry, whisker: str) -> Path:
    """The diagnosis' final model (baseline refit plus the named extension, if any) to ``out``."""
    final = result.final
    summary = {"method": "diagnose", "cause": "+".join(getattr(result, "causes", None) or [result.cause]),
               "metric": final.metric, "error": final.error,
               "whisker": whisker, **modal_summary(final.spec, geometry)}
    return saved_model.save_model(out, final.spec, final.params(), [path], summary)


def _with_condition_splits(data: dict, lines: list[str], tables, material) -> tuple[dict, list[str]]:
    """Add what a uniform model gets wrong across sets: for each condition that differs between
    them, the χ² gain of fitting E and the damping separately per value of that condition."""
    splits = condition_splits(tables, material=material)
    data["condition_splits"] = [{k: v for k, v in s.items()} for s in splits]
    lines.append("  across sets (E and damping fitted per value of a condition, all whiskers):")
    for s in splits:
        values = ", ".join(f"{value}: E {p['E']['value'] / 1e9:.2f} GPa, θ_ζ {p['zeta']['value']:.3f}"
                           for value, p in s["params"].items())
        lines.append(f"    {s['condition']:<12} χ² {s['chi2_shared']:.1f} → {s['chi2_split']:.1f} "
                     f"(gain {100 * s['gain']:.0f} %, ΔBIC {s['delta_bic']:+.1f}); {values}")
    untrimmed = next((s["params"]["no"] for s in splits if s["condition"] == "trimmed"), None)
    if untrimmed is not None:
        _with_statics(data, lines, untrimmed["E"], "the untrimmed sets (trimmed=no)", material)
    else:
        _with_statics(data, lines, data["params"]["E"], "the final model", material)
    _with_damping_laws(data, lines, material)
    return _jsonable(data), lines


def _diagnose_series(measurement, material, report, engine, candidates) -> tuple[dict, list[str], object]:
    result = diagnose(measurement, material, candidates)
    data = result.as_dict()
    lines = [f"{measurement.path}: cause = {' + '.join(result.causes) or result.cause}",
             f"  held-out RMS {result.baseline_heldout * 1e3:.4f} mm (baseline) → {result.gain_after * 1e3:.4f} mm; "
             f"noise {result.noise_m * 1e3:.4f} mm, model-error floor {result.floor_m * 1e3:.4f} mm"]
    lines.append("  candidate             held-out (mm)  explained  ΔBIC      z")
    lines += [f"  {c.name:<20} {c.heldout_error * 1e3:>12.4f} {c.score:>10.2f} {c.bic_delta:>7.0f} {c.z:>6.1f}"
              for c in result.candidates]
    lines += [f"  note: {n}" for n in result.notes]
    if engine:
        _check_on_engine(data, lines, result.final, partial(TrajectoryObjective, measurement), engine)
    if report is not None:
        lines.append(f"  report: {write_report(report, measurement, result)}")
    return _jsonable(data), lines, result


def _diagnose_table(table, material, report, engine) -> tuple[dict, list[str], object]:
    result = diagnose_table(table, material)
    data = result.as_dict()
    lines = [f"{table.path or 'measurement library'}: cause = {result.cause}", f"  {result.summary}"]
    lines += [f"  {i['name']}.{i['param'].split('.')[-1]}: {i['verdict']}" for i in result.identifiability]
    lines += [f"  note: {n}" for n in result.notes]
    if engine:
        _check_on_engine(data, lines, result.final, partial(TableObjective, table), engine)
    if report is not None:
        lines.append(f"  report: {write_table_report(report, table, result)}")
    return _jsonable(data), lines, result


def _check_on_engine(data: dict, lines: list[str], model, objective, engine: str) -> None:
    """Score the final model with the fast simulator and with `engine`; `objective(simulator=None)`."""
    data["engine"] = engine_check(model, objective(), objective(EngineSimulator(engine)), engine)
    lines.append(f"  engine check: {data['engine']}")


def run_synth(config: Path, out: Path, seed: int | None, model_file: str | None = None) -> dict:
    """The summary of the synthetic measurement written to ``out`` (:func:`~.synth.synth`)."""
    settings = load_synth_config(config, {"seed": seed, "model_file": model_file})
    with single_threaded_blas():
        return synth(settings, out)
