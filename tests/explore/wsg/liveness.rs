//! The WSG oracle's rules on errors and liveness (issue 29), numbered as for every protocol:
//! 6 (a connection is lost only for cause), 7 (a Timeout only when its reply did not arrive in
//! time), 8 (a call without timeout ends, and frees what it held) and 9 (a stop is sent at
//! once, faults or not). Rule 10 (the quiet phase serves every kind of call) lives with the
//! quiet phase (`mod.rs`, `every_kind`).

use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{SimEvent, SimRecording};
use gripper::wsg::Status;
use tokio::time::Instant;

use super::byte_stream::delivered_intact;
use super::oracle::{is_motion, t, ClientView, CALL_SLACK};
use super::tap::written_frames;
use super::workload::{CallRec, Res, NEVER_ENDS};

/// How soon after a stop call its stop frame must be written (promise 9): at once, in
/// simulated time; this only absorbs the hand-over from the caller to the connection task.
const AT_ONCE: Duration = Duration::from_millis(1);

/// Appended to a violation of rules 5, 8 or 10 (a call that never ended, or timed out, after
/// the faults stopped) when no request of the call's id reached the device during the call:
/// the client held the id (an earlier request's, a fence waiting for a barrier). Issue 29 B, C
/// and the stuck fences of the WSG report (`known.txt`); a call whose request did reach the
/// device and still failed is not tagged.
pub const NOT_SENT: &str = "[no request of its id reached the device during the call]";

/// Appended to a rule 8 violation when the device answered the call's requests with replies
/// longer than the client's `max_payload_len` (status included), which the client drops as
/// documented: with no timeout, a call whose every reply is dropped never ends (a
/// `max_payload_len` below 2 drops every reply; issue 29 C asks for a clear error or a clamp).
pub const TOO_LONG: &str = "[its replies are longer than max_payload_len]";

/// Appended to a rule 8 violation when the device acknowledged the call's command
/// (E_CMD_PENDING) during the call: a motion or finger power on whose final reply did not end
/// it (issue 29 B: the probes' next step is scheduled at the never-deadline).
pub const ACKNOWLEDGED: &str = "[the device acknowledged it during the call]";

/// Appended to a rule 8 violation when the device answered the call's request with a final
/// status (a refusal, say) during the call and the call still never ended: its answer was lost
/// on the way, and the client, holding the id for it, never gave the call up (issue 29 B's
/// kind: a call without timeout never ends, its id stays held).
pub const ANSWERED: &str = "[the device answered it during the call]";

/// Whether the device received a request of `id` (intact or not) from one of `ours` sessions
/// in `[start, end]`.
pub fn request_reached(
    record: &SimRecording,
    t0: Instant,
    ours: &impl Fn(gripper::wsg::sim::SessionId) -> bool,
    id: u8,
    start: Instant,
    end: Instant,
) -> bool {
    let of_id = |e: &SimEvent| matches!(e, SimEvent::Request { id: rid, .. } if *rid == id);
    recorded(record, t0, ours, start, end, of_id)
}

/// Whether the simulator recorded an event that `is` on one of `ours` sessions in
/// `[start, end]`.
fn recorded(
    record: &SimRecording,
    t0: Instant,
    ours: &impl Fn(gripper::wsg::sim::SessionId) -> bool,
    start: Instant,
    end: Instant,
    is: impl Fn(&SimEvent) -> bool,
) -> bool {
    record.records.iter().any(|r| {
        let at = t0 + r.at;
        is(&r.event) && ours(r.session) && at >= start && at <= end
    })
}

/// Every violation of rules 6–9 for one client.
pub fn check(
    calls: &[&CallRec],
    record: &SimRecording,
    t0: Instant,
    view: &ClientView,
    udp: bool,
    close_start: Option<Instant>,
) -> Vec<String> {
    let mut v = Vec::new();
    v.extend(lost_for_cause(calls, t0, view, udp));
    v.extend(timeouts(calls, record, t0, view, udp, close_start));
    for c in calls.iter().filter(|c| c.res == Res::Hung) {
        let sessions = |s| view.sessions.contains(&s);
        let too_long = |e: &SimEvent| matches!(e, SimEvent::Reply { id, data, .. } if *id == c.id && data.len() + 2 > view.max_payload);
        let tag = if !udp && view.max_payload < super::BARRIER_ECHO_LEN {
            super::SHORT_OF_BARRIER
        } else if recorded(record, t0, &sessions, c.start, c.end, too_long) {
            TOO_LONG
        } else if !request_reached(record, t0, &sessions, c.id, c.start, c.end) {
            NOT_SENT
        } else if recorded(record, t0, &sessions, c.start, c.end, |e| {
            // Acknowledged (E_CMD_PENDING) during the call.
            matches!(e, SimEvent::Reply { id, status: Status::CmdPending, .. } if *id == c.id)
        }) {
            ACKNOWLEDGED
        } else if recorded(record, t0, &sessions, c.start, c.end, |e| {
            // Answered (a final status other than E_CMD_PENDING) during the call.
            matches!(e, SimEvent::Reply { id, status, .. } if *id == c.id && *status != Status::CmdPending)
        }) {
            ANSWERED
        } else {
            ""
        };
        v.push(format!(
            "8 (a call without timeout ends, and frees what it held): {} {} began at {} and had not ended {NEVER_ENDS:?} later {tag}",
            c.who, c.op, t(c.start, t0)
        ));
    }
    if !udp {
        v.extend(stops_at_once(calls, t0, view, close_start));
        v.extend(stops_reach_the_device(calls, record, t0, view));
    }
    v
}

/// Rule 6: the client reports a loss (`connection_events`), or fails a call with
/// `ConnectionLost`, only once its link ended: on TCP and serial the client's end of the
/// stream read its end (the schedule cut it, the device closed or restarted) or a write
/// failed (`tap.rs`); UDP has no connection to lose. The WSG binary client has no give-up
/// time on silence: the link ending is its only cause.
fn lost_for_cause(calls: &[&CallRec], t0: Instant, view: &ClientView, udp: bool) -> Vec<String> {
    let mut v = Vec::new();
    let mut ends: Vec<Instant> = view.taps.iter().filter_map(|(_, l)| l.ended).collect();
    ends.sort();
    let mut previous: Option<Instant> = None;
    for &lost in &view.losses {
        // One link end per loss: after a loss the client runs on a new link (or none).
        let cause = ends
            .iter()
            .any(|&e| e <= lost && previous.is_none_or(|p| e > p));
        if udp || !cause {
            v.push(format!(
                "6 (a connection is lost only for cause): the client reported its connection lost at {}, but its link had not ended (no end of stream, no failed write{})",
                t(lost, t0),
                previous.map(|p| format!(" since the loss at {}", t(p, t0))).unwrap_or_default()
            ));
        }
        previous = Some(lost);
    }
    // A call may also end ConnectionLost on a link that ended while the client was closing (its
    // announcement then waits in vain; no loss is reported while closing).
    for c in calls.iter().filter(|c| c.res == Res::Lost) {
        let ended = ends.iter().any(|&e| e <= c.end) && !udp;
        if !ended && !view.losses.iter().any(|&l| l <= c.end) {
            v.push(format!(
                "6 (a connection is lost only for cause): {} {} ended ConnectionLost at {}, but the client had reported no loss and its link had not ended",
                c.who, c.op, t(c.end, t0)
            ));
        }
    }
    v
}

/// Rule 7: a `Timeout` only when the call's reply did not arrive in time. A call with a
/// timeout of its own that is no motion (a motion's acknowledgement is awaited the query
/// timeout + grace, which may be shorter: documented) fails with `Timeout` at its deadline,
/// not before. On TCP and serial a loop-back's reply is its own (its payload is unique): if the
/// link delivered it intact (`byte_stream.rs`) before the call's deadline while the client
/// held that connection, the call must have got it.
fn timeouts(
    calls: &[&CallRec],
    record: &SimRecording,
    t0: Instant,
    view: &ClientView,
    udp: bool,
    close_start: Option<Instant>,
) -> Vec<String> {
    let mut v = Vec::new();
    for c in calls.iter().filter(|c| c.res == Res::Timeout) {
        let Some(limit) = c.limit else { continue };
        let took = c.end - c.start;
        if !is_motion(c.id) && c.op != "close" && took + AT_ONCE < limit {
            v.push(format!(
                "7 (a Timeout only when its reply did not arrive in time): {} {} ended Timeout after {took:?}, before its timeout of {limit:?}",
                c.who, c.op
            ));
            continue;
        }
        let (Some(echo), false) = (&c.echo, udp) else {
            continue;
        };
        if echo.len() + 2 > view.max_payload {
            continue; // Dropped by the client as documented (`max_payload_len`).
        }
        let deadline = c.start + limit;
        for (i, r) in record.records.iter().enumerate() {
            let at = t0 + r.at;
            let SimEvent::Reply {
                id, status, data, ..
            } = &r.event
            else {
                continue;
            };
            if *id != id::LOOP
                || *status != Status::Success
                || data[..] != echo[..]
                || at < c.start
                || !view.sessions.contains(&r.session)
            {
                continue;
            }
            let Some(got) = delivered_intact(record, view, i) else {
                continue;
            };
            let held = view
                .taps
                .iter()
                .any(|(s, l)| *s == r.session && l.ended.is_none_or(|e| e > got))
                && close_start.is_none_or(|s| s > got);
            if held && got + CALL_SLACK < deadline {
                v.push(format!(
                    "7 (a Timeout only when its reply did not arrive in time): {} {} ended Timeout at {}, but its own reply (the device sent it at {}) reached the client intact at {}, before its deadline {}",
                    c.who, c.op, t(c.end, t0), t(at, t0), t(got, t0), t(deadline, t0)
                ));
            }
        }
    }
    v
}

/// Rule 9 (TCP, serial): a stop or FAST STOP call's frame is written at once, whatever else is
/// on the wire (manual 3.2.3/3.2.4: "unmittelbar"), in the fault phase as in the quiet one:
/// the client wrote a frame of its id within [`AT_ONCE`] of the call, if the call found a
/// live link (one opened before it that had not ended, no loss since) and the client was not
/// closing.
fn stops_at_once(
    calls: &[&CallRec],
    t0: Instant,
    view: &ClientView,
    close_start: Option<Instant>,
) -> Vec<String> {
    let mut v = Vec::new();
    for c in calls {
        let stop = c.id == id::STOP || c.id == id::FAST_STOP;
        if !stop || c.bad || c.quiet || close_start.is_some_and(|s| s <= c.start + AT_ONCE) {
            continue;
        }
        // A call given up, or timed out, before the hand-over: its request need never be sent
        // (a zero timeout, say: the caller gives up before the task reads the request).
        if c.end < c.start + AT_ONCE && matches!(c.res, Res::Cancelled | Res::Timeout) {
            continue;
        }
        // The link the call found: the last one opened by then.
        let Some((_, tap)) = view.taps.iter().rev().find(|(_, l)| l.opened <= c.start) else {
            continue;
        };
        let live = tap.ended.is_none_or(|e| e > c.start + AT_ONCE)
            && !view
                .losses
                .iter()
                .any(|&l| l >= tap.opened && l <= c.start + AT_ONCE);
        if !live {
            continue;
        }
        let sent = written_frames(tap)
            .iter()
            .any(|(at, f)| f.id == c.id && *at >= c.start && *at <= c.start + AT_ONCE);
        if !sent {
            let first = written_frames(tap)
                .into_iter()
                .find(|(at, f)| f.id == c.id && *at >= c.start)
                .map(|(at, _)| format!("{:?} after the call", at - c.start))
                .unwrap_or_else(|| "never".into());
            v.push(format!(
                "9 (a stop is sent at once, faults or not): {} {} (in the fault phase, at {}) was written to the link {first} (ended {:?})",
                c.who, c.op, t(c.start, t0), c.res
            ));
        }
    }
    v
}

/// How long a stop whose request was lost may take to reach the device on a link that works:
/// the client proves it lost by a barrier (a round trip, or the query timeout + grace and the
/// resync pause if that too is lost) and sends it again.
const RESEND_WINDOW: Duration = Duration::from_secs(10);

/// The tag of a lost stop held while a motion written after it within the window has no answer
/// the client could read: its request or its immediate reply was damaged on the way (see
/// [`stops_reach_the_device`]).
const HELD_FOR_A_LOST_MOTION: &str = " [held while a motion written after it has no answer the \
     client could read: its request or its reply damaged (stops.rs)]";

/// Rule 9, the re-send (TCP, serial): a stop or FAST STOP call that did not get its reply (it
/// timed out, or its caller gave up) on a connection that held must still reach the device: the
/// client sends it again once a barrier proves it lost, whether or not its caller still waits
/// (issue 29 E: the device never stops). A violation when no intact stop of its id from that
/// session reached the device within [`RESEND_WINDOW`] of the call, yet the link carried
/// later requests (the device received one intact after that window: not a half-closed or
/// stalled link) and the client reported no loss since the call. Not when the client wrote a
/// motion command (home, pre-position, grasp, release) on that link after the call, within
/// the window, and the device acknowledged a motion of that id (E_CMD_PENDING) after that
/// write: then the program has moved on, and the client drops the lost stop rather than abort
/// that newer motion with it (the documented decision, `src/wsg/client/stops.rs`). A motion
/// the device refused at once ran nothing: the stop is still owed.
fn stops_reach_the_device(
    calls: &[&CallRec],
    record: &SimRecording,
    t0: Instant,
    view: &ClientView,
) -> Vec<String> {
    let mut v = Vec::new();
    for c in calls {
        let stop = c.id == id::STOP || c.id == id::FAST_STOP;
        if !stop || c.bad || !matches!(c.res, Res::Timeout | Res::Cancelled) {
            continue;
        }
        if c.end < c.start + AT_ONCE || view.losses.iter().any(|&l| l >= c.start) {
            continue;
        }
        let Some((session, tap)) = view.taps.iter().rev().find(|(_, l)| l.opened <= c.start) else {
            continue;
        };
        let requests = || {
            record.records.iter().filter_map(|r| match r.event {
                SimEvent::Request {
                    id, corrupt: false, ..
                } if r.session == *session => Some((t0 + r.at, id)),
                _ => None,
            })
        };
        let until = c.start + RESEND_WINDOW;
        let reached = requests().any(|(at, id)| id == c.id && at >= c.start && at <= until);
        let link_works = requests().any(|(at, _)| at > until);
        let accepted = |motion: u8, from: Instant| {
            record.records.iter().any(|r| {
                r.session == *session
                    && t0 + r.at >= from
                    && matches!(r.event, SimEvent::Reply { id, status: Status::CmdPending, .. } if id == motion)
            })
        };
        let moved_on = written_frames(tap).iter().any(|(at, f)| {
            is_motion(f.id) && *at >= c.start && *at <= until && accepted(f.id, *at)
        });
        // The client holds a lost stop while a motion written after it has no answer (it
        // must not abort a motion the program started since, `stops.rs`); a motion whose
        // request was lost on the way too is decided only at its caller's deadline and the
        // recovery probes, and two such in a row outlast the window (the open design question
        // of wsg-serial:0xde1245ed22975681, wsg-serial:0x05084d134e5f8e7a).
        // The client holds a lost stop while a motion written after it has no answer, and
        // decides it at that motion's deadline and the recovery probes (the open design
        // question, stops.rs). Lost: a motion request written after the call within the
        // window that did not reach the device intact (fewer intact requests of its id and
        // payload from its write on than writes of them: identical writes count for each
        // other, so a damaged one is not taken for one that came through), or one that did,
        // whose immediate reply (the next reply of its id) did not reach the client intact.
        // Counting all motion requests received in the window took a release written before
        // the call, held on the way, for a lost one (wsg-serial:0x6295f3317fb5766c); searching
        // any receipt after a write took a home received 40 s later for a damaged one
        // (wsg-serial:0x05084d134e5f8e7a); a pre_position refused at once, its refusal
        // damaged on the way back, held the stop 13 s (wsg-serial:0x39ed1f19df1605d4).
        let writes: Vec<(Instant, gripper::wsg::Frame)> = written_frames(tap)
            .into_iter()
            .filter(|(_, f)| is_motion(f.id))
            .collect();
        let receipts: Vec<(usize, Instant, u8, &bytes::Bytes)> = record
            .records
            .iter()
            .enumerate()
            .filter_map(|(k, r)| match &r.event {
                SimEvent::Request {
                    id,
                    payload,
                    corrupt: false,
                } if r.session == *session && is_motion(*id) => Some((k, t0 + r.at, *id, payload)),
                _ => None,
            })
            .collect();
        let request_lost = writes.iter().any(|(at, f)| {
            let written = writes
                .iter()
                .filter(|(w, g)| w >= at && g.id == f.id && g.payload == f.payload)
                .count();
            let received = receipts
                .iter()
                .filter(|(_, got, id, payload)| got >= at && *id == f.id && **payload == f.payload)
                .count();
            *at >= c.start && *at <= until && received < written
        });
        let reply_lost = receipts.iter().any(|&(k, got, id, payload)| {
            let ours = writes
                .iter()
                .any(|(at, f)| *at >= c.start && *at <= got && f.id == id && f.payload == *payload);
            let reply = record.records[k..].iter().position(|r| {
                r.session == *session && matches!(r.event, SimEvent::Reply { id: i, .. } if i == id)
            });
            ours && got <= until
                && reply.is_some_and(|j| delivered_intact(record, view, k + j).is_none())
        });
        let motion_lost = request_lost || reply_lost;
        if !reached && link_works && !moved_on {
            let tag = if motion_lost {
                HELD_FOR_A_LOST_MOTION
            } else {
                ""
            };
            v.push(format!(
                "9 (a stop is sent at once, faults or not): {} {} (at {}, ended {:?}) never reached the device intact within {RESEND_WINDOW:?}, though the connection held and carried later requests (a lost stop is sent again){tag}",
                c.who, c.op, t(c.start, t0), c.res
            ));
        }
    }
    v
}
