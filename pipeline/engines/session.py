"""A closed-loop trial: an engine's worlds advance one output interval at a time under control.

:class:`Session` starts every world's trial generator (:meth:`~pipeline.engines.base.World.stepping`)
with a still head at the start pose and still whiskers, then, per :meth:`Session.advance`, lets
a controller set each whisker's protraction and the head's frame for the steps of the next
output interval (as functions of time, evaluated at each world's own step times) and returns
the sample recorded at its end. The engine and its compiled worlds stay alive between samples,
and nothing in a session draws random numbers: the same controls give bit-identical samples.

Timing. MuJoCo records a sample at the start of the step after the interval, and that step's
driven joints (and head) already aim at the next interval's first target: the controller's
protraction and head functions are asked for times up to one step beyond the sample's time (it
continues the current interval's control there; the next interval's control takes over one
step later, a latency of one engine step, ≤ 0.1 ms). The Bullet engine records after the interval's last step.

Limits. Free motions are not reused and a whisker whose contact jams (e.g. pressed into a wall
by the head) is not re-simulated with a finer step: it is parked for the rest of the session
(:attr:`Session.jammed`), its wrench and contacts zero from the sample it jammed in on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.engines.base import Engine, TrialSetup, WorldResult
from pipeline.engines.common import start_trial
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, still
from pipeline.scenes.obstacles import Scene


@dataclass(frozen=True)
class Sample:
    """One output sample of every whisker (array order, SI): ``time_s``, ``wrench`` [W, 6]
    (whisker frame), ``contact`` [W, N] per link, ``point_of_contact`` [W] (NaN: none),
    ``nodes`` [W, N+1, 3] (world frame, m)."""

    time_s: float
    wrench: np.ndarray
    contact: np.ndarray
    point_of_contact: np.ndarray
    nodes: np.ndarray


class Session:
    """A closed-loop trial of ``engine``'s array in ``scene``, the head starting at ``pose``,
    for at most ``samples`` output samples; the head may take each base point at most
    ``travel_m`` (m) from its start (MuJoCo builds only the obstacles within reach)."""

    def __init__(self, engine: Engine, scene: Scene, pose: Pose, samples: int, travel_m: float):
        config, array = engine.config, engine.array
        self.interval_s = 1.0 / config.output_rate_hz
        duration = samples * self.interval_s
        drive = still(duration)
        start_trial(array, scene, pose, drive, duration, config.output_rate_hz)
        initial, rates = engine._drive_start(scene, pose, drive)
        loads = tuple(w.physics.loads for w in array.whiskers)
        setup = TrialSetup(scene, pose, drive.continued(duration, self.interval_s), samples, tuple(initial),
                           tuple(rates), loads, head=HeadMotion.still(pose, duration + self.interval_s))
        self.samples, self.sample, self.whiskers = samples, 0, len(array.whiskers)
        self.jammed: dict[int, str] = {}          # array index → why: parked, rows zero from then on
        self.links = array.links
        self.streams = []
        for members, world in engine.worlds:
            result = WorldResult.zeros(samples, len(members), array.links)
            steps = world.stepping(setup.only(members), np.ones(len(members), bool), result, travel_m)
            self.streams.append((members, world, steps, next(steps), result))

    def advance(self, protraction, head) -> Sample:
        """Step every world through the next output interval and return its sample.

        ``protraction(times)`` → [n, W] each whisker's protraction (rad) at ``times`` [n] (s);
        ``head(times)`` → (positions [n, 3] m, rotations [n, 3, 3], per time a tuple of loads
        to add: the head frame's inertial load, :class:`~pipeline.model.head_motion.HeadFrameInertia`)."""
        if self.sample >= self.samples:
            raise RuntimeError(f"the session's {self.samples} samples are used up")
        k = self.sample
        wrench, contact = np.zeros((self.whiskers, 6)), np.zeros((self.whiskers, self.links), bool)
        poc, nodes = np.full(self.whiskers, np.nan), np.zeros((self.whiskers, self.links + 1, 3))
        for members, world, steps, plan, result in self.streams:
            rows, target_times, head_times = plan.interval(k, world.steps_per_sample)
            plan.set_protraction(rows, protraction(target_times)[:, members])
            plan.set_head(rows, *head(head_times))
            recorded = next(steps)
            assert recorded == k, (recorded, k)
            wrench[members], contact[members] = result.wrench[k], result.contact[k]
            poc[members], nodes[members] = result.point_of_contact[k], result.nodes[k]
            self.jammed.update((int(members[j]), message) for j, message in result.jammed.items())
        out = list(self.jammed)
        wrench[out], contact[out], poc[out] = 0.0, False, np.nan
        self.sample += 1
        return Sample((k + 1) * self.interval_s, wrench, contact, poc, nodes)

    def close(self) -> None:
        """Stop the worlds' generators (the engine stays usable)."""
        for _, _, steps, _, _ in self.streams:
            steps.close()
        self.streams = []
