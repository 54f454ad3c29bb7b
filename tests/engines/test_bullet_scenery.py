"""A scan's mesh shape is handed to pybullet in lists that stay small, since pybullet keeps them."""

import numpy as np

from pipeline.engines.bullet.scenery import _mesh_lists


def _grid_mesh(n: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """A flat n × n grid of vertices (mm) in two triangles per cell."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    vertices = np.column_stack([x.ravel(), y.ravel(), np.sin(x.ravel())])
    corner = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    faces = np.concatenate([np.column_stack([corner, corner + 1, corner + n]),
                            np.column_stack([corner + 1, corner + n + 1, corner + n])])
    return vertices, faces.astype(np.int64)


def test_mesh_lists_hold_the_mesh_with_one_int_per_vertex():
    vertices, faces = _grid_mesh()
    points, indices = _mesh_lists(vertices, faces)
    assert np.array_equal(np.array(points), vertices) and indices == faces.ravel().tolist()
    assert len({id(i) for i in indices}) == len(vertices)        # not one int object per corner

