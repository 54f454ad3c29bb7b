"""The set-up cache (pipeline/model/setup_cache.py): one entry per model and code, read back bit
for bit, written again when the model, the engine settings or the code change."""

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.model import setup_cache
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.protocols.whisking import Whisking
from pipeline.scenes import empty

WHISKERS = "RC1,LC1,RA3"          # twins share their physics; RA3 steps at a finer level on MuJoCo


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv(setup_cache.CACHE_ENV, str(tmp_path))
    return tmp_path


def entries(folder) -> list:
    return sorted(p.name for p in folder.glob("*.pickle"))


def counted(calls: list):
    def compute():
        calls.append(1)
        return {"value": np.arange(3.0)}
    return compute


def test_an_entry_is_computed_once_per_input_and_code(folder, monkeypatch):
    calls = []
    for _ in range(2):
        np.testing.assert_array_equal(setup_cache.cached("t", (1.0, "a"), counted(calls))["value"], np.arange(3.0))
    assert len(calls) == 1 and len(entries(folder)) == 1
    setup_cache.cached("t", (-0.0, "a"), counted(calls))       # equal as numbers, not as inputs
    setup_cache.cached("t", (1.0, "a"), counted(calls))
    assert len(calls) == 2
    monkeypatch.setattr(setup_cache, "code_digest", lambda: "other code")
    setup_cache.cached("t", (1.0, "a"), counted(calls))
    assert len(calls) == 3 and len(entries(folder)) == 3


def test_a_damaged_entry_is_computed_again_and_off_keeps_nothing(folder, monkeypatch, capsys):
    calls = []
    setup_cache.cached("t", 1, counted(calls))
    (path,) = folder.glob("*.pickle")
    path.write_bytes(b"not a pickle")
    assert setup_cache.cached("t", 1, counted(calls))["value"][2] == 2.0 and len(calls) == 2
    assert "unreadable" in capsys.readouterr().err
    monkeypatch.setenv(setup_cache.CACHE_ENV, "off")
    setup_cache.cached("u", 1, counted(calls))
    assert len(calls) == 3 and len(entries(folder)) == 1
    with pytest.raises(TypeError):
        setup_cache.canonical(object())


def outputs(config: ModelConfig):
    with Whisking(config, WHISKERS) as whisking:
        output = whisking.run(empty(), Pose(), sinusoidal_whisk(8.0, 40.0, 10.0, 0.004), 0.004)
        array, levels = whisking.array, whisking.engine.levels
    inertia = [w.physics.base_inertia for w in array.whiskers]
    return (levels, output.base_wrench, output.node_positions_m, *(getattr(i, f) for i in inertia
            for f in ("mass", "coupling", "centrifugal", "stiffness", "damping")),
            *(w.chain.link_mass_kg for w in array.whiskers))


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_a_cached_set_up_gives_bit_identical_trials_and_a_changed_model_a_new_entry(folder, monkeypatch, engine):
    config = ModelConfig.model_validate({"engine": {"name": engine}})
    monkeypatch.setenv(setup_cache.CACHE_ENV, "off")
    computed = outputs(config)
    monkeypatch.setenv(setup_cache.CACHE_ENV, str(folder))
    written, read = outputs(config), outputs(config)
    assert len(entries(folder)) == 1
    for a, b, c in zip(computed, written, read):
        assert a.tobytes() == b.tobytes() == c.tobytes()
    stiffer = config.model_copy(update={"material": config.material.model_copy(update={"youngs_modulus_gpa": 4.0})})
    changed = outputs(stiffer)
    assert len(entries(folder)) == 2 and changed[-1].tobytes() == computed[-1].tobytes()    # same masses
    assert not np.array_equal(changed[1], computed[1])
    finer = config.model_copy(update={"engine": config.engine.model_copy(update={"f1_tolerance": 0.001})})
    assert not np.array_equal(outputs(finer)[0], computed[0]) and len(entries(folder)) == 3
