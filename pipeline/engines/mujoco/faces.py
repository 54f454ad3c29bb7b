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
The arithmetic is compiled (:mod:`pipeline.engines.mujoco.face_kernels`); the nearest faces are
Open3D's. Internal units mm.
"""

from __future__ import annotations

import numpy as np

import mujoco

from pipeline.engines.one_sided import ONE_SIDED_DEPTH_MM, OneSidedMesh

DUPLICATE_MM = 1e-3         # a link's contacts this close are one (two prisms' faces read at their shared edge)


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
        # imported here, not at the top: numba ≈0.17 CPU-s and the cached kernels, only scans need them
        from pipeline.engines.mujoco import face_kernels

        self.kernels = face_kernels
        self.mesh_of_geom, self.meshes, self.link_of_geom = mesh_of_geom, meshes, link_of_geom
        self.link_bodies, self.link_lengths_mm, self.link_radii_mm = link_bodies, link_lengths_mm, link_radii_mm
        self.face_offsets = np.cumsum([0] + [len(mesh.normals) for mesh, _ in meshes])
        self.corners = np.concatenate([mesh.corners_mm for mesh, _ in meshes])     # [F, 3, 3] all meshes' faces
        self.normals = np.concatenate([mesh.normals for mesh, _ in meshes])
        self.origins = np.array([origin for _, origin in meshes], float)

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
        frame, pos, dist = contact.frame, contact.pos, contact.dist
        rows, links, link_first, axis, link_of, mesh_of = self.kernels.prism_candidates(
            contact.geom, frame, pos, dist, self.mesh_of_geom, self.link_of_geom, self.link_radii_mm,
            self.link_bodies, self.link_lengths_mm, d.xpos, d.xmat)
        if not rows.size:
            return False
        faces = np.empty(len(axis), np.int64)
        for k, (mesh, origin) in enumerate(self.meshes):
            on = mesh_of == k
            if on.any():
                faces[on] = mesh.nearest_faces(axis[on] - origin) + self.face_offsets[k]
        self.kernels.rewrite_contacts(axis, faces, mesh_of, link_of, rows, links, link_first, self.corners,
                                      self.normals, self.origins, self.link_radii_mm, DUPLICATE_MM,
                                      ONE_SIDED_DEPTH_MM, frame, pos, dist, contact.exclude, contact.efc_address)
        return True
