//! The WSG client's wrong answers found in issue 20 (part 2), each pinned by a test that failed
//! before its fix: over loopback sockets against the in-process simulator.
#![cfg(feature = "sim")]

mod common;

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::BytesMut;
use futures_util::StreamExt;
use gripper::wsg::frame::{self, Frame};
use gripper::wsg::WsgCodec;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, UdpSocket};
use tokio_util::codec::FramedRead;

use common::within;
use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Error, HomingDirection, Status, SystemState};

fn config() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

/// "No timeout" (`Duration::MAX`) is ordinary input: every duration the builder and the calls
/// take saturates instead of overflowing an `Instant`, in the caller or in the task.
#[tokio::test]
async fn duration_max_anywhere_never_panics() {
    let sim = SimServer::bind("127.0.0.1:0", config()).await.unwrap();
    let addr = sim.local_addr().unwrap();
    let client = Client::builder()
        .query_timeout(Duration::MAX)
        .motion_timeout(Duration::MAX)
        .late_reply_grace(Duration::MAX)
        .partial_frame_timeout(Duration::MAX)
        .connect_timeout(Duration::MAX)
        .connect_tcp(addr)
        .await
        .unwrap();
    within("loop", client.loop_back(&b"max"[..])).await.unwrap();
    within("home", client.home(HomingDirection::Default))
        .await
        .unwrap();
    within(
        "power on",
        client.set_finger_power(gripper::wsg::Finger::One, false),
    )
    .await
    .unwrap();
    within("width", client.width_mm()).await.unwrap();
    within(
        "raw",
        client.request_with_timeout(0x06, &b"raw"[..], Duration::MAX),
    )
    .await
    .unwrap();
    let short = client.with_timeouts(Duration::MAX, Duration::MAX);
    within("stop", short.stop()).await.unwrap();
    within("width", short.width_mm()).await.unwrap();
    // Finger power on waits the query timeout plus 500 ms: that sum saturates too.
    within(
        "power on",
        short.set_finger_power(gripper::wsg::Finger::One, true),
    )
    .await
    .unwrap();
    within("close", client.close()).await.unwrap();

    // The same over UDP, whose client has no connect step; the simulator's idle timeout of a
    // UDP session is a `Duration` too.
    let mut cfg = config();
    cfg.udp_idle_timeout = Duration::MAX;
    let sim = SimServer::bind_udp("127.0.0.1:0", cfg).await.unwrap();
    let client = Client::builder()
        .query_timeout(Duration::MAX)
        .late_reply_grace(Duration::MAX)
        .connect_udp(sim.local_addr().unwrap())
        .await
        .unwrap();
    within("udp loop", client.loop_back(&b"max"[..]))
        .await
        .unwrap();
    within("udp close", client.close()).await.unwrap();
}

/// A UDP client with a short late-reply grace (the spacing of the "not moving" probes), homed,
/// and a simulator whose moves last long enough to be caught moving.
async fn udp_moving(grace: Duration) -> (SimServer, Client) {
    let sim = SimServer::bind_udp("127.0.0.1:0", config()).await.unwrap();
    let client = Client::builder()
        .late_reply_grace(grace)
        .connect_udp(sim.local_addr().unwrap())
        .await
        .unwrap();
    within("home", client.home(HomingDirection::Default))
        .await
        .unwrap();
    sim.set_time_scale(1000.0);
    (sim, client)
}

/// Starts a pre-position on its own task and returns once the device reports MOVING (so its
/// E_CMD_PENDING has been sent).
async fn start_move(client: &Client) -> tokio::task::JoinHandle<gripper::wsg::Result<()>> {
    let mover = {
        let c = client.clone();
        tokio::spawn(async move { c.pre_position(20.0, 50.0).await })
    };
    within("moving", async {
        while !client
            .system_state()
            .await
            .unwrap()
            .contains(SystemState::MOVING)
        {}
    })
    .await;
    mover
}

fn count(sim: &SimServer, which: u8) -> usize {
    sim.received_ids().iter().filter(|i| **i == which).count()
}

/// Issue 20.2 #1: one lost final reply (a single UDP datagram) made the client refuse every
/// move of that id with an E_ALREADY_RUNNING the device never sent, for up to the first call's
/// 30 s. The device is idle: the next move must reach it and be answered by it.
#[tokio::test]
async fn a_lost_final_reply_does_not_make_the_client_invent_already_running() {
    let (sim, client) = udp_moving(Duration::from_millis(100)).await;
    let first = start_move(&client).await;
    // The move's final reply is lost; the move ends.
    sim.drop_next_reply(id::PRE_POSITION);
    sim.set_time_scale(0.0);
    within("idle", async {
        while client
            .system_state()
            .await
            .unwrap()
            .contains(SystemState::MOVING)
        {}
    })
    .await;
    within("second move", client.pre_position(60.0, 100.0))
        .await
        .expect("the device is idle: the move must be sent and answered by it");
    assert_eq!(within("width", client.width_mm()).await.unwrap(), 60.0);
    assert_eq!(count(&sim, id::PRE_POSITION), 2);
    // The first call learns that its answer is lost, not a status the device never sent.
    let first = within("first move", first).await.unwrap().unwrap_err();
    assert!(
        matches!(
            first,
            Error::ReplyLost {
                command: id::PRE_POSITION
            }
        ),
        "{first}"
    );
    assert_eq!(first.kind(), gripper::ErrorKind::ReplyLost);
}

/// Issue 20.2 #1: "stop, then start another" when the move's E_CMD_ABORTED arrives after the
/// stop's own E_SUCCESS (the manual fixes no order between them; UDP reorders).
#[tokio::test]
async fn stop_then_move_works_when_the_abort_arrives_after_the_stop_reply() {
    // The abort comes late, but within the grace (a reply later than that is the documented
    // residual risk).
    let (sim, client) = udp_moving(Duration::from_secs(2)).await;
    let first = start_move(&client).await;
    sim.delay_next_reply(id::PRE_POSITION, Duration::from_millis(200));
    within("stop", client.stop()).await.unwrap();
    sim.set_time_scale(0.0);
    within("next move", client.pre_position(60.0, 100.0))
        .await
        .expect("the device stopped: the next move must be sent and answered by it");
    assert_eq!(within("width", client.width_mm()).await.unwrap(), 60.0);
    let first = within("first move", first).await.unwrap().unwrap_err();
    assert_eq!(first.status(), Some(Status::CmdAborted), "{first}");
}

/// A UDP relay between a client and the simulator that loses the next request datagrams of the
/// command ids put into `lose` (one datagram per entry).
struct Relay {
    addr: SocketAddr,
    lose: Arc<Mutex<Vec<u8>>>,
}

impl Relay {
    async fn start(upstream: SocketAddr) -> Relay {
        let socket = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let lose: Arc<Mutex<Vec<u8>>> = Arc::default();
        let relay = Relay {
            addr: socket.local_addr().unwrap(),
            lose: lose.clone(),
        };
        tokio::spawn(async move {
            let mut client = None;
            let mut buf = vec![0u8; 65536];
            while let Ok((n, from)) = socket.recv_from(&mut buf).await {
                let to = if from == upstream {
                    let Some(to) = client else { continue };
                    to
                } else {
                    client = Some(from);
                    // Byte 3 of a frame is its command id (manual 1.2.1).
                    let mut lose = lose.lock().unwrap();
                    if let Some(i) = lose.iter().position(|id| n > 3 && buf[3] == *id) {
                        lose.remove(i);
                        continue;
                    }
                    upstream
                };
                let _ = socket.send_to(&buf[..n], to).await;
            }
        });
        relay
    }
}

/// Issue 20.2 #3: every waiting stop completed on the first stop reply, which may answer an
/// earlier stop, processed before a move that started afterwards. With the later stop's
/// datagram lost, `stop()` returned `Ok` while the fingers kept moving. Manual 1.2.2: a reply
/// acknowledges "the received command": `stop()` may succeed only on a reply to a stop sent at
/// or after the call.
#[tokio::test]
async fn stop_is_ok_only_for_a_stop_the_device_received_after_the_call() {
    let sim = SimServer::bind_udp("127.0.0.1:0", config()).await.unwrap();
    let relay = Relay::start(sim.local_addr().unwrap()).await;
    let client = Client::builder().connect_udp(relay.addr).await.unwrap();
    within("home", client.home(HomingDirection::Default))
        .await
        .unwrap();
    sim.set_time_scale(1000.0);
    // An earlier stop, processed while nothing moves, whose reply is slow.
    sim.delay_next_reply(id::STOP, Duration::from_millis(500));
    let early = {
        let c = client.clone();
        tokio::spawn(async move { c.stop().await })
    };
    within("early stop sent", async {
        while count(&sim, id::STOP) == 0 {
            tokio::task::yield_now().await;
        }
    })
    .await;
    // Then a move starts, and a stop whose datagram is lost.
    let mover = start_move(&client).await;
    relay.lose.lock().unwrap().push(id::STOP);
    within("stop", client.stop()).await.unwrap();
    // Asked after the stop's reply: the device processes it after the stop it answered.
    let state = within("state", client.system_state()).await.unwrap();
    assert!(
        !state.contains(SystemState::MOVING),
        "stop() returned Ok while the fingers move: {state:?}"
    );
    within("early stop", early).await.unwrap().unwrap();
    let moved = within("move", mover).await.unwrap().unwrap_err();
    assert_eq!(moved.status(), Some(Status::CmdAborted), "{moved}");
}

fn encode(f: &Frame) -> Vec<u8> {
    let mut b = BytesMut::new();
    frame::encode(f, &mut b).unwrap();
    b.to_vec()
}

fn reply(command: u8, data: &[u8]) -> Vec<u8> {
    let mut payload = vec![0, 0];
    payload.extend_from_slice(data);
    encode(&Frame::new(command, payload))
}

/// A bogus header: an id whose replies have no fixed length (a raw command), and a length
/// that makes the decoder wait for 4000 bytes (a corrupted length field): about 6 s of the
/// traffic behind it.
const BOGUS: [u8; 6] = [0xAA, 0xAA, 0xAA, 0x90, 0xA0, 0x0F];

/// A TCP "gripper" that writes `BOGUS` once a first request came, then an unrelated 14-byte
/// frame every 20 ms (as a 0x43 stream would), and answers each request after it with `answer`.
async fn corrupted_length_device(answer: fn(&Frame, usize) -> Vec<u8>) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (socket, _) = listener.accept().await.unwrap();
        let (read, write) = socket.into_split();
        let write = Arc::new(tokio::sync::Mutex::new(write));
        let mut requests = FramedRead::new(read, WsgCodec::new());
        let mut n = 0;
        while let Some(Ok(request)) = requests.next().await {
            if n == 0 {
                write.lock().await.write_all(&BOGUS).await.unwrap();
                let w = write.clone();
                tokio::spawn(async move {
                    let noise = reply(0x44, &1.0f32.to_le_bytes());
                    for _ in 0..500 {
                        tokio::time::sleep(Duration::from_millis(20)).await;
                        if w.lock().await.write_all(&noise).await.is_err() {
                            return;
                        }
                    }
                });
            }
            let bytes = answer(&request, n);
            n += 1;
            write.lock().await.write_all(&bytes).await.unwrap();
        }
    });
    addr
}

/// Issue 20.2 #2: the partial-frame timeout restarted on every byte, so a corrupted length
/// field (below the maximum) with a stream of frames behind it held every reply for as long
/// as it took to fill the bogus length. A frame must complete within the timeout from its
/// first byte.
#[tokio::test]
async fn a_corrupted_length_with_traffic_behind_it_is_dropped_from_its_first_byte() {
    let addr = corrupted_length_device(|request, _| match request.id {
        id::LOOP => reply(id::LOOP, &request.payload),
        other => reply(other, &[]),
    })
    .await;
    let client = Client::builder()
        .partial_frame_timeout(Duration::from_millis(200))
        .query_timeout(Duration::from_secs(1))
        .connect_tcp(addr)
        .await
        .unwrap();
    // The first request triggers the bogus header; its reply is held behind it.
    let echo = within("loop", client.loop_back(&b"held"[..])).await;
    assert_eq!(&echo.expect("the held reply is delivered")[..], b"held");
}

/// Issue 20.2 #2: a reply held behind a partial frame must never go to a newer request: the
/// id of a request whose reply may be held is not released while the decoder holds bytes.
#[tokio::test]
async fn a_held_reply_never_goes_to_a_newer_request() {
    // Width requests are answered 1.0 mm, 2.0 mm, ...: each answer names its request.
    let addr = corrupted_length_device(|request, n| match request.id {
        id::WIDTH => reply(id::WIDTH, &(n as f32 + 1.0).to_le_bytes()),
        other => reply(other, &[]),
    })
    .await;
    let client = Client::builder()
        .partial_frame_timeout(Duration::from_millis(600))
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(addr)
        .await
        .unwrap();
    // The first width's answer (1.0) is held; its call times out, its grace passes ...
    let impatient = client.with_timeouts(Duration::from_millis(100), Duration::from_secs(1));
    let first = within("first width", impatient.width_mm()).await;
    assert!(matches!(first, Err(Error::Timeout { .. })), "{first:?}");
    // ... and the next width call must get its own answer, not the held 1.0.
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    let second = within("second width", patient.width_mm()).await.unwrap();
    assert_eq!(
        second, 2.0,
        "the held reply of the first request went to the second"
    );
}

/// The explorer's `wsg-serial:0xee92ace7216a7a5d`: noise inserted after a reply's header made
/// its checksum come out right, and the call returned status 7111, which the device never
/// sent. Data comes only with E_SUCCESS (PROTOCOLS.md §1): a refusal that carries data is a
/// damaged frame, dropped as one; the call times out, and the link goes on.
#[tokio::test]
async fn a_refusal_that_carries_data_is_damage_not_the_devices_status() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (socket, _) = listener.accept().await.unwrap();
        let (read, mut write) = socket.into_split();
        let mut requests = FramedRead::new(read, WsgCodec::new());
        let mut widths = 0;
        while let Some(Ok(request)) = requests.next().await {
            let payload: Vec<u8> = match request.id {
                // Status 0x1BC7 with four bytes of data, under a valid checksum.
                id::WIDTH if widths == 0 => vec![0xC7, 0x1B, 0x27, 0xD3, 0x00, 0x00],
                id::WIDTH => [&[0u8, 0][..], &12.5f32.to_le_bytes()[..]].concat(),
                // The barrier that frees the timed-out id: its echo.
                id::LOOP => [&[0u8, 0][..], &request.payload[..]].concat(),
                _ => continue,
            };
            widths += usize::from(request.id == id::WIDTH);
            let mut out = BytesMut::new();
            frame::encode(&Frame::new(request.id, payload), &mut out).unwrap();
            if write.write_all(&out).await.is_err() {
                return;
            }
        }
    });
    let client = Client::builder()
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(addr)
        .await
        .unwrap();
    let short = client.with_timeouts(Duration::from_millis(200), Duration::from_millis(200));
    let first = within("width", short.width_mm()).await;
    assert!(
        matches!(first, Err(Error::Timeout { command, .. }) if command == id::WIDTH),
        "a status the device never sent: {first:?}"
    );
    assert_eq!(
        within("width again", client.width_mm()).await.unwrap(),
        12.5
    );
}
