"""The turn of each whisker's base sensor by the hinges at its base point (a compliant
follicle's, the twist joint of link 0): the sensor's site rides on the first link, so its
wrench reading is rotated back through the hinges into the whisker frame
(:mod:`pipeline.engines.mujoco`, Base wrench)."""

from __future__ import annotations

import numpy as np

from pipeline.model.rotations import axis_rotation


class FollicleTurns:
    """Per member of a world, the product of its base hinges' rotations, in the order of the
    hinges along its chain."""

    def __init__(self, hinges: list[tuple[int, np.ndarray, np.ndarray, np.ndarray | None]], members: int):
        """``hinges``: in chain order, (coordinate axis of the hinge's frame, the members that
        have a hinge there, the hinges' qpos addresses, the hinge's frame at rest in the whisker
        frame per such member [m, 3, 3], or None for the whisker frame itself: a turn by q is
        F·Rot(axis, q)·Fᵀ); ``members``: how many the world has."""
        everyone = np.arange(members)
        # None: every member has the hinge (a plain product, no gather and scatter of the stack)
        self.hinges = [(axis, None if np.array_equal(member, everyone) else member, frame)
                       for axis, member, _, frame in hinges]
        self.addresses = [qpos for _, _, qpos, _ in hinges]
        self.identities = np.tile(np.eye(3), (members, 1, 1))

    def __bool__(self) -> bool:
        return bool(self.hinges)

    def matrices(self, angles: list[np.ndarray]) -> np.ndarray:
        """[..., members, 3, 3] each member's follicle rotation at its hinges' ``angles`` (rad; per
        hinge of :attr:`hinges` [..., its members], e.g. ``qpos[addresses]`` for every address of
        :attr:`addresses`); each product is the same 3×3 product at any batch shape."""
        rotation = self.identities
        for (axis, member, frame), angle in zip(self.hinges, angles):
            turn = axis_rotation(axis, angle)
            if frame is not None:
                turn = frame @ turn @ np.swapaxes(frame, -1, -2)
            if member is None:
                rotation = rotation @ turn
            else:
                if rotation is self.identities:
                    rotation = np.broadcast_to(rotation, angle.shape[:-1] + rotation.shape).copy()
                rotation[..., member, :, :] = rotation[..., member, :, :] @ turn
        return rotation
