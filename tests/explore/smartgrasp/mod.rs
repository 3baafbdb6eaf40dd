//! SmartGrasp (V3 and V4) under the explorer (issue 21 §3): one simulated Smart Grasping server
//! (its demo project: three parts, grasps, tools 1–3), one or two clients over TCP (in memory,
//! through the fault layer, reconnecting through `Client::open_with` or not), several callers
//! each, a server restart now and then, a quiet phase (recovery), closing, and the oracle.
//!
//! Responses carry no request id: they come back in order, with a response counter (manual
//! 3.2.2.3) and a message type the client checks (`client/pairing.rs`). The oracle checks each
//! answer against the server's record: the response it sent to that request, on that client's
//! connection, during the call.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gripper::reconnect::ReconnectPolicy;
use gripper::smartgrasp::frame::{AnyResponseFrame, FRAME_LEN};
use gripper::smartgrasp::sim::{Fault, SimConfig, SimExchange, SimServer};
use gripper::smartgrasp::types::SelectionCriterion;
use gripper::smartgrasp::{
    Client, ClientConfig, Error, GraspFeedback, GraspMode, GraspRequest, MessageType, PoseFormat,
    Request, Response, Tool,
};
use tokio::time::Instant;

use crate::core::servers::{watch_losses, Servers};
use crate::core::streams::StreamProfile;
use crate::core::{end_fault_phase, note, Caps, Prng, Scenario, SharedTrace};

/// The SmartGrasp scenario.
pub struct SmartGrasp;

/// Entries the simulator records at most (a run stays far below).
const RECORD_CAPACITY: usize = 1 << 20;

/// How late a call may end after its timeout (the task's own bookkeeping; simulated time).
const CALL_SLACK: Duration = Duration::from_millis(10);

impl Scenario for SmartGrasp {
    fn variants(&self) -> &'static [&'static str] {
        &["smartgrasp-v3", "smartgrasp-v4"]
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

/// The server of the moment (a restart replaces it: its connections end with it) and the
/// records of the ones it replaced.
type Sims = Servers<SimServer, Vec<SimExchange>>;

fn new_sim(version: u16) -> Arc<SimServer> {
    let sim = SimServer::in_memory(SimConfig {
        max_version: version,
        ..SimConfig::default()
    });
    sim.start_recording(RECORD_CAPACITY);
    Arc::new(sim)
}

/// One client and what the oracle needs of it.
struct Ctx {
    index: usize,
    client: Client,
    /// Its sessions: (server generation, session number).
    sessions: Arc<Mutex<Vec<(u64, u64)>>>,
    reconnects: bool,
    /// Trusts the response counter (`ClientConfig::strict_response_counter`).
    strict: bool,
    /// Its stream may flip a byte: see [`oracle`].
    corrupts: bool,
    closing: AtomicBool,
    lost: Arc<AtomicBool>,
}

/// One call as the caller saw it.
struct CallRec {
    client: usize,
    request: Request,
    start: Instant,
    end: Instant,
    timeout: Duration,
    result: Result<Response, Error>,
}

async fn run(variant: &'static str, seed: u64, caps: Caps, trace: SharedTrace) -> Vec<String> {
    let version: u16 = if variant.ends_with("v3") { 3 } else { 4 };
    let mut rng = Prng::new(seed);
    let sims: Sims = Servers::new(new_sim(version));
    let faults_on = Arc::new(AtomicBool::new(true));
    let level = rng.between(0, u64::from(caps.faults)) as u32;
    let n_clients = rng.between(1, 2) as usize;
    note(
        &trace,
        format!(
            "run {variant}:{seed:#018x}{} level {level}, {n_clients} clients",
            caps.suffix()
        ),
    );
    let mut violations = Vec::new();
    let mut ctxs = Vec::new();
    for index in 0..n_clients {
        let mut crng = rng.fork();
        let reconnects = crng.one_in(2);
        let strict = crng.one_in(2);
        let random = StreamProfile::random(&mut crng, level, false);
        // Corruption on half the clients only: the frames have no checksum, so a flipped body
        // byte is a value no client can tell from the server's (see `oracle`); the others keep
        // the exact check.
        let corrupts = random.corrupt > 0 && crng.one_in(2);
        let profile = StreamProfile {
            corrupt: if corrupts { random.corrupt } else { 0 },
            ..random
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
            detection_timeout: crng.millis(100, 5000),
            give_up_after: crng.millis(10, 1000),
            connect_timeout: Duration::from_secs(1),
            strict_response_counter: strict,
            project_index: crng.one_in(2).then_some(0),
            reconnect: reconnects.then_some(ReconnectPolicy {
                initial_delay: Duration::from_millis(50),
                max_delay: Duration::from_millis(500),
                factor: 2.0,
                max_attempts: None,
            }),
            ..ClientConfig::default()
        };
        note(&trace, format!("client {index}: {config:?}"));
        // The opening sequence runs through the faults too: a failure there is documented
        // (returned whatever the reconnect policy), and retried like a program would.
        // After 20 failures (short timeouts under heavy faults) the faults stop for this run:
        // opening must then work, and only that failure breaks promise 5.
        let mut client = None;
        for attempt in 0..21 {
            if attempt == 20 {
                note(&trace, "faults off: the opening sequence failed 20 times");
                faults_on.store(false, Ordering::SeqCst);
            }
            match Client::open_with(open.clone(), config.clone()).await {
                Ok(c) => {
                    client = Some(c);
                    break;
                }
                Err(e) => note(
                    &trace,
                    format!("client {index}: open attempt {attempt}: {e}"),
                ),
            }
        }
        let Some(client) = client else {
            violations.push(format!(
                "5 (recovery): client {index} did not open with the faults off"
            ));
            return violations;
        };
        let lost = watch_losses(client.connection_events(), index, trace.clone());
        ctxs.push(Arc::new(Ctx {
            index,
            client,
            sessions,
            reconnects,
            strict,
            corrupts,
            closing: AtomicBool::new(false),
            lost,
        }));
    }

    // The server loses a response now and then: the pairing by order is then out of step,
    // which the client must notice (message type, echoed fields, in strict mode the counter),
    // never pass on as another request's answer. (A call without timeout is then left out: a
    // dropped response would hold it for ever.)
    let drops = if level >= 1 && rng.one_in(2) {
        rng.between(1, 3)
    } else {
        0
    };
    let log = Arc::new(Mutex::new(Vec::<CallRec>::new()));
    let forever = drops == 0;
    let mut callers = Vec::new();
    for ctx in &ctxs {
        let n = rng.between(1, u64::from(caps.callers)) as usize;
        for k in 0..n {
            let ops = rng.between(1, u64::from(caps.ops)) as u32;
            callers.push(tokio::spawn(caller(
                ctx.clone(),
                k,
                rng.fork(),
                ops,
                version,
                forever,
                log.clone(),
                trace.clone(),
            )));
        }
    }
    let restart = (level >= 2 && rng.one_in(4)).then(|| {
        let at = rng.millis(0, 5000);
        sims.restart_at(
            at,
            move || new_sim(version),
            SimServer::recording,
            trace.clone(),
        )
    });
    for _ in 0..drops {
        let at = rng.millis(0, 5000);
        let (sims, trace) = (sims.clone(), trace.clone());
        tokio::spawn(async move {
            tokio::time::sleep(at).await;
            note(&trace, "fault: the server will drop its next response");
            sims.current().0.inject(Fault::DropReply);
        });
    }
    end_fault_phase(callers, restart, &faults_on, &trace).await;

    // Quiet phase: after the recovery bound, a client that reconnects must answer; one that
    // does not must answer or (after a loss) fail with ConnectionLost. Not after a dropped
    // response: in the tolerant default the pairing may stay out of step with no way to see it
    // (same-typed responses) until the oldest call's give-up limit.
    for ctx in &ctxs {
        if ctx.closing.load(Ordering::SeqCst) || drops > 0 {
            continue;
        }
        tokio::time::sleep(Duration::from_secs(5)).await;
        let r = ctx
            .client
            .with_timeout(Duration::from_secs(5))
            .get_state()
            .await;
        note(
            &trace,
            format!("quiet client {}: GET_STATE {r:?}", ctx.index),
        );
        match &r {
            Ok(_) => {}
            Err(Error::ConnectionLost { .. })
                if !ctx.reconnects && ctx.lost.load(Ordering::SeqCst) => {}
            Err(e) => violations.push(format!(
                "5 (recovery): client {} (reconnect {}) failed a call in the quiet phase: {e}",
                ctx.index, ctx.reconnects
            )),
        }
    }
    for ctx in &ctxs {
        ctx.closing.store(true, Ordering::SeqCst);
        let r = ctx
            .client
            .with_timeout(Duration::from_secs(10))
            .close()
            .await;
        note(&trace, format!("close client {}: {r:?}", ctx.index));
        let after = ctx.client.get_state().await;
        // A loss counts if the watcher saw its event, or if close() itself said so: the event
        // of a loss at the instant of the close may not have reached the watcher yet.
        let lost =
            ctx.lost.load(Ordering::SeqCst) || matches!(r, Err(Error::ConnectionLost { .. }));
        let fine = match &after {
            Err(Error::Closed) => true,
            Err(Error::ConnectionLost { .. }) => lost,
            _ => false,
        };
        if !fine {
            violations.push(format!(
                "5 (documented errors): client {} after close(): GET_STATE ended {after:?}, not Error::Closed",
                ctx.index
            ));
        }
    }
    // The oracle needs every server's record; then everything ends.
    let records = sims.all_records(SimServer::recording);
    for (g, rec) in records.iter().enumerate() {
        for e in rec {
            note(
                &trace,
                format!(
                    "sim {g}/{}: {:?} -> {:?}",
                    e.session,
                    e.request,
                    decode(&e.response)
                ),
            );
        }
    }
    let calls = std::mem::take(&mut *log.lock().unwrap());
    violations.extend(oracle(&ctxs, &calls, &records, drops > 0));
    drop(ctxs);
    drop(sims);
    violations
}

/// A random request of the workload: the queries, GET_GRASP in every mode and format the
/// version has, feedback, SET_PROJECT (the demo project 0, or one that does not exist), and
/// in V4 SET_TOOL (tools 1–3 exist, 9 does not).
fn pick(rng: &mut Prng, version: u16) -> Request {
    match rng.below(if version >= 4 { 9 } else { 8 }) {
        0 => Request::GetProtocolVersion,
        1 | 2 => Request::GetState,
        3 => Request::GetObjectCount {
            object_class: rng.below(4) as u16,
        },
        4 | 5 => Request::GetGrasp(GraspRequest {
            grasp_mode: [
                GraspMode::ActiveGrasp,
                GraspMode::AnyGrasp,
                GraspMode::AutoGrasp,
            ][rng.below(3) as usize],
            object_class: rng.below(4) as u16,
            tool: [Tool::Exterior, Tool::Interior][rng.below(2) as usize],
            selection_criterion: SelectionCriterion(rng.between(1, 3) as u8),
            pose_format: if version >= 4 {
                PoseFormat::Abc
            } else {
                [
                    PoseFormat::Quaternion,
                    PoseFormat::AxisAngle,
                    PoseFormat::Wpr,
                    PoseFormat::Abc,
                ][rng.below(4) as usize]
            },
        }),
        6 => Request::GraspFeedback(if rng.one_in(2) {
            GraspFeedback::Ok
        } else {
            GraspFeedback::Bad
        }),
        7 => Request::SetProject {
            project_index: if rng.one_in(4) { 7 } else { 0 },
        },
        _ => Request::SetTool {
            tool_id: if rng.one_in(4) {
                9
            } else {
                rng.between(1, 3) as u16
            },
        },
    }
}

#[allow(clippy::too_many_arguments)]
async fn caller(
    ctx: Arc<Ctx>,
    k: usize,
    mut rng: Prng,
    ops: u32,
    version: u16,
    forever: bool,
    log: Arc<Mutex<Vec<CallRec>>>,
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
        let request = pick(&mut rng, version);
        let timeout = if rng.one_in(30) && forever {
            Duration::MAX
        } else {
            rng.millis(20, 5000)
        };
        let client = ctx.client.with_timeout(timeout);
        let start = Instant::now();
        // Now and then the caller gives up on the call (its future dropped).
        let cancel = rng.one_in(8).then(|| rng.millis(1, 500));
        let result = match cancel {
            Some(after) => tokio::select! {
                // Fixed order (replay); either way the call's future is dropped or done.
                biased;
                r = client.call(request) => Some(r),
                () = tokio::time::sleep(after) => None,
            },
            None => Some(client.call(request).await),
        };
        let end = Instant::now();
        note(
            &trace,
            format!(
                "client {} caller {k}: {request:?} ({timeout:?}) -> {result:?}",
                ctx.index
            ),
        );
        if let Some(result) = result {
            log.lock().unwrap().push(CallRec {
                client: ctx.index,
                request,
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

/// A recorded response, read as the client reads one (`None`: not a whole frame, e.g. the
/// "too old" empty message).
fn decode(bytes: &[u8]) -> Option<Response> {
    let frame: &[u8; FRAME_LEN] = bytes.try_into().ok()?;
    Response::from_any_frame(&AnyResponseFrame::decode(frame)).ok()
}

/// A recorded response read as an answer of type `as_type` (the client reads a V3 type-17
/// response to GET_OBJECT_COUNT as a count: the manual's erratum, `client/pairing.rs`).
fn decode_as(bytes: &[u8], as_type: MessageType) -> Option<Response> {
    let frame: &[u8; FRAME_LEN] = bytes.try_into().ok()?;
    let mut frame = AnyResponseFrame::decode(frame);
    frame.header_mut().message_type = as_type;
    Response::from_any_frame(&frame).ok()
}

/// Whether, in the tolerant pairing, a response to `sent` answers a call of type `call` by its
/// type: the same type, or in V3 a GRASP_FEEDBACK response for a count (the erratum; its echoed
/// class tells them apart only when the count asked for a class, not for 0 = all).
fn same_shape(call: MessageType, sent: MessageType, version: u16) -> bool {
    call == sent
        || (version == 3
            && call == MessageType::GetObjectCount
            && sent == MessageType::GraspFeedback)
}

/// The promises: bounded calls; every answer is one response the server sent to that client,
/// during the call, to that very request (counter included, so it is that one response); one
/// response answers one call; `Closed` only after `close()`.
///
/// What the oracle can and cannot demand:
/// - After a dropped response, in the tolerant default (the counter only recorded: the manual
///   does not say whether it counts per connection), a response of the same type to an earlier
///   request is what no client can tell apart from its own (nor, in V3, a GRASP_FEEDBACK
///   response from a count of all classes: the erratum's type 17). Then the response must still
///   be one the server sent during the call, of a type the call accepts, read as the client
///   reads it ([`same_shape`]). In strict mode the counter tells them apart: exact.
/// - A client whose stream flips bytes: the frames have no checksum (manual 3.2), so a flipped
///   body byte (a count, a pose, a code) reaches the caller as a valid value, and a flipped
///   request byte makes the server answer another request. Then the oracle demands only that
///   some response was sent to that client during the call (one per call): the answer is paired
///   in order, not invented.
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
        let ctx = &ctxs[c.client];
        let bound = c.start.checked_add(c.timeout).map(|t| t + CALL_SLACK);
        if bound.is_some_and(|b| c.end > b) {
            out.push(format!(
                "1 (bounded): client {} {:?} with timeout {:?} took {:?}",
                c.client,
                c.request,
                c.timeout,
                c.end - c.start
            ));
        }
        let answer = match &c.result {
            Ok(r) => r,
            Err(Error::Closed) => {
                if !ctx.closing.load(Ordering::SeqCst) {
                    out.push(format!(
                        "5 (documented errors): client {} {:?} ended Closed without close()",
                        c.client, c.request
                    ));
                }
                continue;
            }
            Err(_) => continue,
        };
        let loose = dropped && !ctx.strict;
        let sessions = ctx.sessions.lock().unwrap().clone();
        let found = sessions.iter().find_map(|&(g, s)| {
            records[g as usize].iter().enumerate().find_map(|(j, e)| {
                let base = e.session == s
                    && e.sent_at >= c.start
                    && e.sent_at <= c.end
                    && !used.contains(&(g, j));
                // Compared as sent: a frame carries only its version's fields (V3 no
                // selection criterion, V4 no tool).
                let exact = || {
                    c.request.to_any_frame(e.request.version()).ok() == Some(e.request)
                        && decode(&e.response).as_ref() == Some(answer)
                };
                let shaped = || {
                    loose
                        && same_shape(
                            c.request.message_type(),
                            e.request.header().message_type,
                            e.request.version(),
                        )
                        && decode_as(&e.response, c.request.message_type()).as_ref() == Some(answer)
                };
                let fits = base && (ctx.corrupts || exact() || shaped());
                fits.then_some((g, j))
            })
        });
        match found {
            Some(k) => {
                used.insert(k);
            }
            None => out.push(format!(
                "2 (the server's answer): client {} {:?} returned {answer:?}, which the server did not send to that request during the call",
                c.client, c.request
            )),
        }
    }
    out
}
