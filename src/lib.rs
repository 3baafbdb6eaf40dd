//! # gripper
//!
//! Async clients and device simulators for the grippers and grasp planners of a robot cell:
//!
//! - [`wsg`]: Weiss WSG grippers' binary protocol (CRC-framed, over TCP, UDP and serial).
//! - [`smartgrasp`]: the SCHUNK 2D Grasping-Kit native protocol V3 (80-byte frames over TCP).
//! - [`griplink`]: Weiss GRIPLINK controllers' ASCII command set (LF-terminated lines over TCP).
//!
//! Every protocol has the same layers: pure encode/decode (no I/O), a tokio-util codec, an async
//! client whose connection is owned by a background task (the handle is cheap to clone and safe to
//! share between tasks), and — behind the default-on `sim` feature — a simulator that behaves like
//! the device, for tests that run without hardware.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

/// Fault-injecting TCP proxy for tests (feature `sim`).
#[cfg(feature = "sim")]
pub mod fault;
pub mod griplink;
/// Reconnecting after a lost connection: backoff policy and connection events, for every client.
pub mod reconnect;
pub mod smartgrasp;
pub mod wsg;
