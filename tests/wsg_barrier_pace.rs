//! A device that answers nothing must get pauses (issue 20, promise 5, found by the explorer:
//! `wsg-serial:0xa5e34824226a756b`). A request whose length field was corrupted on the way can
//! leave the device's decoder waiting for a frame of thousands of bytes; a decoder that drops a
//! partial frame once the line falls silent (as the crate's simulator does) recovers only if the
//! client stops talking for a moment. The client's loop-back barriers (one per command id
//! released without a reply, `src/wsg/client/task.rs`) must therefore each wait their full
//! time from when they are sent, not from when they were queued: a barrier queued behind
//! another was released as soon as it went out and sent again at once, so that with a few
//! fenced ids the line never fell silent and every later call of those ids timed out.

use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::command::id;
use gripper::wsg::Client;
use tokio::time::Instant;

/// Query timeout and grace of the client below: an unanswered request, a barrier included,
/// keeps its id this long from when it is sent (`query_timeout + late_reply_grace`).
const QUERY: Duration = Duration::from_millis(100);
const GRACE: Duration = Duration::from_millis(100);

/// Three queries of different ids time out (the device answers nothing), so three ids are
/// fenced and three barriers queue on the loop-back id. Every barrier must be given its full
/// time on the wire: between two loop-backs the device receives, at least the query timeout
/// plus the grace pass (without the fix, the queued barriers followed each other at once).
#[tokio::test(start_paused = true)]
async fn barriers_of_several_fenced_ids_leave_the_line_silent_between_them() {
    let (ours, theirs) = tokio::io::duplex(1 << 16);
    // The "device": reads every frame, answers none, notes when each loop-back came.
    let device = tokio::spawn(async move {
        let mut frames = tokio_util::codec::FramedRead::new(theirs, gripper::wsg::WsgCodec::new());
        let mut loops = Vec::new();
        let start = Instant::now();
        while let Ok(Some(Ok(frame))) =
            tokio::time::timeout(Duration::from_secs(30), frames.next()).await
        {
            if frame.id == id::LOOP {
                loops.push(Instant::now() - start);
            }
            if start.elapsed() > Duration::from_secs(3) {
                break;
            }
        }
        loops
    });
    let client = Client::builder()
        .query_timeout(QUERY)
        .late_reply_grace(GRACE)
        .attach(ours);
    let (a, b, c) = tokio::join!(client.width_mm(), client.grip_state(), client.system_info());
    assert!(a.is_err() && b.is_err() && c.is_err(), "{a:?} {b:?} {c:?}");
    let loops = device.await.unwrap();
    assert!(loops.len() >= 3, "barriers sent: {loops:?}");
    for pair in loops.windows(2) {
        assert!(
            pair[1] - pair[0] >= QUERY + GRACE,
            "a barrier went out {:?} after the previous one, before that one's time was up \
             (all loop-backs: {loops:?})",
            pair[1] - pair[0]
        );
    }
    drop(client);
}

/// How long the device below needs the line silent to drop a frame it is stuck on: the
/// simulator's rule, and the client's default partial frame timeout.
const RESYNC: Duration = gripper::wsg::client::DEFAULT_PARTIAL_FRAME_TIMEOUT;

/// A device whose decoder is stuck on a request with a corrupted length field (a header
/// announcing 2072 bytes): it swallows every byte until the line has been silent for
/// [`RESYNC`], then drops the stuck header and decodes what it swallowed, as the crate's
/// simulator does. From then on it echoes loop-backs and answers width queries (12.5 mm).
async fn stuck_device(io: tokio::io::DuplexStream) {
    use gripper::wsg::frame::{self, Decoded, DEFAULT_MAX_PAYLOAD_LEN};
    use gripper::wsg::{Reply, Status};
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let (mut rd, mut wr) = tokio::io::split(io);
    let mut buf = bytes::BytesMut::from(&[0xAA, 0xAA, 0xAA, id::WIDTH, 0x18, 0x08][..]);
    let mut stuck = true;
    let mut chunk = [0u8; 512];
    loop {
        let read = if stuck {
            tokio::time::timeout(RESYNC, rd.read(&mut chunk)).await
        } else {
            Ok(rd.read(&mut chunk).await)
        };
        match read {
            Err(_) => {
                // Silent for RESYNC: the stuck header goes, what came after it is decoded.
                stuck = false;
                bytes::Buf::advance(&mut buf, 6);
            }
            Ok(Ok(0) | Err(_)) => return,
            Ok(Ok(n)) => buf.extend_from_slice(&chunk[..n]),
        }
        if stuck {
            continue;
        }
        while let Some(decoded) = frame::decode(&mut buf, DEFAULT_MAX_PAYLOAD_LEN) {
            let Decoded::Frame(f) = decoded else { continue };
            let reply = match f.id {
                id::LOOP => Reply::new(id::LOOP, Status::Success, f.payload),
                id::WIDTH => Reply::new(id::WIDTH, Status::Success, 12.5f32.to_le_bytes().to_vec()),
                _ => continue,
            };
            let mut out = bytes::BytesMut::new();
            frame::encode(&reply.to_frame(), &mut out).unwrap();
            if wr.write_all(&out).await.is_err() {
                return;
            }
        }
    }
}

/// Promise 5 of issue 20 (`wsg-serial:0xae89110881bc3727`): with a query timeout + grace
/// below the device's resync silence, the barriers of a fenced id, one per query timeout +
/// grace, never left the line silent long enough: the device stayed stuck and the id fenced,
/// and every later call of it timed out. An unanswered loop-back now keeps its id the partial
/// frame timeout longer (`Pairing::set_resync`): the line rests, the device resynchronises,
/// the barrier's echo comes and the id works again. Also for a client whose own partial
/// frame timeout is shorter than the device's resync silence (the rest is at least the
/// default: `wsg-serial:0xcacf521c96086ae6`).
#[tokio::test(start_paused = true)]
async fn a_device_stuck_on_a_corrupted_length_gets_the_silence_it_needs() {
    assert!(QUERY + GRACE < RESYNC);
    for partial_frame_timeout in [RESYNC, Duration::from_millis(50)] {
        let (ours, theirs) = tokio::io::duplex(1 << 16);
        let device = tokio::spawn(stuck_device(theirs));
        let client = Client::builder()
            .query_timeout(QUERY)
            .late_reply_grace(GRACE)
            .partial_frame_timeout(partial_frame_timeout)
            .attach(ours);
        // Swallowed: times out, and its id is fenced.
        assert!(client.width_mm().await.is_err());
        tokio::time::sleep(Duration::from_secs(3)).await;
        assert_eq!(
            client.width_mm().await.unwrap(),
            12.5,
            "partial frame timeout {partial_frame_timeout:?}"
        );
        drop(client);
        device.abort();
    }
}

/// A device that answers neither the first width query nor the first loop-back (both lost),
/// then echoes every loop-back and answers every width query (12.5 mm). Returns when each
/// loop-back came.
async fn losing_first_device(io: tokio::io::DuplexStream) -> Vec<Duration> {
    use gripper::wsg::{Reply, Status};
    use tokio::io::AsyncWriteExt;
    let (rd, mut wr) = tokio::io::split(io);
    let mut frames = tokio_util::codec::FramedRead::new(rd, gripper::wsg::WsgCodec::new());
    let (mut widths, mut loops) = (0, Vec::new());
    let start = Instant::now();
    while let Some(Ok(f)) = frames.next().await {
        let reply = match f.id {
            id::LOOP => {
                loops.push(Instant::now() - start);
                if loops.len() == 1 {
                    continue;
                }
                Reply::new(id::LOOP, Status::Success, f.payload)
            }
            id::WIDTH => {
                widths += 1;
                if widths == 1 {
                    continue;
                }
                Reply::new(id::WIDTH, Status::Success, 12.5f32.to_le_bytes().to_vec())
            }
            _ => continue,
        };
        let mut out = bytes::BytesMut::new();
        gripper::wsg::frame::encode(&reply.to_frame(), &mut out).unwrap();
        if wr.write_all(&out).await.is_err() {
            break;
        }
    }
    loops
}

/// A client built without query timeout (`query_timeout(Duration::MAX)`): a barrier is a
/// loop-back without deadline, kept by the reply hold, which was that Duration::MAX. A barrier
/// whose echo was lost was then never sent again, and its id stayed fenced for good: every
/// later call of the id timed out. The reply hold falls back to the default query timeout, so
/// the barrier goes out again, paced (the default query timeout + the resync pause + grace
/// after the first), and the id works again.
#[tokio::test(start_paused = true)]
async fn a_lost_barrier_is_sent_again_on_a_client_without_query_timeout() {
    let (ours, theirs) = tokio::io::duplex(1 << 16);
    let device = tokio::spawn(losing_first_device(theirs));
    let client = Client::builder()
        .query_timeout(Duration::MAX)
        .late_reply_grace(GRACE)
        .attach(ours);
    let impatient = client.with_timeouts(QUERY, QUERY);
    assert!(impatient.width_mm().await.is_err());
    let patient = client.with_timeouts(Duration::from_secs(30), Duration::from_secs(30));
    assert_eq!(patient.width_mm().await.unwrap(), 12.5);
    drop((client, impatient, patient));
    let loops = device.await.unwrap();
    assert_eq!(loops.len(), 2, "loop-backs received: {loops:?}");
    assert!(
        loops[1] - loops[0] >= gripper::wsg::client::DEFAULT_QUERY_TIMEOUT + RESYNC + GRACE,
        "the barrier went out again too soon: {loops:?}"
    );
}

/// How long the device below takes to echo a loop-back (and so to read the next frame): below
/// a loop-back's time on the wire (`QUERY` + `RESYNC` + `GRACE`), so none is given up.
const ECHO: Duration = Duration::from_millis(300);

/// The explorer's `wsg-serial:0xc592a5bd282c39eb`: a stop damaged on the way is sent again at
/// the echo of a loop-back that proves it lost. That loop-back queued behind the barriers of
/// other ids released without a reply, each as slow to come back as the device is, and the
/// stop went out again 12.5 s after its call. Three queries time out (the device answers
/// none), three barriers take the loop-back id; the device drops the first stop and echoes
/// each loop-back `ECHO` after it came. The stop's loop-back goes next, ahead of the queued
/// barriers: the stop reaches the device within the re-send interval and two echoes.
#[tokio::test(start_paused = true)]
async fn a_lost_stops_loop_back_does_not_wait_behind_other_ids_barriers() {
    use gripper::wsg::client::RESEND_STOP_AFTER;
    use gripper::wsg::frame;
    use gripper::wsg::{Reply, Status};
    use tokio::io::AsyncWriteExt;
    assert!(ECHO < QUERY + RESYNC + GRACE);
    let (ours, theirs) = tokio::io::duplex(1 << 16);
    let t0 = Instant::now();
    // The "device": answers no query, drops the first stop (as if its checksum were damaged),
    // answers later stops, echoes loop-backs; notes when each stop came.
    let device = tokio::spawn(async move {
        let (rd, mut wr) = tokio::io::split(theirs);
        let mut frames = tokio_util::codec::FramedRead::new(rd, gripper::wsg::WsgCodec::new());
        let mut stops = Vec::new();
        while let Ok(Some(Ok(f))) =
            tokio::time::timeout(Duration::from_secs(10), frames.next()).await
        {
            let reply = match f.id {
                id::STOP => {
                    stops.push(Instant::now());
                    if stops.len() == 1 {
                        continue;
                    }
                    Reply::new(id::STOP, Status::Success, Vec::new())
                }
                id::LOOP => {
                    tokio::time::sleep(ECHO).await;
                    Reply::new(id::LOOP, Status::Success, f.payload)
                }
                _ => continue,
            };
            let mut out = bytes::BytesMut::new();
            frame::encode(&reply.to_frame(), &mut out).unwrap();
            if wr.write_all(&out).await.is_err() {
                break;
            }
        }
        stops
    });
    let client = Client::builder()
        .query_timeout(QUERY)
        .late_reply_grace(GRACE)
        .attach(ours);
    let (a, b, c) = tokio::join!(client.width_mm(), client.grip_state(), client.system_info());
    assert!(a.is_err() && b.is_err() && c.is_err(), "{a:?} {b:?} {c:?}");
    // The three ids are fenced, their barriers on and queued for the loop-back id.
    tokio::time::sleep_until(t0 + QUERY + GRACE + Duration::from_millis(50)).await;
    let called = Instant::now();
    let short = Duration::from_millis(30);
    assert!(short < RESEND_STOP_AFTER);
    let stop = client.with_timeouts(short, short).stop().await;
    assert!(stop.is_err(), "the dropped stop's call: {stop:?}");
    let stops = device.await.unwrap();
    assert!(
        stops.len() >= 2,
        "the lost stop was never sent again: {stops:?}"
    );
    let resent = stops[1] - called;
    assert!(
        resent <= RESEND_STOP_AFTER + 2 * ECHO + Duration::from_millis(50),
        "the lost stop went out again {resent:?} after its call (its loop-back queued behind \
         the other ids' barriers)"
    );
    drop(client);
}
