//! `gripctl`: commission WSG grippers, GRIPLINK controllers and the SCHUNK 2D Grasping-Kit from a
//! terminal, and serve their simulators, with the `gripper` crate.
//!
//! Every command prints text by default and one JSON object per line with `--json` (accepted
//! anywhere on the line). On failure it prints one line, `gripctl: <what failed>`, to stderr
//! (with `--json`, also `{"error": {...}}` on stdout) and exits with status 1; a command line
//! clap cannot parse exits with 2.

mod common;
mod error;
mod griplink;
mod output;
mod plot;
mod sim;
mod smartgrasp;
mod wsg;

use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};

use crate::error::CliError;
use crate::output::Out;

/// Commission grippers and grasp planners, and serve their simulators.
#[derive(Debug, Parser)]
#[command(name = "gripctl", version, about, propagate_version = true)]
struct Cli {
    /// Print JSON, one object per line, instead of text.
    #[arg(long, global = true)]
    json: bool,
    /// Timeout of connecting and of each request, e.g. 500ms, 2s, 1.5 [default: the library's,
    /// short for queries, long for motion and detection].
    #[arg(long, global = true, value_parser = common::parse_duration)]
    timeout: Option<Duration>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Weiss WSG grippers (binary protocol over TCP port 1000, UDP or RS-232).
    Wsg(wsg::Args),
    /// Weiss GRIPLINK controllers (ASCII lines over TCP port 10001).
    Griplink(griplink::Args),
    /// SCHUNK 2D Grasping-Kit (native protocol V3, TCP port 42001).
    Smartgrasp(smartgrasp::Args),
    /// Serve a simulator.
    Sim(sim::Args),
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    let out = Out::new(cli.json);
    let result = match cli.command {
        Command::Wsg(args) => wsg::run(args, cli.timeout, out).await,
        Command::Griplink(args) => griplink::run(args, cli.timeout, out).await,
        Command::Smartgrasp(args) => smartgrasp::run(args, cli.timeout, out).await,
        Command::Sim(args) => sim::run(args, out).await,
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            report(&e, out);
            ExitCode::FAILURE
        }
    }
}

/// `--help` and `--version` print as clap prints them; a command line that does not parse gets
/// the same one-line error as any other failure (exit status 2), not clap's multi-line usage.
fn usage_error(e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion)
        || e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    {
        let _ = e.print();
        return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
    }
    let rendered = e.render().to_string();
    let message = rendered
        .lines()
        .take_while(|l| !l.starts_with("Usage:"))
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("tip:") && !l.starts_with("For more information")
        })
        .collect::<Vec<_>>()
        .join(" ");
    let message = message.strip_prefix("error: ").unwrap_or(&message);
    let error = CliError::argument(format!("{message} (see gripctl --help)"));
    // The mode could not be parsed; a script that asked for JSON still gets it.
    report(&error, Out::new(std::env::args().any(|a| a == "--json")));
    ExitCode::from(2)
}

fn report(e: &CliError, out: Out) {
    if out.is_json() {
        // Best effort: the error line on stderr is the one that must get out.
        let _ = out.emit("", e.to_json());
    }
    eprintln!("gripctl: {e}");
}
