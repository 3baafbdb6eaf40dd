"""Weiss GRIPLINK controllers' ASCII command set (Rust: ``gripper::griplink``).

``Client.connect("host:port")``; ``client.port(n)`` is the device on port n, with the Rust
``Port``'s methods (``home``, ``grip``, ``grip_and_wait``, ``position_mm``, ...).
``gripper_rs.griplink.sim.SimServer`` is a simulated controller; ``gripper_rs.aio.griplink`` the
asyncio API.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from gripper_rs import _native
from gripper_rs._enum import OpenIntEnum

__all__ = [
    "Answer",
    "Client",
    "DEFAULT_PORT",
    "DeviceState",
    "GripConfig",
    "GripConfigF",
    "GripOutcome",
    "Port",
    "ReleaseOutcome",
    "Status",
    "sim",
]

Client = _native.griplink.Client
Port = _native.griplink.Port

DEFAULT_PORT: int = _native.griplink.DEFAULT_PORT
"""The controller's default TCP port."""


class DeviceState(OpenIntEnum):
    """The state of the device on a port (manual chapter 5); unknown numbers are kept."""

    NOT_CONNECTED = 0
    NOT_INITIALIZED = 1
    DISABLED = 2
    RELEASED = 3
    NO_PART = 4
    HOLDING = 5
    ENABLED = 6
    FAULT = 7


class GripOutcome(enum.Enum):
    """How a grip ended (manual 3.4.4)."""

    HOLDING = "HOLDING"
    NO_PART = "NO_PART"
    FAULT = "FAULT"


class ReleaseOutcome(enum.Enum):
    """How a release ended (manual 3.4.5)."""

    RELEASED = "RELEASED"
    FAULT = "FAULT"


class Status(OpenIntEnum):
    """The controller's status codes (manual chapter 4); ``DeviceError.code`` is one of these."""

    SUCCESS = 0
    """No error. Command successfully executed"""
    OVERRUN = 1
    """Data overrun"""
    RANGE_ERROR = 2
    """Value out of range"""
    NOT_AVAILABLE = 3
    """Function or data not available"""
    NOT_INITIALIZED = 4
    """Device not initialized"""
    TIMEOUT = 5
    """Timeout"""
    INSUFFICIENT_RESOURCES = 6
    """Not enough memory available"""
    CHECKSUM_ERROR = 7
    """Checksum error"""
    ACCESS_DENIED = 8
    """Access denied"""
    INVALID_HANDLE = 9
    """Invalid handle"""
    INVALID_PARAMETER = 10
    """Invalid parameter"""
    INDEX_OUT_OF_BOUNDS = 11
    """Index out of bounds"""
    IO_ERROR = 12
    """Generic I/O error"""
    READ_ERROR = 13
    """Read error"""
    WRITE_ERROR = 14
    """Write error"""
    NOT_FOUND = 15
    """Resource not found"""
    NOT_OPEN = 16
    """File or device not open"""
    EXISTS = 17
    """Resource already exists"""
    NO_COMM = 18
    """Connection error"""
    STATE_CONFLICT = 19
    """Invalid state"""
    NOT_SUPPORTED = 20
    """Command or function not supported"""
    INCONSISTENT_DATA = 21
    """Data inconsistent"""
    CMD_SYNTAX = 22
    """Syntax error"""
    CMD_UNKNOWN = 23
    """Unknown command"""
    CMD_ABORTED = 24
    """Command aborted"""
    CMD_FAILED = 25
    """Command failed"""
    AXIS_BLOCKED = 26
    """Axis is blocked"""
    PENDING = 27
    """Pending action / Not yet finished"""


@dataclass(frozen=True)
class GripConfig:
    """A grip recipe in device units (``GRIPCFG``): a tag and eight parameters."""

    tag: str
    params: list[int]


@dataclass(frozen=True)
class GripConfigF:
    """A grip recipe in physical units (``GRIPCFGF``); for Weiss grippers the first three
    parameters are the no-part limit (mm), the release limit (mm) and the force (%)."""

    tag: str
    params: list[float]


from gripper_rs.griplink import sim  # noqa: E402


@dataclass(frozen=True)
class Answer:
    """The data reply of a raw ``Client.command`` line: ``KEY[indices]=value`` (an ``ACK`` is
    None)."""

    key: str
    """The key, as received (``VALUEF``)."""
    indices: tuple[int, ...]
    """The indices in brackets, in order (port, then value or recipe index)."""
    value: int | float | str | list[Any]
    """The value after ``=``: an integer, a number, a string (without quotes) or a list."""
