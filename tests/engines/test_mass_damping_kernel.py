"""The compiled mass-proportional damping of both engines (pipeline/engines/mass_damping.py) against
the load's own per-link Python (MassDamping.link_forces, applied as any other load): a whisk of
one whisker gives the same base wrench and node positions to round-off (measured: bit for bit in the float32 outputs), and differs from the
whisk without the damping (so an engine that dropped it would fail)."""

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import ArrayModel, bench_whisker
from pipeline.model.effects.loads import Load
from pipeline.model.effects.mass_damping import MassDamping
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes import empty

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6, 10.0)
MATERIAL = MaterialConfig(damping_ratio=0.03)
DAMPING = MassDamping(300.0)                 # 1/s: ζ1 + ≈ 0.25 at f1 ≈ 95 Hz
DURATION_S = 0.02


@dataclass(frozen=True)
class PerLinkMassDamping(Load):
    """The same damping through the engines' generic per-link load path (not recognised as MassDamping)."""

    damping: MassDamping
    needs_velocity: ClassVar[bool] = True
    needs_base: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    def link_forces(self, chain, state):
        return self.damping.link_forces(chain, state)


def _whisk(engine: str, loads: tuple):
    physics = build_physics(ALPHA, MATERIAL)
    array = ArrayModel((bench_whisker(replace(physics, loads=loads), joint_rates=(1.0, 0.3, 0.0)),), MATERIAL, ())
    with create_engine(ModelConfig(material=MATERIAL, engine=EngineConfig(name=engine)), array) as simulator:
        out = simulator.run(empty(), Pose(), sinusoidal_whisk(frequency_hz=25.0, duration_s=DURATION_S), DURATION_S)
    return out.base_wrench.astype(float), out.node_positions_m.astype(float)


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_compiled_mass_damping_is_the_loads_own_per_link_forces(engine):
    wrench, nodes = _whisk(engine, (DAMPING,))
    reference_wrench, reference_nodes = _whisk(engine, (PerLinkMassDamping(DAMPING),))
    undamped_wrench, _ = _whisk(engine, ())
    scale = np.abs(reference_wrench).max(axis=(0, 1))
    effect = np.abs(undamped_wrench - reference_wrench).max(axis=(0, 1)) / scale
    assert effect.max() > 1e-2                                     # the damping matters here
    np.testing.assert_array_less(np.abs(wrench - reference_wrench).max(axis=(0, 1)) / scale, 1e-6)   # outputs are float32
    np.testing.assert_allclose(nodes, reference_nodes, rtol=0, atol=1e-8)
