"""The solver options that keep a whisker's contact solve independent of the other whiskers of
its world (Independence, :mod:`pipeline.engines.mujoco`).

Each whisker touching a static obstacle is its own constraint island, and MuJoCo solves the
islands one by one, but two decisions of the solve look at the whole world: whether the
projected Gauss–Seidel solve starts from the last step's forces (the warm start is kept when
the total cost over every constraint of the world is negative) and when the no-slip pass
stops (its improvement scaled by the world's mean inertia and number of dofs). Without the warm
start the solve starts from zero, and the no-slip pass always makes its
:data:`~pipeline.engines.mujoco.spec.NOSLIP_ITERATIONS` sweeps: a whisker alone and in a
5-whisker world against a wavy wall then differ by ≤ 5·10⁻⁷ of its peak wrench (7.8·10⁻⁵
with both decisions world-wide; tests/engines/test_engine_mujoco_contact.py).
"""

from __future__ import annotations

import mujoco


def independent_islands(model: mujoco.MjModel) -> None:
    """Set ``model``'s solver options so that no decision of the contact solve depends on
    another island (module docstring)."""
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_WARMSTART)
    model.opt.noslip_tolerance = 0.0
