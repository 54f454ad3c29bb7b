"""Bullet's base wrench (pipeline/engines/bullet/wrench.py): on a free whisk its force equals
Σ m·a of the link centres of mass along Bullet's own node paths, rotated into the whisker frame."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.linear.free import whisker_frames
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import empty

pytest.importorskip("pybullet")

DURATION_S = 0.04
OUTPUT_HZ = 10_000.0


@pytest.mark.parametrize("name", ["RA0"])
def test_the_free_base_force_is_the_links_momentum_change(name):
    """RA0 at 12 Hz (its tip 0.34 of its length off the rigid shape: the axial, centripetal force
    matters: pybullet's joint sensor is 7 % off in Fx there, and a wrench one step late 0.9 % in Fy)."""
    config = ModelConfig(engine=EngineConfig(name="bullet", free_whiskers="engine", output_rate_hz=OUTPUT_HZ))
    whisker = build_array(model_rat().select(name), config.material).whiskers[0]
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    with create_engine(config, build_array(model_rat().select(name), config.material)) as engine:
        output = engine.run(empty(), Pose(), drive, DURATION_S)
    chain, h = whisker.chain, 1.0 / OUTPUT_HZ
    nodes = output.node_positions_m[:, 0].astype(float)
    fraction = chain.link_com_m / chain.link_lengths_m
    com = nodes[:, :-1] + (nodes[:, 1:] - nodes[:, :-1]) * fraction[None, :, None]
    acceleration = (com[2:] - 2 * com[1:-1] + com[:-2]) / h ** 2
    head = np.einsum("l,tla->ta", chain.link_mass_kg, acceleration)
    force = np.einsum("tab,ta->tb", whisker_frames(whisker, drive(output.time_s[1:-1])), head)
    wrench = output.base_wrench[1:-1, 0, :3].astype(float)
    error = np.sqrt(((wrench - force) ** 2).mean(0)) / np.sqrt((force ** 2).sum(1).mean())
    assert error.max() < 0.005, error
