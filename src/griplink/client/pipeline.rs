//! Strict in-order pairing of replies with commands (manual 2.1: one reply line per command,
//! in order), as a state machine without I/O (issue 30, quinn-proto's sans-I/O shape; SmartGrasp's
//! `in_flight.rs` is the model): the task writes a command and hands it here with its caller; it
//! hands every line it reads here, with the time it was read; and it does what comes back:
//! complete a call with its result, send a probe, give the connection up. No socket, no clock
//! (`now` is passed in, read only where a path needs it), no channel: a caller is an opaque
//! token ([`Caller`]) that is only asked whether it gave up, so the rules are tested with plain
//! `#[test]`s.
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

use tokio::time::Instant;

use crate::caller::Caller;
use crate::give_up::GiveUp;
use crate::griplink::command::Expect;
use crate::griplink::error::{Error, Result};
use crate::griplink::reply::{interpret_datum, Checked};
use crate::line::codec::Discarded;

/// A command on the wire whose reply has not come yet.
#[derive(Debug)]
struct Slot<C> {
    /// The command line (for error messages and traces).
    line: String,
    /// What the reply must look like.
    expect: Expect,
    /// The caller, who may have gone away.
    caller: C,
    /// When a missing reply means the pairing can no longer be trusted (counted again from
    /// when the slot reaches the front, `crate::give_up`).
    give_up: GiveUp,
    /// `Some` for a resynchronisation probe: lines that do not answer it are skipped (they are
    /// leftovers of the shift); when its answer comes, `caller` (the caller whose reply was out
    /// of step) gets this error.
    probe: Option<Error>,
}

/// What happened to a received line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delivery {
    /// Handed to the caller of the oldest outstanding command (the `done` of
    /// [`Pipeline::on_line`] was called).
    Delivered,
    /// The reply of a caller that timed out or went away: consumed and dropped.
    Discarded,
    /// No command was outstanding: an extra line, dropped (the pairing is in step after it, as
    /// nothing was waiting).
    Unsolicited,
    /// The line did not answer its command: send this probe line (its slot is queued already).
    Resync(&'static str),
    /// The answer to a probe: the pairing is in step again (the caller whose reply was out of
    /// step gets its error through `done`).
    Resynced,
    /// The line did not answer its command while other commands were on the wire: the pairing
    /// is lost, the connection must be given up (the caller of that command gets its error
    /// through `done`; the others through [`Pipeline::drain`]).
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

/// The FIFO of outstanding commands, each with its caller `C`.
#[derive(Debug)]
pub(crate) struct Pipeline<C> {
    slots: VecDeque<Slot<C>>,
    depth: usize,
    /// See [`ClientConfig::give_up_after`](super::ClientConfig::give_up_after).
    give_up_after: Duration,
    probe_timeout: Duration,
}

impl<C: Caller> Pipeline<C> {
    /// A pipeline that allows `depth` commands on the wire at once (at least one), a reply
    /// tolerated `give_up_after` past its call's deadline.
    pub(crate) fn new(depth: usize, give_up_after: Duration) -> Self {
        Pipeline {
            slots: VecDeque::new(),
            depth: depth.max(1),
            give_up_after,
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

    /// The give-up clock of a command sent now whose caller waits until `deadline`, with
    /// `timeout`: its reply is awaited until `deadline` plus `give_up_after`, and behind other
    /// commands its clock starts again when it reaches the front (`crate::give_up`). Its
    /// [`limit`](GiveUp::limit) bounds the command's write too.
    #[inline]
    pub(crate) fn give_up_for(&self, deadline: Instant, timeout: Duration) -> GiveUp {
        GiveUp::new(deadline, self.give_up_after, self.slots.is_empty(), || {
            timeout
        })
    }

    /// Queues a command that was written, with its caller and its clock from
    /// [`Pipeline::give_up_for`].
    #[inline]
    pub(crate) fn push(&mut self, line: String, expect: Expect, caller: C, give_up: GiveUp) {
        self.slots.push_back(Slot {
            line,
            expect,
            caller,
            give_up,
            probe: None,
        });
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
    /// outstanding command. A caller to complete goes to `done` with what it gets (at most one
    /// per line: [`Delivery::Delivered`], [`Delivery::Resynced`], [`Delivery::Lost`]); the task
    /// completes it. `now` is the time the line was received; it is read only when the line
    /// starts a resynchronisation (the probe's give-up clock starts then). The caller supplies
    /// the clock (no I/O here, the time included: quinn-proto's sans-I/O model), so a test can
    /// run the pairing on a clock of its own.
    pub(crate) fn on_line(
        &mut self,
        line: std::result::Result<&str, Discarded>,
        now: impl FnOnce() -> Instant,
        done: impl FnOnce(C, Result<Checked>),
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
            done(slot.caller, Err(error));
            return Delivery::Resynced;
        }
        match result {
            Err(error @ (Error::MalformedReply { .. } | Error::UnexpectedReply { .. })) => {
                tracing::warn!(command = %slot.line, ?line, "griplink: the reply does not answer its command");
                if !self.slots.is_empty() {
                    done(slot.caller, Err(error));
                    return Delivery::Lost;
                }
                let (probe, expect) = probe_for(&slot.line);
                self.slots.push_back(Slot {
                    line: probe.to_owned(),
                    expect,
                    caller: slot.caller,
                    give_up: GiveUp::fixed(crate::deadline::after(now(), self.probe_timeout)),
                    probe: Some(error),
                });
                Delivery::Resync(probe)
            }
            _ if slot.caller.gave_up() => {
                tracing::debug!(command = %slot.line, ?line, "griplink: discarding the late reply of an abandoned call");
                Delivery::Discarded
            }
            result => {
                done(slot.caller, result);
                Delivery::Delivered
            }
        }
    }

    /// The connection ended for `reason`: every outstanding command's caller, oldest first, with
    /// the error it gets. The pipeline is empty afterwards.
    pub(crate) fn drain(&mut self, reason: &Error, mut out: impl FnMut(C, Error)) {
        for slot in self.slots.drain(..) {
            out(slot.caller, reason.clone());
        }
    }
}

/// The rules driven without a runtime: plain `#[test]`s, the clock passed in, callers that are
/// numbers.
#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::rc::Rc;

    use super::*;
    use crate::caller::test::Call;

    const GIVE_UP_AFTER: Duration = Duration::from_secs(30);

    /// Sends `line` as call `id` at `now` (its caller waits a second); the handle that makes
    /// its caller give up.
    fn send(
        p: &mut Pipeline<Call>,
        id: u8,
        line: &str,
        expect: Expect,
        now: Instant,
    ) -> Rc<Cell<bool>> {
        let gone = Rc::new(Cell::new(false));
        let timeout = Duration::from_secs(1);
        let give_up = p.give_up_for(now + timeout, timeout);
        let caller = Call {
            id,
            gone: Rc::clone(&gone),
        };
        p.push(line.into(), expect, caller, give_up);
        gone
    }

    /// Hands `line` to the pipeline, received at `now`: what it did, and the caller it asked
    /// the task to complete, with what.
    fn receive(
        p: &mut Pipeline<Call>,
        line: std::result::Result<&str, Discarded>,
        now: Instant,
    ) -> (Delivery, Option<(u8, Result<Checked>)>) {
        let mut done = None;
        let delivery = p.on_line(line, || now, |c, r| done = Some((c.id, r)));
        (delivery, done)
    }

    fn text(s: &str) -> std::result::Result<&str, Discarded> {
        Ok(s)
    }

    fn state() -> Expect {
        Expect::Data {
            key: "DEVSTATE",
            port: Some(0),
            index: None,
        }
    }

    #[test]
    fn abandoned_slot_eats_its_own_reply() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(4, GIVE_UP_AFTER);
        let a = send(&mut p, 1, "HOME(0)", Expect::Ack, t0);
        send(&mut p, 2, "DEVSTATE[0]?", state(), t0);
        a.set(true); // the caller of HOME timed out
        let (d, done) = receive(&mut p, text("ACK"), t0);
        assert_eq!(d, Delivery::Discarded);
        assert!(done.is_none(), "B must not get A's reply");
        let (d, done) = receive(&mut p, text("DEVSTATE[0]=3"), t0);
        assert_eq!(d, Delivery::Delivered);
        assert!(matches!(done, Some((2, Ok(Checked::Data(_))))), "{done:?}");
        let (d, done) = receive(&mut p, text("ACK"), t0);
        assert_eq!(d, Delivery::Unsolicited);
        assert!(done.is_none());
    }

    #[test]
    fn discarded_line_still_consumes_a_slot() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(2, GIVE_UP_AFTER);
        send(&mut p, 1, "ID?", Expect::Any, t0);
        send(&mut p, 2, "HOME(0)", Expect::Ack, t0);
        let (_, done) = receive(&mut p, Err(Discarded::TooLong), t0);
        assert!(
            matches!(done, Some((1, Err(Error::MalformedReply { .. })))),
            "{done:?}"
        );
        let (_, done) = receive(&mut p, text("ACK"), t0);
        assert!(matches!(done, Some((2, Ok(Checked::Ack)))), "{done:?}");
        assert!(p.is_empty());
    }

    #[test]
    fn drain_reaches_everyone_oldest_first() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(2, GIVE_UP_AFTER);
        send(&mut p, 1, "ID?", Expect::Any, t0);
        send(&mut p, 2, "SN?", Expect::Any, t0);
        assert!(!p.is_empty() && !p.has_room());
        let mut failed = Vec::new();
        p.drain(&Error::Closed, |c, e| failed.push((c.id, e)));
        assert!(
            matches!(&failed[..], [(1, Error::Closed), (2, Error::Closed)]),
            "{failed:?}"
        );
        assert!(p.is_empty() && p.has_room());
    }

    #[test]
    fn out_of_step_reply_resynchronises_before_the_caller_hears() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(1, GIVE_UP_AFTER);
        let sn = Expect::Data {
            key: "SN",
            port: None,
            index: None,
        };
        send(&mut p, 1, "SN?", sn, t0);
        // A duplicate of the previous `ID?` reply arrives for `SN?`.
        let (d, done) = receive(&mut p, text("ID=\"GRIPLINK-ET4\""), t0);
        assert_eq!(d, Delivery::Resync("ID?"));
        assert!(done.is_none(), "told before the probe answered");
        assert!(!p.has_room(), "nothing is sent while resynchronising");
        // SN?'s own reply, then an ERR: leftovers, skipped.
        for leftover in ["SN=\"1\"", "ERR 04"] {
            let (d, done) = receive(&mut p, text(leftover), t0);
            assert_eq!(d, Delivery::Discarded, "{leftover}");
            assert!(done.is_none(), "{leftover}");
        }
        let (d, done) = receive(&mut p, text("ID=\"GRIPLINK-ET4\""), t0);
        assert_eq!(d, Delivery::Resynced);
        assert!(
            matches!(done, Some((1, Err(Error::UnexpectedReply { .. })))),
            "{done:?}"
        );
        assert!(p.is_empty() && p.has_room());
    }

    #[test]
    fn probe_after_an_id_query_is_sn() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(1, GIVE_UP_AFTER);
        send(&mut p, 1, "ID?", Expect::Any, t0);
        let (d, _) = receive(&mut p, Err(Discarded::NotAscii), t0);
        assert_eq!(d, Delivery::Resync("SN?"));
    }

    /// The pairing reads no clock of its own: the probe's give-up counts from the time the
    /// caller says the out-of-step line came, and a line in step does not ask for the time.
    #[test]
    fn the_probes_give_up_counts_from_the_callers_now() {
        let t0 = Instant::now();
        let timeout = Duration::from_secs(3);
        let mut p = Pipeline::new(1, GIVE_UP_AFTER).with_probe_timeout(timeout);
        send(&mut p, 1, "HOME(0)", Expect::Ack, t0);
        let never = || -> Instant { panic!("a line in step read the clock") };
        assert_eq!(p.on_line(text("ACK"), never, drop2), Delivery::Delivered);
        send(&mut p, 2, "HOME(0)", Expect::Ack, t0);
        let received = t0 + Duration::from_secs(3600);
        let (d, _) = receive(&mut p, text("ID=\"x\""), received);
        assert_eq!(d, Delivery::Resync("ID?"));
        assert_eq!(p.give_up_at(never), Some(received + timeout));
    }

    fn drop2(_: Call, _: Result<Checked>) {}

    #[test]
    fn out_of_step_with_others_on_the_wire_is_lost() {
        let t0 = Instant::now();
        let mut p = Pipeline::new(2, GIVE_UP_AFTER);
        send(&mut p, 1, "HOME(0)", Expect::Ack, t0);
        send(&mut p, 2, "LED(0,1)", Expect::Ack, t0);
        let (d, done) = receive(&mut p, text("ID=\"x\""), t0);
        assert_eq!(d, Delivery::Lost);
        assert!(
            matches!(done, Some((1, Err(Error::UnexpectedReply { .. })))),
            "{done:?}"
        );
    }

    /// The give-up clock: a command sent to an idle connection gives up `give_up_after` past its
    /// deadline; one sent behind another counts its timeout and the margin again from when it
    /// reaches the front (`crate::give_up`), read only then.
    #[test]
    fn a_command_behind_another_counts_from_when_it_reaches_the_front() {
        let t0 = Instant::now();
        let s = Duration::from_secs(1);
        let mut p = Pipeline::new(2, GIVE_UP_AFTER);
        send(&mut p, 1, "HOME(0)", Expect::Ack, t0);
        send(&mut p, 2, "LED(0,1)", Expect::Ack, t0);
        let never = || -> Instant { panic!("the front's clock was read again") };
        assert_eq!(p.give_up_at(never), Some(t0 + s + GIVE_UP_AFTER));
        // HOME is answered a minute later: LED's clock starts then.
        let later = t0 + 60 * s;
        let (d, _) = receive(&mut p, text("ACK"), later);
        assert_eq!(d, Delivery::Delivered);
        assert_eq!(p.give_up_at(|| later), Some(later + s + GIVE_UP_AFTER));
        assert_eq!(p.oldest(), Some("LED(0,1)"));
    }
}
