"""``whisker_pipeline/Whisking-v0``: closed-loop whisking with a moving head (docs/closed_loop.md).

One step is one output interval (``engine.output_rate_hz``, 1 kHz by default) of a
:class:`~pipeline.engines.session.Session` on the configured engine, built once per environment
and kept between steps and episodes.

Actions (``Dict``, every component in [−1, 1]):

``whisk``          protraction command per side (right, left), or per side and row (A…E) with
                   ``per_row=True``: −1 … 1 maps linearly onto ``protraction_range_deg``; each
                   whisker's protraction follows its command through a critically damped lag of
                   ``whisk_tau_s`` (:mod:`pipeline.envs.controls`);
``head_velocity``  the head's body twist as fractions of ``max_speed_m_s`` (forward = rostral,
                   lateral = to the right, dorsal) and ``max_turn_rad_s`` (yaw: nose to the left,
                   pitch: nose up, roll: right side down; docs/frames.md), followed through a lag
                   of ``head_tau_s``.

Observations (``Dict``, SI): ``wrench`` [W, 6] each whisker's base force (N) and moment (N·m) in
its whisker frame, ``contact`` [W, N] links touching during the interval, ``protraction`` and
``protraction_rate`` [W] (rad, rad/s: proprioception). ``info``: ``whiskers_in_contact``,
``time_s``, ``head_pose`` (position m, Euler angles as docs/frames.md), ``jammed`` (whiskers
taken out after their contact jammed, with why: :mod:`pipeline.engines.session`).

Scenes: ``"wall"`` a flat wall ahead of the snout, :data:`WALL_GAP_M` beyond the farthest any
whisker's rest shape reaches over the protraction range, so that full forward speed reaches it
within 0.2 s; or any scene name of ``pipeline trial --scene`` (protocols.whisking.parse_scene),
or a :class:`~pipeline.scenes.obstacles.Scene`. The reward is 0: tasks wrap the environment.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pipeline.config.physics import ModelConfig
from pipeline.datasets.writer import write_single_trial
from pipeline.engines.session import Session
from pipeline.envs.controls import CriticalLag, HeadPlant
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.outputs import TrialOutput
from pipeline.protocols.whisking import Whisking, parse_scene
from pipeline.recordings import write_recording
from pipeline.scenes.obstacles import Box, Scene

WALL_GAP_M = 0.003          # the wall ahead starts this far beyond the array's reach
WALL_HALF_THICKNESS_M = 0.0025
ROWS = 5


def reach_ahead_m(array, theta_range_rad) -> float:
    """How far rostrally (head y, m) any whisker's rest shape reaches over the protraction range."""
    thetas = np.linspace(*theta_range_rad, 25)
    return float(max(w.rest_nodes_head(t)[:, 1].max() for w in array.whiskers for t in thetas))


def wall_ahead(array, theta_range_rad) -> Scene:
    """A large wall across the head's path, :data:`WALL_GAP_M` beyond the array's reach."""
    front = reach_ahead_m(array, theta_range_rad) + WALL_GAP_M
    return Scene("wall-ahead", (Box((0.1, WALL_HALF_THICKNESS_M, 0.1), (0.0, front + WALL_HALF_THICKNESS_M, 0.0)),))


class WhiskingEnv(gym.Env):
    """The environment of the module docstring."""

    metadata = {"render_modes": ["rerun"], "render_fps": 30}

    def __init__(self, scene: str | Scene = "wall", whiskers: str = "R", engine: str = "mujoco",
                 per_row: bool = False, max_steps: int = 500, max_speed_m_s: float = 0.1,
                 max_turn_rad_s: float = 3.0, protraction_range_deg=(-15.0, 45.0), whisk_tau_s: float = 0.005,
                 head_tau_s: float = 0.02, model: ModelConfig | None = None, render_mode: str | None = None,
                 recording: str | Path = "outputs/closed_loop.rrd"):
        model = model or ModelConfig()
        self.model = model.model_copy(update={"engine": model.engine.model_copy(update={"name": engine})})
        self.whisking = Whisking(self.model, whiskers)
        array = self.whisking.array
        self.names = list(array.names)
        self.theta_range = np.radians(np.asarray(protraction_range_deg, float))
        self.scene = scene if isinstance(scene, Scene) else (
            wall_ahead(array, self.theta_range) if scene == "wall" else parse_scene(scene))
        self.per_row, self.max_steps = per_row, max_steps
        self.scale = np.array([max_speed_m_s] * 3 + [max_turn_rad_s] * 3)
        self.whisk_tau_s, self.head_tau_s = whisk_tau_s, head_tau_s
        sides = np.array([0 if w.side > 0 else 1 for w in array.whiskers])
        self.group = sides * ROWS + np.array([w.row - 1 for w in array.whiskers]) if per_row else sides
        self.render_mode, self.recording = render_mode, Path(recording)
        w, n = len(self.names), array.links
        self.action_space = spaces.Dict({
            "whisk": spaces.Box(-1.0, 1.0, (2, ROWS) if per_row else (2,), np.float64),
            "head_velocity": spaces.Box(-1.0, 1.0, (6,), np.float64)})
        self.observation_space = spaces.Dict({
            "wrench": spaces.Box(-np.inf, np.inf, (w, 6), np.float64),
            "contact": spaces.MultiBinary((w, n)),
            "protraction": spaces.Box(-np.pi, np.pi, (w,), np.float64),
            "protraction_rate": spaces.Box(-np.inf, np.inf, (w,), np.float64)})
        reach = float(np.linalg.norm([w_.base_point_m for w_ in array.whiskers], axis=1).max())
        duration = max_steps / self.model.engine.output_rate_hz
        self.travel_m = max_speed_m_s * duration + min(2.0, max_turn_rad_s * duration) * reach
        self.session: Session | None = None

    # -- episode -----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if self.session is not None:
            self.session.close()
        engine = self.whisking.engine
        self.start = Pose()
        self.session = Session(engine, self.scene, self.start, self.max_steps, self.travel_m)
        self.finest_step_s = float(min(world.dt_s for _, world in engine.worlds))
        self.head = HeadPlant(self.start, self.head_tau_s, self.finest_step_s,
                              max(world.dt_s for _, world in engine.worlds))
        self.whisk = CriticalLag(np.zeros(int(self.group.max()) + 1), self.whisk_tau_s)
        self.history: list = []
        self.head_poses = [self.start]
        self.protractions = [self.whisk.value[self.group]]
        w, n = len(self.names), self.whisking.array.links
        observation = {"wrench": np.zeros((w, 6)), "contact": np.zeros((w, n), np.int8),
                       "protraction": self.whisk.value[self.group].copy(), "protraction_rate": np.zeros(w)}
        return observation, self._info(0.0, 0)

    def step(self, action):
        if self.session is None:
            raise RuntimeError("call reset() before step()")
        whisk = np.clip(np.asarray(action["whisk"], float), -1.0, 1.0).ravel()
        command = self.theta_range[0] + (whisk + 1.0) * 0.5 * (self.theta_range[1] - self.theta_range[0])
        twist = np.clip(np.asarray(action["head_velocity"], float), -1.0, 1.0) * self.scale
        now, interval = self.session.sample * self.session.interval_s, self.session.interval_s
        frames, commit = self.head.interval(interval, twist)
        sample = self.session.advance(lambda times: self.whisk.at(times - now, command)[0][:, self.group],
                                      lambda times: frames(times - now))
        commit()
        self.whisk.advance(interval, command)
        self.history.append(sample)
        self.head_poses.append(self.head.pose)
        self.protractions.append(self.whisk.value[self.group])
        touching = sample.contact.any(axis=1)
        observation = {"wrench": sample.wrench.copy(), "contact": sample.contact.astype(np.int8),
                       "protraction": self.whisk.value[self.group].copy(),
                       "protraction_rate": self.whisk.rate[self.group].copy()}
        truncated = self.session.sample >= self.max_steps
        return observation, 0.0, False, truncated, self._info(sample.time_s, int(touching.sum()))

    def _info(self, time_s: float, in_contact: int) -> dict:
        pose = self.head_poses[-1]
        return {"whiskers_in_contact": in_contact, "time_s": time_s,
                "head_pose": (np.asarray(pose.position_m), np.asarray(pose.euler_zyx_rad)),
                "jammed": {self.names[k]: why for k, why in self.session.jammed.items()}}

    # -- the episode as a trial -------------------------------------------------------------
    def episode_output(self) -> TrialOutput:
        """The episode so far as a trial's outputs (the engine's shapes and dtypes)."""
        if not self.history:
            raise RuntimeError("no step taken yet")
        return TrialOutput(np.array([s.time_s for s in self.history]),
                           np.array([s.wrench for s in self.history], np.float32),
                           np.array([s.contact for s in self.history]),
                           np.array([s.nodes for s in self.history], np.float32), list(self.names),
                           {"engine": self.model.engine.name, "closed_loop": True},
                           point_of_contact=np.array([s.point_of_contact for s in self.history], np.float32))

    def episode_head(self) -> HeadMotion:
        """The head's trajectory over the episode (its pose at t = 0 and every sample)."""
        times = np.arange(len(self.head_poses)) * self.session.interval_s
        return HeadMotion(times, np.array([p.position_m for p in self.head_poses]),
                          np.array([p.euler_zyx_rad for p in self.head_poses]))

    def episode_drive(self) -> ProtractionDrive:
        """The whiskers' mean protraction over the episode (the dataset keeps one per sample)."""
        times = np.arange(len(self.protractions)) * self.session.interval_s
        return ProtractionDrive(times, np.array([p.mean() for p in self.protractions]), kind="table")

    def record(self, path: str | Path) -> Path:
        """Write the episode so far as a one-trial dataset (docs/dataset.md; viewer and stats read it)."""
        return write_single_trial(path, self.episode_output(), self.model, self.scene, self.start,
                                  self.episode_drive(), self.episode_head())

    def render(self):
        """``render_mode="rerun"``: write the episode so far to ``recording`` (.rrd)."""
        if self.render_mode != "rerun" or not self.history:
            return None

        self.recording.parent.mkdir(parents=True, exist_ok=True)
        write_recording(self.recording, self.episode_output(), self.scene, self.start,
                        recording_id=f"closed-loop/{id(self)}", title="closed-loop episode")
        return None

    def close(self):
        if self.session is not None:
            self.session.close()
            self.session = None
        self.whisking.close()
