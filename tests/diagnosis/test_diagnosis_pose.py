"""The head pose the diagnosis' engine simulator uses for a measurement's gravity direction."""

import numpy as np
import pytest

from pipeline.diagnosis.engine import _pose_for


@pytest.mark.parametrize("direction", [(0.0, 0.0, -1.0), (0.3, -0.5, -0.8), (1.0, 0.0, 0.0),
                                       (0.0, 0.2, 1.0), (0.0, 0.0, 1.0)])
def test_pose_turns_gravity_to_world_down(direction):
    d = np.asarray(direction) / np.linalg.norm(direction)
    pose, rotation = _pose_for(d)
    np.testing.assert_allclose(pose.rotation, rotation, atol=1e-12)      # Euler angles round-trip
    np.testing.assert_allclose(rotation @ d, [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    # the smallest such rotation: it turns by the angle between d and −z, no more
    angle = np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1))
    assert angle == pytest.approx(np.arccos(np.clip(-d[2], -1, 1)), abs=1e-9)
