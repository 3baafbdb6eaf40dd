// The links below name their targets in full: this module's docs are also rendered from the crate
// root (through the doc line on `mod fault` there), where the short paths are not in scope.
//! A fault-injecting TCP proxy, for tests: put it between a client and a server (a simulator or a
//! real device) and make the wire misbehave on purpose.
//!
//! [`FaultProxy::start`] listens on `127.0.0.1:0` and forwards every client connection to the
//! upstream address, both ways. Each direction ([`FaultProxy::client_to_server`],
//! [`FaultProxy::server_to_client`]) has its own [`Faults`], which a test changes while traffic
//! flows:
//!
//! - rules ([`Faults::add`]) that apply a [`Fault`] to frames: [`Delay`], [`Split`] into pieces
//!   flushed separately, [`Merge`] several frames into one write, [`Corrupt`] a byte, [`Drop`] a
//!   frame or [`DropBytes`] inside it, [`Duplicate`], [`Stall`], [`Cut`] the connection after
//!   some bytes of a frame;
//!   once ([`Fault::once`], [`Fault::nth`]) or persistently ([`Fault::always`], [`Fault::every`],
//!   [`Fault::randomly`], limited with [`Rule::times`]);
//! - a stall switch ([`Faults::stall`], [`Faults::release`], [`Faults::release_bytes`]);
//! - [`FaultProxy::cut_connections`] to pull the cable now.
//!
//! Every rule's [`FaultHandle`] counts how often it fired, so a test can assert that the fault it
//! meant to inject really happened ([`FaultHandle::wait_fired`]), and [`FaultProxy::stats`] /
//! [`FaultProxy::wait_for_stats`] let a test wait for the proxy to reach a state (a frame read, a
//! frame held at a stall) instead of sleeping.
//!
//! Frames are found by a [`Framing`]: [`Framing::Bytes`] (each read is a unit),
//! [`Framing::Delimited`] (GRIPLINK lines end in LF), [`Framing::FixedLength`] (SmartGrasp V3
//! frames are 80 bytes), or [`Framing::Custom`] with a function returning a [`FrameLen`]. Bytes
//! that are not a frame (garbage between frames, a frame over [`ProxyConfig::max_frame_len`]) are
//! forwarded untouched, so the proxy's memory stays bounded.
//! Randomness comes from a seeded xorshift generator ([`ProxyConfig::seed`]): runs are reproducible.
//!
//! The fault decisions are pure code (`plan.rs`, `framing.rs`), the sockets are in `proxy.rs`.
//!
//! [`FaultProxy::start`]: crate::fault::FaultProxy::start
//! [`FaultProxy::client_to_server`]: crate::fault::FaultProxy::client_to_server
//! [`FaultProxy::server_to_client`]: crate::fault::FaultProxy::server_to_client
//! [`Faults`]: crate::fault::Faults
//! [`Faults::add`]: crate::fault::Faults::add
//! [`Fault`]: crate::fault::Fault
//! [`Delay`]: crate::fault::Fault::Delay
//! [`Split`]: crate::fault::Fault::Split
//! [`Merge`]: crate::fault::Fault::Merge
//! [`Corrupt`]: crate::fault::Fault::Corrupt
//! [`Drop`]: crate::fault::Fault::Drop
//! [`DropBytes`]: crate::fault::Fault::DropBytes
//! [`Duplicate`]: crate::fault::Fault::Duplicate
//! [`Stall`]: crate::fault::Fault::Stall
//! [`Cut`]: crate::fault::Fault::Cut
//! [`Fault::once`]: crate::fault::Fault::once
//! [`Fault::nth`]: crate::fault::Fault::nth
//! [`Fault::always`]: crate::fault::Fault::always
//! [`Fault::every`]: crate::fault::Fault::every
//! [`Fault::randomly`]: crate::fault::Fault::randomly
//! [`Rule::times`]: crate::fault::Rule::times
//! [`Faults::stall`]: crate::fault::Faults::stall
//! [`Faults::release`]: crate::fault::Faults::release
//! [`Faults::release_bytes`]: crate::fault::Faults::release_bytes
//! [`FaultProxy::cut_connections`]: crate::fault::FaultProxy::cut_connections
//! [`FaultHandle`]: crate::fault::FaultHandle
//! [`FaultHandle::wait_fired`]: crate::fault::FaultHandle::wait_fired
//! [`FaultProxy::stats`]: crate::fault::FaultProxy::stats
//! [`FaultProxy::wait_for_stats`]: crate::fault::FaultProxy::wait_for_stats
//! [`Framing`]: crate::fault::Framing
//! [`Framing::Bytes`]: crate::fault::Framing::Bytes
//! [`Framing::Delimited`]: crate::fault::Framing::Delimited
//! [`Framing::FixedLength`]: crate::fault::Framing::FixedLength
//! [`Framing::Custom`]: crate::fault::Framing::Custom
//! [`FrameLen`]: crate::fault::FrameLen
//! [`ProxyConfig::max_frame_len`]: crate::fault::ProxyConfig::max_frame_len
//! [`ProxyConfig::seed`]: crate::fault::ProxyConfig::seed
//!
//! # Example
//!
//! Corrupt the second line a line server sends back, then check the next one is clean again.
//!
//! ```
//! use gripper::fault::{At, Fault, FaultProxy, Framing, ProxyConfig};
//! use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
//! use tokio::net::{TcpListener, TcpStream};
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> std::io::Result<()> {
//! // An echo server stands in for a simulator.
//! let server = TcpListener::bind("127.0.0.1:0").await?;
//! let upstream = server.local_addr()?;
//! tokio::spawn(async move {
//!     while let Ok((mut socket, _)) = server.accept().await {
//!         tokio::spawn(async move {
//!             let (mut read, mut write) = socket.split();
//!             let _ = tokio::io::copy(&mut read, &mut write).await;
//!         });
//!     }
//! });
//!
//! let config = ProxyConfig::new().framing(Framing::Delimited(b'\n'));
//! let proxy = FaultProxy::start_with(upstream, config).await?;
//! let corrupt = proxy
//!     .server_to_client()
//!     .add(Fault::Corrupt { at: At::Start(0), xor: 0x20 }.nth(2));
//!
//! let mut client = BufReader::new(TcpStream::connect(proxy.local_addr()).await?);
//! let mut line = String::new();
//! for (sent, expected) in [("ack\n", "ack\n"), ("ack\n", "Ack\n"), ("ack\n", "ack\n")] {
//!     client.get_mut().write_all(sent.as_bytes()).await?;
//!     line.clear();
//!     client.read_line(&mut line).await?;
//!     assert_eq!(line, expected);
//! }
//! assert_eq!(corrupt.fired(), 1);
//! assert!(!corrupt.is_active());
//! # Ok(())
//! # }
//! ```

mod framing;
mod plan;
mod proxy;

pub use framing::{FrameLen, Framing};
pub use plan::{At, Fault, Rule, When};
pub use proxy::{Direction, DirectionStats, FaultHandle, FaultProxy, Faults, ProxyConfig, Stats};
