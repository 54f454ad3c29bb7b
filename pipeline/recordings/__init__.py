"""Rerun recordings of trials (``.rrd``) and the viewer launcher. rerun is imported lazily."""

from pipeline.recordings.writer import write_recording

__all__ = ["write_recording"]
