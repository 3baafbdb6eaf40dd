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
//! - **UDP** loses datagrams: a lost stop is never answered, so the replies are taken for
//!   stops one too early, and a call whose own stop was lost, or whose reply was taken for an
//!   earlier stop, would wait in vain. A call that waits [`RESEND_AFTER`] without its reply
//!   gets the stop sent again (idempotent), until its reply comes or its deadline passes. A
//!   stop unanswered for its caller's deadline plus the late-reply grace counts as lost (and
//!   the oldest are given up beyond [`MAX_UNANSWERED`]). Residual risks: a stop reply later
//!   than that grace, or a duplicated one, is taken for a later stop; and a stop sent again
//!   may reach the device after `stop()` returned (UDP reorders), stopping a move started
//!   right after (that move then ends with E_CMD_ABORTED, the device's own answer).

use std::collections::VecDeque;
use std::time::Duration;

use tokio::time::Instant;

use crate::deadline::after;

/// Identifies one request for the task.
pub(crate) type Token = u64;

/// How long a waiting stop call goes without its reply before the stop is sent again: far
/// above a stop's round trip on any transport (the device answers at once), far below a
/// call's timeout.
pub(crate) const RESEND_AFTER: Duration = Duration::from_millis(100);

/// Stops of one id kept unanswered at most on UDP; beyond, the oldest counts as lost.
pub(crate) const MAX_UNANSWERED: usize = 16;

/// What the stops of one id need from the task ([`Stops::due`]).
#[derive(Debug, PartialEq)]
pub(crate) enum StopDue {
    /// Send the stop again (it is recorded as sent).
    Resend,
    /// Ordered transport: send a barrier (a loop-back with a payload of its own) and report its
    /// echo with [`Stops::unfence`].
    Barrier,
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
    /// When unanswered stops that nobody waits for get a barrier (the latest caller's deadline
    /// plus the grace): a reply lost to corruption must not keep later calls one reply behind.
    check_at: Option<Instant>,
}

/// The stops of one command id (0x22 or 0x23).
#[derive(Debug, Default)]
pub(crate) struct Stops {
    /// UDP: stops sent and not answered yet, oldest first: sequence number, and when it counts
    /// as lost.
    unanswered: VecDeque<(u64, Instant)>,
    waiting: Vec<Waiting>,
    next_seq: u64,
    /// When the stop is sent again, or (ordered) a barrier goes out, if no reply has come (only
    /// while someone waits).
    resend_at: Option<Instant>,
    /// `Some` on an ordered transport: the count of [`Ordered`] instead of `unanswered`.
    ordered: Option<Ordered>,
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

    /// Records a stop sent at `now`, counting as lost from `lost_at` (ordered: checked by a
    /// barrier from then, if still unanswered).
    fn sent(&mut self, now: Instant, lost_at: Instant) -> u64 {
        let seq = self.next_seq;
        self.next_seq += 1;
        if let Some(o) = &mut self.ordered {
            o.check_at = Some(o.check_at.map_or(lost_at, |at| at.max(lost_at)));
        } else {
            if self.unanswered.len() >= MAX_UNANSWERED {
                self.unanswered.pop_front();
            }
            self.unanswered.push_back((seq, lost_at));
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
        let first = self.sent(now, after(deadline, grace));
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
                o.oldest - 1
            }
            Some(_) => return Vec::new(),
            None => match self.unanswered.pop_front() {
                Some((seq, _)) => seq,
                None => return Vec::new(),
            },
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
            Some(o) => o.check_at.filter(|_| self.has_unanswered()),
            None => self.unanswered.iter().map(|(_, at)| *at).min(),
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
            self.unanswered.retain(|(_, lost_at)| *lost_at > now);
        } else if self.ordered.as_ref().is_some_and(|o| o.fence.is_some()) {
            return None;
        }
        let resend = self.resend_at.is_some_and(|at| at <= now);
        let latest = self.latest_waiting(now);
        if resend && latest.is_none() {
            // Only callers past their deadline wait (their futures have ended): no resend.
            self.resend_at = None;
        }
        let unanswered = self.has_unanswered();
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
        self.sent(now, after(latest, grace));
        Some(StopDue::Resend)
    }

    /// Ordered transport: the echo of the barrier asked by [`Stops::due`] came back at `now`.
    /// The device answers a connection's commands in order (1.2.2) and the stream keeps it, so
    /// every stop sent before the barrier and still unanswered is lost (its reply corrupted).
    /// Returns whether the stop is to be sent again now (recorded as sent): a caller waits
    /// and no stop that could answer it is unanswered.
    pub(crate) fn unfence(&mut self, now: Instant, grace: Duration) -> bool {
        let Some(o) = &mut self.ordered else {
            return false;
        };
        let Some(fence) = o.fence.take() else {
            return false;
        };
        o.oldest = o.oldest.max(fence);
        let Some(latest) = self.latest_waiting(now) else {
            self.resend_at = None;
            return false;
        };
        if self.has_unanswered() {
            // A stop sent after the barrier is on its way: its reply completes every caller
            // (each one's first stop is not later). A barrier again if it does not come.
            self.resend_at = Some(after(now, RESEND_AFTER));
            return false;
        }
        self.sent(now, after(latest, grace));
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
            && self.ordered.as_ref().is_none_or(|o| o.fence.is_none())
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

    #[test]
    fn unanswered_stops_are_bounded() {
        let now = Instant::now();
        let far = now + Duration::from_secs(3600);
        let mut s = Stops::default();
        for token in 0..(MAX_UNANSWERED as u64 * 4) {
            s.submit(token, far, now, GRACE);
        }
        assert_eq!(s.unanswered.len(), MAX_UNANSWERED);
        // The oldest kept is taken as answered: every call up to it completes.
        let done = s.on_reply();
        assert_eq!(done.len(), MAX_UNANSWERED * 3 + 1);
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
        // Nobody waits for an unanswered stop: checked by a barrier at its deadline + grace,
        // so that later calls are not kept one reply behind.
        s.submit(4, t, at, GRACE);
        assert_eq!(s.prune(|_| false), vec![4]);
        assert_eq!(s.next_due(), Some(t + GRACE));
        assert_eq!(s.due(t + GRACE, GRACE), Some(StopDue::Barrier));
        assert!(!s.is_idle());
        assert!(!s.unfence(t + GRACE, GRACE));
        assert!(s.is_idle());
        assert!(
            s.on_reply().is_empty(),
            "a reply after the echo answers nothing"
        );
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
