//! `gripctl sim wsg`: a WSG gripper over TCP, UDP or a serial pseudo-terminal.

use clap::{Args as ClapArgs, ValueEnum};
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use serde_json::json;

use super::{announce, cannot_listen, check_time_scale, wait_for_ctrl_c};
use crate::error::{CliError, Kind};
use crate::output::Out;

/// Options of `gripctl sim wsg`.
#[derive(Debug, ClapArgs)]
pub struct WsgSim {
    /// Address to serve on; port 0 picks a free port.
    #[arg(long, default_value = "127.0.0.1:1000")]
    listen: String,
    /// Serve UDP (one frame per datagram) instead of TCP.
    #[arg(long, conflicts_with = "pty")]
    udp: bool,
    /// The device's "UDP remote port": UDP replies go to the sender's IP address at this port,
    /// whatever port the request came from (default: the sender's own port).
    #[arg(long, requires = "udp")]
    udp_remote_port: Option<u16>,
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
    /// Wall seconds per simulated second of motion: 1 (the default) is real time, so a move
    /// can be stopped or refused with E_ALREADY_RUNNING as on the device; 0 is instant.
    #[arg(long, default_value_t = SimConfig::standalone().time_scale)]
    time_scale: f64,
    /// Serve the text interface (GCL) instead of the binary protocol, over TCP, from the same
    /// device model (the web interface's "Use text based interface").
    #[arg(long, conflicts_with_all = ["udp", "pty"])]
    text: bool,
    /// A close without 0x07 / `BYE()` does not raise FAST STOP (the web interface's "Enable
    /// Error on TCP Disconnect" switched off).
    #[arg(long)]
    no_fast_stop_on_close: bool,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ModelArg {
    Wsg50,
    Wsg32,
    Wsg25,
    Wsg70,
}

/// Serves until Ctrl-C.
pub async fn run(args: WsgSim, out: Out) -> Result<(), CliError> {
    let model = match args.model {
        ModelArg::Wsg50 => Model::Wsg50,
        ModelArg::Wsg32 => Model::Wsg32,
        ModelArg::Wsg25 => Model::Wsg25,
        ModelArg::Wsg70 => Model::Wsg70,
    };
    check_time_scale(args.time_scale)?;
    // The standalone defaults (real time), with the model and part asked for.
    let mut config = SimConfig {
        part: None,
        time_scale: args.time_scale,
        udp_remote_port: args.udp_remote_port,
        text_interface: args.text,
        fast_stop_on_close: !args.no_fast_stop_on_close,
        ..SimConfig::new(model)
    };
    if !args.no_part {
        config = config.with_part(args.part, args.tolerance);
    }
    let server = if args.pty {
        SimServer::serial_pty(config).map_err(|e| {
            CliError::new(
                Kind::Simulator,
                format!("cannot open a pseudo-terminal: {e}"),
            )
        })?
    } else if args.udp {
        SimServer::bind_udp(args.listen.as_str(), config)
            .await
            .map_err(|e| cannot_listen(&args.listen, &e))?
    } else {
        SimServer::bind(args.listen.as_str(), config)
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
    } else if args.text {
        "tcp (text interface, GCL)"
    } else {
        "tcp"
    };
    let part = (!args.no_part).then_some(args.part);
    let scale = args.time_scale;
    out.emit(
        format!(
            "wsg simulator: {model:?} over {transport}, {}, time scale {scale}{}",
            part.map_or("no part".to_owned(), |w| format!("a {w} mm part")),
            args.udp_remote_port
                .map_or(String::new(), |p| format!(", UDP replies to port {p}"))
        ),
        json!({ "device": "wsg", "model": format!("{model:?}"), "transport": transport,
                "part_mm": part, "time_scale": scale, "udp_remote_port": args.udp_remote_port, "text": args.text }),
    )?;
    wait_for_ctrl_c().await?;
    server.shutdown();
    Ok(())
}
