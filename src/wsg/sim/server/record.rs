//! An optional record of what the simulator processed and sent, per session: the evidence a
//! test oracle checks a client's answers against (issue 20: "every value a call returns is the
//! device's answer to *that* request").
//!
//! Off by default (a server records nothing until [`SimServer::start_recording`] is called) and
//! bounded: the oldest entries give way once the capacity is reached, and
//! [`SimRecording::dropped`] counts them, so an oracle can tell a complete record from a cut
//! one.
//!
//! [`SimServer::start_recording`]: super::SimServer::start_recording

use std::collections::VecDeque;
use std::time::Duration;

use bytes::Bytes;

use crate::wsg::sim::device::{SessionId, SessionKind};
use crate::wsg::Status;

/// One thing the simulator did, as recorded.
#[derive(Clone, Debug, PartialEq)]
pub struct SimRecord {
    /// The session it concerns.
    pub session: SessionId,
    /// When, on the server's (tokio) clock, since the server started.
    pub at: Duration,
    /// What happened.
    pub event: SimEvent,
}

/// What a [`SimRecord`] records.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SimEvent {
    /// A session opened.
    Connected {
        /// Its transport.
        kind: SessionKind,
    },
    /// A session ended (closed, unplugged, or let go by a restart).
    Disconnected,
    /// A frame was received and handed to the device (or answered by an injected status).
    Request {
        /// The command id.
        id: u8,
        /// The payload (empty for a frame with a bad checksum).
        payload: Bytes,
        /// The frame failed its checksum (the device discards it, manual 1.2.1).
        corrupt: bool,
    },
    /// A reply was queued for the session (after the injected faults: a dropped reply is not
    /// recorded).
    Reply {
        /// The command id.
        id: u8,
        /// The status code sent.
        status: Status,
        /// The data after the status code.
        data: Bytes,
        /// Whether a finger motion was still running when the reply was queued: a motion's
        /// final reply must be sent with the fingers stopped.
        moving: bool,
    },
    /// A command line a text (GCL) session sent, as the simulator read it, before it was
    /// handled (`None`: a line longer than the simulator reads, answered `ERR ? 27`). The text
    /// mode's counterpart of [`SimEvent::Request`].
    TextRequest {
        /// The line, without its LF.
        line: Option<String>,
    },
    /// A line was queued for a text (GCL) session: a reply, an `ACK`/`FIN`/`ERR`, or an
    /// `@NAME=value` push. The text mode's counterpart of [`SimEvent::Reply`].
    TextReply {
        /// The line, without its LF.
        line: String,
        /// Whether a finger motion was still running when the line was queued: a `FIN` must
        /// be sent with the fingers stopped.
        moving: bool,
    },
    /// The device restarted ([`SimServer::restart`](super::SimServer::restart)): every session
    /// was let go and the state is the configuration's again.
    Restarted,
}

/// The record so far: oldest first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SimRecording {
    /// The entries kept.
    pub records: Vec<SimRecord>,
    /// Entries that gave way to newer ones (the capacity was reached).
    pub dropped: u64,
}

/// The recorder held in the server's shared state.
#[derive(Debug)]
pub(super) struct Recorder {
    capacity: usize,
    records: VecDeque<SimRecord>,
    dropped: u64,
}

impl Recorder {
    pub(super) fn new(capacity: usize) -> Self {
        Recorder {
            capacity: capacity.max(1),
            records: VecDeque::new(),
            dropped: 0,
        }
    }

    pub(super) fn push(&mut self, record: SimRecord) {
        if self.records.len() >= self.capacity {
            self.records.pop_front();
            self.dropped += 1;
        }
        self.records.push_back(record);
    }

    pub(super) fn snapshot(&self) -> SimRecording {
        SimRecording {
            records: self.records.iter().cloned().collect(),
            dropped: self.dropped,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_oldest_entries_give_way_and_are_counted() {
        let mut r = Recorder::new(2);
        for session in 1..=3 {
            r.push(SimRecord {
                session,
                at: Duration::ZERO,
                event: SimEvent::Disconnected,
            });
        }
        let s = r.snapshot();
        assert_eq!(s.dropped, 1);
        assert_eq!(
            s.records.iter().map(|r| r.session).collect::<Vec<_>>(),
            [2, 3]
        );
    }
}
