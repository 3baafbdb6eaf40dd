//! The one error type of [`crate::wsg`].

use std::sync::Arc;
use std::time::Duration;

use super::{Status, UpdateOptions};
use crate::ErrorKind;

/// Everything a WSG call can fail with.
///
/// The variants keep apart: the device said no ([`Error::Device`], with its status code), the
/// connection ([`Error::Io`], [`Error::ConnectionLost`], [`Error::Closed`]), no answer in time
/// ([`Error::Timeout`]), a reply that does not parse ([`Error::MalformedReply`]), and arguments
/// refused before anything was sent ([`Error::InvalidArgument`],
/// [`Error::SubscriptionConflict`]). [`Error::kind`] classifies them the same way as the other
/// protocols' errors.
///
/// `Clone`, so the reason a connection broke can be handed to every call that was waiting on it.
#[derive(Debug, Clone, thiserror::Error)]
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
    /// Opening or configuring the transport failed (a connect that ran out of its timeout is
    /// an error of kind [`std::io::ErrorKind::TimedOut`]).
    #[error("I/O error: {0}")]
    Io(#[source] Arc<std::io::Error>),
    /// The connection broke: the call was in progress, or the client had already lost its
    /// connection (every later call gets this too).
    #[error("connection lost: {reason}")]
    ConnectionLost {
        /// Why, as far as known.
        reason: Arc<str>,
    },
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
    #[error("invalid {what}: {reason}")]
    InvalidArgument {
        /// Which argument.
        what: &'static str,
        /// Why.
        reason: String,
    },
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

    /// What kind of failure this is, in the classification every protocol shares.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Device { .. } => ErrorKind::Device,
            Error::Io(e) => ErrorKind::of_io(e),
            Error::ConnectionLost { .. } => ErrorKind::ConnectionLost,
            Error::Closed => ErrorKind::Closed,
            Error::Timeout { .. } => ErrorKind::Timeout,
            Error::ReplyLost { .. } => ErrorKind::ReplyLost,
            Error::MalformedReply { .. } => ErrorKind::MalformedReply,
            // Refused before sending, as an out-of-range argument is: the caller changes the
            // options (or drops the other subscriptions) and asks again.
            Error::InvalidArgument { .. } | Error::SubscriptionConflict { .. } => {
                ErrorKind::InvalidArgument
            }
        }
    }

    pub(crate) fn invalid(what: &'static str, reason: impl Into<String>) -> Error {
        Error::InvalidArgument {
            what,
            reason: reason.into(),
        }
    }

    pub(crate) fn lost(reason: impl Into<Arc<str>>) -> Error {
        Error::ConnectionLost {
            reason: reason.into(),
        }
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::Io(Arc::new(e))
    }
}

/// `Result` with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
