"""The Bullet engine's compiled pieces against independent results: the contact solve
(pipeline.engines.bullet.contact.solve_forces, numba) against the same projected Gauss–Seidel in
plain Python on contact problems recorded from peg sweeps and a dataset trial
(bullet_contact_problems.npz: G, u₀, gaps, (h, μ, sweeps), warm start per problem); the spring
joints' mass matrix (pipeline.engines.bullet.mass_matrix) against Bullet's calculateMassMatrix; the
base wrench (pipeline.engines.bullet.wrench) against the same Newton–Euler in numpy; the contact
step's per-point bookkeeping (pipeline.engines.bullet.contact_kernels) and the step's arithmetic
around the inverse dynamics (pipeline.engines.bullet.step_kernels) against the numpy they
replaced, to round-off."""

import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.engines import units as U
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.contact import CONTACT_REACH_MM, PENETRATION_ERP, TOLERANCE, solve_forces
from pipeline.engines.bullet.contact_kernels import contact_rows, contact_system, segment_nodes, warm_start, world_forces
from pipeline.engines.bullet.mass_matrix import chain_mass_matrix, implicit_operator_inverse
from pipeline.engines.bullet.step_kernels import advance, driven_accelerations, largest_change, step_accelerations
from pipeline.engines.bullet.whisker import BulletWhisker
from pipeline.model.array import build_array
from pipeline.model.morphology import model_rat
from pipeline.model.rotations import axis_rotation, matrix_from_xyzw, quat_xyzw, rot_z

PROBLEMS = Path(__file__).with_name("bullet_contact_problems.npz")


def python_solve(G, u0, gaps_mm, h, mu, iterations, start):
    """The contact solve's projected Gauss–Seidel in plain Python floats (the engine's before it was compiled)."""
    per_point = 3 if mu > 0 else 1
    rows = per_point * len(gaps_mm)
    columns = G.T.tolist()
    if start is None or not start.any():
        u, f = u0.tolist(), [0.0] * rows
    else:
        u, f = (u0 + G @ start).tolist(), start.tolist()
    bias = [(g if g >= 0 else PENETRATION_ERP * g) / h for g in gaps_mm.tolist()]
    diagonal = [columns[j][j] for j in range(rows)]
    movable = [(per_point * i, b) for i, b in enumerate(bias) if diagonal[per_point * i] > 0.0]
    for _ in range(iterations):
        largest_change = 0.0
        for r, b in movable:
            normal = f[r]
            change = max(0.0, normal - (u[r] + b) / diagonal[r]) - normal
            if change:
                f[r] = normal + change
                u = [uk + ck * change for uk, ck in zip(u, columns[r])]
                largest_change = max(largest_change, abs(change))
            if per_point == 1:
                continue
            r1, r2 = r + 1, r + 2
            bound = mu * f[r]
            if bound == 0.0 and f[r1] == 0.0 and f[r2] == 0.0:
                continue
            a12 = 0.5 * (columns[r2][r1] + columns[r1][r2])
            t1, t2 = python_disc(diagonal[r1], a12, diagonal[r2], u[r1] - diagonal[r1] * f[r1] - a12 * f[r2],
                                 u[r2] - a12 * f[r1] - diagonal[r2] * f[r2], bound)
            for j, value in ((r1, t1), (r2, t2)):
                if value != f[j]:
                    change = value - f[j]
                    largest_change = max(largest_change, abs(change))
                    f[j] += change
                    u = [uk + ck * change for uk, ck in zip(u, columns[j])]
        if largest_change <= TOLERANCE * max(map(abs, f), default=0.0):
            break
    return np.array(f)


def python_disc(a11, a12, a22, c1, c2, bound):
    """The friction pair's block minimiser on the disc (gauss_seidel.friction_on_disc) in plain Python."""
    trace = a11 + a22
    if not (bound > 0.0 and trace > 0.0):            # unloaded, or no tangential mobility
        return 0.0, 0.0
    lam = 0.0 if a11 * a22 - a12 * a12 > 1e-12 * trace * trace else 1e-12 * trace
    x1 = x2 = 0.0
    for step in range(50):
        det = (a11 + lam) * (a22 + lam) - a12 * a12
        x1, x2 = -((a22 + lam) * c1 - a12 * c2) / det, -((a11 + lam) * c2 - a12 * c1) / det
        size = math.hypot(x1, x2)
        if step == 0 and size <= bound:
            return x1, x2
        if not size > 0.0 or abs(size - bound) <= 1e-12 * bound:
            break
        xy = (x1 * ((a22 + lam) * x1 - a12 * x2) + x2 * ((a11 + lam) * x2 - a12 * x1)) / det
        lam += (size / bound - 1.0) * size * size / xy
    size = math.hypot(x1, x2)
    return (x1 * bound / size, x2 * bound / size) if size > 0.0 else (0.0, 0.0)


def recorded_problems():
    with np.load(PROBLEMS) as data:
        count = sum(name.startswith("G") for name in data.files)
        return [(data[f"G{i}"], data[f"u0{i}"], data[f"gaps{i}"], *data[f"scalars{i}"], data[f"start{i}"])
                for i in range(count)]


def test_the_compiled_contact_solve_is_the_python_solve():
    """24 recorded problems (1–31 points, μ 0, 0.25, 0.5), from their warm start and from zero."""
    problems = recorded_problems()
    assert len(problems) == 24 and {len(p[2]) for p in problems} >= {1, 2, 31}
    loaded = 0
    for G, u0, gaps, h, mu, iterations, start in problems:
        for guess in (start if start.size else None, None):
            expected = python_solve(G, u0, gaps, h, mu, int(iterations), guess)
            forces = solve_forces(G, u0, gaps, h, mu, int(iterations), guess)
            np.testing.assert_allclose(forces, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
            loaded += bool(np.count_nonzero(expected[0::3 if mu > 0 else 1]))
    assert loaded >= 40          # of 48 solves: most push


@pytest.fixture(scope="module")
def whiskers():
    client = BulletClient()
    models = build_array(model_rat(), MaterialConfig()).whiskers
    yield [BulletWhisker(client, model) for model in models[::12]]
    client.close()


def test_the_compiled_mass_matrix_is_bullets(whiskers):
    """Spring joints' block of calculateMassMatrix at random angles (driven ones too: they do
    not enter it), whiskers from the array's shortest to its longest."""
    rng = np.random.default_rng(3)
    for whisker in whiskers:
        for scale in (0.0, 0.1, 0.5):
            q = np.concatenate([rng.normal(size=3), scale * rng.normal(size=whisker.n_dof - 3)])
            bullets = np.array(whisker.client.calculateMassMatrix(whisker.body, q.tolist()))[3:, 3:]
            mine = chain_mass_matrix(q[3:], *whisker._mass_chain)
            np.testing.assert_allclose(mine, bullets, rtol=0, atol=1e-13 * np.abs(bullets).max())


def test_the_implicit_operator_inverse_inverts_it(whiskers):
    whisker = whiskers[0]
    angles = np.linspace(-0.05, 0.05, whisker.n_dof - 3)
    diagonal = 1e-4 * whisker.damping[3:] + 1e-8 * whisker.stiffness[3:]
    operator = chain_mass_matrix(angles, *whisker._mass_chain) + np.diag(diagonal)
    inverse = implicit_operator_inverse(angles, diagonal, *whisker._mass_chain)
    np.testing.assert_allclose(inverse @ operator, np.eye(len(angles)), rtol=0, atol=1e-9)


def _parent(x):
    return np.vstack([np.zeros((1, 3)), x[:-1]])


def numpy_chain_wrench(origins, rotations, local_axes, rates, accelerations, bodies, com, mass, inertia, base,
                       points, forces, torques):
    """pipeline.engines.bullet.wrench.chain_wrench in numpy (the engine's before it was compiled)."""
    n, b = len(origins), len(bodies)
    axes = np.einsum("lij,lj->li", rotations, local_axes)
    spin = axes * rates[:, None]
    omega = np.cumsum(spin, axis=0)
    parent_omega = _parent(omega)
    alpha = np.cumsum(axes * accelerations[:, None] + np.cross(parent_omega, spin), axis=0)
    step = origins - _parent(origins)
    step[0] = 0.0
    turned = np.cross(np.vstack([_parent(alpha), parent_omega]), np.vstack([step, step]))
    origin_acceleration = np.cumsum(turned[:n] + np.cross(parent_omega, turned[n:]), axis=0)
    w, a = omega[bodies], alpha[bodies]
    arm = com - origins[bodies]
    frames = rotations[bodies]
    world_inertia = np.einsum("bij,bj,bkj->bik", frames, inertia, frames)
    spin_momentum = np.einsum("bij,bj->bi", world_inertia, w)
    turned = np.cross(np.vstack([a, w, w]), np.vstack([arm, arm, spin_momentum]))
    momentum_rate = mass[:, None] * (origin_acceleration[bodies] + turned[:b] + np.cross(w, turned[b:2 * b]))
    point = origins[base]
    arms = np.cross(np.vstack([com - point, points - point]), np.vstack([momentum_rate, forces]))
    moment = (arms[:b].sum(axis=0) - arms[b:].sum(axis=0) + np.einsum("bij,bj->i", world_inertia, a)
              + turned[2 * b:].sum(axis=0) - torques.sum(axis=0))
    return np.concatenate([momentum_rate.sum(axis=0) - forces.sum(axis=0), moment])


def numpy_base_wrench(whisker, q, v, accel, rotations, points, forces, torques):
    """BulletWhisker.base_wrench in numpy (internal units): origins, centres of mass, whisker frame."""
    origins = np.vstack([np.zeros(3), np.cumsum(np.einsum("lij,lj->li", rotations[:-1], whisker._link_offsets[1:]),
                                                axis=0)])
    bodies = np.asarray(whisker.whisker_links)
    com = origins[bodies] + rotations[bodies, :, 0] * whisker.link_com[:, None]
    rates, accelerations = np.zeros(len(rotations)), np.zeros(len(rotations))
    rates[whisker.dofs], accelerations[whisker.dofs] = v, accel
    world = numpy_chain_wrench(origins, rotations, whisker._local_axes, rates, accelerations, bodies, com,
                               whisker._link_mass, whisker._link_inertia, whisker.sensor_joint, points, forces, torques)
    rotation = rot_z(whisker.link1_angle) @ rotations[whisker.sensor_joint].T
    for axis, angle in zip(reversed(whisker.follicle_axes), reversed(q[3:3 + len(whisker.follicle_axes)])):
        rotation = axis_rotation(axis, angle) @ rotation
    return np.concatenate([rotation @ world[:3], rotation @ world[3:]])


def test_the_compiled_base_wrench_is_the_numpy_one(whiskers):
    """Random joint states, rates, accelerations and contact forces, whiskers from the array's
    shortest to its longest (compliant follicles: two joints each)."""
    rng = np.random.default_rng(5)
    for whisker in whiskers:
        assert whisker.follicle_axes
        for scale in (0.0, 0.1, 0.5):
            q = np.concatenate([rng.normal(size=3), scale * rng.normal(size=whisker.n_dof - 3)])
            v, accel = 30 * rng.normal(size=whisker.n_dof), 3e4 * rng.normal(size=whisker.n_dof)
            points, forces = 20 * rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
            external = [(points, forces, 0.1 * rng.normal(size=(3, 3)))]
            whisker._set_state(q, v)
            whisker._record_wrench(q.tolist(), v, accel, external)
            rotations, base = whisker._step[3:5]
            expected = numpy_base_wrench(whisker, q, v, accel, rotations, points - base, forces, external[0][2])
            mine = whisker.base_wrench() * np.repeat([U.FORCE, U.TORQUE], 3)
            np.testing.assert_allclose(mine, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def numpy_contact_frames(normals, with_tangents):
    """Per point its normal and two unit tangents (the engine's numpy before it was compiled)."""
    if not with_tangents:
        return normals
    nx, ny, nz = normals.T
    zeros = np.zeros_like(nx)
    t1 = np.where((np.abs(nx) <= np.abs(ny))[:, None], np.stack([zeros, -nz, ny], axis=1),
                  np.stack([nz, zeros, -nx], axis=1))
    t1 /= np.sqrt(np.matmul(t1[:, None, :], t1[:, :, None]))[:, 0]
    t2 = np.stack([ny * t1[:, 2] - nz * t1[:, 1], nz * t1[:, 0] - nx * t1[:, 2], nx * t1[:, 1] - ny * t1[:, 0]], axis=1)
    return np.stack([normals, t1, t2], axis=1).reshape(-1, 3)


def numpy_warm_start(links, points, frames, last_links, last_points, last_forces):
    per_point = len(frames) // len(points)
    distances = ((points[:, None, :] - last_points[None, :, :]) ** 2).sum(axis=2)
    distances[links[:, None] != last_links[None, :]] = np.inf
    nearest = distances.argmin(axis=1)
    near = np.flatnonzero(distances[np.arange(len(points)), nearest] <= CONTACT_REACH_MM ** 2)
    chosen = near[np.unique(nearest[near], return_index=True)[1]]
    start = np.zeros((len(points), per_point))
    start[chosen] = np.matmul(frames.reshape(len(points), per_point, 3)[chosen],
                              last_forces[nearest[chosen]][:, :, None])[..., 0]
    return start.reshape(-1)


def _same(actual, expected):
    """Equal to round-off: the kernels repeat numpy's operations in its order (on this machine's
    OpenBLAS, to the bit), but another BLAS may fuse them differently."""
    np.testing.assert_allclose(actual, expected, rtol=1e-12, atol=1e-12)


def test_the_compiled_contact_bookkeeping_is_numpys():
    """Random points and normals (axis-aligned ones too), with and without tangents, the step
    before's points near them on the same and other links."""
    rng = np.random.default_rng(7)
    for case in range(400):
        count, tangents = int(rng.integers(1, 12)), bool(case % 2)
        normals = rng.normal(size=(count, 3)) if case % 5 else np.eye(3)[rng.integers(0, 3, count)] * rng.choice([-1, 1])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        points, origin = 10 * rng.normal(size=(count, 3)), 10 * rng.normal(size=3)
        frames, arms = contact_rows(normals, points, origin, tangents)
        expected = numpy_contact_frames(normals, tangents)
        per_point = len(expected) // count
        _same(frames, expected)
        _same(arms, np.cross(np.repeat(points, per_point, axis=0) - origin, expected))
        links, last = rng.integers(0, 3, count), int(rng.integers(1, 12))
        last_links, last_forces = rng.integers(0, 3, last), rng.normal(size=(last, 3))
        last_points = points[rng.integers(0, count, last)] + 0.15 * rng.normal(size=(last, 3))
        _same(warm_start(links, points, frames, last_links, last_points, last_forces, CONTACT_REACH_MM),
                                      numpy_warm_start(links, points, expected, last_links, last_points, last_forces))
        forces = rng.normal(size=len(frames))
        _same(world_forces(frames, forces, count),
                                      np.einsum("ij,i->ij", expected, forces).reshape(count, per_point, 3).sum(axis=1))


def test_the_compiled_contact_system_is_numpys(whiskers):
    """The step's contact problem (W·J_Fᵀ, u₀, G) from random rows and Jacobians, points on random
    links of real whiskers (their implicit operators and links beyond), against the numpy of the step."""
    rng = np.random.default_rng(17)
    h = 1e-4
    for whisker in whiskers:
        diagonal = h * whisker.damping[3:] + h * h * whisker.stiffness[3:]
        for case in range(20):
            count, tangents = int(rng.integers(1, 8)), bool(case % 2)
            normals = rng.normal(size=(count, 3))
            normals /= np.linalg.norm(normals, axis=1)[:, None]
            frames, arms = contact_rows(normals, 10 * rng.normal(size=(count, 3)), np.zeros(3), tangents)
            linear, angular = rng.normal(size=(3, whisker.n_dof)), rng.normal(size=(3, whisker.n_dof))
            links = rng.integers(0, len(whisker.whisker_links), count)
            lhs_inverse = implicit_operator_inverse(0.05 * rng.normal(size=whisker.n_dof - 3), diagonal, *whisker._mass_chain)
            v, accel = rng.normal(size=whisker.n_dof), 1e3 * rng.normal(size=whisker.n_dof)
            jacobian = frames @ linear + arms @ angular
            jacobian[whisker._beyond_link[np.repeat(links, len(frames) // count)]] = 0.0
            response = lhs_inverse @ jacobian[:, 3:].T
            expected = (response, jacobian @ (v + h * accel), h * jacobian[:, 3:] @ response)
            got = contact_system(frames, arms, linear, angular, whisker._beyond_link, links, lhs_inverse, v, accel, h)
            for actual, wanted in zip(got, expected):
                _same(actual, wanted)


def test_the_compiled_link_nodes_are_numpys():
    rng = np.random.default_rng(11)
    quaternions = rng.normal(size=(200, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1)[:, None]
    origins, lengths = 30 * rng.normal(size=(200, 3)), rng.uniform(0.5, 3, 200)
    x, y, z, w = quaternions.T
    along = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)
    _same(segment_nodes(origins, quaternions, lengths),
                                  np.stack([origins, origins + lengths[:, None] * along], axis=1))


def test_the_compiled_step_arithmetic_is_numpys(whiskers):
    """A step's accelerations and advance at random states of real whiskers (their implicit
    operator, stiffness and damping) against the numpy of the step."""
    rng = np.random.default_rng(13)
    h = 1e-4
    for whisker in whiskers:
        free = whisker.n_dof - 3
        diagonal = h * whisker.damping[3:] + h * h * whisker.stiffness[3:]
        for _ in range(20):
            q, v = 0.05 * rng.normal(size=whisker.n_dof), 20 * rng.normal(size=whisker.n_dof)
            lhs_inverse = implicit_operator_inverse(q[3:], diagonal, *whisker._mass_chain)
            target, driven_only = q[:3] + 1e-3 * rng.normal(size=3), rng.normal(size=whisker.n_dof)
            then = q[3:] + 1e-4 * rng.normal(size=free)
            assert largest_change(q[3:], then) == np.abs(q[3:] - then).max()
            accel_driven = driven_accelerations(target, q, v, h)
            _same(accel_driven, ((target - q[:3]) / h - v[:3]) / h)
            accel = step_accelerations(accel_driven, lhs_inverse, -whisker.stiffness[3:], whisker.damping[3:], q, v,
                                       driven_only)
            _same(accel, np.concatenate([accel_driven, lhs_inverse @ (
                -whisker.stiffness[3:] * q[3:] - whisker.damping[3:] * v[3:] - driven_only[3:])]))
            v_after = v + h * accel
            for got, expected in zip(advance(q, v, accel, h, whisker.joint_reach_mm),
                                     (q + h * v_after, v_after, h * float(whisker.joint_reach_mm @ np.abs(v_after)))):
                _same(np.asarray(got), np.asarray(expected))


def test_the_chains_own_link_frames_are_bullets(whiskers):
    """Node positions and link frames (the outputs' and the base wrench's) from the chain's own
    kinematics against Bullet's getLinkStates, at random joint angles and a turned, moved base
    (Bullet's are the less exact: its link quaternions' norms are off 1 by up to 7·10⁻⁸, frames by
    up to 3·10⁻⁷, positions by up to 4·10⁻⁶ mm; the chain's own frames are orthonormal to 10⁻¹⁵)."""
    rng = np.random.default_rng(13)
    for whisker in whiskers:
        rotation = axis_rotation(2, 0.7) @ axis_rotation(0, -0.4)
        whisker.place_base(np.array([3.0, -20.0, 7.5]), quat_xyzw(rotation).tolist())
        for scale in (0.0, 0.3):
            q = np.concatenate([rng.normal(size=3), scale * rng.normal(size=whisker.n_dof - 3)])
            whisker._set_state(q, np.zeros(whisker.n_dof))
            whisker.sync()
            states = whisker.client.getLinkStates(whisker.body, whisker._chain_links, computeForwardKinematics=True)
            frames, origins = whisker._link_frames(whisker._chain_links)
            np.testing.assert_allclose(origins, [s[4] for s in states], rtol=0, atol=1e-5)
            np.testing.assert_allclose(frames, matrix_from_xyzw([s[5] for s in states]), rtol=0, atol=1e-6)
            nodes = whisker.link_nodes(np.arange(len(whisker.whisker_links)))
            np.testing.assert_allclose(whisker.node_positions() * U.LENGTH, np.vstack([nodes[:, 0], nodes[-1, 1]]),
                                       rtol=0, atol=1e-5)
            np.testing.assert_allclose(np.einsum("lij,lkj->lik", frames, frames), np.broadcast_to(np.eye(3), frames.shape),
                                       rtol=0, atol=1e-14)
