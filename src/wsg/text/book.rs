//! The WSG text client's book (GCL): the commands on the wire by name and the requests waiting
//! for their name, as a state machine without I/O (issue 30, quinn-proto's sans-I/O shape;
//! SmartGrasp's `in_flight.rs` is the model). The task writes a command and puts it in the book
//! with its caller; it hands every reply line it reads here, with the time it was read; and it
//! does what comes back: complete calls ([`Book::completions`]), deliver a push, write the next
//! request of a freed name or a probe, give the connection up. No socket, no clock (`now` is
//! passed in), no channel: a caller is an opaque token ([`Caller`]) that is only asked whether it
//! gave up, so the rules are tested with plain `#[test]`s.
//!
//! Replies pair with their command **by name** (`ACK MOVE`, `FIN MOVE`, `ERR MOVE 4`, `POS=…`),
//! so queries answered at once run alongside a motion whose `FIN` comes later (the gripper reads
//! and answers during motion, shared note §3.7). One command of each name is on the wire at a
//! time; a second one waits here until the first is answered. A reply carries nothing but the
//! name, so two `MOVE`s on the wire could not be told apart: the `ERR MOVE 4` refusing the
//! second (binary E_ALREADY_RUNNING, our reading §6.2) would end whichever call came first.
//!
//! The rules it holds besides: what a reply line that cannot be read settles (issue 29 M), the
//! probes that find out, the check of an overdue motion with `GRIPSTATE?` (issue 29 L), when
//! `ACK BYE` may have been an unreadable line (issue 29 N), and whose a parse error out of its
//! command's place is ([`Held`]: a damaged request answered under another command's name).

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use tokio::time::Instant;

use super::error::Error;
use super::line::{parse_number, parse_reply, ReplyLine};
use super::push::{Push, Quantity};
use crate::caller::Caller;
use crate::deadline::{after, is_never};
use crate::wsg::{GripState, Status};

/// What a command's call waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Expect {
    /// `NAME=value` (queries and setters).
    Value,
    /// `ACK NAME` (STOP, FASTSTOP, FSACK, BYE, AUTOSEND).
    Ack,
    /// `ACK NAME`, then `FIN NAME` (HOME, MOVE, GRIP, RELEASE).
    Fin,
}

/// What a call gets back.
#[derive(Debug)]
pub(crate) enum Answer {
    /// The value text of `NAME=value`.
    Value(String),
    /// `ACK` (or `FIN` for a motion).
    Done,
}

/// A caller's command, on its way to the task, its caller `C` (the task's is the call's reply
/// channel; `Option<C>` for a command about to be written, `None` for the client's own probes,
/// whose answer nobody waits for).
#[derive(Debug)]
pub(crate) struct Request<C> {
    /// The name replies carry (upper case, no arguments).
    pub name: &'static str,
    pub line: String,
    pub expect: Expect,
    /// The caller stops waiting here; a request not yet sent then is never sent.
    pub deadline: Instant,
    pub timeout: Duration,
    pub waiter: C,
    /// When the call was made.
    pub start: Instant,
    /// A query the client writes on its own (issue 29 L and M), not a caller's.
    pub probe: bool,
}

impl<C> Request<C> {
    /// The request as one about to be written (its caller a caller's, not a probe's `None`).
    pub(crate) fn outgoing(self) -> Request<Option<C>> {
        Request {
            name: self.name,
            line: self.line,
            expect: self.expect,
            deadline: self.deadline,
            timeout: self.timeout,
            waiter: Some(self.waiter),
            start: self.start,
            probe: self.probe,
        }
    }
}

/// A command on the wire.
#[derive(Debug)]
struct Slot<C> {
    line: String,
    expect: Expect,
    /// `None` for the client's own probe: nobody waits for its answer, which is consumed.
    caller: Option<C>,
    /// Past this the reply is so late that nothing can be paired with confidence any more.
    give_up_at: Instant,
    /// Its place in the order lines were written (the gripper answers in that order).
    seq: u64,
    /// A motion's `ACK` was read (its `FIN` or `ERR` comes when the motion ends).
    acked: bool,
    /// An acknowledged motion past its give-up time: a `GRIPSTATE?` asks whether it still runs
    /// (issue 29 L).
    checking: bool,
    /// The gripper reported that motion over without its `FIN` read: if none comes within
    /// `give_up_after` more, the connection is given up.
    over: bool,
    /// The gripper reported it over once with no `FIN` read before that report and no line
    /// that could not be read since its `ACK`. The gripper answers in order, so its `FIN`
    /// would have come first: the report may be a value damaged on the way into another valid
    /// one (`wsg-text:0x9b99dd46f33e9019`: `GRIPSTATE=6` read as `GRIPSTATE=2`, and a healthy
    /// connection was given up while HOME ran). It is asked again; a second such report counts.
    over_unconfirmed: bool,
    /// [`Book::unreadable`] when its `ACK` was read.
    unreadable_at_ack: u64,
    /// A motion whose first reply (`ACK` or `ERR`) never came or could not be read, shown lost
    /// by a later reply ([`Book::settle`]): reported over, it ends, for its `FIN` or `ERR`
    /// (which comes before that report, in order) will not come either.
    first_reply_lost: bool,
    /// `Book::damages` when it was written.
    damages_at_write: u64,
    /// [`Book::unreadable`] when it was written.
    unreadable_at_write: u64,
    /// When it was written, if it is a probe (`Request::probe`).
    probe_at: Option<Instant>,
    /// A command whose reply is not due before this (a call without timeout, or with a long
    /// one): not answered by then, the client asks (`Book::doubt`).
    doubt_at: Option<Instant>,
    /// When its caller stops waiting.
    deadline: Instant,
    /// An `ERR <name> 14`/`15` read out of its place, not yet known to be its own
    /// ([`Held`]).
    held: Option<Held>,
}

impl<C> Slot<C> {
    /// A motion whose held `ERR` is in doubt, the gripper asked whether it runs
    /// ([`Book::doubt_held_motion`]): the one way a held line sits on an acknowledged motion
    /// (a line is held only for a command that waits for a reply due at once). Its line is
    /// never handed over on time or at the connection's end: the motion may run.
    fn in_doubt(&self) -> bool {
        self.acked && self.held.is_some()
    }
}

/// An `ERR <name> 14` or `15` (unknown command, format error: the gripper's answer to a line
/// it could not parse) read while a command answered at once that was written before this one
/// still waits for its reply. A request damaged on the way is answered under whatever name the
/// damage left, maybe another command's: a flipped bit made `GRIPSTATE?` into `GRIP\x13TATE?`,
/// answered `ERR GRIP 15`, which the program's `GRIP(…)` on the wire took while its own
/// `ACK GRIP` followed (`wsg-text:0xba0682223c8b01a8`). The gripper answers in order (shared
/// note §3.7), so the next reply settles whose it was ([`Book::settle_held`]): one to this
/// command or to a line written before it shows it was another's; one to a line written after
/// it shows it was this command's. A probe draws such a reply when none is due; and the call is
/// not kept past its deadline for it: just before, it gets the line, as it would have without
/// the doubt (a motion asked whether it runs aside: [`Book::doubt_held_motion`]).
#[derive(Debug)]
struct Held {
    /// The call's answer if the line is its own (`Error::Device`, which carries the line).
    error: Error,
    /// When the call gets it all the same.
    settle_at: Instant,
    /// `Book::damages` once it was held: it counts as a line that could not be read from the
    /// moment it is read, so that commands written after it see it before their write.
    damages: u64,
    /// `Book::holds` once it was held: with `damages`, whether a line that could not be read
    /// came after it.
    holds: u64,
}

impl Held {
    /// The line it holds.
    fn line(self) -> String {
        match self.error {
            Error::Device { line, .. } => line,
            _ => String::new(),
        }
    }

    /// Whether a line that could not be read (not another held one) came after it, by the
    /// book's counts now.
    fn unreadable_since(&self, damages: u64, holds: u64) -> bool {
        damages - self.damages > holds - self.holds
    }
}

/// How long a command may stay unanswered before the client asks, when its call's deadline is
/// later (issue 29 M): whether the reply the gripper sends at once (shared note §3.7) was lost
/// (a call without timeout whose request was damaged on the way, so that the gripper answered
/// nothing, waited for ever and held its name), or whether an acknowledged motion still runs
/// (a motion without timeout whose `FIN` or `ERR` could not be read waited for ever).
pub(super) const DOUBT_AFTER: Duration = Duration::from_secs(10);

/// When to ask whether an acknowledged motion still runs, `DOUBT_AFTER` past `from`, if its
/// give-up time is never: one with a give-up time is checked then (issue 29 L),
/// while one without timeout (or with `give_up_after` `Duration::MAX`) was never checked, and
/// a `FIN` or `ERR` that could not be read held its call and name for ever.
fn motion_doubt(give_up_at: Instant, from: Instant) -> Option<Instant> {
    is_never(give_up_at, from).then(|| after(from, DOUBT_AFTER))
}

/// The state `GRIPSTATE?` reports while the motion `name` runs (shared note §4.4): that, and
/// not another motion's, shows it runs.
fn moving_state(name: &str) -> Option<GripState> {
    match name {
        "GRIP" => Some(GripState::Grasping),
        "RELEASE" => Some(GripState::Releasing),
        "HOME" | "MOVE" => Some(GripState::Positioning),
        _ => None,
    }
}

/// How long before its caller's deadline a call whose `ERR` is held in doubt ([`Held`]) gets
/// it: the caller's own timer ends the call at the deadline itself, and must not find it
/// unanswered while its answer is here.
const HELD_MARGIN: Duration = Duration::from_millis(2);

/// The least time between two checks of an overdue motion (issue 29 L): `give_up_after` may be
/// zero, and a check every instant would spin.
const RECHECK_FLOOR: Duration = Duration::from_millis(100);

/// The longest a probe waits for its answer. A probe is the client's own query, which the
/// gripper answers at once (shared note §3.7); a program's `query_timeout` of
/// `Duration::MAX` (no timeout for its calls) must not make it wait for ever: an overdue
/// motion checked by a probe whose request was damaged on the way (answered `ERR GRIPSTATM
/// 14`) was then never checked again and held its name for good
/// (`wsg-text:0xfa9c7f60b0e57de1`). A probe unanswered this long past its give-up time gives
/// the connection up, as any unanswered query does.
const PROBE_TIMEOUT_MAX: Duration = Duration::from_secs(10);

/// The timeout of a probe (a query the client makes on its own while it serves): the program's
/// query timeout, at most [`PROBE_TIMEOUT_MAX`].
pub(crate) fn probe_timeout(query_timeout: Duration) -> Duration {
    query_timeout.min(PROBE_TIMEOUT_MAX)
}

/// The names a probe may use (queries answered at once in every state, harmless: shared note,
/// "always"), in order of preference. Four, not three: with `give_up_after` `Duration::MAX`,
/// the first three were once all on the wire unanswered (a damaged LF ran one line into the
/// next, which swallowed a third), no probe could draw the reply that settles them, and a call
/// without timeout waited for its name for ever (`wsg-text:0x4a805d181f1854b8`, issue 29 M).
const PROBES: [(&str, &str); 4] = [
    ("GRIPSTATE", "GRIPSTATE?"),
    ("POS", "POS?"),
    ("SPEED", "SPEED?"),
    ("FORCE", "FORCE?"),
];

/// The commands on the wire (one per name) and the requests waiting for their name, their
/// callers `C`.
pub(crate) struct Book<C> {
    /// Ordered by name, not a `HashMap`: its order is random per map, and it is iterated
    /// when the connection ends (each caller is told, and so woken, in that order) and for
    /// the overdue command named in the error (the earliest give-up time, ties in map
    /// order). With a hash order the same schedule woke the callers in another order from
    /// run to run (`wsg-text:0x5a7dcaabb2430033`, tests/explore/determinism.txt).
    on_wire: BTreeMap<&'static str, Slot<C>>,
    waiting: VecDeque<Request<C>>,
    /// Lines written so far (the next `Slot::seq`).
    sent: u64,
    /// A reply line that could not be paired (damaged, `ERR` without a name) and the `seq` of
    /// the last line written before it: a command answered at once that was written by then
    /// and is still unanswered when a later command's reply arrives lost its reply to that
    /// line (the gripper answers in order, shared note §3.7). Issue 29 M.
    damaged: Option<(u64, String)>,
    /// Names freed by calls failed because their reply was damaged: their next waiting
    /// requests go out.
    freed: Vec<&'static str>,
    /// `TaskConfig::give_up_after`.
    give_up_after: Duration,
    /// Reply lines that could not be paired so far (held ones included, [`Held`]).
    damages: u64,
    /// Lines held so far ([`Held`]).
    holds: u64,
    /// The last answer to a probe of each name not yet handed to a call: when the probe was
    /// written, its line, its value (`Book::answer_from_probe`).
    probe_answers: BTreeMap<&'static str, (Instant, String, String)>,
    /// Calls to complete, with what, in order: taken by the task ([`Book::completions`]) after
    /// each step, before it awaits anything.
    done: Vec<(C, Result<Answer, Error>)>,
}

impl<C: Caller> Book<C> {
    /// An empty book; `give_up_after`: see [`ClientConfig::give_up_after`].
    ///
    /// [`ClientConfig::give_up_after`]: super::ClientConfig::give_up_after
    pub(crate) fn new(give_up_after: Duration) -> Book<C> {
        Book {
            give_up_after,
            damages: 0,
            holds: 0,
            on_wire: BTreeMap::new(),
            waiting: VecDeque::new(),
            sent: 0,
            damaged: None,
            freed: Vec::new(),
            probe_answers: BTreeMap::new(),
            done: Vec::new(),
        }
    }

    /// The calls the last steps completed, with what each gets, in order: the task sends them
    /// before it awaits anything, so that they are told at the same point as when the book
    /// answered them itself.
    pub(crate) fn completions(&mut self) -> std::vec::Drain<'_, (C, Result<Answer, Error>)> {
        self.done.drain(..)
    }

    /// Completes `caller` (a probe's `None`: nobody).
    fn complete(&mut self, caller: Option<C>, result: Result<Answer, Error>) {
        if let Some(caller) = caller {
            self.done.push((caller, result));
        }
    }

    /// Puts a command written to the wire at `now` in the book: its caller (`None`: the
    /// client's own probe), when the caller stops waiting, when it is given up, and whether it
    /// is a probe.
    #[allow(clippy::too_many_arguments)] // a request's parts, as the task holds them
    pub(crate) fn on_wire(
        &mut self,
        name: &'static str,
        line: String,
        expect: Expect,
        caller: Option<C>,
        deadline: Instant,
        give_up_at: Instant,
        now: Instant,
        probe: bool,
    ) {
        self.sent += 1;
        // `BYE()` is left out: nothing is written after it (issue 29 N), so no probe could.
        let doubt_at = after(now, DOUBT_AFTER);
        let doubt_at = (name != "BYE" && doubt_at < give_up_at).then_some(doubt_at);
        let probe_at = probe.then_some(now);
        let slot = Slot {
            line,
            expect,
            caller,
            give_up_at,
            seq: self.sent,
            acked: false,
            checking: false,
            over: false,
            over_unconfirmed: false,
            unreadable_at_ack: 0,
            first_reply_lost: false,
            damages_at_write: self.damages,
            unreadable_at_write: self.unreadable(),
            probe_at,
            doubt_at,
            deadline,
            held: None,
        };
        self.on_wire.insert(name, slot);
    }

    /// Whether `slot` waits for a reply the gripper sends at once (not a motion's `FIN`).
    fn answered_at_once(slot: &Slot<C>) -> bool {
        slot.expect != Expect::Fin || !slot.acked
    }

    /// A reply line that cannot be paired arrived: it may have been the reply of any command
    /// answered at once that is on the wire.
    pub(crate) fn damage(&mut self, text: &str) {
        self.damages += 1;
        if self.on_wire.values().any(Book::answered_at_once) {
            self.damaged = Some((self.sent, text.to_owned()));
        }
    }

    /// Reply lines that could not be read so far, held ones ([`Held`]) left out: what could
    /// have been a motion's `ACK`, `FIN` or `ERR` (a held line is an `ERR` 14 or 15, which no
    /// accepted motion ends with, and no `ACK`).
    fn unreadable(&self) -> u64 {
        self.damages - self.holds
    }

    /// The reply to the command written as `seq`, read at `now`, shows that the commands
    /// answered at once written up to `upto` and still unanswered lost their reply: to `line`,
    /// read as an answer but not paired with them, or (empty) to nothing ([`Book::settle`]).
    fn settle_before(&mut self, upto: u64, line: String, seq: u64, now: Instant) {
        let earlier = self.damaged.replace((upto, line));
        self.settle(seq, now);
        self.damaged = earlier;
    }

    /// Holds an `ERR <name> 14`/`15` read at `now` for the command `key` if it is out of its
    /// place ([`Held`]): `key` waits for a reply due at once, a command written before it
    /// still does too (and cannot have had it in an unreadable line), and its caller's
    /// deadline is not about to come. Whether it held it.
    fn hold(&mut self, key: &'static str, reply: &ReplyLine<'_>, text: &str, now: Instant) -> bool {
        let ReplyLine::Err {
            code: code @ Some(14 | 15),
            ..
        } = *reply
        else {
            return false;
        };
        let Some(slot) = self.on_wire.get(key) else {
            return false;
        };
        let seq = slot.seq;
        // The commands written before it whose reply due at once has not come: out of place
        // unless each of them may have had it in a line that could not be read since the
        // oldest was written (as `Book::bye_unreadable` counts: `ICK MOVE` for MOVE's `ACK`,
        // then the probe written after it answered `ERR GRIPSTATE 15`, its own, when its line
        // ran into the next: `wsg-text:0xe64ab80fb0bf18a2`).
        let (earlier, oldest) = self
            .on_wire
            .values()
            .filter(|s| s.seq < seq && Book::answered_at_once(s))
            .fold((0u64, u64::MAX), |(n, oldest), s| {
                (n + 1, oldest.min(s.damages_at_write))
            });
        // Never a stop's: its name must free at once, for the next stop goes out only then
        // (shared note §3.7; wsg-text:0x1836d2bb3a465209: a second `STOP()` waited 40 ms
        // behind a held `ERR STOP 15`, the first one's own). A stop taken to have failed when
        // it worked is the safe side: its caller stops again.
        let stop = matches!(key, "STOP" | "FASTSTOP");
        let out_of_place = !stop
            && slot.held.is_none()
            && Book::answered_at_once(slot)
            && self.damages.saturating_sub(oldest) < earlier;
        let settle_at = slot
            .deadline
            .checked_sub(HELD_MARGIN)
            .unwrap_or(now)
            .min(after(now, DOUBT_AFTER));
        if !out_of_place || settle_at <= now {
            return false;
        }
        self.damages += 1;
        self.holds += 1;
        let (damages, holds) = (self.damages, self.holds);
        let Some(slot) = self.on_wire.get_mut(key) else {
            return false;
        };
        tracing::debug!(command = %slot.line, line = text, "wsg text: a parse error out of its command's place, held");
        slot.held = Some(Held {
            error: Error::Device {
                command: slot.line.clone(),
                status: code.map(Status::from_code),
                line: text.to_owned(),
            },
            settle_at,
            damages,
            holds,
        });
        true
    }

    /// A reply due at once to the command `key`, written as `seq`, was read at `now` (not an
    /// acknowledged motion's `FIN` or `ERR`, which comes when the motion ends): it settles every
    /// held `ERR` ([`Held`]). The gripper answers in order:
    /// - one held by a command written before `key` was that command's, and the commands written
    ///   before that one and still unanswered lost their replies; unless a line that could not be
    ///   read came after it, which may have been that command's own reply (its `ACK` damaged):
    ///   then that command lost its reply in the damage, as any whose reply could not be read,
    ///   or, a motion, the gripper is asked whether it runs (`Book::doubt_held_motion`);
    /// - one held by `key` itself, or by a command written after it, answered a line written
    ///   before this reply's, damaged.
    ///
    /// The first kind is settled first, so that the outcome does not hang on the names' order.
    fn settle_held(&mut self, key: &str, seq: u64, now: Instant) {
        let (damages, holds) = (self.damages, self.holds);
        let mut held: Vec<(&'static str, u64, Option<bool>)> = self
            .on_wire
            .iter()
            .filter_map(|(&name, s)| {
                // A motion's held line in doubt waits for the gripper's state instead
                // (`Book::doubt_held_motion`).
                let h = s.held.as_ref().filter(|_| !s.in_doubt())?;
                let verdict =
                    (name != key && s.seq < seq).then(|| !h.unreadable_since(damages, holds));
                Some((name, s.seq, verdict))
            })
            .collect();
        // Its own (`Some(true)`), then in doubt (`Some(false)`), then another's (`None`).
        held.sort_by_key(|&(_, held_seq, verdict)| (std::cmp::Reverse(verdict), held_seq));
        for (name, held_seq, verdict) in held {
            match verdict {
                Some(true) => {
                    if self.release_held(name) {
                        self.settle_before(held_seq - 1, String::new(), seq, now);
                    }
                }
                Some(false) if self.doubt_held_motion(name, held_seq, seq, now) => {}
                Some(false) => {
                    if let Some(held) = self.on_wire.get_mut(name).and_then(|s| s.held.take()) {
                        let line = held.line();
                        tracing::warn!(%line, "wsg text: a parse error out of its place, and a line that could not be read after it: its command's reply taken as lost");
                        self.settle_before(held_seq, line, seq, now);
                    }
                }
                None => {
                    if let Some(held) = self.on_wire.get_mut(name).and_then(|s| s.held.take()) {
                        let line = held.line();
                        tracing::warn!(%line, "wsg text: a parse error out of its place was another command's, taken as damaged");
                        self.settle_before(seq - 1, line, seq, now);
                    }
                }
            }
        }
    }

    /// A motion `name`, written as `held_seq`, holds an `ERR` in doubt when the reply to the
    /// command written as `seq` is read at `now`: either the `ERR` was its own (it never ran),
    /// or it answered an earlier line and the line that could not be read after it was the
    /// motion's `ACK` (it runs). The commands written before it lost their reply either way.
    /// The gripper is asked at once (`GRIPSTATE?`, shared note §3.7); `Book::motion_state`
    /// reads its answer: the motion's own moving state, the `ERR` was another's; over twice with
    /// no `FIN` and nothing unreadable since, its `FIN` (which would have come first, in order)
    /// was never sent, and the `ERR` was its own. Before, the motion was taken as acknowledged
    /// at once and its call timed out with its own refusal in hand
    /// (`wsg-text:0x939e47e5d1d27846`: the unreadable line was the probe's own reply,
    /// `GRI\x10STATE=6`). Undecided just before the call's deadline, the held line is dropped
    /// and the call times out: a refusal that may be another line's is never handed over
    /// (`Book::release_due`). Whether `name` is such a motion.
    fn doubt_held_motion(
        &mut self,
        name: &'static str,
        held_seq: u64,
        seq: u64,
        now: Instant,
    ) -> bool {
        let Some(slot) = self.on_wire.get(name) else {
            return false;
        };
        let Some(
            held @ Held {
                error: Error::Device { line, .. },
                ..
            },
        ) = slot.held.as_ref().filter(|_| slot.expect == Expect::Fin)
        else {
            return false;
        };
        // The unreadable lines since the hold must all be able to be the replies of the
        // commands answered at once written between it and `seq` (which lost theirs): one more
        // may have held the motion's `ACK` and its `FIN` run together (`ACK GRIP\x0bFIN GRIP`),
        // and a state reported after that says nothing of whether it ran (review, session 11).
        let between = self
            .on_wire
            .values()
            .filter(|s| s.seq > held_seq && s.seq < seq && Book::answered_at_once(s))
            .count() as u64;
        if self.unreadable().saturating_sub(held.damages - held.holds) > between {
            return false;
        }
        tracing::warn!(%line, "wsg text: a parse error out of its place, and a line that could not be read after it: asking the gripper whether its motion runs");
        let line = line.clone();
        self.settle_before(held_seq - 1, line, seq, now);
        let unreadable = self.unreadable();
        if let Some(slot) = self.on_wire.get_mut(name) {
            slot.acked = true;
            slot.first_reply_lost = true;
            slot.unreadable_at_ack = unreadable;
            slot.doubt_at = Some(now);
        }
        true
    }

    /// The command `name` gets the `ERR` it held: the name is free. Whether it held one.
    fn release_held(&mut self, name: &'static str) -> bool {
        if self.on_wire.get(name).is_none_or(|s| s.held.is_none()) {
            return false;
        }
        if let Some(Slot {
            caller,
            held: Some(held),
            ..
        }) = self.on_wire.remove(name)
        {
            self.complete(caller, Err(held.error));
            self.freed.push(name);
        }
        true
    }

    /// The calls whose held `ERR` was not settled by `now`, just before their deadline, get it
    /// (as they would have without the doubt); but not a motion asked whether it runs, which
    /// may run: its held line is dropped.
    fn release_due(&mut self, now: Instant) {
        let due: Vec<&'static str> = self
            .on_wire
            .iter()
            .filter(|(_, s)| s.held.as_ref().is_some_and(|h| h.settle_at <= now))
            .map(|(&name, _)| name)
            .collect();
        for name in due {
            // A motion asked whether it runs (`Book::doubt_held_motion`) with no answer yet
            // may be running: its caller times out rather than get a refusal that may be
            // another line's (review, session 11); the motion is checked on as any overdue one.
            match self.on_wire.get_mut(name) {
                Some(slot) if slot.in_doubt() => slot.held = None,
                _ => {
                    self.release_held(name);
                }
            }
        }
    }

    /// A reply to the command written as `seq` arrived at `now`: the commands answered at once
    /// written before the damaged line and still unanswered lost their reply to it. They fail, and
    /// their names are free (no reply of theirs can come any more). A motion not yet
    /// acknowledged lost its first reply too, an `ACK` (its `FIN` may still come) or an `ERR`
    /// (none will): it is taken as acknowledged, with that damaged line after its `ACK`, so
    /// that once overdue it is checked with `GRIPSTATE?` and ends when the gripper reports no
    /// motion (issue 29 L; before, it was given up as unanswered: wsg-text:0xaa891d063fc824a5,
    /// `ERR HOME 4` lost in a line run together with `ERR MOVE 19`).
    fn settle(&mut self, seq: u64, now: Instant) {
        let Some((upto, line)) = self.damaged.take_if(|(upto, _)| seq > *upto) else {
            return;
        };
        for slot in self.on_wire.values_mut() {
            if slot.seq <= upto && slot.expect == Expect::Fin && !slot.acked {
                tracing::debug!(command = %slot.line, %line, "wsg text: a motion's first reply damaged, taken as acknowledged");
                slot.acked = true;
                slot.unreadable_at_ack = slot.unreadable_at_write;
                slot.first_reply_lost = true;
                // Without a give-up time (no timeout) it is asked whether it runs a while
                // after this (not at once: a motion just accepted might not show yet), else it
                // waited for ever for a `FIN` that an `ERR` lost in the damage never sends.
                slot.doubt_at = motion_doubt(slot.give_up_at, now);
            }
        }
        let lost: Vec<&'static str> = self
            .on_wire
            .iter()
            .filter(|(_, s)| s.seq <= upto && s.expect != Expect::Fin)
            .map(|(&name, _)| name)
            .collect();
        for name in lost {
            if let Some(slot) = self.on_wire.remove(name) {
                tracing::warn!(command = %slot.line, %line, "wsg text: reply damaged, call failed");
                // No line read (`Book::doubt`): its reply never came, or came unreadable.
                let reason = if line.is_empty() {
                    "no reply to it came (a later command was answered first)"
                } else {
                    "its reply could not be read (a later command was answered first)"
                };
                let error = Error::MalformedReply {
                    command: slot.line,
                    line: line.clone(),
                    reason: reason.into(),
                };
                self.complete(slot.caller, Err(error));
                self.freed.push(name);
            }
        }
    }

    /// Whether a reply to a line written after the one written as `upto` is needed to tell
    /// whether the commands answered at once written by then lost theirs: one of them is still
    /// unanswered, and no command written later waits for a reply due at once (whose reply
    /// would tell). A command whose `ERR` is held ([`Held`]) was answered, in doubt: no such
    /// reply is due to it.
    fn needs_probe(&self, upto: u64) -> bool {
        let suspects = self
            .on_wire
            .values()
            .any(|s| s.seq <= upto && Book::answered_at_once(s));
        let barrier = self
            .on_wire
            .values()
            .any(|s| s.seq > upto && s.held.is_none() && Book::answered_at_once(s));
        suspects && !barrier
    }

    /// A query to write after a damaged line, or after an `ERR` held in doubt ([`Held`]),
    /// when nothing written since waits for a reply the gripper sends at once: its answer
    /// tells which replies were lost, or whose the `ERR` was. `now`: when it is written.
    pub(crate) fn probe(
        &self,
        query_timeout: Duration,
        now: Instant,
    ) -> Option<Request<Option<C>>> {
        let query_timeout = probe_timeout(query_timeout);
        let damaged = self
            .damaged
            .as_ref()
            .is_some_and(|(upto, _)| self.needs_probe(*upto));
        let held = self
            .on_wire
            .values()
            .any(|s| s.held.is_some() && self.needs_probe(s.seq));
        if !damaged && !held {
            return None;
        }
        let (name, line) = PROBES
            .into_iter()
            .find(|(name, _)| !self.on_wire.contains_key(name))?;
        Some(Request {
            name,
            line: line.to_owned(),
            expect: Expect::Value,
            deadline: after(now, query_timeout),
            timeout: query_timeout,
            // Nobody waits for its answer: it is consumed when it comes.
            waiter: None,
            start: now,
            probe: true,
        })
    }

    /// The command on the wire whose give-up time came: an acknowledged motion is checked
    /// with `GRIPSTATE?` (a healthy slow motion is not a reason to give the connection up,
    /// issue 29 L; the gripper answers during motion, shared note §3.7), which this returns if
    /// it is to be written; anything else (or a motion reported over whose `FIN` still did not
    /// come) is `Err` with its line: the connection is given up. `now`: the give-up timer fired.
    pub(crate) fn overdue(
        &mut self,
        query_timeout: Duration,
        give_up_after: Duration,
        now: Instant,
    ) -> Result<Option<Request<Option<C>>>, String> {
        let query_timeout = probe_timeout(query_timeout);
        self.release_due(now);
        if let Some(check) = self.doubt(query_timeout, now) {
            // A probe for the replies due at once is written once this step is done
            // (`Book::probe`).
            return Ok(check);
        }
        let probe_free = !self.on_wire.contains_key("GRIPSTATE");
        let Some(slot) = self.on_wire.values_mut().min_by_key(|s| s.give_up_at) else {
            return Ok(None);
        };
        if slot.give_up_at > now {
            return Ok(None);
        }
        if slot.expect != Expect::Fin || !slot.acked || slot.over {
            return Err(slot.line.clone());
        }
        slot.checking = true;
        // Checked again after the probe's own give-up time (an unanswered probe gives the
        // connection up first), or after a GRIPSTATE? of the program's on the wire.
        let recheck = give_up_after.max(RECHECK_FLOOR);
        let wait = query_timeout.saturating_add(recheck);
        slot.give_up_at = after(now, wait.saturating_add(recheck));
        if !probe_free {
            return Ok(None);
        }
        tracing::debug!(command = %slot.line, "wsg text: motion overdue, asking its state");
        Ok(Some(Request {
            name: "GRIPSTATE",
            line: "GRIPSTATE?".to_owned(),
            expect: Expect::Value,
            deadline: after(now, query_timeout),
            timeout: query_timeout,
            // Nobody waits for its answer: it is consumed when it comes (and read by `on_line`).
            waiter: None,
            start: now,
            probe: true,
        }))
    }

    /// A `GRIPSTATE=` read (a probe's or a program's): the motions being checked still run, or
    /// are over (their `FIN` then has one more `give_up_after` to come).
    fn motion_state(&mut self, value: &str, give_up_after: Duration, now: Instant) {
        let state = parse_number(value)
            .filter(|v| v.fract() == 0.0 && (0.0..=255.0).contains(v))
            .map(|v| GripState::from_u8(v as u8));
        let over = matches!(
            state,
            Some(
                GripState::Idle
                    | GripState::NoPartFound
                    | GripState::PartLost
                    | GripState::Holding
                    | GripState::Error
            )
        );
        let unreadable = self.unreadable();
        let (mut ended, mut refused) = (Vec::new(), Vec::new());
        for (&name, slot) in self.on_wire.iter_mut().filter(|(_, s)| s.checking) {
            slot.checking = false;
            // A motion whose held `ERR` is in doubt (`Book::doubt_held_motion`): moving, the
            // `ERR` answered another line; over with nothing unreadable since, it was its own.
            // Over twice (one flipped bit turns `GRIPSTATE=1` into `=0`; the gripper answers
            // in order, so a FIN would have come before either report). A state that says
            // neither (damaged, reserved, another motion's) is asked again.
            // Moving, or over after a line that could not be read (maybe its `FIN`): the
            // held line goes, and the motion is checked as any other.
            if slot.in_doubt() {
                let moving = state.is_some() && state == moving_state(name);
                if over && unreadable == slot.unreadable_at_ack {
                    if slot.over_unconfirmed {
                        refused.push(name);
                        continue;
                    }
                    slot.over_unconfirmed = true;
                    slot.doubt_at = Some(after(now, RECHECK_FLOOR));
                    continue;
                }
                if !over && !moving {
                    slot.doubt_at = Some(after(now, RECHECK_FLOOR));
                    continue;
                }
                slot.held = None;
                slot.over_unconfirmed = false;
            }
            let against_order =
                over && unreadable == slot.unreadable_at_ack && !slot.first_reply_lost;
            let first = against_order && !slot.over_unconfirmed;
            slot.over_unconfirmed = first;
            slot.over = over && !first;
            slot.give_up_at = after(now, give_up_after.max(RECHECK_FLOOR));
            // Asked again later even when `give_up_after` is `Duration::MAX`.
            slot.doubt_at = motion_doubt(slot.give_up_at, now);
            tracing::debug!(command = %slot.line, value, over, first, "wsg text: overdue motion checked");
            // Over, and a line that could not be read came after its `ACK`: that was its `FIN`
            // or `ERR` (the gripper answers in order: it came before this state). The call
            // ends and the name is free (issue 29 M for motions). So too when its first reply
            // was lost: with no line read in its place (a request the gripper never read,
            // `Book::doubt`), none of its replies came, and none will
            // (`wsg-text:0x66c3c8e7252d7f83`: `HOME()` held with `give_up_after` `Duration::MAX`).
            if over && (unreadable > slot.unreadable_at_ack || slot.first_reply_lost) {
                ended.push(name);
            }
        }
        for name in ended {
            if let Some(slot) = self.on_wire.remove(name) {
                let error = Error::MalformedReply {
                    command: slot.line,
                    line: format!("GRIPSTATE={value}"),
                    reason:
                        "the motion is over and its FIN or ERR did not come or could not be read"
                            .into(),
                };
                self.complete(slot.caller, Err(error));
                self.freed.push(name);
            }
        }
        for name in refused {
            tracing::debug!(
                name,
                "wsg text: the motion never ran: the held parse error was its own"
            );
            self.release_held(name);
        }
    }

    /// After `BYE()`: whether `ACK BYE` may have been a reply line that could not be read. The
    /// gripper answers in order, one reply per command answered at once (shared note §3.7):
    /// once as many unreadable lines came since the oldest such command on the wire was
    /// written as there are such commands, `BYE()` included, each of them (`ACK BYE` too) may
    /// have been one. Nothing is written after `BYE()` (issue 29 N), so no later reply can
    /// settle it as `settle` does, nor a probe: without this, a `BYE()` without timeout whose
    /// `ACK BYE` arrived damaged waited for ever (`wsg-text:0x3bac8274f6da31e9`).
    fn bye_unreadable(&self) -> bool {
        let due = self.on_wire.values().filter(|s| Book::answered_at_once(s));
        let (count, oldest) = due.fold((0u64, u64::MAX), |(n, oldest), s| {
            (n + 1, oldest.min(s.damages_at_write))
        });
        self.on_wire.contains_key("BYE") && self.damages.saturating_sub(oldest) >= count
    }

    /// After `BYE()` (`closing`): if its `ACK BYE` may have been a line that could not be read
    /// ([`Book::bye_unreadable`]), its call fails with why and this is `true`: the session ends
    /// as at `BYE()`'s deadline, for nothing written after `BYE()` can ever tell.
    pub(crate) fn bye_lost_in_damage(&mut self) -> bool {
        if !self.bye_unreadable() {
            return false;
        }
        if let Some(slot) = self.on_wire.remove("BYE") {
            let line = self
                .damaged
                .take()
                .map(|(_, line)| line)
                .unwrap_or_default();
            tracing::warn!(%line, "wsg text: ACK BYE could not be read, connection closed");
            let error = Error::MalformedReply {
                command: slot.line,
                line,
                reason: "a line that could not be read came where ACK BYE was due".into(),
            };
            self.complete(slot.caller, Err(error));
        }
        true
    }

    /// `BYE()`'s call is over (its deadline, its `timeout`) without `ACK BYE`: its caller is told
    /// it timed out (not `Closed`), and it leaves the book.
    pub(crate) fn bye_timed_out(&mut self, timeout: Duration) {
        if let Some(slot) = self.on_wire.remove("BYE") {
            let error = Error::Timeout {
                command: slot.line,
                timeout,
            };
            self.complete(slot.caller, Err(error));
        }
    }

    /// The callers the task watches for leaving: `BYE()`'s if it is on the wire, and those of
    /// the requests waiting for their name (borrowed apart, so that both are watched at once).
    pub(crate) fn watched(&mut self) -> (Option<&mut C>, WaitingCallers<'_, C>) {
        let bye = self
            .on_wire
            .get_mut("BYE")
            .and_then(|slot| slot.caller.as_mut());
        (bye, WaitingCallers(&mut self.waiting))
    }

    /// The earliest give-up time of the commands on the wire, time to doubt a reply
    /// (`Book::doubt`) or to hand over a held `ERR` ([`Held`]), whichever comes first: the
    /// task's timer.
    pub(crate) fn give_up_at(&self) -> Option<Instant> {
        self.on_wire
            .values()
            .map(|s| {
                let at = s.doubt_at.map_or(s.give_up_at, |d| d.min(s.give_up_at));
                s.held.as_ref().map_or(at, |h| h.settle_at.min(at))
            })
            .min()
    }

    /// The commands unanswered [`DOUBT_AFTER`] after they were written (`now`; `None` if
    /// none). A reply due at once that stayed away puts every command written so far in doubt,
    /// as a line that could not be read does, so that the next reply to a line written later
    /// settles them (the gripper answers in order, shared note §3.7: a reply due before it that
    /// did not come is lost) and a probe is written to draw one ([`Book::probe`]). An
    /// acknowledged motion is checked as an overdue one is (issue 29 L): `GRIPSTATE?`, returned
    /// to be written unless one is on the wire already.
    fn doubt(
        &mut self,
        query_timeout: Duration,
        now: Instant,
    ) -> Option<Option<Request<Option<C>>>> {
        let (mut at_once, mut motions) = (false, false);
        for slot in self.on_wire.values_mut() {
            if slot.doubt_at.is_none_or(|at| at > now) {
                continue;
            }
            slot.doubt_at = None;
            tracing::debug!(
                command = %slot.line,
                "wsg text: no reply long after it was written, asking"
            );
            if Book::answered_at_once(slot) {
                at_once = true;
            } else {
                slot.checking = true;
                motions = true;
                // Asked again later if this check's answer is lost too (its own reply run
                // into a damaged `FIN` before it: `wsg-text:0x3ad6c8b5ae93909a`).
                slot.doubt_at = Some(after(now, DOUBT_AFTER));
            }
        }
        if at_once {
            self.damaged = Some((self.sent, String::new()));
        }
        if !motions || self.on_wire.contains_key("GRIPSTATE") {
            return (at_once || motions).then_some(None);
        }
        Some(Some(Request {
            name: "GRIPSTATE",
            line: "GRIPSTATE?".to_owned(),
            expect: Expect::Value,
            deadline: after(now, query_timeout),
            timeout: query_timeout,
            waiter: None,
            start: now,
            probe: true,
        }))
    }

    fn finish(&mut self, name: &str, result: Result<Answer, Error>) {
        if let Some(slot) = self.on_wire.remove(name) {
            // A caller that left (timeout, dropped future) no longer listens: its reply is
            // consumed here and goes to nobody else.
            self.complete(slot.caller, result);
        }
    }

    /// Names freed by calls failed because their reply was damaged (or their motion's `FIN`
    /// could not be read), in order: their next waiting requests go out (not after `BYE()`).
    pub(crate) fn take_freed(&mut self) -> Vec<&'static str> {
        std::mem::take(&mut self.freed)
    }

    /// Drops the waiting requests whose caller left, and fails those whose time ran out
    /// (`now`), so the queue holds only requests someone still waits for (issue 29 K: a queue
    /// full of calls given up blocked every other call).
    pub(crate) fn prune(&mut self, now: Instant) {
        if self
            .waiting
            .iter()
            .any(|r| r.waiter.gave_up() || now >= r.deadline)
        {
            let waiting = std::mem::take(&mut self.waiting);
            self.waiting = waiting
                .into_iter()
                .filter_map(|r| usable(r, now, &mut self.done))
                .collect();
        }
    }

    /// `BYE()` was written: the requests waiting for their name are never sent now, and fail
    /// [`Error::Closed`] (issue 29 N).
    pub(crate) fn close_waiting(&mut self) {
        for request in self.waiting.drain(..) {
            self.done.push((request.waiter, Err(Error::Closed)));
        }
    }

    /// The connection ended for `reason`: every call on the wire (in the order of their names)
    /// and every call waiting for its name fails with it. The book is empty afterwards.
    pub(crate) fn drain(&mut self, reason: &Error) {
        while let Some((_, slot)) = self.on_wire.pop_first() {
            // A held `ERR` came from the gripper: the call gets it, as it would have without
            // the doubt.
            // Not a motion's in doubt (`Book::doubt_held_motion`): it may run.
            let in_doubt = slot.in_doubt();
            let held = slot.held.filter(|_| !in_doubt);
            let error = held.map_or_else(|| reason.clone(), |h| h.error);
            self.complete(slot.caller, Err(error));
        }
        for request in self.waiting.drain(..) {
            self.done.push((request.waiter, Err(reason.clone())));
        }
    }

    /// How many requests wait for their name.
    pub(crate) fn waiting_len(&self) -> usize {
        self.waiting.len()
    }

    /// The earliest deadline of the waiting requests.
    pub(crate) fn waiting_deadline(&self) -> Option<Instant> {
        self.waiting.iter().map(|r| r.deadline).min()
    }

    /// Takes a request read from a channel at `now`: the request to send now if its name is
    /// free, else it waits for its name.
    pub(crate) fn admit(&mut self, request: Request<C>, now: Instant) -> Option<Request<C>> {
        let request = usable(request, now, &mut self.done)?;
        let request = self.answer_from_probe(request)?;
        if self.on_wire.contains_key(request.name) {
            self.prune(now);
            self.waiting.push_back(request);
            None
        } else {
            Some(request)
        }
    }

    /// Answers `request` with a probe's answer if it is the probe's very query and was made
    /// before the probe was written (`None`), else gives it back. The probe is the same line,
    /// read by the gripper after the call was made, so its answer is the gripper's answer to
    /// that query during the call; without this a call that came in behind the client's own
    /// probe of its name waited for the probe's answer, then wrote its line again and could
    /// time out while the answer had come in time (rule 7, `wsg-text:0xe5281323574dafa8`). One
    /// answer serves one call: a later call of the name asks the gripper itself.
    fn answer_from_probe(&mut self, request: Request<C>) -> Option<Request<C>> {
        let fits = self
            .probe_answers
            .get(request.name)
            .is_some_and(|(at, line, _)| request.start <= *at && *line == request.line);
        if !fits || request.expect != Expect::Value {
            return Some(request);
        }
        let (_, _, value) = self.probe_answers.remove(request.name)?;
        tracing::debug!(command = %request.line, %value, "wsg text: answered by the client's own probe");
        self.done.push((request.waiter, Ok(Answer::Value(value))));
        None
    }

    /// The next waiting request of `name` that still has a caller and time (`now`), if any.
    pub(crate) fn next_waiting(&mut self, name: &str, now: Instant) -> Option<Request<C>> {
        loop {
            let i = self.waiting.iter().position(|r| r.name == name)?;
            let request = self.waiting.remove(i)?;
            let request = usable(request, now, &mut self.done);
            if let Some(request) = request.and_then(|r| self.answer_from_probe(r)) {
                return Some(request);
            }
        }
    }

    /// Handles one reply line, read at `now`.
    pub(crate) fn on_line(&mut self, text: &str, now: Instant) -> Handled {
        let reply = match parse_reply(text) {
            Ok(reply) => reply,
            Err(why) => {
                tracing::warn!(line = text, %why, "wsg text: reply that is not GCL, dropped");
                self.damage(text);
                return Handled::Nothing;
            }
        };
        let name = match reply {
            ReplyLine::Push { name, value } => {
                return match (Quantity::from_name(name), parse_number(value)) {
                    (Some(quantity), Some(value)) => Handled::Push(Push { quantity, value }),
                    // Every pushed value is a number (shared note §3.10): one that is none was
                    // damaged on the way, maybe by an LF read as another character that ran
                    // the push and the next reply together (`@POS=104.7JERR HOME 19`: HOME's
                    // ERR swallowed in the push's value, wsg-text:0xaead2f1fc4928e38). It
                    // counts as a line that could not be read, as a reply's value that is no
                    // number does, so that a motion whose reply it may have held ends when
                    // the gripper reports it over (issue 29 L) and a query whose reply it may
                    // have held is settled (issue 29 M).
                    (_, None) => {
                        tracing::warn!(
                            line = text,
                            "wsg text: push whose value is no number, dropped"
                        );
                        self.damage(text);
                        Handled::Nothing
                    }
                    (None, Some(_)) => {
                        tracing::debug!(line = text, "wsg text: push not understood, dropped");
                        Handled::Nothing
                    }
                };
            }
            ReplyLine::Ack(n) | ReplyLine::Fin(n) | ReplyLine::Value { name: n, .. } => n,
            ReplyLine::Err { name: Some(n), .. } => n,
            ReplyLine::Err { name: None, .. } => {
                // No name: it cannot be paired with confidence (§4.3). The caller it was meant
                // for times out rather than a wrong caller failing.
                tracing::warn!(line = text, "wsg text: ERR without a command name, dropped");
                self.damage(text);
                return Handled::Nothing;
            }
        };
        // Names are compared upper-cased: the manual's replies are upper case (§2), a
        // lower-case one is still the same command.
        let Some((&key, slot)) = self
            .on_wire
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
        else {
            tracing::debug!(
                line = text,
                "wsg text: reply for no command on the wire, dropped"
            );
            // A name damaged on the way reads as another name.
            self.damage(text);
            return Handled::Nothing;
        };
        // A reply due at once comes in the order the lines were written (an acknowledged
        // motion's `FIN` or `ERR` comes when the motion ends).
        // No accepted motion ends with a parse error (14, 15: the gripper could not read a
        // line, §4.3), and the client writes one command of a name at a time: one under the
        // name of an acknowledged motion answered another line, damaged into that name (its
        // check `GRIPSTATE?` read as `GRIP\x13TATE?`, review, session 11). Not its end.
        if matches!(
            reply,
            ReplyLine::Err {
                code: Some(14 | 15),
                ..
            }
        ) && slot.expect == Expect::Fin
            && slot.acked
        {
            tracing::warn!(line = text, command = %slot.line, "wsg text: a parse error in the name of a running motion: another line's, damaged");
            self.damage(text);
            return Handled::Nothing;
        }
        let in_order = Book::answered_at_once(slot) && !matches!(reply, ReplyLine::Fin(_));
        let seq = slot.seq;
        if self.hold(key, &reply, text, now) {
            return Handled::Nothing;
        }
        if in_order {
            self.settle_held(key, seq, now);
        }
        let unreadable = self.unreadable();
        let Some(slot) = self.on_wire.get_mut(key) else {
            return Handled::Nothing;
        };
        // A motion's `FIN` comes after its `ACK`, which the gripper sends at once (§3 of the
        // text interface note: `ACK <NAME>` at once, `FIN <NAME>` when done). One read before
        // any `ACK` of the motion on the wire, with no line since its write that could have
        // been that `ACK` unreadable, ends another motion of the name: one whose replies
        // another call took, after a damaged line answered in its name
        // (`wsg-text:0xa1fd31cdef49e64e`: GRIP's replies one behind after `GRIPSTATE?`,
        // damaged into `GRIP[TATE?`, was answered `ERR GRIP 15`; that `FIN GRIP` reported a
        // GRIP done which the gripper had only just read). Dropped, not its end.
        if matches!(reply, ReplyLine::Fin(_))
            && slot.expect == Expect::Fin
            && !slot.acked
            && unreadable == slot.unreadable_at_write
        {
            tracing::warn!(
                line = text,
                command = %slot.line,
                "wsg text: FIN before the ACK of the motion on the wire: another motion's, dropped"
            );
            return Handled::Nothing;
        }
        // A reply to a line written after a damaged one: the replies before it have come.
        // (A motion's `FIN` is no such sign: it comes when the motion ends.)
        if !matches!(reply, ReplyLine::Fin(_)) {
            if matches!(reply, ReplyLine::Ack(_)) && slot.expect == Expect::Fin {
                slot.acked = true;
                slot.unreadable_at_ack = unreadable;
                slot.doubt_at = motion_doubt(slot.give_up_at, now);
            }
            self.settle(seq, now);
        }
        if let (ReplyLine::Value { value, .. }, "GRIPSTATE") = (reply, key) {
            self.motion_state(value, self.give_up_after, now);
        }
        let Some(slot) = self.on_wire.get(key) else {
            return Handled::Nothing;
        };
        let mut unreadable = false;
        let result = match (reply, slot.expect) {
            (ReplyLine::Err { code, .. }, _) => Err(Error::Device {
                command: slot.line.clone(),
                status: code.map(Status::from_code),
                line: text.to_owned(),
            }),
            (ReplyLine::Ack(_), Expect::Ack) | (ReplyLine::Fin(_), Expect::Fin) => Ok(Answer::Done),
            // The motion was accepted; its FIN or ERR follows.
            (ReplyLine::Ack(_), Expect::Fin) => return Handled::Nothing,
            // Every value the client asks for is a number (`Client::number`): one that is none
            // was damaged on the way, maybe by an LF read as another character that ran two
            // replies together (`GRIPSTATE=6JFIN MOVE`: MOVE's FIN swallowed in GRIPSTATE's
            // value, wsg-text:0x837af21cd1f4f6c7). It counts as a line that could not be read
            // (below), so that a motion whose reply it may have held is checked as after any
            // damaged line (issue 29 L).
            (ReplyLine::Value { value, .. }, Expect::Value) if parse_number(value).is_none() => {
                unreadable = true;
                Err(Error::MalformedReply {
                    command: slot.line.clone(),
                    line: text.to_owned(),
                    reason: "not a finite number".into(),
                })
            }
            (ReplyLine::Value { value, .. }, Expect::Value) => {
                // A probe's answer: kept for a call of its query made before it was written.
                if let Some(at) = slot.probe_at {
                    let answer = (at, slot.line.clone(), value.to_owned());
                    self.probe_answers.insert(key, answer);
                }
                Ok(Answer::Value(value.to_owned()))
            }
            _ => Err(Error::UnexpectedReply {
                command: slot.line.clone(),
                line: text.to_owned(),
            }),
        };
        let bye = key == "BYE" && result.is_ok();
        self.finish(key, result);
        if unreadable {
            self.damage(text);
        }
        if bye {
            Handled::Bye
        } else {
            Handled::Freed(key)
        }
    }
}

/// The callers of the requests waiting for their name ([`Book::watched`]).
pub(crate) struct WaitingCallers<'a, C>(&'a mut VecDeque<Request<C>>);

impl<C> WaitingCallers<'_, C> {
    /// Each caller, in the order their requests wait.
    pub(crate) fn iter_mut(&mut self) -> impl Iterator<Item = &mut C> {
        self.0.iter_mut().map(|r| &mut r.waiter)
    }
}

/// What one reply line did.
#[derive(Debug)]
pub(crate) enum Handled {
    /// Nothing a caller waits for (an `ACK` of a motion, a line for nobody).
    Nothing,
    /// A push (`AUTOSEND`): for the subscribers.
    Push(Push),
    /// Answered the command of this name: the name is free.
    Freed(&'static str),
    /// `ACK BYE`: the session is over.
    Bye,
}

/// The request, unless its caller left or its time ran out at `now` (then it is answered, in
/// `done`, and dropped: a command nobody waits for must not move the fingers later).
fn usable<C: Caller>(
    request: Request<C>,
    now: Instant,
    done: &mut Vec<(C, Result<Answer, Error>)>,
) -> Option<Request<C>> {
    if request.waiter.gave_up() {
        tracing::debug!(command = %request.line, "wsg text: caller gone before sending, dropped");
        return None;
    }
    if now >= request.deadline {
        let error = Error::Timeout {
            command: request.line,
            timeout: request.timeout,
        };
        done.push((request.waiter, Err(error)));
        return None;
    }
    Some(request)
}

/// The rules driven without a runtime: plain `#[test]`s, the clock passed in, callers that are
/// numbers.
#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::rc::Rc;

    use super::*;
    use crate::caller::test::Call;

    const S: Duration = Duration::from_secs(1);
    const GIVE_UP_AFTER: Duration = Duration::from_secs(5);

    /// Call `id`'s request `line` (replies name it `name`), made at `now`, its caller waiting
    /// a second; and the handle that makes its caller give up.
    fn request(
        id: u8,
        name: &'static str,
        line: &str,
        expect: Expect,
        now: Instant,
    ) -> (Request<Call>, Rc<Cell<bool>>) {
        let gone = Rc::new(Cell::new(false));
        let request = Request {
            name,
            line: line.into(),
            expect,
            deadline: now + S,
            timeout: S,
            waiter: Call {
                id,
                gone: Rc::clone(&gone),
            },
            start: now,
            probe: false,
        };
        (request, gone)
    }

    /// Writes `request` (as the task does once the book let it go out) at `now`.
    fn write(book: &mut Book<Call>, request: Request<Option<Call>>, now: Instant) {
        let give_up_at = after(request.deadline, GIVE_UP_AFTER);
        let Request {
            name,
            line,
            expect,
            waiter,
            probe,
            deadline,
            ..
        } = request;
        book.on_wire(name, line, expect, waiter, deadline, give_up_at, now, probe);
    }

    /// Admits call `id` at `now` and writes it if its name is free; whether it was written.
    fn call(
        book: &mut Book<Call>,
        id: u8,
        name: &'static str,
        line: &str,
        expect: Expect,
        now: Instant,
    ) -> bool {
        let (r, _) = request(id, name, line, expect, now);
        match book.admit(r, now) {
            Some(r) => {
                write(book, r.outgoing(), now);
                true
            }
            None => false,
        }
    }

    /// The calls completed so far, by number: `Ok(value)` (empty for `ACK`/`FIN`) or the error.
    fn done(book: &mut Book<Call>) -> Vec<(u8, std::result::Result<String, Error>)> {
        book.completions()
            .map(|(c, r)| {
                let r = r.map(|a| match a {
                    Answer::Value(v) => v,
                    Answer::Done => String::new(),
                });
                (c.id, r)
            })
            .collect()
    }

    #[test]
    fn replies_pair_by_name_and_a_query_runs_beside_a_motion() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "MOVE", "MOVE(10)", Expect::Fin, t0));
        assert!(call(&mut book, 2, "POS", "POS?", Expect::Value, t0));
        assert!(matches!(book.on_line("ACK MOVE", t0), Handled::Nothing));
        assert!(matches!(book.on_line("POS=3.5", t0), Handled::Freed("POS")));
        assert!(matches!(
            book.on_line("FIN MOVE", t0 + S),
            Handled::Freed("MOVE")
        ));
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(2, Ok(v)), (1, Ok(e))] if v == "3.5" && e.is_empty()),
            "{done:?}"
        );
        assert_eq!(book.give_up_at(), None);
    }

    #[test]
    fn a_busy_name_waits_and_goes_out_when_freed() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(!call(&mut book, 2, "POS", "POS?", Expect::Value, t0));
        assert_eq!(book.waiting_len(), 1);
        assert!(matches!(book.on_line("POS=1", t0), Handled::Freed("POS")));
        let next = book
            .next_waiting("POS", t0)
            .expect("the second POS? goes out");
        assert_eq!(next.waiter.id, 2);
        assert_eq!(book.waiting_len(), 0);
        assert!(matches!(&done(&mut book)[..], [(1, Ok(v))] if v == "1"));
    }

    #[test]
    fn a_waiting_request_whose_caller_left_or_whose_time_ran_out_is_never_sent() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        let (r2, gone2) = request(2, "POS", "POS?", Expect::Value, t0);
        let (r3, _) = request(3, "POS", "POS?", Expect::Value, t0);
        assert!(book.admit(r2, t0).is_none() && book.admit(r3, t0).is_none());
        gone2.set(true);
        // Call 3's deadline passes: it fails `Timeout`; call 2 left: dropped, told nothing.
        book.prune(t0 + S);
        assert_eq!(book.waiting_len(), 0);
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(3, Err(Error::Timeout { .. }))]),
            "{done:?}"
        );
    }

    /// A motion's `FIN` comes after its `ACK`: one read before the `ACK` of the motion on the
    /// wire, no unreadable line since its write, is another motion's (the damaged name's
    /// cascade, `wsg-text:0xa1fd31cdef49e64e`) and ends nothing. After an unreadable line
    /// (which may have been the `ACK`) it ends the motion, as before.
    #[test]
    fn a_fin_before_the_motions_ack_is_another_motions() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("FIN GRIP", t0), Handled::Nothing));
        assert!(done(&mut book).is_empty(), "not its end");
        assert!(matches!(book.on_line("ACK GRIP", t0), Handled::Nothing));
        assert!(matches!(
            book.on_line("FIN GRIP", t0 + S),
            Handled::Freed("GRIP")
        ));
        assert!(matches!(&done(&mut book)[..], [(1, Ok(e))] if e.is_empty()));
        // An unreadable line after the write may have been its ACK: the FIN ends it.
        assert!(call(&mut book, 2, "GRIP", "GRIP(20)", Expect::Fin, t0));
        book.damage("ACK G\u{1}IP");
        assert!(matches!(
            book.on_line("FIN GRIP", t0 + S),
            Handled::Freed("GRIP")
        ));
        assert!(matches!(&done(&mut book)[..], [(2, Ok(e))] if e.is_empty()));
    }

    /// Issue 29 M: a line that cannot be read, then the reply of a command written after it:
    /// the command answered at once written before it lost its reply, fails and frees its name.
    #[test]
    fn a_damaged_line_is_settled_by_a_later_reply() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        book.damage("P\u{1}S=1");
        // Nothing written since waits for an answer at once: a probe asks.
        let probe = book.probe(S, t0).expect("a probe");
        assert_eq!(
            (probe.name, probe.line.as_str()),
            ("GRIPSTATE", "GRIPSTATE?")
        );
        assert!(probe.waiter.is_none(), "nobody waits for a probe's answer");
        assert_eq!(probe.deadline, t0 + S);
        write(&mut book, probe, t0);
        assert!(
            book.probe(S, t0).is_none(),
            "the probe is a barrier already"
        );
        assert!(matches!(
            book.on_line("GRIPSTATE=0", t0),
            Handled::Freed("GRIPSTATE")
        ));
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{done:?}"
        );
        assert_eq!(book.take_freed(), ["POS"]);
    }

    /// A parse error (`ERR GRIP 15`) while `GRIPSTATE?`, written before `GRIP(…)`, still waits
    /// for its reply may be the answer to `GRIPSTATE?` damaged into `GRIP\x13TATE?`
    /// (`wsg-text:0xba0682223c8b01a8`). It is held: `GRIP`'s own `ACK` (or a reply to a line
    /// written between them, as `TEMP=` in the seed) shows it was another's, which counts as a
    /// damaged line (`GRIPSTATE?` lost its reply to it), and GRIP ends with its own `FIN`.
    #[test]
    fn a_parse_error_out_of_its_place_is_settled_by_the_next_reply() {
        // The replies after the held line, in order; with `TEMP?` written between the two.
        for (between, after) in [
            (false, &["ACK GRIP", "FIN GRIP"][..]),
            (true, &["TEMP=23.4", "ACK GRIP", "FIN GRIP"][..]),
        ] {
            let t0 = Instant::now();
            let mut book = Book::new(GIVE_UP_AFTER);
            let query = Expect::Value;
            assert!(call(&mut book, 1, "GRIPSTATE", "GRIPSTATE?", query, t0));
            if between {
                assert!(call(&mut book, 2, "TEMP", "TEMP?", Expect::Value, t0));
            }
            assert!(call(&mut book, 3, "GRIP", "GRIP(10)", Expect::Fin, t0));
            assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
            assert!(done(&mut book).is_empty(), "GRIP did not take it");
            book.on_line(after[0], t0);
            let first = done(&mut book);
            assert!(
                matches!(&first[..], [(1, Err(Error::MalformedReply { line, .. })), ..] if line == "ERR GRIP 15"),
                "{after:?}: {first:?}"
            );
            if between {
                assert!(
                    matches!(&first[1..], [(2, Ok(v))] if v == "23.4"),
                    "{first:?}"
                );
            }
            for line in &after[1..] {
                book.on_line(line, t0);
            }
            let rest = done(&mut book);
            assert!(matches!(&rest[..], [(3, Ok(_))]), "{after:?}: {rest:?}");
        }
    }

    /// A held parse error that was the command's own: a probe draws a reply to a line written
    /// after it, which settles it for the command; with no reply at all, the call gets it just
    /// before its deadline. In its place (nothing written before it waits), it is the answer
    /// at once.
    #[test]
    fn a_held_parse_error_of_its_own_reaches_its_call() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        let probe = book.probe(S, t0).expect("a probe draws the next reply");
        assert_eq!(probe.line, "GRIPSTATE?");
        write(&mut book, probe, t0);
        assert!(book.probe(S, t0).is_none(), "the probe's reply will tell");
        book.on_line("GRIPSTATE=0", t0);
        let first = done(&mut book);
        assert!(
            matches!(
                &first[..],
                [
                    (
                        2,
                        Err(Error::Device {
                            status: Some(Status::CmdFormatError),
                            ..
                        })
                    ),
                    // In order, POS?'s reply came before GRIP's: it was lost.
                    (1, Err(Error::MalformedReply { .. }))
                ]
            ),
            "{first:?}"
        );
        assert_eq!(book.take_freed(), ["GRIP", "POS"]);

        // No reply comes: the call gets it just before its deadline (`call`'s is a second).
        assert!(call(&mut book, 4, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 3, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 14", t0), Handled::Nothing));
        assert_eq!(book.give_up_at(), Some(t0 + S - HELD_MARGIN));
        let overdue = book.overdue(S, GIVE_UP_AFTER, t0 + S - HELD_MARGIN);
        assert!(matches!(overdue, Ok(None)), "{overdue:?}");
        let second = done(&mut book);
        assert!(
            matches!(
                &second[..],
                [(
                    3,
                    Err(Error::Device {
                        status: Some(Status::CmdUnknown),
                        ..
                    })
                )]
            ),
            "{second:?}"
        );

        // In its place: at once.
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 4, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(call(&mut book, 5, "POS", "POS?", Expect::Value, t0));
        assert!(matches!(
            book.on_line("ERR GRIP 15", t0),
            Handled::Freed("GRIP")
        ));
        let third = done(&mut book);
        assert!(
            matches!(&third[..], [(4, Err(Error::Device { .. }))]),
            "{third:?}"
        );
    }

    /// A stop's parse error is never held: the stop's name must free at once, for the next
    /// stop goes out only then (`wsg-text:0x1836d2bb3a465209`: a second `STOP()` waited 40 ms
    /// behind a held `ERR STOP 15`).
    #[test]
    fn a_stops_parse_error_is_never_held() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "STOP", "STOP()", Expect::Ack, t0));
        assert!(matches!(
            book.on_line("ERR STOP 15", t0),
            Handled::Freed("STOP")
        ));
        assert!(matches!(
            &done(&mut book)[..],
            [(2, Err(Error::Device { .. }))]
        ));
    }

    /// A parse error is in its place when each command written before it that still waits for
    /// a reply due at once may have had it in a line that could not be read: MOVE's `ACK`
    /// arrived as `ICK MOVE`, and the probe written after it was answered `ERR GRIPSTATE 15`
    /// (its line run into the next): the probe's own (`wsg-text:0xe64ab80fb0bf18a2`, where a
    /// held one was then taken for MOVE's by MOVE's `ERR MOVE 19`, and the probe's name stayed
    /// unanswered until the connection was given up).
    #[test]
    fn a_parse_error_behind_an_unreadable_line_is_in_its_place() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "MOVE", "MOVE(51)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ICK MOVE", t0), Handled::Nothing));
        let probe = book.probe(S, t0).expect("a probe");
        write(&mut book, probe, t0);
        assert!(matches!(
            book.on_line("ERR GRIPSTATE 15", t0),
            Handled::Freed("GRIPSTATE")
        ));
    }

    /// A line that could not be read after a held one may have been the held command's own
    /// reply (GRIP's `ACK` read as `ICK GRIP`): the held `ERR GRIP 15` may then be the earlier
    /// query's, and GRIP runs. A later reply settles it as a reply lost in the damage (GRIP is
    /// taken as acknowledged, its `FIN` ends it), never as GRIP's refusal (review, session 10).
    #[test]
    fn a_held_parse_error_followed_by_an_unreadable_line_is_no_ones_for_sure() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(
            &mut book,
            1,
            "GRIPSTATE",
            "GRIPSTATE?",
            Expect::Value,
            t0
        ));
        assert!(call(&mut book, 2, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        assert!(matches!(book.on_line("ICK GRIP", t0), Handled::Nothing));
        let probe = book.probe(S, t0).expect("a probe");
        assert_eq!(probe.line, "POS?");
        write(&mut book, probe, t0);
        book.on_line("POS=1.0", t0);
        let first = done(&mut book);
        assert!(
            matches!(&first[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{first:?}"
        );
        book.on_line("FIN GRIP", t0);
        let second = done(&mut book);
        assert!(matches!(&second[..], [(2, Ok(_))]), "{second:?}");
    }

    /// The book of `wsg-text:0x939e47e5d1d27846` up to the moment GRIP is in doubt: POS?, then
    /// GRIP(79.5), whose own `ERR GRIP 15` (its argument damaged on the way) is held behind
    /// POS?; the probe's own reply cannot be read (`GRI\x10STATE=6`), and a second probe's
    /// answer settles POS? as lost. GRIP's check (`GRIPSTATE?`) is written at `t0`.
    fn grip_in_doubt(t0: Instant) -> Book<Call> {
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "GRIP", "GRIP(79.5)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        let probe = book.probe(S, t0).expect("a probe draws the next reply");
        assert_eq!(probe.line, "GRIPSTATE?");
        write(&mut book, probe, t0);
        book.damage("GRI\u{10}STATE=6");
        let probe = book.probe(S, t0).expect("a second probe");
        let answer = format!("{}=1.0", probe.name);
        write(&mut book, probe, t0);
        book.on_line(&answer, t0);
        let first = done(&mut book);
        assert!(
            matches!(&first[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{first:?}"
        );
        ask(&mut book, t0);
        book
    }

    /// The check `overdue` writes at `now` for a motion in doubt.
    fn ask(book: &mut Book<Call>, now: Instant) {
        let check = book.overdue(S, GIVE_UP_AFTER, now);
        let Ok(Some(check)) = check else {
            panic!("no check at {now:?}: {check:?}")
        };
        assert_eq!(check.line, "GRIPSTATE?");
        write(book, check, now);
    }

    /// `wsg-text:0x939e47e5d1d27846` (`grip_in_doubt`): GRIP is asked whether it runs. Idle
    /// twice (one flipped bit turns `GRIPSTATE=1` into `=0`) with nothing unreadable since:
    /// GRIP never ran, and the `ERR` was its own (before, the call timed out with its refusal
    /// in hand). Its own motion's state (Grasping): the `ERR` was another's, dropped, and
    /// GRIP's `FIN` ends it. Another motion's state, or a parse error in GRIP's name (the
    /// check damaged into it): asked again. Over after an unreadable line (maybe its `FIN`): a
    /// reply lost. Unanswered at the deadline: the call is left to time out, never handed a
    /// refusal that may be another line's.
    #[test]
    fn a_held_motion_in_doubt_is_settled_by_the_grippers_state() {
        let refused = |outcome: &[(u8, std::result::Result<String, Error>)]| {
            matches!(outcome, [(2, Err(Error::Device { line, status, .. }))]
                if line == "ERR GRIP 15" && *status == Some(Status::CmdFormatError))
        };
        let recheck = |t0: Instant| t0 + RECHECK_FLOOR;
        let deadline = |t0: Instant| t0 + S - HELD_MARGIN;

        // Idle, twice.
        let t0 = Instant::now();
        let mut book = grip_in_doubt(t0);
        book.on_line("GRIPSTATE=0", t0);
        assert!(done(&mut book).is_empty(), "one report is not enough");
        ask(&mut book, recheck(t0));
        book.on_line("GRIPSTATE=0", recheck(t0));
        let outcome = done(&mut book);
        assert!(refused(&outcome), "{outcome:?}");
        assert!(!book.on_wire.contains_key("GRIP"));

        // Idle once (a damaged value), then Grasping: it runs.
        for first in ["GRIPSTATE=0", "GRIPSTATE=6", "ERR GRIP 15"] {
            let mut book = grip_in_doubt(t0);
            book.on_line(first, t0);
            assert!(done(&mut book).is_empty(), "{first}");
            if first == "ERR GRIP 15" {
                // The check's own reply, damaged into GRIP's name, is lost: a probe's answer
                // settles it, and GRIP runs on.
                let probe = book.probe(S, t0).expect("a probe");
                assert_eq!(probe.line, "POS?");
                write(&mut book, probe, t0);
                book.on_line("POS=1.0", t0);
                assert!(done(&mut book).iter().all(|(id, _)| *id != 2), "{first}");
                assert!(book.on_wire.contains_key("GRIP"), "{first}: not its end");
                continue;
            }
            ask(&mut book, recheck(t0));
            book.on_line("GRIPSTATE=1", recheck(t0));
            assert!(book.overdue(S, GIVE_UP_AFTER, deadline(t0)).is_ok());
            assert!(
                done(&mut book).is_empty(),
                "{first}: the held line is dropped"
            );
            book.on_line("FIN GRIP", t0 + 2 * S);
            let outcome = done(&mut book);
            assert!(matches!(&outcome[..], [(2, Ok(_))]), "{first}: {outcome:?}");
        }

        // Over after a line that could not be read: its FIN may have been in it.
        let mut book = grip_in_doubt(t0);
        book.damage("FIN G\u{1}IP");
        book.on_line("GRIPSTATE=0", t0);
        let outcome = done(&mut book);
        assert!(
            matches!(&outcome[..], [(2, Err(Error::MalformedReply { .. }))]),
            "{outcome:?}"
        );

        // No answer by the deadline: no refusal; the motion stays, checked as any other.
        let mut book = grip_in_doubt(t0);
        assert!(book.overdue(S, GIVE_UP_AFTER, deadline(t0)).is_ok());
        assert!(done(&mut book).is_empty());
        assert!(book.on_wire.get("GRIP").is_some_and(|s| s.held.is_none()));

        // The connection ends: the connection's error, not the refusal in doubt.
        let mut book = grip_in_doubt(t0);
        book.drain(&Error::Closed);
        let outcome = done(&mut book);
        assert!(
            matches!(&outcome[..], [(2, Err(Error::Closed)), ..]),
            "{outcome:?}"
        );
    }

    /// The unreadable lines since the hold outnumber the replies due at once written between
    /// it and the settling reply: one of them may have held GRIP's `ACK` and `FIN` run
    /// together (`ACK GRIP\x0bFIN GRIP`, a fast grip), so a state reported now says nothing
    /// of whether it ran. It is not asked: no refusal, ever; a reply lost (review, session 11).
    #[test]
    fn a_held_motion_whose_end_may_be_unreadable_is_not_refused() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        let query = Expect::Value;
        assert!(call(&mut book, 1, "GRIPSTATE", "GRIPSTATE?", query, t0));
        assert!(call(&mut book, 2, "GRIP", "GRIP(79.5)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        let probe = book.probe(S, t0).expect("a probe");
        assert_eq!(probe.line, "POS?");
        write(&mut book, probe, t0);
        book.damage("ACK GRIP\u{b}FIN GRIP");
        book.on_line("POS=79.5", t0);
        let first = done(&mut book);
        assert!(
            matches!(&first[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{first:?}"
        );
        assert!(book.on_wire.get("GRIP").is_some_and(|s| s.held.is_none()));
        assert!(book.overdue(S, GIVE_UP_AFTER, t0 + S - HELD_MARGIN).is_ok());
        assert!(done(&mut book).is_empty(), "never its refusal");
    }

    /// An acknowledged motion never ends with a parse error: `ERR GRIP 15` after `ACK GRIP`
    /// answered another line damaged into GRIP's name (review, session 11). GRIP's `FIN` ends
    /// it.
    #[test]
    fn a_parse_error_in_a_running_motions_name_is_not_its_end() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ACK GRIP", t0), Handled::Nothing));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        assert!(done(&mut book).is_empty());
        assert!(matches!(
            book.on_line("FIN GRIP", t0),
            Handled::Freed("GRIP")
        ));
        assert!(matches!(&done(&mut book)[..], [(1, Ok(_))]));
    }

    /// A held line counts as one that could not be read from the moment it is read, not from
    /// when it is settled: a command written in between did not have it after its write. A
    /// parse error for a command written then is held in turn (TEMP? still waits), and a
    /// `BYE()` written then still waits for its `ACK BYE` (review, session 10).
    #[test]
    fn a_held_line_counts_where_it_was_read() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        assert!(call(&mut book, 3, "TEMP", "TEMP?", Expect::Value, t0));
        assert!(call(&mut book, 4, "MOVE", "MOVE(10)", Expect::Fin, t0));
        book.on_line("ACK GRIP", t0);
        assert!(matches!(&done(&mut book)[..], [(1, Err(_))]));
        assert!(matches!(book.on_line("ERR MOVE 15", t0), Handled::Nothing));
        assert!(done(&mut book).is_empty(), "MOVE's ERR is held");

        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        assert!(call(&mut book, 3, "BYE", "BYE()", Expect::Ack, t0));
        book.on_line("ACK GRIP", t0);
        assert!(!book.bye_lost_in_damage(), "ACK BYE is still to come");
    }

    /// Two held lines settled by one reply: the one of a command written before it is that
    /// command's, whatever the names' order (review, session 10): `ERR SPEED 15` is SPEED?'s,
    /// `ERR GRIP 15` answered a line before `TEMP?`, and POS? lost its reply.
    #[test]
    fn held_lines_are_settled_in_the_order_of_their_commands() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 2, "SPEED", "SPEED?", Expect::Value, t0));
        assert!(matches!(book.on_line("ERR SPEED 15", t0), Handled::Nothing));
        assert!(call(&mut book, 3, "TEMP", "TEMP?", Expect::Value, t0));
        assert!(call(&mut book, 4, "GRIP", "GRIP(10)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR GRIP 15", t0), Handled::Nothing));
        book.on_line("TEMP=23.0", t0);
        let done = done(&mut book);
        assert!(
            matches!(
                &done[..],
                [
                    (2, Err(Error::Device { line: speed, .. })),
                    (1, Err(Error::MalformedReply { .. })),
                    (3, Ok(temp)),
                ] if speed == "ERR SPEED 15" && temp == "23.0"
            ),
            "{done:?}"
        );
        assert_eq!(
            book.give_up_at(),
            Some(t0 + S + GIVE_UP_AFTER),
            "GRIP waits"
        );
    }

    /// An acknowledged motion's `ERR` comes when the motion ends, not in the order the lines
    /// were written: it settles no held `ERR` (`wsg-text:0x2ab53e7fdcce4b35`: `ERR HOME 19`
    /// made MOVE's own `ERR MOVE 15`, held behind a query whose reply was lost, another's, and
    /// MOVE timed out though its answer had come).
    #[test]
    fn a_motions_end_settles_no_held_parse_error() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "HOME", "HOME()", Expect::Fin, t0));
        book.on_line("ACK HOME", t0);
        assert!(call(&mut book, 2, "POS", "POS?", Expect::Value, t0));
        assert!(call(&mut book, 3, "MOVE", "MOVE(26)", Expect::Fin, t0));
        assert!(matches!(book.on_line("ERR MOVE 15", t0), Handled::Nothing));
        book.on_line("ERR HOME 19", t0);
        let first = done(&mut book);
        assert!(
            matches!(&first[..], [(1, Err(Error::Device { .. }))]),
            "{first:?}"
        );
        let at = t0 + S - HELD_MARGIN;
        assert_eq!(book.give_up_at(), Some(at), "MOVE's ERR still held");
        assert!(book.overdue(S, GIVE_UP_AFTER, at).is_ok());
        let second = done(&mut book);
        assert!(
            matches!(&second[..], [(3, Err(Error::Device { line, .. }))] if line == "ERR MOVE 15"),
            "{second:?}"
        );
    }

    /// Issue 29 L: an acknowledged motion past its give-up time is checked with `GRIPSTATE?`,
    /// not given up; a query past it gives the connection up.
    #[test]
    fn an_overdue_motion_is_checked_and_an_overdue_query_gives_up() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "HOME", "HOME()", Expect::Fin, t0));
        assert!(matches!(book.on_line("ACK HOME", t0), Handled::Nothing));
        let at = book.give_up_at().expect("HOME on the wire");
        assert_eq!(at, t0 + S + GIVE_UP_AFTER);
        assert!(matches!(book.overdue(S, GIVE_UP_AFTER, at - S), Ok(None)));
        let check = book
            .overdue(S, GIVE_UP_AFTER, at)
            .unwrap()
            .expect("a check");
        assert_eq!(check.line, "GRIPSTATE?");
        write(&mut book, check, at);
        // Still moving: HOME is checked again later, its call goes on.
        assert!(matches!(
            book.on_line("GRIPSTATE=6", at),
            Handled::Freed("GRIPSTATE")
        ));
        assert!(done(&mut book).is_empty());
        assert!(book.give_up_at().unwrap() > at);
        // A query that stays unanswered gives the connection up.
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 2, "POS", "POS?", Expect::Value, t0));
        let at = book.give_up_at().expect("POS on the wire");
        assert_eq!(
            book.overdue(S, GIVE_UP_AFTER, at).unwrap_err(),
            "POS?".to_owned()
        );
    }

    /// An acknowledged motion reported over with no `FIN` before the report and nothing
    /// unreadable since its `ACK` is asked again, not given up a `give_up_after` later: in
    /// order its `FIN` would have come first, and the value may have been damaged into another
    /// valid one (`wsg-text:0x9b99dd46f33e9019`: `GRIPSTATE=6` read as `GRIPSTATE=2` while
    /// HOME ran). A second such report counts: its `FIN` then has `give_up_after` to come.
    #[test]
    fn a_motion_reported_over_against_the_order_is_asked_again() {
        for second in ["GRIPSTATE=6", "GRIPSTATE=0"] {
            let t0 = Instant::now();
            let mut book = Book::new(GIVE_UP_AFTER);
            assert!(call(&mut book, 1, "HOME", "HOME()", Expect::Fin, t0));
            book.on_line("ACK HOME", t0);
            let at = book.give_up_at().expect("HOME on the wire");
            let check = book
                .overdue(S, GIVE_UP_AFTER, at)
                .unwrap()
                .expect("a check");
            write(&mut book, check, at);
            book.on_line("GRIPSTATE=2", at);
            let at2 = book.give_up_at().expect("HOME still on the wire");
            let again = book.overdue(S, GIVE_UP_AFTER, at2);
            let Ok(Some(again)) = again else {
                panic!("{second}: not asked again: {again:?}");
            };
            assert_eq!(again.line, "GRIPSTATE?");
            write(&mut book, again, at2);
            book.on_line(second, at2);
            assert!(done(&mut book).is_empty());
            let at3 = book.give_up_at().expect("HOME still on the wire");
            if second == "GRIPSTATE=6" {
                assert!(matches!(book.overdue(S, GIVE_UP_AFTER, at3), Ok(Some(_))));
                assert!(matches!(
                    book.on_line("FIN HOME", at3),
                    Handled::Freed("HOME")
                ));
                assert!(matches!(&done(&mut book)[..], [(1, Ok(_))]));
            } else {
                let end = book.overdue(S, GIVE_UP_AFTER, at3).unwrap_err();
                assert_eq!(end, "HOME()", "{second}");
            }
        }
    }

    /// Call `id`'s request `line` without timeout (`Duration::MAX`), written at `t0`.
    fn write_without_timeout(
        book: &mut Book<Call>,
        id: u8,
        (name, line, expect): (&'static str, &str, Expect),
        t0: Instant,
    ) {
        let (mut r, _) = request(id, name, line, expect, t0);
        r.timeout = Duration::MAX;
        r.deadline = after(t0, Duration::MAX);
        let r = book.admit(r, t0).expect("its name is free");
        write(book, r.outgoing(), t0);
    }

    /// Issue 29 M: a query without timeout whose request the gripper never read (its LF
    /// damaged on the way, wsg-text:0xfa9c7f60b0e57de1) held its call and its name for ever.
    /// Its reply staying away [`DOUBT_AFTER`], a probe asks; the probe's answer, sent after
    /// any reply to the query would have been (replies come in order), ends the call.
    #[test]
    fn a_reply_due_at_once_that_stays_away_is_doubted_and_a_probe_settles_it() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        write_without_timeout(&mut book, 1, ("POS", "POS?", Expect::Value), t0);
        assert_eq!(book.give_up_at(), Some(t0 + DOUBT_AFTER));
        assert!(book.probe(S, t0).is_none(), "no doubt yet");
        assert!(matches!(
            book.overdue(S, GIVE_UP_AFTER, t0 + DOUBT_AFTER),
            Ok(None)
        ));
        let probe = book.probe(S, t0 + DOUBT_AFTER).expect("a probe asks");
        assert_eq!(probe.line, "GRIPSTATE?");
        write(&mut book, probe, t0 + DOUBT_AFTER);
        assert!(matches!(
            book.on_line("GRIPSTATE=0", t0 + DOUBT_AFTER),
            Handled::Freed("GRIPSTATE")
        ));
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(1, Err(Error::MalformedReply { reason, .. }))] if reason.starts_with("no reply to it came")),
            "{done:?}"
        );
        assert_eq!(book.take_freed(), ["POS"]);
        assert_eq!(book.give_up_at(), None, "nothing left on the wire");
    }

    /// The doubt is only a question: a slow reply that comes before the probe's answer (in
    /// order) is the call's, and the probe's answer then settles nothing.
    #[test]
    fn a_doubted_reply_that_comes_after_all_is_the_calls() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        write_without_timeout(&mut book, 1, ("POS", "POS?", Expect::Value), t0);
        let at = t0 + DOUBT_AFTER;
        assert!(matches!(book.overdue(S, GIVE_UP_AFTER, at), Ok(None)));
        let probe = book.probe(S, at).expect("a probe asks");
        write(&mut book, probe, at);
        assert!(matches!(
            book.on_line("POS=12.5", at),
            Handled::Freed("POS")
        ));
        assert!(matches!(
            book.on_line("GRIPSTATE=0", at),
            Handled::Freed("GRIPSTATE")
        ));
        let done = done(&mut book);
        assert!(matches!(&done[..], [(1, Ok(v))] if v == "12.5"), "{done:?}");
        assert!(book.take_freed().is_empty());
        // A call whose reply is due sooner than the doubt is never doubted.
        assert!(call(&mut book, 2, "POS", "POS?", Expect::Value, at));
        assert_eq!(book.give_up_at(), Some(at + S + GIVE_UP_AFTER));
    }

    /// At `at` the client's probe is written and answered `answer`.
    fn probe_answered(book: &mut Book<Call>, at: Instant, answer: &str) {
        let probe = book.probe(S, at).expect("a probe");
        write(book, probe, at);
        book.on_line(answer, at);
    }

    /// At `at` the motion `name` (call 1) is asked whether it runs; the gripper reports no
    /// motion, and the call ends `MalformedReply` (a line that could not be read came after
    /// its `ACK`), its name free.
    fn asked_over_and_ended(book: &mut Book<Call>, at: Instant, name: &str) {
        let check = book.overdue(S, GIVE_UP_AFTER, at).unwrap().expect("asks");
        assert_eq!(check.line, "GRIPSTATE?");
        write(book, check, at);
        book.on_line("GRIPSTATE=0", at);
        let done = done(book);
        assert!(
            matches!(&done[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{done:?}"
        );
        assert_eq!(book.take_freed(), [name]);
    }

    /// Issue 29 M for motions: an acknowledged motion without timeout has no give-up time, so
    /// it was never checked, and a `FIN` that could not be read held its call and name for
    /// ever (`wsg-text:0x6616913488a6a29b`). [`DOUBT_AFTER`] after its `ACK` the client asks
    /// `GRIPSTATE?`; reported over with an unreadable line after its `ACK`, it ends.
    #[test]
    fn an_acknowledged_motion_without_timeout_is_checked_and_ends_when_over() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        write_without_timeout(&mut book, 1, ("HOME", "HOME()", Expect::Fin), t0);
        assert!(matches!(book.on_line("ACK HOME", t0), Handled::Nothing));
        assert!(matches!(book.on_line("FIN HOMX", t0 + S), Handled::Nothing));
        assert_eq!(book.give_up_at(), Some(t0 + DOUBT_AFTER));
        asked_over_and_ended(&mut book, t0 + DOUBT_AFTER, "HOME");
    }

    /// A motion without timeout whose first reply (its `ERR`, the seed's `ERR GRIP 15`) could
    /// not be read, taken as acknowledged once a probe's answer settled it, is asked
    /// [`DOUBT_AFTER`] later whether it runs, and ends when the gripper reports no motion.
    #[test]
    fn a_motion_without_timeout_whose_first_reply_was_damaged_ends_when_over() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        write_without_timeout(&mut book, 1, ("GRIP", "GRIP(13.5,71)", Expect::Fin), t0);
        book.damage("MRR GRIP 15");
        probe_answered(&mut book, t0, "GRIPSTATE=0");
        assert!(
            done(&mut book).is_empty(),
            "not at once: a motion just accepted may not show"
        );
        assert_eq!(book.give_up_at(), Some(t0 + DOUBT_AFTER));
        asked_over_and_ended(&mut book, t0 + DOUBT_AFTER, "GRIP");
    }

    /// A motion without timeout that nothing answered (its request never read: no line came
    /// in its place) is doubted, taken as acknowledged once the probe's answer shows its first
    /// reply lost, and ends when the gripper then reports no motion, without any damaged line
    /// (`wsg-text:0x66c3c8e7252d7f83`: with `give_up_after` `Duration::MAX` it was asked
    /// every 10 s for ever).
    #[test]
    fn a_motion_that_nothing_answered_ends_when_reported_over() {
        let t0 = Instant::now();
        let mut book = Book::new(Duration::MAX);
        write_without_timeout(&mut book, 1, ("HOME", "HOME()", Expect::Fin), t0);
        let at = t0 + DOUBT_AFTER;
        assert!(matches!(book.overdue(S, Duration::MAX, at), Ok(None)));
        probe_answered(&mut book, at, "GRIPSTATE=0");
        assert!(done(&mut book).is_empty());
        asked_over_and_ended(&mut book, at + DOUBT_AFTER, "HOME");
    }

    /// The check's own answer lost (run into the motion's damaged `FIN` before it, as in
    /// `wsg-text:0x3ad6c8b5ae93909a`): the motion is asked again [`DOUBT_AFTER`] later, and
    /// ends then.
    #[test]
    fn a_motion_whose_check_went_unanswered_is_asked_again() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        write_without_timeout(&mut book, 1, ("MOVE", "MOVE(33)", Expect::Fin), t0);
        book.on_line("ACK MOVE", t0);
        let at = t0 + DOUBT_AFTER;
        let check = book.overdue(S, GIVE_UP_AFTER, at).unwrap().expect("asks");
        write(&mut book, check, at);
        book.on_line("FIN MOVE\u{b}GRIPSTATE=0", at);
        probe_answered(&mut book, at, "POS=33.0");
        assert!(
            done(&mut book).is_empty(),
            "the check failed, the MOVE goes on"
        );
        assert_eq!(
            book.give_up_at(),
            Some(at + DOUBT_AFTER),
            "asked again later"
        );
        assert_eq!(book.take_freed(), ["GRIPSTATE"], "the lost check's name");
        asked_over_and_ended(&mut book, at + DOUBT_AFTER, "MOVE");
    }

    /// Still running when asked: asked again [`DOUBT_AFTER`] later, its call goes on, and its
    /// `FIN` ends it.
    #[test]
    fn a_running_motion_without_timeout_is_asked_again_and_its_fin_ends_it() {
        let t0 = Instant::now();
        let mut book = Book::new(Duration::MAX);
        write_without_timeout(&mut book, 1, ("HOME", "HOME()", Expect::Fin), t0);
        book.on_line("ACK HOME", t0);
        let at = t0 + DOUBT_AFTER;
        let check = book.overdue(S, Duration::MAX, at).unwrap().expect("asks");
        write(&mut book, check, at);
        book.on_line("GRIPSTATE=6", at);
        assert!(done(&mut book).is_empty());
        assert_eq!(
            book.give_up_at(),
            Some(at + DOUBT_AFTER),
            "asked again later"
        );
        assert!(matches!(
            book.on_line("FIN HOME", at + S),
            Handled::Freed("HOME")
        ));
        assert!(matches!(&done(&mut book)[..], [(1, Ok(_))]));
    }

    #[test]
    fn a_push_is_handed_back_and_completes_nobody() {
        let t0 = Instant::now();
        let mut book: Book<Call> = Book::new(GIVE_UP_AFTER);
        let handled = book.on_line("@POS=12.5", t0);
        assert!(
            matches!(handled, Handled::Push(Push { quantity: Quantity::Position, value }) if value == 12.5),
            "{handled:?}"
        );
        assert!(done(&mut book).is_empty());
    }

    /// A call of a probe's very query made before the probe was written gets the probe's
    /// answer (rule 7, `wsg-text:0xe5281323574dafa8`); a later one asks the gripper.
    #[test]
    fn a_call_behind_its_probe_gets_the_probes_answer() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        let (early, _) = request(1, "GRIPSTATE", "GRIPSTATE?", Expect::Value, t0);
        assert!(call(&mut book, 2, "POS", "POS?", Expect::Value, t0));
        book.damage("garbage");
        let probe = book.probe(S, t0 + S / 2).expect("a probe");
        write(&mut book, probe, t0 + S / 2);
        assert!(
            book.admit(early, t0 + S / 2).is_none(),
            "it waits for its name"
        );
        book.on_line("GRIPSTATE=4", t0 + S / 2);
        let next = book.next_waiting("GRIPSTATE", t0 + S / 2);
        assert!(next.is_none(), "answered by the probe");
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(2, Err(Error::MalformedReply { .. })), (1, Ok(v))] if v == "4"),
            "{done:?}"
        );
        let (late, _) = request(3, "GRIPSTATE", "GRIPSTATE?", Expect::Value, t0 + S);
        assert!(
            book.admit(late, t0 + S).is_some(),
            "one answer serves one call"
        );
    }

    /// Issue 29 N: after `BYE()`, an unreadable line where `ACK BYE` was due ends the session.
    #[test]
    fn an_unreadable_ack_bye_ends_the_session() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "BYE", "BYE()", Expect::Ack, t0));
        assert!(!book.bye_lost_in_damage());
        book.damage("ACK B\u{7f}E");
        assert!(book.bye_lost_in_damage());
        let done = done(&mut book);
        assert!(
            matches!(&done[..], [(1, Err(Error::MalformedReply { .. }))]),
            "{done:?}"
        );
        assert_eq!(book.give_up_at(), None);
    }

    /// The end of a connection: the calls on the wire in the order of their names, then those
    /// waiting (a fixed order, tests/explore/determinism.txt).
    #[test]
    fn drain_fails_everyone_in_a_fixed_order() {
        let t0 = Instant::now();
        let mut book = Book::new(GIVE_UP_AFTER);
        assert!(call(&mut book, 1, "SPEED", "SPEED?", Expect::Value, t0));
        assert!(call(&mut book, 2, "MOVE", "MOVE(1)", Expect::Fin, t0));
        assert!(!call(&mut book, 3, "MOVE", "MOVE(2)", Expect::Fin, t0));
        book.drain(&Error::Closed);
        let ids: Vec<u8> = done(&mut book).into_iter().map(|(id, _)| id).collect();
        assert_eq!(ids, [2, 1, 3]);
        assert_eq!((book.give_up_at(), book.waiting_len()), (None, 0));
    }
}
