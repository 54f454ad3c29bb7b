"""Material configuration: whisker material, follicle, damping model, discretisation and the
named presets; and the base of every config model.

Lengths in configs follow their field names (``_mm``, ``_um``); everything is converted
to SI once, where the model is built.
"""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, model_validator


class StrictModel(BaseModel):
    """Base for config models: unknown fields and non-finite numbers (nan, inf) are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class FollicleConfig(StrictModel):
    """Follicle: ``rigid`` (paper default) or a torsional spring-damper about base y and z."""

    kind: Literal["rigid", "compliant"] = "rigid"
    # Defaults: the 'untrimmed' preset's follicle (see MATERIAL_PRESETS: k_f = 5e-7 ± a factor 2,
    # from Fig. 4's rigid/compliant ratio ≥ 5 and the original WHISKiT code's 1.25e-6; c_f for a
    # follicle damping ratio of 0.2 on RB1). The 'trimmed' preset keeps the former 1e-4 / 1e-7.
    stiffness_nm_per_rad: float = Field(5e-7, gt=0, le=1.0,
                                        description="k_f, N·m/rad (compliant only)")
    damping_nms_per_rad: float = Field(2.1e-9, ge=0, le=1e-2,
                                       description="c_f, N·m·s/rad (compliant only)")


# Named material presets (``material: {preset: NAME}`` in a config, ``--preset NAME`` on the CLI):
# the preset's values fill every material field the config does not set itself.
_UNTRIMMED = {"youngs_modulus_gpa": 3.59, "damping_ratio": 0.138, "damping_model": "kelvin_voigt",
              "link_density": "integrated", "base_segment": True,
              "follicle": {"stiffness_nm_per_rad": 5e-7, "damping_nms_per_rad": 2.1e-9}}
MATERIAL_PRESETS = {
    # the paper's two trimmed, motor-driven whiskers (α, B1; Table 1): E and θ_ζ of eq. 3 fitted on
    # the continuum chain at N = 20 (pipeline.diagnosis.material_fit: E = 7.91 GPa, θ_ζ = 0.134,
    # MSA 0.072), and the stiff follicle used with them
    "trimmed": {"youngs_modulus_gpa": 7.91, "damping_ratio": 0.134, "damping_model": "paper",
                "link_density": "integrated", "base_segment": True,
                "follicle": {"stiffness_nm_per_rad": 1e-4, "damping_nms_per_rad": 1e-7}},
    # untrimmed whiskers, isolated and glued at the base (Hartmann et al. 2003 D row, both methods):
    # joint fit of E and the Kelvin–Voigt ζ on the continuum chain (`pipeline calibrate --library
    # --where trimmed=no`, D2 and D4 held out): E = 3.59 ± 0.17 GPa (tensile tests: 3.34 ± 1.48,
    # Quist et al. 2011), ζ1 = 0.138 ± 0.062 (measured 0.11-0.17), the same at any N. Compliant follicle: k_f = 5e-7 N·m/rad, 0.4× the
    # original WHISKiT code's 1.25e-6 (the paper's in-vivo fit is unpublished) and 0.4× the RB1
    # whisker's own base stiffness E·I/S, the largest round value giving Fig. 4's rigid/compliant
    # base-force ratio ≥ 5; c_f for a follicle damping ratio 0.2 on RB1 (c_f = 2·0.2·√(k_f·J),
    # J = 5.7e-11 kg·m²). Uncertain to a factor ≈ 2: only that ratio constrains them.
    "untrimmed": _UNTRIMMED,
    # untrimmed whiskers under Rayleigh damping (pipeline.model.damping.RayleighDamping: ζ1 at modes 1
    # and 3), the law the measurement library supports (docs/measurements.md §10): the same joint fit
    # as 'untrimmed' (`pipeline calibrate --library --where trimmed=no --preset untrimmed_rayleigh`),
    # the same follicle
    "untrimmed_rayleigh": {**_UNTRIMMED, "damping_model": "rayleigh"},
    # the paper's own chain and fit, to reproduce the original and its published numbers: link 1
    # rigid with the follicle, each link's density at its proximal node, E = 7.45 GPa and
    # θ_ζ = 0.118 fitted on α/B1 with that chain (MSA 0.048)
    "paper": {"youngs_modulus_gpa": 7.45, "damping_ratio": 0.118, "damping_model": "paper",
              "link_density": "proximal", "base_segment": False,
              "follicle": {"stiffness_nm_per_rad": 1e-4, "damping_nms_per_rad": 1e-7}},
}


PresetName = Literal["trimmed", "untrimmed", "untrimmed_rayleigh", "paper"]     # the keys of MATERIAL_PRESETS


def _apply_preset(data):
    """Fill the material fields a config leaves unset from its named preset."""
    if not isinstance(data, dict) or data.get("preset") is None:
        return data
    name = data["preset"]
    if name not in MATERIAL_PRESETS:
        raise ValueError(f"unknown preset '{name}' (known: {', '.join(MATERIAL_PRESETS)})")
    preset = MATERIAL_PRESETS[name]
    merged = {**{k: v for k, v in preset.items() if k != "follicle"}, **data}
    follicle = data.get("follicle")
    follicle = follicle.model_dump() if isinstance(follicle, BaseModel) else dict(follicle or {})
    merged["follicle"] = {**preset["follicle"], **follicle}
    return merged


class MaterialConfig(StrictModel):
    """Material and discretisation of every whisker (docs/model.md §2)."""

    preset: Optional[PresetName] = Field(
        None, description="named defaults (MATERIAL_PRESETS) for the fields not set explicitly")

    # Defaults: the 'untrimmed' preset (MATERIAL_PRESETS), fitted on the measured untrimmed
    # whiskers the array has (Hartmann et al. 2003 D row, vibration table and pluck; D2, D4 held
    # out) with the continuum chain: E = 3.59 ± 0.17 GPa, Kelvin–Voigt damping with first-mode
    # ζ1 = 0.138 ± 0.062 at any N (measured 0.11-0.17). The paper's trimmed α and B1 are the 'trimmed' preset,
    # the paper's own chain and fit (E = 7.45 GPa, eq. 3 with θ_ζ = 0.118) the 'paper' preset.
    youngs_modulus_gpa: float = Field(3.59, gt=0.1, le=20.0, description="E, GPa")
    damping_ratio: float = Field(0.138, ge=0.0, le=2.0,
                                 description="θ_ζ of eq. 3 ('paper') or the first mode's ζ1 ('kelvin_voigt', 'rayleigh')")
    damping_model: Literal["paper", "kelvin_voigt", "rayleigh"] = Field(
        "kelvin_voigt", description="'paper': eq. 3 per joint (depends on N); "
                             "'kelvin_voigt': c_n = β·k_n with β set so mode 1 has ζ (converges in N); "
                             "'rayleigh': α·M + β·K with ζ at modes 1 and 3 (pipeline.model.damping)")
    density_base_kg_m3: float = Field(1260.0, gt=100, le=5000)
    density_tip_kg_m3: float = Field(1690.0, gt=100, le=5000)
    # The continuum corrections (docs/model.md §2): the chain converges to the continuous beam at
    # second order in N with both; the 'paper' preset switches both off (the paper's chain).
    link_density: Literal["proximal", "integrated"] = Field(
        "integrated", description="each link's density: the ramp at its proximal node ('proximal', the "
                                  "paper) or the ramp integrated across the link ('integrated')")
    base_segment: bool = Field(
        True, description="the bending compliance of the base half-link as a spring at the base point "
                          "(pipeline.model.effects.base_segment.BaseSegment); false: that arc is rigid (the paper)")
    links: int = Field(20, ge=2, le=120, description="N, links per whisker")
    gravity: bool = False
    follicle: FollicleConfig = FollicleConfig()

    _preset = model_validator(mode="before")(_apply_preset)


def with_preset(material: MaterialConfig, name: str) -> MaterialConfig:
    """``material`` with every field of preset ``name`` set from it (discretisation kept)."""
    values = MATERIAL_PRESETS[name]
    follicle = material.follicle.model_copy(update=values["follicle"])
    return material.model_copy(update={**{k: v for k, v in values.items() if k != "follicle"},
                                       "follicle": follicle, "preset": name})
