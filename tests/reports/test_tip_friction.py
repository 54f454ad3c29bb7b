"""Coulomb friction of both engines on a flat face (pipeline/reports/tip_friction.py).

RC3's tip on a box face at 60° to it, μ = 0.5, the chain with the tip segment (the default
chain's rigid last half-link reads ~8 % high at a tip contact: tests/references/
test_contact_statics.py): the tip slides, sticks while the force turns over and slides back, as
the elastica does. Measured (benchmarks/bench_contact_friction.py --faces --tip-segment): MuJoCo
M / F⊥ / F∥ RMS 1.7 / 4.2 / 8.6 %, stick or slip differs from the elastica on 5 % of the samples,
slip onset 4.45° against the elastica's 4.4°; Bullet the same to 0.3 points. With μ acting as
0.25 (Bullet's old combine rule) 4.0 / 10.0 / 25.3 %, 17 % of the samples, onset 4.09°.
"""

import numpy as np
import pytest
import trimesh

from pipeline.config.physics import ModelConfig
from pipeline.reports.tip_friction import FACE_HALF_EXTENTS_M, FaceCase, reference_of, run_face_case, sawtooth_obstacle

CONFIG = ModelConfig(extensions={"tip_segment": {}})
SWEEP_DEG = 3.6                  # to 5.6°: the elastica's path ends at 5.4° (tip along the face)


@pytest.fixture(scope="module")
def reference():
    return reference_of(CONFIG, "RC3", 60.0, 0.5, SWEEP_DEG)


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_tip_on_a_face_sticks_and_slips_as_coulomb_friction(reference, engine):
    errors = run_face_case(CONFIG, FaceCase("RC3", 60.0, 0.5, engine), SWEEP_DEG, reference).errors
    assert errors["samples"] > 250
    assert errors["moment_rms_pct"] <= 3.0 and errors["transverse_rms_pct"] <= 6.0
    assert errors["axial_rms_pct_of_f"] <= 12.0
    assert errors["slip_disagree_pct"] <= 10.0
    assert 30.0 < errors["ref_stick_pct"] < 70.0        # the case does stick and slip
    assert abs(errors["slip_onset_engine_deg"] - errors["slip_onset_ref_deg"]) <= 0.25
    assert np.isfinite(errors["slip_onset_ref_deg"])


def test_sawtooth_face_is_a_closed_outward_slab_with_its_ridges_on_the_face():
    surface, normal = np.array([0.01, 0.002]), np.array([0.6, 0.8])
    mesh = sawtooth_obstacle(surface, normal, 20e-6, 200e-6)
    solid = trimesh.Trimesh(mesh.vertices_m, mesh.faces, process=False)
    assert solid.is_watertight and solid.is_winding_consistent
    width, height = 2 * FACE_HALF_EXTENTS_M[0], 2 * FACE_HALF_EXTENTS_M[2]
    slab = width * 2 * FACE_HALF_EXTENTS_M[1] * height - 0.5 * 20e-6 * width * height   # less the grooves
    assert solid.volume == pytest.approx(slab, rel=1e-9)                               # > 0: wound outward
    above = (mesh.vertices_m[:, :2] - surface) @ normal
    assert above.max() == pytest.approx(0.0, abs=1e-12)                               # ridges on the face
