//! Weiss WSG grippers' binary command protocol.

pub mod checksum;
pub mod codec;
pub mod command;
mod error;
pub mod frame;
mod status;
pub mod types;

pub use codec::WsgCodec;
pub use command::{Command, HomingDirection, Reply, UpdateMode};
pub use error::{Error, Result};
pub use frame::Frame;
pub use status::Status;
pub use types::{
    DeviceType, Finger, FingerFlags, FingerInfo, FingerType, FirmwareVersion, GraspingStatistics,
    GripState, SoftLimits, SystemInfo, SystemLimits, SystemState,
};
pub mod client;
pub mod subscription;
pub mod transport;

pub use client::{Client, ClientBuilder};
pub use subscription::{Subscription, UpdateOptions};
pub use transport::TransportKind;
