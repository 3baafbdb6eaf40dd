//! The ROS 2 message, service and action types the node speaks, as serde structs.
//!
//! Field order and types are those of the `.msg`/`.srv`/`.action` files of ROS 2 Jazzy: CDR has
//! no field names, so the order *is* the wire format. ros2-client ships none of these packages.

use ros2_client::builtin_interfaces::Time;
use ros2_client::{ActionTypeName, Message, MessageTypeName, ServiceTypeName};
use serde::{Deserialize, Serialize};

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// The coordinate frame of the data.
    pub frame_id: String,
}

impl Header {
    /// A header stamped now (system clock).
    pub fn now(frame_id: &str) -> Self {
        Header {
            stamp: Time::now(),
            frame_id: frame_id.to_owned(),
        }
    }
}

/// `sensor_msgs/msg/JointState`: positions in m for our prismatic joints, velocities in m/s,
/// efforts in N.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp of the readings.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, m.
    pub position: Vec<f64>,
    /// Velocities, m/s.
    pub velocity: Vec<f64>,
    /// Efforts, N.
    pub effort: Vec<f64>,
}
impl Message for JointState {}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// The name of the value.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`], `WARN`, `ERROR` or `STALE`.
    pub level: u8,
    /// The component's name.
    pub name: String,
    /// A summary.
    pub message: String,
    /// The hardware's identity (serial number, address).
    pub hardware_id: String,
    /// The details.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// Level: all is well.
    pub const OK: u8 = 0;
    /// Level: works, with a warning.
    pub const WARN: u8 = 1;
    /// Level: does not work.
    pub const ERROR: u8 = 2;
    /// Level: no recent information.
    pub const STALE: u8 = 3;
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}
impl Message for DiagnosticArray {}

/// `std_srvs/srv/Trigger` request. The `.srv` has no field; IDL structs cannot be empty, so
/// rosidl adds this one byte (`structure_needs_at_least_one_member`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// Always 0; present only because CDR structs need a member.
    pub structure_needs_at_least_one_member: u8,
}
impl Message for TriggerRequest {}

/// `std_srvs/srv/Trigger` response.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// Whether the request was carried out.
    pub success: bool,
    /// What happened, or why not.
    pub message: String,
}
impl Message for TriggerResponse {}

/// `control_msgs/msg/GripperCommand`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GripperCommand {
    /// Target position, m (see the `position_convention` parameter).
    pub position: f64,
    /// Force limit, N; 0 keeps the device's setting.
    pub max_effort: f64,
}

/// `control_msgs/action/GripperCommand` goal.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GripperCommandGoal {
    /// The command.
    pub command: GripperCommand,
}
impl Message for GripperCommandGoal {}

/// `control_msgs/action/GripperCommand` result; the feedback has the same four fields.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GripperCommandResult {
    /// Position reached, m.
    pub position: f64,
    /// Effort at the end, N.
    pub effort: f64,
    /// The fingers stopped before the target: a part is held or they are blocked.
    pub stalled: bool,
    /// The position is within the goal tolerance.
    pub reached_goal: bool,
}
impl Message for GripperCommandResult {}

/// `control_msgs/action/GripperCommand` feedback (same fields as the result).
pub type GripperCommandFeedback = GripperCommandResult;

/// `geometry_msgs/msg/Point`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// z, m.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose in that frame.
    pub pose: Pose,
}
impl Message for PoseStamped {}

/// The DDS type name of `sensor_msgs/msg/JointState`.
pub fn joint_state_type() -> MessageTypeName {
    MessageTypeName::new("sensor_msgs", "JointState")
}

/// The DDS type name of `diagnostic_msgs/msg/DiagnosticArray`.
pub fn diagnostic_array_type() -> MessageTypeName {
    MessageTypeName::new("diagnostic_msgs", "DiagnosticArray")
}

/// The DDS type name of `geometry_msgs/msg/PoseStamped`.
pub fn pose_stamped_type() -> MessageTypeName {
    MessageTypeName::new("geometry_msgs", "PoseStamped")
}

/// The service type `std_srvs/srv/Trigger`.
pub fn trigger_type() -> ServiceTypeName {
    ServiceTypeName::new("std_srvs", "Trigger")
}

/// The action type `control_msgs/action/GripperCommand`.
pub fn gripper_command_type() -> ActionTypeName {
    ActionTypeName::new("control_msgs", "GripperCommand")
}

/// `std_msgs/msg/Float64`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Float64 {
    /// The value.
    pub data: f64,
}
impl Message for Float64 {}

/// `std_msgs/msg/UInt16`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UInt16 {
    /// The value.
    pub data: u16,
}
impl Message for UInt16 {}
