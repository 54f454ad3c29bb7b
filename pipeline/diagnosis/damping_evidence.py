"""Which damping law the measured whiskers support (``calibrate --library``; docs/measurements.md §10).

Per law of :mod:`pipeline.diagnosis.damping_laws`: E and the law's parameter are fitted to the
library's untrimmed whiskers (f1 and ζ1; the held-out whiskers of
:data:`pipeline.measurements.library.HELD_OUT` left out): E from the median (f1 measured/model)²
(f1 ∝ √E at a given ζ1), the parameter by the ratio of mean measured to mean model ζ1 (ζ1 is
linear in it), two passes. Then

- held-out error: RMS of ln(model/measured) of f1 and ζ1 on the held-out whiskers;
- multi-mode evidence, Hartmann et al. (2003) C1 (:func:`~pipeline.measurements.library.c1_modes`:
  its measured geometry, S 53 mm, D 220 / 6 µm, straight): three clear resonances at
  40 / 94 / 188 Hz whose peak magnification grew with mode number, so ζ2 and ζ3 do not exceed ζ1
  (a law is consistent when all three in-plane modes oscillate and ζ2, ζ3 ≤ ζ1, within
  :data:`ZETA_TIE`);
- the C1 check: f1–f3 within 15 % of the measured, ζ1 in the untrimmed whiskers'
  0.11–0.17.

The law picked: the lowest held-out error among the laws consistent with the multi-mode
evidence (all laws when none is); ``tied`` lists the laws whose held-out error is within
:data:`HELD_OUT_TIE` of it (first-mode data cannot separate laws that share ζ1: then the pick is
the first of them in :data:`~pipeline.diagnosis.damping_laws.LAWS` order, and the report says so),
with the model an engine runs for C1 under it (:func:`c1_engine_model`).
"""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.damping_laws import LAWS, in_plane_modes, with_law
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.measurements.library import c1_modes, load_library, split_held_out
from pipeline.model.whisker import WhiskerGeometry

C1_TOLERANCE = 0.15
ZETA1_RANGE = (0.11, 0.17)                      # untrimmed whiskers, both methods (library D-row tables)
EQ3_ZETA1_PER_THETA = 0.23                      # ζ1 ≈ 0.23·θ_ζ under eq. 3 (start of its fit only)
PASSES = 2
ZETA_TIE = 0.05          # relative: a ζ_n within 5 % of ζ1 does not exceed it (drag adds a little to each)
HELD_OUT_TIE = 0.01      # relative: held-out errors closer than this do not separate two laws
ENGINE_LAWS = ("eq3", "kelvin_voigt", "rayleigh")   # modal: the diagnosis' linear model only


def c1_geometry() -> WhiskerGeometry:
    return c1_modes().geometry


def c1_modes_hz() -> np.ndarray:
    return np.array(c1_modes().frequencies_hz)


def _first_modes(spec: ModelSpec, records, law: str) -> tuple[np.ndarray, np.ndarray]:
    rows = [in_plane_modes(with_law(spec, r.geometry, law), 1) for r in records]
    return np.array([f[0] for f, _ in rows]), np.array([z[0] for _, z in rows])


def fit_law(records, law: str, material: MaterialConfig) -> ModelSpec:
    """E and the law's parameter fitted to the records' f1 and ζ1 (module docstring)."""
    f_meas = np.array([r.frequencies_hz[0] for r in records])
    z_meas = np.array([r.damping_ratio for r in records])
    parameter = np.mean(z_meas) / (EQ3_ZETA1_PER_THETA if law == "eq3" else 1.0)
    spec = ModelSpec(material).with_values({"zeta": parameter})
    for _ in range(PASSES):
        f_mod, z_mod = _first_modes(spec, records, law)
        values = spec.values()
        spec = spec.with_values({"E": values["E"] * float(np.nanmedian((f_meas / f_mod) ** 2)),
                                 "zeta": values["zeta"] * float(np.mean(z_meas) / np.nanmean(z_mod))})
    return spec


def held_out_error(spec: ModelSpec, records, law: str) -> float:
    """RMS of ln(model/measured) over f1 and ζ1 of ``records`` (inf when a mode is overdamped)."""
    f_mod, z_mod = _first_modes(spec, records, law)
    f_meas = np.array([r.frequencies_hz[0] for r in records])
    z_meas = np.array([r.damping_ratio for r in records])
    logs = np.concatenate([np.log(f_mod / f_meas), np.log(z_mod / z_meas)])
    return float(np.sqrt(np.mean(logs ** 2))) if np.all(np.isfinite(logs)) else float("inf")


def c1_check(spec: ModelSpec, law: str) -> dict:
    """f1–f3 and ζ1–ζ3 of C1 under ``law``; the multi-mode consistency and the issue's check."""
    f, z = in_plane_modes(with_law(spec, c1_geometry(), law), 3)
    errors = f / c1_modes_hz() - 1
    consistent = bool(np.all(np.isfinite(z)) and max(z[1], z[2]) <= (1 + ZETA_TIE) * z[0])
    within = bool(np.all(np.abs(errors) <= C1_TOLERANCE)) if np.all(np.isfinite(f)) else False
    return {"f_hz": f.tolist(), "zeta": z.tolist(), "f_error": errors.tolist(), "multi_mode_consistent": consistent,
            "f_within_15pct": within, "zeta1_in_range": bool(ZETA1_RANGE[0] <= z[0] <= ZETA1_RANGE[1])}


def damping_law_evidence(material: MaterialConfig | None = None) -> dict:
    """Per law: fitted E and parameter, held-out error, C1 modes and checks; the law picked."""
    material = material or MaterialConfig()
    fitted, held = split_held_out([t for t in load_library() if t.conditions["trimmed"] == "no"])
    laws = {}
    for law in LAWS:
        spec = fit_law(fitted.records, law, material)
        values = spec.values()
        laws[law] = {"E_pa": values["E"], "parameter": values["zeta"],
                     "held_out_error": held_out_error(spec, held.records, law), "c1": c1_check(spec, law)}
    consistent = [law for law, row in laws.items() if row["c1"]["multi_mode_consistent"]]
    pool = consistent or list(laws)
    picked = min(pool, key=lambda law: laws[law]["held_out_error"])
    best = laws[picked]["held_out_error"]
    tied = [law for law in pool if laws[law]["held_out_error"] <= (1 + HELD_OUT_TIE) * best]
    return {"laws": laws, "picked": tied[0], "tied": tied, "consistent_with_multi_mode": consistent,
            "engines_have_it": tied[0] in ENGINE_LAWS, "c1_engine_model": c1_engine_model(laws[tied[0]], tied[0], material)}


def c1_engine_model(row: dict, law: str, material: MaterialConfig) -> dict | None:
    """The model an engine runs for C1 under ``law`` with ``row``'s fitted E and parameter
    (``resonance --modes 3``): material fields and extensions; None for a law the engines lack."""
    if law not in ENGINE_LAWS:
        return None
    return {"youngs_modulus_gpa": row["E_pa"] / 1e9, "damping_ratio": row["parameter"],
            "damping_model": {"eq3": "paper"}.get(law, law), "extensions": {}}
