//! The node's parameters: defaults, a ROS-style YAML parameter file and `-p name:=value` on the
//! command line (`--ros-args` as `ros2 run` passes it), in that order of precedence.
//!
//! A parameter file is what `ros2 param dump` writes and launch files pass:
//!
//! ```yaml
//! gripper:            # the node's name, its full name (/left/gripper) or /** for every node
//!   ros__parameters:
//!     joint_names: [left_finger_joint, right_finger_joint]
//! ```

use std::collections::BTreeMap;
use std::fmt;

use serde_yaml::Value;

/// Which device the node drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceKind {
    /// A Weiss WSG gripper (binary protocol).
    Wsg,
    /// One port of a Weiss GRIPLINK controller (ASCII protocol).
    Griplink,
    /// The SCHUNK 2D Grasping-Kit.
    SmartGrasp,
}

impl DeviceKind {
    fn parse(s: &str) -> Result<Self, String> {
        match s {
            "wsg" => Ok(DeviceKind::Wsg),
            "griplink" => Ok(DeviceKind::Griplink),
            "smartgrasp" => Ok(DeviceKind::SmartGrasp),
            other => Err(format!(
                "unknown device {other:?} (wsg, griplink or smartgrasp)"
            )),
        }
    }
}

/// How a goal's `command.position` and the joint positions are measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PositionConvention {
    /// The opening width between the fingers, m (the default).
    Width,
    /// Each finger's distance from the centre, m: half the opening (the public URDFs' finger
    /// joints).
    Finger,
}

impl PositionConvention {
    /// The ROS position (m) of an opening of `width_mm`.
    pub fn from_width_mm(self, width_mm: f64) -> f64 {
        match self {
            PositionConvention::Width => width_mm / 1000.0,
            PositionConvention::Finger => width_mm / 2000.0,
        }
    }

    /// The opening in mm a ROS position (m) stands for.
    pub fn to_width_mm(self, position_m: f64) -> f64 {
        match self {
            PositionConvention::Width => position_m * 1000.0,
            PositionConvention::Finger => position_m * 2000.0,
        }
    }
}

/// Which request/reply mapping services and actions use on DDS.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mapping {
    /// What `rmw_cyclonedds_cpp` uses.
    Cyclone,
    /// What `rmw_fastrtps_cpp` (the default RMW) and `rmw_connextdds` use.
    Enhanced,
}

impl Mapping {
    /// As ros2-client names it.
    pub fn to_ros2(self) -> ros2_client::ServiceMapping {
        match self {
            Mapping::Cyclone => ros2_client::ServiceMapping::Cyclone,
            Mapping::Enhanced => ros2_client::ServiceMapping::Enhanced,
        }
    }
}

/// The name of every parameter [`Params::set`] takes.
pub const NAMES: [&str; 23] = [
    "device",
    "transport",
    "address",
    "serial_port",
    "baud_rate",
    "griplink_port",
    "joint_names",
    "joint_multipliers",
    "joint_offsets",
    "position_convention",
    "joint_states_rate_hz",
    "speed_m_per_s",
    "goal_tolerance_m",
    "default_effort_n",
    "grasp_on_close",
    "allow_stalling",
    "auto_acknowledge_fast_stop",
    "reconnect",
    "service_mapping",
    "frame_id",
    "object_class",
    "dds_interfaces",
    "use_sim_time",
];

/// Every parameter of the node (the README has the table).
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// The node's name (`__node`).
    pub node_name: String,
    /// The node's namespace (`__ns`), absolute.
    pub namespace: String,
    /// The device.
    pub device: DeviceKind,
    /// WSG transport: `tcp`, `udp` or `serial` (the binary protocol), or `text` (the text
    /// interface, GCL, over TCP).
    pub transport: String,
    /// `host:port` of the WSG (TCP/UDP), the GRIPLINK or the Grasping-Kit.
    pub address: String,
    /// Serial device of a WSG on RS-232.
    pub serial_port: String,
    /// Baud rate of the serial port.
    pub baud_rate: u32,
    /// The GRIPLINK port (0..=3) this node drives.
    pub griplink_port: u8,
    /// The joints `joint_states` names (see [`crate::joint_map`]).
    pub joint_names: Vec<String>,
    /// Joint position per metre of opening, one per joint name; empty: derived from the
    /// number of names (see [`crate::joint_map`]).
    pub joint_multipliers: Vec<f64>,
    /// Joint position at a closed gripper, one per joint name; empty: all 0.
    pub joint_offsets: Vec<f64>,
    /// See [`PositionConvention`].
    pub position_convention: PositionConvention,
    /// `joint_states` rate, Hz.
    pub joint_states_rate_hz: f64,
    /// Finger speed of goals, m/s (of the opening).
    pub speed_m_per_s: f64,
    /// A goal is reached when the position is this close, m.
    pub goal_tolerance_m: f64,
    /// GRIPLINK: the grip force when a goal's `max_effort` is 0, N (0: such a goal is rejected).
    pub default_effort_n: f64,
    /// WSG: a closing goal that stops on a part grasps it there (0x25), so that it is held
    /// with the grasping force; without, the fingers stay where they stopped.
    pub grasp_on_close: bool,
    /// A goal whose fingers stall before its position (a part held, a blocked axis) is
    /// SUCCEEDED rather than ABORTED: gripper_action_controller's parameter, default false as
    /// there. Can be set while the node runs.
    pub allow_stalling: bool,
    /// Acknowledge a FAST STOP found after a reconnect (default: report it, leave it).
    pub auto_acknowledge_fast_stop: bool,
    /// Reconnect a lost link (WSG over TCP or serial, GRIPLINK).
    pub reconnect: bool,
    /// Request/reply mapping; `None` (`auto`, the default): each service served both ways,
    /// each request answered in the mapping of the peer that sent it.
    pub service_mapping: Option<Mapping>,
    /// `use_sim_time` (launch files pass it to every node): accepted; the node stamps with the
    /// system clock all the same.
    pub use_sim_time: bool,
    /// Topic and service remapping rules (`-r FROM:=TO`), both sides fully qualified.
    pub remaps: Vec<(String, String)>,
    /// DDS domain (`ROS_DOMAIN_ID`, 0 when unset).
    pub domain_id: u16,
    /// The IP addresses of the interfaces DDS uses (all when empty), e.g. `[127.0.0.1]` to
    /// keep discovery and traffic on this machine.
    pub dds_interfaces: Vec<std::net::IpAddr>,
    /// Grasping-Kit: the object class to ask grasps for (0: any).
    pub object_class: u16,
    /// Grasping-Kit: the frame of the grasp poses.
    pub frame_id: String,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            node_name: "gripper".into(),
            namespace: "/".into(),
            device: DeviceKind::Wsg,
            transport: "tcp".into(),
            address: String::new(),
            serial_port: String::new(),
            baud_rate: 115_200,
            griplink_port: 0,
            joint_names: crate::joint_map::DEFAULT_JOINT_NAMES
                .map(str::to_owned)
                .to_vec(),
            joint_multipliers: Vec::new(),
            joint_offsets: Vec::new(),
            position_convention: PositionConvention::Width,
            joint_states_rate_hz: 50.0,
            speed_m_per_s: 0.05,
            goal_tolerance_m: 0.001,
            grasp_on_close: true,
            allow_stalling: false,
            default_effort_n: 0.0,
            auto_acknowledge_fast_stop: false,
            reconnect: true,
            service_mapping: None,
            use_sim_time: false,
            remaps: Vec::new(),
            domain_id: 0,
            dds_interfaces: Vec::new(),
            object_class: 0,
            frame_id: "grasping_kit".into(),
        }
    }
}

/// The parameters that take effect while the node runs: set through the parameter services
/// and read where they are used.
#[derive(Clone, Debug, Default)]
pub struct Live {
    /// [`Params::allow_stalling`].
    pub allow_stalling: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Live {
    /// The live parameters, at their start-up values.
    pub fn new(params: &Params) -> Self {
        Live {
            allow_stalling: std::sync::Arc::new(params.allow_stalling.into()),
        }
    }
}

/// What the command line asks for.
#[derive(Clone, Debug, PartialEq)]
pub struct Cli {
    /// The parameters, all sources applied.
    pub params: Params,
    /// `--sim KIND`: start the crate's simulator of that device in process.
    pub sim: Option<DeviceKind>,
    /// `--sim wsg:MODEL` (50, 32, 25 or 70): the simulated WSG's model, so that its stroke is
    /// the one the description (`wsg.launch.py model:=…`) gives its joints; a WSG 50 without.
    pub sim_model: Option<gripper::wsg::sim::Model>,
    /// `--log-level LEVEL` (or `--log-level NODE:=LEVEL` naming this node): the console's and
    /// `/rosout`'s level, as a `tracing` level (`fatal` is `error`).
    pub log_level: Option<tracing::Level>,
    /// Log records go to `/rosout` (`--disable-rosout-logs` turns it off).
    pub rosout_logs: bool,
    /// Log records go to the console (`--disable-stdout-logs` turns it off).
    pub console_logs: bool,
    /// What was accepted but ignored or is doubtful, to be logged once logging runs: an unknown
    /// parameter, a flag the node does not act on, `use_sim_time: true`.
    pub warnings: Vec<String>,
}

/// A parameter error: which parameter, what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError(pub String);

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ParamError {}

/// The usage text (`--help`).
pub const USAGE: &str = "usage: gripper-ros2 [--sim wsg|griplink|smartgrasp] [--params-file FILE] \
[-p NAME:=VALUE]... [--ros-args [-r __ns:=/NS] [-r __node:=NAME] [-r FROM:=TO]... \
[-p NAME:=VALUE]... [--params-file FILE]... [--log-level LEVEL] [--enable|disable-rosout-logs] \
[--enable|disable-stdout-logs] [--]]";

/// The ROS arguments that take no value and that the node does not act on: accepted with a
/// warning (rcl's `--enable-external-lib-logs` and its opposite).
const IGNORED_FLAGS: [&str; 2] = ["--enable-external-lib-logs", "--disable-external-lib-logs"];
/// The ROS arguments with a value that the node does not act on: accepted with a warning
/// (the security enclave; log files and a log configuration: the node logs to the console and
/// `/rosout`).
const IGNORED_WITH_VALUE: [&str; 4] = ["-e", "--enclave", "--log-file-name", "--log-config-file"];

/// `NODE:RULE` or `RULE`: rcl's node-specific prefix (`-r gripper:__ns:=/left`,
/// `-p gripper:rate:=1`). The prefix is the part before the first `:` when that comes before
/// the `:=`.
fn node_prefix(rule: &str) -> (Option<&str>, &str) {
    let assign = rule.find(":=").unwrap_or(rule.len());
    match rule[..assign].find(':') {
        Some(i) => (Some(&rule[..i]), &rule[i + 1..]),
        None => (None, rule),
    }
}

impl Cli {
    /// A command line of these parameters, without a simulator, logging as by default.
    pub fn for_params(params: Params) -> Cli {
        Cli {
            params,
            sim: None,
            sim_model: None,
            log_level: None,
            rosout_logs: true,
            console_logs: true,
            warnings: Vec::new(),
        }
    }

    /// Parses the arguments (without the program name), as rclcpp does: every standard
    /// `--ros-args` flag is honoured or accepted with a warning ([`Cli::warnings`]), so
    /// nothing rclcpp accepts makes the node exit. `env` gives `ROS_DOMAIN_ID`; `read` reads a
    /// parameter file. Errors: a malformed argument, a bad value for a known parameter.
    pub fn parse(
        args: &[String],
        env: impl Fn(&str) -> Option<String>,
        read: impl Fn(&str) -> Result<String, String>,
    ) -> Result<Cli, ParamError> {
        let mut sim = None;
        let mut sim_model = None;
        let mut files = Vec::new();
        let mut overrides: Vec<(Option<String>, String, Value)> = Vec::new();
        let mut remaps: Vec<(Option<String>, String, String)> = Vec::new();
        let mut warnings = Vec::new();
        let mut log_level = None;
        let (mut rosout_logs, mut console_logs) = (true, true);
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| ParamError(format!("{flag} needs a value")))
            };
            match a.as_str() {
                "--ros-args" | "--" => {}
                "--sim" => {
                    let v = value("--sim")?;
                    let (kind, model) = match v.split_once(':') {
                        Some((kind, model)) => (kind, Some(model)),
                        None => (v.as_str(), None),
                    };
                    let kind = DeviceKind::parse(kind).map_err(ParamError)?;
                    sim_model = match (kind, model) {
                        (_, None) => None,
                        (DeviceKind::Wsg, Some(model)) => {
                            Some(wsg_model(model).ok_or_else(|| {
                                ParamError(format!("--sim {v}: the WSG model is 50, 32, 25 or 70"))
                            })?)
                        }
                        (_, Some(_)) => {
                            return Err(ParamError(format!(
                                "--sim {v}: only the WSG simulator takes a model"
                            )))
                        }
                    };
                    sim = Some(kind);
                }
                "--params-file" => files.push(value("--params-file")?),
                "-p" | "--param" => {
                    let v = value("-p")?;
                    let (node, rule) = node_prefix(&v);
                    let (k, v) = split_assignment(rule)?;
                    overrides.push((node.map(str::to_owned), k, parse_scalar(&v)?));
                }
                "-r" | "--remap" => {
                    let v = value("-r")?;
                    let (node, rule) = node_prefix(&v);
                    let (from, to) = split_assignment(rule)?;
                    remaps.push((node.map(str::to_owned), from, to));
                }
                "--log-level" => log_level = Some(value("--log-level")?),
                "--enable-rosout-logs" => rosout_logs = true,
                "--disable-rosout-logs" => rosout_logs = false,
                "--enable-stdout-logs" => console_logs = true,
                "--disable-stdout-logs" => console_logs = false,
                flag if IGNORED_FLAGS.contains(&flag) => {
                    warnings.push(format!("{flag}: ignored (no external logging library)"))
                }
                flag if IGNORED_WITH_VALUE.contains(&flag) => {
                    let v = value(flag)?;
                    warnings.push(format!("{flag} {v}: ignored"));
                }
                other => warnings.push(format!("argument {other:?} ignored; {USAGE}")),
            }
        }
        let mut params = Params::default();
        if let Some(kind) = sim {
            params.device = kind;
        }
        if let Some(d) = env("ROS_DOMAIN_ID").filter(|d| !d.trim().is_empty()) {
            params.domain_id = d
                .trim()
                .parse::<u16>()
                .ok()
                .filter(|d| *d <= 232)
                .ok_or_else(|| ParamError(format!("ROS_DOMAIN_ID {d:?} is not in 0..=232")))?;
        }
        // rcl matches a node-specific prefix against the node's name as the code gives it.
        let original = params.node_name.clone();
        let ours = |node: &Option<String>| node.as_deref().is_none_or(|n| n == original);
        // Remappings first: a parameter file's section is chosen by the node's name.
        for (_, from, to) in remaps.iter().filter(|(n, _, _)| ours(n)) {
            match from.as_str() {
                "__ns" => params.namespace = check_namespace(to)?,
                "__node" | "__name" => params.node_name = check_node_name(to)?,
                _ => {}
            }
        }
        for (_, from, to) in remaps.iter().filter(|(n, _, _)| ours(n)) {
            if !matches!(from.as_str(), "__ns" | "__node" | "__name") {
                let rule = (params.expand(from)?, params.expand(to)?);
                params.remaps.push(rule);
            }
        }
        for f in files {
            let text = read(&f).map_err(|e| ParamError(format!("{f}: {e}")))?;
            for (k, v) in file_params(&text, &params.node_name, &params.namespace)
                .map_err(|e| ParamError(format!("{f}: {e}")))?
            {
                params.set_or_warn(&k, &v, &mut warnings)?;
            }
        }
        for (_, k, v) in overrides.iter().filter(|(n, _, _)| ours(n)) {
            params.set_or_warn(k, v, &mut warnings)?;
        }
        if params.use_sim_time {
            warnings.push(
                "use_sim_time: true is accepted, but the node stamps with the system clock: it \
                 drives a real (or a real-time simulated) gripper"
                    .into(),
            );
        }
        params.validate()?;
        let log_level = match log_level {
            None => None,
            Some(l) => parse_log_level(&l, &params, &mut warnings)?,
        };
        Ok(Cli {
            params,
            sim,
            sim_model,
            log_level,
            rosout_logs,
            console_logs,
            warnings,
        })
    }
}

/// The WSG model of `--sim wsg:MODEL`.
fn wsg_model(model: &str) -> Option<gripper::wsg::sim::Model> {
    use gripper::wsg::sim::Model;
    match model {
        "50" => Some(Model::Wsg50),
        "32" => Some(Model::Wsg32),
        "25" => Some(Model::Wsg25),
        "70" => Some(Model::Wsg70),
        _ => None,
    }
}

/// `--log-level LEVEL` or `--log-level LOGGER:=LEVEL` (rcl). The node's logger is its name,
/// with the namespace in dots (`left.gripper`), as rclcpp names it; another logger's level is
/// ignored with a warning.
fn parse_log_level(
    arg: &str,
    params: &Params,
    warnings: &mut Vec<String>,
) -> Result<Option<tracing::Level>, ParamError> {
    let (logger, level) = match arg.split_once(":=") {
        Some((logger, level)) => (Some(logger), level),
        None => (None, arg),
    };
    let level = match level.to_ascii_lowercase().as_str() {
        "debug" => tracing::Level::DEBUG,
        "info" => tracing::Level::INFO,
        "warn" => tracing::Level::WARN,
        "error" | "fatal" => tracing::Level::ERROR,
        // rcutils' RCUTILS_LOG_SEVERITY_UNSET: the logger keeps its default level.
        "unset" => return Ok(None),
        other => {
            return Err(ParamError(format!(
                "--log-level {other:?}: expected debug, info, warn, error, fatal or unset"
            )))
        }
    };
    let ours = params.logger_name();
    match logger {
        Some(l) if l != ours && l != params.node_name => {
            warnings.push(format!(
                "--log-level {arg}: no logger {l:?} here (the node's logger is {ours:?}); ignored"
            ));
            Ok(None)
        }
        _ => Ok(Some(level)),
    }
}

impl Params {
    /// The fully qualified node name, e.g. `/gripper` or `/left/gripper`.
    pub fn fully_qualified_name(&self) -> String {
        if self.namespace == "/" {
            format!("/{}", self.node_name)
        } else {
            format!("{}/{}", self.namespace, self.node_name)
        }
    }

    /// Sets one parameter from a YAML value.
    pub fn set(&mut self, name: &str, v: &Value) -> Result<(), ParamError> {
        let bad = |what: &str| ParamError(format!("parameter {name}: expected {what}, got {v:?}"));
        let string = || v.as_str().map(str::to_owned).ok_or_else(|| bad("a string"));
        let float = || v.as_f64().ok_or_else(|| bad("a number"));
        let boolean = || v.as_bool().ok_or_else(|| bad("true or false"));
        match name {
            "device" => self.device = DeviceKind::parse(&string()?).map_err(ParamError)?,
            "transport" => self.transport = string()?,
            "address" => self.address = string()?,
            "serial_port" => self.serial_port = string()?,
            "baud_rate" => {
                self.baud_rate = v
                    .as_u64()
                    .and_then(|b| u32::try_from(b).ok())
                    .ok_or_else(|| bad("a baud rate"))?
            }
            "griplink_port" => {
                self.griplink_port = v
                    .as_u64()
                    .and_then(|p| u8::try_from(p).ok())
                    .ok_or_else(|| bad("a port number 0..=3"))?
            }
            "joint_names" => {
                self.joint_names = v
                    .as_sequence()
                    .and_then(|s| s.iter().map(|n| n.as_str().map(str::to_owned)).collect())
                    .ok_or_else(|| bad("a list of strings"))?
            }
            "joint_multipliers" => {
                self.joint_multipliers = float_list(v).ok_or_else(|| bad("a list of numbers"))?
            }
            "joint_offsets" => {
                self.joint_offsets = float_list(v).ok_or_else(|| bad("a list of numbers"))?
            }
            "position_convention" => {
                self.position_convention = match string()?.as_str() {
                    "width" => PositionConvention::Width,
                    "finger" => PositionConvention::Finger,
                    _ => return Err(bad("width or finger")),
                }
            }
            "joint_states_rate_hz" => self.joint_states_rate_hz = float()?,
            "speed_m_per_s" => self.speed_m_per_s = float()?,
            "goal_tolerance_m" => self.goal_tolerance_m = float()?,
            "default_effort_n" => self.default_effort_n = float()?,
            "grasp_on_close" => self.grasp_on_close = boolean()?,
            "allow_stalling" => self.allow_stalling = boolean()?,
            "auto_acknowledge_fast_stop" => self.auto_acknowledge_fast_stop = boolean()?,
            "reconnect" => self.reconnect = boolean()?,
            "service_mapping" => {
                self.service_mapping = match string()?.as_str() {
                    "cyclone" => Some(Mapping::Cyclone),
                    "enhanced" => Some(Mapping::Enhanced),
                    "" | "auto" => None,
                    _ => return Err(bad("cyclone, enhanced or auto")),
                }
            }
            "frame_id" => self.frame_id = string()?,
            "object_class" => {
                self.object_class = v
                    .as_u64()
                    .and_then(|c| u16::try_from(c).ok())
                    .ok_or_else(|| bad("a class id 0..=65535"))?
            }
            "dds_interfaces" => {
                self.dds_interfaces = v
                    .as_sequence()
                    .and_then(|s| {
                        s.iter()
                            .map(|a| a.as_str().and_then(|a| a.parse().ok()))
                            .collect()
                    })
                    .ok_or_else(|| bad("a list of IP addresses"))?
            }
            // ros2 launch passes this one to every node.
            "use_sim_time" => self.use_sim_time = boolean()?,
            other => return Err(ParamError(format!("unknown parameter {other:?}"))),
        }
        Ok(())
    }

    /// Whether `name` is one of the node's parameters.
    pub fn is_known(name: &str) -> bool {
        NAMES.contains(&name)
    }

    /// [`Params::set`], but an unknown parameter is a warning, not an error (rclcpp ignores a
    /// parameter override the node does not declare, e.g. one of a shared `/**` section).
    fn set_or_warn(
        &mut self,
        name: &str,
        v: &Value,
        warnings: &mut Vec<String>,
    ) -> Result<(), ParamError> {
        if Params::is_known(name) {
            self.set(name, v)
        } else {
            warnings.push(format!("unknown parameter {name:?} ignored"));
            Ok(())
        }
    }

    /// The node's logger name, as rclcpp forms it: the namespace and the name joined by dots
    /// (`gripper`, `left.gripper`).
    pub fn logger_name(&self) -> String {
        self.fully_qualified_name()
            .trim_start_matches('/')
            .replace('/', ".")
    }

    /// A topic or service name expanded as rcl expands it: absolute as given, `~` and `~/x`
    /// under the node's fully qualified name, anything else under its namespace.
    pub fn expand(&self, name: &str) -> Result<String, ParamError> {
        let full = if name.starts_with('/') {
            name.to_owned()
        } else if name == "~" {
            self.fully_qualified_name()
        } else if let Some(rest) = name.strip_prefix("~/") {
            format!("{}/{rest}", self.fully_qualified_name())
        } else if self.namespace == "/" {
            format!("/{name}")
        } else {
            format!("{}/{name}", self.namespace)
        };
        let ok = full.len() > 1
            && !full.ends_with('/')
            && !full.contains("//")
            && full.trim_start_matches('/').split('/').all(|t| {
                !t.starts_with(|c: char| c.is_ascii_digit())
                    && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            });
        if ok {
            Ok(full)
        } else {
            Err(ParamError(format!("{name:?} is not a valid ROS name")))
        }
    }

    /// `name` (fully qualified) after the first remapping rule that matches it, as rcl applies
    /// them (the first match wins).
    pub fn remap(&self, name: &str) -> String {
        self.remaps
            .iter()
            .find(|(from, _)| from == name)
            .map_or_else(|| name.to_owned(), |(_, to)| to.clone())
    }

    fn validate(&self) -> Result<(), ParamError> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ParamError(format!(
                    "{name} must be a positive number, got {v}"
                )))
            }
        };
        positive("joint_states_rate_hz", self.joint_states_rate_hz)?;
        // At most 1 kHz: a period shorter than a millisecond would only burn the CPU. At least
        // 0.1 Hz, so that the period is a Duration (1e-300 Hz would overflow it and panic).
        if !(0.1..=1000.0).contains(&self.joint_states_rate_hz) {
            return Err(ParamError(
                "joint_states_rate_hz must be within 0.1..=1000".into(),
            ));
        }
        positive("speed_m_per_s", self.speed_m_per_s)?;
        positive("goal_tolerance_m", self.goal_tolerance_m)?;
        if !self.default_effort_n.is_finite() || self.default_effort_n < 0.0 {
            return Err(ParamError(
                "default_effort_n must be 0 or a positive force".into(),
            ));
        }
        crate::joint_map::JointMap::new(self)?;
        if self.griplink_port > 3 {
            return Err(ParamError("griplink_port must be 0..=3".into()));
        }
        Ok(())
    }
}

/// A YAML list of numbers (integers taken as numbers: `[-1, 1]` is what a user types).
fn float_list(v: &Value) -> Option<Vec<f64>> {
    v.as_sequence()?.iter().map(Value::as_f64).collect()
}

fn split_assignment(s: &str) -> Result<(String, String), ParamError> {
    s.split_once(":=")
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .ok_or_else(|| ParamError(format!("{s:?}: expected NAME:=VALUE")))
}

/// A value as `ros2 run` reads it: YAML (so `[a, b]`, `true`, `1.5` and `text` all work).
fn parse_scalar(s: &str) -> Result<Value, ParamError> {
    serde_yaml::from_str(s).map_err(|e| ParamError(format!("{s:?}: {e}")))
}

fn check_namespace(ns: &str) -> Result<String, ParamError> {
    ros2_client::NodeName::new(ns, "n")
        .map(|_| ns.to_owned())
        .map_err(|e| ParamError(format!("namespace {ns:?}: {e}")))
}

fn check_node_name(name: &str) -> Result<String, ParamError> {
    ros2_client::NodeName::new("/", name)
        .map(|_| name.to_owned())
        .map_err(|e| ParamError(format!("node name {name:?}: {e}")))
}

/// The parameters a file gives this node: the `/**` section first, then the node's own (by
/// name or full name), so that the more specific one wins.
fn file_params(text: &str, node: &str, namespace: &str) -> Result<Vec<(String, Value)>, String> {
    let doc: BTreeMap<String, Value> = serde_yaml::from_str(text).map_err(|e| e.to_string())?;
    let full = if namespace == "/" {
        format!("/{node}")
    } else {
        format!("{namespace}/{node}")
    };
    let mut out = Vec::new();
    // Wildcard sections first (`/**`, `/**/gripper`, `/*/gripper`), then the node's own (by
    // name or full name), so that the more specific one wins.
    let wild: Vec<&str> = doc
        .keys()
        .map(String::as_str)
        .filter(|k| k.contains('*') && matches_pattern(k, &full))
        .collect();
    for key in wild.into_iter().chain([node, full.as_str()]) {
        let Some(section) = doc.get(key) else {
            continue;
        };
        let params = section
            .get("ros__parameters")
            .and_then(Value::as_mapping)
            .ok_or_else(|| format!("section {key:?} has no ros__parameters map"))?;
        for (k, v) in params {
            let k = k
                .as_str()
                .ok_or_else(|| format!("parameter name {k:?} is not a string"))?;
            out.push((k.to_owned(), v.clone()));
        }
    }
    Ok(out)
}

/// Whether a parameter file's node pattern matches the fully qualified node name `full`, as
/// rcl's wildcards do: `*` is one name token, `**` any number of them (none included).
fn matches_pattern(pattern: &str, full: &str) -> bool {
    fn go(p: &[&str], n: &[&str]) -> bool {
        match (p.first(), n.first()) {
            (None, None) => true,
            (Some(&"**"), _) => go(&p[1..], n) || (!n.is_empty() && go(p, &n[1..])),
            (Some(&"*"), Some(_)) => go(&p[1..], &n[1..]),
            (Some(a), Some(b)) if a == b => go(&p[1..], &n[1..]),
            _ => false,
        }
    }
    let tokens = |s: &str| -> Vec<String> {
        s.trim_start_matches('/')
            .split('/')
            .map(str::to_owned)
            .collect()
    };
    let (p, n) = (tokens(pattern), tokens(full));
    let p: Vec<&str> = p.iter().map(String::as_str).collect();
    let n: Vec<&str> = n.iter().map(String::as_str).collect();
    go(&p, &n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_owned).collect()
    }

    fn parse(s: &str, file: &str) -> Result<Cli, ParamError> {
        let file = file.to_owned();
        Cli::parse(&args(s), |_| None, move |_| Ok(file.clone()))
    }

    #[test]
    fn defaults_and_the_sim_flag() {
        let cli = parse("--sim griplink", "").unwrap();
        assert_eq!(cli.sim, Some(DeviceKind::Griplink));
        assert_eq!(cli.params.device, DeviceKind::Griplink);
        assert_eq!(cli.params.fully_qualified_name(), "/gripper");
        assert_eq!(cli.params.service_mapping, None);
        assert_eq!(cli.sim_model, None);
        // The WSG simulator's model, as wsg.launch.py passes it with its description's.
        let cli = parse("--sim wsg:32", "").unwrap();
        assert_eq!(cli.sim, Some(DeviceKind::Wsg));
        assert_eq!(cli.sim_model, Some(gripper::wsg::sim::Model::Wsg32));
        assert!(parse("--sim wsg:99", "").is_err());
        assert!(parse("--sim griplink:32", "").is_err());
    }

    #[test]
    fn remaps_file_and_overrides_in_order() {
        let file = "/**:\n  ros__parameters:\n    joint_states_rate_hz: 10.0\n    frame_id: a\n\
                    /left/hand:\n  ros__parameters:\n    joint_names: [l, r]\n    frame_id: b\n";
        let cli = parse(
            "--ros-args -r __ns:=/left -r __node:=hand --params-file f.yaml -p frame_id:=c \
             -p position_convention:=finger -p dds_interfaces:=[127.0.0.1]",
            file,
        )
        .unwrap();
        let p = cli.params;
        assert_eq!(p.fully_qualified_name(), "/left/hand");
        assert_eq!(p.joint_states_rate_hz, 10.0);
        assert_eq!(p.joint_names, vec!["l".to_owned(), "r".to_owned()]);
        assert_eq!(p.frame_id, "c");
        assert_eq!(p.position_convention, PositionConvention::Finger);
        assert_eq!(
            p.dds_interfaces,
            vec![std::net::IpAddr::from([127, 0, 0, 1])]
        );
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        for bad in [
            "-p joint_states_rate_hz:=0",
            "-p joint_states_rate_hz:=.nan",
            "-p joint_states_rate_hz:=1e-300",
            "-p joint_names:=[]",
            "-p griplink_port:=7",
            "-p baud_rate:=-1",
            "-p use_sim_time:=maybe",
            "-p frame_id",
            "-r __ns:=no_slash",
            "-r joint_states:=2bad",
            "--log-level loud",
            "--sim robot",
            "--sim",
        ] {
            assert!(parse(bad, "").is_err(), "{bad} was accepted");
        }
        assert!(parse("--params-file f", "- not a map").is_err());
    }

    /// What rclcpp accepts does not stop the node: unknown parameters (also in a shared `/**`
    /// section), `use_sim_time`, flags the node does not act on, unknown arguments.
    #[test]
    fn what_rclcpp_accepts_is_accepted_with_warnings() {
        let file = "/**:\n  ros__parameters:\n    use_sim_time: true\n    robot_description: x\n";
        let cli = parse(
            "--ros-args -p nope:=1 --params-file f.yaml -e /enclave --log-file-name x \
             --enable-external-lib-logs --disable-rosout-logs --disable-stdout-logs \
             --log-config-file c --unknown -- --also",
            file,
        )
        .unwrap();
        assert!(cli.params.use_sim_time);
        assert!(!cli.rosout_logs && !cli.console_logs);
        let w = cli.warnings.join("\n");
        for expected in [
            "\"nope\"",
            "\"robot_description\"",
            "use_sim_time",
            "-e /enclave",
            "--log-file-name",
            "--enable-external-lib-logs",
            "--log-config-file",
            "\"--unknown\"",
            "\"--also\"",
        ] {
            assert!(w.contains(expected), "no warning about {expected}: {w}");
        }
        // A known parameter's bad value is still an error (rclcpp's declare throws).
        assert!(parse("--ros-args -p allow_stalling:=3", "").is_err());
    }

    #[test]
    fn log_levels_for_this_node_or_another() {
        let level = |s: &str| parse(s, "").unwrap().log_level;
        assert_eq!(
            level("--ros-args --log-level debug"),
            Some(tracing::Level::DEBUG)
        );
        assert_eq!(
            level("--ros-args --log-level FATAL"),
            Some(tracing::Level::ERROR)
        );
        assert_eq!(
            level("--ros-args -r __ns:=/left --log-level left.gripper:=warn"),
            Some(tracing::Level::WARN)
        );
        // rcutils accepts `unset` (the default level), so the node does too.
        assert_eq!(level("--ros-args --log-level unset"), None);
        assert_eq!(level("--ros-args --log-level gripper:=UNSET"), None);
        let cli = parse("--ros-args --log-level rcl:=debug", "").unwrap();
        assert_eq!(cli.log_level, None);
        assert!(cli.warnings.join("").contains("rcl"), "{:?}", cli.warnings);
    }

    /// rcl's remapping: names expanded with the node's namespace and name, node-specific
    /// rules only for this node, the first matching rule wins.
    #[test]
    fn topic_and_service_remaps() {
        let cli = parse(
            "--ros-args -r __ns:=/left -r joint_states:=/joint_states \
             -r ~/gripper_cmd:=/hand/gripper_cmd -r other:diagnostics:=/elsewhere \
             -r gripper:~/home:=reference -r joint_states:=/second",
            "",
        )
        .unwrap();
        let p = &cli.params;
        assert_eq!(p.remap("/left/joint_states"), "/joint_states");
        assert_eq!(p.remap("/left/gripper/gripper_cmd"), "/hand/gripper_cmd");
        assert_eq!(p.remap("/left/gripper/home"), "/left/reference");
        assert_eq!(p.remap("/diagnostics"), "/diagnostics");
        assert_eq!(p.remap("/left/gripper/stop"), "/left/gripper/stop");
        // A node-specific __ns for another node changes nothing.
        let cli = parse("--ros-args -r other:__ns:=/x -r gripper:__node:=hand", "").unwrap();
        assert_eq!(cli.params.fully_qualified_name(), "/hand");
    }

    #[test]
    fn parameter_file_wildcards() {
        for (key, matches) in [
            ("/**", true),
            ("/**/gripper", true),
            ("/*/gripper", true),
            ("/left/*", true),
            ("/right/*", false),
            ("/*", false),
            ("/**/hand", false),
        ] {
            let file = format!("{key}:\n  ros__parameters:\n    frame_id: from_file\n");
            let cli = parse("--ros-args -r __ns:=/left --params-file f", &file).unwrap();
            assert_eq!(cli.params.frame_id == "from_file", matches, "{key}");
        }
    }

    #[test]
    fn mapping_and_domain_from_the_environment() {
        // RMW_IMPLEMENTATION fixes nothing: each request is answered in its peer's mapping.
        let env = |k: &str| match k {
            "RMW_IMPLEMENTATION" => Some("rmw_cyclonedds_cpp".to_owned()),
            "ROS_DOMAIN_ID" => Some("42".to_owned()),
            _ => None,
        };
        let cli = Cli::parse(&[], env, |_| Err("no file".into())).unwrap();
        assert_eq!(cli.params.service_mapping, None);
        assert_eq!(cli.params.domain_id, 42);
        let cli = Cli::parse(&args("-p service_mapping:=enhanced"), env, |_| {
            Err(String::new())
        });
        assert_eq!(cli.unwrap().params.service_mapping, Some(Mapping::Enhanced));
        let bad = |k: &str| (k == "ROS_DOMAIN_ID").then(|| "300".to_owned());
        assert!(Cli::parse(&[], bad, |_| Err(String::new())).is_err());
    }

    #[test]
    fn joint_mapping_lists_from_the_command_line_and_a_file() {
        let file = "/**:\n  ros__parameters:\n    joint_names: [a, b, c]\n    \
                    joint_multipliers: [-1, 1, 0.5]\n";
        let p = parse("--params-file f -p joint_offsets:=[0.1,0,-0.1]", file)
            .unwrap()
            .params;
        assert_eq!(p.joint_multipliers, vec![-1.0, 1.0, 0.5]);
        assert_eq!(p.joint_offsets, vec![0.1, 0.0, -0.1]);
        // The lists must match the names: three names and two multipliers is refused.
        assert!(parse("-p joint_names:=[a,b,c] -p joint_multipliers:=[1,1]", "").is_err());
        assert!(parse("-p joint_multipliers:=[a,b]", "").is_err());
        assert!(parse("-p joint_offsets:=1.0", "").is_err());
    }

    #[test]
    fn conventions_convert_both_ways() {
        assert_eq!(PositionConvention::Width.from_width_mm(40.0), 0.04);
        assert_eq!(PositionConvention::Finger.from_width_mm(40.0), 0.02);
        assert_eq!(PositionConvention::Finger.to_width_mm(0.02), 40.0);
    }
}
