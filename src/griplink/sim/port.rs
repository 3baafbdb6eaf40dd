//! One port of the simulated controller: its device, the device state (chapter 5), the
//! finger position, and what WSTR needs to know about state transitions (3.4.10).

use std::collections::VecDeque;
use std::time::Duration;

use super::device::SimDevice;
use super::motion::{Motion, MotionEnd};
use crate::griplink::command::GripConfig;
use crate::griplink::state::DeviceState;

/// How many ended motions a port remembers, for blocking commands that look up how theirs
/// ended.
const HISTORY: usize = 64;

/// What WSTR (3.4.10) needs: which state transitions happened, and which were answered.
///
/// A transition is a change of the device state. WSTR answers the first transition after it
/// was issued, or at once one that happened after the last manipulating command and before the
/// WSTR (the motion ended before the WSTR arrived), and otherwise `ERR 05` after its timeout.
/// "When issuing the same command twice, WSTR immediately returns with the current device
/// state": the one WSTR right after a WSTR that reported a transition answers at once.
/// This bookkeeping is per port, shared by every connection, as the manual describes WSTR per
/// device; every WSTR waiting when a transition happens gets it. The manual's wording is terse;
/// this reading is the simulator's: a WSTR sent just after a fast motion sees that motion's
/// end, and a WSTR on an idle port waits and times out.
#[derive(Debug, Clone, Default)]
pub(super) struct Transitions {
    /// State transitions so far.
    pub(super) count: u64,
    /// `count` when the last manipulating command started: earlier transitions are not its.
    command_mark: u64,
    /// The highest `count` a WSTR has reported.
    reported: u64,
    /// The last WSTR reported a transition and nothing manipulating happened since.
    repeat: bool,
    /// WSTRs that answered `ERR 05`.
    pub(super) timeouts: u64,
}

impl Transitions {
    /// A manipulating command starts (GRIP, RELEASE, FLEX…, HOME, ENABLE, DISABLE, SETVAL).
    pub(super) fn command(&mut self) {
        self.command_mark = self.count;
        self.repeat = false;
    }

    /// A transition nobody has reported, since the last manipulating command.
    pub(super) fn unreported(&self) -> bool {
        self.count > self.command_mark.max(self.reported)
    }

    /// Whether a WSTR issued now answers at once; if so, records that it did.
    pub(super) fn answer_at_once(&mut self) -> bool {
        if self.unreported() {
            self.mark_reported(self.count);
            true
        } else {
            std::mem::take(&mut self.repeat)
        }
    }

    /// A WSTR reported the state after transition number `count`.
    pub(super) fn mark_reported(&mut self, count: u64) {
        self.reported = self.reported.max(count);
        self.repeat = true;
    }
}

#[derive(Debug, Clone)]
pub(super) struct PortSim {
    pub(super) device: Option<SimDevice>,
    state: DeviceState,
    pub(super) position_um: i64,
    pub(super) motion: Option<Motion>,
    /// How recent motions ended, for blocking commands that look up theirs after the fact.
    history: VecDeque<(u64, MotionEnd)>,
    pub(super) recipes: Vec<GripConfig>,
    pub(super) tag: String,
    pub(super) fault_next_motion: bool,
    pub(super) led: u32,
    pub(super) clamp: bool,
    /// Whether the actuator is powered. For a gripper state 2 (DS_DISABLED, "idle: the device is
    /// operable and waiting for a command", chapter 5) covers both an enabled idle gripper and
    /// one disabled by DISABLE, whose fingers move by hand (3.4.2); CLAMP needs to know which
    /// (3.4.9).
    pub(super) actuator_on: bool,
    pub(super) transitions: Transitions,
}

impl PortSim {
    pub(super) fn new(device: Option<SimDevice>) -> Self {
        let state = if device.is_some() {
            DeviceState::NotInitialized
        } else {
            DeviceState::NotConnected
        };
        let tag = device.as_ref().map(|d| d.tag.clone()).unwrap_or_default();
        let recipe = device.as_ref().map(SimDevice::default_recipe);
        PortSim {
            device,
            state,
            position_um: 0,
            motion: None,
            history: VecDeque::new(),
            recipes: vec![recipe.unwrap_or_default(); super::device::RECIPES],
            tag,
            fault_next_motion: false,
            led: 0,
            clamp: false,
            actuator_on: false,
            transitions: Transitions::default(),
        }
    }

    pub(super) fn state(&self) -> DeviceState {
        self.state
    }

    /// Whether the gripper must be (re-)enabled before it moves: in `DS_FAULT`, or disabled by
    /// DISABLE (3.4.1, 3.4.2). Not before the first HOME: the reference drive is the start.
    pub(super) fn needs_enable(&self) -> bool {
        self.state == DeviceState::Fault
            || (!self.actuator_on && self.state != DeviceState::NotInitialized)
    }

    /// Sets the device state; a change is a transition (WSTR, 3.4.10).
    pub(super) fn set_state(&mut self, state: DeviceState) {
        if state != self.state {
            self.state = state;
            self.transitions.count += 1;
        }
    }

    pub(super) fn remember(&mut self, id: u64, end: MotionEnd) {
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history.push_back((id, end));
    }

    /// How motion `id` ended, if it is still remembered.
    pub(super) fn ended(&self, id: u64) -> Option<MotionEnd> {
        self.history
            .iter()
            .find(|(h, _)| *h == id)
            .map(|(_, end)| *end)
    }

    pub(super) fn abort_motion(&mut self) {
        if let Some(m) = self.motion.take() {
            self.remember(m.id, MotionEnd::Aborted);
        }
    }

    /// Ends the motion in progress now with `state`, the fingers where they are.
    pub(super) fn end_motion_here(&mut self, state: DeviceState) {
        if let Some(m) = self.motion.take() {
            self.remember(m.id, MotionEnd::Done(state));
        }
        self.set_state(state);
    }

    /// Moves the fingers to where the motion in progress has them at `now`; ends it when due.
    pub(super) fn advance(&mut self, now: Duration) {
        let Some(m) = &self.motion else { return };
        if now >= m.end {
            let (id, to, state) = (m.id, m.to_um, m.end_state);
            self.position_um = to;
            self.motion = None;
            self.set_state(state);
            self.remember(id, MotionEnd::Done(state));
        } else {
            self.position_um = m.position_at(now);
        }
    }

    /// Ends the motion in progress now as if it had run its course.
    pub(super) fn finish_motion(&mut self) {
        if let Some(end) = self.motion.as_ref().map(|m| m.end) {
            self.advance(end);
        }
    }
}
