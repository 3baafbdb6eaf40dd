//! GRIPLINK under the explorer (issue 21 §3): one simulated controller (ET4, a part between the
//! fingers on port 0, real-time motion under the paused clock), one or two clients over TCP (in
//! memory, through the fault layer, reconnecting through `Client::open_with` or not), several
//! callers each, a controller restart now and then, a quiet phase (recovery), closing, and the
//! oracle. GRIPLINK has no sequence numbers: replies pair with commands by order (manual 2.1),
//! which is what the oracle checks, reply by reply.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::griplink::command::{Blocking, Command, Expect};
use gripper::griplink::reply::interpret;
use gripper::griplink::sim::{Fault, SimConfig, SimExchange, SimServer};
use gripper::griplink::{Answer, Client, ClientConfig, Error};
use tokio::time::Instant;

use crate::core::phases::{
    draw_restart, draw_shape, fault_phase, open_retrying, reconnect_policy, run_line,
    unless_given_up, DocumentedErrors,
};
use crate::core::servers::{close_and_check, draw_drops, quiet_call, watch_losses, Servers};
use crate::core::streams::StreamProfile;
use crate::core::{note, Caps, Prng, Scenario, SharedTrace};

/// The GRIPLINK scenario.
pub struct Griplink;

/// Entries the simulator records at most (a run stays far below).
const RECORD_CAPACITY: usize = 1 << 20;

/// How late a call may end after its timeout (the task's own bookkeeping; simulated time).
const CALL_SLACK: Duration = Duration::from_millis(10);

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
    /// Its sessions: (controller generation, session number).
    sessions: Arc<Mutex<Vec<(u64, u64)>>>,
    reconnects: bool,
    closing: AtomicBool,
    lost: Arc<AtomicBool>,
}

/// What every caller of a run shares.
struct RunWide {
    /// Numbers the labels set (unique values: an answer names its request).
    labels: AtomicU64,
    /// Whether a call may have no timeout (not in runs where the controller drops replies).
    forever: bool,
}

/// One call as the caller saw it.
struct CallRec {
    client: usize,
    line: String,
    /// The reply shape the command expects.
    expect: Expect,
    start: Instant,
    end: Instant,
    timeout: Duration,
    result: Result<Answer, Error>,
}

async fn run(variant: &'static str, seed: u64, caps: Caps, trace: SharedTrace) -> Vec<String> {
    let mut rng = Prng::new(seed);
    let sims: Sims = Servers::new(new_sim());
    let faults_on = Arc::new(AtomicBool::new(true));
    let (level, n_clients) = draw_shape(&mut rng, caps);
    note(&trace, run_line(variant, seed, caps, level, n_clients));
    let mut violations = Vec::new();
    let mut ctxs = Vec::new();
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
        let sessions = Arc::new(Mutex::new(Vec::new()));
        let open = sims.opener(
            index,
            crng.fork(),
            profile,
            faults_on.clone(),
            trace.clone(),
            sessions.clone(),
            |sim, io| sim.serve_stream(io),
        );
        let config = ClientConfig {
            query_timeout: crng.millis(50, 2000),
            motion_timeout: crng.millis(500, 10_000),
            give_up_after: crng.millis(10, 1000),
            connect_timeout: Duration::from_secs(1),
            pipeline_depth: crng.between(1, 4) as usize,
            reconnect: reconnects.then(reconnect_policy),
            ..ClientConfig::default()
        };
        let opened = open_retrying(index, &config, &faults_on, &trace, || {
            Client::open_with(open.clone(), config.clone())
        });
        let client = match opened.await {
            Ok(client) => client,
            Err(violation) => return vec![violation],
        };
        let lost = watch_losses(client.connection_events(), index, trace.clone());
        ctxs.push(Arc::new(Ctx {
            index,
            client,
            sessions,
            reconnects,
            closing: AtomicBool::new(false),
            lost,
        }));
    }

    // The controller loses a reply now and then (a real controller's bug, or a test's): the
    // pairing by order is then out of step, which the client must notice by the reply's shape
    // and repair with a probe (client/pipeline.rs), never pass on as another command's answer.
    // (A call without timeout is then left out: a dropped reply would hold it forever.)
    let drops = draw_drops(&mut rng, level);
    let log = Arc::new(Mutex::new(Vec::<CallRec>::new()));
    let run_wide = Arc::new(RunWide {
        labels: AtomicU64::new(0),
        forever: drops == 0,
    });
    let caller = |ctx: &Arc<Ctx>, k, rng, ops| {
        let (log, run_wide, trace) = (log.clone(), run_wide.clone(), trace.clone());
        caller(ctx.clone(), k, rng, ops, log, run_wide, trace)
    };
    let faults = |rng: &mut Prng| {
        let restart = draw_restart(rng, level, |at| {
            sims.restart_at(at, new_sim, SimServer::recording, trace.clone())
        });
        let what = "fault: the controller will drop its next reply";
        sims.drop_replies(rng, drops, &trace, what, |sim| sim.inject(Fault::DropReply));
        restart
    };
    fault_phase(&mut rng, caps, &ctxs, caller, faults, &faults_on, &trace).await;

    // Quiet phase: after the recovery bound, a client that reconnects must answer; one that
    // does not must answer or (after a loss) fail with ConnectionLost. Not after a dropped
    // reply: the pairing may be out of step with no way to see it (same-shaped replies) until
    // the oldest call's give-up limit, which a call without timeout does not have.
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
    let calls = std::mem::take(&mut *log.lock().unwrap());
    violations.extend(oracle(&ctxs, &calls, &records, drops > 0));
    drop(ctxs);
    drop(sims);
    violations
}

/// A random call of the workload: its command.
fn pick(rng: &mut Prng, labels: &AtomicU64) -> Command {
    match rng.below(10) {
        0 => Command::Id,
        1 => Command::SerialNumber,
        2 => Command::Label,
        3 => Command::SetLabel(format!("L{}", labels.fetch_add(1, Ordering::SeqCst))),
        4 => Command::DevState(0),
        5 => Command::Value { port: 0, index: 0 },
        6 => Command::Home(0),
        7 => Command::Grip {
            port: 0,
            index: 0,
            blocking: blocking(rng),
        },
        8 => Command::Release {
            port: 0,
            index: 0,
            blocking: blocking(rng),
        },
        _ => Command::Version,
    }
}

/// Blocking (the reply waits for the end of the motion) or not, at random.
fn blocking(rng: &mut Prng) -> Blocking {
    if rng.one_in(2) {
        Blocking::UntilDone
    } else {
        Blocking::Immediate
    }
}

async fn caller(
    ctx: Arc<Ctx>,
    k: usize,
    mut rng: Prng,
    ops: u32,
    log: Arc<Mutex<Vec<CallRec>>>,
    run_wide: Arc<RunWide>,
    trace: SharedTrace,
) {
    for _ in 0..ops {
        if ctx.closing.load(Ordering::SeqCst) {
            return;
        }
        if rng.one_in(40) {
            ctx.closing.store(true, Ordering::SeqCst);
            let r = ctx.client.close().await;
            note(
                &trace,
                format!("client {} caller {k}: close {r:?}", ctx.index),
            );
            return;
        }
        let command = pick(&mut rng, &run_wide.labels);
        let Ok(line) = command.encode() else { continue };
        let timeout = if rng.one_in(30) && run_wide.forever {
            Duration::MAX
        } else {
            rng.millis(20, 5000)
        };
        let client = ctx.client.with_timeout(timeout);
        let start = Instant::now();
        // Now and then the caller gives up on the call (its future dropped).
        let cancel = rng.one_in(8).then(|| rng.millis(1, 500));
        let result = unless_given_up(cancel, client.execute(&command)).await;
        let end = Instant::now();
        note(
            &trace,
            format!(
                "client {} caller {k}: {line} ({timeout:?}) -> {result:?}",
                ctx.index
            ),
        );
        if let Some(result) = result {
            log.lock().unwrap().push(CallRec {
                client: ctx.index,
                line,
                expect: command.expect(),
                start,
                end,
                timeout,
                result,
            });
        }
        if rng.one_in(3) {
            tokio::time::sleep(rng.millis(0, 300)).await;
        }
    }
}

/// The promises: bounded calls; every answer (a value, or a status the controller reported) is
/// one reply the controller sent to that client, during the call, to that very command line;
/// one reply answers one call; `Closed` only after `close()`.
///
/// When the controller dropped a reply, a later reply of the same shape answering an earlier
/// command is something no client can tell (GRIPLINK has no sequence numbers): then a reply
/// counts if it was sent to that client during the call and, read as the call's own command
/// expects, gives the same answer (the shape check is what the client can and must do).
fn oracle(
    ctxs: &[Arc<Ctx>],
    calls: &[CallRec],
    records: &[Vec<SimExchange>],
    dropped: bool,
) -> Vec<String> {
    let mut out = Vec::new();
    let mut used = std::collections::BTreeSet::new();
    // Earliest end first: a greedy match is then exact for intervals.
    let mut order: Vec<usize> = (0..calls.len()).collect();
    order.sort_by_key(|&i| (calls[i].end, i));
    for i in order {
        let c = &calls[i];
        let bound = c.start.checked_add(c.timeout).map(|t| t + CALL_SLACK);
        if bound.is_some_and(|b| c.end > b) {
            out.push(format!(
                "1 (bounded): client {} {} with timeout {:?} took {:?}",
                c.client,
                c.line,
                c.timeout,
                c.end - c.start
            ));
        }
        let answered = match &c.result {
            Ok(_) | Err(Error::Device { .. }) => true,
            Err(Error::Closed) => {
                if !ctxs[c.client].closing.load(Ordering::SeqCst) {
                    out.push(format!(
                        "5 (documented errors): client {} {} ended Closed without close()",
                        c.client, c.line
                    ));
                }
                false
            }
            _ => false,
        };
        if !answered {
            continue;
        }
        let sessions = ctxs[c.client].sessions.lock().unwrap().clone();
        let found = sessions.iter().find_map(|&(g, s)| {
            records[g as usize].iter().enumerate().find_map(|(j, e)| {
                let fits = e.session == s
                    && (e.request == c.line || dropped)
                    && e.sent_at >= c.start
                    && e.sent_at <= c.end
                    && !used.contains(&(g, j))
                    && same(&interpret(&c.line, c.expect, &e.reply), &c.result);
                fits.then_some((g, j))
            })
        });
        match found {
            Some(k) => {
                used.insert(k);
            }
            None => out.push(format!(
                "2 (the controller's answer): client {} {} returned {:?}, which the controller did not send to that command during the call",
                c.client, c.line, c.result
            )),
        }
    }
    out
}

/// The same answer: equal values, or the same device status.
fn same(a: &Result<Answer, Error>, b: &Result<Answer, Error>) -> bool {
    match (a, b) {
        (Ok(x), Ok(y)) => x == y,
        (Err(x), Err(y)) => x.status().is_some() && x.status() == y.status(),
        _ => false,
    }
}

impl DocumentedErrors for Error {
    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }

    fn is_connection_lost(&self) -> bool {
        matches!(self, Error::ConnectionLost { .. })
    }
}
