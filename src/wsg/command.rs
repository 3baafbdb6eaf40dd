//! Typed commands (manual chapter 3) and replies (manual 1.2.2, 1.3).

use std::time::Duration;

use bytes::{BufMut, Bytes, BytesMut};

use super::frame::Frame;
use super::types::{Finger, Reader, SoftLimits};
use super::Status;

/// Command ids of the manual (chapter 3).
pub mod id {
    /// 3.1.1 Loop.
    pub const LOOP: u8 = 0x06;
    /// 3.1.2 Announce disconnect.
    pub const ANNOUNCE_DISCONNECT: u8 = 0x07;
    /// 3.2.1 Homing.
    pub const HOMING: u8 = 0x20;
    /// 3.2.2 Pre-position fingers.
    pub const PRE_POSITION: u8 = 0x21;
    /// 3.2.3 Stop.
    pub const STOP: u8 = 0x22;
    /// 3.2.4 Fast stop.
    pub const FAST_STOP: u8 = 0x23;
    /// 3.2.5 Acknowledge fast stop or fault.
    pub const ACK_FAST_STOP: u8 = 0x24;
    /// 3.2.6 Grasp part.
    pub const GRASP: u8 = 0x25;
    /// 3.2.7 Release part.
    pub const RELEASE: u8 = 0x26;
    /// 3.3.1 Set acceleration.
    pub const SET_ACCELERATION: u8 = 0x30;
    /// 3.3.2 Get acceleration.
    pub const GET_ACCELERATION: u8 = 0x31;
    /// 3.3.3 Set grasping force.
    pub const SET_FORCE: u8 = 0x32;
    /// 3.3.4 Get grasping force.
    pub const GET_FORCE: u8 = 0x33;
    /// 3.3.5 Set soft limits.
    pub const SET_SOFT_LIMITS: u8 = 0x34;
    /// 3.3.6 Get soft limits.
    pub const GET_SOFT_LIMITS: u8 = 0x35;
    /// 3.3.7 Clear soft limits.
    pub const CLEAR_SOFT_LIMITS: u8 = 0x36;
    /// 3.3.8 Overdrive mode.
    pub const OVERDRIVE: u8 = 0x37;
    /// 3.3.9 Tare force sensor.
    pub const TARE: u8 = 0x38;
    /// 3.4.1 Get system state.
    pub const SYSTEM_STATE: u8 = 0x40;
    /// 3.4.2 Get grip state.
    pub const GRIP_STATE: u8 = 0x41;
    /// 3.4.3 Get grasping statistics (the manual's "40h" is a misprint).
    pub const GRASPING_STATISTICS: u8 = 0x42;
    /// 3.4.4 Get opening width.
    pub const WIDTH: u8 = 0x43;
    /// 3.4.5 Get finger speed.
    pub const SPEED: u8 = 0x44;
    /// 3.4.6 Get finger force.
    pub const FORCE: u8 = 0x45;
    /// 3.4.7 Get temperature.
    pub const TEMPERATURE: u8 = 0x46;
    /// 3.5.1 Get system information.
    pub const SYSTEM_INFO: u8 = 0x50;
    /// 3.5.2 Set device tag.
    pub const SET_TAG: u8 = 0x51;
    /// 3.5.3 Get device tag.
    pub const GET_TAG: u8 = 0x52;
    /// 3.5.4 Get system limits.
    pub const SYSTEM_LIMITS: u8 = 0x53;
    /// 3.6.1 Finger 1 info (finger 2: 0x70).
    pub const FINGER1_INFO: u8 = 0x60;
    /// 3.6.2 Finger 1 flags (finger 2: 0x71).
    pub const FINGER1_FLAGS: u8 = 0x61;
    /// 3.6.3 Finger 1 power (finger 2: 0x72).
    pub const FINGER1_POWER: u8 = 0x62;
    /// 3.6.4 Finger 1 data (finger 2: 0x73).
    pub const FINGER1_DATA: u8 = 0x63;
    /// 3.6.5 Finger 2 info.
    pub const FINGER2_INFO: u8 = 0x70;
    /// 3.6.6 Finger 2 flags.
    pub const FINGER2_FLAGS: u8 = 0x71;
    /// 3.6.7 Finger 2 power.
    pub const FINGER2_POWER: u8 = 0x72;
    /// 3.6.8 Finger 2 data.
    pub const FINGER2_DATA: u8 = 0x73;

    /// The ids that support auto-update (3.4.1, 3.4.2, 3.4.4..3.4.6).
    pub const STREAMABLE: [u8; 5] = [SYSTEM_STATE, GRIP_STATE, WIDTH, SPEED, FORCE];
}

/// Homing direction (manual 3.2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum HomingDirection {
    /// 0: the direction configured on the device.
    #[default]
    Default,
    /// 1: positive direction (outwards).
    Positive,
    /// 2: negative direction (inwards).
    Negative,
}

/// Largest loop payload (manual 3.1.1).
pub const MAX_LOOP_LEN: usize = 256;
/// Longest device tag (manual 3.5.2).
pub const MAX_TAG_LEN: usize = 64;
/// Shortest auto-update period (manual 3.4.1).
pub const MIN_UPDATE_PERIOD: Duration = Duration::from_millis(10);

/// The FLAGS/PERIOD_MS parameters of 0x40, 0x41, 0x43, 0x44, 0x45 (manual 3.4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct UpdateMode {
    /// D0: send updates automatically.
    pub auto: bool,
    /// D1: only when the value changes (the period is still the minimum spacing).
    pub on_change: bool,
    /// The period in ms (at least 10 when `auto`).
    pub period_ms: u16,
}

impl UpdateMode {
    /// One reply, no updates (what a plain query sends).
    pub const ONCE: UpdateMode = UpdateMode {
        auto: false,
        on_change: false,
        period_ms: 0,
    };

    fn flags(self) -> u8 {
        u8::from(self.auto) | u8::from(self.on_change) << 1
    }
}

/// A command with its parameters: every command of the manual's chapter 3.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Command {
    /// 0x06: echo up to 256 bytes.
    Loop(Bytes),
    /// 0x07: announce the disconnect (TCP), so closing does not trigger FAST STOP.
    AnnounceDisconnect,
    /// 0x20: homing (asynchronous).
    Homing(HomingDirection),
    /// 0x21: pre-position the fingers (asynchronous).
    PrePosition {
        /// D0: the width is relative to the current position.
        relative: bool,
        /// D1: stop on block (else clamp with 50 % of the nominal force).
        stop_on_block: bool,
        /// Target width (or distance when relative), mm.
        width_mm: f32,
        /// Speed, mm/s.
        speed_mm_per_s: f32,
    },
    /// 0x22: stop.
    Stop,
    /// 0x23: fast stop.
    FastStop,
    /// 0x24: acknowledge a fast stop (sends "ack").
    AckFastStop,
    /// 0x25: grasp a part (asynchronous).
    Grasp {
        /// Nominal part width, mm.
        width_mm: f32,
        /// Grasping speed, mm/s.
        speed_mm_per_s: f32,
    },
    /// 0x26: release a part (asynchronous).
    Release {
        /// Opening width, mm.
        width_mm: f32,
        /// Opening speed, mm/s.
        speed_mm_per_s: f32,
    },
    /// 0x30: set the acceleration, mm/s².
    SetAcceleration(f32),
    /// 0x31: get the acceleration.
    GetAcceleration,
    /// 0x32: set the grasping force, N.
    SetForce(f32),
    /// 0x33: get the grasping force limit.
    GetForce,
    /// 0x34: set soft limits.
    SetSoftLimits(SoftLimits),
    /// 0x35: get soft limits.
    GetSoftLimits,
    /// 0x36: clear soft limits.
    ClearSoftLimits,
    /// 0x37: overdrive mode on/off.
    Overdrive(bool),
    /// 0x38: tare the force sensor.
    Tare,
    /// 0x40: system state.
    SystemState(UpdateMode),
    /// 0x41: grip state.
    GripState(UpdateMode),
    /// 0x42: grasping statistics, optionally resetting them after reading.
    GraspingStatistics {
        /// D0: reset after reading.
        reset: bool,
    },
    /// 0x43: opening width.
    Width(UpdateMode),
    /// 0x44: finger speed.
    Speed(UpdateMode),
    /// 0x45: finger force.
    Force(UpdateMode),
    /// 0x46: temperature.
    Temperature,
    /// 0x50: system information.
    SystemInfo,
    /// 0x51: set the device tag (ASCII, at most 64 characters).
    SetTag(String),
    /// 0x52: get the device tag.
    GetTag,
    /// 0x53: system limits.
    SystemLimits,
    /// 0x60 / 0x70: finger info.
    FingerInfo(Finger),
    /// 0x61 / 0x71: finger flags.
    FingerFlags(Finger),
    /// 0x62 / 0x72: finger power (switching on is asynchronous).
    FingerPower(Finger, bool),
    /// 0x63 / 0x73: finger data.
    FingerData(Finger),
}

impl Command {
    /// The command id.
    pub fn id(&self) -> u8 {
        match self {
            Command::Loop(_) => id::LOOP,
            Command::AnnounceDisconnect => id::ANNOUNCE_DISCONNECT,
            Command::Homing(_) => id::HOMING,
            Command::PrePosition { .. } => id::PRE_POSITION,
            Command::Stop => id::STOP,
            Command::FastStop => id::FAST_STOP,
            Command::AckFastStop => id::ACK_FAST_STOP,
            Command::Grasp { .. } => id::GRASP,
            Command::Release { .. } => id::RELEASE,
            Command::SetAcceleration(_) => id::SET_ACCELERATION,
            Command::GetAcceleration => id::GET_ACCELERATION,
            Command::SetForce(_) => id::SET_FORCE,
            Command::GetForce => id::GET_FORCE,
            Command::SetSoftLimits(_) => id::SET_SOFT_LIMITS,
            Command::GetSoftLimits => id::GET_SOFT_LIMITS,
            Command::ClearSoftLimits => id::CLEAR_SOFT_LIMITS,
            Command::Overdrive(_) => id::OVERDRIVE,
            Command::Tare => id::TARE,
            Command::SystemState(_) => id::SYSTEM_STATE,
            Command::GripState(_) => id::GRIP_STATE,
            Command::GraspingStatistics { .. } => id::GRASPING_STATISTICS,
            Command::Width(_) => id::WIDTH,
            Command::Speed(_) => id::SPEED,
            Command::Force(_) => id::FORCE,
            Command::Temperature => id::TEMPERATURE,
            Command::SystemInfo => id::SYSTEM_INFO,
            Command::SetTag(_) => id::SET_TAG,
            Command::GetTag => id::GET_TAG,
            Command::SystemLimits => id::SYSTEM_LIMITS,
            Command::FingerInfo(f) => f.base_id(),
            Command::FingerFlags(f) => f.base_id() + 1,
            Command::FingerPower(f, _) => f.base_id() + 2,
            Command::FingerData(f) => f.base_id() + 3,
        }
    }

    /// Whether the device answers E_CMD_PENDING first and the result later (manual 1.3):
    /// homing, pre-position, grasp, release, and switching finger power on.
    pub fn is_async(&self) -> bool {
        matches!(
            self,
            Command::Homing(_)
                | Command::PrePosition { .. }
                | Command::Grasp { .. }
                | Command::Release { .. }
                | Command::FingerPower(_, true)
        )
    }

    /// Checks the arguments against the protocol's limits (not the device's motion limits,
    /// which the device enforces itself).
    pub fn validate(&self) -> Result<(), String> {
        self.check_finite_arguments()?;
        match self {
            Command::Loop(data) if data.len() > MAX_LOOP_LEN => Err(format!(
                "loop data of {} bytes exceeds {MAX_LOOP_LEN}",
                data.len()
            )),
            Command::SetTag(tag) => {
                if tag.len() > MAX_TAG_LEN {
                    Err(format!(
                        "tag of {} characters exceeds {MAX_TAG_LEN}",
                        tag.len()
                    ))
                } else if !tag.bytes().all(|b| b.is_ascii_graphic() || b == b' ') {
                    Err("tag must be printable ASCII".into())
                } else {
                    Ok(())
                }
            }
            Command::SystemState(m)
            | Command::GripState(m)
            | Command::Width(m)
            | Command::Speed(m)
            | Command::Force(m)
                if m.auto && u128::from(m.period_ms) < MIN_UPDATE_PERIOD.as_millis() =>
            {
                Err(format!(
                    "auto-update period of {} ms is below 10 ms",
                    m.period_ms
                ))
            }
            _ => Ok(()),
        }
    }

    /// Refuses a NaN or infinite float parameter (widths, speeds, acceleration, force, soft
    /// limits: the float parameters of 3.2 and 3.3), naming the first one found.
    ///
    /// Shared by [`Command::validate`] (the client refuses before sending) and the simulator
    /// (which answers `E_RANGE_ERROR`), so the two agree on which floats are checked.
    pub(crate) fn check_finite_arguments(&self) -> Result<(), String> {
        let finite = |name: &str, v: f32| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("{name} must be a finite number, got {v}"))
            }
        };
        match self {
            Command::PrePosition {
                width_mm,
                speed_mm_per_s,
                ..
            }
            | Command::Grasp {
                width_mm,
                speed_mm_per_s,
            }
            | Command::Release {
                width_mm,
                speed_mm_per_s,
            } => {
                finite("width_mm", *width_mm)?;
                finite("speed_mm_per_s", *speed_mm_per_s)
            }
            Command::SetAcceleration(v) => finite("acceleration", *v),
            Command::SetForce(v) => finite("force", *v),
            Command::SetSoftLimits(l) => {
                finite("minus_mm", l.minus_mm)?;
                finite("plus_mm", l.plus_mm)
            }
            _ => Ok(()),
        }
    }

    /// Appends the parameters (the frame payload) to `dst`.
    pub fn encode_payload(&self, dst: &mut BytesMut) {
        match self {
            Command::Loop(data) => dst.put_slice(data),
            Command::Homing(dir) => dst.put_u8(match dir {
                HomingDirection::Default => 0,
                HomingDirection::Positive => 1,
                HomingDirection::Negative => 2,
            }),
            Command::PrePosition {
                relative,
                stop_on_block,
                width_mm,
                speed_mm_per_s,
            } => {
                dst.put_u8(u8::from(*relative) | u8::from(*stop_on_block) << 1);
                dst.put_f32_le(*width_mm);
                dst.put_f32_le(*speed_mm_per_s);
            }
            Command::AckFastStop => dst.put_slice(b"ack"),
            Command::Grasp {
                width_mm,
                speed_mm_per_s,
            }
            | Command::Release {
                width_mm,
                speed_mm_per_s,
            } => {
                dst.put_f32_le(*width_mm);
                dst.put_f32_le(*speed_mm_per_s);
            }
            Command::SetAcceleration(v) | Command::SetForce(v) => dst.put_f32_le(*v),
            Command::SetSoftLimits(l) => l.encode(dst),
            Command::Overdrive(on) => dst.put_u8(u8::from(*on)),
            Command::SystemState(m)
            | Command::GripState(m)
            | Command::Width(m)
            | Command::Speed(m)
            | Command::Force(m) => {
                dst.put_u8(m.flags());
                dst.put_u16_le(m.period_ms);
            }
            Command::GraspingStatistics { reset } => dst.put_u8(u8::from(*reset)),
            Command::SetTag(tag) => dst.put_slice(tag.as_bytes()),
            Command::FingerPower(_, on) => dst.put_u8(u8::from(*on)),
            Command::AnnounceDisconnect
            | Command::Stop
            | Command::FastStop
            | Command::GetAcceleration
            | Command::GetForce
            | Command::GetSoftLimits
            | Command::ClearSoftLimits
            | Command::Tare
            | Command::Temperature
            | Command::SystemInfo
            | Command::GetTag
            | Command::SystemLimits
            | Command::FingerInfo(_)
            | Command::FingerFlags(_)
            | Command::FingerData(_) => {}
        }
    }

    /// The command as a frame.
    pub fn to_frame(&self) -> Frame {
        let mut b = BytesMut::new();
        self.encode_payload(&mut b);
        Frame::new(self.id(), b.freeze())
    }

    /// Parses a received command (what a device does). The error is the status a device
    /// answers: E_CMD_UNKNOWN for an id it does not know, E_NO_PARAM_EXPECTED,
    /// E_CMD_FORMAT_ERROR for wrong parameters, E_INVALID_PARAMETER for out-of-range enums.
    pub fn parse(frame: &Frame) -> Result<Command, Status> {
        let p = &frame.payload[..];
        let none = |c: Command| {
            if p.is_empty() {
                Ok(c)
            } else {
                Err(Status::NoParamExpected)
            }
        };
        let fmt = |_| Status::CmdFormatError;
        let mut r = Reader::new(p);
        let two_floats = |r: &mut Reader<'_>| -> Result<(f32, f32), Status> {
            let a = r.f32().map_err(fmt)?;
            let b = r.f32().map_err(fmt)?;
            Ok((a, b))
        };
        let update = |r: &mut Reader<'_>| -> Result<UpdateMode, Status> {
            let flags = r.u8().map_err(fmt)?;
            let period_ms = r.u16().map_err(fmt)?;
            Ok(UpdateMode {
                auto: flags & 1 != 0,
                on_change: flags & 2 != 0,
                period_ms,
            })
        };
        let cmd = match frame.id {
            id::LOOP => {
                if p.len() > MAX_LOOP_LEN {
                    return Err(Status::CmdFormatError);
                }
                return Ok(Command::Loop(frame.payload.clone()));
            }
            id::ANNOUNCE_DISCONNECT => return none(Command::AnnounceDisconnect),
            id::HOMING => {
                // The manual lists the direction byte; accept its absence as "default".
                let dir = if p.is_empty() {
                    0
                } else {
                    r.u8().map_err(fmt)?
                };
                Command::Homing(match dir {
                    0 => HomingDirection::Default,
                    1 => HomingDirection::Positive,
                    2 => HomingDirection::Negative,
                    _ => return Err(Status::InvalidParameter),
                })
            }
            id::PRE_POSITION => {
                let flags = r.u8().map_err(fmt)?;
                let (width_mm, speed_mm_per_s) = two_floats(&mut r)?;
                Command::PrePosition {
                    relative: flags & 1 != 0,
                    stop_on_block: flags & 2 != 0,
                    width_mm,
                    speed_mm_per_s,
                }
            }
            id::STOP => return none(Command::Stop),
            id::FAST_STOP => return none(Command::FastStop),
            id::ACK_FAST_STOP => {
                return if p == b"ack" {
                    Ok(Command::AckFastStop)
                } else {
                    Err(Status::CmdFormatError)
                }
            }
            id::GRASP => {
                let (width_mm, speed_mm_per_s) = two_floats(&mut r)?;
                Command::Grasp {
                    width_mm,
                    speed_mm_per_s,
                }
            }
            id::RELEASE => {
                let (width_mm, speed_mm_per_s) = two_floats(&mut r)?;
                Command::Release {
                    width_mm,
                    speed_mm_per_s,
                }
            }
            id::SET_ACCELERATION => Command::SetAcceleration(r.f32().map_err(fmt)?),
            id::GET_ACCELERATION => return none(Command::GetAcceleration),
            id::SET_FORCE => Command::SetForce(r.f32().map_err(fmt)?),
            id::GET_FORCE => return none(Command::GetForce),
            id::SET_SOFT_LIMITS => {
                let (minus_mm, plus_mm) = two_floats(&mut r)?;
                Command::SetSoftLimits(SoftLimits { minus_mm, plus_mm })
            }
            id::GET_SOFT_LIMITS => return none(Command::GetSoftLimits),
            id::CLEAR_SOFT_LIMITS => return none(Command::ClearSoftLimits),
            id::OVERDRIVE => Command::Overdrive(r.u8().map_err(fmt)? & 1 != 0),
            id::TARE => return none(Command::Tare),
            id::SYSTEM_STATE => Command::SystemState(update(&mut r)?),
            id::GRIP_STATE => Command::GripState(update(&mut r)?),
            id::GRASPING_STATISTICS => Command::GraspingStatistics {
                reset: r.u8().map_err(fmt)? & 1 != 0,
            },
            id::WIDTH => Command::Width(update(&mut r)?),
            id::SPEED => Command::Speed(update(&mut r)?),
            id::FORCE => Command::Force(update(&mut r)?),
            id::TEMPERATURE => return none(Command::Temperature),
            id::SYSTEM_INFO => return none(Command::SystemInfo),
            id::SET_TAG => {
                if p.len() > MAX_TAG_LEN {
                    return Err(Status::Overrun);
                }
                let tag = std::str::from_utf8(p).map_err(|_| Status::InvalidParameter)?;
                return Ok(Command::SetTag(tag.to_owned()));
            }
            id::GET_TAG => return none(Command::GetTag),
            id::SYSTEM_LIMITS => return none(Command::SystemLimits),
            0x60..=0x63 | 0x70..=0x73 => {
                let finger = if frame.id < 0x70 {
                    Finger::One
                } else {
                    Finger::Two
                };
                // 3.6.1, 3.6.2, 3.6.4 take no parameters but, unlike the other commands
                // without any, list E_CMD_FORMAT_ERROR (not E_NO_PARAM_EXPECTED) for them.
                let no_param = |c: Command| {
                    if p.is_empty() {
                        Ok(c)
                    } else {
                        Err(Status::CmdFormatError)
                    }
                };
                match frame.id & 0x0F {
                    0 => return no_param(Command::FingerInfo(finger)),
                    1 => return no_param(Command::FingerFlags(finger)),
                    2 => match r.u8().map_err(fmt)? {
                        0 => Command::FingerPower(finger, false),
                        1 => Command::FingerPower(finger, true),
                        _ => return Err(Status::InvalidParameter),
                    },
                    _ => return no_param(Command::FingerData(finger)),
                }
            }
            _ => return Err(Status::CmdUnknown),
        };
        r.end().map_err(fmt)?;
        Ok(cmd)
    }
}

/// A reply from the device: the command id, the status code and (only with E_SUCCESS) data
/// (manual 1.2.2).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// The id of the command answered.
    pub id: u8,
    /// The status code.
    pub status: Status,
    /// The data after the status code (empty unless the status is E_SUCCESS).
    pub data: Bytes,
}

impl Reply {
    /// A reply with status and data.
    pub fn new(id: u8, status: Status, data: impl Into<Bytes>) -> Self {
        Self {
            id,
            status,
            data: data.into(),
        }
    }

    /// Splits a received frame into status and data. Fails when the payload is shorter than
    /// the status code.
    pub fn from_frame(frame: Frame) -> Result<Reply, String> {
        let Frame { id, mut payload } = frame;
        if payload.len() < 2 {
            return Err(format!(
                "reply of {} bytes has no status code",
                payload.len()
            ));
        }
        let status = Status::from_code(u16::from_le_bytes([payload[0], payload[1]]));
        let data = payload.split_off(2);
        Ok(Reply { id, status, data })
    }

    /// The reply as a frame.
    pub fn to_frame(&self) -> Frame {
        let mut b = BytesMut::with_capacity(2 + self.data.len());
        b.put_u16_le(self.status.code());
        b.put_slice(&self.data);
        Frame::new(self.id, b.freeze())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(f: &Frame) -> Vec<u8> {
        let mut b = BytesMut::new();
        crate::wsg::frame::encode(f, &mut b).unwrap();
        b.to_vec()
    }

    #[test]
    fn computed_vectors_of_protocols_md() {
        assert_eq!(
            hex(&Command::Homing(HomingDirection::Default).to_frame()),
            [0xAA, 0xAA, 0xAA, 0x20, 0x01, 0x00, 0x00, 0x8F, 0x83]
        );
        assert_eq!(
            hex(&Command::Grasp {
                width_mm: 20.0,
                speed_mm_per_s: 50.0
            }
            .to_frame()),
            [
                0xAA, 0xAA, 0xAA, 0x25, 0x08, 0x00, 0x00, 0x00, 0xA0, 0x41, 0x00, 0x00, 0x48, 0x42,
                0xAA, 0x1E
            ]
        );
        assert_eq!(
            hex(&Command::PrePosition {
                relative: false,
                stop_on_block: true,
                width_mm: 35.5,
                speed_mm_per_s: 40.0
            }
            .to_frame()),
            [
                0xAA, 0xAA, 0xAA, 0x21, 0x09, 0x00, 0x02, 0x00, 0x00, 0x0E, 0x42, 0x00, 0x00, 0x20,
                0x42, 0xBA, 0x3C
            ]
        );
        assert_eq!(
            hex(&Command::AckFastStop.to_frame()),
            [0xAA, 0xAA, 0xAA, 0x24, 0x03, 0x00, 0x61, 0x63, 0x6B, 0xDC, 0xB9]
        );
        assert_eq!(
            hex(&Command::Width(UpdateMode {
                auto: true,
                on_change: true,
                period_ms: 50
            })
            .to_frame()),
            [0xAA, 0xAA, 0xAA, 0x43, 0x03, 0x00, 0x03, 0x32, 0x00, 0x58, 0xAD]
        );
        assert_eq!(
            hex(&Command::AnnounceDisconnect.to_frame()),
            [0xAA, 0xAA, 0xAA, 0x07, 0x00, 0x00, 0x35, 0x4C]
        );
    }

    #[test]
    fn replies_of_the_manual() {
        let r = Reply::from_frame(Frame::new(0x90, vec![0x0E, 0x00])).unwrap();
        assert_eq!(r.status, Status::CmdUnknown);
        let r = Reply::from_frame(Frame::new(0x30, vec![0, 0, 0, 0, 0x16, 0x43])).unwrap();
        assert_eq!(crate::wsg::types::decode_f32(&r.data).unwrap(), 150.0);
        assert!(Reply::from_frame(Frame::new(0x30, vec![0])).is_err());
    }

    #[test]
    fn parse_refuses_bad_parameters() {
        assert_eq!(
            Command::parse(&Frame::new(0x90, vec![])),
            Err(Status::CmdUnknown)
        );
        assert_eq!(
            Command::parse(&Frame::new(0x22, vec![1])),
            Err(Status::NoParamExpected)
        );
        assert_eq!(
            Command::parse(&Frame::new(0x25, vec![1, 2])),
            Err(Status::CmdFormatError)
        );
        assert_eq!(
            Command::parse(&Frame::new(0x24, b"ACK".to_vec())),
            Err(Status::CmdFormatError)
        );
        assert_eq!(
            Command::parse(&Frame::new(0x06, vec![0; 257])),
            Err(Status::CmdFormatError)
        );
        // The finger queries list E_CMD_FORMAT_ERROR, not E_NO_PARAM_EXPECTED (3.6.1-3.6.4).
        for id in [0x60, 0x61, 0x63, 0x70, 0x71, 0x73] {
            assert_eq!(
                Command::parse(&Frame::new(id, vec![1])),
                Err(Status::CmdFormatError),
                "{id:#04x}"
            );
            assert!(Command::parse(&Frame::new(id, vec![])).is_ok(), "{id:#04x}");
        }
    }

    fn every_command() -> Vec<Command> {
        let m = UpdateMode {
            auto: true,
            on_change: false,
            period_ms: 20,
        };
        vec![
            Command::Loop(Bytes::from_static(b"hello")),
            Command::AnnounceDisconnect,
            Command::Homing(HomingDirection::Negative),
            Command::PrePosition {
                relative: true,
                stop_on_block: false,
                width_mm: -3.0,
                speed_mm_per_s: 10.0,
            },
            Command::Stop,
            Command::FastStop,
            Command::AckFastStop,
            Command::Grasp {
                width_mm: 1.0,
                speed_mm_per_s: 2.0,
            },
            Command::Release {
                width_mm: 3.0,
                speed_mm_per_s: 4.0,
            },
            Command::SetAcceleration(100.0),
            Command::GetAcceleration,
            Command::SetForce(20.0),
            Command::GetForce,
            Command::SetSoftLimits(SoftLimits {
                minus_mm: 1.0,
                plus_mm: 2.0,
            }),
            Command::GetSoftLimits,
            Command::ClearSoftLimits,
            Command::Overdrive(true),
            Command::Tare,
            Command::SystemState(m),
            Command::GripState(UpdateMode::ONCE),
            Command::GraspingStatistics { reset: true },
            Command::Width(m),
            Command::Speed(m),
            Command::Force(m),
            Command::Temperature,
            Command::SystemInfo,
            Command::SetTag("cell 4".into()),
            Command::GetTag,
            Command::SystemLimits,
            Command::FingerInfo(Finger::One),
            Command::FingerFlags(Finger::Two),
            Command::FingerPower(Finger::Two, true),
            Command::FingerData(Finger::One),
        ]
    }

    #[test]
    fn every_command_round_trips_through_parse() {
        for c in every_command() {
            assert_eq!(Command::parse(&c.to_frame()), Ok(c.clone()), "{c:?}");
            assert!(c.validate().is_ok());
        }
    }
}
