"""MuJoCo contact law: Coulomb friction as configured, a step-free contact, whiskers independent
of the others in their world (docs/model.md, MuJoCo contacts)."""

from pathlib import Path

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.mujoco.substeps import ContactLossSubsteps
from pipeline.model.array import build_array, single_whisker
from pipeline.model.kinematics import Pose, ProtractionDrive, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.model.rotations import rot_z
from pipeline.model.whisker import WhiskerGeometry, rest_nodes
from pipeline.reports.contact_statics import (bench_config, deepest_m, geometry_of, obstacle_circle, rod_of,
                                              run_engine)
from pipeline.scenes import Scene
from pipeline.scenes.obstacles import Cylinder

RC1 = WhiskerGeometry(38.7e-3, 73.8e-6, 5.9e-6, 9.57)
PEG_RADIUS_M = 0.25e-3
SWEEP_RAD_S = np.radians(50.0)


def _peg_sweep(mu: float, fraction: float = 0.6, dt_s: float = 1e-4, duration_s: float = 0.5):
    """RC1 (bench frame) turning slowly about z into a vertical peg its rest shape meets at
    ``fraction`` of its arc after 2°: (output, peg centre, θ at the samples)."""
    point = rest_nodes(RC1, 1000)[int(round(1000 * fraction))]
    at_contact = rot_z(np.radians(2.0)) @ point
    sweep = np.cross([0.0, 0.0, 1.0], at_contact / np.linalg.norm(at_contact))
    centre = at_contact + (PEG_RADIUS_M + RC1.base_radius_m) * sweep
    config = ModelConfig(engine=EngineConfig(name="mujoco", dt_s=dt_s, contact_friction=mu))
    drive = ProtractionDrive(np.array([0.0, duration_s]), np.array([0.0, SWEEP_RAD_S * duration_s]),
                             interpolation="linear")
    with create_engine(config, single_whisker(RC1, config.material)) as engine:
        out = engine.run(Scene("peg", (Cylinder(PEG_RADIUS_M, 0.01, tuple(centre)),)), Pose(), drive, duration_s)
    return out, centre, drive(out.time_s)


def _contact_force_components(out, centre, theta) -> tuple[np.ndarray, np.ndarray]:
    """[T] normal and tangential force of the peg on the whisker (N), from the base force: the
    whisker is quasi-static, so the peg's force balances the follicle's. The base turns by θ
    about z (bench whisker: its frame is the head frame at θ = 0); the normal points from the
    peg's axis to the nearest point of the whisker's links."""
    force = -np.einsum("tij,tj->ti", rot_z(theta), out.base_wrench[:, 0, :3].astype(float))
    nodes = out.node_positions_m[:, 0, :, :2].astype(float)            # [T, N+1, 2] in plane
    start, link = nodes[:, :-1], np.diff(nodes, axis=1)
    along = np.clip(np.einsum("tki,tki->tk", centre[:2] - start, link) / np.sum(link ** 2, axis=2), 0, 1)
    points = start + along[..., None] * link                             # nearest point per link
    gaps = np.linalg.norm(points - centre[:2], axis=2)
    normal = points[np.arange(len(points)), np.argmin(gaps, axis=1)] - centre[:2]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    f_n = np.einsum("ti,ti->t", force[:, :2], normal)
    return f_n, np.linalg.norm(force - f_n[:, None] * np.pad(normal, ((0, 0), (0, 1))), axis=1)


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_sliding_contact_carries_coulomb_friction(mu):
    """While RC1 slides along the peg, tangential/normal force = μ (a pyramidal cone with soft
    contacts gave 0.1–0.29 for μ = 0.5, the axial base force then barely felt friction)."""
    out, centre, theta = _peg_sweep(mu)
    f_n, f_t = _contact_force_components(out, centre, theta)
    loaded = out.contact[:, 0].any(axis=1) & (f_n > 0.2 * f_n.max())
    assert loaded.sum() >= 200
    ratio = f_t[loaded] / f_n[loaded]
    assert np.median(ratio) == pytest.approx(mu, abs=0.01)
    # ≤ μ when it sticks (the slip reverses); the margin is that of the quasi-static balance
    # and the normal taken from the links' axis (μ = 0: P95 0.033), the 5 % left out the
    # contact passing a node between links (μ = 0: up to 0.13 in one sample)
    assert np.percentile(ratio, 95) <= mu + 0.04


def test_friction_changes_the_axial_base_force():
    """At the peak moment, μ = 0.5 turns the follicle's axial force by > 25 % of |F| (μ = 0:
    Fx/|F| = 0.64, μ = 0.5: 0.26; the pyramidal cone gave 0.44)."""
    axial = []
    for mu in (0.0, 0.5):
        wrench = _peg_sweep(mu)[0].base_wrench[:, 0].astype(float)
        peak = np.argmax(np.abs(wrench[:, 5]))
        axial.append(wrench[peak, 0] / np.linalg.norm(wrench[peak, :3]))
    assert axial[0] - axial[1] > 0.25


def _penetration_m(out, centre) -> np.ndarray:
    """[T] how deep (m) the whisker's capsules sink into the peg (< 0: a gap)."""
    chain = single_whisker(RC1, MaterialConfig()).whiskers[0].chain
    radius = 0.5 * (chain.node_radii_m[:-1] + chain.node_radii_m[1:])
    nodes = out.node_positions_m[:, 0, :, :2].astype(float)
    start, link = nodes[:, :-1], np.diff(nodes, axis=1)
    along = np.clip(np.einsum("tki,tki->tk", centre[:2] - start, link) / np.sum(link ** 2, axis=2), 0, 1)
    gaps = np.linalg.norm(start + along[..., None] * link - centre[:2], axis=2) - radius - PEG_RADIUS_M
    return -gaps.min(axis=1)


def test_contact_law_does_not_depend_on_the_step():
    """The contact's time constant is fixed in seconds: pressed quasi-statically into the peg,
    the whisker sinks as deep at half the step (soft-constraint depth ∝ time constant²; with a
    time constant of two steps it sank 4× less at half the step)."""
    depth = []
    for dt_s in (1e-4, 5e-5):
        out, centre, _ = _peg_sweep(0.5, dt_s=dt_s, duration_s=0.3)
        depth.append(_penetration_m(out, centre)[-50:])
    assert depth[0].min() > 0
    np.testing.assert_allclose(depth[1], depth[0], rtol=0.1)      # measured within 5.1 %


def test_whisker_against_a_mesh_is_independent_of_its_world(tmp_path):
    """The faces built for a world depend on all its whiskers (and with them the order of a
    whisker's contacts); each whisker its own tree and island, its result is the same alone."""
    from test_engine_mujoco import _wavy_wall

    scene = _wavy_wall(tmp_path)
    config = ModelConfig(engine=EngineConfig(name="mujoco"))
    drive = sinusoidal_whisk(duration_s=0.06)
    outputs = {}
    for selection in ("RC1", "RB1,RB2,RC1,RC2,RD1"):
        with create_engine(config, build_array(model_rat().select(selection), config.material)) as engine:
            outputs[selection] = engine.run(scene, Pose(), drive, 0.06)
    alone, group = outputs["RC1"], outputs["RB1,RB2,RC1,RC2,RD1"]
    k = group.index("RC1")
    assert alone.contact.any()
    # bit for bit since each whisker hangs from a head body of its own (9.4e-11 of the peak when
    # they shared one, 7.8e-5 with MuJoCo's world-wide warm start and no-slip stop; a step taken in
    # sub-steps on contact loss in one world and not the other made it 0.35)
    np.testing.assert_array_equal(group.base_wrench[:, k], alone.base_wrench[:, 0])
    np.testing.assert_array_equal(group.contact[:, k], alone.contact[:, 0])


def test_whisker_on_a_peg_is_independent_of_a_companion_on_a_scan(tmp_path):
    """A scene with a scan and a peg: LC1 touches only the peg, RC1 only the scan. The world of
    both reaches the scan; LC1's signals are still those it has alone (MuJoCo's speculative
    contacts, decided by the parts a world reached, put them 0.17 of its peak apart)."""
    from test_engine_mujoco import _wavy_wall

    config = ModelConfig(engine=EngineConfig(name="mujoco"))
    drive = sinusoidal_whisk(duration_s=0.06)
    with create_engine(config, build_array(model_rat().select("LC1"), config.material)) as engine:
        node = engine.run(Scene("empty", ()), Pose(), drive, 0.06).node_positions_m[:, 0, 12]
    far = int(np.argmax(np.linalg.norm(node - node[0], axis=1)))        # the node's path, 60 % of S
    peg = Cylinder(PEG_RADIUS_M, 0.01, tuple(map(float, node[far // 2 + 5])))
    scene = Scene("scan and peg", (_wavy_wall(tmp_path).obstacles[0], peg))
    outputs = {}
    for selection in ("LC1", "LC1,RC1"):
        with create_engine(config, build_array(model_rat().select(selection), config.material)) as engine:
            outputs[selection] = engine.run(scene, Pose(), drive, 0.06)
    alone, pair = outputs["LC1"], outputs["LC1,RC1"]
    assert alone.contact.any() and pair.contact[:, pair.index("RC1")].any()
    np.testing.assert_array_equal(pair.base_wrench[:, pair.index("LC1")], alone.base_wrench[:, 0])
    np.testing.assert_array_equal(pair.contact[:, pair.index("LC1")], alone.contact[:, 0])


DRAINPIPE = Path(__file__).resolve().parents[2] / "outputs" / "meshes" / "drainpipe.obj"


@pytest.mark.skipif(not DRAINPIPE.is_file(), reason="needs the built example meshes (make demo)")
def test_whisker_on_a_scan_is_independent_of_its_companions(monkeypatch):
    """A dataset trial on a real scan (configs/simulate.yaml's trial 4 on the drainpipe: RD1 sticks
    and slips along it, μ = 0.5): RD1 alone and with five neighbours, three of them touching,
    records the same signals bit for bit (on a shared head body they differed by up to a third
    of RD1's peak wrench: the round-off of its world-wide centre of mass, amplified by stick–slip)."""
    from pipeline.config.loader import load_config
    from pipeline.config.simulate import SimulateConfig
    from pipeline.runner.scenes import scene_catalogue
    from pipeline.runner.simulate import _layout
    from pipeline.runner.trial import RunSpec, Simulator

    config, _ = load_config(SimulateConfig, Path(__file__).resolve().parents[2] / "configs" / "simulate.yaml",
                            overrides={"scenes": {"folder": str(DRAINPIPE.parent), "include": ["mesh:drainpipe"]}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    trial = {}

    def drawn(scene, pose, drive, duration_s, **options):          # the trial as drawn, not simulated
        trial.update(scene=scene, pose=pose, drive=drive, duration_s=duration_s)
        raise RuntimeError("drawn")

    monkeypatch.setattr(simulator.whisking, "run", drawn)
    simulator.run(4)
    outputs = {}
    for selection in ("RD1", "RD1,RC1,RD2,RE1,RC2,RD3"):
        array = build_array(model_rat().select(selection), config.model.material)
        with create_engine(config.model, array) as engine:
            outputs[selection] = engine.run(**trial)
    alone, group = outputs["RD1"], outputs["RD1,RC1,RD2,RE1,RC2,RD3"]
    k = group.index("RD1")
    assert alone.contact.any(axis=2).sum() > 20 and group.contact.any(axis=(0, 2)).sum() >= 3
    np.testing.assert_array_equal(group.base_wrench[:, k], alone.base_wrench[:, 0])
    np.testing.assert_array_equal(group.contact[:, k], alone.contact[:, 0])
    np.testing.assert_array_equal(group.point_of_contact[:, k], alone.point_of_contact[:, 0])


def test_a_whisker_sliding_off_a_peg_does_not_pass_through_it():
    """RC3 touching a peg at 85 % of S slides off it at ≈ 22°; the step on which its contact
    opens is taken again in sub-steps (pipeline.engines.mujoco.substeps), so no link enters
    the peg (measured −0.002 mm at 40 °/s; 0.195 mm with that step taken whole)."""
    from pipeline.reports.contact_statics import Case, run_case

    result = run_case(ModelConfig(), Case("RC3", 0.85, 0.0, "mujoco"), speed_deg_s=40.0, sweep_deg=23.0)
    assert result.errors["slip_off_engine_deg"] == pytest.approx(21.9, abs=0.5)
    assert result.errors["deepest_mm"] < 0.02


def test_contacts_found_in_sub_steps_enter_the_sample_flags(monkeypatch):
    """RC3 sliding off a peg at 85 % of S: the steps taken again in sub-steps find contacts the
    step's start did not (pipeline.engines.mujoco.substeps); each is flagged in the sample its
    step belongs to."""
    found: list[tuple[float, np.ndarray]] = []
    step = ContactLossSubsteps.step

    def recording(self, d, targets):
        start = d.time
        step(self, d, targets)
        found.extend((start, links) for links, *_ in self.found if links.size)

    monkeypatch.setattr(ContactLossSubsteps, "step", recording)
    config = bench_config(ModelConfig(), "mujoco", 0.0)
    geometry = geometry_of(config, "RC3")
    peg = obstacle_circle(rod_of(geometry, config.material.youngs_modulus_gpa * 1e9), 0.85, False)
    _, out = run_engine(config, geometry, peg, speed_deg_s=40.0, sweep_deg=23.0)
    assert found                                                  # sub-steps ran and touched
    period = 1.0 / config.engine.output_rate_hz
    for start, links in found:
        sample = int(np.floor(start / period + 1e-9))             # the steps starting in [t_k, t_k+1)
        assert out.contact[sample, 0, links].all()


def test_a_whisker_touching_only_in_sub_steps_is_checked_at_the_next_step(monkeypatch):
    """RC5 sliding off a peg at 85 % of S (μ = 0): a step taken again in sub-steps whose whisker
    touched there keeps the last sub-step's contacts for the next step's loss check, so that step
    is sub-stepped too if the whisker would sink (taken whole, with the per-contact time constants
    tried in session 20, the whisker's centre line ended 0.156 mm inside the peg)."""
    kept: list[bool] = []
    substeps = ContactLossSubsteps._substeps

    def recording(self, d, targets, lost, start_time):
        touched, latest = substeps(self, d, targets, lost, start_time)
        kept.append(bool(np.isin(np.flatnonzero(touched & lost), latest[0]).all()))
        return touched, latest

    monkeypatch.setattr(ContactLossSubsteps, "_substeps", recording)
    config = bench_config(ModelConfig(), "mujoco", 0.0)
    geometry = geometry_of(config, "RC5")
    peg = obstacle_circle(rod_of(geometry, config.material.youngs_modulus_gpa * 1e9), 0.85, False)
    _, out = run_engine(config, geometry, peg)
    assert kept and all(kept)
    assert deepest_m(out, peg) < 0.05e-3
