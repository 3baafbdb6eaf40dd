//! GRIPLINK's workload: every public method of `Client`, `Port` and `Watch`, called by name
//! (the API-coverage step greps for `.method(`), with valid and edge-case arguments, on ports
//! 0 and 2 (both hold a device) and the empty ports 1 and 3, so that calls in flight together
//! differ only in a port or an index and a mispaired reply shows. Each call is logged as a
//! [`CallRec`] for the oracle (`oracle.rs`).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use futures_util::StreamExt;
use gripper::griplink::command::{
    Blocking, Command, Expect, FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled,
    GripConfig, GripConfigF,
};
use gripper::griplink::{Client, ClientConfig, Error, WaitBy};
use tokio::time::Instant;

use crate::core::Prng;

/// How the oracle reads the controller's reply to a call's line the way the call's method does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Render {
    /// `execute`/`command`: the `Answer` itself.
    Answer,
    /// A method that returns `()` on `ACK`.
    Unit,
    /// A string value.
    Str,
    /// An integer value.
    Int,
    /// `DEVVID`: `-1` is `None`.
    VendorId,
    /// A float value.
    Float,
    /// A device state.
    State,
    /// `VERBOSE`: the mode reported back.
    Bool,
    /// A recipe with integer parameters.
    Recipe,
    /// A recipe with float parameters.
    RecipeF,
}

/// What one call of the workload does.
#[derive(Clone, Debug)]
pub enum Op {
    /// One command line through its typed method (`render` says which).
    Typed(Command, Render),
    /// `Client::execute`.
    Execute(Command),
    /// `Client::command` with the command's line.
    Raw(Command),
    /// A grip or release helper that waits for the outcome (several commands).
    Wait {
        port: u8,
        kind: WaitKind,
        by: WaitBy,
    },
    /// `watch_state` or `watch_value`: a few readings, then dropped.
    Watch {
        port: u8,
        value: bool,
        interval: Duration,
        n: usize,
    },
    /// The handle's own accessors (no command): `is_closed`, `config`, `port().number()`,
    /// `port().client()`, `connection_events`.
    Local,
}

/// Which helper a [`Op::Wait`] is.
#[derive(Clone, Copy, Debug)]
pub enum WaitKind {
    Grip(u32),
    Release(u32),
    FlexGrip,
    FlexGripScaled,
    FlexRelease,
    FlexReleaseScaled,
}

impl WaitKind {
    /// A grip (its outcomes: holding, no part, fault).
    pub fn is_grip(&self) -> bool {
        matches!(
            self,
            WaitKind::Grip(_) | WaitKind::FlexGrip | WaitKind::FlexGripScaled
        )
    }
}

impl Op {
    /// The single command line the call sends (`None`: several, or none).
    pub fn line(&self) -> Option<String> {
        match self {
            Op::Typed(c, _) | Op::Execute(c) | Op::Raw(c) => c.encode().ok(),
            _ => None,
        }
    }

    /// Its expected reply shape.
    pub fn expect(&self) -> Expect {
        match self {
            Op::Typed(c, _) | Op::Execute(c) => c.expect(),
            _ => Expect::Any,
        }
    }

    /// How the oracle reads its reply.
    pub fn render(&self) -> Render {
        match self {
            Op::Typed(_, r) => *r,
            _ => Render::Answer,
        }
    }

    /// A short name for the call's kind (rule 10 lists the kinds; rule 2 names them).
    pub fn kind(&self) -> String {
        match self {
            Op::Typed(c, _) => format!("typed {}", head(c)),
            Op::Execute(c) => format!("execute {}", head(c)),
            Op::Raw(c) => format!("command {}", head(c)),
            Op::Wait { kind, by, .. } => format!("{kind:?} and wait {by:?}"),
            Op::Watch { value, .. } => format!("watch (value {value})"),
            Op::Local => "local".into(),
        }
    }

    /// Whether a helper (a wait or a watch) may send `line` among its commands.
    pub fn may_send(&self, line: &str) -> bool {
        match self {
            Op::Watch { port, value, .. } => {
                line == if *value {
                    format!("VALUEF[{port}][0]?")
                } else {
                    format!("DEVSTATE[{port}]?")
                }
            }
            Op::Wait { port, .. } => {
                line.contains(&format!("({port},")) || line.contains(&format!("[{port}]"))
            }
            _ => false,
        }
    }
}

/// Whether `c` holds the connection on the controller until it is done (manual 2.1).
pub fn holds(c: &Command) -> bool {
    matches!(
        c,
        Command::Home(_)
            | Command::Wstr(_)
            | Command::WaitVal { .. }
            | Command::WaitValF { .. }
            | Command::Grip {
                blocking: Blocking::UntilDone,
                ..
            }
            | Command::Release {
                blocking: Blocking::UntilDone,
                ..
            }
            | Command::FlexGrip(_, _, Blocking::UntilDone)
            | Command::FlexGripF(_, _, Blocking::UntilDone)
            | Command::FlexRelease(_, _, Blocking::UntilDone)
            | Command::FlexReleaseF(_, _, Blocking::UntilDone)
    )
}

/// The key of a command's line (`GRIP`, `VALUE`…), for the kind's name.
fn head(c: &Command) -> String {
    let line = c.encode().unwrap_or_default();
    line.split(['(', '[', '?', '='])
        .next()
        .unwrap_or("")
        .to_owned()
}

/// The timeout a call gets: the handle's, or the configured one for its command (client docs,
/// "Timeouts and late replies").
pub fn timeout_of(op: &Op, handle: Option<Duration>, config: &ClientConfig) -> Duration {
    if let (Some(t), false) = (handle, matches!(op, Op::Watch { .. })) {
        return t;
    }
    match op {
        Op::Typed(c, _) | Op::Execute(c) | Op::Raw(c) => match c {
            Command::WaitVal { timeout, .. } | Command::WaitValF { timeout, .. } => {
                timeout.saturating_add(config.wait_margin)
            }
            _ if holds(c) => config.motion_timeout,
            _ => config.query_timeout,
        },
        Op::Wait { .. } => config.motion_timeout,
        // Each reading is a query of its own, one interval apart.
        Op::Watch { interval, n, .. } => {
            let each = interval.saturating_add(handle.unwrap_or(config.query_timeout));
            each.saturating_mul(*n as u32 + 1)
        }
        _ => config.query_timeout,
    }
}

/// One call as the caller saw it.
#[derive(Debug)]
pub struct CallRec {
    pub client: usize,
    pub op: Op,
    pub start: Instant,
    pub end: Instant,
    /// Its timeout (`Duration::MAX`: none).
    pub timeout: Duration,
    /// Its result read as its method returns it (`Debug`), or `None` if the caller gave up.
    pub result: Option<Result<String, Error>>,
}

/// A port: 0 and 2 hold a device, 1 and 3 are empty (`SimConfig::et4`).
fn port(rng: &mut Prng) -> u8 {
    rng.below(4) as u8
}

/// Mostly a device's port, now and then an empty one.
fn device_port(rng: &mut Prng) -> u8 {
    if rng.one_in(6) {
        port(rng)
    } else if rng.one_in(2) {
        0
    } else {
        2
    }
}

fn blocking(rng: &mut Prng) -> Blocking {
    if rng.one_in(2) {
        Blocking::UntilDone
    } else {
        Blocking::Immediate
    }
}

/// A recipe index: 0–3, now and then one past the table (16) or `u32::MAX`.
fn index(rng: &mut Prng) -> u32 {
    match rng.below(12) {
        0 => 16,
        1 => u32::MAX,
        _ => rng.below(4) as u32,
    }
}

/// A WAITVAL timeout: short, zero, or beyond the manual's limit now and then.
fn wait_timeout(rng: &mut Prng) -> Duration {
    match rng.below(8) {
        0 => Duration::ZERO,
        1 => Duration::MAX,
        _ => rng.millis(1, 3000),
    }
}

fn flex_grip(rng: &mut Prng) -> FlexGrip {
    FlexGrip {
        position_mm: rng.below(40) as f64 / 2.0,
        force_n: rng.between(1, 100) as f64,
        speed_mm_per_s: rng.between(1, 200) as f64,
        acceleration_mm_per_s2: rng.between(0, 1000) as f64,
    }
}

fn flex_grip_scaled(rng: &mut Prng) -> FlexGripScaled {
    FlexGripScaled {
        position_um: rng.below(20_000) as i32,
        force_mn: rng.between(1, 100_000) as i32,
        speed_um_per_s: rng.between(1, 200_000) as i32,
        acceleration_um_per_s2: rng.between(0, 1_000_000) as i32,
    }
}

fn flex_release(rng: &mut Prng) -> FlexRelease {
    FlexRelease {
        position_mm: rng.below(40) as f64 / 2.0,
        speed_mm_per_s: rng.between(1, 200) as f64,
        acceleration_mm_per_s2: rng.between(0, 1000) as f64,
    }
}

fn flex_release_scaled(rng: &mut Prng) -> FlexReleaseScaled {
    FlexReleaseScaled {
        position_um: rng.below(20_000) as i32,
        speed_um_per_s: rng.between(1, 200_000) as i32,
        acceleration_um_per_s2: rng.between(0, 1_000_000) as i32,
    }
}

/// A random call. `labels` numbers the values the workload sets, so that each `LABEL=`,
/// `DEVTAG=`, `SETVAL` is unique and its echo names its request.
pub fn pick(rng: &mut Prng, labels: &AtomicU64) -> Op {
    use Command as C;
    let unique = || labels.fetch_add(1, Ordering::SeqCst);
    let p = device_port(rng);
    let typed = |c, r| Op::Typed(c, r);
    match rng.below(48) {
        0 => typed(C::Id, Render::Str),
        1 => typed(C::Protocol, Render::Str),
        2 => typed(
            C::ProtAssert {
                identifier: if rng.one_in(3) { "NOPE" } else { "GRIPLINK" }.into(),
                min_version: [0, 1, 3, 4, u32::MAX][rng.below(5) as usize],
            },
            Render::Unit,
        ),
        3 => typed(C::SerialNumber, Render::Str),
        4 => typed(C::Label, Render::Str),
        5 => typed(C::SetLabel(format!("L{}", unique())), Render::Str),
        6 => typed(C::Version, Render::Str),
        7 => typed(C::SetVerbose(rng.one_in(2)), Render::Bool),
        8 => typed(C::DevVid(port(rng)), Render::VendorId),
        9 => typed(C::DevPid(port(rng)), Render::Int),
        10 => typed(
            C::DevAssert {
                port: port(rng),
                vendor_id: if rng.one_in(3) { 1 } else { 815 },
                product_id: rng.below(3) as u32,
            },
            Render::Unit,
        ),
        11 => typed(C::DevName(port(rng)), Render::Str),
        12 => typed(C::DevVendor(port(rng)), Render::Str),
        13 => typed(C::DevSn(port(rng)), Render::Str),
        14 => typed(C::DevTag(port(rng)), Render::Str),
        15 => typed(C::SetDevTag(p, format!("T{}", unique())), Render::Str),
        16 => typed(C::DevVer(port(rng)), Render::Str),
        17 => typed(C::Enable(p), Render::Unit),
        18 => typed(C::Disable(p), Render::Unit),
        19 | 20 => typed(C::Home(p), Render::Unit),
        21 | 22 => typed(
            C::Grip {
                port: p,
                index: index(rng),
                blocking: blocking(rng),
            },
            Render::Unit,
        ),
        23 | 24 => typed(
            C::Release {
                port: p,
                index: index(rng),
                blocking: blocking(rng),
            },
            Render::Unit,
        ),
        25 => typed(C::FlexGripF(p, flex_grip(rng), blocking(rng)), Render::Unit),
        26 => typed(
            C::FlexGrip(p, flex_grip_scaled(rng), blocking(rng)),
            Render::Unit,
        ),
        27 => typed(
            C::FlexReleaseF(p, flex_release(rng), blocking(rng)),
            Render::Unit,
        ),
        28 => typed(
            C::FlexRelease(p, flex_release_scaled(rng), blocking(rng)),
            Render::Unit,
        ),
        29 => typed(
            C::Led {
                port: p,
                index: rng.below(5) as u32,
            },
            Render::Unit,
        ),
        30 => typed(
            C::Clamp {
                port: p,
                enable: rng.one_in(2),
            },
            Render::Unit,
        ),
        31 => typed(C::Wstr(p), Render::State),
        32 => typed(
            C::SetVal {
                port: p,
                index: 1 + rng.below(3) as u32,
                value: unique() as i32,
            },
            Render::Unit,
        ),
        33 => typed(
            C::SetValF {
                port: p,
                index: 1 + rng.below(3) as u32,
                value: unique() as f64 / 4.0,
            },
            Render::Unit,
        ),
        34 => typed(
            C::WaitVal {
                port: p,
                index: 0,
                threshold: rng.below(20_000) as i32,
                window: rng.below(5_000) as i32,
                timeout: wait_timeout(rng),
            },
            Render::Unit,
        ),
        35 => typed(
            C::WaitValF {
                port: p,
                index: 0,
                threshold: rng.below(20) as f64,
                window: rng.below(5) as f64,
                timeout: wait_timeout(rng),
            },
            Render::Unit,
        ),
        36 | 37 => typed(C::DevState(port(rng)), Render::State),
        38 => typed(
            C::Value {
                port: p,
                index: rng.below(4) as u32,
            },
            Render::Int,
        ),
        39 => typed(
            C::ValueF {
                port: p,
                index: rng.below(4) as u32,
            },
            Render::Float,
        ),
        40 => {
            let i = rng.below(4) as u32;
            if rng.one_in(2) {
                typed(C::GripCfg { port: p, index: i }, Render::Recipe)
            } else {
                typed(C::GripCfgF { port: p, index: i }, Render::RecipeF)
            }
        }
        41 => {
            // Recipes 8-15: the motions use 0-3, whose speeds and limits stay the device's.
            let (i, n) = (8 + rng.below(8) as u32, unique() as i32);
            if rng.one_in(2) {
                let config = GripConfig {
                    tag: format!("R{n}"),
                    params: [n, 1, 2, 3, 4, 5, 6, 7],
                };
                typed(
                    C::SetGripCfg {
                        port: p,
                        index: i,
                        config,
                    },
                    Render::Recipe,
                )
            } else {
                let config = GripConfigF {
                    tag: format!("R{n}"),
                    params: [f64::from(n), 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.5],
                };
                typed(
                    C::SetGripCfgF {
                        port: p,
                        index: i,
                        config,
                    },
                    Render::RecipeF,
                )
            }
        }
        42 => Op::Execute(match rng.below(4) {
            0 => C::Id,
            1 => C::DevState(port(rng)),
            2 => C::Value {
                port: p,
                index: rng.below(2) as u32,
            },
            _ => C::Home(p),
        }),
        43 => Op::Raw(match rng.below(3) {
            0 => C::SerialNumber,
            1 => C::DevState(port(rng)),
            _ => C::ValueF { port: p, index: 0 },
        }),
        44 | 45 => Op::Wait {
            port: p,
            kind: match rng.below(6) {
                0 | 1 => WaitKind::Grip(index(rng).min(3)),
                2 => WaitKind::Release(index(rng).min(3)),
                3 => WaitKind::FlexGrip,
                4 => WaitKind::FlexGripScaled,
                _ if rng.one_in(2) => WaitKind::FlexRelease,
                _ => WaitKind::FlexReleaseScaled,
            },
            by: if rng.one_in(2) {
                WaitBy::Transition
            } else {
                // `Duration::ZERO` too: the helper then pauses MIN_POLL_INTERVAL (before the
                // clamp it polled back to back and the simulated clock never moved again:
                // griplink-tcp:0x2726fa0c478ed35b hung).
                WaitBy::Polling(match rng.below(6) {
                    0 => Duration::ZERO,
                    _ => rng.millis(1, 300),
                })
            },
        },
        46 => Op::Watch {
            port: p,
            value: rng.one_in(2),
            interval: match rng.below(6) {
                0 => Duration::ZERO,
                _ => rng.millis(1, 300),
            },
            n: rng.between(1, 4) as usize,
        },
        _ => Op::Local,
    }
}

/// Makes the call `op` through `client` (its timeout set or not), each method by its name;
/// returns its result as the method returned it (`Debug`).
pub async fn perform(client: &Client, op: &Op, rng: &mut Prng) -> Result<String, Error> {
    fn show<T: std::fmt::Debug>(r: Result<T, Error>) -> Result<String, Error> {
        r.map(|v| format!("{v:?}"))
    }
    match op {
        Op::Execute(c) => show(client.execute(c).await),
        Op::Raw(c) => show(client.command(&c.encode()?).await),
        Op::Local => {
            let port = client.port(device_port(rng));
            let same = port.client().config().pipeline_depth == client.config().pipeline_depth;
            drop(client.connection_events());
            // Whether it is closed depends on the faults: called, not judged here (rule 5
            // judges the calls).
            let _ = client.is_closed();
            Ok(format!("{} {same}", port.number()))
        }
        Op::Wait { port, kind, by } => {
            let pt = client.port(*port);
            let by = *by;
            match *kind {
                WaitKind::Grip(i) => show(pt.grip_and_wait(i, by).await),
                WaitKind::Release(i) => show(pt.release_and_wait(i, by).await),
                WaitKind::FlexGrip => show(pt.flex_grip_and_wait(flex_grip(rng), by).await),
                WaitKind::FlexGripScaled => show(
                    pt.flex_grip_scaled_and_wait(flex_grip_scaled(rng), by)
                        .await,
                ),
                WaitKind::FlexRelease => {
                    show(pt.flex_release_and_wait(flex_release(rng), by).await)
                }
                WaitKind::FlexReleaseScaled => show(
                    pt.flex_release_scaled_and_wait(flex_release_scaled(rng), by)
                        .await,
                ),
            }
        }
        Op::Watch {
            port,
            value,
            interval,
            n,
        } => {
            let pt = client.port(*port);
            let mut seen = Vec::new();
            if *value {
                let mut w = pt.watch_value(0, *interval);
                while seen.len() < *n {
                    match w.next().await {
                        Some(r) => seen.push(format!("{r:?}")),
                        None => break,
                    }
                }
            } else {
                let mut w = pt.watch_state(*interval);
                while seen.len() < *n {
                    match w.next().await {
                        Some(r) => seen.push(format!("{r:?}")),
                        None => break,
                    }
                }
            }
            Ok(seen.join(", "))
        }
        Op::Typed(c, _) => typed(client, c).await,
    }
}

/// A typed command through the method that sends it.
async fn typed(client: &Client, c: &Command) -> Result<String, Error> {
    use Command as C;
    fn show<T: std::fmt::Debug>(r: Result<T, Error>) -> Result<String, Error> {
        r.map(|v| format!("{v:?}"))
    }
    match c.clone() {
        C::Id => show(client.id().await),
        C::Protocol => show(client.protocol().await),
        C::ProtAssert {
            identifier,
            min_version,
        } => show(client.protocol_assert(&identifier, min_version).await),
        C::SerialNumber => show(client.serial_number().await),
        C::Label => show(client.label().await),
        C::SetLabel(l) => show(client.set_label(&l).await),
        C::Version => show(client.version().await),
        C::SetVerbose(on) => show(client.set_verbose(on).await),
        C::DevVid(p) => show(client.port(p).vendor_id().await),
        C::DevPid(p) => show(client.port(p).product_id().await),
        C::DevAssert {
            port,
            vendor_id,
            product_id,
        } => show(client.port(port).assert_device(vendor_id, product_id).await),
        C::DevName(p) => show(client.port(p).name().await),
        C::DevVendor(p) => show(client.port(p).vendor().await),
        C::DevSn(p) => show(client.port(p).serial_number().await),
        C::DevTag(p) => show(client.port(p).tag().await),
        C::SetDevTag(p, t) => show(client.port(p).set_tag(&t).await),
        C::DevVer(p) => show(client.port(p).version().await),
        C::Enable(p) => show(client.port(p).enable().await),
        C::Disable(p) => show(client.port(p).disable().await),
        C::Home(p) => show(client.port(p).home().await),
        C::Grip {
            port,
            index,
            blocking,
        } => show(client.port(port).grip(index, blocking).await),
        C::Release {
            port,
            index,
            blocking,
        } => show(client.port(port).release(index, blocking).await),
        C::FlexGripF(p, f, b) => show(client.port(p).flex_grip(f, b).await),
        C::FlexGrip(p, f, b) => show(client.port(p).flex_grip_scaled(f, b).await),
        C::FlexReleaseF(p, f, b) => show(client.port(p).flex_release(f, b).await),
        C::FlexRelease(p, f, b) => show(client.port(p).flex_release_scaled(f, b).await),
        C::Led { port, index } => show(client.port(port).led(index).await),
        C::Clamp { port, enable } => show(client.port(port).clamp(enable).await),
        C::Wstr(p) => show(client.port(p).wait_for_transition().await),
        C::SetVal { port, index, value } => show(client.port(port).set_value(index, value).await),
        C::SetValF { port, index, value } => {
            show(client.port(port).set_value_f(index, value).await)
        }
        C::WaitVal {
            port,
            index,
            threshold,
            window,
            timeout,
        } => show(
            client
                .port(port)
                .wait_value(index, threshold, window, timeout)
                .await,
        ),
        C::WaitValF {
            port,
            index,
            threshold,
            window,
            timeout,
        } => show(
            client
                .port(port)
                .wait_value_f(index, threshold, window, timeout)
                .await,
        ),
        C::DevState(p) => show(client.port(p).state().await),
        C::Value { port, index: 0 } if port % 2 == 0 => show(client.port(port).position_um().await),
        C::Value { port, index } => show(client.port(port).value(index).await),
        C::ValueF { port, index: 0 } if port % 2 == 0 => {
            show(client.port(port).position_mm().await)
        }
        C::ValueF { port, index } => show(client.port(port).value_f(index).await),
        C::GripCfg { port, index } => show(client.port(port).grip_config(index).await),
        C::SetGripCfg {
            port,
            index,
            config,
        } => show(client.port(port).set_grip_config(index, &config).await),
        C::GripCfgF { port, index } => show(client.port(port).grip_config_f(index).await),
        C::SetGripCfgF {
            port,
            index,
            config,
        } => show(client.port(port).set_grip_config_f(index, &config).await),
        other => show(client.execute(&other).await),
    }
}
