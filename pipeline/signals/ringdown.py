"""Signal analysis of a free ring-down: per-mode frequency and damping ratio, and the paper's numbers.

A sampled free decay is modelled as a constant plus a sum of damped sinusoids,

    y(t) = c + Σ_k A_k·exp(−ζ_k·ω_k·t)·cos(ω_k·√(1 − ζ_k²)·t + φ_k),

and fitted in two steps: the matrix-pencil method (Hua & Sarkar 1990, IEEE Trans. ASSP 38:814)
gives the poles z = exp((−ζω ± iω_d)·h) of the signal; a variable-projection least-squares fit
of the damped frequencies and decay rates (amplitudes solved linearly) then refines those of
the leading modes. Every frequency is bounded to (0, Nyquist): a sampled signal cannot show
more. Frequencies are damped (ω_d/2π, Hz); ζ is the modal damping ratio.

Also here: the spectral peak (the paper's f1) and the paper's two-peak log decrement
δ = ln(y0/y1), which the second mode contaminates; kept because the paper's measured δ
(Table 1) were read that way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import find_peaks

MAX_POLES = 17              # largest pencil order: the constant and up to 8 conjugate pairs
RANK_TOLERANCE = 1e-4       # singular values below this fraction of the largest are noise
NYQUIST_MARGIN = 0.98       # poles above this fraction of Nyquist are not trusted
MAX_ZETA = 0.9              # more damped poles are not counted as oscillating modes
HARMONIC_TOLERANCE = 0.02   # relative frequency match of a distortion product of stronger components
PRODUCT_BANDWIDTH_SHARE = 0.25  # or this share of its own decay rate σ (a broad component's ω is that uncertain)
MAX_HARMONIC_ORDER = 3      # harmonics m·f of a mode taken for products (the m-th's share falls as (A/S)^(m−1))
PRODUCT_RATE_TOLERANCE = 0.35  # relative decay-rate match of one (weak components' rates are less certain)
MIN_SHARE = 0.01            # modes whose RMS over the record is below this fraction of the largest are dropped


@dataclass(frozen=True)
class Modes:
    """Damped modes of a ring-down, by ascending frequency: Hz, damping ratio, amplitude (signal units)."""

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    amplitudes: np.ndarray
    residual_rms: float          # RMS of the fitted model's residual (signal units)

    def first(self, k: int) -> "Modes":
        return Modes(self.frequencies_hz[:k], self.damping_ratios[:k], self.amplitudes[:k], self.residual_rms)


def spectral_peak(signal: np.ndarray, rate_hz: float, pad: int = 16) -> tuple[float, float]:
    """(refined, plain) frequency of the largest FFT peak above DC, Hz, both below Nyquist.

    The plain peak is the paper's method; the refined one searches a Hann-windowed,
    zero-padded spectrum within one plain bin of it and interpolates parabolically, by at most
    one padded bin (the unbounded vertex of a flat top once gave 539 Hz for a 341 Hz mode);
    both are capped at Nyquist (a sampled signal shows nothing above it).
    """
    x = signal - signal.mean()
    plain = np.abs(np.fft.rfft(x))
    plain_bin = int(np.argmax(plain[1:]) + 1)
    n = len(x) * pad
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x)), n))
    lo, hi = (plain_bin - 1) * pad, (plain_bin + 1) * pad + 1
    k = float(np.argmax(spectrum[lo:hi]) + lo)
    i = int(k)
    if 1 <= i < len(spectrum) - 1:
        a, b, c = np.log(spectrum[i - 1:i + 2] + 1e-300)
        k = i + float(np.clip(0.5 * (a - c) / (a - 2 * b + c), -1.0, 1.0))   # a flat top can extrapolate far
    nyquist = rate_hz / 2
    return float(np.clip(k * rate_hz / n, 0.0, nyquist)), float(plain_bin * rate_hz / len(x))


def paper_log_decrement(signal: np.ndarray) -> float:
    """The paper's δ = ln(y0/y1) of the first two maxima about the final value (NaN if undefined)."""
    tail = signal[int(0.8 * len(signal)):]
    y = signal - tail.mean()
    sign = 1.0 if abs(y.max()) >= abs(y.min()) else -1.0
    peaks, _ = find_peaks(sign * y)
    if len(peaks) < 2:
        return float("nan")
    y0, y1 = sign * y[peaks[0]], sign * y[peaks[1]]
    return float(np.log(y0 / y1)) if y0 > 0 and y1 > 0 else float("nan")


def ratio_from_decrement(delta: float) -> float:
    """ζ = δ/√(4π² + δ²) (NaN stays NaN)."""
    return float(delta / np.sqrt(4 * np.pi ** 2 + delta ** 2)) if np.isfinite(delta) else float("nan")


def _pencil_poles(vh: np.ndarray, rank: int) -> np.ndarray:
    """Signal poles z_i (complex) of the matrix pencil of rank ``rank`` (rows of ``vh``: right
    singular vectors of the signal's Hankel matrix)."""
    v = vh[:rank].conj().T                                   # [pencil+1, rank]
    return np.linalg.eigvals(np.linalg.pinv(v[:-1]) @ v[1:])


def _basis(t: np.ndarray, rates: np.ndarray, omegas: np.ndarray, decays: np.ndarray) -> np.ndarray:
    """[T, 1 + 2K + J] columns: 1, e^{−σt}cos ω t and e^{−σt}sin ω t per mode, e^{−λt} per decay."""
    decay = np.exp(-np.outer(t, rates))
    return np.hstack([np.ones((len(t), 1)), decay * np.cos(np.outer(t, omegas)),
                      decay * np.sin(np.outer(t, omegas)), np.exp(-np.outer(t, decays))])


def _components(poles: np.ndarray, h: float, nyquist: float, duration: float):
    """(ω_d, σ) of the poles that oscillate (below Nyquist, at least one cycle in the record,
    decaying, under-damped) and the rates λ of the other decaying poles (real exponentials)."""
    s = np.log(poles.astype(complex)) / h
    omega_d, rate = s.imag, -s.real
    decaying = rate > 0
    zeta = rate / np.maximum(np.abs(s), 1e-300)
    oscillating = (decaying & (omega_d * duration > 2 * np.pi) & (zeta < MAX_ZETA)
                   & (omega_d < NYQUIST_MARGIN * 2 * np.pi * nyquist))
    slow = decaying & (np.abs(omega_d) * duration <= 2 * np.pi)
    return omega_d[oscillating], rate[oscillating], np.unique(np.round(rate[slow], 9))


def _project(t, y, omega_d, rate, decays):
    """(amplitudes of the oscillations, residual) of the linear least-squares fit for fixed rates."""
    basis = _basis(t, rate, omega_d, decays)
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    k = len(omega_d)
    return np.hypot(coef[1:k + 1], coef[k + 1:2 * k + 1]), basis @ coef - y


def _refine(t, y, omega_d, rate, decays, nyquist: float):
    """Variable-projection least squares of ω_d (bounded by Nyquist), σ and λ from a start."""
    k = len(omega_d)
    p0 = np.concatenate([omega_d, rate, decays])
    upper = np.concatenate([np.full(k, 2 * np.pi * nyquist), np.full(len(p0) - k, np.inf)])
    lower = np.zeros_like(p0)
    fit = least_squares(lambda p: _project(t, y, p[:k], p[k:2 * k], p[2 * k:])[1],
                        np.clip(p0, lower + 1e-9, upper - 1e-9), bounds=(lower, upper),
                        x_scale=np.maximum(np.abs(p0), 1.0), max_nfev=30)
    return fit.x[:k], fit.x[k:2 * k], fit.x[2 * k:]


def _unresolved(omega_d: np.ndarray, rates: np.ndarray, amplitudes: np.ndarray) -> np.ndarray:
    """True where a component lies well inside the half-power band (|Δω| < (σ_i + σ_j)/2) of a stronger
    one: two such poles are one mode split by noise, not two modes."""
    close = np.abs(omega_d[:, None] - omega_d[None, :]) < 0.5 * (rates[:, None] + rates[None, :])
    weaker = amplitudes[:, None] < amplitudes[None, :]
    return (close & weaker).any(axis=1)


def _distortion_products(freqs: np.ndarray, rates: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """True where a component is a harmonic m·(f, σ), 2 ≤ m ≤ ``MAX_HARMONIC_ORDER``, of a stronger one, or a sum or difference
    tone (f_j ± f_k, σ_j + σ_k) of two stronger ones, within ``HARMONIC_TOLERANCE`` in frequency
    or ``PRODUCT_BANDWIDTH_SHARE`` of the component's own decay rate σ_i (ω, rad/s: the frequency of
    a weak, broad component is known to a fraction of its half-power band), and within
    ``PRODUCT_RATE_TOLERANCE`` in decay rate: products of the geometric nonlinearity (the tip's y is not
    linear in the joint angles), not modes."""
    out = np.zeros(len(freqs), bool)
    tolerance = np.maximum(HARMONIC_TOLERANCE, PRODUCT_BANDWIDTH_SHARE * rates / np.maximum(freqs, 1e-300))
    for i in range(len(freqs)):
        stronger = np.flatnonzero(weights > weights[i])
        for j in stronger:
            order = round(freqs[i] / freqs[j])
            if (2 <= order <= MAX_HARMONIC_ORDER and abs(freqs[i] / (order * freqs[j]) - 1) < tolerance[i]
                    and abs(rates[i] / (order * rates[j]) - 1) < PRODUCT_RATE_TOLERANCE):
                out[i] = True
            for k in stronger:
                if k <= j:
                    continue
                for tone in (freqs[j] + freqs[k], abs(freqs[j] - freqs[k])):
                    if (abs(freqs[i] / tone - 1) < tolerance[i]
                            and abs(rates[i] / (rates[j] + rates[k]) - 1) < PRODUCT_RATE_TOLERANCE):
                        out[i] = True
    return out


def fit_ringdown(signal: np.ndarray, rate_hz: float, modes: int = 3) -> Modes:
    """The ``modes`` lowest-frequency damped modes of a free decay sampled at ``rate_hz`` (Hz).

    The model order (how many components the whole decay holds) is the one of least BIC among
    pencil ranks up to ``MAX_POLES`` (amplitudes fitted linearly to the pencil's poles); only
    that model is refined, so components beyond ``modes`` are still modelled and do not bias
    the reported ones, and noise is not fitted as modes. Real decaying poles (a slow drift
    toward rest) are fitted as exponentials. Not reported as modes: distortion products
    (harmonics, sum and difference tones of stronger components), components inside a stronger
    one's half-power band, and components whose RMS over the record is below ``MIN_SHARE`` of
    the largest (a large but instantly decaying term fitted to the first samples is no mode);
    frequencies stay within (0, Nyquist). Fewer modes are returned when the signal holds fewer.
    """
    empty = Modes(np.array([]), np.array([]), np.array([]), float("nan"))
    y = np.asarray(signal, float)
    scale = np.ptp(y) if len(y) else 0.0
    if len(y) < 12 or not np.isfinite(y).all() or scale == 0:
        return empty
    h, nyquist = 1.0 / rate_hz, 0.5 * rate_hz
    y = (y - y.mean()) / scale
    t = np.arange(len(y)) * h
    hankel = np.lib.stride_tricks.sliding_window_view(y, len(y) // 3 + 1)
    _, singular, vh = np.linalg.svd(hankel, full_matrices=False)
    usable = int(min(MAX_POLES, np.sum(singular > RANK_TOLERANCE * singular[0])))
    best, best_bic = None, np.inf
    for rank in range(2, usable + 1):
        components = _components(_pencil_poles(vh, rank), h, nyquist, t[-1])
        if components[0].size == 0:
            continue
        rss = float(np.sum(_project(t, y, *components)[1] ** 2))
        parameters = 4 * len(components[0]) + 2 * len(components[2]) + 1
        bic = len(y) * np.log(max(rss, 1e-300) / len(y)) + parameters * np.log(len(y))
        if bic < best_bic:
            best, best_bic = components, bic
    if best is None:
        return empty
    omega_d, rate, decays = _refine(t, y, *best, nyquist)
    amplitude, residual = _project(t, y, omega_d, rate, decays)
    amplitude = amplitude * scale
    zeta = rate / np.hypot(omega_d, rate)
    duration = t[-1] + h
    weight = amplitude * np.sqrt(-np.expm1(-2 * rate * duration) / (2 * rate * duration))   # RMS over the record
    valid = (omega_d < NYQUIST_MARGIN * 2 * np.pi * nyquist) & (zeta < MAX_ZETA)
    if not valid.any():
        return empty
    counted = np.where(valid, weight, 0.0)      # a pole that is no mode hides none (an ω → 0, ζ → 1 drift)
    significant = (valid & (weight >= MIN_SHARE * weight[valid].max())
                   & ~_distortion_products(omega_d, rate, counted) & ~_unresolved(omega_d, rate, counted))
    order = np.argsort(omega_d[significant])[:modes]
    return Modes(omega_d[significant][order] / (2 * np.pi), zeta[significant][order],
                 amplitude[significant][order], float(np.sqrt(np.mean(residual ** 2)) * scale))
