//! `diagnostic_msgs/msg/DiagnosticArray` on `/diagnostics`, once a second.

use std::time::Duration;

use ros2_client::{Node, Publisher};
use tokio::sync::watch;

use crate::msgs::{diagnostic_array_type, DiagnosticArray, DiagnosticStatus, Header, KeyValue};
use crate::params::Params;
use crate::telemetry::{Shared, Telemetry};
use crate::{periodic, qos, ros};

/// The diagnostics period (REP 107's 1 Hz).
pub const PERIOD: Duration = Duration::from_secs(1);

/// The status of a device named after the node (`/gripper: WSG 50`): ERROR when the link is
/// down, FAST STOP is on or the device reports a fault; WARN with a warning; OK otherwise.
pub fn status(node_name: &str, t: &Telemetry) -> DiagnosticStatus {
    let (level, message) = if !t.connected {
        let why = t.last_error.as_deref().unwrap_or("not connected yet");
        (DiagnosticStatus::ERROR, format!("disconnected: {why}"))
    } else if t.fast_stop {
        (
            DiagnosticStatus::ERROR,
            "FAST STOP: find the cause, then call ~/acknowledge".to_owned(),
        )
    } else if !t.faults.is_empty() {
        (
            DiagnosticStatus::ERROR,
            format!("fault: {}", t.faults.join(", ")),
        )
    } else if !t.warnings.is_empty() {
        (
            DiagnosticStatus::WARN,
            format!("warning: {}", t.warnings.join(", ")),
        )
    } else {
        (DiagnosticStatus::OK, "ok".to_owned())
    };
    let opt = |v: Option<f64>| v.map_or_else(|| "unknown".to_owned(), |v| format!("{v:.2}"));
    let mut values = vec![
        kv("connected", t.connected.to_string()),
        kv("fast_stop", t.fast_stop.to_string()),
        kv("faults", t.faults.join(", ")),
        kv("warnings", t.warnings.join(", ")),
        kv("temperature_c", opt(t.temperature_c)),
        kv("width_mm", opt(t.width_mm)),
        kv("force_n", opt(t.force_n)),
        kv("reconnects", t.reconnects.to_string()),
        kv("timeouts", t.timeouts.to_string()),
        kv("last_error", t.last_error.clone().unwrap_or_default()),
    ];
    values.extend(t.state.iter().map(|(k, v)| kv(k, v.clone())));
    DiagnosticStatus {
        level,
        name: format!("{node_name}: {}", t.device),
        message,
        hardware_id: t.hardware_id.clone(),
        values,
    }
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_owned(),
        value,
    }
}

fn publisher(node: &mut Node, params: &Params) -> Result<Publisher<DiagnosticArray>, String> {
    let topic = node
        .create_topic(
            &ros::global_name(params, "diagnostics")?,
            diagnostic_array_type(),
            &qos::topic(),
        )
        .map_err(|e| format!("diagnostics topic: {e:?}"))?;
    node.create_publisher(&topic, None)
        .map_err(|e| format!("diagnostics publisher: {e:?}"))
}

/// Creates the publisher and publishes `telemetry` until `shutdown` turns true.
pub fn spawn(
    node: &mut Node,
    params: &Params,
    telemetry: &Shared,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let publisher = publisher(node, params)?;
    let node_name = params.fully_qualified_name();
    let telemetry = telemetry.clone();
    tokio::spawn(periodic::every(PERIOD, shutdown.clone(), move || {
        let msg = DiagnosticArray {
            header: Header::now(""),
            status: vec![status(&node_name, &telemetry.get())],
        };
        if let Err(e) = publisher.publish(msg) {
            tracing::debug!("diagnostics not sent: {e:?}");
        }
        std::future::ready(())
    }));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_follow_link_fast_stop_faults_and_warnings() {
        let mut t = Telemetry {
            device: "WSG 50".into(),
            ..Telemetry::default()
        };
        assert_eq!(status("/g", &t).level, DiagnosticStatus::ERROR);
        t.connected = true;
        assert_eq!(status("/g", &t).level, DiagnosticStatus::OK);
        assert_eq!(status("/g", &t).name, "/g: WSG 50");
        t.warnings.push("TEMP_WARNING".into());
        assert_eq!(status("/g", &t).level, DiagnosticStatus::WARN);
        t.fast_stop = true;
        let s = status("/g", &t);
        assert_eq!(s.level, DiagnosticStatus::ERROR);
        assert!(s.values.contains(&kv("fast_stop", "true".into())));
    }
}
