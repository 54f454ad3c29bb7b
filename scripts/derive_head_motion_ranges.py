"""Derive the head-motion ranges of ``head_motion: approach`` from tracked freely moving rats.

Source data: Wallach, Deutsch, Oram & Ahissar (2020) "Predictive whisker kinematics reveal
context-dependent sensorimotor strategies", PLoS Biol 18(5):e3000571; data and code
github.com/avner-wallach/Rat-Behavior (commit 35ca4ba). Their ``Data/control_c2h_data.mat``
(intact rats) and ``Data/comparative_c2h_data.mat`` (rats with one whisker row) hold, per video
segment filmed from above at 500 frames/s, the head's heading (deg, eye midpoint → nose), the
eye midpoint (px) and the segment's mean eye-midpoint-to-nose length (px).

Per segment: heading unwrapped, heading and eye midpoint low-passed (2nd-order Butterworth,
20 Hz, zero phase: keeps the ≈ 8 Hz head oscillation of exploring rats), differentiated
(central differences); speed in eye–nose lengths per second. Pixel scale: none is recorded, so
speeds are converted with a rat eye-midpoint-to-nose length of ``mouse length × rat/mouse base
point spread``: the mouse length from Bresee et al. (2023) facial landmarks (top view), the
spread (RMS distance of one side's 30 whisker base points from their centroid) from the same
paper's mouse averages and the WHISKiT average rat (both in the same head frame).

    .venv/bin/python scripts/derive_head_motion_ranges.py --rat-behavior CLONE --shared ../shared \
        [--out pipeline/data/behaviour/wallach2020_head_motion.csv]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from scipy.io import loadmat
from scipy.signal import butter, filtfilt

FRAME_RATE_HZ = 500.0
CUTOFF_HZ = 20.0
SETS = ("control_c2h_data", "comparative_c2h_data")
QUANTILES = (5, 10, 25, 50, 75, 90, 95, 97.5, 99)
MIN_FRAMES = 60


def segment_rates(heading_deg: np.ndarray, x_px: np.ndarray, y_px: np.ndarray, length_px: float):
    """(speed in eye–nose lengths/s, |yaw rate| deg/s) per frame of one tracked segment."""
    b, a = butter(2, CUTOFF_HZ / (FRAME_RATE_HZ / 2))
    heading = filtfilt(b, a, np.unwrap(np.radians(heading_deg)))
    x, y = filtfilt(b, a, x_px), filtfilt(b, a, y_px)
    speed = np.hypot(np.gradient(x), np.gradient(y)) * FRAME_RATE_HZ / length_px
    return speed, np.degrees(np.abs(np.gradient(heading))) * FRAME_RATE_HZ


def pooled_rates(data_dir: Path) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Speeds, |yaw rates|, seconds and segment count over :data:`SETS`."""
    speeds, yaws, frames, count = [], [], 0, 0
    for name in SETS:
        data = loadmat(data_dir / f"{name}.mat")
        for head, length in zip(data["hdata"][0], data["headsize"][0].ravel()):
            if head.shape[0] < MIN_FRAMES:
                continue
            speed, yaw = segment_rates(head[:, 0], head[:, 1], head[:, 2], float(length))
            speeds.append(speed)
            yaws.append(yaw)
            frames += head.shape[0]
            count += 1
    return np.concatenate(speeds), np.concatenate(yaws), frames / FRAME_RATE_HZ, count


def _spread(points: np.ndarray) -> float:
    return float(np.sqrt(((points - points.mean(0)) ** 2).sum(1).mean()))


def rat_eye_nose_mm(shared: Path) -> tuple[float, float, float]:
    """(rat eye-midpoint-to-nose length mm, mouse length mm, rat/mouse scale)."""
    def rows(path):
        with open(path, newline="") as handle:
            return list(csv.DictReader(line for line in handle if not line.startswith("#")))

    marks = {r["landmark"]: np.array([float(r[k]) for k in ("x_mm", "y_mm")])
             for r in rows(shared / "data/mouse/bresee2023_mouse_facial_landmarks.csv")}
    eyes = [(marks[f"eye_{s}C"] + marks[f"eye_{s}R"]) / 2 for s in "LR"]
    mouse_mm = float(np.linalg.norm(marks["nose_tip"] - (eyes[0] + eyes[1]) / 2))
    mouse = np.array([[float(r[k]) for k in ("avg_bp_x_mm", "avg_bp_y_mm", "avg_bp_z_mm")]
                      for r in rows(shared / "data/mouse/bresee2023_mouse_per_whisker_means.csv") if r["avg_bp_x_mm"]])
    rat = np.array([[float(r[k]) for k in ("bp_x_mm", "bp_y_mm", "bp_z_mm")]
                    for r in rows(shared / "data/morphology/whiskit_average_rat_params.csv") if r["side"] == "1"])
    scale = _spread(rat) / _spread(mouse)
    return mouse_mm * scale, mouse_mm, scale


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rat-behavior", type=Path, required=True, help="clone of avner-wallach/Rat-Behavior")
    parser.add_argument("--shared", type=Path, required=True, help="the project's shared data folder")
    parser.add_argument("--out", type=Path, default=Path("pipeline/data/behaviour/wallach2020_head_motion.csv"))
    args = parser.parse_args()
    speeds, yaws, seconds, count = pooled_rates(args.rat_behavior / "Data")
    length_mm, mouse_mm, scale = rat_eye_nose_mm(args.shared)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as handle:
        handle.write(f"# Source: Wallach A, Deutsch D, Oram TB, Ahissar E (2020) PLoS Biol 18(5):e3000571; data "
                     f"github.com/avner-wallach/Rat-Behavior (commit 35ca4ba), {', '.join(SETS)}: {count} segments, "
                     f"{seconds:.1f} s of freely moving rats at {FRAME_RATE_HZ:.0f} frames/s. Computed by us "
                     f"(scripts/derive_head_motion_ranges.py): {CUTOFF_HZ:.0f} Hz zero-phase low-pass, central differences.\n")
        handle.write(f"# Speed of the eye midpoint; mm/s with a rat eye-midpoint-to-nose length of {length_mm:.1f} mm = "
                     f"mouse {mouse_mm:.2f} mm (Bresee et al. 2023 J Exp Biol 226:jeb245597, facial landmarks) x "
                     f"rat/mouse base-point spread {scale:.3f} (Bresee 2023 mouse averages; WHISKiT average rat): an estimate.\n")
        writer = csv.writer(handle)
        writer.writerow(["quantile_pct", "speed_eye_nose_lengths_per_s", "speed_mm_s", "yaw_rate_abs_deg_s"])
        for q in QUANTILES:
            v = float(np.percentile(speeds, q))
            writer.writerow([q, f"{v:.3f}", f"{v * length_mm:.1f}", f"{np.percentile(yaws, q):.1f}"])
    print(args.out.read_text())


if __name__ == "__main__":
    main()
