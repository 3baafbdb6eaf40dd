//! The WSG's text interface (GCL, `gripper::wsg::text`) under the explorer (issue 24): the WSG
//! simulator in text mode (`SimConfig::text`, WSG 50, a 40 mm part, real-time motion under the
//! paused clock, every line in and out recorded: `SimEvent::TextRequest`/`TextReply`), one or
//! two clients over in-memory TCP through the fault layer (`Client::from_io`), several callers
//! each, a device restart now and then, a quiet phase (recovery; a live STOP during a slow
//! MOVE), closing, then the oracle (`oracle.rs`). GCL has no ids: replies pair with commands by
//! name, which is what the oracle checks, line by line.
//!
//! The text client does not reconnect by itself: a "reconnecting" client here is one whose
//! callers open a new connection after a loss (or drop theirs without `BYE()` now and then,
//! which raises FAST STOP on the device).

mod edges;
mod liveness;
mod oracle;
mod quiet;
mod tap;
mod workload;

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::wsg::sim::{Model, SessionId, SessionKind, SimConfig, SimEvent, SimServer};
use gripper::wsg::text::{Client, ClientConfig, Error};
use gripper::wsg::HomingDirection;
use tokio::time::Instant;

use self::tap::{SharedTap, Tap};
use self::workload::{classify, CallRec, Expect, Log, Res};
use crate::core::phases::{
    after_close, draw_restart, draw_shape, fault_phase, run_line, DocumentedErrors,
};
use crate::core::streams::{faulty_pipe, StreamProfile};
use crate::core::{note, restart_at, Caps, Prng, Scenario, SharedTrace};

/// The GCL scenario.
pub struct WsgText;

/// Entries the simulator records at most (a run stays far below).
const RECORD_CAPACITY: usize = 1 << 20;

impl Scenario for WsgText {
    fn variants(&self) -> &'static [&'static str] {
        &["wsg-text"]
    }

    fn run(
        &self,
        variant: &'static str,
        seed: u64,
        caps: Caps,
        trace: SharedTrace,
    ) -> Pin<Box<dyn Future<Output = Vec<String>> + '_>> {
        Box::pin(run(variant, seed, caps, trace))
    }
}

/// One client slot: the connection of the moment (a reopen replaces it) and what the oracle
/// needs of it.
pub struct Ctx {
    index: usize,
    /// The connection of the moment, and its index in `sessions` and `taps`.
    client: Mutex<(Client, usize)>,
    /// The simulator sessions it opened, oldest first.
    sessions: Arc<Mutex<Vec<SessionId>>>,
    /// What the client wrote and read on each of those connections (`tap.rs`).
    taps: Mutex<Vec<SharedTap>>,
    /// Whether its callers open a new connection after a loss.
    reconnect: bool,
    /// Whether its link may flip bits (GCL has no checksum: a flipped bit is another line).
    corrupting: bool,
    closing: AtomicBool,
    /// Whether the quiet phase found a name of this client held for good, or its queue full of
    /// such calls (issue 29 K, M): the documented errors after `close()` are then tagged.
    stuck: AtomicBool,
    /// When a `close()` began (a `Closed` before it breaks promise 5).
    closed_at: Mutex<Option<Instant>>,
    config: ClientConfig,
    net: Net,
}

/// What opening a connection needs.
struct Net {
    sim: Arc<SimServer>,
    rng: Mutex<Prng>,
    profile: StreamProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
}

impl Ctx {
    /// Marks the client closing; true if it was already.
    fn start_closing(&self) -> bool {
        self.closed_at
            .lock()
            .unwrap()
            .get_or_insert_with(Instant::now);
        self.closing.swap(true, Ordering::SeqCst)
    }

    /// The connection of the moment.
    fn client(&self) -> Client {
        self.client.lock().unwrap().0.clone()
    }

    /// The connection of the moment and its index (`sessions`, `taps`).
    fn current(&self) -> (Client, usize) {
        self.client.lock().unwrap().clone()
    }

    /// A new connection through the fault layer, served by the simulator as a new session.
    fn open(&self) -> (Client, usize) {
        let n = &self.net;
        let label = format!("c{}", self.index);
        let (near, far) = faulty_pipe(
            &mut n.rng.lock().unwrap(),
            n.profile,
            n.on.clone(),
            n.trace.clone(),
            label,
        );
        let session = n.sim.serve_stream(far, SessionKind::Tcp);
        let conn = {
            let mut sessions = self.sessions.lock().unwrap();
            sessions.push(session);
            sessions.len() - 1
        };
        note(
            &n.trace,
            format!("client {}: session {session}", self.index),
        );
        let (near, tap) = Tap::new(near);
        self.taps.lock().unwrap().push(tap);
        (Client::from_io(near, self.config.clone()), conn)
    }

    /// Replaces the connection (the old one is dropped without `BYE()` once no call holds it).
    fn reopen(&self, why: &str) {
        note(
            &self.net.trace,
            format!("client {}: reopen: {why}", self.index),
        );
        let fresh = self.open();
        *self.client.lock().unwrap() = fresh;
    }

    /// Replaces the connection if it has ended (another caller may have replaced it already).
    fn reopen_if_closed(&self, why: &str) {
        if self.client().is_closed() && !self.closing.load(Ordering::SeqCst) {
            self.reopen(why);
        }
    }
}

async fn run(variant: &'static str, seed: u64, caps: Caps, trace: SharedTrace) -> Vec<String> {
    let mut rng = Prng::new(seed);
    let sim_t0 = Instant::now();
    let mut config = SimConfig::new(Model::Wsg50)
        .with_part(40.0, 2.0)
        .with_time_scale(1.0)
        .text()
        .with_fast_stop_on_close(!rng.one_in(4));
    config.final_reply_lag = rng.millis(0, 300);
    config.text_ack_gap = rng.millis(0, 50);
    let sim = Arc::new(SimServer::in_memory(config));
    sim.start_recording(RECORD_CAPACITY);
    // Off while the gripper is readied (below).
    let on = Arc::new(AtomicBool::new(false));
    let (level, n_clients) = draw_shape(&mut rng, caps);
    // GCL has no checksum: a flipped bit is another well-formed line no client could tell from
    // the device's (`MOVE(20)` read as `MOVE(22)`, `POS=20.0` as `POS=22.0`). Runs with
    // corruption (a third) hold answers to their form and name only (`oracle.rs`).
    let corrupting = level > 0 && rng.one_in(3);
    let run = run_line(variant, seed, caps, level, n_clients);
    note(&trace, format!("{run}, corrupting {corrupting}"));
    // Up to 20 callers per client (issue 29) in a quarter of the full-size runs.
    let caps = if caps.callers == Caps::FULL.callers && rng.one_in(4) {
        Caps {
            callers: 20,
            ..caps
        }
    } else {
        caps
    };
    let mut ctxs = Vec::new();
    for index in 0..n_clients {
        let mut crng = rng.fork();
        let mut profile = StreamProfile::random(&mut crng, level, false);
        if !corrupting {
            profile.corrupt = 0;
        }
        let config = workload::draw_config(&mut crng);
        let reconnect = crng.one_in(2);
        note(
            &trace,
            format!("client {index}: {config:?} reconnect {reconnect} {profile:?}"),
        );
        let net = Net {
            sim: sim.clone(),
            rng: Mutex::new(crng.fork()),
            profile,
            on: on.clone(),
            trace: trace.clone(),
        };
        let sessions = Arc::new(Mutex::new(Vec::new()));
        let (near, _) = tokio::io::duplex(1);
        let ctx = Ctx {
            index,
            // Replaced at once: `open` needs the slot.
            client: Mutex::new((Client::from_io(near, config.clone()), 0)),
            sessions,
            taps: Mutex::new(Vec::new()),
            reconnect,
            corrupting,
            closing: AtomicBool::new(false),
            stuck: AtomicBool::new(false),
            closed_at: Mutex::new(None),
            config,
            net,
        };
        *ctx.client.lock().unwrap() = ctx.open();
        ctxs.push(Arc::new(ctx));
    }

    // The simulator starts in FAST STOP and unreferenced, as a gripper does: most runs ready it
    // first, so that motions run during the faults rather than being refused.
    if rng.one_in(5) {
        note(&trace, "the gripper is not readied");
    } else {
        let c = ctxs[0].client();
        let ready = (
            c.ack_fast_stop().await,
            c.home(HomingDirection::Default).await,
        );
        note(&trace, format!("ready: {ready:?}"));
    }
    on.store(true, Ordering::SeqCst);

    // The fault phase.
    let log = Arc::new(Log::default());
    let caller = |ctx: &Arc<Ctx>, k, rng, ops| {
        workload::caller(ctx.clone(), k, rng, ops, log.clone(), trace.clone())
    };
    let restart = |rng: &mut Prng| {
        draw_restart(rng, level, |at| {
            let sim = sim.clone();
            restart_at(at, &trace, move || sim.restart())
        })
    };
    fault_phase(&mut rng, caps, &ctxs, caller, restart, &on, &trace).await;

    let mut v = Vec::new();
    for ctx in &ctxs {
        v.extend(recovery(ctx, &log, &trace).await);
    }
    for ctx in &ctxs {
        v.extend(quiet::every_kind(ctx, &log, &trace).await);
    }
    // A client whose quiet phase found a name held for good (issue 29 K, M) may hold STOP too.
    let usable =
        |c: &&Arc<Ctx>| !c.closing.load(Ordering::SeqCst) && !c.stuck.load(Ordering::SeqCst);
    if let Some(ctx) = ctxs.iter().find(usable) {
        v.extend(stop_is_not_queued(ctx, &sim, sim_t0, &trace).await);
    }
    // After the stop check: the edge client may leave without `BYE()` (FAST STOP).
    if rng.one_in(4) {
        v.extend(edges::check(&mut rng, &sim, &trace).await);
    }
    for ctx in &ctxs {
        if ctx.start_closing() {
            continue;
        }
        let c = ctx.client();
        let lost = c.is_closed();
        // Bounded: a client may have drawn `Duration::MAX` for its query timeout.
        let c = c.with_timeout(RECOVERY_TIMEOUT);
        let r = c.close().await;
        note(&trace, format!("close client {}: {r:?}", ctx.index));
        let after = c.position_mm().await;
        let lost = lost || matches!(r, Err(Error::ConnectionLost { .. }));
        let stuck = if ctx.stuck.load(Ordering::SeqCst) {
            quiet::FULL
        } else {
            ""
        };
        v.extend(after_close(ctx.index, "POS?", &after, lost).map(|e| e + stuck));
    }

    let record = crate::wsg::note_record(&sim, &trace);
    let sessions: Vec<Vec<SessionId>> = ctxs
        .iter()
        .map(|c| c.sessions.lock().unwrap().clone())
        .collect();
    let calls = log.calls.lock().unwrap().clone();
    let pushes = log.pushes.lock().unwrap().clone();
    let closed_at: Vec<Option<Instant>> =
        ctxs.iter().map(|c| *c.closed_at.lock().unwrap()).collect();
    let exact = !corrupting;
    let mut all = oracle::check(
        &calls, &pushes, &record, sim_t0, &sessions, &closed_at, exact,
    );
    let taps: Vec<Vec<SharedTap>> = ctxs
        .iter()
        .map(|c| c.taps.lock().unwrap().clone())
        .collect();
    let configs: Vec<ClientConfig> = ctxs.iter().map(|c| c.config.clone()).collect();
    let after_close = log.after_close.lock().unwrap().clone();
    all.extend(liveness::check(&calls, &taps, &configs, &after_close));
    all.extend(v);
    drop(ctxs);
    drop(sim);
    all
}

/// The timeout of the recovery calls: longer than the simulator's quiet gap after an `ACK`
/// (`SimConfig::text_ack_gap`, up to 50 ms here), which holds back the reply of a query sent
/// right after an `ACK`ed command (a client's 50 ms query timeout could expire behind it).
const RECOVERY_TIMEOUT: Duration = Duration::from_secs(2);

/// Promise 5: once the faults stop, after the longest a reply can stay away (a call's timeout,
/// at most 5 s or the client's motion timeout, plus its `give_up_after`) and the longest
/// motion, a client's connection works again: `FSACK()` and `POS?` succeed (a reconnecting
/// client opens a new connection if its own was lost); one that does not reconnect fails with
/// `ConnectionLost` if, and only if, its connection ended.
async fn recovery(ctx: &Ctx, log: &Log, trace: &SharedTrace) -> Vec<String> {
    if ctx.closing.load(Ordering::SeqCst) {
        return Vec::new();
    }
    // Capped: a drawn `Duration::MAX` (issue 29) must not overflow the bound.
    let cap = Duration::from_secs(60);
    let longest_call = ctx.config.motion_timeout.clamp(Duration::from_secs(5), cap);
    let bound = longest_call + ctx.config.give_up_after.min(cap) + Duration::from_secs(12);
    tokio::time::sleep(bound).await;
    if ctx.reconnect {
        ctx.reopen_if_closed("recovery: the connection was lost");
    }
    if ctx.corrupting {
        // A corrupted LF in the fault phase leaves a fragment in the client's reader that eats
        // the next reply line (it ends it): a query whose answer nobody checks clears it.
        let flush = ctx
            .client()
            .with_timeout(RECOVERY_TIMEOUT)
            .temperature_c()
            .await;
        note(
            trace,
            format!("recovery client {}: TEMP? {flush:?}", ctx.index),
        );
    }
    let (c, conn) = ctx.current();
    let c = c.with_timeout(RECOVERY_TIMEOUT);
    let lost = c.is_closed();
    let mut v = Vec::new();
    for (line, name, expect) in [
        ("FSACK()", "FSACK", Expect::Ack),
        ("POS?", "POS", Expect::Value),
    ] {
        let start = Instant::now();
        let r = if expect == Expect::Ack {
            c.ack_fast_stop().await.map(|()| Res::Done)
        } else {
            c.position_mm().await.map(Res::Value)
        };
        note(
            trace,
            format!("recovery client {}: {line} {r:?}", ctx.index),
        );
        let res = r.as_ref().map_or_else(classify, Clone::clone);
        match (&res, lost) {
            (Res::Done | Res::Value(_), false) | (Res::Lost(_), true) => {}
            _ => v.push(format!(
                "5 (recovery): client {} (reconnect {}, lost {lost}): {bound:?} after the faults stopped, {line} ended {r:?}{}",
                ctx.index,
                ctx.reconnect,
                recovery_tag(ctx, log, conn, (line, name, expect), start)
            )),
        }
        log.calls.lock().unwrap().push(CallRec {
            client: ctx.index,
            conn,
            line: line.into(),
            name,
            expect,
            start,
            end: Instant::now(),
            timeout: RECOVERY_TIMEOUT,
            res,
        });
    }
    v
}

/// Why a recovery call failed, if it is a known finding: its name held for good (issue 29 M),
/// or the client's queue full of calls given up behind such names (K with M).
fn recovery_tag(
    ctx: &Ctx,
    log: &Log,
    conn: usize,
    (line, name, expect): (&str, &str, Expect),
    start: Instant,
) -> &'static str {
    let held = quiet::held_tag(ctx, log, conn, name, expect, start);
    if held.is_empty() {
        quiet::full_tag(ctx, log, conn, line, start)
    } else {
        held
    }
}

/// Promise 3, live: with the network quiet, a `STOP()` called while a slow `MOVE` runs reaches
/// the device at the instant it is called (not behind the motion), is answered by its own
/// `ACK STOP`, and the `MOVE` ends with its `ERR MOVE` (shared note §3.7).
async fn stop_is_not_queued(
    ctx: &Ctx,
    sim: &SimServer,
    sim_t0: Instant,
    trace: &SharedTrace,
) -> Vec<String> {
    // Bounded calls: a client may have drawn `Duration::MAX` for its default timeouts.
    let c = ctx.client().with_timeout(RECOVERY_TIMEOUT);
    let _ = c.ack_fast_stop().await;
    let m = c.with_timeout(Duration::from_secs(30));
    if m.home(HomingDirection::Default).await.is_err() {
        return Vec::new();
    }
    let width = c.position_mm().await.unwrap_or(0.0);
    let target = if width > 55.0 { 5.0 } else { 105.0 };
    let mover = m.clone();
    let motion_start = Instant::now();
    let motion = tokio::spawn(async move { mover.move_to(target, Some(10.0)).await });
    tokio::time::sleep(Duration::from_millis(200)).await;
    let start = Instant::now();
    let stopped = c.stop().await;
    let took = start.elapsed();
    let motion = motion.await;
    note(
        trace,
        format!("stop check: stop {stopped:?} after {took:?}, move {motion:?}"),
    );
    let rec = sim.recording();
    let at = |r: &gripper::wsg::sim::SimRecord| sim_t0 + r.at;
    let accepted = rec.records.iter().any(|r| {
        matches!(&r.event, SimEvent::TextReply { line, .. } if line == "ACK MOVE")
            && at(r) >= motion_start
            && at(r) < start
    });
    if c.is_closed() || !accepted {
        return Vec::new(); // The motion never started (refused), or the connection ended.
    }
    let mut v = Vec::new();
    let seen = rec.records.iter().find(|r| {
        at(r) >= start
            && matches!(&r.event, SimEvent::TextRequest { line: Some(l) } if l == "STOP()")
    });
    match seen {
        Some(r) if at(r) <= start + Duration::from_millis(1) => {}
        other => v.push(format!(
            "3 (a stop goes out at once): a STOP() called during a slow MOVE on a quiet network reached the device {:?} after the call (stop {stopped:?} after {took:?})",
            other.map(|r| at(r).saturating_duration_since(start))
        )),
    }
    if stopped.is_err() {
        v.push(format!(
            "3 (a stop stops): STOP() during a MOVE on a quiet network ended {stopped:?}"
        ));
    }
    let aborted =
        matches!(&motion, Ok(Err(Error::Device { line, .. })) if line.starts_with("ERR MOVE"));
    if !aborted {
        v.push(format!(
            "3 (a stop stops): the MOVE stopped during its run ended {motion:?}, not with its ERR MOVE"
        ));
    }
    v
}

impl DocumentedErrors for Error {
    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }

    fn is_connection_lost(&self) -> bool {
        matches!(self, Error::ConnectionLost { .. })
    }
}
