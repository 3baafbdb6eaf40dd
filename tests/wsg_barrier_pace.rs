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
