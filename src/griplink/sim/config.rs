//! How the simulated controller looks (identity, role, ports) and how it keeps time.

use std::time::Duration;

use super::device::SimDevice;
use crate::griplink::command::PortNumber;

/// The routing role of the controller (manual 2.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Role {
    /// Only the controller's own ports: 0..ports.
    #[default]
    Standalone,
    /// Ports 0..=31 (slaves' blocks of four); ports without a configured device are empty.
    Master,
}

/// How long a simulated `WSTR` waits for a state transition before it answers `ERR 05`
/// (E_TIMEOUT), before scaling: 10 s.
///
/// Manual 3.4.10 says WSTR "returns with a timeout error" when no transition occurs, but gives
/// no length. 10 s is this simulator's choice: longer than any full-stroke motion of the
/// listed grippers at their default speed, so a WSTR issued during a motion is answered by the
/// motion's end, and short enough that a client's re-asking is exercised.
pub const DEFAULT_WSTR_TIMEOUT: Duration = Duration::from_secs(10);

/// How long a simulated gripper takes to re-enable before its fingers move, when GRIP, RELEASE
/// or HOME finds it in `DS_FAULT` or disabled by DISABLE, before scaling: 100 ms.
///
/// Manual 3.4.1 says only that GRIP, RELEASE and HOME re-enable a Weiss gripper, not how long
/// that takes; a real one needs some cycles to power its actuator and clear the fault. Meanwhile
/// the state still reads `DS_FAULT` (or 2), so a motion that has nothing to do (the fingers at
/// the release limit already, a part already clamped) does not end at the instant of its `ACK`.
/// 100 ms is this simulator's choice.
pub const DEFAULT_ENABLE_TIME: Duration = Duration::from_millis(100);

/// The shortest motion of a simulated gripper, before scaling: 5 ms. A device does not end a
/// motion at the instant of its command's `ACK` even when the fingers are at the target already:
/// it needs at least a control cycle to see that. The value is this simulator's choice.
pub const MIN_MOTION_TIME: Duration = Duration::from_millis(5);

/// How the simulated controller looks and behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// `ID?` answer.
    pub id: String,
    /// Protocol version (`PROTOCOL?` answers `GRIPLINK-V<n>`, PROTASSERT checks against it).
    pub protocol_version: u32,
    /// `SN?` answer.
    pub serial_number: String,
    /// `VER?` answer.
    pub version: String,
    /// Initial `LABEL`.
    pub label: String,
    /// Routing role.
    pub role: Role,
    /// The ports, each empty or holding a device.
    pub ports: Vec<Option<SimDevice>>,
    /// Simulated durations (motion, WSTR and WAITVAL timeouts) are multiplied by this: 1.0 is
    /// real time, 0.0 makes every motion finish at once (what tests want) and every WSTR or
    /// WAITVAL that would wait time out at once.
    pub time_scale: f64,
    /// How long WSTR waits for a transition before answering `ERR 05`, before scaling
    /// (default [`DEFAULT_WSTR_TIMEOUT`]).
    pub wstr_timeout: Duration,
    /// How long a gripper in `DS_FAULT` or disabled takes to re-enable when GRIP, RELEASE or
    /// HOME starts, before scaling (default [`DEFAULT_ENABLE_TIME`]).
    pub enable_time: Duration,
}

impl SimConfig {
    /// A GRIPLINK-ET4 with four ports: an IEG 55-020 holding nothing on port 0, a
    /// CRG 200-085 on port 2, ports 1 and 3 empty. Real time.
    pub fn et4() -> Self {
        SimConfig {
            id: "GRIPLINK-ET4".to_owned(),
            protocol_version: 3,
            serial_number: "123456".to_owned(),
            version: "4.0.0".to_owned(),
            label: "GRIPLINK".to_owned(),
            role: Role::Standalone,
            ports: vec![
                Some(SimDevice::ieg_55_020()),
                None,
                Some(SimDevice::crg_200_085()),
                None,
            ],
            time_scale: 1.0,
            wstr_timeout: DEFAULT_WSTR_TIMEOUT,
            enable_time: DEFAULT_ENABLE_TIME,
        }
    }

    /// A WPG 100-090 gripper: one logical port 0 (manual 1.1). Real time. The manual does not
    /// give a WPG's `ID?` string; `WPG 100-090` is this simulator's choice.
    pub fn wpg() -> Self {
        SimConfig {
            id: "WPG 100-090".to_owned(),
            ports: vec![Some(SimDevice::wpg_100_090())],
            ..SimConfig::et4()
        }
    }

    /// The same configuration with another time scale.
    pub fn time_scale(mut self, scale: f64) -> Self {
        self.time_scale = scale;
        self
    }

    /// The same configuration with another WSTR timeout (before scaling).
    pub fn wstr_timeout(mut self, timeout: Duration) -> Self {
        self.wstr_timeout = timeout;
        self
    }

    /// The same configuration with another re-enable time (before scaling).
    pub fn enable_time(mut self, time: Duration) -> Self {
        self.enable_time = time;
        self
    }

    /// The same configuration with `device` on `port` (growing the port list if needed).
    pub fn device(mut self, port: PortNumber, device: Option<SimDevice>) -> Self {
        let port = usize::from(port);
        if self.ports.len() <= port {
            self.ports.resize(port + 1, None);
        }
        if let Some(slot) = self.ports.get_mut(port) {
            *slot = device;
        }
        self
    }
}
