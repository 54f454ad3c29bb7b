"""What an engine builds once and what it keeps: no MuJoCo model compiled before a trial needs it,
one compile per world and trial set-up, the base inertia and the trial's quasi-steady start shared
by an engine and its coarse free path (start-up and per-trial cost, issue 26)."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.mujoco.world import MujocoWorld
from pipeline.model.array import build_array
from pipeline.model.base_motion import BaseInertia
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import active_pegs, empty


@pytest.fixture()
def compiles(monkeypatch):
    """Counts MujocoWorld._build calls (spec building and compile) per world."""
    counts: dict[int, int] = {}
    build = MujocoWorld._build

    def counted(world, *args, **kwargs):
        counts[id(world)] = counts.get(id(world), 0) + 1
        return build(world, *args, **kwargs)

    monkeypatch.setattr(MujocoWorld, "_build", counted)
    return counts


def _engine(whiskers: str, free_whiskers: str = "engine"):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=free_whiskers))
    return create_engine(config, build_array(model_rat().select(whiskers), config.material))


def test_worlds_compile_on_first_use_and_once_per_set_up(compiles):
    drive = sinusoidal_whisk(duration_s=0.003)
    with _engine("RA0,RC5") as engine:                # two step sizes: two worlds
        assert len(engine.worlds) == 2
        assert compiles == {}                           # building the engine compiles nothing
        for _ in range(2):                              # the same set-up again: nothing recompiled
            engine.run(empty(), Pose(), drive, 0.003)
            assert sorted(compiles.values()) == [1, 1]
        engine.run(active_pegs(lateral_m=0.025, y_m=-0.012), Pose(), drive, 0.003)
        assert max(compiles.values()) == 2              # a new obstacle set: a new model


@pytest.mark.parametrize("path", ["coarse", "extrapolated"])
def test_a_world_no_whisker_needs_compiles_nothing(compiles, path):
    """With the coarse path every whisker of an empty scene is free: the full worlds stay unbuilt."""
    with _engine("RA0,RC5", free_whiskers=path) as engine:
        engine.run(empty(), Pose(), sinusoidal_whisk(duration_s=0.003), 0.003)
        full = {id(world) for _, world in engine.worlds}
        coarse = {id(world) for cheap in engine.free_path.engines for _, world in cheap.worlds}
        assert len(coarse) == len(engine.free_path.configs)
        assert not full & compiles.keys()
        assert coarse == compiles.keys() and set(compiles.values()) == {1}
        for cheap in engine.free_path.engines:
            assert all(mine is theirs for mine, theirs in zip(engine.inertia, cheap.inertia))


def test_quasi_steady_start_remembers_one_drive_by_identity():
    whisker = build_array(model_rat().select("RC1"), ModelConfig().material).whiskers[0]
    inertia = whisker.physics.base_inertia
    assert inertia is whisker.physics.base_inertia            # built once per whisker
    slow, fast = sinusoidal_whisk(frequency_hz=6.0), sinusoidal_whisk(frequency_hz=12.0)
    first = inertia.quasi_steady(whisker, slow)
    assert inertia.quasi_steady(whisker, slow) is first       # the same drive object: remembered
    fresh = BaseInertia.of(whisker.physics).quasi_steady(whisker, slow)
    assert all(np.array_equal(a, b) for a, b in zip(first, fresh))
    other = inertia.quasi_steady(whisker, fast)                 # another drive: computed, and kept
    assert not np.array_equal(other[0], first[0])
    assert inertia.quasi_steady(whisker, slow) is not first     # one entry only
    assert inertia.quasi_steady(whisker, fast, t_s=0.01) is not other   # keyed by the time too
    with pytest.raises(ValueError):
        first[0][0] = 1.0                                       # shared: read-only


def test_a_drive_state_is_its_derivatives_computed_once_per_time():
    """Every whisker's quasi-steady start asks the drive for θ and three derivatives at t = 0:
    the drive answers each time once, with the values its spline gives."""
    drive = sinusoidal_whisk(frequency_hz=9.0)
    for t_s in (0.0, 0.013):
        state = drive.state(t_s)
        assert state == tuple(float(drive(t_s, d)) for d in range(4))
        assert drive.state(t_s) is state
    assert drive.continued(0.1, 0.001).state(0.0) == drive.state(0.0)      # a copy computes its own
