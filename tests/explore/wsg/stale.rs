//! Which stale datagrams the UDP residual tag may excuse. UDP has no sequence numbers: a reply
//! the fault layer duplicated or delayed can answer a newer request of its id, and the client
//! cannot tell (the residual risk of `src/wsg/client/pairing.rs` on UDP). But its rule does
//! keep one kind of stale reply from a newer call: the immediate reply of a request that no
//! other frame of the id could have answered, delivered while that request still held its id
//! (before the earlier of its caller's deadline and its reply hold, plus the late-reply grace).
//! Such a reply answering another call is a bug, not the residual (planted bug 1 of
//! docs/EXPLORER.md: the id given up at the deadline, without the grace).

use gripper::wsg::command::id;
use gripper::wsg::sim::{SessionId, SimEvent, SimRecording};
use gripper::wsg::Status;
use tokio::time::Instant;

use super::oracle::{is_motion, is_streamed, ClientView, Sent};
use super::workload::{CallRec, Res};
use crate::core::datagrams::Faulted;

/// What the tag needs to know about one client besides the stale reply.
pub struct Context<'a> {
    /// The client's calls.
    pub calls: &'a [&'a CallRec],
    /// The simulator's record.
    pub record: &'a SimRecording,
    /// The simulator's time zero.
    pub t0: Instant,
    /// The client.
    pub view: &'a ClientView,
    /// The faulted reply datagrams delivered to the client, decoded (`faulted[k]` is `s`).
    pub faulted: &'a [Sent],
}

/// Whether faulted reply `faulted[k]`, delivered to the client during call `c` and fitting its
/// answer, is one the client's rule cannot keep from `c` (the tag excuses it).
pub fn beyond_the_rule(cx: &Context, k: usize, c: &CallRec) -> bool {
    let s = &cx.faulted[k];
    let Some(origin) = s.origin else {
        return true;
    };
    // A stream's updates share the reply's id and form (manual 1.4), and the stops share their
    // replies (`stops.rs`): their own residuals.
    if is_shared(s.id) {
        return true;
    }
    let ours = |session: SessionId| cx.view.sessions.contains(&session);
    let records = &cx.record.records;
    // The device's reply this copy carries, and the request it answered at that instant (a
    // final reply or an E_CMD_ABORTED answers no request of its own: not this rule's).
    let Some(r) = records.iter().position(|r| {
        ours(r.session)
            && cx.t0 + r.at == origin.sent
            && matches!(&r.event, SimEvent::Reply { id, status, data, .. }
                if *id == s.id && *status == s.status && data[..] == s.data[..])
    }) else {
        return true;
    };
    let session = records[r].session;
    let request = records[..r]
        .iter()
        .rev()
        .find(|q| q.session == session && matches!(q.event, SimEvent::Request { .. }));
    let Some((q_at, payload)) = request.and_then(|q| match &q.event {
        SimEvent::Request { id, payload, .. } if *id == s.id && cx.t0 + q.at == origin.sent => {
            Some((cx.t0 + q.at, payload))
        }
        _ => None,
    }) else {
        return true;
    };
    // When the client sent that request: earlier than the device got it if the link delayed it.
    let sent = cx
        .view
        .faulted_requests
        .iter()
        .filter(|f| f.at == q_at && carries(f, s.id, payload))
        .map(|f| f.sent)
        .min()
        .unwrap_or(q_at);
    // Another frame of the id delivered since may have been taken for the request's reply (a
    // duplicated request's first answer, an older copy): then this one answers the next
    // request, which the rule cannot help.
    if delivered_between(cx, k, sent, s.at, ours) {
        return true;
    }
    if cx.view.losses.iter().any(|&l| l >= sent && l <= s.at) {
        return true;
    }
    // The calls of the id that may have sent it; none: an internal request (a probe, an
    // unsubscribe), whose hold the oracle does not know.
    let senders: Vec<&&CallRec> = cx
        .calls
        .iter()
        .filter(|o| !std::ptr::eq(**o, c) && o.id == s.id && o.start <= sent && o.end >= sent)
        .collect();
    if senders.is_empty() {
        return true;
    }
    // The earliest the client may have given the id up: a caller's own deadline (its
    // timeout wins over the connection's, however much longer); the reply hold from the send
    // only for a call without a timeout, one dropped before its deadline (`Pairing::prune`),
    // or a motion command's acknowledgement (it comes at once, manual 1.3).
    let hold = sent + cx.view.query_timeout;
    let motion = is_motion(s.id);
    let deadline = senders
        .iter()
        .map(|o| match o.limit {
            None => hold,
            Some(l) if o.res == Res::Cancelled || motion => (o.start + l).min(hold),
            Some(l) => o.start + l,
        })
        .min()
        .unwrap_or(hold);
    // At the release instant itself the record does not order the release and the delivery:
    // the client holds the id over [sent, release) (`wsg-udp:0xe861f7c2f9bd8395`: a reply
    // delayed exactly the query timeout + grace arrived as the id was given up).
    s.at >= deadline + cx.view.grace
}

/// Ids whose replies the client may hand to more than one request (streams, stops).
fn is_shared(cmd: u8) -> bool {
    is_streamed(cmd) || cmd == id::STOP || cmd == id::FAST_STOP
}

/// Whether datagram `f` is the request `cmd` with `payload`.
fn carries(f: &Faulted, cmd: u8, payload: &[u8]) -> bool {
    let mut buf = bytes::BytesMut::from(&f.bytes[..]);
    matches!(
        gripper::wsg::frame::decode(&mut buf, gripper::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN),
        Some(gripper::wsg::frame::Decoded::Frame(fr)) if fr.id == cmd && fr.payload[..] == *payload
    )
}

/// Whether a frame of `faulted[k]`'s id other than it reached the client in `[from, to]`: a
/// faulted copy when it was delivered, any other reply of the device when it was sent (or
/// never, if lost: counted anyway, which only excuses more).
fn delivered_between(
    cx: &Context,
    k: usize,
    from: Instant,
    to: Instant,
    ours: impl Fn(SessionId) -> bool,
) -> bool {
    let cmd = cx.faulted[k].id;
    // Inclusive: within one instant the record does not order the steps.
    let within = |at: Instant| at >= from && at <= to;
    let faulted = cx
        .faulted
        .iter()
        .enumerate()
        .any(|(j, f)| j != k && f.id == cmd && within(f.at));
    faulted
        || cx.record.records.iter().any(|r| match &r.event {
            SimEvent::Reply {
                id, status, data, ..
            } if *id == cmd && ours(r.session) && within(cx.t0 + r.at) => {
                unfaulted(cx, cx.t0 + r.at, (*id, *status, data), &ours)
            }
            _ => false,
        })
}

/// Whether one of the device's replies `reply` sent at `at` went through the link untouched:
/// more such replies than the faulted copies sent at that instant account for (a duplicated
/// reply is two copies).
fn unfaulted(
    cx: &Context,
    at: Instant,
    reply: (u8, Status, &[u8]),
    ours: &impl Fn(SessionId) -> bool,
) -> bool {
    let sent = cx
        .record
        .records
        .iter()
        .filter(|r| {
            cx.t0 + r.at == at
                && ours(r.session)
                && matches!(&r.event, SimEvent::Reply { id, status, data, .. }
                    if (*id, *status, &data[..]) == reply)
        })
        .count();
    let copies = |duplicated: bool| {
        cx.faulted
            .iter()
            .filter(|f| {
                f.origin
                    .is_some_and(|o| o.sent == at && o.duplicated == duplicated)
                    && (f.id, f.status, &f.data[..]) == reply
            })
            .count()
    };
    sent > copies(false) + copies(true).div_ceil(2)
}
