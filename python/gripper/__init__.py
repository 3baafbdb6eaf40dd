"""Clients and simulators for Weiss WSG grippers, Weiss GRIPLINK controllers and the SCHUNK 2D
Grasping-Kit, over the ``gripper`` Rust crate.

``from gripper import wsg, griplink, smartgrasp``: blocking clients (the GIL is released while
they wait; any number of threads may share one; Ctrl-C ends a wait), each protocol's simulator as
``<protocol>.sim.SimServer``, and the asyncio API under ``gripper.aio``. Every error is a
``gripper.GripperError`` (see ``gripper.errors``).
"""

from __future__ import annotations

from gripper import _native
from gripper.errors import (
    ClosedError,
    ConnectionLostError,
    DeviceError,
    GripperError,
    InvalidArgumentError,
    MalformedReplyError,
    ProtocolError,
    TimeoutError,
    TransportError,
)

Stream = _native.Stream

from gripper import griplink, smartgrasp, wsg  # noqa: E402  (they use the names above)

__all__ = [
    "ClosedError",
    "ConnectionLostError",
    "DeviceError",
    "GripperError",
    "InvalidArgumentError",
    "MalformedReplyError",
    "ProtocolError",
    "Stream",
    "TimeoutError",
    "TransportError",
    "griplink",
    "smartgrasp",
    "wsg",
]
