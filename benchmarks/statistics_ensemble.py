"""Ensembles for benchmarks/bench_statistics.py: every variant run K times with perturbations far
below anything a user can specify or measure, the same K perturbations for every variant, and the
statistics that tell a pair's sensitivity to any perturbation apart from the effect of a variant
(the step halved, the other engine).

Perturbations (member 0 is always the unperturbed trial, so member 0 against member 0 is the
benchmark's literal statistic):

- ``pose``: the head pose of member m ≥ 1 is moved by ``POSE_SHIFT_M`` (1 µm) along a random
  direction and turned by ``POSE_TURN_RAD`` (1 µrad) about a random axis through the head origin
  (world frame), both drawn from ``numpy.random.default_rng([POSE_SEED, m])``. The scans' surface
  error is 0.42–0.58 mm and a tracked head's error is tens of µm or more, so no user can tell the
  members' poses apart; 1 µrad turns a 50 mm whisker's tip by 0.05 µm. The pose sampler still
  draws the trial's pose from the unperturbed stream; only the engine sees the moved pose.
- ``mu``: the whisker–object friction coefficient of member m is μ·(1 + m·``FRICTION_STEP``)
  (10⁻⁶: no friction coefficient is known to better than a few per cent).

A scale multiplies either (10: 10 µm and 10 µrad, or 10⁻⁵ of μ per member), to see whether the
members' spread grows with the perturbation.

Per (trial, whisker) pair touched in every member of the ensembles compared, of peak |M| and
peak |F_t|: the ensemble's relative spread (range / median and median absolute deviation / median
over the members); the paired |relative difference| between two members of the same step (the
within-ensemble floor); the |relative difference| of the two variants' ensemble medians and its
floor, the same difference between the two halves of one ensemble; whether the two variants'
ensembles do not overlap at all (a difference no member's perturbation explains).
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.model.kinematics import Pose
from pipeline.model.rotations import yaw_pitch_roll

POSE_SHIFT_M = 1e-6
POSE_TURN_RAD = 1e-6
POSE_SEED = 24
FRICTION_STEP = 1e-6
PERTURBATIONS = ("pose", "mu")
BOOTSTRAP_DRAWS = 2000      # resamplings of the pairs for the P90's 90 % interval
SENSITIVE = 0.05            # a pair whose ensemble spread of a peak exceeds this is listed apart
PATH_FIELDS = ("coarse", "refined", "at_rest")
PEAKS = ("peak_moment", "peak_transverse")


def member_pose(pose: Pose, member: int, scale: float = 1.0) -> Pose:
    """``pose`` moved by ``scale`` × ``POSE_SHIFT_M`` and turned by ``scale`` × ``POSE_TURN_RAD``
    about an axis through its origin, both directions random (seeded by ``member``); member 0 or
    scale 0: ``pose`` itself."""
    if member == 0 or scale == 0:
        return pose
    rng = np.random.default_rng([POSE_SEED, member])
    direction, axis = (v / np.linalg.norm(v) for v in rng.standard_normal((2, 3)))
    turned = Rotation.from_rotvec(scale * POSE_TURN_RAD * axis).as_matrix() @ pose.rotation
    return Pose(tuple(np.asarray(pose.position_m) + scale * POSE_SHIFT_M * direction), yaw_pitch_roll(turned))


def member_friction(mu: float, member: int, scale: float = 1.0) -> float:
    """The friction coefficient of ``member`` for a configured ``mu``: μ·(1 + member·scale·10⁻⁶)."""
    return mu * (1.0 + member * scale * FRICTION_STEP)


class MemberWhisking:
    """A :class:`~pipeline.protocols.whisking.Whisking` whose trials run at ``member``'s pose
    (``pose`` perturbation) and which keeps, of its last trial, each whisker's path: ``coarse``
    (the cheap free path), ``refined`` (taken again alone at a finer step after a jam),
    ``at_rest`` (started from rest: its quasi-steady shape would pass through the scene; asked of
    the engine's own start, ``Engine._drive_start``)."""

    def __init__(self, whisking, member: int, pose_scale: float):
        """``pose_scale``: :func:`member_pose`'s scale (0: the pose as given)."""
        self.whisking, self.member, self.pose_scale = whisking, member, pose_scale
        self.paths: dict[str, np.ndarray] = {}

    def run(self, scene, pose: Pose, drive, duration_s: float, head_motion=None):
        if head_motion is not None:
            raise ValueError("the ensembles need a still head (head_motion: none)")
        pose = member_pose(pose, self.member, self.pose_scale)
        output = self.whisking.run(scene, pose, drive, duration_s)
        names, meta = list(output.whisker_names), output.metadata
        angles, rates = self.whisking.engine._drive_start(scene, pose, drive)
        self.paths = {"coarse": np.isin(names, meta["coarse_free_whiskers"]),
                      "refined": np.isin(names, list(meta["jam_refined"])),
                      "at_rest": np.array([not (np.any(a) or np.any(r)) for a, r in zip(angles, rates)])}
        return output

    def __getattr__(self, name):
        return getattr(self.whisking, name)


def paired_summary(d: np.ndarray, prefix: str = "") -> dict[str, float]:
    """Median and P90 of |d| over pairs, the 5–95 % range of the P90 over the pairs resampled with
    replacement (seeded), the median signed d and the share of pairs with |d| > 5 % and > 20 %."""
    d = np.asarray(d, float)
    a = np.abs(d)
    if a.size == 0:
        a = d = np.full(1, np.nan)
    draws = np.random.default_rng(0).integers(0, a.size, (BOOTSTRAP_DRAWS, a.size))
    low, high = np.percentile(np.percentile(a[draws], 90, axis=1), [5, 95])
    values = {"median_abs_rel": np.median(a), "p90_abs_rel": np.percentile(a, 90), "p90_low": low, "p90_high": high,
              "median_rel": np.median(d), "share_above_5pct": np.mean(a > 0.05), "share_above_20pct": np.mean(a > 0.2)}
    return {f"{prefix}{k}": float(v) for k, v in values.items()}


def stack(ensemble: list[dict[str, np.ndarray]], field: str) -> np.ndarray:
    """[K, trials, W] of ``field`` over the members."""
    return np.stack([member[field] for member in ensemble])


def usable(ensemble: list[dict[str, np.ndarray]]) -> np.ndarray:
    """[trials, W]: pairs touched in every member, on trials no member failed."""
    failed = stack(ensemble, "failed").any(axis=0)
    return stack(ensemble, "touched").all(axis=0) & ~failed[:, None]


def spread(ensemble: list[dict[str, np.ndarray]], field: str) -> tuple[np.ndarray, np.ndarray]:
    """[trials, W] relative range (max − min) / median and relative median absolute deviation of
    ``field`` over the members (NaN where a member did not touch)."""
    values = stack(ensemble, field)
    centre = np.median(values, axis=0)
    return (values.max(axis=0) - values.min(axis=0)) / centre, np.median(np.abs(values - centre), axis=0) / centre


def within_floor(ensemble: list[dict[str, np.ndarray]], field: str, mask: np.ndarray) -> np.ndarray:
    """[member pairs, pairs] relative difference of ``field`` between every two members (i < j) of
    one ensemble, over the pairs of ``mask``."""
    values = stack(ensemble, field)[:, mask]
    return np.array([values[j] / values[i] - 1.0 for i, j in combinations(range(len(ensemble)), 2)])


def median_difference(base: list[dict[str, np.ndarray]], other: list[dict[str, np.ndarray]], field: str,
                      mask: np.ndarray) -> np.ndarray:
    """[pairs] relative difference of ``other``'s ensemble median of ``field`` from ``base``'s."""
    return np.median(stack(other, field)[:, mask], axis=0) / np.median(stack(base, field)[:, mask], axis=0) - 1.0


def separated(base: list[dict[str, np.ndarray]], other: list[dict[str, np.ndarray]], field: str) -> np.ndarray:
    """[trials, W] whether the two ensembles' values of ``field`` do not overlap (every member of
    one above every member of the other): for K = 4 against 4 drawn from one distribution, a
    chance of 2 in 70 per pair."""
    a, b = stack(base, field), stack(other, field)
    return (a.max(axis=0) < b.min(axis=0)) | (b.max(axis=0) < a.min(axis=0))


def halves(ensemble: list) -> tuple[list, list]:
    """The first and the second half of the members (the middle one left out if K is odd)."""
    n = len(ensemble) // 2
    return ensemble[:n], ensemble[len(ensemble) - n:]


def path_changes(ensemble: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """[trials, W] per path flag: whether the members disagree on it."""
    return {f: stack(ensemble, f).any(axis=0) & ~stack(ensemble, f).all(axis=0) for f in PATH_FIELDS}


def compare_ensembles(base: list[dict[str, np.ndarray]], other: list[dict[str, np.ndarray]]) -> dict:
    """The statistics of the module docstring, ``other`` (a variant) against ``base``, both of K
    members with the same perturbations. ``*_literal``: member 0 against member 0 (the pairs
    touched in both); ``*_floor_base``/``*_floor_other``: every two members of one ensemble, pooled;
    ``*_median_step``: the ensemble medians; ``*_split_step``/``*_split_floor``: the first half of
    ``base`` against the first half of ``other`` / the second half of ``base``; ``*_stable``: the
    literal statistic on the pairs whose spread (range / median, ``base``) of both peaks is below
    ``SENSITIVE``. ``sensitive``: the other pairs touched in member 0 of both. ``*_separated``: the
    pairs whose two ensembles do not overlap (:func:`separated`); ``*_separated_above_5pct``: those
    of them whose ensemble medians differ by more than 5 % (trial, whisker indices)."""
    mask = usable(base) & usable(other)
    both0 = base[0]["touched"] & other[0]["touched"] & ~(base[0]["failed"] | other[0]["failed"])[:, None]
    (b1, b2), (o1, _) = halves(base), halves(other)
    ranges = {f: spread(base, f)[0] for f in PEAKS}
    stable = both0 & mask & np.all([r < SENSITIVE for r in ranges.values()], axis=0)
    out = {"pairs_all_members": int(mask.sum()), "pairs_member0": int(both0.sum()), "pairs_stable": int(stable.sum()),
           "members": len(base)}
    for field in PEAKS:
        rng, mad = spread(base, field)
        floor = within_floor(base, field, mask)
        step = np.full(mask.shape, np.nan)
        step[mask] = median_difference(base, other, field, mask)
        apart = separated(base, other, field) & mask
        out |= (paired_summary(rng[mask], f"{field}_spread_range_") | paired_summary(mad[mask], f"{field}_spread_mad_")
                | paired_summary(relative(base[0], other[0], field, both0), f"{field}_literal_")
                | paired_summary(floor.ravel(), f"{field}_floor_base_") | paired_summary(floor[0], f"{field}_floor01_")
                | paired_summary(within_floor(other, field, mask).ravel(), f"{field}_floor_other_")
                | paired_summary(step[mask], f"{field}_median_step_")
                | paired_summary(median_difference(b1, o1, field, mask), f"{field}_split_step_")
                | paired_summary(median_difference(b1, b2, field, mask), f"{field}_split_floor_")
                | paired_summary(relative(base[0], other[0], field, stable), f"{field}_stable_"))
        out |= {f"{field}_separated": int(apart.sum()),
                f"{field}_separated_above_5pct": np.argwhere(apart & (np.abs(step) > SENSITIVE)).tolist(),
                f"{field}_pair_median_step": step.tolist(),
                f"{field}_pair_literal": (other[0][field] / base[0][field] - 1.0).tolist()}
    out["sensitive"] = np.argwhere(both0 & ~stable).tolist()
    out["spread_range"] = {f: r.tolist() for f, r in ranges.items()}
    for name, ensemble in (("base", base), ("other", other)):
        for flag, changed in path_changes(ensemble).items():
            out[f"path_{flag}_changes_{name}"] = int(changed.sum())
            out[f"path_{flag}_changes_touching_{name}"] = int((changed & both0).sum())
    return out


def relative(base: dict[str, np.ndarray], other: dict[str, np.ndarray], field: str, mask: np.ndarray) -> np.ndarray:
    """[pairs] other / base − 1 of ``field`` over the pairs of ``mask``."""
    return other[field][mask] / base[field][mask] - 1.0


ROWS = (("literal", "a. literal, member 0 vs member 0"),
        ("floor01", "b. floor, member 0 vs member 1 of the base step"),
        ("floor_base", "b. floor, every two members of the base, pooled"),
        ("floor_other", "b. floor, every two members of the variant, pooled"),
        ("median_step", "c. ensemble medians, variant vs base"),
        ("split_step", "c. half-ensemble medians, variant vs base (first halves)"),
        ("split_floor", "c. floor: the base's two half-ensemble medians"),
        ("stable", "d. literal on the pairs with spread < 5 %"),
        ("spread_range", "spread over the base's members, range / median"),
        ("spread_mad", "spread over the base's members, MAD / median"))


def ensemble_report(base: str, name: str, stats: dict, table: dict[str, np.ndarray], trials: list[int]) -> str:
    """The statistics of :func:`compare_ensembles` as a markdown table (median / P90 (5–95 %
    interval) of |d| per row), the path changes, and the sensitive pairs with their trial,
    whisker, scene, arc length and spreads (``table``: a member 0 table of the base)."""
    pct = {k: 100 * v for k, v in stats.items() if isinstance(v, float)}

    def cell(row, field):
        key = f"{field}_{row}_"
        return (f"{pct[key + 'median_abs_rel']:.1f} / {pct[key + 'p90_abs_rel']:.1f} % "
                f"({pct[key + 'p90_low']:.1f}–{pct[key + 'p90_high']:.1f}); "
                f"{round(stats[key + 'share_above_5pct'] * 100)} % > 5 %")

    lines = [f"{base} vs {name}, ensembles of {stats['members']}: {stats['pairs_all_members']} pairs touched in every "
             f"member of both, {stats['pairs_member0']} in member 0 of both, {stats['pairs_stable']} with spread < 5 %",
             "| statistic | peak \\|M\\| median / P90 (interval) | peak F_t median / P90 (interval) |", "|---|---|---|"]
    lines += [f"| {label} | {cell(row, 'peak_moment')} | {cell(row, 'peak_transverse')} |" for row, label in ROWS]
    lines.append("  path changes between members (all pairs / touching pairs), base; variant: " + ", ".join(
        f"{f} {stats[f'path_{f}_changes_base']}/{stats[f'path_{f}_changes_touching_base']}; "
        f"{stats[f'path_{f}_changes_other']}/{stats[f'path_{f}_changes_touching_other']}" for f in PATH_FIELDS))
    for field, label in zip(PEAKS, ("|M|", "F_t")):
        apart = ", ".join(pair_name(t, w, table, trials) for t, w in stats[f"{field}_separated_above_5pct"])
        lines.append(f"  {label}: {stats[f'{field}_separated']} pairs whose ensembles do not overlap; of them with "
                     f"ensemble medians > 5 % apart: {apart or 'none'}")
    lines.append("  sensitive pairs (trial whisker scene S; spread |M| / F_t over the base's members; F_t literal d, "
                 "ensemble-median d):")
    for t, w in stats["sensitive"]:
        m, f = (100 * stats["spread_range"][k][t][w] for k in PEAKS)
        literal, median = (100 * stats[f"peak_transverse_pair_{k}"][t][w] for k in ("literal", "median_step"))
        lines.append(f"    {pair_name(t, w, table, trials)}; {m:.1f} / {f:.1f} %; {literal:+.1f} %, {median:+.1f} %")
    return "\n".join(lines)


def pair_name(t: int, w: int, table: dict[str, np.ndarray], trials: list[int]) -> str:
    """'trial whisker scene S mm' of a pair (``table``: a member's table)."""
    return f"{trials[t]} {table['whisker'][w]} {table['scene'][t].removeprefix('mesh:')} " \
           f"{1e3 * table['arc_length_m'][w]:.1f} mm"
