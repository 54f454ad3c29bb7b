"""Which faces of a static mesh a whisker that can touch is given: those near its free node paths.

A whisker that runs on the full engine (its coarse free path, :mod:`pipeline.engines.free_path`,
comes too close to the scene) still spends most of its trial near that path: before its first
contact it follows it to 0.16 mm, and a contact pushes it back out of the surface it met. So a
world builds, per whisker, only the faces of its reach ball whose prisms (bounding spheres) come
within the path's padding (:func:`path_padding_m`: base radius, half the longest link, half
the farthest the node or a neighbour moves to or from the sample) plus :data:`SWEPT_MARGIN_M`
of its coarse node paths, instead of every face of the ball: on the dataset trials of
configs/simulate.yaml 3 064 prisms compiled per trial instead of 5 986, 0.23 s compiling
instead of 0.53 (benchmarks/bench_contact_faces.py; docs/scaling.md).

Safety. After the run, every node of the whisker at every output sample must keep farther than
its padding (from the full run's own node paths) from the prisms of its reach ball that were
not built; this is the clearance rule of :class:`~pipeline.engines.common.FreeMotion` (every
point of a link lies within the padding of a sampled node), so a whisker that passes never came
near a face it was not given. One that fails (:meth:`SweptCrop.escaped`; a contact can bend a
whisker 17 mm off its free path) is simulated again with the faces near that run's node paths
added, and after :data:`SWEPT_RUNS` such runs with its whole reach ball; the failed runs are
discarded (6 of 91 whisker runs in 8 dataset trials).
"""

from __future__ import annotations

import numpy as np

from pipeline.engines import units as U

SWEPT_MARGIN_M = 4e-3    # faces built beyond a coarse path's padding (module docstring)
SWEPT_RUNS = 2           # runs with a crop before a whisker gets its whole reach ball


def path_padding_m(padding_m: float, nodes_m: np.ndarray) -> np.ndarray:
    """[T, N+1] padding (m) of each node of a path ``nodes_m`` [T, N+1, 3] at each sample:
    ``padding_m`` plus half the farthest it or a neighbouring node moves to or from this sample
    (a point of a link moves no farther than the link's nodes; between two samples it stays
    within half its move of one of them)."""
    step = np.linalg.norm(np.diff(nodes_m, axis=0), axis=-1)                  # [T-1, N+1]
    step = np.maximum(np.pad(step, ((1, 0), (0, 0))), np.pad(step, ((0, 1), (0, 0))))
    step = np.maximum(step, np.maximum(np.pad(step[:, 1:], ((0, 0), (0, 1))), np.pad(step[:, :-1], ((0, 0), (1, 0)))))
    return padding_m + 0.5 * step


class PrismSpheres:
    """Bounding spheres (m) of a mesh's prisms ``corners`` [F, 6, 3] (mm)."""

    def __init__(self, corners_mm: np.ndarray):
        corners = corners_mm / U.LENGTH
        self.centres = corners.mean(axis=1)
        self.radii = np.linalg.norm(corners - self.centres[:, None], axis=2).max(axis=1)

    def near(self, faces: np.ndarray, nodes_m: np.ndarray, padding_m: np.ndarray) -> np.ndarray:
        """[len(faces)] whether each face's prism may come within a node's padding: ``nodes_m``
        [..., 3], ``padding_m`` [...] (m)."""
        # imported here, not at the top: scipy.spatial ≈0.33 CPU-s, only for trials with a scan
        from scipy.spatial import cKDTree

        result = np.zeros(len(faces), bool)
        if not faces.size:
            return result
        reach = float(self.radii[faces].max() + padding_m.max())
        pairs = cKDTree(self.centres[faces]).sparse_distance_matrix(
            cKDTree(nodes_m.reshape(-1, 3)), reach, output_type="ndarray")
        close = pairs["v"] <= self.radii[faces][pairs["i"]] + padding_m.ravel()[pairs["j"]]
        result[pairs["i"][close]] = True
        return result


class SweptCrop:
    """The faces built for a world's whiskers: per whisker, those of its reach ball near its
    coarse node paths (module docstring)."""

    def __init__(self, spheres: PrismSpheres, reach_faces: list[np.ndarray], guides_m: list,
                 padding_m: np.ndarray):
        """``reach_faces``: per whisker the valid faces of its reach ball; ``guides_m``: per
        whisker the node paths [T, N+1, 3] (m, world) to build faces near (its coarse free path,
        then those of its runs that left their crop), or None for its whole reach ball;
        ``padding_m`` [w]: its links' padding (m)."""
        self.spheres, self.reach_faces, self.padding_m = spheres, reach_faces, padding_m
        self.cropped = np.array([guides is not None for guides in guides_m], bool)
        near = [faces if guides is None else
                faces[np.any([spheres.near(faces, path, path_padding_m(pad, path) + SWEPT_MARGIN_M)
                              for path in guides], axis=0)]
                for faces, guides, pad in zip(reach_faces, guides_m, padding_m)]
        self.faces = np.unique(np.concatenate(near)) if near else np.zeros(0, np.int64)

    def escaped(self, nodes_m: np.ndarray) -> np.ndarray:
        """[w] whether a whisker's node paths ``nodes_m`` [T, w, N+1, 3] (m) of the run came
        within their padding of a prism of its reach ball that was not built."""
        result = np.zeros(len(self.reach_faces), bool)
        for j in np.flatnonzero(self.cropped):
            faces = self.reach_faces[j]
            left_out = faces[~np.isin(faces, self.faces, assume_unique=True)]
            path = nodes_m[:, j].astype(float)
            result[j] = bool(self.spheres.near(left_out, path, path_padding_m(self.padding_m[j], path)).any())
        return result
