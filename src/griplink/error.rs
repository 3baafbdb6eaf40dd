//! The one error type of `griplink`.

use std::io;
use std::sync::Arc;
use std::time::Duration;

use super::status::Status;
use crate::ErrorKind;

/// `Result` with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// Everything that can go wrong talking to a GRIPLINK controller.
///
/// The variants keep apart who said no: the controller ([`Error::Device`]), the connection
/// ([`Error::Io`], [`Error::ConnectionLost`], [`Error::Closed`]), the clock ([`Error::Timeout`]), the
/// bytes on the wire ([`Error::MalformedReply`], [`Error::UnexpectedReply`]) and this crate
/// before anything was sent ([`Error::InvalidArgument`]). [`Error::kind`] classifies them the
/// same way as the other protocols' errors.
#[derive(Debug, Clone, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The controller answered `ERR <code>[ <text>]` (manual 2.4).
    #[error("{command} refused: {}", device_message(*status, text.as_deref()))]
    Device {
        /// The command line that was refused (without LF).
        command: String,
        /// The status code (manual chapter 4).
        status: Status,
        /// The description the controller sends in verbose mode (manual 3.1.7).
        text: Option<String>,
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
    /// The reply line is not valid GRIPLINK (or the codec had to discard it).
    #[error("malformed reply to {command}: {line:?}: {reason}")]
    MalformedReply {
        /// The command line.
        command: String,
        /// The reply line as received (empty if the codec discarded it).
        line: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A well-formed reply that does not answer the command (another key, port or index, or a
    /// value of the wrong type).
    #[error("unexpected reply to {command}: {line:?} (expected {expected})")]
    UnexpectedReply {
        /// The command line.
        command: String,
        /// The reply line.
        line: String,
        /// What was expected instead.
        expected: String,
    },
    /// Connecting failed (refused, or timed out), or reading or writing failed for another
    /// reason than the controller ending the connection.
    #[error("I/O error: {0}")]
    Io(#[source] Arc<io::Error>),
    /// The connection is closed by this side: `close()` was called, or every handle was
    /// dropped.
    #[error("the client was closed")]
    Closed,
    /// The connection was lost after it was open: the controller closed or reset it (possibly
    /// in the middle of a reply line), or the client gave up on it because the in-order pairing of
    /// replies can no longer be trusted (a reply stayed away far past its timeout, the
    /// controller stopped reading, or a reply did not answer its command while other commands
    /// were on the wire). Every later call gets it too, unless the client reconnects.
    #[error("connection lost: {reason}")]
    ConnectionLost {
        /// Why, as far as known.
        reason: Arc<str>,
    },
}

/// `ERR 19 E_STATE_CONFLICT: Invalid state`, plus the controller's own text when verbose mode
/// sent one that says more than the manual's description.
fn device_message(status: Status, text: Option<&str>) -> String {
    let mut s = format!("ERR {:02}", status.code());
    if let Some(ident) = status.identifier() {
        s.push(' ');
        s.push_str(ident);
    }
    s.push_str(&format!(": {status}"));
    if let Some(text) = text.filter(|t| !t.eq_ignore_ascii_case(&status.to_string())) {
        s.push_str(&format!(" (controller: {text})"));
    }
    s
}

impl Error {
    /// The controller's status code, if the controller refused the command.
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
            Error::InvalidArgument { .. } => ErrorKind::InvalidArgument,
            Error::Timeout { .. } => ErrorKind::Timeout,
            // A reply that does not answer its command is as untrustworthy as one that does
            // not parse.
            Error::MalformedReply { .. } | Error::UnexpectedReply { .. } => {
                ErrorKind::MalformedReply
            }
            Error::Io(e) => ErrorKind::of_io(e),
            Error::Closed => ErrorKind::Closed,
            Error::ConnectionLost { .. } => ErrorKind::ConnectionLost,
        }
    }

    pub(crate) fn lost(reason: impl Into<Arc<str>>) -> Error {
        Error::ConnectionLost {
            reason: reason.into(),
        }
    }

    pub(crate) fn invalid(what: &'static str, reason: impl Into<String>) -> Error {
        Error::InvalidArgument {
            what,
            reason: reason.into(),
        }
    }
}

impl From<io::Error> for Error {
    fn from(err: io::Error) -> Self {
        Error::Io(Arc::new(err))
    }
}
