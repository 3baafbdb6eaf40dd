//! Serves a simulated GRIPLINK-ET4 controller over TCP.
//!
//! ```text
//! cargo run --example griplink_simulator -- --listen 127.0.0.1:10001 [--time-scale 1.0] [--part-mm 12] [--wpg]
//! ```
//! Prints `listening on <address>` as its first line of standard output (port 0 picks a free
//! port), then serves until killed. Port 0 holds an IEG 55-020 with a part of `--part-mm`
//! between its fingers (default 12 mm; `--part-mm none` for no part); port 2 a CRG 200-085.
//! `--wpg` simulates a WPG 100-090 (one port) instead.

use std::io::Write as _;
use std::process::ExitCode;

use gripper::griplink::sim::{SimConfig, SimServer};

struct Args {
    listen: String,
    time_scale: f64,
    part_mm: Option<f64>,
    wpg: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut args = Args {
        listen: "127.0.0.1:10001".to_owned(),
        time_scale: 1.0,
        part_mm: Some(12.0),
        wpg: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--listen" => args.listen = value("--listen")?,
            "--time-scale" => {
                let v = value("--time-scale")?;
                args.time_scale = v
                    .parse()
                    .ok()
                    .filter(|s: &f64| s.is_finite() && *s >= 0.0)
                    .ok_or(format!("--time-scale: {v:?} is not a number >= 0"))?;
            }
            "--part-mm" => {
                let v = value("--part-mm")?;
                args.part_mm = if v == "none" {
                    None
                } else {
                    Some(v.parse().map_err(|_| format!("--part-mm: {v:?} is not a number"))?)
                };
            }
            "--wpg" => args.wpg = true,
            "--help" | "-h" => {
                return Err("usage: griplink_simulator [--listen ADDR] [--time-scale X] [--part-mm MM|none] [--wpg]".into())
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    Ok(args)
}

#[tokio::main]
async fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(args) => args,
        Err(msg) => {
            eprintln!("griplink_simulator: {msg}");
            return ExitCode::FAILURE;
        }
    };
    let base = if args.wpg {
        SimConfig::wpg()
    } else {
        SimConfig::et4()
    };
    let mut config = base.time_scale(args.time_scale);
    if let Some(Some(device)) = config.ports.get_mut(0) {
        device.part_width_mm = args.part_mm;
    }
    let server = match SimServer::bind(args.listen.as_str(), config).await {
        Ok(server) => server,
        Err(e) => {
            eprintln!("griplink_simulator: cannot listen on {}: {e}", args.listen);
            return ExitCode::FAILURE;
        }
    };
    println!("listening on {}", server.local_addr());
    let _ = std::io::stdout().flush();
    let _ = tokio::signal::ctrl_c().await;
    server.shutdown();
    ExitCode::SUCCESS
}
