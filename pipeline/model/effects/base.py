"""An effect: a small composable change of the paper's whisker, with its parameters (SI units).

Each effect is one frozen dataclass with its parameters (units and bounds in ``PARAMETERS``),
its equation in the docstring, and up to five hooks, applied by
:func:`pipeline.model.physics.build_physics` in this order, effect by effect in ascending
``order`` (stable):

1. ``material(MaterialConfig) -> MaterialConfig``   switches of the base model
2. ``geometry(WhiskerGeometry) -> WhiskerGeometry``  shape before discretisation
3. ``chain(WhiskerChain) -> WhiskerChain``           masses and stiffnesses (before damping)
4. ``damping(WhiskerChain) -> WhiskerChain``         joint damping (after the damping model)
5. ``physics(WhiskerPhysics) -> WhiskerPhysics``     what is not a chain joint: follicle, twist,
                                                     loads (:mod:`.loads`)

Hooks 1–4 produce an ordinary :class:`~pipeline.model.whisker.WhiskerChain`; hook 5 fills
:class:`~pipeline.model.physics.WhiskerPhysics`, whose joints (:mod:`pipeline.model.joints`)
and loads every engine builds and applies the same way. ``implied_by`` names the effect a
material config switches on by itself (its follicle, gravity, base segment), and
``base_stiffness_nm_per_rad`` a spring at the base point that the damping model must see.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

from pipeline.config.material import MaterialConfig
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics


@dataclass(frozen=True)
class Parameter:
    """One fitted quantity: name, unit, neutral value (the effect off or nominal), bounds."""

    name: str
    unit: str
    neutral: float
    lower: float
    upper: float
    log: bool
    description: str


class Effect:
    """Base class: every hook is the identity; subclasses override the ones they need.

    ``name``: the key configs and model files use (:mod:`.registry`); ``order``: where its hooks
    run among the effects (ascending; ties keep the given order)."""

    name: ClassVar[str] = ""
    order: ClassVar[int] = 0
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = ()

    def values(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def implied_by(cls, material: MaterialConfig) -> "Effect | None":
        """The effect ``material`` switches on by itself, if any."""
        return None

    def material(self, material: MaterialConfig) -> MaterialConfig:
        return material

    def geometry(self, geometry: WhiskerGeometry) -> WhiskerGeometry:
        return geometry

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        return chain

    def base_stiffness_nm_per_rad(self, chain: WhiskerChain) -> float | None:
        """k (N·m/rad) of a spring this effect puts at the base point as part of the whisker
        (the damping model's first mode includes it), or None."""
        return None

    def damping(self, chain: WhiskerChain) -> WhiskerChain:
        return chain

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return physics
