//! The simulated gripper: a pure state machine (no I/O, no clock of its own).
//!
//! The server feeds it frames with the current simulated time (seconds) and asks it for what
//! became due: motion results ([`Device::advance`]) and auto-updates ([`Device::updates_due`],
//! on the wall clock, since update periods are wire-level spacing, not physics).
//!
//! By concern: this file holds the state and its queries; the motion model is in `motion.rs`,
//! the book of sessions and their auto-update streams (`Sessions`, a part the device holds) in
//! `sessions.rs`, what each command does in `commands.rs`.

use bytes::Bytes;

use super::model::SimConfig;
use super::motion::{Motion, MotionKind};
use super::sessions::Sessions;
// Public here since the simulator's first release (`wsg::sim::device::SessionId`).
#[doc(inline)]
pub use super::sessions::{SessionId, SessionKind};
use crate::wsg::command::{id, Command, UpdateMode};
use crate::wsg::frame::Decoded;
use crate::wsg::{GraspingStatistics, GripState, Reply, SoftLimits, Status, SystemState};

/// A reply for one session.
#[derive(Clone, Debug, PartialEq)]
pub struct Out {
    /// Who gets it.
    pub session: SessionId,
    /// The reply.
    pub reply: Reply,
}

/// The simulated WSG.
#[derive(Debug)]
pub struct Device {
    pub(super) cfg: SimConfig,
    pub(super) now: f64,
    pub(super) position_mm: f32,
    pub(super) referenced: bool,
    pub(super) motion: Option<Motion>,
    pub(super) grip: GripState,
    pub(super) fast_stop: bool,
    pub(super) axis_stopped: bool,
    pub(super) target_reached: bool,
    pub(super) cmd_failure: bool,
    pub(super) overdrive: bool,
    pub(super) acceleration: f32,
    pub(super) force_limit: f32,
    pub(super) soft_limits: Option<SoftLimits>,
    pub(super) tag: Option<String>,
    pub(super) stats: GraspingStatistics,
    pub(super) finger_powered: [bool; 2],
    /// Pending finger power-on, per finger.
    pub(super) finger_power_on: [Option<PowerOn>; 2],
    /// The sessions connected, and their auto-update streams.
    pub(super) sessions: Sessions,
}

/// A finger power-on under way (manual 3.6.3: its final reply comes "nach etwa 500 ms").
#[derive(Debug)]
pub(super) struct PowerOn {
    /// When the finger is on, in **wall** seconds: switching power is electronics, not
    /// motion, so the motion time scale does not apply.
    pub(super) due_wall: f64,
    /// Who is owed a final reply, and how many (1.3: every E_CMD_PENDING is followed by one).
    /// One entry per session, so the list is bounded by the sessions, not by the requests.
    pub(super) owed: Vec<(SessionId, u32)>,
}

impl PowerOn {
    /// The final replies of command `id` with `result`, one per acknowledged request.
    pub(super) fn finish(self, id: u8, result: Status) -> impl Iterator<Item = Out> {
        self.owed
            .into_iter()
            .flat_map(move |(session, n)| (0..n).map(move |_| status(session, id, result)))
    }
}

/// The command id of finger `i`'s power switch (0x62, 0x72).
pub(super) fn finger_power_id(i: usize) -> u8 {
    if i == 0 {
        crate::wsg::command::id::FINGER1_POWER
    } else {
        crate::wsg::command::id::FINGER2_POWER
    }
}

pub(super) fn status(session: SessionId, id: u8, s: Status) -> Out {
    Out {
        session,
        reply: Reply::new(id, s, Bytes::new()),
    }
}

pub(super) fn data(session: SessionId, id: u8, d: Bytes) -> Out {
    Out {
        session,
        reply: Reply::new(id, Status::Success, d),
    }
}

pub(super) fn f32_bytes(v: f32) -> Bytes {
    Bytes::copy_from_slice(&v.to_le_bytes())
}

impl Device {
    /// A device fresh from power-on: not referenced, fingers at 0 mm.
    pub fn new(cfg: SimConfig) -> Self {
        Self {
            acceleration: cfg.acceleration_mm_per_s2,
            force_limit: cfg.grasping_force_n,
            cfg,
            now: 0.0,
            position_mm: 0.0,
            referenced: false,
            motion: None,
            grip: GripState::Idle,
            fast_stop: false,
            axis_stopped: false,
            target_reached: false,
            cmd_failure: false,
            overdrive: false,
            soft_limits: None,
            tag: None,
            stats: GraspingStatistics::default(),
            finger_powered: [true, true],
            finger_power_on: [None, None],
            sessions: Sessions::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// The current width, mm.
    pub fn width_mm(&self) -> f32 {
        if !self.referenced {
            return 0.0;
        }
        match &self.motion {
            Some(m) => m.profile.position(self.now - m.start),
            None => self.position_mm,
        }
    }

    pub(super) fn speed_mm_per_s(&self) -> f32 {
        match &self.motion {
            Some(m) => m.profile.speed(self.now - m.start),
            None => 0.0,
        }
    }

    /// Whether the fingers move (SF_MOVING): a motion runs and has not reached its end. Its
    /// final reply may follow later ([`SimConfig::final_reply_lag`]).
    pub(super) fn fingers_moving(&self) -> bool {
        self.motion.is_some_and(|m| self.now < m.end())
    }

    /// The grip state.
    pub fn grip_state(&self) -> GripState {
        self.grip
    }

    /// The system state flags (Anhang B).
    pub fn system_state(&self) -> SystemState {
        let w = self.width_mm();
        let (lim_minus, lim_plus) = match self.soft_limits {
            Some(l) if self.referenced => (w <= l.minus_mm, w >= l.plus_mm),
            _ => (false, false),
        };
        SystemState::empty()
            .with(SystemState::REFERENCED, self.referenced)
            .with(SystemState::MOVING, self.fingers_moving())
            .with(SystemState::SOFT_LIMIT_MINUS, lim_minus)
            .with(SystemState::SOFT_LIMIT_PLUS, lim_plus)
            .with(SystemState::AXIS_STOPPED, self.axis_stopped)
            .with(SystemState::TARGET_POS_REACHED, self.target_reached)
            .with(SystemState::OVERDRIVE_MODE, self.overdrive)
            .with(
                SystemState::FORCECNTL_MODE,
                self.cfg.force_sensor && self.grip == GripState::Holding,
            )
            .with(SystemState::FAST_STOP, self.fast_stop)
            .with(SystemState::CMD_FAILURE, self.cmd_failure)
    }

    /// The grasping statistics.
    pub fn statistics(&self) -> GraspingStatistics {
        self.stats
    }

    /// The part held is lost (pulled out): HOLDING → PART LOST (manual 3.4.2).
    pub fn lose_part(&mut self) {
        if self.grip == GripState::Holding {
            self.grip = GripState::PartLost;
            self.stats.lost_part = self.stats.lost_part.saturating_add(1);
        }
    }

    /// When the next motion finishes, in simulated seconds (a finger power-on finishes on the
    /// wall clock: see [`Device::next_update_due`]).
    pub fn next_event(&self) -> Option<f64> {
        self.motion.as_ref().map(Motion::done)
    }

    /// Advances the simulated time to `now` and returns the results of what finished.
    pub fn advance(&mut self, now: f64) -> Vec<Out> {
        self.now = now.max(self.now);
        let mut out = Vec::new();
        if let Some(m) = self.motion {
            if m.done() <= self.now {
                self.motion = None;
                self.position_mm = m.profile.to_mm as f32;
                self.target_reached = true;
                let result = match m.kind {
                    MotionKind::Homing => {
                        self.referenced = true;
                        self.grip = GripState::Idle;
                        Status::Success
                    }
                    MotionKind::PrePosition { blocked: false } | MotionKind::Release => {
                        self.grip = GripState::Idle;
                        Status::Success
                    }
                    MotionKind::PrePosition { blocked: true } => {
                        self.grip = GripState::Idle;
                        self.target_reached = false;
                        Status::AxisBlocked
                    }
                    MotionKind::Grasp { found: true } => {
                        self.grip = GripState::Holding;
                        Status::Success
                    }
                    MotionKind::Grasp { found: false } => {
                        self.grip = GripState::NoPartFound;
                        self.stats.no_part = self.stats.no_part.saturating_add(1);
                        self.cmd_failure = true;
                        Status::CmdFailed
                    }
                };
                out.push(status(m.session, m.command, result));
            }
        }
        out
    }

    /// Handles a received frame (or a frame with a bad checksum) at simulated time `now`.
    pub fn handle(&mut self, now: f64, session: SessionId, received: &Decoded) -> Vec<Out> {
        self.handle_at(now, None, session, received)
    }

    /// [`Device::handle`] with the wall clock (seconds) for auto-update scheduling.
    pub fn handle_at(
        &mut self,
        now: f64,
        wall: Option<f64>,
        session: SessionId,
        received: &Decoded,
    ) -> Vec<Out> {
        let mut out = self.advance(now);
        let frame = match received {
            Decoded::Corrupt { id, len } => {
                // The manual does not say how the device treats a wrong checksum: it lists
                // E_CHECKSUM_ERROR (Anhang A) under no command, and 1.2.1 only says a frame
                // *missing* its checksum is discarded ("als ungültig verworfen"). Any byte of
                // such a frame may be the broken one, its id included: an answer under that id
                // could fail a caller that sent another command with it. So by default the frame
                // is discarded unanswered (its sender times out, as for a lost frame); see
                // `SimConfig::answer_bad_checksum`.
                if self.cfg.answer_bad_checksum {
                    out.push(status(session, *id, Status::ChecksumError));
                } else {
                    tracing::warn!(id, len, "simulator: frame with a bad checksum discarded");
                }
                return out;
            }
            Decoded::Frame(f) => f,
        };
        if self.sessions.announced(session) {
            out.push(status(session, frame.id, Status::AccessDenied));
            return out;
        }
        match Command::parse(frame) {
            // A NaN or infinite float is never in range. Found by fuzzing (fuzz/wsg_sim): a NaN
            // width, speed or acceleration gave the motion a NaN end time, which the server's
            // settle loop never reached (a hang at time scale 0, a panic in its clock otherwise).
            // Only the finiteness check is shared with `Command::validate`: the simulator
            // still accepts what a device accepts (e.g. auto-update periods under 10 ms).
            Ok(cmd) if cmd.check_finite_arguments().is_err() => {
                out.push(status(session, frame.id, Status::RangeError));
            }
            Ok(cmd) => self.execute(session, wall, cmd, &mut out),
            Err(s) => out.push(status(session, frame.id, s)),
        }
        out
    }

    /// A session opened.
    pub fn connect(&mut self, session: SessionId, kind: SessionKind) {
        self.sessions.connect(session, kind);
    }

    /// A session closed (or was unplugged, or a UDP peer expired). An unannounced TCP close
    /// triggers FAST STOP (manual 1.4.2), which ends a move in progress with E_CMD_ABORTED like
    /// a stop does (1.3): the returned reply goes to whichever session started the move, which
    /// may be another, still connected one (or this one, still reading after a half-close). The
    /// session's auto-updates end.
    pub fn disconnect(&mut self, session: SessionId, now: f64) -> Vec<Out> {
        let mut out = self.advance(now);
        let (kind, announced) = self.sessions.remove(session);
        if kind == Some(SessionKind::Tcp) && !announced && self.cfg.fast_stop_on_close {
            out.extend(self.trigger_fast_stop());
        }
        out
    }

    /// The transport of a session, if it is connected.
    pub fn session_kind(&self, session: SessionId) -> Option<SessionKind> {
        self.sessions.kind(session)
    }

    /// Whether a session has announced its disconnect.
    pub fn announced(&self, session: SessionId) -> bool {
        self.sessions.announced(session)
    }

    /// Whether `session` is still owed something: the final reply of a move it started or of a
    /// finger power-on (3.6.3), or auto-updates (3.4.1) it switched on. A UDP peer is not
    /// forgotten while it is: the device keeps streaming to its UDP remote port whether or not
    /// the driver there ever sends again, and public drivers subscribe once and then only listen.
    pub fn owes_session(&self, session: SessionId) -> bool {
        self.sessions.streams_to(session)
            || self.motion.is_some_and(|m| m.session == session)
            || self
                .finger_power_on
                .iter()
                .flatten()
                .any(|p| p.owed.iter().any(|(s, _)| *s == session))
    }

    /// Answers 0x40–0x45's flags and period (3.4.1): the value now, and with FLAGS bit0 set
    /// updates every period from wall time `wall` (see [`Sessions::set_stream`]).
    pub(super) fn auto_update(
        &mut self,
        session: SessionId,
        id: u8,
        mode: UpdateMode,
        wall: f64,
    ) -> Out {
        let value = self.streamed_value(id);
        self.sessions.set_stream(session, id, mode, wall, &value);
        data(session, id, value)
    }

    fn streamed_value(&self, id: u8) -> Bytes {
        match id {
            id::SYSTEM_STATE => Bytes::copy_from_slice(&self.system_state().bits().to_le_bytes()),
            id::GRIP_STATE => Bytes::copy_from_slice(&[self.grip.to_u8()]),
            id::WIDTH => f32_bytes(self.width_mm()),
            id::SPEED => f32_bytes(self.speed_mm_per_s()),
            _ => f32_bytes(self.force_n()),
        }
    }

    fn force_n(&self) -> f32 {
        if self.grip == GripState::Holding {
            self.force_limit
        } else {
            0.0
        }
    }

    /// How many auto-update streams are on (all sessions).
    pub fn active_streams(&self) -> usize {
        self.sessions.active_streams()
    }

    /// When the next auto-update or finger power-on is due (wall seconds).
    pub fn next_update_due(&self) -> Option<f64> {
        let power = self.finger_power_on.iter().flatten().map(|p| p.due_wall);
        self.sessions
            .next_due()
            .into_iter()
            .chain(power)
            .reduce(f64::min)
    }

    /// The auto-updates due at wall time `wall` (after [`Device::advance`] to the current
    /// simulated time). On-change streams send only when the value moved by the manual's
    /// threshold (3.4.4–3.4.6: 0.01 mm, 0.05 mm/s, 0.05 N; any change of flags or state).
    /// Sessions for which `paused` is true get none this time (their next one is a period
    /// later): the server pauses a connection whose client does not read its replies.
    ///
    /// Finger power-ons due by `wall` finish here too (their 500 ms are wall time, 3.6.3).
    pub fn updates_due(&mut self, wall: f64, paused: impl Fn(SessionId) -> bool) -> Vec<Out> {
        let mut out = Vec::new();
        for i in 0..self.finger_power_on.len() {
            if let Some(p) = self.finger_power_on[i].take_if(|p| p.due_wall <= wall) {
                self.finger_powered[i] = true;
                out.extend(p.finish(finger_power_id(i), Status::Success));
            }
        }
        for (session, id) in self.sessions.due(wall) {
            let value = self.streamed_value(id);
            if let Some(value) = self
                .sessions
                .update(session, id, value, wall, paused(session))
            {
                out.push(data(session, id, value));
            }
        }
        out
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::wsg::command::{HomingDirection, UpdateMode};
    use crate::wsg::Frame;

    fn cmd(d: &mut Device, now: f64, c: Command) -> Vec<Status> {
        d.handle(now, 1, &Decoded::Frame(c.to_frame()))
            .into_iter()
            .map(|o| o.reply.status)
            .collect()
    }

    fn dev() -> Device {
        let mut d = Device::new(SimConfig::default().with_part(40.0, 1.0));
        d.connect(1, SessionKind::Tcp);
        d
    }

    /// Anhang B: SF_MOVING is reset when the fingers stop; the final reply comes when the
    /// command ends (1.3), `final_reply_lag` later. A client must not take the one for the other.
    #[test]
    fn the_final_reply_may_come_after_the_moving_flag_is_reset() {
        let mut cfg = SimConfig::default().with_part(40.0, 1.0);
        cfg.final_reply_lag = std::time::Duration::from_millis(200);
        let mut d = Device::new(cfg);
        d.connect(1, SessionKind::Tcp);
        let home = Command::Homing(HomingDirection::Default);
        assert_eq!(cmd(&mut d, 0.0, home.clone()), [Status::CmdPending]);
        let done = d.next_event().unwrap();
        let stopped = done - 0.2;
        assert!(stopped > 0.0);
        assert!(d.advance(stopped - 0.01).is_empty());
        assert!(d.system_state().contains(SystemState::MOVING));
        // The fingers stand still: the flag is clear, the command not yet over.
        assert!(d.advance(stopped + 0.01).is_empty());
        assert!(!d.system_state().contains(SystemState::MOVING));
        assert_eq!(cmd(&mut d, stopped + 0.02, home), [Status::AlreadyRunning]);
        let finals: Vec<_> = d
            .advance(done)
            .into_iter()
            .map(|o| o.reply.status)
            .collect();
        assert_eq!(finals, [Status::Success]);
    }

    #[test]
    fn motion_needs_homing_and_homing_references() {
        let mut d = dev();
        let pre = Command::PrePosition {
            relative: false,
            stop_on_block: true,
            width_mm: 50.0,
            speed_mm_per_s: 100.0,
        };
        assert_eq!(cmd(&mut d, 0.0, pre.clone()), [Status::NotInitialized]);
        assert_eq!(
            cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default)),
            [Status::CmdPending]
        );
        let t = d.next_event().unwrap();
        assert!(t > 0.0);
        assert_eq!(
            d.advance(t)
                .into_iter()
                .map(|o| o.reply.status)
                .collect::<Vec<_>>(),
            [Status::Success]
        );
        assert!(d.system_state().contains(SystemState::REFERENCED));
        assert_eq!(d.width_mm(), 110.0);
        assert_eq!(cmd(&mut d, t, pre), [Status::CmdPending]);
        // Halfway through the move the width is between start and end.
        let end = d.next_event().unwrap();
        d.advance((t + end) / 2.0);
        let w = d.width_mm();
        assert!(w < 110.0 && w > 50.0, "{w}");
        assert!(d.system_state().contains(SystemState::MOVING));
    }

    /// Regression (fuzz/wsg_sim): GRASP with a NaN width and speed after homing started a motion
    /// whose end time was NaN, so it never ended and the server's settle loop spun forever.
    #[test]
    fn non_finite_float_arguments_are_range_errors() {
        let mut d = dev();
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        let t = d.next_event().unwrap();
        d.advance(t);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for c in [
                Command::Grasp {
                    width_mm: bad,
                    speed_mm_per_s: 50.0,
                },
                Command::Release {
                    width_mm: 60.0,
                    speed_mm_per_s: bad,
                },
                Command::PrePosition {
                    relative: true,
                    stop_on_block: false,
                    width_mm: bad,
                    speed_mm_per_s: 50.0,
                },
                Command::SetAcceleration(bad),
                Command::SetForce(bad),
                Command::SetSoftLimits(SoftLimits {
                    minus_mm: bad,
                    plus_mm: 100.0,
                }),
            ] {
                assert_eq!(cmd(&mut d, t, c.clone()), [Status::RangeError], "{c:?}");
            }
            assert_eq!(d.next_event(), None, "no motion started");
        }
        // The settings are unchanged: a normal move still has a finite end.
        let grasp = Command::Grasp {
            width_mm: 40.0,
            speed_mm_per_s: 50.0,
        };
        assert_eq!(cmd(&mut d, t, grasp), [Status::CmdPending]);
        assert!(d.next_event().is_some_and(f64::is_finite));
    }

    /// Manual 3.2.2: a pre-position that meets a blockage in its direction ends with
    /// E_AXIS_BLOCKED, the fingers stopped there. With `part_blocks_motion`, the part is that
    /// blockage for a move closing past it; without, the move passes (the default, unchanged).
    #[test]
    fn a_blocking_part_stops_a_closing_pre_position_at_its_width() {
        let pre = |width_mm| Command::PrePosition {
            relative: false,
            stop_on_block: true,
            width_mm,
            speed_mm_per_s: 50.0,
        };
        for (blocking, status, end) in [
            (true, Status::AxisBlocked, 40.0),
            (false, Status::Success, 5.0),
        ] {
            let mut cfg = SimConfig::default().with_part(40.0, 1.0);
            cfg.part_blocks_motion = blocking;
            let mut d = Device::new(cfg);
            d.connect(1, SessionKind::Tcp);
            cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
            d.advance(100.0);
            assert_eq!(cmd(&mut d, 100.0, pre(5.0)), [Status::CmdPending]);
            assert_eq!(d.advance(200.0)[0].reply.status, status);
            assert_eq!(d.width_mm(), end, "blocking: {blocking}");
            assert_eq!(d.grip_state(), GripState::Idle);
            // Fingers on the part: closing further is blocked at once.
            if blocking {
                assert_eq!(cmd(&mut d, 200.0, pre(5.0)), [Status::CmdPending]);
                assert_eq!(d.advance(300.0)[0].reply.status, Status::AxisBlocked);
                assert_eq!(d.width_mm(), 40.0);
            }
        }
        // Opening, or closing to a width above the part, is not blocked.
        let mut d = Device::new(
            SimConfig::default()
                .with_part(40.0, 1.0)
                .with_blocking_part(),
        );
        d.connect(1, SessionKind::Tcp);
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        d.advance(100.0);
        cmd(&mut d, 100.0, pre(60.0));
        assert_eq!(d.advance(200.0)[0].reply.status, Status::Success);
        cmd(&mut d, 200.0, pre(90.0));
        assert_eq!(d.advance(300.0)[0].reply.status, Status::Success);
        assert_eq!(d.width_mm(), 90.0);
    }

    #[test]
    fn grasp_finds_the_configured_part_or_fails() {
        let mut d = dev();
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        d.advance(100.0);
        assert_eq!(
            cmd(
                &mut d,
                100.0,
                Command::Grasp {
                    width_mm: 10.0,
                    speed_mm_per_s: 50.0
                }
            ),
            [Status::CmdPending]
        );
        assert_eq!(d.grip_state(), GripState::Grasping);
        assert_eq!(d.advance(200.0)[0].reply.status, Status::CmdFailed);
        assert_eq!(d.grip_state(), GripState::NoPartFound);
        cmd(
            &mut d,
            200.0,
            Command::Release {
                width_mm: 80.0,
                speed_mm_per_s: 50.0,
            },
        );
        d.advance(300.0);
        assert_eq!(
            cmd(
                &mut d,
                300.0,
                Command::Grasp {
                    width_mm: 40.5,
                    speed_mm_per_s: 50.0
                }
            ),
            [Status::CmdPending]
        );
        assert_eq!(d.advance(400.0)[0].reply.status, Status::Success);
        assert_eq!(d.grip_state(), GripState::Holding);
        assert_eq!(d.width_mm(), 40.0);
        assert_eq!(
            d.statistics(),
            GraspingStatistics {
                total: 2,
                no_part: 1,
                lost_part: 0
            }
        );
    }

    #[test]
    fn stop_aborts_and_fast_stop_locks_until_acknowledged() {
        let mut d = dev();
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        d.advance(100.0);
        cmd(
            &mut d,
            100.0,
            Command::Release {
                width_mm: 0.0,
                speed_mm_per_s: 1.0,
            },
        );
        assert_eq!(
            cmd(&mut d, 101.0, Command::Stop),
            [Status::CmdAborted, Status::Success]
        );
        assert!(d.system_state().contains(SystemState::AXIS_STOPPED));
        assert_eq!(d.grip_state(), GripState::Idle);
        assert_eq!(cmd(&mut d, 101.0, Command::FastStop), [Status::Success]);
        assert_eq!(d.grip_state(), GripState::Error);
        assert_eq!(
            cmd(&mut d, 101.0, Command::Homing(HomingDirection::Default)),
            [Status::AccessDenied]
        );
        assert_eq!(cmd(&mut d, 101.0, Command::AckFastStop), [Status::Success]);
        assert!(!d.system_state().contains(SystemState::FAST_STOP));
    }

    #[test]
    fn unknown_ids_bad_checksums_and_disconnects() {
        let mut d = dev();
        let o = d.handle(0.0, 1, &Decoded::Frame(Frame::new(0x90, Bytes::new())));
        assert_eq!(
            o[0].reply,
            Reply::new(0x90, Status::CmdUnknown, Bytes::new())
        );
        // A frame with a bad checksum is discarded (the manual does not say; see `handle_at`),
        // unless configured otherwise.
        let corrupt = Decoded::Corrupt { id: 0x43, len: 3 };
        assert_eq!(d.handle(0.0, 1, &corrupt), []);
        d.cfg.answer_bad_checksum = true;
        let o = d.handle(0.0, 1, &corrupt);
        assert_eq!(
            o[0].reply,
            Reply::new(0x43, Status::ChecksumError, Bytes::new())
        );
        d.disconnect(1, 0.0);
        assert!(
            d.system_state().contains(SystemState::FAST_STOP),
            "unannounced TCP close"
        );
        let mut d = dev();
        assert_eq!(
            cmd(&mut d, 0.0, Command::AnnounceDisconnect),
            [Status::Success]
        );
        assert_eq!(
            cmd(&mut d, 0.0, Command::SystemInfo),
            [Status::AccessDenied]
        );
        d.disconnect(1, 0.0);
        assert!(!d.system_state().contains(SystemState::FAST_STOP));
        d.connect(2, SessionKind::Udp);
        let o = d.handle(
            0.0,
            2,
            &Decoded::Frame(Command::AnnounceDisconnect.to_frame()),
        );
        assert_eq!(o[0].reply.status, Status::NotAvailable);
    }

    #[test]
    fn on_change_updates_only_when_the_value_moves() {
        let mut d = dev();
        let m = UpdateMode {
            auto: true,
            on_change: true,
            period_ms: 10,
        };
        let o = d.handle_at(
            0.0,
            Some(0.0),
            1,
            &Decoded::Frame(Command::GripState(m).to_frame()),
        );
        assert_eq!(o.len(), 1);
        assert!(d.updates_due(0.02, |_| false).is_empty(), "nothing changed");
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        let o = d.updates_due(0.04, |_| false);
        assert_eq!(o.len(), 1);
        assert_eq!(&o[0].reply.data[..], &[GripState::Positioning.to_u8()]);
        // bit0 clear ends the stream.
        d.handle_at(
            0.0,
            Some(0.05),
            1,
            &Decoded::Frame(Command::GripState(UpdateMode::ONCE).to_frame()),
        );
        assert_eq!(d.next_update_due(), None);
    }

    /// Manual 1.3 and 1.4.2: another session's unannounced TCP close is a FAST STOP whose
    /// E_CMD_ABORTED goes to the move's owner; a UDP session is not owed anything after it.
    #[test]
    fn a_lost_connection_answers_the_owner_of_the_move() {
        let mut d = dev();
        d.connect(2, SessionKind::Tcp);
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        assert!(d.owes_session(1));
        assert!(!d.owes_session(2));
        let o = d.disconnect(2, 0.0);
        assert_eq!(o.len(), 1);
        assert_eq!((o[0].session, o[0].reply.id), (1, 0x20));
        assert_eq!(o[0].reply.status, Status::CmdAborted);
        assert!(d.system_state().contains(SystemState::FAST_STOP));
        assert!(!d.owes_session(1));
    }

    /// 0x40–0x45 list only E_SUCCESS and E_CMD_FORMAT_ERROR: a period under 10 ms runs at 10 ms.
    #[test]
    fn a_short_update_period_runs_at_the_minimum() {
        let mut d = dev();
        let m = UpdateMode {
            auto: true,
            on_change: false,
            period_ms: 1,
        };
        let o = d.handle_at(
            0.0,
            Some(0.0),
            1,
            &Decoded::Frame(Command::Width(m).to_frame()),
        );
        assert_eq!(o[0].reply.status, Status::Success);
        assert_eq!(d.next_update_due(), Some(0.01));
    }

    fn power(d: &mut Device, session: SessionId, wall: f64, on: bool) -> Vec<Out> {
        let f = Command::FingerPower(crate::wsg::Finger::One, on).to_frame();
        d.handle_at(0.0, Some(wall), session, &Decoded::Frame(f))
    }

    fn powered(d: &Device) -> bool {
        d.finger_powered[0]
    }

    /// Manual 1.3: every asynchronous command gets its final reply. A second power-on while the
    /// first is pending is acknowledged too, and both callers get the result.
    #[test]
    fn two_pending_power_ons_each_get_their_final_reply() {
        let mut d = dev();
        d.connect(2, SessionKind::Tcp);
        assert_eq!(
            power(&mut d, 1, 0.0, false)[0].reply.status,
            Status::Success
        );
        assert_eq!(
            power(&mut d, 1, 10.0, true)[0].reply.status,
            Status::CmdPending
        );
        assert_eq!(
            power(&mut d, 2, 10.1, true)[0].reply.status,
            Status::CmdPending
        );
        assert!(d.owes_session(1) && d.owes_session(2));
        let due = d.next_update_due().unwrap();
        let o = d.updates_due(due, |_| false);
        let mut got: Vec<_> = o
            .iter()
            .map(|o| (o.session, o.reply.id, o.reply.status))
            .collect();
        got.sort_by_key(|g| g.0);
        assert_eq!(
            got,
            [(1, 0x62, Status::Success), (2, 0x62, Status::Success)]
        );
        assert!(powered(&d));
        assert!(!d.owes_session(1) && !d.owes_session(2));
    }

    /// Manual 3.6.3: switching off "is carried out immediately", also while a power-on is
    /// pending; the pending power-on ends (E_CMD_ABORTED) and never switches the finger on.
    #[test]
    fn power_off_while_a_power_on_is_pending_wins_at_once() {
        let mut d = dev();
        power(&mut d, 1, 0.0, false);
        assert_eq!(
            power(&mut d, 1, 1.0, true)[0].reply.status,
            Status::CmdPending
        );
        let o = power(&mut d, 1, 1.2, false);
        let got: Vec<_> = o.iter().map(|o| (o.reply.id, o.reply.status)).collect();
        assert_eq!(got, [(0x62, Status::CmdAborted), (0x62, Status::Success)]);
        assert!(!powered(&d));
        assert!(d.updates_due(100.0, |_| false).is_empty());
        assert!(
            !powered(&d),
            "the aborted power-on must not switch the finger on later"
        );
    }

    /// The 500 ms of a power-on (3.6.3) are wall time: the motion time scale does not stretch
    /// them (nor make them instant), and the simulated motion clock does not complete them.
    #[test]
    fn power_on_takes_500_ms_of_wall_time_whatever_the_motion_clock() {
        let mut d = dev();
        power(&mut d, 1, 0.0, false);
        assert_eq!(
            power(&mut d, 1, 5.0, true)[0].reply.status,
            Status::CmdPending
        );
        assert!(
            d.advance(1.0e6).is_empty(),
            "the motion clock does not finish it"
        );
        assert_eq!(d.next_update_due(), Some(5.5));
        assert!(d.updates_due(5.49, |_| false).is_empty());
        assert_eq!(d.updates_due(5.5, |_| false).len(), 1);
        assert!(powered(&d));
    }
}
