//! The WSG text interface (GCL) end to end over loopback sockets: the simulator's text mode,
//! driven by a scripted client that reads one line per `recv` as the strictest public drivers
//! do (minWSG compares whole chunks: shared note `WSG-TEXT-INTERFACE.md` §6.3), and by
//! `gripper::wsg::text::Client`.
#![cfg(feature = "sim")]

use std::future::Future;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::text::{Client, Error, Quantity};
use gripper::wsg::{GripState, HomingDirection, Status, SystemState};
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::task::JoinHandle;

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(20);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

/// A text-mode WSG 50 with a 40 mm part (±2 mm); motion takes no time. The gap between `ACK`
/// and `FIN` is wide, so that a busy machine's scheduling cannot make a strict reader see both
/// in one chunk.
fn config() -> SimConfig {
    let mut config = SimConfig::new(Model::Wsg50).with_part(40.0, 2.0).text();
    config.text_ack_gap = Duration::from_millis(150);
    config
}

async fn sim() -> SimServer {
    SimServer::bind("127.0.0.1:0", config()).await.unwrap()
}

/// A client like minWSG: writes a line, then takes each `recv` as one reply, whole.
struct Strict {
    stream: TcpStream,
}

impl Strict {
    async fn connect(server: &SimServer) -> Strict {
        let stream = TcpStream::connect(server.local_addr().unwrap())
            .await
            .unwrap();
        stream.set_nodelay(true).unwrap();
        Strict { stream }
    }

    async fn send(&mut self, line: &str) {
        self.stream
            .write_all(format!("{line}\n").as_bytes())
            .await
            .unwrap();
    }

    /// One `recv`: must be exactly one LF-terminated line.
    async fn chunk(&mut self) -> String {
        let mut buf = [0u8; 1024];
        let n = within("a reply", self.stream.read(&mut buf)).await.unwrap();
        let chunk = std::str::from_utf8(&buf[..n]).unwrap().to_owned();
        assert!(
            chunk.ends_with('\n') && chunk.matches('\n').count() == 1 && !chunk.contains('\r'),
            "not one LF-terminated line per segment: {chunk:?}"
        );
        chunk.trim_end().to_owned()
    }

    /// Sends `line` and expects `replies`, each in a segment of its own.
    async fn expect(&mut self, line: &str, replies: &[&str]) {
        self.send(line).await;
        for reply in replies {
            assert_eq!(self.chunk().await, *reply, "reply to {line}");
        }
    }
}

#[tokio::test]
async fn every_command_with_one_line_per_segment() {
    let server = sim().await;
    let mut g = Strict::connect(&server).await;
    // No greeting; FSACK answered with nothing pending (§3.7).
    g.expect("FSACK()", &["ACK FSACK"]).await;
    g.expect("VERBOSE=0", &["VERBOSE=0"]).await;
    g.expect("MOVE(50)", &["ERR MOVE 3"]).await; // not homed: E_NOT_INITIALIZED
    g.expect("HOME()", &["ACK HOME", "FIN HOME"]).await;
    g.expect("POS?", &["POS=110.0"]).await;
    g.expect("HOME(0)", &["ACK HOME", "FIN HOME"]).await;
    g.expect("POS?", &["POS=0.0"]).await;
    g.expect("HOME(1)", &["ACK HOME", "FIN HOME"]).await;
    // The forms public clients send: spaces after commas, fractions, lower case.
    g.expect("MOVE(30, 200)", &["ACK MOVE", "FIN MOVE"]).await;
    g.expect("MOVE(27.50)", &["ACK MOVE", "FIN MOVE"]).await;
    g.expect("POS?", &["POS=27.5"]).await;
    g.expect("move(60)", &["ACK MOVE", "FIN MOVE"]).await;
    // A zero-length move still has its ACK and FIN apart.
    g.expect("MOVE(60)", &["ACK MOVE", "FIN MOVE"]).await;
    // RELEASE needs a grip first (manual chapter 2).
    g.expect("RELEASE(10)", &["ERR RELEASE 16"]).await;
    g.expect("GRIP(40)", &["ACK GRIP", "FIN GRIP"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=4"]).await;
    g.expect("FORCE?", &["FORCE=40.0"]).await;
    g.expect("GRIP(40)", &["ERR GRIP 16"]).await; // not while holding
                                                  // RELEASE opens BY the pull-back, from where the fingers are.
    g.expect("RELEASE(10)", &["ACK RELEASE", "FIN RELEASE"])
        .await;
    g.expect("POS?", &["POS=50.0"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=0"]).await;
    g.expect("FORCE?", &["FORCE=0.0"]).await;
    g.expect("SPEED?", &["SPEED=0.0"]).await;
    g.expect("TEMP?", &["TEMP=23.4"]).await;
    // GRIP with a part width and speed; with no part there: E_CMD_FAILED, NO PART.
    g.expect("GRIP(20, 40, 50)", &["ACK GRIP", "FIN GRIP"])
        .await;
    g.expect("RELEASE(20,420)", &["ACK RELEASE", "FIN RELEASE"])
        .await;
    g.expect("GRIP(20,10)", &["ACK GRIP", "ERR GRIP 18"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=2"]).await;
    g.expect("RELEASE()", &["ACK RELEASE", "FIN RELEASE"]).await;
    // Per-connection settings; PWT decides what a grip with a part width finds.
    g.expect("PWT?", &["PWT=4.0"]).await;
    g.expect("CLT?", &["CLT=4.0"]).await;
    g.expect("MOVE(60)", &["ACK MOVE", "FIN MOVE"]).await;
    g.expect("GRIP(20, 43)", &["ACK GRIP", "ERR GRIP 18"]).await;
    g.expect("RELEASE(20)", &["ACK RELEASE", "FIN RELEASE"])
        .await;
    g.expect("PWT=8", &["PWT=8.0"]).await;
    g.expect("PWT?", &["PWT=8.0"]).await;
    g.expect("GRIP(20, 43)", &["ACK GRIP", "FIN GRIP"]).await;
    g.expect("POS?", &["POS=40.0"]).await;
    g.expect("RELEASE(20)", &["ACK RELEASE", "FIN RELEASE"])
        .await;
    g.expect("CLT=10", &["CLT=10.0"]).await;
    g.expect("CLT?", &["CLT=10.0"]).await;
    // Unknown commands, GETSTATE() among them (§3.9), and bad syntax.
    g.expect("GETSTATE()", &["ERR GETSTATE 14"]).await;
    g.expect("VERBOSE=(1)", &["ERR VERBOSE 15"]).await;
    g.expect("VERBOSE=1    ", &["VERBOSE=1"]).await;
    g.expect("MOVE(1e5)", &["ERR MOVE 15 E_CMD_FORMAT_ERROR"])
        .await;
    g.expect("MOVE(nan)", &["ERR MOVE 15 E_CMD_FORMAT_ERROR"])
        .await;
    g.expect("MOVE(1, 2, 3)", &["ERR MOVE 15 E_CMD_FORMAT_ERROR"])
        .await;
    g.expect(&"X".repeat(300), &["ERR ? 27 E_OVERRUN"]).await;
    g.expect("STOP()", &["ACK STOP"]).await;
    g.expect("FASTSTOP()", &["ACK FASTSTOP"]).await;
    g.expect("HOME()", &["ERR HOME 16 E_ACCESS_DENIED"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=7"]).await;
    g.expect("FSACK()", &["ACK FSACK"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=0"]).await;
    g.expect("BYE()", &["ACK BYE"]).await;
    // After BYE, everything is refused (binary E_ACCESS_DENIED, §6.2).
    g.expect("POS?", &["ERR POS 16 E_ACCESS_DENIED"]).await;
    drop(g);
    wait_sessions(&server, 0).await;
    assert!(
        !server
            .snapshot()
            .system_state
            .contains(SystemState::FAST_STOP),
        "an announced close is no FAST STOP"
    );
}

async fn wait_sessions(server: &SimServer, n: usize) {
    within("the session count", async {
        while server.snapshot().sessions != n {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await;
}

/// A whole line as a line reader sees it (for replies that may share a segment).
async fn line(reader: &mut BufReader<TcpStream>) -> String {
    let mut line = String::new();
    within("a line", reader.read_line(&mut line)).await.unwrap();
    line.trim_end().to_owned()
}

/// `GRIP()` without a part: the fingers grip each other and the state is HOLDING (manual
/// chapter 2); with the part outward of the fingers, the same.
#[tokio::test]
async fn grip_without_a_part_holds_at_zero() {
    let mut config = config();
    config.part = None;
    let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let mut g = Strict::connect(&server).await;
    g.expect("HOME()", &["ACK HOME", "FIN HOME"]).await;
    g.expect("GRIP()", &["ACK GRIP", "FIN GRIP"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=4"]).await;
    g.expect("POS?", &["POS=0.0"]).await;
    g.expect("RELEASE()", &["ACK RELEASE", "FIN RELEASE"]).await;
    g.expect("POS?", &["POS=10.0"]).await;
}

/// A grip with its force (`GRIP(f)`) on a simulator whose motion takes no time: `ACK GRIP`,
/// then `FIN GRIP`, and the part is held with that force. The force used to be set after the
/// grasp started, which ran the device on and ended the grasp first: `FIN GRIP` came before
/// `ACK GRIP` (the explorer's `wsg-text:0x53236ba78b027b2d`).
#[tokio::test]
async fn a_grip_with_its_force_is_acknowledged_before_it_ends() {
    let server = sim().await;
    let mut g = Strict::connect(&server).await;
    // Homed closed: the grip has nowhere to travel and ends as it starts.
    g.expect("HOME(0)", &["ACK HOME", "FIN HOME"]).await;
    g.expect("POS?", &["POS=0.0"]).await;
    g.expect("GRIP(20)", &["ACK GRIP", "FIN GRIP"]).await;
    g.expect("GRIPSTATE?", &["GRIPSTATE=4"]).await;
    g.expect("FORCE?", &["FORCE=20.0"]).await;
}

#[tokio::test]
async fn several_commands_in_one_segment_and_one_command_in_pieces() {
    let server = sim().await;
    let stream = TcpStream::connect(server.local_addr().unwrap())
        .await
        .unwrap();
    let mut r = BufReader::new(stream);
    r.get_mut().write_all(b"VERBOSE=1\nHOME()\n").await.unwrap();
    assert_eq!(line(&mut r).await, "VERBOSE=1");
    assert_eq!(line(&mut r).await, "ACK HOME");
    assert_eq!(line(&mut r).await, "FIN HOME");
    for piece in ["gr", "ip(", "40", ")\r\n"] {
        r.get_mut().write_all(piece.as_bytes()).await.unwrap();
        r.get_mut().flush().await.unwrap();
    }
    assert_eq!(line(&mut r).await, "ACK GRIP");
    assert_eq!(line(&mut r).await, "FIN GRIP");
}

#[tokio::test]
async fn a_close_without_bye_raises_fast_stop_unless_switched_off() {
    for fast_stop_on_close in [true, false] {
        let config = config().with_fast_stop_on_close(fast_stop_on_close);
        let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
        let mut g = Strict::connect(&server).await;
        g.expect("HOME()", &["ACK HOME", "FIN HOME"]).await;
        drop(g);
        wait_sessions(&server, 0).await;
        let state = server.snapshot().system_state;
        assert_eq!(state.contains(SystemState::FAST_STOP), fast_stop_on_close);
        // The next connection finds motion blocked until FSACK.
        let mut g = Strict::connect(&server).await;
        if fast_stop_on_close {
            g.expect("MOVE(20)", &["ERR MOVE 16"]).await;
            g.expect("FSACK()", &["ACK FSACK"]).await;
        }
        // Homing is kept.
        g.expect("MOVE(20)", &["ACK MOVE", "FIN MOVE"]).await;
    }
}

#[tokio::test]
async fn per_connection_settings_and_pushes() {
    let server = sim().await;
    let mut a = Strict::connect(&server).await;
    let b = TcpStream::connect(server.local_addr().unwrap())
        .await
        .unwrap();
    let mut b = BufReader::new(b);
    a.expect("VERBOSE=1", &["VERBOSE=1"]).await;
    a.expect("PWT=3", &["PWT=3.0"]).await;
    b.get_mut().write_all(b"VERBOSE?\nPWT?\n").await.unwrap();
    assert_eq!(line(&mut b).await, "VERBOSE=0");
    // Twice the simulated part's tolerance (±2 mm).
    assert_eq!(line(&mut b).await, "PWT=4.0");
    // AUTOSEND on b only: @NAME=value, the value at once, then periodically.
    b.get_mut()
        .write_all(b"AUTOSEND(\"GRIPSTATE\",10)\n")
        .await
        .unwrap();
    assert_eq!(line(&mut b).await, "ACK AUTOSEND");
    for _ in 0..3 {
        assert_eq!(line(&mut b).await, "@GRIPSTATE=0");
    }
    b.get_mut()
        .write_all(b"AUTOSEND(GRIPSTATE, 0)\nAUTOSEND('TEMP',10)\nAUTOSEND(\"X\",10)\nPOS?\n")
        .await
        .unwrap();
    let mut rest = Vec::new();
    loop {
        let l = line(&mut b).await;
        if l.starts_with("POS=") {
            break;
        }
        rest.push(l);
    }
    let rest: Vec<_> = rest.iter().filter(|l| !l.starts_with('@')).collect();
    assert_eq!(rest, ["ACK AUTOSEND", "ERR AUTOSEND 5", "ERR AUTOSEND 24"]);
    // a never saw a push.
    a.expect("POS?", &["POS=0.0"]).await;
}

#[tokio::test]
async fn the_client_api_against_the_text_simulator() {
    let server = sim().await;
    let g = Client::connect(server.local_addr().unwrap()).await.unwrap();
    g.ack_fast_stop().await.unwrap();
    assert!(g.set_verbose(true).await.unwrap());
    let not_homed = g.move_to(50.0, None).await.unwrap_err();
    assert_eq!(
        not_homed.status(),
        Some(Status::NotInitialized),
        "{not_homed}"
    );
    g.home(HomingDirection::Default).await.unwrap();
    assert_eq!(g.position_mm().await.unwrap(), 110.0);
    g.move_to(60.0, Some(100.0)).await.unwrap();
    g.grip(Some(30.0)).await.unwrap();
    assert_eq!(g.grip_state().await.unwrap(), GripState::Holding);
    assert_eq!(g.force_n().await.unwrap(), 30.0);
    // MOVE while holding opens the gripper (§3.4, [H]).
    g.move_to(70.0, None).await.unwrap();
    assert_eq!(g.grip_state().await.unwrap(), GripState::Idle);
    g.grip_part(40.0, 40.0, Some(50.0)).await.unwrap();
    let again = g.grip(None).await.unwrap_err();
    assert_eq!(again.status(), Some(Status::AccessDenied));
    assert!(matches!(&again, Error::Device { line, .. } if line == "ERR GRIP 16 E_ACCESS_DENIED"));
    g.release(Some(5.0), Some(100.0)).await.unwrap();
    assert_eq!(g.position_mm().await.unwrap(), 45.0);
    let no_part = g.grip_part(20.0, 10.0, None).await.unwrap_err();
    assert_eq!(no_part.status(), Some(Status::CmdFailed));
    assert_eq!(g.grip_state().await.unwrap(), GripState::NoPartFound);
    g.release(None, None).await.unwrap();
    assert!(matches!(
        g.release(None, Some(1.0)).await,
        Err(Error::InvalidArgument { .. })
    ));
    assert!(matches!(
        g.move_to(f64::NAN, None).await,
        Err(Error::InvalidArgument { .. })
    ));
    assert_eq!(g.speed_mm_per_s().await.unwrap(), 0.0);
    assert_eq!(g.temperature_c().await.unwrap(), 23.4);
    assert_eq!(g.set_part_width_tolerance_mm(4.5).await.unwrap(), 4.5);
    assert_eq!(g.part_width_tolerance_mm().await.unwrap(), 4.5);
    assert_eq!(g.set_clamping_travel_mm(3.0).await.unwrap(), 3.0);
    assert_eq!(g.clamping_travel_mm().await.unwrap(), 3.0);
    assert!(!g.set_verbose(false).await.unwrap());
    g.fast_stop().await.unwrap();
    assert_eq!(g.grip_state().await.unwrap(), GripState::Error);
    let blocked = g.home(HomingDirection::Default).await.unwrap_err();
    assert_eq!(blocked.status(), Some(Status::AccessDenied));
    g.ack_fast_stop().await.unwrap();
    g.home(HomingDirection::Negative).await.unwrap();
    assert_eq!(g.position_mm().await.unwrap(), 0.0);
    // Durations that overflow an Instant are no panic.
    g.with_timeout(Duration::MAX).stop().await.unwrap();
    g.close().await.unwrap();
    assert!(matches!(g.position_mm().await, Err(Error::Closed)));
    wait_sessions(&server, 0).await;
    let state = server.snapshot().system_state;
    assert!(!state.contains(SystemState::FAST_STOP));
}

/// Waits until the gripper reports a motion running (POSITIONING).
async fn moving(g: &Client) {
    within("the move to start", async {
        while g.grip_state().await.unwrap() != GripState::Positioning {
            tokio::task::yield_now().await;
        }
    })
    .await;
}

/// A homed gripper in real time, and a MOVE from 110 mm to 10 mm at 1 mm/s (100 s: long
/// enough to be stopped) running in a task of its own.
async fn slow_move() -> (
    SimServer,
    Client,
    JoinHandle<gripper::wsg::text::Result<()>>,
) {
    let server = sim().await;
    let g = Client::connect(server.local_addr().unwrap()).await.unwrap();
    g.home(HomingDirection::Default).await.unwrap();
    server.set_time_scale(1.0);
    let mover = {
        let g = g.clone();
        tokio::spawn(async move { g.move_to(10.0, Some(1.0)).await })
    };
    moving(&g).await;
    (server, g, mover)
}

#[tokio::test]
async fn stop_ends_a_running_motion_with_its_err_while_queries_run_alongside() {
    let (_server, g, mover) = slow_move().await;
    // Queries are answered while the MOVE waits for its FIN.
    assert!(g.position_mm().await.unwrap() <= 110.0);
    assert!(g.speed_mm_per_s().await.unwrap() >= 0.0);
    g.stop().await.unwrap();
    let aborted = within("the move's ERR", mover).await.unwrap().unwrap_err();
    assert_eq!(aborted.status(), Some(Status::CmdAborted), "{aborted}");
    assert!(matches!(&aborted, Error::Device { line, .. } if line == "ERR MOVE 19"));
    assert_eq!(g.grip_state().await.unwrap(), GripState::Idle);
}

#[tokio::test]
async fn a_second_motion_while_one_runs_is_refused_with_its_own_err() {
    let (_server, g, mover) = slow_move().await;
    let grip = g.grip(None).await.unwrap_err();
    assert_eq!(grip.status(), Some(Status::AlreadyRunning));
    assert!(!mover.is_finished(), "the GRIP's ERR went to the MOVE");
    g.fast_stop().await.unwrap();
    let aborted = within("the move's ERR", mover).await.unwrap().unwrap_err();
    assert_eq!(aborted.status(), Some(Status::CmdAborted));
    g.ack_fast_stop().await.unwrap();
}

#[tokio::test]
async fn autosend_streams_pushes() {
    let server = sim().await;
    let g = Client::connect(server.local_addr().unwrap()).await.unwrap();
    g.home(HomingDirection::Default).await.unwrap();
    let mut positions = g.autosend(Quantity::Position, 10, false).await.unwrap();
    let mut states = g.autosend(Quantity::GripState, 10, false).await.unwrap();
    for _ in 0..3 {
        let push = within("a push", positions.next()).await.unwrap();
        assert_eq!((push.quantity, push.value), (Quantity::Position, 110.0));
    }
    let push = within("a push", states.next()).await.unwrap();
    assert_eq!(push.grip_state(), Some(GripState::Idle));
    // Pushes interleave with replies without disturbing them.
    g.move_to(50.0, None).await.unwrap();
    assert_eq!(g.position_mm().await.unwrap(), 50.0);
    within("a push at 50 mm", async {
        while positions.next().await.unwrap().value != 50.0 {}
    })
    .await;
    g.stop_autosend(Quantity::Position).await.unwrap();
    g.close().await.unwrap();
    // The streams end with the connection (after the pushes they buffered).
    within("the end", async {
        while positions.next().await.is_some() {}
    })
    .await;
    within("the end", async { while states.next().await.is_some() {} }).await;
}

#[tokio::test]
async fn a_dropped_call_never_hands_its_reply_to_the_next() {
    let server = sim().await;
    let g = Client::connect(server.local_addr().unwrap()).await.unwrap();
    g.home(HomingDirection::Default).await.unwrap();
    server.set_time_scale(1.0);
    // The MOVE is on the wire when its call is dropped.
    let first = g.move_to(100.0, Some(1.0));
    assert!(tokio::time::timeout(Duration::from_millis(50), first)
        .await
        .is_err());
    // The next MOVE waits for the first one's reply, which goes to nobody: its own call gets
    // its own answer.
    let second = {
        let g = g.clone();
        tokio::spawn(async move { g.move_to(60.0, None).await })
    };
    assert!(!second.is_finished());
    g.stop().await.unwrap();
    server.set_time_scale(0.0);
    within("the second move", second).await.unwrap().unwrap();
    assert_eq!(g.position_mm().await.unwrap(), 60.0);
    // A call that times out waiting for its name frees nothing that is not its own.
    let short = g.with_timeout(Duration::from_millis(1));
    let _ = short.position_mm().await;
    assert_eq!(g.position_mm().await.unwrap(), 60.0);
}

#[tokio::test]
async fn a_lost_connection_fails_the_calls_in_flight() {
    let (server, g, mover) = slow_move().await;
    server.unplug();
    let lost = within("the move", mover).await.unwrap().unwrap_err();
    assert!(matches!(lost, Error::ConnectionLost { .. }), "{lost}");
    assert!(g.is_closed());
    assert!(matches!(
        g.position_mm().await,
        Err(Error::ConnectionLost { .. })
    ));
}

/// The explorer's setup in small: the client over an in-memory stream (`Client::from_io`), the
/// simulator's record of a text session (`SimEvent::TextRequest`/`TextReply`, the oracle's
/// evidence), a paused clock: each command line, then its replies, with the fingers stopped
/// at `FIN`.
#[tokio::test(start_paused = true)]
async fn a_text_session_over_an_in_memory_stream_is_recorded_line_by_line() {
    use gripper::wsg::sim::{SessionKind, SimEvent};
    let server = SimServer::in_memory(config().with_time_scale(1.0));
    server.start_recording(1000);
    let (near, far) = tokio::io::duplex(4096);
    let session = server.serve_stream(far, SessionKind::Tcp);
    let g = Client::from_io(near, Default::default());
    g.home(HomingDirection::Default).await.unwrap();
    let width = g.position_mm().await.unwrap();
    g.close().await.unwrap();
    let lines: Vec<String> = server
        .recording()
        .records
        .iter()
        .filter(|r| r.session == session)
        .filter_map(|r| match &r.event {
            SimEvent::Connected { .. } => Some("connected".to_owned()),
            SimEvent::TextRequest { line } => Some(format!("> {}", line.as_deref().unwrap())),
            SimEvent::TextReply { line, moving } => Some(format!("< {line} {moving}")),
            _ => None,
        })
        .collect();
    assert_eq!(
        lines,
        [
            "connected".to_owned(),
            "> HOME()".into(),
            "< ACK HOME true".into(),
            "< FIN HOME false".into(),
            "> POS?".into(),
            format!("< POS={width:.1} false"),
            "> BYE()".into(),
            "< ACK BYE false".into(),
        ]
    );
}

/// A `FIN` is recorded with the fingers as they were when its motion ended, even when a
/// command that starts the next motion is read at that very instant (the simulator's timer
/// for the `FIN` is due a microsecond later): the explorer's promise 4 (`FIN` means stopped)
/// reads that flag. Found by the explorer, `wsg-text:0xf2f74ad188308e29`: the `FIN HOME` was
/// queued after the `MOVE` it raced had started, and recorded "moving".
#[tokio::test(start_paused = true)]
async fn a_fin_is_recorded_with_the_fingers_stopped_when_a_motion_starts_at_its_instant() {
    use gripper::wsg::sim::{SessionKind, SimEvent};
    let mut config = config().with_time_scale(1.0);
    config.final_reply_lag = Duration::from_millis(20);
    let server = SimServer::in_memory(config);
    server.start_recording(1000);
    let (near, far) = tokio::io::duplex(4096);
    server.serve_stream(far, SessionKind::Tcp);
    let g = Client::from_io(near, Default::default());
    g.ack_fast_stop().await.unwrap();
    g.home(HomingDirection::Positive).await.unwrap();
    // Homed at the positive end: a second HOME(1) has no travel and ends after the lag.
    let start = tokio::time::Instant::now();
    let homing = tokio::spawn({
        let g = g.clone();
        async move { g.home(HomingDirection::Positive).await }
    });
    tokio::time::sleep_until(start + Duration::from_millis(20)).await;
    g.move_to(50.0, None).await.unwrap();
    homing.await.unwrap().unwrap();
    let fins: Vec<(String, bool)> = server
        .recording()
        .records
        .iter()
        .filter_map(|r| match &r.event {
            SimEvent::TextReply { line, moving } if line.starts_with("FIN") => {
                Some((line.clone(), *moving))
            }
            _ => None,
        })
        .collect();
    assert_eq!(
        fins,
        [
            ("FIN HOME".to_owned(), false),
            ("FIN HOME".into(), false),
            ("FIN MOVE".into(), false)
        ]
    );
}

/// A command line cut off by the end of the stream is not run: its LF ends a command (shared
/// note §2), and `MOVE(10` of a `MOVE(100)` whose connection broke must not move the
/// fingers. Found by the explorer (`wsg-text:0x2a27284c85458b17`: a half-closed connection
/// ended inside `AUTOSEND("SPEED",0)`, and the simulator answered the fragment).
#[tokio::test]
async fn a_command_cut_off_by_the_end_of_the_stream_is_not_run() {
    let server = sim().await;
    server.start_recording(1000);
    let mut s = Strict::connect(&server).await;
    s.expect("FSACK()", &["ACK FSACK"]).await;
    s.stream.write_all(b"MOVE(10").await.unwrap();
    s.stream.shutdown().await.unwrap();
    let mut rest = String::new();
    within("the simulator closes", s.stream.read_to_string(&mut rest))
        .await
        .unwrap();
    assert!(
        !rest.contains("MOVE"),
        "the fragment was answered: {rest:?}"
    );
    let read: Vec<_> = server
        .recording()
        .records
        .into_iter()
        .filter_map(|r| match r.event {
            gripper::wsg::sim::SimEvent::TextRequest { line } => Some(line),
            _ => None,
        })
        .collect();
    assert_eq!(read, [Some("FSACK()".to_owned())]);
}

/// The simulator: another connection's `BYE()` stops a running motion ("all running finger
/// movements are stopped immediately", 3.1.2), and a stop returns the grip state to IDLE
/// (Anhang C), as `STOP()` does. Found by the explorer (`wsg-text:0x8febd7af0c4e9b77`): the
/// state stayed POSITIONING for good, and a client checking an overdue motion with
/// `GRIPSTATE?` was told it still ran.
#[tokio::test]
async fn a_motion_stopped_by_another_connections_bye_leaves_the_grip_state_idle() {
    let (server, g, mover) = slow_move().await;
    let other = Client::connect(server.local_addr().unwrap()).await.unwrap();
    other.close().await.unwrap();
    let aborted = within("the move's ERR", mover).await.unwrap().unwrap_err();
    assert_eq!(aborted.status(), Some(Status::CmdAborted), "{aborted}");
    assert_eq!(g.grip_state().await.unwrap(), GripState::Idle);
}
