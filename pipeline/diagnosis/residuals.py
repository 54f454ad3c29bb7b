"""Where a model misses a measurement: residuals (simulated − measured) in time, frequency,
along the whisker and per direction; and the tracking-noise level they are judged against.

Directions are those of the base frame (the residual rotated by R(t)ᵀ): x along the whisker
at its base (axial), y in the plane of the intrinsic curvature (in-plane), z out of plane.
The noise estimate uses second differences in time, Δ²r = r(t+h) − 2r(t) + r(t−h), whose
variance is 6σ² for white tracking noise while a smooth misfit contributes ≈ (2πf/rate)⁴ of
its own (≈ 3 % at 67 Hz and 1 kHz): σ̂ = √(mean(Δ²r²)/6) over every point and axis.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

from pipeline.diagnosis.deflection import body
from pipeline.diagnosis.features import (TipSignal, decrement, dominant_side, features, is_release,
                                         smoothing_window)
from pipeline.measurements.timeseries import TimeSeriesMeasurement

DIRECTIONS = ("axial", "in_plane", "out_of_plane")


def _body_residuals(trial, simulated: np.ndarray) -> np.ndarray:
    """[T, K, 3] simulated − measured in the base frame (NaN where not tracked)."""
    return body(trial, simulated - trial.positions_m)


def noise_estimate(measurement: TimeSeriesMeasurement, simulated: list[np.ndarray]) -> float:
    """σ̂ (m per coordinate) of the tracking noise, from second differences of the residuals."""
    total, count = 0.0, 0
    for trial, sim in zip(measurement.trials, simulated):
        r = sim - trial.positions_m
        d2 = r[2:] - 2 * r[1:-1] + r[:-2]
        d2 = d2[np.isfinite(d2)]
        total, count = total + float(d2 @ d2), count + d2.size
    return float(np.sqrt(total / (6 * count))) if count else float("nan")


def _rms(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")


def analyse(measurement: TimeSeriesMeasurement, simulated: list[np.ndarray]) -> dict:
    """JSON-ready summary: overall, per trial, per arc fraction, per direction, frequency."""
    body = [_body_residuals(t, s) for t, s in zip(measurement.trials, simulated)]
    fractions = np.unique(np.concatenate([t.arc_fraction for t in measurement.trials]))
    along = []
    for f in fractions:
        parts = [b[:, t.arc_fraction == f] for b, t in zip(body, measurement.trials) if f in t.arc_fraction]
        along.append(_rms(np.concatenate([p.ravel() for p in parts])))
    trials = []
    for trial, sim, b in zip(measurement.trials, simulated, body):
        signal = TipSignal(trial, trial.positions_m)
        measured = signal(trial.positions_m)
        side, window = dominant_side(measured), smoothing_window(measured, trial.sampling_rate_hz)
        meas_f = features(measured, trial.sampling_rate_hz, side, window, is_release(trial))
        sim_f = features(signal(sim), trial.sampling_rate_hz, side, window, is_release(trial))
        early = trial.time_s < trial.time_s[0] + 0.1 * (trial.time_s[-1] - trial.time_s[0])
        trials.append({
            "trial": trial.name, "rms_m": _rms(b),
            "rms_first_tenth_m": _rms(b[early]), "rms_rest_m": _rms(b[~early]),
            "frf_measured_hz": meas_f["frf_hz"], "frf_simulated_hz": sim_f["frf_hz"],
            "frf_shift_rel": sim_f["frf_hz"] / meas_f["frf_hz"] - 1 if meas_f["frf_hz"] > 0 else float("nan"),
            "decrement_measured": decrement(meas_f), "decrement_simulated": decrement(sim_f)})
    stacked = np.concatenate([b.reshape(-1, 3) for b in body])
    return {"rms_m": _rms(stacked),
            "by_direction_m": {d: _rms(stacked[:, i]) for i, d in enumerate(DIRECTIONS)},
            "by_arc_fraction_m": {f"{f:.3g}": v for f, v in zip(fractions, along)},
            "trials": trials}


def tip_residual_spectra(measurement: TimeSeriesMeasurement, simulated: list[np.ndarray]):
    """(frequency Hz, {direction: mean power spectral density m²/Hz}) of the tip residuals."""
    spectra, freq = {d: [] for d in DIRECTIONS}, None
    segment = min(256, *(len(trial.time_s) for trial in measurement.trials))   # one frequency grid
    for trial, sim in zip(measurement.trials, simulated):
        tip = _body_residuals(trial, sim)[:, int(np.argmax(trial.arc_fraction))]
        for i, d in enumerate(DIRECTIONS):
            series = tip[:, i]
            good = np.isfinite(series)
            series = np.interp(np.arange(len(series)), np.flatnonzero(good), series[good])
            freq, psd = welch(series, trial.sampling_rate_hz, nperseg=segment)
            spectra[d].append(psd)
    return freq, {d: np.mean(v, axis=0) for d, v in spectra.items()}
