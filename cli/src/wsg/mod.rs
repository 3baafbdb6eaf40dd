//! `gripctl wsg …`: Weiss WSG grippers over the binary protocol (manual seed 000), over TCP,
//! UDP or RS-232, one command per run.
//!
//! Every run ends with [`Client::close`]: over TCP it announces the disconnect (0x07, manual
//! 3.1.2), since a connection that just drops puts the gripper into FAST STOP. Ctrl-C during a
//! motion sends STOP (0x22) before closing; during `watch` it ends the watch.

mod info;
mod live;
mod show;
mod text;
mod trace;

use std::future::Future;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::{Args as ClapArgs, Subcommand, ValueEnum};
use gripper::wsg::client::{DEFAULT_MOTION_TIMEOUT, DEFAULT_QUERY_TIMEOUT};
use gripper::wsg::transport::DEFAULT_BAUD_RATE;
use gripper::wsg::DEFAULT_PORT;
use gripper::wsg::{Client, ClientBuilder, Error, HomingDirection, SoftLimits, Status};
use serde_json::json;

use crate::common::{parse_duration, parse_hex, with_default_port};
use crate::error::{classify, CliError, DeviceCode, Kind};
use crate::output::Out;
use show::{decode_reply, grip_json, grip_name, num, soft_limits_json, status_json, to_hex};

/// Default finger speed of `move`, `grasp` and `release` when `--speed` is not given, mm/s: slow
/// enough to watch during commissioning on every model (the WSG 25's maximum is well above it).
const DEFAULT_SPEED_MM_PER_S: f32 = 20.0;

/// How long `connect` may take when `--timeout` is not given.
const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// Options of `gripctl wsg`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The gripper: HOST or HOST:PORT (port 1000 when omitted, the WSG's default).
    #[arg(long, default_value = "127.0.0.1", conflicts_with = "serial")]
    addr: String,
    /// Talk UDP to --addr (one frame per datagram) instead of TCP.
    #[arg(long, conflicts_with = "serial")]
    udp: bool,
    /// With --udp: the local address to send from and receive on (the port the gripper is
    /// configured to answer to) [default: any free port].
    #[arg(long, requires = "udp")]
    local: Option<SocketAddr>,
    /// Talk RS-232 over this serial port (8N1) instead of TCP.
    #[arg(long)]
    serial: Option<String>,
    /// Baud rate of --serial.
    #[arg(long, default_value_t = DEFAULT_BAUD_RATE, requires = "serial")]
    baud: u32,
    /// Open --serial without exclusive access (needed for the simulator's pseudo-terminal).
    #[arg(long, requires = "serial")]
    shared: bool,
    /// With home, move, grasp or release: record width, speed and force every 10 ms until the
    /// final reply and draw them in this SVG file.
    #[arg(long, global = true, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Talk the text interface (GCL) over TCP instead of the binary protocol: for a gripper set
    /// to "Use text based interface" (info, home, move, grasp, release, stop, fast-stop, ack,
    /// watch).
    #[arg(long, conflicts_with_all = ["udp", "serial", "plot"])]
    text: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Type, firmware, serial number, limits, tag, temperature, state flags, grip state.
    Info,
    /// Homing (0x20): reference the fingers; needed before any other motion.
    Home {
        /// Direction of the homing move.
        #[arg(long, value_enum, default_value_t = Direction::Default)]
        direction: Direction,
    },
    /// Pre-position (0x21): move the fingers to a width, stopping if blocked.
    Move {
        /// Target width in mm (with --relative: distance from the current width).
        #[arg(allow_negative_numbers = true)]
        width_mm: f32,
        /// Finger speed in mm/s.
        #[arg(long, default_value_t = DEFAULT_SPEED_MM_PER_S)]
        speed: f32,
        /// Move by WIDTH_MM from the current width.
        #[arg(long)]
        relative: bool,
    },
    /// Grasp (0x25) a part of nominal width WIDTH_MM; fails with E_CMD_FAILED if none is found.
    Grasp {
        /// Nominal width of the part in mm.
        width_mm: f32,
        /// Finger speed in mm/s.
        #[arg(long, default_value_t = DEFAULT_SPEED_MM_PER_S)]
        speed: f32,
        /// Set the grasping force (0x32) to this many N first.
        #[arg(long)]
        force: Option<f32>,
    },
    /// Release (0x26) the part, opening to WIDTH_MM.
    Release {
        /// Width to open to, mm.
        width_mm: f32,
        /// Finger speed in mm/s.
        #[arg(long, default_value_t = DEFAULT_SPEED_MM_PER_S)]
        speed: f32,
    },
    /// Stop (0x22) any motion.
    Stop,
    /// FAST STOP (0x23): stop, and refuse motion until `ack`.
    FastStop,
    /// Acknowledge (0x24) a FAST STOP or fault.
    Ack,
    /// Set a parameter.
    #[command(subcommand)]
    Set(Setting),
    /// Live width, speed, force and grip state from auto-updates, until Ctrl-C or --count.
    Watch {
        /// Stop after this many samples.
        #[arg(long)]
        count: Option<u64>,
        /// Update period, e.g. 100ms (at least 10 ms).
        #[arg(long, default_value = "100ms", value_parser = parse_duration)]
        period: Duration,
    },
    /// Loop test (0x06): the gripper echoes bytes; checks each echo.
    Loop {
        /// Bytes per round, 1 to 256.
        #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u16).range(1..=256))]
        size: u16,
        /// Rounds.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
        repeat: u32,
    },
    /// Send command ID with a hex payload, print the reply (status and data).
    Raw {
        /// Command id, e.g. 0x40 or 64.
        #[arg(value_parser = parse_id)]
        id: u8,
        /// Payload in hex, e.g. "00 00 00" or 000000 [default: empty].
        #[arg(default_value = "")]
        payload: String,
    },
}

#[derive(Debug, Subcommand)]
enum Setting {
    /// Grasping force (0x32), N; the gripper clamps it to its limits.
    Force {
        /// Force in N.
        force_n: f32,
    },
    /// Acceleration (0x30), mm/s²; the gripper clamps it to its limits.
    Acceleration {
        /// Acceleration in mm/s².
        mm_per_s2: f32,
    },
    /// Soft limits (0x34), or clear them (0x36).
    SoftLimits {
        /// Negative limit, mm.
        #[arg(required_unless_present = "clear", allow_negative_numbers = true)]
        minus_mm: Option<f32>,
        /// Positive limit, mm.
        #[arg(required_unless_present = "clear", allow_negative_numbers = true)]
        plus_mm: Option<f32>,
        /// Clear the soft limits instead.
        #[arg(long, conflicts_with_all = ["minus_mm", "plus_mm"])]
        clear: bool,
    },
    /// Device tag (0x51): printable ASCII, at most 64 characters.
    Tag {
        /// The tag.
        tag: String,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Direction {
    /// The direction configured on the gripper.
    Default,
    /// Outwards.
    Positive,
    /// Inwards.
    Negative,
}

fn parse_id(text: &str) -> Result<u8, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u8::from_str_radix(hex, 16),
        None => text.parse(),
    };
    parsed.map_err(|_| format!("{text:?} is not a command id (0 to 255, or 0x00 to 0xFF)"))
}

/// Runs one `gripctl wsg` command.
pub async fn run(args: Args, timeout: Option<Duration>, out: Out) -> Result<(), CliError> {
    let is_motion = matches!(
        args.command,
        Command::Home { .. }
            | Command::Move { .. }
            | Command::Grasp { .. }
            | Command::Release { .. }
    );
    if args.plot.is_some() && !is_motion {
        return Err(CliError::argument(
            "--plot traces home, move, grasp and release only",
        ));
    }
    if args.text {
        let place = describe(&args);
        return text::run(&place, args.command, timeout, out)
            .await
            .map_err(|e| e.context(format!("wsg --text {place}")));
    }
    let (client, place) = connect(&args, timeout)
        .await
        .map_err(|e| e.context(format!("wsg {}", describe(&args))))?;
    let context = format!("wsg {place}");
    let is_watch = matches!(args.command, Command::Watch { .. });
    let result = tokio::select! {
        r = execute(&client, args.command, args.plot.as_deref(), timeout, out) => r,
        _ = tokio::signal::ctrl_c() => {
            if is_watch {
                Ok(())
            } else {
                // Whatever was moving must not go on without the operator watching.
                let _ = client.stop().await;
                Err(CliError::new(Kind::Interrupted, "interrupted: STOP sent"))
            }
        }
    };
    // Close in every case (announced on TCP, so the gripper does not go into FAST STOP), within
    // a bound so that a gripper that stopped answering cannot hang the tool.
    let close_timeout = timeout.unwrap_or(DEFAULT_QUERY_TIMEOUT);
    let closed = match tokio::time::timeout(close_timeout, client.close()).await {
        Ok(r) => r.map_err(classify),
        Err(_) => Err(CliError::new(
            Kind::Timeout,
            "closing the connection timed out",
        )),
    };
    result.and(closed).map_err(|e| e.context(context))
}

/// Where the command goes, for messages: the address or serial port.
fn describe(args: &Args) -> String {
    match &args.serial {
        Some(path) => format!("{path} at {} Bd", args.baud),
        None => with_default_port(&args.addr, DEFAULT_PORT),
    }
}

async fn connect(args: &Args, timeout: Option<Duration>) -> Result<(Client, String), CliError> {
    let builder = Client::builder()
        .query_timeout(timeout.unwrap_or(DEFAULT_QUERY_TIMEOUT))
        .motion_timeout(timeout.unwrap_or(DEFAULT_MOTION_TIMEOUT));
    let connect_timeout = timeout.unwrap_or(DEFAULT_CONNECT_TIMEOUT);
    let place = describe(args);
    let connecting = open(args, builder, &place);
    let client = tokio::time::timeout(connect_timeout, connecting)
        .await
        .map_err(|_| {
            CliError::new(
                Kind::Timeout,
                format!("cannot connect: no answer within {connect_timeout:?}"),
            )
        })??;
    Ok((client, place))
}

async fn open(args: &Args, builder: ClientBuilder, addr: &str) -> Result<Client, CliError> {
    let cannot = |e: Error| classify(e).context("cannot connect");
    if let Some(path) = &args.serial {
        return builder
            .serial_exclusive(!args.shared)
            .open_serial(path, args.baud)
            .map_err(cannot);
    }
    if args.udp {
        let remote = tokio::net::lookup_host(addr)
            .await
            .map_err(|e| cannot(Error::from(e)))?
            .next()
            .ok_or_else(|| CliError::argument(format!("{addr} resolves to no address")))?;
        return match args.local {
            Some(local) => builder.connect_udp_from(local, remote).await,
            None => builder.connect_udp(remote).await,
        }
        .map_err(cannot);
    }
    builder.connect_tcp(addr).await.map_err(cannot)
}

async fn execute(
    client: &Client,
    command: Command,
    plot: Option<&Path>,
    timeout: Option<Duration>,
    out: Out,
) -> Result<(), CliError> {
    match command {
        Command::Info => info::info(client, out).await,
        Command::Home { direction } => {
            let direction = match direction {
                Direction::Default => HomingDirection::Default,
                Direction::Positive => HomingDirection::Positive,
                Direction::Negative => HomingDirection::Negative,
            };
            let what = format!("home ({direction:?})");
            run_motion(client, plot, what, None, client.home(direction), out).await?;
            after_motion(client, "homed", out).await
        }
        Command::Move {
            width_mm,
            speed,
            relative,
        } => {
            if relative {
                let what = format!("move by {width_mm:.1} mm at {speed:.1} mm/s");
                run_motion(
                    client,
                    plot,
                    what,
                    None,
                    client.pre_position_relative(width_mm, speed),
                    out,
                )
                .await?;
            } else {
                let what = format!("move to {width_mm:.1} mm at {speed:.1} mm/s");
                run_motion(
                    client,
                    plot,
                    what,
                    Some(width_mm),
                    client.pre_position(width_mm, speed),
                    out,
                )
                .await?;
            }
            after_motion(client, "moved", out).await
        }
        Command::Grasp {
            width_mm,
            speed,
            force,
        } => {
            if let Some(force_n) = force {
                client.set_grasping_force(force_n).await.map_err(classify)?;
            }
            let what = format!("grasp {width_mm:.1} mm at {speed:.1} mm/s");
            run_motion(
                client,
                plot,
                what,
                Some(width_mm),
                client.grasp(width_mm, speed),
                out,
            )
            .await?;
            after_motion(client, "grasped", out).await
        }
        Command::Release { width_mm, speed } => {
            let what = format!("release to {width_mm:.1} mm at {speed:.1} mm/s");
            run_motion(
                client,
                plot,
                what,
                Some(width_mm),
                client.release(width_mm, speed),
                out,
            )
            .await?;
            after_motion(client, "released", out).await
        }
        Command::Stop => {
            client.stop().await.map_err(classify)?;
            after_motion(client, "stopped", out).await
        }
        Command::FastStop => {
            client.fast_stop().await.map_err(classify)?;
            out.emit(
                "FAST STOP: motion refused until `gripctl wsg ack`",
                json!({ "done": "fast-stop" }),
            )
        }
        Command::Ack => {
            client.acknowledge_fast_stop().await.map_err(classify)?;
            out.emit("acknowledged", json!({ "done": "ack" }))
        }
        Command::Set(setting) => set(client, setting, out).await,
        Command::Watch { count, period } => live::watch(client, count, period, out).await,
        Command::Loop { size, repeat } => live::loop_test(client, size, repeat, out).await,
        Command::Raw { id, payload } => {
            let payload = parse_hex(&payload).map_err(CliError::argument)?;
            let timeout = timeout.unwrap_or(DEFAULT_MOTION_TIMEOUT);
            let reply = client
                .request_with_timeout(id, payload, timeout)
                .await
                .map_err(classify)?;
            if reply.status != Status::Success {
                return Err(device_error(
                    format!("command {id:#04x} answered {}", reply.status),
                    reply.status,
                ));
            }
            let hex = to_hex(&reply.data);
            let decoded = decode_reply(id, &reply.data);
            let mut human = format!("{id:#04x} {}: [{hex}]", reply.status.symbol());
            if let Some((text, _)) = &decoded {
                human.push_str(&format!(" = {text}"));
            }
            out.emit(
                human,
                json!({
                    "id": id,
                    "status": status_json(reply.status),
                    "data": hex,
                    "decoded": decoded.map(|(_, v)| v),
                }),
            )
        }
    }
}

/// Runs a motion command, traced into `plot` when asked.
async fn run_motion(
    client: &Client,
    plot: Option<&Path>,
    what: String,
    target_mm: Option<f32>,
    command: impl Future<Output = gripper::wsg::Result<()>>,
    out: Out,
) -> Result<(), CliError> {
    match plot {
        Some(path) => {
            let motion = trace::Motion { what, target_mm };
            trace::traced(client, path, motion, command, out).await
        }
        None => command.await.map_err(classify),
    }
}

/// After a motion: where the fingers ended up, and the grip state (HOLDING after a grasp).
async fn after_motion(client: &Client, done: &str, out: Out) -> Result<(), CliError> {
    let grip = client.grip_state().await.map_err(classify)?;
    let width_mm = client.width_mm().await.map_err(classify)?;
    let force_n = client.force_n().await.map_err(classify)?;
    report_motion(done, width_mm, force_n, grip, out)
}

/// The line (and JSON) after a motion, for both interfaces.
pub(super) fn report_motion(
    done: &str,
    width_mm: f32,
    force_n: f32,
    grip: gripper::wsg::GripState,
    out: Out,
) -> Result<(), CliError> {
    out.emit(
        format!(
            "{done}: width {width_mm:.2} mm, force {force_n:.1} N, grip state {}",
            grip_name(grip)
        ),
        json!({
            "done": done,
            "width_mm": num(width_mm),
            "force_n": num(force_n),
            "grip_state": grip_json(grip),
        }),
    )
}

async fn set(client: &Client, setting: Setting, out: Out) -> Result<(), CliError> {
    match setting {
        Setting::Force { force_n } => {
            client.set_grasping_force(force_n).await.map_err(classify)?;
            // The gripper clamps: report what it took.
            let now = client.grasping_force_n().await.map_err(classify)?;
            out.emit(
                format!("grasping force {now:.1} N"),
                json!({ "grasping_force_n": num(now) }),
            )
        }
        Setting::Acceleration { mm_per_s2 } => {
            client.set_acceleration(mm_per_s2).await.map_err(classify)?;
            let now = client.acceleration_mm_per_s2().await.map_err(classify)?;
            out.emit(
                format!("acceleration {now:.0} mm/s²"),
                json!({ "acceleration_mm_per_s2": num(now) }),
            )
        }
        Setting::SoftLimits {
            minus_mm,
            plus_mm,
            clear,
        } => {
            match (clear, minus_mm, plus_mm) {
                (false, Some(minus_mm), Some(plus_mm)) => client
                    .set_soft_limits(SoftLimits { minus_mm, plus_mm })
                    .await
                    .map_err(classify)?,
                _ => client.clear_soft_limits().await.map_err(classify)?,
            }
            let now = client.soft_limits().await.map_err(classify)?;
            out.emit(
                now.map_or("soft limits: none".to_owned(), |l| {
                    format!("soft limits: {:.2} mm … {:.2} mm", l.minus_mm, l.plus_mm)
                }),
                json!({ "soft_limits": now.map(|l| soft_limits_json(&l)) }),
            )
        }
        Setting::Tag { tag } => {
            client.set_device_tag(&tag).await.map_err(classify)?;
            let now = client.device_tag().await.map_err(classify)?;
            out.emit(
                format!("tag: {}", now.as_deref().unwrap_or("(none)")),
                json!({ "tag": now }),
            )
        }
    }
}

/// A query the gripper may not support: `None` when it answers that it has no such data or
/// does not know the command.
pub(super) fn optional<T>(reply: gripper::wsg::Result<T>) -> Result<Option<T>, CliError> {
    match reply {
        Ok(v) => Ok(Some(v)),
        Err(Error::Device {
            status: Status::NotAvailable | Status::CmdUnknown | Status::FeatureNotSupported,
            ..
        }) => Ok(None),
        Err(e) => Err(classify(e)),
    }
}

pub(super) fn device_error(message: String, status: Status) -> CliError {
    CliError::device(message, device_code(status))
}

/// A WSG status code (binary and text interface share the table) as `gripctl` reports it.
pub(crate) fn device_code(status: Status) -> DeviceCode {
    DeviceCode {
        number: status.code().into(),
        name: status.symbol().to_owned(),
        description: status.description().to_owned(),
    }
}
