//! The pairing rules as a pure state machine: each test drives `Pairing` by hand, with no I/O
//! and no clock but the instants it passes.

use bytes::Bytes;

use super::*;
use crate::wsg::client::FINGER_POWER_ON_DURATION;
use crate::wsg::Error;

fn req(token: Token, id: u8, deadline: Instant) -> Request {
    Request {
        token,
        frame: Frame::new(id, Bytes::new()),
        deadline,
    }
}

fn reply(id: u8, status: Status) -> Reply {
    Reply::new(id, status, Bytes::new())
}

fn sent(s: Submit) -> Option<Token> {
    match s {
        Submit::Send(r) => Some(r.token),
        _ => None,
    }
}

#[test]
fn same_id_queues_different_ids_run() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    assert_eq!(sent(p.submit(req(1, 0x43, t), now)), Some(1));
    assert!(matches!(p.submit(req(2, 0x43, t), now), Submit::Queued));
    assert_eq!(sent(p.submit(req(3, 0x40, t), now)), Some(3));
    assert_eq!(
        p.on_reply(reply(0x40, Status::Success), Instant::now),
        Event::Resolved(3, reply(0x40, Status::Success))
    );
    assert_eq!(
        p.on_reply(reply(0x43, Status::Success), Instant::now),
        Event::Resolved(1, reply(0x43, Status::Success))
    );
    let (next, skipped) = p.next(0x43, |_| true, Instant::now());
    assert_eq!(next.map(|r| r.token), Some(2));
    assert!(skipped.is_empty());
    assert!(matches!(
        p.on_reply(reply(0x43, Status::Success), Instant::now),
        Event::Resolved(2, _)
    ));
    assert!(matches!(
        p.on_reply(reply(0x43, Status::Success), Instant::now),
        Event::Unsolicited(_)
    ));
}

/// A query of a streamed id settled by a barrier: the last E_SUCCESS frame before the echo
/// answers it (earlier ones may be updates sent before the device received it); an echo
/// with no frame before it leaves no later frame to answer it.
#[test]
fn a_streamed_query_is_answered_by_the_last_frame_before_its_barrier() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    p.set_ordered(true);
    let width = |mm: u8| Reply::new(0x43, Status::Success, Bytes::from(vec![mm]));
    assert_eq!(sent(p.submit(req(1, 0x43, t), now)), Some(1));
    p.settle_by_barrier(0x43, 1);
    assert_eq!(
        p.on_reply(width(1), Instant::now),
        Event::Unsolicited(width(1))
    );
    assert_eq!(
        p.on_reply(width(2), Instant::now),
        Event::Unsolicited(width(2))
    );
    assert!(matches!(p.settle(0x43, 1, now), Settled::Answer(r) if r == width(2)));
    assert!(!p.done(0x43));
    // No frame before the echo: lost, and a later frame does not answer it.
    assert_eq!(sent(p.submit(req(2, 0x43, t), now)), Some(2));
    p.settle_by_barrier(0x43, 2);
    assert!(matches!(p.settle(0x43, 2, now), Settled::Nothing));
    assert_eq!(
        p.on_reply(width(3), Instant::now),
        Event::Unsolicited(width(3))
    );
    // A refusal is no update: it answers at once.
    let mut q = Pairing::new(Duration::from_secs(1));
    assert_eq!(sent(q.submit(req(3, 0x43, t), now)), Some(3));
    q.settle_by_barrier(0x43, 3);
    let refused = reply(0x43, Status::CmdFormatError);
    assert_eq!(
        q.on_reply(refused.clone(), Instant::now),
        Event::Resolved(3, refused)
    );
    assert!(matches!(q.settle(0x43, 3, now), Settled::Nothing));
}

/// Issue 29 A: a damaged frame before the echo may have been the query's reply, and the last
/// frame of its id an update sent before the device read the query: the query is sent again,
/// with the same token, and the release of a caller without timeout counts from then.
#[test]
fn a_streamed_query_with_a_damaged_frame_before_its_echo_is_asked_again() {
    let now = Instant::now();
    let grace = Duration::from_secs(1);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    p.set_holds(Duration::from_millis(100), Duration::from_secs(5));
    let width = |mm: u8| Reply::new(0x43, Status::Success, Bytes::from(vec![mm]));
    let never = after(now, Duration::MAX);
    assert_eq!(sent(p.submit(req(1, 0x43, never), now)), Some(1));
    p.settle_by_barrier(0x43, 1);
    assert_eq!(
        p.on_reply(width(1), Instant::now),
        Event::Unsolicited(width(1))
    );
    p.on_damage();
    let later = now + Duration::from_millis(80);
    let Settled::Again(again) = p.settle(0x43, 1, later) else {
        panic!("asked again");
    };
    assert_eq!((again.token, again.frame.id), (1, 0x43));
    assert!(!p.done(0x43), "still the request on the wire");
    // The release of its caller without timeout: the reply hold + grace from the re-send.
    assert_eq!(
        p.next_due(),
        Some(later + Duration::from_millis(100) + grace)
    );
    // Settled again with no damage: the last frame answers.
    p.settle_by_barrier(0x43, 1);
    assert_eq!(
        p.on_reply(width(2), Instant::now),
        Event::Unsolicited(width(2))
    );
    assert!(matches!(p.settle(0x43, 1, later), Settled::Answer(r) if r == width(2)));
    // A line that damages a frame in every round trip: asked again MAX_ASKED_AGAIN times, then
    // no answer is taken (the request waits for its release), however many frames came.
    assert_eq!(sent(p.submit(req(2, 0x43, never), later)), Some(2));
    for round in 0..=MAX_ASKED_AGAIN {
        p.settle_by_barrier(0x43, 2);
        let update = p.on_reply(width(3), Instant::now);
        assert_eq!(update, Event::Unsolicited(width(3)));
        p.on_damage();
        let settled = p.settle(0x43, 2, later);
        if round < MAX_ASKED_AGAIN {
            assert!(matches!(settled, Settled::Again(_)), "{settled:?}");
        } else {
            assert!(matches!(settled, Settled::Nothing), "{settled:?}");
        }
    }
    assert!(!p.done(0x43), "held until its release");
}

#[test]
fn pending_then_final_and_stop_is_not_blocked() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    assert_eq!(sent(p.submit(req(1, 0x21, t), now)), Some(1));
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(1)
    );
    assert_eq!(
        sent(p.submit(req(2, 0x22, t), now)),
        Some(2),
        "stop must not wait for the move"
    );
    assert!(matches!(
        p.on_reply(reply(0x22, Status::Success), Instant::now),
        Event::Stopped(ref t, _) if t == &[2]
    ));
    assert!(
        matches!(p.on_reply(reply(0x21, Status::CmdAborted), Instant::now), Event::Resolved(1, r) if r.status == Status::CmdAborted)
    );
}

#[test]
fn stops_are_never_queued_and_a_reply_completes_only_the_calls_it_can_answer() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    for id in [id::STOP, id::FAST_STOP] {
        // The first stop's reply is outstanding: the second still goes out at once.
        assert_eq!(sent(p.submit(req(1, id, t), now)), Some(1));
        assert_eq!(sent(p.submit(req(2, id, t), now)), Some(2));
        // Only a resend is ever due for a stop (it holds no id).
        assert_eq!(p.next_due(), Some(now + super::super::stops::RESEND_AFTER));
        // The first reply may answer the first stop, sent before the second call: it
        // completes the first call only (issue 20.2 #3).
        assert_eq!(
            p.on_reply(reply(id, Status::Success), Instant::now),
            Event::Stopped(vec![1], reply(id, Status::Success))
        );
        assert_eq!(
            p.on_reply(reply(id, Status::Success), Instant::now),
            Event::Stopped(vec![2], reply(id, Status::Success))
        );
        // A caller that went away is forgotten before the next stop goes out.
        assert_eq!(sent(p.submit(req(3, id, t), now)), Some(3));
        assert_eq!(p.prune(id, |t| t != 3, now), vec![3]);
        assert!(matches!(
            p.on_reply(reply(id, Status::Success), Instant::now),
            Event::Unsolicited(_)
        ));
    }
    assert!(p.drain().is_empty());
}

#[test]
fn dead_queued_callers_are_skipped_and_unanswered_ids_released_after_grace() {
    let now = Instant::now();
    let mut p = Pairing::new(Duration::from_millis(500));
    assert!(matches!(p.submit(req(1, 0x50, now), now), Submit::Send(_)));
    assert!(matches!(p.submit(req(2, 0x50, now), now), Submit::Queued));
    assert!(matches!(p.submit(req(3, 0x50, now), now), Submit::Queued));
    assert_eq!(p.next_due(), Some(now + Duration::from_millis(500)));
    assert!(p.due(now).is_empty());
    assert_eq!(
        p.due(now + Duration::from_millis(500)),
        vec![Due::Released(0x50, 1)]
    );
    let (next, skipped) = p.next(0x50, |t| t != 2, Instant::now());
    assert_eq!(next.map(|r| r.token), Some(3));
    assert_eq!(skipped, vec![2]);
}

/// A call without timeout (deadline `Instant` + `Duration::MAX`, saturated) whose reply is
/// lost, or whose caller dropped the call, does not keep its id for ever
/// (wsg-udp:0x8fdf7f0a06b3bd7e): unacknowledged, it is released the reply hold + grace
/// after it was sent; an acknowledged motion goes under recovery the motion hold after it
/// was sent (and is released only on evidence, as before).
#[test]
fn a_request_without_deadline_keeps_its_id_only_for_the_holds() {
    let now = Instant::now();
    let never = after(now, Duration::MAX);
    let grace = Duration::from_millis(100);
    let (query, motion) = (Duration::from_secs(1), Duration::from_secs(10));
    let mut p = Pairing::new(grace);
    p.set_holds(query, motion);
    assert!(matches!(
        p.submit(req(1, 0x50, never), now),
        Submit::Send(_)
    ));
    assert!(matches!(p.submit(req(2, 0x50, never), now), Submit::Queued));
    assert_eq!(p.next_due(), Some(now + query + grace));
    assert!(p.due(now + query).is_empty());
    assert_eq!(p.due(now + query + grace), vec![Due::Released(0x50, 1)]);
    let later = now + query + grace;
    assert_eq!(p.next(0x50, |_| true, later).0.map(|r| r.token), Some(2));
    // The next one is bounded from when it was sent.
    assert_eq!(p.next_due(), Some(later + query + grace));
    assert!(matches!(
        p.on_reply(reply(0x50, Status::Success), Instant::now),
        Event::Resolved(2, _)
    ));

    assert!(matches!(
        p.submit(req(3, 0x21, never), now),
        Submit::Send(_)
    ));
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(3)
    );
    assert_eq!(p.due(now + motion), vec![Due::Probe(0x21, 3)]);
}

/// A connection without motion timeout (`Duration::MAX`) has no motion hold: an acknowledged
/// motion of a caller without timeout whose final reply is lost must still go under recovery
/// (issue 29 B, rule 8: `wsg-serial:0xac729dceeaab2b0d`, a home whose final reply arrived
/// damaged was never probed and held its caller 350 s, until another home came). It is probed
/// from the reply hold after it was sent, once per grace while the device moves, and released
/// on two "not moving" a grace apart, as any motion under recovery.
#[test]
fn a_connection_without_motion_timeout_still_recovers_a_motion_without_deadline() {
    let now = Instant::now();
    let never = after(now, Duration::MAX);
    let grace = Duration::from_millis(100);
    let query = Duration::from_secs(1);
    let mut p = Pairing::new(grace);
    p.set_holds(query, Duration::MAX);
    assert_eq!(sent(p.submit(req(1, 0x20, never), now)), Some(1));
    assert_eq!(
        p.on_reply(reply(0x20, Status::CmdPending), Instant::now),
        Event::Accepted(1)
    );
    // Its final reply is lost: the first probe is due the reply hold after the send.
    assert_eq!(p.next_due(), Some(now + query));
    assert!(p.due(now + query - Duration::from_millis(1)).is_empty());
    assert_eq!(p.due(now + query), vec![Due::Probe(0x20, 1)]);
    // Still moving: asked again a grace later, the caller still waits.
    let t = now + query;
    assert_eq!(
        p.on_probe(0x20, 1, Observation::Moving, t, 10),
        Verdict::Running(vec![])
    );
    assert_eq!(p.next_due(), Some(t + grace));
    assert_eq!(p.due(t + grace), vec![Due::Probe(0x20, 1)]);
    // The move ended; its final reply never comes: two "not moving" a grace apart end it.
    let t = t + grace;
    assert_eq!(
        p.on_probe(0x20, 1, Observation::Idle, t, 11),
        Verdict::Undecided
    );
    assert_eq!(p.due(t + grace), vec![Due::Probe(0x20, 1)]);
    assert_eq!(
        p.on_probe(0x20, 1, Observation::Idle, t + grace, 12),
        Verdict::Abandoned
    );
    assert!(!p.done(0x20));
    assert_eq!(p.next_due(), None);
}

/// A connection without query timeout either (`Duration::MAX`): the default query timeout
/// stands in for the reply hold, so nothing the holds bound is kept for ever. Above all the
/// client's own loop-back barriers, which have no deadline: one whose echo was lost was never
/// released, so never sent again, and its id stayed fenced for good.
#[test]
fn a_connection_without_any_timeout_still_bounds_its_holds() {
    let now = Instant::now();
    let never = after(now, Duration::MAX);
    let grace = Duration::from_millis(100);
    let resync = Duration::from_millis(500);
    let hold = super::super::DEFAULT_QUERY_TIMEOUT;
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    p.set_resync(resync);
    p.set_holds(Duration::MAX, Duration::MAX);
    assert_eq!(p.reply_hold(), hold);
    // A barrier (a loop-back without deadline) whose echo is lost: released, to be sent again.
    assert_eq!(sent(p.submit(req(1, id::LOOP, never), now)), Some(1));
    assert_eq!(p.next_due(), Some(now + hold + resync + grace));
    assert_eq!(
        p.due(now + hold + resync + grace),
        vec![Due::Released(id::LOOP, 1)]
    );
    // A call without timeout whose reply is lost: fenced after the hold.
    assert_eq!(sent(p.submit(req(2, 0x50, never), now)), Some(2));
    assert_eq!(p.due(now + hold + grace), vec![Due::Fenced(0x50, 2)]);
    // An acknowledged motion without timeout: probed from the hold on.
    assert_eq!(sent(p.submit(req(3, 0x20, never), now)), Some(3));
    assert_eq!(
        p.on_reply(reply(0x20, Status::CmdPending), Instant::now),
        Event::Accepted(3)
    );
    assert_eq!(p.due(now + hold), vec![Due::Probe(0x20, 3)]);
}

#[test]
fn an_acknowledged_non_motion_request_is_released_after_its_deadline_and_grace() {
    // Finger power (0x62) answers E_CMD_PENDING and its final reply "nach etwa 500 ms"
    // (3.6.3): a lost final reply must not hold the id for good. Its caller's deadline (here
    // at once) is not enough: the command has not ended then, and its final reply would come
    // after the release; the id is kept until it has ended (FINGER_POWER_ON_DURATION after
    // the send), plus the grace.
    let now = Instant::now();
    let grace = Duration::from_millis(500);
    let ended = now + FINGER_POWER_ON_DURATION + grace;
    let mut p = Pairing::new(grace);
    assert!(matches!(p.submit(req(1, 0x62, now), now), Submit::Send(_)));
    // Acknowledged at once (a later acknowledgement moves the release: its own test).
    assert_eq!(
        p.on_reply(reply(0x62, Status::CmdPending), || now),
        Event::Accepted(1)
    );
    assert!(matches!(p.submit(req(2, 0x62, now), now), Submit::Queued));
    assert_eq!(p.next_due(), Some(ended));
    assert!(p.due(now + grace).is_empty());
    assert_eq!(p.due(ended), vec![Due::Released(0x62, 1)]);
    assert_eq!(
        p.next(0x62, |_| true, Instant::now()).0.map(|r| r.token),
        Some(2)
    );
}

#[test]
fn a_second_motion_call_is_refused_only_when_a_probe_after_it_sees_the_device_move() {
    let now = Instant::now();
    let t = now + Duration::from_secs(10);
    let mut p = Pairing::new(Duration::from_secs(1));
    for id in [id::HOMING, id::PRE_POSITION, id::GRASP, id::RELEASE] {
        assert!(matches!(p.submit(req(1, id, t), now), Submit::Send(_)));
        // Not acknowledged yet: the second waits to see whether the first runs ...
        assert!(matches!(p.submit(req(2, id, t), now), Submit::Queued));
        assert_eq!(p.next_due(), Some(t + Duration::from_secs(1)));
        assert_eq!(
            p.on_reply(reply(id, Status::CmdPending), Instant::now),
            Event::Accepted(1)
        );
        // ... and once it does, the device is asked at once (no refusal on a belief).
        p.verify_queued(id, now);
        assert_eq!(p.next_due(), Some(now));
        assert_eq!(p.due(now), vec![Due::Probe(id, 1)]);
        // A call made after the probe went out (probe token 10) is not refused on it ...
        assert!(matches!(p.submit(req(11, id, t), now), Submit::Queued));
        assert_eq!(
            p.on_probe(id, 1, Observation::Moving, now, 10),
            Verdict::Running(vec![2])
        );
        // ... it gets a probe of its own, at once.
        assert_eq!(p.due(now), vec![Due::Probe(id, 1)]);
        assert_eq!(
            p.on_probe(id, 1, Observation::Moving, now, 12),
            Verdict::Running(vec![11])
        );
        // Nobody waits: no probe before the first call's deadline.
        assert_eq!(p.next_due(), Some(t));
        assert!(matches!(
            p.on_reply(reply(id, Status::Success), Instant::now),
            Event::Resolved(1, _)
        ));
        assert_eq!(p.next(id, |_| true, now).0.map(|r| r.token), None);
    }
    // A refused first call frees the id for the one queued behind it.
    assert!(matches!(p.submit(req(4, 0x21, t), now), Submit::Send(_)));
    assert!(matches!(p.submit(req(5, 0x21, t), now), Submit::Queued));
    assert!(matches!(
        p.on_reply(reply(0x21, Status::AccessDenied), Instant::now),
        Event::Resolved(4, _)
    ));
    assert_eq!(
        p.next(0x21, |_| true, Instant::now()).0.map(|r| r.token),
        Some(5)
    );
}

/// Issue 20.2 #1: a second call behind an acknowledged move whose final reply is lost is
/// sent once the device said twice, a grace apart, that it does not move, before the first
/// call's deadline: never refused on the belief that the move still runs.
#[test]
fn a_lost_final_reply_frees_the_id_for_a_waiting_call_before_the_deadline() {
    let now = Instant::now();
    let grace = Duration::from_millis(100);
    let t = now + Duration::from_secs(30);
    let mut p = Pairing::new(grace);
    assert!(matches!(p.submit(req(1, 0x21, t), now), Submit::Send(_)));
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(1)
    );
    assert!(matches!(p.submit(req(2, 0x21, t), now), Submit::Queued));
    assert_eq!(p.due(now), vec![Due::Probe(0x21, 1)]);
    assert_eq!(
        p.on_probe(0x21, 1, Observation::Idle, now, 3),
        Verdict::Undecided
    );
    assert_eq!(p.next_due(), Some(now + grace));
    assert_eq!(p.due(now + grace), vec![Due::Probe(0x21, 1)]);
    assert_eq!(
        p.on_probe(0x21, 1, Observation::Idle, now + grace, 4),
        Verdict::Abandoned
    );
    assert_eq!(
        p.next(0x21, |_| true, Instant::now()).0.map(|r| r.token),
        Some(2)
    );
}

#[test]
fn recovery_needs_two_idle_observations_a_grace_apart() {
    let now = Instant::now();
    let grace = Duration::from_millis(200);
    let deadline = now + Duration::from_secs(1);
    let mut p = Pairing::new(grace);
    assert!(matches!(
        p.submit(req(1, 0x25, deadline), now),
        Submit::Send(_)
    ));
    assert_eq!(
        p.on_reply(reply(0x25, Status::CmdPending), Instant::now),
        Event::Accepted(1)
    );
    // Nothing is due before the caller's deadline, and then a probe, never a release.
    assert_eq!(p.next_due(), Some(deadline));
    assert!(p.due(deadline - Duration::from_millis(1)).is_empty());
    assert_eq!(p.due(deadline), vec![Due::Probe(0x25, 1)]);
    assert_eq!(p.next_due(), None, "one probe at a time");
    // Past the deadline a new call waits for the verdict instead of being refused.
    let later = deadline + Duration::from_millis(1);
    assert!(matches!(
        p.submit(req(2, 0x25, later + grace), later),
        Submit::Queued
    ));
    // Moving: the waiting call is refused, the next probe comes a grace later.
    assert_eq!(
        p.on_probe(0x25, 1, Observation::Moving, later, 100),
        Verdict::Running(vec![2])
    );
    assert_eq!(p.next_due(), Some(later + grace));
    // One "idle" is not enough ...
    let t1 = later + grace;
    assert_eq!(p.due(t1), vec![Due::Probe(0x25, 1)]);
    assert_eq!(
        p.on_probe(0x25, 1, Observation::Idle, t1, 100),
        Verdict::Undecided
    );
    // ... a failed probe starts over ...
    assert_eq!(p.due(t1 + grace), vec![Due::Probe(0x25, 1)]);
    assert_eq!(
        p.on_probe(0x25, 1, Observation::Unknown, t1 + grace, 100),
        Verdict::Undecided
    );
    let t2 = t1 + grace * 2;
    assert_eq!(p.due(t2), vec![Due::Probe(0x25, 1)]);
    assert_eq!(
        p.on_probe(0x25, 1, Observation::Idle, t2, 100),
        Verdict::Undecided
    );
    // ... and a final reply in between ends the recovery: it answers its own request.
    assert!(matches!(
        p.submit(req(3, 0x25, t2 + grace), t2),
        Submit::Queued
    ));
    assert!(matches!(
        p.on_reply(reply(0x25, Status::AxisBlocked), Instant::now),
        Event::Resolved(1, r) if r.status == Status::AxisBlocked
    ));
    assert_eq!(
        p.on_probe(0x25, 1, Observation::Idle, t2 + grace, 100),
        Verdict::Undecided
    );
    let (next, _) = p.next(0x25, |_| true, Instant::now());
    let next = next.unwrap();
    assert_eq!(next.token, 3);
    // Two idle observations in a row with no final reply: abandoned, the id is free.
    assert_eq!(
        p.on_reply(reply(0x25, Status::CmdPending), Instant::now),
        Event::Accepted(3)
    );
    let d = next.deadline;
    assert_eq!(p.due(d), vec![Due::Probe(0x25, 3)]);
    assert_eq!(
        p.on_probe(0x25, 3, Observation::Idle, d, 100),
        Verdict::Undecided
    );
    assert_eq!(p.due(d + grace), vec![Due::Probe(0x25, 3)]);
    assert_eq!(
        p.on_probe(0x25, 3, Observation::Idle, d + grace, 100),
        Verdict::Abandoned
    );
    assert!(matches!(
        p.on_reply(reply(0x25, Status::Success), Instant::now),
        Event::Unsolicited(_)
    ));
}

/// The explorer's `wsg-tcp:0x8f85c166eeff961d`, distilled: a home under recovery gets a
/// first "not moving"; a call of the id queued then must not pull the second probe forward
/// (two "not moving" a few ms apart abandoned the home while its final reply, due up to
/// the Anhang B lag after the fingers stop, was still coming; it then completed the next
/// home). A second "not moving" less than a grace after the first does not abandon either.
#[test]
fn a_queued_call_pulls_only_the_first_recovery_probe_forward() {
    let now = Instant::now();
    let grace = Duration::from_millis(1000);
    let ms = Duration::from_millis;
    for deadline in [now + ms(100), after(now, Duration::MAX)] {
        let mut p = Pairing::new(grace);
        p.set_ordered(true);
        p.set_holds(ms(500), ms(100));
        assert!(matches!(
            p.submit(req(1, id::HOMING, deadline), now),
            Submit::Send(_)
        ));
        assert_eq!(
            p.on_reply(reply(id::HOMING, Status::CmdPending), Instant::now),
            Event::Accepted(1)
        );
        assert_eq!(p.due(now + ms(100)), vec![Due::Probe(id::HOMING, 1)]);
        let t1 = now + ms(110);
        assert_eq!(
            p.on_probe(id::HOMING, 1, Observation::Idle, t1, 2),
            Verdict::Undecided
        );
        // Another home queues 20 ms later: the next probe stays a grace after the first
        // "not moving" (and is due then even for a caller without a deadline).
        assert!(matches!(
            p.submit(req(3, id::HOMING, deadline), t1 + ms(20)),
            Submit::Queued
        ));
        p.verify_queued(id::HOMING, t1 + ms(20));
        assert_eq!(p.next_due(), Some(t1 + grace));
        assert!(p.due(t1 + ms(20)).is_empty());
        // Even a "not moving" that came sooner (a probe already out) does not abandon.
        assert_eq!(
            p.on_probe(id::HOMING, 1, Observation::Idle, t1 + ms(40), 4),
            Verdict::Undecided
        );
        // The home's final reply, 300 ms after the first "not moving", is its own.
        assert_eq!(
            p.on_reply(reply(id::HOMING, Status::Success), Instant::now),
            Event::Resolved(1, reply(id::HOMING, Status::Success))
        );
        assert_eq!(
            p.next(id::HOMING, |_| true, t1 + ms(300))
                .0
                .map(|r| r.token),
            Some(3)
        );
    }
}

#[test]
fn replies_that_cannot_answer_the_request_on_the_wire_are_unsolicited() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    let looped = |data: &'static [u8]| Reply::new(id::LOOP, Status::Success, data);
    let mut echo = req(1, id::LOOP, t);
    echo.frame.payload = Bytes::from_static(b"mine");
    assert!(matches!(p.submit(echo, now), Submit::Send(_)));
    // A copy of an earlier loop reply: another payload.
    assert_eq!(
        p.on_reply(looped(b"old"), Instant::now),
        Event::Unsolicited(looped(b"old"))
    );
    assert_eq!(
        p.on_reply(looped(b"mine"), Instant::now),
        Event::Resolved(1, looped(b"mine"))
    );
    // An acknowledged move refuses a duplicate of itself; its final reply still ends it.
    assert!(matches!(p.submit(req(2, 0x21, t), now), Submit::Send(_)));
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(2)
    );
    assert!(matches!(
        p.on_reply(reply(0x21, Status::AlreadyRunning), Instant::now),
        Event::Unsolicited(_)
    ));
    assert_eq!(
        p.on_reply(reply(0x21, Status::Success), Instant::now),
        Event::Resolved(2, reply(0x21, Status::Success))
    );
    // Not acknowledged: E_ALREADY_RUNNING is this request's own refusal.
    assert!(matches!(p.submit(req(3, 0x21, t), now), Submit::Send(_)));
    assert!(matches!(
        p.on_reply(reply(0x21, Status::AlreadyRunning), Instant::now),
        Event::Resolved(3, _)
    ));
}

/// Issue 20.2 #4: an E_CMD_PENDING reordered after its own final reply (UDP) must not make
/// the next request of the id count as surely acknowledged: its own E_ALREADY_RUNNING
/// would then be dropped as a duplicate's, and the call would wait until its deadline.
#[test]
fn a_pending_reordered_after_its_final_reply_does_not_swallow_the_next_refusal() {
    let now = Instant::now();
    let t = now + Duration::from_secs(30);
    let mut p = Pairing::new(Duration::from_secs(1));
    assert!(matches!(p.submit(req(1, 0x21, t), now), Submit::Send(_)));
    assert_eq!(
        p.on_reply(reply(0x21, Status::Success), Instant::now),
        Event::Resolved(1, reply(0x21, Status::Success))
    );
    assert_eq!(
        p.next(0x21, |_| true, Instant::now()).0.map(|r| r.token),
        None
    );
    assert!(matches!(p.submit(req(2, 0x21, t), now), Submit::Send(_)));
    // The first request's late E_CMD_PENDING (or the second's own: they cannot be told
    // apart) ...
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(2)
    );
    // ... so the device's refusal of the second still ends it.
    assert_eq!(
        p.on_reply(reply(0x21, Status::AlreadyRunning), Instant::now),
        Event::Resolved(2, reply(0x21, Status::AlreadyRunning))
    );
    // A request acknowledged with nothing owed still drops a duplicate's refusal.
    assert!(matches!(p.submit(req(3, 0x21, t), now), Submit::Send(_)));
    assert_eq!(
        p.on_reply(reply(0x21, Status::CmdPending), Instant::now),
        Event::Accepted(3)
    );
    assert!(matches!(
        p.on_reply(reply(0x21, Status::AlreadyRunning), Instant::now),
        Event::Unsolicited(_)
    ));
}

/// On an ordered transport an id released with no reply is fenced: its next request waits
/// for the barrier, and a reply of the id before it answers nothing. On UDP, or once the
/// request was acknowledged, it is released as before.
#[test]
fn an_id_released_without_a_reply_waits_for_its_barrier_on_an_ordered_transport() {
    let now = Instant::now();
    let t = now + Duration::from_millis(100);
    let grace = Duration::from_millis(50);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    assert!(matches!(p.submit(req(1, 0x43, t), now), Submit::Send(_)));
    assert!(matches!(p.submit(req(2, 0x43, t), now), Submit::Queued));
    assert_eq!(p.due(t + grace), vec![Due::Fenced(0x43, 1)]);
    // Fenced: nothing goes out, and a new call queues too.
    assert_eq!(
        p.next(0x43, |_| true, Instant::now()).0.map(|r| r.token),
        None
    );
    assert!(matches!(p.submit(req(3, 0x43, t), now), Submit::Queued));
    // The late reply answers nobody.
    assert!(matches!(
        p.on_reply(reply(0x43, Status::Success), Instant::now),
        Event::Unsolicited(_)
    ));
    p.unfence(0x43, now);
    for token in [2, 3] {
        assert_eq!(
            p.next(0x43, |_| true, Instant::now()).0.map(|r| r.token),
            Some(token)
        );
        assert!(matches!(
            p.on_reply(reply(0x43, Status::Success), Instant::now),
            Event::Resolved(t, _) if t == token
        ));
    }
    assert_eq!(
        p.next(0x43, |_| true, Instant::now()).0.map(|r| r.token),
        None
    );
    // A loop-back needs no barrier: its reply must echo its own payload.
    assert!(matches!(
        p.submit(req(4, id::LOOP, t), now),
        Submit::Send(_)
    ));
    assert_eq!(p.due(t + grace), vec![Due::Released(id::LOOP, 4)]);
    // (An acknowledged finger power on is fenced too, once its command has ended:
    // an_acknowledged_finger_power_on_is_fenced_on_an_ordered_transport.)
    // A released motion whose E_CMD_PENDING comes before the barrier runs after all: it is
    // back on the wire under recovery (probed at once), its final reply ends it.
    assert!(matches!(
        p.submit(req(6, id::GRASP, t), now),
        Submit::Send(_)
    ));
    assert_eq!(p.due(t + grace), vec![Due::Fenced(id::GRASP, 6)]);
    assert_eq!(
        p.on_reply(reply(id::GRASP, Status::CmdPending), Instant::now),
        Event::Accepted(6)
    );
    p.unfence(id::GRASP, now);
    assert_eq!(p.next(id::GRASP, |_| true, now).0.map(|r| r.token), None);
    assert_eq!(p.due(t + grace), vec![Due::Probe(id::GRASP, 6)]);
    assert!(matches!(
        p.on_reply(reply(id::GRASP, Status::Success), Instant::now),
        Event::Resolved(6, _)
    ));
    // Unordered (UDP): released as before.
    let mut p = Pairing::new(grace);
    assert!(matches!(p.submit(req(1, 0x43, t), now), Submit::Send(_)));
    assert_eq!(p.due(t + grace), vec![Due::Released(0x43, 1)]);
}

/// The explorer's `wsg-serial:0xfdb842249ad7b4b3`, distilled: finger power on is acknowledged,
/// its caller times out, and its final reply, sent when the command ended (3.6.3: "nach etwa
/// 500 ms"), is stalled on the stream past the grace. Released on time, that reply completed
/// the next finger power call. On an ordered transport the id is fenced instead: the device
/// sent the final reply before it received the barrier, so it comes before the echo and
/// answers nobody, and the next call goes out after the echo. On UDP it is released as before.
#[test]
fn an_acknowledged_finger_power_on_is_fenced_on_an_ordered_transport() {
    let now = Instant::now();
    let t = now + Duration::from_millis(100);
    let grace = Duration::from_millis(50);
    let ended = now + FINGER_POWER_ON_DURATION + grace;
    for ordered in [true, false] {
        let mut p = Pairing::new(grace);
        p.set_ordered(ordered);
        assert_eq!(sent(p.submit(req(1, id::FINGER1_POWER, t), now)), Some(1));
        // Acknowledged at once.
        assert_eq!(
            p.on_reply(reply(id::FINGER1_POWER, Status::CmdPending), || now),
            Event::Accepted(1)
        );
        assert!(matches!(
            p.submit(req(2, id::FINGER1_POWER, t), now),
            Submit::Queued
        ));
        // Not before the command has ended, whatever the caller's deadline.
        assert!(p.due(t + grace).is_empty());
        if !ordered {
            assert_eq!(p.due(ended), vec![Due::Released(id::FINGER1_POWER, 1)]);
            continue;
        }
        assert_eq!(p.due(ended), vec![Due::Fenced(id::FINGER1_POWER, 1)]);
        assert_eq!(
            p.next(id::FINGER1_POWER, |_| true, ended)
                .0
                .map(|r| r.token),
            None
        );
        // The stalled final reply, before the echo: it answers nobody.
        assert!(matches!(
            p.on_reply(reply(id::FINGER1_POWER, Status::Success), Instant::now),
            Event::Unsolicited(_)
        ));
        p.unfence(id::FINGER1_POWER, ended);
        assert_eq!(
            p.next(id::FINGER1_POWER, |_| true, ended)
                .0
                .map(|r| r.token),
            Some(2)
        );
        // The next call is answered by its own replies only.
        assert_eq!(
            p.on_reply(reply(id::FINGER1_POWER, Status::CmdPending), Instant::now),
            Event::Accepted(2)
        );
        assert!(matches!(
            p.on_reply(reply(id::FINGER1_POWER, Status::CmdFailed), Instant::now),
            Event::Resolved(2, _)
        ));
    }
}

/// The explorer's `wsg-tcp:0xe47e133ec0985c92`, distilled: finger power on's request is held on
/// the way past its caller's deadline, so the request is released unanswered and fenced; the
/// device receives it just before the barrier and acknowledges it before the echo. Its final
/// reply comes about FINGER_POWER_ON_DURATION later, after the echo: the id stays taken until
/// then, so that final reply does not complete the next finger power call. (Before the fix the
/// echo freed the id, and the next power-on returned the old one's E_SUCCESS at once.)
#[test]
fn a_finger_power_on_acknowledged_after_its_release_keeps_its_id_until_it_has_ended() {
    let now = Instant::now();
    let t = now + Duration::from_millis(100);
    let grace = Duration::from_millis(50);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    assert_eq!(sent(p.submit(req(1, id::FINGER1_POWER, t), now)), Some(1));
    assert_eq!(p.due(t + grace), vec![Due::Fenced(id::FINGER1_POWER, 1)]);
    assert!(matches!(
        p.submit(req(2, id::FINGER1_POWER, t + grace), t + grace),
        Submit::Queued
    ));
    // The late request reaches the device: its acknowledgement comes before the echo.
    let acked = t + Duration::from_secs(2);
    assert_eq!(
        p.on_reply(reply(id::FINGER1_POWER, Status::CmdPending), || acked),
        Event::Accepted(1)
    );
    p.unfence(id::FINGER1_POWER, acked);
    // The id is still taken: the command runs until about FINGER_POWER_ON_DURATION from now.
    assert_eq!(
        p.next(id::FINGER1_POWER, |_| true, acked)
            .0
            .map(|r| r.token),
        None
    );
    assert!(p.due(acked + FINGER_POWER_ON_DURATION).is_empty());
    // Its final reply answers it (its caller is gone), not the next call.
    assert!(matches!(
        p.on_reply(reply(id::FINGER1_POWER, Status::Success), || acked),
        Event::Resolved(1, _)
    ));
    assert_eq!(
        p.next(id::FINGER1_POWER, |_| true, acked)
            .0
            .map(|r| r.token),
        Some(2)
    );
    assert_eq!(
        p.on_reply(reply(id::FINGER1_POWER, Status::CmdPending), || acked),
        Event::Accepted(2)
    );
}

/// The explorer's `wsg-tcp:0x4214ee25a9542f20`, distilled: a finger power on held on the way
/// reaches the device late, and its E_CMD_PENDING comes back before its release. The device
/// ends it FINGER_POWER_ON_DURATION after it *received* it: the id is kept until then + grace
/// (counted from the acknowledgement), so its final reply answers it, not the next call.
/// (Before the fix the id was released at its write + FINGER_POWER_ON_DURATION + grace, the
/// echo freed it, and the next finger power call returned the old one's E_SUCCESS.)
#[test]
fn a_finger_power_on_acknowledged_late_keeps_its_id_until_it_has_ended() {
    let now = Instant::now();
    let t = now + Duration::from_millis(100);
    let grace = Duration::from_millis(50);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    assert_eq!(sent(p.submit(req(1, id::FINGER1_POWER, t), now)), Some(1));
    // Acknowledged 400 ms after the write, before its release (the write +
    // FINGER_POWER_ON_DURATION + grace; its caller's deadline + grace has passed).
    let acked = now + Duration::from_millis(400);
    assert!(acked > t + grace && acked < now + FINGER_POWER_ON_DURATION + grace);
    assert_eq!(
        p.on_reply(reply(id::FINGER1_POWER, Status::CmdPending), || acked),
        Event::Accepted(1)
    );
    // Past the write + FINGER_POWER_ON_DURATION + grace, and the deadline + grace: still kept.
    assert!(p.due(now + FINGER_POWER_ON_DURATION + grace).is_empty());
    assert!(p.due(acked + FINGER_POWER_ON_DURATION).is_empty());
    assert!(matches!(
        p.submit(
            req(2, id::FINGER1_POWER, acked + FINGER_POWER_ON_DURATION),
            acked
        ),
        Submit::Queued
    ));
    // Its final reply answers it (its caller is gone), not the next call.
    let ended = acked + FINGER_POWER_ON_DURATION;
    assert!(matches!(
        p.on_reply(reply(id::FINGER1_POWER, Status::Success), || ended),
        Event::Resolved(1, _)
    ));
    assert_eq!(
        p.next(id::FINGER1_POWER, |_| true, ended)
            .0
            .map(|r| r.token),
        Some(2)
    );
}

/// The explorer's `wsg-tcp:0xbd5fd685504fe279`, distilled: a home's E_CMD_PENDING is
/// corrupted (dropped), so the home is released with no reply at all and fenced; the
/// barrier comes back without it. The home runs nevertheless, and its final reply, later,
/// must not complete the next home (sent after the barrier, not acknowledged yet).
#[test]
fn a_released_motion_without_any_reply_stays_under_recovery_after_its_barrier() {
    let now = Instant::now();
    let t = now + Duration::from_millis(100);
    let grace = Duration::from_millis(50);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    assert!(matches!(
        p.submit(req(1, id::HOMING, t), now),
        Submit::Send(_)
    ));
    let echo = t + grace;
    assert_eq!(p.due(echo), vec![Due::Fenced(id::HOMING, 1)]);
    assert!(!p.unfence(id::HOMING, echo));
    // The next home waits: the device is asked whether it moves.
    assert!(matches!(
        p.submit(req(2, id::HOMING, echo + grace), echo),
        Submit::Queued
    ));
    assert_eq!(p.next(id::HOMING, |_| true, echo).0.map(|r| r.token), None);
    assert_eq!(p.due(echo), vec![Due::Probe(id::HOMING, 1)]);
    // The first home's final reply ends the first home (its caller is gone), not the next.
    assert_eq!(
        p.on_reply(reply(id::HOMING, Status::Success), Instant::now),
        Event::Resolved(1, reply(id::HOMING, Status::Success))
    );
    assert_eq!(
        p.next(id::HOMING, |_| true, echo).0.map(|r| r.token),
        Some(2)
    );
    assert_eq!(
        p.on_reply(reply(id::HOMING, Status::CmdPending), Instant::now),
        Event::Accepted(2)
    );
}

/// A released motion whose E_CMD_PENDING comes before its barrier's echo goes under
/// recovery on the normal schedule (the motion hold after it was sent), also for a caller
/// without timeout: its saturated deadline must not leave it unprobed for good.
#[test]
fn a_released_motion_accepted_before_its_barrier_is_probed_within_the_motion_hold() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let mut p = Pairing::new(ms(50));
    p.set_ordered(true);
    p.set_holds(ms(50), ms(300));
    let no_timeout = after(now, Duration::MAX);
    assert!(matches!(
        p.submit(req(1, id::HOMING, no_timeout), now),
        Submit::Send(_)
    ));
    assert_eq!(p.due(now + ms(100)), vec![Due::Fenced(id::HOMING, 1)]);
    assert_eq!(
        p.on_reply(reply(id::HOMING, Status::CmdPending), Instant::now),
        Event::Accepted(1)
    );
    assert_eq!(p.next_due(), Some(now + ms(300)));
    assert_eq!(p.due(now + ms(300)), vec![Due::Probe(id::HOMING, 1)]);
}

/// On an ordered transport an unanswered loop-back keeps its id the resync pause longer
/// than other requests (the line rests so that a device stuck on a corrupted length field
/// can drop it, `wsg-serial:0xae89110881bc3727`); a caller's loop-back with a timeout is
/// still released at its deadline + grace; UDP needs no pause.
#[test]
fn an_unanswered_loop_back_keeps_its_id_for_the_resync_pause_on_an_ordered_transport() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let never = after(now, Duration::MAX);
    for ordered in [true, false] {
        let mut p = Pairing::new(ms(100));
        p.set_ordered(ordered);
        p.set_holds(ms(100), ms(1000));
        p.set_resync(ms(500));
        assert_eq!(sent(p.submit(req(1, id::LOOP, never), now)), Some(1));
        assert_eq!(sent(p.submit(req(2, 0x50, never), now)), Some(2));
        let due = p.due(now + ms(200));
        assert_eq!(
            due.contains(&Due::Released(id::LOOP, 1)),
            !ordered,
            "{due:?}"
        );
        if ordered {
            assert_eq!(due, vec![Due::Fenced(0x50, 2)]);
            assert!(p.due(now + ms(699)).is_empty());
            assert_eq!(p.due(now + ms(700)), vec![Due::Released(id::LOOP, 1)]);
        }
        // A caller's loop-back with a timeout: its deadline + grace.
        assert_eq!(sent(p.submit(req(3, id::LOOP, now + ms(50)), now)), Some(3));
        assert_eq!(p.due(now + ms(150)), vec![Due::Released(id::LOOP, 3)]);
    }
}

/// Stops on an ordered transport: a barrier, not a resend, for a call that waits too long,
/// and its echo reaches the stops (see [`super::super::stops`] for the count itself).
#[test]
fn a_waiting_stop_call_gets_a_barrier_on_an_ordered_transport() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    p.set_ordered(true);
    assert_eq!(sent(p.submit(req(1, id::STOP, t), now)), Some(1));
    let at = now + super::super::stops::RESEND_AFTER;
    assert_eq!(p.due(at), vec![Due::StopBarrier(id::STOP)]);
    // The echo: the stop sent before it, unanswered, is lost; it is sent again.
    assert!(p.unfence(id::STOP, at));
    assert_eq!(
        p.on_reply(reply(id::STOP, Status::Success), Instant::now),
        Event::Stopped(vec![1], reply(id::STOP, Status::Success))
    );
    assert!(p.drain().is_empty());
}

/// Issue 29 E at the pairing: a stop whose caller timed out is still sent again once a barrier
/// proves it lost. A motion command the pairing hands out afterwards (sent at once, or later
/// from its id's queue) makes the next lost stop be dropped instead, once the device
/// acknowledged it or while its answer is still out; one the device refused at once ran
/// nothing, and a query moves nothing.
#[test]
fn a_lost_stop_is_owed_to_the_device_until_a_motion_is_sent_after_it() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let resend = super::super::stops::RESEND_AFTER;
    let mut p = Pairing::new(Duration::from_secs(1));
    p.set_ordered(true);
    // The caller's timeout (50 ms) ends before any re-send was due.
    assert_eq!(sent(p.submit(req(1, id::STOP, now + ms(50)), now)), Some(1));
    // A query sent after it, and a grasp the device refuses (E_ALREADY_RUNNING: the move
    // the stop was for still runs).
    assert_eq!(
        sent(p.submit(req(2, id::SYSTEM_STATE, now + ms(50)), now)),
        Some(2)
    );
    assert_eq!(
        sent(p.submit(req(3, id::GRASP, now + ms(50)), now)),
        Some(3)
    );
    assert!(matches!(
        p.on_reply(reply(id::GRASP, Status::AlreadyRunning), Instant::now),
        Event::Resolved(3, _)
    ));
    let at = now + resend;
    assert_eq!(p.next_due(), Some(at));
    assert_eq!(p.due(at), vec![Due::StopBarrier(id::STOP)]);
    assert!(p.unfence(id::STOP, at), "proven lost: sent again");
    // A grasp goes out (at once) after the re-sent stop, which is lost too, and the device
    // accepts it: the stop is dropped.
    assert_eq!(
        sent(p.submit(req(4, id::GRASP, at + ms(10_000)), at)),
        Some(4)
    );
    assert_eq!(
        p.on_reply(reply(id::GRASP, Status::CmdPending), Instant::now),
        Event::Accepted(4)
    );
    let at = at + resend;
    assert_eq!(p.due(at), vec![Due::StopBarrier(id::STOP)]);
    assert!(!p.unfence(id::STOP, at), "the program moved on");
    // A release goes out, then a stop call, then a release queued behind the first goes out
    // (from the queue) after the stop; its answer is still out at the echo: it decides.
    assert_eq!(
        sent(p.submit(req(5, id::RELEASE, at + ms(10_000)), at)),
        Some(5)
    );
    assert_eq!(sent(p.submit(req(6, id::STOP, at + ms(50)), at)), Some(6));
    assert!(matches!(
        p.submit(req(7, id::RELEASE, at + ms(10_000)), at),
        Submit::Queued
    ));
    assert!(matches!(
        p.on_reply(reply(id::RELEASE, Status::NotInitialized), Instant::now),
        Event::Resolved(5, _)
    ));
    assert_eq!(
        p.next(id::RELEASE, |_| true, at).0.map(|r| r.token),
        Some(7)
    );
    let at = at + resend;
    assert_eq!(p.due(at), vec![Due::StopBarrier(id::STOP)]);
    assert!(
        !p.unfence(id::STOP, at),
        "the queued release went out after it"
    );
    assert!(p.due(at).is_empty(), "waits for the release's answer");
    // Refused: it ran nothing, and the stop goes out again.
    assert!(matches!(
        p.on_reply(reply(id::RELEASE, Status::AlreadyRunning), Instant::now),
        Event::Resolved(7, _)
    ));
    assert!(p.next_due().is_some_and(|due| due <= at));
    assert_eq!(p.due(at), vec![Due::ResendStop(id::STOP)]);
    // Its reply: the timed-out calls (never pruned: no stop call since) are answered, and
    // the task finds their waiters gone.
    assert_eq!(
        p.on_reply(reply(id::STOP, Status::Success), Instant::now),
        Event::Stopped(vec![1, 6], reply(id::STOP, Status::Success))
    );
}

/// The explorer's `wsg-serial:0x69627d80b4046207`, distilled: a stop lost, then a motion sent
/// after it whose request was lost too (no answer at all). At the stop's echo the motion's
/// answer decides; none comes, and the released motion goes under recovery. Two "not moving" a
/// grace apart say it does not run: the stop is owed again, at once (before: it waited until a
/// later motion was refused, 28 s into the run).
#[test]
fn a_lost_stop_is_owed_again_once_the_motion_sent_after_it_is_found_idle() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let grace = ms(100);
    let resend = super::super::stops::RESEND_AFTER;
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    assert_eq!(sent(p.submit(req(1, id::STOP, now + ms(50)), now)), Some(1));
    let deadline = now + ms(60);
    assert_eq!(
        sent(p.submit(req(2, id::PRE_POSITION, deadline), now)),
        Some(2)
    );
    let at = now + resend;
    assert_eq!(p.due(at), vec![Due::StopBarrier(id::STOP)]);
    assert!(!p.unfence(id::STOP, at), "the motion's answer decides");
    // The motion got no answer: released at its deadline + grace, fenced, under recovery
    // after its own barrier.
    let released = deadline + grace;
    assert!(p.due(released).contains(&Due::Fenced(id::PRE_POSITION, 2)));
    assert!(!p.unfence(id::PRE_POSITION, released));
    assert_eq!(p.due(released), vec![Due::Probe(id::PRE_POSITION, 2)]);
    assert_eq!(
        p.on_probe(id::PRE_POSITION, 2, Observation::Idle, released, 10),
        Verdict::Undecided
    );
    let second = released + grace;
    assert_eq!(
        p.on_probe(id::PRE_POSITION, 2, Observation::Idle, second, 11),
        Verdict::Abandoned
    );
    assert_eq!(p.due(second), vec![Due::ResendStop(id::STOP)]);
}

#[test]
fn prune_drops_only_queued_dead_callers() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    assert!(matches!(p.submit(req(1, 0x50, t), now), Submit::Send(_)));
    for token in 2..=5 {
        assert!(matches!(p.submit(req(token, 0x50, t), now), Submit::Queued));
    }
    assert_eq!(p.prune(0x50, |t| t == 1 || t == 4, now), vec![2, 3, 5]);
    assert!(matches!(
        p.on_reply(reply(0x50, Status::Success), Instant::now),
        Event::Resolved(1, _)
    ));
    let (next, skipped) = p.next(0x50, |_| true, Instant::now());
    assert_eq!(next.map(|r| r.token), Some(4));
    assert!(skipped.is_empty());
    assert_eq!(p.drain(), vec![4]);
}

proptest::proptest! {
    /// Any interleaving of calls (three ids, some asynchronous) and device replies: every
    /// final reply reaches the request it answers, one request per id is on the wire, and
    /// every call is sent once.
    #[test]
    fn replies_always_reach_their_own_request(
        ops in proptest::collection::vec((0u8..3, proptest::bool::ANY, proptest::bool::ANY), 1..200)
    ) {
        use std::collections::{HashMap, VecDeque};
        let deadline = Instant::now() + Duration::from_secs(60);
        let mut p = Pairing::new(Duration::from_secs(1));
        // What the device has received and not finally answered, per id: (token, async, acked).
        let mut wire: HashMap<u8, VecDeque<(Token, bool, bool)>> = HashMap::new();
        let mut is_async: HashMap<Token, bool> = HashMap::new();
        let mut sent = 0u64;
        let mut resolved = 0u64;
        let mut next_token = 0;
        for (id, submit, asynchronous) in ops {
            if submit {
                next_token += 1;
                is_async.insert(next_token, asynchronous);
                let r = Request { token: next_token, frame: Frame::new(id, Bytes::new()), deadline };
                if let Submit::Send(r) = p.submit(r, Instant::now()) {
                    wire.entry(id).or_default().push_back((r.token, asynchronous, false));
                    sent += 1;
                }
            } else if let Some(front) = wire.get_mut(&id).and_then(|q| q.front_mut()) {
                let (token, asynchronous, acked) = *front;
                if asynchronous && !acked {
                    front.2 = true;
                    proptest::prop_assert_eq!(p.on_reply(reply(id, Status::CmdPending), Instant::now), Event::Accepted(token));
                    continue;
                }
                wire.get_mut(&id).map(VecDeque::pop_front);
                // The reply carries the token it answers, so a mix-up shows.
                let r = Reply::new(id, Status::Success, Bytes::copy_from_slice(&token.to_le_bytes()));
                match p.on_reply(r, Instant::now) {
                    Event::Resolved(t, r) => {
                        proptest::prop_assert_eq!(&t.to_le_bytes()[..], &r.data[..]);
                        resolved += 1;
                    }
                    other => proptest::prop_assert!(false, "{:?}", other),
                }
                let (next, skipped) = p.next(id, |_| true, Instant::now());
                proptest::prop_assert!(skipped.is_empty());
                if let Some(r) = next {
                    let asynchronous = is_async[&r.token];
                    wire.entry(id).or_default().push_back((r.token, asynchronous, false));
                    sent += 1;
                }
            }
            for q in wire.values() {
                proptest::prop_assert!(q.len() <= 1, "two requests of one id on the wire");
            }
        }
        let waiting = p.drain().len() as u64;
        proptest::prop_assert_eq!(resolved + waiting, next_token);
        proptest::prop_assert!(sent >= resolved);
    }
}

/// A caller's own timeout wins over the connection's holds (issue 20 follow-up): a request
/// whose caller waits longer than the reply hold keeps its id until its own deadline + grace,
/// and its reply up to then resolves it; once the caller is found gone (a call of the id
/// queues), the hold bounds it again. Same for an acknowledged motion: probed from its
/// caller's deadline, or from the motion hold once the caller is gone.
#[test]
fn a_per_call_timeout_longer_than_the_holds_keeps_its_id_until_its_own_deadline() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let grace = ms(100);
    let (query, motion) = (ms(1000), ms(2000));
    for ordered in [false, true] {
        let mut p = Pairing::new(grace);
        p.set_ordered(ordered);
        p.set_holds(query, motion);
        // A 10 s query, answered after 5 s: between the hold (1.1 s) and its deadline.
        assert_eq!(sent(p.submit(req(1, 0x43, now + ms(10_000)), now)), Some(1));
        assert_eq!(p.next_due(), Some(now + ms(10_100)));
        assert!(p.due(now + query + grace).is_empty());
        assert!(p.due(now + ms(5000)).is_empty());
        assert_eq!(
            p.on_reply(reply(0x43, Status::Success), Instant::now),
            Event::Resolved(1, reply(0x43, Status::Success))
        );

        // Unanswered: released at its own deadline + grace, not at the hold.
        assert_eq!(sent(p.submit(req(2, 0x43, now + ms(10_000)), now)), Some(2));
        assert!(p.due(now + ms(10_099)).is_empty());
        let released = if ordered {
            Due::Fenced(0x43, 2)
        } else {
            Due::Released(0x43, 2)
        };
        assert_eq!(p.due(now + ms(10_100)), vec![released]);

        // A caller that went away: the next call of the id finds it gone, and the hold bounds
        // the request from its send on (nobody waits for the long deadline).
        assert_eq!(sent(p.submit(req(3, 0x44, now + ms(10_000)), now)), Some(3));
        // Gone after its deadline: it timed out, and keeps its id its grace past it.
        assert!(p.prune(0x44, |t| t != 3, now + ms(10_000)).is_empty());
        assert_eq!(p.next_due(), Some(now + ms(10_100)));
        // Gone before: the hold bounds it.
        assert!(p.prune(0x44, |t| t != 3, now + ms(500)).is_empty());
        assert!(matches!(
            p.submit(req(4, 0x44, now + ms(10_000)), now + ms(500)),
            Submit::Queued
        ));
        assert_eq!(p.next_due(), Some(now + query + grace));
        let released = if ordered {
            Due::Fenced(0x44, 3)
        } else {
            Due::Released(0x44, 3)
        };
        assert_eq!(p.due(now + query + grace), vec![released]);

        // An acknowledged motion whose caller waits 10 s: no probe at the motion hold, only
        // from its deadline; once its caller is gone, from the motion hold.
        assert_eq!(
            sent(p.submit(req(5, id::GRASP, now + ms(10_000)), now)),
            Some(5)
        );
        assert_eq!(
            p.on_reply(reply(id::GRASP, Status::CmdPending), Instant::now),
            Event::Accepted(5)
        );
        assert_eq!(p.next_due(), Some(now + ms(10_000)));
        assert!(p.due(now + motion).is_empty());
        assert!(p.prune(id::GRASP, |t| t != 5, now + motion).is_empty());
        assert_eq!(p.next_due(), Some(now + motion));
        assert_eq!(p.due(now + motion), vec![Due::Probe(id::GRASP, 5)]);
    }
}

/// A motion command's caller waits with the motion timeout, but the device acknowledges it at
/// once (1.3): a motion whose request or E_CMD_PENDING was lost is released the reply hold +
/// grace after it was sent, not at its caller's deadline (with per-call timeouts winning over
/// the holds, a lost `home` datagram on UDP failed only after the 30 s motion timeout). Once
/// acknowledged, it goes under recovery at its caller's deadline.
#[test]
fn a_motion_waits_for_its_acknowledgement_only_the_reply_hold() {
    let now = Instant::now();
    let ms = Duration::from_millis;
    let grace = ms(100);
    let (query, motion) = (ms(1000), ms(30_000));
    for ordered in [false, true] {
        let mut p = Pairing::new(grace);
        p.set_ordered(ordered);
        p.set_holds(query, motion);
        assert_eq!(
            sent(p.submit(req(1, id::HOMING, now + motion), now)),
            Some(1)
        );
        assert_eq!(p.next_due(), Some(now + query + grace));
        let released = if ordered {
            Due::Fenced(id::HOMING, 1)
        } else {
            Due::Released(id::HOMING, 1)
        };
        assert_eq!(p.due(now + query + grace), vec![released]);

        // Acknowledged: the hold no longer applies; recovery starts at the deadline.
        let mut p = Pairing::new(grace);
        p.set_ordered(ordered);
        p.set_holds(query, motion);
        assert_eq!(
            sent(p.submit(req(2, id::HOMING, now + motion), now)),
            Some(2)
        );
        assert_eq!(
            p.on_reply(reply(id::HOMING, Status::CmdPending), Instant::now),
            Event::Accepted(2)
        );
        assert!(p.due(now + query + grace).is_empty());
        assert_eq!(p.next_due(), Some(now + motion));
    }
}

/// The outputs waiting, in a form a test can compare.
fn outputs(p: &mut Pairing) -> Vec<String> {
    std::iter::from_fn(|| p.poll())
        .map(|o| match o {
            Output::Complete(t, Ok(r)) => format!("ok {t} {:#x} {:?}", r.id, &r.data[..]),
            Output::Complete(t, Err(e)) => match e {
                Error::ReplyLost { command } => format!("lost {t} {command:#x}"),
                Error::Device { command, status } => format!("{status:?} {t} {command:#x}"),
                Error::Timeout { command, timeout } => {
                    format!("timeout {t} {command:#x} {timeout:?}")
                }
                Error::MalformedReply { command, .. } => format!("malformed {t} {command:#x}"),
                e => format!("error {t} {e}"),
            },
            Output::Update(r) => format!("update {:#x} {:?}", r.id, &r.data[..]),
            Output::Value(r) => format!("value {:#x} {:?}", r.id, &r.data[..]),
            Output::Request(kind) => format!("{kind:?}"),
            Output::SendStop(id) => format!("stop {id:#x}"),
            Output::Resend(r) => format!("resend {} {:#x}", r.token, r.frame.id),
            Output::Next(id) => format!("next {id:#x}"),
        })
        .collect()
}

/// A system state reply (manual 3.4.1): SF_MOVING (bit 1) set or not.
fn system_state(moving: bool) -> Reply {
    let flags: u32 = if moving { 1 << 1 } else { 0 };
    Reply::new(
        id::SYSTEM_STATE,
        Status::Success,
        Bytes::copy_from_slice(&flags.to_le_bytes()),
    )
}

/// Issue 30: the pairing makes its recovery probes itself, decodes their system state and
/// says which calls complete with what: "moving" refuses the calls queued before the probe,
/// two "not moving" a grace apart end the motion with `ReplyLost`; a probe's E_SUCCESS
/// answer is a value for the subscribers of 0x40 too.
#[test]
fn the_pairing_interprets_its_own_probes() {
    let now = Instant::now();
    let grace = Duration::from_secs(1);
    let t = now + Duration::from_secs(10);
    let mut p = Pairing::new(grace);
    p.set_holds(Duration::from_secs(1), Duration::from_secs(30));
    let home = p.token();
    assert!(matches!(
        p.submit(req(home, id::HOMING, t), now),
        Submit::Send(_)
    ));
    let second = p.token();
    assert!(matches!(
        p.submit(req(second, id::HOMING, t), now),
        Submit::Queued
    ));
    assert_eq!(
        p.receive(reply(id::HOMING, Status::CmdPending), || now),
        None
    );
    assert!(outputs(&mut p).is_empty());
    // A call waits behind the acknowledged move: the device is asked at once.
    p.expire(now);
    assert_eq!(outputs(&mut p), ["Probe { id: 32, token: 1 }"]);
    let probe = p.request(
        Internal::Probe {
            id: id::HOMING,
            token: home,
        },
        now,
    );
    assert_eq!((probe.token, probe.frame.id), (3, id::SYSTEM_STATE));
    assert_eq!(probe.deadline, now + Duration::from_secs(1));
    assert!(matches!(p.submit(probe, now), Submit::Send(_)));
    assert_eq!(p.receive(system_state(true), || now), None);
    assert_eq!(
        outputs(&mut p),
        [
            "value 0x40 [2, 0, 0, 0]",
            "AlreadyRunning 2 0x20",
            "next 0x40"
        ]
    );
    // Nobody waits any more: the next probe at the caller's deadline.
    assert_eq!(p.next_due(), Some(t));
    p.expire(t);
    assert_eq!(outputs(&mut p), ["Probe { id: 32, token: 1 }"]);
    let probe = p.request(
        Internal::Probe {
            id: id::HOMING,
            token: home,
        },
        t,
    );
    assert!(matches!(p.submit(probe, t), Submit::Send(_)));
    assert_eq!(p.receive(system_state(false), || t), None);
    assert_eq!(outputs(&mut p), ["value 0x40 [0, 0, 0, 0]", "next 0x40"]);
    // A malformed answer observes nothing: the first "not moving" no longer counts.
    p.expire(t + grace);
    assert_eq!(outputs(&mut p), ["Probe { id: 32, token: 1 }"]);
    let probe = p.request(
        Internal::Probe {
            id: id::HOMING,
            token: home,
        },
        t + grace,
    );
    assert!(matches!(p.submit(probe, t + grace), Submit::Send(_)));
    p.receive_malformed(id::SYSTEM_STATE, "too short", || t + grace);
    assert_eq!(outputs(&mut p), ["next 0x40"]);
    // Two "not moving" a grace apart: the final reply is lost.
    for at in [t + grace * 2, t + grace * 3] {
        p.expire(at);
        assert_eq!(outputs(&mut p), ["Probe { id: 32, token: 1 }"]);
        let probe = p.request(
            Internal::Probe {
                id: id::HOMING,
                token: home,
            },
            at,
        );
        assert!(matches!(p.submit(probe, at), Submit::Send(_)));
        assert_eq!(p.receive(system_state(false), || at), None);
        if at == t + grace * 2 {
            assert_eq!(outputs(&mut p), ["value 0x40 [0, 0, 0, 0]", "next 0x40"]);
        }
    }
    assert_eq!(
        outputs(&mut p),
        [
            "value 0x40 [0, 0, 0, 0]",
            "lost 1 0x20",
            "next 0x20",
            "next 0x40"
        ]
    );
    assert!(p.internal.is_empty());
}

/// Issue 30: on an ordered transport the pairing fences a released id with a barrier of its
/// own, sends another when one is refused, and frees the id when its echo comes; the caller
/// still waiting gets its timeout. A barrier is never pruned (no caller waits for it).
#[test]
fn the_pairing_interprets_its_own_barriers() {
    let now = Instant::now();
    let grace = Duration::from_millis(50);
    let t = now + Duration::from_millis(100);
    let mut p = Pairing::new(grace);
    p.set_ordered(true);
    p.set_holds(Duration::from_millis(100), Duration::from_secs(1));
    let first = p.token();
    assert!(matches!(
        p.submit(req(first, 0x43, t), now),
        Submit::Send(_)
    ));
    let second = p.token();
    let later = t + Duration::from_secs(10);
    assert!(matches!(
        p.submit(req(second, 0x43, later), now),
        Submit::Queued
    ));
    p.expire(t + grace);
    assert_eq!(
        outputs(&mut p),
        ["timeout 1 0x43 100ms", "Barrier { id: 67, refused: 0 }"]
    );
    let barrier = p.request(
        Internal::Barrier {
            id: 0x43,
            refused: 0,
        },
        t + grace,
    );
    assert_eq!(barrier.frame.id, id::LOOP);
    assert_eq!(barrier.frame.payload.len() + 2, BARRIER_ECHO_LEN);
    assert!(matches!(p.submit(barrier, t + grace), Submit::Send(_)));
    assert!(p.prune(id::LOOP, |_| false, t + grace).is_empty());
    // Refused (a stale answer, say): another barrier.
    assert_eq!(
        p.receive(reply(id::LOOP, Status::AccessDenied), || t + grace),
        None
    );
    assert_eq!(
        outputs(&mut p),
        ["Barrier { id: 67, refused: 1 }", "next 0x6"]
    );
    let barrier = p.request(
        Internal::Barrier {
            id: 0x43,
            refused: 1,
        },
        t + grace,
    );
    let echo = Reply::new(id::LOOP, Status::Success, barrier.frame.payload.clone());
    assert!(matches!(p.submit(barrier, t + grace), Submit::Send(_)));
    // The late reply of the released request answers nobody; the echo frees the id.
    assert_eq!(p.receive(reply(0x43, Status::Success), || t + grace), None);
    assert_eq!(outputs(&mut p), ["update 0x43 []"]);
    assert_eq!(p.receive(echo, || t + grace), None);
    assert_eq!(outputs(&mut p), ["next 0x43", "next 0x6"]);
    assert_eq!(
        p.next(0x43, |_| true, t + grace).0.map(|r| r.token),
        Some(second)
    );
    // A fence whose barriers are refused again and again is given up after three.
    let lone = p.token();
    assert!(matches!(p.submit(req(lone, 0x50, t), now), Submit::Send(_)));
    p.expire(t + grace);
    assert_eq!(
        outputs(&mut p),
        ["timeout 5 0x50 100ms", "Barrier { id: 80, refused: 0 }"]
    );
    for refused in 0..3 {
        let barrier = p.request(Internal::Barrier { id: 0x50, refused }, t + grace);
        assert!(matches!(p.submit(barrier, t + grace), Submit::Send(_)));
        p.receive_malformed(id::LOOP, "too short", || t + grace);
        let again = format!("Barrier {{ id: 80, refused: {} }}", refused + 1);
        let expected: Vec<&str> = if refused < 2 {
            vec![&again, "next 0x6"]
        } else {
            vec!["next 0x50", "next 0x6"]
        };
        assert_eq!(outputs(&mut p), expected);
    }
    assert!(p.internal.is_empty());
}

/// The explorer's `wsg-serial:0xc592a5bd282c39eb`: a stop's loop-back (its echo proves the
/// stop lost, and only then is it sent again) goes ahead of the loop-backs queued for fenced
/// ids, not behind them: there it waited 7 s, and the stop went out again 12.5 s after its
/// call.
#[test]
fn a_lost_stops_barrier_goes_ahead_of_other_ids_barriers() {
    let now = Instant::now();
    let mut p = Pairing::new(Duration::from_millis(50));
    p.set_ordered(true);
    let barrier = |p: &mut Pairing, id: u8| p.request(Internal::Barrier { id, refused: 0 }, now);
    let on_wire = barrier(&mut p, 0x43);
    let echo = Reply::new(id::LOOP, Status::Success, on_wire.frame.payload.clone());
    assert!(matches!(p.submit(on_wire, now), Submit::Send(_)));
    for fenced in [0x40, 0x41, 0x44] {
        let queued = barrier(&mut p, fenced);
        assert!(matches!(p.submit(queued, now), Submit::Queued));
    }
    let stop = barrier(&mut p, id::STOP);
    let stop_token = stop.token;
    assert!(matches!(p.submit(stop, now), Submit::Queued));
    assert_eq!(p.receive(echo, || now), None);
    outputs(&mut p);
    assert_eq!(
        p.next(id::LOOP, |_| true, now).0.map(|r| r.token),
        Some(stop_token)
    );
}

/// Issue 30: a query of a streamed id is settled by the pairing's own barrier: the last
/// E_SUCCESS frame of the id before the echo completes it (each frame went to the
/// subscribers as it came).
#[test]
fn the_pairing_settles_a_streamed_query_with_its_own_barrier() {
    let now = Instant::now();
    let t = now + Duration::from_secs(1);
    let mut p = Pairing::new(Duration::from_secs(1));
    p.set_ordered(true);
    let query = p.token();
    assert!(matches!(
        p.submit(req(query, 0x43, t), now),
        Submit::Send(_)
    ));
    let barrier = p.settle_barrier(0x43, query, now);
    let echo = Reply::new(id::LOOP, Status::Success, barrier.frame.payload.clone());
    assert!(matches!(p.submit(barrier, now), Submit::Send(_)));
    for v in [1u8, 2] {
        assert_eq!(
            p.receive(Reply::new(0x43, Status::Success, vec![v]), || now),
            None
        );
    }
    assert_eq!(p.receive(echo, || now), None);
    assert_eq!(
        outputs(&mut p),
        [
            "update 0x43 [1]",
            "update 0x43 [2]",
            "next 0x43",
            "ok 1 0x43 [2]",
            "next 0x6"
        ]
    );
    // A call's reply is handed back directly (the hot path), with no output.
    let call = p.token();
    assert!(matches!(p.submit(req(call, 0x50, t), now), Submit::Send(_)));
    let answer = Reply::new(0x50, Status::Success, vec![7]);
    assert_eq!(p.receive(answer.clone(), || now), Some((call, answer)));
    assert!(outputs(&mut p).is_empty());
    let call = p.token();
    assert!(matches!(p.submit(req(call, 0x50, t), now), Submit::Send(_)));
    p.receive_malformed(0x50, "too short", || now);
    assert_eq!(outputs(&mut p), ["malformed 4 0x50", "next 0x50"]);
    assert!(p.internal.is_empty());
}
