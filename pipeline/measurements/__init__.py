"""Measured whisker data: tracked time series (HDF5) and resonance tables (CSV).

Formats and their versions are documented in docs/measurements.md; every loader validates
its file and raises :class:`~pipeline.errors.UserError` naming file, trial (or line) and field.
"""

from __future__ import annotations

import csv
from pathlib import Path

from pipeline.errors import UserError
from pipeline.measurements.table import ResonanceRecord, ResonanceTable, load_table
from pipeline.measurements.timeseries import (ReleaseDrive, RotationDrive, TimeSeriesMeasurement, Trial,
                                              load_timeseries, write_timeseries)

PAPER_ALPHA_B1 = Path(__file__).parent / "data" / "paper_alpha_b1.csv"


def load_measurement(path: str | Path) -> TimeSeriesMeasurement | ResonanceTable:
    """A time series (``.h5``/``.hdf5``) or a resonance table (``.csv``), validated; a file
    that cannot be decoded (corrupt HDF5, binary bytes in a CSV) is a UserError naming it."""
    suffix = Path(path).suffix.lower()
    try:
        if suffix in (".h5", ".hdf5"):
            return load_timeseries(path)
        if suffix == ".csv":
            return load_table(path)
    except (OSError, RuntimeError, UnicodeDecodeError, csv.Error, KeyError, ValueError, TypeError,
            SystemError) as exc:      # SystemError: h5py's lock around a link name that is not UTF-8
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise UserError(f"{path}: corrupt or unreadable measurement file ({reason})") from None
    raise UserError(f"{path}: unknown measurement type '{suffix}' (.h5/.hdf5 time series or "
                    ".csv resonance table)")


__all__ = ["PAPER_ALPHA_B1", "ReleaseDrive", "ResonanceRecord", "ResonanceTable", "RotationDrive",
           "TimeSeriesMeasurement", "Trial", "load_measurement", "load_table", "load_timeseries",
           "write_timeseries"]
