//! Serves the simulated Smart Grasping server (V4 and V3) with the demo project (three parts)
//! until killed. `--max-version 3` makes it a V3-only server, which answers V4 requests with the
//! "too old" empty message (manual 1.3).
//!
//! ```text
//! cargo run --example smartgrasp_simulator -- --listen 127.0.0.1:42001
//! cargo run --example smartgrasp_simulator -- --max-version 3
//! ```
//!
//! The first line of standard output is `listening on <bound address>` (port 0 picks a free
//! port). Set `RUST_LOG=debug` to see every request.
//!
//! GRASP_FEEDBACK OK takes the grasped part out of the bin, standing in for the robot, so that a
//! picking loop (`smartgrasp_pick`) ends; SCHUNK's server ignores feedback, and so does the
//! simulator by default (`SimConfig::feedback_removes_objects`).

use std::io::Write;
use std::process::ExitCode;

use gripper::smartgrasp::sim::{SimConfig, SimServer};

#[tokio::main]
async fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let (listen, max_version) = match parse_args(std::env::args().skip(1)) {
        Ok(args) => args,
        Err(message) => {
            eprintln!("smartgrasp_simulator: {message}");
            eprintln!("usage: smartgrasp_simulator [--listen HOST:PORT] [--max-version 3|4]");
            return ExitCode::from(2);
        }
    };
    let config = SimConfig {
        max_version,
        feedback_removes_objects: true,
        ..SimConfig::default()
    };
    let server = match SimServer::bind(listen.as_str(), config).await {
        Ok(server) => server,
        Err(e) => {
            eprintln!("smartgrasp_simulator: cannot listen on {listen}: {e}");
            return ExitCode::FAILURE;
        }
    };
    // Scripts wait for this exact first line; flush so they do not wait on a pipe's buffer.
    println!("listening on {}", server.local_addr());
    let _ = std::io::stdout().flush();
    if let Err(e) = tokio::signal::ctrl_c().await {
        eprintln!("smartgrasp_simulator: cannot wait for Ctrl-C: {e}");
        return ExitCode::FAILURE;
    }
    server.shutdown();
    ExitCode::SUCCESS
}

fn parse_args(mut args: impl Iterator<Item = String>) -> Result<(String, u16), String> {
    let mut listen = format!("127.0.0.1:{}", gripper::smartgrasp::DEFAULT_PORT);
    let mut max_version = SimConfig::default().max_version;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--listen" => listen = args.next().ok_or("--listen needs an address")?,
            "--max-version" => {
                max_version = match args.next().as_deref() {
                    Some("3") => 3,
                    Some("4") => 4,
                    other => return Err(format!("--max-version takes 3 or 4, not {other:?}")),
                }
            }
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok((listen, max_version))
}
