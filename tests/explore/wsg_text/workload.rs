//! The GCL workload: what one caller does over `gripper::wsg::text::Client`, and what each call
//! returned, recorded for the oracle with the exact command line the client writes (the
//! simulator records the lines it reads: the oracle pairs them).

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::wsg::text::line::{encode_call, encode_set};
use gripper::wsg::text::{Client, Error, Quantity};
use gripper::wsg::HomingDirection;
use tokio::time::Instant;

use super::Ctx;
use crate::core::phases::unless_given_up;
use crate::core::{note, Prng, SharedTrace};

/// What a command's reply is, on the wire (the client's pairing by name: `task.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expect {
    /// `NAME=value`.
    Value,
    /// `ACK NAME`.
    Ack,
    /// `ACK NAME`, then `FIN NAME`.
    Fin,
}

/// How a call ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Res {
    /// A value (a grip state or a VERBOSE mode as its number).
    Value(f64),
    /// `ACK` (or `FIN` for a motion).
    Done,
    /// `Error::Device`: this `ERR` line.
    Device(String),
    /// `Error::Closed`.
    Closed,
    /// `Error::ConnectionLost`.
    Lost,
    /// `Error::Timeout`.
    Timeout,
    /// `Error::MalformedReply` or `Error::UnexpectedReply`: a line of the call's name that is
    /// not a fit answer (only a corrupted line may be one).
    Malformed(String),
    /// Anything else (the workload's arguments are valid: always a violation).
    Other(String),
}

/// One call as the oracle sees it.
#[derive(Clone, Debug)]
pub struct CallRec {
    /// Which client (index).
    pub client: usize,
    /// The command line the client writes.
    pub line: String,
    /// The name its replies carry.
    pub name: &'static str,
    /// What answers it.
    pub expect: Expect,
    /// Call start and end (simulated).
    pub start: Instant,
    /// See `start`.
    pub end: Instant,
    /// Its timeout (`Duration::MAX`: none).
    pub timeout: Duration,
    /// How it ended.
    pub res: Res,
}

/// A push a stream handed out.
#[derive(Clone, Debug)]
pub struct PushRec {
    /// Which client.
    pub client: usize,
    /// `POS`, `SPEED`, …
    pub name: &'static str,
    /// The value.
    pub value: f64,
    /// When the stream handed it out.
    pub at: Instant,
}

/// Everything the callers of a run recorded.
#[derive(Default)]
pub struct Log {
    /// Every call that ended (not the cancelled ones).
    pub calls: Mutex<Vec<CallRec>>,
    /// Every push received.
    pub pushes: Mutex<Vec<PushRec>>,
}

/// A call of the workload: its line, name, reply form, and how to make it.
struct Op {
    line: String,
    name: &'static str,
    expect: Expect,
    call: Call,
}

enum Call {
    Home(HomingDirection),
    Move(f64, Option<f64>),
    Grip(Option<f64>),
    GripPart(f64, f64, Option<f64>),
    Release(Option<f64>, Option<f64>),
    Stop,
    FastStop,
    FastStopAck,
    Query(&'static str),
    Verbose(bool),
    SetTolerance(&'static str, f64),
    Autosend(Quantity, u16, bool),
    AutosendOff(Quantity),
}

/// Whole or half millimetres and speeds: the lines stay short and readable in a trace.
fn half(rng: &mut Prng, lo: u64, hi: u64) -> f64 {
    rng.between(lo * 2, hi * 2) as f64 / 2.0
}

fn op(rng: &mut Prng) -> Op {
    use Expect::{Ack, Fin, Value};
    let speed = |rng: &mut Prng| rng.one_in(2).then(|| half(rng, 10, 200));
    let (name, expect, call) = match rng.below(24) {
        0 | 1 => {
            let dir = [
                HomingDirection::Default,
                HomingDirection::Positive,
                HomingDirection::Negative,
            ][rng.below(3) as usize];
            ("HOME", Fin, Call::Home(dir))
        }
        2..=4 => ("MOVE", Fin, Call::Move(half(rng, 0, 110), speed(rng))),
        5 => (
            "GRIP",
            Fin,
            Call::Grip(rng.one_in(2).then(|| half(rng, 5, 80))),
        ),
        6 | 7 => {
            let w = if rng.one_in(2) {
                40.0
            } else {
                half(rng, 0, 110)
            };
            ("GRIP", Fin, Call::GripPart(half(rng, 5, 80), w, speed(rng)))
        }
        8 => {
            let d = rng.one_in(3).then(|| half(rng, 1, 30));
            let v = d.and_then(|_| speed(rng));
            ("RELEASE", Fin, Call::Release(d, v))
        }
        9 | 10 => ("STOP", Ack, Call::Stop),
        11 => {
            if rng.one_in(3) {
                ("FASTSTOP", Ack, Call::FastStop)
            } else {
                ("FSACK", Ack, Call::FastStopAck)
            }
        }
        12 | 13 => ("FSACK", Ack, Call::FastStopAck),
        14..=18 => {
            let q = ["POS", "SPEED", "FORCE", "GRIPSTATE", "TEMP"][rng.below(5) as usize];
            (q, Value, Call::Query(q))
        }
        19 => ("VERBOSE", Value, Call::Verbose(rng.one_in(2))),
        20 => {
            let what = if rng.one_in(2) { "PWT" } else { "CLT" };
            if rng.one_in(2) {
                (what, Value, Call::Query(what))
            } else {
                (what, Value, Call::SetTolerance(what, half(rng, 0, 20)))
            }
        }
        _ => {
            let q = [
                Quantity::Position,
                Quantity::Speed,
                Quantity::Force,
                Quantity::GripState,
                Quantity::Temperature,
            ][rng.below(5) as usize];
            if rng.one_in(5) {
                ("AUTOSEND", Ack, Call::AutosendOff(q))
            } else {
                let interval = rng.between(20, 500) as u16;
                ("AUTOSEND", Ack, Call::Autosend(q, interval, rng.one_in(3)))
            }
        }
    };
    let line = line_of(name, &call);
    Op {
        line,
        name,
        expect,
        call,
    }
}

/// The line `gripper::wsg::text::Client` writes for `call` (its encoders, `line.rs`).
fn line_of(name: &str, call: &Call) -> String {
    let args = |a: &[(&'static str, Option<f64>)]| {
        let a: Vec<_> = a.iter().filter_map(|(w, v)| v.map(|v| (*w, v))).collect();
        encode_call(name, &a).unwrap_or_default()
    };
    match call {
        Call::Home(HomingDirection::Default) => "HOME()".into(),
        Call::Home(HomingDirection::Positive) => "HOME(1)".into(),
        Call::Home(_) => "HOME(0)".into(),
        Call::Move(w, v) => args(&[("w", Some(*w)), ("v", *v)]),
        Call::Grip(f) => args(&[("f", *f)]),
        Call::GripPart(f, w, v) => args(&[("f", Some(*f)), ("w", Some(*w)), ("v", *v)]),
        Call::Release(d, v) => args(&[("d", *d), ("v", *v)]),
        Call::Stop | Call::FastStop | Call::FastStopAck => format!("{name}()"),
        Call::Query(q) => format!("{q}?"),
        Call::Verbose(on) => format!("VERBOSE={}", u8::from(*on)),
        Call::SetTolerance(what, mm) => encode_set(what, "mm", *mm).unwrap_or_default(),
        Call::Autosend(q, ms, on_change) => {
            let flag = if *on_change { ",true" } else { "" };
            format!("AUTOSEND(\"{}\",{ms}{flag})", q.name())
        }
        Call::AutosendOff(q) => format!("AUTOSEND(\"{}\",0)", q.name()),
    }
}

fn res<T>(r: Result<T, Error>, value: impl Fn(T) -> Res) -> Res {
    match r {
        Ok(v) => value(v),
        Err(e) => classify(&e),
    }
}

/// How an error reads to the oracle.
pub fn classify(e: &Error) -> Res {
    match e {
        Error::Device { line, .. } => Res::Device(line.clone()),
        Error::Closed => Res::Closed,
        Error::ConnectionLost { .. } => Res::Lost,
        Error::Timeout { .. } => Res::Timeout,
        Error::MalformedReply { .. } | Error::UnexpectedReply { .. } => {
            Res::Malformed(e.to_string())
        }
        other => Res::Other(other.to_string()),
    }
}

/// Runs `call` on `c`: how it ended, and when. An `AUTOSEND` that starts a stream ends with
/// its `ACK`; then it reads a few pushes (logged), drops the stream and stops the pushes (a
/// call of its own, logged).
async fn perform(
    c: &Client,
    call: &Call,
    ctx: &Ctx,
    rng: &mut Prng,
    log: &Log,
    trace: &SharedTrace,
) -> (Res, Instant) {
    if let Call::Autosend(q, ms, on_change) = call {
        return autosend(c, *q, *ms, *on_change, ctx, rng, log, trace).await;
    }
    let done = |()| Res::Done;
    let num = Res::Value;
    let r = match call {
        Call::Home(d) => res(c.home(*d).await, done),
        Call::Move(w, v) => res(c.move_to(*w, *v).await, done),
        Call::Grip(f) => res(c.grip(*f).await, done),
        Call::GripPart(f, w, v) => res(c.grip_part(*f, *w, *v).await, done),
        Call::Release(d, v) => res(c.release(*d, *v).await, done),
        Call::Stop => res(c.stop().await, done),
        Call::FastStop => res(c.fast_stop().await, done),
        Call::FastStopAck => res(c.ack_fast_stop().await, done),
        Call::Query("POS") => res(c.position_mm().await, num),
        Call::Query("SPEED") => res(c.speed_mm_per_s().await, num),
        Call::Query("FORCE") => res(c.force_n().await, num),
        Call::Query("GRIPSTATE") => res(c.grip_state().await, |s| Res::Value(s.to_u8().into())),
        Call::Query("TEMP") => res(c.temperature_c().await, num),
        Call::Query("PWT") => res(c.part_width_tolerance_mm().await, num),
        Call::Query(_) => res(c.clamping_travel_mm().await, num),
        Call::Verbose(on) => res(c.set_verbose(*on).await, |b| Res::Value(f64::from(b))),
        Call::SetTolerance("PWT", mm) => res(c.set_part_width_tolerance_mm(*mm).await, num),
        Call::SetTolerance(_, mm) => res(c.set_clamping_travel_mm(*mm).await, num),
        Call::AutosendOff(q) | Call::Autosend(q, ..) => res(c.stop_autosend(*q).await, done),
    };
    (r, Instant::now())
}

// The call's parts and the run's handles, each needed once: a struct would only rename them.
#[allow(clippy::too_many_arguments)]
async fn autosend(
    c: &Client,
    q: Quantity,
    ms: u16,
    on_change: bool,
    ctx: &Ctx,
    rng: &mut Prng,
    log: &Log,
    trace: &SharedTrace,
) -> (Res, Instant) {
    let mut pushes = match c.autosend(q, ms, on_change).await {
        Err(e) => return (classify(&e), Instant::now()),
        Ok(pushes) => pushes,
    };
    let acked = Instant::now();
    // Read a few, each within a bound, then drop the stream.
    for _ in 0..rng.between(1, 4) {
        let wait = Duration::from_millis(u64::from(ms) * 2 + 100);
        let Ok(Some(p)) = tokio::time::timeout(wait, pushes.recv()).await else {
            break;
        };
        note(trace, format!("client {}: push {p:?}", ctx.index));
        log.pushes.lock().unwrap().push(PushRec {
            client: ctx.index,
            name: p.quantity.name(),
            value: p.value,
            at: Instant::now(),
        });
    }
    drop(pushes);
    let off = Call::AutosendOff(q);
    let start = Instant::now();
    let c = c.with_timeout(ctx.config.query_timeout);
    let r = res(c.stop_autosend(q).await, |()| Res::Done);
    note(
        trace,
        format!(
            "client {}: {} -> {r:?}",
            ctx.index,
            line_of("AUTOSEND", &off)
        ),
    );
    log.calls.lock().unwrap().push(CallRec {
        client: ctx.index,
        line: line_of("AUTOSEND", &off),
        name: "AUTOSEND",
        expect: Expect::Ack,
        start,
        end: Instant::now(),
        timeout: ctx.config.query_timeout,
        res: r,
    });
    (Res::Done, acked)
}

/// One caller: `ops` calls on its client with random timeouts and cancellations; now and then
/// it closes the client (`BYE()`), or drops its connection without `BYE()` and opens another
/// (the device raises FAST STOP); after a lost connection a reconnecting client opens another.
pub async fn caller(
    ctx: Arc<Ctx>,
    k: usize,
    mut rng: Prng,
    ops: u32,
    log: Arc<Log>,
    trace: SharedTrace,
) {
    for _ in 0..ops {
        if ctx.closing.load(Ordering::SeqCst) {
            return;
        }
        if rng.one_in(150) {
            ctx.start_closing();
            let r = ctx.client().close().await;
            note(
                &trace,
                format!("client {} caller {k}: close {r:?}", ctx.index),
            );
            return;
        }
        if ctx.reconnect && rng.one_in(60) {
            ctx.reopen("a caller drops the connection without BYE()");
            continue;
        }
        let op = op(&mut rng);
        let timeout = match rng.below(30) {
            0 if ctx.forever => Duration::MAX,
            0..=14 => rng.millis(20, 5000),
            _ => match op.expect {
                Expect::Fin => ctx.config.motion_timeout,
                _ => ctx.config.query_timeout,
            },
        };
        let client = ctx.client().with_timeout(timeout);
        let start = Instant::now();
        let cancel = rng.one_in(8).then(|| rng.millis(1, 500));
        let mut prng = rng.fork();
        let call = perform(&client, &op.call, &ctx, &mut prng, &log, &trace);
        let ended = unless_given_up(cancel, call).await;
        note(
            &trace,
            format!(
                "client {} caller {k}: {} ({timeout:?}) -> {:?}",
                ctx.index,
                op.line,
                ended.as_ref().map(|e| &e.0)
            ),
        );
        let Some((res, end)) = ended else { continue };
        let lost = res == Res::Lost;
        log.calls.lock().unwrap().push(CallRec {
            client: ctx.index,
            line: op.line,
            name: op.name,
            expect: op.expect,
            start,
            end,
            timeout,
            res,
        });
        if lost && ctx.reconnect {
            ctx.reopen_if_closed("the connection was lost");
        }
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}
