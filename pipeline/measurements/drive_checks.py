"""Warnings about drives a fit cannot follow exactly (no errors: the data stay usable).

An abrupt motor stop recorded at the camera's 1 kHz is a corner in θ(t) that falls between
two samples: any interpolation (the fits use PCHIP) rounds it over one sample interval dt,
so near the stop the drive angle is known only to about |Δω|·dt/8 (Δω the change of angular
velocity at the corner), which the tip, at a distance S from the base, turns into a position
uncertainty of S·|Δω|·dt/8. A corner is a sample whose change of angular velocity is more
than ``KINK_RATIO`` times that two samples before and after (a smooth drive changes its
velocity gradually); it is reported when the tip uncertainty exceeds ``KINK_ERROR_M``, the
low end of tracking noise (the paper's pulse on the α whisker, stopped at 25 rad/s: ≈ 93 µm
at 1 kHz, warned; ≈ 9 µm at 10 kHz, not warned). The estimate is kinematic, an upper bound:
the whisker filters the drive, so the error of a fitted trajectory is smaller (≈ 10 µm
measured for the 1 kHz case).
"""

from __future__ import annotations

import numpy as np

KINK_RATIO = 5.0
KINK_ERROR_M = 20e-6


def abrupt_changes(time_s: np.ndarray, angles_rad: np.ndarray, arc_length_m: float) -> list[tuple[float, float, float]]:
    """(time s, |Δω| rad/s, tip uncertainty m) of every corner of a sampled rotation drive."""
    if len(time_s) < 5:
        return []
    dt = np.diff(time_s)
    omega = np.diff(angles_rad, axis=0) / dt[:, None]
    jump = np.linalg.norm(np.diff(omega, axis=0), axis=1)        # at samples 1 .. D−2
    step = 0.5 * (dt[1:] + dt[:-1])
    padded = np.pad(jump, 2, mode="edge")
    neighbours = np.maximum(padded[:-4], padded[4:])
    uncertainty = arc_length_m * jump * step / 8
    corners = np.flatnonzero((jump > KINK_RATIO * neighbours) & (uncertainty > KINK_ERROR_M))
    return [(float(time_s[i + 1]), float(jump[i]), float(uncertainty[i])) for i in corners]


def drive_warnings(trial_name: str, time_s: np.ndarray, angles_rad: np.ndarray, arc_length_m: float) -> list[str]:
    """One message per trial with corners (the largest reported)."""
    found = abrupt_changes(time_s, angles_rad, arc_length_m)
    if not found:
        return []
    when, jump, uncertainty = max(found, key=lambda c: c[2])
    rate = 1.0 / np.median(np.diff(time_s))
    return [f"trial '{trial_name}': the drive's angular velocity changes by {jump:.3g} rad/s within one "
            f"sample at t = {when:.4g} s ({rate:.0f} Hz drive; an abrupt stop?): near it the drive is "
            f"known to ≈ {uncertainty * 1e6:.0f} µm at the tip. Record the drive faster (≥ 10 kHz) or "
            f"resample it from its known shape"]
