//! A simulated GRIPLINK controller (feature `sim`), for tests without hardware.
//!
//! - [`parse`]: the controller's command parser (pure);
//! - [`controller`]: the controller and device state machines (pure, time passed in), split
//!   by concern: devices and their default recipes, ports and state transitions, motion,
//!   held replies (WSTR, WAITVAL, blocking motions), command dispatch;
//! - [`SimServer`]: serves it over TCP, with fault injection ([`Fault`]).
//!
//! Simulated motion takes `distance / speed × time_scale` of wall time: use
//! [`SimConfig::time_scale`]`(0.0)` in tests so that motion costs no time (every motion is done
//! by the time the next command arrives), or a small scale to watch it move. WSTR and WAITVAL
//! timeouts are scaled the same way. The server uses tokio's clock, so it also runs under a
//! paused test clock.

mod config;
pub mod controller;
mod device;
mod dispatch;
mod motion;
mod moves;
pub mod parse;
mod port;
mod reply;
mod server;
#[cfg(test)]
mod tests;
mod wait;

// Inlined, so that this page lists them with their summaries.
#[doc(inline)]
pub use controller::{Controller, Role, SimConfig, SimDevice};
pub use server::{Fault, ReplyGate, SimExchange, SimServer};
