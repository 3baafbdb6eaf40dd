//! An in-process WSG gripper that speaks the binary protocol over TCP, UDP, a serial
//! pseudo-terminal or any byte stream (feature `sim`, on by default).
//!
//! [`device`] is the pure state machine (homing, moves with trapezoidal profiles within the
//! model's limits, the grip states of Anhang C, stop and FAST STOP, soft limits, force,
//! overdrive, auto-updates, tag, statistics, finger interface); [`SimServer`] serves it.
//!
//! Simulated motion costs no wall time with [`SimConfig::time_scale`] = 0 (the default): a move's
//! final reply follows its E_CMD_PENDING at once. Give it a large scale (e.g. 1000) to have a move
//! still running when a stop arrives.

mod commands;
pub mod device;
mod model;
mod motion;
mod server;
mod sessions;

// Inlined, so that this page lists them with their summaries.
#[doc(inline)]
pub use device::{Device, Out, SessionId, SessionKind};
pub use model::{Model, Part, SimConfig, SimFinger, DEFAULT_UDP_IDLE_TIMEOUT};
pub use server::{SimServer, SimSnapshot};
pub use sessions::MIN_UPDATE_PERIOD_MS;
