"""A triangle mesh read one-sided: the surface of the solid behind its faces (faces wound
outward), as both engines' contacts with scans see it (:mod:`pipeline.engines.bullet.contact`,
:mod:`pipeline.engines.mujoco.faces`).

A capsule axis point c touches the surface at its nearest point q: in front of q's face, along
(c − q)/|c − q| (a face's own normal, or an edge's or vertex's direction), so two faces meeting
at an edge give the same contact; behind it (the axis has crossed the surface), along the face's
outward normal, pushed back out the way it came. Internal units mm.
"""

from __future__ import annotations

import numpy as np

ONE_SIDED_DEPTH_MM = 0.25   # a capsule axis farther behind a mesh face than this does not touch it
MERGE_MM = 0.1              # a link's contact points closer than this to a deeper one are dropped


class OneSidedMesh:
    """A triangle mesh as the surface of the solid behind it (faces wound outward): the point of
    the surface nearest to given points and the outward normal of its face (mm, the mesh's
    frame; Open3D's closest-point query, single precision). With ``double_precision``, it also
    keeps each face's corners ``corners_mm`` [F, 3, 3] and unit normal ``normals`` [F, 3], so
    that the point on the face :meth:`nearest_faces` finds can be computed in double precision
    (:func:`~pipeline.engines.one_sided_kernels.closest_on_triangle`) and a contact's gap and
    normal change smoothly with the axis point (MuJoCo: single-precision points made its
    contacts jitter by ~10⁻⁶ mm, and a whisker's result depend on the other whiskers of its
    world by up to 8 % of its peak)."""

    def __init__(self, mesh, double_precision: bool = False):
        self.surface = mesh.surface                 # metres, built once per mesh
        if double_precision:
            self.corners_mm = (np.asarray(mesh.vertices_m, float) * 1e3)[np.asarray(mesh.faces, np.int64)]
            a, b, c = np.moveaxis(self.corners_mm, 1, 0)
            normals = _cross(b - a, c - a)
            self.normals = normals / np.sqrt(_dot(normals, normals))[:, None]

    def nearest(self, points_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """([P, 3] nearest surface point, [P, 3] its face's outward unit normal) of ``points_mm``."""
        nearest_m, normals = self.surface.closest_points(points_mm / 1e3)
        return nearest_m * 1e3, normals

    def nearest_faces(self, points_mm: np.ndarray) -> np.ndarray:
        """[P] the index of the face nearest each point [P, 3] (found in single precision)."""
        return self.surface.closest_faces(points_mm / 1e3)


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """[...] the dot products of the vectors [..., 3]."""
    return np.einsum("...j,...j->...", u, v)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """[..., 3] the cross products of the vectors [..., 3]."""
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1], u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def one_sided(axis_mm: np.ndarray, radii_mm: np.ndarray, mesh: OneSidedMesh, offset_mm: np.ndarray,
              reach_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Contacts of capsule axis points ``axis_mm`` [P, 3] (capsule ``radii_mm`` [P]) with the
    solid behind a mesh's faces (the mesh at ``offset_mm``): (kept [P] bool, points on the
    capsules, normals toward them, gaps), kept where the gap is at most ``reach_mm``.

    The contact is the axis point c's distance d to the nearest point q of the surface: in
    front of q's face, normal (c − q)/d (a face's own normal, or an edge's or vertex's
    direction) and gap d − r; behind it (the axis has crossed the surface), the face's outward
    normal and gap −(d + r), or no contact beyond :data:`ONE_SIDED_DEPTH_MM` (behind the
    scanned surface, where nothing is). Bullet's own reading of a capsule against one triangle
    of no thickness, once they overlap, is a penetration direction: sideways across the
    triangle's edge, or inward once the axis has crossed, pushing the link on through; with the
    faces around a link pushing it from opposite sides the step's problem had no bounded
    solution (the jam). MuJoCo's convex prism per face pushes a link out through its nearest
    side wall (the wedge)."""
    # imported here, not at the top: numba ≈0.17 CPU-s and the cached kernels, only meshes need them
    from pipeline.engines.one_sided_kernels import one_sided_points

    local = axis_mm - offset_mm
    nearest, outward = mesh.nearest(local)
    return one_sided_points(local, nearest, outward, axis_mm, radii_mm, reach_mm, ONE_SIDED_DEPTH_MM)
