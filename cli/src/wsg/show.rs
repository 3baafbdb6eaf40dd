//! How the gripper's values are shown: the manual's names, text and JSON.

use gripper::wsg::types::decode_temperature_c;
use gripper::wsg::{
    GraspingStatistics, GripState, SoftLimits, Status, SystemInfo, SystemLimits, SystemState,
};
use serde_json::{json, Value};

/// A status code as JSON: the manual's symbol, number and description (Anhang A).
pub(super) fn status_json(status: Status) -> Value {
    json!({ "name": status.symbol(), "code": status.code(), "description": status.description() })
}

/// The device type as the data sheets write it.
pub(super) fn device_name(info: SystemInfo) -> String {
    use gripper::wsg::DeviceType;
    match info.device_type {
        DeviceType::Unknown => "unknown".into(),
        DeviceType::Wsg50 => "WSG 50".into(),
        DeviceType::Wsg32 => "WSG 32".into(),
        DeviceType::Kms40 => "KMS 40".into(),
        DeviceType::Wts => "WTS".into(),
        DeviceType::Wsg25 => "WSG 25".into(),
        DeviceType::Wsg70 => "WSG 70".into(),
        DeviceType::Other(n) => format!("device type {n}"),
    }
}

/// The grip state's name as the manual's state diagram writes it (Anhang C).
pub(super) fn grip_name(g: GripState) -> String {
    match g {
        GripState::Idle => "IDLE".into(),
        GripState::Grasping => "GRASPING".into(),
        GripState::NoPartFound => "NO PART FOUND".into(),
        GripState::PartLost => "PART LOST".into(),
        GripState::Holding => "HOLDING".into(),
        GripState::Releasing => "RELEASING".into(),
        GripState::Positioning => "POSITIONING".into(),
        GripState::Error => "ERROR".into(),
        GripState::Reserved(n) => format!("reserved grip state {n}"),
    }
}

pub(super) fn grip_json(g: GripState) -> Value {
    json!({ "name": grip_name(g), "code": g.to_u8() })
}

/// The system state flags with the manual's names (Anhang B).
const FLAGS: &[(SystemState, &str)] = &[
    (SystemState::REFERENCED, "SF_REFERENCED"),
    (SystemState::MOVING, "SF_MOVING"),
    (SystemState::BLOCKED_MINUS, "SF_BLOCKED_MINUS"),
    (SystemState::BLOCKED_PLUS, "SF_BLOCKED_PLUS"),
    (SystemState::SOFT_LIMIT_MINUS, "SF_SOFT_LIMIT_MINUS"),
    (SystemState::SOFT_LIMIT_PLUS, "SF_SOFT_LIMIT_PLUS"),
    (SystemState::AXIS_STOPPED, "SF_AXIS_STOPPED"),
    (SystemState::TARGET_POS_REACHED, "SF_TARGET_POS_REACHED"),
    (SystemState::OVERDRIVE_MODE, "SF_OVERDRIVE_MODE"),
    (SystemState::FORCECNTL_MODE, "SF_FORCECNTL_MODE"),
    (SystemState::FAST_STOP, "SF_FAST_STOP"),
    (SystemState::TEMP_WARNING, "SF_TEMP_WARNING"),
    (SystemState::TEMP_FAULT, "SF_TEMP_FAULT"),
    (SystemState::POWER_FAULT, "SF_POWER_FAULT"),
    (SystemState::CURR_FAULT, "SF_CURR_FAULT"),
    (SystemState::FINGER_FAULT, "SF_FINGER_FAULT"),
    (SystemState::CMD_FAILURE, "SF_CMD_FAILURE"),
    (SystemState::SCRIPT_RUNNING, "SF_SCRIPT_RUNNING"),
    (SystemState::SCRIPT_FAILURE, "SF_SCRIPT_FAILURE"),
];

pub(super) fn flag_names(state: SystemState) -> Vec<String> {
    let mut names: Vec<String> = FLAGS
        .iter()
        .filter(|(flag, _)| state.contains(*flag))
        .map(|(_, name)| (*name).to_owned())
        .collect();
    let known = FLAGS.iter().fold(0, |bits, (flag, _)| bits | flag.bits());
    // Reserved bits are shown rather than dropped.
    let rest = state.bits() & !known;
    if rest != 0 {
        names.push(format!("reserved bits {rest:#x}"));
    }
    names
}

pub(super) fn flags_text(state: SystemState) -> String {
    let names = flag_names(state);
    if names.is_empty() {
        format!("{:#010x} (no flags)", state.bits())
    } else {
        format!("{:#010x} {}", state.bits(), names.join(" "))
    }
}

pub(super) fn flags_json(state: SystemState) -> Value {
    json!({ "bits": state.bits(), "flags": flag_names(state) })
}

pub(super) fn limits_json(l: &SystemLimits) -> Value {
    json!({
        "stroke_mm": num(l.stroke_mm),
        "min_speed_mm_per_s": num(l.min_speed_mm_per_s),
        "max_speed_mm_per_s": num(l.max_speed_mm_per_s),
        "min_acceleration_mm_per_s2": num(l.min_acceleration_mm_per_s2),
        "max_acceleration_mm_per_s2": num(l.max_acceleration_mm_per_s2),
        "min_force_n": num(l.min_force_n),
        "nominal_force_n": num(l.nominal_force_n),
        "overdrive_force_n": num(l.overdrive_force_n),
    })
}

pub(super) fn soft_limits_json(l: &SoftLimits) -> Value {
    json!({ "minus_mm": num(l.minus_mm), "plus_mm": num(l.plus_mm) })
}

/// The reply data of the queries the library has a type for, decoded; `None` for the others.
pub(super) fn decode_reply(id: u8, data: &[u8]) -> Option<(String, Value)> {
    match id {
        0x40 => SystemState::decode(data)
            .ok()
            .map(|s| (flags_text(s), flags_json(s))),
        0x41 => GripState::decode(data)
            .ok()
            .map(|g| (grip_name(g), grip_json(g))),
        0x42 => GraspingStatistics::decode(data).ok().map(|s| {
            (
                format!(
                    "{} grasps, {} no part, {} lost",
                    s.total, s.no_part, s.lost_part
                ),
                json!({ "total": s.total, "no_part": s.no_part, "lost_part": s.lost_part }),
            )
        }),
        // 0x43–0x45 (manual 3.4.4–3.4.6): one f32, little endian, in bytes 0..3 (PROTOCOLS.md
        // erratum: the manual lists it as "Byte 0").
        0x43..=0x45 => {
            let bytes: [u8; 4] = data.try_into().ok()?;
            let v = f32::from_le_bytes(bytes);
            let unit = ["mm", "mm/s", "N"][usize::from(id - 0x43)];
            Some((format!("{v} {unit}"), num(v)))
        }
        0x46 => decode_temperature_c(data)
            .ok()
            .map(|t| (format!("{t:.1} °C"), num(t))),
        0x50 => SystemInfo::decode(data).ok().map(|i| {
            (
                format!(
                    "{}, hardware revision {}, firmware {}, serial {}",
                    device_name(i),
                    i.hardware_revision,
                    i.firmware,
                    i.serial_number
                ),
                json!({
                    "device_type": device_name(i),
                    "hardware_revision": i.hardware_revision,
                    "firmware": i.firmware.to_string(),
                    "serial_number": i.serial_number,
                }),
            )
        }),
        0x53 => SystemLimits::decode(data)
            .ok()
            .map(|l| (format!("{l:?}"), limits_json(&l))),
        _ => None,
    }
}

/// An f32 from the wire as JSON, by its shortest decimal form: 23.4 °C prints as 23.4, not as
/// the 23.399999618530273 a plain widening to f64 gives.
pub(super) fn num(v: f32) -> Value {
    v.to_string()
        .parse::<f64>()
        .ok()
        .and_then(serde_json::Number::from_f64)
        .map_or(Value::Null, Value::Number)
}

pub(super) fn to_hex(data: &[u8]) -> String {
    data.iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_keep_reserved_bits() {
        let state = SystemState::REFERENCED | SystemState::FAST_STOP | SystemState(1 << 30);
        assert_eq!(
            flags_text(state),
            "0x40001001 SF_REFERENCED SF_FAST_STOP reserved bits 0x40000000"
        );
        assert_eq!(flags_text(SystemState::empty()), "0x00000000 (no flags)");
    }

    #[test]
    fn wire_floats_print_as_written() {
        assert_eq!(num(23.4), json!(23.4));
        assert_eq!(num(f32::NAN), Value::Null);
    }

    #[test]
    fn replies_decode_by_command_id() {
        let (text, value) = decode_reply(0x43, &40.5f32.to_le_bytes()).expect("width");
        assert_eq!(text, "40.5 mm");
        assert_eq!(value, json!(40.5));
        let (text, _) = decode_reply(0x41, &[4]).expect("grip state");
        assert_eq!(text, "HOLDING");
        // Wrong length or an id without a decoder: no decoded value, never a panic.
        assert_eq!(decode_reply(0x43, &[1, 2, 3]), None);
        assert_eq!(decode_reply(0x20, &[]), None);
    }
}
