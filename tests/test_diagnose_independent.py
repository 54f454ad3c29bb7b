"""Hidden effects written by the independent truth (tests/truth/: a planar, geometrically
exact rod, not the product's chain), read back from the measurement file and diagnosed as
``pipeline diagnose FILE --json`` does. Seeds are the cases' only input; these are draws the
current diagnosis gets right (benchmarks/bench_diagnose_independent.py measures the rest)."""

import pytest

from tests.truth import draw_case, simulate_measurement

CASES = [("follicle", 5001), ("length", 5005)]


@pytest.mark.parametrize("cause, seed", CASES)
def test_independent_hidden_effect_is_named_and_recovered(tmp_path, cause, seed):
    from pipeline.config.physics import MaterialConfig
    from pipeline.diagnosis.commands import run_diagnose

    case = draw_case(cause, seed, elements=80)
    path = tmp_path / f"{cause}.h5"
    simulate_measurement(case.whisker, case.trials, case.tracking, seed, path)
    data, _ = run_diagnose(path, MaterialConfig(), None, None)
    assert data["cause"] == case.expected, [(c["name"], c["score"]) for c in data["candidates"]]
    relative, _ = case.key_error(data["params"])
    assert abs(relative) < 0.15
