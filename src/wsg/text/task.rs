//! The background task that owns a GCL connection: it writes command lines and pairs each reply
//! with its command **by name** (`ACK MOVE`, `FIN MOVE`, `ERR MOVE 4`, `POS=…`), so queries
//! answered at once run alongside a motion whose `FIN` comes later (the gripper reads and
//! answers during motion, shared note §3.7).
//!
//! One command of each name is on the wire at a time; a second one waits in the task until the
//! first is answered. A reply carries nothing but the name, so two `MOVE`s on the wire could not
//! be told apart: the `ERR MOVE 4` refusing the second (binary E_ALREADY_RUNNING, our reading
//! §6.2) would end whichever call came first.

use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

use super::error::Error;
use super::line::{parse_number, parse_reply, ReplyLine};
use super::push::{Push, PushSubscriber, Quantity};
use crate::deadline::move_timer;
use crate::line::{io_error, peer_closed, Failure, LineConn, LineError, LineTask};
use crate::supervisor::CloseRequest;
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

pub(crate) type Waiter = oneshot::Sender<Result<Answer, Error>>;

/// A caller's command, on its way to the task.
#[derive(Debug)]
pub(crate) struct Request {
    /// The name replies carry (upper case, no arguments).
    pub name: &'static str,
    pub line: String,
    pub expect: Expect,
    /// The caller stops waiting here; a request not yet sent then is never sent.
    pub deadline: Instant,
    pub timeout: Duration,
    pub waiter: Waiter,
    /// When the call was made.
    pub start: Instant,
    /// A query the client writes on its own (issue 29 L and M), not a caller's.
    pub probe: bool,
}

/// A command on the wire.
#[derive(Debug)]
struct Slot {
    line: String,
    expect: Expect,
    waiter: Waiter,
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
    /// `Book::damages` when its `ACK` was read.
    damages_at_ack: u64,
    /// `Book::damages` when it was written.
    damages_at_write: u64,
    /// When it was written, if it is a probe (`Request::probe`).
    probe_at: Option<Instant>,
}

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

/// A probe's timeout: the program's query timeout, at most [`PROBE_TIMEOUT_MAX`].
fn probe_timeout(query_timeout: Duration) -> Duration {
    query_timeout.min(PROBE_TIMEOUT_MAX)
}

/// The names a probe may use (queries answered at once, harmless), in order of preference.
const PROBES: [(&str, &str); 3] = [
    ("GRIPSTATE", "GRIPSTATE?"),
    ("POS", "POS?"),
    ("SPEED", "SPEED?"),
];

/// What the handles and the task share.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    failure: Failure<Error>,
    /// Set by [`Client::close`](super::Client::close) before it queues `BYE()`.
    pub(crate) close: CloseRequest,
    pub(crate) subscribers: Mutex<Vec<PushSubscriber>>,
    /// What the program set up on the connection that a reconnect restores, by what it sets
    /// (`VERBOSE`, `PWT`, `CLT`, one `AUTOSEND` per quantity): the last line the gripper
    /// accepted, in the order first set.
    settings: Mutex<Vec<Setting>>,
}

/// A line the gripper accepted that a new connection needs again.
#[derive(Debug, Clone)]
struct Setting {
    /// What it sets (`"VERBOSE"`, `"PWT"`, `"CLT"`, `"AUTOSEND GRIPSTATE"`).
    key: String,
    /// The command's name in the replies.
    name: &'static str,
    line: String,
    expect: Expect,
}

impl Shared {
    /// Why the connection is gone ([`Error::Closed`] if no reason was recorded).
    pub(crate) fn failure(&self) -> Error {
        self.failure.get()
    }

    fn record(&self, error: &Error) {
        self.failure.record(error);
    }

    /// Remembers `line` (accepted by the gripper) as what sets `key`, for a reconnect.
    pub(crate) fn remember(&self, key: String, name: &'static str, line: String, expect: Expect) {
        if let Ok(mut settings) = self.settings.lock() {
            let setting = Setting {
                key,
                name,
                line,
                expect,
            };
            match settings.iter_mut().find(|s| s.key == setting.key) {
                Some(old) => *old = setting,
                None => settings.push(setting),
            }
        }
    }

    /// Forgets what sets `key` (an `AUTOSEND` switched off).
    pub(crate) fn forget(&self, key: &str) {
        if let Ok(mut settings) = self.settings.lock() {
            settings.retain(|s| s.key != key);
        }
    }

    fn settings(&self) -> Vec<Setting> {
        self.settings.lock().map(|s| s.clone()).unwrap_or_default()
    }

    fn deliver(&self, push: Push) {
        if let Ok(mut subs) = self.subscribers.lock() {
            subs.retain(|s| s.deliver(push));
        }
    }
}

/// Task settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskConfig {
    pub give_up_after: Duration,
    /// Requests held while a command of their name is on the wire, at most.
    pub waiting_len: usize,
    /// Timeout of each command that restores the session after a reconnect.
    pub query_timeout: Duration,
}

/// Everything the task needs besides the connection (and how to open it again: the line
/// session's `LineLink`).
pub(crate) struct Task {
    pub requests: mpsc::Receiver<Request>,
    /// `STOP()` and `FASTSTOP()`, apart from the other calls: a stop must never wait behind
    /// calls that wait for their name (issue 29 K; the manual's STOP/FASTSTOP are answered
    /// during a motion, chapter 2). The task reads it whatever the queue holds.
    pub stops: mpsc::Receiver<Request>,
    pub config: TaskConfig,
    pub shared: Arc<Shared>,
}

pub(crate) use crate::deadline::after;

impl LineError for Error {
    const PEER: &'static str = "gripper";

    fn connection_lost(why: String) -> Self {
        Error::lost(why)
    }

    fn invalid_line(reason: String) -> Self {
        Error::invalid("command line", reason)
    }

    fn closed() -> Self {
        Error::Closed
    }

    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }
}

/// The commands on the wire (one per name) and the requests waiting for their name.
struct Book {
    /// Ordered by name, not a `HashMap`: its order is random per map, and it is iterated
    /// when the connection ends (each caller is told, and so woken, in that order) and for
    /// the overdue command named in the error (the earliest give-up time, ties in map
    /// order). With a hash order the same schedule woke the callers in another order from
    /// run to run (`wsg-text:0x5a7dcaabb2430033`, tests/explore/determinism.txt).
    on_wire: BTreeMap<&'static str, Slot>,
    waiting: VecDeque<Request>,
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
    /// Reply lines that could not be paired so far.
    damages: u64,
    /// The last answer to a probe of each name not yet handed to a call: when the probe was
    /// written, its line, its value (`Book::answer_from_probe`).
    probe_answers: BTreeMap<&'static str, (Instant, String, String)>,
}

impl Book {
    fn new(give_up_after: Duration) -> Book {
        Book {
            give_up_after,
            damages: 0,
            on_wire: BTreeMap::new(),
            waiting: VecDeque::new(),
            sent: 0,
            damaged: None,
            freed: Vec::new(),
            probe_answers: BTreeMap::new(),
        }
    }

    /// Puts a command written to the wire in the book.
    fn on_wire(
        &mut self,
        name: &'static str,
        line: String,
        expect: Expect,
        waiter: Waiter,
        give_up_at: Instant,
        probe_at: Option<Instant>,
    ) {
        self.sent += 1;
        let slot = Slot {
            line,
            expect,
            waiter,
            give_up_at,
            seq: self.sent,
            acked: false,
            checking: false,
            over: false,
            damages_at_ack: 0,
            damages_at_write: self.damages,
            probe_at,
        };
        self.on_wire.insert(name, slot);
    }

    /// Whether `slot` waits for a reply the gripper sends at once (not a motion's `FIN`).
    fn answered_at_once(slot: &Slot) -> bool {
        slot.expect != Expect::Fin || !slot.acked
    }

    /// A reply line that cannot be paired arrived: it may have been the reply of any command
    /// answered at once that is on the wire.
    fn damage(&mut self, text: &str) {
        self.damages += 1;
        if self.on_wire.values().any(Book::answered_at_once) {
            self.damaged = Some((self.sent, text.to_owned()));
        }
    }

    /// A reply to the command written as `seq` arrived: the commands answered at once written
    /// before the damaged line and still unanswered lost their reply to it. They fail, and
    /// their names are free (no reply of theirs can come any more). A motion not yet
    /// acknowledged lost its first reply too, an `ACK` (its `FIN` may still come) or an `ERR`
    /// (none will): it is taken as acknowledged, with that damaged line after its `ACK`, so
    /// that once overdue it is checked with `GRIPSTATE?` and ends when the gripper reports no
    /// motion (issue 29 L; before, it was given up as unanswered: wsg-text:0xaa891d063fc824a5,
    /// `ERR HOME 4` lost in a line run together with `ERR MOVE 19`).
    fn settle(&mut self, seq: u64) {
        let Some((upto, line)) = self.damaged.take_if(|(upto, _)| seq > *upto) else {
            return;
        };
        for slot in self.on_wire.values_mut() {
            if slot.seq <= upto && slot.expect == Expect::Fin && !slot.acked {
                tracing::debug!(command = %slot.line, %line, "wsg text: a motion's first reply damaged, taken as acknowledged");
                slot.acked = true;
                slot.damages_at_ack = slot.damages_at_write;
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
                let _ = slot.waiter.send(Err(Error::MalformedReply {
                    command: slot.line,
                    line: line.clone(),
                    reason: "its reply could not be read (a later command was answered first)"
                        .into(),
                }));
                self.freed.push(name);
            }
        }
    }

    /// A query to write after a damaged line, when nothing written since waits for a reply
    /// the gripper sends at once: its answer tells which replies were lost.
    fn probe(&self, query_timeout: Duration) -> Option<Request> {
        let query_timeout = probe_timeout(query_timeout);
        let (upto, _) = self.damaged.as_ref()?;
        let suspects = self
            .on_wire
            .values()
            .any(|s| s.seq <= *upto && Book::answered_at_once(s));
        let barrier = self
            .on_wire
            .values()
            .any(|s| s.seq > *upto && Book::answered_at_once(s));
        if !suspects || barrier {
            return None;
        }
        let (name, line) = PROBES
            .into_iter()
            .find(|(name, _)| !self.on_wire.contains_key(name))?;
        // Nobody waits for its answer: it is consumed when it comes.
        let (waiter, _) = oneshot::channel();
        Some(Request {
            name,
            line: line.to_owned(),
            expect: Expect::Value,
            deadline: after(Instant::now(), query_timeout),
            timeout: query_timeout,
            waiter,
            start: Instant::now(),
            probe: true,
        })
    }

    /// The command on the wire whose give-up time came: an acknowledged motion is checked
    /// with `GRIPSTATE?` (a healthy slow motion is not a reason to give the connection up,
    /// issue 29 L; the gripper answers during motion, shared note §3.7), which this returns if
    /// it is to be written; anything else (or a motion reported over whose `FIN` still did not
    /// come) is `Err` with its line: the connection is given up.
    fn overdue(
        &mut self,
        query_timeout: Duration,
        give_up_after: Duration,
    ) -> Result<Option<Request>, String> {
        let now = Instant::now();
        let query_timeout = probe_timeout(query_timeout);
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
        // Nobody waits for its answer: it is consumed when it comes (and read by `on_line`).
        let (waiter, _) = oneshot::channel();
        Ok(Some(Request {
            name: "GRIPSTATE",
            line: "GRIPSTATE?".to_owned(),
            expect: Expect::Value,
            deadline: after(now, query_timeout),
            timeout: query_timeout,
            waiter,
            start: now,
            probe: true,
        }))
    }

    /// A `GRIPSTATE=` read (a probe's or a program's): the motions being checked still run, or
    /// are over (their `FIN` then has one more `give_up_after` to come).
    fn motion_state(&mut self, value: &str, give_up_after: Duration) {
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
        let now = Instant::now();
        let damages = self.damages;
        let mut ended = Vec::new();
        for (&name, slot) in self.on_wire.iter_mut().filter(|(_, s)| s.checking) {
            slot.checking = false;
            slot.over = over;
            slot.give_up_at = after(now, give_up_after.max(RECHECK_FLOOR));
            tracing::debug!(command = %slot.line, value, over, "wsg text: overdue motion checked");
            // Over, and a line that could not be read came after its `ACK`: that was its `FIN`
            // or `ERR` (the gripper answers in order: it came before this state). The call
            // ends and the name is free (issue 29 M for motions).
            if over && damages > slot.damages_at_ack {
                ended.push(name);
            }
        }
        for name in ended {
            if let Some(slot) = self.on_wire.remove(name) {
                let _ = slot.waiter.send(Err(Error::MalformedReply {
                    command: slot.line,
                    line: format!("GRIPSTATE={value}"),
                    reason: "the motion is over and its FIN or ERR could not be read".into(),
                }));
                self.freed.push(name);
            }
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

    /// The earliest give-up time of the commands on the wire.
    fn give_up_at(&self) -> Option<Instant> {
        self.on_wire.values().map(|s| s.give_up_at).min()
    }

    fn finish(&mut self, name: &str, result: Result<Answer, Error>) {
        if let Some(slot) = self.on_wire.remove(name) {
            // A caller that left (timeout, dropped future) no longer listens: its reply is
            // consumed here and goes to nobody else.
            let _ = slot.waiter.send(result);
        }
    }

    /// Drops the waiting requests whose caller left, and fails those whose time ran out, so
    /// the queue holds only requests someone still waits for (issue 29 K: a queue full of
    /// calls given up blocked every other call).
    fn prune(&mut self) {
        let now = Instant::now();
        if self
            .waiting
            .iter()
            .any(|r| r.waiter.is_closed() || now >= r.deadline)
        {
            let waiting = std::mem::take(&mut self.waiting);
            self.waiting = waiting.into_iter().filter_map(usable).collect();
        }
    }

    /// The earliest deadline of the waiting requests.
    fn waiting_deadline(&self) -> Option<Instant> {
        self.waiting.iter().map(|r| r.deadline).min()
    }

    /// Takes a request read from a channel: the request to send now if its name is free,
    /// else it waits for its name.
    fn admit(&mut self, request: Request) -> Option<Request> {
        let request = self.answer_from_probe(usable(request)?)?;
        if self.on_wire.contains_key(request.name) {
            self.prune();
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
    fn answer_from_probe(&mut self, request: Request) -> Option<Request> {
        let fits = self
            .probe_answers
            .get(request.name)
            .is_some_and(|(at, line, _)| request.start <= *at && *line == request.line);
        if !fits || request.expect != Expect::Value {
            return Some(request);
        }
        let (_, _, value) = self.probe_answers.remove(request.name)?;
        tracing::debug!(command = %request.line, %value, "wsg text: answered by the client's own probe");
        let _ = request.waiter.send(Ok(Answer::Value(value)));
        None
    }

    /// The next waiting request of `name` that still has a caller and time, if any.
    fn next_waiting(&mut self, name: &str) -> Option<Request> {
        loop {
            let i = self.waiting.iter().position(|r| r.name == name)?;
            let request = self.waiting.remove(i)?;
            if let Some(request) = usable(request).and_then(|r| self.answer_from_probe(r)) {
                return Some(request);
            }
        }
    }

    /// Handles one reply line.
    fn on_line(&mut self, text: &str, shared: &Shared) -> Handled {
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
                match (Quantity::from_name(name), parse_number(value)) {
                    (Some(quantity), Some(value)) => shared.deliver(Push { quantity, value }),
                    _ => tracing::debug!(line = text, "wsg text: push not understood, dropped"),
                }
                return Handled::Nothing;
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
            .iter_mut()
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
        // A reply to a line written after a damaged one: the replies before it have come.
        // (A motion's `FIN` is no such sign: it comes when the motion ends.)
        if !matches!(reply, ReplyLine::Fin(_)) {
            let seq = slot.seq;
            if matches!(reply, ReplyLine::Ack(_)) && slot.expect == Expect::Fin {
                slot.acked = true;
                slot.damages_at_ack = self.damages;
            }
            self.settle(seq);
        }
        if let (ReplyLine::Value { value, .. }, "GRIPSTATE") = (reply, key) {
            self.motion_state(value, self.give_up_after);
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

/// What one reply line did.
enum Handled {
    /// Nothing a caller waits for (an `ACK` of a motion, a push, a line for nobody).
    Nothing,
    /// Answered the command of this name: the name is free.
    Freed(&'static str),
    /// `ACK BYE`: the session is over.
    Bye,
}

/// The request, unless its caller left or its time ran out (then it is answered and dropped:
/// a command nobody waits for must not move the fingers later).
fn usable(request: Request) -> Option<Request> {
    if request.waiter.is_closed() {
        tracing::debug!(command = %request.line, "wsg text: caller gone before sending, dropped");
        return None;
    }
    if Instant::now() >= request.deadline {
        let _ = request.waiter.send(Err(Error::Timeout {
            command: request.line,
            timeout: request.timeout,
        }));
        return None;
    }
    Some(request)
}

/// Resolves when the caller of `BYE()` has left (its future dropped); never if `BYE()` is not
/// on the wire.
async fn bye_caller_gone(on_wire: &mut BTreeMap<&'static str, Slot>) {
    std::future::poll_fn(|cx| match on_wire.get_mut("BYE") {
        Some(slot) => slot.waiter.poll_closed(cx),
        None => std::task::Poll::Pending,
    })
    .await
}

/// Resolves when the caller of a waiting request has left (its future dropped).
async fn any_caller_gone(waiting: &mut VecDeque<Request>) {
    std::future::poll_fn(|cx| {
        if waiting
            .iter_mut()
            .any(|r| r.waiter.poll_closed(cx).is_ready())
        {
            std::task::Poll::Ready(())
        } else {
            std::task::Poll::Pending
        }
    })
    .await
}

/// The text session the supervisor runs: restored with the settings the gripper accepted
/// (`VERBOSE`, `PWT`, `CLT`, `AUTOSEND`), in the order they were first set.
impl LineTask for Task {
    type Error = Error;
    type Request = Request;

    fn requests(&mut self) -> &mut mpsc::Receiver<Request> {
        &mut self.requests
    }

    fn abandoned(&self) -> bool {
        self.requests.is_closed()
    }

    async fn serve(&mut self, conn: &mut LineConn, reconnects: bool) -> Error {
        serve(
            conn,
            &mut self.requests,
            &mut self.stops,
            self.config,
            &self.shared,
            reconnects,
        )
        .await
    }

    async fn restore(&self, conn: &mut LineConn) -> Result<(), Error> {
        for setting in self.shared.settings() {
            exchange(conn, setting, self.config.query_timeout, &self.shared).await?;
        }
        Ok(())
    }

    fn ended(&mut self, reason: &Error) {
        self.shared.record(reason);
        // The supervisor refuses what is left in `requests`; the stops are ours to refuse.
        self.stops.close();
        while let Ok(request) = self.stops.try_recv() {
            Self::refuse(request, reason);
        }
        if let Ok(mut subs) = self.shared.subscribers.lock() {
            // Ends every push stream.
            subs.clear();
        }
    }

    fn refuse(request: Request, reason: &Error) {
        let _ = request.waiter.send(Err(reason.clone()));
    }
}

/// One setting sent again on a new connection, before any call is served on it: paired by the
/// same rules as a call's reply (pushes that arrive meanwhile go to their subscribers).
async fn exchange(
    conn: &mut LineConn,
    setting: Setting,
    timeout: Duration,
    shared: &Shared,
) -> Result<(), Error> {
    let deadline = after(Instant::now(), timeout);
    let command = setting.line.clone();
    conn.writer.send::<Error>(&setting.line, deadline).await?;
    let (waiter, mut answer) = oneshot::channel();
    let mut book = Book::new(timeout);
    book.on_wire(
        setting.name,
        setting.line,
        setting.expect,
        waiter,
        deadline,
        None,
    );
    loop {
        let line = match tokio::time::timeout_at(deadline, conn.reader.next_line()).await {
            Err(_) => return Err(Error::Timeout { command, timeout }),
            Ok(None) => return Err(peer_closed()),
            Ok(Some(line)) => line.map_err(io_error::<Error>)?,
        };
        let Ok(text) = line.text() else { continue };
        book.on_line(text, shared);
        if let Ok(result) = answer.try_recv() {
            return result.map(drop);
        }
    }
}

/// Serves calls over one connection until it closes, fails or every handle is dropped; fails
/// the calls in flight and those waiting for their name with the reason, which it returns.
/// When the connection is over for good (closed, or lost with no reconnect to follow), the
/// reason is recorded and the request queue closed before any caller hears why (as GRIPLINK's
/// task does, issue 21).
async fn serve(
    conn: &mut LineConn,
    requests: &mut mpsc::Receiver<Request>,
    stops: &mut mpsc::Receiver<Request>,
    config: TaskConfig,
    shared: &Shared,
    reconnects: bool,
) -> Error {
    let mut book = Book::new(config.give_up_after);
    let timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(timer);
    // While the queue is full: the earliest deadline of a waiting request, when it leaves.
    let queue_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(queue_timer);
    // A request whose line could not be written: told why at the end.
    let mut unsent = None;
    // `BYE()` is on the wire (with its call's timeout; `bye_timer` is at its deadline):
    // nothing more is sent.
    let mut closing: Option<Duration> = None;
    let bye_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(bye_timer);
    let end = 'serve: loop {
        let give_up = book.give_up_at();
        if let Some(at) = give_up {
            move_timer(timer.as_mut(), at);
        }
        book.prune();
        let full = book.waiting.len() >= config.waiting_len;
        let queue_deadline = if full { book.waiting_deadline() } else { None };
        if let Some(at) = queue_deadline {
            move_timer(queue_timer.as_mut(), at);
        }
        let mut to_send: Option<Request> = None;
        tokio::select! {
            // Replies first: they free names and callers.
            biased;
            line = conn.reader.next_line() => match line {
                Some(Ok(line)) => match line.text() {
                    Ok(text) => match book.on_line(text, shared) {
                        Handled::Bye => break Error::Closed,
                        // `BYE()` answered otherwise (`ERR BYE`, a reply of another kind): its
                        // call has its answer, and the program is done with the connection all
                        // the same (issue 29 N).
                        Handled::Freed("BYE") if closing.is_some() => break Error::Closed,
                        // After `BYE()` nothing more is written (issue 29 N).
                        Handled::Freed(_) if closing.is_some() => {}
                        // A name freed: its next waiting request goes out.
                        Handled::Freed(name) => to_send = book.next_waiting(name),
                        Handled::Nothing => {}
                    },
                    Err(why) => {
                        tracing::warn!(%why, "wsg text: reply line discarded");
                        book.damage(&why.to_string());
                    }
                },
                Some(Err(e)) => break io_error(e),
                None => break peer_closed(),
            },
            () = &mut timer, if give_up.is_some() => {
                match book.overdue(config.query_timeout, config.give_up_after) {
                    // Not after `BYE()` (issue 29 N): the session ends at its deadline anyway.
                    Ok(probe) if closing.is_none() => to_send = probe,
                    Ok(_) => {}
                    Err(command) => {
                        tracing::error!(%command, "wsg text: reply overdue, giving up on the connection");
                        break Error::lost(format!(
                            "no reply to {command} long after its timeout; replies can no longer be paired"
                        ));
                    }
                }
            },
            // `BYE()`'s call is over without `ACK BYE`: the connection is closed then, so
            // the calls after `close()` fail `Closed` (issue 29 N).
            () = &mut bye_timer, if closing.is_some() => {
                // Its caller is told it timed out (not `Closed`), whichever timer fires first.
                if let (Some(slot), Some(timeout)) = (book.on_wire.remove("BYE"), closing) {
                    let _ = slot.waiter.send(Err(Error::Timeout {
                        command: slot.line,
                        timeout,
                    }));
                }
                break Error::Closed;
            }
            // Nobody waits for `ACK BYE` any more and nothing is written after `BYE()`: the
            // session is over (a `BYE()` without timeout whose caller left kept the connection
            // and its task alive for ever).
            () = bye_caller_gone(&mut book.on_wire), if closing.is_some() => break Error::Closed,
            // A stop is read whatever the queue holds (issue 29 K).
            request = stops.recv(), if closing.is_none() => {
                let Some(request) = request else { break Error::Closed };
                to_send = book.admit(request);
            }
            request = requests.recv(), if closing.is_none() && !full => {
                let Some(request) = request else { break Error::Closed };
                to_send = book.admit(request);
            }
            // The queue is full: a request leaves it when its time runs out or its caller
            // leaves, and the channel is read again.
            () = &mut queue_timer, if queue_deadline.is_some() => {}
            () = any_caller_gone(&mut book.waiting), if full => {}
        }
        // `ACK BYE` may have been a line that could not be read, and nothing written after
        // `BYE()` can ever tell (`Book::bye_unreadable`): the session ends as at `BYE()`'s
        // deadline, its caller told why.
        if closing.is_some() && book.bye_unreadable() {
            if let Some(slot) = book.on_wire.remove("BYE") {
                let line = book
                    .damaged
                    .take()
                    .map(|(_, line)| line)
                    .unwrap_or_default();
                tracing::warn!(%line, "wsg text: ACK BYE could not be read, connection closed");
                let _ = slot.waiter.send(Err(Error::MalformedReply {
                    command: slot.line,
                    line,
                    reason: "a line that could not be read came where ACK BYE was due".into(),
                }));
            }
            break Error::Closed;
        }
        let mut outgoing: VecDeque<Request> = to_send.into_iter().collect();
        // Names freed by calls whose reply was damaged: their next waiting requests go out
        // (not after `BYE()`).
        for name in std::mem::take(&mut book.freed) {
            if closing.is_none() {
                outgoing.extend(book.next_waiting(name));
            }
        }
        // After what there is to send, a probe if a damaged line left calls in doubt (M).
        let mut probed = closing.is_some();
        loop {
            let request = match outgoing.pop_front() {
                Some(request) => request,
                None if !probed => {
                    probed = true;
                    match book.probe(config.query_timeout) {
                        Some(probe) => {
                            tracing::debug!(command = %probe.line, "wsg text: probe after a damaged reply");
                            probe
                        }
                        None => break,
                    }
                }
                None => break,
            };
            let give_up_at = after(request.deadline, config.give_up_after);
            match conn.writer.send(&request.line, give_up_at).await {
                Ok(()) => {}
                // Refused by the codec, nothing sent (`Client::submit` checks the line first,
                // so this is only a second guard).
                Err(err @ Error::InvalidArgument { .. }) => {
                    let _ = request.waiter.send(Err(err));
                    continue;
                }
                Err(e) => {
                    unsent = Some(request.waiter);
                    break 'serve e;
                }
            }
            tracing::trace!(command = %request.line, "wsg text: sent");
            if request.name == "BYE" {
                closing = Some(request.timeout);
                move_timer(bye_timer.as_mut(), request.deadline);
                // The calls waiting for their name are never sent now.
                for waiting in book.waiting.drain(..).chain(outgoing.drain(..)) {
                    let _ = waiting.waiter.send(Err(Error::Closed));
                }
                probed = true;
            }
            let probe_at = request.probe.then(Instant::now);
            book.on_wire(
                request.name,
                request.line,
                request.expect,
                request.waiter,
                give_up_at,
                probe_at,
            );
        }
    };
    if closing.is_some() || matches!(end, Error::Closed) || !reconnects {
        shared.record(&end);
        requests.close();
        stops.close();
    }
    if let Some(waiter) = unsent {
        let _ = waiter.send(Err(end.clone()));
    }
    while let Some((_, slot)) = book.on_wire.pop_first() {
        let _ = slot.waiter.send(Err(end.clone()));
    }
    for request in book.waiting.drain(..) {
        let _ = request.waiter.send(Err(end.clone()));
    }
    conn.writer.shutdown().await;
    // After BYE() the program is done with the connection, however it ended: a loss then is
    // not reconnected.
    if closing.is_some() && reconnects {
        Error::Closed
    } else {
        end
    }
}
