"""One pybullet physics server and its functions with the client id bound: ``client.getAABB(body,
-1)`` for ``pybullet.getAABB(body, -1, physicsClientId=...)``.

Built on ``pybullet_utils.bullet_client.BulletClient`` (shipped with pybullet), which binds the
id on every attribute lookup; here each function is bound once, on first use, because the
engine's step loop calls a few of them per whisker and step."""

from __future__ import annotations

import os

import pybullet
from pybullet_utils.bullet_client import BulletClient as _PybulletClient


class BulletClient(_PybulletClient):
    """A DIRECT (headless) pybullet server; disconnected by :meth:`close` or when collected."""

    def __init__(self):             # not the base's: its connect(..., options="") prints "argv[0]="
        self._shapes, self._pid = {}, os.getpid()
        self._client = pybullet.connect(pybullet.DIRECT)

    def __getattr__(self, name: str):
        attribute = super().__getattr__(name)
        self.__dict__[name] = attribute          # later lookups skip __getattr__
        return attribute

    def close(self) -> None:
        """Disconnect the server (idempotent)."""
        if self._client >= 0 and pybullet.isConnected(self._client):
            pybullet.disconnect(self._client)
        self._client = -1
