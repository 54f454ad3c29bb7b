"""One PNG per validation section (matplotlib, Agg backend), its published-vs-ours lines below it."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from pipeline.model.outputs import SIGNALS, SIGNAL_UNITS
from pipeline.reports.checks import Section
from pipeline.reports.stats_figures import pyplot

ROW_COLOURS = dict(zip("ABCDE", ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")))


def _footer(fig, section: Section) -> None:
    lines = [check.line() for check in section.checks]
    text = "\n".join(textwrap.fill(line, 150) for line in lines)
    fig.text(0.01, -0.01, "Published vs ours:\n" + text, ha="left", va="top", fontsize=7, family="monospace")


def table1(section: Section, plt):
    s = section.summary
    fig, axes = plt.subplots(1, 4, figsize=(15, 3.4), gridspec_kw={"width_ratios": [3, 1, 1, 1]})
    for name, (t, y) in section.series.items():
        axes[0].plot(t, y * 1e3, label=name)
    axes[0].axvline(0.128, color="grey", lw=0.8, ls=":")
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("tip y (mm)")
    axes[0].legend()
    by_name = {c.name: c for c in section.checks}
    for ax, key, label in zip(axes[1:], ("f1_hz", "log_decrement", "damping_ratio"), ("f1 (Hz)", "δ", "ζ")):
        for i, whisker in enumerate(s["whiskers"]):
            c = by_name[f"{whisker}_{key}"]
            ax.errorbar(i - 0.15, c.published, yerr=c.published_sd, fmt="o", color="k",
                        label="measured" if i == 0 else None)
            ax.errorbar(i, c.also_published["paper_simulation"], yerr=c.also_published["paper_simulation_sd"],
                        fmt="s", color="grey", label="paper sim." if i == 0 else None)
            ax.plot(i + 0.15, c.simulated, "r^", label="ours" if i == 0 else None)
        ax.set_xticks(range(len(s["whiskers"])), s["whiskers"])
        ax.set_title(label)
    axes[1].legend(fontsize=7)
    return fig


def fig2(section: Section, plt):
    s = section.summary
    right = np.array(s["side"]) > 0
    arc, f1, fit = (np.asarray(s[k])[right] for k in ("arc_length_mm", "f1_hz", "fit_f1_hz"))
    residual = np.asarray(s["relative_residual"])[right]
    rows = [n[1] for n, r in zip(s["whiskers"], right) if r]
    names = [n for n, r in zip(s["whiskers"], right) if r]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    grid = np.linspace(arc.min() * 0.9, arc.max() * 1.05, 200)
    curve = s["fit"]["coefficient"] * grid ** s["fit"]["exponent"] + s["fit"]["offset"]
    axes[0].plot(grid, curve, "k-", label="published fit 8963·S^−1.4 − 3.8")
    band_label = (f"±{s['band']:.0%} band (ours: spans the paper's measured scatter; "
                  "its prediction interval is drawn, not tabulated)")
    for factor, label in ((1 - s["band"], band_label), (1 + s["band"], None)):
        axes[0].plot(grid, curve * factor, "k--", lw=0.7, label=label)
    for row in "ABCDE":
        pick = [r == row for r in rows]
        axes[0].scatter(arc[pick], f1[pick], color=ROW_COLOURS[row], label=f"row {row}", s=18)
        axes[1].scatter(arc[pick], residual[pick], color=ROW_COLOURS[row], s=18)
    for name, value in s["engine_f1_hz"].items():
        if name in names:
            axes[0].scatter(arc[names.index(name)], value, marker="x", color="k", s=50, label=f"engine {name}")
    axes[0].set_yscale("log")
    axes[0].set_xlabel("arc length S (mm)")
    axes[0].set_ylabel("f1 (Hz)")
    axes[0].legend(fontsize=7)
    axes[1].axhline(0, color="k")
    for edge in (-s["band"], s["band"]):
        axes[1].axhline(edge, color="k", ls="--", lw=0.7,
                        label=f"±{s['band']:.0%} band: outside = off the published fit by more" if edge > 0 else None)
    axes[1].axvline(15, color="grey", ls=":", label="15 mm: shorter whiskers may fall outside")
    axes[1].legend(fontsize=7)
    axes[1].set_xlabel("arc length S (mm)")
    axes[1].set_ylabel("f1 / fit − 1")
    axes[1].set_title("residuals (right side; the left mirrors it)")
    return fig


def fig3_shock(section: Section, plt):
    s = section.summary
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    cmap = plt.get_cmap("viridis")
    speeds = s["speeds_deg_s"]
    for ax, shape in zip(axes[:2], ("straight", "curved")):
        for j, speed in enumerate(speeds):
            t, dmz = section.series["traces"][(shape, speed)]
            colour = cmap(j / max(len(speeds) - 1, 1))
            ax.plot(t * 1e3, dmz, color=colour, label=f"{speed:g} °/s")
            run = next(r for r in s["runs"] if (r["whisker"], r["shape"], r["speed_deg_s"]) ==
                       (s["trace_whisker"], shape, speed))
            ax.plot(run["shock_ms"], run["shock_dmz_dt"], "v", color=colour, ms=6)
        ax.axvline(0, color="k", lw=0.8)
        ax.set_xlabel("time from contact (ms)")
        ax.set_ylabel("dMz/dt (N·m/s)")
        ax.set_title(f"{s['trace_whisker']} {shape}")
    axes[0].legend(fontsize=7)
    for shape, colour in (("straight", "tab:blue"), ("curved", "tab:red")):
        runs = [r for r in s["runs"] if r["shape"] == shape]
        axes[2].scatter([r["speed_deg_s"] for r in runs], [r["peak_normalised"] for r in runs], color=colour,
                        s=14, label=f"{shape}: adj. r² {s['peak_vs_speed'][shape]['adj_r2']:.3f}")
        fit = s["peak_vs_speed"][shape]
        x = np.array([min(speeds), max(speeds)])
        axes[2].plot(x, fit["slope"] * x + fit["intercept"], color=colour)
    axes[2].set_xlabel("speed (°/s)")
    axes[2].set_ylabel("|Ṁz,max| / straight mean")
    axes[2].legend(fontsize=7)
    ax = axes[3]
    curvature = [r["curvature_per_mm"] for r in s["runs"]]
    twin = ax.twinx()
    x = np.array([min(curvature), max(curvature)])
    for axis, key, colour, marker, name in ((ax, "bending_moment_qs", "tab:blue", "o", "M_b (N·m)"),
                                            (twin, "transverse_force_qs", "tab:orange", "^", "F_t (N)")):
        fit = s["quasi_static_vs_curvature"][key]
        axis.scatter(curvature, [r[key] for r in s["runs"]], s=14, color=colour, marker=marker,
                     label=f"{name}: r² {fit['r2']:.3f}, p {fit['p_value']:.2g}")
        axis.plot(x, fit["slope"] * x + fit["intercept"], color=colour, lw=0.8)
    ax.set_xlabel("curvature A (1/mm)")
    ax.set_ylabel("M_b, mean of 30 ms (N·m)")
    twin.set_ylabel("F_t, mean of 30 ms (N)")
    ax.legend(loc="lower left", fontsize=6)
    twin.legend(loc="center right", fontsize=6)
    return fig


def fig3_front(section: Section, plt):
    s = section.summary
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.8), sharey=True)
    for ax, (group, names) in zip(axes, s["groups"].items()):
        for name in names:
            p = section.series["points"][name]
            ax.plot(p["t_s"] * 1e3, p["position"], "o-", ms=3, label=name)
        fit = s["speed_by_fraction"][group][str(s["fraction"])]
        ax.set_title(f"{group}: {fit['speed_m_s']:.2f} m/s (r² {fit['r2']:.3f})")
        ax.set_xlabel("time from contact (ms)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("front position (fraction of S from the base)")
    return fig


def fig4(section: Section, plt):
    runs = section.series["runs"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.6))
    for kind, colour in (("rigid", "tab:red"), ("compliant", "tab:blue")):
        r = runs[kind]
        t = r["time_s"] * 1e3
        axes[0].plot(t, r["tip_m"][:, 2] * 1e3, color=colour, label=kind)
        axes[1].plot(t, r["wrench"][:, 2], color=colour, label=kind)
        axes[2].plot(t, r["wrench"][:, 4], color=colour, label=kind)
    for ax, label in zip(axes, ("tip deflection z (mm)", "F_z (N)", "M_y (N·m)")):
        ax.set_xlabel("time after release (ms)")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    return fig


def fig5(section: Section, plt):
    runs = section.series["runs"]
    fig, axes = plt.subplots(4, len(runs), figsize=(5 * len(runs), 11), squeeze=False,
                             gridspec_kw={"height_ratios": [2, 2, 1, 1]}, layout="constrained")
    for j, run in enumerate(runs.values()):
        t_ms = run["time_s"] * 1e3
        extent = (t_ms[0], t_ms[-1], len(run["names"]) - 0.5, -0.5)
        poc = axes[0, j].imshow(run["poc"].T, aspect="auto", extent=extent, cmap="viridis", vmin=0, vmax=1,
                                interpolation="nearest")
        moment = np.log10(np.maximum(run["moment"].T, 1e-12))
        m = axes[1, j].imshow(moment, aspect="auto", extent=extent, cmap="magma", interpolation="nearest",
                              vmin=max(moment.max() - 4, -12), vmax=moment.max())
        for ax in axes[:2, j]:
            ax.set_yticks(range(len(run["names"])), run["names"], fontsize=7)
        axes[0, j].set_title(f"{run['scene']}: POC")
        axes[1, j].set_title("log10 M (N·m)")
        if run["signals"] is not None:
            for row, signals in ((2, range(3)), (3, range(3, 6))):
                for k in signals:
                    axes[row, j].plot(t_ms, run["signals"][:, k], lw=0.8, label=f"{SIGNALS[k]} ({SIGNAL_UNITS[k]})")
                axes[row, j].legend(loc="upper left", fontsize=6)
            axes[2, j].set_title(f"base signals of {run['signal_whisker']}")
        axes[3, j].set_xlabel("time (ms)")
    fig.colorbar(poc, ax=axes[0, -1], label="POC")
    fig.colorbar(m, ax=axes[1, -1], label="log10 M")
    return fig


def contact_statics(section: Section, plt):
    """Base Mz, Fy, Fx against the base angle: the engine (solid) and the elastica (dashed)."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    labels = ("Mz (N·m)", "Fy, transverse (N)", "Fx, axial (N)")
    for n, (case, (angle, engine, reference)) in enumerate(section.series.items()):
        colour = f"C{n % 10}"
        inside = np.isfinite(reference[:, 0])
        for j, ax in enumerate(axes):
            ax.plot(angle[inside], engine[inside, j], color=colour, lw=0.9, label=case if j == 0 else None)
            ax.plot(angle[inside], reference[inside, j], color=colour, lw=0.9, ls="--")
    for ax, label in zip(axes, labels):
        ax.set_xlabel("base angle (°)")
        ax.set_title(label)
    axes[0].legend(fontsize=6, title="solid: engine, dashed: elastica", title_fontsize=6)
    return fig


DRAW = {"table1": table1, "fig2": fig2, "fig3_shock": fig3_shock, "fig3_front": fig3_front, "fig4": fig4,
        "fig5": fig5, "contact_statics": contact_statics}


def write_figure(section: Section, out: Path) -> Path | None:
    """``<out>/<section>.png``, or None for a section without a figure."""
    draw = DRAW.get(section.name)
    if draw is None:
        return None
    plt = pyplot()
    fig = draw(section, plt)
    fig.suptitle(section.title, y=1.02)
    _footer(fig, section)
    path = Path(out) / f"{section.name}.png"
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path
