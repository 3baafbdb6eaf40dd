//! `gripctl sim smartgrasp`: a SCHUNK 2D Grasping-Kit server with a scene of parts.

use clap::{Args as ClapArgs, ValueEnum};
use gripper::smartgrasp::sim::{SimConfig, SimServer};
use gripper::smartgrasp::ServerState;
use serde_json::json;

use super::monitor;
use super::{announce, cannot_listen, wait_for_ctrl_c};
use crate::error::CliError;
use crate::output::Out;

/// Options of `gripctl sim smartgrasp`.
#[derive(Debug, ClapArgs)]
pub struct SmartgraspSim {
    /// Address to serve on; port 0 picks a free port.
    #[arg(long, default_value = "127.0.0.1:42001")]
    listen: String,
    /// Also serve a picture of the scene over HTTP on this address, at /monitor/latest_result
    /// as the kit does; port 0 picks a free port.
    #[arg(long, value_name = "ADDR")]
    http: Option<String>,
    /// The scene of project 0: the demo bin (two parts of class 1, one of class 2) or empty.
    #[arg(long, value_enum, default_value_t = Scene::Demo)]
    scene: Scene,
    /// How many copies of the scene's parts are in the bin (0 to 1000).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(0..=1000))]
    copies: u16,
    /// What GET_STATE reports; detection calls fail with ERROR unless operational.
    #[arg(long, value_enum, default_value_t = StateArg::Operational)]
    state: StateArg,
    /// The highest protocol version the server speaks (default 4): it answers requests of a
    /// higher version with the "too old" empty message (3: a V3-only server; below 3 it answers
    /// every request that way).
    #[arg(long, alias = "protocol-version", default_value_t = gripper::smartgrasp::frame::v4::PROTOCOL_VERSION)]
    max_version: u16,
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

/// Serves until Ctrl-C.
pub async fn run(args: SmartgraspSim, out: Out) -> Result<(), CliError> {
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
    let monitor = match &args.http {
        Some(http) => Some(monitor::serve(&server, http, out).await?),
        None => None,
    };
    wait_for_ctrl_c().await?;
    drop(monitor);
    server.shutdown();
    Ok(())
}

fn smartgrasp_config(args: &SmartgraspSim) -> SimConfig {
    let mut config = SimConfig {
        max_version: args.max_version,
        server_state: match args.state {
            StateArg::Init => ServerState::Init,
            StateArg::Operational => ServerState::Operational,
            StateArg::Stopped => ServerState::Stopped,
            StateArg::Error => ServerState::Error,
        },
        // A bin that empties as parts are reported picked: GRASP_FEEDBACK OK stands in for the
        // robot taking the part out (SCHUNK's server ignores feedback; a simulator option).
        feedback_removes_objects: true,
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
