//! A simulated GRIPLINK controller (feature `sim`), for tests without hardware.
//!
//! - [`parse`]: the controller's command parser (pure);
//! - [`controller`]: the controller and device state machines (pure, time passed in);
//! - [`SimServer`]: serves it over TCP, with fault injection ([`Fault`]).
//!
//! Simulated motion takes `distance / speed × time_scale` of wall time: use
//! [`SimConfig::time_scale`]`(0.0)` in tests so that motion costs no time (every motion is done
//! by the time the next command arrives), or a small scale to watch it move. The server uses
//! tokio's clock, so it also runs under a paused test clock.

pub mod controller;
pub mod parse;
mod server;

// Inlined, so that this page lists them with their summaries.
#[doc(inline)]
pub use controller::{Controller, Role, SimConfig, SimDevice};
pub use server::{Fault, ReplyGate, SimServer};
