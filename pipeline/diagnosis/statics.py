"""What E the quasi-static measurements imply, and whether the dynamic fit's E explains them.

Model: the linear chain's statics (:func:`~pipeline.engines.linear.chain.linearise`: K q = Jᵀ F),
i.e. the same discretised whisker (joint springs, base segment, follicle) that the resonance
fit uses, so the comparison is between one model's two readings. Not the large-deflection
elastica (pipeline.references.elastica): the measured quantity is an initial slope (Solomon &
Hartmann 2006: the base moment rate at first touch, dM/dt = C·ω/d), where deflections are
small and the linear statics is exact to first order.

A whisker rotated by θ about its base against a peg at arc distance d (straight whisker, peg
normal to it in the plane) is pushed by δ = θ·d there, so the peg force is δ/c(d) with c the
chain's compliance at d, and the base moment is M = d²·θ/c(d). The source fitted C of a
cylinder (M = C·θ/d) to M over its distances by least squares; the model's moments are fitted
the same way, and E scales C: E = E_model·C_measured/C_model. Sources that printed an E fitted
with their own beam model are taken as printed (sd: a printed range read as uniform).
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.engines.linear.chain import linearise
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.measurements.statics import StaticRecord
from pipeline.model.whisker import WhiskerGeometry

# Solomon & Hartmann's 45 mm whisker: the tip diameter is not reported; the untrimmed D-row
# whiskers of the library have 4-10 µm tips (Belli et al. 2017, Table 3).
ASSUMED_TIP_DIAMETER_M = 5e-6
STATIC_LINKS = 80     # links of the chain in the statics: C of a cylinder within 0.4 % of 3·E·I at 5-35 mm
AGREEMENT_Z = 2.0      # |E_static − E_dynamic| within this many combined sd: one model explains both


def peg_moment_stiffness(spec: ModelSpec, geometry: WhiskerGeometry, distances_m) -> np.ndarray:
    """Base moment per base rotation M/θ (N·m/rad) of the whisker pushed by a peg at each arc
    distance (m), from the linear chain's statics (with at least :data:`STATIC_LINKS` links: a peg
    a few links from the base sees the chain's discretisation, 9 % in C at 5 mm with 20 links)."""
    material = spec.material.model_copy(update={"links": max(spec.material.links, STATIC_LINKS)})
    whisker = linearise(ModelSpec(material, spec.extensions).physics(geometry))
    fractions = np.asarray(distances_m, float) / geometry.arc_length_m
    links, _ = whisker.locate(fractions)
    points = whisker.rest_points(fractions)
    normal = np.array([0.0, 1.0, 0.0])
    jac = np.einsum("a,pan->pn", normal, whisker.jacobian(points, links))         # [P, n]
    compliance = np.einsum("pn,pn->p", jac, np.linalg.solve(whisker.stiffness, jac.T).T)
    return np.asarray(distances_m, float) ** 2 / compliance


def cylinder_fit(distances_m, moment_stiffness) -> float:
    """Least-squares C (N·m²) of M/θ = C/d over the distances (the source's Eqn S5 fit)."""
    inverse = 1.0 / np.asarray(distances_m, float)
    return float(np.sum(inverse * moment_stiffness) / np.sum(inverse ** 2))


def record_youngs_modulus(record: StaticRecord, spec: ModelSpec,
                          tip_diameter_m: float = ASSUMED_TIP_DIAMETER_M) -> tuple[float, float]:
    """(E, sd) in Pa that ``record`` implies; sd NaN when the source gives no spread."""
    if record.quantity == "E_Pa":
        spread = (record.high - record.low) / math.sqrt(12) if math.isfinite(record.low) else math.nan
        return record.value, spread
    tip = record.tip_diameter_m if math.isfinite(record.tip_diameter_m) else tip_diameter_m
    geometry = WhiskerGeometry(record.arc_length_m, record.base_diameter_m / 2, tip / 2)
    model_c = cylinder_fit(record.peg_distances_m, peg_moment_stiffness(spec, geometry, record.peg_distances_m))
    return spec.values()["E"] * record.value / model_c, math.nan


def static_vs_dynamic(records: list[StaticRecord], spec: ModelSpec, dynamic_e_pa: float,
                      dynamic_sd_pa: float) -> dict:
    """Per source the E it implies; their mean with its standard error (the scatter between
    sources, which are different whiskers and methods); and the z of static against dynamic E.
    Resonances fix E/ρ, so ``density_factor`` is the factor on the model's density under which
    the static E would also give the measured resonances."""
    sources = {}
    for record in records:
        value, sd = record_youngs_modulus(record, spec)
        sources[record.source] = {"whisker": record.whisker, "quantity": record.quantity, "E_pa": value,
                                  "sd_pa": sd}
    values = np.array([s["E_pa"] for s in sources.values()])
    mean = float(np.mean(values))
    standard_error = float(np.std(values, ddof=1) / math.sqrt(len(values))) if len(values) > 1 else math.nan
    z = (mean - dynamic_e_pa) / math.hypot(standard_error, dynamic_sd_pa)
    return {"sources": sources, "static_E_pa": mean, "static_se_pa": standard_error,
            "dynamic_E_pa": dynamic_e_pa, "dynamic_sd_pa": dynamic_sd_pa, "z": z,
            "one_model_explains_both": bool(abs(z) <= AGREEMENT_Z), "density_factor": mean / dynamic_e_pa,
            "assumed_tip_diameter_m": ASSUMED_TIP_DIAMETER_M}
