//! Command handling (manual chapter 3): what each command does to the simulated gripper and
//! what it answers. Motion commands start a [`Motion`](super::motion::Motion); their final reply
//! comes from [`Device::advance`] or from whatever aborts them (stop, FAST STOP, 0x07, a lost
//! TCP connection).

use bytes::{BufMut, Bytes, BytesMut};

use super::device::{data, f32_bytes, status, Device, Out, PowerOn, SessionId, SessionKind};
use super::motion::{Motion, MotionKind, Profile};
use crate::wsg::command::{Command, HomingDirection, MAX_TAG_LEN};
use crate::wsg::{
    Finger, FingerFlags, FingerInfo, FingerType, GraspingStatistics, GripState, Status, SystemInfo,
};

impl Device {
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
            settle: self.cfg.final_reply_lag.as_secs_f64(),
        });
        self.axis_stopped = false;
        self.target_reached = false;
        self.cmd_failure = false;
        status(session, command, Status::CmdPending)
    }

    /// Stops the current motion where it is; returns the E_CMD_ABORTED for its caller.
    pub(super) fn abort_motion(&mut self) -> Option<Out> {
        let m = self.motion.take()?;
        self.position_mm = m.profile.position(self.now - m.start);
        Some(status(m.session, m.command, Status::CmdAborted))
    }

    pub(super) fn trigger_fast_stop(&mut self) -> Option<Out> {
        self.fast_stop = true;
        self.grip = GripState::Error;
        self.abort_motion()
    }

    pub(super) fn execute(
        &mut self,
        session: SessionId,
        wall: Option<f64>,
        cmd: Command,
        out: &mut Vec<Out>,
    ) {
        let id = cmd.id();
        let ok = |out: &mut Vec<Out>| out.push(status(session, id, Status::Success));
        match cmd {
            Command::Loop(d) => out.push(data(session, id, d)),
            Command::AnnounceDisconnect => {
                if self.sessions.kind(session) == Some(SessionKind::Tcp) {
                    // "All running finger movements are stopped immediately" (3.1.2): a stop,
                    // which returns to IDLE in any state except ERROR (Anhang C) as STOP does.
                    // Before, a motion stopped so left the grip state POSITIONING for good: a
                    // client checking an overdue motion with GRIPSTATE? was told it still ran
                    // (wsg-text:0x8febd7af0c4e9b77, another connection's BYE() during HOME).
                    let aborted = self.abort_motion();
                    if aborted.is_some() && self.grip != GripState::Error {
                        self.grip = GripState::Idle;
                    }
                    out.extend(aborted);
                    self.sessions.announce(session);
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
                        // A part between the fingers stops a move that closes past it (3.2.2),
                        // also one that starts on it (fingers holding it).
                        let here = self.width_mm();
                        let part = self.cfg.part.filter(|p| {
                            self.cfg.part_blocks_motion && here >= p.width_mm && target < p.width_mm
                        });
                        let (kind, end) = match part {
                            Some(p) => (MotionKind::PrePosition { blocked: true }, p.width_mm),
                            None => (MotionKind::PrePosition { blocked: false }, target),
                        };
                        out.push(self.start(session, id, kind, end, speed_mm_per_s));
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
                out.push(self.auto_update(session, id, m, wall.unwrap_or(0.0)));
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
                    // A second power-on while one is pending joins it: both are acknowledged
                    // and both get the final reply when the finger is on (1.3). The 500 ms are
                    // wall time (3.6.3: "nach etwa 500 ms"), not scaled like motion.
                    let due_wall = wall.unwrap_or(0.0)
                        + crate::wsg::client::FINGER_POWER_ON_DURATION.as_secs_f64();
                    let p = self.finger_power_on[i].get_or_insert(PowerOn {
                        due_wall,
                        owed: Vec::new(),
                    });
                    match p.owed.iter_mut().find(|(s, _)| *s == session) {
                        Some((_, n)) => *n = n.saturating_add(1),
                        None => p.owed.push((session, 1)),
                    }
                    out.push(status(session, id, Status::CmdPending));
                } else {
                    // Switching off "is carried out immediately" (3.6.3), a pending power-on
                    // included: it ends unfinished, and never switches the finger on later.
                    if let Some(p) = self.finger_power_on[i].take() {
                        out.extend(p.finish(id, Status::CmdAborted));
                    }
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

    pub(super) fn max_force(&self) -> f32 {
        if self.overdrive {
            self.cfg.limits.overdrive_force_n
        } else {
            self.cfg.limits.nominal_force_n
        }
    }
}

fn finger_index(f: Finger) -> usize {
    match f {
        Finger::One => 0,
        Finger::Two => 1,
    }
}
