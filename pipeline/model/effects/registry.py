"""The effects by name (the ``extensions`` keys of configs and model files), and the effects a
model config describes."""

from __future__ import annotations

from pipeline.config.material import MaterialConfig
from pipeline.config.physics import ModelConfig
from pipeline.errors import UserError
from pipeline.model.effects.arc_length import ArcLength
from pipeline.model.effects.base import Effect
from pipeline.model.effects.base_segment import BaseSegment
from pipeline.model.effects.damping_gradient import DampingGradient
from pipeline.model.effects.density_change import DensityChange
from pipeline.model.effects.drag import AirDrag
from pipeline.model.effects.follicle import CompliantFollicle
from pipeline.model.effects.gravity import Gravity
from pipeline.model.effects.integrated_density import IntegratedDensity
from pipeline.model.effects.mass_damping import MassDamping
from pipeline.model.effects.stiffness_gradient import StiffnessGradient
from pipeline.model.effects.tip_segment import TipSegment
from pipeline.model.effects.twist import Twist

EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls for cls in (
        CompliantFollicle,
        StiffnessGradient,
        DampingGradient,
        DensityChange,
        ArcLength,
        AirDrag,
        Gravity,
        Twist,
        MassDamping,
        BaseSegment,
        TipSegment,
        IntegratedDensity,
    )
}


def make_effect(name: str, **values: float) -> Effect:
    """The effect called ``name`` with the given parameters (others at their defaults)."""
    if name not in EFFECTS:
        raise UserError(f"unknown model extension '{name}' (known: {', '.join(EFFECTS)})")
    cls = EFFECTS[name]
    known = {p.name for p in cls.PARAMETERS}
    unknown = set(values) - known
    if unknown:
        raise UserError(f"extension '{name}' has no parameter {', '.join(sorted(unknown))} "
                        f"(parameters: {', '.join(sorted(known))})")
    for p in cls.PARAMETERS:
        if p.name in values and not p.lower <= float(values[p.name]) <= p.upper:
            raise UserError(f"extension '{name}': {p.name} = {values[p.name]} {p.unit} is outside "
                            f"[{p.lower:g}, {p.upper:g}]")
    return cls(**{k: float(v) for k, v in values.items()})


def material_effects(material: MaterialConfig) -> tuple[Effect, ...]:
    """The effects ``material`` switches on by itself (its compliant follicle, gravity, base
    segment), in registry order."""
    return tuple(e for cls in EFFECTS.values() if (e := cls.implied_by(material)) is not None)


def _checked_units(loaded) -> None:
    """Every parameter of a model file in the unit its effect defines (one line otherwise)."""
    for name, params in loaded.content.extensions.items():
        units = {p.name: p.unit for p in EFFECTS[name].PARAMETERS} if name in EFFECTS else {}
        for field, entry in params.items():
            if field in units and entry.unit != units[field]:
                raise UserError(f"model file {loaded.path}: field 'extensions.{name}.{field}.unit' = "
                                f"'{entry.unit}': must be '{units[field]}'")


def effects_from(values: dict[str, dict[str, float]], where: str) -> tuple[Effect, ...]:
    """The effects ``{name: {parameter: value}}`` (in the order given); a bad name or value is
    one :class:`UserError` line naming ``where`` (the config or model file) and the field."""
    effects = []
    for name, params in values.items():
        try:
            effects.append(make_effect(name, **params))
        except UserError as exc:
            raise UserError(f"{where}: field 'extensions.{name}': {exc}") from None
    return tuple(effects)


def model_parts(config: ModelConfig) -> tuple[MaterialConfig, tuple[Effect, ...]]:
    """The material and the effects (in the order given) that ``config`` describes: its own,
    on top of those of its model file (``config.file``, merged when the config was loaded)."""
    loaded = config.model_file
    if loaded is not None:
        _checked_units(loaded)
    return config.material, effects_from(config.extensions,
                                         f"model file {loaded.path}" if loaded else "model config")
