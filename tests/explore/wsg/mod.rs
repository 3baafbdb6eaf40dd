//! The WSG under the explorer: one simulated gripper, one or two clients over TCP, serial or
//! UDP (in memory, through the fault layers), several callers each, a fault phase, a quiet
//! phase (recovery, promise 5; a stop during a motion, promise 3), closing, then the oracle.

mod byte_stream;
mod oracle;
mod stale;
mod workload;

use std::collections::BTreeSet;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SessionKind, SimConfig, SimEvent, SimServer};
use gripper::wsg::{Client, Status};
use tokio::time::Instant;

use self::oracle::ClientView;
use self::workload::{CallRec, ClientCtx, Log, Res};
use crate::core::datagrams::{faulty_datagrams, DatagramProfile};
use crate::core::phases::{
    after_close, draw_restart, draw_shape, fault_phase, reconnect_policy, run_line,
    DocumentedErrors,
};
use crate::core::streams::{faulty_pipe_logged, StreamProfile, MAX_STALL};
use crate::core::{note, restart_at, Caps, Prng, Scenario, SharedTrace};

/// The WSG scenario.
pub struct Wsg;

/// Entries the simulator records at most (a run stays far below).
const RECORD_CAPACITY: usize = 1 << 20;

impl Scenario for Wsg {
    fn variants(&self) -> &'static [&'static str] {
        &["wsg-tcp", "wsg-serial", "wsg-udp"]
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

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Transport {
    Tcp,
    Serial,
    Udp,
}

async fn run(variant: &'static str, seed: u64, caps: Caps, trace: SharedTrace) -> Vec<String> {
    let transport = match variant {
        "wsg-tcp" => Transport::Tcp,
        "wsg-serial" => Transport::Serial,
        _ => Transport::Udp,
    };
    let mut rng = Prng::new(seed);
    let sim_t0 = Instant::now();
    // The final reply of a motion comes this long after its fingers stopped (SF_MOVING already
    // clear, Anhang B): one "not moving" is no proof that a move is over. Every client's grace
    // is longer, as the pairing's two-probe rule needs (`pairing.rs`).
    let mut config = SimConfig::new(Model::Wsg50)
        .with_part(40.0, 2.0)
        .with_time_scale(1.0);
    config.final_reply_lag = rng.millis(0, 300);
    let settle = config.final_reply_lag;
    let sim = Arc::new(SimServer::in_memory(config));
    sim.start_recording(RECORD_CAPACITY);
    let faults_on = Arc::new(AtomicBool::new(true));
    let (level, n_clients) = draw_shape(&mut rng, caps);
    note(&trace, run_line(variant, seed, caps, level, n_clients));

    let mut ctxs = Vec::new();
    for index in 0..n_clients {
        let mut crng = rng.fork();
        ctxs.push(Arc::new(
            open_client(
                index, transport, &mut crng, level, settle, &sim, &faults_on, &trace,
            )
            .await,
        ));
    }

    // The fault phase: every caller runs its calls; a device restart now and then.
    let log = Arc::new(Log::default());
    let caller = |ctx: &Arc<ClientCtx>, k, rng, ops| {
        workload::caller(ctx.clone(), k, rng, ops, log.clone(), trace.clone())
    };
    let restart = |rng: &mut Prng| {
        draw_restart(rng, level, |at| {
            let sim = sim.clone();
            restart_at(at, &trace, move || sim.restart())
        })
    };
    fault_phase(&mut rng, caps, &ctxs, caller, restart, &faults_on, &trace).await;

    // The quiet phase.
    let mut quiet = Vec::new();
    for ctx in &ctxs {
        quiet.extend(recovery(ctx, &log, &trace).await);
    }
    if let Some(ctx) = ctxs.iter().find(|c| !c.closing.load(Ordering::SeqCst)) {
        quiet.extend(stop_is_not_queued(ctx, &sim, sim_t0, &trace).await);
    }
    for ctx in &ctxs {
        if !ctx.closing.swap(true, Ordering::SeqCst) {
            let lost = ctx.first_loss().is_some();
            let r = ctx.client.close().await;
            note(&trace, format!("close client {}: {r:?}", ctx.index));
            let after = ctx.client.width_mm().await;
            // After a loss, ConnectionLost stays a fair answer (the connection is gone either way).
            quiet.extend(after_close(ctx.index, "width_mm()", &after, lost));
        }
    }

    let record = note_record(&sim, &trace);
    let views: Vec<ClientView> = ctxs
        .iter()
        .map(|c| ClientView {
            sessions: c
                .sessions
                .lock()
                .unwrap()
                .iter()
                .copied()
                .collect::<BTreeSet<_>>(),
            reconnect: c.reconnect,
            first_loss: c.first_loss(),
            losses: c.losses.lock().unwrap().clone(),
            grace: c.grace,
            query_timeout: c.query_timeout,
            faulted: c.faulted.lock().unwrap().clone(),
            faulted_requests: c.faulted_requests.lock().unwrap().clone(),
            carried: c
                .carried
                .lock()
                .unwrap()
                .iter()
                .map(|(s, log)| (*s, log.lock().unwrap().clone()))
                .collect(),
        })
        .collect();
    let calls = log.calls.lock().unwrap().clone();
    let updates = log.updates.lock().unwrap().clone();
    let mut v = oracle::check(&calls, &updates, &record, sim_t0, &views);
    v.extend(quiet);
    drop(ctxs);
    drop(sim);
    v
}

// The run's draws and handles, each needed once here: a struct would only rename them.
#[allow(clippy::too_many_arguments)]
async fn open_client(
    index: usize,
    transport: Transport,
    rng: &mut Prng,
    level: u32,
    settle: Duration,
    sim: &Arc<SimServer>,
    faults_on: &Arc<AtomicBool>,
    trace: &SharedTrace,
) -> ClientCtx {
    let query_timeout = rng.millis(50, 1000);
    let motion_timeout = rng.millis(1000, 10_000);
    let grace = rng.millis(50, 2000).max(settle + Duration::from_millis(50));
    let reconnect = transport != Transport::Udp && rng.one_in(2);
    let announce = transport == Transport::Tcp;
    let mut b = Client::builder()
        .query_timeout(query_timeout)
        .motion_timeout(motion_timeout)
        .late_reply_grace(grace)
        .announce_disconnect(announce);
    if rng.one_in(3) {
        b = b.partial_frame_timeout(rng.millis(20, 500));
    }
    if reconnect {
        b = b.reconnect(reconnect_policy());
    }
    let sessions = Arc::new(Mutex::new(Vec::new()));
    let carried = Arc::new(Mutex::new(Vec::new()));
    let faulted: crate::core::datagrams::FaultedLog = Default::default();
    let faulted_requests: crate::core::datagrams::FaultedLog = Default::default();
    let label = format!("client {index}");
    note(trace, format!("{label}: {transport:?} query {query_timeout:?} motion {motion_timeout:?} grace {grace:?} reconnect {reconnect}"));
    let client = match transport {
        Transport::Udp => {
            let profile = DatagramProfile::random(rng, level);
            note(trace, format!("{label}: {profile:?}"));
            let (up_tx, up_rx) = faulty_datagrams(
                rng,
                profile,
                faults_on.clone(),
                trace.clone(),
                format!("{label} c>s"),
                faulted_requests.clone(),
            );
            let (down_tx, down_rx) = faulty_datagrams(
                rng,
                profile,
                faults_on.clone(),
                trace.clone(),
                format!("{label} s>c"),
                faulted.clone(),
            );
            sessions
                .lock()
                .unwrap()
                .push(sim.serve_datagrams(up_rx, down_tx));
            b.attach_datagrams(up_tx, down_rx)
        }
        Transport::Tcp | Transport::Serial => {
            let serial = transport == Transport::Serial;
            let kind = if serial {
                SessionKind::Serial
            } else {
                SessionKind::Tcp
            };
            let profile = StreamProfile::random(rng, level, serial);
            note(trace, format!("{label}: {profile:?}"));
            let net = Arc::new(Mutex::new(rng.fork()));
            let (sim, on, trace, sessions, carried) = (
                sim.clone(),
                faults_on.clone(),
                trace.clone(),
                sessions.clone(),
                carried.clone(),
            );
            let connect = move || {
                let mut rng = net.lock().unwrap();
                let down = crate::core::streams::CarriedLog::default();
                let (c, s) = faulty_pipe_logged(
                    &mut rng,
                    profile,
                    on.clone(),
                    trace.clone(),
                    label.clone(),
                    Some(down.clone()),
                );
                let session = sim.serve_stream(s, kind);
                note(&trace, format!("{label}: connected as session {session}"));
                sessions.lock().unwrap().push(session);
                carried.lock().unwrap().push((session, down));
                async move { Ok(c) }
            };
            b.connect_with(connect)
                .await
                .expect("an in-memory connect cannot fail")
        }
    };
    let losses = Arc::new(Mutex::new(Vec::new()));
    workload::watch_losses(&client, losses.clone());
    ClientCtx {
        index,
        losses,
        faulted,
        faulted_requests,
        carried,
        client,
        sessions,
        reconnect,
        announce,
        closing: AtomicBool::new(false),
        query_timeout,
        motion_timeout,
        grace,
    }
}

/// Promise 5: once the faults stop, a client with reconnect recovers within a bound and its
/// next call succeeds; without reconnect, if it lost its connection, every call fails with
/// ConnectionLost. The bound: a motion's timeout plus the late-reply grace (ids busy with a
/// call that timed out are free again by then) plus the longest reconnect wait, plus the
/// longest stall ([`MAX_STALL`]): one that began just before the faults were turned off holds
/// the bytes for that long afterwards (wsg-serial:0x51f787988b892550: a 2.98 s hold outlasted
/// a 2.3 s bound; a false alarm).
async fn recovery(ctx: &ClientCtx, log: &Log, trace: &SharedTrace) -> Vec<String> {
    if ctx.closing.load(Ordering::SeqCst) {
        return Vec::new();
    }
    let bound =
        ctx.motion_timeout + ctx.grace + Duration::from_millis(500) + ctx.query_timeout + MAX_STALL;
    tokio::time::sleep(bound).await;
    let lost = ctx.first_loss().is_some();
    let mut v = Vec::new();
    let start = Instant::now();
    let r = ctx.client.system_info().await;
    note(
        trace,
        format!("recovery client {}: system_info {r:?}", ctx.index),
    );
    match (&r, ctx.reconnect, lost) {
        (Ok(_), _, _) => {}
        (Err(gripper::wsg::Error::ConnectionLost { .. }), false, true) => {}
        _ => v.push(format!(
            "5 (recovery): client {} (reconnect {}, lost before: {lost}): {:?} after the faults stopped, the next call (system_info) ended {r:?}",
            ctx.index, ctx.reconnect, bound
        )),
    }
    let end = Instant::now();
    // Its answer is checked like any other call's.
    log.calls.lock().unwrap().push(CallRec {
        client: ctx.index,
        who: format!("{}.recovery", ctx.index),
        op: "system_info".into(),
        id: id::SYSTEM_INFO,
        start,
        end,
        limit: Some(ctx.query_timeout),
        res: match r {
            Ok(_) => Res::Ok(workload::Expect::Success),
            Err(e) => workload::classify(&e),
        },
    });
    v
}

/// Promise 3, live: with the network quiet, a stop sent while a slow motion runs reaches the
/// device at once (not behind the motion), and the motion ends E_CMD_ABORTED.
async fn stop_is_not_queued(
    ctx: &ClientCtx,
    sim: &SimServer,
    sim_t0: Instant,
    trace: &SharedTrace,
) -> Vec<String> {
    let c = ctx.client.clone();
    let losses_before = ctx.losses.lock().unwrap().len();
    let _ = c.acknowledge_fast_stop().await;
    if c.home(gripper::wsg::HomingDirection::Default)
        .await
        .is_err()
    {
        return Vec::new();
    }
    let width = c.width_mm().await.unwrap_or(0.0);
    let target = if width > 55.0 { 5.0 } else { 105.0 };
    let mover = c.clone();
    let motion_start = Instant::now();
    let motion = tokio::spawn(async move { mover.pre_position(target, 5.0).await });
    tokio::time::sleep(Duration::from_millis(100)).await;
    let start = Instant::now();
    let stopped = c.stop().await;
    let took = start.elapsed();
    let motion = motion.await;
    note(
        trace,
        format!("stop check: stop {stopped:?} after {took:?}, motion {motion:?}"),
    );
    let rec = sim.recording();
    let stop_seen = rec.records.iter().find(|r| {
        sim_t0 + r.at >= start && matches!(r.event, SimEvent::Request { id: id::STOP, .. })
    });
    let mut v = Vec::new();
    // A connection that ended meanwhile (a half-close from the fault phase reaching its end,
    // say) makes this no test of the stop's queueing: its calls fail or wait for a reconnect.
    if ctx.losses.lock().unwrap().len() != losses_before {
        return v;
    }
    let pending = rec.records.iter().any(|r| {
        matches!(
            r.event,
            SimEvent::Reply {
                id: id::PRE_POSITION,
                status: Status::CmdPending,
                ..
            }
        ) && sim_t0 + r.at >= motion_start
            && sim_t0 + r.at < start
    });
    if !pending {
        return v; // The motion never started (e.g. refused): nothing to stop.
    }
    match stop_seen {
        Some(r) if sim_t0 + r.at <= start + Duration::from_millis(1) => {}
        other => v.push(format!(
            "3 (a stop goes out at once): a stop called during a slow motion on a quiet network reached the device {:?} after the call (stop {stopped:?} after {took:?})",
            other.map(|r| (sim_t0 + r.at).saturating_duration_since(start))
        )),
    }
    if !matches!(
        motion,
        Ok(Err(gripper::wsg::Error::Device {
            status: Status::CmdAborted,
            ..
        }))
    ) {
        v.push(format!(
            "3 (a stop stops): the motion stopped during its run ended {motion:?}"
        ));
    }
    v
}

impl DocumentedErrors for gripper::wsg::Error {
    fn is_closed(&self) -> bool {
        matches!(self, gripper::wsg::Error::Closed)
    }

    fn is_connection_lost(&self) -> bool {
        matches!(self, gripper::wsg::Error::ConnectionLost { .. })
    }
}

/// The simulator's whole record, into the trace (the digest covers it) and for the oracle; the
/// text interface's scenario (`wsg_text`) records the same simulator.
pub fn note_record(sim: &SimServer, trace: &SharedTrace) -> gripper::wsg::sim::SimRecording {
    let record = sim.recording();
    for r in &record.records {
        note(
            trace,
            format!("sim {}us {} {:?}", r.at.as_micros(), r.session, r.event),
        );
    }
    record
}
