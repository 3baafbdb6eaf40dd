//! Picks every part out of the bin with a SCHUNK 2D Grasping-Kit: opens the session (version
//! negotiation, state, register as KUKA, project 0, and with V4 the tool and workspace), then
//! GET_GRASP → (move the robot) → GRASP_FEEDBACK OK until the server reports no object, printing
//! each grasp pose in metres and in the robot's own format.
//!
//! Speaks V4 when the server offers it (SET_TOOL, SET_WORKSPACE, a selection criterion), V3
//! otherwise; `--tool`, `--workspace` and `--selection` only matter with V4.
//!
//! ```text
//! cargo run --example smartgrasp_pick                          # against the in-process simulator
//! cargo run --example smartgrasp_pick -- --addr 10.0.0.5:42001 # against a server (port optional)
//! cargo run --example smartgrasp_pick -- --format wpr          # FANUC's W, P, R instead of ABC
//! cargo run --example smartgrasp_pick -- --tool 1 --workspace 0 --selection 1
//! ```

use std::process::ExitCode;

use gripper::smartgrasp::sim::{SimConfig, SimServer};
use gripper::smartgrasp::{
    Client, ClientConfig, GetGraspOutcome, GraspFeedback, GraspMode, GraspRequest, PoseFormat,
    RobotSystem, SelectionCriterion, Tool,
};

/// A real bin is refilled or re-imaged between picks; this bounds the loop if a server never
/// reports an empty scene.
const MAX_PICKS: usize = 1000;

struct Args {
    addr: Option<String>,
    format: PoseFormat,
    /// V4: SET_TOOL's id.
    tool: Option<u16>,
    /// V4: SET_WORKSPACE's id.
    workspace: Option<u16>,
    /// V4: GET_GRASP's selection criterion.
    selection: u8,
}

#[tokio::main]
async fn main() -> ExitCode {
    let args = match parse_args(std::env::args().skip(1)) {
        Ok(args) => args,
        Err(message) => {
            eprintln!("smartgrasp_pick: {message}");
            eprintln!("usage: smartgrasp_pick [--addr HOST:PORT] [--format abc|wpr|quaternion|axis-angle] [--tool ID] [--workspace ID] [--selection N]");
            return ExitCode::from(2);
        }
    };
    match run(args).await {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("smartgrasp_pick: {message}");
            ExitCode::FAILURE
        }
    }
}

async fn run(args: Args) -> Result<(), String> {
    // Without --addr, a simulator in this process (kept alive until the end of `run`).
    let (_simulator, addr) = match args.addr {
        Some(addr) => (None, addr),
        None => {
            // GRASP_FEEDBACK OK stands in for the robot taking the part out, so that the bin
            // empties (a simulator option; SCHUNK's server ignores feedback).
            let config = SimConfig {
                feedback_removes_objects: true,
                ..SimConfig::default()
            };
            let sim = SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("cannot start the simulator: {e}"))?;
            let addr = sim.local_addr().to_string();
            println!("simulator on {addr}");
            (Some(sim), addr)
        }
    };
    let robot = match args.format {
        PoseFormat::Wpr => RobotSystem::Fanuc,
        PoseFormat::AxisAngle => RobotSystem::Ur,
        _ => RobotSystem::Kuka,
    };
    let config = ClientConfig {
        robot_system: Some(robot),
        project_index: Some(0),
        tool_id: args.tool,
        workspace_id: args.workspace,
        ..ClientConfig::default()
    };
    let client = Client::connect(addr.as_str(), config)
        .await
        .map_err(|e| format!("opening the session with {addr} failed: {e}"))?;
    let count = client
        .get_object_count(0)
        .await
        .map_err(|e| format!("GET_OBJECT_COUNT failed: {e}"))?;
    println!(
        "connected to {addr} as {robot}, protocol v{} (the server speaks up to v{}); {} objects in the scene",
        client.protocol_version(),
        client.server_version(),
        count.object_count
    );

    let request = GraspRequest {
        grasp_mode: GraspMode::AutoGrasp,
        object_class: 0,
        // V3 only; V4 grasps with the tool SET_TOOL chose.
        tool: Tool::Exterior,
        // V4 only.
        selection_criterion: SelectionCriterion(args.selection),
        pose_format: args.format,
    };
    for pick in 1..=MAX_PICKS {
        let outcome = client
            .get_grasp(request)
            .await
            .map_err(|e| format!("GET_GRASP failed: {e}"))?;
        let grasp = match outcome {
            GetGraspOutcome::Grasp(grasp) => grasp,
            GetGraspOutcome::NoObject => {
                println!("scene is empty after {} picks", pick - 1);
                return Ok(());
            }
            GetGraspOutcome::NoGrasp => {
                return Err(format!(
                    "objects left after {} picks, but no grasp for them",
                    pick - 1
                ))
            }
            GetGraspOutcome::InvalidObjectClass => {
                return Err("the server does not know the requested object class".into())
            }
        };
        let si = grasp.pose.to_si().map_err(|e| format!("grasp pose: {e}"))?;
        let [x, y, z] = si.position_m;
        let [qx, qy, qz, qw] = si.orientation.xyzw();
        println!(
            "pick {pick}: class {} instance {} ({}), stroke {:.3} mm, {} candidates, {} objects",
            grasp.object_class,
            grasp.object_instance,
            grasp.grasp_mode,
            f64::from(grasp.stroke_um) / 1000.0,
            grasp.candidate_count,
            grasp.object_count,
        );
        println!(
            "  pose: x {x:.6} m, y {y:.6} m, z {z:.6} m, q [{qx:.6}, {qy:.6}, {qz:.6}, {qw:.6}]"
        );
        println!("  {}: {}", grasp.pose.format(), grasp.pose);
        if let Some(offset) = grasp.object_offset {
            println!(
                "  V4 object offset: x {} µm, y {} µm, rz {} µdeg",
                offset.x_um, offset.y_um, offset.rz_udeg
            );
        }
        // Here the robot would open to the stroke, approach, close and lift.
        client
            .grasp_feedback(GraspFeedback::Ok)
            .await
            .map_err(|e| format!("GRASP_FEEDBACK failed: {e}"))?;
    }
    Err(format!("the scene was not empty after {MAX_PICKS} picks"))
}

fn parse_args(mut args: impl Iterator<Item = String>) -> Result<Args, String> {
    let mut parsed = Args {
        addr: None,
        format: PoseFormat::Abc,
        tool: None,
        workspace: None,
        selection: 1,
    };
    fn number<T: std::str::FromStr>(flag: &str, value: Option<String>) -> Result<T, String> {
        value
            .as_deref()
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{flag} needs a number"))
    }
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--addr" => {
                let addr = args.next().ok_or("--addr needs HOST:PORT")?;
                // A bare host name or IPv4 address gets the server's port (manual 1.1).
                parsed.addr = Some(if addr.contains(':') {
                    addr
                } else {
                    format!("{addr}:{}", gripper::smartgrasp::DEFAULT_PORT)
                });
            }
            "--format" => {
                parsed.format = match args.next().as_deref() {
                    Some("abc") => PoseFormat::Abc,
                    Some("wpr") => PoseFormat::Wpr,
                    Some("quaternion") => PoseFormat::Quaternion,
                    Some("axis-angle") => PoseFormat::AxisAngle,
                    other => return Err(format!("unknown pose format {other:?}")),
                }
            }
            "--tool" => parsed.tool = Some(number("--tool", args.next())?),
            "--workspace" => parsed.workspace = Some(number("--workspace", args.next())?),
            "--selection" => parsed.selection = number("--selection", args.next())?,
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok(parsed)
}
