//! A robot cell in one program: the SCHUNK 2D Grasping-Kit says where to grasp, a Weiss WSG
//! gripper picks every part of the bin, then a GRIPLINK gripper does the same with a second bin.
//!
//! ```text
//! cargo run --example pick_and_place            # all three devices simulated in this process
//! cargo run --example pick_and_place -- --smartgrasp 10.0.0.5 --wsg 10.0.0.20 --griplink 10.0.0.40
//!     --smartgrasp HOST[:PORT]   a Grasping-Kit (default port 42001)
//!     --wsg HOST[:PORT]          a WSG gripper over TCP (default port 1000)
//!     --griplink HOST[:PORT]     a GRIPLINK controller (default port 10001)
//!     --griplink-port N          the controller's port the gripper is on (default 0)
//!     --wsg-project N            the Grasping-Kit project of the WSG's bin (default 0)
//!     --griplink-project N       the Grasping-Kit project of the GRIPLINK gripper's bin (default 1)
//!     --tool ID, --workspace ID  Grasping-Kit V4: the tool and workspace to choose by id
//!     --selection N              Grasping-Kit V4: GET_GRASP's selection criterion (default 1)
//! ```
//! The Grasping-Kit is spoken to in protocol V4 when it offers it, V3 otherwise (the simulated
//! one speaks both); the V4-only options are then ignored.
//! Any device not given on the command line is simulated. The robot's own motion is not part
//! of this example: where the robot would move, the log says so.

use std::process::ExitCode;
use std::time::Duration;

use gripper::{griplink, smartgrasp, wsg};
use smartgrasp::{GetGraspOutcome, GraspFeedback, GraspMode, GraspRequest, PoseFormat, Tool};

/// The parts in the simulated bins: the WSG's are 40 mm wide, the GRIPLINK gripper's 30 mm.
const WSG_PART_MM: f32 = 40.0;
const GRIPLINK_PART_MM: f64 = 30.0;
/// How far the fingers open beyond the part before the approach.
const CLEARANCE_MM: f32 = 10.0;

#[derive(Default)]
struct Args {
    smartgrasp: Option<String>,
    wsg: Option<String>,
    griplink: Option<String>,
    griplink_port: u8,
    wsg_project: u32,
    griplink_project: u32,
    /// Grasping-Kit V4: SET_TOOL's id (`--tool`).
    smartgrasp_tool: Option<u16>,
    /// Grasping-Kit V4: SET_WORKSPACE's id (`--workspace`).
    smartgrasp_workspace: Option<u16>,
    /// Grasping-Kit V4: GET_GRASP's selection criterion (`--selection`).
    smartgrasp_selection: Option<u8>,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        griplink_project: 1,
        ..Args::default()
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or_else(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--smartgrasp" => args.smartgrasp = Some(with_port(value()?, 42001)),
            "--wsg" => args.wsg = Some(with_port(value()?, 1000)),
            "--griplink" => args.griplink = Some(with_port(value()?, 10001)),
            "--griplink-port" => args.griplink_port = number(&flag, value()?)?,
            "--wsg-project" => args.wsg_project = number(&flag, value()?)?,
            "--griplink-project" => args.griplink_project = number(&flag, value()?)?,
            // Grasping-Kit V4 only (ignored when the server speaks V3).
            "--tool" => args.smartgrasp_tool = Some(number(&flag, value()?)?),
            "--workspace" => args.smartgrasp_workspace = Some(number(&flag, value()?)?),
            "--selection" => args.smartgrasp_selection = Some(number(&flag, value()?)?),
            "-h" | "--help" => {
                return Err("usage: pick_and_place [--smartgrasp ADDR] [--wsg ADDR] \
                            [--griplink ADDR] [--griplink-port N] [--wsg-project N] \
                            [--griplink-project N] [--tool ID] [--workspace ID] [--selection N]"
                    .into())
            }
            other => return Err(format!("unknown argument {other} (try --help)")),
        }
    }
    Ok(args)
}

fn number<T: std::str::FromStr>(flag: &str, v: String) -> Result<T, String>
where
    T::Err: std::fmt::Display,
{
    v.parse().map_err(|e| format!("{flag} {v}: {e}"))
}

/// Adds the device's default port where the address has none: `host`, `10.0.0.5` and a bare
/// IPv6 address get it; `host:port`, `10.0.0.5:port` and `[::1]:port` keep theirs.
fn with_port(addr: String, default_port: u16) -> String {
    if addr.parse::<std::net::SocketAddr>().is_ok() {
        addr
    } else if addr.parse::<std::net::Ipv6Addr>().is_ok() {
        format!("[{addr}]:{default_port}")
    } else if addr
        .rsplit_once(':')
        .is_some_and(|(_, port)| port.parse::<u16>().is_ok())
    {
        addr
    } else {
        format!("{addr}:{default_port}")
    }
}

/// The simulators this run started; dropping them shuts them down.
#[derive(Default)]
struct Simulators {
    _smartgrasp: Option<smartgrasp::sim::SimServer>,
    _wsg: Option<wsg::sim::SimServer>,
    _griplink: Option<griplink::sim::SimServer>,
}

/// A Grasping-Kit scene: one bin per project, each with `count` parts of class 1 whose
/// exterior grasp has the given stroke.
fn simulated_bins() -> smartgrasp::sim::SimConfig {
    use smartgrasp::sim::{SimConfig, SimGrasp, SimObject, SimProject};
    use smartgrasp::{SiPose, UnitQuaternion};
    let bin = |count: u16, stroke_mm: f64, x_mm: f64| {
        SimProject::from_scene(
            (0..count)
                .map(|i| SimObject {
                    class_id: 1,
                    instance: i,
                    grasps: vec![SimGrasp {
                        tool: Tool::Exterior,
                        active: true,
                        stroke_um: (stroke_mm * 1000.0).round() as i32,
                        angle_offset_udeg: 0,
                        center_offset_um: [0, 0, 0],
                        object_offset: smartgrasp::ObjectOffset::default(),
                        pose: SiPose {
                            position_m: [
                                x_mm / 1000.0,
                                (f64::from(i) * 60.0 - 60.0) / 1000.0,
                                0.05,
                            ],
                            // Tool pointing down, turned 30° per part about the base's z axis.
                            orientation: UnitQuaternion::from_rpy(
                                std::f64::consts::PI,
                                0.0,
                                (f64::from(i) * 30.0).to_radians(),
                            ),
                        },
                    }],
                    auto_grasp: None,
                })
                .collect(),
        )
    };
    SimConfig {
        projects: vec![
            bin(3, f64::from(WSG_PART_MM), 450.0),
            bin(2, GRIPLINK_PART_MM, 300.0),
        ],
        // The bins empty as parts are picked: GRASP_FEEDBACK OK stands in for the robot taking
        // the part out (a simulator option; SCHUNK's server ignores feedback).
        feedback_removes_objects: true,
        ..SimConfig::default()
    }
}

async fn start(args: &Args) -> Result<(String, String, String, Simulators), String> {
    let mut sims = Simulators::default();
    let smartgrasp_addr = match &args.smartgrasp {
        Some(a) => a.clone(),
        None => {
            let sim = smartgrasp::sim::SimServer::bind("127.0.0.1:0", simulated_bins())
                .await
                .map_err(|e| format!("cannot start the Grasping-Kit simulator: {e}"))?;
            let addr = sim.local_addr().to_string();
            println!("simulated Grasping-Kit on {addr}");
            sims._smartgrasp = Some(sim);
            addr
        }
    };
    let wsg_addr = match &args.wsg {
        Some(a) => a.clone(),
        None => {
            // Motion in the simulator takes no wall time (time scale 0).
            let config = wsg::sim::SimConfig::new(wsg::sim::Model::Wsg50)
                .with_part(WSG_PART_MM, 2.0)
                .with_time_scale(0.0);
            let sim = wsg::sim::SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("cannot start the WSG simulator: {e}"))?;
            let addr = sim
                .local_addr()
                .ok_or("the WSG simulator has no address")?
                .to_string();
            println!("simulated WSG 50 on {addr}");
            sims._wsg = Some(sim);
            addr
        }
    };
    let griplink_addr = match &args.griplink {
        Some(a) => a.clone(),
        None => {
            let device = griplink::sim::SimDevice::wpg_100_090().with_part(GRIPLINK_PART_MM);
            let config = griplink::sim::SimConfig::et4()
                .device(args.griplink_port, Some(device))
                .time_scale(0.0);
            let sim = griplink::sim::SimServer::bind("127.0.0.1:0", config)
                .await
                .map_err(|e| format!("cannot start the GRIPLINK simulator: {e}"))?;
            let addr = sim.local_addr().to_string();
            println!("simulated GRIPLINK-ET4 on {addr}");
            sims._griplink = Some(sim);
            addr
        }
    };
    Ok((smartgrasp_addr, wsg_addr, griplink_addr, sims))
}

/// What a grasp needs from the gripper: pre-position, grasp, report, release.
trait Gripper {
    async fn pick(&self, stroke_mm: f64) -> Result<(), String>;
}

struct Wsg(wsg::Client);

impl Gripper for Wsg {
    async fn pick(&self, stroke_mm: f64) -> Result<(), String> {
        let e = |step: &'static str| move |e: wsg::Error| format!("WSG {step}: {e}");
        let width_mm = stroke_mm as f32;
        let open_mm = width_mm + CLEARANCE_MM;
        self.0
            .pre_position(open_mm, 100.0)
            .await
            .map_err(e("pre-position"))?;
        println!("  WSG pre-positioned to {open_mm:.1} mm; robot approaches");
        self.0.grasp(width_mm, 50.0).await.map_err(e("grasp"))?;
        let width = self.0.width_mm().await.map_err(e("width"))?;
        let force = self.0.force_n().await.map_err(e("force"))?;
        let state = self.0.grip_state().await.map_err(e("grip state"))?;
        println!("  WSG grasped: {state:?} at {width:.1} mm with {force:.1} N; robot places");
        self.0.release(open_mm, 100.0).await.map_err(e("release"))?;
        println!("  WSG released");
        Ok(())
    }
}

struct GriplinkGripper(griplink::Port);

/// The grip recipe the GRIPLINK pick writes and uses (recipes are the device's, manual 3.6).
const RECIPE: u32 = 15;

impl Gripper for GriplinkGripper {
    async fn pick(&self, stroke_mm: f64) -> Result<(), String> {
        let e = |step: &'static str| move |e: griplink::Error| format!("GRIPLINK {step}: {e}");
        // No part closer than 5 mm below the stroke; release to the stroke plus clearance.
        let recipe = griplink::GripConfigF::gripper(
            "pick_and_place",
            stroke_mm - 5.0,
            stroke_mm + f64::from(CLEARANCE_MM),
            50.0,
        );
        self.0
            .set_grip_config_f(RECIPE, &recipe)
            .await
            .map_err(e("recipe"))?;
        let by = griplink::WaitBy::Polling(Duration::from_millis(10));
        match self.0.grip_and_wait(RECIPE, by).await.map_err(e("grip"))? {
            griplink::GripOutcome::Holding => {}
            other => return Err(format!("GRIPLINK grip ended {other:?}")),
        }
        let position = self.0.position_mm().await.map_err(e("position"))?;
        println!("  GRIPLINK holding at {position:.3} mm; robot places");
        match self
            .0
            .release_and_wait(RECIPE, by)
            .await
            .map_err(e("release"))?
        {
            griplink::ReleaseOutcome::Released => {}
            other => return Err(format!("GRIPLINK release ended {other:?}")),
        }
        println!("  GRIPLINK released");
        Ok(())
    }
}

/// Asks for grasps until the bin is empty, picking each with `gripper`. Returns the parts picked.
async fn empty_the_bin(
    kit: &smartgrasp::Client,
    gripper: &impl Gripper,
    project: u32,
    selection: u8,
) -> Result<u32, String> {
    let e = |step: &'static str| move |e: smartgrasp::Error| format!("Grasping-Kit {step}: {e}");
    kit.set_project(project).await.map_err(e("set project"))?;
    // V3 names the tool here; V4 uses the tool chosen with SET_TOOL (1 = exterior in the
    // simulator) and the selection criterion instead (its values are not public; SCHUNK's KUKA
    // example sends 1 to 3).
    let request = GraspRequest {
        grasp_mode: GraspMode::AutoGrasp,
        object_class: 0,
        tool: Tool::Exterior,
        selection_criterion: smartgrasp::SelectionCriterion(selection),
        pose_format: PoseFormat::Abc,
    };
    let mut picked = 0;
    loop {
        let grasp = match kit.get_grasp(request).await.map_err(e("get grasp"))? {
            GetGraspOutcome::Grasp(grasp) => grasp,
            GetGraspOutcome::NoObject => break,
            other => return Err(format!("Grasping-Kit: {other:?}")),
        };
        let si = grasp.pose.to_si().map_err(|e| format!("grasp pose: {e}"))?;
        let [x, y, z] = si.position_m;
        println!(
            "part {} (class {}, {} in the bin): grasp at ({x:.3}, {y:.3}, {z:.3}) m, KUKA {}, stroke {:.1} mm",
            grasp.object_instance,
            grasp.object_class,
            grasp.object_count,
            grasp.pose,
            grasp.stroke_m() * 1000.0,
        );
        let outcome = gripper.pick(grasp.stroke_m() * 1000.0).await;
        // The Grasping-Kit learns from every attempt; a failed pick is BAD feedback.
        let feedback = if outcome.is_ok() {
            GraspFeedback::Ok
        } else {
            GraspFeedback::Bad
        };
        kit.grasp_feedback(feedback).await.map_err(e("feedback"))?;
        outcome?;
        picked += 1;
    }
    Ok(picked)
}

async fn run(args: Args) -> Result<(), String> {
    let (smartgrasp_addr, wsg_addr, griplink_addr, _sims) = start(&args).await?;

    let kit = smartgrasp::Client::connect(
        smartgrasp_addr.as_str(),
        smartgrasp::ClientConfig {
            robot_system: Some(smartgrasp::RobotSystem::Kuka),
            // V4 only; skipped with a warning by a V3 server.
            tool_id: args.smartgrasp_tool,
            workspace_id: args.smartgrasp_workspace,
            ..smartgrasp::ClientConfig::default()
        },
    )
    .await
    .map_err(|e| format!("Grasping-Kit at {smartgrasp_addr}: {e}"))?;
    println!(
        "Grasping-Kit ready (protocol v{}), registered as KUKA",
        kit.protocol_version()
    );

    let wsg = wsg::Client::connect_tcp(wsg_addr.as_str())
        .await
        .map_err(|e| format!("WSG at {wsg_addr}: {e}"))?;
    let info = wsg.system_info().await.map_err(|e| format!("WSG: {e}"))?;
    println!(
        "WSG: {:?}, firmware {}; homing",
        info.device_type, info.firmware
    );
    wsg.home(wsg::HomingDirection::Default)
        .await
        .map_err(|e| format!("WSG homing: {e}"))?;
    let wsg = Wsg(wsg);
    let selection = args.smartgrasp_selection.unwrap_or(1);
    let picked = empty_the_bin(&kit, &wsg, args.wsg_project, selection).await?;
    println!("WSG bin empty: {picked} parts picked");
    // Announce the disconnect (0x07) so the WSG does not go into FAST STOP.
    wsg.0.close().await.map_err(|e| format!("WSG close: {e}"))?;

    let controller = griplink::Client::connect(griplink_addr.as_str())
        .await
        .map_err(|e| format!("GRIPLINK at {griplink_addr}: {e}"))?;
    let port = controller.port(args.griplink_port);
    let name = port.name().await.map_err(|e| format!("GRIPLINK: {e}"))?;
    println!("GRIPLINK port {}: {name}; homing", args.griplink_port);
    port.home()
        .await
        .map_err(|e| format!("GRIPLINK homing: {e}"))?;
    let picked = empty_the_bin(
        &kit,
        &GriplinkGripper(port),
        args.griplink_project,
        selection,
    )
    .await?;
    println!("GRIPLINK bin empty: {picked} parts picked");
    controller
        .close()
        .await
        .map_err(|e| format!("GRIPLINK close: {e}"))?;
    Ok(())
}

#[tokio::main]
async fn main() -> ExitCode {
    let result = match parse_args() {
        Ok(args) => run(args).await,
        Err(e) => Err(e),
    };
    match result {
        Ok(()) => {
            println!("done");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("pick_and_place: {e}");
            ExitCode::FAILURE
        }
    }
}
