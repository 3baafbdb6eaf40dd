//! Weiss WSG grippers' binary command protocol (WSG 50, 32, 25, 70) over TCP, UDP and RS-232.
//!
//! Layers, each usable alone:
//! - [`checksum`]: the manual's CRC table and update rule (Anhang D);
//! - [`frame`]: pure encode/decode of `AA AA AA | id | len | payload | crc` frames, resyncing
//!   byte-wise on noise; [`WsgCodec`]: the tokio-util codec over it;
//! - [`command`], [`types`], [`Status`]: typed commands, reply data and status codes;
//! - [`Client`]: the async client; [`Subscription`]: auto-update streams;
//! - `sim` (feature `sim`): a simulated gripper serving TCP, UDP and a serial pseudo-terminal.
//!
//! # Example
//! ```
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use gripper::wsg::{sim, Client, GripState, HomingDirection};
//!
//! // A simulated WSG 50 with a 40 mm part between the fingers; motion takes no wall time.
//! let config = sim::SimConfig::new(sim::Model::Wsg50).with_part(40.0, 2.0);
//! let simulator = sim::SimServer::tcp(config, "127.0.0.1:0").await?;
//! let addr = simulator.local_addr().expect("TCP server has an address");
//!
//! let gripper = Client::connect_tcp(addr).await?;
//! println!("{:?}", gripper.system_info().await?);
//! gripper.home(HomingDirection::Default).await?;
//! gripper.pre_position(60.0, 100.0).await?;
//! gripper.grasp(40.0, 50.0).await?;
//! assert_eq!(gripper.grip_state().await?, GripState::Holding);
//! gripper.release(60.0, 100.0).await?;
//! gripper.close().await?; // announces the disconnect (0x07): no FAST STOP
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! ```

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
#[cfg(feature = "sim")]
pub mod sim;
