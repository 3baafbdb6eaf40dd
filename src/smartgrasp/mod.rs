//! SCHUNK 2D Grasping-Kit "Smart Grasping" native protocol V3 (manual seed 002): 80-byte big
//! endian frames over TCP, port 42001.
//!
//! Layers, each usable alone:
//! - [`frame`]: the 6-byte prefix and the 80-byte request/response frames, every field of the
//!   layout table (pure);
//! - [`types`], [`message`], [`pose`]: the enumerations, typed requests and responses of the eight
//!   message types, and poses in the four formats with SI conversions (pure);
//! - [`codec`]: tokio-util codecs that read the prefix first and refuse any length but 74;
//! - [`Client`]: the async client, a cloneable handle to a task that owns the connection and checks
//!   every response (type, message type, response counter, response code);
//! - `sim` (feature `sim`): a simulated server.
//!
//! ```
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> gripper::smartgrasp::Result<()> {
//! use gripper::smartgrasp::sim::{SimConfig, SimServer};
//! use gripper::smartgrasp::{
//!     Client, ClientConfig, GetGraspOutcome, GraspFeedback, GraspMode, GraspRequest, PoseFormat,
//!     RobotSystem, Tool,
//! };
//!
//! let server = SimServer::bind("127.0.0.1:0", SimConfig::default()).await?;
//! let config = ClientConfig {
//!     robot_system: Some(RobotSystem::Kuka),
//!     project_index: Some(0),
//!     ..ClientConfig::default()
//! };
//! let client = Client::connect(server.local_addr(), config).await?;
//! let request = GraspRequest {
//!     grasp_mode: GraspMode::AutoGrasp,
//!     object_class: 0,
//!     tool: Tool::Exterior,
//!     pose_format: PoseFormat::Abc,
//! };
//! let mut picked = 0;
//! while let GetGraspOutcome::Grasp(grasp) = client.get_grasp(request).await? {
//!     let si = grasp.pose.to_si()?;
//!     println!("grasp at {:?} m, KUKA: {}", si.position_m, grasp.pose);
//!     // ... move the robot, close the gripper ...
//!     client.grasp_feedback(GraspFeedback::Ok).await?;
//!     picked += 1;
//! }
//! assert_eq!(picked, 3);
//! assert_eq!(server.registered_clients(), [RobotSystem::Kuka]);
//! # Ok(())
//! # }
//! ```

mod client;
pub mod codec;
pub mod error;
pub mod frame;
pub mod message;
pub mod pose;
#[cfg(feature = "sim")]
pub mod sim;
pub mod types;

pub use client::{Client, ClientConfig, GetGraspOutcome, DEFAULT_PORT};
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
