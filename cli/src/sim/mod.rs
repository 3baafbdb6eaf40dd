//! `gripctl sim …`: serves a protocol's simulator until Ctrl-C (or until killed).
//!
//! The first line of standard output is always `listening on <bound address>`, flushed, in text
//! and JSON mode alike: scripts and tests start the simulator on port 0 and read the address from
//! it, as they do with the `*_simulator` examples.

mod griplink;
mod monitor;
mod smartgrasp;
mod wsg;

use std::io::Write;

use clap::{Args as ClapArgs, Subcommand};

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
    /// part between the fingers. Motion runs in real time unless --time-scale says otherwise.
    Wsg(wsg::WsgSim),
    /// A Weiss GRIPLINK-ET4 controller (IEG 55-020 on port 0, CRG 200-085 on port 2), or a
    /// WPG 100-090 with --wpg.
    Griplink(griplink::GriplinkSim),
    /// A SCHUNK 2D Grasping-Kit server (protocol V3) with a scene of parts.
    Smartgrasp(smartgrasp::SmartgraspSim),
}

/// Runs `gripctl sim …` until Ctrl-C.
pub async fn run(args: Args, out: Out) -> Result<(), CliError> {
    match args.device {
        Device::Wsg(sim) => wsg::run(sim, out).await,
        Device::Griplink(sim) => griplink::run(sim, out).await,
        Device::Smartgrasp(sim) => smartgrasp::run(sim, out).await,
    }
}

/// A time scale multiplies simulated durations: it must be a number, 0 or more.
pub(super) fn check_time_scale(scale: f64) -> Result<(), CliError> {
    if scale.is_finite() && scale >= 0.0 {
        Ok(())
    } else {
        Err(CliError::argument("--time-scale must be 0 or more"))
    }
}

/// The contract with scripts: exactly this first line, flushed at once.
pub(super) fn announce(addr: &dyn std::fmt::Display) -> Result<(), CliError> {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "listening on {addr}")
        .and_then(|()| stdout.flush())
        .map_err(|e| CliError::output(&e))
}

/// Binding the simulator's address failed.
pub(super) fn cannot_listen(listen: &str, e: &std::io::Error) -> CliError {
    CliError::new(Kind::Simulator, format!("cannot listen on {listen}: {e}"))
}

/// Serves until Ctrl-C; a test or script that kills the process ends it as well.
pub(super) async fn wait_for_ctrl_c() -> Result<(), CliError> {
    tokio::signal::ctrl_c()
        .await
        .map_err(|e| CliError::new(Kind::Simulator, format!("cannot wait for Ctrl-C: {e}")))
}
