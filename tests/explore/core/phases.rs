//! The parts of a run every scenario shares, whatever its protocol: opening a client through the
//! faults, the callers of the fault phase and the restart drawn for it, a call a caller may give
//! up on, and the documented errors after `close()` (promise 5).
//!
//! Each helper draws from the run's generator in the order the scenarios drew before they
//! shared it: a seed keeps its path (the digests of `--determinism` and `--replay` tell).

use std::fmt::{Debug, Display};
use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use super::{end_fault_phase, note, Caps, Prng, Restart, SharedTrace};
use gripper::reconnect::ReconnectPolicy;

/// A run's fault level (0 to `caps.faults`) and number of clients (1 or 2), drawn in that
/// order.
pub fn draw_shape(rng: &mut Prng, caps: Caps) -> (u32, usize) {
    let level = rng.between(0, u64::from(caps.faults)) as u32;
    (level, rng.between(1, 2) as usize)
}

/// A run's first trace line: its key, fault level and number of clients.
pub fn run_line(variant: &str, seed: u64, caps: Caps, level: u32, n_clients: usize) -> String {
    let key = format!("{variant}:{seed:#018x}{}", caps.suffix());
    format!("run {key} level {level}, {n_clients} clients")
}

/// The reconnect policy of a client that reconnects: quick, so that a run stays short.
pub fn reconnect_policy() -> ReconnectPolicy {
    ReconnectPolicy {
        initial_delay: Duration::from_millis(50),
        max_delay: Duration::from_millis(500),
        factor: 2.0,
        max_attempts: None,
    }
}

/// How many times the opening of a client may fail under the faults before they stop for the
/// run (short timeouts under heavy faults can fail it every time).
const OPEN_ATTEMPTS_UNDER_FAULTS: u32 = 20;

/// Opens client `index` (`open`, with `config`, which is noted first) as a program would: a
/// failed opening is documented (returned whatever the reconnect policy) and retried. After
/// [`OPEN_ATTEMPTS_UNDER_FAULTS`] failures the faults stop for this run (`faults_on`): opening
/// must then work; `Err` with the violation of promise 5 if it did not.
pub async fn open_retrying<C, E: Display, F: Future<Output = Result<C, E>>>(
    index: usize,
    config: &impl Debug,
    faults_on: &AtomicBool,
    trace: &SharedTrace,
    mut open: impl FnMut() -> F,
) -> Result<C, String> {
    note(trace, format!("client {index}: {config:?}"));
    for attempt in 0..=OPEN_ATTEMPTS_UNDER_FAULTS {
        if attempt == OPEN_ATTEMPTS_UNDER_FAULTS {
            note(trace, "faults off: the opening sequence failed 20 times");
            faults_on.store(false, Ordering::SeqCst);
        }
        match open().await {
            Ok(c) => return Ok(c),
            Err(e) => note(
                trace,
                format!("client {index}: open attempt {attempt}: {e}"),
            ),
        }
    }
    Err(format!(
        "5 (recovery): client {index} did not open with the faults off"
    ))
}

/// The fault phase: spawns the callers, for each client in turn 1 to `caps.callers` of them,
/// each with 1 to `caps.ops` calls and a generator of its own (drawn in that order;
/// `caller(ctx, k, rng, ops)` is the `k`-th caller of client `ctx`); then `faults` arms the
/// run's other faults (a restart, [`draw_restart`], which it returns); then waits for the
/// callers and turns the faults off ([`end_fault_phase`]).
pub async fn fault_phase<C, T: Future<Output = ()> + Send + 'static>(
    rng: &mut Prng,
    caps: Caps,
    ctxs: &[C],
    mut caller: impl FnMut(&C, usize, Prng, u32) -> T,
    faults: impl FnOnce(&mut Prng) -> Option<Restart>,
    on: &AtomicBool,
    trace: &SharedTrace,
) {
    let mut callers = Vec::new();
    for ctx in ctxs {
        let n = rng.between(1, u64::from(caps.callers)) as usize;
        for k in 0..n {
            let ops = rng.between(1, u64::from(caps.ops)) as u32;
            callers.push(tokio::spawn(caller(ctx, k, rng.fork(), ops)));
        }
    }
    let restart = faults(rng);
    end_fault_phase(callers, restart, on, trace).await;
}

/// The device restart of a fault phase: in one run of four from fault level 2, at 0–5 s;
/// `schedule(at)` arms it ([`super::restart_at`], `Servers::restart_at`), and
/// [`end_fault_phase`] calls it off if it is not due by then.
pub fn draw_restart(
    rng: &mut Prng,
    level: u32,
    schedule: impl FnOnce(Duration) -> Restart,
) -> Option<Restart> {
    (level >= 2 && rng.one_in(4)).then(|| schedule(rng.millis(0, 5000)))
}

/// Runs `call`, or gives up on it (drops its future) `after` it began: a caller's cancellation.
/// `None` if it was given up.
pub async fn unless_given_up<T>(
    after: Option<Duration>,
    call: impl Future<Output = T>,
) -> Option<T> {
    match after {
        Some(after) => tokio::select! {
            // Fixed order (replay); either way the call ends here, or its future is dropped.
            biased;
            r = call => Some(r),
            () = tokio::time::sleep(after) => None,
        },
        None => Some(call.await),
    }
}

/// The two documented errors of a client whose `close()` was called (promise 5).
pub trait DocumentedErrors {
    /// `Error::Closed`: the client was closed.
    fn is_closed(&self) -> bool;
    /// `Error::ConnectionLost`: the connection ended.
    fn is_connection_lost(&self) -> bool;
}

/// Promise 5 after `close()`: a call (`what`) of client `index` fails with `Closed`, or with
/// `ConnectionLost` if the client lost its connection (`lost`); the violation otherwise.
pub fn after_close<T: Debug, E: DocumentedErrors + Debug>(
    index: usize,
    what: &str,
    after: &Result<T, E>,
    lost: bool,
) -> Option<String> {
    let fine = match after {
        Err(e) if e.is_closed() => true,
        Err(e) if e.is_connection_lost() => lost,
        _ => false,
    };
    (!fine).then(|| {
        format!(
            "5 (documented errors): client {index} after close(): {what} ended {after:?}, not Error::Closed"
        )
    })
}
