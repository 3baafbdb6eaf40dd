//! SmartGrasp's oracle: the promises of docs/EXPLORER.md, each violation named by its number.
//!
//! 1. *bounded*: every call ends within its timeout + [`CALL_SLACK`].
//! 2. *the server's answer*: every answer (a `Response` from `call`, or what a typed method
//!    made of one) is one response the server sent to that client, during the call, to that
//!    very request, read as sent (counter included); one response answers one call. What it
//!    cannot demand (a dropped response in the tolerant default; a stream that flips bytes): see
//!    [`answers`].
//! 5. *documented errors*: `Closed` only after `close()`.
//! 6. *a connection is lost only for cause*: a loss for an overdue response needs the server
//!    silent (no response reaching the client) for at least `give_up_after` while a request
//!    waited; a loss for a response that broke the protocol needs a reason for one (a dropped
//!    response, a flipped byte).
//! 7. *a Timeout only when its reply did not arrive in time*: a call that timed out must not have
//!    had its response delivered intact to the client before its deadline.
//! 8. *a call without timeout ends*: a `Duration::MAX` call ends (the caller's guard), and not
//!    later than its response's delivery.
//! 10. *the quiet phase serves every kind of call*: checked in `mod.rs`.
//!
//! Rule 9 (a stop is sent at once) has nothing to judge: the Smart Grasping protocol has no stop.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use gripper::smartgrasp::frame::{AnyResponseFrame, FRAME_LEN};
use gripper::smartgrasp::sim::SimExchange;
use gripper::smartgrasp::{
    ClientConfig, Error, GetGraspOutcome, MessageType, ObjectCount, Request, Response,
    ResponseBody, ResponseCode,
};
use tokio::time::Instant;

use crate::core::matching;
use crate::core::servers::{self, session_at, silence_before, SessionRec};

/// How late a call may end after its timeout (the task's own bookkeeping; simulated time).
pub const CALL_SLACK: Duration = Duration::from_millis(10);

/// How much earlier than a call's deadline its response must have reached the client for a
/// `Timeout` to be wrong (a response and the deadline at one instant may go either way).
const DELIVERY_MARGIN: Duration = Duration::from_millis(1);

/// How a call was made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Via {
    /// `Client::call`: the `Response` itself.
    Call,
    /// The request's typed method (`get_state`, `get_grasp`…).
    Typed,
}

/// One call as the caller saw it.
#[derive(Debug)]
pub struct CallRec {
    pub client: usize,
    pub request: Request,
    pub via: Via,
    pub start: Instant,
    pub end: Instant,
    /// Its timeout (`Duration::MAX`: none).
    pub timeout: Duration,
    /// What its method returned (`Debug`), `None` if the caller gave up.
    pub result: Option<Result<String, Error>>,
}

/// What the oracle knows of one client.
pub struct ClientView {
    pub sessions: Vec<SessionRec>,
    pub closing: bool,
    /// Trusts the response counter (`ClientConfig::strict_response_counter`).
    pub strict: bool,
    /// Its stream may flip a byte.
    pub corrupts: bool,
    pub losses: Vec<(Instant, String)>,
    pub give_up_after: Duration,
}

/// The configured timeout of a request's type (`ClientConfig`'s docs).
pub fn configured_timeout(config: &ClientConfig, request: &Request) -> Duration {
    match request.message_type() {
        MessageType::GetGrasp
        | MessageType::GetObjectCount
        | MessageType::SetProject
        | MessageType::SetTool
        | MessageType::SetWorkspace => config.detection_timeout,
        _ => config.query_timeout,
    }
}

/// A recorded response, read as the client reads one (`None`: not a whole frame, e.g. the
/// "too old" empty message).
pub fn decode(bytes: &[u8]) -> Option<Response> {
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

/// A response as the call's method returns it (`Debug`): `Err` with the response code where
/// the typed method makes the code an error (`Error::Device`), `None` where it would fail
/// otherwise.
fn render(c: &CallRec, r: &Response) -> Option<Result<String, ResponseCode>> {
    if c.via == Via::Call {
        return Some(Ok(format!("{r:?}")));
    }
    let success = r.code == ResponseCode::Success;
    Some(match (&c.request, &r.body) {
        // The method hands the pose over in the format asked for (converting where the
        // response carries another: a V4 quaternion, or a same-shaped response of another
        // request after a dropped one).
        (Request::GetGrasp(asked), ResponseBody::Grasp(g)) if success => {
            let mut g = *g;
            g.pose = g.pose.to_format(asked.pose_format).ok()?;
            Ok(format!("{:?}", GetGraspOutcome::Grasp(g)))
        }
        (Request::GetGrasp(_), _) => match r.code {
            ResponseCode::NoObject => Ok(format!("{:?}", GetGraspOutcome::NoObject)),
            ResponseCode::NoGrasp => Ok(format!("{:?}", GetGraspOutcome::NoGrasp)),
            ResponseCode::InvalidObjectClass => {
                Ok(format!("{:?}", GetGraspOutcome::InvalidObjectClass))
            }
            ResponseCode::Success => return None,
            code => Err(code),
        },
        _ if !success => Err(r.code),
        (Request::GetProtocolVersion, ResponseBody::ProtocolVersion(v)) => Ok(format!("{v:?}")),
        (Request::GetState, ResponseBody::State(s)) => Ok(format!("{s:?}")),
        (Request::GetObjectCount { object_class }, ResponseBody::ObjectCount(n)) => {
            let n = ObjectCount {
                object_class: *object_class,
                ..*n
            };
            Ok(format!("{n:?}"))
        }
        (
            Request::RegisterClient(_)
            | Request::SetProject { .. }
            | Request::SetTool { .. }
            | Request::SetWorkspace { .. }
            | Request::GraspFeedback(_)
            | Request::RobotPose(_),
            _,
        ) => Ok("()".into()),
        _ => return None,
    })
}

/// Whether the call's result is `r` read as its method reads it.
fn fits(c: &CallRec, r: Option<Response>) -> bool {
    let Some(r) = r else { return false };
    match (render(c, &r), c.result.as_ref()) {
        (Some(Ok(a)), Some(Ok(b))) => a == *b,
        (Some(Err(code)), Some(Err(Error::Device { status, .. }))) => code == *status,
        _ => false,
    }
}

/// A response the server sent: where, what, and when it reached the client intact.
type Sent<'a> = servers::Sent<'a, SimExchange>;

/// The opening sequence's requests, in their order (`client/session.rs`): a session's records
/// that start with them in this order are the client's own.
const OPENING: [MessageType; 6] = [
    MessageType::GetProtocolVersion,
    MessageType::GetState,
    MessageType::RegisterClient,
    MessageType::SetProject,
    MessageType::SetTool,
    MessageType::SetWorkspace,
];

/// Every response sent on one of `view`'s sessions, in order, with when it was delivered.
fn sent_on<'a>(view: &ClientView, records: &'a [Vec<SimExchange>]) -> Vec<Sent<'a>> {
    servers::sent_on(
        &view.sessions,
        records,
        |e| e.session,
        |e| e.response.len() as u64,
    )
}

/// The keys of the responses to each session's opening sequence (the client's own requests, no
/// caller's): a session's records that start with [`OPENING`]'s requests in that order.
fn openings(sent: &[Sent]) -> BTreeSet<(u64, usize)> {
    let mut out = BTreeSet::new();
    let mut step: BTreeMap<(u64, u64), Option<usize>> = BTreeMap::new();
    for s in sent {
        let k = step.entry((s.gen, s.session)).or_insert(Some(0));
        let t = s.exchange.request.header().message_type;
        *k = k.and_then(|k| OPENING[k..].iter().position(|&o| o == t).map(|p| k + p + 1));
        if k.is_some() {
            out.insert(s.key);
        }
    }
    out
}

/// Whether a call's answer counts as answered (rule 2 judges it).
fn answered(c: &CallRec) -> bool {
    matches!(c.result, Some(Ok(_) | Err(Error::Device { .. })))
}

/// The oracle over every client's calls and every server's record. `dropped`: the server
/// dropped responses in this run.
pub fn judge(
    views: &[ClientView],
    calls: &[CallRec],
    records: &[Vec<SimExchange>],
    dropped: bool,
) -> Vec<String> {
    let mut out = Vec::new();
    let sent: Vec<Vec<Sent>> = views.iter().map(|v| sent_on(v, records)).collect();
    for c in calls {
        let bound = c.start.checked_add(c.timeout).map(|t| t + CALL_SLACK);
        if c.result.is_some() && bound.is_some_and(|b| c.end > b) {
            out.push(format!(
                "1 (bounded): client {} {:?} with timeout {:?} took {:?}",
                c.client,
                c.request,
                c.timeout,
                c.end - c.start
            ));
        }
        if c.timeout == Duration::MAX && c.result.is_none() {
            out.push(format!(
                "8 (a call without timeout ends): client {} {:?} did not end within {:?}",
                c.client,
                c.request,
                c.end - c.start
            ));
        }
        if matches!(c.result, Some(Err(Error::Closed))) && !views[c.client].closing {
            out.push(format!(
                "5 (documented errors): client {} {:?} ended Closed without close()",
                c.client, c.request
            ));
        }
    }
    answers(views, calls, &sent, dropped, &mut out);
    for (i, v) in views.iter().enumerate() {
        losses(i, v, calls, &sent[i], dropped, &mut out);
    }
    timeouts(views, calls, &sent, dropped, &mut out);
    out
}

/// Rule 2, a maximum matching of the answered calls to the responses that fit them.
///
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
fn answers(
    views: &[ClientView],
    calls: &[CallRec],
    sent: &[Vec<Sent>],
    dropped: bool,
    out: &mut Vec<String>,
) {
    let judged: Vec<&CallRec> = calls.iter().filter(|c| answered(c)).collect();
    let edges: Vec<Vec<(u64, usize)>> = judged
        .iter()
        .map(|c| {
            let view = &views[c.client];
            let loose = dropped && !view.strict;
            sent[c.client]
                .iter()
                .filter(|s| {
                    let e = s.exchange;
                    let base = e.sent_at >= c.start && e.sent_at <= c.end;
                    // Compared as sent: a frame carries only its version's fields (V3 no
                    // selection criterion, V4 no tool).
                    let exact = || {
                        c.request.to_any_frame(e.request.version()).ok() == Some(e.request)
                            && fits(c, decode(&e.response))
                    };
                    let shaped = || {
                        loose
                            && same_shape(
                                c.request.message_type(),
                                e.request.header().message_type,
                                e.request.version(),
                            )
                            && fits(c, decode_as(&e.response, c.request.message_type()))
                    };
                    base && (view.corrupts || exact() || shaped())
                })
                .map(|s| s.key)
                .collect()
        })
        .collect();
    let owner = matching::maximum(&edges);
    let matched: BTreeSet<usize> = owner.values().copied().collect();
    for (i, c) in judged.iter().enumerate() {
        if !matched.contains(&i) {
            out.push(format!(
                "2 (the server's answer): client {} {:?} {:?} returned {:?}, which the server did not send to that request during the call",
                c.client, c.via, c.request, c.result
            ));
        }
    }
}

/// Rule 6: each loss client `i` reported.
fn losses(
    i: usize,
    view: &ClientView,
    calls: &[CallRec],
    sent: &[Sent],
    dropped: bool,
    out: &mut Vec<String>,
) {
    for (t, reason) in &view.losses {
        let Some(s) = session_at(&view.sessions, *t) else {
            continue;
        };
        let overdue = reason.contains("the server stopped answering");
        if overdue && !dropped && !view.corrupts {
            let (silence, last) = silence_before(s, sent, *t);
            if silence < view.give_up_after {
                let tag = if behind(i, view, calls, (s.opened, *t, last), reason) {
                    " [the request waited behind another's response; its give-up time counted from when it was sent]"
                } else {
                    ""
                };
                out.push(format!(
                    "6 (a connection is lost only for cause): client {i} declared its connection lost ({reason}) {silence:?} after the server's last response reached it, less than give_up_after {:?}: the server was answering in order{tag}",
                    view.give_up_after
                ));
            }
        } else if !overdue
            && !dropped
            && !view.corrupts
            && !reason.contains("closed the connection")
            && !reason.contains("stopped reading")
        {
            out.push(format!(
                "6 (a connection is lost only for cause): client {i} declared its connection lost ({reason}), but the server dropped no response and the stream flipped no byte"
            ));
        }
    }
}

/// Issue 29 H: whether the loss is the client's documented give-up of a request that waited
/// behind a slow response (which reached the client at `last`, after the request was sent):
/// its give-up time counted from the send (`deadline + give_up_after`), not from when it
/// reached the front.
fn behind(
    i: usize,
    view: &ClientView,
    calls: &[CallRec],
    (opened, t, last): (Instant, Instant, Instant),
    reason: &str,
) -> bool {
    // The client's own marker query (GET_PROTOCOL_VERSION or GET_STATE, sent before a call of
    // the type of an abandoned request, `client/in_flight.rs` `marker_before`) is no caller's: it
    // counts when a call it may have preceded was sent before the last response and got none.
    let marker = ["GET_PROTOCOL_VERSION", "GET_STATE"]
        .iter()
        .any(|m| reason.contains(&format!("no response to {m} ")));
    calls.iter().any(|c| {
        c.client == i
            && c.start < last
            && c.end >= opened
            && !answered(c)
            && (marker
                || (reason.contains(&format!("no response to {} ", c.request.message_type()))
                    && c.start
                        .checked_add(c.timeout)
                        .and_then(|d| d.checked_add(view.give_up_after))
                        .is_some_and(|g| g <= t + DELIVERY_MARGIN)))
    })
}

/// Rules 7 and 8: a call that timed out (or, without a timeout, ended late) while its response
/// had reached the client intact in time: a response to the call's own request (the same
/// frame), sent and delivered during the call, in a run without dropped responses, to a client
/// whose stream flips no byte, and no other call of the client with the same request overlapped.
fn timeouts(
    views: &[ClientView],
    calls: &[CallRec],
    sent: &[Vec<Sent>],
    dropped: bool,
    out: &mut Vec<String>,
) {
    if dropped {
        return;
    }
    let opening: Vec<BTreeSet<(u64, usize)>> = sent.iter().map(|s| openings(s)).collect();
    for c in calls {
        if views[c.client].corrupts {
            continue;
        }
        let forever = c.timeout == Duration::MAX;
        let timed_out = matches!(c.result, Some(Err(Error::Timeout { .. })));
        if !timed_out && !forever {
            continue;
        }
        let deadline = c.start.checked_add(c.timeout);
        let found = sent[c.client].iter().find(|s| {
            let Some(d) = s.delivered else { return false };
            let e = s.exchange;
            // The client sends GET_PROTOCOL_VERSION or GET_STATE on its own as a marker behind
            // an abandoned request (`client/in_flight.rs`): then any call overlapping counts.
            let marker = matches!(
                e.request.header().message_type,
                MessageType::GetProtocolVersion | MessageType::GetState
            );
            // Another call that may have sent that request: one overlapping, or an earlier one
            // that got no answer (its response may still have been on its way).
            let others = calls.iter().any(|o| {
                !std::ptr::eq(o, c)
                    && o.client == c.client
                    && o.start <= d
                    && (o.end >= c.start || !answered(o))
                    && (marker
                        || o.request.to_any_frame(e.request.version()).ok() == Some(e.request))
            });
            !opening[c.client].contains(&s.key)
                && c.request.to_any_frame(e.request.version()).ok() == Some(e.request)
                && e.sent_at >= c.start
                && deadline.is_none_or(|dl| d + DELIVERY_MARGIN < dl)
                && decode(&e.response).is_some()
                && !others
        });
        let Some(s) = found else { continue };
        let d = s.delivered.expect("found");
        if timed_out {
            out.push(format!(
                "7 (a Timeout only when its reply did not arrive in time): client {} {:?} {:?} with timeout {:?} ended {:?}, but its response reached the client intact {:?} after the call began",
                c.client,
                c.via,
                c.request,
                c.timeout,
                c.result,
                d - c.start
            ));
        } else if c.end > d + CALL_SLACK && c.result.is_some() {
            out.push(format!(
                "8 (a call without timeout ends): client {} {:?} {:?} without timeout ended {:?} after its response reached the client",
                c.client,
                c.via,
                c.request,
                c.end - d
            ));
        }
    }
}
