//! One command id's state in the pairing machine: the request on the wire ([`InFlight`]),
//! what waits behind it, and what a released request leaves behind ([`IdState`]). The rules
//! that read and change them are in the parent module ([`super::Pairing`]).

use std::collections::VecDeque;
use std::time::Duration;

use bytes::Bytes;
use tokio::time::Instant;

use super::{is_motion, Request, Token};
use crate::deadline::{after, is_never};
use crate::wsg::client::FINGER_POWER_ON_DURATION;
use crate::wsg::command::id;
use crate::wsg::{Frame, Reply, Status};

#[derive(Debug)]
pub(super) struct InFlight {
    pub(super) token: Token,
    /// E_CMD_PENDING seen: a final reply is guaranteed to follow.
    pub(super) acknowledged: bool,
    pub(super) deadline: Instant,
    /// When an unanswered request gives its id up: deadline + grace.
    pub(super) release_at: Instant,
    /// Its caller waits, with a timeout of its own (not [`is_never`]): only its deadline
    /// bounds the id, the holds do not ([`super::Pairing::set_holds`]). Cleared when the caller is
    /// found gone ([`super::Pairing::prune`]); never set for a caller without timeout.
    pub(super) held: bool,
    /// When an unacknowledged request gives its id up if not [`InFlight::held`]: sent +
    /// [`super::Pairing::set_holds`]'s reply hold + grace (1.2.2, 1.3: the device answers a command,
    /// or acknowledges it with E_CMD_PENDING, at once).
    pub(super) unacked_release_at: Instant,
    /// When an acknowledged command that is no motion (finger power on) gives its id up at the
    /// earliest: sent + [`FINGER_POWER_ON_DURATION`] + grace, moved to its E_CMD_PENDING's
    /// arrival + that duration + grace if later. The device ends it that long after it received
    /// it (3.6.3: "nach etwa 500 ms"), no later than the acknowledgement came, so its final reply
    /// has been sent by then, whatever its caller's timeout (zero included).
    pub(super) ended_release_at: Instant,
    /// When an acknowledged motion goes under recovery if not [`InFlight::held`]: sent +
    /// the motion hold (recovery releases only on evidence, so starting it early is sound).
    pub(super) motion_probe_at: Instant,
    /// An acknowledged motion command under recovery: when the next probe is due (`None`
    /// while one is out).
    pub(super) probe_at: Option<Instant>,
    /// When the answer of the last probe, "not moving", arrived (the first of the two
    /// observations needed; the second probe goes out a grace period after it).
    pub(super) idle_seen: Option<Instant>,
    /// Acknowledged by an E_CMD_PENDING that may have been the late one of the previous
    /// request of this id (see [`IdState::pending_owed`]): an E_ALREADY_RUNNING may then be
    /// this request's own refusal, and is not dropped.
    pub(super) ack_doubtful: bool,
    /// How many times it was sent again because a damaged frame came before its barrier's
    /// echo ([`super::Pairing::settle`], at most [`super::MAX_ASKED_AGAIN`]).
    pub(super) asked_again: u8,
    /// The payload sent: a loop reply (0x06) must echo it.
    pub(super) payload: Bytes,
    /// How its reply is told from the auto-updates of its id (see
    /// [`super::Pairing::settle_by_barrier`]).
    pub(super) settle: Settle,
}

/// How the request on the wire of an id is answered.
#[derive(Debug, Default)]
pub(super) enum Settle {
    /// By the next reply of its id.
    #[default]
    First,
    /// The device may stream updates of this id, which share the reply's id and form (manual
    /// 1.4, 3.4.1–3.4.6): by the last E_SUCCESS frame of the id received before the echo of a
    /// loop-back sent after the request. A frame that is not E_SUCCESS is no update: the reply.
    Barrier {
        /// The last E_SUCCESS frame of the id received so far.
        last: Option<Reply>,
        /// A damaged frame came since the request went out ([`super::Pairing::on_damage`]):
        /// it may have been the reply, and `last` an update sent before the device read the
        /// request (issue 29 A). The request is asked again at the echo.
        damaged: bool,
    },
    /// The loop-back's echo came with no frame of the id before it (the request got no reply:
    /// the device answers in order), or the loop-back got none: no later frame of the id is
    /// taken for its reply; the request waits for its release.
    Lost,
}

/// When an unacknowledged request sent at `sent` gives its id up if its caller's deadline does
/// not bound it: the reply hold + grace (1.2.2, 1.3: the device answers at once).
fn unacked_release(sent: Instant, reply_hold: Duration, grace: Duration) -> Instant {
    after(after(sent, reply_hold), grace)
}

impl InFlight {
    pub(super) fn new(
        req: &Request,
        grace: Duration,
        holds: (Duration, Duration),
        now: Instant,
    ) -> Self {
        Self {
            token: req.token,
            acknowledged: false,
            deadline: req.deadline,
            release_at: after(req.deadline, grace),
            held: !is_never(req.deadline, now),
            unacked_release_at: unacked_release(now, holds.0, grace),
            ended_release_at: after(after(now, FINGER_POWER_ON_DURATION), grace),
            motion_probe_at: after(now, holds.1),
            probe_at: None,
            idle_seen: None,
            ack_doubtful: false,
            asked_again: 0,
            payload: req.frame.payload.clone(),
            settle: Settle::First,
        }
    }

    /// Asks to be sent again at `now` (a streamed request whose settle window saw damage,
    /// [`super::Pairing::settle`]): a request to write (the same token and deadline), and a
    /// caller without timeout waits the reply hold from this send, as from the first. `None`
    /// once it was asked again [`super::MAX_ASKED_AGAIN`] times in a row.
    pub(super) fn ask_again(
        &mut self,
        id: u8,
        token: Token,
        now: Instant,
        reply_hold: Duration,
        grace: Duration,
    ) -> Option<Request> {
        if self.asked_again >= super::MAX_ASKED_AGAIN {
            return None;
        }
        self.asked_again += 1;
        self.unacked_release_at = unacked_release(now, reply_hold, grace);
        Some(Request {
            token,
            frame: Frame::new(id, self.payload.clone()),
            deadline: self.deadline,
        })
    }

    /// Whether `reply` provably answers some other request of the same id: a duplicate of an
    /// earlier reply, or the device's answer to a duplicated request (faults seen on UDP and by
    /// the fault matrix). Such a reply is consumed as unsolicited instead of ending this request.
    pub(super) fn rejects(&self, reply: &Reply) -> bool {
        // A loop reply carries the payload it echoes (3.1.1): another payload is not ours.
        let foreign_echo =
            reply.id == id::LOOP && reply.status == Status::Success && reply.data != self.payload;
        // Once the device has acknowledged this command, E_ALREADY_RUNNING cannot be its final
        // reply (1.3: that code is only ever an immediate refusal): it refuses a duplicate of it.
        // Unless the acknowledgement itself may have been another request's (UDP reorders).
        let refused_duplicate =
            self.acknowledged && !self.ack_doubtful && reply.status == Status::AlreadyRunning;
        let lost = matches!(self.settle, Settle::Lost);
        foreign_echo || refused_duplicate || lost
    }

    /// When this request needs the task next: its release, or its next recovery probe.
    pub(super) fn due(&self, id: u8) -> Option<Instant> {
        if self.acknowledged && is_motion(id) {
            self.probe_at
        } else if self.acknowledged && !self.held {
            // Acknowledged (not a motion), its caller without timeout or gone: its saturated
            // deadline bounds nothing, so the holds do. Its final reply comes about
            // FINGER_POWER_ON_DURATION after the acknowledgement (finger power on, manual
            // 3.6.3, is the only asynchronous command that is no motion): a lost one is given
            // up that much after the reply hold (issue 29 B: the call never ended). Never
            // before the command has ended (a caller gone before its short deadline): below.
            Some(
                self.release_at
                    .min(after(self.unacked_release_at, FINGER_POWER_ON_DURATION))
                    .max(self.ended_release_at),
            )
        } else if self.acknowledged {
            // Acknowledged (not a motion): its final reply is owed, the deadline bounds it, but
            // not before the command has ended (a caller with a short timeout): released (or
            // fenced, on an ordered transport) earlier, its final reply would come after the
            // release and answer the next call of the id.
            Some(self.release_at.max(self.ended_release_at))
        } else if self.held && !is_motion(id) {
            // Held: its caller's own deadline wins over the reply hold. Not a motion's: its
            // deadline is the motion timeout (30 s by default), while its E_CMD_PENDING comes
            // at once (1.3), so the reply hold still bounds the wait for that: a motion
            // command whose request or acknowledgement was lost fails after the query timeout
            // + grace, as before per-call timeouts won (not after the motion timeout).
            Some(self.release_at)
        } else {
            Some(self.release_at.min(self.unacked_release_at))
        }
    }

    /// When an acknowledged motion goes under recovery: at its caller's deadline, or, when
    /// its caller has none or is gone (not [`InFlight::held`]), the motion hold after it was
    /// sent if that comes first.
    pub(super) fn recovery_at(&self) -> Instant {
        if self.held {
            self.deadline
        } else {
            self.deadline.min(self.motion_probe_at)
        }
    }

    /// Its caller is gone: the holds bound the id from now on (a dropped call does not keep
    /// its id until its deadline: nobody waits for the reply).
    pub(super) fn forsake(&mut self) {
        self.held = false;
        if let Some(at) = self.probe_at {
            self.probe_at = Some(at.min(self.motion_probe_at));
        }
    }
}

#[derive(Debug, Default)]
pub(super) struct IdState {
    pub(super) in_flight: Option<InFlight>,
    pub(super) queue: VecDeque<Request>,
    /// The last request of this id got its final reply without an E_CMD_PENDING first: if it
    /// was asynchronous, its E_CMD_PENDING may still come (UDP reorders, manual 1.3 fixes the
    /// order only as sent), and must not be taken for the next request's acknowledgement.
    pub(super) pending_owed: bool,
    /// A request of this id was released with no reply at all, on an ordered transport: its
    /// reply may still be on its way, so the next request of the id waits until a barrier
    /// ([`super::Due::Fenced`]) proves that every reply sent before it has been read
    /// ([`super::Pairing::unfence`]).
    pub(super) fenced: bool,
    /// The request that fenced the id, if it may be acknowledged (a motion, finger power):
    /// if its E_CMD_PENDING still comes (before the barrier), the command runs and its final
    /// reply will follow, so it is taken back on the wire (a motion under recovery,
    /// [`super::Due::Probe`]; finger power until it has ended); if its final answer comes
    /// first, that is its answer (`Pairing::on_reply`).
    pub(super) released: Option<InFlight>,
}

impl IdState {
    /// Calls wait behind the acknowledged motion command of this id (`id`): ask the device
    /// at once whether it moves (a probe), unless a probe is out already. The calls are sent
    /// when the motion's final reply comes (or it is found lost), or refused when the device
    /// says it moves: never refused on the belief that it still runs.
    ///
    /// Only the first probe is pulled forward to `now`. After a first "not moving", the next
    /// probe is pulled forward no further than a `grace` after that answer: the release rule
    /// needs its two observations a grace apart whatever queues, since the final
    /// reply may follow the end of the move by that much (Anhang B). Pulling it to "now"
    /// abandoned a move whose final reply was still coming, and that reply then completed
    /// the next call of the id (the explorer's `wsg-tcp:0x8f85c166eeff961d`).
    pub(super) fn verify_soon(&mut self, id: u8, now: Instant, grace: Duration) {
        if self.queue.is_empty() || !is_motion(id) {
            return;
        }
        if let Some(f) = self.in_flight.as_mut().filter(|f| f.acknowledged) {
            if let Some(at) = f.probe_at {
                let soonest = f.idle_seen.map_or(now, |seen| after(seen, grace).max(now));
                f.probe_at = Some(at.min(soonest));
            }
        }
    }
}
