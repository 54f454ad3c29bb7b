"""Natural tactile statistics of a dataset (``pipeline stats``), streamed one ok trial at a time.

Each ok trial's valid samples are read (base wrench, contact flags and the stored point of
contact), folded into running sums (:class:`Tally`: counts, log-binned histograms,
a merged covariance) per scene and then dropped, so memory does not grow with the number of
trials. Per-scene tallies merge into the
scene classes (the part of the scene name before ``:``) and into the whole dataset.

A whisker is *in contact* at a sample when any of its links is; its point of contact (POC,
arc length fraction of S, docs/dataset.md) is binned on :data:`POC_BINS` whatever the number
of links. Moment magnitude
M = √(Mx² + My² + Mz²) (eq. 10), transverse force F_t = √(Fy² + Fz²) (eq. 7); both are binned
on fixed log-spaced edges (10 per decade) so that reports of different datasets compare;
values below the first edge (M = 0 included) count as underflow, above the last as overflow.
A contact run is a maximal stretch of consecutive in-contact samples of one whisker; runs end
with their trial.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.activity import Activity
from pipeline.datasets.reader import DatasetFile
from pipeline.datasets.versions import resolve
from pipeline.errors import UserError
from pipeline.reports.document import write_json
from pipeline.reports.stats_figures import write_figures, write_report

MOMENT_BINS_NM = np.logspace(-12, -3, 91)
FORCE_BINS_N = np.logspace(-10, -1, 91)
POC_BINS = np.linspace(0.0, 1.0, 51)       # 2 % of the arc length S per bin
DEFAULT_OUT = Path("reports/stats")


def moment_magnitude(wrench: np.ndarray) -> np.ndarray:
    """[..., 6] → [...] M (N·m), float64."""
    return np.sqrt((wrench[..., 3:].astype(np.float64) ** 2).sum(-1))


def transverse_force(wrench: np.ndarray) -> np.ndarray:
    """[..., 6] → [...] F_t (N), float64."""
    return np.sqrt((wrench[..., 1:3].astype(np.float64) ** 2).sum(-1))


def contact_runs(touching: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(whisker, start sample, length) of every run of True in ``touching`` [T, W], ordered by
    whisker, then start."""
    t, w = touching.shape
    padded = np.zeros((w, t + 2), np.int8)
    padded[:, 1:-1] = np.asarray(touching, bool).T
    step = np.diff(padded, axis=1)
    whisker, start = np.nonzero(step == 1)
    _, stop = np.nonzero(step == -1)
    return whisker, start, stop - start


@dataclass
class Histogram:
    """Counts per whisker on fixed ``edges`` (numpy's rule: the last bin includes its right
    edge); NaN values are skipped."""

    edges: np.ndarray
    counts: np.ndarray        # [W, bins]
    underflow: np.ndarray     # [W]
    overflow: np.ndarray      # [W]

    @classmethod
    def empty(cls, edges: np.ndarray, whiskers: int) -> "Histogram":
        return cls(np.asarray(edges, float), np.zeros((whiskers, len(edges) - 1), np.int64),
                   np.zeros(whiskers, np.int64), np.zeros(whiskers, np.int64))

    def add(self, values: np.ndarray) -> None:
        """Count ``values`` [T, W]."""
        values = np.asarray(values, float)
        bins = len(self.edges) - 1
        index = np.searchsorted(self.edges, values, side="right") - 1
        index[values == self.edges[-1]] = bins - 1
        inside = (index >= 0) & (index < bins) & ~np.isnan(values)
        flat = (np.broadcast_to(np.arange(values.shape[1]), values.shape) * bins + index)[inside]
        self.counts += np.bincount(flat, minlength=self.counts.size).reshape(self.counts.shape)
        self.underflow += (values < self.edges[0]).sum(axis=0)
        self.overflow += (values > self.edges[-1]).sum(axis=0)

    def __iadd__(self, other: "Histogram") -> "Histogram":
        self.counts += other.counts
        self.underflow += other.underflow
        self.overflow += other.overflow
        return self


@dataclass
class RunningCovariance:
    """Count, mean and co-moment of [T, W] samples, merged chunk by chunk (Chan et al.)."""

    n: int
    mean: np.ndarray          # [W]
    comoment: np.ndarray      # [W, W] Σ (x − mean)(x − mean)ᵀ

    @classmethod
    def empty(cls, whiskers: int) -> "RunningCovariance":
        return cls(0, np.zeros(whiskers), np.zeros((whiskers, whiskers)))

    def add(self, x: np.ndarray) -> None:
        x = np.asarray(x, np.float64)
        if len(x):
            mean = x.mean(axis=0)
            centred = x - mean
            self += RunningCovariance(len(x), mean, centred.T @ centred)

    def __iadd__(self, other: "RunningCovariance") -> "RunningCovariance":
        if other.n:
            n = self.n + other.n
            delta = other.mean - self.mean
            self.comoment = self.comoment + other.comoment + np.outer(delta, delta) * (self.n * other.n / n)
            self.mean = self.mean + delta * (other.n / n)
            self.n = n
        return self

    def correlation(self) -> np.ndarray:
        """[W, W] Pearson correlation; NaN for a whisker whose values never change."""
        sd = np.sqrt(np.diag(self.comoment))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = self.comoment / np.outer(sd, sd)
        corr[~np.isfinite(corr)] = np.nan
        return corr


@dataclass
class Tally:
    """Running sums of the statistics over the trials of one scene (or merged over several)."""

    whiskers: int
    samples: int                  # longest trial: bound of a contact run
    trials: int = 0
    valid_samples: int = 0
    contact_samples: np.ndarray = field(init=False)
    in_contact: np.ndarray = field(init=False)              # [W+1] samples with k whiskers in contact
    runs: np.ndarray = field(init=False)                    # [samples+1] runs by length (samples)
    runs_per_whisker: np.ndarray = field(init=False)
    run_samples_per_whisker: np.ndarray = field(init=False)
    moment_in_contact_sum: np.ndarray = field(init=False)   # Σ M over in-contact samples
    poc_sum: np.ndarray = field(init=False)                 # Σ POC over in-contact samples
    force_sum: np.ndarray = field(init=False)

    def __post_init__(self):
        w = self.whiskers
        self.contact_samples = np.zeros(w, np.int64)
        self.in_contact = np.zeros(w + 1, np.int64)
        self.runs = np.zeros(self.samples + 1, np.int64)
        self.runs_per_whisker = np.zeros(w, np.int64)
        self.run_samples_per_whisker = np.zeros(w, np.int64)
        self.moment_in_contact_sum = np.zeros(w)
        self.poc_sum = np.zeros(w)
        self.force_sum = np.zeros(w)
        self.moment = Histogram.empty(MOMENT_BINS_NM, w)
        self.moment_contact = Histogram.empty(MOMENT_BINS_NM, w)
        self.force = Histogram.empty(FORCE_BINS_N, w)
        self.force_contact = Histogram.empty(FORCE_BINS_N, w)
        self.poc = Histogram.empty(POC_BINS, w)
        self.moment_cov = RunningCovariance.empty(w)

    def add_trial(self, wrench: np.ndarray, touching: np.ndarray, poc: np.ndarray) -> None:
        """One trial's valid samples: wrench [T, W, 6], touching [T, W], POC [T, W] (NaN: none;
        counted where touching)."""
        m, ft = moment_magnitude(wrench), transverse_force(wrench)
        self.trials += 1
        self.valid_samples += len(touching)
        self.contact_samples += touching.sum(axis=0)
        self.in_contact += np.bincount(touching.sum(axis=1), minlength=self.whiskers + 1)
        whisker, _, length = contact_runs(touching)
        self.runs += np.bincount(length, minlength=self.samples + 1)
        self.runs_per_whisker += np.bincount(whisker, minlength=self.whiskers)
        self.run_samples_per_whisker += np.bincount(whisker, weights=length, minlength=self.whiskers).astype(np.int64)
        self.moment_in_contact_sum += np.where(touching, m, 0.0).sum(axis=0)
        self.force_sum += ft.sum(axis=0)
        self.moment.add(m)
        self.moment_contact.add(np.where(touching, m, np.nan))
        self.force.add(ft)
        self.force_contact.add(np.where(touching, ft, np.nan))
        poc = np.where(touching, np.asarray(poc, np.float64), np.nan)
        self.poc.add(poc)
        self.poc_sum += np.nansum(poc, axis=0)
        self.moment_cov.add(m)

    def __iadd__(self, other: "Tally") -> "Tally":
        for name in ("trials", "valid_samples", "contact_samples", "in_contact", "runs", "runs_per_whisker",
                     "run_samples_per_whisker", "moment_in_contact_sum", "poc_sum", "force_sum"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for name in ("moment", "moment_contact", "force", "force_contact", "poc", "moment_cov"):
            mine = getattr(self, name)
            mine += getattr(other, name)
        return self

    # -- derived -------------------------------------------------------------------------
    @property
    def contact_probability(self) -> np.ndarray:
        return self.contact_samples / max(self.valid_samples, 1)

    def mean_in_contact(self) -> float:
        return float(np.arange(self.whiskers + 1) @ self.in_contact / max(self.valid_samples, 1))

    def mean_run_s(self, rate_hz: float) -> float:
        total = self.runs.sum()
        return float(np.arange(len(self.runs)) @ self.runs / total / rate_hz) if total else float("nan")

    def summary(self, rate_hz: float) -> dict:
        """The short per-scene numbers compared across scenes."""
        with np.errstate(invalid="ignore", divide="ignore"):
            moment_contact = self.moment_in_contact_sum / self.contact_samples
        return {"trials": self.trials, "valid_samples": self.valid_samples,
                "contact_probability": self.contact_probability,
                "whiskers_in_contact_mean": self.mean_in_contact(),
                "contact_duration_mean_s": self.mean_run_s(rate_hz),
                "moment_mean_nm": self.moment_cov.mean,
                "moment_in_contact_mean_nm": moment_contact}


def scene_class(scene: str) -> str:
    """``mesh:rock`` → ``mesh``; fixed scenes are their own class."""
    return scene.split(":", 1)[0]


def array_order(rows: np.ndarray, cols: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """Whisker indices ordered right side first, then by row (A…E), then by column (0 = Greek)."""
    return np.lexsort((cols, rows, -np.asarray(sides)))


def read_tallies(ds, activity: Activity | None = None) -> dict[str, Tally]:
    """One :class:`Tally` per scene over the ok trials of the open dataset ``ds``, read one trial
    at a time (only its valid samples); ``activity`` is told how many are read."""
    names, samples = ds.whiskers["name"], int(ds.attrs["samples"])
    wrench, contact, point_of_contact = ds.base_wrench, ds.contact, ds.point_of_contact
    tallies: dict[str, Tally] = {}
    for done, i in enumerate(ds.ok):
        if activity is not None:
            activity.update(f"read {done}/{len(ds.ok)} ok trials")
        i = int(i)
        n = int(ds.trials["samples"][i]) or samples
        window = dict(trial=i, time=slice(0, n))
        touching = contact.isel(**window).values.astype(bool).any(axis=2)
        scene = str(ds.trials["scene"][i])
        tally = tallies.setdefault(scene, Tally(len(names), samples))
        tally.add_trial(wrench.isel(**window).values, touching, point_of_contact.isel(**window).values)
    return tallies


def merged(tallies) -> Tally:
    tallies = list(tallies)
    total = Tally(tallies[0].whiskers, tallies[0].samples)
    for tally in tallies:
        total += tally
    return total


def statistics(tallies: dict[str, Tally], whiskers: dict, rate_hz: float) -> dict:
    """The JSON of stats.json (without the dataset's identity) from the per-scene tallies."""
    total = merged(tallies.values())
    names = [str(n) for n in whiskers["name"]]
    order = array_order(whiskers["row"], whiskers["col"], whiskers["side"])
    corr = total.moment_cov.correlation()
    classes: dict[str, Tally] = {}
    for scene, tally in tallies.items():
        classes.setdefault(scene_class(scene), Tally(tally.whiskers, tally.samples))
        classes[scene_class(scene)] += tally
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_run = total.run_samples_per_whisker / total.runs_per_whisker / rate_hz
        poc_mean = total.poc_sum / total.poc.counts.sum(axis=1)
    all_probability = total.contact_probability
    return {
        "valid_samples": total.valid_samples, "sampling_rate_hz": rate_hz,
        "whiskers": names, "whisker_row": whiskers["row"], "whisker_col": whiskers["col"],
        "whisker_side": whiskers["side"],
        "contact_probability": all_probability, "contact_samples": total.contact_samples,
        "whiskers_in_contact": {"counts": total.in_contact, "mean": total.mean_in_contact()},
        "point_of_contact": {"bin_edges": total.poc.edges, "counts": total.poc.counts, "mean": poc_mean},
        "moment_magnitude": {"bin_edges_nm": MOMENT_BINS_NM, "counts": total.moment.counts,
                             "counts_in_contact": total.moment_contact.counts,
                             "underflow": total.moment.underflow, "overflow": total.moment.overflow,
                             "mean_nm": total.moment_cov.mean},
        "transverse_force": {"bin_edges_n": FORCE_BINS_N, "counts": total.force.counts,
                             "counts_in_contact": total.force_contact.counts,
                             "underflow": total.force.underflow, "overflow": total.force.overflow,
                             "mean_n": total.force_sum / max(total.valid_samples, 1)},
        "contact_duration": {"counts": total.runs, "mean_all_s": total.mean_run_s(rate_hz),
                             "runs": total.runs_per_whisker, "mean_s": mean_run},
        "moment_correlation": {"order": [names[i] for i in order], "order_index": order,
                               "matrix": corr[np.ix_(order, order)]},
        "scenes": {scene: {**t.summary(rate_hz),
                           "contact_probability_minus_all": t.contact_probability - all_probability}
                   for scene, t in sorted(tallies.items())},
        "scene_classes": {name: t.summary(rate_hz) for name, t in sorted(classes.items())},
    }


def stats_report(target: str | Path, root: str | Path | None, out: str | Path | None = None,
                 activity: Activity | None = None) -> dict:
    """Write report.md, the figures and stats.json of a dataset's ok trials into ``out``
    (default ``reports/stats/<name>_v<k>/``); returns a summary with their paths. ``activity``
    shows each step (and the trials read) on stderr."""
    start = time.perf_counter()
    path = resolve(target, root)
    with DatasetFile(path) as ds:
        label = str(ds.attrs.get("label") or ds.attrs.get("name") or path.stem)
        counts = {"trials": len(ds.status), "trials_ok": len(ds.ok), "trials_failed": len(ds.failed),
                  "trials_pending": len(ds.pending)}
        if not counts["trials_ok"]:
            raise UserError(f"{label}: no trial has status ok ({counts['trials_failed']} failed, "
                            f"{counts['trials_pending']} pending)")
        rate = float(ds.attrs["sampling_rate_hz"])
        activity = activity or Activity("stats", enabled=False)
        activity.step(f"reading the {counts['trials_ok']} ok trials of {label}")
        tallies = read_tallies(ds, activity)
        whiskers = {k: ds.whiskers[k].to_numpy() for k in ("name", "row", "col", "side")}
    out = Path(out) if out is not None else DEFAULT_OUT / label.replace("/", "_")
    out.mkdir(parents=True, exist_ok=True)
    activity.step("computing the statistics")
    stats = {"dataset": label, "file": str(path), **counts, "trials_used": counts["trials_ok"],
             **statistics(tallies, whiskers, rate)}
    activity.step(f"drawing the figures into {out}")
    figures = write_figures(stats, out)
    stats["seconds"] = time.perf_counter() - start
    json_path = write_json(out / "stats.json", stats)
    report = write_report(stats, figures, out / "report.md")
    return {"dataset": label, "trials_used": counts["trials_ok"], "seconds": time.perf_counter() - start,
            "report": str(report), "json": str(json_path), "figures": [str(f) for f in figures],
            "out": str(out)}
