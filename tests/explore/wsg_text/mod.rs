//! The WSG's text interface (GCL, `gripper::wsg::text`) under the explorer (issue 24): the WSG
//! simulator in text mode (`SimConfig::text`, WSG 50, a 40 mm part, real-time motion under the
//! paused clock, every line in and out recorded: `SimEvent::TextRequest`/`TextReply`), one or
//! two clients over in-memory TCP through the fault layer (`Client::from_io`), several callers
//! each, a device restart now and then, a quiet phase (recovery; a live STOP during a slow
//! MOVE), closing, then the oracle (`oracle.rs`). GCL has no ids: replies pair with commands by
//! name, which is what the oracle checks, line by line.
//!
//! Every client runs over the connections its opener opens (`Client::open_with`: an in-memory
//! pipe through the fault layer to a new simulator session, tapped); in one run of two a client
//! reconnects (`ClientConfig::reconnect`, the explorer's quick policy) after a loss: a cut of
//! the fault layer, a device restart, or a give-up. Its connection events are followed
//! (`connection_events`): rule 6 judges each loss it reports. After recovery a reconnecting
//! client's connection is cut on purpose, and what a reconnect restores must be restored
//! (`restore.rs`).

mod edges;
mod liveness;
mod oracle;
mod quiet;
mod restore;
mod tap;
mod workload;

use std::collections::{BTreeMap, BTreeSet};
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures_util::StreamExt;

use gripper::reconnect::{ConnectionEvent, ConnectionEvents};
use gripper::wsg::sim::{Model, SessionId, SessionKind, SimConfig, SimEvent, SimServer};
use gripper::wsg::text::{Client, ClientConfig, Error};
use gripper::wsg::HomingDirection;
use gripper::wsg::SystemState;
use tokio::time::Instant;

use self::tap::{Cut, SharedTap, Tap};
use self::workload::{classify, AfterClose, CallRec, Expect, Log, Res};
use crate::core::phases::{
    after_close, draw_restart, draw_shape, fault_phase, reconnect_policy, run_line,
    DocumentedErrors,
};
use crate::core::servers::{watch_losses_logged, Losses};
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

/// One client and what the oracle needs of it.
pub struct Ctx {
    index: usize,
    /// The client, over the connections its opener opens (`Client::open_with`).
    client: Client,
    /// Its connections, oldest first: the simulator session, the tap, when it opened.
    conns: Conns,
    /// Whether it reconnects (`ClientConfig::reconnect`).
    reconnect: bool,
    /// Whether its link may flip bits (GCL has no checksum: a flipped bit is another line).
    corrupting: bool,
    closing: AtomicBool,
    /// Whether the quiet phase found a name of this client held for good, or its queue full of
    /// such calls (issue 29 K, M): the documented errors after `close()` are then tagged.
    stuck: AtomicBool,
    /// When a `close()` began (a `Closed` before it breaks promise 5).
    closed_at: Mutex<Option<Instant>>,
    /// Each loss the client reported (`connection_events`), with when (rule 6 judges it).
    losses: Losses,
    /// When the client was without a connection: from each reported loss to the session's
    /// restore (`None`: not restored); calls made meanwhile wait (rule 9 judges a stop from the
    /// restore).
    downs: Downs,
    config: ClientConfig,
}

/// One connection a client's opener opened.
#[derive(Clone)]
pub struct Conn {
    /// The simulator session that serves it.
    pub session: SessionId,
    /// What the client wrote and read on it (`tap.rs`).
    pub tap: SharedTap,
    /// Cuts it on the client's side (`restore.rs`).
    pub cut: Arc<Cut>,
    /// When it was opened.
    pub opened: Instant,
}

/// A client's connections, oldest first.
pub type Conns = Arc<Mutex<Vec<Conn>>>;

impl Ctx {
    /// Marks the client closing; true if it was already.
    fn start_closing(&self) -> bool {
        self.closed_at
            .lock()
            .unwrap()
            .get_or_insert_with(Instant::now);
        self.closing.swap(true, Ordering::SeqCst)
    }

    /// The client.
    fn client(&self) -> Client {
        self.client.clone()
    }

    /// The client and the index of the connection of the moment (the last opened; a call made
    /// while a reconnecting client is between connections goes out on the next one, which
    /// [`resolve_conns`] tells after the run).
    fn current(&self) -> (Client, usize) {
        let n = self.conns.lock().unwrap().len();
        (self.client.clone(), n.saturating_sub(1))
    }

    /// The taps of its connections, oldest first.
    fn taps(&self) -> Vec<SharedTap> {
        self.conns
            .lock()
            .unwrap()
            .iter()
            .map(|c| c.tap.clone())
            .collect()
    }
}

/// The opener of client `index`: each call makes a new in-memory pipe through the fault layer
/// (`profile`, on while `on`), serves its far end on the simulator as a new session, taps the
/// client's end, and notes the connection in `conns`.
fn opener(
    index: usize,
    sim: Arc<SimServer>,
    rng: Prng,
    profile: StreamProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
    conns: Conns,
) -> impl Fn() -> std::future::Ready<std::io::Result<Tap>> + Send + Sync + 'static {
    let rng = Mutex::new(rng);
    move || {
        let (near, far) = faulty_pipe(
            &mut rng.lock().unwrap(),
            profile,
            on.clone(),
            trace.clone(),
            format!("c{index}"),
        );
        let session = sim.serve_stream(far, SessionKind::Tcp);
        let (near, tap, cut) = Tap::new(near);
        let mut conns = conns.lock().unwrap();
        conns.push(Conn {
            session,
            tap,
            cut,
            opened: Instant::now(),
        });
        note(
            &trace,
            format!(
                "client {index}: connection {} session {session}",
                conns.len() - 1
            ),
        );
        std::future::ready(Ok(near))
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
        let conns = Conns::default();
        let open = opener(
            index,
            sim.clone(),
            crng.fork(),
            profile,
            on.clone(),
            trace.clone(),
            conns.clone(),
        );
        let config = ClientConfig {
            reconnect: reconnect.then(reconnect_policy),
            ..config
        };
        // The first open cannot fail (an in-memory pipe, the faults off while readying).
        let client = match Client::open_with(open, config.clone()).await {
            Ok(client) => client,
            Err(e) => return vec![format!("5 (recovery): client {index} did not open: {e}")],
        };
        let (_, losses) = watch_losses_logged(client.connection_events(), index, trace.clone());
        let downs = watch_downs(client.connection_events());
        let ctx = Ctx {
            index,
            client,
            conns,
            reconnect,
            corrupting,
            closing: AtomicBool::new(false),
            stuck: AtomicBool::new(false),
            closed_at: Mutex::new(None),
            losses,
            downs,
            config,
        };
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
        v.extend(recovery(ctx, &sim, &log, &trace).await);
    }
    for ctx in &ctxs {
        v.extend(restore::check(ctx, &log, &trace).await);
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
    let conns: Vec<Vec<Conn>> = ctxs
        .iter()
        .map(|c| c.conns.lock().unwrap().clone())
        .collect();
    let sessions: Vec<Vec<SessionId>> = conns
        .iter()
        .map(|c| c.iter().map(|c| c.session).collect())
        .collect();
    let taps: Vec<Vec<SharedTap>> = conns
        .iter()
        .map(|c| c.iter().map(|c| c.tap.clone()).collect())
        .collect();
    let mut calls = log.calls.lock().unwrap().clone();
    let mut after_close = log.after_close.lock().unwrap().clone();
    let pushes = log.pushes.lock().unwrap().clone();
    let closed_at: Vec<Option<Instant>> =
        ctxs.iter().map(|c| *c.closed_at.lock().unwrap()).collect();
    let exact = !corrupting;
    let losses: Vec<Vec<(Instant, String)>> = ctxs
        .iter()
        .map(|c| c.losses.lock().unwrap().clone())
        .collect();
    let configs: Vec<ClientConfig> = ctxs.iter().map(|c| c.config.clone()).collect();
    let downs: Vec<Vec<Down>> = ctxs
        .iter()
        .map(|c| c.downs.lock().unwrap().clone())
        .collect();
    // What each reconnect restored on its connection (the first has none).
    let restores: Vec<Vec<_>> = conns
        .iter()
        .zip(&downs)
        .map(|(conns, downs)| {
            conns
                .iter()
                .enumerate()
                .map(|(k, c)| {
                    if k == 0 {
                        return Default::default();
                    }
                    let restored = downs
                        .iter()
                        .find(|(lost, r)| *lost <= c.opened && r.is_none_or(|r| r >= c.opened))
                        .and_then(|d| d.1);
                    liveness::restore_writes(&c.tap.lock().unwrap(), restored)
                })
                .collect()
        })
        .collect();
    resolve_conns(&mut calls, &mut after_close, &conns, &restores);
    let mut all = oracle::check(
        &calls, &pushes, &record, sim_t0, &sessions, &closed_at, exact,
    );
    let damaged_errors = oracle::damaged_parse_errors(&record, sim_t0, &sessions);
    all.extend(liveness::check(
        &calls,
        (&taps, &damaged_errors),
        &configs,
        &after_close,
        &downs,
        &restores,
        exact,
    ));
    all.extend(liveness::losses(&losses, &conns, &calls, &configs, exact));
    all.extend(v);
    drop(ctxs);
    drop(sim);
    all
}

/// A time a client was without a connection: from a reported loss to the restore of the next
/// session (`None`: never restored).
pub type Down = (Instant, Option<Instant>);

/// A client's [`Down`] times, oldest first.
type Downs = Arc<Mutex<Vec<Down>>>;

/// Follows a client's connection events into its [`Down`] times.
fn watch_downs(mut events: ConnectionEvents) -> Downs {
    let downs = Downs::default();
    let log = downs.clone();
    tokio::spawn(async move {
        while let Some(ev) = events.next().await {
            let now = Instant::now();
            let mut log = log.lock().unwrap();
            match ev {
                ConnectionEvent::Lost { .. } => log.push((now, None)),
                ConnectionEvent::Restored { .. } => {
                    if let Some(last) = log.last_mut() {
                        last.1.get_or_insert(now);
                    }
                }
                _ => {}
            }
        }
    });
    downs
}

/// The timeout of the recovery calls: longer than the simulator's quiet gap after an `ACK`
/// (`SimConfig::text_ack_gap`, up to 50 ms here), which holds back the reply of a query sent
/// right after an `ACK`ed command (a client's 50 ms query timeout could expire behind it).
const RECOVERY_TIMEOUT: Duration = Duration::from_secs(2);

/// Promise 5: once the faults stop, after the longest a reply can stay away (a call's timeout,
/// at most 5 s or the client's motion timeout, plus its `give_up_after`) and the longest
/// motion, a client's connection works again: `FSACK()` and `POS?` succeed (a reconnecting
/// client has reconnected by then if its connection was lost: its backoff is at most 0.5 s);
/// one that does not reconnect fails with `ConnectionLost` if, and only if, its connection
/// ended.
async fn recovery(ctx: &Ctx, sim: &SimServer, log: &Log, trace: &SharedTrace) -> Vec<String> {
    if ctx.closing.load(Ordering::SeqCst) {
        return Vec::new();
    }
    // Capped: a drawn `Duration::MAX` (issue 29) must not overflow the bound.
    let cap = Duration::from_secs(60);
    let longest_call = ctx.config.motion_timeout.clamp(Duration::from_secs(5), cap);
    let bound = longest_call + ctx.config.give_up_after.min(cap) + Duration::from_secs(12);
    tokio::time::sleep(bound).await;
    // A motion the fault phase started may outlast that bound: a damaged argument can slow it
    // to the model's least speed (`GRIP(57,2.5)` read as `GRIP(57,2,5)`, 5 mm/s, ran 22 s, and
    // the quiet phase's HOME was refused E_ALREADY_RUNNING: wsg-text:0xc56aae17ae8b2929). The
    // recovery waits for the fingers to rest too, at most as long as 110 mm at 0.1 mm/s
    // takes. Reading the simulator's state writes nothing: a run whose fingers rest by then
    // takes the path it took before.
    let rest_by = Instant::now() + Duration::from_secs(1200);
    while sim.snapshot().system_state.contains(SystemState::MOVING) && Instant::now() < rest_by {
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    if ctx.corrupting {
        // A corrupted LF in the fault phase leaves a fragment in the client's reader that eats
        // the next reply line (it ends it): a query whose answer nobody checks clears it. The
        // same on the way out: a request whose LF was flipped leaves a fragment in the device's
        // reader, which the next request written ends, and the device answers that line once
        // (`ERR <name> 15`, the fragment's name): the flush then goes unanswered.
        let (c, conn) = ctx.current();
        let c = c.with_timeout(RECOVERY_TIMEOUT);
        // Of a name not held (issue 29 M: a call without timeout whose request was damaged
        // holds its name, so a flush of that name would never be written and the fragment
        // would eat the recovery's `FSACK()`; wsg-text:0xfdead7c406213832, `TEMP?`).
        let free = |name: &str| {
            ctx.taps().get(conn).is_none_or(|tap| {
                !liveness::busy(
                    &tap.lock().unwrap(),
                    name,
                    Expect::Value,
                    Instant::now(),
                    usize::MAX,
                )
            })
        };
        let flush = if free("TEMP") {
            ("TEMP?", c.temperature_c().await)
        } else if free("PWT") {
            ("PWT?", c.part_width_tolerance_mm().await)
        } else if free("CLT") {
            ("CLT?", c.clamping_travel_mm().await)
        } else {
            ("FORCE?", c.force_n().await)
        };
        note(
            trace,
            format!("recovery client {}: {} {:?}", ctx.index, flush.0, flush.1),
        );
        if matches!(flush.1, Err(Error::Timeout { .. })) {
            // The flush unanswered: `give_up_after` past its timeout the client gives its
            // connection up (documented; rule 6 judges the loss), and a reconnecting client
            // reconnects (its backoff is at most 0.5 s). Recovery is judged after that
            // (wsg-text:0x8288e5c59fe194ae: the flush ate the device's fragment of a damaged
            // `GRIP(...)` and the give-up fell in the quiet phase).
            let cap = Duration::from_secs(60);
            tokio::time::sleep(ctx.config.give_up_after.min(cap) + Duration::from_secs(1)).await;
        }
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

/// Which connection each call went out on: the one its own line was written on during the call
/// (a call made while a reconnecting client was between connections waits and goes out on the
/// next one), else the one of the moment when it began (`CallRec::conn`). The same for each
/// `close()` of the fault phase and its `BYE()`. A write is one call's only, paired as
/// `liveness::own_writes` pairs them (in the order the calls began; the restore's writes,
/// `restores[client][conn]`, are no call's): a call made at the instant an earlier call of its
/// line was written on the old connection went out on the next one
/// (wsg-text:0x38a5ce55b54960f5: a `STOP()` made as the one before it was written, then the
/// connection half-closed; it was written at the restore, but was taken for the old write and
/// judged never written, rule 9). Of the connections with such a write, the last: a call
/// written on one connection ends when that connection is lost, before the next one is opened,
/// so a call with writes of its line on two connections was written on the later one, and the
/// earlier write was another call's (`wsg-text:0xa5b2e65cdc30e782`: a `TEMP?` without timeout,
/// held in the client's channel across a reconnect, was kept on the old connection by another
/// call's `TEMP?` written there; its own write on the new one was then paired with a later
/// `TEMP?`, held behind a full queue and never written, whose `Timeout` rule 7 took for a reply
/// read in time).
fn resolve_conns(
    calls: &mut [CallRec],
    after_close: &mut [AfterClose],
    conns: &[Vec<Conn>],
    restores: &[Vec<BTreeSet<u64>>],
) {
    let mut order: Vec<usize> = (0..calls.len()).collect();
    order.sort_by_key(|&i| calls[i].start);
    // Calls begun at one instant cannot be told apart by the records (wsg-text:0xb2ce32dcc0fcc68d:
    // three `STOP()`s at one instant): a write one of them took is the others' to take too.
    let mut taken = BTreeMap::new();
    for i in order {
        let c = &mut calls[i];
        // A caller's calls after a lost one are filed under the next connection
        // (`workload::caller`), which never opens for a client that does not reconnect: such a
        // call is judged on the last one there is.
        c.conn = c.conn.min(conns[c.client].len().saturating_sub(1));
        let found = conns[c.client]
            .iter()
            .enumerate()
            .skip(c.conn)
            .filter_map(|(k, conn)| {
                let tap = conn.tap.lock().unwrap();
                tap.written
                    .lines
                    .iter()
                    .find(|l| {
                        l.at >= c.start
                            && l.at <= c.end
                            && l.text == c.line
                            && taken
                                .get(&(c.client, k, l.seq))
                                .is_none_or(|&start| start == c.start)
                            && !restores[c.client][k].contains(&l.seq)
                    })
                    .map(|l| (k, l.seq))
            })
            .next_back();
        if let Some((k, seq)) = found {
            taken.insert((c.client, k, seq), c.start);
            c.conn = k;
        } else if matches!(c.res, Res::Lost(_)) {
            // Never written, yet lost with a connection: the one open when it ended, not the
            // one current when it began (wsg-text:0xe717a526d9d1e7a2: a `MOVE` made on
            // connection 3, waiting behind another until connection 4 was given up, had that
            // loss judged on connection 3, whose restore's `VERBOSE=0` was answered; rule 6).
            if let Some((k, _)) = conns[c.client]
                .iter()
                .enumerate()
                .skip(c.conn)
                .rfind(|(_, conn)| conn.opened <= c.end)
            {
                c.conn = k;
            }
        } else if let Some((k, _)) = conns[c.client]
            .iter()
            .enumerate()
            .skip(c.conn + 1)
            .rfind(|(_, conn)| conn.opened <= c.start)
        {
            // Never written, and begun once a later connection was open: made at the instant
            // the opener recorded it, but before, it was filed under the lost one
            // (wsg-text:0xed902f456207c5f0: a `STOP()` waiting behind the unanswered `STOP()`
            // of connection 4 was judged on connection 3, and rule 9 saw no stop on the wire).
            c.conn = k;
        }
    }
    let written_on = |client: usize, from: usize, line: &str, start: Instant, end: Instant| {
        conns[client]
            .iter()
            .enumerate()
            .skip(from)
            .filter_map(|(k, c)| {
                let tap = c.tap.lock().unwrap();
                let written = tap
                    .written
                    .lines
                    .iter()
                    .any(|l| l.at >= start && l.at <= end && l.text == line);
                written.then_some(k)
            })
            .next_back()
    };
    for a in after_close.iter_mut() {
        if let Some(k) = written_on(a.client, a.conn, "BYE()", a.close.0, a.after.0) {
            a.conn = k;
        }
    }
}
