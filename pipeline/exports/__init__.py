"""Exports of simulated datasets to other tools' formats, and an importer of the original's output.

- ``nwb``: one NWB file per dataset version (pynwb), trials on one session timeline.
- ``whiskit``: one trial in the CSV folder layout of the original WHISKiT Physics C++ program,
  its reader, and a per-whisker comparison with a dataset trial.

Every module reads datasets through ``source.read_trials`` only. Formats: docs/export.md.
"""
