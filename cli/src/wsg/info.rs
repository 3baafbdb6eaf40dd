//! `gripctl wsg info`: everything a commissioning engineer reads off the gripper first.

use gripper::wsg::{Client, SystemInfo, SystemLimits};
use serde_json::json;

use super::show::{
    device_name, flags_json, flags_text, grip_json, grip_name, limits_json, num, soft_limits_json,
};
use super::{classify, optional};
use crate::error::CliError;
use crate::output::Out;

pub(super) async fn info(client: &Client, out: Out) -> Result<(), CliError> {
    let system: SystemInfo = client.system_info().await.map_err(classify)?;
    let state = client.system_state().await.map_err(classify)?;
    let grip = client.grip_state().await.map_err(classify)?;
    let width_mm = client.width_mm().await.map_err(classify)?;
    let tag = client.device_tag().await.map_err(classify)?;
    let soft_limits = client.soft_limits().await.map_err(classify)?;
    // Older firmware lacks some queries: one it does not know must not hide the rest.
    let limits: Option<SystemLimits> = optional(client.system_limits().await)?;
    let temperature_c = optional(client.temperature_c().await)?;
    let force_n = optional(client.grasping_force_n().await)?;
    let acceleration = optional(client.acceleration_mm_per_s2().await)?;

    let device = device_name(system);
    let na = || "n/a".to_owned();
    let limits_text = limits.map_or(na(), |l| {
        format!(
            "stroke {:.1} mm, speed {:.1}–{:.1} mm/s, acceleration {:.0}–{:.0} mm/s², \
             force min {:.1} N, nominal {:.1} N, overdrive {:.1} N",
            l.stroke_mm,
            l.min_speed_mm_per_s,
            l.max_speed_mm_per_s,
            l.min_acceleration_mm_per_s2,
            l.max_acceleration_mm_per_s2,
            l.min_force_n,
            l.nominal_force_n,
            l.overdrive_force_n,
        )
    });
    let human = format!(
        "type: {device}, hardware revision {}\n\
         firmware: {}\n\
         serial number: {}\n\
         tag: {}\n\
         limits: {limits_text}\n\
         set: grasping force {}, acceleration {}, soft limits {}\n\
         temperature: {}\n\
         state: {}\n\
         grip state: {}, width {width_mm:.2} mm",
        system.hardware_revision,
        system.firmware,
        system.serial_number,
        tag.as_deref().unwrap_or("(none)"),
        force_n.map_or(na(), |f| format!("{f:.1} N")),
        acceleration.map_or(na(), |a| format!("{a:.0} mm/s²")),
        soft_limits.map_or("none".to_owned(), |l| format!(
            "{:.2} mm … {:.2} mm",
            l.minus_mm, l.plus_mm
        )),
        temperature_c.map_or(na(), |t| format!("{t:.1} °C")),
        flags_text(state),
        grip_name(grip),
    );
    let json = json!({
        "device_type": { "name": device, "code": system.device_type.to_u8() },
        "hardware_revision": system.hardware_revision,
        "firmware": system.firmware.to_string(),
        "serial_number": system.serial_number,
        "tag": tag,
        "limits": limits.map(|l| limits_json(&l)),
        "grasping_force_n": force_n.map(num),
        "acceleration_mm_per_s2": acceleration.map(num),
        "soft_limits": soft_limits.map(|l| soft_limits_json(&l)),
        "temperature_c": temperature_c.map(num),
        "system_state": flags_json(state),
        "grip_state": grip_json(grip),
        "width_mm": num(width_mm),
    });
    out.emit(human, json)
}
