//! The one error type of `smartgrasp`, keeping apart: the server said no, the server is too old,
//! a response was lost, a malformed reply, I/O, a lost or closed connection, timeout, and
//! arguments refused before sending.

use std::sync::Arc;
use std::time::Duration;

use super::message::RequestError;
use super::pose::PoseError;
use super::types::{MessageType, ResponseCode, ServerState};
// `Malformed` has a room of its own, below `message` (which decodes responses into it) and this
// file (whose `Error` wraps it); it is re-exported here, where it has always been public.
#[doc(inline)]
pub use super::malformed::Malformed;
use crate::ErrorKind;

/// Result of this module.
pub type Result<T> = std::result::Result<T, Error>;

/// Everything that can go wrong talking to a Smart Grasping server.
///
/// The variants keep apart who said no: the server ([`Error::Device`], [`Error::ServerTooOld`],
/// [`Error::NotOperational`]), the connection ([`Error::Io`], [`Error::ConnectionLost`],
/// [`Error::Closed`], [`Error::ResponseLost`]), the clock ([`Error::Timeout`]), the bytes on the
/// wire ([`Error::MalformedReply`]) and this crate before anything was sent
/// ([`Error::InvalidArgument`], [`Error::Pose`]). [`Error::kind`] classifies them the same way
/// as the other protocols' errors.
///
/// `Clone`, so the reason a connection broke can be handed to every call that was waiting on it.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The server answered with a response code other than SUCCESS where the call has no typed
    /// outcome for it (see [`GetGraspOutcome`](super::GetGraspOutcome) for the grasp call's).
    #[error("the server refused {message_type}: {status}")]
    Device {
        /// The request's message type.
        message_type: MessageType,
        /// The response code the server sent.
        status: ResponseCode,
    },
    /// The server speaks an older protocol version: it answered with an empty message (manual
    /// 1.3), or GET_PROTOCOL_VERSION reported a version below 3, or below the version the
    /// configuration pins ([`ClientConfig::protocol_version`](super::ClientConfig::protocol_version)).
    /// The connection is closed.
    #[error("the server is too old: it speaks protocol v{server_version}, this client needs v{client_version}")]
    ServerTooOld {
        /// The highest version the server supports.
        server_version: u16,
        /// The version this client speaks.
        client_version: u16,
    },
    /// The opening sequence found the server in a state other than OPERATIONAL.
    #[error("the server is not operational: {state}")]
    NotOperational {
        /// The state GET_STATE reported.
        state: ServerState,
    },
    /// A response was lost: the server answered a later request, and the counter skipped
    /// (manual 3.2.2.3). The call that was waiting for it gets this error instead of someone
    /// else's answer. By default a counter gap alone is only recorded
    /// ([`Client::counter_gaps`](super::Client::counter_gaps)); this error needs the response
    /// to fit a later request and not this one, or
    /// [`ClientConfig::strict_response_counter`](super::ClientConfig::strict_response_counter).
    #[error(
        "a response was lost: expected response counter {expected}, the server sent {received}"
    )]
    ResponseLost {
        /// The counter the next response should have carried.
        expected: u8,
        /// The counter it carried.
        received: u8,
    },
    /// No response within the call's timeout. The request's slot is kept: its late reply will be
    /// consumed and discarded.
    #[error("no response to {message_type} within {timeout:?}")]
    Timeout {
        /// The request's message type.
        message_type: MessageType,
        /// The timeout that ran out.
        timeout: Duration,
    },
    /// The server sent something the protocol does not allow.
    #[error("malformed reply: {0}")]
    MalformedReply(#[from] Malformed),
    /// Reading from or writing to the socket failed, or connecting failed.
    #[error("I/O error: {0}")]
    Io(#[source] Arc<std::io::Error>),
    /// The connection was lost: the server closed it, it stopped reading requests, or an earlier
    /// error broke it. Without [`ClientConfig::reconnect`](super::ClientConfig::reconnect) (or
    /// once its policy gave up) every later call gets this too.
    #[error("connection lost: {reason}")]
    ConnectionLost {
        /// Why, as far as known.
        reason: Arc<str>,
    },
    /// The client was closed with [`Client::close`](super::Client::close); later calls on any
    /// clone get this too.
    #[error("the client was closed")]
    Closed,
    /// The request cannot be sent in the protocol version the connection speaks: a V4-only
    /// message (SET_TOOL, SET_WORKSPACE) to a V3 server, or a value V4 cannot carry (a
    /// quaternion pose, a project number over 65535). Nothing was sent.
    #[error("cannot send: {0}")]
    Request(#[from] RequestError),
    /// An argument was refused before anything was sent.
    #[error("invalid {what}: {reason}")]
    InvalidArgument {
        /// Which argument.
        what: &'static str,
        /// Why.
        reason: String,
    },
    /// A pose could not be converted.
    #[error("pose: {0}")]
    Pose(#[from] PoseError),
}

impl Error {
    /// The server's response code, if the server refused the request ([`Error::Device`]).
    pub fn status(&self) -> Option<ResponseCode> {
        match self {
            Error::Device { status, .. } => Some(*status),
            _ => None,
        }
    }
}

impl Error {
    /// What kind of failure this is, in the classification every protocol shares.
    pub fn kind(&self) -> ErrorKind {
        match self {
            // The server's state is its answer that it cannot serve the call.
            Error::Device { .. } | Error::NotOperational { .. } => ErrorKind::Device,
            Error::ServerTooOld { .. } => ErrorKind::Incompatible,
            Error::ResponseLost { .. } => ErrorKind::ReplyLost,
            Error::Timeout { .. } => ErrorKind::Timeout,
            Error::MalformedReply(_) => ErrorKind::MalformedReply,
            Error::Io(e) => ErrorKind::of_io(e),
            Error::ConnectionLost { .. } => ErrorKind::ConnectionLost,
            Error::Closed => ErrorKind::Closed,
            // Nothing was sent: the request (or its pose) cannot be put on the wire.
            Error::Request(_) | Error::InvalidArgument { .. } | Error::Pose(_) => {
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
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::Io(Arc::new(e))
    }
}
