//! What the node knows about its device, shared by the topics, the action and the services.

use std::sync::{Arc, Mutex, MutexGuard};

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

    /// Counts a timeout and keeps its message.
    pub fn timed_out(&self, what: String) {
        let mut t = self.lock();
        t.timeouts += 1;
        t.last_error = Some(what);
    }
}
