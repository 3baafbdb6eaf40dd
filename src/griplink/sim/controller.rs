//! The simulated controller and its devices: a pure state machine (no I/O, no clock). The
//! server passes the current time in; motion takes simulated time, scaled by
//! [`SimConfig::time_scale`].
//!
//! Device behaviour follows chapter 3 and the states of chapter 5:
//! - a device starts `DS_NOT_INITIALIZED`; `HOME` (always blocking) moves the fingers to the
//!   open end of the stroke and ends idle, `DS_DISABLED` (the GRIP polling example shows a
//!   freshly homed gripper in state 2, "DS_IDLE");
//! - `GRIP` closes (or opens) towards the recipe's no-part limit and ends `DS_HOLDING` where it
//!   meets the configured part, else `DS_NO_PART`; it is refused with `E_STATE_CONFLICT` in
//!   `DS_HOLDING` or `DS_NO_PART` (3.4.4) and in `DS_FAULT`;
//! - `RELEASE` moves to the recipe's release limit and ends `DS_RELEASED`;
//! - `ENABLE` turns `DS_DISABLED` into `DS_ENABLED`; `DISABLE` aborts any motion and ends
//!   `DS_DISABLED`, which also clears `DS_FAULT` (as does `HOME`);
//! - `CLAMP` is only accepted while disabled (3.4.9, Weiss grippers);
//! - value index 0 is the finger position (µm for VALUE, mm for VALUEF, 3.5.2) and SETVAL
//!   index 0 pre-positions the fingers.
//!
//! Faults for users' tests: [`Controller::inject_fault`] (fault now) and
//! [`Controller::fault_next_motion`] (the next motion ends in `DS_FAULT`).

use std::collections::VecDeque;
use std::time::Duration;

use crate::griplink::command::{Blocking, Command, GripConfig, GripConfigF, PortNumber};
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;
use crate::griplink::value::format_float;

/// Weiss Robotics' IO-Link vendor id (manual chapter 7).
pub const WEISS_VENDOR_ID: u32 = 815;

/// How many grip recipes each simulated device has.
pub const RECIPES: usize = 16;

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

    fn stroke_um(&self) -> i64 {
        um(self.stroke_mm)
    }
}

/// The routing role of the controller (manual 2.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Role {
    /// Only the controller's own ports: 0..ports.
    #[default]
    Standalone,
    /// Ports 0..=31 (slaves' blocks of four); ports without a configured device are empty.
    Master,
}

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
    /// real time, 0.0 makes every motion finish at once (what tests want).
    pub time_scale: f64,
    /// How long WSTR waits for a transition before answering `E_TIMEOUT` (before scaling).
    pub wstr_timeout: Duration,
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
            wstr_timeout: Duration::from_secs(10),
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

/// Per-connection settings.
#[derive(Debug, Clone, Default)]
pub struct Session {
    /// `VERBOSE=1`: `ERR` replies carry the manual's description. Kept per connection, so one
    /// client's choice does not change another's replies.
    pub verbose: bool,
}

/// What the controller does with a command.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Answer at once with this line.
    Reply(String),
    /// Hold the answer (and this connection's later commands) until [`Controller::poll`]
    /// gives one.
    Wait(Wait),
    /// `BYE()`: answer `ACK`, then close the connection.
    Bye,
}

/// A reply being held back.
#[derive(Debug, Clone, PartialEq)]
pub enum Wait {
    /// A blocking motion command: ACK when motion `id` ends.
    Motion {
        /// Port index.
        port: usize,
        /// The motion.
        id: u64,
    },
    /// WSTR: the new state when the motion in progress ends, `E_TIMEOUT` at `deadline`.
    Transition {
        /// Port index.
        port: usize,
        /// When to give up.
        deadline: Duration,
    },
    /// WAITVAL(F): ACK when the position is within `low..=high` µm, `E_TIMEOUT` at `deadline`.
    Value {
        /// Port index.
        port: usize,
        /// Lower window bound, µm.
        low: f64,
        /// Upper window bound, µm.
        high: f64,
        /// When to give up.
        deadline: Duration,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum MotionEnd {
    Done(DeviceState),
    Aborted,
}

#[derive(Debug, Clone)]
struct Motion {
    id: u64,
    from_um: i64,
    to_um: i64,
    start: Duration,
    end: Duration,
    end_state: DeviceState,
}

#[derive(Debug, Clone)]
struct PortSim {
    device: Option<SimDevice>,
    state: DeviceState,
    position_um: i64,
    motion: Option<Motion>,
    /// How recent motions ended, for blocking commands that poll after the fact.
    history: VecDeque<(u64, MotionEnd)>,
    recipes: Vec<GripConfig>,
    tag: String,
    fault_next_motion: bool,
    led: u32,
    clamp: bool,
}

const HISTORY: usize = 64;
/// How often a WAITVAL re-reads the position while the fingers move (simulated time).
const VALUE_POLL: Duration = Duration::from_millis(5);

fn um(mm: f64) -> i64 {
    let v = (mm * 1000.0).round();
    if v.is_finite() {
        v.clamp(i64::MIN as f64, i64::MAX as f64) as i64
    } else {
        0
    }
}

fn mm_text(um: i64) -> String {
    format_float(um as f64 / 1000.0).unwrap_or_else(|| "0".to_owned())
}

impl PortSim {
    fn new(device: Option<SimDevice>) -> Self {
        let state = if device.is_some() {
            DeviceState::NotInitialized
        } else {
            DeviceState::NotConnected
        };
        let tag = device.as_ref().map(|d| d.tag.clone()).unwrap_or_default();
        PortSim {
            device,
            state,
            position_um: 0,
            motion: None,
            history: VecDeque::new(),
            recipes: vec![GripConfig::default(); RECIPES],
            tag,
            fault_next_motion: false,
            led: 0,
            clamp: false,
        }
    }

    fn remember(&mut self, id: u64, end: MotionEnd) {
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history.push_back((id, end));
    }

    fn abort_motion(&mut self) {
        if let Some(m) = self.motion.take() {
            self.remember(m.id, MotionEnd::Aborted);
        }
    }

    fn advance(&mut self, now: Duration) {
        let Some(m) = &self.motion else { return };
        if now >= m.end {
            let (id, to, state) = (m.id, m.to_um, m.end_state);
            self.position_um = to;
            self.state = state;
            self.motion = None;
            self.remember(id, MotionEnd::Done(state));
        } else {
            let total = (m.end - m.start).as_secs_f64();
            let done = now.saturating_sub(m.start).as_secs_f64();
            let frac = if total > 0.0 { done / total } else { 1.0 };
            self.position_um = m.from_um + ((m.to_um - m.from_um) as f64 * frac).round() as i64;
        }
    }
}

/// The simulated controller: configuration, label, and a state machine per port.
#[derive(Debug, Clone)]
pub struct Controller {
    config: SimConfig,
    label: String,
    ports: Vec<PortSim>,
    next_motion: u64,
}

/// An `ERR` reply line, with two-digit codes as the manual prints them (`ERR 04`).
pub fn error_line(status: Status, verbose: bool) -> String {
    if verbose {
        format!("ERR {:02} {status}", status.code())
    } else {
        format!("ERR {:02}", status.code())
    }
}

type Step = Result<Outcome, Status>;

fn reply(line: String) -> Step {
    Ok(Outcome::Reply(line))
}

fn ack() -> Step {
    reply("ACK".to_owned())
}

impl Controller {
    /// A controller in its power-on state.
    pub fn new(config: SimConfig) -> Self {
        let count = match config.role {
            Role::Standalone => config.ports.len(),
            Role::Master => usize::from(crate::griplink::command::MAX_PORT) + 1,
        };
        let ports = (0..count)
            .map(|i| PortSim::new(config.ports.get(i).cloned().flatten()))
            .collect();
        Controller {
            label: config.label.clone(),
            config,
            ports,
            next_motion: 1,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The number of addressable ports.
    pub fn port_count(&self) -> usize {
        self.ports.len()
    }

    /// The device state on `port` (after advancing to `now`).
    pub fn state(&mut self, port: usize, now: Duration) -> Option<DeviceState> {
        self.advance(now);
        self.ports.get(port).map(|p| p.state)
    }

    /// The finger position on `port` in µm (after advancing to `now`).
    pub fn position_um(&mut self, port: usize, now: Duration) -> Option<i64> {
        self.advance(now);
        self.ports.get(port).map(|p| p.position_um)
    }

    /// Whether the device on `port` is moving at `now`.
    pub fn is_moving(&mut self, port: usize, now: Duration) -> bool {
        self.advance(now);
        self.ports.get(port).is_some_and(|p| p.motion.is_some())
    }

    /// Changes the time scale for motions started from now on (see [`SimConfig::time_scale`]).
    pub fn set_time_scale(&mut self, scale: f64) {
        self.config.time_scale = scale;
    }

    /// Puts a part of `width_mm` between the fingers of the device on `port` (`None`: no part).
    pub fn set_part(&mut self, port: usize, width_mm: Option<f64>) {
        if let Some(d) = self.ports.get_mut(port).and_then(|p| p.device.as_mut()) {
            d.part_width_mm = width_mm;
        }
    }

    /// Faults the device on `port` now: a motion in progress stops, the state becomes
    /// `DS_FAULT`.
    pub fn inject_fault(&mut self, port: usize, now: Duration) {
        self.advance(now);
        if let Some(p) = self.ports.get_mut(port).filter(|p| p.device.is_some()) {
            if let Some(m) = p.motion.take() {
                p.remember(m.id, MotionEnd::Done(DeviceState::Fault));
            }
            p.state = DeviceState::Fault;
        }
    }

    /// Makes the next motion of the device on `port` end in `DS_FAULT`.
    pub fn fault_next_motion(&mut self, port: usize) {
        if let Some(p) = self.ports.get_mut(port) {
            p.fault_next_motion = true;
        }
    }

    /// Completes or interpolates every motion up to `now`.
    pub fn advance(&mut self, now: Duration) {
        for p in &mut self.ports {
            p.advance(now);
        }
    }

    fn scaled(&self, d: Duration) -> Duration {
        let scale = self.config.time_scale;
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            0.0
        };
        Duration::try_from_secs_f64(d.as_secs_f64() * scale).unwrap_or(Duration::from_secs(86_400))
    }

    fn port(&self, port: PortNumber) -> Result<usize, Status> {
        let i = usize::from(port);
        if i < self.ports.len() {
            Ok(i)
        } else {
            Err(Status::IndexOutOfBounds)
        }
    }

    /// The port's state and device; `E_NOT_INITIALIZED` when no device is connected (as the
    /// manual documents for DEVPID, 3.2.2).
    fn device(&self, port: PortNumber) -> Result<(usize, &SimDevice), Status> {
        let i = self.port(port)?;
        match self.ports.get(i).and_then(|p| p.device.as_ref()) {
            Some(d) => Ok((i, d)),
            None => Err(Status::NotInitialized),
        }
    }

    fn ports_mut(&mut self, i: usize) -> Result<&mut PortSim, Status> {
        self.ports.get_mut(i).ok_or(Status::IndexOutOfBounds)
    }

    /// Starts a motion on port `i` to `to_um`, ending in `end_state` (or `DS_FAULT` if a fault
    /// was armed). Replaces any motion in progress.
    fn start_motion(
        &mut self,
        i: usize,
        to_um: i64,
        speed_um_per_s: f64,
        end_state: DeviceState,
        now: Duration,
    ) -> Result<u64, Status> {
        let id = self.next_motion;
        self.next_motion += 1;
        let from_um = self.ports_mut(i)?.position_um;
        let seconds = if speed_um_per_s > 0.0 {
            (to_um - from_um).unsigned_abs() as f64 / speed_um_per_s
        } else {
            0.0
        };
        let duration = self.scaled(Duration::try_from_secs_f64(seconds).unwrap_or(Duration::ZERO));
        let p = self.ports_mut(i)?;
        p.abort_motion();
        let end_state = if std::mem::take(&mut p.fault_next_motion) {
            DeviceState::Fault
        } else {
            end_state
        };
        p.motion = Some(Motion {
            id,
            from_um,
            to_um,
            start: now,
            end: now + duration,
            end_state,
        });
        p.advance(now);
        Ok(id)
    }

    /// A grip towards `limit_um`: holds the part if the fingers meet it on the way.
    fn grip(
        &mut self,
        port: PortNumber,
        limit_um: i64,
        speed_um_per_s: f64,
        blocking: Blocking,
        now: Duration,
    ) -> Step {
        let (i, device) = self.device(port)?;
        let stroke = device.stroke_um();
        let part = device.part_width_mm.map(um);
        let default_speed = device.speed_mm_per_s * 1000.0;
        let state = self.ports.get(i).map(|p| p.state);
        match state {
            Some(DeviceState::NotInitialized) => return Err(Status::NotInitialized),
            Some(DeviceState::Holding | DeviceState::NoPart | DeviceState::Fault) => {
                return Err(Status::StateConflict)
            }
            _ => {}
        }
        if !(0..=stroke).contains(&limit_um) {
            return Err(Status::RangeError);
        }
        let from = self.ports_mut(i)?.position_um;
        let (stop, end) = match part {
            Some(w) if (limit_um < w && w < from) || (from < w && w < limit_um) => {
                (w, DeviceState::Holding)
            }
            _ => (limit_um, DeviceState::NoPart),
        };
        let speed = if speed_um_per_s > 0.0 {
            speed_um_per_s
        } else {
            default_speed
        };
        let id = self.start_motion(i, stop, speed, end, now)?;
        self.motion_reply(i, id, blocking)
    }

    /// A release (or pre-position) to `target_um`, ending `DS_RELEASED`.
    fn release(
        &mut self,
        port: PortNumber,
        target_um: i64,
        speed_um_per_s: f64,
        blocking: Blocking,
        now: Duration,
    ) -> Step {
        let (i, device) = self.device(port)?;
        let stroke = device.stroke_um();
        let default_speed = device.speed_mm_per_s * 1000.0;
        match self.ports.get(i).map(|p| p.state) {
            Some(DeviceState::NotInitialized) => return Err(Status::NotInitialized),
            Some(DeviceState::Fault) => return Err(Status::StateConflict),
            _ => {}
        }
        if !(0..=stroke).contains(&target_um) {
            return Err(Status::RangeError);
        }
        let speed = if speed_um_per_s > 0.0 {
            speed_um_per_s
        } else {
            default_speed
        };
        let id = self.start_motion(i, target_um, speed, DeviceState::Released, now)?;
        self.motion_reply(i, id, blocking)
    }

    fn motion_reply(&self, port: usize, id: u64, blocking: Blocking) -> Step {
        match blocking {
            Blocking::Immediate => ack(),
            Blocking::UntilDone => Ok(Outcome::Wait(Wait::Motion { port, id })),
        }
    }

    fn recipe(&self, port: PortNumber, index: u32) -> Result<(usize, &GripConfig), Status> {
        let (i, _) = self.device(port)?;
        self.ports
            .get(i)
            .and_then(|p| p.recipes.get(index as usize))
            .map(|r| (i, r))
            .ok_or(Status::IndexOutOfBounds)
    }

    fn recipe_line(&self, port: PortNumber, index: u32, float: bool) -> Result<String, Status> {
        let (_, r) = self.recipe(port, index)?;
        let key = if float { "GRIPCFGF" } else { "GRIPCFG" };
        let mut line = format!("{key}[{port}][{index}]=[\"{}\"", r.tag);
        for p in r.params {
            line.push(',');
            if float {
                line.push_str(&mm_text(i64::from(p)));
            } else {
                line.push_str(&p.to_string());
            }
        }
        line.push(']');
        Ok(line)
    }

    fn set_recipe(
        &mut self,
        port: PortNumber,
        index: u32,
        config: GripConfig,
    ) -> Result<(), Status> {
        let (i, device) = self.device(port)?;
        let stroke = device.stroke_um();
        let p = config.params;
        let in_stroke = |v: i32| (0..=stroke).contains(&i64::from(v));
        if !in_stroke(p[0]) || !in_stroke(p[1]) || !(0..=100_000).contains(&p[2]) {
            return Err(Status::RangeError);
        }
        if p[3..].iter().any(|v| *v < 0) {
            return Err(Status::RangeError);
        }
        let slot = self
            .ports_mut(i)?
            .recipes
            .get_mut(index as usize)
            .ok_or(Status::IndexOutOfBounds)?;
        *slot = config;
        Ok(())
    }

    /// Executes one command at time `now` for a connection with `session`.
    pub fn execute(&mut self, session: &mut Session, command: &Command, now: Duration) -> Outcome {
        self.advance(now);
        match self.run(session, command, now) {
            Ok(outcome) => outcome,
            Err(status) => Outcome::Reply(error_line(status, session.verbose)),
        }
    }

    fn run(&mut self, session: &mut Session, command: &Command, now: Duration) -> Step {
        use Command::*;
        match command {
            Id => reply(format!("ID=\"{}\"", self.config.id)),
            Protocol => reply(format!(
                "PROTOCOL=\"GRIPLINK-V{}\"",
                self.config.protocol_version
            )),
            ProtAssert {
                identifier,
                min_version,
            } => {
                if identifier.eq_ignore_ascii_case("GRIPLINK")
                    && *min_version <= self.config.protocol_version
                {
                    ack()
                } else {
                    Err(Status::NotSupported)
                }
            }
            SerialNumber => reply(format!("SN=\"{}\"", self.config.serial_number)),
            Label => reply(format!("LABEL=\"{}\"", self.label)),
            SetLabel(label) => {
                self.label = label.clone();
                reply(format!("LABEL=\"{}\"", self.label))
            }
            Version => reply(format!("VER=\"{}\"", self.config.version)),
            SetVerbose(on) => {
                session.verbose = *on;
                reply(format!("VERBOSE={}", u8::from(*on)))
            }
            DevVid(p) => {
                let i = self.port(*p)?;
                let vid = self
                    .ports
                    .get(i)
                    .and_then(|s| s.device.as_ref())
                    .map_or(-1, |d| i64::from(d.vendor_id));
                reply(format!("DEVVID[{p}]={vid}"))
            }
            DevPid(p) => reply(format!("DEVPID[{p}]={}", self.device(*p)?.1.product_id)),
            DevAssert {
                port,
                vendor_id,
                product_id,
            } => {
                self.port(*port)?;
                match self.device(*port) {
                    Ok((_, d)) if d.vendor_id == *vendor_id && d.product_id == *product_id => ack(),
                    _ => Err(Status::CmdFailed),
                }
            }
            DevName(p) => reply(format!("DEVNAME[{p}]=\"{}\"", self.device(*p)?.1.name)),
            DevVendor(p) => reply(format!("DEVVENDOR[{p}]=\"{}\"", self.device(*p)?.1.vendor)),
            DevSn(p) => reply(format!(
                "DEVSN[{p}]=\"{}\"",
                self.device(*p)?.1.serial_number
            )),
            DevVer(p) => reply(format!("DEVVER[{p}]=\"{}\"", self.device(*p)?.1.version)),
            DevTag(p) => {
                let (i, _) = self.device(*p)?;
                reply(format!("DEVTAG[{p}]=\"{}\"", self.ports_mut(i)?.tag))
            }
            SetDevTag(p, tag) => {
                let (i, _) = self.device(*p)?;
                self.ports_mut(i)?.tag = tag.clone();
                reply(format!("DEVTAG[{p}]=\"{tag}\""))
            }
            Bye => Ok(Outcome::Bye),
            Enable(p) => {
                let (i, _) = self.device(*p)?;
                let port = self.ports_mut(i)?;
                match port.state {
                    DeviceState::NotInitialized => Err(Status::NotInitialized),
                    DeviceState::Fault => Err(Status::StateConflict),
                    DeviceState::Disabled => {
                        port.state = DeviceState::Enabled;
                        ack()
                    }
                    _ => ack(),
                }
            }
            Disable(p) => {
                let (i, _) = self.device(*p)?;
                let port = self.ports_mut(i)?;
                port.abort_motion();
                if port.state != DeviceState::NotInitialized {
                    port.state = DeviceState::Disabled;
                }
                ack()
            }
            Home(p) => {
                let (i, d) = self.device(*p)?;
                let (open, speed) = (d.stroke_um(), d.speed_mm_per_s * 1000.0);
                let id = self.start_motion(i, open, speed, DeviceState::Disabled, now)?;
                self.motion_reply(i, id, Blocking::UntilDone)
            }
            Grip {
                port,
                index,
                blocking,
            } => {
                let (_, r) = self.recipe(*port, *index)?;
                let (limit, speed) = (i64::from(r.params[0]), f64::from(r.params[3]));
                self.grip(*port, limit, speed, *blocking, now)
            }
            Release {
                port,
                index,
                blocking,
            } => {
                let (_, r) = self.recipe(*port, *index)?;
                let (limit, speed) = (i64::from(r.params[1]), f64::from(r.params[5]));
                self.release(*port, limit, speed, *blocking, now)
            }
            FlexGrip(p, a, b) => {
                if a.force_mn < 0 || a.speed_um_per_s < 0 || a.acceleration_um_per_s2 < 0 {
                    return Err(Status::RangeError);
                }
                let speed = f64::from(a.speed_um_per_s);
                self.grip(*p, i64::from(a.position_um), speed, *b, now)
            }
            FlexGripF(p, a, b) => {
                if a.force_n < 0.0 || a.speed_mm_per_s < 0.0 || a.acceleration_mm_per_s2 < 0.0 {
                    return Err(Status::RangeError);
                }
                let speed = a.speed_mm_per_s * 1000.0;
                self.grip(*p, um(a.position_mm), speed, *b, now)
            }
            FlexRelease(p, a, b) => {
                if a.speed_um_per_s < 0 || a.acceleration_um_per_s2 < 0 {
                    return Err(Status::RangeError);
                }
                let speed = f64::from(a.speed_um_per_s);
                self.release(*p, i64::from(a.position_um), speed, *b, now)
            }
            FlexReleaseF(p, a, b) => {
                if a.speed_mm_per_s < 0.0 || a.acceleration_mm_per_s2 < 0.0 {
                    return Err(Status::RangeError);
                }
                let speed = a.speed_mm_per_s * 1000.0;
                self.release(*p, um(a.position_mm), speed, *b, now)
            }
            Led { port, index } => {
                let (i, _) = self.device(*port)?;
                self.ports_mut(i)?.led = *index;
                ack()
            }
            Clamp { port, enable } => {
                let (i, _) = self.device(*port)?;
                let p = self.ports_mut(i)?;
                if !matches!(p.state, DeviceState::Disabled | DeviceState::NotInitialized) {
                    return Err(Status::StateConflict);
                }
                p.clamp = *enable;
                ack()
            }
            Wstr(p) => {
                let (i, _) = self.device(*p)?;
                let deadline = now + self.scaled(self.config.wstr_timeout);
                let port = self.ports_mut(i)?;
                if port.motion.is_some() {
                    Ok(Outcome::Wait(Wait::Transition { port: i, deadline }))
                } else {
                    reply(format!("WSTR[{p}]={}", port.state.code()))
                }
            }
            SetVal { port, index, value } => self.set_value(*port, *index, i64::from(*value), now),
            SetValF { port, index, value } => self.set_value(*port, *index, um(*value), now),
            WaitVal {
                port,
                index,
                threshold,
                window,
                timeout,
            } => self.wait_value(
                *port,
                *index,
                f64::from(*threshold),
                f64::from(*window),
                *timeout,
                now,
            ),
            WaitValF {
                port,
                index,
                threshold,
                window,
                timeout,
            } => self.wait_value(
                *port,
                *index,
                threshold * 1000.0,
                window * 1000.0,
                *timeout,
                now,
            ),
            DevState(p) => {
                let i = self.port(*p)?;
                let state = self.ports_mut(i)?.state;
                reply(format!("DEVSTATE[{p}]={}", state.code()))
            }
            Value { port, index } | ValueF { port, index } => {
                let (i, _) = self.device(*port)?;
                if *index != 0 {
                    return Err(Status::IndexOutOfBounds);
                }
                let pos = self.ports_mut(i)?.position_um;
                if matches!(command, ValueF { .. }) {
                    reply(format!("VALUEF[{port}][{index}]={}", mm_text(pos)))
                } else {
                    let pos = pos.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
                    reply(format!("VALUE[{port}][{index}]={pos}"))
                }
            }
            GripCfg { port, index } => reply(self.recipe_line(*port, *index, false)?),
            GripCfgF { port, index } => reply(self.recipe_line(*port, *index, true)?),
            SetGripCfg {
                port,
                index,
                config,
            } => {
                self.set_recipe(*port, *index, config.clone())?;
                reply(self.recipe_line(*port, *index, false)?)
            }
            SetGripCfgF {
                port,
                index,
                config,
            } => {
                let scaled = scale_recipe(config)?;
                self.set_recipe(*port, *index, scaled)?;
                reply(self.recipe_line(*port, *index, true)?)
            }
        }
    }

    fn set_value(&mut self, port: PortNumber, index: u32, target_um: i64, now: Duration) -> Step {
        let (i, d) = self.device(port)?;
        let (stroke, speed) = (d.stroke_um(), d.speed_mm_per_s * 1000.0);
        if index != 0 {
            return Err(Status::IndexOutOfBounds);
        }
        let state = self.ports_mut(i)?.state;
        match state {
            DeviceState::NotInitialized => return Err(Status::NotInitialized),
            DeviceState::Fault => return Err(Status::StateConflict),
            _ => {}
        }
        if !(0..=stroke).contains(&target_um) {
            return Err(Status::RangeError);
        }
        self.start_motion(i, target_um, speed, state, now)?;
        ack()
    }

    fn wait_value(
        &mut self,
        port: PortNumber,
        index: u32,
        threshold_um: f64,
        window_um: f64,
        timeout: Duration,
        now: Duration,
    ) -> Step {
        let (i, _) = self.device(port)?;
        if index != 0 {
            return Err(Status::IndexOutOfBounds);
        }
        if window_um < 0.0 {
            return Err(Status::RangeError);
        }
        Ok(Outcome::Wait(Wait::Value {
            port: i,
            low: threshold_um - window_um / 2.0,
            high: threshold_um + window_um / 2.0,
            deadline: now + self.scaled(timeout),
        }))
    }

    /// The held reply, once it is due at `now`; `None` while it is still held.
    pub fn poll(&mut self, session: &Session, wait: &Wait, now: Duration) -> Option<String> {
        self.advance(now);
        let err = |s| Some(error_line(s, session.verbose));
        match wait {
            Wait::Motion { port, id } => {
                let p = self.ports.get(*port)?;
                if p.motion.as_ref().is_some_and(|m| m.id == *id) {
                    return None;
                }
                match p.history.iter().find(|(h, _)| h == id).map(|(_, end)| *end) {
                    Some(MotionEnd::Done(DeviceState::Fault)) => err(Status::CmdFailed),
                    Some(MotionEnd::Done(_)) => Some("ACK".to_owned()),
                    Some(MotionEnd::Aborted) | None => err(Status::CmdAborted),
                }
            }
            Wait::Transition { port, deadline } => {
                let p = self.ports.get(*port)?;
                if p.motion.is_none() {
                    Some(format!("WSTR[{port}]={}", p.state.code()))
                } else if now >= *deadline {
                    err(Status::Timeout)
                } else {
                    None
                }
            }
            Wait::Value {
                port,
                low,
                high,
                deadline,
            } => {
                let pos = self.ports.get(*port)?.position_um as f64;
                if (*low..=*high).contains(&pos) {
                    Some("ACK".to_owned())
                } else if now >= *deadline {
                    err(Status::Timeout)
                } else {
                    None
                }
            }
        }
    }

    /// When a held reply may next become due (the server sleeps until then unless another
    /// connection changes something first).
    pub fn next_wake(&self, wait: &Wait, now: Duration) -> Duration {
        let motion_end = |port: usize| {
            self.ports
                .get(port)
                .and_then(|p| p.motion.as_ref())
                .map(|m| m.end)
        };
        match wait {
            Wait::Motion { port, .. } => motion_end(*port).unwrap_or(now),
            Wait::Transition { port, deadline } => {
                motion_end(*port).map_or(*deadline, |end| end.min(*deadline))
            }
            Wait::Value { port, deadline, .. } => match motion_end(*port) {
                Some(_) => {
                    (now + self.scaled(VALUE_POLL).max(Duration::from_millis(1))).min(*deadline)
                }
                None => *deadline,
            },
        }
    }
}

fn scale_recipe(config: &GripConfigF) -> Result<GripConfig, Status> {
    let mut params = [0i32; 8];
    for (slot, v) in params.iter_mut().zip(config.params) {
        *slot = i32::try_from(um(v)).map_err(|_| Status::RangeError)?;
    }
    Ok(GripConfig {
        tag: config.tag.clone(),
        params,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::griplink::sim::parse::parse_command;

    fn run(c: &mut Controller, s: &mut Session, line: &str, now: Duration) -> Outcome {
        let cmd = parse_command(line).expect(line);
        c.execute(s, &cmd, now)
    }

    fn text(o: Outcome) -> String {
        match o {
            Outcome::Reply(r) => r,
            other => panic!("expected a reply, got {other:?}"),
        }
    }

    #[test]
    fn grip_cycle_in_simulated_time() {
        let cfg = SimConfig::et4().device(0, Some(SimDevice::ieg_55_020().with_part(12.0)));
        let mut c = Controller::new(cfg);
        let mut s = Session::default();
        let t0 = Duration::ZERO;
        assert_eq!(text(run(&mut c, &mut s, "GRIP(0,0)", t0)), "ERR 04");
        let Outcome::Wait(home) = run(&mut c, &mut s, "HOME(0)", t0) else {
            panic!("HOME must block")
        };
        assert_eq!(c.poll(&s, &home, t0), None);
        let t1 = c.next_wake(&home, t0);
        assert_eq!(t1, Duration::from_millis(400)); // 20 mm at 50 mm/s
        assert_eq!(c.poll(&s, &home, t1).as_deref(), Some("ACK"));
        assert_eq!(
            text(run(&mut c, &mut s, "DEVSTATE[0]?", t1)),
            "DEVSTATE[0]=2"
        );
        assert_eq!(
            text(run(
                &mut c,
                &mut s,
                "GRIPCFG[0][1]=[\"part\",5000,18000,50000,0,0,0,0,0]",
                t1
            )),
            "GRIPCFG[0][1]=[\"part\",5000,18000,50000,0,0,0,0,0]"
        );
        assert_eq!(text(run(&mut c, &mut s, "GRIP(0,1)", t1)), "ACK");
        let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", t1) else {
            panic!("WSTR must wait while moving")
        };
        let t2 = c.next_wake(&wstr, t1);
        assert_eq!(c.poll(&s, &wstr, t2).as_deref(), Some("WSTR[0]=5"));
        assert_eq!(
            text(run(&mut c, &mut s, "VALUE[0][0]?", t2)),
            "VALUE[0][0]=12000"
        );
        assert_eq!(
            text(run(&mut c, &mut s, "VALUEF[0][0]?", t2)),
            "VALUEF[0][0]=12"
        );
        assert_eq!(text(run(&mut c, &mut s, "GRIP(0,1)", t2)), "ERR 19");
        s.verbose = true;
        assert_eq!(
            text(run(&mut c, &mut s, "GRIP(0,1)", t2)),
            "ERR 19 Invalid state"
        );
        assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,1)", t2)), "ACK");
        let t3 = t2 + Duration::from_secs(1);
        assert_eq!(
            text(run(&mut c, &mut s, "DEVSTATE[0]?", t3)),
            "DEVSTATE[0]=3"
        );
        assert_eq!(
            text(run(&mut c, &mut s, "VALUEF[0][0]?", t3)),
            "VALUEF[0][0]=18"
        );
    }

    #[test]
    fn waitval_and_wstr_in_simulated_time() {
        let mut c = Controller::new(SimConfig {
            wstr_timeout: Duration::from_millis(100),
            ..SimConfig::et4()
        });
        let mut s = Session::default();
        let ms = Duration::from_millis;
        let Outcome::Wait(home) = run(&mut c, &mut s, "HOME(0)", ms(0)) else {
            panic!("HOME must block")
        };
        assert_eq!(c.poll(&s, &home, ms(400)).as_deref(), Some("ACK"));
        // Pre-position from 20 mm to 0 mm at 50 mm/s: 400 ms of motion.
        assert_eq!(text(run(&mut c, &mut s, "SETVALF(0,0,0)", ms(400))), "ACK");
        let Outcome::Wait(wait) = run(&mut c, &mut s, "WAITVAL(0,0,10000,1000,1000)", ms(400))
        else {
            panic!("WAITVAL must wait")
        };
        assert_eq!(c.poll(&s, &wait, ms(500)), None); // 15 mm
        assert_eq!(c.next_wake(&wait, ms(500)), ms(505));
        assert_eq!(c.poll(&s, &wait, ms(600)).as_deref(), Some("ACK")); // 10 mm
                                                                        // A window the fingers never reach: E_TIMEOUT at the WAITVAL's own timeout.
        let Outcome::Wait(wait) = run(&mut c, &mut s, "WAITVAL(0,0,30000,10,1000)", ms(600)) else {
            panic!("WAITVAL must wait")
        };
        assert_eq!(c.poll(&s, &wait, ms(1599)), None);
        assert_eq!(c.poll(&s, &wait, ms(1600)).as_deref(), Some("ERR 05"));
        // WSTR answers at once when nothing moves, and times out when a motion outlasts it.
        assert_eq!(text(run(&mut c, &mut s, "WSTR[0]?", ms(1600))), "WSTR[0]=2");
        c.set_time_scale(100.0);
        assert_eq!(
            text(run(&mut c, &mut s, "SETVAL(0,0,20000)", ms(1600))),
            "ACK"
        );
        let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", ms(1600)) else {
            panic!("WSTR must wait while moving")
        };
        // The motion takes 0.4 s x 100; WSTR gives up after 0.1 s x 100.
        let deadline = ms(1600) + Duration::from_secs(10);
        assert_eq!(c.next_wake(&wstr, ms(1600)), deadline);
        assert_eq!(c.poll(&s, &wstr, deadline - ms(1)), None);
        assert_eq!(c.poll(&s, &wstr, deadline).as_deref(), Some("ERR 05"));
    }

    #[test]
    fn ports_and_devices() {
        let mut c = Controller::new(SimConfig::et4().time_scale(0.0));
        let mut s = Session::default();
        let z = Duration::ZERO;
        assert_eq!(text(run(&mut c, &mut s, "DEVVID[1]?", z)), "DEVVID[1]=-1");
        assert_eq!(text(run(&mut c, &mut s, "DEVPID[1]?", z)), "ERR 04");
        assert_eq!(
            text(run(&mut c, &mut s, "DEVSTATE[1]?", z)),
            "DEVSTATE[1]=0"
        );
        assert_eq!(text(run(&mut c, &mut s, "DEVSTATE[4]?", z)), "ERR 11");
        assert_eq!(text(run(&mut c, &mut s, "DEVPID[2]?", z)), "DEVPID[2]=50");
        assert_eq!(text(run(&mut c, &mut s, "DEVASSERT(0,815,20)", z)), "ACK");
        assert_eq!(
            text(run(&mut c, &mut s, "DEVASSERT(0,815,50)", z)),
            "ERR 25"
        );
        let mut master = Controller::new(SimConfig {
            role: Role::Master,
            ..SimConfig::wpg()
        });
        assert_eq!(master.port_count(), 32);
        assert_eq!(
            text(run(&mut master, &mut s, "DEVVID[31]?", z)),
            "DEVVID[31]=-1"
        );
    }
}
