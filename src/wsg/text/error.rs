//! The one error type of `wsg::text`.

use std::io;
use std::sync::Arc;
use std::time::Duration;

use crate::wsg::Status;
use crate::ErrorKind;

/// `Result` with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// Everything that can go wrong talking GCL to a WSG.
///
/// The variants keep apart who said no: the gripper ([`Error::Device`]), the connection
/// ([`Error::Io`], [`Error::ConnectionLost`], [`Error::Closed`]), the clock ([`Error::Timeout`]),
/// the bytes on the wire ([`Error::MalformedReply`], [`Error::UnexpectedReply`]) and this crate
/// before anything was sent ([`Error::InvalidArgument`]). [`Error::kind`] classifies them the
/// same way as the other protocols' errors.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The gripper answered `ERR` to the command.
    #[error("{command} refused: {line:?}{}", status.map(|s| format!(" ({s})")).unwrap_or_default())]
    Device {
        /// The command line (without LF).
        command: String,
        /// The numeral code read with the WSG binary protocol's table, when the line carries
        /// one. That GCL uses the binary table is our reading (shared note §4.3): the line is
        /// kept whole in `line`.
        status: Option<Status>,
        /// The `ERR …` line as received.
        line: String,
    },
    /// An argument was refused before anything was sent.
    #[error("invalid {what}: {reason}")]
    InvalidArgument {
        /// Which argument.
        what: &'static str,
        /// Why.
        reason: String,
    },
    /// No reply within the call's timeout. The connection stays usable: the late reply is
    /// consumed and discarded when it comes.
    #[error("no reply to {command} within {timeout:?}")]
    Timeout {
        /// The command line.
        command: String,
        /// The timeout that expired.
        timeout: Duration,
    },
    /// A reply with the command's name that is not GCL or not a number where one is due; or a
    /// reply that could not be read at all (damaged, `ERR` without a name): the client then
    /// probes with a query, and a command answered at once that is still unanswered when a
    /// command written later is answered lost its reply to that line (the gripper answers in
    /// order), whatever its timeout, even `Duration::MAX`.
    #[error("malformed reply to {command}: {line:?}: {reason}")]
    MalformedReply {
        /// The command line.
        command: String,
        /// The reply line as received.
        line: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A reply with the command's name but of the wrong form (`ACK` for a query, a value for a
    /// motion).
    #[error("unexpected reply to {command}: {line:?}")]
    UnexpectedReply {
        /// The command line.
        command: String,
        /// The reply line.
        line: String,
    },
    /// The connection was lost (closed by the gripper, reset, or given up by this client
    /// because a reply stayed away far beyond its timeout).
    #[error("connection lost: {reason}")]
    ConnectionLost {
        /// Why, as far as known.
        reason: Arc<str>,
    },
    /// The connection was closed by this client ([`Client::close`](super::Client::close) or
    /// every handle dropped).
    #[error("the client was closed")]
    Closed,
    /// An I/O error of the socket.
    #[error("I/O error: {0}")]
    Io(#[source] Arc<io::Error>),
}

impl From<io::Error> for Error {
    fn from(e: io::Error) -> Self {
        Error::Io(Arc::new(e))
    }
}

impl Error {
    /// The gripper's status code, for [`Error::Device`] with a numeral code.
    pub fn status(&self) -> Option<Status> {
        match self {
            Error::Device { status, .. } => *status,
            _ => None,
        }
    }

    /// What kind of failure this is, in the classification every protocol shares.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Device { .. } => ErrorKind::Device,
            Error::InvalidArgument { .. } => ErrorKind::InvalidArgument,
            Error::Timeout { .. } => ErrorKind::Timeout,
            // A reply of the wrong form is as untrustworthy as one that does not parse.
            Error::MalformedReply { .. } | Error::UnexpectedReply { .. } => {
                ErrorKind::MalformedReply
            }
            Error::ConnectionLost { .. } => ErrorKind::ConnectionLost,
            Error::Closed => ErrorKind::Closed,
            Error::Io(e) => ErrorKind::of_io(e),
        }
    }

    pub(crate) fn lost(reason: impl Into<Arc<str>>) -> Error {
        Error::ConnectionLost {
            reason: reason.into(),
        }
    }

    pub(crate) fn invalid(what: &'static str, reason: impl Into<String>) -> Self {
        Error::InvalidArgument {
            what,
            reason: reason.into(),
        }
    }
}
