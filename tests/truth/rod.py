"""Exact planar dynamics and statics of the nodal rod of :mod:`.whisker`.

State: positions q [n, 2] and velocities v [n, 2] of the free nodes 1..n in the (inertial)
rest frame; node 0, the base point, is fixed at the origin. The follicle's driven direction
θ(t) (rad, about z) enters through the base vertex. Forces (no small-angle approximation):

- bending, vertex i: M_i = k_i·(ψ_i − ψ̄_i) + c_i·ψ̇_i with ψ_i the turning angle between
  edge i−1 and edge i (ψ_0: between the direction θ(t) and edge 0); the generalised force on
  the angle α_e of edge e is M_{e+1} − M_e, and on its nodes ±(M_{e+1} − M_e)·e⊥/|e|²;
- stretching, edge e: T_e = k_a·(|e| − ē) + c_a·d|e|/dt along the edge;
- drag per unit length on the normal velocity of each edge's midpoint,
  f = −c_lin·v_n − ½ρ_air·C_d·d·|v_n|·v_n, half to each end node; gravity m·g on every node.

Integrated by scipy's implicit BDF (stiff: the axial springs ring at MHz) with a banded
Jacobian sparsity, split at the drive's discontinuities; rtol 1e-7 keeps the integration error
below 0.5 µm on a 30 mm whisker (1e-6: 0.5 µm; looser tolerances are slower, not faster).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import solve_banded
from scipy.sparse import lil_matrix

from .whisker import AIR_DENSITY_KG_M3, Discretised, TruthWhisker, discretise


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _perp(a):
    return np.stack([-a[..., 1], a[..., 0]], axis=-1)


class Rod:
    """One truth whisker ready to simulate. ``tau0`` (s) is fixed from ζ₁ and the first mode."""

    def __init__(self, whisker: TruthWhisker, damped: bool = True):
        self.whisker = whisker
        self.d: Discretised = discretise(whisker)
        self.n = whisker.elements
        e = whisker.effects
        direction = np.asarray(e.gravity_direction, float)
        self.gravity = e.gravity * direction / np.linalg.norm(direction)
        self.tau0 = 0.0
        self.follicle_c = 0.0
        if damped and whisker.zeta1 > 0:
            omega1 = self.natural_frequencies(1)[0] * 2 * np.pi
            self.tau0 = 2 * whisker.zeta1 / omega1
        if damped:
            self.follicle_c = self.d.follicle_c

    # -- forces ----------------------------------------------------------------------------
    def forces(self, q, v, theta, theta_dot):
        """[n, 2] total force on nodes 1..n (N)."""
        d = self.d
        pos = np.vstack([np.zeros(2), q])
        vel = np.vstack([np.zeros(2), v])
        edge = np.diff(pos, axis=0)
        edge_dot = np.diff(vel, axis=0)
        length2 = np.einsum("ij,ij->i", edge, edge)
        length = np.sqrt(length2)
        alpha_dot = _cross(edge, edge_dot) / length2
        base = np.array([np.cos(theta), np.sin(theta)])
        psi = np.empty(self.n)
        psi[0] = np.arctan2(base[0] * edge[0, 1] - base[1] * edge[0, 0], base @ edge[0])
        psi[1:] = np.arctan2(_cross(edge[:-1], edge[1:]), np.einsum("ij,ij->i", edge[:-1], edge[1:]))
        psi_dot = np.concatenate([[alpha_dot[0] - theta_dot], np.diff(alpha_dot)])
        moment = d.bend_k * (psi - d.rest_turn) + (self.tau0 * d.bend_c * psi_dot)
        moment[0] += self.follicle_c * psi_dot[0]
        q_edge = np.append(moment[1:], 0.0) - moment      # generalised force on α_e
        push = (q_edge / length2)[:, None] * _perp(edge)
        stretch = d.axial_k * (length - d.rest_lengths) + self.tau0 * d.axial_c * \
            np.einsum("ij,ij->i", edge, edge_dot) / length
        pull = (stretch / length)[:, None] * edge
        on_edge = push - pull                             # force on each edge's distal node
        f = on_edge.copy()
        f[:-1] -= on_edge[1:]                              # reaction on the proximal node
        e = self.whisker.effects
        if e.drag_linear or e.drag_cd:
            unit = edge / length[:, None]
            middle = 0.5 * (vel[1:] + vel[:-1])
            normal = middle - np.einsum("ij,ij->i", middle, unit)[:, None] * unit
            speed = np.linalg.norm(normal, axis=1)
            per_length = -(e.drag_linear + 0.5 * AIR_DENSITY_KG_M3 * e.drag_cd * d.edge_diameter * speed)[:, None] \
                * normal
            half = 0.5 * per_length * length[:, None]
            f += half
            f[:-1] += half[1:]
        if e.gravity:
            f += d.node_mass[:, None] * self.gravity
        return f

    def rhs(self, drive):
        m = self.d.node_mass[:, None]
        n = self.n

        def f(t, y):
            q, v = y[:2 * n].reshape(n, 2), y[2 * n:].reshape(n, 2)
            theta, theta_dot = drive.angle(t), drive.rate(t)
            return np.concatenate([y[2 * n:], (self.forces(q, v, theta, theta_dot) / m).ravel()])
        return f

    def sparsity(self):
        """Jacobian pattern: a node's force depends on nodes within two of it."""
        n = self.n
        pattern = lil_matrix((4 * n, 4 * n), dtype=int)
        for i in range(n):
            for c in range(2):
                pattern[2 * i + c, 2 * n + 2 * i + c] = 1
            for j in range(max(0, i - 2), min(n, i + 3)):
                for a in range(2):
                    for b in range(2):
                        pattern[2 * n + 2 * i + a, 2 * j + b] = 1
                        pattern[2 * n + 2 * i + a, 2 * n + 2 * j + b] = 1
        return pattern.tocsr()

    # -- statics and modes -------------------------------------------------------------------
    def rest_state(self) -> np.ndarray:
        return self.d.rest_nodes[1:].copy()

    def static(self, load=None, start=None, theta=0.0, steps=1) -> np.ndarray:
        """Equilibrium node positions [n, 2] under gravity and ``load(q) -> [n, 2]`` (N), by
        Newton's method with a finite-difference Jacobian and ``steps`` load increments."""
        q = self.rest_state() if start is None else start.copy()
        zero = np.zeros_like(q)
        for step in range(1, steps + 1):
            share = step / steps

            def residual(x):
                qq = x.reshape(-1, 2)
                f = self.forces(qq, zero, theta, 0.0)
                if load is not None:
                    f = f + share * load(qq)
                return f.ravel()
            q = _newton(residual, q.ravel()).reshape(-1, 2)
        return q

    def stiffness_and_mass(self, q=None):
        """Tangent stiffness K = −∂F/∂q [2n, 2n] at ``q`` (rest by default) and lumped mass."""
        q = self.rest_state() if q is None else q
        zero = np.zeros_like(q)
        k = -_jacobian(lambda x: self.forces(x.reshape(-1, 2), zero, 0.0, 0.0).ravel(), q.ravel(), band=2)
        return k, np.repeat(self.d.node_mass, 2)

    def natural_frequencies(self, count: int = 3) -> np.ndarray:
        """Lowest ``count`` undamped natural frequencies (Hz) about the rest shape."""
        from scipy.linalg import eigh

        k, m = self.stiffness_and_mass()
        k = 0.5 * (k + k.T)
        scale = 1 / np.sqrt(m)
        omega_sq = eigh(scale[:, None] * k * scale[None, :], eigvals_only=True, subset_by_index=[0, count - 1])
        return np.sqrt(np.maximum(omega_sq, 0)) / (2 * np.pi)

    def energy(self, q, v, theta=0.0) -> float:
        """Kinetic + elastic energy (J), no gravity (for conservation checks)."""
        d = self.d
        pos = np.vstack([np.zeros(2), q])
        edge = np.diff(pos, axis=0)
        length = np.linalg.norm(edge, axis=1)
        base = np.array([np.cos(theta), np.sin(theta)])
        psi = np.concatenate([[np.arctan2(base[0] * edge[0, 1] - base[1] * edge[0, 0], base @ edge[0])],
                              np.arctan2(_cross(edge[:-1], edge[1:]), np.einsum("ij,ij->i", edge[:-1], edge[1:]))])
        elastic = 0.5 * np.sum(d.bend_k * (psi - d.rest_turn) ** 2) + 0.5 * np.sum(d.axial_k * (length - d.rest_lengths) ** 2)
        return float(elastic + 0.5 * np.sum(d.node_mass[:, None] * v ** 2))

    # -- dynamics ----------------------------------------------------------------------------
    def simulate(self, drive, q0, times, v0=None, rtol=1e-7, method="BDF"):
        """Positions [T, n+1, 2] (node 0 included) at ``times`` (s) from (q0, v0) at times[0]."""
        n = self.n
        y = np.concatenate([q0.ravel(), (np.zeros_like(q0) if v0 is None else v0).ravel()])
        scale = self.whisker.true_length_m
        atol = np.concatenate([np.full(2 * n, 1e-8 * scale / 0.03), np.full(2 * n, 1e-5)])
        out = np.empty((len(times), n + 1, 2))
        out[:, 0] = 0.0
        breaks = [t for t in drive.breaks if times[0] < t < times[-1]]
        edges = [times[0]] + breaks + [times[-1]]
        kwargs = {"jac_sparsity": self.sparsity()} if method in ("BDF", "Radau") else {}
        for a, b in zip(edges[:-1], edges[1:]):
            inside = (times >= a) & (times <= b)
            t_eval = np.append(times[inside][times[inside] < b], b)
            sol = solve_ivp(self.rhs(drive), (a, b), y, method=method, t_eval=t_eval, rtol=rtol,
                            atol=atol, **kwargs)
            if not sol.success:
                raise RuntimeError(f"truth integration failed: {sol.message}")
            states = sol.y[:2 * n].T.reshape(-1, n, 2)
            out[inside, 1:] = states[:inside.sum()] if times[inside][-1] == b else states[:-1]
            y = sol.y[:, -1]
        return out


def _jacobian(fun, x, band=None):
    """Central-difference Jacobian of ``fun`` at ``x``. With ``band`` (nodes), x holds (x, y)
    per node and a node's value depends only on nodes within ``band``: columns are perturbed
    in groups of nodes 2·band + 1 apart."""
    h = 1e-9 * max(np.abs(x).max(), 1e-3)
    size = x.size
    jac = np.zeros((size, size))
    stride = 2 * (2 * band + 1) if band is not None else size
    node = np.arange(size) // 2
    for start in range(min(stride, size)):
        columns = np.arange(start, size, stride)
        step = np.zeros(size)
        step[columns] = h
        diff = (fun(x + step) - fun(x - step)) / (2 * h)
        for j in columns:
            rows = np.abs(node - node[j]) <= band if band is not None else slice(None)
            jac[rows, j] = diff[rows]
    return jac


def _newton(residual, x, tol=1e-9, iterations=30):
    scale = max(np.abs(x).max(), 1e-6)
    for _ in range(iterations):
        r = residual(x)
        jac = _jacobian(residual, x, band=2)
        width = 5                                   # (x, y) of nodes within two: 5 diagonals each side
        banded = np.zeros((2 * width + 1, x.size))
        for offset in range(-width, width + 1):
            diagonal = np.diagonal(jac, offset)
            banded[width - offset, max(offset, 0):max(offset, 0) + diagonal.size] = diagonal
        dx = solve_banded((width, width), banded, -r)
        x = x + dx
        if np.abs(dx).max() < tol * scale:
            return x
    raise RuntimeError("truth statics: Newton did not converge")
