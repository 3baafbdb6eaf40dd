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

use gripper::smartgrasp::frame::{AnyResponseFrame, FRAME_LEN};
use gripper::smartgrasp::sim::{Fault, SimConfig, SimExchange, SimServer};
use gripper::smartgrasp::types::SelectionCriterion;
use gripper::smartgrasp::{
    Client, ClientConfig, Error, GraspFeedback, GraspMode, GraspRequest, MessageType, PoseFormat,
    Request, Response, Tool,
};
use tokio::time::Instant;

use crate::core::phases::{
    draw_restart, draw_shape, fault_phase, open_retrying, reconnect_policy, run_line,
    unless_given_up, DocumentedErrors,
};
use crate::core::servers::{
    close_and_check, draw_drops, quiet_call, watch_losses, Servers, Sessions,
};
use crate::core::streams::StreamProfile;
use crate::core::{note, Caps, Prng, Scenario, SharedTrace};

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
    /// Its sessions.
    sessions: Sessions,
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
    let (level, n_clients) = draw_shape(&mut rng, caps);
    note(&trace, run_line(variant, seed, caps, level, n_clients));
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
            reconnect: reconnects.then(reconnect_policy),
            ..ClientConfig::default()
        };
        // The opening sequence runs through the faults too (SET_PROJECT, GET_PROTOCOL_VERSION).
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
    let drops = draw_drops(&mut rng, level);
    let log = Arc::new(Mutex::new(Vec::<CallRec>::new()));
    let forever = drops == 0;
    let caller = |ctx: &Arc<Ctx>, k, rng, ops| {
        let (log, trace) = (log.clone(), trace.clone());
        caller(ctx.clone(), k, rng, ops, version, forever, log, trace)
    };
    let faults = |rng: &mut Prng| {
        let fresh = move || new_sim(version);
        let restart = draw_restart(rng, level, |at| {
            sims.restart_at(at, fresh, SimServer::recording, trace.clone())
        });
        let what = "fault: the server will drop its next response";
        sims.drop_replies(rng, drops, &trace, what, |sim| sim.inject(Fault::DropReply));
        restart
    };
    fault_phase(&mut rng, caps, &ctxs, caller, faults, &faults_on, &trace).await;

    // Quiet phase: after the recovery bound, a client that reconnects must answer; one that
    // does not must answer or (after a loss) fail with ConnectionLost. Not after a dropped
    // response: in the tolerant default the pairing may stay out of step with no way to see it
    // (same-typed responses) until the oldest call's give-up limit.
    for ctx in &ctxs {
        if ctx.closing.load(Ordering::SeqCst) || drops > 0 {
            continue;
        }
        let quiet = quiet_call(
            ctx.index,
            ctx.reconnects,
            &ctx.lost,
            "GET_STATE",
            &trace,
            || async {
                ctx.client
                    .with_timeout(Duration::from_secs(5))
                    .get_state()
                    .await
            },
        );
        violations.extend(quiet.await);
    }
    for ctx in &ctxs {
        ctx.closing.store(true, Ordering::SeqCst);
        let within = ctx.client.with_timeout(Duration::from_secs(10));
        let close = within.close();
        let (index, lost) = (ctx.index, &ctx.lost);
        let closed = close_and_check(index, "GET_STATE", lost, true, &trace, close, || async {
            ctx.client.get_state().await
        });
        violations.extend(closed.await);
    }
    // The oracle needs every server's record; then everything ends.
    let records = sims.all_records_noted(SimServer::recording, &trace, |e: &SimExchange| {
        let response = decode(&e.response);
        format!("{}: {:?} -> {response:?}", e.session, e.request)
    });
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
        let result = unless_given_up(cancel, client.call(request)).await;
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
        let found = sessions.iter().find_map(|rec| {
            let (g, s) = (rec.gen, rec.session);
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

impl DocumentedErrors for Error {
    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }

    fn is_connection_lost(&self) -> bool {
        matches!(self, Error::ConnectionLost { .. })
    }
}
