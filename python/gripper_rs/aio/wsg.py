"""The WSG client for asyncio (``gripper_rs.wsg`` has the types and the simulator)."""

from __future__ import annotations

from gripper_rs import _native

__all__ = ["Client"]

Client = _native.wsg.AioClient
