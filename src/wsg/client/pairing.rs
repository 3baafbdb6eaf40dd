//! Pairing replies with requests: a pure state machine, no I/O (the model of rumqttc's state).
//! It interprets the answers of its own requests (probes, barriers) too and tells the task
//! what to do in plain [`Output`]s ([`internal`]).
//!
//! The protocol has no sequence numbers: a reply carries only its command id. So:
//! - at most one request per command id is on the wire; later calls with the same id queue
//!   behind it, while different ids run concurrently;
//! - an E_CMD_PENDING reply (manual 1.3) acknowledges an asynchronous command and keeps the id
//!   busy until the final reply; any other status is final;
//! - a request whose caller timed out or went away stays on the wire until its reply arrives
//!   (the late reply is consumed here and discarded by the task), so the reply can never reach
//!   the next caller of that id.
//!
//! Three kinds of command are treated apart:
//! - **Stop (0x22) and FAST STOP (0x23)** are never queued (manual 3.2.3/3.2.4: they stop
//!   "unmittelbar"): each is sent at once, whatever is on the wire. They carry no data, so
//!   their replies cannot be told apart: a call completes only on a reply to a stop sent at or
//!   after it, and the stop is sent again while none comes ([`super::stops`],
//!   [`Event::Stopped`], [`Due::ResendStop`]).
//! - **Motion commands** (0x20, 0x21, 0x25, 0x26): the device refuses a motion command while
//!   another one runs (3.2.1/3.2.2/3.2.6/3.2.7: E_ALREADY_RUNNING). A second call of the id
//!   queues behind the first, and once the first is acknowledged the device's state is asked
//!   at once ([`Due::Probe`]): "moving" refuses the calls made before that probe went out
//!   ([`Verdict::Running`]); the first's final reply, or two "not moving" a grace apart
//!   ([`Verdict::Abandoned`]), sends the next. The client never refuses on the belief that
//!   the first still runs (its final reply may be lost, or come after a stop's reply): the
//!   residual risk is SF_MOVING itself (Anhang B: not synchronised with the end of a move, so
//!   a refusal right at the end of a move may be one the device would no longer give).
//! - Everything else queues behind the request of its id on the wire.
//!
//! How long an id stays "poisoned" by a request that got no (final) reply: until its caller's
//! deadline plus a grace period ([`Pairing::new`]); then the id is released, acknowledged or
//! not, so a lost frame cannot block it forever. The caller's own timeout wins: a per-call
//! timeout longer than the connection's (`Client::with_timeouts`) keeps the id until *its*
//! deadline plus grace, so the device's answer up to then reaches it. Two callers have no
//! deadline that bounds anything, and for them the *holds* ([`Pairing::set_holds`], the
//! connection's query and motion timeouts) do: a caller without timeout ([`is_never`](crate::deadline::is_never):
//! `Duration::MAX`), and one that is gone (dropped its call; nobody waits for the reply). An
//! unacknowledged request of theirs is released the reply hold plus grace after it was sent,
//! and an acknowledged motion goes under recovery (below) the motion hold after it was sent
//! (or at the deadline, if that comes first). One exception: a motion command's deadline is
//! the motion timeout, but the device acknowledges it at once (1.3), so the reply hold bounds
//! the wait for its E_CMD_PENDING whoever the caller is (a `home` whose datagram was lost
//! fails after the query timeout + grace, not after 30 s). A gone caller is noticed when another call of
//! the id is submitted ([`Pairing::prune`]): the id matters only to a call that wants it, and
//! that call then waits at most the hold from the gone request's send, not the gone caller's
//! whole (maybe long) timeout; until then the id just stays taken, harming nobody. (A caller
//! that timed out is not "gone" so: its request keeps the id its grace past its deadline.)
//! On UDP the residual risk is a reply arriving later than that grace (or hold): it would be
//! taken as the reply to the next request of the same id.
//! On an ordered transport (TCP, serial: [`Pairing::set_ordered`]) a request released with no
//! reply at all *fences* its id instead ([`Due::Fenced`]): the pairing sends a loop-back with a
//! payload of its own, and the next request of the id waits until its echo comes back
//! ([`Pairing::unfence`]). The device answers a connection's commands one after the other
//! (1.2.2: each reply acknowledges "the received command"), and the stream keeps that order,
//! so the immediate reply of the released request, if any, comes before the echo: a reply of
//! the id before the echo is that late one (unsolicited), and none comes after it. Only an
//! immediate reply is fenced so: a final reply comes when its command ends. So a released
//! motion is taken back on the wire under recovery (below) when its E_CMD_PENDING comes before
//! the echo, and also when none came at all by the echo (a corrupted E_CMD_PENDING is dropped
//! like a lost one, and the move's final reply would complete the next request of the id). An
//! acknowledged non-motion command (finger power on, 3.6.3) is fenced too: its final reply
//! comes when it ends, "nach etwa 500 ms" ([`FINGER_POWER_ON_DURATION`](super::FINGER_POWER_ON_DURATION)), and its release
//! comes later than that (its caller's deadline, by default the query timeout +
//! that duration, plus the grace; at least that duration + grace after it was sent or acknowledged,
//! whichever is later), so the device has sent that reply before it
//! receives the barrier, and the echo comes after it. Released as before, a final reply stalled
//! past the grace completed the next call of the id (the explorer's
//! `wsg-serial:0xfdb842249ad7b4b3`); the residual risk is a device that ends the command later
//! than its release (then the reply after the echo answers the next call). Stops are never
//! given up on time on an ordered transport: a barrier proves their replies lost
//! ([`super::stops`], [`Due::StopBarrier`]).
//!
//! An acknowledged motion command is not released that way: it may still be moving (a move
//! can outlast its caller's timeout), and its final reply, E_CMD_ABORTED after a stop included,
//! always comes (1.3). From its caller's deadline on it is under *recovery*: the pairing asks the
//! device's system state ([`Due::Probe`]), and the request is abandoned only on evidence that
//! its final reply is lost: two "not moving" observations, each from a probe sent after the
//! deadline, the second probe sent a full grace period after the first answer arrived, with no
//! final reply in between ([`Pairing::on_probe`]). One observation is not enough: SF_MOVING is
//! not synchronised with the end of the move (Anhang B), UDP reorders, and while 0x40 is
//! streamed the answer may be a stream frame sent just before the probe arrived. The residual
//! risk is a final reply sent more than a grace period after the device said twice that it no
//! longer moves.
//!
//! Two kinds of reply provably answer another request of the same id and are treated as
//! unsolicited: a loop reply that does not echo the payload on the wire, and E_ALREADY_RUNNING
//! for an acknowledged request (the device's refusal of a duplicate of it). The second needs
//! the acknowledgement to be the request's own: when the previous request of the id got its
//! final reply without an E_CMD_PENDING first, that E_CMD_PENDING may still come (UDP
//! reorders), so the next one acknowledges "doubtfully" and E_ALREADY_RUNNING still ends the
//! request ([`IdState::pending_owed`]). On TCP and serial replies keep their order and this
//! never happens; on UDP the residual risk is a duplicated request refused while its original
//! runs, in that same situation.

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use self::in_flight::{IdState, InFlight, Settle};
pub(crate) use self::internal::{Internal, Output, BARRIER_ECHO_LEN};
use super::stops::{StopDue, Stops};
use super::FINGER_POWER_ON_DURATION;
use crate::deadline::{after, is_unbounded};
use crate::int_map::IntMap;
use crate::wsg::command::id;
use crate::wsg::{Frame, Reply, Status};

/// Identifies one request for the task (defined with the stops, which hold tokens too and
/// must not import the pairing that holds them).
pub(crate) use super::stops::Token;

/// Whether `id` is a motion command (manual 3.2.1, 3.2.2, 3.2.6, 3.2.7): asynchronous, refused
/// by the device with E_ALREADY_RUNNING while another motion runs.
pub(crate) fn is_motion(id: u8) -> bool {
    matches!(id, id::HOMING | id::PRE_POSITION | id::GRASP | id::RELEASE)
}

/// Whether a request of `id` may be acknowledged (E_CMD_PENDING, 1.3) and finish later: a
/// motion, or finger power (on, 3.6.3: "nach etwa 500 ms").
fn may_be_acknowledged(id: u8) -> bool {
    is_motion(id) || matches!(id, id::FINGER1_POWER | id::FINGER2_POWER)
}

/// Whether `id` is stop or FAST STOP (manual 3.2.3, 3.2.4): never queued.
pub(crate) fn is_stop(id: u8) -> bool {
    matches!(id, id::STOP | id::FAST_STOP)
}

/// A request waiting to be sent or on the wire.
#[derive(Debug)]
pub(crate) struct Request {
    pub(crate) token: Token,
    pub(crate) frame: Frame,
    /// When the caller stops waiting.
    pub(crate) deadline: Instant,
}

/// How many times in a row a request of a streamed id is sent again because a damaged frame
/// came before its barrier's echo ([`Pairing::settle`]): each costs a round trip, and a line
/// that damages something in every round trip answers nothing reliably; then the request
/// waits for its release, as one whose reply was lost (a caller without timeout is bounded by
/// the reply hold from the last send).
pub(crate) const MAX_ASKED_AGAIN: u8 = 3;

/// What the echo of a barrier settling a request of a streamed id decides ([`Pairing::settle`]).
#[derive(Debug)]
enum Settled {
    /// The request's answer (the id is free).
    Answer(Reply),
    /// Send the request again (a damaged frame may have been its reply); it is still the
    /// request on the wire of its id.
    Again(Request),
    /// No answer: the request is no longer on the wire, or got no frame (it waits for its
    /// release).
    Nothing,
}

/// What a received reply means.
#[derive(Debug, PartialEq)]
pub(crate) enum Event {
    /// The final reply of the request `Token`.
    Resolved(Token, Reply),
    /// The final reply of every stop (or FAST STOP) request listed: it answers a stop sent at
    /// or after each of their calls (see [`super::stops`]).
    Stopped(Vec<Token>, Reply),
    /// The asynchronous request `Token` was accepted (E_CMD_PENDING); its result follows.
    Accepted(Token),
    /// No request of this id is on the wire (an auto-update, or a reply that came after its id
    /// was released).
    Unsolicited(Reply),
}

/// What became of a submitted request.
#[derive(Debug)]
pub(crate) enum Submit {
    /// Its id is free (or it is a stop): send it now.
    Send(Request),
    /// It waits behind the request of its id on the wire.
    Queued,
}

/// What a request whose time has come needs ([`Pairing::due`]; what the pairing makes of it:
/// [`Pairing::expire`]).
#[derive(Debug, PartialEq)]
pub(crate) enum Due {
    /// The request `Token` of this id got no final reply by its deadline plus grace: its id is
    /// released. Call [`Pairing::next`] for the id.
    Released(u8, Token),
    /// Like [`Due::Released`], on an ordered transport, for a request that got no reply at
    /// all, or an acknowledged one that is no motion (finger power on): the id stays fenced (its next request waits) until the echo of a loop-back sent
    /// now comes back. On a stream the device answers in order, so that echo comes after any
    /// reply to a request sent before it (see [`Pairing::unfence`]).
    Fenced(u8, Token),
    /// The acknowledged motion `Token` of this id is past its deadline: ask the device whether
    /// it still moves, and report the answer with [`Pairing::on_probe`].
    Probe(u8, Token),
    /// A stop call of this id (stop or FAST STOP) still waits for a reply to a stop sent at or
    /// after it: send the stop again (it is recorded as sent).
    ResendStop(u8),
    /// On an ordered transport, stops of this id (stop or FAST STOP) are unanswered too long:
    /// send a barrier (a loop-back) for the id; its echo ([`Pairing::unfence`]) proves the
    /// stops sent before it and still unanswered lost (see [`super::stops`]).
    StopBarrier(u8),
}

/// What a recovery probe found out about a motion command (see [`Pairing::on_probe`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Observation {
    /// The device moves (SF_MOVING set).
    Moving,
    /// The device does not move.
    Idle,
    /// The probe got no usable answer.
    Unknown,
}

/// The outcome of a recovery probe.
#[derive(Debug, PartialEq)]
pub(crate) enum Verdict {
    /// The final reply is lost: the request is abandoned and its id free. Call
    /// [`Pairing::next`].
    Abandoned,
    /// The device moves: these calls, queued behind the move before the probe was sent, are to
    /// be refused with E_ALREADY_RUNNING (3.2.2: the device refuses a motion command while one
    /// runs). Calls queued after it wait for the next probe.
    Running(Vec<Token>),
    /// No conclusion yet (or the request is gone): another probe follows.
    Undecided,
}

/// The pairing state of one connection.
#[derive(Debug)]
pub(crate) struct Pairing {
    ids: IntMap<u8, IdState>,
    /// The stop and FAST STOP requests sent and not answered yet, by id.
    stops: IntMap<u8, Stops>,
    grace: Duration,
    /// (reply hold, motion hold): see [`Pairing::set_holds`].
    holds: (Duration, Duration),
    /// The transport keeps replies in order and loses none (TCP, serial): a released id can
    /// be fenced by a barrier ([`Due::Fenced`]).
    ordered: bool,
    /// On an ordered transport, how much longer than other requests an unanswered loop-back
    /// keeps its id: see [`Pairing::set_resync`].
    resync: Duration,
    /// The requests of the pairing's own on the wire or queued, and what they are for
    /// ([`internal`]); every other token is a caller's.
    internal: IntMap<Token, Internal>,
    /// What the task has to do next ([`Pairing::poll`]).
    out: VecDeque<Output>,
    /// The last token handed out ([`Pairing::token`]).
    next_token: Token,
    /// The deadline of a recovery probe from when it is made: the connection's query timeout
    /// as configured ([`Pairing::set_holds`]).
    probe_timeout: Duration,
}

impl Pairing {
    /// `grace`: how long after its caller's deadline an unanswered request keeps its id, and
    /// the spacing of the two observations that release a motion command under recovery.
    pub(crate) fn new(grace: Duration) -> Self {
        Self {
            ids: IntMap::default(),
            stops: IntMap::default(),
            grace,
            holds: (Duration::MAX, Duration::MAX),
            ordered: false,
            resync: Duration::ZERO,
            internal: IntMap::default(),
            out: VecDeque::new(),
            next_token: 0,
            probe_timeout: super::DEFAULT_QUERY_TIMEOUT,
        }
    }

    /// On an ordered transport, an unanswered loop-back (0x06: every barrier is one) keeps its
    /// id `resync` longer than other requests: the reply hold + `resync` + grace from its
    /// send. A request whose length field was corrupted on the way may leave the device's
    /// decoder waiting for thousands of bytes, every later frame swallowed, until the line
    /// falls silent (the manual says nothing about how the device recovers, 1.2.1; the
    /// crate's simulator drops such a frame after the partial frame timeout of silence). The
    /// barriers of fenced ids follow each other as each is released: at one per reply hold +
    /// grace the line would never be silent that long, and the fenced ids would stay fenced.
    /// So the line rests for `resync` after each barrier, and the barrier still gets its
    /// round trip after the device resynchronised (the explorer's
    /// `wsg-serial:0xae89110881bc3727`). Only loop-backs: a stop is never held, and a caller's
    /// own loop-back with a timeout is released at its deadline + grace as before. A stop's
    /// barrier (its echo proves the stop's reply lost, [`super::stops`]) is a loop-back too:
    /// when that echo is lost as well, the stop goes out again up to `resync` later than
    /// without the rest; and a device stuck so would swallow a re-sent stop anyway, which only
    /// the rest lets through.
    pub(crate) fn set_resync(&mut self, resync: Duration) {
        self.resync = resync;
    }

    /// The (reply hold, motion hold) of a request of `id` ([`Pairing::set_holds`],
    /// [`Pairing::set_resync`]).
    fn holds_of(&self, id: u8) -> (Duration, Duration) {
        let (reply, motion) = self.holds;
        if self.ordered && id == id::LOOP {
            (reply.saturating_add(self.resync), motion)
        } else {
            (reply, motion)
        }
    }

    /// Bounds how long a request keeps its id when its caller's deadline bounds nothing: the
    /// caller has no timeout ([`is_never`](crate::deadline::is_never), `Duration::MAX`) or is gone ([`Pairing::prune`]).
    /// Then an unacknowledged request is released `reply` + grace after it was sent (its
    /// immediate reply or E_CMD_PENDING is lost), and an acknowledged motion goes under
    /// recovery `motion` after it was sent. A caller without timeout still waiting then gets
    /// the error of the release. A caller waiting with a timeout of its own is bounded by its
    /// deadline only, however much longer than `reply` or `motion` it is: the call gets the
    /// timeout it asked for.
    ///
    /// A motion hold of "no timeout" (`Duration::MAX`: the connection's motion timeout is
    /// none) bounds nothing: the reply hold stands in for it. Recovery releases a motion only
    /// on the device's evidence that its final reply is lost (two "not moving" a grace apart,
    /// [`Pairing::on_probe`]), so starting it early is sound: a move that runs on is probed
    /// once per grace until it ends, and its final reply still completes the call. Without
    /// it an acknowledged motion of a caller without timeout whose final reply was lost (a
    /// damaged frame is dropped like a lost one) was never probed, and held its id and its
    /// caller until another call of the id came (issue 29 B, rule 8 of the explorer:
    /// `wsg-serial:0xac729dceeaab2b0d`, `wsg-udp:0x66132f2f8481310d`,
    /// `wsg-tcp:0xf9a242cb8cee5995`, each on a client drawn with no motion timeout).
    ///
    /// A reply hold of "no timeout" (the connection's query timeout is none) bounds nothing
    /// either: the default query timeout stands in for it (the device answers a command, or
    /// acknowledges it, at once: 1.2.2, 1.3). The holds are what bound the client's own
    /// requests, which have no caller and no deadline: a loop-back barrier whose echo was lost
    /// was never sent again with an unbounded reply hold, and its id stayed fenced for good
    /// (`tests/wsg_barrier_pace.rs`).
    pub(crate) fn set_holds(&mut self, reply: Duration, motion: Duration) {
        self.probe_timeout = reply;
        let reply = if is_unbounded(reply) {
            super::DEFAULT_QUERY_TIMEOUT
        } else {
            reply
        };
        let motion = if is_unbounded(motion) { reply } else { motion };
        self.holds = (reply, motion);
    }

    /// The reply hold in force ([`Pairing::set_holds`]): what a caller without timeout whose
    /// request was released waited for.
    pub(crate) fn reply_hold(&self) -> Duration {
        self.holds.0
    }

    /// Says whether the transport keeps replies in order (TCP, serial, an attached stream):
    /// then an id released with no reply waits for a barrier before its next request goes out
    /// ([`Due::Fenced`]). On UDP it cannot: a barrier's echo proves nothing about a datagram
    /// still on its way.
    pub(crate) fn set_ordered(&mut self, ordered: bool) {
        self.ordered = ordered;
    }

    /// The barrier of fenced id `id` came back at `now`: every reply the device sent before it
    /// has been read, so no immediate reply of the released request can come any more. Call
    /// [`Pairing::next`] for it. A released motion command got no reply at all, E_CMD_PENDING
    /// included, yet that may have been lost (a corrupted frame is dropped) while the move
    /// runs, and its final reply then comes at any time: it goes back on the wire under
    /// recovery, like a move that outlasts its caller, so that a final reply cannot complete
    /// the next request of the id (the explorer's `wsg-tcp:0xbd5fd685504fe279`). For stop or
    /// FAST STOP: the unanswered stops sent before the barrier are lost; returns whether the
    /// stop is to be sent again now (recorded as sent).
    fn unfence(&mut self, id: u8, now: Instant) -> bool {
        if let Some(stops) = self.stops.get_mut(&id) {
            let again = stops.unfence(now, self.grace);
            if stops.is_idle() {
                self.stops.remove(&id);
            }
            return again;
        }
        if let Some(st) = self.ids.get_mut(&id) {
            st.fenced = false;
            // A released motion goes back under recovery (it may run, its acknowledgement
            // lost); a released finger power request never acknowledged before the echo got
            // no reply at all: it runs nothing, and nothing of it is owed.
            if let Some(mut f) = st.released.take().filter(|_| is_motion(id)) {
                f.acknowledged = true;
                f.probe_at = Some(now);
                st.in_flight = Some(f);
            }
        }
        false
    }

    /// A request of `id` is handed to the task to send: a motion command the device accepts
    /// makes the stops sent before it no longer owed to the device once nobody waits for them
    /// ([`super::stops`]: a late stop would abort this newer motion).
    fn sending(&mut self, id: u8) {
        if is_motion(id) && !self.stops.is_empty() {
            for stops in self.stops.values_mut() {
                stops.motion_sent(id);
            }
        }
    }

    /// Motion command `id` got its first answer: acknowledged (`accepted`, E_CMD_PENDING) or
    /// a final one without that (refused: it never ran). See [`Pairing::sending`].
    fn motion_answered(&mut self, id: u8, accepted: bool) {
        if is_motion(id) && !self.stops.is_empty() {
            for stops in self.stops.values_mut() {
                stops.motion_answered(id, accepted);
            }
        }
    }

    /// Takes `req` in at `now`: send it, queue it, or refuse it.
    pub(crate) fn submit(&mut self, req: Request, now: Instant) -> Submit {
        let id = req.frame.id;
        if is_stop(id) {
            let (grace, ordered, hold) = (self.grace, self.ordered, self.holds.0);
            self.stops
                .entry(id)
                .or_insert_with(|| Stops::new(ordered).with_reply_hold(hold))
                .submit(req.token, req.deadline, now, grace);
            return Submit::Send(req);
        }
        // A loop-back that proves a stop lost goes ahead of the loop-backs queued for other
        // ids (each may hold the loop-back id its query timeout + partial frame timeout +
        // grace): a lost stop is sent again only at its echo (the explorer's
        // wsg-serial:0xc592a5bd282c39eb: behind the barriers of four fenced ids, a stop went out
        // again 12.5 s after its call).
        let urgent = matches!(
            self.internal.get(&req.token),
            Some(Internal::Barrier { id, .. }) if is_stop(*id)
        );
        let holds = self.holds_of(id);
        let st = self.ids.entry(id).or_default();
        if st.in_flight.is_none() && st.queue.is_empty() && !st.fenced {
            st.in_flight = Some(InFlight::new(&req, self.grace, holds, now));
            self.sending(id);
            return Submit::Send(req);
        }
        if urgent {
            st.queue.push_front(req);
        } else {
            st.queue.push_back(req);
        }
        st.verify_soon(id, now, self.grace);
        Submit::Queued
    }

    /// Drops the queued (never sent) requests of `id` whose caller is gone, and the waiting stop
    /// requests whose caller is gone; returns their tokens. Called before queueing another, so
    /// that callers who keep timing out cannot grow the queue: it holds at most one request per
    /// live caller. A request of `id` on the wire whose caller went away before its deadline
    /// (`now`) is bounded by the holds from now on ([`Pairing::set_holds`]): the call about
    /// to queue behind it waits at most until the hold after its send, not until the gone
    /// caller's deadline. A caller gone at or after its deadline timed out: its request keeps
    /// the id until that deadline + grace, as any (a late reply may still come).
    pub(crate) fn prune(
        &mut self,
        id: u8,
        alive: impl Fn(Token) -> bool,
        now: Instant,
    ) -> Vec<Token> {
        let mut gone = Vec::new();
        // The pairing's own requests wait for no caller: always alive.
        let internal = &self.internal;
        let alive = |t| alive(t) || internal.contains_key(&t);
        if let Some(stops) = self.stops.get_mut(&id) {
            gone.extend(stops.prune(alive));
        }
        // One lookup (the hot path: a call of an id nobody else uses finds no state at all).
        let Some(st) = self.ids.get_mut(&id) else {
            return gone;
        };
        if let Some(f) = st.in_flight.as_mut() {
            if f.held && now < f.deadline && !alive(f.token) {
                f.forsake();
            }
        }
        if !st.queue.is_empty() {
            st.queue.retain(|r| {
                let keep = alive(r.token);
                if !keep {
                    gone.push(r.token);
                }
                keep
            });
        }
        gone
    }

    /// The request of `id` on the wire is done: whether requests of `id` wait to be sent
    /// ([`Pairing::next`] then sends them). If none waits, the id's state goes now (one map
    /// lookup on the hot path: a reply with nobody queued behind it).
    pub(crate) fn done(&mut self, id: u8) -> bool {
        let Some(st) = self.ids.get_mut(&id) else {
            return false;
        };
        if !st.queue.is_empty() {
            return true;
        }
        if st.in_flight.is_none() && !st.pending_owed && !st.fenced {
            self.ids.remove(&id);
        }
        false
    }

    /// Asks for a probe at `now` if calls of motion command `id` wait behind its acknowledged
    /// request (called when it is acknowledged).
    fn verify_queued(&mut self, id: u8, now: Instant) {
        if let Some(st) = self.ids.get_mut(&id) {
            st.verify_soon(id, now, self.grace);
        }
    }

    /// Pairs a received reply.
    fn on_reply(&mut self, reply: Reply, now: impl Fn() -> Instant) -> Event {
        if is_stop(reply.id) {
            let done = self.stop_replied(reply.id);
            return if done.is_empty() {
                Event::Unsolicited(reply)
            } else {
                Event::Stopped(done, reply)
            };
        }
        let Some(st) = self.ids.get_mut(&reply.id) else {
            return Event::Unsolicited(reply);
        };
        if st.in_flight.is_none() && reply.status == Status::CmdPending {
            if let Some(mut f) = st.released.take_if(|_| !is_motion(reply.id)) {
                // Finger power on, released unacknowledged (its request reached the device
                // late), accepted now: it ends FINGER_POWER_ON_DURATION from now, its final
                // reply then, likely after the barrier's echo would free the id. Back on the
                // wire, acknowledged, kept until it has ended, so that final reply cannot
                // answer the next request of the id (the explorer's wsg-tcp:0xe47e133ec0985c92:
                // the next finger power on returned the old one's E_SUCCESS at once).
                f.acknowledged = true;
                f.held = false;
                f.ended_release_at = after(after(now(), FINGER_POWER_ON_DURATION), self.grace);
                let token = f.token;
                st.in_flight = Some(f);
                return Event::Accepted(token);
            }
            if let Some(mut f) = st.released.take() {
                // The released motion was received after all and runs: its final reply will
                // come at any time, before or after the barrier. Back on the wire, acknowledged,
                // probed on the schedule of any acknowledged motion: at its caller's deadline or
                // the motion hold after it was sent, whichever comes first (usually passed: at
                // once). The deadline alone is never for a caller without timeout (saturated).
                tracing::warn!(
                    id = reply.id,
                    "WSG motion released without a reply was accepted after all: under recovery"
                );
                f.acknowledged = true;
                f.held = false;
                f.probe_at = Some(f.recovery_at());
                let token = f.token;
                st.in_flight = Some(f);
                self.motion_answered(reply.id, true);
                return Event::Accepted(token);
            }
        }
        let Some(f) = st.in_flight.as_mut() else {
            if st.fenced && st.released.is_some() {
                // A released request's own final answer, before its barrier's echo: on an
                // ordered stream nothing else of its id can come now (one request of an id is
                // on the wire at a time; motions and finger power are not streamed). For a
                // motion without E_CMD_PENDING before it: it ran nothing, or its
                // acknowledgement was damaged and it has ended; either way nothing a stop could
                // abort, and nothing to put back on the wire at the echo. A lost stop waiting
                // for this answer is owed again ([`super::stops`]; dropped here, the stop went
                // out only when a later motion was refused: the explorer's
                // `wsg-tcp:0x701cd76bbfcd92f7`).
                st.released = None;
                tracing::debug!(id = reply.id, status = %reply.status,
                    "WSG released request answered before its barrier's echo: nothing of it runs");
                self.motion_answered(reply.id, false);
            } else if st.fenced {
                // The released request's late reply (or an auto-update of the id): no request
                // of the id is on the wire, so it answers none.
                tracing::debug!(id = reply.id, status = %reply.status,
                    "WSG reply of a fenced id (released after its deadline, barrier not back yet)");
            }
            return Event::Unsolicited(reply);
        };
        if f.rejects(&reply) {
            tracing::warn!(id = reply.id, status = %reply.status,
                "WSG reply that cannot answer the request on the wire: dropped");
            return Event::Unsolicited(reply);
        }
        if let (Settle::Barrier { last, .. }, Status::Success) = (&mut f.settle, reply.status) {
            // An update or the reply: the loop-back's echo decides (`Pairing::settle`).
            *last = Some(reply.clone());
            return Event::Unsolicited(reply);
        }
        if reply.status == Status::CmdPending {
            let token = f.token;
            if !f.acknowledged {
                f.acknowledged = true;
                f.ack_doubtful = std::mem::take(&mut st.pending_owed);
                f.probe_at = Some(f.recovery_at());
                if !is_motion(reply.id) {
                    // Finger power on ends about FINGER_POWER_ON_DURATION after the device
                    // *received* it, which is no later than this acknowledgement's arrival:
                    // from its write alone, a request held on the way was released before its
                    // final reply, and that reply answered the next request of the id (the
                    // explorer's wsg-tcp:0x4214ee25a9542f20: received 630 ms after its write).
                    f.ended_release_at = f
                        .ended_release_at
                        .max(after(after(now(), FINGER_POWER_ON_DURATION), self.grace));
                }
                self.motion_answered(reply.id, true);
            }
            return Event::Accepted(token);
        }
        let token = f.token;
        let acknowledged = f.acknowledged;
        // E_ALREADY_RUNNING is only ever an immediate refusal (no E_CMD_PENDING before it).
        st.pending_owed = !acknowledged && reply.status != Status::AlreadyRunning;
        st.in_flight = None;
        if !acknowledged {
            // Refused at once (or answered without E_CMD_PENDING): the motion never ran.
            self.motion_answered(reply.id, false);
        }
        Event::Resolved(token, reply)
    }

    /// The request `token` of `id` just sent is answered through a loop-back barrier sent after
    /// it ([`Pairing::settle`]): the device may stream updates of `id` (manual 1.4), which
    /// carry the reply's id and form, so the next frame of `id` may be an update sent before
    /// the device received the request. Sound on ordered transports only (the device answers
    /// in order, and the stream keeps it).
    fn settle_by_barrier(&mut self, id: u8, token: Token) {
        if let Some(f) = self.in_flight_mut(id, token) {
            f.settle = Settle::Barrier {
                last: None,
                damaged: false,
            };
        }
    }

    /// The decoder dropped a damaged frame (a bad checksum, or bytes skipped as noise): it may
    /// have been the reply of a request settled by a barrier, and the last frame of its id an
    /// update the device sent before it read the request (issue 29 A). Each such request is
    /// asked again at its echo ([`Pairing::settle`]). Rare, so a walk over the ids.
    pub(crate) fn on_damage(&mut self) {
        for st in self.ids.values_mut() {
            if let Some(InFlight {
                settle: Settle::Barrier { damaged, .. },
                ..
            }) = st.in_flight.as_mut()
            {
                *damaged = true;
            }
        }
    }

    /// The echo of the barrier sent after request `token` of `id` came at `now`: every frame
    /// the device sent before it has been read, the reply to the request among them, so the
    /// last E_SUCCESS frame of `id` is the reply or an update sent after it (a value measured
    /// after the device received the request): it answers, and the id is free. Unless a
    /// damaged frame came in between, which may have been the reply: the request is to be sent
    /// again (a query or a stream's switch, both idempotent), with a barrier of its own
    /// ([`Settled::Again`]), at most [`MAX_ASKED_AGAIN`] times. Nothing when the request is no longer on the wire, or got no frame
    /// at all (then it is lost: it waits for its release, and no later frame answers it).
    fn settle(&mut self, id: u8, token: Token, now: Instant) -> Settled {
        let (reply_hold, _) = self.holds_of(id);
        let grace = self.grace;
        let Some(f) = self.in_flight_mut(id, token) else {
            return Settled::Nothing;
        };
        let Settle::Barrier { last, damaged } = std::mem::replace(&mut f.settle, Settle::Lost)
        else {
            return Settled::Nothing;
        };
        if damaged {
            return match f.ask_again(id, token, now, reply_hold, grace) {
                Some(request) => Settled::Again(request),
                None => {
                    tracing::warn!(
                        id,
                        "WSG frames damaged before every echo of a streamed query: \
                        no answer taken, the query waits for its release"
                    );
                    Settled::Nothing
                }
            };
        }
        let Some(reply) = last else {
            return Settled::Nothing;
        };
        if let Some(st) = self.ids.get_mut(&id) {
            st.in_flight = None;
            st.pending_owed = false;
        }
        Settled::Answer(reply)
    }

    /// The barrier sent after request `token` of `id` got no echo: the frames of `id` cannot
    /// be told apart, so none answers it (it waits for its release).
    fn settle_failed(&mut self, id: u8, token: Token) {
        if let Some(f) = self.in_flight_mut(id, token) {
            f.settle = Settle::Lost;
        }
    }

    fn in_flight_mut(&mut self, id: u8, token: Token) -> Option<&mut InFlight> {
        self.ids
            .get_mut(&id)?
            .in_flight
            .as_mut()
            .filter(|f| f.token == token)
    }

    /// A reply (usable or not) of stop id `id` arrived: the stop calls it completes.
    fn stop_replied(&mut self, id: u8) -> Vec<Token> {
        let Some(stops) = self.stops.get_mut(&id) else {
            return Vec::new();
        };
        let done = stops.on_reply();
        if stops.is_idle() {
            self.stops.remove(&id);
        }
        done
    }

    /// A reply of `id` too short to carry a status code: it still ends the request(s) on the
    /// wire (it is their answer, just unusable). Returns their tokens.
    fn on_malformed(&mut self, id: u8) -> Vec<Token> {
        if is_stop(id) {
            return self.stop_replied(id);
        }
        self.ids
            .get_mut(&id)
            .and_then(|st| st.in_flight.take())
            .map(|f| f.token)
            .into_iter()
            .collect()
    }

    /// The next request of `id` to send once its id is free, skipping requests whose caller is
    /// gone (they were never sent, so nothing needs to be consumed for them). Returns the
    /// skipped tokens too, so their bookkeeping can be dropped.
    pub(crate) fn next(
        &mut self,
        id: u8,
        alive: impl Fn(Token) -> bool,
        now: Instant,
    ) -> (Option<Request>, Vec<Token>) {
        let mut skipped = Vec::new();
        let holds = self.holds_of(id);
        let internal = &self.internal;
        let alive = |t| alive(t) || internal.contains_key(&t);
        let Some(st) = self.ids.get_mut(&id) else {
            return (None, skipped);
        };
        if st.in_flight.is_some() || st.fenced {
            return (None, skipped);
        }
        while let Some(req) = st.queue.pop_front() {
            if alive(req.token) {
                st.in_flight = Some(InFlight::new(&req, self.grace, holds, now));
                self.sending(id);
                return (Some(req), skipped);
            }
            skipped.push(req.token);
        }
        if !st.pending_owed && !st.fenced {
            self.ids.remove(&id);
        }
        (None, skipped)
    }

    /// Records what a probe of the acknowledged motion `token` of `id` observed, at `now`
    /// (when its answer arrived, or when the probe was given up); `probe` is the probe's own
    /// token (tokens grow: calls with a smaller one were made before the probe was sent).
    ///
    /// The request is abandoned on the second "not moving" in a row; the probe after the first
    /// is due a grace period later, so a final reply sent after the device stopped moving has
    /// that long to arrive (Anhang B: the flags are not synchronised with the end of a move).
    /// "Moving" refuses the calls made before the probe went out: what they are refused on was
    /// true after they were made.
    fn on_probe(
        &mut self,
        id: u8,
        token: Token,
        seen: Observation,
        now: Instant,
        probe: Token,
    ) -> Verdict {
        let grace = self.grace;
        let Some(st) = self.ids.get_mut(&id) else {
            return Verdict::Undecided;
        };
        let Some(f) = st.in_flight.as_mut().filter(|f| f.token == token) else {
            return Verdict::Undecided;
        };
        match (seen, f.idle_seen) {
            (Observation::Idle, Some(first)) if now >= after(first, grace) => {
                st.in_flight = None;
                // The device's word for a motion whose answer never came: it does not run. A
                // lost stop that waited for that answer is owed again ([`super::stops`]): it
                // stayed unsent until a later motion was refused (the explorer's
                // `wsg-serial:0x69627d80b4046207`: a pre-position sent after a lost FAST STOP,
                // its request damaged, never answered).
                self.motion_answered(id, false);
                return Verdict::Abandoned;
            }
            // A second "not moving" less than a grace after the first proves nothing yet (the
            // final reply may still come, Anhang B): the first stands, another probe follows.
            (Observation::Idle, Some(_)) => {}
            (Observation::Idle, None) => f.idle_seen = Some(now),
            (Observation::Moving | Observation::Unknown, _) => f.idle_seen = None,
        }
        let mut refused = Vec::new();
        if seen == Observation::Moving {
            st.queue.retain(|r| {
                let before = r.token < probe;
                if before {
                    refused.push(r.token);
                }
                !before
            });
        }
        f.probe_at = Some(if seen == Observation::Moving && !st.queue.is_empty() {
            // Calls made after that probe went out: ask again for them.
            now
        } else if !st.queue.is_empty() || now >= f.recovery_at() {
            after(now, grace)
        } else {
            // Nobody waits and the caller still does: no more probes before its deadline.
            // `recovery_at`, not the deadline: a caller without timeout (or one gone) has a
            // saturated deadline, and waiting for it left a move whose final reply was lost
            // unprobed for good after its first "not moving" (issue 29 B).
            f.recovery_at().max(after(now, grace))
        });
        if seen == Observation::Moving {
            Verdict::Running(refused)
        } else {
            Verdict::Undecided
        }
    }

    /// When the next request needs the task ([`Pairing::due`]).
    pub(crate) fn next_due(&self) -> Option<Instant> {
        let ids = self
            .ids
            .iter()
            .filter_map(|(id, st)| st.in_flight.as_ref()?.due(*id))
            .min();
        // Checked apart: this runs on every pass of the task's loop, and stops are rare.
        if self.stops.is_empty() {
            return ids;
        }
        let stops = self.stops.values().filter_map(Stops::next_due).min();
        match (ids, stops) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The requests whose time has come by `now`: released ids (call [`Pairing::next`] for each
    /// afterwards) and recovery probes to send.
    fn due(&mut self, now: Instant) -> Vec<Due> {
        let mut out = Vec::new();
        let grace = self.grace;
        for (id, stops) in &mut self.stops {
            match stops.due(now, grace) {
                Some(StopDue::Resend) => out.push(Due::ResendStop(*id)),
                Some(StopDue::Barrier) => out.push(Due::StopBarrier(*id)),
                None => {}
            }
        }
        self.stops.retain(|_, s| !s.is_idle());
        for (id, st) in &mut self.ids {
            let Some(f) = &mut st.in_flight else {
                continue;
            };
            if f.due(*id).is_none_or(|at| at > now) {
                continue;
            }
            if f.acknowledged && is_motion(*id) {
                f.probe_at = None;
                out.push(Due::Probe(*id, f.token));
            } else if self.ordered && *id != id::LOOP {
                // No (final) reply: on an ordered stream the next request of the id waits for
                // a barrier. (A loop reply needs none: it must echo its own payload.) An
                // acknowledged one here is no motion (those are probed above): finger power on,
                // whose command has ended by now, so its final reply comes before the echo
                // (module docs; wsg-serial:0xfdb842249ad7b4b3).
                st.fenced = true;
                out.push(Due::Fenced(*id, f.token));
                st.released = st.in_flight.take().filter(|_| may_be_acknowledged(*id));
            } else {
                out.push(Due::Released(*id, f.token));
                st.in_flight = None;
            }
        }
        out
    }

    /// Forgets everything (the pairing's own requests and the outputs not taken yet
    /// included); returns every token still waiting or on the wire.
    pub(crate) fn drain(&mut self) -> Vec<Token> {
        self.internal.clear();
        self.out.clear();
        let mut out = Vec::new();
        for (_, st) in self.ids.drain() {
            out.extend(st.in_flight.map(|f| f.token));
            out.extend(st.queue.into_iter().map(|r| r.token));
        }
        for (_, stops) in self.stops.drain() {
            out.extend(stops.drain());
        }
        out
    }
}

mod in_flight;
mod internal;
#[cfg(test)]
mod tests;
