//! `gripctl wsg --text …`: the same subcommands over the WSG's text interface (GCL,
//! `gripper::wsg::text`), for a gripper set to "Use text based interface", where they map:
//! `info` (the GCL queries), `home`, `move` (absolute only), `grasp` (`GRIP(force, width,
//! speed)`), `release` (GCL releases by a pull-back distance: the tool reads the width first and
//! pulls back to WIDTH_MM), `stop`, `fast-stop`, `ack` (`FSACK()`) and `watch` (`AUTOSEND`).
//! Every run ends with `BYE()`, so the gripper does not raise FAST STOP.

use std::time::Duration;

use gripper::wsg::text::{Client, ClientConfig, Quantity};
use gripper::wsg::{GripState, HomingDirection};
use serde_json::json;

use super::show::{grip_json, grip_name};
use super::{report_motion, Command, Direction};
use crate::error::{classify, CliError, Kind};
use crate::output::Out;

/// The force of `grasp` without `--force`, N: GCL's `GRIP` takes the force first, so one is
/// always sent (half a WSG 50's nominal force, as the simulator's default).
const DEFAULT_FORCE_N: f32 = 40.0;

/// Connects, runs `command`, and says `BYE()` in every case.
pub(super) async fn run(
    addr: &str,
    command: Command,
    timeout: Option<Duration>,
    out: Out,
) -> Result<(), CliError> {
    let mut config = ClientConfig::default();
    if let Some(t) = timeout {
        config.query_timeout = t;
        config.motion_timeout = t;
        config.connect_timeout = t;
    }
    let client = Client::connect_with(addr, config)
        .await
        .map_err(|e| classify(e).context("cannot connect"))?;
    let is_watch = matches!(command, Command::Watch { .. });
    let result = tokio::select! {
        r = execute(&client, command, out) => r,
        _ = tokio::signal::ctrl_c() => {
            if is_watch {
                Ok(())
            } else {
                let _ = client.stop().await;
                Err(CliError::new(Kind::Interrupted, "interrupted: STOP() sent"))
            }
        }
    };
    let closed = client.close().await.map_err(classify);
    result.and(closed)
}

async fn execute(client: &Client, command: Command, out: Out) -> Result<(), CliError> {
    match command {
        Command::Info => {
            let pos = client.position_mm().await.map_err(classify)?;
            let speed = client.speed_mm_per_s().await.map_err(classify)?;
            let force = client.force_n().await.map_err(classify)?;
            let grip = client.grip_state().await.map_err(classify)?;
            let temp = client.temperature_c().await.map_err(classify)?;
            out.emit(
                format!(
                    "width: {pos:.1} mm\nspeed: {speed:.1} mm/s\nforce: {force:.1} N\n\
                     grip state: {}\ntemperature: {temp:.1} °C",
                    grip_name(grip)
                ),
                json!({ "width_mm": pos, "speed_mm_per_s": speed, "force_n": force,
                        "grip_state": grip_json(grip), "temperature_c": temp }),
            )
        }
        Command::Home { direction } => {
            let direction = match direction {
                Direction::Default => HomingDirection::Default,
                Direction::Positive => HomingDirection::Positive,
                Direction::Negative => HomingDirection::Negative,
            };
            client.home(direction).await.map_err(classify)?;
            after_motion(client, "homed", out).await
        }
        Command::Move {
            width_mm,
            speed,
            relative: false,
        } => {
            let speed = Some(f64::from(speed));
            client
                .move_to(f64::from(width_mm), speed)
                .await
                .map_err(classify)?;
            after_motion(client, "moved", out).await
        }
        Command::Grasp {
            width_mm,
            speed,
            force,
        } => {
            let force = f64::from(force.unwrap_or(DEFAULT_FORCE_N));
            client
                .grip_part(force, f64::from(width_mm), Some(f64::from(speed)))
                .await
                .map_err(classify)?;
            after_motion(client, "grasped", out).await
        }
        Command::Release { width_mm, speed } => {
            // GCL's RELEASE is relative (manual chapter 2): pull back by what is missing.
            let now = client.position_mm().await.map_err(classify)?;
            let pull_back = f64::from(width_mm) - now;
            client
                .release(Some(pull_back), Some(f64::from(speed)))
                .await
                .map_err(classify)?;
            after_motion(client, "released", out).await
        }
        Command::Stop => {
            client.stop().await.map_err(classify)?;
            after_motion(client, "stopped", out).await
        }
        Command::FastStop => {
            client.fast_stop().await.map_err(classify)?;
            out.emit(
                "FAST STOP: motion refused until `gripctl wsg --text ack`",
                json!({ "done": "fast-stop" }),
            )
        }
        Command::Ack => {
            client.ack_fast_stop().await.map_err(classify)?;
            out.emit("acknowledged", json!({ "done": "ack" }))
        }
        Command::Watch { count, period } => watch(client, count, period, out).await,
        other => Err(CliError::argument(format!(
            "{} is not available over the text interface",
            name(&other)
        ))),
    }
}

fn name(command: &Command) -> &'static str {
    match command {
        Command::Move { .. } => "move --relative",
        Command::Set(_) => "set",
        Command::Loop { .. } => "loop",
        Command::Raw { .. } => "raw",
        _ => "this command",
    }
}

async fn after_motion(client: &Client, done: &str, out: Out) -> Result<(), CliError> {
    let grip = client.grip_state().await.map_err(classify)?;
    let width_mm = client.position_mm().await.map_err(classify)?;
    let force_n = client.force_n().await.map_err(classify)?;
    // GCL's values have one decimal (shared note §2): `f32` keeps them exactly.
    report_motion(done, width_mm as f32, force_n as f32, grip, out)
}

/// `AUTOSEND` of the width, speed, force and grip state; one line each time all four have a
/// value newer than the last line.
async fn watch(
    client: &Client,
    count: Option<u64>,
    period: Duration,
    out: Out,
) -> Result<(), CliError> {
    let ms = u16::try_from(period.as_millis().max(10))
        .map_err(|_| CliError::argument("--period is at most 65535 ms over the text interface"))?;
    let mut pushes = client.pushes();
    for q in [
        Quantity::Position,
        Quantity::Speed,
        Quantity::Force,
        Quantity::GripState,
    ] {
        drop(client.autosend(q, ms, false).await.map_err(classify)?);
    }
    let mut sample: [Option<f64>; 4] = [None; 4];
    let mut printed = 0u64;
    while count.is_none_or(|c| printed < c) {
        let Some(push) = pushes.recv().await else {
            return Err(CliError::new(Kind::Connection, "the connection ended"));
        };
        let slot = match push.quantity {
            Quantity::Position => 0,
            Quantity::Speed => 1,
            Quantity::Force => 2,
            _ => 3,
        };
        sample[slot] = Some(push.value);
        if let [Some(w), Some(s), Some(f), Some(g)] = sample {
            let grip = GripState::from_u8(g.clamp(0.0, 255.0) as u8);
            out.emit(
                format!(
                    "width {w:.2} mm, speed {s:.1} mm/s, force {f:.1} N, grip state {}",
                    grip_name(grip)
                ),
                json!({ "width_mm": w, "speed_mm_per_s": s, "force_n": f,
                        "grip_state": grip_json(grip) }),
            )?;
            sample = [None; 4];
            printed += 1;
        }
    }
    Ok(())
}
