//! SCHUNK 2D Grasping-Kit "Smart Grasping" native protocol V3 (under construction).

pub mod codec;
pub mod error;
pub mod frame;
pub mod message;
pub mod pose;
pub mod types;

pub use error::{Error, Malformed, Result};
pub use message::{
    Grasp, GraspRequest, ObjectCount, Request, RequestError, Response, ResponseBody,
};
pub use pose::{
    AbcPose, AxisAnglePose, Pose, PoseError, QuaternionPose, SiPose, UnitQuaternion, WprPose,
};
pub use types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ResponseCode,
    RobotSystem, ServerState, Tool,
};
