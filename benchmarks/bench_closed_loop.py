"""Closed loop against open loop: CPU cost per simulated second of the same motion.

Run: .venv/bin/python benchmarks/bench_closed_loop.py [--whiskers R] [--engine mujoco]
     [--steps 250] [--runs 3]

An episode of ``whisker_pipeline/Whisking-v0`` (the wall ahead, both sides whisking at 8 Hz
through the whole protraction range) is stepped with the head still, then with it moving
forward at full speed (it reaches the wall). The same motion is then run open loop, as
``pipeline simulate``'s trials run (``Engine.run``, one call per trial), with the episode's
protraction as the drive and its head path as the head trajectory. The table gives the median
CPU seconds per simulated second of ``--runs`` runs each (after one warm-up that builds the
worlds), and the ratio closed / open.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import pipeline.envs


def episode(env, steps: int, speed: float) -> float:
    """CPU seconds of one episode of ``steps`` steps."""
    env.reset(seed=0)
    start = time.process_time()
    for k in range(steps):
        phase = np.sin(2 * np.pi * 8.0 * k / 1000.0)
        env.step({"whisk": np.array([phase, phase]), "head_velocity": np.array([speed, 0, 0, 0, 0, 0.0])})
    return time.process_time() - start


def open_loop(env, steps: int) -> float:
    """CPU seconds of ``Engine.run`` with the last episode's drive and head path."""
    unwrapped = env.unwrapped
    drive, head = unwrapped.episode_drive(), unwrapped.episode_head()
    still = np.ptp(head.position_m, axis=0).max() == 0.0
    start = time.process_time()
    unwrapped.whisking.engine.run(unwrapped.scene, unwrapped.start, drive, steps / 1000.0,
                                  head_motion=None if still else head)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--whiskers", default="R")
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--steps", type=int, default=250)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    env = gym.make(pipeline.envs.ENV_ID, scene="wall", whiskers=args.whiskers, engine=args.engine,
                   max_steps=args.steps)
    simulated = args.steps / 1000.0
    print(f"{args.engine}, whiskers {args.whiskers}, {simulated:g} s episodes; CPU s per simulated s (median of {args.runs})")
    print(f"{'head':<10} {'closed loop':>12} {'open loop':>10} {'ratio':>6}")
    for label, speed in (("still", 0.0), ("forward", 1.0)):
        episode(env, args.steps, speed)                                     # warm-up: builds the worlds
        open_loop(env, args.steps)
        closed, opened = [], []
        for _ in range(args.runs):
            closed.append(episode(env, args.steps, speed) / simulated)
            opened.append(open_loop(env, args.steps) / simulated)
        c, o = float(np.median(closed)), float(np.median(opened))
        print(f"{label:<10} {c:12.2f} {o:10.2f} {c / o:6.2f}")
    env.close()


if __name__ == "__main__":
    main()
