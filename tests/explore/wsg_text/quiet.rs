//! Rule 10, **the quiet phase serves every kind of call** (issue 29): after recovery, with the
//! network quiet, each client makes one call of every kind the workload makes (every command
//! name, the push streams included) and each must succeed; a client whose connection ended
//! without reconnect must fail each with `ConnectionLost`. The calls are logged like the
//! workload's, so promise 2 checks their answers too. A kind whose name a call without timeout
//! still holds (rule 8: its reply never reached the client) is tagged: issue 29 M.

use std::sync::atomic::Ordering;
use std::time::Duration;

use gripper::wsg::text::{Client, Quantity};
use gripper::wsg::HomingDirection;
use tokio::time::Instant;

use super::workload::{classify, CallRec, Expect, Log, Res};
use super::Ctx;
use crate::core::{note, SharedTrace};

/// Timeouts of the quiet calls: a motion here runs at most 110 mm at the default speed; a reply
/// comes at once, behind the simulator's quiet gap after an `ACK` (at most 50 ms).
const MOTION: Duration = Duration::from_secs(30);
const QUERY: Duration = Duration::from_secs(2);

/// One call of every kind, in an order the device accepts (a release needs a grip before it;
/// the part width tolerance and clamping travel are set first: the fault phase may have left
/// them at 0 on this connection, and the part is 40 mm ± 2 mm).
const KINDS: [(&str, &str, Expect); 24] = [
    ("FSACK()", "FSACK", Expect::Ack),
    ("PWT=5", "PWT", Expect::Value),
    ("CLT=5", "CLT", Expect::Value),
    ("HOME()", "HOME", Expect::Fin),
    ("MOVE(60,50)", "MOVE", Expect::Fin),
    ("GRIP()", "GRIP", Expect::Fin),
    ("RELEASE()", "RELEASE", Expect::Fin),
    ("GRIP(10,40,50)", "GRIP", Expect::Fin),
    ("RELEASE(5,50)", "RELEASE", Expect::Fin),
    ("STOP()", "STOP", Expect::Ack),
    ("FASTSTOP()", "FASTSTOP", Expect::Ack),
    ("FSACK()", "FSACK", Expect::Ack),
    ("POS?", "POS", Expect::Value),
    ("SPEED?", "SPEED", Expect::Value),
    ("FORCE?", "FORCE", Expect::Value),
    ("GRIPSTATE?", "GRIPSTATE", Expect::Value),
    ("TEMP?", "TEMP", Expect::Value),
    ("VERBOSE=1", "VERBOSE", Expect::Value),
    ("VERBOSE=0", "VERBOSE", Expect::Value),
    ("PWT?", "PWT", Expect::Value),
    ("CLT?", "CLT", Expect::Value),
    ("AUTOSEND(\"POS\",50)", "AUTOSEND", Expect::Ack),
    ("AUTOSEND(\"POS\",0)", "AUTOSEND", Expect::Ack),
    ("HOME(1)", "HOME", Expect::Fin),
];

/// Makes the call of `line` on `c`: its result, and for an `AUTOSEND` on, whether a push came
/// (on its own stream and on a stream of every push) within a second.
async fn call(c: &Client, line: &str) -> (Result<Res, gripper::wsg::text::Error>, Option<bool>) {
    let q = c.with_timeout(QUERY);
    let m = c.with_timeout(MOTION);
    let done = |r: Result<(), _>| r.map(|()| Res::Done);
    let num = |r: Result<f64, _>| r.map(Res::Value);
    let r = match line {
        "FSACK()" => done(q.ack_fast_stop().await),
        "HOME()" => done(m.home(HomingDirection::Default).await),
        "HOME(1)" => done(m.home(HomingDirection::Positive).await),
        "MOVE(60,50)" => done(m.move_to(60.0, Some(50.0)).await),
        "GRIP()" => done(m.grip(None).await),
        "RELEASE()" => done(m.release(None, None).await),
        "GRIP(10,40,50)" => done(m.grip_part(10.0, 40.0, Some(50.0)).await),
        "RELEASE(5,50)" => done(m.release(Some(5.0), Some(50.0)).await),
        "STOP()" => done(q.stop().await),
        "FASTSTOP()" => done(q.fast_stop().await),
        "POS?" => num(q.position_mm().await),
        "SPEED?" => num(q.speed_mm_per_s().await),
        "FORCE?" => num(q.force_n().await),
        "GRIPSTATE?" => q.grip_state().await.map(|s| Res::Value(s.to_u8().into())),
        "TEMP?" => num(q.temperature_c().await),
        "VERBOSE=1" => q.set_verbose(true).await.map(|b| Res::Value(f64::from(b))),
        "VERBOSE=0" => q.set_verbose(false).await.map(|b| Res::Value(f64::from(b))),
        "PWT=5" => num(q.set_part_width_tolerance_mm(5.0).await),
        "PWT?" => num(q.part_width_tolerance_mm().await),
        "CLT=5" => num(q.set_clamping_travel_mm(5.0).await),
        "CLT?" => num(q.clamping_travel_mm().await),
        "AUTOSEND(\"POS\",0)" => done(q.stop_autosend(Quantity::Position).await),
        _ => {
            let mut every = q.pushes();
            let r = q.autosend(Quantity::Position, 50, false).await;
            let Ok(mut own) = r else {
                return (r.map(|_| Res::Done), None);
            };
            let within = |s| tokio::time::timeout(Duration::from_secs(1), s);
            let got = within(own.recv()).await.ok().flatten().is_some()
                && within(every.recv()).await.ok().flatten().is_some();
            return (Ok(Res::Done), Some(got));
        }
    };
    (r, None)
}

/// The tag of a call that failed because its name is held for good: a command of the name was
/// written on the connection and never answered by the call's start, and nothing bounds it (a
/// call of the name without timeout, or a client without give-up time): issue 29 M.
const HELD: &str = " [its name is held by a call whose reply never came, with no bound]";

/// The tag of a call refused by the device (FAST STOP not acknowledged, a release without a
/// grip) after an earlier quiet call failed with [`HELD`] or [`FULL`].
pub const AFTER_HELD: &str =
    " [refused after an earlier quiet call could not be made: a name held by a call whose reply never came]";

/// The tag of a call never written because the client's queue was full of calls given up
/// unwritten, their names held (issue 29 K with M).
pub const FULL: &str = " [behind a full queue of calls not yet sent]";

/// [`FULL`] if a call of `line` made at `start` on connection `conn` was never written while at
/// least `queue_len` earlier calls of the connection had been given up without being written.
pub fn full_tag(ctx: &Ctx, log: &Log, conn: usize, line: &str, start: Instant) -> &'static str {
    let Some(tap) = ctx.taps().get(conn).cloned() else {
        return "";
    };
    let tap = tap.lock().unwrap();
    let written = |text: &str, from: Instant, to: Instant| {
        tap.written
            .lines
            .iter()
            .any(|l| l.at >= from && l.at <= to && l.text == text)
    };
    if written(line, start, Instant::now()) {
        return "";
    }
    let given_up = log
        .calls
        .lock()
        .unwrap()
        .iter()
        .filter(|o| {
            o.client == ctx.index
                && o.conn == conn
                && o.end <= start
                && matches!(o.res, Res::Timeout | Res::Cancelled | Res::Hung)
                && !written(&o.line, o.start, o.end)
        })
        .count();
    if given_up >= ctx.config.queue_len.max(1) {
        FULL
    } else {
        ""
    }
}

/// [`HELD`] if it applies to a call of `name` made at `start` on connection `conn`, else "".
pub fn held_tag(
    ctx: &Ctx,
    log: &Log,
    conn: usize,
    name: &str,
    expect: Expect,
    start: Instant,
) -> &'static str {
    let Some(tap) = ctx.taps().get(conn).cloned() else {
        return "";
    };
    let busy = super::liveness::busy(&tap.lock().unwrap(), name, expect, start, usize::MAX);
    let unbounded = ctx.config.give_up_after == Duration::MAX
        || log.calls.lock().unwrap().iter().any(|o| {
            o.client == ctx.index && o.conn == conn && o.name == name && o.timeout == Duration::MAX
        });
    if busy && unbounded {
        HELD
    } else {
        ""
    }
}

/// Rule 10 for one client.
pub async fn every_kind(ctx: &Ctx, log: &Log, trace: &SharedTrace) -> Vec<String> {
    if ctx.closing.load(Ordering::SeqCst) {
        return Vec::new();
    }
    let (c, conn) = ctx.current();
    let lost = c.is_closed();
    let mut v = Vec::new();
    // A call failed because a name is held (or the queue is full of such calls): what the
    // device refuses afterwards (FAST STOP not acknowledged, a release without its grip) follows.
    let mut held_before = false;
    for (line, name, expect) in KINDS {
        let start = Instant::now();
        let (r, pushed) = call(&c, line).await;
        note(
            trace,
            format!("quiet client {}: {line} {r:?} pushes {pushed:?}", ctx.index),
        );
        let res = r.as_ref().map_or_else(classify, Clone::clone);
        let fine = match (&res, lost) {
            (Res::Done | Res::Value(_), false) => pushed != Some(false),
            (Res::Lost(_), true) => true,
            _ => false,
        };
        if !fine {
            let mut tag = held_tag(ctx, log, conn, name, expect, start);
            if tag.is_empty() {
                tag = full_tag(ctx, log, conn, line, start);
            }
            if tag.is_empty() && held_before && matches!(res, Res::Device(_)) {
                tag = AFTER_HELD;
            }
            held_before |= !tag.is_empty();
            if !tag.is_empty() {
                ctx.stuck.store(true, Ordering::SeqCst);
            }
            v.push(format!(
                "10 (the quiet phase serves every kind of call): client {} (reconnect {}, lost {lost}): {line} ended {r:?}{}{tag}",
                ctx.index,
                ctx.reconnect,
                if pushed == Some(false) { ", and no push came within 1 s" } else { "" }
            ));
        }
        let timeout = if expect == Expect::Fin { MOTION } else { QUERY };
        log.calls.lock().unwrap().push(CallRec {
            client: ctx.index,
            conn,
            line: line.into(),
            name,
            expect,
            start,
            end: Instant::now(),
            timeout,
            res,
        });
    }
    v
}
