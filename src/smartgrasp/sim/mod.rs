//! A simulated Smart Grasping server, for tests without hardware (feature `sim`).
//!
//! [`SimServer`] serves protocols V4 and V3 over TCP from a pure state machine ([`SimState`]),
//! each request in the layout and with the version it used (manual 1.3; [`SimConfig::max_version`]
//! 3 makes it a V3-only server that answers V4 with the "too old" empty message):
//! projects, each a scene of objects with class ids and grasp definitions; GET_GRASP in any pose
//! format with NO_OBJECT / NO_GRASP / INVALID_OBJECT_CLASS when they apply; GRASP_FEEDBACK
//! answered SUCCESS with no effect, as SCHUNK's examples say it has none (or, with
//! [`SimConfig::feedback_removes_objects`], taking the object out of the scene on OK, for picking
//! loops against the simulator); REGISTER_CLIENT and ROBOT_POSE recorded; a response counter per
//! connection that wraps (configurable start); a configurable highest protocol version; V4's tools and
//! workspaces by id; and [`Fault`]s to inject. Nothing in it moves, so it costs no wall time,
//! except a [`Fault::DelayReply`] a test asks for.
//!
//! [`SimServer::serve_monitor`] serves a picture of the scene ([`scene_svg`]) over HTTP at the
//! path where the real kit serves its latest detection result.

mod http;
mod scene_svg;
mod server;
mod state;

pub use http::{MonitorServer, MAX_REQUEST_BYTES, MONITOR_PATH, REQUEST_TIMEOUT};
pub use scene_svg::scene_svg;

pub use server::{SimExchange, SimServer};
pub use state::{
    parse_request, Action, Fault, SimConfig, SimConnection, SimGrasp, SimObject, SimProject,
    SimState, RECORD_LIMIT,
};
