"""Step size per whisker: MuJoCo's folded step (h·K·v in the joint damping) rings at the f1 its
update matrix predicts, and a whisker whose damping cannot carry the fold keeps the linearly
implicit step."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.stepping import damped_first_mode, damping_folds, scheme_f1_error
from pipeline.model.array import build_array, single_whisker
from pipeline.model.kinematics import Pose
from pipeline.model.morphology import load_morphology
from pipeline.scenes import empty
from pipeline.signals.resonance import pulse_drive
from pipeline.signals.ringdown import spectral_peak

RATE_HZ = 10_000.0
DURATION_S = 0.4
RING_START_S = 0.133          # 5 ms after the pulse stops


def _ra4():
    material = MaterialConfig(base_segment=False)     # a rigid base: the chain the step plan analyses
    return build_array(load_morphology("model_rat").select("RA4"), material).whiskers[0], material


def _compiled_world(engine):
    """The engine's first world after a short trial (a world compiles its model for a trial)."""
    engine.run(empty(), Pose(), pulse_drive(duration_s=0.002), 0.002)
    return engine.worlds[0][1]


def test_folded_step_rings_at_the_f1_its_update_matrix_predicts():
    """RA4 (14 mm, f1 150 Hz) at 10⁻⁴ s: predicted −0.60 % folded, −1.03 % linearly implicit."""
    whisker, material = _ra4()
    physics = whisker.physics
    folded, implicit = (scheme_f1_error(physics, 1e-4, folded=f) for f in (True, False))
    assert implicit - folded < -0.003          # the two schemes are told apart by the test
    config = ModelConfig(material=material, engine=EngineConfig(name="mujoco", dt_s=1e-4, f1_tolerance=0.0,
                                                                output_rate_hz=RATE_HZ))
    with create_engine(config, single_whisker(physics.chain.geometry, material)) as engine:
        out = engine.run(empty(), Pose(), pulse_drive(duration_s=DURATION_S), DURATION_S)
    tip_y = out.node_positions_m[out.time_s > RING_START_S, 0, -1, 1].astype(float)
    measured = spectral_peak(tip_y, RATE_HZ)[0] / (damped_first_mode(physics).imag / (2 * np.pi)) - 1
    assert measured == pytest.approx(folded, abs=5e-4)       # measured −0.60 %


def test_a_whisker_without_enough_damping_keeps_the_spring_correction():
    """c ≥ h·k/4 decides: the default Kelvin–Voigt damping folds at 10⁻⁴ s, an undamped chain
    does not, and the MuJoCo world then applies h·K·v to its joints instead."""
    whisker, material = _ra4()
    assert damping_folds(whisker, 1e-4)
    undamped = MaterialConfig(damping_ratio=0.0)
    array = single_whisker(whisker.chain.geometry, undamped)
    assert not damping_folds(array.whiskers[0], 1e-4)
    config = ModelConfig(material=undamped, engine=EngineConfig(name="mujoco", dt_s=1e-4, f1_tolerance=0.0))
    with create_engine(config, array) as engine:
        world = _compiled_world(engine)
        springs = world.model.jnt_dofadr[world.model.jnt_stiffness > 0]
        assert np.allclose(world.spring_rate[springs], 1e-4 * world.model.jnt_stiffness[world.model.jnt_stiffness > 0])
        assert np.all(world.model.dof_damping[springs] >= 0)
    config = ModelConfig(material=material, engine=EngineConfig(name="mujoco", dt_s=1e-4, f1_tolerance=0.0))
    with create_engine(config, single_whisker(whisker.chain.geometry, material)) as engine:
        world = _compiled_world(engine)
        assert not world.spring_rate.any()
