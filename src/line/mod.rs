//! The line layer: what both LF line protocols share, GRIPLINK and the WSG text interface (GCL).
//! Neither protocol imports the other; both import this.
//!
//! - [`codec`]: LF-terminated lines as a tokio-util codec (public as `griplink::codec`).
//! - `client`: a line client's connection: opening it, sending a line within a time limit,
//!   reading lines, and the mapping of transport errors to the protocol's own error.
//! - `session`: a line task as the connection supervisor runs it.

mod client;
pub mod codec;
mod session;

pub(crate) use client::{io_error, peer_closed, Failure, LineConn, LineError, Opener};
pub(crate) use session::{restore_wait, run, LineLink, LineTask};
