//! Serves the simulated Smart Grasping server (V3) with the demo project (three parts) until
//! killed.
//!
//! ```text
//! cargo run --example smartgrasp_simulator -- --listen 127.0.0.1:42001
//! ```
//!
//! The first line of standard output is `listening on <bound address>` (port 0 picks a free
//! port). Set `RUST_LOG=debug` to see every request.

use std::io::Write;
use std::process::ExitCode;

use gripper::smartgrasp::sim::{SimConfig, SimServer};

#[tokio::main]
async fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let listen = match parse_args(std::env::args().skip(1)) {
        Ok(listen) => listen,
        Err(message) => {
            eprintln!("smartgrasp_simulator: {message}");
            eprintln!("usage: smartgrasp_simulator [--listen HOST:PORT]");
            return ExitCode::from(2);
        }
    };
    let server = match SimServer::bind(listen.as_str(), SimConfig::default()).await {
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

fn parse_args(mut args: impl Iterator<Item = String>) -> Result<String, String> {
    let mut listen = format!("127.0.0.1:{}", gripper::smartgrasp::DEFAULT_PORT);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--listen" => listen = args.next().ok_or("--listen needs an address")?,
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok(listen)
}
