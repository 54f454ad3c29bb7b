"""A closed-loop controller: whisk and move forward until a whisker touches, then turn toward it.

    python examples/closed_loop_controller.py --steps 400 --out outputs/closed_loop.h5

Runs ``whisker_pipeline/Whisking-v0`` (docs/closed_loop.md) with the wall ahead: both sides
whisk at 8 Hz while the head moves forward at half speed; at the first contact the head stops
advancing and turns toward the side that touched (yaw to the right for a right whisker), the
touching side's protraction held back (as rats reduce protraction after contact: Mitchinson et
al. 2007). Prints the contact and the turn; ``--out`` writes the episode as a one-trial dataset
(``pipeline stats`` and ``pipeline view`` read it).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import pipeline.envs

WHISK_HZ = 8.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="environment steps (1 ms each)")
    parser.add_argument("--whiskers", default="R", help="whisker selection (R, L, all, RC1,RD2, ...)")
    parser.add_argument("--engine", default="mujoco", choices=("mujoco", "bullet"))
    parser.add_argument("--out", default=None, help="write the episode as a dataset file (.h5)")
    args = parser.parse_args()

    env = gym.make(pipeline.envs.ENV_ID, scene="wall", whiskers=args.whiskers, engine=args.engine,
                   max_steps=args.steps)
    names = env.unwrapped.names
    env.reset(seed=0)
    touched_side, start_yaw, info = 0, 0.0, {}
    for k in range(args.steps):
        phase = np.sin(2 * np.pi * WHISK_HZ * k / 1000.0)
        whisk = np.array([phase, phase])
        if touched_side:                      # turn toward the touch; the touching side holds back
            whisk[0 if touched_side > 0 else 1] = -0.5
            head = np.array([0.0, 0.0, 0.0, -0.5 * touched_side, 0.0, 0.0])
        else:
            head = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
        observation, _, terminated, truncated, info = env.step({"whisk": whisk, "head_velocity": head})
        if not touched_side and info["whiskers_in_contact"]:
            touching = [n for n, c in zip(names, observation["contact"].any(axis=1)) if c]
            touched_side = 1 if touching[0].startswith("R") else -1
            start_yaw = float(info["head_pose"][1][0])
            print(f"first contact at t = {info['time_s'] * 1e3:.0f} ms by {', '.join(touching)}")
        if terminated or truncated:
            break
    if touched_side:
        turned = np.degrees(float(info["head_pose"][1][0]) - start_yaw)
        print(f"turned {abs(turned):.1f} degrees toward the {'right' if turned < 0 else 'left'} "
              f"by t = {info['time_s'] * 1e3:.0f} ms")
    else:
        print("no contact")
    if args.out:
        print(f"episode written to {env.unwrapped.record(args.out)}")
    env.close()


if __name__ == "__main__":
    main()
