//! The give-up clock of a request answered in order (GRIPLINK's pipeline, SmartGrasp's queue of
//! requests in flight): issue 29 F and H, one rule kept once.
//!
//! A reply missing long past its call's timeout means the peer is not answering the way the
//! protocol promises, and the connection is given up. But a request answered in order cannot be
//! answered before the ones ahead of it: one sent behind a long blocking `HOME` (or a long
//! `with_timeout` detection) waits for that one first. Its give-up clock therefore starts when it
//! reaches the front: from then it has its own timeout and the give-up margin, and never less
//! than counted from its call's start. Without that, a healthy connection was declared lost when
//! the long call was answered and the next reply took a moment.
//!
//! Sans-I/O: the clock is read by the caller, and only when a request has just reached the front
//! behind another (never on the path of a request sent to an idle connection).

use std::time::Duration;

use tokio::time::Instant;

use crate::deadline::after;

/// When a request's missing reply gives the connection up.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GiveUp {
    at: Instant,
    /// The request's own timeout plus the give-up margin, counted again from when it reaches
    /// the front.
    budget: Duration,
    /// Whether it was at the front already (its clock is `at`).
    at_front: bool,
}

impl GiveUp {
    /// A request whose caller waits until `deadline`, its reply tolerated `give_up_after` past
    /// it. `at_front`: sent with nothing ahead of it. `timeout`: the caller's timeout, asked only
    /// for a request queued behind others.
    pub(crate) fn new(
        deadline: Instant,
        give_up_after: Duration,
        at_front: bool,
        timeout: impl FnOnce() -> Duration,
    ) -> Self {
        GiveUp {
            at: after(deadline, give_up_after),
            budget: if at_front {
                Duration::ZERO
            } else {
                timeout().saturating_add(give_up_after)
            },
            at_front,
        }
    }

    /// A request at the front from the start, given up at `at`.
    pub(crate) fn fixed(at: Instant) -> Self {
        GiveUp {
            at,
            budget: Duration::ZERO,
            at_front: true,
        }
    }

    /// When to give up. Ask it of the request at the front only: the first time, its clock is
    /// re-based on `now()`, when it reached the front.
    pub(crate) fn at_front(&mut self, now: impl FnOnce() -> Instant) -> Instant {
        if !self.at_front {
            self.at_front = true;
            self.at = self.at.max(after(now(), self.budget));
        }
        self.at
    }

    /// The give-up time as it stands (before any re-basing): a write's limit.
    pub(crate) fn limit(&self) -> Instant {
        self.at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Duration = Duration::from_secs(1);

    #[test]
    fn a_request_sent_to_an_idle_connection_gives_up_past_its_deadline() {
        let t0 = Instant::now();
        let mut g = GiveUp::new(t0 + 2 * S, 30 * S, true, || unreachable!("not asked"));
        assert_eq!(g.at_front(|| unreachable!("not asked")), t0 + 32 * S);
    }

    #[test]
    fn a_queued_request_counts_from_when_it_reaches_the_front() {
        let t0 = Instant::now();
        // A 2 s query behind a HOME that took 40 s: 2 s + 30 s from then, not from its call.
        let mut g = GiveUp::new(t0 + 2 * S, 30 * S, false, || 2 * S);
        assert_eq!(g.limit(), t0 + 32 * S);
        assert_eq!(g.at_front(|| t0 + 40 * S), t0 + 72 * S);
        // Re-based once: later asks do not move it.
        assert_eq!(g.at_front(|| t0 + 60 * S), t0 + 72 * S);
    }

    #[test]
    fn never_earlier_than_from_the_call_and_no_overflow() {
        let t0 = Instant::now();
        let mut g = GiveUp::new(t0 + 2 * S, 30 * S, false, || 2 * S);
        assert_eq!(g.at_front(|| t0), t0 + 32 * S);
        let mut never = GiveUp::new(after(t0, Duration::MAX), Duration::MAX, false, || {
            Duration::MAX
        });
        assert!(never.at_front(|| t0) > t0 + 86_400 * 365 * S);
    }
}
