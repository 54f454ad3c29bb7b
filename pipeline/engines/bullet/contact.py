"""Whisker–obstacle contact solved inside the implicit step of :mod:`pipeline.engines.bullet`.

Bullet's own contact solver sees a link's inertia but not the joint springs that the implicit
step folds into its operator (M + h·C + h²·K); its impulses then bend the chain as if it were
free, and at rest the contact force balances only M·(M + h²K)⁻¹·K·q instead of K·q: a kink at
the contact link, forces 5–40 % low and a whisker sinking through a thin peg under load. So
Bullet only *finds* contacts here (``getClosestPoints``, its response is filtered off) and the
forces come from the step's own operator:

    a_F = W·(r + J_Fᵀ·f),  W = (M_FF + h·C + h²·K)⁻¹,  r the contact-free right-hand side,

with f per contact point a normal force f_n ≥ 0 and a friction force |f_t| ≤ μ·f_n (a cone).
The velocity after the step at a point, u = J·(v + h·a) = u₀ + G·f with G = h·J_F·W·J_Fᵀ, must
not close the gap g (mm, < 0: penetration) within the step: u_n ≥ −g/h for g ≥ 0, and
u_n ≥ −:data:`PENETRATION_ERP`·g/h inside (pushed out over a few steps, no pop); friction
opposes sliding relative to the obstacle's surface (u_t = its velocity while |f_t| < μ·f_n).
Projected Gauss–Seidel over the points (at most ``engine.solver_iterations`` sweeps, compiled:
:mod:`~pipeline.engines.bullet.gauss_seidel`) solves this small problem (a few points per whisker). The forces enter the step's accelerations
through W·J_Fᵀ·f and the base wrench as external forces at the points, exactly as the loads do. At rest a = 0 and the springs balance the contact: K·q = Jᵀ·f.

Contacts are looked for within :data:`CONTACT_REACH_MM` of the surface (farther than any link
moves in a step), so that a link is caught before it crosses a thin peg or a triangle; a
point farther than its gap only limits motion that would cross it. μ is the configured
Coulomb coefficient itself (Bullet's own rule would multiply two bodies' coefficients).

Internal units mm–mg–s.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.gauss_seidel import gauss_seidel
from pipeline.engines.one_sided import MERGE_MM, one_sided
from pipeline.engines.one_sided_kernels import distinct_points

CONTACT_REACH_MM = 0.25      # speculative contact distance (a tip moves ≲ 0.15 mm per step)
CLEARANCE_MM = 2.0           # distance queried: a gap found up to this is a whisker's leeway (find_contacts)
PENETRATION_ERP = 0.2        # fraction of a penetration removed per step
TOLERANCE = 1e-6             # Gauss–Seidel stops when no force changes by more than this × the largest


@dataclass(frozen=True)
class Contacts:
    """A whisker's contact points with the obstacles, P of them (internal units, world frame)."""

    links: np.ndarray            # [P] 0-based whisker link
    points_mm: np.ndarray        # [P, 3] on the whisker's surface
    normals: np.ndarray          # [P, 3] unit, from the obstacle toward the whisker
    gaps_mm: np.ndarray          # [P] distance to the obstacle, < 0 inside
    surface_velocity: np.ndarray   # [P, 3] mm/s, the obstacle's (friction acts on the relative sliding)

    def __len__(self) -> int:
        return len(self.links)

    @classmethod
    def joined(cls, parts: list["Contacts"]) -> "Contacts":
        """The points of ``parts`` in turn."""
        if len(parts) == 1:
            return parts[0]
        return cls(*(np.concatenate([getattr(part, column.name) for part in parts]) for column in fields(cls)))


def find_contacts(client: BulletClient, obstacles, whiskers, still: bool) -> dict[int, Contacts]:
    """:class:`Contacts` within :data:`CONTACT_REACH_MM` of the obstacles, per whisker body id
    (a whisker with none is left out).

    ``obstacles``: (body id, velocity [3] mm/s, :class:`~pipeline.engines.one_sided.OneSidedMesh` or None, offset [3] mm of
    the mesh frame) of each; ``whiskers``: the :class:`~pipeline.engines.bullet.whisker.BulletWhisker`
    to look at. ``getClosestPoints`` gives the points. With ``still``
    (obstacles and bases at rest) a whisker–obstacle pair is not looked at again until the
    whisker's travel bound (:attr:`~pipeline.engines.bullet.whisker.BulletWhisker.travel_mm`) could
    have closed the gap found last down to the reach: the same contacts, fewer queries. The query
    reaches :data:`CLEARANCE_MM` (a gap found up to it is leeway) unless the pair had a point
    within the reach at its last query, or nothing is still (the pair is looked at again on the next
    step anyway): then only the reach, and fewer points come back (Bullet's points within the reach
    are the same whatever the distance asked: each triangle's, or shape's, is computed on its own).
    On a mesh they only name the links near it: the contacts are those of :func:`~pipeline.engines.one_sided.one_sided` at
    the capsule axis points Bullet found and at both nodes of each such link (the deepest
    point of a link that crosses a face is an end, where Bullet's witness point is not).
    A mesh gives one point per triangle near a link: a link's points within :data:`MERGE_MM`
    of a deeper one are dropped (near-copies that only slow the solve down), and so are points
    whose normal opposes a deeper one's of the same link and obstacle (a link between two
    faces of a sheet thinner than the reach: pushed from both sides, the step's problem has no
    bounded solution; the deeper side pushes it out)."""
    found: dict[int, list[Contacts]] = {}
    for obstacle, velocity, mesh, offset in obstacles:
        for whisker in whiskers:
            if still and whisker.travel_mm < whisker.next_query_mm.get(obstacle, 0.0):
                continue
            whisker.sync()
            distance = CLEARANCE_MM if still and obstacle not in whisker.within_reach else CONTACT_REACH_MM
            link_of, gaps, where, normals = _as_arrays(client.getClosestPoints(obstacle, whisker.body, distance),
                                                       whisker.link_index)
            whisker.next_query_mm[obstacle] = whisker.travel_mm + (gaps.min() if len(gaps) else distance) - CONTACT_REACH_MM
            near = gaps <= CONTACT_REACH_MM
            if not near.any():
                whisker.within_reach.discard(obstacle)
                continue
            whisker.within_reach.add(obstacle)
            link_of, gaps, where, normals = link_of[near], gaps[near], where[near], normals[near]
            kept = np.ones(len(gaps), bool)
            if mesh is not None:
                touched = np.unique(link_of)
                axis = np.concatenate([where + whisker.capsule_radii[link_of, None] * normals,
                                       whisker.link_nodes(touched).reshape(-1, 3)])
                link_of = np.concatenate([link_of, np.repeat(touched, 2)])
                kept, where, normals, gaps = one_sided(axis, whisker.capsule_radii[link_of], mesh, offset,
                                                       CONTACT_REACH_MM)
            chosen = _distinct(kept, link_of, where, normals, gaps, velocity)
            if len(chosen):
                found.setdefault(whisker.body, []).append(chosen)
    return {body: Contacts.joined(parts) for body, parts in found.items()}


def _as_arrays(points, link_index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``getClosestPoints``' points (obstacle A, whisker B) as arrays, those on whisker links only
    (``link_index`` [Bullet links]: a Bullet link's whisker link, −1 for none): whisker link [P],
    gap [P] (mm), point on the whisker [P, 3] and normal [P, 3] toward the whisker (from A)."""
    if not points:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
    table = np.array([(point[4], point[8], *point[6], *point[7]) for point in points])
    link_of = link_index[table[:, 0].astype(np.int64)]
    on_whisker = link_of >= 0
    table = table[on_whisker]
    return (link_of[on_whisker], table[:, 1], np.ascontiguousarray(table[:, 2:5]),
            -np.ascontiguousarray(table[:, 5:8]))


def _distinct(kept: np.ndarray, link_of: np.ndarray, where: np.ndarray, normals: np.ndarray, gaps: np.ndarray,
              velocity: np.ndarray) -> Contacts:
    """The ``kept`` points, deepest first, less those within :data:`MERGE_MM` of a deeper one of
    the same link or with a normal opposing its (:func:`find_contacts`,
    :func:`~pipeline.engines.one_sided_kernels.distinct_points`)."""
    where, normals = np.asarray(where, float), np.asarray(normals, float)
    order = np.argsort(gaps, kind="stable")
    order = order[np.asarray(kept, bool)[order]]
    chosen = distinct_points(order, link_of, where, normals, MERGE_MM)
    return Contacts(link_of[chosen], where[chosen], normals[chosen], gaps[chosen],
                    np.repeat(np.asarray(velocity, float)[None], len(chosen), axis=0))


def solve_forces(G: np.ndarray, u0: np.ndarray, gaps_mm: np.ndarray, h: float, mu: float,
                 iterations: int, start: np.ndarray | None = None) -> np.ndarray:
    """Contact forces f of the step (module docstring): per point the normal force, and with
    μ > 0 two tangential ones ([P] or [3P], the rows of :func:`~pipeline.engines.bullet.contact_kernels.contact_rows`), by projected
    Gauss–Seidel (:func:`~pipeline.engines.bullet.gauss_seidel.gauss_seidel`).

    ``G``: velocity after the step per unit force; ``u0``: velocity after the step without
    contact; ``gaps_mm`` [P]; ``start``: forces to start the sweeps from (a guess, e.g. the
    step before's; zeros without). A point that no spring joint can move (on link 1 with a rigid
    follicle: the drive is rigid) gets no force."""
    if start is None or not start.any():
        u, f = u0.astype(float), np.zeros(len(u0))
    else:
        u, f = u0 + G @ start, start.astype(float)
    bias = np.where(gaps_mm >= 0, gaps_mm, PENETRATION_ERP * gaps_mm) / h
    gauss_seidel(np.ascontiguousarray(G, dtype=float), u, f, bias, 3 if mu > 0 else 1, mu, iterations, TOLERANCE)
    return f
