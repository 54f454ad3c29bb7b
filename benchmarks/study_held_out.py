"""Held-out f1 error of candidate model changes on the untrimmed D row (issue 14).

Every candidate is fitted on the fitted records only (D1, D3 of both Hartmann 2003 tables; D2
and D4 held out before any fit, ``pipeline.measurements.library.HELD_OUT``) and then predicts the
held-out f1. Candidates: the uniform model (E, ζ); the cone actually measured vs a cone run to a
point (tip diameter → the model's floor); uniform density instead of the defaults' rise toward the
tip weighed by Yang et al. 2019 (1.26 → 1.69 g/cm³); E rising toward the tip as in Quist et al. 2011's tensile tests
(2.90 → 3.96 GPa, fixed) and fitted; a compliant glue joint (follicle k_f fitted); a length
offset of the clamp. Then the whisker-to-whisker scatter: E matching each whisker alone, and the
f1 scatter the tensile tests' E spread implies.

Run: .venv/bin/python benchmarks/study_held_out.py   (≈ 1 min; docs/measurements.md §2b)
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from pipeline.config.material import MaterialConfig, with_preset
from pipeline.diagnosis.joint import calibrate_sets, held_out_errors
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.measurements.library import HELD_OUT, load_library, material_table
from pipeline.measurements.table import combine
from pipeline.model.effects.arc_length import MIN_TIP_RADIUS_M
from pipeline.model.effects.density_change import DensityChange
from pipeline.model.effects.stiffness_gradient import StiffnessGradient

DENSITY_GRADIENT = float(np.log(1.69 / 1.26))      # Yang et al. 2019: distal / proximal density
STIFFNESS_GRADIENT = float(np.log(3.96 / 2.90))    # Quist et al. 2011: tip / base segment E


def untrimmed_tables():
    return [t for t in load_library() if t.conditions["trimmed"] == "no"]


def pointed(tables):
    """The same whiskers with the tip diameter at the model's floor (a cone to a point)."""
    return [replace(t, records=tuple(replace(r, geometry=replace(r.geometry, tip_radius_m=MIN_TIP_RADIUS_M))
                                     for r in t.records)) for t in tables]


def run(label, tables, names=("E", "zeta"), extensions=(), material=None):
    start = time.process_time()
    result = calibrate_sets(tables, names, material or with_preset(MaterialConfig(), "untrimmed"),
                            extensions=extensions)
    held = result["held_out"]
    errors = " ".join(f"{w.replace('hartmann2003_Drow_', '')} {100 * r['f1_error']:+.1f}%"
                      for w, r in held["whiskers"].items())
    params = ", ".join(f"{k} {v['value']:.3g}" for k, v in result["params"].items())
    print(f"{label:<46} {params:<48} fit χ² {result['chi2']:7.1f}  held-out {errors}  "
          f"median |err| {100 * held['median_abs_f1_error']:.1f}%  ζ1 model {held['zeta1_model'][0]:.3f}-"
          f"{held['zeta1_model'][1]:.3f}  ({time.process_time() - start:.0f} s)",
          flush=True)
    return result


def per_whisker_e(tables, material):
    """E (GPa) that matches each record's f1 alone (f1 ∝ √E)."""
    out = {}
    for table in tables:
        for record in table.records:
            spec = ModelSpec(material)
            held = held_out_errors(combine([replace(table, records=(record,))]), spec)
            (row,) = held["whiskers"].values()
            ratio = row["f1_model_hz"] / record.frequencies_hz[0]
            out[f"{table.path.stem.split('_')[-1]}:{record.whisker}"] = material.youngs_modulus_gpa / ratio ** 2
    return out


def leave_one_out(tables, names, label):
    """Supplementary to the fixed D2/D4 hold-out: each D-row whisker held out in turn (both
    tables), the others fitted; the median |f1 error| over all held-out predictions."""
    errors = []
    for whisker in ("D1", "D2", "D3", "D4"):
        HELD_OUT.clear()
        HELD_OUT.update({t.path.stem: (whisker,) for t in tables})
        result = calibrate_sets(tables, names, with_preset(MaterialConfig(), "untrimmed"))
        errors += [r["f1_error"] for r in result["held_out"]["whiskers"].values()]
    print(f"leave-one-out, {label:<36} f1 errors " + " ".join(f"{100 * e:+.1f}%" for e in errors)
          + f"  median |err| {100 * np.median(np.abs(errors)):.1f}%", flush=True)


def main():
    tables = untrimmed_tables()
    material = with_preset(MaterialConfig(), "untrimmed")
    run("uniform E, ζ (the defaults' fit)", tables)
    run("cone to a point (tip diameter → 3 µm)", pointed(tables))
    run("uniform density (no Yang 2019 gradient)", tables,
        extensions=(DensityChange(gradient=-DENSITY_GRADIENT),))
    run("E gradient, Quist 2011 tip/base (fixed)", tables,
        extensions=(StiffnessGradient(gamma=STIFFNESS_GRADIENT),))
    run("E gradient fitted", tables, names=("E", "zeta", "stiffness_gradient.gamma"))
    run("compliant glue joint (follicle k_f fitted)", tables, names=("E", "zeta", "follicle.k_f"))
    run("clamp length (length.scale fitted)", tables, names=("E", "zeta", "length.scale"))
    fixed = dict(HELD_OUT)
    try:
        leave_one_out(tables, ("E", "zeta"), "uniform E, ζ")
        leave_one_out(pointed(tables), ("E", "zeta"), "cone to a point")
        leave_one_out(tables, ("E", "zeta", "follicle.k_f"), "with glue joint k_f")
    finally:                                   # the library's fixed hold-out again
        HELD_OUT.clear()
        HELD_OUT.update(fixed)
    e = per_whisker_e(tables, material)
    print("E matching each whisker alone (GPa):", ", ".join(f"{k} {v:.2f}" for k, v in e.items()))
    values = np.array(list(e.values()))
    spread = float(np.std(np.log(values), ddof=1))
    print(f"whisker-to-whisker SD of ln E: {spread:.3f} → f1 scatter ≈ {100 * spread / 2:.1f}% (f1 ∝ √E)")
    tensile = next(r for r in material_table() if r["whisker_or_region"] == "all segments")
    cv = tensile["sd"] / tensile["value"]
    print(f"tensile E {tensile['value']} ± {tensile['sd']} GPa (CV {100 * cv:.0f}%) → f1 scatter ≈ "
          f"{100 * cv / 2:.0f}%, median |f1 error| of a perfect mean model ≈ {100 * 0.674 * cv / 2:.0f}%")


if __name__ == "__main__":
    main()
