"""The resonance protocol's drive and analysis (paper §4.5.1, docs/model.md §5), shared by the engine
protocol (:mod:`pipeline.protocols.resonance`) and the fast simulator (:mod:`pipeline.diagnosis`).

A straight whisker lies along x in the horizontal plane, its base clamped to a motor turning
about the vertical axis by ν(t) = ν0·exp(−½((t−μ)/σ)²), ν0 = π/3, σ = 25 ms, μ = 4σ, stopped
abruptly at 128 ms and held. 1 s at 1 kHz. Per-mode f and ζ come from a damped-sinusoid fit
to the tip's y from ``SETTLE_S`` after the stop (:mod:`pipeline.signals.ringdown`): the stop
leaves the whisker at its largest deflection, where the tip's y holds strong distortion
products of the modes, and excites the modes above the third. ``SETTLE_S`` is one decay time
1/(ζ4·ω4) of the slowest fourth mode among the library's untrimmed whiskers under either law
(C1 under Rayleigh damping: 274 Hz, ζ 0.196, 3.0 ms); from the stop itself the fit of that
whisker took a 73 Hz component for a mode. The paper's own numbers
(FFT peak after dropping the first 125 samples, δ = ln(y0/y1) of the first two peaks after
the stop) are kept under ``f1_fft_bin_hz`` and ``paper_log_decrement``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.signals.ringdown import fit_ringdown, paper_log_decrement, ratio_from_decrement, spectral_peak
from pipeline.model.kinematics import ProtractionDrive

PULSE_AMPLITUDE_RAD = np.pi / 3
PULSE_SIGMA_S = 0.025
STOP_S = 0.128
DURATION_S = 1.0
DROPPED_SAMPLES = 125
SETTLE_S = 0.003            # the ring-down fit starts this long after the stop (module docstring)


def pulse_drive(stop_s: float = STOP_S, duration_s: float = DURATION_S) -> ProtractionDrive:
    """ν(t) of eq. 5 until ``stop_s``, then held (piecewise linear at 10 µs)."""
    t = np.arange(0.0, duration_s + 1e-9, 1e-5)
    mu = 4 * PULSE_SIGMA_S
    nu = PULSE_AMPLITUDE_RAD * np.exp(-0.5 * ((np.minimum(t, stop_s) - mu) / PULSE_SIGMA_S) ** 2)
    return ProtractionDrive(t, nu, interpolation="linear")


MODES = 3                   # modes fitted and reported by default


@dataclass(frozen=True)
class ResonanceResult:
    """What the protocol measures on the tip's y (m) at the output rate.

    f1 and ζ1 come from a fit of damped sinusoids to the free ring-down from ``SETTLE_S`` after
    the stop (:func:`pipeline.signals.ringdown.fit_ringdown`), bounded by Nyquist; the paper's numbers
    (plain FFT peak, two-peak δ and the ζ derived from it) are kept under their own names.
    """

    frequencies_hz: tuple[float, ...]   # damped f1..fK of the ring-down fit
    damping_ratios: tuple[float, ...]   # ζ1..ζK of the same modes
    f1_fft_bin_hz: float                # the paper's plain FFT peak (bin spacing 1/0.875 s)
    paper_log_decrement: float          # the paper's δ = ln(y0/y1), first two peaks after the stop
    paper_damping_ratio: float          # ζ = δ/√(4π² + δ²) of that δ
    tip_y_m: np.ndarray                 # [T] tip y (m) at the output rate
    time_s: np.ndarray

    @property
    def f1_hz(self) -> float:
        return self.frequencies_hz[0] if self.frequencies_hz else float("nan")

    @property
    def damping_ratio(self) -> float:
        """ζ1, the first mode's damping ratio from the ring-down fit."""
        return self.damping_ratios[0] if self.damping_ratios else float("nan")

    def as_dict(self, modes: int | None = None) -> dict:
        """f1..fK (Hz), ζ1..ζK, and the paper's numbers; K = all fitted modes unless ``modes``."""
        k = len(self.frequencies_hz) if modes is None else modes
        out = {}
        for i in range(k):
            found = i < len(self.frequencies_hz)
            out[f"f{i + 1}_hz"] = self.frequencies_hz[i] if found else float("nan")
            out[f"zeta{i + 1}"] = self.damping_ratios[i] if found else float("nan")
        out.update({"f1_fft_bin_hz": self.f1_fft_bin_hz, "paper_log_decrement": self.paper_log_decrement,
                    "paper_damping_ratio": self.paper_damping_ratio})
        return out


def analyse_tip(tip_y_m: np.ndarray, time_s: np.ndarray, rate_hz: float, modes: int = MODES) -> ResonanceResult:
    """Ring-down fit of the free decay from ``SETTLE_S`` after the stop plus the paper's FFT peak
    and δ (its first two peaks after the stop itself)."""
    free = tip_y_m[time_s > STOP_S]
    fitted = fit_ringdown(tip_y_m[time_s > STOP_S + SETTLE_S], rate_hz, modes)
    plain = spectral_peak(tip_y_m[DROPPED_SAMPLES:], rate_hz)[1]
    delta = paper_log_decrement(free)
    return ResonanceResult(tuple(float(f) for f in fitted.frequencies_hz),
                           tuple(float(z) for z in fitted.damping_ratios), plain, delta,
                           ratio_from_decrement(delta), tip_y_m, time_s)
