//! What a reply can break: [`Malformed`], the decoding error of a response and of its pairing
//! with its request. Its own room, below both the typed messages (`message.rs` decodes responses
//! into it) and the module's error (`error.rs` wraps it in [`Error::MalformedReply`]), so that
//! neither of those imports the other both ways.
//!
//! [`Error::MalformedReply`]: super::Error::MalformedReply

use super::pose::PoseError;
use super::types::{CommunicationType, MessageType};

/// A reply that breaks the protocol's rules.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Malformed {
    /// The prefix's length field is neither 74 (a V3 or V4 frame) nor 0 (the "too old" answer). The
    /// stream cannot be resynchronised, so the connection is reported broken; the length is not
    /// allocated.
    #[error("frame length {length} (a V3 or V4 frame has 74 bytes after the prefix)")]
    FrameLength {
        /// The length field as received.
        length: u32,
    },
    /// A response carried another version in its prefix than its request (a server answers
    /// with the version the request used, manual 1.3).
    #[error("protocol version {version} in the response to a request of another version")]
    Version {
        /// The version as received.
        version: u16,
    },
    /// The header's communication type is not "response".
    #[error("communication type {0} where a response was expected")]
    CommunicationType(CommunicationType),
    /// The response's message type differs from the request's: the pairing of requests and
    /// responses cannot be trusted any more, so the connection is closed.
    #[error("response of type {received} to a {expected} request")]
    MessageType {
        /// The request's message type.
        expected: MessageType,
        /// The response's message type.
        received: MessageType,
    },
    /// A SUCCESS V3 response does not repeat a field of the request it was paired with, as the
    /// manual says it does (GET_GRASP: the tool and a non-zero object class, 3.3.3.1;
    /// GET_OBJECT_COUNT: object class, 3.3.4.1). It answers another request (or was corrupted):
    /// the connection is closed rather than hand it to this caller. GET_GRASP's pose format is
    /// no echo (it is the format the response's pose is written in, 3.3.3.1), and a V4
    /// response is checked by its header only (PROTOCOLS.md 2b).
    #[error("the response to {request} does not repeat the request's {field}")]
    Echo {
        /// The request's message type.
        request: MessageType,
        /// The field that differs.
        field: &'static str,
    },
    /// A response arrived while no request was waiting.
    #[error("unsolicited response (counter {counter})")]
    Unsolicited {
        /// Its response counter.
        counter: u8,
    },
    /// A SUCCESS response without the body its message type has.
    #[error("a SUCCESS response without its body")]
    MissingBody,
    /// A successful GET_GRASP response carried a pose that cannot be read.
    #[error("grasp pose: {0}")]
    Pose(PoseError),
}
