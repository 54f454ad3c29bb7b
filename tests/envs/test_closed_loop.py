"""The closed-loop environment: gymnasium's checks, determinism, a forward-moving head reaching
the wall ahead, an episode rendered through rerun and written and read back as a dataset trial,
the example controller."""

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import pipeline.envs
from pipeline.envs import ENV_ID

REPO = Path(__file__).resolve().parents[2]
WHISKERS = "RC1,RD2"


def whisk_then_go(env, steps: int, speed: float):
    """Whisk both sides at 8 Hz, the head moving forward at ``speed`` (fraction of full); returns
    the observations' wrenches and contacts and the step of the first contact (None: none)."""
    env.reset(seed=3)
    wrenches, first = [], None
    for k in range(steps):
        phase = np.sin(2 * np.pi * 8.0 * k / 1000.0)
        observation, _, _, _, info = env.step({"whisk": np.array([phase, phase]),
                                               "head_velocity": np.array([speed, 0, 0, 0, 0, 0.0])})
        wrenches.append(observation["wrench"])
        if first is None and info["whiskers_in_contact"]:
            first = k
    return np.array(wrenches), first


@pytest.fixture(params=["mujoco", pytest.param("bullet", marks=pytest.mark.slow)], scope="module")
def env(request):
    environment = gym.make(ENV_ID, scene="wall", whiskers=WHISKERS, engine=request.param)
    yield environment
    environment.close()


@pytest.fixture(params=["mujoco", "bullet"], scope="module")
def any_engine_env(request):
    environment = gym.make(ENV_ID, scene="wall", whiskers=WHISKERS, engine=request.param)
    yield environment
    environment.close()


def test_gymnasium_check_env_passes():
    environment = gym.make(ENV_ID, scene="none", whiskers="RC1", max_steps=40)
    check_env(environment.unwrapped, skip_render_check=True)
    environment.close()


def test_moving_forward_reaches_the_wall_a_still_head_never_touches(env):
    """Bullet's variant is slow (the head's inertial load on every link, ≈ 30 s); MuJoCo's is fast."""
    _, still = whisk_then_go(env, 200, 0.0)
    _, forward = whisk_then_go(env, 200, 1.0)
    assert still is None
    assert forward is not None and forward < 200          # full forward speed: within 0.2 s


def test_the_same_seed_and_actions_give_bit_identical_episodes(any_engine_env):
    first, _ = whisk_then_go(any_engine_env, 15, 0.7)
    second, _ = whisk_then_go(any_engine_env, 15, 0.7)
    assert np.abs(first).max() > 0
    assert np.array_equal(first, second)


def test_a_closed_loop_episode_is_a_dataset_trial(tmp_path):
    import pipeline.datasets as datasets
    from pipeline.reports.stats import stats_report

    environment = gym.make(ENV_ID, scene="wall", whiskers=WHISKERS, engine="mujoco", render_mode="rerun",
                           recording=tmp_path / "episode.rrd")
    whisk_then_go(environment.unwrapped, 180, 1.0)
    environment.unwrapped.render()
    assert (tmp_path / "episode.rrd").stat().st_size > 0
    path = environment.unwrapped.record(tmp_path / "episode.h5")
    head = environment.unwrapped.episode_head()
    environment.close()
    with datasets.open_file(path) as ds:
        trial = ds.trial(0)
        assert trial["status"] == "ok" and trial["whiskers_in_contact"] >= 1
        stored = trial["head_position_m"]
        assert np.allclose(stored, head.table(ds.time_s)["head_position_m"], atol=1e-7)
        assert stored[-1, 1] > 0.012                                     # moved forward ≈ 14 mm
    report = stats_report(path, None, tmp_path / "stats")
    assert report


def test_example_controller_turns_toward_a_touch(tmp_path):
    result = subprocess.run([sys.executable, str(REPO / "examples" / "closed_loop_controller.py"), "--steps", "250",
                             "--whiskers", WHISKERS, "--out", str(tmp_path / "episode.h5")],
                            capture_output=True, text=True, cwd=REPO, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "first contact" in result.stdout and "turned" in result.stdout
    assert (tmp_path / "episode.h5").is_file()
