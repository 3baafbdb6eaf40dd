//! The protocol-agnostic core of the explorer: the seeded generator, the event trace and its
//! digest, the in-memory networks with their faults, and the deterministic runtime a run lives
//! in. A protocol plugs in with a [`Scenario`]: its workload and its oracle (see `wsg/`).
//!
//! # Why a run is deterministic
//!
//! A run is a pure function of its seed:
//! - **One generator.** Every random choice (workload, client settings, faults) comes from a
//!   SplitMix64 generator seeded by the run's seed; each component gets its own generator
//!   forked from it in a fixed order, so adding draws in one component does not shift another.
//! - **One thread, one queue.** The run is one `current_thread` tokio runtime: tasks run one at
//!   a time in the FIFO order they were woken, and wake-ups come only from other tasks (the
//!   in-memory pipes and channels) or from the timer, so the order is the same every time.
//! - **No operating system.** The runtime has no I/O driver at all (`enable_time` only): the
//!   networks are `tokio::io::duplex` pipes and channels, so no socket readiness, port number
//!   or kernel buffer can differ between two runs.
//! - **A simulated clock.** The clock is paused (`start_paused`) and jumps to the next timer
//!   when every task waits: motions, timeouts and delays cost no wall time, and `Instant::now`
//!   is the same in every replay. The library and simulator use tokio's clock only.
//! - **No random branch choice.** `tokio::select!` without `biased;` starts at a random branch
//!   (tokio's thread-local generator, seeded per process): every `select!` a run reaches (client
//!   task, connection keeper, simulator actor and connections, these fault layers) is `biased;`
//!   with a comment saying why its order is fair.
//! - **No hash order.** Maps that are iterated (the simulator's sessions, its UDP peers, the
//!   text client's commands on the wire) are ordered maps; the client's `IntMap` hashes with a
//!   fixed function.
//! - **No random waiter order.** A `watch` channel wakes its waiters in an order the runtime's
//!   generator (seeded afresh per runtime) picks: what ends several connections at one instant
//!   in a run is a `CancellationToken`, which wakes them in the order they came.
//!
//! The proof is [`determinism_check`]: a seed run twice (or more) must give the same trace digest (the
//! trace holds every call with its simulated times and outcome, every fault, and the
//! simulator's whole record), checked in `cargo test` and CI on a number of seeds.

pub mod datagrams;
pub mod matching;
pub mod phases;
pub mod prng;
pub mod servers;
pub mod streams;

use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Once};
use std::time::Duration;

use tokio::time::Instant;

pub use prng::Prng;

/// Panics seen anywhere (library, simulator, explorer) since the process started, with where
/// and why (the first few).
static PANICS: AtomicU64 = AtomicU64::new(0);
static PANIC_NOTES: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Counts every panic (tokio catches a task's panic; the count still sees it) and keeps its
/// place and message for the report instead of printing a backtrace.
pub fn install_panic_counter() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        std::panic::set_hook(Box::new(move |info| {
            PANICS.fetch_add(1, Ordering::SeqCst);
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let at = info.location().map(|l| l.to_string()).unwrap_or_default();
            let mut notes = PANIC_NOTES.lock().unwrap_or_else(|e| e.into_inner());
            if notes.len() < 8 {
                notes.push(format!("{msg} at {at}"));
            }
        }));
    });
}

fn panics() -> u64 {
    PANICS.load(Ordering::SeqCst)
}

/// Lines kept in a trace for printing; the digest covers every line either way.
const TRACE_KEEP: usize = 20_000;

/// The event trace of one run: every line goes into the digest (FNV-1a, 64 bit).
#[derive(Debug)]
pub struct Trace {
    t0: Instant,
    lines: Vec<String>,
    digest: u64,
    count: u64,
}

/// A trace shared by the run's tasks.
pub type SharedTrace = Arc<Mutex<Trace>>;

impl Trace {
    /// An empty trace whose times count from now.
    pub fn new() -> SharedTrace {
        Arc::new(Mutex::new(Trace {
            t0: Instant::now(),
            lines: Vec::new(),
            digest: 0xcbf2_9ce4_8422_2325,
            count: 0,
        }))
    }

    /// Adds a line, stamped with the simulated time.
    pub fn add(&mut self, line: String) {
        let us = self.t0.elapsed().as_micros();
        let line = format!("{us:>12}us {line}");
        for b in line.bytes().chain([b'\n']) {
            self.digest ^= u64::from(b);
            self.digest = self.digest.wrapping_mul(0x0100_0000_01b3);
        }
        self.count += 1;
        if std::env::var_os("EXPLORE_LIVE").is_some() {
            eprintln!("{line}");
        }
        if self.lines.len() < TRACE_KEEP {
            self.lines.push(line);
        }
    }

    /// The digest of every line so far.
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// The lines kept.
    pub fn lines(&self) -> &[String] {
        &self.lines
    }
}

/// Adds a line to a shared trace.
pub fn note(trace: &SharedTrace, line: impl Into<String>) {
    trace
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .add(line.into());
}

/// A device restart scheduled by [`restart_at`] or `Servers::restart_at`, until it is due.
pub type Restart = tokio::task::JoinHandle<()>;

/// The end of a fault phase: waits for every caller (one that panicked is counted by the panic
/// hook), calls off every restart not yet due, then turns the faults off (`on`) and notes it.
///
/// A restart is a fault, drawn at 0–5 s whatever the fault phase's length: one still to come
/// would land in the quiet phase, whose recovery bound counts from "faults off" (promise 5). In
/// the WSG scenario one came in the middle of the recovery call, which then failed with
/// ConnectionLost on a client without reconnect (wsg-tcp:0xe3c42e54efcedf17).
pub async fn end_fault_phase(
    callers: Vec<tokio::task::JoinHandle<()>>,
    restarts: impl IntoIterator<Item = Restart>,
    on: &std::sync::atomic::AtomicBool,
    trace: &SharedTrace,
) {
    for c in callers {
        let _ = c.await;
    }
    for r in restarts {
        if !r.is_finished() {
            r.abort();
            note(
                trace,
                "fault: a restart not due by the end of the fault phase is called off",
            );
        }
    }
    on.store(false, Ordering::SeqCst);
    note(trace, "faults off");
}

/// After `at`, notes that the device restarts and calls `restart` (e.g. `SimServer::restart`);
/// [`end_fault_phase`] calls it off if it is not due by then.
pub fn restart_at(
    at: Duration,
    trace: &SharedTrace,
    restart: impl FnOnce() + Send + 'static,
) -> Restart {
    let trace = trace.clone();
    tokio::spawn(async move {
        tokio::time::sleep(at).await;
        note(&trace, "fault: the device restarts");
        restart();
    })
}

/// How much a run is allowed to do: the seed's draws are capped by these (for shrinking).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Caps {
    /// Concurrent callers per client, at most.
    pub callers: u32,
    /// Calls per caller, at most.
    pub ops: u32,
    /// Fault intensity, 0 (none) to 3.
    pub faults: u32,
}

impl Caps {
    /// No cap beyond the scenario's own.
    pub const FULL: Caps = Caps {
        callers: 4,
        ops: 12,
        faults: 3,
    };

    /// The suffix of a replay key (empty for [`Caps::FULL`]).
    pub fn suffix(&self) -> String {
        if *self == Caps::FULL {
            String::new()
        } else {
            format!(":c{}o{}f{}", self.callers, self.ops, self.faults)
        }
    }
}

/// One protocol's runs: a name per transport (`wsg-udp`), a workload and an oracle.
pub trait Scenario: Sync {
    /// The names this scenario answers to, e.g. `["wsg-tcp", "wsg-serial", "wsg-udp"]`.
    fn variants(&self) -> &'static [&'static str];

    /// Runs `seed` of `variant` inside the deterministic runtime; returns the violations of
    /// the oracle (empty: the run passed) and the simulated time it took.
    fn run(
        &self,
        variant: &'static str,
        seed: u64,
        caps: Caps,
        trace: SharedTrace,
    ) -> std::pin::Pin<Box<dyn Future<Output = Vec<String>> + '_>>;
}

/// The result of one run.
#[derive(Debug)]
pub struct Outcome {
    /// What the oracle found (empty: passed).
    pub violations: Vec<String>,
    /// Digest of the whole trace.
    pub digest: u64,
    /// Simulated time the run took.
    pub simulated: Duration,
    /// The trace lines kept.
    pub trace: Vec<String>,
}

/// Simulated time after which a run counts as hung.
pub const RUN_LIMIT: Duration = Duration::from_secs(3600);

/// Wall time after which a run counts as hung (a debug build runs a seed in well under a
/// second).
const WATCHDOG: Duration = Duration::from_secs(60);

/// Runs one seed in a fresh single-threaded runtime with a paused clock and no I/O driver.
pub fn run_one(scenario: &dyn Scenario, variant: &'static str, seed: u64, caps: Caps) -> Outcome {
    install_panic_counter();
    let panics_before = panics();
    PANIC_NOTES
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .clear();
    // A run that spins without letting the simulated clock move would hang the process: a
    // watchdog on the wall clock names it and ends the process.
    let (done, watch) = std::sync::mpsc::channel::<()>();
    let name = format!("{variant}:{seed:#018x}{}", caps.suffix());
    std::thread::spawn(move || {
        if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = watch.recv_timeout(WATCHDOG) {
            eprintln!("HUNG {name}: no end after {WATCHDOG:?} of wall time (a task spins without letting the simulated clock move)");
            eprintln!("  replay: cargo test --release --test explore -- --replay {name}");
            std::process::exit(2);
        }
    });
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .start_paused(true)
        .build()
        .expect("a current-thread runtime");
    let (mut violations, trace, simulated, alive) = rt.block_on(async {
        let trace = Trace::new();
        let t0 = Instant::now();
        let run = scenario.run(variant, seed, caps, trace.clone());
        let violations = match tokio::time::timeout(RUN_LIMIT, run).await {
            Ok(v) => v,
            Err(_) => vec![format!(
                "1: the run did not end within {RUN_LIMIT:?} (simulated)"
            )],
        };
        // Everything the run spawned must have ended: let it wind down first (simulated).
        let mut alive = 0;
        for _ in 0..100 {
            tokio::time::sleep(Duration::from_millis(100)).await;
            alive = tokio::runtime::Handle::current()
                .metrics()
                .num_alive_tasks();
            if alive == 0 {
                break;
            }
        }
        (violations, trace, t0.elapsed(), alive)
    });
    drop(rt);
    let _ = done.send(());
    if alive != 0 {
        violations.push(format!(
            "1 (no leak): {alive} tasks still alive 10 s (simulated) after every client and the simulator were closed"
        ));
    }
    let panicked = panics() - panics_before;
    if panicked != 0 {
        // One violation per panic (issue 29): a known.txt line that names one panic's message
        // and place must not cover another panic of the same run.
        let notes = PANIC_NOTES.lock().unwrap_or_else(|e| e.into_inner());
        for note in notes.iter() {
            violations.push(format!("1 (no panic): a panic during the run: {note}"));
        }
        if panicked > notes.len() as u64 {
            violations.push(format!(
                "1 (no panic): {panicked} panics during the run, {} of them not kept",
                panicked - notes.len() as u64
            ));
        }
    }
    let t = trace.lock().unwrap_or_else(|e| e.into_inner());
    Outcome {
        violations,
        digest: t.digest(),
        simulated,
        trace: t.lines().to_vec(),
    }
}

/// Runs `seed` of `variant` under `caps` `runs` times (at least twice); `Ok` with the digest
/// if every run gave the same trace, `Err` with the first differing line otherwise.
///
/// One process, fresh runtimes: each tokio runtime seeds its own generator (used by e.g. the
/// shard a `watch` receiver waits on) from the operating system, so a run that depends on it
/// takes another path now and then within one process too: more runs, more chances to see it.
pub fn determinism_check(
    scenario: &dyn Scenario,
    variant: &'static str,
    seed: u64,
    caps: Caps,
    runs: u64,
) -> Result<u64, String> {
    let a = run_one(scenario, variant, seed, caps);
    for run in 2..=runs.max(2) {
        let b = run_one(scenario, variant, seed, caps);
        if a.digest == b.digest {
            continue;
        }
        let first = a
            .trace
            .iter()
            .zip(&b.trace)
            .position(|(x, y)| x != y)
            .unwrap_or(a.trace.len().min(b.trace.len()));
        return Err(format!(
            "{variant}:{seed:#018x}{} is not deterministic: run {run} of {} differs from run 1, digests {:#x} and {:#x}; first difference at line {first}:\n  {}\n  {}",
            caps.suffix(),
            runs.max(2),
            a.digest,
            b.digest,
            a.trace.get(first).map_or("(end)", String::as_str),
            b.trace.get(first).map_or("(end)", String::as_str),
        ));
    }
    Ok(a.digest)
}
