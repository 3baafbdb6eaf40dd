//! Weiss GRIPLINK Unified Command Set (protocol version 3): ASCII lines over TCP.
pub mod codec;
pub mod command;
pub mod error;
pub mod reply;
pub mod state;
pub mod status;
pub mod value;

pub use command::{Blocking, Command, PortNumber};
pub use error::{Error, Result};
pub use state::DeviceState;
pub use status::Status;
