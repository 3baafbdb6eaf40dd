"""The griplink client for asyncio (``gripper_rs.griplink`` has the types and the simulator)."""

from __future__ import annotations

from gripper_rs import _native

__all__ = ["Client", "Port"]

Client = _native.griplink.AioClient
Port = _native.griplink.AioPort
