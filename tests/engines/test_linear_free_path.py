"""The linear chain as the free-whisker path (pipeline/engines/linear/free.py): its base wrench
and node paths match the full engine's on whiskers that bend little, a whisker that bends more
keeps the engine, and the chain's wrench is Newton–Euler of its own motion."""

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid
from scipy.linalg import expm
from threadpoolctl import threadpool_limits

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.linear.chain import linearise
from pipeline.engines.linear.free import (LINEAR_PATH_MARGIN_M, MAX_BEND, bend, free_response, running_integral,
                                         whisker_frames)
from pipeline.engines.linear.modal import _state_matrix, discretise, modal
from pipeline.engines.linear.rotating import com_hessian, rotating_matrices
from pipeline.engines.linear.wrench import _hessian, _second
from pipeline.model.array import build_array
from pipeline.model.effects.registry import model_parts
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import empty

DURATION_S = 0.06
POSE = Pose((0.001, -0.002, 0.0005), (0.3, 0.1, -0.05))


def _engine(whiskers: str, free_whiskers: str, extensions=None):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=free_whiskers), extensions=extensions or {})
    return create_engine(config, build_array(model_rat().select(whiskers), *model_parts(config)))


def _relative_errors(cheap: np.ndarray, full: np.ndarray) -> np.ndarray:
    """[W, 6] RMS difference over the RMS force (force components) or moment (moment components)."""
    error = np.sqrt(((cheap - full) ** 2).mean(axis=0))
    magnitude = [np.sqrt((full[..., part] ** 2).sum(-1).mean(0)) for part in (slice(0, 3), slice(3, 6))]
    return error / np.repeat(np.stack(magnitude, axis=1), 3, axis=1)


def test_linear_path_matches_the_engine_within_one_percent():
    """A long whisker bending 5 % of its length (RA1 at 9 Hz, f₁/f ≈ 3.9: the rotating base's
    loads matter), a middle one and a short one (RC2, RD6); benchmarks/bench_free_whiskers.py
    measures the whole array."""
    drive = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S)
    with _engine("RA1,RC2,RD6", "engine") as full, _engine("RA1,RC2,RD6", "linear") as cheap:
        reference, linear = (e.run(empty(), POSE, drive, DURATION_S) for e in (full, cheap))
    assert linear.metadata["coarse_free_whiskers"] == ["RA1", "RC2", "RD6"]
    assert linear.metadata["whisker_steps"] == 0
    errors = _relative_errors(linear.base_wrench.astype(float), reference.base_wrench.astype(float))
    assert errors.max() < 0.01, errors
    assert not linear.contact.any() and np.isnan(linear.point_of_contact).all()
    assert np.abs(linear.node_positions_m - reference.node_positions_m).max() < 0.2 * LINEAR_PATH_MARGIN_M


def test_linear_path_carries_mass_proportional_damping_into_the_wrench():
    """With Rayleigh damping (``mass_damping`` α = 300/s) the links' damping forces enter the
    base wrench as they do in the engine (without them RA1 was 28 % off)."""
    drive = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S)
    extensions = {"mass_damping": {"alpha": 300.0}}
    with _engine("RA1,RC2", "engine", extensions) as full, _engine("RA1,RC2", "linear", extensions) as cheap:
        reference, linear = (e.run(empty(), POSE, drive, DURATION_S) for e in (full, cheap))
    assert linear.metadata["coarse_free_whiskers"] == ["RA1", "RC2"]
    errors = _relative_errors(linear.base_wrench.astype(float), reference.base_wrench.astype(float))
    assert errors.max() < 0.01, errors


def test_a_whisker_that_bends_much_keeps_the_engine():
    """RA0 at 12 Hz bends 0.34 of its length (the linear chain is 4.6 % off there): the engine runs it."""
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    with _engine("RA0,RD6", "linear") as cheap:
        output = cheap.run(empty(), POSE, drive, DURATION_S)
        assert not cheap.free_path.linear[0] and cheap.free_path.linear[1]
    assert output.metadata["coarse_free_whiskers"] == ["RD6"]
    whisker = build_array(model_rat().select("RA0"), ModelConfig().material).whiskers[0]
    nodes = (output.node_positions_m[:, 0].astype(float) - POSE.position_m) @ POSE.rotation
    assert bend(whisker, drive, output.time_s, nodes) > MAX_BEND


@pytest.mark.parametrize("name", ["RA1", "RD6"])
def test_the_wrench_is_newton_euler_of_the_chains_own_motion(name):
    """The base force equals Σ m·a of the link centres of mass (second differences of the
    chain's own node paths at 10 kHz), rotated into the whisker frame."""
    whisker = build_array(model_rat().select(name), ModelConfig().material).whiskers[0]
    chain, h = whisker.chain, 1e-4
    drive = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S)
    samples = int(round(DURATION_S / h))
    wrench, nodes, _ = free_response(whisker, linearise(whisker.physics), drive.continued(DURATION_S, h), samples, h)
    times = np.arange(1, samples + 1) * h
    fraction = chain.link_com_m / chain.link_lengths_m
    com = nodes[:, :-1] + (nodes[:, 1:] - nodes[:, :-1]) * fraction[None, :, None]
    acceleration = (com[2:] - 2 * com[1:-1] + com[:-2]) / h ** 2
    head = np.einsum("l,tla->ta", chain.link_mass_kg, acceleration)
    force = np.einsum("tab,ta->tb", whisker_frames(whisker, drive(times[1:-1])), head)
    error = np.sqrt(((wrench[1:-1, :3] - force) ** 2).mean(0)) / np.sqrt((force ** 2).sum(1).mean())
    assert error.max() < 0.01, error


def test_the_cached_step_is_the_exact_exponential_per_whisker_and_step():
    """:func:`~pipeline.engines.linear.modal.discretise` (input columns scaled to unit size before
    the matrix exponential) against the exponential of the unscaled augmented matrix, per whisker
    and step; the cache on each chain keeps whiskers and steps apart, and a response from a warm
    cache (an earlier trial's drive) is the response from a cold one."""
    whiskers = build_array(model_rat().select("RA1,RD6"), ModelConfig().material).whiskers
    chains = [linearise(w.physics) for w in whiskers]
    columns, steps = tuple(range(12)), {}
    with threadpool_limits(limits=1, user_api="blas"):       # as the free path runs them: threads cost more
        for k, lin in enumerate(chains):
            mod = modal(lin)
            n = len(mod.omega)
            for h in (2.5e-4, 1e-3):
                phi, g0, g1, _ = steps[k, h] = discretise(lin, h, columns, False)
                aug = np.zeros((2 * n + 24,) * 2)
                aug[:2 * n, :2 * n], aug[n:2 * n, 2 * n:2 * n + 12] = _state_matrix(mod) * h, mod.inputs[:, :12] * h
                aug[2 * n:2 * n + 12, 2 * n + 12:] = np.eye(12)
                exact = expm(aug)
                for mine, theirs in ((phi, exact[:2 * n, :2 * n]), (g0 + g1, exact[:2 * n, 2 * n:2 * n + 12]),
                                     (g1, exact[:2 * n, 2 * n + 12:])):
                    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-8 * np.abs(theirs).max())
                assert discretise(lin, h, columns, False) is steps[k, h]
        assert not np.allclose(steps[0, 2.5e-4][0], steps[0, 1e-3][0])
        assert not np.allclose(steps[0, 2.5e-4][0], steps[1, 2.5e-4][0])
        drive, other = sinusoidal_whisk(9.0, 45.0, 20.0, DURATION_S), sinusoidal_whisk(6.0, 30.0, 10.0, DURATION_S)
        warm, cold = chains[0], linearise(whiskers[0].physics)
        free_response(whiskers[0], warm, other.continued(DURATION_S, 1e-3), 60, 1e-3)
        for a, b in zip(free_response(whiskers[0], warm, drive.continued(DURATION_S, 1e-3), 60, 1e-3)[:2],
                        free_response(whiskers[0], cold, drive.continued(DURATION_S, 1e-3), 60, 1e-3)[:2]):
            np.testing.assert_array_equal(a, b)


def test_running_integral_is_scipys_cumulative_trapezoid_to_the_bit():
    """The free path integrates the base's rate without importing scipy.integrate (≈ 15 MB per
    worker), to the same bits as scipy's cumulative_trapezoid (the outputs stay identical)."""
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(1e-5, 2e-5, 401))
    for shape in [(401,), (401, 3), (401, 2, 3)]:
        values = rng.normal(size=shape)
        assert np.array_equal(running_integral(values, times),
                              cumulative_trapezoid(values, times, axis=0, initial=0.0))


def test_a_chain_keeps_its_com_hessian_only_until_the_wrench_has_its_copy():
    """The rotating matrices' modal projection and the wrench's copy (the Hessian's entries i ≤ j
    of the joints that move each link, ≈ 1/6) are what a worker keeps of the centre-of-mass
    Hessian; the Hessian itself goes once the wrench has its copy, from which the wrench's
    matrix is rebuilt exactly."""
    whisker = build_array(model_rat().select("RA1"), *model_parts(ModelConfig())).whiskers[0]
    lin = linearise(whisker.physics)
    second = com_hessian(lin)
    rotating_matrices(lin)
    assert "com_hessian" in lin.cache                 # the wrench has not taken its copy yet
    transposed = _hessian(lin)
    assert "com_hessian" not in lin.cache and not np.shares_memory(transposed, second)    # a copy: second is freed
    original = np.transpose(second, (2, 0, 3, 1)).reshape(second.shape[2], -1)
    assert np.array_equal(transposed, original)
    assert lin.cache["wrench_hessian"].nbytes < 0.25 * transposed.nbytes
    assert np.array_equal(_hessian(lin), transposed)
    other = linearise(whisker.physics)                # a drive that needs the rotating matrices only later
    _hessian(other)
    assert "com_hessian" not in other.cache and "rotating" not in other.cache
    rng = np.random.default_rng(3)
    with threadpool_limits(limits=1, user_api="blas"):        # as the free path runs
        for t in (1, 7, 126, 251):                            # the wrench's terms: the full matrix's to the bit
            x, y = rng.normal(size=(2, t, lin.n))
            expected = np.einsum("tlai,ti->tla", (x @ original).reshape(t, -1, 3, lin.n), y)
            assert _second(_hessian(lin), x, y).tobytes() == expected.tobytes()
    for k, matrices in enumerate(rotating_matrices(other)):
        assert np.array_equal(matrices, rotating_matrices(lin)[k])
    assert "com_hessian" not in other.cache
