//! The simulated controller: a pure state machine (no I/O, no clock). The server passes the
//! current time in; motion takes simulated time, scaled by [`SimConfig::time_scale`].
//!
//! The behaviour is split by concern, each file importing only those below it:
//! - what a command does with its reply: answered at once, held back ([`Wait`]) or the end of
//!   the connection ([`Outcome`], `reply.rs`);
//! - [`SimDevice`] and its default recipes (`device.rs`), [`SimConfig`] (`config.rs`);
//! - one port's device state, transitions and WSTR bookkeeping (`port.rs`), and the motion in
//!   progress it holds (`motion.rs`);
//! - the commands that move the fingers: HOME, GRIP, RELEASE, FLEX…, SETVAL and the states they
//!   end in (`moves.rs`);
//! - replies held back: blocking motions, WSTR, WAITVAL (`wait.rs`);
//! - command dispatch: every command of chapter 3 (`dispatch.rs`).
//!
//! Device states follow chapter 5. These devices are Weiss grippers: `ENABLE` leaves or puts
//! them in state 2 (`DS_DISABLED`, "idle: the device is operable and waiting for a command"),
//! also out of `DS_FAULT`; state 6 (`DS_ENABLED`) is scoped to sensors in the table and is
//! never reported. `DISABLE` aborts any motion, frees the fingers (3.4.2) and ends in state 2.
//! `CLAMP` is only accepted while the actuator is off (3.4.9, Weiss grippers).
//! Value index 0 is the finger position (µm for VALUE, mm for VALUEF, 3.5.2).
//!
//! Faults for users' tests: [`Controller::inject_fault`] (fault now) and
//! [`Controller::fault_next_motion`] (the next motion ends in `DS_FAULT`).

use std::time::Duration;

use super::port::PortSim;
use crate::griplink::command::PortNumber;
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;

pub use super::config::{
    Role, SimConfig, DEFAULT_ENABLE_TIME, DEFAULT_WSTR_TIMEOUT, MIN_MOTION_TIME,
};
pub use super::device::{SimDevice, DEFAULT_FORCE_PERCENT, RECIPES, WEISS_VENDOR_ID};
pub use super::reply::{error_line, Approach, Outcome, Session, Wait};
pub use super::wait::VALUE_POLL;

/// The simulated controller: configuration, label, and a state machine per port.
#[derive(Debug, Clone)]
pub struct Controller {
    pub(super) config: SimConfig,
    pub(super) label: String,
    pub(super) ports: Vec<PortSim>,
    pub(super) next_motion: u64,
}

impl Controller {
    /// A controller in its power-on state.
    pub fn new(config: SimConfig) -> Self {
        let count = match config.role {
            Role::Standalone => config.ports.len(),
            Role::Master => usize::from(crate::griplink::command::MAX_PORT) + 1,
        };
        let ports = (0..count)
            .map(|i| PortSim::new(config.ports.get(i).cloned().flatten()))
            .collect();
        Controller {
            label: config.label.clone(),
            config,
            ports,
            next_motion: 1,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The number of addressable ports.
    pub fn port_count(&self) -> usize {
        self.ports.len()
    }

    /// The device state on `port` (after advancing to `now`).
    pub fn state(&mut self, port: usize, now: Duration) -> Option<DeviceState> {
        self.advance(now);
        self.ports.get(port).map(PortSim::state)
    }

    /// The finger position on `port` in µm (after advancing to `now`).
    pub fn position_um(&mut self, port: usize, now: Duration) -> Option<i64> {
        self.advance(now);
        self.ports.get(port).map(|p| p.position_um)
    }

    /// Whether the device on `port` is moving at `now`.
    pub fn is_moving(&mut self, port: usize, now: Duration) -> bool {
        self.advance(now);
        self.ports.get(port).is_some_and(|p| p.motion.is_some())
    }

    /// How many WSTRs on `port` have answered `ERR 05` because no transition came in time.
    pub fn wstr_timeouts(&self, port: usize) -> u64 {
        self.ports.get(port).map_or(0, |p| p.transitions.timeouts)
    }

    /// Changes the time scale for motions and waits started from now on (see
    /// [`SimConfig::time_scale`]).
    pub fn set_time_scale(&mut self, scale: f64) {
        self.config.time_scale = scale;
    }

    /// Puts a part of `width_mm` between the fingers of the device on `port` (`None`: no part).
    pub fn set_part(&mut self, port: usize, width_mm: Option<f64>) {
        if let Some(d) = self.ports.get_mut(port).and_then(|p| p.device.as_mut()) {
            d.part_width_mm = width_mm;
        }
    }

    /// Faults the device on `port` now: a motion in progress stops, the state becomes
    /// `DS_FAULT`.
    pub fn inject_fault(&mut self, port: usize, now: Duration) {
        self.advance(now);
        if let Some(p) = self.ports.get_mut(port).filter(|p| p.device.is_some()) {
            p.end_motion_here(DeviceState::Fault);
        }
    }

    /// Makes the next motion of the device on `port` end in `DS_FAULT`.
    pub fn fault_next_motion(&mut self, port: usize) {
        if let Some(p) = self.ports.get_mut(port) {
            p.fault_next_motion = true;
        }
    }

    /// Ends the motion in progress on `port` now, as if it had run its course (for tests that
    /// hold a slow motion, check something, then let it finish).
    pub fn finish_motion(&mut self, port: usize, now: Duration) {
        self.advance(now);
        if let Some(p) = self.ports.get_mut(port) {
            p.finish_motion();
        }
    }

    /// Completes or interpolates every motion up to `now`.
    pub fn advance(&mut self, now: Duration) {
        for p in &mut self.ports {
            p.advance(now);
        }
    }

    /// A simulated duration in wall time (see [`SimConfig::time_scale`]).
    pub(super) fn scaled(&self, d: Duration) -> Duration {
        let scale = self.config.time_scale;
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            0.0
        };
        Duration::try_from_secs_f64(d.as_secs_f64() * scale).unwrap_or(Duration::from_secs(86_400))
    }

    /// The index of `port`; `E_INDEX_OUT_OF_BOUNDS` beyond the controller's ports (2.3).
    pub(super) fn port(&self, port: PortNumber) -> Result<usize, Status> {
        let i = usize::from(port);
        if i < self.ports.len() {
            Ok(i)
        } else {
            Err(Status::IndexOutOfBounds)
        }
    }

    /// The port's index and device; `E_NOT_INITIALIZED` when no device is connected (as the
    /// manual documents for DEVPID, 3.2.2).
    pub(super) fn device(&self, port: PortNumber) -> Result<(usize, &SimDevice), Status> {
        let i = self.port(port)?;
        match self.ports.get(i).and_then(|p| p.device.as_ref()) {
            Some(d) => Ok((i, d)),
            None => Err(Status::NotInitialized),
        }
    }

    pub(super) fn port_sim(&mut self, i: usize) -> Result<&mut PortSim, Status> {
        self.ports.get_mut(i).ok_or(Status::IndexOutOfBounds)
    }
}
