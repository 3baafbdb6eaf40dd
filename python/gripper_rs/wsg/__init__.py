"""Weiss WSG grippers' binary protocol (Rust: ``gripper::wsg``).

``Client.connect_tcp("host:port")``, ``Client.connect_udp``, ``Client.open_serial``; the Rust
client's methods under the same names (``home``, ``pre_position(width_mm, speed_mm_per_s)``,
``grasp``, ``release``, ``stop``, ``width_mm()``, ``grip_state()``, ``subscribe_width_mm(period_s)``,
...). ``gripper_rs.wsg.sim.SimServer`` is a simulated gripper; ``gripper_rs.aio.wsg`` the asyncio
API.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from gripper_rs import _native
from gripper_rs._enum import OpenIntEnum

__all__ = [
    "Client",
    "DEFAULT_PORT",
    "DeviceType",
    "FingerFlags",
    "FingerInfo",
    "FingerType",
    "GraspingStatistics",
    "GripState",
    "HomingDirection",
    "Reply",
    "SoftLimits",
    "Status",
    "SystemInfo",
    "SystemLimits",
    "SystemState",
    "sim",
    "text",
]

Client = _native.wsg.Client

DEFAULT_PORT: int = _native.wsg.DEFAULT_PORT
"""The gripper's default TCP port."""


class HomingDirection(enum.IntEnum):
    """Direction of a homing move (command 0x20)."""

    DEFAULT = 0
    """The direction configured on the device."""
    POSITIVE = 1
    """Outwards."""
    NEGATIVE = 2
    """Inwards."""


class GripState(OpenIntEnum):
    """The grip state (manual 3.4.2, command 0x41); 8..255 are reserved and kept."""

    IDLE = 0
    GRASPING = 1
    NO_PART_FOUND = 2
    PART_LOST = 3
    HOLDING = 4
    RELEASING = 5
    POSITIONING = 6
    ERROR = 7


class SystemState(enum.IntFlag, boundary=enum.KEEP):
    """The system state flags (manual, Anhang B, command 0x40); reserved bits are kept."""

    REFERENCED = 1 << 0
    MOVING = 1 << 1
    BLOCKED_MINUS = 1 << 2
    BLOCKED_PLUS = 1 << 3
    SOFT_LIMIT_MINUS = 1 << 4
    SOFT_LIMIT_PLUS = 1 << 5
    AXIS_STOPPED = 1 << 6
    TARGET_POS_REACHED = 1 << 7
    OVERDRIVE_MODE = 1 << 8
    FORCECNTL_MODE = 1 << 9
    FAST_STOP = 1 << 12
    TEMP_WARNING = 1 << 13
    TEMP_FAULT = 1 << 14
    POWER_FAULT = 1 << 15
    CURR_FAULT = 1 << 16
    FINGER_FAULT = 1 << 17
    CMD_FAILURE = 1 << 18
    SCRIPT_RUNNING = 1 << 19
    SCRIPT_FAILURE = 1 << 20


class FingerFlags(enum.IntFlag, boundary=enum.KEEP):
    """Finger state flags (manual 3.6.2, commands 0x61 / 0x71)."""

    POWER_ON = 1 << 0
    CONFIG_AVAIL = 1 << 1
    COMM_OPEN = 1 << 2
    POWER_FAULT = 1 << 8
    COMM_FAULT = 1 << 9


class DeviceType(OpenIntEnum):
    """The device type in the system information (command 0x50)."""

    UNKNOWN = 0
    WSG50 = 1
    WSG32 = 2
    KMS40 = 3
    WTS = 4
    WSG25 = 5
    WSG70 = 6


class FingerType(OpenIntEnum):
    """A finger's type (commands 0x60 / 0x70)."""

    GENERIC = 0
    FMF = 1
    DSA = 2


class Status(OpenIntEnum):
    """The device's status codes (manual, Anhang A); ``DeviceError.code`` is one of these."""

    SUCCESS = 0
    """no error, command successful"""
    NOT_AVAILABLE = 1
    """function or data not available"""
    NO_SENSOR = 2
    """no measuring converter connected"""
    NOT_INITIALIZED = 3
    """device not initialized"""
    ALREADY_RUNNING = 4
    """already running"""
    FEATURE_NOT_SUPPORTED = 5
    """the function is not supported"""
    INCONSISTENT_DATA = 6
    """one or more parameters are inconsistent"""
    TIMEOUT = 7
    """timeout"""
    READ_ERROR = 8
    """error while reading data"""
    WRITE_ERROR = 9
    """error while writing data"""
    INSUFFICIENT_RESOURCES = 10
    """not enough memory"""
    CHECKSUM_ERROR = 11
    """checksum error"""
    NO_PARAM_EXPECTED = 12
    """parameter given although none expected"""
    NOT_ENOUGH_PARAMS = 13
    """too few parameters for the command"""
    CMD_UNKNOWN = 14
    """unknown command"""
    CMD_FORMAT_ERROR = 15
    """command format error"""
    ACCESS_DENIED = 16
    """access denied"""
    ALREADY_OPEN = 17
    """interface already open"""
    CMD_FAILED = 18
    """error while executing a command"""
    CMD_ABORTED = 19
    """command execution aborted by the user"""
    INVALID_HANDLE = 20
    """invalid handle"""
    NOT_FOUND = 21
    """device or file not found"""
    NOT_OPEN = 22
    """device or file not open"""
    IO_ERROR = 23
    """input/output error"""
    INVALID_PARAMETER = 24
    """invalid parameter"""
    INDEX_OUT_OF_BOUNDS = 25
    """index out of bounds"""
    CMD_PENDING = 26
    """command not yet completed; a reply with the result follows"""
    OVERRUN = 27
    """data overrun"""
    RANGE_ERROR = 28
    """range error"""
    AXIS_BLOCKED = 29
    """axis blocked"""
    FILE_EXISTS = 30
    """file already exists"""


@dataclass(frozen=True)
class SoftLimits:
    """Soft limits (commands 0x34 / 0x35), mm."""

    minus_mm: float
    plus_mm: float


@dataclass(frozen=True)
class GraspingStatistics:
    """Grasping statistics (command 0x42)."""

    total: int
    no_part: int
    lost_part: int


@dataclass(frozen=True)
class SystemInfo:
    """System information (command 0x50); ``firmware`` as "major.minor.patch"."""

    device_type: DeviceType
    hardware_revision: int
    firmware_version: int
    firmware: str
    serial_number: int


@dataclass(frozen=True)
class SystemLimits:
    """The system limits (command 0x53)."""

    stroke_mm: float
    min_speed_mm_per_s: float
    max_speed_mm_per_s: float
    min_acceleration_mm_per_s2: float
    max_acceleration_mm_per_s2: float
    min_force_n: float
    nominal_force_n: float
    overdrive_force_n: float


@dataclass(frozen=True)
class FingerInfo:
    """A finger's type and data size (commands 0x60 / 0x70)."""

    finger_type: FingerType
    data_size: int


from gripper_rs.wsg import sim  # noqa: E402  (sim builds on the records above)
from gripper_rs.wsg import text  # noqa: E402  (the text interface's client, GCL)


@dataclass(frozen=True)
class Reply:
    """The final reply to a raw ``Client.request``, whatever its status."""

    id: int
    """The id of the command answered."""
    status: Status
    """The status code (``Status.SUCCESS``, or the device's refusal)."""
    data: bytes
    """The data after the status code (empty unless the status is ``SUCCESS``)."""
