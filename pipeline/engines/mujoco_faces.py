"""MuJoCo's contacts with a scan as contacts with its triangles, read one-sided
(:mod:`pipeline.engines.one_sided`, as Bullet reads them).

MuJoCo collides a scan as one convex prism per face (:class:`~pipeline.engines.mujoco.MeshPrisms`).
A link pressed into the surface near an edge between two faces is nearer both prisms' slanted
side walls than their faces: two opposed contacts squeeze it and friction holds it (a wedge),
as deep as the step let it sink. Here the prisms only *find* which link touches the scan: after
MuJoCo's collision, every link–prism contact is rewritten before the constraints are built
(:meth:`FaceContacts.step`), and the step goes on as ``mj_step`` does.

Each link–prism contact is read at its capsule axis point (the axis point under MuJoCo's
witness, ``pos − n·(dist/2 + r)`` from the link's side): its contact with the surface (nearest
face, edge or vertex; an axis that has crossed a face pushed back out along the face's normal,
:func:`~pipeline.engines.one_sided.one_sided`), kept where it penetrates (gap ≤ 0). Per link,
deepest first, a contact within :data:`~pipeline.engines.one_sided.MERGE_MM` of a kept one, or
whose normal opposes one (a link between two faces: the deeper pushes it out), is dropped.
A kept contact takes the new position, normal and tangents, and distance in MuJoCo's list; the
others are excluded (``exclude`` 1, no constraint row), so the contact count never grows.
Internal units mm.
"""

from __future__ import annotations

import numpy as np

from pipeline.engines.one_sided import MERGE_MM, OneSidedMesh, one_sided


def contact_frames(normals: np.ndarray) -> np.ndarray:
    """[C, 9] MuJoCo contact frames: each unit normal [C, 3] then two unit tangents (rows,
    right-handed)."""
    x, y, z = normals.T
    along_x = np.abs(x) >= np.abs(y)          # a tangent ⟂ n: n × y when n is nearer x than y, else n × x
    t1 = np.where(along_x[:, None], np.stack([-z, np.zeros_like(x), x], 1), np.stack([np.zeros_like(x), z, -y], 1))
    t1 /= np.sqrt(np.einsum("ij,ij->i", t1, t1))[:, None]
    a, b, c = t1.T
    t2 = np.stack([y * c - z * b, z * a - x * c, x * b - y * a], 1)
    return np.concatenate([normals, t1, t2], axis=1)


def _first_free(conflicts: np.ndarray) -> np.ndarray:
    """[K] bool: greedy in order, each candidate kept unless it conflicts with a kept earlier one."""
    kept = np.zeros(len(conflicts), bool)
    for i, row in enumerate(conflicts):
        kept[i] = not (row[:i] & kept[:i]).any()
    return kept


class FaceContacts:
    """Rewrites a MuJoCo world's link–prism contacts as one-sided contacts with the scan's
    triangles (module docstring).

    ``mesh_of_geom`` [ngeom + 1]: per geom, the index into ``meshes`` of the static mesh whose
    prism it is, or −1; ``meshes``: (:class:`OneSidedMesh`, its origin in the world, mm);
    ``link_of_geom`` [ngeom + 1] the flat whisker link of a geom or −1; ``link_radii_mm``
    [flat links] each link's capsule radius."""

    def __init__(self, mesh_of_geom: np.ndarray, meshes: list[tuple[OneSidedMesh, np.ndarray]],
                 link_of_geom: np.ndarray, link_radii_mm: np.ndarray):
        self.mesh_of_geom, self.meshes = mesh_of_geom, meshes
        self.link_of_geom, self.link_radii_mm = link_of_geom, link_radii_mm

    def step(self, m, d) -> None:
        """One ``mj_step`` of the discrete integrator with the prism contacts rewritten
        (bit-identical to ``mj_step`` on a step without any)."""
        import mujoco

        mujoco.mj_checkPos(m, d)
        mujoco.mj_checkVel(m, d)
        mujoco.mj_fwdPosition(m, d)
        if d.ncon and self.rewrite(d):
            mujoco.mj_makeConstraint(m, d)
            mujoco.mj_island(m, d)
            mujoco.mj_projectConstraint(m, d)
        mujoco.mj_sensorPos(m, d)
        mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_POS, 0)
        mujoco.mj_checkAcc(m, d)
        flags = m.opt.disableflags     # the discrete integrator's update: v += h·a, q += h·v (the
        m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)   # metric has D)
        mujoco.mj_Euler(m, d)
        m.opt.disableflags = flags

    def rewrite(self, d) -> bool:
        """Rewrite the current link–prism contacts of ``d`` in place; False if there are none."""
        contact = d.contact
        geoms = contact.geom
        mesh = self.mesh_of_geom[geoms].max(axis=1)
        pair_links = self.link_of_geom[geoms]
        rows = np.flatnonzero((mesh >= 0) & (pair_links.max(axis=1) >= 0))
        if not rows.size:
            return False
        pair_links = pair_links[rows]
        links = pair_links.max(axis=1)
        sign = np.where(pair_links[:, 0] >= 0, -1.0, 1.0)[:, None]    # normals point from geom 0 to geom 1
        radii = self.link_radii_mm[links]
        axis = contact.pos[rows] + sign * contact.frame[rows, :3] * (0.5 * contact.dist[rows] + radii)[:, None]
        if len(self.meshes) == 1:
            kept, points, normals, gaps = one_sided(axis, radii, *self.meshes[0], 0.0)
        else:
            mesh = mesh[rows]
            kept = np.zeros(len(axis), bool)
            points, normals, gaps = np.zeros_like(axis), np.zeros_like(axis), np.zeros(len(axis))
            for k in np.unique(mesh):
                on = mesh == k
                kept[on], points[on], normals[on], gaps[on] = one_sided(axis[on], radii[on], *self.meshes[k], 0.0)
        candidates = np.flatnonzero(kept)
        order = candidates[np.lexsort((gaps[candidates], links[candidates]))]   # per link, deepest first
        ordered_points, ordered_normals = points[order], normals[order]
        conflicts = (links[order, None] == links[None, order]) & (
            (np.sum((ordered_points[:, None] - ordered_points[None]) ** 2, axis=2) < MERGE_MM ** 2)
            | (ordered_normals @ ordered_normals.T < 0.0))
        chosen = np.zeros(len(rows), bool)
        chosen[order[_first_free(conflicts)]] = True
        contact.exclude[rows[~chosen]] = 1
        contact.efc_address[rows[~chosen]] = -1                        # read as no force after the solve
        rows, normals, gaps, sign = rows[chosen], normals[chosen], gaps[chosen], sign[chosen]
        contact.frame[rows] = contact_frames(sign * normals)
        contact.pos[rows] = points[chosen] - 0.5 * gaps[:, None] * normals     # midway between the surfaces
        contact.dist[rows] = gaps
        return True

