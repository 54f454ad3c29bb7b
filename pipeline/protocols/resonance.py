"""Resonance protocol on an engine (paper §4.5.1, docs/model.md §5): a Gaussian pulse of base
rotation, an abrupt stop, then ringing; drive and analysis in :mod:`pipeline.signals.resonance`."""

from __future__ import annotations

from pipeline.engines import create_engine
from pipeline.signals.resonance import DURATION_S, MODES, ResonanceResult, analyse_tip, pulse_drive
from pipeline.config.physics import ModelConfig
from pipeline.errors import UserError
from pipeline.model.array import single_whisker
from pipeline.model.effects.registry import model_parts
from pipeline.model.kinematics import Pose
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes import empty


def run_resonance(geometry: WhiskerGeometry, config: ModelConfig, modes: int = MODES) -> ResonanceResult:
    """Simulate the resonance protocol for one whisker and analyse its tip (SI in and out)."""
    if config.material.damping_ratio <= 0:
        raise UserError("damping ratio ζ = 0: the resonance protocol measures modes from a decaying "
                        "ring-down, and an undamped whisker's fit mistakes its second mode for f1; use ζ > 0 "
                        "(e.g. --zeta 1e-4)")
    material, extensions = model_parts(config)
    array = single_whisker(geometry, material, extensions=extensions)
    with create_engine(config, array) as engine:
        output = engine.run(empty(), Pose(), pulse_drive(), DURATION_S)
    tip_y = output.node_positions_m[:, 0, -1, 1].astype(float)
    return analyse_tip(tip_y, output.time_s, config.engine.output_rate_hz, modes)
