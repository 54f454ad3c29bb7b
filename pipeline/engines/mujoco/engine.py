"""The MuJoCo engine: the template of :mod:`pipeline.engines.base` with a
:class:`~pipeline.engines.mujoco.world.MujocoWorld` per step size, and the prisms of the
scenes it simulated last."""

from __future__ import annotations

import mujoco
import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.base import Engine
from pipeline.engines.mujoco.prisms import MeshPrisms
from pipeline.engines.mujoco.world import MujocoWorld
from pipeline.engines.stepping import folded_refinement_levels
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.scenes.obstacles import Scene

PRISM_SCENES = 4               # the engine keeps the prisms of this many scenes (≈ 6 MB per 40 k faces)


class MujocoEngine(Engine):
    """The WHISKiT model on MuJoCo (the scheme: :mod:`pipeline.engines.mujoco`)."""

    name = "mujoco"

    def __init__(self, array: ArrayModel, config: EngineConfig, levels: np.ndarray | None = None):
        # MuJoCo would print its warnings and append them to ./MUJOCO_LOG.TXT; the engine reads
        # the same conditions from data.warning and handles them (jam refinement)
        mujoco.set_mju_user_warning(lambda message: None)
        self._prisms: dict[tuple, MeshPrisms] = {}
        self._scene_keys: list = []               # the scenes whose prisms are kept, latest last
        super().__init__(array, config, levels)

    @classmethod
    def step_levels(cls, array: ArrayModel, config: EngineConfig) -> np.ndarray:
        return folded_refinement_levels(array, config)

    def make_world(self, whiskers: list[WhiskerModel], dt_s: float) -> MujocoWorld:
        return MujocoWorld(whiskers, self.config, dt_s, self._prisms)

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, **options):
        if scene.key in self._scene_keys:         # a dataset cycles through a few scenes
            self._scene_keys.remove(scene.key)
        self._scene_keys.append(scene.key)
        for key in self._scene_keys[:-PRISM_SCENES]:
            for cached in [c for c in self._prisms if c[0] == key]:
                del self._prisms[cached]
        del self._scene_keys[:-PRISM_SCENES]
        return super().run(scene, pose, drive, duration_s, **options)
