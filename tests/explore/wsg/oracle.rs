//! The WSG oracle: checks what the callers got against what the simulator recorded. Each
//! violation names the promise of issue 20 it breaks (1–5).

use std::collections::BTreeSet;
use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{SessionId, SessionKind, SimEvent, SimRecording};
use gripper::wsg::{Status, SystemState};
use tokio::time::Instant;

use super::byte_stream::{passed_crc_damaged, reply_lost_on_streams, DAMAGED_PASSED_CRC};
use super::stale;
use super::workload::{CallRec, Expect, Res, Update};
use crate::core::datagrams::Faulted;
use crate::core::streams::Carried;

/// How far past its timeout a call may end (promise 1): the client fails a call at its
/// deadline, so this only absorbs the hand-over from the connection task to the caller.
pub const CALL_SLACK: Duration = Duration::from_millis(10);

/// One reply the device sent to one client (or a copy the fault layer delivered).
pub struct Sent {
    /// When the device sent it (a faulted copy: when it was delivered).
    pub at: Instant,
    /// For a faulted copy: when the device sent it.
    pub origin: Option<Origin>,
    /// The command id.
    pub id: u8,
    /// Its status.
    pub status: Status,
    /// Its data after the status.
    pub data: Vec<u8>,
    moving: bool,
}

/// Where a faulted copy came from.
#[derive(Clone, Copy)]
pub struct Origin {
    /// When the device sent it.
    pub sent: Instant,
    /// The link delivered it twice (this is one of the two copies).
    pub duplicated: bool,
}

/// What one client is, for the oracle.
pub struct ClientView {
    /// Its sessions.
    pub sessions: BTreeSet<SessionId>,
    /// It reconnects after a loss.
    pub reconnect: bool,
    /// When it first reported a lost connection.
    pub first_loss: Option<Instant>,
    /// Every instant it reported a lost connection.
    pub losses: Vec<Instant>,
    /// Its late-reply grace.
    pub grace: Duration,
    /// Its query timeout (the reply hold of `Pairing::set_holds`).
    pub query_timeout: Duration,
    /// The reply datagrams the fault layer delivered to it duplicated or delayed (UDP; empty
    /// on streams).
    pub faulted: Vec<Faulted>,
    /// The request datagrams the fault layer delivered from it duplicated or delayed.
    pub faulted_requests: Vec<Faulted>,
    /// Per stream session (TCP, serial), what the link did with the bytes the device sent it
    /// (empty on UDP).
    pub carried: Vec<(SessionId, Carried)>,
    /// Per stream connection (TCP, serial), what the client's end saw (`tap.rs`).
    pub taps: Vec<(SessionId, super::tap::TapLog)>,
    /// The longest reply payload it accepts (`max_payload_len`).
    pub max_payload: usize,
    /// Violations seen directly (accessors' answers).
    pub notes: Vec<String>,
}

/// Appended to a promise 2, 3 or 4 violation whose answer fits a reply datagram the fault
/// layer delivered to the client duplicated or delayed during the call: the documented
/// residual risk of UDP (no sequence numbers), which `known.txt` may name for `wsg-udp` only.
pub const FROM_FAULTED: &str = "[fits a duplicated or delayed datagram delivered during the call]";

/// Appended to a promise 2 violation whose call fits a reply the device sent, which the matching
/// gave to another call that may itself have taken a duplicated or delayed datagram (the
/// matching has no item for such a copy): the UDP residual of that other call, seen here.
pub const DISPLACED: &str =
    "[its reply went to a call that fits a duplicated or delayed datagram delivered during it]";

/// Appended to a promise 2 violation of a streamed id's call none of whose requests reached the
/// device intact before the call ended (a corrupted or cut request; the client answers only
/// after the echo of a loop-back sent after the request, so a request that was not lost was
/// received before): its answer was a frame of the device's stream, which cannot be told from
/// a reply (manual 1.4). The residual risk of the
/// client's barrier rule for streamed ids, which `known.txt` may name for TCP and serial.
pub const NO_REQUEST: &str = "[no request of this streamed id reached the device during the call]";

/// The replies among `faulted` datagrams, decoded as the client decodes them (manual 1.2.2:
/// the payload starts with the 16-bit status code, little endian).
fn faulted_replies(faulted: &[Faulted]) -> Vec<Sent> {
    let mut out = Vec::new();
    for copy in faulted {
        let mut buf = bytes::BytesMut::from(&copy.bytes[..]);
        while let Some(decoded) =
            gripper::wsg::frame::decode(&mut buf, gripper::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN)
        {
            let gripper::wsg::frame::Decoded::Frame(f) = decoded else {
                continue;
            };
            if f.payload.len() < 2 {
                continue;
            }
            out.push(Sent {
                at: copy.at,
                origin: Some(Origin {
                    sent: copy.sent,
                    duplicated: copy.duplicated,
                }),
                id: f.id,
                status: Status::from_code(u16::from_le_bytes([f.payload[0], f.payload[1]])),
                data: f.payload[2..].to_vec(),
                moving: false,
            });
        }
    }
    out
}

/// `at` as microseconds since `t0`, as the trace prints it.
pub fn t(at: Instant, t0: Instant) -> String {
    format!("{}us", at.saturating_duration_since(t0).as_micros())
}

/// Every violation found.
pub fn check(
    calls: &[CallRec],
    updates: &[Update],
    record: &SimRecording,
    sim_t0: Instant,
    clients: &[ClientView],
) -> Vec<String> {
    let mut v = Vec::new();
    if record.dropped != 0 {
        v.push(format!(
            "explorer: the simulator's record lost {} entries (raise its capacity)",
            record.dropped
        ));
    }
    for (ci, view) in clients.iter().enumerate() {
        let mine: Vec<&CallRec> = calls.iter().filter(|c| c.client == ci).collect();
        v.extend(check_client(&mine, updates, record, sim_t0, ci, view));
    }
    v
}

fn check_client(
    calls: &[&CallRec],
    updates: &[Update],
    record: &SimRecording,
    t0: Instant,
    ci: usize,
    view: &ClientView,
) -> Vec<String> {
    let mut v = Vec::new();
    let ours = |s: SessionId| view.sessions.contains(&s);
    let sent: Vec<Sent> = record
        .records
        .iter()
        .enumerate()
        .filter(|(_, r)| ours(r.session))
        .filter_map(|(i, r)| match &r.event {
            SimEvent::Reply {
                id,
                status,
                data,
                moving,
            } => Some(Sent {
                at: t0 + r.at,
                origin: None,
                id: *id,
                status: *status,
                data: data.to_vec(),
                moving: *moving && !moving_is_the_next_motion(record, i),
            }),
            _ => None,
        })
        .collect();
    let udp = record.records.iter().any(|r| {
        ours(r.session)
            && matches!(
                r.event,
                SimEvent::Connected {
                    kind: SessionKind::Udp
                }
            )
    });
    let close_start = calls
        .iter()
        .filter(|c| c.op == "close")
        .map(|c| c.start)
        .min();
    let first_lost = view.first_loss;
    let faulted = faulted_replies(&view.faulted);
    let stale = stale::Context {
        calls,
        record,
        t0,
        view,
        faulted: &faulted,
    };

    for c in calls {
        // 1: bounded.
        if let (Some(limit), false) = (c.limit, c.res == Res::Cancelled) {
            let took = c.end - c.start;
            if took > limit + CALL_SLACK {
                v.push(format!(
                    "1 (every call ends within its timeout + {CALL_SLACK:?}): {} {} took {took:?} with a timeout of {limit:?} and ended {:?}",
                    c.who, c.op, c.res
                ));
            }
        }
        match &c.res {
            Res::Other(e) => v.push(format!("2 (no wrong answer): {} {} failed with {e}", c.who, c.op)),
            Res::Invalid if !c.bad => v.push(format!(
                "2 (no wrong answer): {} {} failed with InvalidArgument, but its arguments are valid",
                c.who, c.op
            )),
            r if c.bad && !matches!(r, Res::Invalid | Res::Cancelled) => v.push(format!(
                "2 (bad input is a typed error): {} {} was called with an invalid argument and ended {r:?}, not InvalidArgument",
                c.who, c.op
            )),
            Res::Closed if close_start.is_none_or(|s| c.end < s) => v.push(format!(
                "5 (documented errors): {} {} got Error::Closed at {} but close() was never called before it (a lost connection is ConnectionLost)",
                c.who, c.op, t(c.end, t0)
            )),
            _ => {}
        }
        // 5: without reconnect, every call after a loss fails with ConnectionLost.
        if let (false, Some(lost)) = (view.reconnect, first_lost) {
            let fine = matches!(
                c.res,
                Res::Lost | Res::Cancelled | Res::Closed | Res::Conflict | Res::Invalid
            );
            if c.start > lost && !fine {
                v.push(format!(
                    "5 (documented errors): client {ci} lost its connection at {} (no reconnect), yet {} {} then ended {:?}",
                    t(lost, t0), c.who, c.op, c.res
                ));
            }
        }
    }

    // 2, 3, 4: each answer is one reply the device sent to this client during the call; one
    // reply answers one call (a maximum matching: a greedy pass may give a call the only reply
    // another call fits).
    // close() while the client reconnects (in a backoff wait or an attempt) ends Ok with no
    // disconnect announced: there is no connection to send it on (the close() docs, issue 30:
    // the supervisor's close request). Such a close, ended after a loss with no session opened
    // since, answers nothing of the device's (wsg-tcp:0x29ecd0fe15482184: the cut at 502 ms,
    // the close() at that instant).
    let connected: Vec<Instant> = record
        .records
        .iter()
        .filter(|r| ours(r.session) && matches!(r.event, SimEvent::Connected { .. }))
        .map(|r| t0 + r.at)
        .collect();
    let closed_unconnected = |c: &CallRec| {
        c.op == "close"
            && view.reconnect
            && view
                .losses
                .iter()
                .any(|&lost| lost <= c.end && !connected.iter().any(|&at| at > lost && at <= c.end))
    };
    let answered: Vec<&CallRec> = calls
        .iter()
        .copied()
        .filter(|c| answered(c) && !closed_unconnected(c))
        .collect();
    let mut windows = Vec::with_capacity(answered.len());
    for c in &answered {
        // A streamed id's auto-updates share the reply's id and form (manual 1.4): on a byte
        // stream its answer must have been sent once the device had received a request of it
        // during the call (the client answers with a frame sent after its request, reply or
        // later update), not an update sent before. The earliest such request bounds it (this
        // call's or earlier). UDP keeps the next frame (documented residual risk).
        let strict = is_streamed(c.id) && !udp;
        let received = strict
            .then(|| first_request(record, t0, c.id, c.start, &ours))
            .flatten()
            .filter(|&(i, at)| {
                at < c.end || !next_calls_request(calls, c, (record, &sent), t0, i, &ours)
            })
            .map(|(_, at)| at);
        let not_before = match received {
            Some(at) => at,
            None if strict => c.end + Duration::from_nanos(1),
            None => c.start,
        };
        windows.push((strict, received, not_before));
    }
    let candidates = |i: usize| -> Vec<usize> {
        let (c, (_, _, not_before)) = (answered[i], windows[i]);
        (0..sent.len())
            .filter(|&k| sent[k].at >= not_before && sent[k].at <= c.end && fits(c, &sent[k]))
            .collect()
    };
    // A stop reply may serve several stop calls: promise 3 asks for a stop the device
    // processed during the call (sent at or after it), and one stop sent after two calls began
    // is that for both (the client completes every call whose first stop is not later than the
    // one answered: `src/wsg/client/stops.rs`). Only stop calls match stop replies, so no other
    // call can share one: they stay out of the matching.
    let shared = |c: &CallRec| c.id == id::STOP || c.id == id::FAST_STOP;
    let edges: Vec<Vec<usize>> = (0..answered.len())
        .map(|i| {
            if shared(answered[i]) {
                Vec::new()
            } else {
                candidates(i)
            }
        })
        .collect();
    let owner = crate::core::matching::maximum(&edges);
    let matched: BTreeSet<usize> = owner.values().copied().collect();
    for (i, c) in answered.iter().copied().enumerate() {
        let ok = if shared(c) {
            !candidates(i).is_empty()
        } else {
            matched.contains(&i)
        };
        if ok {
            continue;
        }
        let (strict, received, _) = windows[i];
        // Whether call `o` may have taken a faulted copy delivered during it, beyond the
        // client's rule (the documented UDP residual).
        let took_faulted = |o: &CallRec| {
            (0..faulted.len()).any(|k| {
                let s = &faulted[k];
                s.at >= o.start
                    && s.at <= o.end
                    && fits(o, s)
                    && stale::beyond_the_rule(&stale, k, o)
            })
        };
        // Displaced: a genuine reply it fits went, in the matching, to another call that may
        // itself have taken a faulted copy; the matching has no item for the copy, so that call
        // took the reply this one needed (wsg-udp:0x2853d243948c6cd4: a delayed grip state 6
        // answered a subscribe, whose window held the one genuine 0x41 reply, the 7 of the
        // grip_state after it).
        // Not when it fits a faulted copy the client's rule should have kept from it (planted
        // bug 1's mistake): that copy, not the displacement, may be what it took.
        let within_rule = (0..faulted.len()).any(|k| {
            let s = &faulted[k];
            s.at >= c.start && s.at <= c.end && fits(c, s) && !stale::beyond_the_rule(&stale, k, c)
        });
        let displaced = !within_rule
            && candidates(i)
                .iter()
                .filter_map(|e| owner.get(e))
                .any(|&j| took_faulted(answered[j]));
        let window = format!("[{}, {}]", t(c.start, t0), t(c.end, t0));
        let tag = if took_faulted(c) {
            FROM_FAULTED
        } else if displaced {
            DISPLACED
        } else if strict && received.is_none_or(|at| at >= c.end) {
            NO_REQUEST
        } else if answer(c).is_some_and(|r| passed_crc_damaged(record, view, &r, c.end)) {
            DAMAGED_PASSED_CRC
        } else {
            ""
        };
        match &c.res {
            Res::Device(cmd, Status::AlreadyRunning) => {
                if !motion_running(record, t0, c.start, c.end) {
                    // The client refuses on a probe's SF_MOVING (or passes the device's own
                    // refusal on): a stale copy of either is what it may have taken.
                    let stale = faulted.iter().any(|s| {
                        s.at >= c.start
                            && s.at <= c.end
                            && (s.id == *cmd && s.status == Status::AlreadyRunning
                                || s.id == id::SYSTEM_STATE
                                    && s.status == Status::Success
                                    && SystemState::decode(&s.data)
                                        .is_ok_and(|f| f.contains(SystemState::MOVING)))
                    });
                    let tag = if stale { FROM_FAULTED } else { "" };
                    v.push(format!(
                        "4 (a status is the device's): {} {} got E_ALREADY_RUNNING in {window}, but the device sent none and was executing no motion at the call {tag}",
                        c.who, c.op
                    ));
                }
            }
            Res::Ok(Expect::Motion)
                if sent.iter().any(|s| s.id == c.id && s.status == Status::Success && s.at >= c.start && s.at <= c.end) =>
            {
                v.push(format!(
                    "4 (a completed motion has stopped): {} {} returned Ok in {window} on a final reply sent while the fingers were moving {tag}",
                    c.who, c.op
                ));
            }
            Res::Ok(Expect::Success) if c.id == id::STOP || c.id == id::FAST_STOP => v.push(format!(
                "3 (stop Ok only if the device processed a stop sent at or after the call): {} {} returned Ok in {window}, but no {:#04x} reply of this client in that window was left unpaired {tag}",
                c.who, c.op, c.id
            )),
            _ => v.push(format!(
                "2 (each answer is the device's answer to that request): {} {} ended {:?} in {window}, but the device sent no such reply (left unpaired) to this client in that window {tag}",
                c.who, c.op, c.res
            )),
        }
    }
    // ReplyLost: the client gave the final reply up only after the device acknowledged the
    // motion (E_CMD_PENDING) during the call.
    for c in calls.iter().filter(|c| matches!(c.res, Res::ReplyLost(_))) {
        let Res::ReplyLost(cmd) = c.res else { continue };
        let acked = sent.iter().any(|s| {
            s.id == cmd && s.status == Status::CmdPending && s.at >= c.start && s.at <= c.end
        });
        if !acked {
            // A stale copy of an earlier E_CMD_PENDING of that id may have been taken for the
            // acknowledgement (UDP).
            let stale = faulted.iter().any(|s| {
                s.id == cmd && s.status == Status::CmdPending && s.at >= c.start && s.at <= c.end
            });
            let tag = if stale { FROM_FAULTED } else { "" };
            v.push(format!(
                "4 (a status is the device's): {} {} ended ReplyLost, but the device acknowledged no {cmd:#04x} of this client during the call {tag}",
                c.who, c.op
            ));
        }
    }
    v.extend(reply_lost_on_streams(calls, record, t0, view, close_start));
    v.extend(super::liveness::check(
        calls,
        record,
        t0,
        view,
        udp,
        close_start,
    ));
    v.extend(view.notes.iter().cloned());
    // An update may be any value of that id the device sent this client before it was
    // received: a stream shared by several subscribers (3.4.1: one stream per value) may hand a
    // new one a value sent just before it subscribed, which is still the device's.
    for u in updates.iter().filter(|u| u.client == ci) {
        let ok = sent.iter().any(|s| {
            s.id == u.id && s.status == Status::Success && s.data == u.data && s.at <= u.at
        });
        if !ok {
            let reply = gripper::wsg::Reply::new(u.id, Status::Success, u.data.clone());
            let tag = if passed_crc_damaged(record, view, &reply, u.at) {
                DAMAGED_PASSED_CRC
            } else {
                ""
            };
            v.push(format!(
                "2 (each answer is the device's): client {ci} received an auto-update {:02x?} of {:#04x} at {} that the device never sent it {tag}",
                u.data, u.id, t(u.at, t0)
            ));
        }
    }
    v
}

/// The reply frame call `c` ended on, as far as its result tells (a command's plain E_SUCCESS
/// and a device error are taken to carry no data, as the simulator sends them).
fn answer(c: &CallRec) -> Option<gripper::wsg::Reply> {
    let (cmd, status, data) = match &c.res {
        Res::Ok(Expect::Exact(st, d)) => (c.id, *st, d.clone()),
        Res::Ok(Expect::Data(d)) => (c.id, Status::Success, d.clone()),
        Res::Ok(Expect::Success | Expect::Motion) => (c.id, Status::Success, Vec::new()),
        Res::Device(cmd, st) => (*cmd, *st, Vec::new()),
        _ => return None,
    };
    Some(gripper::wsg::Reply::new(cmd, status, data))
}

/// Whether reply `s` carries what call `c` returned.
fn fits(c: &CallRec, s: &Sent) -> bool {
    match &c.res {
        Res::Ok(Expect::Success) => s.id == c.id && s.status == Status::Success,
        Res::Ok(Expect::Data(d)) => s.id == c.id && s.status == Status::Success && s.data == *d,
        Res::Ok(Expect::Motion) => s.id == c.id && s.status == Status::Success && !s.moving,
        Res::Ok(Expect::Exact(st, d)) => s.id == c.id && s.status == *st && s.data == *d,
        Res::Device(cmd, st) => s.id == *cmd && s.status == *st,
        _ => false,
    }
}

/// Whether the device may have been executing a motion during `[start, end]` (manual 3.2.2:
/// E_ALREADY_RUNNING means the module *is* executing a motion, whichever client started it):
/// one acknowledged (E_CMD_PENDING) before `start` without its final reply or a restart before
/// `start` (records at the very instant `start` may come before or after the call, so they do
/// not count against it), or one acknowledged during the call.
fn motion_running(record: &SimRecording, t0: Instant, start: Instant, end: Instant) -> bool {
    let mut running: BTreeSet<(SessionId, u8)> = BTreeSet::new();
    for r in &record.records {
        let at = t0 + r.at;
        if at > end {
            break;
        }
        match &r.event {
            SimEvent::Restarted if at < start => running.clear(),
            SimEvent::Reply { id, status, .. } if is_motion(*id) => {
                if *status == Status::CmdPending {
                    if at >= start {
                        return true;
                    }
                    running.insert((r.session, *id));
                } else if at < start && *status != Status::AlreadyRunning {
                    // E_ALREADY_RUNNING refuses a duplicate; it does not end the motion.
                    running.remove(&(r.session, *id));
                }
            }
            _ => {}
        }
    }
    !running.is_empty()
}

/// Whether the `moving` of reply `i` may be a motion the device started after producing it:
/// the simulator samples its fingers when it queues the replies of one step, and in one step it
/// may first end a motion (its final reply, due then) and then start the motion of a request
/// received at that instant (recorded before the reply, acknowledged after it). That reply was
/// produced with the fingers stopped; what they did afterwards is the next motion's.
fn moving_is_the_next_motion(record: &SimRecording, i: usize) -> bool {
    let at = record.records[i].at;
    let same_step = |r: &&gripper::wsg::sim::SimRecord| r.at == at;
    let requested: BTreeSet<u8> = record.records[..i]
        .iter()
        .rev()
        .take_while(same_step)
        .filter_map(|r| match r.event {
            SimEvent::Request { id, .. } if is_motion(id) => Some(id),
            _ => None,
        })
        .collect();
    record.records[i + 1..]
        .iter()
        .take_while(same_step)
        .any(|r| matches!(r.event, SimEvent::Reply { id, status: Status::CmdPending, .. } if requested.contains(&id)))
}

/// The first intact request of `id` the device received from this client at or after
/// `start`: its record index and when.
fn first_request(
    record: &SimRecording,
    t0: Instant,
    id: u8,
    start: Instant,
    ours: &impl Fn(SessionId) -> bool,
) -> Option<(usize, Instant)> {
    record
        .records
        .iter()
        .enumerate()
        .find_map(|(i, r)| match &r.event {
            SimEvent::Request {
                id: rid,
                corrupt: false,
                ..
            } if *rid == id && ours(r.session) && t0 + r.at >= start => Some((i, t0 + r.at)),
            _ => None,
        })
}

/// Whether call `c` ended on an answer of the device (a value, a status): one reply of the
/// device must account for it.
fn answered(c: &CallRec) -> bool {
    matches!(c.res, Res::Device(..)) || matches!(&c.res, Res::Ok(e) if *e != Expect::Nothing)
}

/// Whether request `i` of `c`'s id, received at the very instant `c` ended, may be the request
/// of a later call of the id on this client rather than `c`'s own: the calls of the id that had
/// begun by then (not before `c`), were still going and ended on an answer of the device cannot
/// each have another intact request of the id within their time (one request per call; a
/// call of a streamed id sends its request only once the previous one of the id is off the
/// wire, `c` ending at that instant included). The record's instants do not order the client's
/// steps within one instant, so at that instant the request may be either's; it goes to the
/// later calls if they need it. (`c` then counts as a call whose request did not reach the
/// device: its request was corrupted, and the stream's frame it got is the documented
/// residual, tagged [`NO_REQUEST`]. `wsg-tcp:0x8f85c166eeff961d`: a width query whose request
/// was corrupted ended on its barrier's echo at the instant the next width query's request,
/// rewritten to the stream's flags, reached the device, and took that query's reply in the
/// matching; `wsg-serial:0x7cf70070d2357529`: the same with a subscription and a width query
/// after it, two calls and one request after that instant.) A later call can use only a
/// request before the last frame fitting its answer (its answer is sent after its request): a
/// request of the id at its very end after that (the client's own request turning the updates
/// off) is not its own (`wsg-serial:0x9db67a1a2ae25add`: the later call was left unpaired, and
/// the call whose request was corrupted went untagged).
fn next_calls_request(
    calls: &[&CallRec],
    c: &CallRec,
    (record, sent): (&SimRecording, &[Sent]),
    t0: Instant,
    i: usize,
    ours: &impl Fn(SessionId) -> bool,
) -> bool {
    let at = t0 + record.records[i].at;
    let later: Vec<&CallRec> = calls
        .iter()
        .copied()
        .filter(|b| {
            !std::ptr::eq(*b, c)
                && b.id == c.id
                && b.start >= c.start
                && b.start <= at
                && b.end >= at
                && answered(b)
        })
        .collect();
    // Each later call, until the last frame fitting its answer (none: it claims no request).
    let last_fit = |b: &CallRec| {
        sent.iter()
            .filter(|s| s.at >= b.start && s.at <= b.end && fits(b, s))
            .map(|s| s.at)
            .max()
    };
    let mut later: Vec<(&CallRec, Instant)> = later
        .into_iter()
        .filter_map(|b| Some((b, last_fit(b)?)))
        .collect();
    later.sort_by_key(|&(_, until)| until);
    // The other intact requests of the id from this client: earliest end first, each takes the
    // earliest one within its time (for intervals this finds an assignment if one exists).
    let mut others: Vec<Instant> = record
        .records
        .iter()
        .enumerate()
        .filter(|(k, r)| {
            *k != i
                && ours(r.session)
                && matches!(r.event, SimEvent::Request { id, corrupt: false, .. } if id == c.id)
        })
        .map(|(_, r)| t0 + r.at)
        .collect();
    later.iter().any(
        |&(b, until)| match others.iter().position(|&t| t >= b.start && t <= until) {
            Some(k) => {
                others.remove(k);
                false
            }
            None => true,
        },
    )
}

/// Ids with auto-updates (manual 3.4.1, 3.4.2, 3.4.4–3.4.6).
pub fn is_streamed(id: u8) -> bool {
    matches!(
        id,
        id::SYSTEM_STATE | id::GRIP_STATE | id::WIDTH | id::SPEED | id::FORCE
    )
}

/// Motion commands (manual 3.2.1, 3.2.2, 3.2.6, 3.2.7).
pub fn is_motion(id: u8) -> bool {
    matches!(id, id::HOMING | id::PRE_POSITION | id::GRASP | id::RELEASE)
}
