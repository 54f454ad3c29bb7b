"""Step convergence of the sampled base signals: what the 1 kHz output of each whisker carries.

Run: .venv/bin/python benchmarks/short_whisker_steps.py [--whiskers RC6,RD6,...] [--rate 1000]

The MuJoCo engine picks each whisker's step from its f1 error (pipeline.engines.stepping). The
shortest whiskers (7.4 mm, f1 560–760 Hz) ring above the Nyquist frequency of a 1 kHz output,
so the question is what their *sampled* base wrench loses at a coarser step. Each listed
whisker (model rat, its place in the array) runs at every step dt_s/2^j, j = 0..3, and at a
reference step dt_s/32, under two drives: the dataset's free whisk (8 Hz, 35°/15°, 125 ms) and
the resonance pulse (docs/model.md §5), of which the 100 ms of free ringing from 5 ms after
its stop are compared. Printed per whisker and step: the RMS of the
difference of the sampled six-component base wrench (force and moment each scaled by the
reference's RMS) from the reference, in % of the reference; * marks the step the f1 criterion
picks. Compare a short whisker's row with what the longer whiskers carry at their own steps.
"""

from __future__ import annotations

import argparse

import numpy as np

DEFAULT_WHISKERS = "RA4,RB4,RC4,RD4,RE4,RC5,RD5,RE5,RC6,RD6,RE6"
DURATION_S = 0.125
RING_S = (0.133, 0.233)        # the pulse stops at 0.128 s
LEVELS = (0, 1, 2, 3)
REFERENCE_LEVEL = 5


def wrenches(names: str, dt_s: float, drive, rate_hz: float, window_s=(0.0, DURATION_S)) -> np.ndarray:
    """[T, W, 6] base wrench of the whiskers ``names`` (each at ``dt_s``) in an empty scene, the
    samples within ``window_s``."""
    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines import create_engine
    from pipeline.model.array import build_array
    from pipeline.model.kinematics import Pose
    from pipeline.model.morphology import load_morphology
    from pipeline.scenes import empty

    config = ModelConfig(engine=EngineConfig(name="mujoco", dt_s=dt_s, f1_tolerance=0.0, output_rate_hz=rate_hz))
    array = build_array(load_morphology("model_rat").select(names), config.material)
    with create_engine(config, array) as engine:
        out = engine.run(empty(), Pose(), drive, window_s[1])
    inside = (out.time_s >= window_s[0] - 1e-9) & (out.time_s <= window_s[1] + 1e-9)
    return out.base_wrench[inside].astype(float)


def relative_rms(signal: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """[W] RMS difference over time and the six components, force and moment each scaled by
    the reference's RMS of that part, in % (1 = the reference's own size)."""
    parts = []
    for columns in (slice(0, 3), slice(3, 6)):
        scale = np.sqrt(np.mean(reference[:, :, columns] ** 2, axis=(0, 2)))
        parts.append((signal[:, :, columns] - reference[:, :, columns]) / scale[None, :, None])
    difference = np.concatenate(parts, axis=2)
    return 100 * np.sqrt(np.mean(difference ** 2, axis=(0, 2)) / 2)


def main() -> None:
    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines.stepping import first_frequency_hz, folded_refinement_levels
    from pipeline.model.array import build_array
    from pipeline.model.kinematics import sinusoidal_whisk
    from pipeline.model.morphology import load_morphology
    from pipeline.signals.resonance import pulse_drive

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--whiskers", default=DEFAULT_WHISKERS)
    parser.add_argument("--rate", type=float, default=1000.0, help="output rate, Hz")
    args = parser.parse_args()
    config = ModelConfig(engine=EngineConfig(name="mujoco", output_rate_hz=args.rate))
    array = build_array(load_morphology("model_rat").select(args.whiskers), config.material)
    chosen = folded_refinement_levels(array, config.engine)
    f1 = first_frequency_hz(array)
    dt = config.engine.dt_s
    drives = {"whisk": (sinusoidal_whisk(duration_s=DURATION_S), (0.0, DURATION_S)),
              "pulse": (pulse_drive(duration_s=RING_S[1]), RING_S)}
    errors = {}
    for label, (drive, window) in drives.items():
        reference = wrenches(args.whiskers, dt / 2 ** REFERENCE_LEVEL, drive, args.rate, window)
        errors[label] = np.array([relative_rms(wrenches(args.whiskers, dt / 2 ** j, drive, args.rate, window),
                                               reference) for j in LEVELS])        # [level, W]
    print(f"Sampled base wrench ({args.rate:g} Hz) against dt_s/{2 ** REFERENCE_LEVEL}: RMS difference, % "
          "(whisk | pulse); * the step the f1 criterion picks")
    header = " | ".join(f"{dt / 2 ** j:9.3g} s     " for j in LEVELS)
    print(f"{'whisker':>7} | {'S mm':>5} | {'f1 Hz':>6} | {header}")
    for w, whisker in enumerate(array.whiskers):
        cells = " | ".join(f"{errors['whisk'][j, w]:6.2f}|{errors['pulse'][j, w]:6.2f}{'*' if chosen[w] == j else ' '}"
                           for j in LEVELS)
        print(f"{whisker.name:>7} | {whisker.chain.geometry.arc_length_m * 1e3:5.1f} | {f1[w]:6.0f} | {cells}")


if __name__ == "__main__":
    main()
