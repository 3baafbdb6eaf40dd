//! GRIPLINK under the explorer (issue 21 §3): one simulated controller (ET4, a part between the
//! fingers on port 0, real-time motion under the paused clock), one or two clients over TCP (in
//! memory, through the fault layer, reconnecting through `Client::open_with` or not), several
//! callers each, a controller restart now and then, a quiet phase (recovery), closing, and the
//! oracle. GRIPLINK has no sequence numbers: replies pair with commands by order (manual 2.1),
//! which is what the oracle checks, reply by reply.

mod oracle;
mod workload;

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::griplink::command::Command;
use gripper::griplink::sim::{Fault, SimConfig, SimExchange, SimServer};
use gripper::griplink::{Client, ClientConfig, Error, WaitBy};
use tokio::time::Instant;

use self::oracle::ClientView;
use self::workload::{perform, pick, timeout_of, CallRec, Op, Render, WaitKind};
use crate::core::phases::{
    draw_restart, draw_shape, fault_phase, open_retrying, reconnect_policy, run_line,
    unless_given_up, DocumentedErrors,
};
use crate::core::servers::{
    close_and_check, draw_drops, quiet_call, watch_losses_logged, Losses, Servers, Sessions,
};
use crate::core::streams::StreamProfile;
use crate::core::{note, Caps, Prng, Scenario, SharedTrace};

/// The GRIPLINK scenario.
pub struct Griplink;

/// Entries the simulator records at most (a run stays far below).
const RECORD_CAPACITY: usize = 1 << 20;

/// How long a call without timeout may take before the caller's guard calls it hung (rule 8):
/// far beyond anything the run's faults allow (a 3 s stall, a give-up of at most 1 s,
/// reconnects every 0.5 s) -- unless the controller still holds a reply then: a blocking
/// motion may be slow for real (a FLEX… drawn at 1 µm/s takes a day over the whole stroke;
/// griplink-tcp:0x05d4b74b6354804d, 82 µm/s, 889 s), and WSTRs pipelined one behind another
/// hold the line up to 10 s each. The guard then waits on, up to [`HELD_LIMIT`].
const FOREVER_GUARD: Duration = Duration::from_secs(600);

/// How long a wait helper without timeout runs before its caller gives it up: rule 8 does not
/// judge it (it waits as long as the device gives it no sign, `oracle.rs`), so the guard only
/// ends the run's part of it. Short: a helper polling at `MIN_POLL_INTERVAL` (1 ms, drawn as
/// `WaitBy::Polling(ZERO)`) makes a thousand round trips per simulated second, and under the
/// 600 s guard one run took over a minute of wall time (griplink-tcp:0x10c5c05e830bc2c8,
/// reported as a task that spins).
const HELPER_GUARD: Duration = Duration::from_secs(10);

/// The longest a run waits for the controller to answer what it holds (see [`FOREVER_GUARD`]),
/// then goes on: well below the run's own limit (`core::RUN_LIMIT`, 3,600 s). A reply held on a
/// connection the client has given up may be a grip at 13 µm/s, 5,156 s long, that nobody
/// reads: at 48 h the run never reached its quiet phase (griplink-tcp:0xde5f21a5f5ca4acb).
const HELD_LIMIT: Duration = Duration::from_secs(1800);

impl Scenario for Griplink {
    fn variants(&self) -> &'static [&'static str] {
        &["griplink-tcp"]
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

/// The controller of the moment (a restart replaces it: its connections end with it) and the
/// records of the ones it replaced.
type Sims = Servers<SimServer, Vec<SimExchange>>;

fn new_sim() -> Arc<SimServer> {
    let sim = SimServer::in_memory(SimConfig::et4().time_scale(1.0));
    sim.set_part(0, Some(30.0));
    sim.start_recording(RECORD_CAPACITY);
    Arc::new(sim)
}

/// One client and what the oracle needs of it.
struct Ctx {
    index: usize,
    client: Client,
    sessions: Sessions,
    reconnects: bool,
    closing: AtomicBool,
    lost: Arc<AtomicBool>,
    losses: Losses,
}

/// What every caller of a run shares.
struct RunWide {
    /// Numbers the values set (unique values: an answer names its request).
    labels: AtomicU64,
    /// Whether a call may have no timeout (not in runs where the controller drops replies).
    forever: bool,
    log: Mutex<Vec<CallRec>>,
    trace: SharedTrace,
    /// The controller of the moment (whether it still holds a reply).
    sims: Sims,
}

/// The client's configuration: every option drawn (pipeline depths beyond the default 1 up to
/// none at all, queue lengths, line limits small enough to discard replies, WAITVAL margins).
fn draw_config(crng: &mut Prng, reconnects: bool) -> ClientConfig {
    ClientConfig {
        query_timeout: crng.millis(50, 2000),
        motion_timeout: crng.millis(500, 10_000),
        wait_margin: crng.millis(0, 3000),
        give_up_after: crng.millis(10, 1000),
        connect_timeout: Duration::from_secs(1),
        // Small limits discard the longer replies (recipes, long strings; documented), but
        // keep `ID?`'s, the resynchronisation probe's answer.
        max_line_len: if crng.one_in(8) {
            crng.between(20, 40) as usize
        } else {
            ClientConfig::default().max_line_len
        },
        queue_len: [1, 2, 4, 64, 1000][crng.below(5) as usize],
        pipeline_depth: match crng.below(8) {
            0 => 8,
            1 => usize::MAX,
            n => (n as usize).min(4),
        },
        reconnect: reconnects.then(reconnect_policy),
    }
}

async fn run(variant: &'static str, seed: u64, caps: Caps, trace: SharedTrace) -> Vec<String> {
    let mut rng = Prng::new(seed);
    let sims: Sims = Servers::new(new_sim());
    let faults_on = Arc::new(AtomicBool::new(true));
    let (level, n_clients) = draw_shape(&mut rng, caps);
    note(&trace, run_line(variant, seed, caps, level, n_clients));
    let mut violations = Vec::new();
    let mut ctxs = Vec::new();
    let mut configs = Vec::new();
    for index in 0..n_clients {
        let mut crng = rng.fork();
        let reconnects = crng.one_in(2);
        let profile = StreamProfile {
            // No corruption: TCP's checksum delivers bytes intact or not at all, and GRIPLINK
            // has no checksum of its own (manual 2.1), so a flipped bit is another well-formed
            // line no client could tell from the controller's (the WSG, with its CRC, is
            // searched with corruption).
            corrupt: 0,
            ..StreamProfile::random(&mut crng, level, false)
        };
        let sessions = Sessions::default();
        let open = sims.opener(
            index,
            crng.fork(),
            profile,
            faults_on.clone(),
            trace.clone(),
            sessions.clone(),
            |sim, io| sim.serve_stream(io),
        );
        let config = draw_config(&mut crng, reconnects);
        let opened = open_retrying(index, &config, &faults_on, &trace, || {
            Client::open_with(open.clone(), config.clone())
        });
        let client = match opened.await {
            Ok(client) => client,
            Err(violation) => return vec![violation],
        };
        let (lost, losses) = watch_losses_logged(client.connection_events(), index, trace.clone());
        configs.push(config);
        ctxs.push(Arc::new(Ctx {
            index,
            client,
            sessions,
            reconnects,
            closing: AtomicBool::new(false),
            lost,
            losses,
        }));
    }

    // The controller loses a reply now and then (a real controller's bug, or a test's): the
    // pairing by order is then out of step, which the client must notice by the reply's shape
    // and repair with a probe (client/pipeline.rs), never pass on as another command's answer.
    // (A call without timeout is then left out: a dropped reply would hold it forever.)
    let drops = draw_drops(&mut rng, level);
    let run_wide = Arc::new(RunWide {
        labels: AtomicU64::new(0),
        forever: drops == 0,
        log: Mutex::new(Vec::new()),
        trace: trace.clone(),
        sims: sims.clone(),
    });
    let caller = |ctx: &Arc<Ctx>, k, rng, ops| caller(ctx.clone(), k, rng, ops, run_wide.clone());
    let faults = |rng: &mut Prng| {
        let restart = draw_restart(rng, level, |at| {
            sims.restart_at(at, new_sim, SimServer::recording, trace.clone())
        });
        let what = "fault: the controller will drop its next reply";
        sims.drop_replies(rng, drops, &trace, what, |sim| sim.inject(Fault::DropReply));
        device_faults(rng, &sims, &trace);
        restart
    };
    fault_phase(&mut rng, caps, &ctxs, caller, faults, &faults_on, &trace).await;

    // Quiet phase (rule 10): after the recovery bound, every kind of call the client's callers
    // made must be served: a client that reconnects must answer; one that does not must answer
    // or (after a loss) fail with ConnectionLost. Not after a dropped reply: the pairing may be
    // out of step with no way to see it (same-shaped replies) until the oldest call's give-up
    // limit, which a call without timeout does not have.
    // The recovery bound: the longest the controller may hold a line (a WSTR, 10 s, manual
    // 3.4.10) beyond the shared 5 s of `quiet_call`, so that no call of the fault phase is
    // still on the wire -- and longer while the controller still holds a reply of the fault
    // phase (a slow motion, WSTRs pipelined one behind another: griplink-tcp:0xcd95b950468dad5f
    // held the line until 42 s with four WSTRs).
    tokio::time::sleep(Duration::from_secs(8)).await;
    until_answered(&sims, &trace).await;
    for ctx in &ctxs {
        if ctx.closing.load(Ordering::SeqCst) || drops > 0 {
            continue;
        }
        let quiet = quiet_call(
            ctx.index,
            ctx.reconnects,
            &ctx.lost,
            "ID?",
            &trace,
            || async { ctx.client.with_timeout(Duration::from_secs(5)).id().await },
        );
        violations.extend(quiet.await);
        violations.extend(quiet_kinds(ctx, &run_wide).await);
        // One run in eight, chosen from the seed without a draw (every other path stays).
        if ctx.index == 0 && seed.rotate_left(17) % 8 == 0 {
            fault_again(ctx, &sims, &run_wide).await;
        }
    }
    for ctx in &ctxs {
        // Closed again even if a caller closed it: its close() may have timed out before
        // BYE() was sent (then the connection stays open, as documented).
        // (Not checked after a dropped reply: then only noted.)
        ctx.closing.store(true, Ordering::SeqCst);
        let within = ctx.client.with_timeout(Duration::from_secs(10));
        let close = within.close();
        let (index, lost, check) = (ctx.index, &ctx.lost, drops == 0);
        let closed = close_and_check(index, "ID?", lost, check, &trace, close, || async {
            ctx.client.id().await
        });
        violations.extend(closed.await);
    }
    // The oracle needs every controller's record; then everything ends.
    let records = sims.all_records_noted(SimServer::recording, &trace, |e: &SimExchange| {
        format!("{}: {:?} -> {:?}", e.session, e.request, e.reply)
    });
    let calls = std::mem::take(&mut *run_wide.log.lock().unwrap());
    let views: Vec<ClientView> = ctxs
        .iter()
        .zip(&configs)
        .map(|(ctx, config)| ClientView {
            sessions: ctx.sessions.lock().unwrap().clone(),
            closing: ctx.closing.load(Ordering::SeqCst),
            losses: ctx.losses.lock().unwrap().clone(),
            give_up_after: config.give_up_after,
            max_line_len: config.max_line_len,
        })
        .collect();
    violations.extend(oracle::judge(&views, &calls, &records, drops > 0));
    drop(ctxs);
    drop(sims);
    violations
}

/// Waits until the controller holds no reply (see [`FOREVER_GUARD`]; at most [`HELD_LIMIT`]),
/// and notes it if it had to wait.
async fn until_answered(sims: &Sims, trace: &SharedTrace) {
    let start = Instant::now();
    while start.elapsed() < HELD_LIMIT && held(sims).await {
        tokio::time::sleep(Duration::from_secs(1)).await;
    }
    if start.elapsed() > Duration::from_millis(1) {
        note(
            trace,
            format!(
                "quiet: the controller held a reply {:?} longer",
                start.elapsed()
            ),
        );
    }
}

/// Whether the controller holds a reply. A held reply may end at the instant the next blocking
/// command behind it starts (pipelined WSTRs): none held counts only if none is held a
/// millisecond later either.
async fn held(sims: &Sims) -> bool {
    if sims.current().0.held_replies() > 0 {
        return true;
    }
    tokio::time::sleep(Duration::from_millis(1)).await;
    sims.current().0.held_replies() > 0
}

/// A call without timeout, given up on only by rule 8's guard (see [`FOREVER_GUARD`]).
async fn unless_hung<T>(call: impl Future<Output = T>, sims: &Sims) -> Option<T> {
    tokio::pin!(call);
    let start = Instant::now();
    let mut guard = FOREVER_GUARD;
    loop {
        if let Some(result) = unless_given_up(Some(guard), call.as_mut()).await {
            return Some(result);
        }
        if start.elapsed() >= HELD_LIMIT || !held(sims).await {
            return None;
        }
        guard = Duration::from_secs(60);
    }
}

/// The device faults of a fault phase: now and then, at 0–5 s, a device faults at once or its
/// next motion ends in `DS_FAULT` (a grip from `DS_FAULT` re-enables the gripper first, manual
/// 3.4.1: the waits' hardest case).
fn device_faults(rng: &mut Prng, sims: &Sims, trace: &SharedTrace) {
    if !rng.one_in(3) {
        return;
    }
    for _ in 0..rng.between(1, 3) {
        let (at, port, now) = (rng.millis(0, 5000), rng.below(2) as u8 * 2, rng.one_in(2));
        let (sims, trace) = (sims.clone(), trace.clone());
        tokio::spawn(async move {
            tokio::time::sleep(at).await;
            let sim = sims.current().0;
            note(
                &trace,
                format!("fault: device {port} faults (at once: {now})"),
            );
            if now {
                sim.inject_device_fault(port);
            }
            sim.fault_next_motion(port);
        });
    }
}

/// Issue 29 G, on purpose (the fault phase meets it only by chance): the empty-handed gripper on
/// port 2 closes on nothing (`DS_NO_PART` at its limit), faults, and a `grip_and_wait` starts in
/// `DS_FAULT`; an `ENABLE` of the same port shows the re-enable (a state other than `DS_FAULT`
/// read after the command: the simulator keeps a motion's start state until its end, so it
/// shows none of its own), then the device faults again, its fingers where they were. The
/// client docs say that state and the `DS_FAULT` read after it end the wait: rule 7
/// (`oracle.rs`, `fault_waits`) judges the 1.5 s wait, well below the 2 s re-enable window that
/// would end it otherwise.
async fn fault_again(ctx: &Ctx, sims: &Sims, run_wide: &RunWide) {
    let client = ctx.client.with_timeout(Duration::from_secs(20));
    let port = client.port(2);
    let prepared = (
        port.home().await,
        port.grip_and_wait(0, WaitBy::Polling(Duration::from_millis(10)))
            .await,
    );
    note(
        &run_wide.trace,
        format!(
            "quiet client {}: fault again, prepared {prepared:?}",
            ctx.index
        ),
    );
    let sim = sims.current().0;
    sim.inject_device_fault(2);
    sim.fault_next_motion(2);
    let op = Op::Wait {
        port: 2,
        kind: WaitKind::Grip(0),
        by: WaitBy::Polling(Duration::from_millis(10)),
    };
    let timeout = Duration::from_millis(1500);
    let waiter = ctx.client.with_timeout(timeout);
    let start = Instant::now();
    // The re-enable shows (ENABLE: `DS_DISABLED`), then the device faults again, its fingers
    // where they were.
    let enable = async {
        tokio::time::sleep(Duration::from_millis(20)).await;
        let enabled = port.enable().await;
        tokio::time::sleep(Duration::from_millis(100)).await;
        sim.inject_device_fault(2);
        enabled
    };
    let mut rng = Prng::new(0);
    let (result, enabled) = tokio::join!(perform(&waiter, &op, &mut rng), enable);
    note(
        &run_wide.trace,
        format!(
            "quiet client {}: fault again: {result:?} (enable {enabled:?})",
            ctx.index
        ),
    );
    run_wide.log.lock().unwrap().push(CallRec {
        client: ctx.index,
        op,
        start,
        end: Instant::now(),
        timeout,
        result: Some(result),
    });
}

/// Rule 10: in the quiet phase one call of every kind (one command each, valid arguments, a
/// device's port) is served: Ok, or the device's own refusal (its state decides, e.g. a GRIP
/// of a faulted gripper), never an error of the client's or the connection's.
async fn quiet_kinds(ctx: &Ctx, run_wide: &RunWide) -> Vec<String> {
    use gripper::griplink::command::Blocking;
    use Command as C;
    let kinds = [
        Op::Typed(C::Id, Render::Str),
        Op::Typed(C::Protocol, Render::Str),
        Op::Typed(C::SerialNumber, Render::Str),
        Op::Typed(C::Version, Render::Str),
        Op::Typed(C::Label, Render::Str),
        Op::Typed(C::DevState(2), Render::State),
        Op::Typed(C::DevName(2), Render::Str),
        Op::Typed(C::Value { port: 0, index: 0 }, Render::Int),
        Op::Typed(C::ValueF { port: 2, index: 0 }, Render::Float),
        Op::Typed(C::GripCfg { port: 0, index: 0 }, Render::Recipe),
        Op::Typed(C::Home(2), Render::Unit),
        Op::Typed(
            C::Release {
                port: 2,
                index: 0,
                blocking: Blocking::Immediate,
            },
            Render::Unit,
        ),
        Op::Execute(C::DevState(0)),
        Op::Raw(C::SerialNumber),
    ];
    let mut out = Vec::new();
    if ctx.lost.load(Ordering::SeqCst) && !ctx.reconnects {
        return out;
    }
    let client = ctx.client.with_timeout(Duration::from_secs(20));
    let mut rng = Prng::new(0);
    for op in kinds {
        let start = Instant::now();
        let result = perform(&client, &op, &mut rng).await;
        note(
            &run_wide.trace,
            format!("quiet client {}: {} -> {result:?}", ctx.index, op.kind()),
        );
        // A reply longer than the client's line limit is discarded, as documented.
        let discarded = matches!(&result, Err(Error::MalformedReply { reason, .. }) if reason.contains("too long"))
            && ctx.client.config().max_line_len < ClientConfig::default().max_line_len;
        let served = matches!(&result, Ok(_) | Err(Error::Device { .. })) || discarded;
        if !served {
            out.push(format!(
                "10 (the quiet phase serves every kind of call): client {} {} ({}) failed in the quiet phase: {result:?}",
                ctx.index,
                op.kind(),
                op.line().unwrap_or_default()
            ));
        }
        run_wide.log.lock().unwrap().push(CallRec {
            client: ctx.index,
            op,
            start,
            end: Instant::now(),
            timeout: Duration::from_secs(20),
            result: Some(result),
        });
    }
    out
}

/// A burst's calls: `op` again with another port or index, so that calls in flight together
/// differ only there (a reply paired with the wrong one shows in its echo).
fn sibling(op: &Op, k: usize) -> Op {
    use Command as C;
    let swap = |p: u8| if k % 2 == 1 { p ^ 2 } else { p };
    let idx = |i: u32| i.wrapping_add(k as u32 / 2) % 4;
    let c = match op {
        Op::Typed(c, _) | Op::Execute(c) | Op::Raw(c) => c.clone(),
        other => return other.clone(),
    };
    let c = match c {
        C::DevState(p) => C::DevState(swap(p)),
        C::DevName(p) => C::DevName(swap(p)),
        C::DevPid(p) => C::DevPid(swap(p)),
        C::DevVid(p) => C::DevVid(swap(p)),
        C::DevTag(p) => C::DevTag(swap(p)),
        C::Value { port, index } => C::Value {
            port: swap(port),
            index: idx(index),
        },
        C::ValueF { port, index } => C::ValueF {
            port: swap(port),
            index: idx(index),
        },
        C::GripCfg { port, index } => C::GripCfg {
            port: swap(port),
            index: idx(index),
        },
        C::GripCfgF { port, index } => C::GripCfgF {
            port: swap(port),
            index: idx(index),
        },
        other => other,
    };
    match op {
        Op::Typed(_, r) => Op::Typed(c, *r),
        Op::Execute(_) => Op::Execute(c),
        _ => Op::Raw(c),
    }
}

async fn caller(ctx: Arc<Ctx>, k: usize, mut rng: Prng, ops: u32, run_wide: Arc<RunWide>) {
    for _ in 0..ops {
        if ctx.closing.load(Ordering::SeqCst) {
            return;
        }
        if rng.one_in(40) {
            ctx.closing.store(true, Ordering::SeqCst);
            let r = ctx.client.close().await;
            note(
                &run_wide.trace,
                format!("client {} caller {k}: close {r:?}", ctx.index),
            );
            return;
        }
        let op = pick(&mut rng, &run_wide.labels);
        // Now and then a burst: up to 5 calls at once that differ only in a port or an index
        // (4 callers of 5: 20 calls in flight on one client).
        let n = if rng.one_in(6) {
            rng.between(2, 5) as usize
        } else {
            1
        };
        let calls: Vec<_> = (0..n)
            .map(|i| {
                let op = if i == 0 { op.clone() } else { sibling(&op, i) };
                let sub = rng.fork();
                one_call(ctx.clone(), k, op, sub, run_wide.clone())
            })
            .collect();
        futures_util::future::join_all(calls).await;
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}

/// One call: its timeout (the handle's, none, or the configured default), made by name,
/// given up now and then, logged for the oracle.
async fn one_call(ctx: Arc<Ctx>, k: usize, op: Op, mut rng: Prng, run_wide: Arc<RunWide>) {
    let handle = match rng.below(30) {
        0 if run_wide.forever => Some(Duration::MAX),
        0..=9 => None,
        _ => Some(rng.millis(20, 5000)),
    };
    let client = match handle {
        Some(t) => ctx.client.with_timeout(t),
        None => ctx.client.clone(),
    };
    let timeout = timeout_of(&op, handle, ctx.client.config());
    let start = Instant::now();
    // Now and then the caller gives up on the call (its future dropped); a call without
    // timeout is given up on only by the guard of rule 8.
    let result = if timeout == Duration::MAX && matches!(op, Op::Wait { .. }) {
        // A wait helper without timeout waits as long as the device gives it no sign (rule 8
        // exempts it, `oracle.rs`), and its own WSTRs keep the controller holding a reply: the
        // guard must not wait on those, or it waits past the run's limit
        // (griplink-tcp:0x89cd105f4b8ce78c: a transition wait on a port that never changes).
        unless_given_up(Some(HELPER_GUARD), perform(&client, &op, &mut rng)).await
    } else if timeout == Duration::MAX {
        unless_hung(perform(&client, &op, &mut rng), &run_wide.sims).await
    } else {
        let cancel = rng.one_in(8).then(|| rng.millis(1, 500));
        unless_given_up(cancel, perform(&client, &op, &mut rng)).await
    };
    let end = Instant::now();
    note(
        &run_wide.trace,
        format!(
            "client {} caller {k}: {} {:?} ({timeout:?}) -> {result:?}",
            ctx.index,
            op.kind(),
            op.line()
        ),
    );
    if timeout == Duration::MAX && result.is_none() {
        note(
            &run_wide.trace,
            format!(
                "8 (a call without timeout ends): client {} {} did not end within {FOREVER_GUARD:?}",
                ctx.index,
                op.kind()
            ),
        );
    }
    run_wide.log.lock().unwrap().push(CallRec {
        client: ctx.index,
        op,
        start,
        end,
        timeout,
        result,
    });
}

impl DocumentedErrors for Error {
    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }

    fn is_connection_lost(&self) -> bool {
        matches!(self, Error::ConnectionLost { .. })
    }
}
