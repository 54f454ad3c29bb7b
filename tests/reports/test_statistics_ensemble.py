"""The ensemble statistics of benchmarks/statistics_ensemble.py (issue 24) on synthetic per-pair
tables: the members' perturbations, spreads, the within-ensemble floor and the ensemble medians."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.config.physics import ModelConfig
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.protocols.whisking import Whisking
from pipeline.scenes import empty

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "statistics_ensemble.py"
_SPEC = importlib.util.spec_from_file_location("statistics_ensemble", _PATH)
ens = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(ens)

TRIALS, WHISKERS = 6, 5


def member(moment, transverse, touched=None, failed=None) -> dict[str, np.ndarray]:
    """One member's table [TRIALS, WHISKERS] as bench_statistics.run_variant returns it."""
    touched = np.ones((TRIALS, WHISKERS), bool) if touched is None else touched
    table = {"touched": touched, "failed": np.zeros(TRIALS, bool) if failed is None else failed,
             "peak_moment": np.where(touched, moment, np.nan), "peak_transverse": np.where(touched, transverse, np.nan)}
    return table | {f: np.zeros((TRIALS, WHISKERS), bool) for f in ens.PATH_FIELDS}


def ensemble(k: int, seed: int, scale: float = 0.0) -> list[dict[str, np.ndarray]]:
    """k members around one set of peaks, each member's peaks × (1 + scale·N(0, 1))."""
    rng = np.random.default_rng(seed)
    moment, transverse = rng.uniform(1.0, 2.0, (2, TRIALS, WHISKERS))
    return [member(moment * (1 + scale * rng.standard_normal(moment.shape)),
                   transverse * (1 + scale * rng.standard_normal(moment.shape))) for _ in range(k)]


def test_member_zero_is_the_pose_and_the_others_move_by_a_micrometre_and_a_microradian():
    pose = Pose((0.01, -0.02, 0.005), (0.7, -0.2, 0.3))
    assert ens.member_pose(pose, 0) is pose
    moved = [ens.member_pose(pose, m) for m in (1, 2, 3)]
    for other in moved:
        assert np.isclose(np.linalg.norm(np.subtract(other.position_m, pose.position_m)), 1e-6, rtol=1e-6)
        turn = Rotation.from_matrix(other.rotation @ pose.rotation.T).magnitude()
        assert np.isclose(turn, 1e-6, rtol=1e-4)
    directions = [np.subtract(p.position_m, pose.position_m) for p in moved]
    assert not np.allclose(directions[0], directions[1])          # each member its own direction
    assert ens.member_pose(pose, 2) == moved[1]                     # seeded by the member index
    ten = ens.member_pose(pose, 2, scale=10.0)
    assert np.allclose(np.subtract(ten.position_m, pose.position_m), 10 * directions[1], rtol=1e-6, atol=0)
    assert ens.member_pose(pose, 2, scale=0.0) is pose


def test_member_friction():
    assert ens.member_friction(0.5, 0) == 0.5
    assert np.isclose(ens.member_friction(0.5, 3), 0.5 * (1 + 3e-6), rtol=0, atol=1e-15)
    assert np.isclose(ens.member_friction(0.5, 3, scale=10.0), 0.5 * (1 + 3e-5), rtol=0, atol=1e-15)


def test_spread_is_the_range_and_the_mad_over_the_members_relative_to_their_median():
    values = [1.0, 1.1, 0.9, 1.3]
    table = [member(np.full((TRIALS, WHISKERS), v), np.ones((TRIALS, WHISKERS))) for v in values]
    rng, mad = ens.spread(table, "peak_moment")
    median = np.median(values)
    assert np.allclose(rng, (1.3 - 0.9) / median)
    assert np.allclose(mad, np.median(np.abs(np.subtract(values, median))) / median)
    assert np.allclose(ens.spread(table, "peak_transverse")[0], 0.0)


def test_usable_pairs_are_touched_by_every_member_on_trials_none_failed():
    a = ensemble(3, 0)
    a[1]["touched"] = a[1]["touched"].copy()
    a[1]["touched"][2, 3] = False
    a[2]["failed"] = np.eye(1, TRIALS, 4, dtype=bool)[0]
    mask = ens.usable(a)
    assert not mask[2, 3] and not mask[4].any()
    assert mask.sum() == TRIALS * WHISKERS - 1 - WHISKERS


def test_identical_ensembles_have_no_median_difference_and_the_floor_is_their_own_spread():
    base = ensemble(4, 1, scale=0.03)
    stats = ens.compare_ensembles(base, base)
    for field in ("peak_moment", "peak_transverse"):
        assert stats[f"{field}_median_step_median_abs_rel"] == 0.0 == stats[f"{field}_median_step_p90_abs_rel"]
        assert stats[f"{field}_literal_p90_abs_rel"] == 0.0
        assert stats[f"{field}_floor_base_p90_abs_rel"] == stats[f"{field}_floor_other_p90_abs_rel"] > 0.0


def test_the_floor_comes_from_members_of_one_step_only():
    """A base whose members agree has no floor, however far the variant's members lie from it or
    from each other; a variant that is the base × 1.3 has a 30 % step difference and the same floor."""
    quiet = ensemble(4, 2)
    noisy = [member(m["peak_moment"] * 1.3 * (1 + 0.2 * k), m["peak_transverse"] * 0.5) for k, m in enumerate(quiet)]
    stats = ens.compare_ensembles(quiet, noisy)
    assert stats["peak_moment_floor_base_p90_abs_rel"] == 0.0 == stats["peak_moment_split_floor_p90_abs_rel"]
    assert stats["peak_moment_floor_other_p90_abs_rel"] > 0.1
    scaled = [member(m["peak_moment"] * 1.3, m["peak_transverse"]) for m in quiet]
    stats = ens.compare_ensembles(quiet, scaled)
    assert np.isclose(stats["peak_moment_median_step_median_abs_rel"], 0.3)
    assert np.isclose(stats["peak_moment_literal_p90_abs_rel"], 0.3)
    assert stats["peak_transverse_median_step_p90_abs_rel"] == 0.0
    assert ens.within_floor(quiet, "peak_moment", ens.usable(quiet)).shape == (6, TRIALS * WHISKERS)


def test_pairs_whose_spread_exceeds_five_percent_are_listed_apart_from_the_stable_statistic():
    base = ensemble(4, 3)
    base[2]["peak_transverse"] = base[2]["peak_transverse"].copy()
    base[2]["peak_transverse"][1, 2] *= 1.5                 # one sensitive pair
    other = [member(m["peak_moment"], m["peak_transverse"] * 1.01) for m in base]
    other[0]["peak_transverse"][1, 2] *= 2.0                 # its literal difference is large
    stats = ens.compare_ensembles(base, other)
    assert stats["sensitive"] == [[1, 2]]
    assert stats["pairs_stable"] == TRIALS * WHISKERS - 1
    assert np.isclose(stats["peak_transverse_stable_p90_abs_rel"], 0.01)
    assert stats["peak_transverse_literal_p90_abs_rel"] >= 0.01


def test_halves_leave_the_middle_member_out_when_the_ensemble_is_odd():
    assert ens.halves([0, 1, 2, 3, 4]) == ([0, 1], [3, 4])
    assert ens.halves([0, 1, 2, 3]) == ([0, 1], [2, 3])


def test_paired_summary_of_known_differences():
    d = np.array([-0.3, 0.01, 0.02, -0.04, 0.06, 0.0, 0.1, -0.005, 0.03, 0.2])
    s = ens.paired_summary(d, "x_")
    assert np.isclose(s["x_median_abs_rel"], np.median(np.abs(d)))
    assert np.isclose(s["x_p90_abs_rel"], np.percentile(np.abs(d), 90))
    assert s["x_p90_low"] <= s["x_p90_abs_rel"] <= s["x_p90_high"]
    assert s["x_share_above_5pct"] == 0.4 and s["x_share_above_20pct"] == 0.1
    assert np.isnan(ens.paired_summary(np.array([]))["p90_abs_rel"])


def test_path_changes_flag_the_pairs_on_which_members_disagree():
    a = ensemble(3, 4)
    a[1]["refined"] = np.zeros((TRIALS, WHISKERS), bool)
    a[1]["refined"][0, 1] = True
    changes = ens.path_changes(a)
    assert changes["refined"].sum() == 1 and changes["refined"][0, 1]
    assert not changes["coarse"].any()


def test_separated_pairs_are_those_whose_ensembles_do_not_overlap():
    base = ensemble(4, 5, scale=0.01)
    other = [member(m["peak_moment"] * 1.2, m["peak_transverse"]) for m in base]     # |M| 20 % up
    assert ens.separated(base, other, "peak_moment").all()
    assert not ens.separated(base, other, "peak_transverse").any()            # the same values overlap
    stats = ens.compare_ensembles(base, other)
    assert stats["peak_moment_separated"] == TRIALS * WHISKERS == len(stats["peak_moment_separated_above_5pct"])
    assert stats["peak_transverse_separated"] == 0


def test_the_report_names_the_sensitive_pairs():
    base = ensemble(4, 6)
    base[1]["peak_moment"] = base[1]["peak_moment"] * np.where(np.arange(WHISKERS) == 4, 1.2, 1.0)
    table = base[0] | {"whisker": np.array([f"RC{k}" for k in range(WHISKERS)]),
                       "scene": np.array([f"mesh:rock{t}" for t in range(TRIALS)]),
                       "arc_length_m": np.linspace(0.01, 0.05, WHISKERS)}
    stats = ens.compare_ensembles(base, base)
    text = ens.ensemble_report("default", "half", stats, table, list(range(10, 10 + TRIALS)))
    assert stats["pairs_stable"] == TRIALS * (WHISKERS - 1)
    assert "    10 RC4 rock0 50.0 mm; 20.0 / 0.0 %" in text and "    11 RC3" not in text


@pytest.mark.slow
def test_a_member_s_pose_reaches_the_engine_and_its_paths_are_kept():
    """Member 1 of ``pose`` runs the engine at a head pose 1 µm away: every node of a whisker
    sweeping free moves by about that much (less than 1 µm + 1 µrad × 60 mm), member 0 by nothing."""
    drive, pose = sinusoidal_whisk(8.0, 30.0, 10.0, 0.02), Pose((0.001, 0.002, 0.0), (0.3, 0.1, -0.2))
    with Whisking(ModelConfig(whiskers="RC1,RC2")) as whisking:
        nodes = []
        for m in (0, 1):
            member_whisking = ens.MemberWhisking(whisking, m, pose_scale=1.0)
            nodes.append(member_whisking.run(empty(), pose, drive, 0.02).node_positions_m.astype(float))
            assert set(member_whisking.paths) == set(ens.PATH_FIELDS)
            assert all(flags.shape == (2,) for flags in member_whisking.paths.values())
        again = ens.MemberWhisking(whisking, 0, pose_scale=1.0).run(empty(), pose, drive, 0.02)
    moved = np.linalg.norm(nodes[1] - nodes[0], axis=-1)
    assert np.array_equal(again.node_positions_m, nodes[0].astype(np.float32))
    assert 0.5e-6 < np.median(moved) and moved.max() < 1.2e-6
