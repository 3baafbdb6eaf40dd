//! The motion in progress on a port, which the port holds ([`PortSim`](super::port)): straight
//! from where the fingers were to the target, between a start and an end in simulated time, and
//! how it ended (for a blocking command that waits for it). What starts a motion, and where it
//! stops, is the finger commands' (`moves.rs`).

use std::time::Duration;

use crate::griplink::state::DeviceState;

/// How a motion ended, for a blocking command that waits for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum MotionEnd {
    Done(DeviceState),
    Aborted,
}

/// A motion in progress: straight from `from_um` to `to_um` between `start` and `end`.
#[derive(Debug, Clone)]
pub(super) struct Motion {
    pub(super) id: u64,
    from_um: i64,
    pub(super) to_um: i64,
    start: Duration,
    pub(super) end: Duration,
    pub(super) end_state: DeviceState,
}

impl Motion {
    /// Motion `id`, from `from_um` at `start` to `to_um` at `end`, ending in `end_state`.
    pub(super) fn new(
        id: u64,
        (from_um, to_um): (i64, i64),
        (start, end): (Duration, Duration),
        end_state: DeviceState,
    ) -> Self {
        Motion {
            id,
            from_um,
            to_um,
            start,
            end,
            end_state,
        }
    }

    /// The finger position at `now` (before `end`).
    pub(super) fn position_at(&self, now: Duration) -> i64 {
        let total = self.end.saturating_sub(self.start).as_secs_f64();
        let done = now.saturating_sub(self.start).as_secs_f64();
        let frac = if total > 0.0 {
            (done / total).min(1.0)
        } else {
            1.0
        };
        self.from_um + ((self.to_um - self.from_um) as f64 * frac).round() as i64
    }
}
