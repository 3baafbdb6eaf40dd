"""The smartgrasp client for asyncio (``gripper.smartgrasp`` has the types and the simulator)."""

from __future__ import annotations

from gripper import _native

__all__ = ["Client"]

Client = _native.smartgrasp.AioClient

