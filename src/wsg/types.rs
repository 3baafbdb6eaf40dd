//! Typed reply data and parameters of the WSG commands (manual chapter 3, Anhang B and C).
//!
//! Every type that crosses the wire has `decode` (from a reply's data, never panicking) and
//! `encode` (used by the simulator and tests).

use std::fmt;

use bytes::{BufMut, BytesMut};

/// Reads little-endian fields from reply data without panicking.
#[derive(Debug)]
pub(crate) struct Reader<'a> {
    data: &'a [u8],
}

impl<'a> Reader<'a> {
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Self { data }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let (head, rest) = self
            .data
            .split_first_chunk::<N>()
            .ok_or_else(|| format!("needs {N} more bytes, has {}", self.data.len()))?;
        self.data = rest;
        Ok(*head)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take::<1>()?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    pub(crate) fn i16(&mut self) -> Result<i16, String> {
        Ok(i16::from_le_bytes(self.take()?))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    pub(crate) fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take()?))
    }
    /// Fails when bytes are left over: a reply with the wrong length is malformed.
    pub(crate) fn end(self) -> Result<(), String> {
        if self.data.is_empty() {
            Ok(())
        } else {
            Err(format!("{} unexpected trailing bytes", self.data.len()))
        }
    }
}

/// Decodes a single little-endian f32 (width, speed, force, acceleration replies).
pub(crate) fn decode_f32(data: &[u8]) -> Result<f32, String> {
    let mut r = Reader::new(data);
    let v = r.f32()?;
    r.end()?;
    Ok(v)
}

macro_rules! flag_set {
    (
        $(#[$meta:meta])*
        $name:ident($int:ty) { $( $(#[$fmeta:meta])* $flag:ident = $bit:literal; )* }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub $int);

        impl $name {
            $( $(#[$fmeta])* pub const $flag: $name = $name(1 << $bit); )*
            const NAMES: &'static [(&'static str, $int)] = &[ $( (stringify!($flag), 1 << $bit), )* ];

            /// The raw bits.
            pub const fn bits(self) -> $int {
                self.0
            }
            /// Whether every flag of `other` is set.
            pub const fn contains(self, other: $name) -> bool {
                self.0 & other.0 == other.0
            }
            /// No flag set.
            pub const fn empty() -> Self {
                $name(0)
            }
            /// `self` with the flags of `other` set (or cleared when `on` is false).
            #[must_use]
            pub const fn with(self, other: $name, on: bool) -> Self {
                if on { $name(self.0 | other.0) } else { $name(self.0 & !other.0) }
            }
        }

        impl std::ops::BitOr for $name {
            type Output = $name;
            fn bitor(self, rhs: $name) -> $name {
                $name(self.0 | rhs.0)
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}(", stringify!($name))?;
                let mut rest = self.0;
                let mut first = true;
                for (name, bit) in Self::NAMES {
                    if self.0 & bit != 0 {
                        write!(f, "{}{}", if first { "" } else { " | " }, name)?;
                        first = false;
                        rest &= !bit;
                    }
                }
                if rest != 0 {
                    write!(f, "{}{:#x}", if first { "" } else { " | " }, rest)?;
                }
                write!(f, ")")
            }
        }
    };
}

flag_set! {
    /// The system state flags (manual, Anhang B), returned by command 0x40.
    ///
    /// Reserved bits are kept as received.
    SystemState(u32) {
        /// D0: the fingers are referenced (homed) and motion commands are accepted.
        REFERENCED = 0;
        /// D1: the fingers are moving.
        MOVING = 1;
        /// D2: the axis is blocked in negative direction.
        BLOCKED_MINUS = 2;
        /// D3: the axis is blocked in positive direction.
        BLOCKED_PLUS = 3;
        /// D4: the negative soft limit is reached.
        SOFT_LIMIT_MINUS = 4;
        /// D5: the positive soft limit is reached.
        SOFT_LIMIT_PLUS = 5;
        /// D6: a motion was stopped by the stop command.
        AXIS_STOPPED = 6;
        /// D7: the target position was reached.
        TARGET_POS_REACHED = 7;
        /// D8: overdrive mode is on.
        OVERDRIVE_MODE = 8;
        /// D9: force control with force measurement fingers is active.
        FORCECNTL_MODE = 9;
        /// D12: FAST STOP; must be acknowledged (0x24).
        FAST_STOP = 12;
        /// D13: temperature warning.
        TEMP_WARNING = 13;
        /// D14: temperature fault; motion is refused.
        TEMP_FAULT = 14;
        /// D15: supply voltage out of range.
        POWER_FAULT = 15;
        /// D16: motor current too high.
        CURR_FAULT = 16;
        /// D17: a finger is faulty.
        FINGER_FAULT = 17;
        /// D18: the last command failed.
        CMD_FAILURE = 18;
        /// D19: a script is running.
        SCRIPT_RUNNING = 19;
        /// D20: a script failed.
        SCRIPT_FAILURE = 20;
    }
}

flag_set! {
    /// Finger state flags (manual 3.6.2 / 3.6.6), returned by 0x61 / 0x71.
    FingerFlags(u16) {
        /// Bit 0: the finger is powered.
        POWER_ON = 0;
        /// Bit 1: the finger provides configuration data (a smart sensor finger).
        CONFIG_AVAIL = 1;
        /// Bit 2: a command interface to the finger is open.
        COMM_OPEN = 2;
        /// Bit 8: an over-current fault was detected.
        POWER_FAULT = 8;
        /// Bit 9: a communication fault occurred.
        COMM_FAULT = 9;
    }
}

impl SystemState {
    /// Decodes the u32 of a 0x40 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let v = r.u32()?;
        r.end()?;
        Ok(SystemState(v))
    }
}

impl FingerFlags {
    /// Decodes the u16 of a 0x61/0x71 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let v = r.u16()?;
        r.end()?;
        Ok(FingerFlags(v))
    }
}

/// The grip state (manual 3.4.2 and the state diagram of Anhang C), returned by 0x41.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GripState {
    /// 0: idle, ready for commands.
    Idle,
    /// 1: closing to grasp; no part detected yet.
    Grasping,
    /// 2: closed without finding a part (until the next motion command).
    NoPartFound,
    /// 3: a grasped part was lost before release (until the next motion command).
    PartLost,
    /// 4: holding a part with the set grasping force.
    Holding,
    /// 5: opening to release a part.
    Releasing,
    /// 6: homing or pre-positioning.
    Positioning,
    /// 7: an error occurred or FAST STOP was triggered (until the next motion command; FAST STOP
    /// must be acknowledged first).
    Error,
    /// 8..=255: reserved by the manual; the number is kept.
    Reserved(u8),
}

impl GripState {
    /// The state with wire value `v`.
    pub const fn from_u8(v: u8) -> Self {
        match v {
            0 => GripState::Idle,
            1 => GripState::Grasping,
            2 => GripState::NoPartFound,
            3 => GripState::PartLost,
            4 => GripState::Holding,
            5 => GripState::Releasing,
            6 => GripState::Positioning,
            7 => GripState::Error,
            other => GripState::Reserved(other),
        }
    }

    /// The wire value.
    pub const fn to_u8(self) -> u8 {
        match self {
            GripState::Idle => 0,
            GripState::Grasping => 1,
            GripState::NoPartFound => 2,
            GripState::PartLost => 3,
            GripState::Holding => 4,
            GripState::Releasing => 5,
            GripState::Positioning => 6,
            GripState::Error => 7,
            GripState::Reserved(v) => v,
        }
    }

    /// Decodes the u8 of a 0x41 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let v = r.u8()?;
        r.end()?;
        Ok(GripState::from_u8(v))
    }
}

/// Grasping statistics (manual 3.4.3, command 0x42).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct GraspingStatistics {
    /// Grasp commands received in total.
    pub total: u32,
    /// Grasps that found no part.
    pub no_part: u16,
    /// Grasps whose part was lost before the fingers opened.
    pub lost_part: u16,
}

impl GraspingStatistics {
    /// Decodes a 0x42 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let s = Self {
            total: r.u32()?,
            no_part: r.u16()?,
            lost_part: r.u16()?,
        };
        r.end()?;
        Ok(s)
    }

    /// Encodes the reply data.
    pub fn encode(&self, dst: &mut BytesMut) {
        dst.put_u32_le(self.total);
        dst.put_u16_le(self.no_part);
        dst.put_u16_le(self.lost_part);
    }
}

/// Soft limits (manual 3.3.5, commands 0x34 / 0x35).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftLimits {
    /// Limit in negative (closing) direction, mm.
    pub minus_mm: f32,
    /// Limit in positive (opening) direction, mm.
    pub plus_mm: f32,
}

impl SoftLimits {
    /// Decodes a 0x35 reply or 0x34 parameters.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let s = Self {
            minus_mm: r.f32()?,
            plus_mm: r.f32()?,
        };
        r.end()?;
        Ok(s)
    }

    /// Encodes the two floats.
    pub fn encode(&self, dst: &mut BytesMut) {
        dst.put_f32_le(self.minus_mm);
        dst.put_f32_le(self.plus_mm);
    }
}

/// Device type of the system information (manual 3.5.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DeviceType {
    /// 0: unknown.
    Unknown,
    /// 1: WSG 50.
    Wsg50,
    /// 2: WSG 32.
    Wsg32,
    /// 3: force-torque sensor KMS 40.
    Kms40,
    /// 4: tactile sensing module WTS.
    Wts,
    /// 5: WSG 25.
    Wsg25,
    /// 6: WSG 70.
    Wsg70,
    /// A value the manual does not list.
    Other(u8),
}

impl DeviceType {
    /// The type with wire value `v`.
    pub const fn from_u8(v: u8) -> Self {
        match v {
            0 => DeviceType::Unknown,
            1 => DeviceType::Wsg50,
            2 => DeviceType::Wsg32,
            3 => DeviceType::Kms40,
            4 => DeviceType::Wts,
            5 => DeviceType::Wsg25,
            6 => DeviceType::Wsg70,
            other => DeviceType::Other(other),
        }
    }

    /// The wire value.
    pub const fn to_u8(self) -> u8 {
        match self {
            DeviceType::Unknown => 0,
            DeviceType::Wsg50 => 1,
            DeviceType::Wsg32 => 2,
            DeviceType::Kms40 => 3,
            DeviceType::Wts => 4,
            DeviceType::Wsg25 => 5,
            DeviceType::Wsg70 => 6,
            DeviceType::Other(v) => v,
        }
    }
}

/// Firmware version (manual 3.5.1): D15..12 major, D11..8 minor, D7..4 patch, D3..0
/// pre-release number (0 for a release).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FirmwareVersion(pub u16);

impl FirmwareVersion {
    /// Major version (bits 15..12).
    pub const fn major(self) -> u8 {
        (self.0 >> 12) as u8
    }
    /// Minor version (bits 11..8).
    pub const fn minor(self) -> u8 {
        ((self.0 >> 8) & 0xF) as u8
    }
    /// Patch version (bits 7..4).
    pub const fn patch(self) -> u8 {
        ((self.0 >> 4) & 0xF) as u8
    }
    /// Pre-release number (bits 3..0), 0 for a release.
    pub const fn pre_release(self) -> u8 {
        (self.0 & 0xF) as u8
    }
}

impl fmt::Display for FirmwareVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.major(), self.minor(), self.patch())?;
        if self.pre_release() != 0 {
            write!(f, "-pre{}", self.pre_release())?;
        }
        Ok(())
    }
}

/// System information (manual 3.5.1, command 0x50).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SystemInfo {
    /// The device type.
    pub device_type: DeviceType,
    /// Hardware revision.
    pub hardware_revision: u8,
    /// Firmware version.
    pub firmware: FirmwareVersion,
    /// Serial number.
    pub serial_number: u32,
}

impl SystemInfo {
    /// Decodes a 0x50 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let s = Self {
            device_type: DeviceType::from_u8(r.u8()?),
            hardware_revision: r.u8()?,
            firmware: FirmwareVersion(r.u16()?),
            serial_number: r.u32()?,
        };
        r.end()?;
        Ok(s)
    }

    /// Encodes the reply data.
    pub fn encode(&self, dst: &mut BytesMut) {
        dst.put_u8(self.device_type.to_u8());
        dst.put_u8(self.hardware_revision);
        dst.put_u16_le(self.firmware.0);
        dst.put_u32_le(self.serial_number);
    }
}

/// System limits (manual 3.5.4, command 0x53).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SystemLimits {
    /// Stroke, mm.
    pub stroke_mm: f32,
    /// Minimum speed, mm/s.
    pub min_speed_mm_per_s: f32,
    /// Maximum speed, mm/s.
    pub max_speed_mm_per_s: f32,
    /// Minimum acceleration, mm/s².
    pub min_acceleration_mm_per_s2: f32,
    /// Maximum acceleration, mm/s².
    pub max_acceleration_mm_per_s2: f32,
    /// Minimum grasping force, N.
    pub min_force_n: f32,
    /// Nominal grasping force, N.
    pub nominal_force_n: f32,
    /// Maximum grasping force in overdrive mode, N.
    pub overdrive_force_n: f32,
}

impl SystemLimits {
    /// Decodes a 0x53 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let s = Self {
            stroke_mm: r.f32()?,
            min_speed_mm_per_s: r.f32()?,
            max_speed_mm_per_s: r.f32()?,
            min_acceleration_mm_per_s2: r.f32()?,
            max_acceleration_mm_per_s2: r.f32()?,
            min_force_n: r.f32()?,
            nominal_force_n: r.f32()?,
            overdrive_force_n: r.f32()?,
        };
        r.end()?;
        Ok(s)
    }

    /// Encodes the reply data.
    pub fn encode(&self, dst: &mut BytesMut) {
        for v in [
            self.stroke_mm,
            self.min_speed_mm_per_s,
            self.max_speed_mm_per_s,
            self.min_acceleration_mm_per_s2,
            self.max_acceleration_mm_per_s2,
            self.min_force_n,
            self.nominal_force_n,
            self.overdrive_force_n,
        ] {
            dst.put_f32_le(v);
        }
    }
}

/// Which finger of the finger interface (manual 3.6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Finger {
    /// Finger 1 (commands 0x60..0x63).
    One,
    /// Finger 2 (commands 0x70..0x73).
    Two,
}

impl Finger {
    /// The id of this finger's "info" command; flags, power and data follow at +1, +2, +3.
    pub const fn base_id(self) -> u8 {
        match self {
            Finger::One => 0x60,
            Finger::Two => 0x70,
        }
    }
}

/// Finger type (manual 3.6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FingerType {
    /// 0: generic finger or no sensor finger.
    Generic,
    /// 1: WSG-FMF force measurement finger.
    Fmf,
    /// 2: WSG-DSA tactile sensing finger.
    Dsa,
    /// 3..=255: reserved; the number is kept.
    Reserved(u8),
}

impl FingerType {
    /// The type with wire value `v`.
    pub const fn from_u8(v: u8) -> Self {
        match v {
            0 => FingerType::Generic,
            1 => FingerType::Fmf,
            2 => FingerType::Dsa,
            other => FingerType::Reserved(other),
        }
    }
    /// The wire value.
    pub const fn to_u8(self) -> u8 {
        match self {
            FingerType::Generic => 0,
            FingerType::Fmf => 1,
            FingerType::Dsa => 2,
            FingerType::Reserved(v) => v,
        }
    }
}

/// Finger information (manual 3.6.1, commands 0x60 / 0x70).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FingerInfo {
    /// The finger type.
    pub finger_type: FingerType,
    /// Length of the finger's data (commands 0x63 / 0x73), 0 when it provides none.
    pub data_size: u16,
}

impl FingerInfo {
    /// Decodes a 0x60/0x70 reply.
    pub fn decode(data: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(data);
        let s = Self {
            finger_type: FingerType::from_u8(r.u8()?),
            data_size: r.u16()?,
        };
        r.end()?;
        Ok(s)
    }

    /// Encodes the reply data.
    pub fn encode(&self, dst: &mut BytesMut) {
        dst.put_u8(self.finger_type.to_u8());
        dst.put_u16_le(self.data_size);
    }
}

/// Decodes the temperature of a 0x46 reply: i16 in steps of 0.1 °C (manual 3.4.7; its example
/// "FFF5h = -1.0 °C" contradicts its other examples: FFF5h is -1.1 °C).
pub fn decode_temperature_c(data: &[u8]) -> Result<f32, String> {
    let mut r = Reader::new(data);
    let v = r.i16()?;
    r.end()?;
    Ok(f32::from(v) / 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn firmware_version_bits() {
        let v = FirmwareVersion(0x4123);
        assert_eq!(
            (v.major(), v.minor(), v.patch(), v.pre_release()),
            (4, 1, 2, 3)
        );
        assert_eq!(v.to_string(), "4.1.2-pre3");
        assert_eq!(FirmwareVersion(0x2150).to_string(), "2.1.5");
    }

    #[test]
    fn temperature_examples_of_the_manual() {
        // The manual (3.4.7) prints "FFF5h = -1.0 °C", but its other examples (FFFFh = -0.1,
        // 000Ah = 1.0) fix the encoding as two's complement tenths: FFF5h is -1.1 and -1.0 is
        // FFF6h. We follow the consistent reading.
        for (raw, c) in [
            (0xFFF6u16, -1.0f32),
            (0xFFF5, -1.1),
            (0xFFFF, -0.1),
            (0, 0.0),
            (0x0A, 1.0),
            (0xC8, 20.0),
            (0x1F4, 50.0),
            (0xEA, 23.4),
        ] {
            let got = decode_temperature_c(&raw.to_le_bytes()).unwrap();
            assert!((got - c).abs() < 1e-4, "{raw:#x}: {got} != {c}");
        }
    }

    #[test]
    fn system_state_debug_names_flags_and_keeps_reserved_bits() {
        let s = SystemState(0b11 | 1 << 30);
        assert!(s.contains(SystemState::REFERENCED | SystemState::MOVING));
        assert_eq!(
            format!("{s:?}"),
            "SystemState(REFERENCED | MOVING | 0x40000000)"
        );
        assert_eq!(SystemState::decode(&[3, 0, 0, 0]).unwrap(), SystemState(3));
        assert!(SystemState::decode(&[3, 0, 0]).is_err());
    }

    #[test]
    fn unknown_enum_values_are_kept() {
        assert_eq!(DeviceType::from_u8(9), DeviceType::Other(9));
        assert_eq!(GripState::from_u8(200), GripState::Reserved(200));
        assert_eq!(FingerType::from_u8(7).to_u8(), 7);
        assert_eq!(DeviceType::from_u8(6), DeviceType::Wsg70);
    }

    #[test]
    fn short_or_long_replies_are_errors_not_panics() {
        assert!(SystemLimits::decode(&[0; 31]).is_err());
        assert!(SystemLimits::decode(&[0; 33]).is_err());
        assert!(SystemInfo::decode(&[]).is_err());
        assert!(GraspingStatistics::decode(&[0; 8]).is_ok());
        assert!(decode_f32(&[0; 5]).is_err());
    }
}
