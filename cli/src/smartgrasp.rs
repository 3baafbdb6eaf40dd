//! `gripctl smartgrasp …`: the SCHUNK 2D Grasping-Kit's native protocol, V3 (manual seed 002) or
//! V4 (known from SCHUNK's public KUKA example, PROTOCOLS.md 2b), one request per command over a
//! fresh connection. V4 is used when the server offers it, unless `--protocol 3` pins V3.

mod image;

use std::time::Duration;

use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use gripper::smartgrasp::frame::{v4, PROTOCOL_VERSION};
use gripper::smartgrasp::{
    Client, ClientConfig, Error, GetGraspOutcome, Grasp, GraspFeedback, GraspMode, GraspRequest,
    Malformed, ObjectCount, Pose, PoseError, PoseFormat, RobotSystem, SelectionCriterion,
    ServerState, Tool, DEFAULT_PORT,
};
use serde_json::{json, Value};

use crate::common::{split_name, with_default_port};
use crate::error::{classify, CliError, DeviceCode};
use crate::output::Out;

/// Options of `gripctl smartgrasp`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The Smart Grasping server: HOST or HOST:PORT (port 42001 when omitted, manual 1.1).
    #[arg(long, default_value = "127.0.0.1")]
    addr: String,
    /// The protocol version to speak: the highest the server offers (3 or 4), or pinned.
    #[arg(long, value_enum, default_value_t = Protocol::Auto)]
    protocol: Protocol,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Protocol {
    /// The highest version both speak (GET_PROTOCOL_VERSION first).
    Auto,
    /// V3 (manual seed 002).
    #[value(name = "3")]
    V3,
    /// V4 (SCHUNK's public KUKA example).
    #[value(name = "4")]
    V4,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// GET_PROTOCOL_VERSION: the server's highest protocol version (manual 3.3.2.1).
    Version,
    /// GET_STATE: whether the server is ready (manual 3.3.2.2).
    State,
    /// REGISTER_CLIENT: tell the server which robot system this is (manual 3.3.2.3).
    Register {
        /// The robot system.
        #[arg(value_enum)]
        robot: Robot,
    },
    /// SET_PROJECT: activate a project by index (V3, manual 3.3.2.4) or by the ID seen in the
    /// web frontend (V4).
    Project {
        /// The project's index (V3) or ID (V4).
        index: u32,
    },
    /// SET_TOOL (V4 only): choose the tool by the ID configured on the device.
    Tool {
        /// The tool ID seen in the web frontend.
        id: u16,
    },
    /// SET_WORKSPACE (V4 only): choose the workspace by the ID configured on the device.
    Workspace {
        /// The workspace ID seen in the web frontend.
        id: u16,
    },
    /// GET_GRASP: a grasp for the current scene, in metres and in the robot's format
    /// (manual 3.3.3.1). NO_OBJECT and NO_GRASP are results (exit status 0), not failures.
    Grasp(GraspArgs),
    /// GET_OBJECT_COUNT: objects in the scene, and those of a class (manual 3.3.4.1).
    Count {
        /// Object class to count candidates of; 0 = every class.
        #[arg(long, default_value_t = 0)]
        class: u16,
    },
    /// GRASP_FEEDBACK: the result of the last grasp (manual 3.3.3.2).
    Feedback {
        /// ok: the part was picked (it leaves the scene); bad: it was not.
        #[arg(value_enum)]
        result: Feedback,
    },
    /// ROBOT_POSE: tell the server the end effector's pose in the robot base frame
    /// (manual 3.3.5.1).
    RobotPose(RobotPoseArgs),
    /// The latest detection result, an image the kit serves over HTTP at
    /// /monitor/latest_result (the simulator: its scene, with `sim smartgrasp --http`).
    Image(image::ImageArgs),
}

#[derive(Debug, ClapArgs)]
struct GraspArgs {
    /// Which grasps may be returned.
    #[arg(long, value_enum, default_value_t = Mode::Auto)]
    mode: Mode,
    /// Object class to grasp; 0 = any class.
    #[arg(long, default_value_t = 0)]
    class: u16,
    /// The tool: V3 names it in the request (exterior, interior, contact; default exterior);
    /// V4 chooses it by ID with SET_TOOL first (a number; default: the server's current tool).
    #[arg(long, value_parser = parse_tool)]
    tool: Option<ToolArg>,
    /// V4 only: choose this workspace ID first (SET_WORKSPACE).
    #[arg(long)]
    workspace: Option<u16>,
    /// V4 only: the selection criterion (its values are not public; SCHUNK's example sends 1 to
    /// 3). Ignored by V3.
    #[arg(long, default_value_t = 1)]
    selection: u8,
    /// Pose format of the answer [default: the --robot's own, else abc].
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Register as this robot system before asking (REGISTER_CLIENT).
    #[arg(long, value_enum)]
    robot: Option<Robot>,
    /// Activate this project before asking (SET_PROJECT).
    #[arg(long)]
    project: Option<u32>,
}

#[derive(Debug, ClapArgs)]
struct RobotPoseArgs {
    /// The format of the values.
    #[arg(long, value_enum)]
    format: Format,
    /// X Y Z in mm, then the rotation: W P R (wpr) or A B C (abc) in degrees, RX RY RZ in
    /// radians (axis-angle), or qx qy qz qw (quaternion).
    #[arg(required = true, num_args = 6..=7, allow_negative_numbers = true)]
    values: Vec<f64>,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Robot {
    Ur,
    Kuka,
    Yaskawa,
    Fanuc,
    Abb,
    Horst,
    SiemensPlc,
}

impl From<Robot> for RobotSystem {
    fn from(r: Robot) -> RobotSystem {
        match r {
            Robot::Ur => RobotSystem::Ur,
            Robot::Kuka => RobotSystem::Kuka,
            Robot::Yaskawa => RobotSystem::Yaskawa,
            Robot::Fanuc => RobotSystem::Fanuc,
            Robot::Abb => RobotSystem::Abb,
            Robot::Horst => RobotSystem::Horst,
            Robot::SiemensPlc => RobotSystem::SiemensPlc,
        }
    }
}

impl Robot {
    /// The pose format the robot's controller writes poses in (manual 5).
    fn native_format(self) -> Format {
        match self {
            Robot::Kuka => Format::Abc,
            Robot::Fanuc | Robot::Yaskawa => Format::Wpr,
            Robot::Ur => Format::AxisAngle,
            Robot::Abb | Robot::Horst | Robot::SiemensPlc => Format::Quaternion,
        }
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Mode {
    /// ACTIVE_GRASP: the object's active grasp only.
    Active,
    /// ANY_GRASP: any user-defined grasp.
    Any,
    /// AUTO_GRASP: any user-defined grasp, else model-free planning.
    Auto,
}

/// `--tool`: a V3 tool name, or a V4 tool ID.
#[derive(Debug, Clone, Copy)]
enum ToolArg {
    /// V3: the tool enumeration (3.3.3.1).
    Named(Tool),
    /// V4: the tool ID for SET_TOOL.
    Id(u16),
}

fn parse_tool(text: &str) -> Result<ToolArg, String> {
    match text {
        "exterior" => Ok(ToolArg::Named(Tool::Exterior)),
        "interior" => Ok(ToolArg::Named(Tool::Interior)),
        "contact" => Ok(ToolArg::Named(Tool::Contact)),
        other => other.parse().map(ToolArg::Id).map_err(|_| {
            format!("{other:?} is neither exterior, interior, contact (V3) nor a tool ID (V4)")
        }),
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Format {
    /// Position, quaternion qx qy qz qw.
    Quaternion,
    /// Position, rotation vector (Universal Robots).
    AxisAngle,
    /// Position, W P R about the fixed axes (FANUC, Yaskawa).
    Wpr,
    /// Position, A B C about z, y', x'' (KUKA).
    Abc,
}

impl From<Format> for PoseFormat {
    fn from(f: Format) -> PoseFormat {
        match f {
            Format::Quaternion => PoseFormat::Quaternion,
            Format::AxisAngle => PoseFormat::AxisAngle,
            Format::Wpr => PoseFormat::Wpr,
            Format::Abc => PoseFormat::Abc,
        }
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Feedback {
    Ok,
    Bad,
}

/// Runs one `gripctl smartgrasp` command.
pub async fn run(args: Args, timeout: Option<Duration>, out: Out) -> Result<(), CliError> {
    let addr = with_default_port(&args.addr, DEFAULT_PORT);
    let context = format!("smartgrasp {addr}");
    execute(&addr, args.protocol, args.command, timeout, out)
        .await
        .map_err(|e| e.context(context))
}

async fn execute(
    addr: &str,
    protocol: Protocol,
    command: Command,
    timeout: Option<Duration>,
    out: Out,
) -> Result<(), CliError> {
    if let Command::Image(args) = command {
        return image::fetch(addr, args, timeout, out).await;
    }
    if let Command::RobotPose(args) = &command {
        // The values are checked before connecting: a typo needs no server to be reported.
        let pose = pose_from_args(args)?;
        let client = connect(addr, protocol, timeout).await?;
        client.robot_pose(pose).await.map_err(classify)?;
        return out.emit(
            format!("robot pose sent: {}: {pose}", pose.format()),
            json!({ "robot_pose": pose_json(&pose)? }),
        );
    }
    if let Command::Version = command {
        // Asked as V3, which every server since V3 answers in full (manual 1.3, 3.3.2.1).
        let client = connect_as(addr, Some(PROTOCOL_VERSION), timeout).await?;
        let version = client.get_protocol_version().await.map_err(classify)?;
        let highest = v4::PROTOCOL_VERSION;
        return out.emit(
            format!("protocol version {version} (this client speaks 3 and {highest})"),
            json!({ "protocol_version": version, "client_version": highest }),
        );
    }
    let client = connect(addr, protocol, timeout).await?;
    match command {
        Command::Version => Ok(()), // answered above
        Command::State => {
            let state = client.get_state().await.map_err(classify)?;
            out.emit(state, json!({ "state": named(u8::from(state), state) }))
        }
        Command::Register { robot } => {
            let robot = RobotSystem::from(robot);
            client.register_client(robot).await.map_err(classify)?;
            out.emit(
                format!("registered as {robot}"),
                json!({ "registered": named(u8::from(robot), robot) }),
            )
        }
        Command::Project { index } => {
            client.set_project(index).await.map_err(classify)?;
            out.emit(
                format!("project {index} active"),
                json!({ "project": index }),
            )
        }
        Command::Tool { id } => {
            client.set_tool(id).await.map_err(classify)?;
            out.emit(format!("tool {id} active"), json!({ "tool_id": id }))
        }
        Command::Workspace { id } => {
            client.set_workspace(id).await.map_err(classify)?;
            out.emit(
                format!("workspace {id} active"),
                json!({ "workspace_id": id }),
            )
        }
        Command::Grasp(grasp) => {
            let tool = open_session(&client, &grasp).await?;
            let format = grasp
                .format
                .or(grasp.robot.map(Robot::native_format))
                .unwrap_or(Format::Abc);
            let request = GraspRequest {
                grasp_mode: match grasp.mode {
                    Mode::Active => GraspMode::ActiveGrasp,
                    Mode::Any => GraspMode::AnyGrasp,
                    Mode::Auto => GraspMode::AutoGrasp,
                },
                object_class: grasp.class,
                tool,
                selection_criterion: SelectionCriterion(grasp.selection),
                pose_format: format.into(),
            };
            match client.get_grasp(request).await.map_err(classify)? {
                GetGraspOutcome::Grasp(g) => {
                    let (human, json) = grasp_report(&g)?;
                    out.emit(human, json)
                }
                GetGraspOutcome::NoObject => out.emit(
                    "no object in the scene (NO_OBJECT)",
                    json!({ "outcome": "NO_OBJECT" }),
                ),
                GetGraspOutcome::NoGrasp => out.emit(
                    "objects found, but no grasp for them (NO_GRASP)",
                    json!({ "outcome": "NO_GRASP" }),
                ),
                // Asking for a class the project does not have is the caller's mistake.
                GetGraspOutcome::InvalidObjectClass => {
                    let code = gripper::smartgrasp::ResponseCode::InvalidObjectClass;
                    Err(CliError::device(
                        format!(
                            "the server refused GET_GRASP for class {}: {code}",
                            grasp.class
                        ),
                        DeviceCode::from_display(u8::from(code).into(), &code.to_string()),
                    ))
                }
            }
        }
        Command::Count { class } => {
            check_operational(&client).await?;
            let count = client.get_object_count(class).await.map_err(classify)?;
            out.emit(count_text(&count), count_json(&count))
        }
        Command::Feedback { result } => {
            let feedback = match result {
                Feedback::Ok => GraspFeedback::Ok,
                Feedback::Bad => GraspFeedback::Bad,
            };
            client.grasp_feedback(feedback).await.map_err(classify)?;
            out.emit(
                format!("feedback sent: {feedback}"),
                json!({ "feedback": named(u8::from(feedback), feedback) }),
            )
        }
        Command::RobotPose(_) | Command::Image(_) => Ok(()), // answered above
    }
}

/// Connects without the opening sequence (`state` must work on a server that is not ready, and
/// each command checks what it needs itself), in the version `protocol` asks for. `Auto` asks
/// GET_PROTOCOL_VERSION as V3 on a first connection (every server since V3 answers it) and
/// speaks V4 on a second one when the server offers it.
async fn connect(
    addr: &str,
    protocol: Protocol,
    timeout: Option<Duration>,
) -> Result<Client, CliError> {
    let version = match protocol {
        Protocol::V3 => PROTOCOL_VERSION,
        Protocol::V4 => v4::PROTOCOL_VERSION,
        Protocol::Auto => {
            let probe = connect_as(addr, Some(PROTOCOL_VERSION), timeout).await?;
            let offered = probe.get_protocol_version().await.map_err(classify)?;
            // Release the probe's connection before opening the next.
            let _ = probe.close().await;
            if offered < PROTOCOL_VERSION {
                return Err(classify(Error::ServerTooOld {
                    server_version: offered,
                    client_version: PROTOCOL_VERSION,
                }));
            }
            offered.min(v4::PROTOCOL_VERSION)
        }
    };
    connect_as(addr, Some(version), timeout).await
}

async fn connect_as(
    addr: &str,
    version: Option<u16>,
    timeout: Option<Duration>,
) -> Result<Client, CliError> {
    let mut config = ClientConfig {
        protocol_version: version,
        ..ClientConfig::default()
    };
    if let Some(t) = timeout {
        config.connect_timeout = t;
        config.query_timeout = t;
        config.detection_timeout = t;
    }
    Client::connect_without_opening(addr, config)
        .await
        .map_err(|e| classify(e).context("cannot connect"))
}

/// The manual's opening sequence (manual 6) before GET_GRASP: the server must be OPERATIONAL,
/// then register, set the project, and with V4 the tool and workspace, when asked to. Done here
/// step by step (not by `Client::connect`) so that a refused connection and a refused request
/// read differently. Returns the V3 tool for the request.
async fn open_session(client: &Client, grasp: &GraspArgs) -> Result<Tool, CliError> {
    check_operational(client).await?;
    if let Some(robot) = grasp.robot {
        // Informational (manual 3.3.2.3): a refusal does not stop the grasp (the command
        // `register` reports it).
        match client.register_client(robot.into()).await {
            Ok(()) | Err(Error::Device { .. }) => {}
            Err(e) => return Err(classify(e)),
        }
    }
    if let Some(project) = grasp.project {
        client.set_project(project).await.map_err(classify)?;
    }
    let v4 = client.protocol_version() >= v4::PROTOCOL_VERSION;
    let tool = match (grasp.tool, v4) {
        (None, _) => Tool::Exterior,
        (Some(ToolArg::Named(tool)), false) => tool,
        (Some(ToolArg::Id(id)), true) => {
            client.set_tool(id).await.map_err(classify)?;
            Tool::Exterior
        }
        (Some(ToolArg::Named(_)), true) => {
            return Err(CliError::argument(
                "the server speaks V4, which chooses the tool by ID: --tool <number>",
            ))
        }
        (Some(ToolArg::Id(_)), false) => {
            return Err(CliError::argument(
                "the server speaks V3, which names the tool: --tool exterior|interior|contact",
            ))
        }
    };
    if let Some(workspace) = grasp.workspace {
        client.set_workspace(workspace).await.map_err(classify)?;
    }
    Ok(tool)
}

/// Detection calls need an OPERATIONAL server: say so instead of a bare ERROR.
async fn check_operational(client: &Client) -> Result<(), CliError> {
    let state = client.get_state().await.map_err(classify)?;
    if state != ServerState::Operational {
        return Err(classify(Error::NotOperational { state }));
    }
    Ok(())
}

impl crate::error::Classify for Error {
    fn kind(&self) -> gripper::ErrorKind {
        Error::kind(self)
    }
    /// The response code the server refused with, or the state it is in instead of
    /// OPERATIONAL.
    fn code(&self) -> Option<DeviceCode> {
        match self {
            Error::Device { status, .. } => Some(DeviceCode::from_display(
                u8::from(*status).into(),
                &status.to_string(),
            )),
            Error::NotOperational { state } => Some(DeviceCode::from_display(
                u8::from(*state).into(),
                &state.to_string(),
            )),
            _ => None,
        }
    }
}

/// An enumeration as JSON: the manual's name, its number and description.
fn named(number: u8, value: impl std::fmt::Display) -> Value {
    let text = value.to_string();
    let (name, description) = split_name(&text);
    json!({ "name": name, "code": number, "description": description })
}

fn grasp_report(g: &Grasp) -> Result<(String, Value), CliError> {
    let si = g.pose.to_si().map_err(malformed_pose)?;
    let [x, y, z] = metres(g.pose.position_um());
    let [qx, qy, qz, qw] = si.orientation.xyzw();
    let mm = |um: i32| f64::from(um) / 1000.0;
    let [cx, cy] = g.center_offset_um.map(mm);
    let mut centre = vec![cx, cy];
    centre.extend(g.center_offset_z_um.map(mm));
    let centre = centre
        .iter()
        .map(|v| format!("{v:.3}"))
        .collect::<Vec<_>>()
        .join(", ");
    // What only one version delivers (V3: tool echo and angle offset; V4: reference frame and
    // object offset), on a line of its own.
    let mut extra = Vec::new();
    if let Some(tool) = g.tool {
        extra.push(format!("tool {}", split_name(&tool.to_string()).0));
    }
    if let Some(udeg) = g.angle_offset_udeg {
        extra.push(format!("angle offset {:.4}°", f64::from(udeg) * 1e-6));
    }
    if let Some(frame) = g.reference_frame {
        extra.push(format!("reference frame {}", frame.0));
    }
    if let Some(o) = g.object_offset {
        extra.push(format!(
            "object offset [{:.3}, {:.3}] mm, rz {:.4}°",
            mm(o.x_um),
            mm(o.y_um),
            f64::from(o.rz_udeg) * 1e-6
        ));
    }
    let human = format!(
        "grasp: class {} instance {}, {}\n\
         pose (m): x {x:.6}, y {y:.6}, z {z:.6}, q [{qx:.6}, {qy:.6}, {qz:.6}, {qw:.6}]\n\
         pose ({}): {}\n\
         stroke {:.3} mm, centre offset [{centre}] mm\n\
         {}\n\
         {} objects in the scene, {} candidates",
        g.object_class,
        g.object_instance,
        g.grasp_mode,
        g.pose.format(),
        g.pose,
        f64::from(g.stroke_um) / 1000.0,
        extra.join(", "),
        g.object_count,
        g.candidate_count,
    );
    let mut centre_um: Vec<i32> = g.center_offset_um.to_vec();
    centre_um.extend(g.center_offset_z_um);
    let json = json!({
        "outcome": "GRASP",
        "grasp_mode": named(u8::from(g.grasp_mode), g.grasp_mode),
        "object_class": g.object_class,
        "object_instance": g.object_instance,
        "tool": g.tool.map(|t| named(u8::from(t), t)),
        "stroke_m": f64::from(g.stroke_um) / 1e6,
        "stroke_um": g.stroke_um,
        "angle_offset_rad": g.angle_offset_rad(),
        "angle_offset_udeg": g.angle_offset_udeg,
        "center_offset_m": centre_um.iter().map(|&v| f64::from(v) / 1e6).collect::<Vec<_>>(),
        "center_offset_um": centre_um,
        "reference_frame": g.reference_frame.map(|f| f.0),
        "object_offset": g.object_offset.map(|o| json!({
            "x_um": o.x_um, "y_um": o.y_um, "rz_udeg": o.rz_udeg,
        })),
        "pose": pose_json(&g.pose)?,
        "object_count": g.object_count,
        "candidate_count": g.candidate_count,
    });
    Ok((human, json))
}

/// A pose the server sent that cannot be read: a malformed reply.
fn malformed_pose(e: PoseError) -> CliError {
    classify(Error::MalformedReply(Malformed::Pose(e)))
}

/// A pose as JSON: in metres with a unit quaternion, and in its own format, exact on the wire.
fn pose_json(pose: &Pose) -> Result<Value, CliError> {
    let si = pose.to_si().map_err(malformed_pose)?;
    Ok(json!({
        "position_m": metres(pose.position_um()),
        "orientation_xyzw": si.orientation.xyzw(),
        "format": pose.format().to_string(),
        "wire": pose.to_wire(),
        "robot": pose.to_string(),
    }))
}

/// µm to metres, dividing (not multiplying by 1e-6) so that 450000 µm prints as 0.45.
fn metres(um: [i32; 3]) -> [f64; 3] {
    um.map(|v| f64::from(v) / 1e6)
}

fn count_text(c: &ObjectCount) -> String {
    let class = match c.object_class {
        0 => "any class".to_owned(),
        n => format!("class {n}"),
    };
    format!(
        "{} objects in the scene, {} candidates of {class}",
        c.object_count, c.candidate_count
    )
}

fn count_json(c: &ObjectCount) -> Value {
    json!({
        "object_class": c.object_class,
        "object_count": c.object_count,
        "candidate_count": c.candidate_count,
    })
}

/// The command line's values (mm and degrees, radians or a plain quaternion) as the wire's
/// integers (µm and µdeg, µrad, quaternion × 10^6; manual 5).
fn pose_from_args(args: &RobotPoseArgs) -> Result<Pose, CliError> {
    let wanted = match args.format {
        Format::Quaternion => 7,
        _ => 6,
    };
    if args.values.len() != wanted {
        return Err(CliError::argument(format!(
            "a {} pose has {wanted} values (X Y Z and the rotation), not {}",
            PoseFormat::from(args.format),
            args.values.len()
        )));
    }
    let mut wire = [0i32; 7];
    for (i, (slot, &value)) in wire.iter_mut().zip(&args.values).enumerate() {
        // Position mm → µm; every rotation unit is scaled by 10^6 on the wire.
        let scale = if i < 3 { 1e3 } else { 1e6 };
        *slot = to_i32(value * scale).ok_or_else(|| {
            CliError::argument(format!(
                "pose value {value} does not fit the wire's 32-bit integer"
            ))
        })?;
    }
    Pose::from_wire(args.format.into(), wire).map_err(|e| CliError::argument(e.to_string()))
}

fn to_i32(v: f64) -> Option<i32> {
    let v = v.round();
    (v.is_finite() && v >= f64::from(i32::MIN) && v <= f64::from(i32::MAX)).then_some(v as i32)
}
