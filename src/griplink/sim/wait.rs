//! Replies the controller holds back: a blocking motion (`do_block=1`, HOME), WSTR (3.4.10)
//! and WAITVAL (3.4.12).
//!
//! - A blocking motion answers `ACK` when its motion ends, `ERR 25` (E_CMD_FAILED) when it
//!   ended in `DS_FAULT`, `ERR 24` (E_CMD_ABORTED) when another command replaced or stopped it.
//! - WSTR answers the device state after the next state transition (see
//!   [`Transitions`](super::port) for when it answers at once), and `ERR 05` (E_TIMEOUT) after
//!   [`SimConfig::wstr_timeout`](super::SimConfig::wstr_timeout) when none occurs. A motion
//!   that ends in the state it started in (RELEASE from `DS_RELEASED`) is no transition.
//! - WAITVAL is reach/cross (3.4.12): a value that starts below the window answers `ACK` once
//!   it is at least `threshold − window/2`, one that starts above once it is at most
//!   `threshold + window/2`, one inside at once; `ERR 05` after its own timeout. A value that
//!   steps over a window of size 0 is ACKed. The simulator samples the value every
//!   [`VALUE_POLL`] of simulated time while the fingers move. The manual says "larger
//!   than"/"less than"; a value exactly on the bound counts here as reached, so that WAITVAL
//!   on a SETVAL's own target with window 0 (application example 1) ends.

use std::time::Duration;

use super::controller::Controller;
use super::motion::MotionEnd;
use super::reply::{error_line, Approach, Outcome, Session, Step, Wait};
use crate::griplink::command::PortNumber;
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;

/// How often a WAITVAL re-reads the value while the fingers move (simulated time).
pub const VALUE_POLL: Duration = Duration::from_millis(5);

impl Controller {
    /// `WSTR[p]?` at `now` (3.4.10).
    pub(super) fn wstr(&mut self, port: PortNumber, now: Duration) -> Step {
        let (i, _) = self.device(port)?;
        let deadline = now + self.scaled(self.config.wstr_timeout);
        let p = self.port_sim(i)?;
        if p.transitions.answer_at_once() {
            return Ok(Outcome::Reply(wstr_line(i, p.state())));
        }
        Ok(Outcome::Wait(Wait::Transition {
            port: i,
            after: p.transitions.count,
            deadline,
        }))
    }

    /// `WAITVAL(p,index,threshold,window,timeout)` at `now`, threshold and window in µm
    /// (3.4.12).
    pub(super) fn wait_value(
        &mut self,
        port: PortNumber,
        index: u32,
        threshold_um: f64,
        window_um: f64,
        timeout: Duration,
        now: Duration,
    ) -> Step {
        let (i, _) = self.device(port)?;
        if index != 0 {
            return Err(Status::IndexOutOfBounds);
        }
        if window_um.is_nan() || window_um < 0.0 || !threshold_um.is_finite() {
            return Err(Status::RangeError);
        }
        let (low, high) = (
            threshold_um - window_um / 2.0,
            threshold_um + window_um / 2.0,
        );
        let pos = self.port_sim(i)?.position_um as f64;
        let (bound_um, approach) = if pos < low {
            (low, Approach::FromBelow)
        } else if pos > high {
            (high, Approach::FromAbove)
        } else {
            return Ok(Outcome::Reply("ACK".to_owned()));
        };
        Ok(Outcome::Wait(Wait::Value {
            port: i,
            bound_um,
            approach,
            deadline: now + self.scaled(timeout),
        }))
    }

    /// The held reply, once it is due at `now`; `None` while it is still held.
    pub fn poll(&mut self, session: &Session, wait: &Wait, now: Duration) -> Option<String> {
        self.advance(now);
        let err = |s| Some(error_line(s, session.verbose));
        match wait {
            Wait::Motion { port, id } => {
                let p = self.ports.get(*port)?;
                if p.motion.as_ref().is_some_and(|m| m.id == *id) {
                    return None;
                }
                match p.ended(*id) {
                    Some(MotionEnd::Done(DeviceState::Fault)) => err(Status::CmdFailed),
                    Some(MotionEnd::Done(_)) => Some("ACK".to_owned()),
                    Some(MotionEnd::Aborted) | None => err(Status::CmdAborted),
                }
            }
            Wait::Transition {
                port,
                after,
                deadline,
            } => {
                let p = self.ports.get_mut(*port)?;
                if p.transitions.count > *after {
                    let count = p.transitions.count;
                    p.transitions.mark_reported(count);
                    Some(wstr_line(*port, p.state()))
                } else if now >= *deadline {
                    p.transitions.timeouts += 1;
                    err(Status::Timeout)
                } else {
                    None
                }
            }
            Wait::Value {
                port,
                bound_um,
                approach,
                deadline,
            } => {
                let pos = self.ports.get(*port)?.position_um as f64;
                let reached = match approach {
                    Approach::FromBelow => pos >= *bound_um,
                    Approach::FromAbove => pos <= *bound_um,
                };
                if reached {
                    Some("ACK".to_owned())
                } else if now >= *deadline {
                    err(Status::Timeout)
                } else {
                    None
                }
            }
        }
    }

    /// When a held reply may next become due (the server sleeps until then unless another
    /// connection changes something first).
    pub fn next_wake(&self, wait: &Wait, now: Duration) -> Duration {
        let motion_end = |port: usize| {
            self.ports
                .get(port)
                .and_then(|p| p.motion.as_ref())
                .map(|m| m.end)
        };
        match wait {
            Wait::Motion { port, .. } => motion_end(*port).unwrap_or(now),
            Wait::Transition { port, deadline, .. } => {
                motion_end(*port).map_or(*deadline, |end| end.min(*deadline))
            }
            Wait::Value { port, deadline, .. } => match motion_end(*port) {
                Some(_) => {
                    (now + self.scaled(VALUE_POLL).max(Duration::from_millis(1))).min(*deadline)
                }
                None => *deadline,
            },
        }
    }
}

fn wstr_line(port: usize, state: DeviceState) -> String {
    format!("WSTR[{port}]={}", state.code())
}
