//! `gripctl griplink …`: Weiss GRIPLINK controllers (Unified Command Set, manual seed 004), ASCII
//! lines over TCP, one command per run. Every run ends with `BYE()` (manual 3.3.1).

mod trace;

use std::future::Future;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::{Args as ClapArgs, Subcommand};
use gripper::griplink::client::{GripOutcome, ReleaseOutcome, WaitBy};
use gripper::griplink::command::{FlexGrip, FlexRelease, GripConfigF, MAX_PORT};
use gripper::griplink::reply::Data;
use gripper::griplink::value::Value as WireValue;
use gripper::griplink::{
    Answer, Blocking, Client, ClientConfig, DeviceState, Error, Port, PortNumber, Status,
    DEFAULT_PORT,
};
use serde_json::{json, Value};

use crate::common::{parse_duration, with_default_port};
use crate::error::{classify, CliError, DeviceCode, Kind};
use crate::output::Out;
use trace::{Motion, Tracer};

/// How often `grip` and `release` poll the device state for the outcome (DEVSTATE, manual
/// 3.4.4 option 2), leaving the connection free in between.
const OUTCOME_POLL: Duration = Duration::from_millis(20);

/// Options of `gripctl griplink`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// The controller: HOST or HOST:PORT (port 10001 when omitted).
    #[arg(long, default_value = "127.0.0.1")]
    addr: String,
    /// The device port the command addresses (0 to 31).
    #[arg(long, global = true, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=i64::from(MAX_PORT)))]
    port: PortNumber,
    /// With home, grip, release, flexgrip or flexrelease: poll the position and device state
    /// every 20 ms (over a second connection) until the final reply and draw them in this SVG.
    #[arg(long, global = true, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The controller's ID, protocol, version, serial number and label, and each port's device.
    Info,
    /// HOME: reference drive; returns when it is done (manual 3.4.3).
    Home,
    /// GRIP with a recipe, and wait for the outcome: DS_HOLDING, else an error (manual 3.4.4).
    Grip {
        /// The grip recipe (GRIPCFG index).
        #[arg(default_value_t = 0)]
        recipe: u32,
    },
    /// RELEASE with a recipe, and wait for DS_RELEASED (manual 3.4.5).
    Release {
        /// The grip recipe (GRIPCFG index).
        #[arg(default_value_t = 0)]
        recipe: u32,
    },
    /// FLEXGRIPF: grip with explicit parameters; waits until done (manual 3.4.6).
    Flexgrip {
        /// Target position, the no-part limit, mm.
        position_mm: f64,
        /// Gripping force, N.
        force_n: f64,
        /// Speed, mm/s; 0 = computed from the force.
        #[arg(long, default_value_t = 0.0)]
        speed: f64,
        /// Acceleration, mm/s²; 0 = the device's default.
        #[arg(long, default_value_t = 0.0)]
        acceleration: f64,
    },
    /// FLEXRELEASEF: release or pre-position to a position; waits until done (manual 3.4.7).
    Flexrelease {
        /// Target position, mm.
        position_mm: f64,
        /// Speed, mm/s; 0 = the device's default.
        #[arg(long, default_value_t = 0.0)]
        speed: f64,
        /// Acceleration, mm/s²; 0 = the device's default.
        #[arg(long, default_value_t = 0.0)]
        acceleration: f64,
    },
    /// DEVSTATE: the device's state (manual 3.5.1, chapter 5).
    State,
    /// VALUEF: a process value in the device's unit; index 0 is a gripper's position in mm.
    Value {
        /// The value index.
        #[arg(default_value_t = 0)]
        index: u32,
    },
    /// Poll the device state and position until Ctrl-C or --count samples.
    Watch {
        /// Stop after this many samples.
        #[arg(long)]
        count: Option<u64>,
        /// Polling period, e.g. 100ms (the same option as `gripctl wsg watch`).
        #[arg(long, alias = "interval", default_value = "100ms", value_parser = parse_duration)]
        period: Duration,
    },
    /// Grip recipes (GRIPCFGF, manual 3.6.1).
    #[command(subcommand)]
    Recipe(Recipe),
    /// Send one command line, print the reply (e.g. `raw 'DEVNAME[0]?'`).
    Raw {
        /// The line, without LF.
        line: String,
    },
}

#[derive(Debug, Subcommand)]
enum Recipe {
    /// Read a recipe.
    Get {
        /// The recipe index.
        index: u32,
    },
    /// Write a recipe (a Weiss gripper's parameters; the rest 0).
    Set {
        /// The recipe index.
        index: u32,
        /// The recipe's name (at most 32 characters).
        tag: String,
        /// No-part limit, mm.
        no_part_limit_mm: f64,
        /// Release limit, mm.
        release_limit_mm: f64,
        /// Force factor, % (0 to 100).
        force_percent: f64,
        /// WPG only: grip speed, mm/s.
        #[arg(long, default_value_t = 0.0)]
        grip_speed: f64,
        /// WPG only: grip acceleration, mm/s².
        #[arg(long, default_value_t = 0.0)]
        grip_acceleration: f64,
        /// WPG only: release speed, mm/s.
        #[arg(long, default_value_t = 0.0)]
        release_speed: f64,
        /// WPG only: release acceleration, mm/s².
        #[arg(long, default_value_t = 0.0)]
        release_acceleration: f64,
    },
}

/// Runs one `gripctl griplink` command.
pub async fn run(args: Args, timeout: Option<Duration>, out: Out) -> Result<(), CliError> {
    let is_motion = matches!(
        args.command,
        Command::Home
            | Command::Grip { .. }
            | Command::Release { .. }
            | Command::Flexgrip { .. }
            | Command::Flexrelease { .. }
    );
    if args.plot.is_some() && !is_motion {
        return Err(CliError::argument(
            "--plot traces home, grip, release, flexgrip and flexrelease only",
        ));
    }
    let addr = with_default_port(&args.addr, DEFAULT_PORT);
    let mut context = format!("griplink {addr}");
    let mut config = ClientConfig::default();
    if let Some(t) = timeout {
        config.connect_timeout = t;
        config.query_timeout = t;
        config.motion_timeout = t;
    }
    let client = Client::connect_with(addr.as_str(), config.clone())
        .await
        .map_err(|e| classify(e).context(format!("{context}: cannot connect")))?;
    let tracer = match &args.plot {
        Some(path) => match Tracer::connect(&addr, config, args.port, path).await {
            Ok(tracer) => Some(tracer),
            Err(e) => {
                let _ = tokio::time::timeout(close_timeout(timeout), client.close()).await;
                return Err(e.context(context));
            }
        },
        None => None,
    };
    let port = client.port(args.port);
    // Controller-wide commands do not name a port in their errors.
    if !matches!(args.command, Command::Info | Command::Raw { .. }) {
        context.push_str(&format!(" port {}", args.port));
    }
    let is_watch = matches!(args.command, Command::Watch { .. });
    let result = tokio::select! {
        r = execute(&client, &port, args.command, tracer.as_ref(), out) => r,
        _ = tokio::signal::ctrl_c() => if is_watch {
            Ok(())
        } else {
            Err(CliError::new(Kind::Interrupted, "interrupted"))
        },
    };
    // BYE() in every case, so the controller ends the session cleanly (manual 3.3.1); bounded,
    // since it queues behind a blocking motion that Ctrl-C left running.
    if let Some(tracer) = tracer {
        // Best effort: the motion's own connection is the one whose close matters.
        let _ = tokio::time::timeout(close_timeout(timeout), tracer.close()).await;
    }
    let closed = match tokio::time::timeout(close_timeout(timeout), client.close()).await {
        Ok(r) => r.map_err(classify),
        Err(_) => Err(CliError::new(Kind::Timeout, "no answer to BYE()")),
    };
    result.and(closed).map_err(|e| e.context(context))
}

/// How long `BYE()` may take.
fn close_timeout(timeout: Option<Duration>) -> Duration {
    timeout.unwrap_or(ClientConfig::default().query_timeout)
}

/// Runs a motion command, traced when `--plot` asked.
async fn run_motion<T>(
    tracer: Option<&Tracer>,
    motion: impl FnOnce() -> Motion,
    command: impl Future<Output = gripper::griplink::Result<T>>,
    out: Out,
) -> Result<T, CliError> {
    match tracer {
        Some(tracer) => tracer.traced(motion(), command, out).await,
        None => command.await.map_err(classify),
    }
}

/// A recipe motion for a trace, with the recipe's target and force limit; read only when there
/// is a trace, and without them when the recipe cannot be read (no reference line then).
async fn recipe_motion(
    tracer: Option<&Tracer>,
    port: &Port,
    what: String,
    index: u32,
    grip: bool,
) -> Motion {
    let recipe = match tracer {
        Some(_) => port.grip_config_f(index).await.ok(),
        None => None,
    };
    // GRIPCFGF parameters of a gripper: no-part limit, release limit, force factor (3.6.1).
    Motion {
        what,
        target_mm: recipe
            .as_ref()
            .map(|r| if grip { r.params[0] } else { r.params[1] }),
        force: recipe
            .filter(|_| grip)
            .map(|r| format!("{} %", r.params[2])),
    }
}

async fn execute(
    client: &Client,
    port: &Port,
    command: Command,
    tracer: Option<&Tracer>,
    out: Out,
) -> Result<(), CliError> {
    match command {
        Command::Info => info(client, out).await,
        Command::Home => {
            let motion = || Motion {
                what: "home".to_owned(),
                ..Motion::default()
            };
            run_motion(tracer, motion, port.home(), out).await?;
            after_motion(port, "homed", out).await
        }
        Command::Grip { recipe } => {
            let motion =
                recipe_motion(tracer, port, format!("grip recipe {recipe}"), recipe, true).await;
            let waiting = port.grip_and_wait(recipe, WaitBy::Polling(OUTCOME_POLL));
            let outcome = run_motion(tracer, || motion, waiting, out).await?;
            match outcome {
                GripOutcome::Holding => after_motion(port, "gripped", out).await,
                GripOutcome::NoPart => {
                    Err(state_error("the grip found no part", DeviceState::NoPart))
                }
                GripOutcome::Fault => {
                    Err(state_error("the grip ended in a fault", DeviceState::Fault))
                }
            }
        }
        Command::Release { recipe } => {
            let what = format!("release recipe {recipe}");
            let motion = recipe_motion(tracer, port, what, recipe, false).await;
            let waiting = port.release_and_wait(recipe, WaitBy::Polling(OUTCOME_POLL));
            let outcome = run_motion(tracer, || motion, waiting, out).await?;
            match outcome {
                ReleaseOutcome::Released => after_motion(port, "released", out).await,
                ReleaseOutcome::Fault => Err(state_error(
                    "the release ended in a fault",
                    DeviceState::Fault,
                )),
            }
        }
        Command::Flexgrip {
            position_mm,
            force_n,
            speed,
            acceleration,
        } => {
            let params = FlexGrip {
                position_mm,
                force_n,
                speed_mm_per_s: speed,
                acceleration_mm_per_s2: acceleration,
            };
            let motion = || Motion {
                what: format!("flexgrip to {position_mm:.1} mm"),
                target_mm: Some(position_mm),
                force: Some(format!("{force_n:.1} N")),
            };
            let gripping = port.flex_grip(params, Blocking::UntilDone);
            run_motion(tracer, motion, gripping, out).await?;
            match port.state().await.map_err(classify)? {
                DeviceState::Holding => after_motion(port, "gripped", out).await,
                DeviceState::NoPart => {
                    Err(state_error("the grip found no part", DeviceState::NoPart))
                }
                // Anything but holding after a finished grip is not a grip.
                other => Err(state_error("the grip did not end holding a part", other)),
            }
        }
        Command::Flexrelease {
            position_mm,
            speed,
            acceleration,
        } => {
            let params = FlexRelease {
                position_mm,
                speed_mm_per_s: speed,
                acceleration_mm_per_s2: acceleration,
            };
            let motion = || Motion {
                what: format!("flexrelease to {position_mm:.1} mm"),
                target_mm: Some(position_mm),
                force: None,
            };
            let releasing = port.flex_release(params, Blocking::UntilDone);
            run_motion(tracer, motion, releasing, out).await?;
            match port.state().await.map_err(classify)? {
                DeviceState::Fault => Err(state_error(
                    "the release ended in a fault",
                    DeviceState::Fault,
                )),
                _ => after_motion(port, "released", out).await,
            }
        }
        Command::State => {
            let state = port.state().await.map_err(classify)?;
            out.emit(state, json!({ "state": state_json(state) }))
        }
        Command::Value { index } => {
            let value = port.value_f(index).await.map_err(classify)?;
            out.emit(value, json!({ "index": index, "value": value }))
        }
        Command::Watch { count, period } => watch(port, count, period, out).await,
        Command::Recipe(Recipe::Get { index }) => {
            let recipe = port.grip_config_f(index).await.map_err(classify)?;
            out.emit(recipe_text(index, &recipe), recipe_json(index, &recipe))
        }
        Command::Recipe(Recipe::Set {
            index,
            tag,
            no_part_limit_mm,
            release_limit_mm,
            force_percent,
            grip_speed,
            grip_acceleration,
            release_speed,
            release_acceleration,
        }) => {
            let mut recipe =
                GripConfigF::gripper(tag, no_part_limit_mm, release_limit_mm, force_percent);
            recipe.params[3] = grip_speed;
            recipe.params[4] = grip_acceleration;
            recipe.params[5] = release_speed;
            recipe.params[6] = release_acceleration;
            let stored = port
                .set_grip_config_f(index, &recipe)
                .await
                .map_err(classify)?;
            out.emit(recipe_text(index, &stored), recipe_json(index, &stored))
        }
        Command::Raw { line } => match client.command(&line).await.map_err(classify)? {
            Answer::Ack => out.emit("ACK", json!({ "reply": "ACK" })),
            Answer::Data(data) => out.emit(&data, data_json(&data)),
        },
    }
}

async fn info(client: &Client, out: Out) -> Result<(), CliError> {
    let id = client.id().await.map_err(classify)?;
    let protocol = client.protocol().await.map_err(classify)?;
    let version = client.version().await.map_err(classify)?;
    let serial = client.serial_number().await.map_err(classify)?;
    let label = client.label().await.map_err(classify)?;
    let mut human = format!(
        "ID: {id}\nprotocol: {protocol}\nversion: {version}\nserial number: {serial}\nlabel: {label}"
    );
    let mut ports = Vec::new();
    let mut empty = Vec::new();
    for number in 0..=MAX_PORT {
        let port = client.port(number);
        // The controller has as many ports as answer; the first one past them is out of bounds.
        let vendor_id = match port.vendor_id().await {
            Ok(v) => v,
            Err(Error::Device {
                status: Status::IndexOutOfBounds,
                ..
            }) => break,
            Err(e) => return Err(classify(e)),
        };
        let Some(vendor_id) = vendor_id else {
            empty.push(number);
            ports.push(json!({ "port": number, "device": null }));
            continue;
        };
        let name = port.name().await.map_err(classify)?;
        let product_id = port.product_id().await.map_err(classify)?;
        let state = port.state().await.map_err(classify)?;
        // Not every IO-Link device has these: one it lacks must not hide the rest.
        let vendor = optional(port.vendor().await)?;
        let serial = optional(port.serial_number().await)?;
        let version = optional(port.version().await)?;
        let tag = optional(port.tag().await)?;
        let na = |v: &Option<String>| v.clone().unwrap_or_else(|| "n/a".to_owned());
        human.push_str(&format!(
            "\nport {number}: {name} ({}, vendor {vendor_id}, product {product_id}), \
             serial {}, firmware {}, tag {}, {state}",
            na(&vendor),
            na(&serial),
            na(&version),
            tag.as_ref().map_or("n/a".to_owned(), |t| format!("{t:?}")),
        ));
        ports.push(json!({
            "port": number,
            "device": {
                "name": name,
                "vendor": vendor,
                "vendor_id": vendor_id,
                "product_id": product_id,
                "serial_number": serial,
                "version": version,
                "tag": tag,
                "state": state_json(state),
            },
        }));
    }
    if !empty.is_empty() {
        let list: Vec<String> = empty.iter().map(u8::to_string).collect();
        human.push_str(&format!("\nno device on port {}", list.join(", ")));
    }
    out.emit(
        human,
        json!({
            "id": id,
            "protocol": protocol,
            "version": version,
            "serial_number": serial,
            "label": label,
            "ports": ports,
        }),
    )
}

async fn after_motion(port: &Port, done: &str, out: Out) -> Result<(), CliError> {
    let state = port.state().await.map_err(classify)?;
    let position_mm = port.position_mm().await.map_err(classify)?;
    out.emit(
        format!("{done}: position {position_mm:.3} mm, {state}"),
        json!({ "done": done, "position_mm": position_mm, "state": state_json(state) }),
    )
}

async fn watch(
    port: &Port,
    count: Option<u64>,
    interval: Duration,
    out: Out,
) -> Result<(), CliError> {
    let mut ticker = tokio::time::interval(interval);
    // A slow controller delays the next sample rather than bunching samples up.
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let start = Instant::now();
    let mut emitted = 0;
    while count.is_none_or(|n| emitted < n) {
        ticker.tick().await;
        let state = port.state().await.map_err(classify)?;
        let position_mm = port.position_mm().await.map_err(classify)?;
        let elapsed = start.elapsed().as_secs_f64();
        out.emit(
            format!("{elapsed:8.3} s  position {position_mm:8.3} mm  {state}"),
            json!({ "elapsed_s": elapsed, "position_mm": position_mm, "state": state_json(state) }),
        )?;
        emitted += 1;
    }
    Ok(())
}

/// A reading the device may not support: `None` when it answers that it has no such data.
fn optional<T>(reading: gripper::griplink::Result<T>) -> Result<Option<T>, CliError> {
    match reading {
        Ok(v) => Ok(Some(v)),
        Err(Error::Device {
            status: Status::NotAvailable | Status::NotSupported | Status::CmdUnknown,
            ..
        }) => Ok(None),
        Err(e) => Err(classify(e)),
    }
}

impl crate::error::Classify for Error {
    fn kind(&self) -> gripper::ErrorKind {
        Error::kind(self)
    }
    /// The controller's status code, with the manual's identifier and description.
    fn code(&self) -> Option<DeviceCode> {
        self.status().map(|status| DeviceCode {
            number: status.code(),
            name: status.identifier().unwrap_or("unknown").to_owned(),
            description: status.description().unwrap_or_default().to_owned(),
        })
    }
}

/// A motion that ended in the wrong device state: the state is the device's answer.
fn state_error(what: &str, state: DeviceState) -> CliError {
    CliError::device(
        format!("{what}: {state} ({})", state_description(state)),
        DeviceCode {
            number: u32::try_from(state.code()).unwrap_or(u32::MAX),
            name: state.to_string(),
            description: state_description(state).to_owned(),
        },
    )
}

/// The manual's meaning of each device state (chapter 5).
fn state_description(state: DeviceState) -> &'static str {
    match state {
        DeviceState::NotConnected => "no device connected",
        DeviceState::NotInitialized => "not initialized; a gripper needs HOME first",
        DeviceState::Disabled => "idle, waiting for a command",
        DeviceState::Released => "released: at the release position",
        DeviceState::NoPart => "the grip reached the no-part limit without finding a part",
        DeviceState::Holding => "holding a part with the gripping force",
        DeviceState::Enabled => "in operation",
        DeviceState::Fault => "fault; see the device manual for recovery",
        _ => "a state the manual does not list",
    }
}

fn state_json(state: DeviceState) -> Value {
    json!({
        "name": state.to_string(),
        "code": state.code(),
        "description": state_description(state),
    })
}

fn recipe_text(index: u32, r: &GripConfigF) -> String {
    let p = r.params;
    format!(
        "recipe {index} {:?}: no-part limit {} mm, release limit {} mm, force {} %, \
         grip speed {} mm/s, grip acceleration {} mm/s², release speed {} mm/s, \
         release acceleration {} mm/s²",
        r.tag, p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    )
}

fn recipe_json(index: u32, r: &GripConfigF) -> Value {
    let p = r.params;
    json!({
        "index": index,
        "tag": r.tag,
        "no_part_limit_mm": p[0],
        "release_limit_mm": p[1],
        "force_percent": p[2],
        "grip_speed_mm_per_s": p[3],
        "grip_acceleration_mm_per_s2": p[4],
        "release_speed_mm_per_s": p[5],
        "release_acceleration_mm_per_s2": p[6],
        "params": p,
    })
}

fn data_json(data: &Data) -> Value {
    json!({ "reply": data.to_string(), "key": data.key, "indices": data.indices, "value": wire_json(&data.value) })
}

fn wire_json(v: &WireValue) -> Value {
    match v {
        WireValue::Int(i) => json!(i),
        // ±INF has no JSON number: it is written as the string the controller sent.
        WireValue::Float(f) if f.is_finite() => json!(f),
        WireValue::Float(f) => json!(if *f > 0.0 { "+INF" } else { "-INF" }),
        WireValue::Str(s) => json!(s),
        WireValue::List(items) => Value::Array(items.iter().map(wire_json).collect()),
    }
}
