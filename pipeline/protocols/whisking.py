"""A whisking trial: the array whisks (docs/model.md §4) in a scene at a head pose."""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.engines import create_engine, engine_class
from pipeline.errors import UserError
from pipeline.model.array import ArrayModel, build_array
from pipeline.model.effects.registry import model_parts
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, ProtractionDrive, sinusoidal_whisk, still
from pipeline.model.morphology import load_morphology
from pipeline.model.setup_cache import cached
from pipeline.model.outputs import TrialOutput
from pipeline.scenes import Scene, active_pegs, empty, mesh_scene, passive_peg, wall

SCENE_NAMES = ("none", "peg-passive", "pegs-active", "wall", "mesh:PATH")


def parse_scene(text: str) -> Scene:
    """'none', 'peg-passive', 'pegs-active', 'wall' or 'mesh:PATH' (mesh in metres)."""
    fixed = {"none": empty, "peg-passive": passive_peg, "pegs-active": active_pegs, "wall": wall}
    if text in fixed:
        return fixed[text]()
    if text.startswith("mesh:") and len(text) > 5:
        return mesh_scene(text[5:])
    raise UserError(f"unknown scene '{text}' (choose from {', '.join(SCENE_NAMES)})")


def default_drive(scene: Scene, config: ModelConfig, duration_s: float) -> ProtractionDrive:
    """The paper's drives: still whiskers for the passive peg, the configured whisk otherwise."""
    if scene.name == "peg-passive":
        return still(duration_s)
    w = config.whisk
    return sinusoidal_whisk(w.frequency_hz, w.protraction_deg, w.retraction_deg, duration_s)


class Whisking:
    """The configured array (or the selection ``whiskers`` of it) on one engine, both built on
    first use and kept for any number of trials; :meth:`close` (or a ``with`` block) frees the
    engine."""

    def __init__(self, config: ModelConfig, whiskers: str | None = None):
        self.config, self.whiskers = config, config.whiskers if whiskers is None else whiskers
        self._engine = None

    @cached_property
    def _setup(self) -> tuple[ArrayModel, np.ndarray]:
        """The array and its engine's step level per whisker, its base inertia computed: what
        depends on the model alone, kept on disk between processes (:mod:`pipeline.model.setup_cache`)."""
        morphology = load_morphology(self.config.morphology).select(self.whiskers)
        if len(morphology) == 0:
            raise UserError(f"no whiskers selected by '{self.whiskers}'")
        material, extensions = model_parts(self.config)
        engine = self.config.engine

        def compute() -> tuple[ArrayModel, np.ndarray]:
            array = build_array(morphology, material, extensions)
            for whisker in array.whiskers:
                whisker.physics.base_inertia
            return array, engine_class(engine.name).step_levels(array, engine)

        return cached("array", (morphology.whiskers, morphology.origin_m, material, extensions, engine), compute)

    @property
    def array(self) -> ArrayModel:
        return self._setup[0]

    @property
    def engine(self):
        if self._engine is None:
            self._engine = create_engine(self.config, *self._setup)
        return self._engine

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
            head_motion: HeadMotion | None = None) -> TrialOutput:
        """One trial: the array follows ``drive`` for ``duration_s`` (s) in ``scene`` at ``pose``
        (the head moving along ``head_motion`` from there, if given)."""
        if head_motion is None:
            return self.engine.run(scene, pose, drive, duration_s)
        return self.engine.run(scene, pose, drive, duration_s, head_motion=head_motion)

    def close(self) -> None:
        if self._engine is not None:
            self._engine.close()
            self._engine = None

    def __enter__(self) -> "Whisking":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_trial(config: ModelConfig, scene: Scene, pose: Pose = Pose(), duration_s: float | None = None,
              whiskers: str | None = None, drive: ProtractionDrive | None = None,
              progress: Callable[[int, int], None] | None = None) -> TrialOutput:
    """Build the configured array (or a selection of it) and run one trial on a new engine;
    ``progress``: called with (whisker steps done, planned) as the trial goes (Engine.progress)."""
    duration_s = config.whisk.duration_s if duration_s is None else duration_s
    with Whisking(config, whiskers) as whisking:
        whisking.engine.progress = progress
        return whisking.run(scene, pose, drive or default_drive(scene, config, duration_s), duration_s)
