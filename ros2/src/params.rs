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
    /// The mapping for an `RMW_IMPLEMENTATION` value: Cyclone for `rmw_cyclonedds_cpp`,
    /// Enhanced otherwise (Fast DDS is the default RMW when the variable is unset).
    pub fn for_rmw(rmw: Option<&str>) -> Self {
        match rmw {
            Some("rmw_cyclonedds_cpp") => Mapping::Cyclone,
            _ => Mapping::Enhanced,
        }
    }

    /// As ros2-client names it.
    pub fn to_ros2(self) -> ros2_client::ServiceMapping {
        match self {
            Mapping::Cyclone => ros2_client::ServiceMapping::Cyclone,
            Mapping::Enhanced => ros2_client::ServiceMapping::Enhanced,
        }
    }
}

/// Every parameter of the node (the README has the table).
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// The node's name (`__node`).
    pub node_name: String,
    /// The node's namespace (`__ns`), absolute.
    pub namespace: String,
    /// The device.
    pub device: DeviceKind,
    /// WSG transport: `tcp`, `udp` or `serial`.
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
    /// WSG: a closing goal grasps a part (0x25) rather than pre-positions (0x21).
    pub grasp_on_close: bool,
    /// Acknowledge a FAST STOP found after a reconnect (default: report it, leave it).
    pub auto_acknowledge_fast_stop: bool,
    /// Reconnect a lost link (WSG over TCP or serial, GRIPLINK).
    pub reconnect: bool,
    /// Request/reply mapping; `None`: from `RMW_IMPLEMENTATION`.
    pub service_mapping: Option<Mapping>,
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
            default_effort_n: 0.0,
            auto_acknowledge_fast_stop: false,
            reconnect: true,
            service_mapping: None,
            domain_id: 0,
            dds_interfaces: Vec::new(),
            object_class: 0,
            frame_id: "grasping_kit".into(),
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
[-p NAME:=VALUE]... [--ros-args [-r __ns:=/NS] [-r __node:=NAME] [-p NAME:=VALUE]... \
[--params-file FILE]...]";

impl Cli {
    /// Parses the arguments (without the program name). `env` gives `ROS_DOMAIN_ID` and
    /// `RMW_IMPLEMENTATION`; `read` reads a parameter file.
    pub fn parse(
        args: &[String],
        env: impl Fn(&str) -> Option<String>,
        read: impl Fn(&str) -> Result<String, String>,
    ) -> Result<Cli, ParamError> {
        let mut sim = None;
        let mut files = Vec::new();
        let mut overrides: Vec<(String, Value)> = Vec::new();
        let mut remaps: Vec<(String, String)> = Vec::new();
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| ParamError(format!("{flag} needs a value")))
            };
            match a.as_str() {
                "--ros-args" | "--" => {}
                "--sim" => sim = Some(DeviceKind::parse(&value("--sim")?).map_err(ParamError)?),
                "--params-file" => files.push(value("--params-file")?),
                "-p" | "--param" => {
                    let (k, v) = split_assignment(&value("-p")?)?;
                    overrides.push((k, parse_scalar(&v)?));
                }
                "-r" | "--remap" => remaps.push(split_assignment(&value("-r")?)?),
                other => return Err(ParamError(format!("unknown argument {other:?}; {USAGE}"))),
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
        // Remappings first: a parameter file's section is chosen by the node's name.
        for (from, to) in remaps {
            match from.as_str() {
                "__ns" => params.namespace = check_namespace(&to)?,
                "__node" | "__name" => params.node_name = check_node_name(&to)?,
                other => {
                    return Err(ParamError(format!(
                        "remapping {other:?} is not supported (only __ns and __node)"
                    )))
                }
            }
        }
        let mapping_from_env = Mapping::for_rmw(env("RMW_IMPLEMENTATION").as_deref());
        for f in files {
            let text = read(&f).map_err(|e| ParamError(format!("{f}: {e}")))?;
            for (k, v) in file_params(&text, &params.node_name, &params.namespace)
                .map_err(|e| ParamError(format!("{f}: {e}")))?
            {
                params.set(&k, &v)?;
            }
        }
        for (k, v) in overrides {
            params.set(&k, &v)?;
        }
        if params.service_mapping.is_none() {
            params.service_mapping = Some(mapping_from_env);
        }
        params.validate()?;
        Ok(Cli { params, sim })
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
            "use_sim_time" => {
                if boolean()? {
                    return Err(ParamError(
                        "use_sim_time: true is not supported (the node stamps with the system clock)"
                            .into(),
                    ));
                }
            }
            other => return Err(ParamError(format!("unknown parameter {other:?}"))),
        }
        Ok(())
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
    for key in ["/**", node, full.as_str()] {
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
        assert_eq!(cli.params.service_mapping, Some(Mapping::Enhanced));
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
            "-p nope:=1",
            "-p frame_id",
            "-r __ns:=no_slash",
            "--sim robot",
            "--sim",
        ] {
            assert!(parse(bad, "").is_err(), "{bad} was accepted");
        }
        assert!(parse("--params-file f", "- not a map").is_err());
    }

    #[test]
    fn mapping_and_domain_from_the_environment() {
        let env = |k: &str| match k {
            "RMW_IMPLEMENTATION" => Some("rmw_cyclonedds_cpp".to_owned()),
            "ROS_DOMAIN_ID" => Some("42".to_owned()),
            _ => None,
        };
        let cli = Cli::parse(&[], env, |_| Err("no file".into())).unwrap();
        assert_eq!(cli.params.service_mapping, Some(Mapping::Cyclone));
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
