//! The WSG simulator's device state machine fed arbitrary command frames from several sessions.
//!
//! Input: `[config, record...]`, each record `[op, dt, id, len, payload[len]]`. The config byte
//! picks the model, a part to grasp or none, and the time scale (0: motion ends at once, as the
//! server settles it; 1: real durations). `op` picks the session (4 of them: TCP, TCP, UDP,
//! serial) and what happens: a frame (handled as `SimServer` does, `handle_at` with the
//! simulated and wall time; never id `AA`, which the server's decoder cannot yield), a frame with
//! a bad checksum, or the session closing and a new one opening in its place.
//! `dt` moves both clocks forward (0–2.55 s).
//!
//! Checked, besides "no panic":
//! - every command frame gets a reply with its id on its session, right away;
//! - every reply goes to a session that exists or existed (a reply to a peer that left while its
//!   motion ran is dropped by the server); an ended session gets no more auto-updates;
//! - every reply fits a frame and reads back through the client's path (encode,
//!   `frame::decode`, `Reply::from_frame`) as itself; the client's typed decoders of reply data
//!   never panic on it;
//! - no hang, no panic in the server's clock: the next motion event is a number (the server turns
//!   it into a wall-clock `Duration`), and settling as the server does (advance to each next
//!   event) ends within 1 000 steps, each moving time forward.
#![no_main]

use bytes::BytesMut;
use gripper::wsg::frame::{self, Decoded, Frame};
use gripper::wsg::sim::{Device, Model, Out, SessionKind, SimConfig};
use gripper::wsg::types::decode_temperature_c;
use gripper::wsg::{
    FingerFlags, FingerInfo, GraspingStatistics, GripState, Reply, SoftLimits, SystemInfo,
    SystemLimits, SystemState,
};
use gripper_fuzz as _; // the bounded allocator
use libfuzzer_sys::fuzz_target;

const KINDS: [SessionKind; 4] = [
    SessionKind::Tcp,
    SessionKind::Tcp,
    SessionKind::Udp,
    SessionKind::Serial,
];

fn check_out(out: &Out, sessions: u64) {
    // A reply may outlive its session (a UDP or serial peer left while its motion ran: the
    // server drops it), but never names a session that never existed.
    assert!(
        out.session < sessions,
        "reply {out:?} to an unknown session"
    );
    let mut bytes = BytesMut::new();
    frame::encode(&out.reply.to_frame(), &mut bytes).expect("a reply fits a frame");
    let decoded = frame::decode(&mut bytes, usize::from(u16::MAX));
    let Some(Decoded::Frame(received)) = decoded else {
        panic!("reply {out:?} does not decode: {decoded:?}");
    };
    assert!(bytes.is_empty());
    assert_eq!(Reply::from_frame(received).as_ref(), Ok(&out.reply));
    // What the client may do with the data, whichever command it was for.
    let data = &out.reply.data[..];
    let _ = SystemState::decode(data);
    let _ = FingerFlags::decode(data);
    let _ = GripState::decode(data);
    let _ = GraspingStatistics::decode(data);
    let _ = SoftLimits::decode(data);
    let _ = SystemInfo::decode(data);
    let _ = SystemLimits::decode(data);
    let _ = FingerInfo::decode(data);
    let _ = decode_temperature_c(data);
}

/// Settles motion as the server does at time scale 0, or just checks the next event at others.
fn settle(device: &mut Device, now: &mut f64, instant: bool, sessions: u64) {
    for out in device.advance(*now) {
        check_out(&out, sessions);
    }
    let mut steps = 0;
    while let Some(t) = device.next_event() {
        assert!(!t.is_nan(), "next motion event at NaN");
        if !instant {
            break;
        }
        *now = t.max(*now);
        for out in device.advance(t) {
            check_out(&out, sessions);
        }
        if let Some(next) = device.next_event() {
            assert!(next > t, "advancing to {t} leaves the next event at {next}");
        }
        steps += 1;
        assert!(steps < 1_000, "motion never settles");
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&config, mut rest)) = data.split_first() else {
        return;
    };
    let model = [Model::Wsg50, Model::Wsg32, Model::Wsg25, Model::Wsg70][usize::from(config & 3)];
    let mut cfg = SimConfig::new(model);
    if config & 4 != 0 {
        cfg = cfg.with_part(f32::from(config >> 3), 1.0);
    }
    let instant = config & 0x80 == 0;
    if !instant {
        cfg = cfg.with_time_scale(1.0);
    }
    let mut device = Device::new(cfg);
    // The session id of each of the four slots; a slot that reconnects gets a new id, as a new
    // connection does in the server.
    let mut ids = [0u64, 1, 2, 3];
    let mut sessions = 4u64;
    let mut closed = Vec::new();
    for (id, kind) in ids.iter().zip(KINDS) {
        device.connect(*id, kind);
    }
    let mut now = 0.0f64;

    while let [op, dt, id, len, tail @ ..] = rest {
        let len = usize::from(*len).min(tail.len());
        let (payload, tail) = tail.split_at(len);
        rest = tail;
        // The server's frame decoder never yields id AA (it reads the last three bytes of an AA
        // run as the preamble), so the device never sees it.
        let id = &if *id == 0xAA { 0xAB } else { *id };
        now += f64::from(*dt) / 100.0;
        let slot = usize::from(op & 3);
        let sid = ids[slot];
        match (op >> 2) & 3 {
            3 => {
                device.disconnect(sid, now);
                closed.push(sid);
                ids[slot] = sessions;
                device.connect(sessions, KINDS[slot]);
                sessions += 1;
                settle(&mut device, &mut now, instant, sessions);
                continue;
            }
            2 => {
                let received = Decoded::Corrupt {
                    id: *id,
                    len: len as u16,
                };
                let outs = device.handle_at(now, Some(now), sid, &received);
                for out in &outs {
                    check_out(out, sessions);
                }
                assert!(outs.iter().any(|o| o.session == sid && o.reply.id == *id));
            }
            _ => {
                let received = Decoded::Frame(Frame::new(*id, payload.to_vec()));
                let outs = device.handle_at(now, Some(now), sid, &received);
                for out in &outs {
                    check_out(out, sessions);
                }
                assert!(
                    outs.iter().any(|o| o.session == sid && o.reply.id == *id),
                    "no reply to {received:?}: {outs:?}"
                );
            }
        }
        settle(&mut device, &mut now, instant, sessions);
        for out in device.updates_due(now, |_| false) {
            check_out(&out, sessions);
            assert!(
                !closed.contains(&out.session),
                "auto-update {out:?} after its session closed"
            );
        }
    }
});
