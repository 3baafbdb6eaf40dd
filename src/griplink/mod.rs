//! Weiss GRIPLINK Unified Command Set (protocol version 3): ASCII lines over TCP, for
//! GRIPLINK-ET4 controllers, WPG and INTRAPAL grippers and the IO-Link devices behind them.
//!
//! Layers, each usable alone:
//! - [`command`]: every command of the manual as a typed [`Command`], encoded to one line with
//!   every argument checked first (no scientific notation, no NaN, no quote or newline inside a
//!   string: nothing can inject a second command);
//! - [`reply`]: reply lines parsed and checked against the command they answer;
//! - [`codec`]: the LF line codec;
//! - [`client`]: the async [`Client`] (a background task owns the connection; replies are paired
//!   with commands strictly in order; every call has a timeout) and the per-port [`Port`] handle;
//! - [`sim`] (feature `sim`): a simulated controller serving TCP.
//!
//! Status codes ([`Status`], manual chapter 4) are not the WSG codes.
//!
//! Faults on the wire (lost, duplicated, corrupted, cut lines), cancelled calls and what
//! cannot be detected are described in the [`client`] module docs.
//!
//! # Memory bounds
//! Nothing a peer sends and nothing a slow caller does makes this module's memory grow without
//! limit:
//! - **Reply lines** ([`ClientConfig::max_line_len`], default 1024 bytes): the codec buffers at
//!   most that many bytes of an unfinished line plus one socket read; a longer line is skipped
//!   up to its LF without being buffered and fails its call with [`Error::MalformedReply`].
//! - **Command lines**: at most `max_line_len` bytes; a longer one (possible only through
//!   [`Client::command`]) is refused with [`Error::InvalidArgument`] before anything is sent.
//!   Typed commands are far shorter (strings are limited to 32 characters, float arguments to
//!   [`command::MAX_FLOAT_ARG_LEN`] characters).
//! - **Commands on the wire** ([`ClientConfig::pipeline_depth`], default 1): each holds its line
//!   and its caller's reply channel; a resynchronisation probe takes one of these places.
//! - **Queued calls** ([`ClientConfig::queue_len`], default 64): a bounded channel to the
//!   connection's task; more callers wait (each in its own future, within its own timeout) to
//!   enter it. A queued call whose caller gave up is dropped, never sent. While a lost
//!   connection is being restored ([`ClientConfig::reconnect`]) calls wait the same way.
//! - **Polling streams** ([`Port::watch_state`], [`Port::watch_value`]): one reading buffered in
//!   the stream and at most one more waiting to be put there; the poller then waits for the
//!   consumer instead of polling, so a slow consumer slows the polling. Readings it did not
//!   take are never made (no backlog): the next reading it gets may be as old as its own pause.
//! - **Connection events** ([`Client::connection_events`]): at most 32 buffered per stream; a
//!   reader that falls further behind loses the oldest and is told how many
//!   ([`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed)).
//! - **Simulator** ([`sim`]): per connection, one command line of at most 1024 bytes (longer:
//!   `ERR 01`) and one reply; the fault queue holds what the test injected.
//!
//! # Where the manual and the field may differ
//!
//! The manual's `VALUEF` example answers with the `VALUE` key (`VALUE[0][0]=42.456`; PROTOCOLS.md,
//! GRIPLINK errata). The client accepts that key for `VALUEF` only with a fraction (or `±INF`):
//! an integer `VALUE` line is the reply of a `VALUE` query (µm), and taken for a `VALUEF` reply
//! (mm) behind a lost reply it was a reading a thousand times too large. A firmware that prints
//! a whole `VALUEF` reading without a fraction *and* under the `VALUE` key gets
//! [`Error::UnexpectedReply`] for it rather than a value that may be wrong.
//!
//! # Example
//! ```
//! # #[cfg(feature = "sim")]
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use std::time::Duration;
//! use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
//! use gripper::griplink::{Client, DeviceState, GripConfigF, GripOutcome, WaitBy};
//!
//! // A GRIPLINK-ET4 whose IEG 55-020 on port 0 has a 12 mm part between its fingers;
//! // time scale 0: motion takes no time.
//! let config = SimConfig::et4()
//!     .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
//!     .time_scale(0.0);
//! let server = SimServer::bind("127.0.0.1:0", config).await?;
//!
//! let client = Client::connect(server.local_addr()).await?;
//! assert_eq!(client.id().await?, "GRIPLINK-ET4");
//! client.protocol_assert("GRIPLINK", 3).await?;
//!
//! let gripper = client.port(0);
//! assert_eq!(gripper.vendor_id().await?, Some(815));
//! gripper.home().await?;
//! // Recipe 1: no-part limit 5 mm, release limit 18 mm, 50 % force.
//! gripper.set_grip_config_f(1, &GripConfigF::gripper("part", 5.0, 18.0, 50.0)).await?;
//! let outcome = gripper.grip_and_wait(1, WaitBy::Polling(Duration::from_millis(10))).await?;
//! assert_eq!(outcome, GripOutcome::Holding);
//! assert_eq!(gripper.position_mm().await?, 12.0);
//! gripper.release_and_wait(1, WaitBy::Transition).await?;
//! assert_eq!(gripper.state().await?, DeviceState::Released);
//! client.close().await?;
//! # Ok(()) }
//! # #[cfg(not(feature = "sim"))]
//! # fn main() {}
//! ```
pub mod client;
pub use crate::line::codec;
pub mod command;
pub mod error;
pub mod reply;
#[cfg(feature = "sim")]
pub mod sim;
pub mod state;
pub mod status;
pub mod value;

// Inlined: the module page lists them with their summaries (`client` stays public for its
// docs on timeouts, replies out of step and cancellation).
#[doc(inline)]
pub use client::{Client, ClientConfig, Port, DEFAULT_PORT};
#[doc(inline)]
pub use client::{GripOutcome, ReleaseOutcome, WaitBy, Watch};
#[doc(inline)]
pub use command::{
    Blocking, Command, FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled, GripConfig,
    GripConfigF, PortNumber, MAX_PORT,
};
#[doc(inline)]
pub use error::{Error, Result};
#[doc(inline)]
pub use reply::Answer;
#[doc(inline)]
pub use state::DeviceState;
#[doc(inline)]
pub use status::Status;
