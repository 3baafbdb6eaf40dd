//! A per-call timeout is the timeout the call gets (issue 20 follow-up): a handle from
//! `Client::with_timeouts` with a query timeout longer than the connection's hears a device
//! that answers between the two, and a call that does time out names its own timeout. Before,
//! the connection's reply hold released the request at the connection's query timeout +
//! grace, and the call failed with an error naming the connection's timeout. Raw "grippers"
//! on loopback sockets, on tokio's paused clock (the device's delay costs no wall time).

mod common;

use std::future::Future;
use std::net::SocketAddr;
use std::time::Duration;

use bytes::BytesMut;
use gripper::wsg::command::id;
use gripper::wsg::frame::{self, Frame};
use gripper::wsg::{Client, Error};

/// The connection's query timeout and grace: the per-call timeout below is longer than both.
const QUERY: Duration = Duration::from_secs(1);
const GRACE: Duration = Duration::from_secs(2);
/// The per-call timeout.
const PER_CALL: Duration = Duration::from_secs(10);
/// The device's delays, one per width request in turn: the first between the connection's
/// hold (query + grace) and the per-call timeout, the second past the per-call timeout.
const DELAYS: [Duration; 2] = [Duration::from_secs(5), Duration::from_secs(15)];

/// A reply frame of `command` with E_SUCCESS and `data`.
fn reply(command: u8, data: &[u8]) -> Vec<u8> {
    let mut payload = vec![0, 0];
    payload.extend_from_slice(data);
    let mut b = BytesMut::new();
    frame::encode(&Frame::new(command, payload), &mut b).unwrap();
    b.to_vec()
}

/// The answer to a request: a width of `n + 1` mm for the `n`th width request (from 0, counted
/// in `widths` as the request is read), after its delay, so each answer names its request; an
/// echo for a loop-back; an empty E_SUCCESS otherwise. The count moves on before the answer is
/// awaited, so the answer owns all it needs (a device's task holds it across its delay).
fn answer(request: Frame, widths: &mut usize) -> impl Future<Output = Vec<u8>> + Send + 'static {
    let n = *widths;
    if request.id == id::WIDTH {
        *widths += 1;
    }
    async move {
        match request.id {
            id::WIDTH => {
                tokio::time::sleep(DELAYS.get(n).copied().unwrap_or_default()).await;
                reply(id::WIDTH, &(n as f32 + 1.0).to_le_bytes())
            }
            id::LOOP => reply(id::LOOP, &request.payload),
            other => reply(other, &[]),
        }
    }
}

/// A TCP "gripper" that answers its requests one after the other, in order.
async fn slow_tcp_device() -> SocketAddr {
    let mut widths = 0;
    common::wsg_tcp_device(move |request| answer(request, &mut widths)).await
}

/// A UDP "gripper" that answers its requests one after the other.
async fn slow_udp_device() -> SocketAddr {
    let socket = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let addr = socket.local_addr().unwrap();
    tokio::spawn(async move {
        let mut buf = [0u8; 512];
        let mut widths = 0;
        while let Ok((len, from)) = socket.recv_from(&mut buf).await {
            let mut bytes = BytesMut::from(&buf[..len]);
            let Some(frame::Decoded::Frame(request)) =
                frame::decode(&mut bytes, frame::DEFAULT_MAX_PAYLOAD_LEN)
            else {
                continue;
            };
            let bytes = answer(request, &mut widths).await;
            let _ = socket.send_to(&bytes, from).await;
        }
    });
    addr
}

/// The scenario on one connection: the device's answer after 5 s reaches a 10 s call (the
/// connection's query timeout is 1 s, its grace 2 s), and a call the device answers after
/// 15 s fails with a timeout naming 10 s, after 10 s (not after the connection's 1 s + 2 s).
async fn per_call_timeout_wins(client: Client) {
    let patient = client.with_timeouts(PER_CALL, PER_CALL);
    let start = tokio::time::Instant::now();
    let width = patient.width_mm().await;
    assert_eq!(
        width.unwrap(),
        1.0,
        "a reply within the per-call timeout is the call's"
    );
    assert_eq!(start.elapsed(), DELAYS[0]);

    let start = tokio::time::Instant::now();
    let late = patient.width_mm().await;
    assert!(
        matches!(late, Err(Error::Timeout { command: id::WIDTH, timeout }) if timeout == PER_CALL),
        "the error names the timeout applied: {late:?}"
    );
    assert_eq!(start.elapsed(), PER_CALL);
}

#[tokio::test(start_paused = true)]
async fn a_per_call_timeout_longer_than_the_connections_is_the_one_applied_on_tcp() {
    let addr = slow_tcp_device().await;
    let client = Client::builder()
        .query_timeout(QUERY)
        .late_reply_grace(GRACE)
        .connect_tcp(addr)
        .await
        .unwrap();
    per_call_timeout_wins(client).await;
}

#[tokio::test(start_paused = true)]
async fn a_per_call_timeout_longer_than_the_connections_is_the_one_applied_on_udp() {
    let addr = slow_udp_device().await;
    let client = Client::builder()
        .query_timeout(QUERY)
        .late_reply_grace(GRACE)
        .connect_udp(addr)
        .await
        .unwrap();
    per_call_timeout_wins(client).await;
}

/// A motion's caller waits with the motion timeout, but its E_CMD_PENDING comes at once
/// (manual 1.3): a `home` whose datagram the device never got fails once the connection's
/// query timeout + grace have passed since it was sent, naming the query timeout, not after
/// the 30 s motion timeout (which the first cut of the per-call rule waited for).
#[tokio::test(start_paused = true)]
async fn a_motion_without_acknowledgement_fails_after_the_query_timeout_and_grace() {
    // A "gripper" that hears nothing (the request datagram is lost on the way).
    let deaf = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let client = Client::builder()
        .query_timeout(QUERY)
        .late_reply_grace(GRACE)
        .motion_timeout(Duration::from_secs(30))
        .connect_udp(deaf.local_addr().unwrap())
        .await
        .unwrap();
    let start = tokio::time::Instant::now();
    let home = client.home(gripper::wsg::HomingDirection::Default).await;
    assert!(
        matches!(home, Err(Error::Timeout { command: id::HOMING, timeout }) if timeout == QUERY),
        "the error names the timeout applied: {home:?}"
    );
    assert_eq!(start.elapsed(), QUERY + GRACE);
    drop(deaf);
}
