"""Resonance protocol (paper §4.5.1, docs/model.md §5): a Gaussian pulse of base rotation, then ringing.

A straight whisker lies along x in the horizontal plane, its base clamped to a motor turning
about the vertical axis by ν(t) = ν0·exp(−½((t−μ)/σ)²), ν0 = π/3, σ = 25 ms, μ = 4σ, stopped
abruptly at 128 ms and held. 1 s at 1 kHz; after dropping the first 125 samples, f1 is the
FFT peak of the tip's y coordinate and δ = ln(y0/y1) of the first two peaks after release.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks

from pipeline.config.physics import ModelConfig
from pipeline.model.array import single_whisker
from pipeline.model.extensions import model_parts
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes import empty

PULSE_AMPLITUDE_RAD = np.pi / 3
PULSE_SIGMA_S = 0.025
STOP_S = 0.128
DURATION_S = 1.0
DROPPED_SAMPLES = 125


def pulse_drive(stop_s: float = STOP_S, duration_s: float = DURATION_S) -> ProtractionDrive:
    """ν(t) of eq. 5 until ``stop_s``, then held (piecewise linear at 10 µs)."""
    t = np.arange(0.0, duration_s + 1e-9, 1e-5)
    mu = 4 * PULSE_SIGMA_S
    nu = PULSE_AMPLITUDE_RAD * np.exp(-0.5 * ((np.minimum(t, stop_s) - mu) / PULSE_SIGMA_S) ** 2)
    return ProtractionDrive(t, nu, interpolation="linear")


@dataclass(frozen=True)
class ResonanceResult:
    f1_hz: float                 # FFT peak, refined between bins (parabolic, zero-padded)
    f1_fft_bin_hz: float         # the paper's plain FFT peak (bin spacing 1/0.875 s)
    log_decrement: float         # δ = ln(y0/y1), first two peaks after release
    damping_ratio: float         # ζ = δ/√(4π² + δ²)
    tip_y_m: np.ndarray          # [T] tip y (m), 1 kHz
    time_s: np.ndarray

    def as_dict(self) -> dict:
        return {"f1_hz": self.f1_hz, "log_decrement": self.log_decrement,
                "damping_ratio": self.damping_ratio, "f1_fft_bin_hz": self.f1_fft_bin_hz}


def spectral_peak(signal: np.ndarray, rate_hz: float, pad: int = 16) -> tuple[float, float]:
    """(refined, plain) frequency of the largest FFT peak above DC, Hz.

    The plain peak is the paper's method; the refined one searches a Hann-windowed,
    zero-padded spectrum within one plain bin of it and interpolates parabolically.
    """
    x = signal - signal.mean()
    plain = np.abs(np.fft.rfft(x))
    plain_bin = int(np.argmax(plain[1:]) + 1)
    n = len(x) * pad
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x)), n))
    lo, hi = (plain_bin - 1) * pad, (plain_bin + 1) * pad + 1
    k = int(np.argmax(spectrum[lo:hi]) + lo)
    if 1 <= k < len(spectrum) - 1:
        a, b, c = np.log(spectrum[k - 1:k + 2] + 1e-300)
        k = k + 0.5 * (a - c) / (a - 2 * b + c)
    return float(k * rate_hz / n), float(plain_bin * rate_hz / len(x))


def log_decrement(signal: np.ndarray) -> float:
    """ln(y0/y1) of the first two maxima of the oscillation about its final value."""
    tail = signal[int(0.8 * len(signal)):]
    y = signal - tail.mean()
    sign = 1.0 if abs(y.max()) >= abs(y.min()) else -1.0
    peaks, _ = find_peaks(sign * y)
    if len(peaks) < 2:
        return float("nan")
    y0, y1 = sign * y[peaks[0]], sign * y[peaks[1]]
    return float(np.log(y0 / y1)) if y0 > 0 and y1 > 0 else float("nan")


def analyse_tip(tip_y_m: np.ndarray, time_s: np.ndarray, rate_hz: float) -> ResonanceResult:
    ringing = tip_y_m[DROPPED_SAMPLES:]
    refined, plain = spectral_peak(ringing, rate_hz)
    after_stop = tip_y_m[time_s > STOP_S]
    delta = log_decrement(after_stop)
    zeta = delta / np.sqrt(4 * np.pi ** 2 + delta ** 2) if np.isfinite(delta) else float("nan")
    return ResonanceResult(refined, plain, delta, float(zeta), tip_y_m, time_s)


def run_resonance(geometry: WhiskerGeometry, config: ModelConfig) -> ResonanceResult:
    """Simulate the resonance protocol for one whisker and analyse its tip (SI in and out)."""
    from pipeline.engines import create_engine

    material, extensions = model_parts(config)
    array = single_whisker(geometry, material, extensions=extensions)
    with create_engine(config, array) as engine:
        output = engine.run(empty(), Pose(), pulse_drive(), DURATION_S)
    tip_y = output.node_positions_m[:, 0, -1, 1].astype(float)
    return analyse_tip(tip_y, output.time_s, config.engine.output_rate_hz)
