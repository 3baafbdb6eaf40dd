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
//! on it, and no other does.
//!
//! - **TCP and serial** keep the order and lose nothing (a corrupted reply aside): the oldest
//!   unanswered stop is exactly the one answered. Sound.
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

use super::pairing::Token;
use crate::deadline::after;

/// How long a waiting stop call goes without its reply before the stop is sent again: far
/// above a stop's round trip on any transport (the device answers at once), far below a
/// call's timeout.
pub(crate) const RESEND_AFTER: Duration = Duration::from_millis(100);

/// Stops of one id kept unanswered at most; beyond, the oldest counts as lost.
pub(crate) const MAX_UNANSWERED: usize = 16;

/// A caller waiting for a stop reply.
#[derive(Debug)]
struct Waiting {
    token: Token,
    /// The sequence number of the first stop sent at or after the call.
    first: u64,
    deadline: Instant,
}

/// The stops of one command id (0x22 or 0x23).
#[derive(Debug, Default)]
pub(crate) struct Stops {
    /// Stops sent and not answered yet, oldest first: sequence number, and when it counts as
    /// lost.
    unanswered: VecDeque<(u64, Instant)>,
    waiting: Vec<Waiting>,
    next_seq: u64,
    /// When the stop is sent again if no reply has come (only while someone waits).
    resend_at: Option<Instant>,
}

impl Stops {
    /// Records a stop sent at `now`, counting as lost from `lost_at`.
    fn sent(&mut self, now: Instant, lost_at: Instant) -> u64 {
        let seq = self.next_seq;
        self.next_seq += 1;
        if self.unanswered.len() >= MAX_UNANSWERED {
            self.unanswered.pop_front();
        }
        self.unanswered.push_back((seq, lost_at));
        self.resend_at = Some(after(now, RESEND_AFTER));
        seq
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
        let Some((answered, _)) = self.unanswered.pop_front() else {
            return Vec::new();
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
        let lost = self.unanswered.iter().map(|(_, at)| *at).min();
        match (self.resend_at, lost) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// At `now`: gives up the stops unanswered too long, and says whether the stop is to be
    /// sent again (recording it as sent): a caller still within its deadline has waited
    /// [`RESEND_AFTER`] since the last one.
    pub(crate) fn due(&mut self, now: Instant, grace: Duration) -> bool {
        self.unanswered.retain(|(_, lost_at)| *lost_at > now);
        if self.resend_at.is_none_or(|at| at > now) {
            return false;
        }
        let Some(latest) = self
            .waiting
            .iter()
            .map(|w| w.deadline)
            .filter(|d| *d > now)
            .max()
        else {
            // Only callers past their deadline wait (their futures have ended): no resend.
            self.resend_at = None;
            return false;
        };
        self.sent(now, after(latest, grace));
        true
    }

    /// Every waiting call's token (the state is dropped).
    pub(crate) fn drain(self) -> impl Iterator<Item = Token> {
        self.waiting.into_iter().map(|w| w.token)
    }

    /// Whether nothing is kept (the entry can go).
    pub(crate) fn is_idle(&self) -> bool {
        self.waiting.is_empty() && self.unanswered.is_empty()
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
        assert!(!s.due(now + RESEND_AFTER / 2, GRACE));
        let again = now + RESEND_AFTER;
        assert!(s.due(again, GRACE), "sent again");
        assert_eq!(s.on_reply(), vec![2]);
        // Nobody waits: no more resends; the stop sent again is answered or given up.
        assert!(!s.due(again + RESEND_AFTER, GRACE));
        assert_eq!(s.next_due(), Some(t + GRACE));
        assert!(!s.due(t + GRACE, GRACE));
        assert!(s.is_idle());
        // A call past its deadline is not served by resends.
        s.submit(3, t, t, GRACE);
        assert!(!s.due(t + RESEND_AFTER, GRACE));
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
}
