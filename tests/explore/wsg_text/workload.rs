//! The GCL workload: what one caller does over `gripper::wsg::text::Client`, and what each call
//! returned, recorded for the oracle with the exact command line the client writes (the
//! simulator records the lines it reads: the oracle pairs them).

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::wsg::text::line::{encode_call, encode_set};
use gripper::wsg::text::{Client, ClientConfig, Error, Quantity};
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
    /// `Error::ConnectionLost`, with its message (why: the oracle's rule 6 reads it).
    Lost(String),
    /// `Error::Timeout`.
    Timeout,
    /// `Error::MalformedReply` or `Error::UnexpectedReply`: a line of the call's name that is
    /// not a fit answer (only a corrupted line may be one).
    Malformed(String),
    /// Anything else (the workload's arguments are valid: always a violation).
    Other(String),
    /// The caller gave up on it (its future dropped) at `end`.
    Cancelled,
    /// A call without timeout (`Duration::MAX`) that had not ended [`FOREVER_BOUND`] after it
    /// began: the caller dropped it (rule 8).
    Hung,
}

/// How long the explorer waits for a call without timeout before it drops it and reports it
/// (rule 8): far beyond the longest motion (110 mm at 10 mm/s), stall (3 s), timeout and
/// give-up time a run draws, so a call that has not ended by then has no bound.
pub const FOREVER_BOUND: Duration = Duration::from_secs(120);

/// One call as the oracle sees it.
#[derive(Clone, Debug)]
pub struct CallRec {
    /// Which client (index).
    pub client: usize,
    /// Which of its connections (index into its sessions and taps).
    pub conn: usize,
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

/// A `close()` in the fault phase and the call made right after it.
#[derive(Clone, Debug)]
pub struct AfterClose {
    /// Which client, and which connection.
    pub client: usize,
    /// See `client`.
    pub conn: usize,
    /// When `close()` began, and how it ended.
    pub close: (Instant, Res),
    /// The call after it: start, end, how it ended.
    pub after: (Instant, Instant, Res),
}

/// Everything the callers of a run recorded.
#[derive(Default)]
pub struct Log {
    /// Every call (a cancelled one as [`Res::Cancelled`]).
    pub calls: Mutex<Vec<CallRec>>,
    /// Every push received.
    pub pushes: Mutex<Vec<PushRec>>,
    /// Every `close()` of the fault phase and the call after it.
    pub after_close: Mutex<Vec<AfterClose>>,
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
            // By its GCL name, in either case (`Quantity::from_name` takes any).
            let name = ["POS", "speed", "FORCE", "GripState", "TEMP"][rng.below(5) as usize];
            let q = Quantity::from_name(name).expect("a GCL push name");
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
        Error::ConnectionLost { reason } => Res::Lost(reason.to_string()),
        Error::Timeout { .. } => Res::Timeout,
        Error::MalformedReply { .. } | Error::UnexpectedReply { .. } => {
            Res::Malformed(e.to_string())
        }
        other => Res::Other(other.to_string()),
    }
}

/// Where a call runs and where it is logged.
struct At<'a> {
    ctx: &'a Ctx,
    /// The connection (index into the client's sessions and taps).
    conn: usize,
    log: &'a Log,
    trace: &'a SharedTrace,
}

/// Runs `call` on `c`: how it ended, and when. An `AUTOSEND` that starts a stream ends with
/// its `ACK`; then it reads a few pushes (logged), drops the stream and stops the pushes (a
/// call of its own, logged).
async fn perform(c: &Client, call: &Call, at: &At<'_>, rng: &mut Prng) -> (Res, Instant) {
    if let Call::Autosend(q, ms, on_change) = call {
        return autosend(c, (*q, *ms, *on_change), at, rng).await;
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

/// `AUTOSEND(q, ms[, true])`: ends with its `ACK`; then reads a few pushes from its stream (or,
/// one time in three, from a stream of every push, `Client::pushes`, taken before), drops it,
/// and stops the pushes (a call of its own, logged).
async fn autosend(
    c: &Client,
    (q, ms, on_change): (Quantity, u16, bool),
    at: &At<'_>,
    rng: &mut Prng,
) -> (Res, Instant) {
    let every = rng.one_in(3).then(|| c.pushes());
    let mut pushes = match c.autosend(q, ms, on_change).await {
        Err(e) => return (classify(&e), Instant::now()),
        Ok(own) => every.unwrap_or(own),
    };
    let acked = Instant::now();
    // Read a few, each within a bound, then drop the stream.
    for _ in 0..rng.between(1, 4) {
        let wait = Duration::from_millis(u64::from(ms) * 2 + 100);
        let Ok(Some(p)) = tokio::time::timeout(wait, pushes.recv()).await else {
            break;
        };
        note(at.trace, format!("client {}: push {p:?}", at.ctx.index));
        at.log.pushes.lock().unwrap().push(PushRec {
            client: at.ctx.index,
            name: p.quantity.name(),
            value: p.value,
            at: Instant::now(),
        });
    }
    note(
        at.trace,
        format!("client {}: pushes missed {}", at.ctx.index, pushes.missed()),
    );
    drop(pushes);
    let off = Call::AutosendOff(q);
    let timeout = c.config().query_timeout;
    // Logged even if the caller drops this call midway (its request may wait in the client's
    // queue: rule 9 counts what the queue holds).
    let mut logged = Logged {
        log: at.log,
        rec: Some(CallRec {
            client: at.ctx.index,
            conn: at.conn,
            line: line_of("AUTOSEND", &off),
            name: "AUTOSEND",
            expect: Expect::Ack,
            start: Instant::now(),
            end: Instant::now(),
            timeout,
            res: Res::Cancelled,
        }),
    };
    let c = c.with_timeout(timeout);
    let r = forever_bounded(timeout, async {
        (
            res(c.stop_autosend(q).await, |()| Res::Done),
            Instant::now(),
        )
    })
    .await
    .0;
    note(
        at.trace,
        format!(
            "client {}: {} -> {r:?}",
            at.ctx.index,
            line_of("AUTOSEND", &off)
        ),
    );
    logged.end(r);
    (Res::Done, acked)
}

/// A call's record, logged when it ends, or as [`Res::Cancelled`] when its future is dropped.
struct Logged<'a> {
    log: &'a Log,
    rec: Option<CallRec>,
}

impl Logged<'_> {
    /// The call ended: `res`, now.
    fn end(&mut self, res: Res) {
        if let Some(mut rec) = self.rec.take() {
            rec.end = Instant::now();
            rec.res = res;
            self.log.calls.lock().unwrap().push(rec);
        }
    }
}

impl Drop for Logged<'_> {
    fn drop(&mut self) {
        self.end(Res::Cancelled);
    }
}

/// Rule 8: a call without timeout must end; past [`FOREVER_BOUND`] it is dropped and reported
/// ([`Res::Hung`]). A call with a timeout runs as it is.
async fn forever_bounded(
    timeout: Duration,
    call: impl std::future::Future<Output = (Res, Instant)>,
) -> (Res, Instant) {
    if timeout != Duration::MAX {
        return call.await;
    }
    match tokio::time::timeout(FOREVER_BOUND, call).await {
        Ok(ended) => ended,
        Err(_) => (Res::Hung, Instant::now()),
    }
}

/// The timeout of the call made right after a `close()` (it must fail at once).
pub const AFTER_CLOSE_TIMEOUT: Duration = Duration::from_secs(2);

/// A client configuration: the ranges the scenario always drew, and now and then an edge value
/// (issue 29): a timeout of `Duration::MAX` or zero, no give-up time or an immediate one, a
/// long queue or push buffer. (`usize::MAX` sizes are drawn by `edges.rs`, on a client of its
/// own: they panic today, issue 29 O.)
pub fn draw_config(rng: &mut Prng) -> ClientConfig {
    let mut config = ClientConfig {
        query_timeout: rng.millis(50, 2000),
        motion_timeout: rng.millis(1000, 10_000),
        give_up_after: rng.millis(100, 5000),
        queue_len: rng.between(1, 8) as usize,
        push_buffer: rng.between(1, 8) as usize,
        ..ClientConfig::default()
    };
    match rng.below(40) {
        0 => config.query_timeout = Duration::MAX,
        1 => config.motion_timeout = Duration::MAX,
        2 => config.give_up_after = Duration::ZERO,
        3 => config.give_up_after = Duration::MAX,
        4 => config.queue_len = 1000,
        5 => config.push_buffer = 1000,
        // (A zero default timeout fails every call the quiet phase makes: `edges.rs` draws it.)
        _ => {}
    }
    config
}

/// One caller: `ops` calls on its client with random timeouts (now and then none,
/// `Duration::MAX`, or zero) and cancellations; now and then it closes the client (`BYE()`),
/// then checks that a call fails as documented. (A reconnecting client reconnects by itself.)
pub async fn caller(
    ctx: Arc<Ctx>,
    k: usize,
    mut rng: Prng,
    ops: u32,
    log: Arc<Log>,
    trace: SharedTrace,
) {
    // The first connection a call of this caller can be written on.
    let mut after_loss = 0;
    for _ in 0..ops {
        if ctx.closing.load(Ordering::SeqCst) {
            return;
        }
        if rng.one_in(150) {
            ctx.start_closing();
            let (c, conn) = ctx.current();
            let start = Instant::now();
            // Rule 8 for `close()` too: a client whose default timeout is `Duration::MAX`
            // closes without one; past `FOREVER_BOUND` it is dropped and reported, not left to
            // hang the run (wsg-text:0x3bac8274f6da31e9 waited for a damaged `ACK BYE`).
            let timeout = c.config().query_timeout;
            let r = forever_bounded(timeout, async {
                (res(c.close().await, |()| Res::Done), Instant::now())
            })
            .await
            .0;
            note(
                &trace,
                format!("client {} caller {k}: close {r:?}", ctx.index),
            );
            // After `close()`, a call fails at once, with `Closed` (or `ConnectionLost` if the
            // connection was lost): not a timeout on a connection that reads no more calls
            // (issue 29 N: a `BYE()` answered otherwise than `ACK BYE`).
            let after_start = Instant::now();
            let after = c.with_timeout(AFTER_CLOSE_TIMEOUT).position_mm().await;
            note(
                &trace,
                format!(
                    "client {} caller {k}: POS? after close: {after:?}",
                    ctx.index
                ),
            );
            log.after_close.lock().unwrap().push(AfterClose {
                client: ctx.index,
                conn,
                close: (start, r),
                after: (after_start, Instant::now(), res(after, Res::Value)),
            });
            return;
        }
        let op = op(&mut rng);
        let timeout = match rng.below(30) {
            0 => Duration::MAX,
            1 => Duration::ZERO,
            2..=15 => rng.millis(20, 5000),
            _ => match op.expect {
                Expect::Fin => ctx.config.motion_timeout,
                _ => ctx.config.query_timeout,
            },
        };
        let (client, conn) = ctx.current();
        // After a call of this caller ended `Lost`, its next ones are made after that loss and
        // cannot be written on the lost connection, even at its very instant, before the next
        // one opens: wsg-text:0x1b1ffbad994b9acc, a `POS?` made then was credited with the
        // client's own probe written on the lost connection at that instant, and its `Timeout`
        // was judged a reply read in time (rule 7).
        let conn = conn.max(after_loss);
        let client = client.with_timeout(timeout);
        let start = Instant::now();
        let cancel = rng.one_in(8).then(|| rng.millis(1, 500));
        let mut prng = rng.fork();
        let at = At {
            ctx: &ctx,
            conn,
            log: &log,
            trace: &trace,
        };
        let call = forever_bounded(timeout, perform(&client, &op.call, &at, &mut prng));
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
        let (res, end) = ended.unwrap_or_else(|| (Res::Cancelled, Instant::now()));
        if matches!(res, Res::Lost(_)) {
            // The next connection opens a backoff after the loss (`phases::reconnect_policy`,
            // 50 ms at least): the one current now is the lost one.
            after_loss = after_loss.max(ctx.current().1 + 1);
        }
        log.calls.lock().unwrap().push(CallRec {
            client: ctx.index,
            conn,
            line: op.line,
            name: op.name,
            expect: op.expect,
            start,
            end,
            timeout,
            res,
        });
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}
