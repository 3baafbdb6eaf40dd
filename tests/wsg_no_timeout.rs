//! Calls without timeout (`Duration::MAX`) whose final reply is lost must still end (issue 29
//! B): over a loopback TCP socket, against a scripted device that acknowledges a command
//! (E_CMD_PENDING) and never sends its final reply.

mod common;

use common::within;
use std::net::SocketAddr;
use std::time::Duration;

use bytes::BytesMut;
use futures_util::StreamExt;
use gripper::wsg::command::id;
use gripper::wsg::frame::{self, Frame};
use gripper::wsg::{Client, Error, Finger, UpdateOptions, WsgCodec};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpListener;
use tokio_util::codec::FramedRead;

/// E_CMD_PENDING (manual, status codes): the command runs, its final reply follows.
const CMD_PENDING: u16 = 26;

fn reply(command: u8, status: u16, data: &[u8]) -> Vec<u8> {
    let mut payload = status.to_le_bytes().to_vec();
    payload.extend_from_slice(data);
    let mut b = BytesMut::new();
    frame::encode(&Frame::new(command, payload), &mut b).unwrap();
    b.to_vec()
}

/// A TCP "gripper" that acknowledges every command with E_CMD_PENDING and never sends its
/// final reply (the reply lost), but answers loop-backs (0x06) with their echo and system
/// state (0x40) with "no flag set" (not moving).
async fn device_losing_final_replies() -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (socket, _) = listener.accept().await.unwrap();
        let (read, mut write) = socket.into_split();
        let mut requests = FramedRead::new(read, WsgCodec::new());
        while let Some(Ok(request)) = requests.next().await {
            let bytes = match request.id {
                id::LOOP => reply(id::LOOP, 0, &request.payload),
                0x40 => reply(0x40, 0, &[0, 0, 0, 0]),
                other => reply(other, CMD_PENDING, &[]),
            };
            if write.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    addr
}

async fn client(addr: SocketAddr) -> Client {
    Client::builder()
        .query_timeout(Duration::from_millis(200))
        // The motion hold: when a motion without timeout goes under recovery.
        .motion_timeout(Duration::from_millis(300))
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(addr)
        .await
        .unwrap()
}

/// A motion without timeout, acknowledged, whose final reply is lost: two "not moving" a grace
/// apart prove it lost, and the call fails with `ReplyLost`. Before the fix the probe after
/// the first "not moving" was scheduled at the caller's (saturated) deadline: never.
#[tokio::test]
async fn an_acknowledged_motion_without_timeout_whose_final_reply_is_lost_ends() {
    let client = client(device_losing_final_replies().await).await;
    let forever = client.with_timeouts(Duration::from_millis(200), Duration::MAX);
    let moved = within("pre_position", forever.pre_position(20.0, 50.0)).await;
    assert!(
        matches!(moved, Err(Error::ReplyLost { command: 0x21 })),
        "{moved:?}"
    );
}

/// Finger power on without timeout, acknowledged, whose final reply is lost: released by the
/// reply hold plus the power-on time, not never.
#[tokio::test]
async fn an_acknowledged_finger_power_on_without_timeout_whose_final_reply_is_lost_ends() {
    let client = client(device_losing_final_replies().await).await;
    let forever = client.with_timeouts(Duration::MAX, Duration::MAX);
    let powered = within(
        "finger power on",
        forever.set_finger_power(Finger::One, true),
    )
    .await;
    assert!(matches!(powered, Err(Error::Timeout { .. })), "{powered:?}");
}

/// The same while system state (0x40) is streamed: a probe's query is then answered through a
/// loop-back barrier (the last 0x40 frame before its echo), and that answer was dropped instead
/// of reaching the recovery, so the motion kept a probe out for ever and its id stayed held
/// (the explorer's wsg-serial:0x81263a75df4c46d4).
#[tokio::test]
async fn a_probe_answered_through_a_barrier_still_counts() {
    let client = client(device_losing_final_replies().await).await;
    let _states = within(
        "subscribe",
        client.subscribe_system_state(UpdateOptions::periodic(Duration::from_millis(100))),
    )
    .await
    .unwrap();
    let forever = client.with_timeouts(Duration::from_millis(200), Duration::MAX);
    let moved = within("pre_position", forever.pre_position(20.0, 50.0)).await;
    assert!(
        matches!(moved, Err(Error::ReplyLost { command: 0x21 })),
        "{moved:?}"
    );
}

/// A connection without motion timeout (`ClientBuilder::motion_timeout(Duration::MAX)`): a
/// motion called with the connection's timeouts has no deadline, and no motion hold bounds it
/// either. Its final reply lost, it must still go under recovery and end (issue 29 B, rule 8
/// of the explorer: `wsg-serial:0xac729dceeaab2b0d`, a home whose final reply arrived damaged
/// was never probed and held its caller until another home came 350 s later).
#[tokio::test]
async fn a_motion_on_a_connection_without_motion_timeout_whose_final_reply_is_lost_ends() {
    let client = Client::builder()
        .query_timeout(Duration::from_millis(200))
        .motion_timeout(Duration::MAX)
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(device_losing_final_replies().await)
        .await
        .unwrap();
    let moved = within("pre_position", client.pre_position(20.0, 50.0)).await;
    assert!(
        matches!(moved, Err(Error::ReplyLost { command: 0x21 })),
        "{moved:?}"
    );
}
