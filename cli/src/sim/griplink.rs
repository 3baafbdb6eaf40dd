//! `gripctl sim griplink`: a GRIPLINK-ET4 controller, or a WPG gripper.

use clap::Args as ClapArgs;
use gripper::griplink::sim::{SimConfig, SimServer};
use serde_json::json;

use super::{announce, cannot_listen, check_time_scale, wait_for_ctrl_c};
use crate::error::CliError;
use crate::output::Out;

/// Options of `gripctl sim griplink`.
#[derive(Debug, ClapArgs)]
pub struct GriplinkSim {
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

/// Serves until Ctrl-C.
pub async fn run(args: GriplinkSim, out: Out) -> Result<(), CliError> {
    check_time_scale(args.time_scale)?;
    let base = if args.wpg {
        SimConfig::wpg()
    } else {
        SimConfig::et4()
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
    let server = SimServer::bind(args.listen.as_str(), config)
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
