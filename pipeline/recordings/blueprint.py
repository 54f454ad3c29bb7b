"""Default viewer layout of a trial recording: the 3-D scene on the left, base signals of the
most loaded whiskers on the right, the time panel below (playing at 1/10 real time)."""

from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

from pipeline.model.outputs import TrialOutput

SHOWN_WHISKERS = 3
PLAYBACK_SPEED = 0.1
TIMELINE = "sim_time"             # the recordings' time axis (simulated seconds)


def loaded_whiskers(output: TrialOutput, count: int = SHOWN_WHISKERS) -> list[str]:
    """Names of the ``count`` whiskers with the largest peak |M| (array order on ties)."""
    peak = np.nan_to_num(output.moment_magnitude()).max(axis=0) if len(output.time_s) else \
        np.zeros(len(output.whisker_names))
    order = np.argsort(-peak, kind="stable")[:count]
    return [output.whisker_names[i] for i in order]


def make_blueprint(output: TrialOutput):
    shown = loaded_whiskers(output)
    rows = [rrb.Horizontal(
        rrb.TimeSeriesView(origin=f"signals/{name}/force", name=f"{name} force (N)"),
        rrb.TimeSeriesView(origin=f"signals/{name}/moment", name=f"{name} moment (N·m)"),
    ) for name in shown]
    rows.append(rrb.TimeSeriesView(
        origin="signals",
        contents=[f"signals/{name}/moment_magnitude" for name in output.whisker_names],
        name="|M| all whiskers (N·m)", plot_legend=rrb.PlotLegend(visible=False)))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="whiskers and scene"),
            rrb.Vertical(*rows),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE, playback_speed=PLAYBACK_SPEED),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
