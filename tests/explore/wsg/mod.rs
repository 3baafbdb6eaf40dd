//! The WSG under the explorer: one simulated gripper, one or two clients over TCP, serial or
//! UDP (in memory, through the fault layers), several callers each, a fault phase, a quiet
//! phase (recovery, promise 5; a stop during a motion, promise 3), closing, then the oracle.

mod byte_stream;
mod liveness;
mod oracle;
mod stale;
mod tap;
mod workload;

use std::collections::BTreeSet;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SessionKind, SimConfig, SimEvent, SimServer};
use gripper::wsg::{Client, Status, TransportKind};
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
                index, transport, &mut crng, level, settle, &sim, sim_t0, &faults_on, &trace,
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
    // One run in ten crowds each client with up to five times the callers (20 at full caps):
    // more stops than the client keeps unanswered, more requests than a small queue holds.
    let crowd = rng.one_in(10);
    let callers = if crowd {
        caps.callers * 5
    } else {
        caps.callers
    };
    // Half the crowded runs are stop storms: half of every call a stop, so that more stops of
    // one id go unanswered than the client keeps track of on UDP (issue 29 D, `stops.rs`
    // MAX_UNANSWERED).
    let storm = crowd && rng.one_in(2);
    if crowd {
        note(
            &trace,
            format!("crowd: up to {callers} callers per client, storm {storm}"),
        );
    }
    for ctx in &ctxs {
        ctx.storm.store(storm, Ordering::SeqCst);
    }
    let phase_caps = Caps { callers, ..caps };
    fault_phase(
        &mut rng, phase_caps, &ctxs, caller, restart, &faults_on, &trace,
    )
    .await;

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
            taps: c
                .taps
                .lock()
                .unwrap()
                .iter()
                .map(|(s, log)| (*s, log.lock().unwrap().clone()))
                .collect(),
            max_payload: c.options.max_payload(),
            notes: c.notes.lock().unwrap().clone(),
        })
        .collect();
    let calls = log.calls.lock().unwrap().clone();
    let updates = log.updates.lock().unwrap().clone();
    let mut v = oracle::check(&calls, &updates, &record, sim_t0, &views);
    v.extend(log.notes.lock().unwrap().iter().cloned());
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
    sim_t0: Instant,
    faults_on: &Arc<AtomicBool>,
    trace: &SharedTrace,
) -> ClientCtx {
    let query_timeout = rng.millis(50, 1000);
    // Now and then "no timeout" for motions (issue 29 B: a motion whose final reply is lost
    // must still end, on the probes' evidence).
    let motion_timeout = if rng.one_in(20) {
        Duration::MAX
    } else {
        rng.millis(1000, 10_000)
    };
    let grace = rng.millis(50, 2000).max(settle + Duration::from_millis(50));
    let reconnect = transport != Transport::Udp && rng.one_in(2);
    let announce = transport == Transport::Tcp;
    let mut options = BuilderOptions::draw(rng);
    note(trace, format!("client {index}: {options:?}"));
    if let Some(n) = options.request_queue {
        // A request queue too large for tokio's channel panics as the client starts (a finding,
        // counted by the panic hook as promise 1); that must not end the whole process, so
        // the size is tried on a client of its own first, and the run goes on with the default.
        let (io, _peer) = tokio::io::duplex(64);
        let trial = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            Client::builder().request_queue(n).attach(io)
        }));
        if trial.is_err() {
            note(
                trace,
                format!("client {index}: request_queue({n}) panicked; the default instead"),
            );
            options.request_queue = None;
        }
    }
    let mut b = options.apply(
        Client::builder()
            .query_timeout(query_timeout)
            .motion_timeout(motion_timeout)
            .late_reply_grace(grace)
            .announce_disconnect(announce),
    );
    if rng.one_in(3) {
        b = b.partial_frame_timeout(rng.millis(20, 500));
    }
    if reconnect {
        b = b.reconnect(reconnect_policy());
    }
    // A stream client without reconnect is attached (`ClientBuilder::attach`) one time in two.
    let attach = !reconnect && rng.one_in(2);
    let sessions = Arc::new(Mutex::new(Vec::new()));
    let carried = Arc::new(Mutex::new(Vec::new()));
    let taps = Arc::new(Mutex::new(Vec::new()));
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
            let (sim, on, trace, sessions, carried, taps) = (
                sim.clone(),
                faults_on.clone(),
                trace.clone(),
                sessions.clone(),
                carried.clone(),
                taps.clone(),
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
                let tap = tap::TapLog::new();
                taps.lock().unwrap().push((session, tap.clone()));
                let c = tap::Tap::new(c, tap);
                async move { Ok(c) }
            };
            if attach {
                let io = connect().await.expect("an in-memory connect cannot fail");
                b.attach(io)
            } else {
                b.connect_with(connect)
                    .await
                    .expect("an in-memory connect cannot fail")
            }
        }
    };
    let losses = Arc::new(Mutex::new(Vec::new()));
    workload::watch_losses(&client, losses.clone());
    let expected = if transport == Transport::Udp {
        TransportKind::Udp
    } else {
        TransportKind::Attached
    };
    let mut notes = Vec::new();
    if client.transport() != expected {
        notes.push(format!(
            "2 (each answer is the device's): client {index}'s transport() is {:?}, not {expected:?}",
            client.transport()
        ));
    }
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
        options,
        notes: Mutex::new(notes),
        kinds: Default::default(),
        sim: sim.clone(),
        sim_t0,
        taps,
        storm: AtomicBool::new(false),
    }
}

/// Appended to a quiet-phase violation (promises 3, 5, 10) of a TCP or serial client whose
/// `max_payload_len` is below the length of the echo of its own loop-back barriers
/// ([`BARRIER_ECHO_LEN`]): the client drops every echo, so no barrier completes and an id that
/// waits for one stays held (issue 29 C; since the builder clamps `max_payload_len` to at least
/// that length (fixwsg) it no longer applies, and is kept for a client that would not clamp).
pub const SHORT_OF_BARRIER: &str = "[max_payload_len below the barrier echo's length]";

/// The payload length of a barrier's echo: E_SUCCESS (2 bytes) and the barrier's payload,
/// "gripper barrier " and an 8-byte token (`client/task/recovery.rs`).
pub const BARRIER_ECHO_LEN: usize = 2 + 16 + 8;

/// The builder options a client is opened with besides its timeouts (issue 29: every option
/// drawn, its extremes included).
#[derive(Clone, Copy, Debug)]
pub struct BuilderOptions {
    /// `subscription_buffer` (None: the default).
    pub subscription_buffer: Option<usize>,
    /// `request_queue` (None: the default).
    pub request_queue: Option<usize>,
    /// `max_payload_len` (None: the default).
    pub max_payload_len: Option<usize>,
}

impl BuilderOptions {
    /// The draw: mostly the defaults, then small values, and now and then the extremes.
    fn draw(rng: &mut Prng) -> Self {
        let mut size = |small: u64, extreme: usize| match rng.below(8) {
            0 => Some(rng.between(0, small) as usize),
            1 if rng.one_in(4) => Some(extreme),
            _ => None,
        };
        BuilderOptions {
            subscription_buffer: size(4, usize::MAX),
            request_queue: size(4, usize::MAX),
            // 0 to 64 bytes: below the longest replies (system info, limits) and now and then
            // below the barrier's echo.
            max_payload_len: size(64, usize::MAX),
        }
    }

    /// The builder with these options (and the connect timeout and serial exclusivity, which
    /// an in-memory link ignores).
    fn apply(self, mut b: gripper::wsg::ClientBuilder) -> gripper::wsg::ClientBuilder {
        if let Some(n) = self.subscription_buffer {
            b = b.subscription_buffer(n);
        }
        if let Some(n) = self.request_queue {
            b = b.request_queue(n);
        }
        if let Some(n) = self.max_payload_len {
            b = b.max_payload_len(n);
        }
        b.connect_timeout(Duration::from_secs(1))
            .serial_exclusive(false)
    }

    /// The longest reply payload the client accepts: `max_payload_len` as the builder
    /// documents it, clamped to the barrier echo's length and the frame's 16-bit length field
    /// (issue 29 C, fixed on fixwsg).
    pub fn max_payload(&self) -> usize {
        self.max_payload_len
            .map_or(gripper::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN, |n| {
                n.clamp(BARRIER_ECHO_LEN, usize::from(u16::MAX))
            })
    }
}

/// Promise 5: once the faults stop, a client with reconnect recovers within a bound and its
/// next call succeeds; without reconnect, if it lost its connection, every call fails with
/// ConnectionLost. The bound: a motion's timeout plus the late-reply grace (ids busy with a
/// call that timed out are free again by then) plus the longest reconnect wait, plus the
/// longest stall ([`MAX_STALL`]): one that began just before the faults were turned off holds
/// the bytes for that long afterwards (wsg-serial:0x51f787988b892550: a 2.98 s hold outlasted
/// a 2.3 s bound; a false alarm).
async fn recovery(ctx: &Arc<ClientCtx>, log: &Arc<Log>, trace: &SharedTrace) -> Vec<String> {
    if ctx.closing.load(Ordering::SeqCst) {
        return Vec::new();
    }
    // A motion timeout of Duration::MAX ("none"): its probes begin at the longest motion the
    // workload draws instead (110 mm at 5 mm/s).
    let motion = ctx.motion_timeout.min(Duration::from_secs(23));
    // On UDP a datagram delayed before the faults stopped may come that much later.
    let delayed = Duration::from_millis(crate::core::datagrams::MAX_DELAY_MS);
    let bound =
        motion + ctx.grace + Duration::from_millis(500) + ctx.query_timeout + MAX_STALL + delayed;
    tokio::time::sleep(bound).await;
    let lost = ctx.first_loss().is_some();
    let mut v = Vec::new();
    let start = Instant::now();
    let r = ctx.client.system_info().await;
    note(
        trace,
        format!("recovery client {}: system_info {r:?}", ctx.index),
    );
    let not_sent = || {
        let sessions = ctx.sessions.lock().unwrap().clone();
        let ours = |s| sessions.contains(&s);
        let record = ctx.sim_record();
        let sent = liveness::request_reached(
            &record,
            ctx.sim_t0,
            &ours,
            id::SYSTEM_INFO,
            start,
            Instant::now(),
        );
        if sent {
            ""
        } else {
            liveness::NOT_SENT
        }
    };
    let too_long = || {
        let max = ctx.options.max_payload();
        too_long_reply(&ctx.sim_record(), id::SYSTEM_INFO, Instant::now(), max, ctx)
    };
    match (&r, ctx.reconnect, lost) {
        (Ok(_), _, _) => {}
        (Err(gripper::wsg::Error::ConnectionLost { .. }), false, true) => {}
        (Err(gripper::wsg::Error::Timeout { .. }), _, _) if too_long() => {}
        _ => v.push(format!(
            "5 (recovery): client {} (reconnect {}, lost before: {lost}): {:?} after the faults stopped, the next call (system_info) ended {r:?} {} {}",
            ctx.index, ctx.reconnect, bound, ctx.echo_tag(), not_sent()
        )),
    }
    let end = Instant::now();
    v.extend(every_kind(ctx, log, trace, lost).await);
    // Its answer is checked like any other call's.
    log.calls.lock().unwrap().push(CallRec {
        client: ctx.index,
        who: format!("{}.recovery", ctx.index),
        op: "system_info".into(),
        id: id::SYSTEM_INFO,
        start,
        end,
        limit: Some(ctx.query_timeout),
        bad: false,
        echo: None,
        quiet: true,
        res: match r {
            Ok(_) => Res::Ok(workload::Expect::Success),
            Err(e) => workload::classify(&e),
        },
    });
    v
}

/// Promise 10: in the quiet phase every kind of call the client's callers made is served
/// once more (valid arguments, the client's timeouts, one after the other): it ends on the
/// device's answer, a value or a device status (which promises 2 and 4 judge), not on a
/// `Timeout`, `ReplyLost`, a lost connection or any other error of the client's own. Excused:
/// `ConnectionLost` of a client without reconnect that lost its connection (promise 5), and a
/// `Timeout` whose reply the device sent longer than the client's `max_payload_len` (the
/// documented drop; the oracle sees that reply in the record).
async fn every_kind(
    ctx: &Arc<ClientCtx>,
    log: &Arc<Log>,
    trace: &SharedTrace,
    lost: bool,
) -> Vec<String> {
    let kinds: Vec<u64> = ctx.kinds.lock().unwrap().iter().copied().collect();
    let mut rng = Prng::new(0x5155_4945_5400 ^ ctx.index as u64);
    let mut v = Vec::new();
    for kind in kinds.into_iter().filter(|&k| !workload::is_close(k)) {
        let who = format!("{}.quiet.{kind}", ctx.index);
        let (c2, l2, t2, mut r2) = (ctx.clone(), log.clone(), trace.clone(), rng.fork());
        // In a task of its own: a panic (counted by the hook, promise 1) ends only this call.
        let call = tokio::spawn(async move {
            workload::one_call(&c2, &who, &mut r2, workload::How::Quiet(kind), &l2, &t2).await
        });
        if call.await.is_err() {
            continue;
        }
        let c = log
            .calls
            .lock()
            .unwrap()
            .last()
            .cloned()
            .expect("just logged");
        let served = match &c.res {
            Res::Ok(_) | Res::Device(..) => true,
            Res::Lost => !ctx.reconnect && lost,
            Res::Timeout => {
                let max = ctx.options.max_payload();
                too_long_reply(&ctx.sim_record(), c.id, c.end, max, ctx)
            }
            _ => false,
        };
        if !served {
            let hung = c.res == Res::Hung;
            let sessions = ctx.sessions.lock().unwrap().clone();
            let ours = |s| sessions.contains(&s);
            let record = ctx.sim_record();
            let sent = liveness::request_reached(&record, ctx.sim_t0, &ours, c.id, c.start, c.end);
            let tag = if sent { "" } else { liveness::NOT_SENT };
            v.push(format!(
                "10 (the quiet phase serves every kind of call): client {} {} {} ended {:?} in [{}, {}] after the faults stopped {} {tag}",
                ctx.index, c.who, c.op, c.res, oracle::t(c.start, ctx.sim_t0), oracle::t(c.end, ctx.sim_t0), ctx.echo_tag()
            ));
            if hung {
                break; // A call that never ends may hold the line: the rest would wait as long.
            }
        }
    }
    v
}

/// Whether the device sent client `ctx` a reply of `id` by `end` longer than `max` (status
/// included): one the client drops as documented (`ClientBuilder::max_payload_len`), during
/// the call or before it (the request it answered then keeps the id for its grace, and the
/// call waits behind it). `start` is unused: any such reply before the call may hold it.
fn too_long_reply(
    record: &gripper::wsg::sim::SimRecording,
    id: u8,
    end: Instant,
    max: usize,
    ctx: &ClientCtx,
) -> bool {
    let sessions = ctx.sessions.lock().unwrap().clone();
    record.records.iter().any(|r| {
        let at = ctx.sim_t0 + r.at;
        matches!(&r.event, SimEvent::Reply { id: rid, data, .. } if *rid == id && data.len() + 2 > max)
            && sessions.contains(&r.session)
            && at <= end
    })
}

/// Promise 3, live: with the network quiet, a stop sent while a slow motion runs reaches the
/// device at once (not behind the motion), and the motion ends E_CMD_ABORTED.
async fn stop_is_not_queued(
    ctx: &ClientCtx,
    sim: &SimServer,
    sim_t0: Instant,
    trace: &SharedTrace,
) -> Vec<String> {
    // A motion timeout of the quiet phase's own: the client's may be Duration::MAX (issue 29 B
    // would then hold this check for ever).
    let c = ctx
        .client
        .with_timeouts(ctx.query_timeout, Duration::from_secs(30));
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
            "3 (a stop goes out at once): a stop called during a slow motion on a quiet network reached the device {:?} after the call (stop {stopped:?} after {took:?}) {}",
            other.map(|r| (sim_t0 + r.at).saturating_duration_since(start)), ctx.echo_tag()
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
            "3 (a stop stops): the motion stopped during its run ended {motion:?} {}",
            ctx.echo_tag()
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
