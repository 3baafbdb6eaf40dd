//! Strict in-order pairing of replies with commands (manual 2.1: one reply line per command,
//! in order). No I/O: the task feeds it lines and it hands results to the waiting callers.
//!
//! A caller that timed out or dropped its future keeps its slot: the reply that eventually
//! comes for its command is consumed here and discarded, so the next caller gets its own reply
//! and never a stale one.
//!
//! A line that does not answer its command (another key, port or index, `ACK` for a query, a
//! value for an `ACK` command, or not GRIPLINK at all) may be a wrong reply, but it may as well
//! be an extra line (a duplicated reply, a reply split in two by a corrupted byte) that shifts
//! every later reply by one. The pairing is then resynchronised with a probe, a harmless query
//! of our own ([`Delivery::Resync`]): every line is skipped until the probe's answer arrives, and
//! only then does the caller get its error, so that whatever it does next happens on a
//! connection in step again. If other commands are on the wire, their replies could be anyone's:
//! the connection is given up ([`Delivery::Lost`]).

use std::collections::VecDeque;
use std::time::Duration;

use tokio::sync::oneshot;
use tokio::time::Instant;

use crate::give_up::GiveUp;
use crate::griplink::command::Expect;
use crate::griplink::error::{Error, Result};
use crate::griplink::reply::{interpret_datum, Checked};
use crate::line::codec::Discarded;

/// Where a caller waits for its result.
pub(crate) type Waiter = oneshot::Sender<Result<Checked>>;

/// A command on the wire whose reply has not come yet.
#[derive(Debug)]
pub(crate) struct Slot {
    /// The command line (for error messages and traces).
    pub line: String,
    /// What the reply must look like.
    pub expect: Expect,
    /// The caller, who may have gone away.
    pub waiter: Waiter,
    /// When a missing reply means the pairing can no longer be trusted (counted again from
    /// when the slot reaches the front, `crate::give_up`).
    pub give_up: GiveUp,
    /// `Some` for a resynchronisation probe: lines that do not answer it are skipped (they are
    /// leftovers of the shift); when its answer comes, `waiter` (the caller whose reply was out
    /// of step) gets this error.
    pub probe: Option<Error>,
}

/// What happened to a received line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delivery {
    /// Handed to the caller of the oldest outstanding command.
    Delivered,
    /// The reply of a caller that timed out or went away: consumed and dropped.
    Discarded,
    /// No command was outstanding: an extra line, dropped (the pairing is in step after it, as
    /// nothing was waiting).
    Unsolicited,
    /// The line did not answer its command: send this probe line (its slot is queued already).
    Resync(&'static str),
    /// The answer to a probe: the pairing is in step again.
    Resynced,
    /// The line did not answer its command while other commands were on the wire: the pairing
    /// is lost, the connection must be given up.
    Lost,
}

/// How long a resynchronisation probe may take, by default.
const PROBE_TIMEOUT: Duration = Duration::from_secs(10);

/// The probe after `suspect`'s reply was out of step: `ID?`, or `SN?` if the suspect was an
/// `ID` query itself (its own late reply must not be taken for the probe's answer).
fn probe_for(suspect: &str) -> (&'static str, Expect) {
    let data = |key| Expect::Data {
        key,
        port: None,
        index: None,
    };
    if suspect
        .get(..2)
        .is_some_and(|k| k.eq_ignore_ascii_case("ID"))
    {
        ("SN?", data("SN"))
    } else {
        ("ID?", data("ID"))
    }
}

/// The FIFO of outstanding commands.
#[derive(Debug)]
pub(crate) struct Pipeline {
    slots: VecDeque<Slot>,
    depth: usize,
    probe_timeout: Duration,
}

impl Pipeline {
    /// A pipeline that allows `depth` commands on the wire at once (at least one).
    pub(crate) fn new(depth: usize) -> Self {
        Pipeline {
            slots: VecDeque::new(),
            depth: depth.max(1),
            probe_timeout: PROBE_TIMEOUT,
        }
    }

    /// How long a probe may take before the connection is given up.
    pub(crate) fn with_probe_timeout(mut self, timeout: Duration) -> Self {
        self.probe_timeout = timeout;
        self
    }

    /// Whether another command may be sent: not while resynchronising.
    pub(crate) fn has_room(&self) -> bool {
        self.slots.len() < self.depth && !self.slots.iter().any(|s| s.probe.is_some())
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    pub(crate) fn push(&mut self, slot: Slot) {
        self.slots.push_back(slot);
    }

    /// When the oldest outstanding reply is so late that the connection must be given up.
    /// Only the oldest counts: later replies cannot come before it. `now` is read only when a
    /// command has just reached the front behind another (its give-up clock starts then).
    pub(crate) fn give_up_at(&mut self, now: impl FnOnce() -> Instant) -> Option<Instant> {
        self.slots.front_mut().map(|s| s.give_up.at_front(now))
    }

    /// The line of the oldest outstanding command.
    pub(crate) fn oldest(&self) -> Option<&str> {
        self.slots.front().map(|s| s.line.as_str())
    }

    /// Pairs a received line (its text, or why the codec discarded it) with the oldest
    /// outstanding command. `now` is the time the line was received; it is read only when the
    /// line starts a resynchronisation (the probe's give-up clock starts then). The caller
    /// supplies the clock (no I/O here, the time included: quinn-proto's sans-I/O model), so a
    /// test can run the pairing on a clock of its own.
    pub(crate) fn on_line(
        &mut self,
        line: std::result::Result<&str, Discarded>,
        now: impl FnOnce() -> Instant,
    ) -> Delivery {
        let Some(slot) = self.slots.pop_front() else {
            tracing::warn!(
                ?line,
                "griplink: reply with no command outstanding, ignored"
            );
            return Delivery::Unsolicited;
        };
        let result = match line {
            Ok(text) => interpret_datum(&slot.line, slot.expect, text),
            Err(why) => Err(Error::MalformedReply {
                command: slot.line.clone(),
                line: String::new(),
                reason: why.to_string(),
            }),
        };
        if let Some(error) = slot.probe {
            // Only the probe's own answer ends the resynchronisation: even an `ERR` could be
            // the leftover reply of the command that was out of step.
            if result.is_err() {
                tracing::debug!(?line, "griplink: skipping a line while resynchronising");
                self.slots.push_front(Slot {
                    probe: Some(error),
                    ..slot
                });
                return Delivery::Discarded;
            }
            tracing::info!("griplink: replies are in step again");
            let _ = slot.waiter.send(Err(error));
            return Delivery::Resynced;
        }
        match result {
            Err(error @ (Error::MalformedReply { .. } | Error::UnexpectedReply { .. })) => {
                tracing::warn!(command = %slot.line, ?line, "griplink: the reply does not answer its command");
                if !self.slots.is_empty() {
                    let _ = slot.waiter.send(Err(error));
                    return Delivery::Lost;
                }
                let (probe, expect) = probe_for(&slot.line);
                self.slots.push_back(Slot {
                    line: probe.to_owned(),
                    expect,
                    waiter: slot.waiter,
                    give_up: GiveUp::fixed(crate::deadline::after(now(), self.probe_timeout)),
                    probe: Some(error),
                });
                Delivery::Resync(probe)
            }
            _ if slot.waiter.is_closed() => {
                tracing::debug!(command = %slot.line, ?line, "griplink: discarding the late reply of an abandoned call");
                Delivery::Discarded
            }
            result => match slot.waiter.send(result) {
                Ok(()) => Delivery::Delivered,
                Err(_) => Delivery::Discarded,
            },
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

    fn slot(line: &str, expect: Expect) -> (Slot, oneshot::Receiver<Result<Checked>>) {
        let (tx, rx) = oneshot::channel();
        (
            Slot {
                line: line.into(),
                expect,
                waiter: tx,
                give_up: GiveUp::fixed(Instant::now()),
                probe: None,
            },
            rx,
        )
    }

    fn text(s: &str) -> std::result::Result<&str, Discarded> {
        Ok(s)
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
        assert_eq!(p.on_line(text("ACK"), Instant::now), Delivery::Discarded);
        assert!(rx_b.try_recv().is_err(), "B must not get A's reply");
        assert_eq!(
            p.on_line(text("DEVSTATE[0]=3"), Instant::now),
            Delivery::Delivered
        );
        assert!(matches!(rx_b.try_recv(), Ok(Ok(Checked::Data(_)))));
        assert_eq!(p.on_line(text("ACK"), Instant::now), Delivery::Unsolicited);
    }

    #[tokio::test]
    async fn discarded_line_still_consumes_a_slot() {
        let mut p = Pipeline::new(2);
        let (a, mut rx_a) = slot("ID?", Expect::Any);
        let (b, mut rx_b) = slot("HOME(0)", Expect::Ack);
        p.push(a);
        p.push(b);
        p.on_line(Err(Discarded::TooLong), Instant::now);
        assert!(matches!(
            rx_a.try_recv(),
            Ok(Err(Error::MalformedReply { .. }))
        ));
        p.on_line(text("ACK"), Instant::now);
        assert!(matches!(rx_b.try_recv(), Ok(Ok(Checked::Ack))));
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

    #[tokio::test]
    async fn out_of_step_reply_resynchronises_before_the_caller_hears() {
        let mut p = Pipeline::new(1);
        let sn = Expect::Data {
            key: "SN",
            port: None,
            index: None,
        };
        let (b, mut rx_b) = slot("SN?", sn);
        p.push(b);
        // A duplicate of the previous `ID?` reply arrives for `SN?`.
        let d = p.on_line(text("ID=\"GRIPLINK-ET4\""), Instant::now);
        assert!(matches!(d, Delivery::Resync("ID?")), "{d:?}");
        assert!(rx_b.try_recv().is_err(), "told before the probe answered");
        assert!(!p.has_room(), "nothing is sent while resynchronising");
        // SN?'s own reply, then an ERR: leftovers, skipped.
        assert!(matches!(
            p.on_line(text("SN=\"1\""), Instant::now),
            Delivery::Discarded
        ));
        assert!(matches!(
            p.on_line(text("ERR 04"), Instant::now),
            Delivery::Discarded
        ));
        assert!(matches!(
            p.on_line(text("ID=\"GRIPLINK-ET4\""), Instant::now),
            Delivery::Resynced
        ));
        assert!(matches!(
            rx_b.try_recv(),
            Ok(Err(Error::UnexpectedReply { .. }))
        ));
        assert!(p.is_empty() && p.has_room());
    }

    #[tokio::test]
    async fn probe_after_an_id_query_is_sn() {
        let mut p = Pipeline::new(1);
        let (a, _rx) = slot("ID?", Expect::Any);
        p.push(a);
        assert!(matches!(
            p.on_line(Err(Discarded::NotAscii), Instant::now),
            Delivery::Resync("SN?")
        ));
    }

    /// The pairing reads no clock of its own: the probe's give-up counts from the time the
    /// caller says the out-of-step line came, and a line in step does not ask for the time.
    #[tokio::test]
    async fn the_probes_give_up_counts_from_the_callers_now() {
        let timeout = Duration::from_secs(3);
        let mut p = Pipeline::new(1).with_probe_timeout(timeout);
        let (a, _rx_a) = slot("HOME(0)", Expect::Ack);
        p.push(a);
        let never = || -> Instant { panic!("a line in step read the clock") };
        assert_eq!(p.on_line(text("ACK"), never), Delivery::Delivered);
        let (b, _rx_b) = slot("HOME(0)", Expect::Ack);
        p.push(b);
        let received = Instant::now() + Duration::from_secs(3600);
        let d = p.on_line(text("ID=\"x\""), || received);
        assert_eq!(d, Delivery::Resync("ID?"));
        assert_eq!(p.give_up_at(never), Some(received + timeout));
    }

    #[tokio::test]
    async fn out_of_step_with_others_on_the_wire_is_lost() {
        let mut p = Pipeline::new(2);
        let (a, mut rx_a) = slot("HOME(0)", Expect::Ack);
        let (b, _rx_b) = slot("LED(0,1)", Expect::Ack);
        p.push(a);
        p.push(b);
        assert!(matches!(
            p.on_line(text("ID=\"x\""), Instant::now),
            Delivery::Lost
        ));
        assert!(matches!(
            rx_a.try_recv(),
            Ok(Err(Error::UnexpectedReply { .. }))
        ));
    }
}
