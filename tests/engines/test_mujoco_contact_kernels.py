"""The compiled contact readers (pipeline/engines/mujoco/contact_kernels.py) against the plain
numpy arithmetic they replace, on random contact lists with excluded, separated, flex (geom −1)
and obstacle-only pairs."""

import numpy as np
import pytest

from pipeline.engines.mujoco import contact_kernels as kernels
from pipeline.model.rotations import rotation_zyx


def contact_list(seed: int, contacts: int = 40, bodies: int = 12, geoms: int = 15):
    """MuJoCo-shaped arrays: contacts (dist, exclude, geom [C, 2], frame [C, 9], pos [C, 3]),
    body poses (xpos [B, 3], xmat [B, 9]) and per geom its body; geoms 0–2 are obstacles'."""
    rng = np.random.default_rng(seed)
    dist = rng.uniform(-0.05, 0.05, contacts)
    exclude = (rng.random(contacts) < 0.2).astype(np.int32)
    geom = rng.integers(-1, geoms, (contacts, 2)).astype(np.int32)
    frame = rng.normal(size=(contacts, 9))
    pos = rng.normal(size=(contacts, 3))
    xpos = rng.normal(size=(bodies, 3))
    xmat = np.array([rotation_zyx(*angles).ravel() for angles in rng.uniform(-3, 3, (bodies, 3))])
    geom_bodyid = rng.integers(0, bodies, geoms).astype(np.int32)
    of_geom = np.r_[np.full(3, -1), np.arange(geoms - 3), -1].astype(np.int64)    # last entry: geom −1
    return dist, exclude, geom, frame, pos, xpos, xmat, geom_bodyid, of_geom


@pytest.mark.parametrize("seed", range(4))
def test_touching_links_match_the_numpy_reading(seed):
    dist, exclude, geom, _, pos, xpos, xmat, _, link_of_geom = contact_list(seed)
    link_bodies = np.random.default_rng(seed).integers(0, len(xpos), link_of_geom.max() + 1)
    lengths = np.random.default_rng(seed + 1).uniform(0.5, 2.0, len(link_bodies))
    pressed = (dist <= 0.0) & (exclude == 0)
    links = link_of_geom[geom[pressed]].max(axis=1)
    mine = links >= 0
    links = links[mine]
    proximal = xpos[link_bodies[links]]
    distal = proximal + xmat[link_bodies[links]][:, 0::3] * lengths[links, None]
    expected = (links, pos[pressed][mine], proximal, distal)
    found = kernels.touching_links(dist, exclude, geom, pos, xpos, xmat, link_of_geom, link_bodies, lengths)
    assert len(expected[0]) > 0
    for a, b in zip(found, expected):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", range(4))
def test_pressed_contacts_match_the_numpy_reading(seed):
    dist, exclude, geom, frame, pos, xpos, xmat, geom_bodyid, member_of_geom = contact_list(seed)
    pressed = (dist <= 0.0) & (exclude == 0)
    geoms = geom[pressed]
    link_second = member_of_geom[geoms[:, 1]] >= 0
    members = member_of_geom[geoms].max(axis=1)
    mine = members >= 0
    link_geoms = np.where(link_second, geoms[:, 1], geoms[:, 0])[mine]
    normals = frame[pressed][mine, :3] * np.where(link_second[mine], 1.0, -1.0)[:, None]
    bodies = geom_bodyid[link_geoms]
    points = pos[pressed][mine]
    local = np.einsum("cji,cj->ci", xmat[bodies].reshape(-1, 3, 3), points - xpos[bodies])
    expected = (members[mine], bodies, points, local, normals, dist[pressed][mine])
    found = kernels.pressed_contacts(dist, exclude, geom, frame, pos, xpos, xmat, member_of_geom, geom_bodyid)
    assert len(expected[0]) > 0
    for a, b in zip(found, expected):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


def test_no_contacts_give_empty_readings():
    dist, exclude, geom, frame, pos, xpos, xmat, geom_bodyid, of_geom = contact_list(0, contacts=0)
    assert all(len(part) == 0 for part in kernels.pressed_contacts(dist, exclude, geom, frame, pos, xpos, xmat,
                                                                   of_geom, geom_bodyid))
    assert all(len(part) == 0 for part in kernels.touching_links(dist, exclude, geom, pos, xpos, xmat, of_geom,
                                                                 np.zeros(20, np.int64), np.ones(20)))


@pytest.mark.parametrize("seed", range(4))
def test_a_step_s_contacts_read_in_one_call_are_both_readings_and_the_members_in_contact(seed):
    """step_contacts: pressed_contacts and touching_links of the same list, and the members of
    every contact that is not excluded (penetrating or not), as the world's numpy reading took
    them (both geoms of each contact, in order)."""
    dist, exclude, geom, frame, pos, xpos, xmat, geom_bodyid, link_of_geom = contact_list(seed)
    member_of_geom = np.where(link_of_geom >= 0, link_of_geom // 4, -1)
    link_bodies = np.random.default_rng(seed).integers(0, len(xpos), link_of_geom.max() + 1)
    lengths = np.random.default_rng(seed + 1).uniform(0.5, 2.0, len(link_bodies))
    pressed, touching, members = kernels.step_contacts(dist, exclude, geom, frame, pos, xpos, xmat, member_of_geom,
                                                       geom_bodyid, link_of_geom, link_bodies, lengths)
    expected = (kernels.pressed_contacts(dist, exclude, geom, frame, pos, xpos, xmat, member_of_geom, geom_bodyid),
                kernels.touching_links(dist, exclude, geom, pos, xpos, xmat, link_of_geom, link_bodies, lengths))
    for found, reading in zip((pressed, touching), expected):
        for a, b in zip(found, reading):
            np.testing.assert_array_equal(a, b)
    links = link_of_geom[geom[exclude == 0]].ravel()
    np.testing.assert_array_equal(members, links[links >= 0] // 4)
    assert (dist[exclude == 0] > 0).any() and len(members) > len(pressed[0])    # separated contacts count too
