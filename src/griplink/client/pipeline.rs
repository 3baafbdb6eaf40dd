//! Strict in-order pairing of replies with commands (manual 2.1: one reply line per command,
//! in order). No I/O: the task feeds it lines and it hands results to the waiting callers.
//!
//! A caller that timed out or dropped its future keeps its slot: the reply that eventually
//! comes for its command is consumed here and discarded, so the next caller gets its own reply
//! and never a stale one.

use std::collections::VecDeque;

use tokio::sync::oneshot;
use tokio::time::Instant;

use crate::griplink::codec::Line;
use crate::griplink::command::Expect;
use crate::griplink::error::{Error, Result};
use crate::griplink::reply::{interpret, Answer};

/// Where a caller waits for its result.
pub(crate) type Waiter = oneshot::Sender<Result<Answer>>;

/// A command on the wire whose reply has not come yet.
#[derive(Debug)]
pub(crate) struct Slot {
    /// The command line (for error messages and traces).
    pub line: String,
    /// What the reply must look like.
    pub expect: Expect,
    /// The caller, who may have gone away.
    pub waiter: Waiter,
    /// When a missing reply means the pairing can no longer be trusted.
    pub give_up_at: Instant,
}

/// What happened to a received line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delivery {
    /// Handed to the caller of the oldest outstanding command.
    Delivered,
    /// The reply of a caller that timed out or went away: consumed and dropped.
    Discarded,
    /// No command was outstanding.
    Unsolicited,
}

/// The FIFO of outstanding commands.
#[derive(Debug)]
pub(crate) struct Pipeline {
    slots: VecDeque<Slot>,
    depth: usize,
}

impl Pipeline {
    /// A pipeline that allows `depth` commands on the wire at once (at least one).
    pub(crate) fn new(depth: usize) -> Self {
        Pipeline {
            slots: VecDeque::new(),
            depth: depth.max(1),
        }
    }

    pub(crate) fn has_room(&self) -> bool {
        self.slots.len() < self.depth
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    pub(crate) fn push(&mut self, slot: Slot) {
        self.slots.push_back(slot);
    }

    /// When the oldest outstanding reply is so late that the connection must be given up.
    /// Only the oldest counts: later replies cannot come before it.
    pub(crate) fn give_up_at(&self) -> Option<Instant> {
        self.slots.front().map(|s| s.give_up_at)
    }

    /// The line of the oldest outstanding command.
    pub(crate) fn oldest(&self) -> Option<&str> {
        self.slots.front().map(|s| s.line.as_str())
    }

    /// Pairs a received line with the oldest outstanding command.
    pub(crate) fn on_line(&mut self, line: Line) -> Delivery {
        let Some(slot) = self.slots.pop_front() else {
            tracing::warn!(
                ?line,
                "griplink: reply with no command outstanding, ignored"
            );
            return Delivery::Unsolicited;
        };
        if slot.waiter.is_closed() {
            tracing::debug!(command = %slot.line, ?line, "griplink: discarding the late reply of an abandoned call");
            return Delivery::Discarded;
        }
        let result = match line {
            Line::Text(text) => interpret(&slot.line, slot.expect, &text),
            Line::Discarded(why) => Err(Error::MalformedReply {
                command: slot.line.clone(),
                line: String::new(),
                reason: why.to_string(),
            }),
        };
        match slot.waiter.send(result) {
            Ok(()) => Delivery::Delivered,
            Err(_) => Delivery::Discarded,
        }
    }

    /// Fails every outstanding command with `error`.
    pub(crate) fn fail_all(&mut self, error: &Error) {
        for slot in self.slots.drain(..) {
            let _ = slot.waiter.send(Err(error.clone()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::griplink::reply::Answer;

    fn slot(line: &str, expect: Expect) -> (Slot, oneshot::Receiver<Result<Answer>>) {
        let (tx, rx) = oneshot::channel();
        (
            Slot {
                line: line.into(),
                expect,
                waiter: tx,
                give_up_at: Instant::now(),
            },
            rx,
        )
    }

    fn text(s: &str) -> Line {
        Line::Text(s.into())
    }

    #[tokio::test]
    async fn abandoned_slot_eats_its_own_reply() {
        let mut p = Pipeline::new(4);
        let (a, rx_a) = slot("HOME(0)", Expect::Ack);
        let state = Expect::Data {
            key: "DEVSTATE",
            port: Some(0),
            index: None,
        };
        let (b, mut rx_b) = slot("DEVSTATE[0]?", state);
        p.push(a);
        p.push(b);
        drop(rx_a); // the caller of HOME timed out
        assert_eq!(p.on_line(text("ACK")), Delivery::Discarded);
        assert!(rx_b.try_recv().is_err(), "B must not get A's reply");
        assert_eq!(p.on_line(text("DEVSTATE[0]=3")), Delivery::Delivered);
        assert!(matches!(rx_b.try_recv(), Ok(Ok(Answer::Data(_)))));
        assert_eq!(p.on_line(text("ACK")), Delivery::Unsolicited);
    }

    #[tokio::test]
    async fn discarded_line_still_consumes_a_slot() {
        let mut p = Pipeline::new(2);
        let (a, mut rx_a) = slot("ID?", Expect::Any);
        let (b, mut rx_b) = slot("HOME(0)", Expect::Ack);
        p.push(a);
        p.push(b);
        p.on_line(Line::Discarded(crate::griplink::codec::Discarded::TooLong));
        assert!(matches!(
            rx_a.try_recv(),
            Ok(Err(Error::MalformedReply { .. }))
        ));
        p.on_line(text("ACK"));
        assert!(matches!(rx_b.try_recv(), Ok(Ok(Answer::Ack))));
        assert!(p.is_empty());
    }

    #[tokio::test]
    async fn fail_all_reaches_everyone() {
        let mut p = Pipeline::new(2);
        let (a, mut rx_a) = slot("ID?", Expect::Any);
        p.push(a);
        assert!(!p.is_empty());
        p.fail_all(&Error::Closed);
        assert!(matches!(rx_a.try_recv(), Ok(Err(Error::Closed))));
        assert!(p.is_empty() && p.has_room());
    }
}
