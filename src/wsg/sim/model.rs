//! Simulator configuration: the gripper model, the part to find, timing and device identity.

use crate::wsg::{DeviceType, FingerType, FirmwareVersion, SystemLimits};

/// A WSG gripper model, with its limits.
///
/// The limits are approximations of the public data sheets, good enough to exercise a client;
/// set [`SimConfig::limits`] to match a particular device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// WSG 50 (110 mm stroke, 80 N).
    Wsg50,
    /// WSG 32 (68 mm stroke, 45 N).
    Wsg32,
    /// WSG 25 (64 mm stroke, 20 N).
    Wsg25,
    /// WSG 70 (80 mm stroke, 80 N).
    Wsg70,
}

impl Model {
    /// The device type reported by system information (0x50).
    pub fn device_type(self) -> DeviceType {
        match self {
            Model::Wsg50 => DeviceType::Wsg50,
            Model::Wsg32 => DeviceType::Wsg32,
            Model::Wsg25 => DeviceType::Wsg25,
            Model::Wsg70 => DeviceType::Wsg70,
        }
    }

    /// The system limits (0x53).
    pub fn limits(self) -> SystemLimits {
        let (stroke_mm, max_speed, nominal, overdrive) = match self {
            Model::Wsg50 => (110.0, 420.0, 80.0, 80.0),
            Model::Wsg32 => (68.0, 400.0, 45.0, 60.0),
            Model::Wsg25 => (64.0, 420.0, 20.0, 20.0),
            Model::Wsg70 => (80.0, 400.0, 80.0, 120.0),
        };
        SystemLimits {
            stroke_mm,
            min_speed_mm_per_s: 0.1,
            max_speed_mm_per_s: max_speed,
            min_acceleration_mm_per_s2: 100.0,
            max_acceleration_mm_per_s2: 5000.0,
            min_force_n: 5.0_f32.min(nominal),
            nominal_force_n: nominal,
            overdrive_force_n: overdrive,
        }
    }
}

/// A part between the fingers: a grasp whose nominal width is within `tolerance_mm` of
/// `width_mm` finds it and holds it at `width_mm`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Part {
    /// The part's actual width, mm.
    pub width_mm: f32,
    /// How far the nominal grasp width may be off (the "clamping travel" window), mm.
    pub tolerance_mm: f32,
}

/// A simulated finger of the finger interface (manual 3.6).
#[derive(Clone, Debug, PartialEq)]
pub struct SimFinger {
    /// The finger type (0x60 / 0x70).
    pub finger_type: FingerType,
    /// The bytes "finger data" (0x63 / 0x73) returns; empty → E_NOT_AVAILABLE.
    pub data: Vec<u8>,
}

impl Default for SimFinger {
    fn default() -> Self {
        Self {
            finger_type: FingerType::Generic,
            data: Vec::new(),
        }
    }
}

/// Everything the simulator can be configured with.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// The model (device type in system information).
    pub model: Model,
    /// The system limits (defaults to the model's).
    pub limits: SystemLimits,
    /// The part to be found by a grasp, if any.
    pub part: Option<Part>,
    /// Wall seconds per simulated second of motion: 0.0 makes motion instant (tests), 1.0 is
    /// real time, 1000.0 makes a move last long enough to be stopped. Auto-update periods are
    /// always wall-clock periods.
    pub time_scale: f64,
    /// Distance a grasp travels past its nominal width before reporting "no part", mm.
    pub clamping_travel_mm: f32,
    /// Whether force measurement fingers are fitted (tare works, force control flag).
    pub force_sensor: bool,
    /// Hardware revision (0x50).
    pub hardware_revision: u8,
    /// Firmware version (0x50).
    pub firmware: FirmwareVersion,
    /// Serial number (0x50).
    pub serial_number: u32,
    /// Temperature inside the gripper (0x46), °C.
    pub temperature_c: f32,
    /// Default acceleration, mm/s².
    pub acceleration_mm_per_s2: f32,
    /// Default grasping force, N.
    pub grasping_force_n: f32,
    /// Speed of a homing move, mm/s.
    pub homing_speed_mm_per_s: f32,
    /// Fingers 1 and 2.
    pub fingers: [SimFinger; 2],
}

impl SimConfig {
    /// A WSG 50 with no part, instant motion.
    pub fn new(model: Model) -> Self {
        let limits = model.limits();
        Self {
            model,
            limits,
            part: None,
            time_scale: 0.0,
            clamping_travel_mm: 2.0,
            force_sensor: false,
            hardware_revision: 1,
            firmware: FirmwareVersion(0x4120),
            serial_number: 4711,
            temperature_c: 23.4,
            acceleration_mm_per_s2: 1000.0,
            grasping_force_n: limits.nominal_force_n / 2.0,
            homing_speed_mm_per_s: limits.max_speed_mm_per_s / 4.0,
            fingers: [SimFinger::default(), SimFinger::default()],
        }
    }

    /// With a part to find.
    #[must_use]
    pub fn with_part(mut self, width_mm: f32, tolerance_mm: f32) -> Self {
        self.part = Some(Part {
            width_mm,
            tolerance_mm,
        });
        self
    }

    /// With a time scale (see [`SimConfig::time_scale`]).
    #[must_use]
    pub fn with_time_scale(mut self, time_scale: f64) -> Self {
        self.time_scale = time_scale;
        self
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        Self::new(Model::Wsg50)
    }
}
