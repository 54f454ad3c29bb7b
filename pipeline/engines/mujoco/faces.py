"""MuJoCo's contacts with a scan as contacts with its triangles, read one-sided
(:mod:`pipeline.engines.one_sided`, as Bullet reads them).

MuJoCo collides a scan as one convex prism per face (:class:`~pipeline.engines.mujoco.prisms.MeshPrisms`).
A link pressed into the surface near an edge between two faces is nearer both prisms' slanted
side walls than their faces: two opposed contacts squeeze it and friction holds it (a wedge),
as deep as the step let it sink. Here the prisms only *find* which link touches the scan: after
MuJoCo's collision, every link–prism contact is rewritten before the constraints are built
(:meth:`FaceContacts.step`), and the step goes on as ``mj_step`` does.

Per link with prism contacts, the candidates are each contact's capsule axis point (the axis
point under MuJoCo's witness, ``pos − n·(dist/2 + r)`` from the link's side) and those of the
link's two nodes that have crossed the surface; each reads its contact with the surface
(nearest face, edge or vertex; a crossed axis pushed back out along the face normal), kept
where it penetrates (gap ≤ 0). Deepest first, a candidate within :data:`DUPLICATE_MM` of a kept
one of the same link (two prisms read at their shared edge), or whose normal opposes one (a
link between two faces: the deeper pushes it out), is dropped. The kept ones take the link's
contact slots in MuJoCo's list (deepest first: position, normal and tangents, distance); slots
left over are excluded (``exclude`` 1, no constraint row) and candidates beyond the slots
dropped, so the contact count never grows.
Internal units mm.
"""

from __future__ import annotations

import numpy as np

from pipeline.engines.one_sided import OneSidedMesh, one_sided
import mujoco

DUPLICATE_MM = 1e-3         # a link's contacts this close are one (two prisms' faces read at their shared edge)


def contact_frames(normals: np.ndarray) -> np.ndarray:
    """[C, 9] MuJoCo contact frames: each unit normal [C, 3] then two unit tangents (rows,
    right-handed; Duff et al. 2017's branchless orthonormal basis)."""
    x, y, z = normals.T
    s = np.copysign(1.0, z)
    a = -1.0 / (s + z)
    b = x * y * a
    return np.stack([x, y, z, 1.0 + s * x * x * a, s * b, -s * x, b, s + y * y * a, -y], axis=1)


def _first_free(conflicts: np.ndarray) -> np.ndarray:
    """[K] bool: greedy in order, each candidate kept unless it conflicts with a kept earlier one."""
    kept = np.zeros(len(conflicts), bool)
    chosen: list[int] = []
    for i, row in enumerate(conflicts.tolist()):       # plain lists: a few dozen candidates
        if not any(row[j] for j in chosen):
            chosen.append(i)
    kept[chosen] = True
    return kept


class FaceContacts:
    """Rewrites a MuJoCo world's link–prism contacts as one-sided contacts with the scan's
    triangles (module docstring).

    ``mesh_of_geom`` [ngeom + 1]: per geom, the index into ``meshes`` of the static mesh whose
    prism it is, or −1; ``meshes``: (:class:`OneSidedMesh`, its origin in the world, mm);
    ``link_of_geom`` [ngeom + 1] the flat whisker link of a geom or −1; ``link_bodies``,
    ``link_lengths_mm``, ``link_radii_mm`` [flat links] each link's body, length and capsule
    radius."""

    def __init__(self, mesh_of_geom: np.ndarray, meshes: list[tuple[OneSidedMesh, np.ndarray]],
                 link_of_geom: np.ndarray, link_bodies: np.ndarray, link_lengths_mm: np.ndarray,
                 link_radii_mm: np.ndarray):
        self.mesh_of_geom, self.meshes, self.link_of_geom = mesh_of_geom, meshes, link_of_geom
        self.link_bodies, self.link_lengths_mm, self.link_radii_mm = link_bodies, link_lengths_mm, link_radii_mm

    def step(self, m, d) -> None:
        """One ``mj_step`` of the discrete integrator with the prism contacts rewritten
        (bit-identical to ``mj_step`` on a step without any)."""
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
        mesh, pair_links = mesh[rows], pair_links[rows]
        links = pair_links.max(axis=1)
        link_first = pair_links[:, 0] >= 0                          # normals point from geom 0 to geom 1
        toward_link = contact.frame[rows, :3] * np.where(link_first, -1.0, 1.0)[:, None]
        radii = self.link_radii_mm[links]
        witness = contact.pos[rows] + toward_link * (0.5 * contact.dist[rows] + radii)[:, None]
        touched, first = np.unique(links, return_index=True)
        bodies = self.link_bodies[touched]
        proximal = d.xpos[bodies]
        distal = proximal + d.xmat[bodies][:, 0::3] * self.link_lengths_mm[touched, None]
        link_of = np.concatenate([links, touched, touched])
        mesh_of = np.concatenate([mesh, mesh[first], mesh[first]])
        axis = np.concatenate([witness, proximal, distal])
        kept = np.zeros(len(axis), bool)
        points, normals, gaps = np.zeros_like(axis), np.zeros_like(axis), np.zeros(len(axis))
        for k in np.unique(mesh_of):
            on = mesh_of == k
            surface, origin = self.meshes[k]
            kept[on], points[on], normals[on], gaps[on] = one_sided(axis[on], self.link_radii_mm[link_of[on]],
                                                                    surface, origin, 0.0)
        kept[len(rows):] &= gaps[len(rows):] < -self.link_radii_mm[link_of[len(rows):]]   # nodes: crossed only
        order = np.flatnonzero(kept)[np.lexsort((gaps[kept], link_of[kept]))]   # per link, deepest first
        link_of, points, normals, gaps = link_of[order], points[order], normals[order], gaps[order]
        near = np.sum((points[:, None] - points[None]) ** 2, axis=2) < DUPLICATE_MM ** 2
        opposed = normals @ normals.T < 0.0
        chosen = _first_free((link_of[:, None] == link_of[None]) & (near | opposed))
        link_of, points, normals, gaps = link_of[chosen], points[chosen], normals[chosen], gaps[chosen]
        slot_key = self._ranked(links)
        chosen_key = self._ranked(link_of)                           # ascending: sorted by link, then rank
        at = np.minimum(np.searchsorted(chosen_key, slot_key), max(chosen_key.size - 1, 0))
        filled = chosen_key[at] == slot_key if chosen_key.size else np.zeros(rows.size, bool)
        empty = rows[~filled]
        contact.exclude[empty] = 1
        contact.efc_address[empty] = -1                                # read as no force after the solve
        rows, at, link_first = rows[filled], at[filled], link_first[filled]
        normal = normals[at] * np.where(link_first, -1.0, 1.0)[:, None]
        contact.frame[rows] = contact_frames(normal)
        contact.pos[rows] = points[at] - 0.5 * gaps[at, None] * normals[at]    # midway between the surfaces
        contact.dist[rows] = gaps[at]
        return True

    @staticmethod
    def _ranked(links: np.ndarray) -> np.ndarray:
        """[C] a key per entry: its link, then its rank among the entries of that link, as
        ``link·C' + rank`` (C' larger than any rank)."""
        order = np.argsort(links, kind="stable")
        sorted_links = links[order]
        rank = np.empty(len(links), np.int64)
        rank[order] = np.arange(len(links)) - np.searchsorted(sorted_links, sorted_links)
        return links.astype(np.int64) * (1 << 20) + rank
