//! Replies that come late or twice must never answer a later request of their id (issue 20
//! follow-up, found by the explorer): raw "grippers" on loopback sockets that answer exactly
//! as the schedule needs, each answer naming the request it answers.

mod common;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bytes::BytesMut;
use common::within;
use gripper::wsg::command::id;
use gripper::wsg::frame::{self, Frame};
use gripper::wsg::Client;
use tokio::net::UdpSocket;

/// A reply frame of `command` with E_SUCCESS and `data`.
fn reply(command: u8, data: &[u8]) -> Vec<u8> {
    let mut payload = vec![0, 0];
    payload.extend_from_slice(data);
    let mut b = BytesMut::new();
    frame::encode(&Frame::new(command, payload), &mut b).unwrap();
    b.to_vec()
}

/// A loop-back's echo.
fn echo(request: &Frame) -> Vec<u8> {
    reply(id::LOOP, &request.payload)
}

/// The answer to the `n`th width request (from 0): `n + 1` mm, so each answer names its request.
fn width_reply(n: usize) -> Vec<u8> {
    reply(id::WIDTH, &(n as f32 + 1.0).to_le_bytes())
}

/// A UDP "gripper" that answers the first width request twice (a duplicated datagram) and every
/// later one once. Both copies are sent from one poll of its task, so on this single-threaded
/// runtime both are in the client's socket buffer before the client reads the first.
async fn duplicating_udp_device() -> SocketAddr {
    let socket = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let addr = socket.local_addr().unwrap();
    tokio::spawn(async move {
        let mut buf = [0u8; 512];
        let mut n = 0;
        while let Ok((len, from)) = socket.recv_from(&mut buf).await {
            if len < frame::HEADER_LEN || buf[3] != id::WIDTH {
                continue;
            }
            let answer = width_reply(n);
            let copies = if n == 0 { 2 } else { 1 };
            for _ in 0..copies {
                socket.send_to(&answer, from).await.unwrap();
            }
            n += 1;
        }
    });
    addr
}

/// (a) UDP: the copy of a reply, already received when its original was paired, answered the
/// next request of its id, which was sent from inside the pairing of the original
/// (`wsg-udp:0x96519dd7d49df4ae`). A frame already received cannot answer a request sent after
/// it: it is paired (here: dropped as unsolicited) before the next request goes out.
#[tokio::test]
async fn a_duplicated_reply_already_received_never_answers_the_next_request_of_its_id() {
    let addr = duplicating_udp_device().await;
    let client = Client::builder().connect_udp(addr).await.unwrap();
    // The second call queues behind the first (one request per id on the wire) and goes out
    // when the first's reply is paired.
    let (first, second) = within("widths", async {
        tokio::join!(client.width_mm(), client.width_mm())
    })
    .await;
    assert_eq!(first.unwrap(), 1.0);
    assert_eq!(
        second.unwrap(),
        2.0,
        "the copy of the first reply answered the second request"
    );
}

/// A TCP "gripper" that handles its requests one after the other, in order, as the device's
/// command interpreter does: the first width request takes `slow` (a device or link stalled
/// past the caller's timeout plus the late-reply grace), every later request is answered at
/// once. Loop-back requests get `loop_answer`; each one received is counted in `loops`.
async fn slow_first_tcp_device(
    slow: Duration,
    loop_answer: fn(&Frame) -> Vec<u8>,
    loops: Arc<AtomicUsize>,
) -> SocketAddr {
    let mut widths = 0;
    common::wsg_tcp_device(move |request| {
        // Counted as read; only the first width request's answer is stalled.
        let (stall, answer) = match request.id {
            id::WIDTH => {
                widths += 1;
                ((widths == 1).then_some(slow), width_reply(widths - 1))
            }
            id::LOOP => {
                loops.fetch_add(1, Ordering::SeqCst);
                (None, loop_answer(&request))
            }
            other => (None, reply(other, &[])),
        };
        async move {
            if let Some(stall) = stall {
                tokio::time::sleep(stall).await;
            }
            answer
        }
    })
    .await
}

/// A client of the TCP "gripper" at `addr` with a 50 ms late-reply grace, whose first call
/// (`call` on a handle with a 100 ms timeout) timed out: where the TCP tests below start, the
/// device's answer to that call is still to come (stalled past the timeout plus the grace).
async fn first_call_timed_out<T: std::fmt::Debug, F>(
    addr: SocketAddr,
    what: &str,
    call: impl FnOnce(Client) -> F,
) -> Client
where
    F: std::future::Future<Output = gripper::wsg::Result<T>>,
{
    let client = Client::builder()
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(addr)
        .await
        .unwrap();
    let impatient = client.with_timeouts(Duration::from_millis(100), Duration::from_secs(1));
    let first = within(what, call(impatient)).await;
    assert!(
        matches!(first, Err(gripper::wsg::Error::Timeout { .. })),
        "{first:?}"
    );
    client
}

/// (b) TCP: a reply stalled past its request's timeout plus the grace answered the next request
/// of its id (`wsg-tcp:0xe9966f076d4f365c`). On an ordered stream that is provably avoidable:
/// the next request waits until the echo of a loop-back sent after the release comes back,
/// and a reply of the id before that echo is the stale one.
#[tokio::test]
async fn a_reply_stalled_past_the_grace_never_answers_the_next_request_on_tcp() {
    let loops = Arc::new(AtomicUsize::new(0));
    let addr = slow_first_tcp_device(Duration::from_millis(600), echo, loops.clone()).await;
    let client =
        first_call_timed_out(addr, "first width", |c| async move { c.width_mm().await }).await;
    // Queued behind the first request, the second goes out once its id is released (the
    // first's deadline plus the grace), while the first's reply is still on its way.
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    let second = within("second width", patient.width_mm()).await.unwrap();
    assert_eq!(
        second, 2.0,
        "the stalled reply of the first request answered the second"
    );
    // The link goes on.
    assert_eq!(
        &within("loop", client.loop_back(&b"after"[..]))
            .await
            .unwrap()[..],
        b"after"
    );
}

/// (b) A device that answers no loop-back with its echo (here: E_CMD_UNKNOWN) must not make the
/// client send barriers as fast as it answers: after three refusals the fenced id is released
/// as on UDP, and its next call is sent and answered.
#[tokio::test]
async fn a_device_that_refuses_every_barrier_gets_three_and_the_id_goes_on() {
    let loops = Arc::new(AtomicUsize::new(0));
    let refuse = |_: &Frame| {
        let mut b = BytesMut::new();
        frame::encode(&Frame::new(id::LOOP, vec![0x0E, 0]), &mut b).unwrap();
        b.to_vec()
    };
    let addr = slow_first_tcp_device(Duration::from_millis(300), refuse, loops.clone()).await;
    let client =
        first_call_timed_out(addr, "first width", |c| async move { c.width_mm().await }).await;
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    // The stalled reply came before the refusals: still not taken for this call.
    assert_eq!(
        within("second width", patient.width_mm()).await.unwrap(),
        2.0
    );
    assert_eq!(loops.load(Ordering::SeqCst), 3, "barriers sent");
}

/// A reply frame of `command` with status `status` and no data.
fn status_reply(command: u8, status: u16) -> Vec<u8> {
    let mut b = BytesMut::new();
    frame::encode(&Frame::new(command, status.to_le_bytes().to_vec()), &mut b).unwrap();
    b.to_vec()
}

/// E_CMD_PENDING and E_CMD_FAILED (manual, Anhang A).
const CMD_PENDING: u16 = 26;
const CMD_FAILED: u16 = 18;

/// A TCP "gripper" that acknowledges the first finger power on (0x62, manual 3.6.3) at once,
/// then stalls its output: the on's final E_SUCCESS, sent when the power-on ended, waits on the
/// link until the device has read its next request, and is written just before that request's
/// own answer (the stream keeps the order the device sent in). Loop-backs are echoed; every
/// later finger power on is acknowledged and then fails (E_CMD_FAILED), so its answer tells it
/// apart from the first one's.
async fn stalled_finger_power_device() -> SocketAddr {
    let mut stalled: Vec<u8> = Vec::new();
    let mut powers = 0;
    common::wsg_tcp_device(move |request| {
        let mut answer = std::mem::take(&mut stalled);
        match request.id {
            id::FINGER1_POWER if powers == 0 => {
                powers += 1;
                answer.extend(status_reply(id::FINGER1_POWER, CMD_PENDING));
                stalled = status_reply(id::FINGER1_POWER, 0);
            }
            id::FINGER1_POWER => {
                answer.extend(status_reply(id::FINGER1_POWER, CMD_PENDING));
                answer.extend(status_reply(id::FINGER1_POWER, CMD_FAILED));
            }
            id::LOOP => answer.extend(echo(&request)),
            other => answer.extend(reply(other, &[])),
        }
        std::future::ready(answer)
    })
    .await
}

/// (c) TCP: finger power on, acknowledged, its caller timed out; its final reply, stalled on
/// the link past the grace, completed the next finger power call
/// (`wsg-serial:0xfdb842249ad7b4b3`). On an ordered stream the id is fenced: the final reply
/// was sent before the device received the barrier, so it comes before the echo, and the next
/// call is answered by its own replies.
#[tokio::test]
async fn a_finger_power_final_reply_stalled_past_the_grace_never_answers_the_next_call() {
    the_next_finger_power_call_gets_its_own_answer(stalled_finger_power_device().await, true).await;
}

/// A first finger power on to `addr` times out; the next finger power call (`on`) gets its own
/// answer, the device's E_CMD_FAILED (each device below fails it), never the first's E_SUCCESS.
async fn the_next_finger_power_call_gets_its_own_answer(addr: SocketAddr, on: bool) {
    let client = first_call_timed_out(addr, "first finger power on", |c| async move {
        c.set_finger_power(gripper::wsg::Finger::One, true).await
    })
    .await;
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    let second = within(
        "second finger power call",
        patient.set_finger_power(gripper::wsg::Finger::One, on),
    )
    .await;
    assert!(
        matches!(
            second,
            Err(gripper::wsg::Error::Device {
                command: id::FINGER1_POWER,
                status: gripper::wsg::Status::CmdFailed
            })
        ),
        "the first call's final reply answered the second: {second:?}"
    );
}

/// A TCP "gripper" whose first finger power on reaches it 400 ms after it was written (held on
/// the way, the requests behind it too): it acknowledges it then and ends it
/// `FINGER_POWER_ON_DURATION` later, sending the final E_SUCCESS with whatever it answers next
/// once that time has come (a later finger power waits for it, as the device's interpreter
/// does). The later finger power on is acknowledged and fails (E_CMD_FAILED), so its answer
/// tells it from the first's.
async fn late_received_finger_power_device() -> SocketAddr {
    use gripper::wsg::client::FINGER_POWER_ON_DURATION;
    use tokio::time::{sleep_until, Instant};
    let mut final_due: Option<Instant> = None;
    let mut powers = 0;
    common::wsg_tcp_device(move |request| {
        let now = Instant::now();
        let mut wait_until = None;
        let mut answer = Vec::new();
        match request.id {
            id::FINGER1_POWER if powers == 0 => {
                // The first: received 400 ms from now, acknowledged then.
                powers += 1;
                let received = now + Duration::from_millis(400);
                final_due = Some(received + FINGER_POWER_ON_DURATION);
                wait_until = Some(received);
                answer.extend(status_reply(id::FINGER1_POWER, CMD_PENDING));
            }
            id::FINGER1_POWER => {
                // The next one: the first's final reply goes first, when it is due.
                if let Some(due) = final_due.take() {
                    answer.extend(status_reply(id::FINGER1_POWER, 0));
                    wait_until = Some(due);
                }
                answer.extend(status_reply(id::FINGER1_POWER, CMD_PENDING));
                answer.extend(status_reply(id::FINGER1_POWER, CMD_FAILED));
            }
            other => {
                if final_due.take_if(|due| now >= *due).is_some() {
                    answer.extend(status_reply(id::FINGER1_POWER, 0));
                }
                answer.extend(if other == id::LOOP {
                    echo(&request)
                } else {
                    reply(other, &[])
                });
            }
        }
        async move {
            if let Some(at) = wait_until {
                sleep_until(at).await;
            }
            answer
        }
    })
    .await
}

/// (d) TCP: finger power on held on the way reached the device 630 ms after it was written, and
/// its E_CMD_PENDING came back before the id's release, counted from the write
/// (`wsg-tcp:0x4214ee25a9542f20`). The device ends it `FINGER_POWER_ON_DURATION` after it
/// received it: released earlier, the id's barrier came back before that final reply, and the
/// next finger power call returned the first's E_SUCCESS. The id is now kept until
/// `FINGER_POWER_ON_DURATION` + grace after the acknowledgement.
#[tokio::test]
async fn a_finger_power_on_received_late_never_answers_the_next_call() {
    the_next_finger_power_call_gets_its_own_answer(
        late_received_finger_power_device().await,
        false,
    )
    .await;
}
