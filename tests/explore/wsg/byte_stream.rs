//! What the byte-stream links (TCP, serial) tell the WSG oracle: which frames they delivered
//! intact and which they damaged (`core/streams.rs`, its `CarriedLog`), for the promise-4
//! check of a lost final reply and the checksum's residual tag.

use gripper::wsg::command::id;
use gripper::wsg::sim::{SessionId, SimEvent, SimRecording};
use gripper::wsg::{Status, SystemState};
use tokio::time::Instant;

use super::oracle::{t, ClientView};
use super::workload::{CallRec, Res};
use crate::core::streams::Carried;

/// How far before a reply a damaged byte can still cost it: a damaged length field (or noise
/// that looks like a header) makes the client's decoder take up to one frame of the longest
/// payload it accepts as one bogus frame, whose checksum then fails (manual 1.2.1: preamble,
/// id, 16-bit length, payload, CRC).
const DAMAGE_REACH: u64 = (gripper::wsg::frame::HEADER_LEN
    + gripper::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN
    + gripper::wsg::frame::CHECKSUM_LEN) as u64;

/// Promise 4 on TCP and serial: [`Res::ReplyLost`] says the motion's final reply was lost
/// (`Error::ReplyLost`). An ordered, reliable stream loses a reply only with its connection or
/// by a fault that damages it, so the claim is false when the device sent the motion's final
/// reply on the session that acknowledged it, no later than the call's end plus the client's
/// grace (the documented bound: only a final reply later than a grace after the second "not
/// moving" is the residual risk, `client/mod.rs` "Lost final replies", manual Anhang B), and
/// the link delivered that reply's bytes with no damage that could reach them, while the
/// client still held that connection and had not begun to close. (UDP loses datagrams: not
/// checked there.)
pub fn reply_lost_on_streams(
    calls: &[&CallRec],
    record: &SimRecording,
    t0: Instant,
    view: &ClientView,
    close_start: Option<Instant>,
) -> Vec<String> {
    let mut v = Vec::new();
    if view.carried.is_empty() {
        return v;
    }
    let wire = on_wire(record, view);
    for c in calls {
        let Res::ReplyLost(cmd) = c.res else { continue };
        // The call's own acknowledgement: on an ordered stream no other request of its id is
        // on the wire after it until the call ends, so it is the last one before the end (at
        // the very instant of the end it may be the next request's).
        let Some((i, ack)) = record.records.iter().enumerate().rev().find(|(_, r)| {
            let at = t0 + r.at;
            at >= c.start
                && at < c.end
                && view.sessions.contains(&r.session)
                && matches!(r.event, SimEvent::Reply { id, status: Status::CmdPending, .. } if id == cmd)
        }) else {
            continue;
        };
        let Some(fin) = final_reply(record, i, cmd) else {
            continue;
        };
        let sent_at = t0 + record.records[fin].at;
        if sent_at > c.end + view.grace {
            continue;
        }
        let at = match intact(record, view, &wire, fin) {
            Intact::At(at) => at,
            Intact::No => continue,
            Intact::Mismatch(e) => {
                v.push(e);
                continue;
            }
        };
        let acked_at = t0 + ack.at;
        let held = !view.losses.iter().any(|&l| l >= acked_at && l <= at)
            && close_start.is_none_or(|s| s > at);
        if !held {
            continue;
        }
        let SimEvent::Reply { status, .. } = &record.records[fin].event else {
            continue;
        };
        // The client's rule is two "not moving" a grace apart (`client/mod.rs`): say when the
        // device's last two were closer (how the rule was broken, not just that it was).
        let idle: Vec<Instant> = record.records[i..]
            .iter()
            .filter(|r| r.session == ack.session && t0 + r.at <= c.end)
            .filter(|r| matches!(&r.event, SimEvent::Reply { id: id::SYSTEM_STATE, status: Status::Success, data, .. }
                if SystemState::decode(data).is_ok_and(|f| !f.contains(SystemState::MOVING))))
            .map(|r| t0 + r.at)
            .collect();
        let close = match idle[..] {
            [.., a, b] if b.saturating_duration_since(a) < view.grace => CLOSE_IDLES,
            _ => "",
        };
        v.push(format!(
            "4 (ReplyLost only for a final reply that was lost): {} {} ended ReplyLost at {}, but the device's final reply ({status:?}, sent at {} on session {}, the one that acknowledged it at {}) reached the client intact at {} while it held that connection {close}",
            c.who,
            c.op,
            t(c.end, t0),
            t(sent_at, t0),
            ack.session,
            t(acked_at, t0),
            t(at, t0)
        ));
    }
    v
}

/// What the link did with one reply's bytes.
enum Intact {
    /// Delivered intact, by then.
    At(Instant),
    /// Not delivered, or not provably intact.
    No,
    /// The log and the record disagree (an explorer bug).
    Mismatch(String),
}

/// Whether reply record `fin` reached the client intact, and when: the link delivered its
/// bytes with no damage that could reach them (within [`DAMAGE_REACH`] before them), not torn
/// across two writes apart in time.
fn intact(record: &SimRecording, view: &ClientView, wire: &[Option<OnWire>], fin: usize) -> Intact {
    let session = record.records[fin].session;
    let (Some(w), Some((_, carried))) =
        (&wire[fin], view.carried.iter().find(|(s, _)| *s == session))
    else {
        return Intact::No;
    };
    let Some(kept) = carried.input.get(w.start as usize..w.end() as usize) else {
        return Intact::No; // Beyond what the log kept.
    };
    if kept != w.bytes.as_slice() {
        return Intact::Mismatch(format!(
            "explorer: session {session}'s stream at byte {} is not the reply the simulator recorded there ({kept:02x?}, not {:02x?})",
            w.start, w.bytes
        ));
    }
    // A damaged byte may cost every frame up to DAMAGE_REACH after it. A frame torn across
    // two writes apart in time may lose its head to the client's partial-frame timeout
    // (`transport.rs`, resync): itself, and the frames after it only if its tail holds a
    // preamble (manual 1.2.1: AA AA AA) that a decoder could take for a header.
    let reach = |d: u64| d < w.end() && d + DAMAGE_REACH >= w.start;
    let torn = wire.iter().flatten().any(|o| {
        o.session == session
            && delivered(carried, o.start + 1) != delivered(carried, o.end())
            && (o.start == w.start
                || reach(o.start) && o.bytes[1..].windows(3).any(|p| p == [0xAA; 3]))
    });
    if torn || carried.damaged.iter().any(|&d| reach(d)) {
        return Intact::No;
    }
    match delivered(carried, w.end()) {
        Some(at) => Intact::At(at),
        None => Intact::No,
    }
}

/// When reply record `i` reached the client intact over its stream session (see
/// [`reply_lost_on_streams`]), if it did (None on UDP).
pub fn delivered_intact(record: &SimRecording, view: &ClientView, i: usize) -> Option<Instant> {
    match intact(record, view, &on_wire(record, view), i) {
        Intact::At(at) => Some(at),
        _ => None,
    }
}

/// Appended to a promise 2 violation (an auto-update the device never sent) when the link
/// delivered that update's frame, by the time the client received it, with bytes the fault layer
/// damaged inside it, and the device sent no such frame: the damaged frame still passed its
/// CRC16. That is the checksum's own limit (manual 1.2 CRC: CRC-CCITT detects every 1- or 2-bit
/// error and every burst up to 16 bits, not every insertion or length change; a random damaged
/// frame passes about once in 65,536), the documented residual risk of TCP and serial, which
/// `known.txt` may name for them only.
pub const DAMAGED_PASSED_CRC: &str =
    "[the frame carries bytes the fault layer damaged and still passed its CRC16]";

/// Whether `reply`, received by `by` (an update, or a call's answer), came from a frame the
/// link damaged that still passed its CRC16: some stream session of this client delivered, no
/// later than `by`, the exact frame of `reply` (as the device would encode it) with a damaged
/// byte inside it, and the device sent no such frame on that session (`Carried::output`,
/// `Carried::output_damaged`). (`wsg-serial:0x8fb9d7a79c2aad1f`: two noise bytes inserted
/// into a 0x50 reply made a frame whose checksum held, answering `request(0x50)`.)
pub fn passed_crc_damaged(
    record: &SimRecording,
    view: &ClientView,
    reply: &gripper::wsg::Reply,
    by: Instant,
) -> bool {
    let mut frame = bytes::BytesMut::new();
    if gripper::wsg::frame::encode(&reply.to_frame(), &mut frame).is_err() {
        return false;
    }
    let wire = on_wire(record, view);
    view.carried.iter().any(|(session, carried)| {
        let sent = wire
            .iter()
            .flatten()
            .any(|w| w.session == *session && w.bytes[..] == frame[..]);
        let len = frame.len();
        !sent
            && carried
                .output
                .windows(len)
                .enumerate()
                .filter(|(_, w)| *w == &frame[..])
                .any(|(start, _)| {
                    let (start, end) = (start as u64, (start + len) as u64);
                    let by = carried
                        .output_delivered
                        .iter()
                        .find(|(_, e)| *e >= end)
                        .is_some_and(|(at, _)| *at <= by);
                    by && carried
                        .output_damaged
                        .iter()
                        .any(|&d| d >= start && d < end)
                })
    })
}

/// Appended to a promise 4 ReplyLost violation when the device's last two "not moving" answers
/// to the client's probes after the acknowledgement came less than a grace apart (the client's
/// rule wants two a grace apart; `known.txt` names this open finding by it).
pub const CLOSE_IDLES: &str = "[its last two \"not moving\" came less than a grace apart]";

/// Where one reply the device sent on a stream session lies in that session's byte stream.
struct OnWire {
    /// The session.
    session: SessionId,
    /// Its first byte's offset.
    start: u64,
    /// Its frame, as the device encoded it.
    bytes: Vec<u8>,
}

impl OnWire {
    /// The offset just past its last byte.
    fn end(&self) -> u64 {
        self.start + self.bytes.len() as u64
    }
}

/// For each record, where its reply lies in its session's stream (`None`: not a reply, or
/// not on a stream of this client). The device writes the replies of a session in the order
/// it records them (`SimEvent::Reply`), one frame each.
fn on_wire(record: &SimRecording, view: &ClientView) -> Vec<Option<OnWire>> {
    let mut offsets: std::collections::BTreeMap<SessionId, u64> = Default::default();
    record
        .records
        .iter()
        .map(|r| {
            let SimEvent::Reply {
                id, status, data, ..
            } = &r.event
            else {
                return None;
            };
            if !view.carried.iter().any(|(s, _)| *s == r.session) {
                return None;
            }
            let offset = offsets.entry(r.session).or_insert(0);
            let mut b = bytes::BytesMut::new();
            let reply = gripper::wsg::Reply::new(*id, *status, data.clone());
            gripper::wsg::frame::encode(&reply.to_frame(), &mut b).ok()?;
            let start = *offset;
            *offset += b.len() as u64;
            Some(OnWire {
                session: r.session,
                start,
                bytes: b.to_vec(),
            })
        })
        .collect()
}

/// When the link had written every byte before offset `end` to the client's end.
fn delivered(carried: &Carried, end: u64) -> Option<Instant> {
    carried
        .delivered
        .iter()
        .find(|(_, e)| *e >= end)
        .map(|(at, _)| *at)
}

/// The index of the final reply to the motion command `cmd` acknowledged by record `ack`: the
/// next reply of that id on its session, E_ALREADY_RUNNING aside (it refuses a duplicate and
/// does not end the motion, 1.3). None if the session ended, the device restarted or a new
/// acknowledgement came first.
fn final_reply(record: &SimRecording, ack: usize, cmd: u8) -> Option<usize> {
    let session = record.records[ack].session;
    for (i, r) in record.records.iter().enumerate().skip(ack + 1) {
        match &r.event {
            SimEvent::Restarted => return None,
            SimEvent::Disconnected if r.session == session => return None,
            SimEvent::Reply { id, status, .. } if r.session == session && *id == cmd => {
                match status {
                    Status::AlreadyRunning => {}
                    Status::CmdPending => return None,
                    _ => return Some(i),
                }
            }
            _ => {}
        }
    }
    None
}
