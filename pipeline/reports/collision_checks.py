"""Fig. 3: collisions with an edge (docs/model.md §5), straight and curved whiskers, six speeds.

The shock (Fig. 3A–C) comes from :func:`pipeline.protocols.collision.run_collision` (the motor
holds the base from the first contact; dMz/dt of the Hann-smoothed Mz). The paper's Ṁz,max is
the *first negative* peak of dMz/dt after contact: its time and magnitude are what every check
uses (the largest |dMz/dt| lobe within 10 ms, often a later positive one, stays in the summary
for reference). Straight vs curved: both shapes of a whisker are divided by the mean over the
speeds of its *straight* peaks, so the curved line keeps its own level and slope, and the
slopes are compared by a t test that fails when they agree. Trends with curvature are judged
by a sign *and* its significance (p < 0.05), r², slope and p shown beside; so is the curved /
straight ratio of the peak (Wilcoxon signed-rank over the pairs of one whisker and speed). The quasi-static
bending moment and transverse force are means over the first 30 ms after contact.

The shock-wave front (Fig. 3D) needs finer time than 1 kHz: each whisker collides once more
sampled at 10 kHz, and again without the edge with the motor stopped at the same angle, so the
difference of the two runs' node positions is the edge's effect alone. A node's arrival time is
when that difference first exceeds a fraction of the peak displacement of the contact node
(linearly interpolated between samples); the front speed is the slope of the distance from the
contact node against arrival time over the nodes reached within 4 ms. Flexural waves are
dispersive (higher frequencies run faster), so the speed depends on the fraction; the summary
gives it for three fractions.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.signal import find_peaks
from scipy.stats import wilcoxon

from pipeline.config.physics import ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import single_whisker
from pipeline.model.effects.registry import model_parts
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import load_morphology
from pipeline.model.outputs import TrialOutput
from pipeline.model.whisker import WhiskerGeometry
from pipeline.protocols.collision import (SPEEDS_DEG_S, START_GAP_RAD, edge_scene, hann_smooth,
                                          run_collision)
from pipeline.reports import published as P
from pipeline.reports.checks import Section, check, linear_fit, rigid, slope_difference_p, with_output_rate
from pipeline.reports.document import number
from pipeline.scenes import empty

QUASI_STATIC_S = 0.030
SMOOTHING_LEAD_S = 0.005        # half the paper's 10-sample Hann window at 1 kHz
MIN_PAIRS = 5                   # the fewest pairs whose one-sided signed-rank p can be < 0.05 (1/2⁵)
TRACE_WINDOW_S = (-0.005, 0.030)
FRONT_RATE_HZ = 10_000.0
FRONT_SPEED_DEG_S = 540.0
FRONT_AFTER_CONTACT_S = 0.010
FRONT_WINDOW_S = 0.004
FRONT_FRACTION = 0.02
FRONT_FRACTIONS = (0.01, 0.02, 0.05)
COLUMN_1 = ("RA1", "RB1", "RC1", "RD1")
GREEK = ("RA0", "RB0", "RC0", "RD0")

Progress = Callable[[str], None]


def geometries(config: ModelConfig, name: str) -> dict[str, WhiskerGeometry]:
    """The array whisker ``name`` straight and with its intrinsic curvature."""
    s = load_morphology(config.morphology)[name]
    return {"straight": WhiskerGeometry(s.arc_length_m, s.base_radius_m, s.tip_radius_m),
            "curved": WhiskerGeometry(s.arc_length_m, s.base_radius_m, s.tip_radius_m, s.curvature_per_m)}


def collision_runs(config: ModelConfig, names, speeds=SPEEDS_DEG_S, progress: Progress = lambda _: None) -> list[dict]:
    """Every (whisker, shape, speed) collision: dicts with the CollisionResult under ``result``."""
    bench = rigid(config)
    records = []
    for name in names:
        for shape, geometry in geometries(config, name).items():
            progress(f"fig. 3: {name} {shape}, collisions at {', '.join(f'{s:g}' for s in speeds)} °/s")
            material, extensions = model_parts(bench)
            with create_engine(bench, single_whisker(geometry, material, extensions=extensions)) as engine:
                for speed in speeds:
                    records.append({"whisker": name, "shape": shape, "speed_deg_s": float(speed),
                                    "curvature_per_mm": geometry.curvature_per_m * 1e-3,
                                    "result": run_collision(geometry, bench, speed, engine)})
    return records


def dmz_trace(output: TrialOutput) -> tuple[np.ndarray, np.ndarray]:
    """(time from contact, dMz/dt of the smoothed Mz) within TRACE_WINDOW_S of the first contact."""
    rate = output.sample_rate_hz
    dmz = np.gradient(hann_smooth(output.base_wrench[:, 0].astype(float))[:, 5], 1 / rate)
    k0 = int(np.argmax(output.contact[:, 0].any(axis=1)))
    lo, hi = (max(0, k0 + int(round(w * rate))) for w in TRACE_WINDOW_S)
    return output.time_s[lo:hi] - output.time_s[k0], dmz[lo:hi]


def first_negative_peak(time_s: np.ndarray, dmz: np.ndarray, lead_s: float = SMOOTHING_LEAD_S) -> tuple[float, float]:
    """(time in ms, value in N·m/s) of the first negative local minimum of dMz/dt from ``lead_s``
    before contact on — the paper's Ṁz,max; (NaN, NaN) if there is none. The centred smoothing
    moves a dip at contact up to half its width earlier; before that the whisker turns freely."""
    peaks, _ = find_peaks(-dmz)
    found = [p for p in peaks if time_s[p] >= -lead_s - 1e-9 and dmz[p] < 0]
    return (float(time_s[found[0]] * 1e3), float(dmz[found[0]])) if found else (float("nan"), float("nan"))


def trend(x, y, published: P.Published, name: str, label: str):
    """A check that y falls with x (the paper's sign), judged by the sign and p < 0.05 of the
    regression slope; ours is r² (the published number), slope and p shown beside."""
    fit = linear_fit(x, y)
    falls = bool(fit["slope"] < 0 and fit["p_value"] < 0.05)
    detail = f"slope {number(fit['slope'], 3)}, p {number(fit['p_value'], 2)}, n {fit['n']}"
    return check(name, label, published, fit["r2"], falls, "falls: negative slope, p < 0.05", detail=detail), fit


def normalised_peaks(rows: list[dict], key: str = "shock_dmz_dt") -> list[float]:
    """|``key``| of every row divided by the mean over the speeds of its whisker's straight
    runs (NaN where that mean is undefined): one scale per whisker, the same for both shapes."""
    out = []
    for row in rows:
        straight = [abs(o[key]) for o in rows if o["whisker"] == row["whisker"] and o["shape"] == "straight"]
        scale = np.nanmean(straight) if np.isfinite(straight).any() else np.nan
        out.append(float(abs(row[key]) / scale) if scale > 0 else float("nan"))
    return out


def straight_vs_curved(rows: list[dict]) -> dict:
    """Per-shape regressions of the normalised peak on speed, the slopes' t test, and the
    curved / straight ratio of the peak at the same whisker and speed (median, pairs smaller)."""
    fits = {}
    for shape in ("straight", "curved"):
        runs = [r for r in rows if r["shape"] == shape and np.isfinite(r["peak_normalised"])]
        fits[shape] = linear_fit([r["speed_deg_s"] for r in runs], [r["peak_normalised"] for r in runs])
    straight = {(r["whisker"], r["speed_deg_s"]): abs(r["shock_dmz_dt"]) for r in rows if r["shape"] == "straight"}
    ratios = np.array([abs(r["shock_dmz_dt"]) / straight[(r["whisker"], r["speed_deg_s"])]
                       for r in rows if r["shape"] == "curved"])
    ratios = ratios[np.isfinite(ratios)]
    return {"fits": fits, "slopes_differ_p": slope_difference_p(fits["straight"], fits["curved"]),
            "ratio": float(np.median(ratios)) if ratios.size else float("nan"),
            "pairs_smaller": int(np.sum(ratios < 1)), "pairs": int(ratios.size),
            "smaller_p": smaller_p(ratios)}


def smaller_p(ratios: np.ndarray) -> float:
    """One-sided Wilcoxon signed-rank p-value that the ratios are below 1 (on ln ratio; NaN with
    fewer than 3 pairs or all equal to 1)."""
    logs = np.log(ratios[ratios > 0])
    if logs.size < 3 or not np.any(logs):
        return float("nan")
    return float(wilcoxon(logs, alternative="less").pvalue)


def quasi_static(output: TrialOutput) -> tuple[float, float]:
    """Mean bending moment (N·m) and transverse force (N) over QUASI_STATIC_S after contact."""
    k0 = int(np.argmax(output.contact[:, 0].any(axis=1)))
    window = slice(k0, k0 + int(round(QUASI_STATIC_S * output.sample_rate_hz)))
    return float(output.bending_moment()[window, 0].mean()), float(output.transverse_force()[window, 0].mean())


def shock_section(records: list[dict]) -> Section:
    """Section ``fig3_shock`` from :func:`collision_runs`."""
    rows = []
    for r in records:
        result = r["result"]
        mb, ft = quasi_static(result.output)
        shock_ms, shock = first_negative_peak(*dmz_trace(result.output))
        rows.append({k: v for k, v in r.items() if k != "result"} | {
            "contact_link": result.first_contact_link + 1, "shock_ms": shock_ms, "shock_dmz_dt": shock,
            "largest_lobe_ms": result.peak_time_after_contact_s * 1e3, "largest_lobe_dmz_dt": result.peak_dmz_dt,
            "bending_moment_at_largest_lobe": result.bending_moment_at_peak,
            "transverse_force_at_largest_lobe": result.transverse_force_at_peak,
            "bending_moment_qs": mb, "transverse_force_qs": ft})
    for row, value in zip(rows, normalised_peaks(rows)):
        row["peak_normalised"] = value
    shapes = straight_vs_curved(rows)
    fits, p_slopes, ratio = shapes["fits"], shapes["slopes_differ_p"], shapes["ratio"]
    curvature = [r["curvature_per_mm"] for r in rows]
    links = [r["contact_link"] for r in rows]
    link = max(set(links), key=links.count)
    shock_ms = float(np.nanmedian([r["shock_ms"] for r in rows]))
    checks = [
        check("first_contact_link", "link that hits the edge", P.CONTACT_LINK, link, link == P.CONTACT_LINK.value,
              "the same link (1-based)"),
        check("dmz_first_negative_peak_ms", "first negative dMz/dt peak after contact (ms, median)",
              P.DMZ_PEAK_DELAY_MS, shock_ms, abs(shock_ms - P.DMZ_PEAK_DELAY_MS.value) <= 1.0,
              "within 1 ms (one sample)"),
    ]
    for shape in ("straight", "curved"):
        adj = fits[shape]["adj_r2"]
        checks.append(check(f"peak_vs_speed_adj_r2_{shape}", f"first negative peak vs speed, {shape}: adj. r²",
                            P.PEAK_VS_SPEED_ADJ_R2, adj, adj >= P.PEAK_VS_SPEED_ADJ_R2.value - 0.1,
                            "≥ published − 0.1"))
    checks += [
        check("slopes_differ_p", "straight vs curved slope of the normalised peak: p", P.SLOPES_DIFFER_P, p_slopes,
              p_slopes < 1e-3, "p < 0.001 (both shapes scaled by the straight mean)",
              detail=f"slopes {number(fits['straight']['slope'], 3)} straight, "
                     f"{number(fits['curved']['slope'], 3)} curved, per °/s"),
        check("curved_over_straight_peak", "curved / straight first negative peak (median)", P.CURVED_PEAK_SMALLER,
              ratio, bool(ratio < 1.0 and shapes["smaller_p"] < 0.05) if shapes["pairs"] >= MIN_PAIRS else None,
              f"< 1, Wilcoxon p < 0.05 (no verdict below {MIN_PAIRS} pairs)",
              detail=f"smaller in {shapes['pairs_smaller']} of {shapes['pairs']} pairs, "
                     f"p {number(shapes['smaller_p'], 2)}"),
    ]
    qs = {}
    for key, name, label, published in (
            ("bending_moment_qs", "qs_bending_moment_vs_curvature_r2", "M_b (first 30 ms) vs curvature: r²",
             P.QS_BENDING_MOMENT_R2),
            ("transverse_force_qs", "qs_transverse_force_vs_curvature_r2", "F_t (first 30 ms) vs curvature: r²",
             P.QS_TRANSVERSE_FORCE_R2)):
        judged, qs[key] = trend(curvature, [r[key] for r in rows], published, name, label)
        checks.append(judged)
    first = records[0]["whisker"]
    traces = {(r["shape"], r["speed_deg_s"]): dmz_trace(r["result"].output) for r in records if r["whisker"] == first}
    whiskers = sorted({r["whisker"] for r in rows}, key=[r["whisker"] for r in rows].index)
    summary = {"whiskers": whiskers, "speeds_deg_s": sorted({r["speed_deg_s"] for r in rows}), "runs": rows,
               "peak_vs_speed": fits, "slopes_differ_p": p_slopes, "curved_over_straight_peak": ratio,
               "curved_smaller_pairs": [shapes["pairs_smaller"], shapes["pairs"]],
               "curved_smaller_p": shapes["smaller_p"],
               "quasi_static_vs_curvature": qs, "trace_whisker": first}
    speeds = ", ".join(f"{s:g}" for s in summary["speeds_deg_s"])
    caption = (f"Fig. 3A–C: collisions of {', '.join(whiskers)} (straight and with their intrinsic curvature) "
               f"with an edge at {speeds} °/s, rigid follicle; the motor holds the base from the first contact. "
               f"A: dMz/dt of {first} around contact (the paper's 10-sample Hann smoothing is centred, so the "
               "dip starts before contact); markers: the first negative peak, the paper's Ṁz,max. B: |Ṁz,max| "
               "divided by the mean over the speeds of the same whisker's straight runs (both shapes), with "
               "the regression per shape. C: bending moment and transverse force (means over 30 ms after "
               "contact) against curvature, with the regressions.")
    return Section("fig3_shock", "Fig. 3A–C: the shock of a collision", checks, summary, {"traces": traces}, caption)


# -- the shock-wave front --------------------------------------------------------------
def front_runs(geometry: WhiskerGeometry, config: ModelConfig, speed_deg_s: float = FRONT_SPEED_DEG_S):
    """(with the edge, without it) at FRONT_RATE_HZ; the base stops at the first contact in both."""
    bench = with_output_rate(rigid(config), FRONT_RATE_HZ)
    omega, dt = np.radians(speed_deg_s), bench.engine.dt_s
    duration = START_GAP_RAD / omega + FRONT_AFTER_CONTACT_S
    drive = ProtractionDrive(np.array([0.0, duration]), np.array([0.0, omega * duration]), interpolation="linear")
    material, extensions = model_parts(bench)
    with create_engine(bench, single_whisker(geometry, material, extensions=extensions)) as engine:
        hit = engine.run(edge_scene(geometry), Pose(), drive, duration, stop_drive_on_contact=True)
        first = hit.node_positions_m[-1, 0, 1].astype(float)       # link 0 turns with the base
        stop = round(np.arctan2(first[1], first[0]) / omega / dt) * dt
        held = ProtractionDrive(np.array([0.0, stop, duration]), omega * np.array([0.0, stop, stop]),
                                interpolation="linear")
        free = engine.run(empty(), Pose(), held, duration)
    return hit, free


def front_arrival(hit: TrialOutput, free: TrialOutput, *, threshold_m: float) -> np.ndarray:
    """[N+1] time (s) at which each node of whisker 0 first moves ``threshold_m`` away from its
    position without the edge, from the first contact on; NaN if never, or if it had before."""
    d = np.linalg.norm(hit.node_positions_m[:, 0].astype(float) - free.node_positions_m[:, 0], axis=-1)
    t = hit.time_s
    arrival = np.full(d.shape[1], np.nan)
    touching = hit.contact[:, 0].any(axis=1)
    if not touching.any():
        return arrival
    k0 = int(np.argmax(touching))
    for n in range(d.shape[1]):
        if (d[:k0, n] > threshold_m).any():
            continue
        above = np.flatnonzero(d[k0:, n] > threshold_m)
        if above.size:
            k = k0 + int(above[0])
            if k == 0:
                arrival[n] = t[0]
            else:
                arrival[n] = t[k - 1] + (threshold_m - d[k - 1, n]) / (d[k, n] - d[k - 1, n]) * (t[k] - t[k - 1])
    return arrival


def front_points(arrival: np.ndarray, arc_m: np.ndarray, contact_node: int,
                 window_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(time since the contact node moved, distance from it toward the base) of the nodes
    proximal to ``contact_node`` that the front reached (within ``window_s``)."""
    nodes = np.arange(contact_node + 1)
    t = arrival[nodes] - arrival[contact_node]
    x = arc_m[contact_node] - np.asarray(arc_m)[nodes]
    keep = np.isfinite(t) & (t >= 0) & (t <= (np.inf if window_s is None else window_s))
    return t[keep], x[keep]


def front_speed(t: np.ndarray, x: np.ndarray) -> dict:
    """The front's speed (m/s): slope of distance against time, with the fit's r²."""
    fit = linear_fit(t, x)
    return {"speed_m_s": fit["slope"], "r2": fit["r2"], "n": fit["n"], "intercept_m": fit["intercept"]}


def front_of(hit: TrialOutput, free: TrialOutput, arc_length_m: float, fraction: float):
    """(points (t, x), contact node) of one whisker's front at ``fraction`` of the contact node's peak."""
    node = int(np.argmax(hit.contact[np.argmax(hit.contact[:, 0].any(axis=1)), 0]))
    d = np.linalg.norm(hit.node_positions_m[:, 0, node].astype(float) - free.node_positions_m[:, 0, node], axis=-1)
    arrival = front_arrival(hit, free, threshold_m=fraction * d.max())
    arc = np.arange(hit.links + 1) / hit.links * arc_length_m
    return front_points(arrival, arc, node, FRONT_WINDOW_S), node


def front_section(config: ModelConfig, progress: Progress = lambda _: None) -> Section:
    """Section ``fig3_front``: the front speed over the column-1 and the Greek-column whiskers."""
    morphology = load_morphology(config.morphology)
    groups = {"column1": COLUMN_1, "greek": GREEK}
    fits, points, per_whisker = {}, {}, {}
    for group, names in groups.items():
        progress(f"fig. 3: shock-wave front on {', '.join(names)} ({FRONT_RATE_HZ / 1e3:g} kHz)")
        runs = {}
        for name in names:
            s = morphology[name]
            geometry = WhiskerGeometry(s.arc_length_m, s.base_radius_m, s.tip_radius_m)
            runs[name] = (front_runs(geometry, config), s.arc_length_m)
        fits[group] = {}
        for fraction in FRONT_FRACTIONS:
            pooled_t, pooled_x = [], []
            for name, ((hit, free), arc_length) in runs.items():
                (t, x), node = front_of(hit, free, arc_length, fraction)
                pooled_t.append(t)
                pooled_x.append(x)
                if fraction == FRONT_FRACTION:
                    points[name] = {"t_s": t, "position": (node / hit.links * arc_length - x) / arc_length}
                    per_whisker[name] = front_speed(t, x)
            fits[group][fraction] = front_speed(np.concatenate(pooled_t), np.concatenate(pooled_x))
    col, greek = fits["column1"][FRONT_FRACTION], fits["greek"][FRONT_FRACTION]
    also = {"analytic_m_s": P.FRONT_SPEED_ANALYTIC_M_S, "measured_m_s": P.FRONT_SPEED_MEASURED_M_S}
    checks = [
        check("front_speed_column1_m_s", "front speed, column 1 (m/s)", P.FRONT_SPEED_COLUMN1_M_S, col["speed_m_s"],
              abs(col["speed_m_s"] / P.FRONT_SPEED_COLUMN1_M_S.value - 1) <= 0.2, "within 20 %",
              also_published=also),
        check("front_r2_column1", "front fit r², column 1", P.FRONT_R2_COLUMN1, col["r2"], col["r2"] >= 0.8,
              "≥ 0.8"),
        check("front_speed_greek_m_s", "front speed, Greek column (m/s)", P.FRONT_SPEED_GREEK_M_S,
              greek["speed_m_s"], abs(greek["speed_m_s"] / P.FRONT_SPEED_GREEK_M_S.value - 1) <= 0.2,
              "within 20 %"),
        check("front_r2_greek", "front fit r², Greek column", P.FRONT_R2_GREEK, greek["r2"], greek["r2"] >= 0.8,
              "≥ 0.8"),
    ]
    summary = {"groups": {g: list(n) for g, n in groups.items()}, "speed_deg_s": FRONT_SPEED_DEG_S,
               "rate_hz": FRONT_RATE_HZ, "window_s": FRONT_WINDOW_S, "fraction": FRONT_FRACTION,
               "speed_by_fraction": {g: {str(f): v for f, v in by.items()} for g, by in fits.items()},
               "per_whisker": per_whisker}
    caption = (f"Fig. 3D: position of the shock-wave front (fraction of the arc length from the base) after "
               f"collisions at {FRONT_SPEED_DEG_S:g} °/s, sampled at {FRONT_RATE_HZ / 1e3:g} kHz; a node is reached "
               f"when it has moved {FRONT_FRACTION:.0%} of the contact node's peak displacement away from where it "
               f"is without the edge. Speed = slope over the nodes reached within {FRONT_WINDOW_S * 1e3:g} ms, "
               f"pooled per column (column 1: {', '.join(COLUMN_1)}; Greek: {', '.join(GREEK)}). The front of a "
               "dispersive flexural wave has no unique speed: at " + ", ".join(
                   f"{f:.0%} → {fits['column1'][f]['speed_m_s']:.2f} m/s" for f in FRONT_FRACTIONS) + " (column 1).")
    return Section("fig3_front", "Fig. 3D: the shock-wave front", checks, summary, {"points": points}, caption)
