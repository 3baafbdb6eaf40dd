//! Edge values of the text client's API (issue 29): in one run of four, after the quiet phase, a
//! client of its own (a new session, a link that splits lines into pieces, no other fault) with
//! a configuration drawn from the extremes (`usize::MAX`, `0` and `1` sizes, `Duration::ZERO`
//! and `Duration::MAX` timeouts and give-up times) makes a few calls, some with a zero or no
//! timeout, and a few with arguments the client must refuse with `InvalidArgument`
//! (not-finite numbers, a speed without a distance). What is judged: no panic (the core's count;
//! issue 29 O: a `usize::MAX` `queue_len` or `push_buffer` hits tokio's semaphore assertion, a
//! `usize::MAX` `max_line_len` overflows in the line codec), every call ends within its
//! timeout + `CALL_SLACK` (rule 1) or, without one, within `FOREVER_BOUND` (rule 8), and bad
//! input is a typed error sent nowhere.

use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use gripper::wsg::sim::{SessionKind, SimServer};
use gripper::wsg::text::{Client, ClientConfig, Error, Quantity};
use gripper::wsg::HomingDirection;
use tokio::time::Instant;

use super::tap::Tap;
use super::workload::FOREVER_BOUND;
use crate::core::streams::{faulty_pipe, StreamProfile};
use crate::core::{note, Prng, SharedTrace};

/// How late a call may end after its timeout (as `oracle.rs`).
const CALL_SLACK: Duration = Duration::from_millis(10);

/// One of `values`.
fn pick<T: Copy>(rng: &mut Prng, values: &[T]) -> T {
    values[rng.below(values.len() as u64) as usize]
}

/// A configuration with edge values, each field on its own (about one in three an extreme).
fn draw(rng: &mut Prng) -> ClientConfig {
    let d = ClientConfig::default();
    let mut size = |default: usize| {
        if rng.one_in(3) {
            pick(rng, &[usize::MAX, 0, 1])
        } else {
            default
        }
    };
    let (max_line_len, queue_len, push_buffer) =
        (size(d.max_line_len), size(d.queue_len), size(d.push_buffer));
    let mut time = |default: Duration| {
        if rng.one_in(3) {
            pick(rng, &[Duration::ZERO, Duration::MAX])
        } else {
            default
        }
    };
    ClientConfig {
        query_timeout: time(d.query_timeout),
        motion_timeout: time(d.motion_timeout),
        give_up_after: time(d.give_up_after),
        max_line_len,
        queue_len,
        push_buffer,
        ..d
    }
}

/// Runs `call` with the bound its timeout promises: `Some` if it ended within it.
async fn bounded<T>(timeout: Duration, call: impl Future<Output = T>) -> Option<T> {
    let bound = if timeout == Duration::MAX {
        FOREVER_BOUND
    } else {
        timeout.min(FOREVER_BOUND) + CALL_SLACK
    };
    tokio::time::timeout(bound, call).await.ok()
}

/// The calls, on a task of their own (a panic in one is counted by the core and ends only
/// them): the violations they show.
async fn calls(c: Client, trace: SharedTrace) -> Vec<String> {
    let mut v = Vec::new();
    let config = c.config().clone();
    let mut judge = |what: &str, timeout: Duration, ended: Option<String>| {
        note(&trace, format!("edge: {what} ({timeout:?}) -> {ended:?}"));
        if ended.is_none() {
            let rule = if timeout == Duration::MAX {
                "8 (a call without timeout ends, and frees what it held)"
            } else {
                "1 (bounded)"
            };
            v.push(format!(
                "{rule}: edge client ({config:?}): {what} with timeout {timeout:?} had not ended within it"
            ));
        }
    };
    let q = config.query_timeout;
    let r = bounded(q, c.ack_fast_stop()).await;
    judge("FSACK()", q, r.map(|r| format!("{r:?}")));
    let r = bounded(q, c.position_mm()).await;
    judge("POS?", q, r.map(|r| format!("{r:?}")));
    for t in [Duration::ZERO, Duration::MAX] {
        let r = bounded(t, c.with_timeout(t).position_mm()).await;
        judge("POS?", t, r.map(|r| format!("{r:?}")));
    }
    let m = config.motion_timeout;
    let r = bounded(m, c.home(HomingDirection::Default)).await;
    judge("HOME()", m, r.map(|r| format!("{r:?}")));
    let r = bounded(q, c.autosend(Quantity::Position, 20, false)).await;
    let got = match r {
        Some(Ok(mut pushes)) => {
            let mut every = c.pushes();
            let one = tokio::time::timeout(Duration::from_secs(1), pushes.recv()).await;
            let all = tokio::time::timeout(Duration::from_secs(1), every.recv()).await;
            Some(format!(
                "Ok: {one:?} {all:?}, missed {} {}",
                pushes.missed(),
                every.missed()
            ))
        }
        other => other.map(|r| format!("{:?}", r.map(drop))),
    };
    judge("AUTOSEND(\"POS\",20)", q, got);
    let r = bounded(q, c.stop_autosend(Quantity::Position)).await;
    judge("AUTOSEND(\"POS\",0)", q, r.map(|r| format!("{r:?}")));
    // Bad input: a typed error at once, whatever the configuration.
    let bad: [(&str, Result<(), Error>); 4] = [
        ("move_to(NaN)", c.move_to(f64::NAN, None).await),
        (
            "grip_part(1, inf)",
            c.grip_part(1.0, f64::INFINITY, None).await,
        ),
        ("release(None, Some(10))", c.release(None, Some(10.0)).await),
        (
            "set_clamping_travel_mm(-inf)",
            c.set_clamping_travel_mm(f64::NEG_INFINITY).await.map(drop),
        ),
    ];
    let mut typed = Vec::new();
    for (what, r) in bad {
        note(&trace, format!("edge: {what} -> {r:?}"));
        if !matches!(r, Err(Error::InvalidArgument { .. })) {
            typed.push(format!(
                "5 (documented errors): edge client: {what} ended {r:?}, not InvalidArgument"
            ));
        }
    }
    let r = bounded(q, c.close()).await;
    judge("BYE()", q, r.map(|r| format!("{r:?}")));
    v.extend(typed);
    v
}

/// The edge check: a client of its own on `sim`.
pub async fn check(rng: &mut Prng, sim: &Arc<SimServer>, trace: &SharedTrace) -> Vec<String> {
    let config = draw(rng);
    note(trace, format!("edge client: {config:?}"));
    // Lines in pieces: the codec's partial-line path (where a huge `max_line_len` overflowed).
    let profile = StreamProfile {
        split: 2,
        ..StreamProfile::default()
    };
    let on = Arc::new(AtomicBool::new(true));
    let (near, far) = faulty_pipe(rng, profile, on, trace.clone(), "edge".into());
    let session = sim.serve_stream(far, SessionKind::Tcp);
    note(trace, format!("edge client: session {session}"));
    let (near, _tap, _cut) = Tap::new(near);
    // A panic here (a channel of `usize::MAX`) is the core's to count; the run goes on.
    let opened = std::panic::catch_unwind(AssertUnwindSafe(|| Client::from_io(near, config)));
    let Ok(client) = opened else {
        note(trace, "edge client: from_io panicked");
        return Vec::new();
    };
    let start = Instant::now();
    let r = tokio::spawn(calls(client, trace.clone())).await;
    note(
        trace,
        format!("edge client: done after {:?}", start.elapsed()),
    );
    r.unwrap_or_default()
}
