//! One classification of every protocol's errors: [`ErrorKind`].
//!
//! Each protocol keeps its own error enum ([`wsg::Error`](crate::wsg::Error),
//! [`wsg::text::Error`](crate::wsg::text::Error), [`griplink::Error`](crate::griplink::Error),
//! [`smartgrasp::Error`](crate::smartgrasp::Error)), because what a call failed *on* is the
//! protocol's own (a command id, a command line, a message type; a status code from the
//! protocol's table). What a caller *does* about it is the same for all of them: report the
//! device's refusal, retry after a timeout, reconnect after a lost connection, fix the argument.
//! `kind()` on each of them answers that question once, so tools (the Python package, `gripctl`,
//! the ROS 2 node) do not each match on four enums.
//!
//! The variants the four enums share have one shape and one message in all of them, so that a
//! caller who matches on one protocol's error can match on another's the same way:
//!
//! | variant | shape | message |
//! |---|---|---|
//! | `InvalidArgument` | `{ what: &'static str, reason: String }` | `invalid {what}: {reason}` |
//! | `Io` | `(Arc<std::io::Error>)`, also its `source()` | `I/O error: {0}` |
//! | `ConnectionLost` | `{ reason: Arc<str> }` | `connection lost: {reason}` |
//! | `Closed` | unit | `the client was closed` |
//!
//! Why these shapes: `what` names the argument for a program and `reason` tells a person what
//! was wrong with its value (both were needed to keep every message informative); the errors are
//! `Clone`, because the one reason a connection broke is handed to every call that was waiting
//! on it, and `std::io::Error` is not `Clone`, hence the `Arc`; `Arc<str>` makes that hand-out a
//! reference count, not a copy per waiter.

/// What kind of failure an error of any protocol is: what the caller can do about it.
///
/// Every protocol's `Error` has a `kind()`; the device's own code, the command and the timeout
/// stay in the protocol's error. New kinds may be added (hence `#[non_exhaustive]`): a match
/// should treat an unknown kind like [`ErrorKind::Io`], a failure of the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device answered and refused: an error status (WSG, GRIPLINK, the GCL text
    /// interface), a response code other than SUCCESS, or a SmartGrasp server that is not
    /// OPERATIONAL. The code is in the protocol's error (its `status()`).
    Device,
    /// The device speaks a protocol version this client cannot use (a SmartGrasp server older
    /// than V3, or older than the version the configuration pins). Reconnecting does not help.
    Incompatible,
    /// No answer in time: a call's reply did not come within its timeout (the connection stays
    /// usable, the late reply is discarded), or connecting did not finish within the connect
    /// timeout.
    Timeout,
    /// The device accepted the request but its answer was lost on the wire (a WSG final reply
    /// after E_CMD_PENDING, a SmartGrasp response the counter skipped): what the request
    /// achieved is unknown; query the device's state.
    ReplyLost,
    /// A reply arrived that the protocol does not allow, or that does not answer the request
    /// it was paired with.
    MalformedReply,
    /// The call was refused before anything was sent: an argument out of the protocol's range,
    /// a request the connection's protocol version cannot carry, a subscription that clashes
    /// with a running stream.
    InvalidArgument,
    /// Connecting, or reading or writing the transport, failed (refused, unreachable, reset, no
    /// such serial port).
    Io,
    /// The connection was lost after it was open (closed or reset by the device, or given up by
    /// the client because the pairing of replies could no longer be trusted). Every later call
    /// gets it too, unless the client reconnects.
    ConnectionLost,
    /// The client was closed by this side (`close()`, or every handle dropped).
    Closed,
}

impl ErrorKind {
    /// Whether the client has no connection any more ([`ErrorKind::ConnectionLost`] or
    /// [`ErrorKind::Closed`]): every later call fails the same way (until a reconnect), so
    /// closing such a client has nothing left to do.
    pub fn is_disconnected(self) -> bool {
        matches!(self, ErrorKind::ConnectionLost | ErrorKind::Closed)
    }

    /// Whether the link failed rather than the device or the request ([`ErrorKind::Io`],
    /// [`ErrorKind::ConnectionLost`], [`ErrorKind::Closed`]): a stream of readings ends here.
    pub fn is_transport(self) -> bool {
        matches!(
            self,
            ErrorKind::Io | ErrorKind::ConnectionLost | ErrorKind::Closed
        )
    }

    /// A short lowercase name, stable for logs and machine-readable output (`"device"`,
    /// `"timeout"`, `"connection_lost"`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorKind::Device => "device",
            ErrorKind::Incompatible => "incompatible",
            ErrorKind::Timeout => "timeout",
            ErrorKind::ReplyLost => "reply_lost",
            ErrorKind::MalformedReply => "malformed_reply",
            ErrorKind::InvalidArgument => "invalid_argument",
            ErrorKind::Io => "io",
            ErrorKind::ConnectionLost => "connection_lost",
            ErrorKind::Closed => "closed",
        }
    }

    /// The kind of an [`std::io::Error`] carried by a protocol's `Io` variant: a connect that
    /// ran out of its time is a [`ErrorKind::Timeout`] (the clients report the connect timeout
    /// as [`std::io::ErrorKind::TimedOut`]), anything else [`ErrorKind::Io`].
    pub(crate) fn of_io(e: &std::io::Error) -> ErrorKind {
        if e.kind() == std::io::ErrorKind::TimedOut {
            ErrorKind::Timeout
        } else {
            ErrorKind::Io
        }
    }
}

impl std::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::ErrorKind::{self, *};

    const ALL: [ErrorKind; 9] = [
        Device,
        Incompatible,
        Timeout,
        ReplyLost,
        MalformedReply,
        InvalidArgument,
        Io,
        ConnectionLost,
        Closed,
    ];

    #[test]
    fn the_helpers_pick_the_documented_kinds() {
        let disconnected: Vec<_> = ALL.into_iter().filter(|k| k.is_disconnected()).collect();
        assert_eq!(disconnected, [ConnectionLost, Closed]);
        let transport: Vec<_> = ALL.into_iter().filter(|k| k.is_transport()).collect();
        assert_eq!(transport, [Io, ConnectionLost, Closed]);
    }

    #[test]
    fn names_are_distinct_and_displayed() {
        let mut names: Vec<_> = ALL.iter().map(|k| k.as_str()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), ALL.len());
        assert_eq!(ConnectionLost.to_string(), "connection_lost");
    }

    #[test]
    fn a_timed_out_io_error_is_a_timeout_any_other_is_io() {
        let e = |kind| std::io::Error::new(kind, "x");
        assert_eq!(ErrorKind::of_io(&e(std::io::ErrorKind::TimedOut)), Timeout);
        assert_eq!(
            ErrorKind::of_io(&e(std::io::ErrorKind::ConnectionRefused)),
            Io
        );
    }
}
