"""The arguments of ``pybullet.createMultiBody`` for a chain of links, gathered link by link."""

from __future__ import annotations

import numpy as np

from pipeline.model.rotations import quat_xyzw

MAX_MULTIBODY_LINKS = 127    # pybullet: joint indices of one multibody stop at 126
IDENTITY_QUAT = (0.0, 0.0, 0.0, 1.0)
CAPSULE_ALONG_X = (0.0, 0.7071067811865476, 0.0, 0.7071067811865476)   # z axis → x axis


def quat(matrix: np.ndarray) -> list[float]:
    return quat_xyzw(matrix).tolist()


class LinkList:
    """Accumulates the per-link arguments of ``createMultiBody``."""

    def __init__(self):
        self.columns = {k: [] for k in ("linkMasses", "linkCollisionShapeIndices",
                                        "linkVisualShapeIndices", "linkPositions",
                                        "linkOrientations", "linkInertialFramePositions",
                                        "linkInertialFrameOrientations", "linkParentIndices",
                                        "linkJointTypes", "linkJointAxis")}
        self.inertia: list[list[float]] = []

    def add(self, parent: int, joint_type: int, axis, position=(0, 0, 0), rotation=None,
            mass=0.0, inertia=(0.0, 0.0, 0.0), shape=-1, com=(0.0, 0.0, 0.0)) -> int:
        """Add a link; returns its link index (its id as a parent is index + 1)."""
        c = self.columns
        c["linkMasses"].append(mass)
        c["linkCollisionShapeIndices"].append(shape)
        c["linkVisualShapeIndices"].append(-1)
        c["linkPositions"].append(list(position))
        c["linkOrientations"].append(IDENTITY_QUAT if rotation is None else quat(rotation))
        c["linkInertialFramePositions"].append(list(com))
        c["linkInertialFrameOrientations"].append(IDENTITY_QUAT)
        c["linkParentIndices"].append(parent + 1)
        c["linkJointTypes"].append(joint_type)
        c["linkJointAxis"].append(list(axis))
        self.inertia.append(list(inertia))
        return len(self.inertia) - 1
