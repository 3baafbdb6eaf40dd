//! Serves the simulated WSG gripper so any program can connect to it.
//!
//! ```text
//! cargo run --example wsg_simulator -- --listen 127.0.0.1:1000 [--part MM | --no-part]
//!                                      [--udp [--udp-remote-port PORT]]
//!                                      [--time-scale S] [--model wsg50|wsg32|wsg25|wsg70]
//!                                      [--text] [--no-fast-stop-on-close]
//! cargo run --example wsg_simulator -- --pty          # serial: prints the pseudo-terminal path
//!     (open it non-exclusively: `wsg_pick --serial PATH --shared`)
//! ```
//! The first line of standard output is `listening on <address or path>`; then it runs until
//! killed.
//!
//! Without options it serves [`SimConfig::standalone`]: a WSG 50 with a 40 mm part in **real
//! time** (`--time-scale 1`), so a move takes as long as on the device and a client can stop
//! it, abort it or be refused with E_ALREADY_RUNNING; `--time-scale 0` makes motion instant.
//! `--udp-remote-port PORT` is the device's "UDP remote port" setting: replies go to the
//! sender's IP address at PORT, whatever port the request came from.
//! `--text` serves the text interface (GCL, `gripper::wsg::text`) on TCP instead of the binary
//! protocol, from the same device model. `--no-fast-stop-on-close` is the web interface's switch
//! that keeps a close without 0x07 / `BYE()` from raising FAST STOP.

use std::io::Write;
use std::process::ExitCode;

use gripper::wsg::sim::{Model, SimConfig, SimServer};

struct Args {
    listen: String,
    udp: bool,
    pty: bool,
    config: SimConfig,
}

fn parse() -> Result<Args, String> {
    let mut args = Args {
        listen: "127.0.0.1:1000".into(),
        udp: false,
        pty: false,
        config: SimConfig::standalone(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--listen" => args.listen = value("--listen")?,
            "--udp" => args.udp = true,
            "--udp-remote-port" => {
                let port: u16 = value("--udp-remote-port")?
                    .parse()
                    .map_err(|e| format!("--udp-remote-port: {e}"))?;
                args.config.udp_remote_port = Some(port);
            }
            "--pty" => args.pty = true,
            "--text" => args.config.text_interface = true,
            "--no-fast-stop-on-close" => args.config.fast_stop_on_close = false,
            "--no-part" => args.config.part = None,
            "--part" => {
                let w: f32 = value("--part")?
                    .parse()
                    .map_err(|e| format!("--part: {e}"))?;
                args.config = args.config.with_part(w, 2.0);
            }
            "--time-scale" => {
                let s: f64 = value("--time-scale")?
                    .parse()
                    .map_err(|e| format!("--time-scale: {e}"))?;
                if !(s.is_finite() && s >= 0.0) {
                    return Err("--time-scale must be 0 or more".into());
                }
                args.config.time_scale = s;
            }
            "--model" => {
                let model = match value("--model")?.to_ascii_lowercase().as_str() {
                    "wsg50" => Model::Wsg50,
                    "wsg32" => Model::Wsg32,
                    "wsg25" => Model::Wsg25,
                    "wsg70" => Model::Wsg70,
                    other => return Err(format!("unknown model {other}")),
                };
                let old = &args.config;
                args.config = SimConfig {
                    part: old.part,
                    time_scale: old.time_scale,
                    udp_remote_port: old.udp_remote_port,
                    text_interface: old.text_interface,
                    fast_stop_on_close: old.fast_stop_on_close,
                    ..SimConfig::new(model)
                };
            }
            "-h" | "--help" => return Err(
                "usage: wsg_simulator [--listen ADDR] [--udp [--udp-remote-port PORT] | --pty] \
                            [--part MM | --no-part] [--time-scale S (default 1: real time)] \
                            [--model wsg50|wsg32|wsg25|wsg70] [--text] [--no-fast-stop-on-close]"
                    .into(),
            ),
            other => return Err(format!("unknown argument {other} (try --help)")),
        }
    }
    if args.config.text_interface && (args.udp || args.pty) {
        return Err("--text is served over TCP only".into());
    }
    if args.config.udp_remote_port.is_some() && !args.udp {
        return Err("--udp-remote-port needs --udp".into());
    }
    Ok(args)
}

#[tokio::main]
async fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("wsg_simulator: {e}");
            return ExitCode::from(2);
        }
    };
    let server = if args.pty {
        serve_pty(args.config)
    } else if args.udp {
        SimServer::bind_udp(args.listen.as_str(), args.config).await
    } else {
        SimServer::bind(args.listen.as_str(), args.config).await
    };
    let server = match server {
        Ok(s) => s,
        Err(e) => {
            eprintln!("wsg_simulator: cannot serve on {}: {e}", args.listen);
            return ExitCode::FAILURE;
        }
    };
    let place = match (server.local_addr(), server.serial_path()) {
        (Some(addr), _) => addr.to_string(),
        (None, Some(path)) => path.to_owned(),
        (None, None) => "nowhere".into(),
    };
    let mut out = std::io::stdout().lock();
    if writeln!(out, "listening on {place}")
        .and_then(|()| out.flush())
        .is_err()
    {
        return ExitCode::FAILURE;
    }
    drop(out);
    std::future::pending::<()>().await;
    drop(server);
    ExitCode::SUCCESS
}

#[cfg(all(unix, feature = "serial"))]
fn serve_pty(config: SimConfig) -> std::io::Result<SimServer> {
    SimServer::serial_pty(config)
}

#[cfg(not(all(unix, feature = "serial")))]
fn serve_pty(_: SimConfig) -> std::io::Result<SimServer> {
    Err(std::io::Error::other(
        "pseudo-terminals need unix and the `serial` feature",
    ))
}
