"""Scalar features of a tip trajectory (paper §4.4.1) and the median symmetric accuracy.

The tip signal is the deflection of the most distal tracked point in the base frame
(R(t)ᵀ·p(t), minus its final resting value), projected on its principal transverse
direction, over the free ringing (after the last base motion, or from the release).
Features: FRF, the first-mode frequency (spectral peak, refined between bins), and the
magnitudes y0, y1 of the first two peaks on the side of the larger excursion, with
δ = ln(y0/y1). Peaks are read on the signal smoothed over about a quarter period
(Savitzky–Golay, quadratic; the same window for measurement and simulation) and must stand
out by a tenth of the largest excursion, so tracking noise neither makes peaks of its own
nor biases their heights.

MSA (eq. 4a, 4b): exp(median |ln(sim/exp)|) − 1 over the pooled features; 4a (motor-driven
trials) pools FRF, δ and the amplitude A = y0; 4b (release) pools FRF, y0 and y1.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks, savgol_filter

from pipeline.diagnosis.deflection import deflection
from pipeline.diagnosis.drives import base_motion, last_motion_time
from pipeline.measurements.timeseries import ReleaseDrive, Trial
from pipeline.signals.ringdown import spectral_peak

PEAK_PROMINENCE = 0.1       # of the largest excursion


def msa(log_ratios) -> float:
    """Median symmetric accuracy: exp(median |ln(sim/exp)|) − 1."""
    values = np.abs(np.asarray(log_ratios, float))
    values = values[np.isfinite(values)]
    return float(np.exp(np.median(values)) - 1) if values.size else float("nan")


def _fill(signal: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN samples (ends held; zeros when none is finite)."""
    good = np.isfinite(signal)
    if good.all():
        return signal
    if not good.any():
        return np.zeros_like(signal)
    index = np.arange(len(signal))
    return np.interp(index, index[good], signal[good])


class TipSignal:
    """How to turn a trial's positions into its scalar tip signal (fixed by the measurement):
    the tip's deflection (:mod:`.deflection`) on its principal direction among the measured
    transverse axes (y, and z when tracked)."""

    def __init__(self, trial: Trial, measured: np.ndarray):
        self.trial = trial
        self.point = int(np.argmax(trial.arc_fraction))
        self.rotation = base_motion(trial.drive, trial.time_s).rotation
        self.start = int(np.searchsorted(trial.time_s, last_motion_time(trial.drive)))
        self.axes = [a for a in (1, 2) if trial.measured_axes[a]]
        tip = self._deflection(measured)
        tracked = np.isfinite(tip).all(axis=1)
        # a drive still moving at the end leaves too few ringing frames for a direction
        transverse = tip[self.start:][tracked[self.start:]] if tracked[self.start:].sum() >= 3 else tip[tracked]
        _, _, vt = np.linalg.svd(transverse - transverse.mean(axis=0), full_matrices=False)
        self.direction = vt[0]

    def _deflection(self, positions: np.ndarray) -> np.ndarray:
        """[T, measured transverse axes] tip deflection (m)."""
        return deflection(self.trial, positions[:, [self.point]], self.rotation)[:, 0, self.axes]

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        """Ringing part of the projected tip deflection (m)."""
        return _fill(self._deflection(positions)[self.start:] @ self.direction)


def smoothing_window(signal: np.ndarray, rate_hz: float) -> int:
    """Odd window of about a quarter period of the signal's spectral peak (≥ 3 samples)."""
    peak = spectral_peak(signal, rate_hz)[0] if np.ptp(signal) > 0 else 0.0
    quarter = 0.25 * rate_hz / peak if peak > 0 else 0.0
    return int(max(3, 2 * int(quarter // 2) + 1))


def peaks(signal: np.ndarray, side: float, window: int) -> tuple[float, float]:
    """(y0, y1): the first two peak magnitudes on ``side`` (±1); NaN when missing."""
    if len(signal) > window:
        signal = savgol_filter(signal, window, 2)
    scale = np.abs(signal).max()
    found, _ = find_peaks(side * signal, prominence=PEAK_PROMINENCE * scale) if scale > 0 else ([], None)
    values = [side * signal[i] for i in found[:2] if side * signal[i] > 0]
    values += [np.nan] * (2 - len(values))
    return float(values[0]), float(values[1])


def features(signal: np.ndarray, rate_hz: float, side: float, window: int,
             release: bool) -> dict[str, float]:
    """FRF (Hz) and the eq. 4a (motor) or 4b (release) features of one ringing signal."""
    frf = spectral_peak(signal, rate_hz)[0] if len(signal) > 8 and np.ptp(signal) > 0 else np.nan
    y0, y1 = peaks(signal, side, window)
    if release:
        return {"frf_hz": frf, "y0_m": y0, "y1_m": y1}
    return {"frf_hz": frf, "log_decrement": decrement({"y0_m": y0, "y1_m": y1}), "amplitude_m": y0}


def decrement(f: dict[str, float]) -> float:
    """δ of a feature dict: its log decrement, or ln(y0/y1) for a release (NaN if undefined)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(f["log_decrement"] if "log_decrement" in f else np.log(f["y0_m"] / f["y1_m"]))


def dominant_side(signal: np.ndarray) -> float:
    return 1.0 if signal.max() >= -signal.min() else -1.0


def is_release(trial: Trial) -> bool:
    return isinstance(trial.drive, ReleaseDrive)
