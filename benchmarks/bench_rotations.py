"""Per-call CPU cost of the rotations of pipeline/model/rotations.py against scipy's Rotation
doing the same (results checked equal first), to decide which to use (issue 18 §6).

Run: .venv/bin/python benchmarks/bench_rotations.py
Prints one table, microseconds per call (best of 5 × 200 calls).
"""

import timeit

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.model.rotations import axis_rotation, quat_wxyz, rotation_zyx, z_onto

rng = np.random.default_rng(0)
angles = rng.uniform(-1, 1, 3)
m = rotation_zyx(*angles)
assert np.allclose(m, Rotation.from_euler("ZYX", angles).as_matrix())
q = Rotation.from_matrix(m).as_quat(scalar_first=True, canonical=True)
assert np.allclose(q, quat_wxyz(m))
a = rng.normal(size=3)
assert np.allclose(z_onto(a) @ [0, 0, 1], a / np.linalg.norm(a))
many = rng.uniform(-1, 1, (1000, 3))
cases = {
    "rotation_zyx (one)": (lambda: rotation_zyx(*angles), lambda: Rotation.from_euler("ZYX", angles).as_matrix()),
    "rotation_zyx (1000)": (lambda: rotation_zyx(many[:, 0], many[:, 1], many[:, 2]),
                            lambda: Rotation.from_euler("ZYX", many).as_matrix()),
    "quat_wxyz (one)": (lambda: quat_wxyz(m), lambda: Rotation.from_matrix(m).as_quat(scalar_first=True, canonical=True)),
    "z_onto (one)": (lambda: z_onto(a), lambda: Rotation.align_vectors([a], [[0, 0, 1]])[0].as_matrix()),
    "axis_rotation z (one)": (lambda: axis_rotation(2, 0.3), lambda: Rotation.from_euler("z", 0.3).as_matrix()),
}
print(f"{'function':<24}{'numpy µs':>10}{'scipy µs':>10}")
for name, (ours, theirs) in cases.items():
    t = [min(timeit.repeat(f, number=200, repeat=5)) / 200 * 1e6 for f in (ours, theirs)]
    print(f"{name:<24}{t[0]:>10.1f}{t[1]:>10.1f}")
