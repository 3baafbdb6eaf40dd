//! Pairing stop and FAST STOP replies with the calls they may answer: a pure state machine, no
//! I/O (part of [`super::pairing`]).
//!
//! A stop is never queued (manual 3.2.3/3.2.4: it stops "unmittelbar"), so several stops of one
//! id may be on the wire, and their replies carry nothing that tells them apart. A call may
//! only succeed on a reply to a stop sent at or after the call: a reply acknowledges "the
//! received command" (1.2.2), and an earlier stop may have been processed before a move that
//! started afterwards. So each stop sent gets a sequence number, each call remembers the first
//! stop sent for it, and a reply is taken for the **oldest** stop still unanswered: it answers
//! that one or a later one, so every call whose first stop is not later than that one completes
//! on it, and no other does. That holds only while no stop counts as unanswered whose reply
//! has in fact come (a reply lost to corruption) and none counts as answered or lost whose
//! reply is still on its way: the transports differ in how they keep the count right.
//!
//! - **TCP and serial** ([`Stops::new`] with `ordered`) keep the order and lose nothing but a
//!   corrupted reply. A stop is never given up on time: its reply may be stalled in transit
//!   for any time (a reply later than the grace, taken then for a later stop, made `stop()`
//!   return `Ok` for a stop the device had not received yet: the explorer's
//!   `wsg-tcp:0x2082b0e305e913c4`). A call that waits [`RESEND_AFTER`] without its reply gets a
//!   *barrier* instead ([`StopDue::Barrier`]): a loop-back whose echo (it comes after the reply
//!   to every command sent before it, 1.2.2) proves every stop sent before it and still
//!   unanswered lost ([`Stops::unfence`]); only then is the stop sent again. Sound; the count
//!   is two numbers, so no bound drops a stop unproven.
//!
//!   A stop the program asked for is a safety command: it is **delivered even after its caller
//!   stopped waiting** (timed out, or dropped the call). A stop whose reply has not come
//!   [`RESEND_AFTER`] after it was sent gets a barrier whether or not anybody waits, and a stop
//!   the echo proves lost is sent again ([`Stops::unfence`]) until the device answers one, at
//!   most [`MAX_OWED_RESENDS`] times in a row (each one proven lost by a barrier the device
//!   answered). Without it a stop whose *request* was damaged on the wire (the device drops
//!   it unanswered, 1.2.1) was never sent again once its caller had timed out, and the fingers
//!   never stopped (issue 29 E, the explorer's rule 9: `wsg-tcp:0xd11252be6d410fee`). One
//!   exception, the lead's decision: a stop whose caller is gone is **dropped** (logged) once
//!   the program has sent a motion command (home, pre-position, grasp, release: 3.2.1, 3.2.2,
//!   3.2.6, 3.2.7) after it: the program has moved on, and the late stop would abort that
//!   newer motion (3.2.3: it stops "jede laufende Fingerbewegung"). Only a motion the device
//!   may run counts: one it acknowledged (E_CMD_PENDING, 1.3). When a motion sent after the
//!   stop is still unanswered at the echo (sent after the barrier), the decision waits for its
//!   answer ([`Stops::motion_answered`]): a refusal that came after its caller gave up counts,
//!   and so does the device's word for one that never got an answer, two "not moving" a grace
//!   apart under recovery (it does not run: the stop is owed again). Until then the stop is
//!   held, the cautious side for the motion. A motion the device refused at once
//!   (E_ALREADY_RUNNING while the move the stop was for still runs, 3.2.2; E_NOT_INITIALIZED;
//!   E_ACCESS_DENIED after FAST STOP) starts nothing a stop could abort, and the stop is still
//!   owed (the explorer's `wsg-serial:0xd61c40d7cc3acb90`, `wsg-serial:0x06c24b314c9fa72f`).
//!   A newer stop of the id supersedes it too: its reply answers both, as for any stop. The
//!   re-send still goes out only at a barrier's echo, so the ordered count stays sound.
//! - **UDP** loses datagrams: a lost stop is never answered, so the replies are taken for
//!   stops one too early, and a call whose own stop was lost, or whose reply was taken for an
//!   earlier stop, would wait in vain. A call that waits [`RESEND_AFTER`] without its reply
//!   gets the stop sent again (idempotent), until its reply comes or its deadline passes. A
//!   stop unanswered for its caller's deadline plus the late-reply grace counts as lost; one
//!   whose callers have no timeout, the reply hold plus the grace after it was sent, as any
//!   request without timeout ([`super::pairing`]): a lost stop of such a caller counted as
//!   unanswered for ever, and every later stop call waited a resend per such stop before a
//!   reply could be its own, past its timeout (issue 29 D, the explorer's
//!   `wsg-udp:0xaf073ffc53d9a31d`: a quiet connection answering every stop at once). The
//!   count is never cut short to bound it: beyond [`MAX_UNANSWERED`] runs, a new stop joins
//!   the newest run, which then counts as lost when the last of its stops would. Evicting the
//!   oldest instead made a timely reply to it complete a call whose stop came later (issue
//!   29 D). Residual risks: a stop reply later than that grace, or a duplicated one, is taken
//!   for a later stop; and a stop sent again may reach the device after `stop()` returned
//!   (UDP reorders), stopping a move started right after (that move then ends with
//!   E_CMD_ABORTED, the device's own answer).

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use crate::deadline::{after, is_never};

/// Identifies one request for the task.
pub(crate) type Token = u64;

/// How long a waiting stop call goes without its reply before the stop is sent again: far
/// above a stop's round trip on any transport (the device answers at once), far below a
/// call's timeout.
pub(crate) const RESEND_AFTER: Duration = Duration::from_millis(100);

/// Runs of unanswered stops of one id kept at most on UDP ([`Run`]); beyond, a new stop joins
/// the newest run.
pub(crate) const MAX_UNANSWERED: usize = 16;

/// Ordered transport: how many times in a row a stop nobody waits for any more is sent again,
/// each time after a barrier's echo proved the one before lost, before it is given up (logged).
/// Each re-send costs [`RESEND_AFTER`] and a round trip, so the last goes out about a second
/// after the first was proven lost: a link that damages eight stops in a row while it carries
/// the barriers intact is no link a stop gets through; a bound keeps the task from sending
/// stops for ever to a device that never answers them.
pub(crate) const MAX_OWED_RESENDS: u32 = 8;

/// What the stops of one id need from the task ([`Stops::due`]).
#[derive(Debug, PartialEq)]
pub(crate) enum StopDue {
    /// Send the stop again (it is recorded as sent).
    Resend,
    /// Ordered transport: send a barrier (a loop-back with a payload of its own) and report its
    /// echo with [`Stops::unfence`].
    Barrier,
}

/// UDP: unanswered stops, `len` of them numbered from `first` on, all counting as lost at
/// `lost_at`. A reply answers the oldest (the next is `first + 1`). A stop joins a run only
/// when every run is kept ([`MAX_UNANSWERED`]), and only the newest, so a run's stops are
/// consecutive.
#[derive(Debug)]
struct Run {
    first: u64,
    len: u64,
    lost_at: Instant,
}

/// A caller waiting for a stop reply.
#[derive(Debug)]
struct Waiting {
    token: Token,
    /// The sequence number of the first stop sent at or after the call.
    first: u64,
    deadline: Instant,
}

/// The count of an ordered transport (TCP, serial): stops `oldest..next_seq` are unanswered.
/// No stop leaves it but by its reply (the oldest) or by a barrier's proof (all before it), so
/// it stays a range: two numbers, whatever the number of stops.
#[derive(Debug, Default)]
struct Ordered {
    /// The oldest stop not answered yet.
    oldest: u64,
    /// A barrier is out: the stops before this one still unanswered at its echo are lost.
    fence: Option<u64>,
    /// When unanswered stops get a barrier, whether or not anybody waits: [`RESEND_AFTER`]
    /// after the earliest stop sent since the last barrier went out. A stop proven lost is
    /// owed to the device (module docs), and a reply lost to corruption must not keep later
    /// calls one reply behind.
    check_at: Option<Instant>,
    /// The sequence number of the next stop when the latest motion command the device
    /// acknowledged was sent: the stops before it were sent before that motion, and are
    /// dropped, not sent again, once proven lost while nobody waits for them (module docs).
    moved_before: u64,
    /// The motions sent and not answered yet (at most one per motion id, [`super::pairing`]):
    /// their id, and the sequence number of the next stop when they were sent. Acknowledged,
    /// one counts for [`Ordered::moved_before`]; refused, it is forgotten; still out at a
    /// barrier's echo, it defers the decision ([`Ordered::deferred`]).
    moves_out: Vec<(u8, u64)>,
    /// A stop nobody waits for, proven lost by the echo of the barrier `fence` while a motion
    /// sent after it was unanswered: sent again if that motion is refused, dropped if it is
    /// accepted ([`Stops::motion_answered`]). Its echo's instant: when the re-send is due.
    deferred: Option<(u64, Instant)>,
    /// A deferred stop is to be sent again ([`Stops::due`]), from this instant.
    resend_owed: Option<Instant>,
    /// How many times in a row a stop nobody waited for was sent again after a barrier proved
    /// the one before lost ([`MAX_OWED_RESENDS`]); reset by a reply and by a call.
    owed_resends: u32,
}

/// The stops of one command id (0x22 or 0x23).
#[derive(Debug, Default)]
pub(crate) struct Stops {
    /// UDP: stops sent and not answered yet, oldest first.
    unanswered: VecDeque<Run>,
    waiting: Vec<Waiting>,
    next_seq: u64,
    /// When the stop is sent again, or (ordered) a barrier goes out, if no reply has come (only
    /// while someone waits).
    resend_at: Option<Instant>,
    /// `Some` on an ordered transport: the count of [`Ordered`] instead of `unanswered`.
    ordered: Option<Ordered>,
    /// UDP: how long after it was sent a stop whose callers have no timeout counts as lost,
    /// before the grace ([`Stops::with_reply_hold`]).
    reply_hold: Duration,
}

impl Stops {
    /// The stops of one id on a transport that keeps replies in order and loses none but a
    /// corrupted one (`ordered`: TCP, serial), or on UDP.
    pub(crate) fn new(ordered: bool) -> Self {
        Self {
            ordered: ordered.then(Ordered::default),
            ..Self::default()
        }
    }

    /// On UDP, a stop sent for callers without timeout ([`is_never`]) counts as lost `hold` +
    /// the grace after it was sent: the reply hold of [`super::pairing::Pairing::set_holds`],
    /// the bound of any request without timeout.
    pub(crate) fn with_reply_hold(mut self, hold: Duration) -> Self {
        self.reply_hold = hold;
        self
    }

    /// When a stop sent at `now` for callers waiting until `deadline` counts as lost on UDP.
    fn lost_at(&self, deadline: Instant, now: Instant, grace: Duration) -> Instant {
        let until = if is_never(deadline, now) {
            after(now, self.reply_hold)
        } else {
            deadline
        };
        after(until, grace)
    }

    /// Records a stop sent at `now`, counting as lost from `lost_at` on UDP (ordered: checked
    /// by a barrier [`RESEND_AFTER`] after `now`, if still unanswered).
    fn sent(&mut self, now: Instant, lost_at: Instant) -> u64 {
        let seq = self.next_seq;
        self.next_seq += 1;
        if let Some(o) = &mut self.ordered {
            // Checked soon whoever waits: a lost stop is owed to the device (module docs).
            let check = after(now, RESEND_AFTER);
            o.check_at = Some(o.check_at.map_or(check, |at| at.min(check)));
        } else {
            let full = self.unanswered.len() >= MAX_UNANSWERED;
            match self.unanswered.back_mut() {
                // Bounded without counting a stop lost before its time (module docs).
                Some(run) if full => {
                    run.len += 1;
                    run.lost_at = run.lost_at.max(lost_at);
                }
                _ => self.unanswered.push_back(Run {
                    first: seq,
                    len: 1,
                    lost_at,
                }),
            }
        }
        self.resend_at = Some(after(now, RESEND_AFTER));
        seq
    }

    /// Whether some stop sent is not answered (nor given up) yet.
    fn has_unanswered(&self) -> bool {
        match &self.ordered {
            Some(o) => o.oldest < self.next_seq,
            None => !self.unanswered.is_empty(),
        }
    }

    /// The latest deadline of the callers still waiting at `now`.
    fn latest_waiting(&self, now: Instant) -> Option<Instant> {
        self.waiting
            .iter()
            .map(|w| w.deadline)
            .filter(|d| *d > now)
            .max()
    }

    /// A stop call `token` with `deadline` whose stop is sent now.
    pub(crate) fn submit(
        &mut self,
        token: Token,
        deadline: Instant,
        now: Instant,
        grace: Duration,
    ) {
        let first = self.sent(now, self.lost_at(deadline, now, grace));
        if let Some(o) = &mut self.ordered {
            o.owed_resends = 0;
        }
        self.waiting.push(Waiting {
            token,
            first,
            deadline,
        });
    }

    /// A reply (or a malformed one) of this id arrived: the calls it completes. Empty when no
    /// stop is unanswered (a duplicate, or the reply to a stop given up as lost) or nobody
    /// waits for it.
    pub(crate) fn on_reply(&mut self) -> Vec<Token> {
        let answered = match &mut self.ordered {
            Some(o) if o.oldest < self.next_seq => {
                o.oldest += 1;
                o.owed_resends = 0;
                // A stop sent after the deferred one was answered: the device got a stop.
                o.deferred = None;
                o.resend_owed = None;
                o.oldest - 1
            }
            Some(_) => return Vec::new(),
            None => {
                let Some(run) = self.unanswered.front_mut() else {
                    return Vec::new();
                };
                let seq = run.first;
                run.first += 1;
                run.len -= 1;
                if run.len == 0 {
                    self.unanswered.pop_front();
                }
                seq
            }
        };
        let mut done = Vec::new();
        self.waiting.retain(|w| {
            let ends = w.first <= answered;
            if ends {
                done.push(w.token);
            }
            !ends
        });
        if self.waiting.is_empty() {
            self.resend_at = None;
        }
        done
    }

    /// The program sent motion command `id` (manual 3.2.1, 3.2.2, 3.2.6, 3.2.7): unless the
    /// device refuses it ([`Stops::motion_answered`]), the stops sent before it are no longer
    /// owed to the device once nobody waits for them (module docs).
    pub(crate) fn motion_sent(&mut self, id: u8) {
        if let Some(o) = &mut self.ordered {
            o.moves_out.retain(|(m, _)| *m != id);
            o.moves_out.push((id, self.next_seq));
        }
    }

    /// The motion `id` sent last got its first answer: `accepted` (E_CMD_PENDING, 1.3: it
    /// runs), or not (refused at once, or some other final reply: it never ran).
    pub(crate) fn motion_answered(&mut self, id: u8, accepted: bool) {
        let Some(o) = &mut self.ordered else {
            return;
        };
        let Some(at) = o.moves_out.iter().position(|(m, _)| *m == id) else {
            return;
        };
        let (_, mark) = o.moves_out.swap_remove(at);
        if accepted {
            o.moved_before = o.moved_before.max(mark);
        }
        let Some((fence, echo)) = o.deferred else {
            return;
        };
        if o.moved_before >= fence {
            o.deferred = None;
            o.owed_resends = 0;
            tracing::warn!(
                "a stop whose caller stopped waiting was lost (a barrier proved it), and the \
                 device accepted a motion command sent after it: not sent again, it would abort \
                 that motion"
            );
        } else if o.moves_out.iter().all(|(_, mark)| *mark < fence) {
            // Every motion sent after it was refused: it ran nothing, the stop is owed.
            o.deferred = None;
            o.resend_owed = Some(echo);
        }
    }

    /// Forgets the waiting calls whose caller is gone; returns their tokens.
    pub(crate) fn prune(&mut self, alive: impl Fn(Token) -> bool) -> Vec<Token> {
        let mut gone = Vec::new();
        self.waiting.retain(|w| {
            let keep = alive(w.token);
            if !keep {
                gone.push(w.token);
            }
            keep
        });
        if self.waiting.is_empty() {
            self.resend_at = None;
        }
        gone
    }

    /// When [`Stops::due`] has something to do.
    pub(crate) fn next_due(&self) -> Option<Instant> {
        let lost = match &self.ordered {
            // The barrier's echo (or its own timeout, in the task) comes first.
            Some(o) if o.fence.is_some() => return None,
            Some(o) if o.resend_owed.is_some() => return o.resend_owed,
            Some(o) => o.check_at.filter(|_| self.has_unanswered()),
            None => self.unanswered.iter().map(|run| run.lost_at).min(),
        };
        match (self.resend_at, lost) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// At `now`: on UDP gives up the stops unanswered too long, and says whether the stop is
    /// to be sent again (recording it as sent): a caller still within its deadline has waited
    /// [`RESEND_AFTER`] since the last one. On an ordered transport, such a caller (or stops
    /// unanswered past their check) gets a barrier instead, while a stop is unanswered: the
    /// stop is sent again only once the barrier proved it lost ([`Stops::unfence`]).
    pub(crate) fn due(&mut self, now: Instant, grace: Duration) -> Option<StopDue> {
        if self.ordered.is_none() {
            self.unanswered.retain(|run| run.lost_at > now);
        } else if self.ordered.as_ref().is_some_and(|o| o.fence.is_some()) {
            return None;
        }
        let unanswered = self.has_unanswered();
        if let Some(o) = &mut self.ordered {
            if o.resend_owed.take().is_some() && !unanswered && o.owed_resends < MAX_OWED_RESENDS {
                // A deferred stop: the motions sent after it were refused (module docs).
                o.owed_resends += 1;
                tracing::warn!(
                    resend = o.owed_resends,
                    "a stop whose caller stopped waiting was lost (a barrier proved it), and the \
                     motion sent after it was refused: sent again"
                );
                self.sent(now, now);
                return Some(StopDue::Resend);
            }
        }
        let resend = self.resend_at.is_some_and(|at| at <= now);
        let latest = self.latest_waiting(now);
        if resend && latest.is_none() {
            // Only callers past their deadline wait (their futures have ended): no resend.
            self.resend_at = None;
        }
        let next_seq = self.next_seq;
        if let Some(o) = &mut self.ordered {
            let check = o.check_at.is_some_and(|at| at <= now);
            if check {
                o.check_at = None;
            }
            if unanswered && ((resend && latest.is_some()) || check) {
                o.fence = Some(next_seq);
                self.resend_at = None;
                return Some(StopDue::Barrier);
            }
        }
        let latest = latest.filter(|_| resend)?;
        self.sent(now, self.lost_at(latest, now, grace));
        Some(StopDue::Resend)
    }

    /// Ordered transport: the echo of the barrier asked by [`Stops::due`] came back at `now`.
    /// The device answers a connection's commands in order (1.2.2) and the stream keeps it, so
    /// every stop sent before the barrier and still unanswered is lost (its request or its
    /// reply damaged). Returns whether the stop is to be sent again now (recorded as sent): no
    /// stop sent after the barrier is unanswered (its reply would answer everyone), and a
    /// caller waits, or a stop was proven lost that is still owed to the device: no motion
    /// was sent after it, and it was not sent again [`MAX_OWED_RESENDS`] times in a row
    /// already (module docs).
    pub(crate) fn unfence(&mut self, now: Instant, grace: Duration) -> bool {
        let Some(o) = &mut self.ordered else {
            return false;
        };
        let Some(fence) = o.fence.take() else {
            return false;
        };
        // The newest stop proven lost, if any: `fence - 1` (all before the fence are lost).
        let lost = o.oldest < fence;
        o.oldest = o.oldest.max(fence);
        let Some(latest) = self.latest_waiting(now) else {
            self.resend_at = None;
            return self.owed(now, lost, fence);
        };
        if self.has_unanswered() {
            // A stop sent after the barrier is on its way: its reply completes every caller
            // (each one's first stop is not later). A barrier again if it does not come.
            self.resend_at = Some(after(now, RESEND_AFTER));
            return false;
        }
        self.sent(now, self.lost_at(latest, now, grace));
        true
    }

    /// [`Stops::unfence`] with nobody waiting: whether a stop proven lost (`lost`, the newest
    /// one `fence - 1`) is sent again now (recorded as sent, checked by a barrier
    /// [`RESEND_AFTER`] later).
    fn owed(&mut self, now: Instant, lost: bool, fence: u64) -> bool {
        if !lost || self.has_unanswered() {
            // Nothing lost, or a stop sent after the barrier is on its way: it gets a barrier
            // of its own ([`Stops::sent`]).
            return false;
        }
        let Some(o) = &mut self.ordered else {
            return false;
        };
        if o.moved_before >= fence {
            tracing::warn!(
                "a stop whose caller stopped waiting was lost (a barrier proved it), but the \
                 device accepted a motion command sent after it: not sent again, it would abort \
                 that motion"
            );
            o.owed_resends = 0;
            return false;
        }
        if o.moves_out.iter().any(|(_, mark)| *mark >= fence) {
            // A motion sent after it is not answered yet: accepted, the stop would abort it;
            // refused, it ran nothing and the stop is owed. Its answer decides.
            o.deferred = Some((fence, now));
            return false;
        }
        if o.owed_resends >= MAX_OWED_RESENDS {
            tracing::warn!(
                resends = o.owed_resends,
                "a stop whose caller stopped waiting was lost again and again: given up"
            );
            o.owed_resends = 0;
            return false;
        }
        o.owed_resends += 1;
        tracing::warn!(
            resend = o.owed_resends,
            "a stop whose caller stopped waiting was lost (a barrier proved it): sent again"
        );
        // No caller: it counts as lost only by a barrier's proof (`lost_at` is for UDP).
        self.sent(now, now);
        true
    }

    /// Every waiting call's token (the state is dropped).
    pub(crate) fn drain(self) -> impl Iterator<Item = Token> {
        self.waiting.into_iter().map(|w| w.token)
    }

    /// Whether nothing is kept (the entry can go).
    pub(crate) fn is_idle(&self) -> bool {
        self.waiting.is_empty()
            && !self.has_unanswered()
            && self.ordered.as_ref().is_none_or(|o| {
                o.fence.is_none() && o.deferred.is_none() && o.resend_owed.is_none()
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRACE: Duration = Duration::from_secs(1);

    #[test]
    fn a_reply_completes_only_calls_whose_stop_is_not_later_than_the_oldest_unanswered() {
        let now = Instant::now();
        let t = now + Duration::from_secs(1);
        let mut s = Stops::default();
        s.submit(1, t, now, GRACE);
        s.submit(2, t, now, GRACE);
        // The first reply answers the first stop (or, if that was lost, the second: either
        // way a stop sent at or after call 1). Call 2 waits for another.
        assert_eq!(s.on_reply(), vec![1]);
        assert_eq!(s.on_reply(), vec![2]);
        // No stop unanswered: a duplicate completes nothing.
        s.submit(3, t, now, GRACE);
        assert_eq!(s.on_reply(), vec![3]);
        assert!(s.on_reply().is_empty());
        assert!(s.is_idle());
    }

    #[test]
    fn a_call_whose_stop_was_lost_gets_it_sent_again_until_its_deadline() {
        let now = Instant::now();
        let t = now + Duration::from_millis(250);
        let mut s = Stops::default();
        s.submit(1, t, now, GRACE);
        s.submit(2, t, now, GRACE);
        // Stop 1 is lost; stop 2's reply is taken for stop 1.
        assert_eq!(s.on_reply(), vec![1]);
        assert_eq!(s.next_due(), Some(now + RESEND_AFTER));
        assert_eq!(s.due(now + RESEND_AFTER / 2, GRACE), None);
        let again = now + RESEND_AFTER;
        assert_eq!(s.due(again, GRACE), Some(StopDue::Resend), "sent again");
        assert_eq!(s.on_reply(), vec![2]);
        // Nobody waits: no more resends; the stop sent again is answered or given up.
        assert_eq!(s.due(again + RESEND_AFTER, GRACE), None);
        assert_eq!(s.next_due(), Some(t + GRACE));
        assert_eq!(s.due(t + GRACE, GRACE), None);
        assert!(s.is_idle());
        // A call past its deadline is not served by resends.
        s.submit(3, t, t, GRACE);
        assert_eq!(s.due(t + RESEND_AFTER, GRACE), None);
        assert_eq!(s.prune(|_| false), vec![3]);
    }

    /// Issue 29 D: more stops unanswered than the bound must not make a reply to the oldest
    /// complete a call whose stop came later. Beyond the bound a new stop joins the newest run,
    /// and the run counts as lost when its last stop would.
    #[test]
    fn unanswered_stops_are_bounded_without_giving_one_up_before_its_time() {
        let now = Instant::now();
        let mut s = Stops::default();
        let calls = MAX_UNANSWERED as u64 * 4;
        for token in 0..calls {
            let deadline = now + Duration::from_secs(token + 1);
            s.submit(token, deadline, now, GRACE);
        }
        assert_eq!(s.unanswered.len(), MAX_UNANSWERED);
        // The first reply may be the oldest stop's own: it completes call 0 alone (evicting
        // the oldest completed 49 calls on it, 48 of them on a stop sent before them).
        assert_eq!(s.on_reply(), vec![0]);
        assert_eq!(s.on_reply(), vec![1]);
        // The runs before the merged one are given up at their own time (the stop is sent
        // again for the callers still within their deadline); the merged one only when its
        // last stop is, so the next reply answers its first stop, call 15's.
        let merged = MAX_UNANSWERED as u64 - 1;
        let last_single = now + Duration::from_secs(merged) + GRACE;
        assert_eq!(s.due(last_single, GRACE), Some(StopDue::Resend));
        assert_eq!(
            s.unanswered.len(),
            2,
            "the merged run, and the stop sent again"
        );
        assert_eq!(s.on_reply(), (2..=merged).collect::<Vec<_>>());
        let merged_lost = now + Duration::from_secs(calls) + GRACE;
        assert_eq!(s.due(merged_lost, GRACE), None);
        assert!(!s.has_unanswered());
        assert_eq!(s.on_reply(), Vec::<Token>::new(), "nothing left to answer");
    }

    /// Issue 29 D (the explorer's `wsg-udp:0xaf073ffc53d9a31d`): on UDP a stop lost while its
    /// caller had no timeout counted as unanswered for ever, and each such stop cost every
    /// later stop call a resend before a reply could be its own. It counts as lost the reply
    /// hold + grace after it was sent, as any request without timeout.
    #[test]
    fn on_udp_a_stop_of_a_caller_without_timeout_counts_as_lost_after_the_reply_hold() {
        let hold = Duration::from_millis(300);
        let now = Instant::now();
        let never = after(now, Duration::MAX);
        let mut s = Stops::default().with_reply_hold(hold);
        s.submit(1, never, now, GRACE);
        // Its reply is lost; the stop goes out again, and that reply answers the first stop.
        let again = now + RESEND_AFTER;
        assert_eq!(s.due(again, GRACE), Some(StopDue::Resend));
        assert_eq!(s.on_reply(), vec![1]);
        // The re-sent stop counts as unanswered, and is given up hold + grace after it went.
        let lost = again + hold + GRACE;
        assert_eq!(s.next_due(), Some(lost));
        assert_eq!(s.due(lost, GRACE), None);
        assert!(s.is_idle());
        // A later call's reply is its own at once.
        s.submit(2, lost + Duration::from_millis(200), lost, GRACE);
        assert_eq!(s.on_reply(), vec![2]);
        // A caller with a timeout of its own keeps its stops until its deadline + grace.
        let deadline = lost + Duration::from_secs(10);
        s.submit(3, deadline, lost, GRACE);
        assert_eq!(s.next_due(), Some(lost + RESEND_AFTER));
        assert_eq!(s.prune(|_| false), vec![3]);
        assert_eq!(s.next_due(), Some(deadline + GRACE));
    }

    /// The explorer's `wsg-tcp:0x2082b0e305e913c4`, distilled: stop replies stalled on the
    /// stream past the caller's deadline plus the grace. On UDP the stops count as lost by
    /// then, and the first stalled reply completes the next call, whose own stop the device
    /// has not even received (the documented residual risk there). On TCP and serial nothing
    /// is given up on time: the stalled reply answers its own stop, and a barrier's echo is the
    /// only proof that a stop is lost.
    #[test]
    fn on_an_ordered_transport_a_stop_reply_later_than_the_grace_answers_only_its_own_stop() {
        let now = Instant::now();
        let t1 = now + Duration::from_millis(250);
        let later = t1 + GRACE + Duration::from_secs(1);
        let t2 = later + Duration::from_millis(250);
        for ordered in [true, false] {
            let mut s = Stops::new(ordered);
            s.submit(1, t1, now, GRACE);
            let barrier = s.due(now + RESEND_AFTER, GRACE);
            // The caller gives up; the replies stay stalled well past its deadline + grace.
            assert_eq!(s.prune(|t| t != 1), vec![1]);
            assert_eq!(s.due(t1 + GRACE, GRACE), None);
            s.submit(2, t2, later, GRACE);
            // The first stalled reply arrives.
            let done = s.on_reply();
            if ordered {
                assert_eq!(barrier, Some(StopDue::Barrier));
                assert!(done.is_empty(), "the reply of the stop sent for call 1");
                // The barrier's echo, after it: the stop of call 2 is still on its way.
                assert!(!s.unfence(later, GRACE));
                assert_eq!(s.on_reply(), vec![2]);
                assert!(s.is_idle());
            } else {
                assert_eq!(barrier, Some(StopDue::Resend));
                assert_eq!(done, vec![2], "UDP's residual risk");
            }
        }
    }

    #[test]
    fn on_an_ordered_transport_a_stop_whose_reply_was_corrupted_is_sent_again_after_a_barrier() {
        let now = Instant::now();
        let t = now + Duration::from_secs(1);
        let mut s = Stops::new(true);
        s.submit(1, t, now, GRACE);
        // Its reply is corrupted (dropped). No stop is sent again before a barrier proves it.
        assert_eq!(s.next_due(), Some(now + RESEND_AFTER));
        let at = now + RESEND_AFTER;
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert_eq!(s.next_due(), None, "waits for the echo");
        assert_eq!(s.due(at + RESEND_AFTER, GRACE), None);
        // A call made while the barrier is out: its stop goes out, after the barrier.
        s.submit(2, t, at, GRACE);
        assert!(!s.unfence(at, GRACE), "call 2's stop answers both");
        assert_eq!(s.on_reply(), vec![1, 2]);
        // The same, with nothing sent after the barrier: the stop goes out again at its echo.
        s.submit(3, t, at, GRACE);
        assert_eq!(s.due(at + RESEND_AFTER, GRACE), Some(StopDue::Barrier));
        assert!(s.unfence(at + RESEND_AFTER, GRACE), "sent again");
        assert_eq!(s.on_reply(), vec![3]);
        assert!(s.is_idle());
        // Nobody waits for an unanswered stop: still checked by a barrier RESEND_AFTER after
        // it was sent, so that later calls are not kept one reply behind (and a lost stop is
        // owed to the device: the next test).
        s.submit(4, t, at, GRACE);
        assert_eq!(s.prune(|_| false), vec![4]);
        assert_eq!(s.next_due(), Some(at + RESEND_AFTER));
        assert_eq!(s.due(at + RESEND_AFTER, GRACE), Some(StopDue::Barrier));
        assert!(!s.is_idle());
        // Its reply comes before the echo: nothing is lost, nothing sent again.
        assert!(s.on_reply().is_empty(), "nobody waits for it");
        assert!(!s.unfence(at + RESEND_AFTER, GRACE));
        assert!(s.is_idle());
        assert!(
            s.on_reply().is_empty(),
            "a reply after the echo answers nothing"
        );
    }

    /// Issue 29 E (the explorer's `wsg-tcp:0xd11252be6d410fee`), distilled: a stop whose
    /// request was damaged (the device never got it) and whose caller timed out before any
    /// re-send. A barrier proves it lost, and it is sent again though nobody waits: the device
    /// must stop. Checked again after each re-send, at most MAX_OWED_RESENDS times in a row.
    #[test]
    fn on_an_ordered_transport_a_lost_stop_is_sent_again_after_its_caller_stopped_waiting() {
        let now = Instant::now();
        let t = now + Duration::from_millis(50);
        let mut s = Stops::new(true);
        s.submit(1, t, now, GRACE);
        // The caller times out before RESEND_AFTER: no re-send was due while it waited.
        assert_eq!(s.due(t, GRACE), None);
        let mut at = now + RESEND_AFTER;
        assert_eq!(s.next_due(), Some(at));
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(
            s.unfence(at, GRACE),
            "proven lost: sent again, nobody waiting"
        );
        // That one is damaged too: again, up to the bound.
        for _ in 1..MAX_OWED_RESENDS {
            assert_eq!(s.next_due(), Some(at + RESEND_AFTER));
            at += RESEND_AFTER;
            assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
            assert!(s.unfence(at, GRACE), "sent again");
        }
        at += RESEND_AFTER;
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(!s.unfence(at, GRACE), "given up after MAX_OWED_RESENDS");
        assert!(!s.has_unanswered());
        // The timed-out caller is forgotten when the next stop call prunes.
        assert_eq!(s.prune(|_| false), vec![1]);
        assert!(s.is_idle());

        // The device answers a re-sent stop: done, and the count starts again. (This caller
        // dropped its call: the task prunes it when the next stop call comes.)
        s.submit(2, at + Duration::from_secs(5), at, GRACE);
        assert_eq!(s.prune(|_| false), vec![2]);
        at += RESEND_AFTER;
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(s.unfence(at, GRACE));
        assert!(s.on_reply().is_empty(), "nobody waits for it");
        assert!(s.is_idle());
        assert_eq!(s.ordered.as_ref().map(|o| o.owed_resends), Some(0));

        // A newer stop (a call) sent while the barrier is out supersedes it: its reply answers
        // both, no re-send.
        s.submit(3, at + Duration::from_secs(5), at, GRACE);
        assert_eq!(s.prune(|_| false), vec![3]);
        at += RESEND_AFTER;
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        s.submit(4, at + Duration::from_secs(1), at, GRACE);
        assert!(!s.unfence(at, GRACE), "call 4's stop is on its way");
        assert_eq!(s.on_reply(), vec![4]);
        assert!(s.is_idle());
    }

    /// The lead's decision on issue 29 E: a lost stop nobody waits for is not sent again once
    /// the program sent a motion command after it (the late stop would abort that motion);
    /// a motion sent before it does not matter, nor does one while its caller still waits.
    #[test]
    fn on_an_ordered_transport_a_motion_sent_after_a_lost_stop_drops_it() {
        let now = Instant::now();
        let t = now + Duration::from_millis(50);
        let at = now + RESEND_AFTER;
        let grasp = crate::wsg::command::id::GRASP;
        let home = crate::wsg::command::id::HOMING;
        // A motion after the stop, acknowledged by the device: dropped.
        let mut s = Stops::new(true);
        s.submit(1, t, now, GRACE);
        s.motion_sent(grasp);
        s.motion_answered(grasp, true);
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(!s.unfence(at, GRACE), "the program moved on");
        assert!(!s.has_unanswered());
        // Refused at once (E_ALREADY_RUNNING, say: the move the stop was for still runs): the
        // stop is still owed.
        let mut s = Stops::new(true);
        s.submit(1, t, now, GRACE);
        s.motion_sent(grasp);
        s.motion_answered(grasp, false);
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(
            s.unfence(at, GRACE),
            "a refused motion runs nothing: sent again"
        );
        // A motion sent after that re-send whose answer is still out at the echo (sent after
        // the barrier): its answer decides. Refused: the stop is sent again.
        let echo = at + RESEND_AFTER;
        assert_eq!(s.due(echo, GRACE), Some(StopDue::Barrier));
        s.motion_sent(home);
        assert!(!s.unfence(echo, GRACE), "waits for the motion's answer");
        assert!(!s.is_idle());
        assert_eq!(s.next_due(), None);
        s.motion_answered(home, false);
        assert_eq!(s.next_due(), Some(echo));
        assert_eq!(s.due(echo, GRACE), Some(StopDue::Resend));
        // Lost again, a motion out at the echo again: accepted, the stop is dropped.
        let echo = echo + RESEND_AFTER;
        assert_eq!(s.due(echo, GRACE), Some(StopDue::Barrier));
        s.motion_sent(home);
        assert!(!s.unfence(echo, GRACE));
        s.motion_answered(home, true);
        assert_eq!(s.next_due(), None);
        assert!(!s.has_unanswered());
        assert_eq!(s.prune(|_| false), vec![1]);
        assert!(s.is_idle());
        // A motion before the stop: the stop is still owed.
        let mut s = Stops::new(true);
        s.motion_sent(grasp);
        s.motion_answered(grasp, true);
        s.submit(1, t, now, GRACE);
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(s.unfence(at, GRACE), "sent again");
        // Two stops, an accepted motion between them, both lost: the newer one is owed.
        let mut s = Stops::new(true);
        s.submit(1, t, now, GRACE);
        s.motion_sent(grasp);
        s.submit(2, t, now, GRACE);
        s.motion_answered(grasp, true);
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(s.unfence(at, GRACE), "the stop after the motion is owed");
        // A caller still waiting gets its stop sent again whatever was sent after it.
        let mut s = Stops::new(true);
        s.submit(1, now + Duration::from_secs(1), now, GRACE);
        s.motion_sent(grasp);
        s.motion_answered(grasp, true);
        assert_eq!(s.due(at, GRACE), Some(StopDue::Barrier));
        assert!(s.unfence(at, GRACE), "its caller waits");
    }

    #[test]
    fn on_an_ordered_transport_no_bound_gives_a_stop_up_unproven() {
        let now = Instant::now();
        let far = now + Duration::from_secs(3600);
        let mut s = Stops::new(true);
        for token in 0..(MAX_UNANSWERED as u64 * 4) {
            s.submit(token, far, now, GRACE);
        }
        // The replies come in order: each completes its own call.
        for token in 0..(MAX_UNANSWERED as u64 * 4) {
            assert_eq!(s.on_reply(), vec![token]);
        }
        assert!(s.is_idle());
    }
}
