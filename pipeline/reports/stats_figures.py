"""Figures and report.md of ``pipeline stats`` (matplotlib, Agg backend), drawn from stats.json's
numbers only."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from pipeline.reports.document import Markdown, number

ROWS = "ABCDE"
COLUMNS = 7


def pyplot():
    matplotlib.use("Agg")
    return plt


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return path


def _array_grid(values, stats: dict, side: int) -> np.ndarray:
    """[5 rows, 7 columns] of ``values`` per whisker on one side; NaN where there is none."""
    grid = np.full((len(ROWS), COLUMNS), np.nan)
    for v, row, col, s in zip(values, stats["whisker_row"], stats["whisker_col"], stats["whisker_side"]):
        if s == side and v is not None:
            grid[row - 1, col] = v
    return grid


def contact_map(stats: dict, path: Path) -> Path:
    plt = pyplot()
    sides = [s for s in (1, -1) if s in stats["whisker_side"]]
    fig, axes = plt.subplots(1, len(sides), figsize=(4.2 * len(sides), 3.4), squeeze=False)
    top = max(max(stats["contact_probability"]), 1e-9)
    for ax, side in zip(axes[0], sides):
        grid = _array_grid(stats["contact_probability"], stats, side)
        image = ax.imshow(grid, cmap="viridis", vmin=0, vmax=top)
        for (r, c), v in np.ndenumerate(grid):
            if np.isfinite(v):
                ax.text(c, r, f"{v:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if v < 0.6 * top else "black")
        ax.set_xticks(range(COLUMNS))
        ax.set_yticks(range(len(ROWS)), list(ROWS))
        ax.set_xlabel("column (0 = Greek arc)")
        ax.set_title(f"{'right' if side > 0 else 'left'} side")
    fig.colorbar(image, ax=axes[0].tolist(), label="P(contact)")
    fig.suptitle("contact probability per whisker")
    return _save(fig, path)


def _per_whisker_image(ax, counts, edges, names, label: str, log_x: bool):
    counts = np.asarray(counts, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = counts / counts.sum(axis=1, keepdims=True)
    shown = np.log10(np.where(fraction > 0, fraction, np.nan))
    x = np.log10(edges) if log_x else np.asarray(edges)
    image = ax.pcolormesh(x, np.arange(len(names) + 1) - 0.5, shown, cmap="magma", shading="flat", vmin=-4, vmax=0)
    ax.set_yticks(range(len(names)), names, fontsize=6 if len(names) > 20 else 8)
    ax.invert_yaxis()
    ax.set_xlabel(label)
    return image


def histograms(stats: dict, key: str, edges_key: str, unit: str, path: Path) -> Path:
    """Per-whisker log-binned histograms (all samples and in contact), rows in array order."""
    plt = pyplot()
    data = stats[key]
    order = stats["moment_correlation"]["order_index"]
    names = [stats["whiskers"][i] for i in order]
    edges = np.asarray(data[edges_key])
    fig, axes = plt.subplots(1, 3, figsize=(13, 0.18 * len(names) + 3), gridspec_kw={"width_ratios": [3, 3, 2]},
                             layout="constrained")
    for ax, counts, title in ((axes[0], data["counts"], "all samples"),
                              (axes[1], data["counts_in_contact"], "in contact")):
        image = _per_whisker_image(ax, np.asarray(counts)[order], edges, names, f"log10 {unit}", True)
        ax.set_title(title)
    fig.colorbar(image, ax=axes[:2].tolist(), label="log10 fraction of the whisker's samples", shrink=0.6)
    centres = np.sqrt(edges[:-1] * edges[1:])
    for counts, label in ((data["counts"], "all"), (data["counts_in_contact"], "in contact")):
        pooled = np.asarray(counts).sum(axis=0)
        axes[2].step(centres, pooled, where="mid", label=label)
    axes[2].set_xscale("log")
    axes[2].set_yscale("log")
    axes[2].set_xlabel(unit)
    axes[2].set_title("all whiskers")
    axes[2].legend()
    fig.suptitle(f"{key.replace('_', ' ')} per whisker")
    return _save(fig, path)


def poc_figure(stats: dict, path: Path) -> Path:
    plt = pyplot()
    data = stats["point_of_contact"]
    order = stats["moment_correlation"]["order_index"]
    names = [stats["whiskers"][i] for i in order]
    edges = np.asarray(data["bin_edges"])
    fig, axes = plt.subplots(1, 2, figsize=(11, 0.18 * len(names) + 3), layout="constrained")
    image = _per_whisker_image(axes[0], np.asarray(data["counts"])[order], edges, names, "POC (0 base, 1 tip)",
                               False)
    fig.colorbar(image, ax=axes[0], label="log10 fraction of the whisker's contacts", shrink=0.6)
    axes[1].bar((edges[:-1] + edges[1:]) / 2, np.asarray(data["counts"]).sum(axis=0), width=np.diff(edges))
    axes[1].set_xlabel("POC (fraction of the arc length S)")
    axes[1].set_ylabel("in-contact samples, all whiskers")
    fig.suptitle("point of contact")
    return _save(fig, path)


def duration_figure(stats: dict, path: Path) -> Path:
    plt = pyplot()
    d = stats["contact_duration"]
    counts = np.asarray(d["counts"])
    lengths_ms = np.arange(len(counts)) / stats["sampling_rate_hz"] * 1e3
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
    axes[0].bar(lengths_ms[1:], counts[1:], width=1e3 / stats["sampling_rate_hz"])
    axes[0].set_yscale("log")
    axes[0].set_xlabel("contact duration (ms)")
    axes[0].set_ylabel("contacts")
    axes[0].set_title(f"all whiskers: mean {number(d['mean_all_s'] and d['mean_all_s'] * 1e3)} ms")
    mean = np.array([np.nan if v is None else v * 1e3 for v in d["mean_s"]])
    grid = np.vstack([_array_grid(mean, stats, 1), np.full((1, COLUMNS), np.nan), _array_grid(mean, stats, -1)])
    image = axes[1].imshow(grid, cmap="viridis")
    fig.colorbar(image, ax=axes[1], label="ms")
    axes[1].set_yticks([*range(len(ROWS)), *range(len(ROWS) + 1, 2 * len(ROWS) + 1)],
                       [f"R{r}" for r in ROWS] + [f"L{r}" for r in ROWS])
    axes[1].set_xlabel("column")
    axes[1].set_title("mean duration per whisker (ms)")
    return _save(fig, path)


def in_contact_figure(stats: dict, path: Path) -> Path:
    plt = pyplot()
    counts = np.asarray(stats["whiskers_in_contact"]["counts"], float)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.bar(np.arange(len(counts)), counts / counts.sum())
    ax.set_xlabel("whiskers in contact at a time step")
    ax.set_ylabel("fraction of time steps")
    ax.set_title(f"mean {number(stats['whiskers_in_contact']['mean'])} whiskers in contact")
    return _save(fig, path)


def correlation_figure(stats: dict, path: Path) -> Path:
    plt = pyplot()
    corr = stats["moment_correlation"]
    matrix = np.array([[np.nan if v is None else v for v in row] for row in corr["matrix"]], float)
    names = corr["order"]
    fig, ax = plt.subplots(figsize=(0.16 * len(names) + 4, 0.16 * len(names) + 3))
    image = ax.imshow(matrix, cmap="RdBu_r", vmin=-1, vmax=1)
    small = 6 if len(names) > 20 else 8
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=small)
    ax.set_yticks(range(len(names)), names, fontsize=small)
    fig.colorbar(image, ax=ax, label="Pearson r of M")
    ax.set_title("moment magnitude correlation (by side, row, column)")
    return _save(fig, path)


def scenes_figure(stats: dict, path: Path) -> Path:
    """P(contact) per whisker for each scene class and scene, and their mean whiskers in contact."""
    plt = pyplot()
    order = stats["moment_correlation"]["order_index"]
    names = [stats["whiskers"][i] for i in order]
    groups = {**{f"class {k}": v for k, v in stats["scene_classes"].items()}, **stats["scenes"]}
    labels = [f"{name} ({data['trials']})" for name, data in groups.items()]
    matrix = np.array([np.asarray(data["contact_probability"], float)[order] for data in groups.values()])
    fig, axes = plt.subplots(1, 2, figsize=(14, 0.35 * len(groups) + 2.5), gridspec_kw={"width_ratios": [4, 1]},
                             layout="constrained")
    image = axes[0].imshow(matrix, aspect="auto", cmap="viridis", vmin=0)
    axes[0].set_xticks(range(len(names)), names, rotation=90, fontsize=6 if len(names) > 20 else 8)
    axes[0].set_yticks(range(len(labels)), labels, fontsize=8)
    fig.colorbar(image, ax=axes[0], label="P(contact)")
    axes[1].barh(range(len(labels)), [g["whiskers_in_contact_mean"] for g in groups.values()])
    axes[1].set_yticks(range(len(labels)), [])
    axes[1].invert_yaxis()
    axes[1].set_xlabel("mean whiskers in contact")
    fig.suptitle("scene classes and scenes (trials)")
    return _save(fig, path)


def write_figures(stats: dict, out: Path) -> list[Path]:
    out = Path(out)
    return [contact_map(stats, out / "contact_probability.png"),
            poc_figure(stats, out / "point_of_contact.png"),
            histograms(stats, "moment_magnitude", "bin_edges_nm", "M (N·m)", out / "moment_histograms.png"),
            histograms(stats, "transverse_force", "bin_edges_n", "F_t (N)", out / "force_histograms.png"),
            duration_figure(stats, out / "contact_durations.png"),
            in_contact_figure(stats, out / "whiskers_in_contact.png"),
            correlation_figure(stats, out / "moment_correlation.png"),
            scenes_figure(stats, out / "scenes.png")]


MIN_CONTACT = 0.01      # contact probability for a whisker to enter the "strongest pairs" list

def _top(values, names, k: int = 5) -> str:
    values = np.array([np.nan if v is None else v for v in values], float)
    best = [i for i in np.argsort(-np.nan_to_num(values, nan=-np.inf))[:k] if np.isfinite(values[i])]
    return ", ".join(f"{names[i]} {number(values[i], 3)}" for i in best) or "–"


def _strongest_pairs(corr: dict, touching: set[str], k: int = 5) -> str:
    """The ``k`` largest |r| between whiskers that both touch (``touching``), left/right twins
    left out: whiskers that never touch carry only the drive's inertial moment, the same time
    course for all of them, and would top the list with r ≈ 1."""
    matrix = np.array([[np.nan if v is None else v for v in row] for row in corr["matrix"]], float)
    names = corr["order"]
    upper = tuple(np.array([(i, j) for i, j in zip(*np.triu_indices(len(matrix), 1))
                            if names[i][1:] != names[j][1:] and {names[i], names[j]} <= touching],
                           int).reshape(-1, 2).T)
    values = matrix[upper]
    best = np.argsort(-np.nan_to_num(np.abs(values), nan=-1))[:k]
    return ", ".join(f"{corr['order'][upper[0][i]]}–{corr['order'][upper[1][i]]} {number(values[i], 3)}"
                     for i in best if np.isfinite(values[i])) or "–"


def write_report(stats: dict, figures: list[Path], path: Path) -> Path:
    names = stats["whiskers"]
    doc = Markdown(f"Natural tactile statistics: {stats['dataset']}")
    doc.paragraph(f"{stats['trials_used']} ok trials of {stats['trials']} ({stats['trials_failed']} failed, "
                  f"{stats['trials_pending']} pending), {stats['valid_samples']} time steps at "
                  f"{number(stats['sampling_rate_hz'])} Hz, {len(names)} whiskers. Read one trial at a time "
                  f"from `{stats['file']}`; all numbers are in `stats.json`.")
    figure = {Path(f).stem: Path(f).name for f in figures}
    doc.heading("Contact probability")
    doc.paragraph(f"Fraction of time steps in which any link of a whisker touches. Highest: "
                  f"{_top(stats['contact_probability'], names)}.")
    doc.image("contact probability", figure["contact_probability"])
    doc.heading("Point of contact")
    doc.paragraph("POC = arc length fraction of S where the whisker touches (0 base, 1 tip; docs/dataset.md), "
                  f"over in-contact samples, bins of {100 * np.diff(stats['point_of_contact']['bin_edges'])[0]:.3g} % "
                  "of S. Mean POC: "
                  f"{_top(stats['point_of_contact']['mean'], names)} (highest).")
    doc.image("point of contact", figure["point_of_contact"])
    for key, unit, suffix, name in (("moment_magnitude", "N·m", "nm", "moment_histograms"),
                                    ("transverse_force", "N", "n", "force_histograms")):
        data = stats[key]
        edges, mean = data[f"bin_edges_{suffix}"], data[f"mean_{suffix}"]
        doc.heading(key.replace("_", " ").capitalize())
        doc.paragraph(f"Log-spaced bins (10 per decade, {number(edges[0])}–{number(edges[-1])} {unit}); "
                      f"{sum(data['underflow'])} steps below the first edge, {sum(data['overflow'])} above the "
                      f"last. Largest means ({unit}): {_top(mean, names)}.")
        doc.image(key, figure[name])
    d = stats["contact_duration"]
    doc.heading("Contact duration")
    doc.paragraph(f"{sum(d['counts'])} contacts (runs of consecutive in-contact steps, cut at trial ends), mean "
                  f"{number(d['mean_all_s'] and d['mean_all_s'] * 1e3)} ms. Longest mean per whisker (s): "
                  f"{_top(d['mean_s'], names)}.")
    doc.image("contact durations", figure["contact_durations"])
    doc.heading("Whiskers in contact per time step")
    doc.paragraph(f"Mean {number(stats['whiskers_in_contact']['mean'])}; no whisker in contact in "
                  f"{number(stats['whiskers_in_contact']['counts'][0] / max(stats['valid_samples'], 1))} of "
                  "the time steps.")
    doc.image("whiskers in contact", figure["whiskers_in_contact"])
    doc.heading("Cross-whisker correlation of moment magnitude")
    touching = {n for n, p in zip(names, stats["contact_probability"]) if p is not None and p >= MIN_CONTACT}
    doc.paragraph("Pearson correlation of M over all time steps, whiskers ordered by side, row and column. "
                  f"Strongest pairs of whiskers in contact ≥ {MIN_CONTACT:.0%} of the time (left/right twins "
                  f"aside): {_strongest_pairs(stats['moment_correlation'], touching)}.")
    doc.image("moment correlation", figure["moment_correlation"])
    doc.heading("Scenes and scene classes")
    rows = []
    for kind, groups in (("class", stats["scene_classes"]), ("scene", stats["scenes"])):
        for name, g in groups.items():
            rows.append([kind, name, g["trials"], number(float(np.mean(g["contact_probability"]))),
                         number(g["whiskers_in_contact_mean"]),
                         number(g["contact_duration_mean_s"] and g["contact_duration_mean_s"] * 1e3),
                         number(float(np.nanmean(np.asarray(g["moment_mean_nm"], float))))])
    doc.table(["", "name", "trials", "mean P(contact)", "whiskers in contact", "contact duration (ms)",
               "mean M (N·m)"], rows)
    doc.image("scenes", figure["scenes"])
    return doc.write(path)
