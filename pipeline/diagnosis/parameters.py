"""Fit parameters and the model they define.

A :class:`ModelSpec` is the base material (:class:`~pipeline.config.physics.MaterialConfig`:
discretisation, damping model, E, ζ, density) plus a tuple of model extensions. Parameters
are named ``E`` (Young's modulus, Pa), ``zeta`` (the damping parameter θ_ζ of the material's
damping model) and ``<extension>.<parameter>`` (e.g. ``follicle.k_f``); a
:class:`ParameterSpace` maps their values to the unbounded-scale vector an optimiser sees
(log for positive scale parameters).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.errors import UserError
from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.effects.registry import EFFECTS
from pipeline.model.physics import build_physics

BASELINE = (
    Parameter("E", "Pa", 7.45e9, 0.2e9, 20e9, True, "Young's modulus θ_E (eq. 2 on the link length)"),
    Parameter("zeta", "1", 0.118, 1e-3, 2.0, True, "damping parameter θ_ζ of the damping model (eq. 3)"),
)
BASELINE_NAMES = tuple(p.name for p in BASELINE)


def all_parameters() -> dict[str, Parameter]:
    table = {p.name: p for p in BASELINE}
    for ext_name, cls in EFFECTS.items():
        for p in cls.PARAMETERS:
            table[f"{ext_name}.{p.name}"] = p
    return table


PARAMETERS = all_parameters()


def parameter(name: str) -> Parameter:
    if name not in PARAMETERS:
        raise UserError(f"unknown parameter '{name}' (known: {', '.join(PARAMETERS)})")
    return PARAMETERS[name]


def parse_names(text: str) -> tuple[str, ...]:
    """'E,zeta,follicle.k_f' → validated names, in order, without repeats."""
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    if not names:
        raise UserError("--params needs at least one parameter name")
    for name in names:
        parameter(name)
    return names


@dataclass(frozen=True)
class ModelSpec:
    """Base material plus extensions: everything that defines one whisker model."""

    material: MaterialConfig
    extensions: tuple[Effect, ...] = ()

    def extension(self, name: str) -> Effect | None:
        return next((e for e in self.extensions if e.name == name), None)

    def with_values(self, values: dict[str, float]) -> "ModelSpec":
        """The spec with the named parameters set (an extension is added if absent)."""
        material, extensions = self.material, list(self.extensions)
        update = {}
        if "E" in values:
            update["youngs_modulus_gpa"] = float(values["E"]) / 1e9
        if "zeta" in values:
            update["damping_ratio"] = float(values["zeta"])
        if update:
            material = material.model_copy(update=update)
        grouped: dict[str, dict[str, float]] = {}
        for name, value in values.items():
            if "." in name:
                ext, field = name.split(".", 1)
                grouped.setdefault(ext, {})[field] = float(value)
        for ext, fields in grouped.items():
            current = next((e for e in extensions if e.name == ext), None)
            if current is None:
                extensions.append(EFFECTS[ext](**fields))
            else:
                extensions[extensions.index(current)] = replace(current, **fields)
        return ModelSpec(material, tuple(extensions))

    def values(self) -> dict[str, float]:
        result = {"E": self.material.youngs_modulus_gpa * 1e9, "zeta": self.material.damping_ratio}
        for ext in self.extensions:
            result.update({f"{ext.name}.{k}": v for k, v in ext.values().items()})
        return result

    def physics(self, geometry):
        return build_physics(geometry, self.material, self.extensions)


class ParameterSpace:
    """Named parameters ↔ optimiser vector x of order one: x = ln(value/neutral) for ``log``
    parameters, x = value otherwise; with bounds."""

    def __init__(self, names):
        self.names = tuple(names)
        self.specs = [parameter(n) for n in self.names]

    def _x(self, p: Parameter, value: float) -> float:
        return float(np.log(value / p.neutral)) if p.log else float(value)

    def to_x(self, values: dict[str, float]) -> np.ndarray:
        return np.array([self._x(p, float(np.clip(values[n], p.lower, p.upper)))
                         for n, p in zip(self.names, self.specs)])

    def to_values(self, x: np.ndarray) -> dict[str, float]:
        return {n: float(p.neutral * np.exp(xi) if p.log else xi) for n, p, xi in zip(self.names, self.specs, x)}

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([self._x(p, p.lower) for p in self.specs]),
                np.array([self._x(p, p.upper) for p in self.specs]))

    def value_sd(self, x: np.ndarray, x_sd: np.ndarray) -> dict[str, float]:
        """Standard deviations of the values from those of x (delta method for the logs)."""
        values = self.to_values(x)
        return {n: float(values[n] * s if p.log else s) for n, p, s in zip(self.names, self.specs, x_sd)}

    def units(self) -> dict[str, str]:
        return {n: p.unit for n, p in zip(self.names, self.specs)}
