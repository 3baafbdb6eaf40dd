//! SCHUNK 2D Grasping-Kit "Smart Grasping" native protocol, V3 (manual seed 002) and V4: 80-byte
//! big endian frames over TCP, port 42001.
//!
//! # Two protocol versions
//!
//! V3 follows SCHUNK's manual. No V4 manual is public: the V4 layout ([`frame::v4`]) is read from
//! SCHUNK's own KUKA example (repository `SCHUNK-SE-Co-KG/SCHUNK_2DGrasping_Examples`, files
//! `KUKA-KRC/SCHUNK_GRASPINGKIT.src/.dat`, commit 57ade13 of 2025-06-11), as
//! `shared/PROTOCOLS.md` section 2b lists it: SET_TOOL (5) and SET_WORKSPACE (6) choose tool and
//! workspace by the ids configured on the device, GET_GRASP carries a selection criterion instead
//! of a tool, and its response a reference frame, an object offset and a two-axis centre offset.
//! What the example does not pin is kept raw ([`SelectionCriterion`], [`ReferenceFrame`], response
//! bytes 10–13, 68–71, 76–79) and documented as such, never given a meaning. GRASP_FEEDBACK has
//! no effect, by SCHUNK's own comments ("no effect in V4"; its V3 file: "Has no effect on
//! Version 3"); the simulator follows them unless told to take the object out on OK
//! (`sim::SimConfig::feedback_removes_objects`).
//!
//! [`Client::connect`] negotiates: GET_PROTOCOL_VERSION asked as V3 (every server since V3
//! answers it, manual 1.3 and 3.3.2.1), then the highest version both speak;
//! [`ClientConfig::protocol_version`] pins 3 or 4. One [`Request`], [`Response`] and [`Grasp`]
//! serve both versions, so cell code works with either: what only one version carries is an
//! `Option` in a response, and ignored by the other version in a request.
//!
//! Layers, each usable alone:
//! - [`frame`]: the 6-byte prefix and the 80-byte request/response frames of both versions, every
//!   field of the layout (pure);
//! - [`types`], [`message`], [`pose`]: the enumerations, typed requests and responses of the ten
//!   message types, and poses in the four formats with SI conversions (pure);
//! - [`codec`]: tokio-util codecs that read the prefix first and refuse any length but 74;
//! - [`Client`]: the async client, a cloneable handle to a task that owns the connection and checks
//!   every response (type, message type, response code, echoed fields; the response counter is
//!   recorded, and trusted only in [`ClientConfig::strict_response_counter`] mode);
//! - `sim` (feature `sim`): a simulated server.
//!
//! # Faults, cancellation and reconnecting
//!
//! Every call has a timeout and fails with a typed [`Error`]; the fault matrix
//! (`tests/smartgrasp_faults.rs`, through `gripper::fault::FaultProxy` framed with
//! [`codec::proxy_frame_len`]) pins down what each wire fault becomes. Dropping a call's future is safe
//! at any point (see [`Client`]: a request that was sent may still be acted on by the server).
//! With [`ClientConfig::reconnect`] the client reconnects after a lost connection and restores
//! registration and project; [`Client::connection_events`] reports it. [`Client::close`] ends the
//! connection for good (no reconnecting), and every later call fails with [`Error::Closed`].
//!
//! # Tolerance where the manual is silent
//!
//! Where the manual leaves room, the client records what it sees and goes on, rather than drop a
//! connection a real server may rightly use (each pinned in `tests/smartgrasp_tolerance.rs`):
//! - the response counter's scope is not specified (3.2.2.3; the examples 6.4 and 6.5 both show
//!   3): a gap is counted ([`Client::counter_gaps`]) and warned about, the call gets its response;
//!   [`ClientConfig::strict_response_counter`] trusts the counter instead;
//! - a response byte-identical to the previous one is an answer like any other: a server whose
//!   counter never moves (SCHUNK's KRL never reads it) or counts across its clients (the same
//!   value 256 responses later) sends them. Only in strict mode, where the counter is known to
//!   count this connection's responses, is an exact repeat a copy, and skipped (TCP itself never
//!   duplicates; a copy made by faulty equipment otherwise arrives unsolicited and breaks the
//!   connection, or, right before a call of the same type, is taken as its answer);
//! - a GET_OBJECT_COUNT answered as message type 17 (the manual's table, an erratum for 32) is
//!   read as a count;
//! - REGISTER_CLIENT is informational (3.3.2.3): its code is reported
//!   ([`Client::registration`]), not fatal to the connect;
//! - a server that stays connected but stops answering is given up
//!   [`ClientConfig::give_up_after`] past the call's own timeout (the configured one of its type,
//!   or [`Client::with_timeout`]'s), then reconnected to if configured.
//!
//! What V3 cannot detect, and so neither can this client: frames carry no checksum and
//! responses no request id. A corrupted byte that still reads as a valid value (a count, a pose
//! coordinate, a server state, a response code: SUCCESS turned NO_OBJECT looks like an empty bin)
//! reaches the caller. The client checks everything the protocol offers — prefix length and
//! version, communication and message type, the response counter, and the fields a response
//! repeats from its request — and closes the connection when they disagree. Over TCP such
//! corruption needs faulty equipment; a cell that must rule it out checks plausibility itself.
//! Without a request id, the reply to a request right behind one whose caller gave up could be
//! either's; the client sends a side-effect-free query of another type between them (only then),
//! so that a request lost on the wire (not something TCP does) or a late reply never shifts the
//! pairing.
//!
//! # Memory bounds
//!
//! Per client, whatever the server or the callers do:
//! - frames: the decoder holds at most one frame (80 bytes) beyond tokio-util's 8 KiB read
//!   buffer; it refuses any prefix length but 74 (and 0) before buffering a byte of it, so a
//!   hostile 4 GB length allocates nothing;
//! - requests in flight: at most 16 sent and unanswered (one 80-byte request and a reply slot
//!   each), plus the one marker query above; a server that stops answering gets no more, and
//!   is given up [`ClientConfig::give_up_after`] past the oldest call's timeout;
//! - request channel: at most 32 calls queued towards the connection task; further callers wait
//!   for room, each within its own timeout, and a call given up while queued is never sent;
//! - connection events: each [`Client::connection_events`] stream buffers at most 32 events; a
//!   reader further behind loses the oldest and gets a
//!   [`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed) in their place;
//! - session: the last REGISTER_CLIENT and SET_PROJECT request, one of each.
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
//!     RobotSystem, SelectionCriterion, Tool,
//! };
//!
//! // GRASP_FEEDBACK OK stands in for the robot taking the part out, so that the loop ends (a
//! // simulator option: SCHUNK's server ignores feedback, and the camera sees the bin empty).
//! let sim = SimConfig {
//!     feedback_removes_objects: true,
//!     ..SimConfig::default()
//! };
//! let server = SimServer::bind("127.0.0.1:0", sim).await?;
//! let config = ClientConfig {
//!     robot_system: Some(RobotSystem::Kuka),
//!     project_index: Some(0),
//!     ..ClientConfig::default()
//! };
//! let client = Client::connect(server.local_addr(), config).await?;
//! assert_eq!(client.protocol_version(), 4); // the simulator speaks V3 and V4
//! let request = GraspRequest {
//!     grasp_mode: GraspMode::AutoGrasp,
//!     object_class: 0,
//!     tool: Tool::Exterior,                          // V3: the tool of this grasp
//!     selection_criterion: SelectionCriterion(1),    // V4 (the tool is set with SET_TOOL)
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
mod malformed;
pub mod message;
pub mod pose;
#[cfg(feature = "sim")]
pub mod sim;
pub mod types;

#[doc(inline)]
pub use client::{Client, ClientConfig, GetGraspOutcome, DEFAULT_PORT};
#[doc(inline)]
pub use error::{Error, Malformed, Result};
#[doc(inline)]
pub use message::{
    Grasp, GraspRequest, ObjectCount, ObjectOffset, Request, RequestError, Response, ResponseBody,
};
#[doc(inline)]
pub use pose::{
    AbcPose, AxisAnglePose, Pose, PoseError, QuaternionPose, SiPose, UnitQuaternion, WprPose,
};
#[doc(inline)]
pub use types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ReferenceFrame,
    ResponseCode, RobotSystem, SelectionCriterion, ServerState, Tool,
};
