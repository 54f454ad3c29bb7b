"""Scheduler-less runs split into shards (job arrays): ``--shard i/N`` runs a contiguous block.

Shard i of N holds trials [(i−1)·n/N, i·n/N) in its own dataset file under
``<root>/<name>/shards/<run>/shard_<i>_of_<N>/``, where ``<run>`` is a hash of the resolved
config, so every job of the array finds the same folder without coordination. A shard run
starts or continues its shard (safe to requeue); ``pipeline datasets join NAME`` stitches the
shards into a new version.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.reader import decode_attr
from pipeline.datasets.schema import DATA_FILE, FAILED, OK
from pipeline.datasets.versions import SHARDS_DIR
from pipeline.errors import UserError
from pipeline.hdf5_files import open_hdf5
from pipeline.provenance import json_sha256


@dataclass(frozen=True)
class Shard:
    number: int          # 1..count
    count: int

    @classmethod
    def parse(cls, text: str) -> "Shard":
        match = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", text)
        if not match or not 1 <= int(match.group(1)) <= int(match.group(2)):
            raise UserError(f"--shard '{text}' must be i/N with 1 ≤ i ≤ N (e.g. 3/8)")
        return cls(int(match.group(1)), int(match.group(2)))

    def indices(self, trials: int) -> range:
        return range((self.number - 1) * trials // self.count, self.number * trials // self.count)

    @property
    def label(self) -> str:
        return f"shard_{self.number:03d}_of_{self.count:03d}"


def plan_fields(config: SimulateConfig) -> dict:
    """The config fields that define the trials (not where they run or are stored); a still head
    (``head_motion.kind`` none) is left out, so runs from before the field existed keep their id."""
    still = config.head_motion.kind == "none"
    return config.model_dump(mode="json", exclude={"cluster": True, "dataset": {"root"}, **({"head_motion": True} if still else {})})


def run_id(config: SimulateConfig) -> str:
    return json_sha256(plan_fields(config))[:12]


def shard_counts(folder: Path) -> dict:
    """Trials of the shard in ``folder`` by status: {number, count, trials, ok, failed, pending}
    (all of its block pending if its data file is not there yet or cannot be read while written)."""
    match = re.fullmatch(r"shard_(\d+)_of_(\d+)", folder.name)
    number, count = int(match.group(1)), int(match.group(2))
    counts = {"number": number, "count": count, "trials": 0, "ok": 0, "failed": 0, "pending": 0}
    try:
        with open_hdf5(folder / DATA_FILE, "dataset file") as f:
            start, stop = decode_attr(f.attrs["trial_range"])
            status = f["trials/status"][start:stop]
    except (OSError, RuntimeError, KeyError, UserError):
        return counts
    ok, failed = int((status == OK.encode()).sum()), int((status == FAILED.encode()).sum())
    return {**counts, "trials": len(status), "ok": ok, "failed": failed, "pending": len(status) - ok - failed}


def shard_folder(config: SimulateConfig, shard: Shard) -> Path:
    return Path(config.dataset.root) / config.dataset.name / SHARDS_DIR / run_id(config) / shard.label
