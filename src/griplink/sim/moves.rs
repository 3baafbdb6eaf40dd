//! Finger motion: HOME, GRIP, RELEASE, the FLEX commands and SETVAL move the fingers at a
//! speed, in simulated time; where they stop decides the device state they end in.
//!
//! - `HOME` (always blocking, 3.4.3) moves the fingers to the open end of the stroke and ends
//!   idle, `DS_DISABLED` (the GRIP polling example shows a freshly homed gripper in state 2,
//!   "DS_IDLE").
//! - `GRIP`/`FLEXGRIP` move towards the no-part limit and end `DS_HOLDING` where they meet the
//!   configured part, else `DS_NO_PART`; refused with `E_STATE_CONFLICT` in `DS_HOLDING` or
//!   `DS_NO_PART` (3.4.4).
//! - `RELEASE`/`FLEXRELEASE` move to the release limit and end `DS_RELEASED` (3.4.5, 3.4.7).
//! - GRIP, RELEASE and HOME re-enable a gripper in `DS_FAULT` or disabled by DISABLE
//!   ("Grippers by WEISS ROBOTICS: The device will be (re-)enabled automatically when executing
//!   a GRIP(), RELEASE() or HOME() command", 3.4.1); the fingers start moving after
//!   [`SimConfig::enable_time`](super::SimConfig::enable_time), the state unchanged meanwhile.
//!   Only those three: FLEXGRIP, FLEXRELEASE and SETVAL on such a gripper are refused with
//!   `E_STATE_CONFLICT` (the manual does not say which error a device gives; this one says
//!   "invalid state", which it is), and ENABLE first makes them work.
//! - No motion ends at the instant of its `ACK`: it lasts at least
//!   [`MIN_MOTION_TIME`](super::controller::MIN_MOTION_TIME), even with the fingers at the target.
//! - While the fingers move, the state keeps its start value (the polling examples of 3.4.4 and
//!   3.4.5 show the start state until the end), so a RELEASE from `DS_RELEASED` or a motion from
//!   `DS_FAULT` may end with no transition at all (3.4.7: "a state transition may not occur").
//!   This is the hardest case for a client and the one the manual warns about.
//! - `SETVAL` index 0 pre-positions the fingers and keeps the state.

use std::time::Duration;

use super::controller::Controller;
use super::motion::Motion;
use super::reply::{ack, Outcome, Step, Wait};
use crate::griplink::command::{Blocking, PortNumber};
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;

impl Controller {
    /// Starts a motion on port `i` to `to_um`, ending in `end_state` (or `DS_FAULT` if a fault
    /// was armed). Replaces any motion in progress.
    pub(super) fn start_motion(
        &mut self,
        i: usize,
        to_um: i64,
        speed_um_per_s: f64,
        end_state: DeviceState,
        now: Duration,
    ) -> Result<u64, Status> {
        let id = self.next_motion;
        self.next_motion += 1;
        let from_um = self.port_sim(i)?.position_um;
        let seconds = if speed_um_per_s > 0.0 {
            (to_um - from_um).unsigned_abs() as f64 / speed_um_per_s
        } else {
            0.0
        };
        let travel = Duration::try_from_secs_f64(seconds).unwrap_or(Duration::ZERO);
        let duration = self.scaled(travel.max(super::config::MIN_MOTION_TIME));
        let enable = self.scaled(self.config().enable_time);
        let p = self.port_sim(i)?;
        // Re-enabling first (3.4.1): the fingers stay where they are meanwhile.
        let start = if p.needs_enable() { now + enable } else { now };
        p.abort_motion();
        p.actuator_on = true;
        let end_state = if std::mem::take(&mut p.fault_next_motion) {
            DeviceState::Fault
        } else {
            end_state
        };
        p.motion = Some(Motion::new(
            id,
            (from_um, to_um),
            (start, start + duration),
            end_state,
        ));
        p.advance(now);
        Ok(id)
    }

    /// What GRIP and RELEASE (`reenables`) and their FLEX forms check before they move to
    /// `to_um` (3.4.1, 3.4.4), then the start of a manipulating command. Returns the port index,
    /// the device's default speed and the part width, µm.
    fn begin_motion(
        &mut self,
        port: PortNumber,
        to_um: i64,
        grip: bool,
        reenables: bool,
    ) -> Result<(usize, f64, Option<i64>), Status> {
        let (i, device) = self.device(port)?;
        let stroke = device.stroke_um();
        let default_speed = device.default_speed_um_per_s();
        let part = device.part_width_mm.map(super::device::um);
        let p = self.port_sim(i)?;
        match p.state() {
            DeviceState::NotInitialized => return Err(Status::NotInitialized),
            DeviceState::Holding | DeviceState::NoPart if grip => {
                return Err(Status::StateConflict)
            }
            // Only GRIP, RELEASE and HOME re-enable (3.4.1).
            _ if p.needs_enable() && !reenables => return Err(Status::StateConflict),
            // DS_FAULT and DS_DISABLED: re-enabled automatically (3.4.1).
            _ => {}
        }
        if !(0..=stroke).contains(&to_um) {
            return Err(Status::RangeError);
        }
        p.transitions.command();
        Ok((i, default_speed, part))
    }

    /// `HOME`: to the open end of the stroke, always blocking (3.4.3). Also the way out of
    /// `DS_NOT_INITIALIZED`.
    pub(super) fn home(&mut self, port: PortNumber, now: Duration) -> Step {
        let (i, d) = self.device(port)?;
        let (open, speed) = (d.stroke_um(), d.default_speed_um_per_s());
        self.port_sim(i)?.transitions.command();
        let id = self.start_motion(i, open, speed, DeviceState::Disabled, now)?;
        Ok(motion_reply(i, id, Blocking::UntilDone))
    }

    /// A grip towards `limit_um`: holds the part if the fingers meet it on the way. `reenables`:
    /// GRIP, not FLEXGRIP (3.4.1).
    pub(super) fn grip(
        &mut self,
        port: PortNumber,
        limit_um: i64,
        speed_um_per_s: f64,
        blocking: Blocking,
        reenables: bool,
        now: Duration,
    ) -> Step {
        let (i, default_speed, part) = self.begin_motion(port, limit_um, true, reenables)?;
        let from = self.port_sim(i)?.position_um;
        let (stop, end) = match part {
            Some(w) if (limit_um < w && w < from) || (from < w && w < limit_um) => {
                (w, DeviceState::Holding)
            }
            _ => (limit_um, DeviceState::NoPart),
        };
        let speed = or_default(speed_um_per_s, default_speed);
        let id = self.start_motion(i, stop, speed, end, now)?;
        Ok(motion_reply(i, id, blocking))
    }

    /// A release (or pre-position) to `target_um`, ending `DS_RELEASED`. `reenables`: RELEASE,
    /// not FLEXRELEASE (3.4.1).
    pub(super) fn release(
        &mut self,
        port: PortNumber,
        target_um: i64,
        speed_um_per_s: f64,
        blocking: Blocking,
        reenables: bool,
        now: Duration,
    ) -> Step {
        let (i, default_speed, _) = self.begin_motion(port, target_um, false, reenables)?;
        let speed = or_default(speed_um_per_s, default_speed);
        let id = self.start_motion(i, target_um, speed, DeviceState::Released, now)?;
        Ok(motion_reply(i, id, blocking))
    }

    /// `SETVAL` index 0: pre-positions the fingers, keeping the state (3.4.11).
    pub(super) fn set_value(
        &mut self,
        port: PortNumber,
        index: u32,
        target_um: i64,
        now: Duration,
    ) -> Step {
        let (i, d) = self.device(port)?;
        let (stroke, speed) = (d.stroke_um(), d.default_speed_um_per_s());
        if index != 0 {
            return Err(Status::IndexOutOfBounds);
        }
        let p = self.port_sim(i)?;
        let state = p.state();
        match state {
            DeviceState::NotInitialized => return Err(Status::NotInitialized),
            // Only GRIP, RELEASE and HOME re-enable (3.4.1): not in DS_FAULT, nor disabled.
            _ if p.needs_enable() => return Err(Status::StateConflict),
            _ => {}
        }
        if !(0..=stroke).contains(&target_um) {
            return Err(Status::RangeError);
        }
        p.transitions.command();
        self.start_motion(i, target_um, speed, state, now)?;
        ack()
    }
}

fn or_default(speed_um_per_s: f64, default: f64) -> f64 {
    if speed_um_per_s > 0.0 {
        speed_um_per_s
    } else {
        default
    }
}

fn motion_reply(port: usize, id: u64, blocking: Blocking) -> Outcome {
    match blocking {
        Blocking::Immediate => Outcome::Reply("ACK".to_owned()),
        Blocking::UntilDone => Outcome::Wait(Wait::Motion { port, id }),
    }
}
