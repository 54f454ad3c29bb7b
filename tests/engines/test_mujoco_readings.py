"""A MuJoCo world's samples converted at the end of its run (pipeline.engines.mujoco.readings)
against the same samples converted one at a time: the same numbers to the bit, and a sample whose
base moment is implausible is still converted, and its jam found, at once."""

import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.base import WorldResult
from pipeline.engines.common import MAX_PLAUSIBLE_MOMENT_NM
from pipeline.engines.mujoco import readings
from pipeline.engines.units import TORQUE
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import active_pegs

SELECTION = "RC1,RC2,RA4,LC1"          # RC1 meets its peg, the others whisk freely (compliant follicle)


def _run(monkeypatch, eager: bool):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers="engine"))
    init = readings.SampleReadings.__init__
    monkeypatch.setattr(readings.SampleReadings, "__init__",
                        lambda self, world, samples, **_: init(self, world, samples, eager=eager))
    drive = sinusoidal_whisk(duration_s=0.03)
    with create_engine(config, build_array(model_rat().select(SELECTION), config.material)) as engine:
        out = engine.run(active_pegs(lateral_m=0.025, y_m=-0.012), Pose(), drive, 0.03)
        world = next(w for _, w in engine.worlds if hasattr(w, "data"))
        return out, world


def test_samples_converted_at_the_end_are_those_converted_one_by_one(monkeypatch):
    at_end, _ = _run(monkeypatch, eager=False)
    one_by_one, _ = _run(monkeypatch, eager=True)
    assert at_end.contact.any() and np.abs(at_end.base_wrench).max() > 0
    for name in ("base_wrench", "node_positions_m", "contact", "point_of_contact"):
        assert np.array_equal(getattr(at_end, name), getattr(one_by_one, name), equal_nan=True), name


def test_a_sample_that_may_be_implausible_is_converted_at_once(monkeypatch):
    _, world = _run(monkeypatch, eager=False)
    d = world.data
    kept = readings.SampleReadings(world, 3, eager=False)
    result = WorldResult.zeros(3, len(world.members), world.links)
    d.sensordata[:] = 0.0
    assert not kept.read(d, 0)                                   # quiet: waits for the end
    d.sensordata[3:6] = [0.0, 0.4 * MAX_PLAUSIBLE_MOMENT_NM * TORQUE, 0.0]   # member 0's moment, below half
    assert not kept.read(d, 1)
    d.sensordata[3:6] = [0.0, 2.0 * MAX_PLAUSIBLE_MOMENT_NM * TORQUE, 0.0]
    assert kept.read(d, 2)
    sample, members = kept.convert(result, 3)
    assert sample == 2 and list(members) == [0]
    assert abs(np.linalg.norm(result.wrench[1, 0, 3:]) - 0.4 * MAX_PLAUSIBLE_MOMENT_NM) < 1e-6 * MAX_PLAUSIBLE_MOMENT_NM
    d.sensordata[3] = np.nan
    assert readings.SampleReadings(world, 1, eager=False).read(d, 0)     # not finite: at once too
