"""One browsable trial per mesh: the right array whisks beside a cleaned scan (workflow stage).

Until poses are sampled per scene (dataset stage), the mesh is placed by its bounding box
beside the right array (:func:`pipeline.scenes.library.beside_right_array`).
"""

from __future__ import annotations

import json
from pathlib import Path

from pipeline.config import load_config
from pipeline.config.physics import ModelConfig
from pipeline.errors import SimulationError
from pipeline.errors import UserError
from pipeline.model.kinematics import Pose
from pipeline.protocols.whisking import run_trial
from pipeline.recordings import write_recording
from pipeline.scenes import Scene
from pipeline.scenes.library import beside_right_array, load_mesh


def whisk_beside_meshes(config_path: str | Path | None, meshes: str = "outputs/meshes",
                        out: str = "outputs/trials", whiskers: str = "R",
                        duration_s: float = 0.25, distance_mm: float = 28.0,
                        engine: str | None = None) -> dict:
    """Run one trial per ``<meshes>/*.obj`` and write ``<out>/<mesh>.rrd``; returns a summary.
    ``engine`` (bullet or mujoco) overrides the model config's engine."""
    overrides = {"engine": {"name": engine}} if engine else None
    config, _ = load_config(ModelConfig, config_path, env_prefix="PIPELINE_MODEL_", overrides=overrides)
    paths = sorted(Path(meshes).glob("*.obj"))
    if not paths:
        raise UserError(f"no meshes in {meshes}: run `pipeline build-meshes` first")
    Path(out).mkdir(parents=True, exist_ok=True)
    summary = {}
    for path in paths:
        mesh = beside_right_array(load_mesh(path), distance_mm * 1e-3)
        scene = Scene(f"mesh:{path.stem}", (mesh,))
        try:
            output = run_trial(config, scene, Pose(), duration_s, whiskers)
        except SimulationError as exc:          # recorded, the other meshes still run
            summary[path.stem] = {"failed": str(exc)}
            continue
        recording = write_recording(Path(out) / f"{path.stem}.rrd", output, scene, Pose(),
                                    recording_id=f"demo-{path.stem}", title=f"whisking beside {path.stem}")
        summary[path.stem] = {"recording": str(recording),
                              "whiskers_in_contact": output.whiskers_in_contact(),
                              "cpu_seconds": round(output.metadata["cpu_seconds"], 1)}
    (Path(out) / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
