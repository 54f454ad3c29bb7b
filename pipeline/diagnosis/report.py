"""``pipeline diagnose --report DIR``: a markdown report with PNG figures.

Time series: measured vs simulated tip trajectories (baseline and named cause), residual
spectra of the tip per direction, error along the whisker, candidate scores. Resonance
tables: measured vs simulated features per whisker and what the table can identify.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from pipeline.diagnosis.deflection import body as base_frame
from pipeline.diagnosis.drives import base_motion
from pipeline.diagnosis.residuals import DIRECTIONS, tip_residual_spectra


def _pyplot():
    matplotlib.use("Agg")
    return plt


def _params_table(params: dict) -> list[str]:
    lines = ["| parameter | value | sd | unit |", "|---|---|---|---|"]
    lines += [f"| {n} | {p['value']:.4g} | {p['sd']:.2g} | {p['unit']} |" for n, p in params.items()]
    return lines


def _tip_figure(plt, measurement, diagnosis, path: Path) -> None:
    trials = measurement.trials
    fig, axes = plt.subplots(len(trials), 2, figsize=(11, 2.2 * len(trials)), squeeze=False, sharex="row")
    for row, trial in enumerate(trials):
        rotation = base_motion(trial.drive, trial.time_s).rotation
        tip = [int(np.argmax(trial.arc_fraction))]

        def body(positions):
            return base_frame(trial, positions[:, tip], rotation)[:, 0] * 1e3

        for col, (axis, label) in enumerate(((1, "in-plane y"), (2, "out-of-plane z"))):
            ax = axes[row, col]
            ax.plot(trial.time_s, body(trial.positions_m)[:, axis], ".", ms=2, color="0.5", label="measured")
            ax.plot(trial.time_s, body(diagnosis.simulated["baseline"][row])[:, axis], lw=1, label="baseline")
            if diagnosis.cause not in ("none", "unexplained"):
                ax.plot(trial.time_s, body(diagnosis.simulated["cause"][row])[:, axis], lw=1,
                        label=diagnosis.cause)
            ax.set_title(f"{trial.name}: tip {label} (base frame)", fontsize=9)
            ax.set_ylabel("mm")
        axes[row, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _spectra_figure(plt, measurement, diagnosis, path: Path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.2), sharey=True)
    for key in ("baseline", "cause"):
        if key == "cause" and diagnosis.cause in ("none", "unexplained"):
            continue
        freq, spectra = tip_residual_spectra(measurement, diagnosis.simulated[key])
        for ax, d in zip(axes, DIRECTIONS):
            ax.semilogy(freq, spectra[d], label=key if key == "baseline" else diagnosis.cause)
    for ax, d in zip(axes, DIRECTIONS):
        ax.set_title(f"tip residual, {d}", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
    axes[0].set_ylabel("PSD (m²/Hz)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _along_figure(plt, diagnosis, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for label, analysis in (("baseline", diagnosis.analysis), (diagnosis.cause, diagnosis.cause_analysis)):
        data = analysis["by_arc_fraction_m"]
        ax.plot([float(k) for k in data], np.array(list(data.values())) * 1e3, "o-", label=label)
    ax.axhline(diagnosis.noise_m * 1e3, color="0.6", ls="--", label="noise σ̂")
    ax.set_xlabel("arc fraction s/S")
    ax.set_ylabel("RMS residual (mm, per coordinate)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _scores_figure(plt, diagnosis, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 3.2))
    names = [c.name for c in diagnosis.candidates]
    errors = np.array([c.heldout_error for c in diagnosis.candidates]) * 1e3
    colors = ["C3" if n == diagnosis.cause else "C0" for n in names]
    ax.bar(names, errors, color=colors)
    ax.axhline(diagnosis.baseline_heldout * 1e3, color="k", label="baseline")
    ax.axhline(diagnosis.noise_m * 1e3, color="0.6", ls="--", label="noise σ̂")
    ax.set_ylabel("held-out RMS (mm)")
    ax.tick_params(axis="x", labelrotation=30, labelsize=8)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(directory: str | Path, measurement, diagnosis) -> Path:
    """Write report.md and its figures for a time-series diagnosis; returns the markdown path."""
    plt = _pyplot()
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    _tip_figure(plt, measurement, diagnosis, out / "tip_trajectories.png")
    _spectra_figure(plt, measurement, diagnosis, out / "residual_spectra.png")
    _along_figure(plt, diagnosis, out / "error_along_whisker.png")
    _scores_figure(plt, diagnosis, out / "candidate_scores.png")
    a = diagnosis.analysis
    lines = [f"# Diagnosis of {measurement.path or measurement.whisker}", "",
             f"**Cause: {diagnosis.cause}.** Held-out RMS error {diagnosis.baseline_heldout * 1e3:.4f} mm "
             f"(baseline) → {diagnosis.gain_after * 1e3:.4f} mm; tracking noise estimated at "
             f"{diagnosis.noise_m * 1e3:.4f} mm per coordinate, model-error floor "
             f"{diagnosis.floor_m * 1e3:.4f} mm.", "",
             f"Training trials: {', '.join(diagnosis.split['train'])}; held out: "
             f"{', '.join(diagnosis.split['heldout'])}.", "", "## Fitted parameters", ""]
    lines += _params_table(diagnosis.final.params()) + ["", "## Baseline residuals (all trials)", "",
                                                        "| direction | RMS (mm) |", "|---|---|"]
    lines += [f"| {d} | {v * 1e3:.4f} |" for d, v in a["by_direction_m"].items()]
    lines += ["", "| arc fraction | RMS (mm) |", "|---|---|"]
    lines += [f"| {f} | {v * 1e3:.4f} |" for f, v in a["by_arc_fraction_m"].items()]
    lines += ["", "| trial | RMS (mm) | first 10 % (mm) | FRF measured (Hz) | FRF simulated (Hz) "
                  "| δ measured | δ simulated |",
              "|---|---|---|---|---|---|---|"]
    lines += [f"| {t['trial']} | {t['rms_m'] * 1e3:.4f} | {t['rms_first_tenth_m'] * 1e3:.4f} | "
              f"{t['frf_measured_hz']:.2f} | {t['frf_simulated_hz']:.2f} | {t['decrement_measured']:.3f} | "
              f"{t['decrement_simulated']:.3f} |" for t in a["trials"]]
    lines += ["", "## Candidates", "", "| candidate | held-out RMS (mm) | share of excess explained | ΔBIC |",
              "|---|---|---|---|"]
    lines += [f"| {c.name} | {c.heldout_error * 1e3:.4f} | {c.score:.2f} | {c.bic_delta:.1f} |"
              for c in diagnosis.candidates]
    lines += ["", *[f"- {n}" for n in diagnosis.notes], "",
              "![tip trajectories](tip_trajectories.png)", "", "![residual spectra](residual_spectra.png)", "",
              "![error along the whisker](error_along_whisker.png)", "",
              "![candidate scores](candidate_scores.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def write_table_report(directory: str | Path, table, diagnosis) -> Path:
    """Write report.md and a feature figure for a resonance-table diagnosis."""
    plt = _pyplot()
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    rows = diagnosis.rows
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.2))
    for ax, key, label in ((axes[0], "f1_hz", "f1 (Hz)"), (axes[1], "log_decrement", "log decrement δ")):
        x = np.arange(len(rows))
        meas = [r["measured"].get(key, (np.nan, np.nan)) for r in rows]
        ax.errorbar(x - 0.1, [m[0] for m in meas], yerr=[m[1] for m in meas], fmt="o", label="measured")
        ax.plot(x + 0.1, [r["simulated"][key] for r in rows], "s", label="baseline fit")
        ax.set_xticks(x, [r["whisker"] for r in rows])
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "features.png", dpi=110)
    plt.close(fig)
    lines = [f"# Diagnosis of {table.path}", "", f"**Cause: {diagnosis.cause}.** {diagnosis.summary}", "",
             "## Baseline fit", ""] + _params_table(diagnosis.baseline.params())
    lines += ["", "| whisker | feature | measured | simulated | (sim − exp)/sd |", "|---|---|---|---|---|"]
    for r in rows:
        for key, (value, sd) in r["measured"].items():
            lines.append(f"| {r['whisker']} | {key} | {value:.4g} ± {sd:.2g} | {r['simulated'][key]:.4g} | "
                         f"{r['z'][key]:+.2f} |")
    lines += ["", "## What this table can identify", "", "| candidate | parameter | verdict |", "|---|---|---|"]
    lines += [f"| {i['name']} | {i['param']} | {i['verdict']} |" for i in diagnosis.identifiability]
    lines += ["", *[f"- {n}" for n in diagnosis.notes], "", "![features](features.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
