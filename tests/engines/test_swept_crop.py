"""Faces cropped to the free paths of the whiskers that can touch (pipeline/engines/swept_crop.py):
a node that grazes a face left out is caught, and a whisker that leaves its crop gets the same
result as with its whole reach ball."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine, swept_crop
from pipeline.engines.swept_crop import PrismSpheres, SweptCrop, path_padding_m
from pipeline.engines.units import LENGTH
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import Scene

PADDING_M = 5e-4


def _point_prisms(points_m: np.ndarray) -> PrismSpheres:
    """Prisms shrunk to points (bounding spheres of radius 0): gaps are exact distances."""
    return PrismSpheres(np.repeat(points_m[:, None] * LENGTH, 6, axis=1))


def test_padding_covers_the_moves_of_a_node_and_its_neighbours():
    nodes = np.zeros((4, 3, 3))
    nodes[2:, 2, 0] = 1e-3                                   # the tip jumps 1 mm between samples 1 and 2
    padding = path_padding_m(PADDING_M, nodes)
    expected = np.full((4, 3), PADDING_M)
    expected[1:3, 1:] += 5e-4                                # the tip and its neighbour, both samples
    np.testing.assert_allclose(padding, expected)


def test_a_node_grazing_a_left_out_face_escapes_the_crop():
    """Faces on a line beside a still two-node path: those within the padding plus the margin are
    built; nodes moved just inside the padding of the nearest left-out face escape, just outside
    they do not."""
    path = np.zeros((3, 2, 3))
    path[:, 1, 0] = 1e-3
    offsets = np.arange(1, 40) * 5e-4                        # faces along y, 0.5 mm apart
    faces_m = np.stack([np.zeros_like(offsets), offsets, np.zeros_like(offsets)], axis=1)
    crop = SweptCrop(_point_prisms(faces_m), [np.arange(len(offsets))], [[path]], np.array([PADDING_M]))
    built = offsets[crop.faces]
    assert built.max() <= PADDING_M + swept_crop.SWEPT_MARGIN_M + 1e-12 < offsets[len(crop.faces)]
    first_left_out = offsets[len(crop.faces)]
    for clearance, escapes in ((PADDING_M + 1e-6, False), (PADDING_M - 1e-6, True)):
        moved = path.copy()
        moved[:, 0, 1] = first_left_out - clearance          # the base node slides toward the faces
        assert crop.escaped(moved[:, None]).tolist() == [escapes], clearance
    whole_reach = SweptCrop(crop.spheres, [np.arange(len(offsets))], [None], np.array([PADDING_M]))
    assert len(whole_reach.faces) == len(offsets) and not whole_reach.escaped(path[:, None]).any()


def _engine(free_whiskers: str):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=free_whiskers))
    return create_engine(config, build_array(model_rat().select("RC0,RC1,RC2"), config.material))


@pytest.mark.parametrize("margin_m", [0.0, swept_crop.SWEPT_MARGIN_M])
def test_cropped_whiskers_match_their_whole_reach(monkeypatch, margin_m):
    """Three whiskers pressed into a sphere of 1.1 mm faces, with faces cropped to their free
    paths (no margin: they leave the crop and run again) and with their whole reach ball: the
    same contacts, the same base wrench up to the trace of the contacts' order (module docstring
    of pipeline/engines/mujoco/, Independence); fewer faces built."""
    import trimesh

    from pipeline.scenes.obstacles import TriangleMesh

    monkeypatch.setattr(swept_crop, "SWEPT_MARGIN_M", margin_m)
    escapes, faces = [], []
    escaped, init = SweptCrop.escaped, SweptCrop.__init__

    def counted_init(self, *args):
        init(self, *args)
        faces.append((len(self.faces), len(np.unique(np.concatenate(self.reach_faces)))))

    monkeypatch.setattr(SweptCrop, "escaped", lambda self, nodes: escapes.append(escaped(self, nodes)) or escapes[-1])
    monkeypatch.setattr(SweptCrop, "__init__", counted_init)
    ico = trimesh.creation.icosphere(subdivisions=4, radius=0.015)
    scene = Scene("sphere", (TriangleMesh(np.asarray(ico.vertices) + [0.045, -0.010, 0.0], np.asarray(ico.faces),
                                          "ball"),))
    drive = sinusoidal_whisk(duration_s=0.06)
    with _engine("coarse") as cropped, _engine("engine") as whole:
        out, reference = (e.run(scene, Pose(), drive, 0.06) for e in (cropped, whole))
    assert reference.contact.any(axis=(0, 2)).all()
    built, reach = faces[0]
    assert built < 0.8 * reach
    if margin_m == 0.0:
        assert np.concatenate(escapes).any()                 # some left the crop and ran again
    np.testing.assert_array_equal(out.contact, reference.contact)
    peak = np.abs(reference.base_wrench).max(axis=0)
    assert np.all(np.abs(out.base_wrench - reference.base_wrench) <= 1e-3 * peak + 1e-12)
