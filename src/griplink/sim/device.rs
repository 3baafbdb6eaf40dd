//! The simulated devices: what each one reports (chapter 3.2), its stroke and speed, the part
//! between its fingers, and the grip recipes it ships with.

use crate::griplink::command::GripConfig;
use crate::griplink::value::format_float;

/// Weiss Robotics' IO-Link vendor id (manual chapter 7).
pub const WEISS_VENDOR_ID: u32 = 815;

/// How many grip recipes each simulated device has.
pub const RECIPES: usize = 16;

/// The gripping force of the default recipes, in percent (GRIPCFG parameter 3, scaled ×1000
/// on the wire).
pub const DEFAULT_FORCE_PERCENT: f64 = 50.0;

/// A device on a port of the simulated controller.
#[derive(Debug, Clone, PartialEq)]
pub struct SimDevice {
    /// IO-Link vendor id (`DEVVID`).
    pub vendor_id: u32,
    /// Product id (`DEVPID`, manual chapter 7).
    pub product_id: u32,
    /// Product name (`DEVNAME`).
    pub name: String,
    /// Vendor name (`DEVVENDOR`).
    pub vendor: String,
    /// Serial number (`DEVSN`).
    pub serial_number: String,
    /// Firmware version (`DEVVER`).
    pub version: String,
    /// Initial application tag (`DEVTAG`).
    pub tag: String,
    /// Finger stroke: positions run from 0 to this, in mm.
    pub stroke_mm: f64,
    /// Finger speed when a command asks for the default, in mm/s.
    pub speed_mm_per_s: f64,
    /// Width of the part between the fingers, in mm: a grip that passes it holds it. `None`: no
    /// part, every grip ends `DS_NO_PART`.
    pub part_width_mm: Option<f64>,
}

impl SimDevice {
    /// A Weiss device with the given product id, name and stroke, no part.
    pub fn weiss(product_id: u32, name: &str, stroke_mm: f64) -> Self {
        SimDevice {
            vendor_id: WEISS_VENDOR_ID,
            product_id,
            name: name.to_owned(),
            vendor: "WEISS ROBOTICS".to_owned(),
            serial_number: "000042".to_owned(),
            version: "1.0.1".to_owned(),
            tag: String::new(),
            stroke_mm,
            speed_mm_per_s: 50.0,
            part_width_mm: None,
        }
    }

    /// IEG 55-020 servo gripper (product id 20, 20 mm stroke).
    pub fn ieg_55_020() -> Self {
        SimDevice::weiss(20, "IEG 55-020", 20.0)
    }

    /// CRG 200-085 servo gripper (product id 50, 85 mm stroke).
    pub fn crg_200_085() -> Self {
        SimDevice::weiss(50, "CRG 200-085", 85.0)
    }

    /// WPG 100-090 servo gripper (product id 6050, 90 mm stroke).
    pub fn wpg_100_090() -> Self {
        SimDevice::weiss(6050, "WPG 100-090", 90.0)
    }

    /// WPG 300-120 servo gripper (product id 6060, 120 mm stroke).
    pub fn wpg_300_120() -> Self {
        SimDevice::weiss(6060, "WPG 300-120", 120.0)
    }

    /// The same device with a part of `width_mm` between its fingers.
    pub fn with_part(mut self, width_mm: f64) -> Self {
        self.part_width_mm = Some(width_mm);
        self
    }

    /// The recipe every slot of this device holds at power-on: an outside grip over the whole
    /// stroke. No-part limit at the closed end (0 mm), release limit at the open end (the
    /// stroke, where HOME leaves the fingers), [`DEFAULT_FORCE_PERCENT`] force, and 0 for the
    /// speeds and accelerations (the device's defaults, 3.4.6). So `GRIP(p,i)` closes on a part
    /// and `RELEASE(p,i)` opens away from it, as a gripper out of the box does.
    ///
    /// The manual does not list factory recipes; these values are this simulator's choice.
    pub fn default_recipe(&self) -> GripConfig {
        let release = i32::try_from(self.stroke_um()).unwrap_or(i32::MAX);
        GripConfig {
            tag: "default".to_owned(),
            params: [0, release, um_i32(DEFAULT_FORCE_PERCENT), 0, 0, 0, 0, 0],
        }
    }

    pub(super) fn stroke_um(&self) -> i64 {
        um(self.stroke_mm)
    }

    pub(super) fn default_speed_um_per_s(&self) -> f64 {
        self.speed_mm_per_s * 1000.0
    }
}

/// mm (or any unit) to its ×1000 scaled integer (3.5.2), saturating; 0 for NaN.
pub(super) fn um(mm: f64) -> i64 {
    let v = (mm * 1000.0).round();
    if v.is_finite() {
        v.clamp(i64::MIN as f64, i64::MAX as f64) as i64
    } else {
        0
    }
}

fn um_i32(mm: f64) -> i32 {
    i32::try_from(um(mm)).unwrap_or(i32::MAX)
}

/// A scaled integer as the float the F commands answer (`12000` → `12`).
pub(super) fn mm_text(um: i64) -> String {
    format_float(um as f64 / 1000.0).unwrap_or_else(|| "0".to_owned())
}
