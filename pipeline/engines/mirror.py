"""Mirror twins: whiskers whose free motion is another whisker's, reflected.

The model's arrays are bilaterally symmetric: a left whisker is its right twin reflected in the
head's x = 0 plane (M = diag(−1, 1, 1), head frame) with its whisker frame's z axis flipped
(D = diag(1, 1, −1)): base point M·b, frame M·R(θ)·D at every protraction θ, the same physics
(:func:`twins` checks all three). Driven by the same protraction, without loads that depend on
the head's pose (the free paths' condition, :mod:`pipeline.engines.free_path`), its free
motion is its twin's reflected: node positions M·x (head frame), base force D·F and moment −D·M
(whisker frame: :data:`WRENCH_SIGNS`), and each spring joint's angle and rate negated unless its
axis is the frame's z axis (a reflection P turns R_a(φ) into R_{P·a}(−φ)). On the linear chain
the reflected twin equals the whisker's own free motion to 10⁻¹² of the wrench and 4·10⁻¹⁵ m
(tests/engines/test_free_path.py), so the free paths compute one whisker of each pair.
"""

from __future__ import annotations

import dataclasses

import numpy as np

WRENCH_SIGNS = np.array([1.0, 1.0, -1.0, -1.0, -1.0, 1.0])   # (F, M) of a twin, whisker frame
HEAD_MIRROR = np.array([-1.0, 1.0, 1.0])                       # M: node positions of a twin, head frame
FRAME_MIRROR = np.array([1.0, 1.0, -1.0])                      # D: the whisker frame's axes
PROBE_ANGLES_RAD = (-0.6, 0.0, 0.7, 1.4)                        # protractions at which twins' frames are compared


def twins(whiskers) -> np.ndarray:
    """[W] per whisker the index of the whisker whose free motion gives its own: its first
    mirror twin (the lower index) or itself."""
    source = np.arange(len(whiskers))
    for k, whisker in enumerate(whiskers):
        for j in range(k):
            if source[j] == j and is_twin(whiskers[j], whisker):
                source[k] = j
                break
    return source


def is_twin(a, b) -> bool:
    """Whether whisker b is whisker a reflected (module docstring)."""
    if not np.allclose(b.base_point_m, HEAD_MIRROR * a.base_point_m, rtol=0, atol=1e-12):
        return False
    if not all(np.allclose(b.frame(t), HEAD_MIRROR[:, None] * a.frame(t) * FRAME_MIRROR, rtol=0, atol=1e-12)
               for t in PROBE_ANGLES_RAD):
        return False
    z = a.physics.layout.axes[:, 2]                       # D·axis = ±axis: in the frame's x–y plane or along z
    return bool(np.all(np.isclose(z, 0, atol=1e-12) | np.isclose(np.abs(z), 1))) and _same(a.physics, b.physics)


def joint_signs(layout) -> np.ndarray:
    """[n] the factor from a whisker's spring-joint angles (and rates) to its twin's: +1 about
    the frame's z axis, −1 about an axis in its x–y plane."""
    return -np.einsum("na,a,na->n", layout.axes, FRAME_MIRROR, layout.axes)


def mirrored(wrench: np.ndarray, head_nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A twin's base wrench [T, 6] (whisker frame) and node positions [T, N+1, 3] (head frame)
    from the whisker's."""
    return wrench * WRENCH_SIGNS, head_nodes * HEAD_MIRROR


def _same(a, b) -> bool:
    """Deep equality of model objects: dataclasses field by field, arrays exactly."""
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    return a == b
