//! What the node knows about its device, shared by the topics, the action and the services.

use std::sync::{Arc, Mutex, MutexGuard};

use gripper::ErrorKind;

/// The latest readings and counters of one device.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// What the device is, e.g. `WSG 50` (the diagnostics' name).
    pub device: String,
    /// Its identity: serial number, address.
    pub hardware_id: String,
    /// The link is up.
    pub connected: bool,
    /// Opening width, mm (`None` until the first reading).
    pub width_mm: Option<f64>,
    /// Finger speed, mm/s.
    pub speed_mm_per_s: Option<f64>,
    /// Gripping force, N.
    pub force_n: Option<f64>,
    /// A part is held (the device's grip state says so).
    pub holding: bool,
    /// Temperature, °C.
    pub temperature_c: Option<f64>,
    /// FAST STOP (or the device's equivalent) is active.
    pub fast_stop: bool,
    /// Faults the device reports, under the manual's names.
    pub faults: Vec<String>,
    /// Warnings the device reports, under the manual's names.
    pub warnings: Vec<String>,
    /// Further state for the diagnostics, under the manual's names (flags, grip state).
    pub state: Vec<(String, String)>,
    /// Reconnects since the start.
    pub reconnects: u64,
    /// Calls that timed out since the start.
    pub timeouts: u64,
    /// The last error seen on the link or a call.
    pub last_error: Option<String>,
}

impl Telemetry {
    /// Sets a value of [`Telemetry::state`].
    pub fn set_state(&mut self, key: &str, value: String) {
        match self.state.iter_mut().find(|(k, _)| k == key) {
            Some(entry) => entry.1 = value,
            None => self.state.push((key.to_owned(), value)),
        }
    }
}

/// The shared telemetry of a node.
#[derive(Clone, Debug, Default)]
pub struct Shared(Arc<Mutex<Telemetry>>);

impl Shared {
    /// Telemetry of a device named `device`, with identity `hardware_id`.
    pub fn new(device: &str, hardware_id: &str) -> Self {
        Shared(Arc::new(Mutex::new(Telemetry {
            device: device.to_owned(),
            hardware_id: hardware_id.to_owned(),
            ..Telemetry::default()
        })))
    }

    /// Locks it (a panic elsewhere does not poison it for the rest of the node).
    pub fn lock(&self) -> MutexGuard<'_, Telemetry> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A copy of the current state.
    pub fn get(&self) -> Telemetry {
        self.lock().clone()
    }

    /// Records a failed call or reading of any protocol: keeps `message` as the last error and
    /// counts a timeout ([`ErrorKind::Timeout`], the protocol's `Error::kind()`). The node's one
    /// classification of errors: every node (WSG, GCL, GRIPLINK, Grasping-Kit) reports through it.
    pub fn note_error(&self, kind: ErrorKind, message: String) {
        let mut t = self.lock();
        if kind == ErrorKind::Timeout {
            t.timeouts += 1;
        }
        t.last_error = Some(message);
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use gripper::{griplink, smartgrasp, wsg};

    use super::Shared;

    /// Every protocol's timeout counts, the connect timeout (an I/O error of kind `TimedOut`)
    /// included; the GCL and Grasping-Kit nodes once kept only the message.
    #[test]
    fn every_protocols_timeout_is_counted_and_other_errors_are_not() {
        let t = Shared::new("test", "");
        let timeout = Duration::from_millis(5);
        let timeouts = [
            wsg::Error::Timeout {
                command: 0x43,
                timeout,
            }
            .kind(),
            wsg::text::Error::Timeout {
                command: "POS?".into(),
                timeout,
            }
            .kind(),
            griplink::Error::Timeout {
                command: "POS[0]".into(),
                timeout,
            }
            .kind(),
            smartgrasp::Error::Timeout {
                message_type: smartgrasp::MessageType::GetState,
                timeout,
            }
            .kind(),
            wsg::Error::from(std::io::Error::from(std::io::ErrorKind::TimedOut)).kind(),
        ];
        for kind in timeouts {
            t.note_error(kind, format!("{kind}"));
        }
        assert_eq!(t.get().timeouts, 5);
        t.note_error(
            griplink::Error::Closed.kind(),
            "the client was closed".into(),
        );
        t.note_error(
            smartgrasp::Error::ConnectionLost {
                reason: "reset".into(),
            }
            .kind(),
            "connection lost: reset".into(),
        );
        let t = t.get();
        assert_eq!(t.timeouts, 5);
        assert_eq!(t.last_error.as_deref(), Some("connection lost: reset"));
    }
}
