"""Mirror twins (pipeline/engines/mirror.py): a left whisker's free motion is its right twin's
reflected, so the free paths compute one whisker of each pair."""

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (its BLAS loaded before the thread limit below, which covers loaded ones)
from threadpoolctl import threadpool_limits

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.linear.chain import linearise
from pipeline.engines.linear.free import free_response
from pipeline.engines.mirror import joint_signs, mirrored, twins
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import empty

DURATION_S = 0.04
POSE = Pose((0.001, -0.002, 0.0005), (0.3, 0.1, -0.05))


def test_every_left_whisker_of_the_model_rat_is_its_right_twin_reflected():
    array = build_array(model_rat(), MaterialConfig())
    source = twins(array.whiskers)
    pairs = {array.names[k]: array.names[s] for k, s in enumerate(source) if k != s}
    assert len(pairs) == len(array.whiskers) // 2 and all(k == "L" + s[1:] for k, s in pairs.items())
    other = build_array(model_rat().select("LC2"), MaterialConfig(youngs_modulus_gpa=4.0)).whiskers
    assert list(twins(array.whiskers[array.names.index("RC2"):][:1] + other)) == [0, 1]    # other physics


def test_a_reflected_twin_is_the_linear_chains_own_free_motion():
    right, left = build_array(model_rat().select("RA1,LA1"), MaterialConfig()).whiskers
    drive = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S).continued(DURATION_S, 1e-3)
    with threadpool_limits(limits=1, user_api="blas"):       # as the free path runs it: threads cost more
        (wrench, nodes, joints), (own_wrench, own_nodes, own_joints) = (
            free_response(w, linearise(w.physics), drive, 40, 1e-3) for w in (right, left))
    twin_wrench, twin_nodes = mirrored(wrench, nodes)
    np.testing.assert_allclose(twin_wrench, own_wrench, rtol=0, atol=1e-10 * np.abs(own_wrench).max())
    np.testing.assert_allclose(twin_nodes, own_nodes, rtol=0, atol=1e-12)
    for part, own in zip(joints, own_joints):
        np.testing.assert_allclose(joint_signs(left.physics.layout) * part, own, rtol=0, atol=1e-8 * np.abs(own).max())


@pytest.mark.parametrize("path", ["coarse", "extrapolated"])
def test_the_coarse_path_gives_a_twin_the_full_engines_free_motion(path):
    """LC2 from RC2's coarse run(s), reflected, against LC2 on the full step, at a turned head."""
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    engines = [create_engine(ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=choice)),
                             build_array(model_rat().select("RC2,LC2"), MaterialConfig())) for choice in ("engine", path)]
    with engines[0] as full, engines[1] as cheap:
        reference, coarse = (e.run(empty(), POSE, drive, DURATION_S) for e in (full, cheap))
        assert [len(engine.array.whiskers) for engine in cheap.free_path.engines] == [1] * len(cheap.free_path.configs)
    assert coarse.metadata["coarse_free_whiskers"] == ["RC2", "LC2"]
    a, b = coarse.base_wrench[:, 1].astype(float), reference.base_wrench[:, 1].astype(float)
    scale = np.repeat([np.sqrt((b[:, part] ** 2).sum(-1).mean()) for part in (slice(0, 3), slice(3, 6))], 3)
    assert (np.sqrt(((a - b) ** 2).mean(axis=0)) / scale).max() < 0.01
    assert np.abs(coarse.node_positions_m[:, 1] - reference.node_positions_m[:, 1]).max() < 1e-4
