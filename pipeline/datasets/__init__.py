"""Versioned HDF5 datasets of simulated trials: schema, writer, reader, versions, manifests.

Schema and layout: docs/dataset.md. h5py, xarray and pandas are imported only inside functions.
"""

from pipeline.datasets.frames import to_head_frame, to_world_frame
from pipeline.datasets.reader import DatasetFile, open_dataset as open, open_file, table  # noqa: A001 (pipeline.datasets.open)
from pipeline.datasets.trials import TrialDataset
from pipeline.datasets.writer import write_single_trial

__all__ = ["DatasetFile", "TrialDataset", "open", "open_file", "table", "to_head_frame", "to_world_frame", "write_single_trial"]
