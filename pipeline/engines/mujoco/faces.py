"""MuJoCo's contacts with a scan, found and read by the engine: the links' capsules against the
scan's triangles, read one-sided (:mod:`pipeline.engines.one_sided`, as Bullet reads them), added
to MuJoCo's contact list after its own collision (pegs, primitives) and before the constraints
are built (:meth:`ScanContacts.step`).

The scan's faces (those the world's whiskers can reach) sit in a uniform grid
(:mod:`pipeline.engines.triangle_grid`, built with the model). Per step, for each link that may
collide (its geom's ``contype``), each triangle its capsule touches (the axis within the radius)
gives the link a contact slot and a candidate, the axis point nearest the triangle; a link with
slots adds its two nodes as candidates. Each candidate reads its contact with the surface
(nearest face, edge or vertex within the larger of the radius and
:data:`~pipeline.engines.one_sided.ONE_SIDED_DEPTH_MM`; a crossed axis pushed back out along the
face normal), kept where it penetrates (gap ≤ 0; a node only where its axis crossed). Deepest
first, a candidate within :data:`DUPLICATE_MM` of a kept one of the same link (two faces read at
their shared edge), or whose normal opposes one (a link between two faces: the deeper pushes it
out), is dropped; a link keeps at most its slots. Each kept candidate becomes one MuJoCo contact
(``mj_addContact``; geom 0 the link's capsule, geom 1 the scan's anchor geom on the world body,
the contact law of every geom: package docstring, Contacts) at the point midway between the
surfaces. The arithmetic is compiled (:mod:`pipeline.engines.mujoco.face_kernels`).
Internal units mm.

A link thinner than :data:`SCAN_RADIUS_MIN_MM` is read against the scan with that radius (the
scan's surface moves out by 30 µm less the radius for the distal links, whose radii are 1.5–30 µm; the
scans' surface lies 0.42–0.58 mm from their data, median). MuJoCo's soft contact sinks a link
pressed at whisking speed by up to ~22 µm at the default step (a tip on a faceted peg,
benchmarks/bench_stick_slip.py), more than a tip's radius, so with its own radius the tip's axis
went through the faces. The one-sided reading of a crossed axis jumps, in normal and depth,
between the faces' normals and the edges' directions, and the peaks did not converge in the step
(docs/model.md, "Issue 24, session 18"). With the wider radius the axis stays outside.
"""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np

from pipeline.engines import units as U
from pipeline.engines.one_sided import ONE_SIDED_DEPTH_MM
from pipeline.scenes.obstacles import TriangleMesh

# MuJoCo's effective metric M + h·D + h²·K of the discrete integrator, built at the end of its
# position stage on the arena after the contacts and constraints (so built again once contacts are
# added); not in the Python bindings (MuJoCo 4.0: ``mj_effBuild(m, d, active, flg_factor)``), so
# looked up through the bindings' own extension module, which links MuJoCo's library (whatever its
# file is called on the platform).
_EFFECTIVE_METRIC = ctypes.CDLL(mujoco._functions.__file__).mj_effBuild
_EFFECTIVE_METRIC.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_int]
_EFFECTIVE_METRIC.restype = None

SCAN_RADIUS_MIN_MM = 0.03    # the least radius a link is read with against a scan (module docstring)
DUPLICATE_MM = 1e-3         # a link's contacts this close are one (two faces read at their shared edge)
GRID_CELL_MM = 1.0          # the scan grid's cell (about a face of a dataset scan across)


class ScanContacts:
    """Adds a MuJoCo world's link contacts with the static meshes' triangles to each step
    (module docstring).

    ``corners`` [F, 3, 3] and unit outward ``normals`` [F, 3]: the faces (mm, world);
    ``anchor`` the geom contacts with them name; ``link_geoms``, ``link_bodies``,
    ``link_lengths_mm``, ``link_radii_mm`` [flat links] each link's capsule geom, body, length
    and radius."""

    def __init__(self, model: mujoco.MjModel, corners: np.ndarray, normals: np.ndarray, anchor: int,
                 link_geoms: np.ndarray, link_bodies: np.ndarray, link_lengths_mm: np.ndarray,
                 link_radii_mm: np.ndarray):
        # imported here, not at the top: numba ≈0.17 CPU-s and the cached kernels, only scans need them
        from pipeline.engines.mujoco import face_kernels
        from pipeline.engines.triangle_grid import TriangleGrid

        self.kernels = face_kernels
        self.grid = TriangleGrid(corners, normals, GRID_CELL_MM)
        self.scratch = np.empty(len(corners), np.int64)
        self.anchor, self.link_geoms, self.link_bodies = anchor, link_geoms, link_bodies
        self.link_lengths_mm = link_lengths_mm
        self.link_radii_mm = np.maximum(link_radii_mm, SCAN_RADIUS_MIN_MM)     # read against the scan
        self.template = _template(model, anchor)

    def step(self, m, d) -> None:
        """One ``mj_step`` of the discrete integrator with the scan's contacts added
        (bit-identical to ``mj_step`` on a step without any)."""
        mujoco.mj_checkPos(m, d)
        mujoco.mj_checkVel(m, d)
        mujoco.mj_fwdPosition(m, d)
        found = self.contacts(m, d)
        if found is not None:
            metric = d.efm_active
            mujoco.mj_collision(m, d)      # again: its contacts end the arena, those added follow them
            self.append(m, d, *found)
            position_stage_after_collision(m, d, metric)
        mujoco.mj_sensorPos(m, d)
        mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_POS, 0)
        mujoco.mj_checkAcc(m, d)
        flags = m.opt.disableflags     # the discrete integrator's update: v += h·a, q += h·v (the
        m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)   # metric has D)
        mujoco.mj_Euler(m, d)
        m.opt.disableflags = flags

    def contacts(self, m, d) -> tuple[np.ndarray, ...] | None:
        """The links' current contacts with the scan (:func:`~pipeline.engines.mujoco.face_kernels.scan_contacts`),
        or None if there are none."""
        searched = m.geom_contype[self.link_geoms] != 0
        if not searched.any():
            return None
        grid = self.grid.arrays()
        axis, link_of, node, slots = self.kernels.scan_candidates(
            searched, self.link_bodies, self.link_lengths_mm, self.link_radii_mm, d.xpos, d.xmat, self.grid.centres,
            self.grid.radii, *grid, self.scratch)
        if not len(axis):
            return None
        found = self.kernels.scan_contacts(axis, link_of, node, slots, self.link_radii_mm, DUPLICATE_MM,
                                           ONE_SIDED_DEPTH_MM, *grid, self.scratch)
        return found if len(found[0]) else None

    def append(self, m, d, links: np.ndarray, middle: np.ndarray, toward_link: np.ndarray, gaps: np.ndarray) -> None:
        """Append the contacts (:meth:`contacts`) to ``d``'s contact list, which must end the
        arena (right after ``mj_collision``)."""
        first = d.ncon
        for _ in range(len(links)):
            if mujoco.mj_addContact(m, d, self.template):
                raise MemoryError("MuJoCo's contact buffer is full")
        contact = d.contact
        self.kernels.fill_contacts(first, links, middle, toward_link, gaps, self.link_geoms, self.anchor,
                                   contact.geom, contact.frame, contact.pos, contact.dist)


def position_stage_after_collision(m: mujoco.MjModel, d: mujoco.MjData, metric: int) -> None:
    """MuJoCo's position stage (``mj_fwdPosition``) from its collision on: the constraints,
    islands and projections, transmissions and the effective metric (``metric``: the
    ``efm_active`` the stage had set)."""
    mujoco.mj_makeConstraint(m, d)
    mujoco.mj_island(m, d)
    mujoco.mj_projectConstraint(m, d)
    mujoco.mj_transmission(m, d)
    _EFFECTIVE_METRIC(m._address, d._address, int(metric != 0), 1)


def triangles_mm(mesh: TriangleMesh, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The corners [F, 3, 3] (mm, world) and unit outward normals [F, 3] of the mesh's
    ``faces`` (indices) that are not degenerate (area above 10⁻¹² of the largest's)."""
    corners = (np.asarray(mesh.vertices_m, float) * U.LENGTH)[np.asarray(mesh.faces, np.int64)[faces]]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.linalg.norm(normals, axis=1)
    valid = area2 > 1e-12 * max(float(np.max(area2, initial=0.0)), 1e-30)
    return corners[valid], normals[valid] / area2[valid, None]


def _template(model: mujoco.MjModel, anchor: int) -> mujoco.MjContact:
    """A contact with the contact law of the scan's ``anchor`` geom against a whisker capsule
    (the same on both geoms: MuJoCo's mix of two equal geoms is either's own)."""
    contact = mujoco.MjContact()
    contact.dim = int(model.geom_condim[anchor])
    friction = np.maximum(model.geom_friction[anchor][[0, 0, 1, 2, 2]], mujoco.mjMINMU)    # as MuJoCo mixes
    contact.friction = friction
    contact.mu = friction[0]
    contact.solref = model.geom_solref[anchor]
    contact.solimp = model.geom_solimp[anchor]
    contact.includemargin = model.geom_margin[anchor] - model.geom_gap[anchor]
    contact.geom = [-1, anchor]
    contact.flex = contact.elem = contact.vert = [-1, -1]
    contact.efc_address = -1
    return contact
