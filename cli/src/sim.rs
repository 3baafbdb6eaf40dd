//! `gripctl sim …`: serves a protocol's simulator until Ctrl-C (or until killed).
//!
//! The first line of standard output is always `listening on <bound address>`, flushed, in text
//! and JSON mode alike: scripts and tests start the simulator on port 0 and read the address from
//! it, as they do with the `*_simulator` examples.

use std::io::Write;

use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use gripper::smartgrasp::sim::{SimConfig, SimServer};
use gripper::smartgrasp::ServerState;
use serde_json::json;

use crate::error::{CliError, Kind};
use crate::output::Out;

/// Options of `gripctl sim`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    #[command(subcommand)]
    device: Device,
}

#[derive(Debug, Subcommand)]
enum Device {
    /// A Weiss WSG gripper (binary protocol) over TCP, UDP or a serial pseudo-terminal, with a
    /// part between the fingers. Motion takes no wall time unless --time-scale says so.
    Wsg(WsgSim),
    /// A Weiss GRIPLINK-ET4 controller (IEG 55-020 on port 0, CRG 200-085 on port 2), or a
    /// WPG 100-090 with --wpg.
    Griplink(GriplinkSim),
    /// A SCHUNK 2D Grasping-Kit server (protocol V3) with a scene of parts.
    Smartgrasp(SmartgraspSim),
}

#[derive(Debug, ClapArgs)]
struct SmartgraspSim {
    /// Address to serve on; port 0 picks a free port.
    #[arg(long, default_value = "127.0.0.1:42001")]
    listen: String,
    /// The scene of project 0: the demo bin (two parts of class 1, one of class 2) or empty.
    #[arg(long, value_enum, default_value_t = Scene::Demo)]
    scene: Scene,
    /// How many copies of the scene's parts are in the bin.
    #[arg(long, default_value_t = 1)]
    copies: u16,
    /// What GET_STATE reports; detection calls fail with ERROR unless operational.
    #[arg(long, value_enum, default_value_t = StateArg::Operational)]
    state: StateArg,
    /// The highest protocol version the server speaks (below 3 it answers "too old").
    #[arg(long, default_value_t = gripper::smartgrasp::frame::PROTOCOL_VERSION)]
    protocol_version: u16,
}

#[derive(Debug, ClapArgs)]
struct WsgSim {
    /// Address to serve on; port 0 picks a free port.
    #[arg(long, default_value = "127.0.0.1:1000")]
    listen: String,
    /// Serve UDP (one frame per datagram) instead of TCP.
    #[arg(long, conflicts_with = "pty")]
    udp: bool,
    /// Serve on a new serial pseudo-terminal instead (its path is printed; open it with
    /// `gripctl wsg --serial PATH --shared`).
    #[arg(long)]
    pty: bool,
    /// The gripper model (device type and limits).
    #[arg(long, value_enum, default_value_t = ModelArg::Wsg50)]
    model: ModelArg,
    /// Width of the part between the fingers, mm.
    #[arg(long, default_value_t = 40.0, conflicts_with = "no_part")]
    part: f32,
    /// How far a grasp's nominal width may be off the part's and still find it, mm.
    #[arg(long, default_value_t = 2.0)]
    tolerance: f32,
    /// No part: every grasp ends in NO PART FOUND.
    #[arg(long)]
    no_part: bool,
    /// Wall seconds per simulated second of motion: 0 is instant, 1 real time.
    #[arg(long, default_value_t = 0.0)]
    time_scale: f64,
}

#[derive(Debug, ClapArgs)]
struct GriplinkSim {
    /// Address to serve on; port 0 picks a free port.
    #[arg(long, default_value = "127.0.0.1:10001")]
    listen: String,
    /// Simulate a WPG 100-090 gripper (one port) instead of a GRIPLINK-ET4.
    #[arg(long)]
    wpg: bool,
    /// Width of the part between the fingers of the gripper on port 0, mm.
    #[arg(long, default_value_t = 12.0, conflicts_with = "no_part")]
    part: f64,
    /// No part on port 0: every grip ends in DS_NO_PART.
    #[arg(long)]
    no_part: bool,
    /// Wall seconds per simulated second of motion: 0 is instant, 1 real time.
    #[arg(long, default_value_t = 0.0)]
    time_scale: f64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ModelArg {
    Wsg50,
    Wsg32,
    Wsg25,
    Wsg70,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Scene {
    Demo,
    Empty,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum StateArg {
    Init,
    Operational,
    Stopped,
    Error,
}

/// Runs `gripctl sim …` until Ctrl-C.
pub async fn run(args: Args, out: Out) -> Result<(), CliError> {
    match args.device {
        Device::Wsg(sim) => wsg(sim, out).await,
        Device::Griplink(sim) => griplink(sim, out).await,
        Device::Smartgrasp(sim) => smartgrasp(sim, out).await,
    }
}

async fn griplink(args: GriplinkSim, out: Out) -> Result<(), CliError> {
    use gripper::griplink::sim::{SimConfig as GriplinkConfig, SimServer as GriplinkServer};
    check_time_scale(args.time_scale)?;
    let base = if args.wpg {
        GriplinkConfig::wpg()
    } else {
        GriplinkConfig::et4()
    };
    let mut config = base.time_scale(args.time_scale);
    let part = (!args.no_part).then_some(args.part);
    if let Some(Some(device)) = config.ports.get_mut(0) {
        device.part_width_mm = part;
    }
    let devices: Vec<String> = config
        .ports
        .iter()
        .enumerate()
        .filter_map(|(i, d)| d.as_ref().map(|d| format!("{} on port {i}", d.name)))
        .collect();
    let id = config.id.clone();
    let server = GriplinkServer::start(args.listen.as_str(), config)
        .await
        .map_err(|e| cannot_listen(&args.listen, &e))?;
    announce(&server.local_addr())?;
    out.emit(
        format!(
            "griplink simulator: {id}, {}; {} on port 0",
            devices.join(", "),
            part.map_or("no part".to_owned(), |w| format!("a {w} mm part"))
        ),
        json!({ "device": "griplink", "id": id, "ports": devices, "part_mm": part }),
    )?;
    wait_for_ctrl_c().await?;
    server.shutdown();
    Ok(())
}

fn check_time_scale(scale: f64) -> Result<(), CliError> {
    if scale.is_finite() && scale >= 0.0 {
        Ok(())
    } else {
        Err(CliError::argument("--time-scale must be 0 or more"))
    }
}

async fn wsg(args: WsgSim, out: Out) -> Result<(), CliError> {
    use gripper::wsg::sim::{Model, SimConfig as WsgConfig, SimServer as WsgServer};
    let model = match args.model {
        ModelArg::Wsg50 => Model::Wsg50,
        ModelArg::Wsg32 => Model::Wsg32,
        ModelArg::Wsg25 => Model::Wsg25,
        ModelArg::Wsg70 => Model::Wsg70,
    };
    check_time_scale(args.time_scale)?;
    let mut config = WsgConfig::new(model).with_time_scale(args.time_scale);
    if !args.no_part {
        config = config.with_part(args.part, args.tolerance);
    }
    let server = if args.pty {
        WsgServer::serial_pty(config).map_err(|e| {
            CliError::new(
                Kind::Simulator,
                format!("cannot open a pseudo-terminal: {e}"),
            )
        })?
    } else if args.udp {
        WsgServer::udp(config, args.listen.as_str())
            .await
            .map_err(|e| cannot_listen(&args.listen, &e))?
    } else {
        WsgServer::tcp(config, args.listen.as_str())
            .await
            .map_err(|e| cannot_listen(&args.listen, &e))?
    };
    let place = match (server.local_addr(), server.serial_path()) {
        (Some(addr), _) => addr.to_string(),
        (None, Some(path)) => path.to_owned(),
        (None, None) => {
            return Err(CliError::new(
                Kind::Simulator,
                "the simulator serves nowhere",
            ));
        }
    };
    announce(&place)?;
    let transport = if args.pty {
        "serial"
    } else if args.udp {
        "udp"
    } else {
        "tcp"
    };
    let part = (!args.no_part).then_some(args.part);
    out.emit(
        format!(
            "wsg simulator: {model:?} over {transport}, {}",
            part.map_or("no part".to_owned(), |w| format!("a {w} mm part"))
        ),
        json!({ "device": "wsg", "model": format!("{model:?}"), "transport": transport, "part_mm": part }),
    )?;
    wait_for_ctrl_c().await?;
    server.shutdown();
    Ok(())
}

async fn smartgrasp(args: SmartgraspSim, out: Out) -> Result<(), CliError> {
    let config = smartgrasp_config(&args);
    let parts = config.projects.first().map_or(0, |p| p.scene.len());
    let state = config.server_state;
    let server = SimServer::bind(args.listen.as_str(), config)
        .await
        .map_err(|e| cannot_listen(&args.listen, &e))?;
    announce(&server.local_addr())?;
    out.emit(
        format!("smartgrasp simulator: {parts} parts in project 0, {state}"),
        json!({ "device": "smartgrasp", "parts": parts, "state": state.to_string() }),
    )?;
    wait_for_ctrl_c().await?;
    server.shutdown();
    Ok(())
}

fn smartgrasp_config(args: &SmartgraspSim) -> SimConfig {
    let mut config = SimConfig {
        protocol_version: args.protocol_version,
        server_state: match args.state {
            StateArg::Init => ServerState::Init,
            StateArg::Operational => ServerState::Operational,
            StateArg::Stopped => ServerState::Stopped,
            StateArg::Error => ServerState::Error,
        },
        ..SimConfig::default()
    };
    let demo = SimConfig::demo_project();
    let scene = match args.scene {
        Scene::Demo => &demo.scene[..],
        Scene::Empty => &[],
    };
    if let Some(project) = config.projects.first_mut() {
        project.scene.clear();
        for copy in 0..args.copies {
            for object in scene {
                // Instance ids stay unique within a class: each copy takes the next block of them.
                let stride = scene
                    .iter()
                    .filter(|o| o.class_id == object.class_id)
                    .map(|o| o.instance + 1)
                    .max()
                    .unwrap_or(1);
                let mut part = object.clone();
                part.instance = object.instance.saturating_add(copy.saturating_mul(stride));
                project.scene.push(part);
            }
        }
    }
    config
}

/// The contract with scripts: exactly this first line, flushed at once.
fn announce(addr: &dyn std::fmt::Display) -> Result<(), CliError> {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "listening on {addr}")
        .and_then(|()| stdout.flush())
        .map_err(|e| CliError::output(&e))
}

fn cannot_listen(listen: &str, e: &std::io::Error) -> CliError {
    CliError::new(Kind::Simulator, format!("cannot listen on {listen}: {e}"))
}

async fn wait_for_ctrl_c() -> Result<(), CliError> {
    tokio::signal::ctrl_c()
        .await
        .map_err(|e| CliError::new(Kind::Simulator, format!("cannot wait for Ctrl-C: {e}")))
}
