"""The smartgrasp client for asyncio (``gripper_rs.smartgrasp`` has the types and the simulator)."""

from __future__ import annotations

from gripper_rs import _native

__all__ = ["Client"]

Client = _native.smartgrasp.AioClient

