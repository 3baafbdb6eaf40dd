//! # gripper
//!
//! Async clients and device simulators for the grippers and grasp planners of a robot cell:
//!
//! - [`wsg`]: Weiss WSG grippers' binary protocol (CRC-framed, over TCP, UDP and serial).
//! - [`smartgrasp`]: the SCHUNK 2D Grasping-Kit native protocol V3 and V4 (80-byte frames over
//!   TCP).
//! - [`griplink`]: Weiss GRIPLINK controllers' ASCII command set (LF-terminated lines over TCP).
//!
//! Every protocol has the same layers: pure encode/decode (no I/O), a tokio-util codec, an async
//! client whose connection is owned by a background task (the handle is cheap to clone and safe to
//! share between tasks), and — behind the default-on `sim` feature — a simulator that behaves like
//! the device, for tests that run without hardware.
//!
//! # Where a client's work runs
//!
//! Each client's connection is one task that owns the transport, pairs replies and runs the
//! timers. A call queues its request and then polls that task itself, so the request leaves from
//! the caller's thread without waking another one; replies, timers, auto-updates and reconnects
//! wake a spawned *keeper* task that polls the same task (on a `current_thread` runtime, the
//! waiting caller reads its own reply first). On a multi-thread runtime, calls made from a
//! spawned task are the cheapest: a call from the thread in `block_on` (where `#[tokio::main]`
//! runs `main`) waits for the reply to be handed over from a worker thread, as any tokio I/O
//! there does. The repository's `BENCHMARKS.md` has the figures.
//!
//! # Example
//!
//! A Grasping-Kit tells where the next part is; a WSG gripper pre-positions to the returned
//! stroke and grasps it. Both devices are simulated here; with real ones, only the addresses
//! change.
//!
//! ```
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use gripper::{smartgrasp, wsg};
//! use smartgrasp::{GetGraspOutcome, GraspFeedback, GraspMode, GraspRequest, PoseFormat, Tool};
//!
//! // The simulated Grasping-Kit's demo bin, and a WSG 50 with an 86 mm part to find.
//! let kit_sim = smartgrasp::sim::SimServer::bind("127.0.0.1:0", Default::default()).await?;
//! let wsg_config = wsg::sim::SimConfig::new(wsg::sim::Model::Wsg50).with_part(86.0, 2.0);
//! let wsg_sim = wsg::sim::SimServer::bind("127.0.0.1:0", wsg_config).await?;
//!
//! let kit = smartgrasp::Client::connect(kit_sim.local_addr(), Default::default()).await?;
//! let gripper = wsg::Client::connect_tcp(wsg_sim.local_addr().expect("a TCP address")).await?;
//! gripper.home(wsg::HomingDirection::Default).await?;
//!
//! let request = GraspRequest {
//!     grasp_mode: GraspMode::ActiveGrasp,
//!     object_class: 1,
//!     tool: Tool::Exterior,
//!     selection_criterion: smartgrasp::SelectionCriterion(1),
//!     pose_format: PoseFormat::Quaternion,
//! };
//! if let GetGraspOutcome::Grasp(grasp) = kit.get_grasp(request).await? {
//!     let stroke_mm = (grasp.stroke_m() * 1000.0) as f32;
//!     println!("grasp at {:?} m, stroke {stroke_mm} mm", grasp.pose.to_si()?.position_m);
//!     gripper.pre_position(stroke_mm + 10.0, 100.0).await?;
//!     gripper.grasp(stroke_mm, 50.0).await?;
//!     assert_eq!(gripper.grip_state().await?, wsg::GripState::Holding);
//!     gripper.release(stroke_mm + 10.0, 100.0).await?;
//!     kit.grasp_feedback(GraspFeedback::Ok).await?;
//! }
//! gripper.close().await?; // announces the disconnect, so the gripper does not FAST STOP
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod caller;
mod client_stream;
mod connection;
mod deadline;
pub mod error;
pub use error::ErrorKind;
/// Fault-injecting TCP proxy for tests (feature `sim`).
#[cfg(feature = "sim")]
pub mod fault;
mod give_up;
pub mod griplink;
mod int_map;
mod line;
mod queue;
/// Reconnecting after a lost connection: backoff policy and connection events, shared by the
/// `smartgrasp`, `griplink` and `wsg` clients (wsg over TCP and serial; UDP has no connection).
pub mod reconnect;
pub mod smartgrasp;
mod supervisor;
pub mod wsg;
