"""A MuJoCo world's output samples: the raw readings of each sample (base sensors in the site
frame, follicle angles, link origins and tips, internal units) kept as they are and turned into
the result's SI arrays (whisker-frame wrench, node positions in m) in one pass over many samples,
with the same arithmetic as one sample at a time, so the same numbers.

A run nobody reads sample by sample (:meth:`~pipeline.engines.mujoco.world.MujocoWorld._simulate`)
converts at its end; a sample whose raw base moments, squared and summed over the world's members,
could make one implausible (above half :data:`~pipeline.engines.common.MAX_PLAUSIBLE_MOMENT_NM`,
or not finite: rotating a moment keeps its length, so a reading below half the limit cannot
exceed it after the rotation) is converted at once, so a jam is still found at the sample it
happens in and the run stops there."""

from __future__ import annotations

import numpy as np

from pipeline.engines import units as U
from pipeline.engines.base import WorldResult
from pipeline.engines import common


class SampleReadings:
    """The raw readings of one world run's samples (``world``: its follicle turns, link bodies
    and tip sites), converted into a :class:`~pipeline.engines.base.WorldResult`."""

    def __init__(self, world, samples: int, eager: bool):
        """``eager``: convert every sample as it is read (someone reads the result as it grows)."""
        members = len(world.members)
        self.follicle, self.link_bodies, self.tip_sites = world.follicle, world.flat_link_bodies, world.tip_sites
        self.links = world.links
        self.sensors = np.empty((samples, members, 2, 3))
        self.angles = [np.empty((samples, len(a))) for a in self.follicle.addresses]
        self.origins = np.empty((samples, self.link_bodies.size, 3))
        self.tips = np.empty((samples, members, 3))
        self.eager = eager
        # the raw moment (internal units, squared) below which a sample's conversion can wait (checked
        # on the sum over the members, which no member's exceeds); the limit as it is now
        self.safe_squared = (0.5 * common.MAX_PLAUSIBLE_MOMENT_NM * U.TORQUE) ** 2
        self.converted = 0                      # samples before this one are in the result

    def read(self, d, sample: int) -> bool:
        """Keep ``d``'s readings as output ``sample``; whether to convert now (:meth:`convert`)."""
        sensors = self.sensors[sample]
        np.copyto(sensors.reshape(-1), d.sensordata)
        qpos = d.qpos
        for angles, addresses in zip(self.angles, self.follicle.addresses):
            np.take(qpos, addresses, out=angles[sample])
        np.take(d.xpos, self.link_bodies, axis=0, out=self.origins[sample])
        np.take(d.site_xpos, self.tip_sites, axis=0, out=self.tips[sample])
        if self.eager:
            return True
        torque = sensors[:, 1].ravel()
        return not torque @ torque <= self.safe_squared

    def convert(self, result: WorldResult, until: int) -> tuple[int, np.ndarray] | None:
        """Write samples up to ``until`` (exclusive) into ``result``'s wrench and nodes; the first
        of them with implausible base moments and those members' indices, or None."""
        rows = slice(self.converted, until)
        self.converted = until
        wrench = self.sensors[rows]                          # [t, w, (force, torque), 3], site frame
        if self.follicle:
            turns = self.follicle.matrices([angles[rows] for angles in self.angles])
            wrench = wrench @ np.swapaxes(turns, -1, -2)
        out = result.wrench[rows]
        with np.errstate(over="ignore", invalid="ignore"):           # a jam shows as inf/nan
            np.divide(wrench[..., 0, :], U.FORCE, out=out[..., :3])
            np.divide(wrench[..., 1, :], U.TORQUE, out=out[..., 3:])
        nodes = result.nodes[rows]
        origins = self.origins[rows]
        np.divide(origins.reshape(nodes[:, :, :-1].shape), U.LENGTH, out=nodes[:, :, :-1])
        np.divide(self.tips[rows], U.LENGTH, out=nodes[:, :, -1])
        bad = common.implausible(out.reshape(-1, 6))
        if not bad.size:
            return None
        sample, member = np.divmod(bad, out.shape[1])
        first = sample.min()
        return rows.start + int(first), member[sample == first]
