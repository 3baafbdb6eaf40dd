//! The WSG simulator as third-party drivers use the device (issue #10, items 6–11), over raw
//! TCP and UDP sockets: real time by default, the "UDP remote port", idle UDP sessions,
//! backpressure instead of dropped replies, half-close, 0x07 before a reset, E_CMD_ABORTED for
//! the owner of a move ended by another session's close, and the manual's status codes.
#![cfg(feature = "sim")]

use std::net::SocketAddr;
use std::time::Duration;

use bytes::{BufMut, BytesMut};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpStream, UdpSocket};
use tokio::time::timeout;

use gripper::wsg::command::id;
use gripper::wsg::frame::{self, Decoded};
use gripper::wsg::sim::{SimConfig, SimServer, MAX_UDP_SESSIONS};
use gripper::wsg::{Command, Frame, HomingDirection, Reply, Status, SystemState, UpdateMode};

/// How long any single expected event may take (generous: the machine is shared).
const PATIENCE: Duration = Duration::from_secs(10);

fn encode(frame: &Frame) -> BytesMut {
    let mut b = BytesMut::new();
    frame::encode(frame, &mut b).expect("encodable");
    b
}

fn bytes_of(cmd: Command) -> BytesMut {
    encode(&cmd.to_frame())
}

/// A loop (0x06) request whose payload is `n`, so its reply says which request it answers.
fn numbered_loop(n: u32) -> BytesMut {
    bytes_of(Command::Loop(n.to_le_bytes().to_vec().into()))
}

/// A raw TCP client: writes bytes, reads whole reply frames.
struct Raw {
    stream: TcpStream,
    buf: BytesMut,
}

impl Raw {
    async fn connect(addr: SocketAddr) -> Raw {
        Raw {
            stream: TcpStream::connect(addr).await.expect("connect"),
            buf: BytesMut::new(),
        }
    }

    async fn send(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).await.expect("write");
    }

    /// The next reply, or `None` at end of stream.
    async fn next(&mut self) -> Option<Reply> {
        loop {
            if let Some(d) = frame::decode(&mut self.buf, 4096) {
                match d {
                    Decoded::Frame(f) => return Some(Reply::from_frame(f).expect("a reply")),
                    Decoded::Corrupt { id, .. } => panic!("corrupt reply frame, id {id:#04x}"),
                }
            }
            let n = timeout(PATIENCE, self.stream.read_buf(&mut self.buf))
                .await
                .expect("a reply in time")
                .expect("readable");
            if n == 0 {
                return None;
            }
        }
    }

    async fn reply(&mut self) -> Reply {
        self.next().await.expect("a reply before end of stream")
    }

    /// The next reply that is not an auto-update of `stream_id`.
    async fn reply_skipping(&mut self, stream_id: u8) -> Reply {
        loop {
            let r = self.reply().await;
            if r.id != stream_id {
                return r;
            }
        }
    }
}

/// A simulator on a free TCP port, and a raw client connected to it.
async fn serve(config: SimConfig) -> (SimServer, Raw) {
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let raw = Raw::connect(sim.local_addr().unwrap()).await;
    (sim, raw)
}

fn status_of(r: &Reply) -> (u8, Status) {
    (r.id, r.status)
}

/// Waits (bounded) until the simulator's snapshot satisfies `ok`.
async fn until(sim: &SimServer, what: &str, ok: impl Fn(&gripper::wsg::sim::SimSnapshot) -> bool) {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let snapshot = sim.snapshot();
        if ok(&snapshot) {
            return;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "{what}: still {snapshot:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

// ---- item 6: real time by default ----------------------------------------------------------

/// The standalone simulators' defaults (`wsg_simulator` and `gripctl sim wsg` without options
/// serve `SimConfig::standalone()`): a move lasts, so a second one is refused with
/// E_ALREADY_RUNNING and a stop ends it with E_CMD_ABORTED (manual 1.3, 3.2.1, 3.2.3). The
/// homing is the move: nothing needs to finish, so the test costs no wall time.
#[tokio::test]
async fn standalone_defaults_move_in_real_time_stop_and_already_running() {
    let config = SimConfig::standalone();
    assert_eq!(config.time_scale, 1.0);
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let mut raw = Raw::connect(sim.local_addr().unwrap()).await;
    let homing = bytes_of(Command::Homing(HomingDirection::Default));
    raw.send(&homing).await;
    assert_eq!(
        status_of(&raw.reply().await),
        (id::HOMING, Status::CmdPending)
    );
    raw.send(&homing).await;
    assert_eq!(
        status_of(&raw.reply().await),
        (id::HOMING, Status::AlreadyRunning)
    );
    raw.send(&bytes_of(Command::Stop)).await;
    let mut got = [raw.reply().await, raw.reply().await].map(|r| (r.id, r.status.code()));
    got.sort_unstable();
    let want = [
        (id::HOMING, Status::CmdAborted),
        (id::STOP, Status::Success),
    ];
    assert_eq!(got, want.map(|(id, s)| (id, s.code())));
    assert!(sim
        .snapshot()
        .system_state
        .contains(SystemState::AXIS_STOPPED));
}

// ---- item 7: UDP remote port, idle sessions -------------------------------------------------

/// Like the device's "UDP remote port": a driver sends from one socket (any port, here two) and
/// listens on another; every reply reaches the listener, none the senders.
#[tokio::test]
async fn udp_replies_go_to_the_remote_port_whatever_port_sent() {
    let listener = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let config = SimConfig {
        udp_remote_port: Some(port),
        ..SimConfig::new(gripper::wsg::sim::Model::Wsg50)
    };
    let sim = SimServer::bind_udp("127.0.0.1:0", config).await.unwrap();
    let addr = sim.local_addr().unwrap();
    let senders = [
        UdpSocket::bind("127.0.0.1:0").await.unwrap(),
        UdpSocket::bind("127.0.0.1:0").await.unwrap(),
    ];
    const N: u32 = 100;
    let mut buf = [0u8; 512];
    for n in 0..N {
        let sender = &senders[n as usize % 2];
        sender.send_to(&numbered_loop(n), addr).await.unwrap();
        let (len, from) = timeout(PATIENCE, listener.recv_from(&mut buf))
            .await
            .expect("the reply reaches the remote port")
            .unwrap();
        assert_eq!(from, addr);
        let mut b = BytesMut::from(&buf[..len]);
        let Some(Decoded::Frame(f)) = frame::decode_eof(&mut b, 4096) else {
            panic!("not a frame");
        };
        let reply = Reply::from_frame(f).unwrap();
        assert_eq!(
            (reply.id, &reply.data[..]),
            (id::LOOP, &n.to_le_bytes()[..])
        );
    }
    for sender in &senders {
        let mut one = [0u8; 64];
        assert!(
            sender.try_recv_from(&mut one).is_err(),
            "no reply goes to the sending port"
        );
    }
    // One host, one reply address: one session.
    assert_eq!(sim.snapshot().sessions, 1);
}

/// Every new sender address used to stay a session for good; now a silent one is forgotten, but
/// not while it is still owed a move's final reply or auto-updates it switched on (a driver that
/// subscribes once and then only listens keeps its stream, as on the device).
#[tokio::test]
async fn idle_udp_sessions_are_forgotten_unless_something_is_due() {
    let config = SimConfig {
        udp_idle_timeout: Duration::from_millis(100),
        ..SimConfig::new(gripper::wsg::sim::Model::Wsg50)
    };
    let sim = SimServer::bind_udp("127.0.0.1:0", config).await.unwrap();
    let addr = sim.local_addr().unwrap();
    let mut buf = [0u8; 512];
    // One peer homes slowly: it is owed the final reply.
    let mover = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    sim.set_time_scale(1000.0);
    mover
        .send_to(&bytes_of(Command::Homing(HomingDirection::Default)), addr)
        .await
        .unwrap();
    timeout(PATIENCE, mover.recv_from(&mut buf))
        .await
        .unwrap()
        .unwrap();
    assert_eq!(&buf[3..8], &[id::HOMING, 2, 0, 26, 0], "E_CMD_PENDING");
    // Ten peers that ask once, one with an auto-update stream.
    let mut peers = Vec::new();
    for n in 0..10 {
        let peer = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        peer.send_to(&numbered_loop(n), addr).await.unwrap();
        timeout(PATIENCE, peer.recv_from(&mut buf))
            .await
            .unwrap()
            .unwrap();
        peers.push(peer);
    }
    let stream = UpdateMode {
        auto: true,
        on_change: false,
        period_ms: 10,
    };
    peers[0]
        .send_to(&bytes_of(Command::Width(stream)), addr)
        .await
        .unwrap();
    until(&sim, "eleven sessions, one stream", |s| {
        s.sessions == 11 && s.streams == 1
    })
    .await;
    until(&sim, "the idle peers forgotten", |s| s.sessions == 2).await;
    assert_eq!(
        sim.snapshot().streams,
        1,
        "the listening peer keeps its stream"
    );
    assert!(sim.snapshot().system_state.contains(SystemState::MOVING));
    // Once the listener switches its stream off, it is forgotten too.
    let off = UpdateMode {
        auto: false,
        ..stream
    };
    peers[0]
        .send_to(&bytes_of(Command::Width(off)), addr)
        .await
        .unwrap();
    until(&sim, "the listener forgotten once its stream is off", |s| {
        s.sessions == 1 && s.streams == 0
    })
    .await;
    // The mover still gets its final reply (after the stop's E_CMD_ABORTED).
    mover.send_to(&bytes_of(Command::Stop), addr).await.unwrap();
    let mut statuses = Vec::new();
    for _ in 0..2 {
        let (len, _) = timeout(PATIENCE, mover.recv_from(&mut buf))
            .await
            .unwrap()
            .unwrap();
        assert_eq!(len, 10, "a status-only reply");
        statuses.push((buf[3], buf[6]));
    }
    statuses.sort();
    assert_eq!(
        statuses,
        [(id::HOMING, 19), (id::STOP, 0)],
        "aborted, stopped"
    );
    until(&sim, "the mover forgotten once answered", |s| {
        s.sessions == 0
    })
    .await;
    // A forgotten peer that comes back is a new session and is answered.
    peers[3].send_to(&numbered_loop(3), addr).await.unwrap();
    let (len, _) = timeout(PATIENCE, peers[3].recv_from(&mut buf))
        .await
        .unwrap()
        .unwrap();
    assert_eq!(&buf[6..len - 2], &[0, 0, 3, 0, 0, 0]);
}

/// A flood of sender addresses cannot grow the simulator's sessions without bound, however
/// much each one is still owed: past the cap, the longest-silent session makes room.
#[tokio::test]
async fn udp_sessions_are_capped() {
    let sim = SimServer::bind_udp("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let addr = sim.local_addr().unwrap();
    let mut buf = [0u8; 512];
    let stream = UpdateMode {
        auto: true,
        on_change: false,
        period_ms: 1000,
    };
    let mut peers = Vec::new();
    for _ in 0..MAX_UDP_SESSIONS + 8 {
        // Each subscribes, so none may be forgotten for being idle.
        let peer = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        peer.send_to(&bytes_of(Command::Width(stream)), addr)
            .await
            .unwrap();
        timeout(PATIENCE, peer.recv_from(&mut buf))
            .await
            .unwrap()
            .unwrap();
        peers.push(peer);
    }
    let snapshot = sim.snapshot();
    assert_eq!(snapshot.sessions, MAX_UDP_SESSIONS);
    assert_eq!(snapshot.streams, MAX_UDP_SESSIONS);
    // The newest sender is served.
    let last = peers.last().unwrap();
    last.send_to(&numbered_loop(7), addr).await.unwrap();
    loop {
        let (len, _) = timeout(PATIENCE, last.recv_from(&mut buf))
            .await
            .unwrap()
            .unwrap();
        if buf[3] == id::LOOP {
            assert_eq!(&buf[6..len - 2], &[0, 0, 7, 0, 0, 0]);
            break;
        }
    }
}

// ---- item 8: no reply dropped ----------------------------------------------------------------

/// 1,000 requests written before any reply is read, over a connection with a small receive
/// buffer: the simulator stops reading while its replies wait, and every reply arrives, in
/// order.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_thousand_pipelined_requests_all_get_their_reply() {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let stream = socket.connect(sim.local_addr().unwrap()).await.unwrap();
    let (mut rd, mut wr) = stream.into_split();
    const N: u32 = 1000;
    // Fat requests (256-byte echoes) so the replies outgrow the socket buffers.
    let writer = tokio::spawn(async move {
        let mut all = BytesMut::new();
        for n in 0..N {
            let mut payload = vec![0u8; 256];
            payload[..4].copy_from_slice(&n.to_le_bytes());
            all.put_slice(&bytes_of(Command::Loop(payload.into())));
        }
        wr.write_all(&all).await.unwrap();
        wr
    });
    let mut buf = BytesMut::new();
    for n in 0..N {
        let reply = loop {
            if let Some(d) = frame::decode(&mut buf, 4096) {
                let Decoded::Frame(f) = d else {
                    panic!("corrupt reply")
                };
                break Reply::from_frame(f).unwrap();
            }
            let got = timeout(PATIENCE, rd.read_buf(&mut buf))
                .await
                .unwrap_or_else(|_| panic!("reply {n} of {N} never came"))
                .unwrap();
            assert_ne!(got, 0, "closed before reply {n}");
        };
        assert_eq!((reply.id, reply.status), (id::LOOP, Status::Success));
        assert_eq!(&reply.data[..4], &n.to_le_bytes(), "reply {n} in order");
    }
    let _still_open = timeout(PATIENCE, writer).await.unwrap().unwrap();
    assert_eq!(sim.received_ids().len(), N as usize);
}

/// A client that writes 200 requests and its 0x07, then half-closes (shutdown write), still
/// reads all 201 replies before the simulator closes its side; the close was announced.
#[tokio::test]
async fn a_half_close_after_200_requests_gets_every_reply() {
    let (sim, mut raw) = serve(SimConfig::default()).await;
    let mut all = BytesMut::new();
    for n in 0..200 {
        all.put_slice(&numbered_loop(n));
    }
    all.put_slice(&bytes_of(Command::AnnounceDisconnect));
    raw.send(&all).await;
    raw.stream.shutdown().await.unwrap();
    for n in 0..200u32 {
        let reply = raw.next().await.unwrap_or_else(|| panic!("reply {n} lost"));
        assert_eq!(
            (reply.id, &reply.data[..]),
            (id::LOOP, &n.to_le_bytes()[..])
        );
    }
    assert_eq!(
        status_of(&raw.reply().await),
        (id::ANNOUNCE_DISCONNECT, Status::Success)
    );
    assert!(raw.next().await.is_none(), "then the simulator closes");
    until(&sim, "the session ends", |s| s.sessions == 0).await;
    assert!(!sim.snapshot().system_state.contains(SystemState::FAST_STOP));
}

// ---- item 9: a received 0x07 always counts -------------------------------------------------

/// A client streams auto-updates, pipelines requests and its 0x07, then resets the connection
/// (close with linger 0) without reading: the simulator's writes fail, yet it reads and handles
/// the 0x07 first, so the close is announced and there is no FAST STOP. Flaky before (a write
/// failure ended the session before the 0x07 was read): 200 rounds.
/// On two workers, as the standalone simulator runs: the actor answers while the connection is
/// still reading, so writes race with the reset.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_announced_close_followed_by_a_reset_never_fast_stops() {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let addr = sim.local_addr().unwrap();
    let stream = UpdateMode {
        auto: true,
        on_change: false,
        period_ms: 10,
    };
    let mut tail = BytesMut::new();
    for n in 0..50 {
        let mut payload = vec![0u8; 256];
        payload[..4].copy_from_slice(&u32::to_le_bytes(n));
        tail.put_slice(&bytes_of(Command::Loop(payload.into())));
    }
    tail.put_slice(&bytes_of(Command::AnnounceDisconnect));
    for round in 0..200 {
        let mut raw = Raw::connect(addr).await;
        raw.send(&bytes_of(Command::SystemState(stream))).await;
        assert_eq!(raw.reply().await.id, id::SYSTEM_STATE);
        raw.send(&tail).await;
        raw.stream.set_zero_linger().unwrap();
        drop(raw);
        until(&sim, "the session ends", |s| s.sessions == 0).await;
        assert!(
            !sim.snapshot().system_state.contains(SystemState::FAST_STOP),
            "round {round}: the 0x07 was not counted"
        );
    }
}

// ---- item 10: every session gets its final reply --------------------------------------------

/// Session A moves; session B closes without 0x07: FAST STOP (1.4.2), and A's move ends with
/// E_CMD_ABORTED (1.3) instead of never answering.
#[tokio::test]
async fn an_unannounced_close_aborts_the_move_of_another_session() {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let addr = sim.local_addr().unwrap();
    let mut a = Raw::connect(addr).await;
    a.send(&bytes_of(Command::Homing(HomingDirection::Default)))
        .await;
    assert_eq!(
        status_of(&a.reply().await),
        (id::HOMING, Status::CmdPending)
    );
    assert_eq!(status_of(&a.reply().await), (id::HOMING, Status::Success));
    sim.set_time_scale(1000.0);
    a.send(&bytes_of(Command::PrePosition {
        relative: false,
        stop_on_block: false,
        width_mm: 10.0,
        speed_mm_per_s: 10.0,
    }))
    .await;
    assert_eq!(
        status_of(&a.reply().await),
        (id::PRE_POSITION, Status::CmdPending)
    );
    let mut b = Raw::connect(addr).await;
    b.send(&numbered_loop(1)).await;
    b.reply().await;
    drop(b);
    assert_eq!(
        status_of(&a.reply().await),
        (id::PRE_POSITION, Status::CmdAborted)
    );
    let state = sim.snapshot().system_state;
    assert!(state.contains(SystemState::FAST_STOP), "{state:?}");
    assert!(!state.contains(SystemState::MOVING), "{state:?}");
}

/// The owner of a move half-closes without 0x07: the FAST STOP's E_CMD_ABORTED still reaches it
/// before the simulator closes.
#[tokio::test]
async fn a_half_closing_owner_reads_its_own_aborted_move() {
    let (sim, mut a) = serve(SimConfig::default()).await;
    sim.set_time_scale(1000.0);
    a.send(&bytes_of(Command::Homing(HomingDirection::Default)))
        .await;
    assert_eq!(
        status_of(&a.reply().await),
        (id::HOMING, Status::CmdPending)
    );
    a.stream.shutdown().await.unwrap();
    assert_eq!(
        status_of(&a.reply().await),
        (id::HOMING, Status::CmdAborted)
    );
    assert!(a.next().await.is_none());
    assert!(sim.snapshot().system_state.contains(SystemState::FAST_STOP));
}

// ---- item 11: the manual's status codes --------------------------------------------------------

/// 0x40–0x45 list E_SUCCESS and E_CMD_FORMAT_ERROR only (3.4.1–3.4.6): a period under the
/// 10 ms minimum is served (at the minimum), not refused with E_INVALID_PARAMETER.
#[tokio::test]
async fn an_update_period_under_10_ms_is_not_refused() {
    let (sim, mut raw) = serve(SimConfig::default()).await;
    for period_ms in [0, 1, 9] {
        let mode = UpdateMode {
            auto: true,
            on_change: false,
            period_ms,
        };
        raw.send(&bytes_of(Command::Width(mode))).await;
        let reply = raw.reply().await;
        assert_eq!(
            status_of(&reply),
            (id::WIDTH, Status::Success),
            "{period_ms}"
        );
        // And updates follow.
        let update = raw.reply().await;
        assert_eq!(status_of(&update), (id::WIDTH, Status::Success));
        raw.send(&bytes_of(Command::Width(UpdateMode::ONCE))).await;
        // Updates already queued may precede the answer; then the stream is off.
        until(&sim, "the stream off", |s| s.streams == 0).await;
        raw.send(&numbered_loop(period_ms.into())).await;
        assert_eq!(raw.reply_skipping(id::WIDTH).await.id, id::LOOP);
    }
}

/// The finger queries take no parameter and list E_CMD_FORMAT_ERROR for a wrong format
/// (3.6.1, 3.6.2, 3.6.4), not E_NO_PARAM_EXPECTED.
#[tokio::test]
async fn finger_queries_with_parameters_are_format_errors() {
    let (_sim, mut raw) = serve(SimConfig::default()).await;
    for id in [0x60, 0x61, 0x63, 0x70, 0x71, 0x73] {
        raw.send(&encode(&Frame::new(id, vec![0]))).await;
        assert_eq!(
            status_of(&raw.reply().await),
            (id, Status::CmdFormatError),
            "{id:#04x}"
        );
    }
}

/// A header whose length promises more than ever comes is dropped after the partial-frame
/// timeout, as the client does, and the request behind it is answered.
#[tokio::test]
async fn a_stalled_partial_frame_is_dropped_and_what_follows_is_answered() {
    let (_sim, mut raw) = serve(SimConfig::default()).await;
    let mut bytes = BytesMut::from(&[0xAA, 0xAA, 0xAA, 0x06, 0x89, 0x00, 1, 2, 3][..]);
    bytes.put_slice(&numbered_loop(7));
    raw.send(&bytes).await;
    let reply = raw.reply().await;
    assert_eq!(
        (reply.id, &reply.data[..]),
        (id::LOOP, &7u32.to_le_bytes()[..])
    );
}

/// A frame with a bad checksum is discarded unanswered by default (manual 1.2.1: E_CHECKSUM_ERROR
/// is listed under no command, and the broken byte may be the id): the next reply is the next
/// request's. Configured to answer, it is E_CHECKSUM_ERROR under the received id.
#[tokio::test]
async fn a_bad_checksum_is_not_answered_by_default() {
    let mut corrupt = bytes_of(Command::Homing(HomingDirection::Default));
    let last = corrupt.len() - 1;
    corrupt[last] ^= 0x01;
    for answer_bad_checksum in [false, true] {
        let config = SimConfig {
            answer_bad_checksum,
            ..SimConfig::default()
        };
        let (sim, mut raw) = serve(config).await;
        raw.send(&corrupt).await;
        raw.send(&numbered_loop(5)).await;
        if answer_bad_checksum {
            assert_eq!(
                status_of(&raw.reply().await),
                (id::HOMING, Status::ChecksumError)
            );
        }
        let reply = raw.reply().await;
        assert_eq!(
            (reply.id, &reply.data[..]),
            (id::LOOP, &5u32.to_le_bytes()[..])
        );
        assert_eq!(sim.received_ids(), [id::HOMING, id::LOOP]);
    }
}
