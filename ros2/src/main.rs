//! `gripper-ros2`: the node's command line (see the library, `gripper_ros2`, and the README's
//! "ROS 2" section).

use std::process::ExitCode;

use gripper_ros2::params::{Cli, USAGE};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "-h" || a == "--help") {
        println!("{USAGE}");
        return ExitCode::SUCCESS;
    }
    let cli = match Cli::parse(
        &args,
        |k| std::env::var(k).ok(),
        |f| std::fs::read_to_string(f).map_err(|e| e.to_string()),
    ) {
        Ok(cli) => cli,
        Err(e) => {
            eprintln!("gripper-ros2: {e}");
            return ExitCode::from(2);
        }
    };
    // After the parse: --log-level and the log destinations are arguments.
    gripper_ros2::logging::init(&cli);
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("gripper-ros2: no runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match runtime.block_on(gripper_ros2::run(cli, signal())) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gripper-ros2: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Completes on SIGINT or SIGTERM (or at once if they cannot be watched).
async fn signal() {
    use tokio::signal::unix::{signal, SignalKind};
    let (Ok(mut term), Ok(mut int)) = (
        signal(SignalKind::terminate()),
        signal(SignalKind::interrupt()),
    ) else {
        eprintln!("gripper-ros2: cannot watch SIGINT/SIGTERM");
        return;
    };
    tokio::select! {
        _ = term.recv() => {}
        _ = int.recv() => {}
    }
}
