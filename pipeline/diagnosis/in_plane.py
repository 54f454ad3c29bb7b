"""The in-plane modes of a linearised chain that a summary or a correction needs, robust to
damping: a fitted model may be overdamped in-plane (ζ ≥ 1 leaves no oscillating in-plane
mode, and ζ near 1 a damped frequency near 0 Hz), which is a finding, not an error.

- :func:`undamped_in_plane_hz`: natural frequencies ω/2π (Hz) of the undamped modes whose
  mass-normalised shape is mostly in-plane (z joints), ascending; they exist for any damping.
- :func:`first_damped_in_plane`: damped frequency (Hz) and damping ratio of the first
  oscillating in-plane mode, NaN for both when there is none.
"""

from __future__ import annotations

import numpy as np

from pipeline.engines.linear.modal import damped_modes, modal
from pipeline.engines.linear.chain import LinearWhisker

IN_PLANE_PREFIXES = ("z", "follicle_z")


def undamped_in_plane_hz(lin: LinearWhisker) -> np.ndarray:
    """Undamped in-plane natural frequencies (Hz), ascending."""
    mod = modal(lin)
    rows = [i for i, s in enumerate(lin.dofs.labels) if s.startswith(IN_PLANE_PREFIXES)]
    share = (mod.shapes[rows] ** 2).sum(axis=0) / (mod.shapes ** 2).sum(axis=0)
    return np.sort(mod.omega[share > 0.5]) / (2 * np.pi)


def first_damped_in_plane(lin: LinearWhisker) -> tuple[float, float]:
    """(damped frequency Hz, damping ratio) of the first oscillating in-plane mode; (NaN, NaN)
    when the chain has none (overdamped in-plane)."""
    freqs, zetas, in_plane = damped_modes(lin)
    if not in_plane.any():
        return float("nan"), float("nan")
    return float(freqs[in_plane][0]), float(zetas[in_plane][0])
