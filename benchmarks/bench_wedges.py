"""Where the dataset statistics do not converge in the step (issue 24): links wedged between
the prisms of a scan (MuJoCo).

Run: .venv/bin/python benchmarks/bench_wedges.py [--trials 0-11] [--depth-um 10] [--json out.json]

MuJoCo collides a scan as one convex prism per face (pipeline/engines/mujoco/, Triangle
meshes). A link pressed into the surface near an edge between two faces can be nearer the
slanted side walls of both prisms than their faces: the two contacts then push it sideways in
opposite directions (normals more than 90° apart), and with friction the squeeze holds it — a
tip sticks while its base moment climbs, until it lets go at an instant that depends on the
step. Per step, this benchmark counts for every whisker the steps on which one of its links is
pressed by two contacts whose normals are more than 90° apart, both deeper than ``--depth-um``;
it runs the trials of configs/simulate.yaml at the default step and with every whisker's step
halved (as benchmarks/bench_statistics.py) and prints, for the pairs touched in both, the
paired |relative difference| of peak |M| and peak |F_t| (median, P90) separately for the pairs
wedged at either step and those never wedged.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bench_statistics import REPO, VARIANTS, trial_table
from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator


class WedgeRecorder:
    """Wraps ``mujoco.mj_step`` (and the MuJoCo world's model build, to name the whiskers of
    each model) to count, per whisker name, the steps on which a link of it is wedged."""

    def __init__(self, depth_mm: float):
        import mujoco

        from pipeline.engines import mujoco as engine

        self.mujoco, self.world, self.depth_mm = mujoco, engine.MujocoWorld, depth_mm
        self.step, self.build = mujoco.mj_step, engine.MujocoWorld._build
        self.worlds: dict[int, tuple] = {}      # id(model) → (geom → flat link or −1, links, member names)
        self.counts: dict[str, int] = {}

    def __enter__(self):
        recorder, mujoco = self, self.mujoco

        def build(world, *args, **kwargs):
            recorder.build(world, *args, **kwargs)
            recorder.worlds[id(world.model)] = (world.link_of_geom, world.links,
                                                [world.whiskers[k].name for k in world.members])

        def step(m, d):
            recorder.step(m, d)
            if d.ncon > 1 and id(m) in recorder.worlds:
                recorder._count(d, *recorder.worlds[id(m)])

        self.world._build, mujoco.mj_step = build, step
        return self

    def __exit__(self, *exc):
        self.world._build, self.mujoco.mj_step = self.build, self.step

    def _count(self, d, link_of_geom: np.ndarray, n_links: int, names: list[str]) -> None:
        contact = d.contact
        deep = contact.dist < -self.depth_mm
        pairs = link_of_geom[contact.geom[deep]]                         # [C, 2]: the whisker's link, or −1
        links = pairs.max(axis=1)
        mine = links >= 0
        if np.count_nonzero(mine) < 2:
            return
        outward = contact.frame[deep][mine, :3] * np.where(pairs[mine, 0] >= 0, 1.0, -1.0)[:, None]
        links = links[mine]
        opposed = (links[:, None] == links[None, :]) & (outward @ outward.T < 0.0)
        for name in {names[j] for j in links[opposed.any(axis=1)] // n_links}:
            self.counts[name] = self.counts.get(name, 0) + 1


def run(variant: str, trials: list[int], depth_mm: float) -> tuple[dict, list[dict]]:
    """Per trial the bench_statistics table and the wedged-step counts per whisker name."""
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides=VARIANTS[variant] | {"scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    tables, counts = [], []
    for index in trials:
        with WedgeRecorder(depth_mm) as recorder:
            result = simulator.run(index)
        tables.append(trial_table(result.arrays, result.record.samples))
        counts.append(dict(recorder.counts))
        print(f"  {variant}: trial {index}: wedged steps {recorder.counts}", flush=True)
    names = [n.decode() if isinstance(n, bytes) else str(n) for n in simulator.spec.layout.whiskers["name"]]
    return {"names": names, "tables": tables}, counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", default="0-11", help="first-last trial index")
    parser.add_argument("--depth-um", type=float, default=10.0, help="both contacts deeper than this (µm)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    first, last = map(int, args.trials.split("-"))
    trials = list(range(first, last + 1))
    base, base_counts = run("default", trials, args.depth_um * 1e-3)
    half, half_counts = run("half", trials, args.depth_um * 1e-3)
    rows = []
    for t, (a, b) in enumerate(zip(base["tables"], half["tables"])):
        for w in np.flatnonzero(a["touched"] & b["touched"]):
            name = base["names"][w]
            rows.append({"trial": trials[t], "whisker": name,
                         "wedged_default": base_counts[t].get(name, 0), "wedged_half": half_counts[t].get(name, 0),
                         "peak_moment": float(b["peak_moment"][w] / a["peak_moment"][w] - 1),
                         "peak_transverse": float(b["peak_transverse"][w] / a["peak_transverse"][w] - 1)})
    wedged = np.array([r["wedged_default"] + r["wedged_half"] > 0 for r in rows])
    for label, chosen in (("all", np.ones_like(wedged)), ("wedged at either step", wedged), ("never wedged", ~wedged)):
        if not chosen.any():
            continue
        text = [f"{label}: {int(chosen.sum())} pairs"]
        for field in ("peak_moment", "peak_transverse"):
            d = 100 * np.abs([r[field] for r, c in zip(rows, chosen) if c])
            text.append(f"{field} |d| median {np.median(d):.1f} % P90 {np.percentile(d, 90):.1f} %")
        print("; ".join(text))
    if args.json:
        args.json.write_text(json.dumps({"trials": args.trials, "pairs": rows}, indent=1))


if __name__ == "__main__":
    main()
