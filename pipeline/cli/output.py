"""How commands print: progress while they run, a summary table or JSON, the next steps."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from pipeline import console
from pipeline.activity import Activity
from pipeline.console import print_json


def busy(label: str, text: str, json_output: bool) -> Activity:
    """Progress of a command that may run for a while (``with busy(...)``): silent for a
    second, then ``label: text`` and a line every few seconds on stderr; none with --json."""
    activity = Activity(label, enabled=not json_output)
    activity.update(text)
    return activity


def print_summary(summary: dict, json_output: bool, title: str = "", next_steps: Iterable[str] = ()) -> None:
    """``summary`` as JSON, or as a table of rounded values with units and the next steps."""
    if json_output:
        print_json(summary)
    else:
        console.show(console.summary_table(summary, title), next_steps=next_steps)


def dataset_label(folder: str) -> str:
    """``NAME/vK`` of a version folder, the folder itself for a shard or a file."""
    path = Path(folder)
    return f"{path.parent.name}/{path.name}" if path.name.startswith("v") and path.name[1:].isdigit() else folder


def next_for_dataset(target: str) -> list[str]:
    """The next steps after a dataset is written or shown."""
    return [f"pipeline stats {target}  (tactile statistics)", f"pipeline view {target} --trial 0 --web"]


def one_line(text: object) -> str:
    """``text`` with every run of white space (newlines too) as one space."""
    return " ".join(str(text).split())
