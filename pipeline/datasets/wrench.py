"""Force and moment at the whisker base in either layout: ``base_force`` and ``base_moment``
(N and N m along ``xyz``, schema version 4) or ``base_wrench`` (Fx Fy Fz Mx My Mz along
``signal``, versions 1 to 3). Readers ask for any of the three names; what the file lacks is
made from what it has (numpy, one trial at a time).
"""

from __future__ import annotations

import numpy as np

from pipeline.datasets.schema import WRENCH_PARTS
from pipeline.errors import UserError
from pipeline.hdf5_files import first_line

WRENCH = "base_wrench"
READABLE = (WRENCH, *WRENCH_PARTS)


def read_array(dataset, key) -> np.ndarray:
    """``dataset[key]``; UserError naming the file if its data are damaged (a flipped bit in a chunk
    or its index, found only when read)."""
    try:
        return np.asarray(dataset[key])
    except (OSError, RuntimeError) as exc:
        raise UserError(f"{dataset.file.filename}: damaged dataset file: {dataset.name} "
                        f"({first_line(exc)})") from None


def read_trial(f, index: int, names) -> dict[str, np.ndarray]:
    """Arrays ``names`` of trial ``index`` of the open h5py file ``f`` (names the file does not
    store are left out, but the three wrench names are always there)."""
    arrays = {}
    for name in names:
        if name in f:
            arrays[name] = read_array(f[name], index)
        elif name == WRENCH and all(part in f for part in WRENCH_PARTS):
            arrays[name] = np.concatenate([read_array(f[part], index) for part in WRENCH_PARTS], axis=-1)
        elif name in WRENCH_PARTS and WRENCH in f:
            part = WRENCH_PARTS.index(name)
            arrays[name] = read_array(f[WRENCH], index)[..., 3 * part:3 * part + 3]
    return arrays
