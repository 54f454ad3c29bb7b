"""Checks of a trial's arrays before it is written and when a dataset is verified.

Non-finite values. A trial whose base wrench, protraction or node positions hold a NaN or an
infinity within its samples is not ``ok`` (:func:`non_finite`; padding past a trial's last
sample is NaN by design and not counted).

Edge jumps. A trial must not start or end with an artefact of the protocol (docs/dataset.md):
for a whisker that touches nothing, the largest change between consecutive samples of its base
moment (or force) vector that touches the first or the last two samples — ‖x₁ − x₀‖, ‖x₂ − x₁‖,
‖x_{T−2} − x_{T−3}‖, ‖x_{T−1} − x_{T−2}‖ — is at most :data:`EDGE_JUMP_LIMIT` times the largest
change elsewhere (:func:`edge_jump_ratios`).

The writer refuses ``ok`` to a trial with non-finite values (:class:`~pipeline.datasets.writer.
DatasetWriter`); ``pipeline datasets show --verify`` reports both checks over a dataset
(:func:`scan`).
"""

from __future__ import annotations

import numpy as np

from pipeline.datasets.schema import WRENCH_PARTS
from pipeline.datasets.wrench import read_array, read_trial

EDGE_JUMP_LIMIT = 2.0          # edge jump / largest jump elsewhere above this is reported
EDGE_DIFFERENCES = 2           # consecutive-sample changes counted at each end
CHECKED_ARRAYS = ("base_force", "base_moment", "protraction_rad", "node_positions_m")


def edge_jump_ratios(wrench: np.ndarray) -> np.ndarray:
    """[W, 2] (moment, force): the largest change between consecutive samples of the vector
    at either end of the trial over the largest change elsewhere, per whisker of ``wrench``
    [T, W, 6] (SI, one trial's samples). NaN for trials too short to have an elsewhere
    (T < 2·:data:`EDGE_DIFFERENCES` + 2) and for a whisker whose signal never changes."""
    wrench = np.asarray(wrench, float)
    samples, whiskers = wrench.shape[:2]
    ratios = np.full((whiskers, 2), np.nan)
    if samples < 2 * EDGE_DIFFERENCES + 2:
        return ratios
    for column, part in enumerate((slice(3, 6), slice(0, 3))):
        jumps = np.linalg.norm(np.diff(wrench[:, :, part], axis=0), axis=-1)       # [T-1, W]
        edge = np.maximum(jumps[:EDGE_DIFFERENCES].max(axis=0), jumps[-EDGE_DIFFERENCES:].max(axis=0))
        inner = jumps[EDGE_DIFFERENCES:-EDGE_DIFFERENCES].max(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios[:, column] = np.where(inner > 0, edge / inner, np.nan)
    return ratios


def free_whiskers(contact: np.ndarray) -> np.ndarray:
    """[W] whiskers with no contact flag in ``contact`` [T, W, N]."""
    return ~np.asarray(contact, bool).any(axis=(0, 2))


def edge_jumps(wrench: np.ndarray, contact: np.ndarray) -> int:
    """How many whiskers that touched nothing have an edge jump above :data:`EDGE_JUMP_LIMIT`
    times their largest jump elsewhere (moment or force); ``wrench`` [T, W, 6], ``contact``
    [T, W, N], one trial's samples."""
    ratios = edge_jump_ratios(wrench)[free_whiskers(contact)]
    return int(np.sum(np.any(ratios > EDGE_JUMP_LIMIT, axis=1)))


def non_finite(arrays: dict[str, np.ndarray], samples: int, node_every: int) -> list[str]:
    """Names of the arrays among :data:`CHECKED_ARRAYS` with a non-finite value within the
    trial's first ``samples`` samples (node positions: the rows stored every ``node_every``-th
    sample up to then)."""
    rows = {"node_positions_m": samples // node_every if node_every else 0}
    return [name for name in CHECKED_ARRAYS if name in arrays
            and not np.isfinite(np.asarray(arrays[name])[:rows.get(name, samples)]).all()]


def scan(ds) -> dict:
    """Non-finite values and edge jumps of every ok trial of an open
    :class:`~pipeline.datasets.reader.DatasetFile` (``pipeline datasets show --verify``):
    ``non_finite_ok_trials`` (trial indices), ``edge_jump_trials`` and ``edge_jump_pairs`` (how
    many trials and (trial, free whisker) pairs have one) and ``edge_jump_worst`` (up to 5
    trials with the most)."""
    node_every = int(ds.attrs.get("node_every", 0) or 0)
    samples = ds.trial_columns["samples"]
    bad, jumps = [], {}
    for index in ds.ok:
        n = int(samples[index])
        arrays = read_trial(ds.samples, index, CHECKED_ARRAYS)
        if non_finite(arrays, n, node_every):
            bad.append(int(index))
        wrench = np.concatenate([arrays[part] for part in WRENCH_PARTS], axis=-1)
        count = edge_jumps(wrench[:n], read_array(ds.samples["contact"], index)[:n])
        if count:
            jumps[int(index)] = count
    return {"non_finite_ok_trials": bad, "edge_jump_trials": len(jumps), "edge_jump_pairs": sum(jumps.values()),
            "edge_jump_worst": sorted(jumps, key=lambda i: (-jumps[i], i))[:5]}
