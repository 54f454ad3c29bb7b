"""The Bullet engine's compiled pieces against independent results: the contact solve
(pipeline.engines.bullet.contact.solve_forces, numba) against the same projected Gauss–Seidel in
plain Python on contact problems recorded from peg sweeps and a dataset trial
(bullet_contact_problems.npz: G, u₀, gaps, (h, μ, sweeps), warm start per problem); the spring
joints' mass matrix (pipeline.engines.bullet.mass_matrix) against Bullet's calculateMassMatrix."""

import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.contact import PENETRATION_ERP, TOLERANCE, solve_forces
from pipeline.engines.bullet.mass_matrix import chain_mass_matrix, implicit_operator_inverse
from pipeline.engines.bullet.whisker import BulletWhisker
from pipeline.model.array import build_array
from pipeline.model.morphology import model_rat

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
            t1 = f[r1] - u[r1] / diagonal[r1]
            t2 = f[r2] - u[r2] / diagonal[r2]
            size = math.hypot(t1, t2)
            if size > bound:
                t1, t2 = (t1 * bound / size, t2 * bound / size) if size > 0 else (0.0, 0.0)
            for j, value in ((r1, t1), (r2, t2)):
                if value != f[j]:
                    change = value - f[j]
                    largest_change = max(largest_change, abs(change))
                    f[j] += change
                    u = [uk + ck * change for uk, ck in zip(u, columns[j])]
        if largest_change <= TOLERANCE * max(map(abs, f), default=0.0):
            break
    return np.array(f)


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
