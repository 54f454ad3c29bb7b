"""Prescribed rotations θ(t) (rad, about the rest frame's z) of the follicle about the base point."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Still:
    """The base held at θ = 0 (releases)."""

    breaks: tuple = ()

    def angle(self, t):
        return 0.0 * np.asarray(t, float)

    def rate(self, t):
        return 0.0 * np.asarray(t, float)


@dataclass(frozen=True)
class GaussianPulse:
    """θ(t) = amplitude·exp(−½((t − 4σ)/σ)²) until ``stop_s``, then held (paper eq. 5 with the
    resonance protocol's abrupt stop). amplitude rad, sigma_s and stop_s s."""

    amplitude_rad: float
    sigma_s: float = 0.025
    stop_s: float = 0.128

    @property
    def breaks(self) -> tuple:
        return (self.stop_s,)

    def angle(self, t):
        t = np.minimum(np.asarray(t, float), self.stop_s)
        return self.amplitude_rad * np.exp(-0.5 * ((t - 4 * self.sigma_s) / self.sigma_s) ** 2)

    def rate(self, t):
        t = np.asarray(t, float)
        x = (t - 4 * self.sigma_s) / self.sigma_s
        moving = self.amplitude_rad * np.exp(-0.5 * x ** 2) * (-x / self.sigma_s)
        return np.where(t < self.stop_s, moving, 0.0)
