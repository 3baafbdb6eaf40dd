//! The simulated gripper: a pure state machine (no I/O, no clock of its own).
//!
//! The server feeds it frames with the current simulated time (seconds) and asks it for what
//! became due: motion results ([`Device::advance`]) and auto-updates ([`Device::updates_due`],
//! on the wall clock, since update periods are wire-level spacing, not physics).

use std::collections::{BTreeMap, HashSet};

use bytes::{BufMut, Bytes, BytesMut};

use super::model::SimConfig;
use crate::wsg::command::{id, Command, HomingDirection, UpdateMode, MAX_TAG_LEN};
use crate::wsg::frame::Decoded;
use crate::wsg::{
    Finger, FingerFlags, FingerInfo, FingerType, GraspingStatistics, GripState, Reply, SoftLimits,
    Status, SystemInfo, SystemState,
};

/// Identifies one connection (TCP connection, UDP peer, serial port) to the device.
pub type SessionId = u64;

/// The kind of a session's transport (the disconnect announcement is TCP-only, manual 3.1.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SessionKind {
    /// A TCP connection: an unannounced close triggers FAST STOP (manual 1.4.2).
    Tcp,
    /// A UDP peer.
    Udp,
    /// A serial line (or any other byte stream).
    Serial,
}

/// A reply for one session.
#[derive(Clone, Debug, PartialEq)]
pub struct Out {
    /// Who gets it.
    pub session: SessionId,
    /// The reply.
    pub reply: Reply,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum MotionKind {
    Homing,
    PrePosition,
    Grasp { found: bool },
    Release,
}

/// A trapezoidal move (accelerate, cruise, decelerate) from `from_mm` to `to_mm`.
#[derive(Clone, Copy, Debug)]
struct Profile {
    from_mm: f64,
    to_mm: f64,
    acc: f64,
    v_peak: f64,
    t_acc: f64,
    total: f64,
}

impl Profile {
    fn new(from_mm: f32, to_mm: f32, speed: f32, acc: f32) -> Self {
        let (from_mm, to_mm, v, acc) = (
            f64::from(from_mm),
            f64::from(to_mm),
            f64::from(speed),
            f64::from(acc),
        );
        let dist = (to_mm - from_mm).abs();
        let (t_acc, v_peak, total) = if dist <= v * v / acc {
            let t = (dist / acc).sqrt();
            (t, acc * t, 2.0 * t)
        } else {
            (v / acc, v, dist / v + v / acc)
        };
        Self {
            from_mm,
            to_mm,
            acc,
            v_peak,
            t_acc,
            total,
        }
    }

    fn travelled(&self, t: f64) -> f64 {
        let dist = (self.to_mm - self.from_mm).abs();
        if t <= 0.0 {
            0.0
        } else if t >= self.total {
            dist
        } else if t < self.t_acc {
            0.5 * self.acc * t * t
        } else if t < self.total - self.t_acc {
            0.5 * self.acc * self.t_acc * self.t_acc + self.v_peak * (t - self.t_acc)
        } else {
            let r = self.total - t;
            dist - 0.5 * self.acc * r * r
        }
    }

    fn position(&self, t: f64) -> f32 {
        let s = self.travelled(t);
        let p = if self.to_mm >= self.from_mm {
            self.from_mm + s
        } else {
            self.from_mm - s
        };
        p as f32
    }

    fn speed(&self, t: f64) -> f32 {
        let v = if t <= 0.0 || t >= self.total {
            0.0
        } else if t < self.t_acc {
            self.acc * t
        } else if t < self.total - self.t_acc {
            self.v_peak
        } else {
            self.acc * (self.total - t)
        };
        v as f32
    }
}

#[derive(Clone, Copy, Debug)]
struct Motion {
    session: SessionId,
    command: u8,
    kind: MotionKind,
    start: f64,
    profile: Profile,
}

impl Motion {
    fn end(&self) -> f64 {
        self.start + self.profile.total
    }
}

#[derive(Clone, Debug)]
struct Stream {
    mode: UpdateMode,
    next_due: f64,
    last: Option<Bytes>,
}

/// The simulated WSG.
#[derive(Debug)]
pub struct Device {
    cfg: SimConfig,
    now: f64,
    position_mm: f32,
    referenced: bool,
    motion: Option<Motion>,
    grip: GripState,
    fast_stop: bool,
    axis_stopped: bool,
    target_reached: bool,
    cmd_failure: bool,
    overdrive: bool,
    acceleration: f32,
    force_limit: f32,
    soft_limits: Option<SoftLimits>,
    tag: Option<String>,
    stats: GraspingStatistics,
    finger_powered: [bool; 2],
    /// Pending finger power-on: (session, due time).
    finger_power_on: [Option<(SessionId, f64)>; 2],
    sessions: BTreeMap<SessionId, SessionKind>,
    announced: HashSet<SessionId>,
    streams: BTreeMap<(SessionId, u8), Stream>,
}

fn status(session: SessionId, id: u8, s: Status) -> Out {
    Out {
        session,
        reply: Reply::new(id, s, Bytes::new()),
    }
}

fn data(session: SessionId, id: u8, d: Bytes) -> Out {
    Out {
        session,
        reply: Reply::new(id, Status::Success, d),
    }
}

fn f32_bytes(v: f32) -> Bytes {
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
            sessions: BTreeMap::new(),
            announced: HashSet::new(),
            streams: BTreeMap::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// A session opened.
    pub fn connect(&mut self, session: SessionId, kind: SessionKind) {
        self.sessions.insert(session, kind);
    }

    /// A session closed (or was unplugged). An unannounced TCP close triggers FAST STOP (manual
    /// 1.4.2); the session's auto-updates end.
    pub fn disconnect(&mut self, session: SessionId, now: f64) {
        self.now = now.max(self.now);
        let kind = self.sessions.remove(&session);
        let announced = self.announced.remove(&session);
        self.streams.retain(|(s, _), _| *s != session);
        if kind == Some(SessionKind::Tcp) && !announced {
            // The abort replies would go to the closed session: nobody to send them to.
            let _ = self.trigger_fast_stop();
        }
    }

    /// The transport of a session, if it is connected.
    pub fn session_kind(&self, session: SessionId) -> Option<SessionKind> {
        self.sessions.get(&session).copied()
    }

    /// Whether a session has announced its disconnect.
    pub fn announced(&self, session: SessionId) -> bool {
        self.announced.contains(&session)
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

    fn speed_mm_per_s(&self) -> f32 {
        match &self.motion {
            Some(m) => m.profile.speed(self.now - m.start),
            None => 0.0,
        }
    }

    fn force_n(&self) -> f32 {
        if self.grip == GripState::Holding {
            self.force_limit
        } else {
            0.0
        }
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
            .with(SystemState::MOVING, self.motion.is_some())
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

    /// When the next motion (or finger power-on) finishes, in simulated seconds.
    pub fn next_event(&self) -> Option<f64> {
        let motion = self.motion.as_ref().map(Motion::end);
        let power = self.finger_power_on.iter().flatten().map(|(_, t)| *t);
        motion.into_iter().chain(power).reduce(f64::min)
    }

    /// Advances the simulated time to `now` and returns the results of what finished.
    pub fn advance(&mut self, now: f64) -> Vec<Out> {
        self.now = now.max(self.now);
        let mut out = Vec::new();
        if let Some(m) = self.motion {
            if m.end() <= self.now {
                self.motion = None;
                self.position_mm = m.profile.to_mm as f32;
                self.target_reached = true;
                let result = match m.kind {
                    MotionKind::Homing => {
                        self.referenced = true;
                        self.grip = GripState::Idle;
                        Status::Success
                    }
                    MotionKind::PrePosition | MotionKind::Release => {
                        self.grip = GripState::Idle;
                        Status::Success
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
        for (i, slot) in self.finger_power_on.iter_mut().enumerate() {
            if let Some((session, due)) = *slot {
                if due <= self.now {
                    *slot = None;
                    self.finger_powered[i] = true;
                    out.push(status(session, 0x62 + 0x10 * i as u8, Status::Success));
                }
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
            // A device answers a frame with a bad checksum under the received id.
            Decoded::Corrupt { id, .. } => {
                out.push(status(session, *id, Status::ChecksumError));
                return out;
            }
            Decoded::Frame(f) => f,
        };
        if self.announced.contains(&session) {
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

    fn motion_allowed(&self, session: SessionId, id: u8, needs_reference: bool) -> Result<(), Out> {
        if self.fast_stop {
            Err(status(session, id, Status::AccessDenied))
        } else if needs_reference && !self.referenced {
            Err(status(session, id, Status::NotInitialized))
        } else if self.motion.is_some() {
            Err(status(session, id, Status::AlreadyRunning))
        } else {
            Ok(())
        }
    }

    /// The immediate checks of a referenced motion to `target` (3.2.2, 3.2.6, 3.2.7).
    fn check_motion_to(&self, session: SessionId, id: u8, target: f32) -> Result<(), Out> {
        self.motion_allowed(session, id, true)?;
        if self.within_soft_limits(target) {
            Ok(())
        } else {
            Err(status(session, id, Status::RangeError))
        }
    }

    fn within_soft_limits(&self, w: f32) -> bool {
        self.soft_limits
            .is_none_or(|l| w >= l.minus_mm && w <= l.plus_mm)
    }

    fn clamp_speed(&self, v: f32) -> f32 {
        v.clamp(
            self.cfg.limits.min_speed_mm_per_s,
            self.cfg.limits.max_speed_mm_per_s,
        )
    }

    fn start(
        &mut self,
        session: SessionId,
        command: u8,
        kind: MotionKind,
        to_mm: f32,
        speed: f32,
    ) -> Out {
        let from = self.width_mm();
        self.start_from(session, command, kind, from, to_mm, speed)
    }

    fn start_from(
        &mut self,
        session: SessionId,
        command: u8,
        kind: MotionKind,
        from: f32,
        to_mm: f32,
        speed: f32,
    ) -> Out {
        let to = to_mm.clamp(0.0, self.cfg.limits.stroke_mm);
        self.motion = Some(Motion {
            session,
            command,
            kind,
            start: self.now,
            profile: Profile::new(from, to, self.clamp_speed(speed), self.acceleration),
        });
        self.axis_stopped = false;
        self.target_reached = false;
        self.cmd_failure = false;
        status(session, command, Status::CmdPending)
    }

    /// Stops the current motion where it is; returns the E_CMD_ABORTED for its caller.
    fn abort_motion(&mut self) -> Option<Out> {
        let m = self.motion.take()?;
        self.position_mm = m.profile.position(self.now - m.start);
        Some(status(m.session, m.command, Status::CmdAborted))
    }

    fn trigger_fast_stop(&mut self) -> Option<Out> {
        self.fast_stop = true;
        self.grip = GripState::Error;
        self.abort_motion()
    }

    fn execute(&mut self, session: SessionId, wall: Option<f64>, cmd: Command, out: &mut Vec<Out>) {
        let id = cmd.id();
        let ok = |out: &mut Vec<Out>| out.push(status(session, id, Status::Success));
        match cmd {
            Command::Loop(d) => out.push(data(session, id, d)),
            Command::AnnounceDisconnect => {
                if self.sessions.get(&session) == Some(&SessionKind::Tcp) {
                    // "All running finger movements are stopped immediately" (3.1.2).
                    out.extend(self.abort_motion());
                    self.announced.insert(session);
                    ok(out);
                } else {
                    out.push(status(session, id, Status::NotAvailable));
                }
            }
            Command::Homing(dir) => match self.motion_allowed(session, id, false) {
                Err(e) => out.push(e),
                Ok(()) => {
                    let target = match dir {
                        HomingDirection::Negative => 0.0,
                        _ => self.cfg.limits.stroke_mm,
                    };
                    // Homing starts from wherever the fingers are; before referencing that is
                    // unknown, so the simulated fingers start from the opposite end.
                    let from = if self.referenced {
                        self.width_mm()
                    } else {
                        self.cfg.limits.stroke_mm - target
                    };
                    self.grip = GripState::Positioning;
                    let speed = self.cfg.homing_speed_mm_per_s;
                    out.push(self.start_from(session, id, MotionKind::Homing, from, target, speed));
                }
            },
            Command::PrePosition {
                relative,
                width_mm,
                speed_mm_per_s,
                ..
            } => {
                let target = if relative {
                    self.width_mm() + width_mm
                } else {
                    width_mm
                };
                match self.check_motion_to(session, id, target) {
                    Err(e) => out.push(e),
                    Ok(()) => {
                        self.grip = GripState::Positioning;
                        let kind = MotionKind::PrePosition;
                        out.push(self.start(session, id, kind, target, speed_mm_per_s));
                    }
                }
            }
            Command::Grasp {
                width_mm,
                speed_mm_per_s,
            } => match self.check_motion_to(session, id, width_mm) {
                Err(e) => out.push(e),
                Ok(()) => {
                    self.stats.total = self.stats.total.saturating_add(1);
                    let here = self.width_mm();
                    let part = self
                        .cfg
                        .part
                        .filter(|p| (p.width_mm - width_mm).abs() <= p.tolerance_mm);
                    let (found, end) = match part {
                        Some(p) => (true, p.width_mm),
                        None if width_mm <= here => (false, width_mm - self.cfg.clamping_travel_mm),
                        None => (false, width_mm + self.cfg.clamping_travel_mm),
                    };
                    self.grip = GripState::Grasping;
                    out.push(self.start(
                        session,
                        id,
                        MotionKind::Grasp { found },
                        end,
                        speed_mm_per_s,
                    ));
                }
            },
            Command::Release {
                width_mm,
                speed_mm_per_s,
            } => match self.check_motion_to(session, id, width_mm) {
                Err(e) => out.push(e),
                Ok(()) => {
                    self.grip = GripState::Releasing;
                    out.push(self.start(
                        session,
                        id,
                        MotionKind::Release,
                        width_mm,
                        speed_mm_per_s,
                    ));
                }
            },
            Command::Stop => {
                out.extend(self.abort_motion());
                self.axis_stopped = true;
                // Anhang C: a stop in any state except ERROR returns to IDLE.
                if self.grip != GripState::Error {
                    self.grip = GripState::Idle;
                }
                ok(out);
            }
            Command::FastStop => {
                out.extend(self.trigger_fast_stop());
                ok(out);
            }
            Command::AckFastStop => {
                self.fast_stop = false;
                if self.grip == GripState::Error {
                    self.grip = GripState::Idle;
                }
                ok(out);
            }
            Command::SetAcceleration(a) => {
                let l = &self.cfg.limits;
                self.acceleration =
                    a.clamp(l.min_acceleration_mm_per_s2, l.max_acceleration_mm_per_s2);
                ok(out);
            }
            Command::GetAcceleration => out.push(data(session, id, f32_bytes(self.acceleration))),
            Command::SetForce(f) => {
                self.force_limit = f.clamp(self.cfg.limits.min_force_n, self.max_force());
                ok(out);
            }
            Command::GetForce => out.push(data(session, id, f32_bytes(self.force_limit))),
            Command::SetSoftLimits(l) => {
                self.soft_limits = Some(l);
                ok(out);
            }
            Command::GetSoftLimits => match self.soft_limits {
                Some(l) => {
                    let mut b = BytesMut::new();
                    l.encode(&mut b);
                    out.push(data(session, id, b.freeze()));
                }
                None => out.push(status(session, id, Status::NotAvailable)),
            },
            Command::ClearSoftLimits => {
                self.soft_limits = None;
                ok(out);
            }
            Command::Overdrive(on) => {
                self.overdrive = on;
                self.force_limit = self.force_limit.min(self.max_force());
                ok(out);
            }
            Command::Tare => {
                let s = if !self.cfg.force_sensor {
                    Status::NotAvailable
                } else if self.grip == GripState::Holding {
                    Status::AccessDenied
                } else {
                    Status::Success
                };
                out.push(status(session, id, s));
            }
            Command::SystemState(m)
            | Command::GripState(m)
            | Command::Width(m)
            | Command::Speed(m)
            | Command::Force(m) => {
                if m.auto && m.period_ms < 10 {
                    out.push(status(session, id, Status::InvalidParameter));
                    return;
                }
                let value = self.streamed_value(id);
                if m.auto {
                    let now = wall.unwrap_or(0.0);
                    let next_due = now + f64::from(m.period_ms) / 1000.0;
                    self.streams.insert(
                        (session, id),
                        Stream {
                            mode: m,
                            next_due,
                            last: Some(value.clone()),
                        },
                    );
                } else {
                    // FLAGS bit0 clear: answer once and stop any updates (3.4.1).
                    self.streams.remove(&(session, id));
                }
                out.push(data(session, id, value));
            }
            Command::GraspingStatistics { reset } => {
                let mut b = BytesMut::new();
                self.stats.encode(&mut b);
                if reset {
                    self.stats = GraspingStatistics::default();
                }
                out.push(data(session, id, b.freeze()));
            }
            Command::Temperature => {
                let tenths = (self.cfg.temperature_c * 10.0).round() as i16;
                out.push(data(
                    session,
                    id,
                    Bytes::copy_from_slice(&tenths.to_le_bytes()),
                ));
            }
            Command::SystemInfo => {
                let mut b = BytesMut::new();
                SystemInfo {
                    device_type: self.cfg.model.device_type(),
                    hardware_revision: self.cfg.hardware_revision,
                    firmware: self.cfg.firmware,
                    serial_number: self.cfg.serial_number,
                }
                .encode(&mut b);
                out.push(data(session, id, b.freeze()));
            }
            Command::SetTag(tag) => {
                // "No special characters" (3.5.2): letters, digits, space, '-', '_', '.'.
                let plain = tag
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b" -_.".contains(&b));
                if tag.len() > MAX_TAG_LEN {
                    out.push(status(session, id, Status::Overrun));
                } else if !plain {
                    out.push(status(session, id, Status::InvalidParameter));
                } else {
                    self.tag = Some(tag);
                    ok(out);
                }
            }
            Command::GetTag => match &self.tag {
                Some(t) => out.push(data(session, id, Bytes::from(t.clone().into_bytes()))),
                None => out.push(status(session, id, Status::NotAvailable)),
            },
            Command::SystemLimits => {
                let mut b = BytesMut::new();
                self.cfg.limits.encode(&mut b);
                out.push(data(session, id, b.freeze()));
            }
            Command::FingerInfo(f) => {
                let sim = &self.cfg.fingers[finger_index(f)];
                let data_size = u16::try_from(sim.data.len()).unwrap_or(u16::MAX);
                let mut b = BytesMut::new();
                FingerInfo {
                    finger_type: sim.finger_type,
                    data_size,
                }
                .encode(&mut b);
                out.push(data(session, id, b.freeze()));
            }
            Command::FingerFlags(f) => {
                let i = finger_index(f);
                let flags = FingerFlags::empty()
                    .with(FingerFlags::POWER_ON, self.finger_powered[i])
                    .with(
                        FingerFlags::CONFIG_AVAIL,
                        self.cfg.fingers[i].finger_type != FingerType::Generic,
                    );
                let mut b = BytesMut::new();
                b.put_u16_le(flags.bits());
                out.push(data(session, id, b.freeze()));
            }
            Command::FingerPower(f, on) => {
                let i = finger_index(f);
                if self.cfg.fingers[i].finger_type != FingerType::Generic {
                    // Only generic fingers can be switched (3.6.3); the manual names no code.
                    out.push(status(session, id, Status::AccessDenied));
                } else if on {
                    self.finger_power_on[i] = Some((session, self.now + 0.5));
                    out.push(status(session, id, Status::CmdPending));
                } else {
                    self.finger_powered[i] = false;
                    ok(out);
                }
            }
            Command::FingerData(f) => {
                let d = &self.cfg.fingers[finger_index(f)].data;
                if d.is_empty() {
                    out.push(status(session, id, Status::NotAvailable));
                } else {
                    out.push(data(session, id, Bytes::from(d.clone())));
                }
            }
            // `Command` is non-exhaustive for users; every variant is handled above.
            #[allow(unreachable_patterns)]
            _ => out.push(status(session, id, Status::CmdUnknown)),
        }
    }

    fn max_force(&self) -> f32 {
        if self.overdrive {
            self.cfg.limits.overdrive_force_n
        } else {
            self.cfg.limits.nominal_force_n
        }
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

    /// How many auto-update streams are on (all sessions).
    pub fn active_streams(&self) -> usize {
        self.streams.len()
    }

    /// When the next auto-update is due (wall seconds).
    pub fn next_update_due(&self) -> Option<f64> {
        self.streams.values().map(|s| s.next_due).reduce(f64::min)
    }

    /// The auto-updates due at wall time `wall` (after [`Device::advance`] to the current
    /// simulated time). On-change streams send only when the value moved by the manual's
    /// threshold (3.4.4–3.4.6: 0.01 mm, 0.05 mm/s, 0.05 N; any change of flags or state).
    pub fn updates_due(&mut self, wall: f64) -> Vec<Out> {
        let due: Vec<(SessionId, u8)> = self
            .streams
            .iter()
            .filter(|(_, s)| s.next_due <= wall)
            .map(|(k, _)| *k)
            .collect();
        let mut out = Vec::new();
        for (session, id) in due {
            let value = self.streamed_value(id);
            let Some(s) = self.streams.get_mut(&(session, id)) else {
                continue;
            };
            let period = f64::from(s.mode.period_ms) / 1000.0;
            // Never fall behind by more than one period (no bursts after a stall).
            s.next_due = (s.next_due + period).max(wall);
            let changed = match &s.last {
                None => true,
                Some(last) => changed(id, last, &value),
            };
            if !s.mode.on_change || changed {
                s.last = Some(value.clone());
                out.push(data(session, id, value));
            }
        }
        out
    }
}

fn finger_index(f: Finger) -> usize {
    match f {
        Finger::One => 0,
        Finger::Two => 1,
    }
}

fn changed(id: u8, last: &[u8], now: &[u8]) -> bool {
    let threshold = match id {
        id::WIDTH => 0.01,
        id::SPEED | id::FORCE => 0.05,
        _ => return last != now,
    };
    match (
        crate::wsg::types::decode_f32(last),
        crate::wsg::types::decode_f32(now),
    ) {
        (Ok(a), Ok(b)) => (a - b).abs() >= threshold,
        _ => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let o = d.handle(0.0, 1, &Decoded::Corrupt { id: 0x43, len: 3 });
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
        assert!(d.updates_due(0.02).is_empty(), "nothing changed");
        cmd(&mut d, 0.0, Command::Homing(HomingDirection::Default));
        let o = d.updates_due(0.04);
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

    #[test]
    fn trapezoid_reaches_its_end() {
        let p = Profile::new(0.0, 100.0, 50.0, 100.0);
        assert!((p.total - 2.5).abs() < 1e-9, "{}", p.total);
        assert_eq!(p.position(p.total), 100.0);
        assert!((p.speed(1.0) - 50.0).abs() < 1e-4);
        let short = Profile::new(10.0, 9.0, 400.0, 100.0);
        assert!((short.total - 0.2).abs() < 1e-9);
        assert_eq!(short.position(1.0), 9.0);
    }
}
