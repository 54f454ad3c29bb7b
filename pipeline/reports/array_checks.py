"""Fig. 5: the right array against a passive peg, two active pegs and a natural scene.

Each scene is one trial of :func:`pipeline.protocols.whisking.run_trial` with the paper's drive
(still for the passive peg, the configured whisk otherwise). The natural scene is a cleaned
scan mesh (default: the drainpipe built by ``pipeline build-meshes``) placed by the dataset's
pose sampler with the right side facing it, so that whiskers reach it and none starts inside;
without built meshes the drainpipe's synthetic reference surface (the object the example scan
was made of) stands in. The paper's observations are checked as signs of rank
correlations and differences.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.config.simulate import PoseSamplingConfig
from pipeline.errors import UserError
from pipeline.meshes.synthetic import scene_mesh
from pipeline.model.kinematics import Pose
from pipeline.protocols.whisking import Whisking, default_drive, run_trial
from pipeline.reports import published as P
from pipeline.reports.checks import Section, check, spearman
from pipeline.reports.stats import contact_runs
from pipeline.scenes import Scene, TriangleMesh, active_pegs, passive_peg
from pipeline.scenes.library import load_mesh
from pipeline.scenes.poses import PoseSampler, PoseSamplingError

DEFAULT_MESH = Path("outputs/meshes/drainpipe.obj")
QUICK_WHISKERS = ("RD0", "RC1", "RD2")
FULL_WHISKERS = ("RA0", "RA1", "RA2", "RB0", "RB1", "RB2", "RC0", "RC1", "RC2", "RD0", "RD1", "RD2", "RE1", "RE2")
SIGNAL_WHISKER = "RD0"          # δ, the paper's Fig. 5F
DURATION_S = {"peg-passive": 0.25, "pegs-active": 0.25, "natural": 0.25}
QUICK_DURATION_S = {"peg-passive": 0.25, "pegs-active": 0.125, "natural": 0.125}
POSE_SEED = 0


def slip_off(signals: dict) -> float:
    """Mean rise of the POC at the last sample of a contact over the median of its earlier
    samples, over the contacts of two samples or more (NaN without any)."""
    poc = signals["poc"]
    rises = [poc[s + n - 1, w] - np.median(poc[s:s + n - 1, w])
             for w, s, n in zip(*contact_runs(signals["touching"])) if n >= 2]
    return float(np.mean(rises)) if rises else float("nan")


def natural_scene(mesh: Path | None, config: ModelConfig, whiskers, drive) -> tuple[Scene, Pose, str]:
    """(scene, head pose, note): the mesh (or the synthetic drainpipe) with a sampled pose facing
    the right side."""
    if mesh is None and not DEFAULT_MESH.is_file():
        reference = scene_mesh("drainpipe")
        surface = TriangleMesh(np.asarray(reference.vertices) * 1e-3, np.asarray(reference.faces),
                               "synthetic drainpipe")
        name, source = "drainpipe", (f"the drainpipe's synthetic reference surface (no scan mesh at "
                                     f"{DEFAULT_MESH}: `pipeline build-meshes`)")
    else:
        path = Path(mesh) if mesh is not None else DEFAULT_MESH
        surface, name, source = load_mesh(path), path.stem, path.name
    array = Whisking(config, ",".join(whiskers)).array  # the array that run_scenes whisks
    # rim_margin_mm 0: with the heading fixed and half the array reaching, no pose in 5 000 keeps every
    # sweep 1 mm from the drainpipe scan's open rims; the figure's pose stays the one it always had
    sampling = PoseSamplingConfig(right_side_probability=1.0, heading_deg=0.0, pitch_deg=0.0, roll_deg=0.0,
                                  min_whiskers_reaching=max(1, (len(whiskers) + 1) // 2), max_attempts=5000,
                                  rim_margin_mm=0.0)
    theta = drive(np.linspace(0.0, drive.duration_s, 200))
    try:
        sample = PoseSampler(surface, array, sampling).sample(np.random.default_rng(POSE_SEED),
                                                              (float(theta.min()), float(theta.max())),
                                                              float(theta[0]))
    except PoseSamplingError as exc:
        raise UserError(f"natural scene {source}: {exc}") from None
    note = (f"{source}, head {sample.distance_m * 1e3:.0f} mm from the aimed surface point, "
            f"{sample.whiskers_reaching} whiskers reaching (pose seed {POSE_SEED})")
    return Scene(f"mesh:{name}", (surface,)), sample.pose, note


def display_order(names: list[str]) -> list[int]:
    """Indices by column (caudal → rostral), then row (A → E), as the paper's Fig. 5."""
    return sorted(range(len(names)), key=lambda i: (int(names[i][2]), names[i][1]))


def run_scenes(config: ModelConfig, quick: bool, mesh: Path | None,
               progress: Callable[[str], None] = lambda _: None) -> dict:
    whiskers = QUICK_WHISKERS if quick else FULL_WHISKERS
    durations = QUICK_DURATION_S if quick else DURATION_S
    runs = {}
    for key, make in (("peg-passive", passive_peg), ("pegs-active", active_pegs), ("natural", None)):
        duration = durations[key]
        if make is None:
            drive = default_drive(Scene("natural"), config, duration)
            scene, pose, note = natural_scene(mesh, config, whiskers, drive)
        else:
            scene, pose, note = make(), Pose(), ""
            drive = default_drive(scene, config, duration)
        progress(f"fig. 5: {scene.name}, {len(whiskers)} right whiskers, {duration * 1e3:g} ms")
        output = run_trial(config, scene, pose, duration, ",".join(whiskers), drive)
        order = display_order(output.whisker_names)
        runs[key] = {"scene": scene.name, "note": note, "time_s": output.time_s,
                     "names": [output.whisker_names[i] for i in order],
                     "touching": output.contact.any(axis=2)[:, order], "poc": output.point_of_contact[:, order],
                     "moment": output.moment_magnitude()[:, order], "signal_whisker": SIGNAL_WHISKER,
                     "signals": output.base_wrench[:, output.index(SIGNAL_WHISKER)]
                     if SIGNAL_WHISKER in output.whisker_names else None}
    return runs


def first_contact_s(run: dict) -> np.ndarray:
    touching = run["touching"]
    return np.where(touching.any(axis=0), run["time_s"][np.argmax(touching, axis=0)], np.nan)


def array_section(config: ModelConfig, quick: bool = False, mesh: Path | None = None,
                  progress: Callable[[str], None] = lambda _: None) -> Section:
    runs = run_scenes(config, quick, mesh, progress)
    columns = {key: np.array([int(n[2]) for n in run["names"]]) for key, run in runs.items()}
    slips = {key: slip_off(run) for key, run in runs.items()}
    rostral = spearman(columns["peg-passive"], first_contact_s(runs["peg-passive"]))
    in_contact = [(run["poc"][run["touching"]], run["moment"][run["touching"]]) for run in runs.values()]
    m_poc = spearman(np.concatenate([p for p, _ in in_contact]), np.concatenate([m for _, m in in_contact]))
    active = ("pegs-active", "natural")
    mean_m = np.concatenate([runs[k]["moment"].mean(axis=0) for k in active])
    caudal = spearman(np.concatenate([columns[k] for k in active]), mean_m)
    less_slip = slips["natural"] - slips["pegs-active"]
    checks = [
        check("slip_off_passive_peg", "POC rise at the end of a contact, passive peg", P.SLIP_OFF,
              slips["peg-passive"], slips["peg-passive"] > 0, "> 0"),
        check("rostral_first_passive_peg", "rank corr. column vs first contact time, passive peg", P.ROSTRAL_FIRST,
              rostral, rostral < 0, "< 0 (rostral columns first)"),
        check("m_poc_rank_correlation", "rank corr. POC vs M in contact, all scenes", P.M_POC_INVERSE, m_poc,
              m_poc < 0, "< 0"),
        check("caudal_larger_m", "rank corr. column vs mean M, whisking scenes", P.CAUDAL_LARGER_M, caudal,
              caudal < 0, "< 0 (caudal columns larger)"),
        check("natural_minus_pegs_slip_off", "POC rise at contact end, natural − active pegs",
              P.LESS_SLIP_ON_SURFACE, less_slip, less_slip < 0, "< 0"),
    ]
    summary = {key: {"scene": run["scene"], "note": run["note"], "whiskers": run["names"],
                     "duration_s": float(run["time_s"][-1]),
                     "contact_probability": run["touching"].mean(axis=0),
                     "first_contact_s": first_contact_s(run), "max_moment_N_m": run["moment"].max(axis=0),
                     "slip_off": slips[key]}
               for key, run in runs.items()}
    whiskers = runs["peg-passive"]["names"]
    caption = (f"Fig. 5: {len(whiskers)} whiskers of the right array ({', '.join(whiskers)}) against a passive "
               "peg (still array, peg 0.4 m/s rostral → caudal), two active pegs and a natural scene "
               f"({runs['natural']['note'] or runs['natural']['scene']}). Rows: POC and moment magnitude M per "
               f"whisker (by column, then row) over time; the six base signals of {SIGNAL_WHISKER} (δ).")
    return Section("fig5", "Fig. 5: the array in three scenes", checks, summary, {"runs": runs}, caption)
