//! The one error type of [`crate::wsg`].

use std::time::Duration;

use super::{Status, UpdateOptions};

/// Everything a WSG call can fail with.
///
/// The variants keep apart: the device said no ([`Error::Device`], with its status code), the
/// connection ([`Error::Io`], [`Error::ConnectionLost`], [`Error::Closed`]), no answer in time
/// ([`Error::Timeout`]), a reply that does not parse ([`Error::MalformedReply`]), and arguments
/// refused before anything was sent ([`Error::InvalidArgument`],
/// [`Error::SubscriptionConflict`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The device answered the command with a status other than E_SUCCESS.
    #[error("device answered command {command:#04x} with {status}")]
    Device {
        /// The command id.
        command: u8,
        /// The status code of the (final) reply.
        status: Status,
    },
    /// Opening or configuring the transport failed.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The connection broke: the call was in progress, or the client had already lost its
    /// connection (every later call gets this too).
    #[error("connection to the gripper lost: {0}")]
    ConnectionLost(String),
    /// The client was closed with [`Client::close`](super::Client::close).
    #[error("the client was closed")]
    Closed,
    /// No (final) reply arrived within the call's timeout.
    #[error("no reply to command {command:#04x} within {timeout:?}")]
    Timeout {
        /// The command id.
        command: u8,
        /// The timeout that elapsed.
        timeout: Duration,
    },
    /// The device acknowledged the motion command (E_CMD_PENDING, manual 1.3), then said twice,
    /// a late-reply grace apart, that the fingers do not move, and its final reply never came:
    /// it was lost on the wire. What the command achieved is unknown; query the state (e.g.
    /// the width or the grip state).
    #[error("the final reply to command {command:#04x} was lost (the device no longer moves)")]
    ReplyLost {
        /// The command id.
        command: u8,
    },
    /// A reply arrived but its data does not have the documented layout.
    #[error("malformed reply to command {command:#04x}: {reason}")]
    MalformedReply {
        /// The command id.
        command: u8,
        /// What is wrong with it.
        reason: String,
    },
    /// The arguments were refused before sending (out of the protocol's range).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A subscription asked for other update options than the value's stream already has.
    /// The device sends one stream per value (manual 3.4.1), so serving the new options would
    /// change the stream under the subscribers it has: subscribe with `active`, or drop the
    /// other subscriptions first.
    #[error("command {command:#04x} is already streamed with {active:?}")]
    SubscriptionConflict {
        /// The command id of the value.
        command: u8,
        /// The options the stream runs with.
        active: UpdateOptions,
    },
}

impl Error {
    /// The device's status code, if the device answered with an error.
    pub fn status(&self) -> Option<Status> {
        match self {
            Error::Device { status, .. } => Some(*status),
            _ => None,
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
