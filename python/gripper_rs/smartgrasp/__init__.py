"""The SCHUNK 2D Grasping-Kit native protocol (Rust: ``gripper::smartgrasp``).

``Client.connect("host:port")``; ``get_grasp(grasp_mode, object_class, tool, pose_format)``,
``grasp_feedback``, ``get_object_count``, ``robot_pose``, ...
``gripper_rs.smartgrasp.sim.SimServer`` is a simulated Grasping-Kit;
``gripper_rs.aio.smartgrasp`` the asyncio API.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from gripper_rs import _native
from gripper_rs._enum import OpenIntEnum

__all__ = [
    "Client",
    "DEFAULT_PORT",
    "GetGraspOutcome",
    "Grasp",
    "GraspMode",
    "GraspResult",
    "ObjectCount",
    "Pose",
    "PoseFormat",
    "ResponseCode",
    "RobotSystem",
    "ServerState",
    "Tool",
    "sim",
]

Client = _native.smartgrasp.Client

DEFAULT_PORT: int = _native.smartgrasp.DEFAULT_PORT
"""The Grasping-Kit's default TCP port."""


class ResponseCode(OpenIntEnum):
    """A response's code (manual 3.2); ``DeviceError.code`` is one of these."""

    SUCCESS = 1
    ERROR = 2
    NO_OBJECT = 3
    NO_GRASP = 4
    INVALID_OBJECT_CLASS = 5


class ServerState(OpenIntEnum):
    """The server's state (GET_STATE)."""

    INIT = 1
    OPERATIONAL = 2
    STOPPED = 3
    ERROR = 4


class RobotSystem(OpenIntEnum):
    """The robot system a client registers as (REGISTER_CLIENT)."""

    UR = 1
    KUKA = 2
    YASKAWA = 3
    FANUC = 4
    ABB = 5
    HORST = 6
    SIEMENS_PLC = 128


class GraspMode(OpenIntEnum):
    """How the server picks a grasp (GET_GRASP)."""

    ACTIVE_GRASP = 1
    ANY_GRASP = 2
    AUTO_GRASP = 3


class Tool(OpenIntEnum):
    """The tool the grasp is for."""

    EXTERIOR = 1
    INTERIOR = 2
    CONTACT = 3


class PoseFormat(OpenIntEnum):
    """How a pose's orientation is written on the wire."""

    QUATERNION = 1
    AXIS_ANGLE = 2
    WPR = 16
    ABC = 17


class GetGraspOutcome(enum.Enum):
    """What a GET_GRASP found."""

    GRASP = "GRASP"
    NO_OBJECT = "NO_OBJECT"
    NO_GRASP = "NO_GRASP"
    INVALID_OBJECT_CLASS = "INVALID_OBJECT_CLASS"


@dataclass(frozen=True)
class Pose:
    """A pose as on the wire (``format`` and seven integers: µm and the orientation's µ-units),
    with its position in metres and, when valid, its orientation as a unit quaternion."""

    format: PoseFormat
    wire: list[int]
    position_m: list[float]
    orientation_xyzw: list[float] | None


@dataclass(frozen=True)
class ObjectOffset:
    """Protocol V4's object offset in a grasp (its frame is not public)."""

    x_um: int
    y_um: int
    rz_udeg: int


@dataclass(frozen=True)
class Grasp:
    """A grasp from GET_GRASP (V3 manual 3.3.3.1; V4 as SCHUNK's public KUKA example reads it).
    What only one protocol version delivers is ``None`` from the other."""

    grasp_mode: GraspMode
    object_class: int
    object_instance: int
    stroke_um: int
    center_offset_um: list[int]
    pose: Pose
    object_count: int
    candidate_count: int
    # V3 only.
    center_offset_z_um: int | None
    angle_offset_udeg: int | None
    tool: Tool | None
    # V4 only (the reference frame's values are not public: kept as the number received).
    reference_frame: int | None
    object_offset: ObjectOffset | None

    @property
    def stroke_m(self) -> float:
        """The stroke in metres."""
        return self.stroke_um * 1e-6

    @property
    def stroke_mm(self) -> float:
        """The stroke in millimetres."""
        return self.stroke_um * 1e-3


@dataclass(frozen=True)
class GraspResult:
    """A GET_GRASP's answer: ``grasp`` is set when ``outcome`` is ``GRASP``."""

    outcome: GetGraspOutcome
    grasp: Grasp | None


@dataclass(frozen=True)
class ObjectCount:
    """A GET_OBJECT_COUNT's answer."""

    object_class: int
    object_count: int
    candidate_count: int


from gripper_rs.smartgrasp import sim  # noqa: E402
