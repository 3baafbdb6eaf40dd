//! Simulator configuration: the gripper model, the part to find, timing and device identity.

use std::time::Duration;

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

/// How many UDP sessions the simulator keeps at once (the real device answers one remote
/// port); a new sender beyond this replaces the session that has been silent longest.
pub const MAX_UDP_SESSIONS: usize = 256;

/// The default of [`SimConfig::udp_idle_timeout`].
pub const DEFAULT_UDP_IDLE_TIMEOUT: Duration = Duration::from_secs(60);

/// Everything the simulator can be configured with.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// The model (device type in system information).
    pub model: Model,
    /// The system limits (defaults to the model's).
    pub limits: SystemLimits,
    /// The part to be found by a grasp, if any.
    pub part: Option<Part>,
    /// Wall seconds per simulated second of motion: 0.0 makes motion instant (the default of
    /// [`SimConfig::new`], for tests), 1.0 is real time (the default of the standalone
    /// simulators, [`SimConfig::standalone`]), 1000.0 makes a move last long enough to be
    /// stopped. Auto-update periods and the 500 ms of a finger power-on (3.6.3) are always
    /// wall-clock time.
    pub time_scale: f64,
    /// Distance a grasp travels past its nominal width before reporting "no part", mm.
    pub clamping_travel_mm: f32,
    /// The [`SimConfig::part`] sits between the fingers and blocks a pre-position (0x21) that
    /// closes past it: the fingers stop on its width and the command ends with E_AXIS_BLOCKED
    /// (manual 3.2.2, flag D1 "Stop bei Blockierung"). Default off: a pre-position then passes
    /// through the part, as if it were only put there for a grasp.
    pub part_blocks_motion: bool,
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
    /// Answer a frame with a bad checksum with E_CHECKSUM_ERROR under the id it carries, instead
    /// of discarding it (the default). The manual names the code (Anhang A) but lists it under
    /// no command and does not say how a wrong checksum is treated (1.2.1 only discards frames
    /// *missing* their checksum); since the id of a corrupted frame may be the corrupted byte,
    /// such an answer can fail a caller that sent another command with that id. Turn it on to
    /// test a client's handling of the code.
    pub answer_bad_checksum: bool,
    /// The device's "UDP remote port" setting (web interface, "Settings -> Command
    /// Interface"): UDP replies go to the sender's IP address at this port, whatever port the
    /// request came from, as public UDP drivers expect (they send from one socket and listen on
    /// another; see the WSG field notes in `PROTOCOLS.md`). `None` (the default) answers the
    /// sender's address and port. All senders with one IP address are then one session.
    pub udp_remote_port: Option<u16>,
    /// A UDP session (a peer, or with [`SimConfig::udp_remote_port`] an IP address) from which
    /// no datagram came for this long is forgotten, unless it is still owed something: the
    /// final reply of a move or finger power-on, or auto-updates it switched on (the device keeps
    /// streaming to its remote port, and drivers that subscribe once and then only listen rely
    /// on that). UDP has no connection to close, so without this every sender address would
    /// stay a session for the life of the simulator. At most [`MAX_UDP_SESSIONS`] are kept: a
    /// new sender beyond that replaces the longest-silent one. Default 60 s.
    pub udp_idle_timeout: Duration,
    /// Serve the text interface (GCL, [`wsg::text`](crate::wsg::text)) on TCP instead of the
    /// binary protocol: the web interface's "Use text based interface" (Settings → Command
    /// Interface). See [`SimConfig::text`].
    pub text_interface: bool,
    /// An unannounced TCP close (no 0x07, no `BYE()`) raises FAST STOP (binary manual 1.4.2,
    /// GCL manual chapter 2). The web interface can switch this off ("Enable Error on TCP
    /// Disconnect"); default on.
    pub fast_stop_on_close: bool,
    /// Text mode: the least time between a motion's `ACK` and the next line written to that
    /// connection (its `FIN`, even for a zero-length move). Public GCL clients read one line
    /// per `recv` and compare whole chunks, so `ACK` and `FIN` must not arrive together
    /// (shared note §6.2, §6.3). Default 20 ms.
    pub text_ack_gap: Duration,
    /// How long a motion's final reply comes after its fingers stopped (a grasp's force build-up,
    /// the controller settling), as motion time (scaled by [`SimConfig::time_scale`]). Meanwhile
    /// SF_MOVING is already clear: the manual resets it "wenn die Bewegung stoppt" (Anhang B)
    /// and sends the final reply when the command ends (1.3), and ties the two together nowhere.
    /// A client that takes one "not moving" for the end of a move is then wrong. Default 0 (flag
    /// and final reply together).
    pub final_reply_lag: Duration,
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
            part_blocks_motion: false,
            force_sensor: false,
            hardware_revision: 1,
            firmware: FirmwareVersion(0x4120),
            serial_number: 4711,
            temperature_c: 23.4,
            acceleration_mm_per_s2: 1000.0,
            grasping_force_n: limits.nominal_force_n / 2.0,
            homing_speed_mm_per_s: limits.max_speed_mm_per_s / 4.0,
            fingers: [SimFinger::default(), SimFinger::default()],
            answer_bad_checksum: false,
            udp_remote_port: None,
            udp_idle_timeout: DEFAULT_UDP_IDLE_TIMEOUT,
            text_interface: false,
            fast_stop_on_close: true,
            text_ack_gap: Duration::from_millis(20),
            final_reply_lag: Duration::ZERO,
        }
    }

    /// Serving GCL, the text interface, over TCP ([`SimConfig::text_interface`]): LF-only
    /// replies, one line per write, `ACK` and `FIN` apart by [`SimConfig::text_ack_gap`]; the
    /// same device model as the binary protocol.
    #[must_use]
    pub fn text(mut self) -> Self {
        self.text_interface = true;
        self
    }

    /// With or without FAST STOP on an unannounced TCP close ([`SimConfig::fast_stop_on_close`]).
    #[must_use]
    pub fn with_fast_stop_on_close(mut self, on: bool) -> Self {
        self.fast_stop_on_close = on;
        self
    }

    /// What the standalone simulators (`wsg_simulator`, `gripctl sim wsg`) serve without
    /// options: a WSG 50 with a 40 mm part (±2 mm) in **real time** (time scale 1), so a move
    /// lasts as long as on the device and a client's stop, abort and E_ALREADY_RUNNING handling
    /// can be exercised against it. In-process tests usually want [`SimConfig::new`] (instant).
    pub fn standalone() -> Self {
        Self::new(Model::Wsg50)
            .with_part(40.0, 2.0)
            .with_time_scale(1.0)
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

    /// With the part blocking a pre-position that closes past it (see
    /// [`SimConfig::part_blocks_motion`]).
    #[must_use]
    pub fn with_blocking_part(mut self) -> Self {
        self.part_blocks_motion = true;
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
