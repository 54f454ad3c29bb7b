"""MuJoCo's contacts with a scan, found and read by the engine: the links' capsules against the
scan's triangles, read one-sided (:mod:`pipeline.engines.one_sided`, as Bullet reads them), added
to MuJoCo's contact list after its own collision (pegs, primitives) and before the constraints
are built (:meth:`ScanContacts.step`).

The scan's faces (those the world's whiskers can reach) sit in a uniform grid
(:mod:`pipeline.engines.triangle_grid`, built with the model). Per step, for each link that may
collide (its geom's ``contype``), each triangle its capsule touches or nearly touches (the axis
within the radius and :data:`~pipeline.engines.mujoco.face_kernels.SPECULATIVE_MM`)
gives the link a contact slot and a candidate, the axis point nearest the triangle; a link with
slots adds its two nodes as candidates. Each candidate reads its contact with the surface
(nearest face, edge or vertex within the larger of the radius and
:data:`~pipeline.engines.one_sided.ONE_SIDED_DEPTH_MM`; a crossed axis pushed back out along the
face normal), kept where it penetrates or lies within ``SPECULATIVE_MM`` of the surface (a node
only where its axis crossed). Deepest
first, a candidate within :data:`DUPLICATE_MM` of a kept one of the same link (two faces read at
their shared edge), or whose normal opposes one (a link between two faces: the deeper pushes it
out), is dropped; a link keeps at most its slots. Each kept candidate becomes one MuJoCo contact
(``mj_addContact``; geom 0 the link's capsule, geom 1 the scan's anchor geom on the world body,
the contact law of every geom: package docstring, Contacts) at the point midway between the
surfaces. The arithmetic is compiled (:mod:`pipeline.engines.mujoco.face_kernels`).

A contact found apart from the surface (gap g > 0) is speculative, as MuJoCo's own speculative
contacts with primitives: its margin makes the soft contact's reference acceleration the one that
puts its point on the surface at the step's end, −(g/h + v)/h with v its separating speed
(:func:`~pipeline.engines.mujoco.step_kernels.speculative_distance`), so the solve pushes only a
link that would otherwise cross the surface within the step, and stops it there. After the step,
one whose normal force came out positive held its link on the surface and reads as touching
(distance 0). Without them, a link whose soft contact had pushed it back to the surface (or that
the friction cone lifted while sliding) lost its contact for a step, its load drove it 10–50 µm into
the scan in that step, and the sliding tips chattered, more at coarser steps (docs/model.md,
"Issue 24, session 23").
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

import mujoco
import numpy as np

from pipeline.engines import units as U
from pipeline.engines.mujoco.native import RawData, contact_address, function_addresses
from pipeline.engines.one_sided import ONE_SIDED_DEPTH_MM
from pipeline.scenes.obstacles import TriangleMesh

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
        from pipeline.engines.mujoco import step_kernels
        from pipeline.engines.triangle_grid import TriangleGrid

        self.kernels = step_kernels
        self.grid = TriangleGrid(corners, normals, GRID_CELL_MM)
        self.scratch = np.empty(len(corners), np.int64)
        self.anchor, self.link_geoms, self.link_bodies = anchor, link_geoms, link_bodies
        self.link_lengths_mm = link_lengths_mm
        self.link_radii_mm = np.maximum(link_radii_mm, SCAN_RADIUS_MIN_MM)     # read against the scan
        self.template = _template(model, anchor)
        time_constant, dmax = float(model.geom_solref[anchor][0]), float(model.geom_solimp[anchor][1])
        self.law = (1.0 / (dmax * time_constant) ** 2, 2.0 / (dmax * time_constant), time_constant,
                    np.array(model.geom_solimp[anchor], float))    # k, b, τ, solimp (step_kernels.speculative_distance)
        self.template_address = contact_address(self.template)
        self._arguments: dict[int, tuple] = {}      # per MjData (kept): it and the compiled step's arguments
        self.damping = None
        """The mass-proportional damping the compiled step applies (a
        :class:`~pipeline.engines.mujoco.loads.LinkLoads` with nothing else to apply), or None:
        none, or applied by MuJoCo's control callback."""

    def step(self, m, d) -> None:
        """One ``mj_step`` of the discrete integrator with the scan's contacts added (bit-identical
        to ``mj_step`` on a step without any), in compiled code
        (:func:`~pipeline.engines.mujoco.step_kernels.scan_step`): MuJoCo's position stage, the
        scan search, and when it finds contacts the collision again (its contacts end the arena,
        those added follow them, :func:`~pipeline.engines.mujoco.face_kernels.fill_contacts`)
        and the position stage from there (the constraints, islands, projections, transmissions
        and the effective metric with the activity flag the stage had set), then the rest of the
        step (with :attr:`damping`'s force) and the discrete integrator's update (v += h·a,
        q += h·v, without Euler damping: the metric has D)."""
        if not self.kernels.scan_step(*self.arguments(m, d)):
            raise MemoryError("MuJoCo's contact buffer is full")

    def arguments(self, m, d) -> tuple:
        """The compiled step's arguments for the model ``m`` and its data ``d`` (made at its first
        step: views of their memory, :class:`~pipeline.engines.mujoco.native.RawData`), the last
        :attr:`damping`'s for ``d``."""
        if id(d) not in self._arguments:
            raw = RawData(m, d)
            search = (m.geom_contype, self.link_geoms, self.link_bodies, self.link_lengths_mm, self.link_radii_mm,
                      d.xpos, d.xmat, self.grid.centres, self.grid.radii, DUPLICATE_MM, ONE_SIDED_DEPTH_MM,
                      *self.grid.arrays(), self.scratch)
            scan = (search, (d.qvel, np.empty(3 * m.nv), np.empty(6), raw.model64, *self.law))
            self._arguments[id(d)] = d, (function_addresses(), m._address, d._address, raw.header, raw.pointers,
                                         raw.option, raw.rows64, raw.rows32, raw.fields, self.template_address,
                                         self.anchor, scan)
        damping = None if self.damping is None else self.damping.joint_force_arguments(d)
        return *self._arguments[id(d)][1], damping


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
