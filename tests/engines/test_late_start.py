"""Late start of whiskers that can touch (``engine.late_start``, pipeline/engines/late_start.py):
a whisker that meets a peg mid-whisk, started on the full engine a little before its first
possible contact from its free path's state (the coarse run's or the linear chain's), touches
when and as hard as when run from t = 0."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.late_start import LATE_START_LEAD_S
from pipeline.model.array import build_array
from pipeline.model.kinematics import sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import empty
from test_free_path import PEG_RADIUS_M, POSE, _placed_at_clearance

DURATION_S = 0.06
PEAK_TOLERANCE = 0.03     # relative; measured 1.4 % from the coarse run, 0.03 % from the linear chain (RC1, 12 Hz)


def _engine(free_whiskers: str, late_start: bool):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=free_whiskers, late_start=late_start))
    return create_engine(config, build_array(model_rat().select("RC1"), config.material))


def test_drive_shifted_is_the_same_motion_seen_later():
    drive = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S)
    times = np.linspace(0.0, 0.03, 7)
    np.testing.assert_allclose(drive.shifted(0.02)(times), drive(times + 0.02), atol=1e-12)
    np.testing.assert_allclose(drive.shifted(0.02)(times, 1), drive(times + 0.02, 1), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("free_whiskers", ["coarse", "extrapolated", "linear"])
def test_a_late_start_touches_at_the_same_sample_with_the_same_peak(free_whiskers):
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    with _engine(free_whiskers, False) as cheap:
        free = cheap.run(empty(), POSE, drive, DURATION_S)
    scene = _placed_at_clearance(free.node_positions_m.astype(float)[:, 0], free.time_s, -2 * PEG_RADIUS_M)
    with _engine(free_whiskers, False) as full, _engine(free_whiskers, True) as late:
        reference, started = (e.run(scene, POSE, drive, DURATION_S) for e in (full, late))
    start = started.metadata["late_start_samples"]["RC1"]
    onset = np.flatnonzero(reference.contact.any(axis=-1)[:, 0])[0]
    period = float(reference.time_s[1] - reference.time_s[0])
    assert 0 < start <= onset - LATE_START_LEAD_S / period          # started late, before contact
    assert np.flatnonzero(started.contact.any(axis=-1)[:, 0])[0] == onset
    for part in (slice(0, 3), slice(3, 6)):
        peak, late_peak = (np.linalg.norm(out.base_wrench.astype(float)[:, 0, part], axis=-1).max()
                           for out in (reference, started))
        assert abs(late_peak - peak) <= PEAK_TOLERANCE * peak
    np.testing.assert_array_equal(started.base_wrench[:start], free.base_wrench[:start])   # the free path's
