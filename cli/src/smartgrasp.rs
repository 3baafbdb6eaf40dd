//! `gripctl smartgrasp …`: the SCHUNK 2D Grasping-Kit's native protocol V3 (manual seed 002),
//! one request per command over a fresh connection.

mod image;

use std::time::Duration;

use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use gripper::smartgrasp::frame::PROTOCOL_VERSION;
use gripper::smartgrasp::{
    Client, ClientConfig, Error, GetGraspOutcome, Grasp, GraspFeedback, GraspMode, GraspRequest,
    ObjectCount, Pose, PoseFormat, RobotSystem, ServerState, Tool, DEFAULT_PORT,
};
use serde_json::{json, Value};

use crate::common::{split_name, with_default_port};
use crate::error::{CliError, DeviceCode, Kind};
use crate::output::Out;

/// Options of `gripctl smartgrasp`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The Smart Grasping server: HOST or HOST:PORT (port 42001 when omitted, manual 1.1).
    #[arg(long, default_value = "127.0.0.1")]
    addr: String,
    #[command(subcommand)]
    command: Command,
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
    /// SET_PROJECT: activate a project by index (manual 3.3.2.4).
    Project {
        /// The project's index.
        index: u32,
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
    /// The tool the robot grasps with.
    #[arg(long, value_enum, default_value_t = ToolArg::Exterior)]
    tool: ToolArg,
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

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ToolArg {
    /// Two-finger parallel gripper, outer grip.
    Exterior,
    /// Two-finger parallel gripper, inner grip.
    Interior,
    /// Suction, magnet or adhesion.
    Contact,
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
    execute(&addr, args.command, timeout, out)
        .await
        .map_err(|e| e.context(context))
}

async fn execute(
    addr: &str,
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
        let client = connect(addr, timeout).await?;
        client.robot_pose(pose).await.map_err(classify)?;
        return out.emit(
            format!("robot pose sent: {}: {pose}", pose.format()),
            json!({ "robot_pose": pose_json(&pose)? }),
        );
    }
    let client = connect(addr, timeout).await?;
    match command {
        Command::Version => {
            let version = client.get_protocol_version().await.map_err(classify)?;
            out.emit(
                format!("protocol version {version} (this client speaks {PROTOCOL_VERSION})"),
                json!({ "protocol_version": version, "client_version": PROTOCOL_VERSION }),
            )
        }
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
        Command::Grasp(grasp) => {
            open_session(&client, &grasp).await?;
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
                tool: match grasp.tool {
                    ToolArg::Exterior => Tool::Exterior,
                    ToolArg::Interior => Tool::Interior,
                    ToolArg::Contact => Tool::Contact,
                },
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

/// Connects without the opening sequence: `version` and `state` must work on a server that is
/// not ready, and each command checks what it needs itself.
async fn connect(addr: &str, timeout: Option<Duration>) -> Result<Client, CliError> {
    let mut config = ClientConfig::default();
    if let Some(t) = timeout {
        config.connect_timeout = t;
        config.query_timeout = t;
        config.detection_timeout = t;
    }
    Client::connect_without_opening(addr, config)
        .await
        .map_err(|e| classify(e).context("cannot connect"))
}

/// The manual's opening sequence (manual 6) before GET_GRASP: the server must speak V3 and be
/// OPERATIONAL, then register and set the project when asked to. Done here step by step (not by
/// `Client::connect`) so that a refused connection and a refused request read differently.
async fn open_session(client: &Client, grasp: &GraspArgs) -> Result<(), CliError> {
    check_operational(client).await?;
    if let Some(robot) = grasp.robot {
        client
            .register_client(robot.into())
            .await
            .map_err(classify)?;
    }
    if let Some(project) = grasp.project {
        client.set_project(project).await.map_err(classify)?;
    }
    Ok(())
}

/// Detection calls need a V3 server in OPERATIONAL state: say so instead of a bare ERROR.
async fn check_operational(client: &Client) -> Result<(), CliError> {
    let server_version = client.get_protocol_version().await.map_err(classify)?;
    if server_version < PROTOCOL_VERSION {
        return Err(classify(Error::ServerTooOld {
            server_version,
            client_version: PROTOCOL_VERSION,
        }));
    }
    let state = client.get_state().await.map_err(classify)?;
    if state != ServerState::Operational {
        return Err(classify(Error::NotOperational { state }));
    }
    Ok(())
}

/// The library's error as a `gripctl` error: the device's code where it gave one.
fn classify(e: Error) -> CliError {
    let message = e.to_string();
    match e {
        Error::Device { status, .. } => CliError::device(
            message,
            DeviceCode::from_display(u8::from(status).into(), &status.to_string()),
        ),
        Error::NotOperational { state } => CliError::device(
            message,
            DeviceCode::from_display(u8::from(state).into(), &state.to_string()),
        ),
        Error::ServerTooOld { .. } => CliError::new(Kind::Device, message),
        Error::Timeout { .. } => CliError::new(Kind::Timeout, message),
        Error::Io(io) if io.kind() == std::io::ErrorKind::TimedOut => {
            CliError::new(Kind::Timeout, io.to_string())
        }
        Error::Io(io) => CliError::new(Kind::Connection, io.to_string()),
        Error::ConnectionLost { .. } | Error::Closed | Error::ResponseLost { .. } => {
            CliError::new(Kind::Connection, message)
        }
        Error::MalformedReply(_) | Error::Pose(_) => CliError::new(Kind::Malformed, message),
        Error::InvalidArgument(_) => CliError::argument(message),
        // `smartgrasp::Error` is non-exhaustive: a kind added later still gets its message through.
        _ => CliError::new(Kind::Connection, message),
    }
}

/// An enumeration as JSON: the manual's name, its number and description.
fn named(number: u8, value: impl std::fmt::Display) -> Value {
    let text = value.to_string();
    let (name, description) = split_name(&text);
    json!({ "name": name, "code": number, "description": description })
}

fn grasp_report(g: &Grasp) -> Result<(String, Value), CliError> {
    let si = g.pose.to_si().map_err(|e| classify(e.into()))?;
    let [x, y, z] = metres(g.pose.position_um());
    let [qx, qy, qz, qw] = si.orientation.xyzw();
    let [cx, cy, cz] = g.center_offset_um.map(|um| f64::from(um) / 1000.0);
    let human = format!(
        "grasp: class {} instance {}, {}, tool {}\n\
         pose (m): x {x:.6}, y {y:.6}, z {z:.6}, q [{qx:.6}, {qy:.6}, {qz:.6}, {qw:.6}]\n\
         pose ({}): {}\n\
         stroke {:.3} mm, angle offset {:.4}°, centre offset [{cx:.3}, {cy:.3}, {cz:.3}] mm\n\
         {} objects in the scene, {} candidates",
        g.object_class,
        g.object_instance,
        g.grasp_mode,
        split_name(&g.tool.to_string()).0,
        g.pose.format(),
        g.pose,
        f64::from(g.stroke_um) / 1000.0,
        f64::from(g.angle_offset_udeg) * 1e-6,
        g.object_count,
        g.candidate_count,
    );
    let json = json!({
        "outcome": "GRASP",
        "grasp_mode": named(u8::from(g.grasp_mode), g.grasp_mode),
        "object_class": g.object_class,
        "object_instance": g.object_instance,
        "tool": named(u8::from(g.tool), g.tool),
        "stroke_m": f64::from(g.stroke_um) / 1e6,
        "stroke_um": g.stroke_um,
        "angle_offset_rad": g.angle_offset_rad(),
        "angle_offset_udeg": g.angle_offset_udeg,
        "center_offset_m": metres(g.center_offset_um),
        "center_offset_um": g.center_offset_um,
        "pose": pose_json(&g.pose)?,
        "object_count": g.object_count,
        "candidate_count": g.candidate_count,
    });
    Ok((human, json))
}

/// A pose as JSON: in metres with a unit quaternion, and in its own format, exact on the wire.
fn pose_json(pose: &Pose) -> Result<Value, CliError> {
    let si = pose.to_si().map_err(|e| classify(e.into()))?;
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
