"""Clients and simulators for Weiss WSG grippers, Weiss GRIPLINK controllers and the SCHUNK 2D
Grasping-Kit, over the ``gripper`` Rust crate.

``from gripper_rs import wsg, griplink, smartgrasp``: blocking clients (the GIL is released while
they wait; any number of threads may share one; Ctrl-C ends a wait), each protocol's simulator as
``<protocol>.sim.SimServer``, and the asyncio API under ``gripper_rs.aio``. Every error is a
``gripper_rs.GripperError`` (see ``gripper_rs.errors``).
"""

from __future__ import annotations

import atexit

from gripper_rs import _lifecycle, _native
from gripper_rs.errors import (
    ClosedError,
    ConnectionLostError,
    DeviceError,
    GripperError,
    InvalidArgumentError,
    MalformedReplyError,
    ProtocolError,
    TransportError,
)
from gripper_rs.errors import TimeoutError as TimeoutError  # re-exported, not in __all__

Stream = _native.Stream

__version__: str = _native.__version__
"""The package's version (the Rust crate's: one number for both)."""

# Before the interpreter is finalized, let the runtime's last completions reach Python (see
# `_quiesce` in python/src/runtime.rs): one that arrives during finalization crashes the process.
atexit.register(_native._quiesce)
# Registered after `_quiesce`, so run before it (atexit runs last-in, first-out): the clients
# still open are closed, announcing the disconnect (see gripper_rs/_lifecycle.py).
atexit.register(_lifecycle.close_all)

from gripper_rs import griplink, reconnect, smartgrasp, wsg  # noqa: E402  (they use the names above)
from gripper_rs.reconnect import ConnectionEvent, ReconnectPolicy  # noqa: E402

reset_logging_cache = _native.reset_logging_cache

# `TimeoutError` is importable by name but not in `__all__`: `from gripper_rs import *` would
# shadow the builtin (ours is a subclass of it).
__all__ = [
    "ClosedError",
    "ConnectionEvent",
    "ConnectionLostError",
    "DeviceError",
    "GripperError",
    "InvalidArgumentError",
    "MalformedReplyError",
    "ProtocolError",
    "ReconnectPolicy",
    "Stream",
    "TransportError",
    "__version__",
    "griplink",
    "reconnect",
    "reset_logging_cache",
    "smartgrasp",
    "wsg",
]
