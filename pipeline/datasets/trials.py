"""A PyTorch-style map dataset over the finished trials of a dataset (no torch import).

    ds = TrialDataset("natural/v2", arrays=("base_wrench", "contact"))
    item = ds[0]       # {"trial": 17, "scene": "mesh:rock_pile", "samples": 125, "base_wrench": ...}
    # torch.utils.data.DataLoader(ds, num_workers=4) works: each worker process opens the file itself.

Arrays come padded to the dataset's full time axis (NaN / 0 after ``samples``), so items of one
dataset batch together; ``h5py.File`` objects cannot be pickled, so the file is opened lazily
in whichever process reads.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.datasets.schema import ARRAYS, OK, array_group
from pipeline.datasets.versions import resolve
from pipeline.datasets.wrench import READABLE, WRENCH, read_trial
from pipeline.hdf5_files import open_hdf5


class TrialDataset:
    """Items = trials whose status is ``status`` (default 'ok'), in trial order."""

    def __init__(self, target: str | Path, arrays: tuple[str, ...] = ("base_wrench", "contact"),
                 root: str | Path | None = None, status: str = OK):
        unknown = [a for a in arrays if a not in ARRAYS and a not in READABLE]
        if unknown:
            raise KeyError(f"unknown arrays {unknown} (known: {', '.join([*ARRAYS, WRENCH])})")
        self.path = resolve(target, root)
        self.arrays = tuple(arrays)
        with open_hdf5(self.path, "dataset file") as f:
            table = f["trials"]
            self.indices = np.flatnonzero(table["status"][()] == status.encode())
            self.scenes = np.char.decode(table["scene"][()][self.indices], "utf-8")
            self.samples = table["samples"][()][self.indices]
        self._file = None
        self._pid = None

    def __len__(self) -> int:
        return len(self.indices)

    def _opened(self):
        if self._file is None or self._pid != os.getpid():
            self._file, self._pid = open_hdf5(self.path, "dataset file"), os.getpid()
        return self._file

    def __getitem__(self, item: int) -> dict[str, Any]:
        if not -len(self) <= item < len(self):
            raise IndexError(f"item {item} out of range for {len(self)} trials")
        f = self._opened()
        index = int(self.indices[item])
        return {"trial": index, "scene": str(self.scenes[item]), "samples": int(self.samples[item]),
                **read_trial(array_group(f), index, self.arrays)}

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_file": None, "_pid": None}
