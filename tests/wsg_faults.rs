//! The fault matrix: the real WSG client over TCP through the fault proxy (framed with
//! `wsg::frame::frame_len`) to the simulator, one fault at a time, in each direction. Every call
//! must end in its own right answer or the right typed error, within its timeout (never a wrong
//! answer, a panic or a hang), and the next call on a healthy link must work. UDP datagrams are
//! dropped and duplicated by a small relay in this file.
//!
//! Real sockets, so the real clock: client timeouts are short to keep the suite fast, and the
//! outer bound of each call (`bounded`) only catches hangs. Nothing sleeps to let things settle:
//! tests wait for the proxy's counters or for the simulator's log of received ids.
#![cfg(feature = "sim")]

mod common;

use std::future::Future;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use gripper::fault::{At, Fault, FaultProxy};
use gripper::wsg::client::DEFAULT_PARTIAL_FRAME_TIMEOUT;
use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Error, HomingDirection, Status, SystemState};
use tokio::net::UdpSocket;

/// Query timeout of the calls that are meant to time out (`Rig::impatient`).
const QUERY: Duration = Duration::from_millis(300);
/// Motion timeout of the calls that are meant to time out.
const MOTION: Duration = Duration::from_millis(500);
/// Timeout of every other call: generous, so that a loaded machine does not fail a call that
/// should succeed.
const SURE: Duration = Duration::from_secs(3);
/// How long past its timeout a call may take before the test calls it a hang (a loaded machine
/// runs late; a real hang never ends).
const SLACK: Duration = Duration::from_secs(5);
/// A fault the test ends itself (by releasing or removing it), never by waiting it out.
const LONG: Duration = Duration::from_secs(3600);

fn config() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

struct Rig {
    sim: SimServer,
    proxy: FaultProxy,
    client: Client,
}

impl Rig {
    async fn new(config: SimConfig) -> Rig {
        Self::with_partial_frame_timeout(config, DEFAULT_PARTIAL_FRAME_TIMEOUT).await
    }

    /// A frame must complete within the partial-frame timeout from its first byte (issue
    /// 20.2 #2): a test that has the proxy deliver a frame byte by byte, with a pause after
    /// each, gives it a timeout above that frame's delivery time on a loaded machine.
    async fn with_partial_frame_timeout(config: SimConfig, partial: Duration) -> Rig {
        let (sim, proxy) = common::wsg_sim_behind_proxy(config).await;
        let client = client_with(proxy.local_addr(), partial).await;
        Rig { sim, proxy, client }
    }

    /// A handle whose calls wait long enough for a late reply or a resync.
    fn patient(&self) -> Client {
        self.client.with_timeouts(SURE, SURE)
    }

    /// A handle for the calls a fault makes time out.
    fn impatient(&self) -> Client {
        self.client.with_timeouts(QUERY, MOTION)
    }

    fn count_received(&self, command: u8) -> usize {
        self.sim
            .received_ids()
            .iter()
            .filter(|i| **i == command)
            .count()
    }
}

async fn client_to(addr: SocketAddr) -> Client {
    client_with(addr, DEFAULT_PARTIAL_FRAME_TIMEOUT).await
}

async fn client_with(addr: SocketAddr, partial_frame_timeout: Duration) -> Client {
    Client::builder()
        .query_timeout(SURE)
        .motion_timeout(SURE)
        .late_reply_grace(Duration::from_millis(100))
        .partial_frame_timeout(partial_frame_timeout)
        .connect_tcp(addr)
        .await
        .unwrap()
}

/// Runs a call and fails the test if it outlives its own timeout (plus slack): a hang.
async fn bounded<F: Future>(timeout: Duration, call: F) -> F::Output {
    tokio::time::timeout(timeout + SLACK, call)
        .await
        .expect("the call hung past its timeout")
}

/// A loop-back whose payload names the caller: its reply must be exactly that payload.
async fn echo(client: &Client, tag: &str) -> Result<Vec<u8>, Error> {
    bounded(
        Duration::from_secs(3),
        client.loop_back(tag.as_bytes().to_vec()),
    )
    .await
    .map(|b| b.to_vec())
}

/// The link works: answers that identify their question come back right, on several ids.
async fn assert_healthy(client: &Client, tag: &str) {
    let patient = client.with_timeouts(SURE, SURE);
    assert_eq!(echo(&patient, tag).await.unwrap(), tag.as_bytes());
    let info = bounded(QUERY, patient.system_info()).await.unwrap();
    assert_eq!(info.serial_number, 4711);
    assert_eq!(bounded(QUERY, patient.temperature_c()).await.unwrap(), 23.4);
}

fn assert_timeout(result: Result<impl std::fmt::Debug, Error>, command: u8) {
    match result {
        Err(Error::Timeout { command: c, .. }) if c == command => {}
        other => panic!("expected a timeout of {command:#04x}, got {other:?}"),
    }
}

fn assert_lost<T: std::fmt::Debug>(result: Result<T, Error>) {
    assert!(
        matches!(result, Err(Error::ConnectionLost { .. })),
        "expected ConnectionLost, got {result:?}"
    );
}

// ---- delay ------------------------------------------------------------------------------------

#[tokio::test]
async fn a_delay_within_the_timeout_changes_nothing() {
    let rig = Rig::new(config()).await;
    for faults in [rig.proxy.server_to_client(), rig.proxy.client_to_server()] {
        let delay = faults.add(Fault::Delay(QUERY).once());
        assert_eq!(echo(&rig.client, "delayed").await.unwrap(), b"delayed");
        assert_eq!(delay.fired(), 1);
    }
    assert_healthy(&rig.client, "after delays").await;
}

#[tokio::test]
async fn a_reply_delayed_past_the_timeout_times_out_and_is_never_handed_on() {
    let rig = Rig::new(config()).await;
    let delay = rig
        .proxy
        .server_to_client()
        .add(Fault::Delay(QUERY * 2).once());
    assert_timeout(
        bounded(QUERY, rig.impatient().loop_back(b"late".to_vec())).await,
        id::LOOP,
    );
    assert_eq!(delay.fired(), 1);
    // The late "late" reply arrives while this call waits (the id was released after the
    // grace): it must not be taken for this call's answer.
    assert_eq!(echo(&rig.patient(), "mine").await.unwrap(), b"mine");
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_request_delayed_past_the_timeout_times_out_and_the_next_call_works() {
    let rig = Rig::new(config()).await;
    rig.proxy
        .client_to_server()
        .add(Fault::Delay(QUERY * 2).once());
    assert_timeout(
        bounded(QUERY, rig.impatient().system_info()).await,
        id::SYSTEM_INFO,
    );
    assert_eq!(echo(&rig.patient(), "next").await.unwrap(), b"next");
    assert_healthy(&rig.client, "after").await;
}

// ---- split and merge --------------------------------------------------------------------------

#[tokio::test]
async fn frames_split_into_single_bytes_decode_in_both_directions() {
    // 210 bytes with a 1 ms pause after each: at least 210 ms per frame, more under load.
    let rig = Rig::with_partial_frame_timeout(config(), Duration::from_secs(10)).await;
    let split = Fault::Split {
        piece_len: 1,
        pause: Duration::from_millis(1),
    };
    let replies = rig.proxy.server_to_client().add(split.always());
    let requests = rig.proxy.client_to_server().add(split.always());
    let payload: String = (0..200)
        .map(|i| char::from(b'a' + (i % 26) as u8))
        .collect();
    assert_eq!(
        echo(&rig.patient(), &payload).await.unwrap(),
        payload.as_bytes()
    );
    assert_healthy(&rig.client, "split").await;
    assert!(replies.fired() >= 4 && requests.fired() >= 4);
}

#[tokio::test]
async fn merged_frames_are_each_paired_with_their_own_call() {
    let rig = Rig::new(config()).await;
    for faults in [rig.proxy.server_to_client(), rig.proxy.client_to_server()] {
        let writes = faults.stats().writes;
        let merge = faults.add(
            Fault::Merge {
                frames: 3,
                max_wait: LONG,
            }
            .once(),
        );
        let patient = rig.patient();
        let (a, b, c) = tokio::join!(
            echo(&patient, "merged"),
            patient.system_info(),
            patient.temperature_c()
        );
        assert_eq!(a.unwrap(), b"merged");
        assert_eq!(b.unwrap().serial_number, 4711);
        assert_eq!(c.unwrap(), 23.4);
        assert_eq!(merge.fired(), 1);
        assert_eq!(faults.stats().writes, writes + 1, "three frames, one write");
    }
}

// ---- corrupt ----------------------------------------------------------------------------------

/// Where a reply to `loop_back(b"corrupt")` (`AA AA AA 06 | 09 00 | 00 00 | "corrupt" | crc`) is
/// hit, and with which bits.
const REPLY_BYTES: [(&str, At, u8); 6] = [
    ("checksum", At::End(0), 0x01),
    ("id", At::Start(3), 0x01),
    // 9 → 8: the checksum falls on the wrong bytes.
    ("length, shorter", At::Start(4), 0x01),
    // 9 → 137: the decoder waits for bytes that never come, until the partial-frame timeout.
    ("length, longer", At::Start(4), 0x80),
    // 9 + 0x2000: above the maximum payload, noise at once.
    ("length, over the maximum", At::Start(5), 0x20),
    ("payload", At::Start(9), 0x20),
];

#[tokio::test]
async fn a_corrupted_reply_is_skipped_the_call_times_out_and_the_next_works() {
    for (what, at, xor) in REPLY_BYTES {
        let rig = Rig::new(config()).await;
        let corrupt = rig
            .proxy
            .server_to_client()
            .add(Fault::Corrupt { at, xor }.once());
        let result = bounded(QUERY, rig.impatient().loop_back(b"corrupt".to_vec())).await;
        assert_eq!(corrupt.fired(), 1, "{what}");
        match result {
            Err(Error::Timeout {
                command: id::LOOP, ..
            }) => {}
            other => panic!("{what}: expected a timeout, got {other:?}"),
        }
        assert_eq!(
            echo(&rig.patient(), what).await.unwrap(),
            what.as_bytes(),
            "{what}"
        );
        assert_healthy(&rig.client, what).await;
    }
}

#[tokio::test]
async fn a_corrupted_request_is_refused_or_unanswered_never_misread() {
    // (what, where, bits, SimConfig::answer_bad_checksum, what the device answers the loop)
    let cases: [(&str, At, u8, bool, Option<Status>); 6] = [
        // A frame with a bad checksum is discarded unanswered (1.2.1; an answer under its id
        // could fail another caller): the call times out.
        ("checksum", At::End(0), 0x01, false, None),
        ("payload", At::Start(7), 0x20, false, None),
        ("length, shorter", At::Start(4), 0x01, false, None),
        // Configured to answer, the simulator says E_CHECKSUM_ERROR under the received id.
        (
            "checksum, answered",
            At::End(0),
            0x01,
            true,
            Some(Status::ChecksumError),
        ),
        // The answer (if any) goes to id 0x16, which nobody asked: the call times out.
        ("id", At::Start(3), 0x10, true, None),
        // Above the maximum: the device skips it as noise and says nothing.
        ("length, over the maximum", At::Start(5), 0x20, false, None),
    ];
    for (what, at, xor, answer_bad_checksum, status) in cases {
        let rig = Rig::new(SimConfig {
            answer_bad_checksum,
            ..config()
        })
        .await;
        rig.proxy
            .client_to_server()
            .add(Fault::Corrupt { at, xor }.once());
        let result = bounded(QUERY, rig.impatient().loop_back(b"corrupt".to_vec())).await;
        match (status, result) {
            (Some(s), Err(Error::Device { command, status })) => {
                assert_eq!((command, status), (id::LOOP, s), "{what}")
            }
            (None, result) => assert_timeout(result, id::LOOP),
            (_, other) => panic!("{what}: got {other:?}"),
        }
        assert_healthy(&rig.client, what).await;
    }
}

// ---- drop -------------------------------------------------------------------------------------

#[tokio::test]
async fn a_dropped_frame_times_out_in_either_direction_and_the_next_call_works() {
    let rig = Rig::new(config()).await;
    for (n, faults) in [rig.proxy.server_to_client(), rig.proxy.client_to_server()]
        .into_iter()
        .enumerate()
    {
        let dropped = faults.add(Fault::Drop.once());
        assert_timeout(
            bounded(QUERY, rig.impatient().loop_back(b"dropped".to_vec())).await,
            id::LOOP,
        );
        assert_eq!(dropped.fired(), 1);
        assert_healthy(&rig.client, &format!("after drop {n}")).await;
    }
}

#[tokio::test]
async fn a_dropped_pending_ack_still_ends_the_motion_on_its_final_reply() {
    let rig = Rig::new(config()).await;
    // Homing answers E_CMD_PENDING, then E_SUCCESS: drop the first.
    let dropped = rig.proxy.server_to_client().add(Fault::Drop.once());
    bounded(MOTION, rig.client.home(HomingDirection::Default))
        .await
        .unwrap();
    assert_eq!(dropped.fired(), 1);
    let state = rig.client.system_state().await.unwrap();
    assert!(state.contains(SystemState::REFERENCED), "{state:?}");
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_dropped_final_reply_times_out_the_motion_and_other_commands_still_work() {
    let rig = Rig::new(config()).await;
    let dropped = rig.proxy.server_to_client().add(Fault::Drop.nth(2));
    assert_timeout(
        bounded(MOTION, rig.impatient().home(HomingDirection::Default)).await,
        id::HOMING,
    );
    assert_eq!(dropped.fired(), 1);
    // The move itself happened.
    let state = rig.client.system_state().await.unwrap();
    assert!(state.contains(SystemState::REFERENCED), "{state:?}");
    assert_healthy(&rig.client, "after").await;
    // Other motion commands are not held up by the lost reply.
    bounded(MOTION, rig.client.pre_position(50.0, 100.0))
        .await
        .unwrap();
    assert_eq!(rig.client.width_mm().await.unwrap(), 50.0);
    // Nor is the same command: the client asks the device whether the lost move still runs,
    // and, as it does not, releases the id instead of waiting for that reply for ever.
    bounded(MOTION, rig.client.home(HomingDirection::Default))
        .await
        .unwrap();
    assert_eq!(rig.client.width_mm().await.unwrap(), 110.0);
    assert_eq!(rig.count_received(id::HOMING), 2);
}

#[tokio::test]
async fn a_timed_out_move_that_still_runs_keeps_its_id_until_its_final_reply() {
    let rig = Rig::new(config()).await;
    rig.client.home(HomingDirection::Default).await.unwrap();
    rig.sim.set_time_scale(1000.0);
    let impatient = rig.impatient();
    assert_timeout(
        bounded(MOTION, impatient.pre_position(20.0, 50.0)).await,
        id::PRE_POSITION,
    );
    // Past the first call's deadline the client asks the device (0x40) whether it still moves;
    // it does, so the next move of the id is refused as the device would refuse it (3.2.2)
    // instead of being queued (issue 10 item 4: this test used to expect queuing), and unsent.
    let err = bounded(SURE, rig.patient().pre_position(90.0, 50.0))
        .await
        .unwrap_err();
    assert_eq!(err.status(), Some(Status::AlreadyRunning), "{err}");
    assert!(
        rig.count_received(id::SYSTEM_STATE) >= 1,
        "no probe was sent"
    );
    assert_eq!(
        rig.count_received(id::PRE_POSITION),
        1,
        "sent during the move"
    );
    // The stop ends the first move; its late E_CMD_ABORTED frees the id for the next one.
    rig.patient().stop().await.unwrap();
    rig.sim.set_time_scale(0.0);
    bounded(SURE, rig.patient().pre_position(90.0, 50.0))
        .await
        .unwrap();
    assert_eq!(rig.patient().width_mm().await.unwrap(), 90.0);
    assert_eq!(rig.count_received(id::PRE_POSITION), 2);
}

// ---- duplicate --------------------------------------------------------------------------------

#[tokio::test]
async fn a_duplicated_reply_never_reaches_the_next_caller_of_its_id() {
    let rig = Rig::new(config()).await;
    let patient = rig.patient();
    // Sequential: the copy is consumed before the next request of the id goes out.
    let dup = rig.proxy.server_to_client().add(Fault::Duplicate.once());
    assert_eq!(echo(&patient, "first").await.unwrap(), b"first");
    assert_eq!(echo(&patient, "second").await.unwrap(), b"second");
    assert_eq!(dup.fired(), 1);
    // Concurrent: "B" is queued behind "A" and goes out as soon as A's reply is paired; the
    // copy of A's reply must not answer it.
    let dup = rig.proxy.server_to_client().add(Fault::Duplicate.once());
    let (a, b) = tokio::join!(echo(&patient, "A"), echo(&patient, "B"));
    assert_eq!((a.unwrap(), b.unwrap()), (b"A".to_vec(), b"B".to_vec()));
    assert_eq!(dup.fired(), 1);
    // Another id, whose answer does not name its question.
    let dup = rig.proxy.server_to_client().add(Fault::Duplicate.once());
    assert_eq!(patient.system_info().await.unwrap().serial_number, 4711);
    assert_eq!(dup.fired(), 1);
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_duplicated_query_is_answered_twice_and_the_second_answer_is_dropped() {
    let rig = Rig::new(config()).await;
    let patient = rig.patient();
    let dup = rig.proxy.client_to_server().add(Fault::Duplicate.once());
    let (a, b) = tokio::join!(echo(&patient, "asked once"), echo(&patient, "then me"));
    assert_eq!(a.unwrap(), b"asked once");
    assert_eq!(b.unwrap(), b"then me");
    assert_eq!(dup.fired(), 1);
    assert_eq!(rig.count_received(id::LOOP), 3);
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_duplicated_motion_request_during_the_move_is_refused_and_the_call_gets_its_own_result() {
    let rig = Rig::new(config()).await;
    rig.client.home(HomingDirection::Default).await.unwrap();
    // Moves now last long enough for the copy to arrive while the first still runs: the device
    // refuses the copy with E_ALREADY_RUNNING, which is not the final reply of the move.
    rig.sim.set_time_scale(1000.0);
    let dup = rig.proxy.client_to_server().add(Fault::Duplicate.once());
    let mover = {
        let c = rig.patient();
        tokio::spawn(async move { c.pre_position(20.0, 50.0).await })
    };
    dup.wait_fired(1).await;
    // Wait until the device has answered both (the second answer is E_ALREADY_RUNNING).
    while rig.count_received(id::PRE_POSITION) < 2 {
        rig.patient().temperature_c().await.unwrap();
    }
    // One more round trip: the refusal, sent before its answer, has been paired by now.
    rig.patient().temperature_c().await.unwrap();
    assert!(
        !mover.is_finished(),
        "the refusal of the copy ended the call"
    );
    rig.patient().stop().await.unwrap();
    let err = bounded(MOTION, mover).await.unwrap().unwrap_err();
    assert_eq!(err.status(), Some(Status::CmdAborted), "{err}");
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_duplicated_instant_motion_request_moves_twice_and_the_call_gets_one_result() {
    // With instant motion both copies run to the end: the device answers PENDING, SUCCESS twice.
    let rig = Rig::new(config()).await;
    let dup = rig.proxy.client_to_server().add(Fault::Duplicate.once());
    bounded(MOTION, rig.client.home(HomingDirection::Default))
        .await
        .unwrap();
    assert_eq!(dup.fired(), 1);
    bounded(MOTION, rig.client.pre_position(30.0, 100.0))
        .await
        .unwrap();
    assert_eq!(rig.client.width_mm().await.unwrap(), 30.0);
    assert_eq!(rig.count_received(id::HOMING), 2);
    assert_healthy(&rig.client, "after").await;
}

// ---- stall ------------------------------------------------------------------------------------

#[tokio::test]
async fn a_stall_released_within_the_timeout_delivers_the_answer() {
    let rig = Rig::new(config()).await;
    let replies = rig.proxy.server_to_client();
    replies.stall();
    let call = {
        let c = rig.patient();
        tokio::spawn(async move { c.loop_back(b"held".to_vec()).await })
    };
    replies.wait_for(|s| s.held_bytes > 0).await;
    replies.release();
    assert_eq!(&bounded(QUERY, call).await.unwrap().unwrap()[..], b"held");
    assert_healthy(&rig.client, "after").await;
}

#[tokio::test]
async fn a_stall_past_the_timeout_times_out_and_after_release_the_link_works() {
    let rig = Rig::new(config()).await;
    let requests = rig.proxy.client_to_server();
    requests.stall();
    assert_timeout(
        bounded(QUERY, rig.impatient().loop_back(b"stalled".to_vec())).await,
        id::LOOP,
    );
    requests.release();
    assert_healthy(&rig.client, "after").await;
}

// ---- cut --------------------------------------------------------------------------------------

#[tokio::test]
async fn a_cut_before_or_inside_a_frame_fails_the_call_with_connection_lost() {
    let cases = [
        ("reply, before it", true, 0),
        ("reply, mid-frame", true, 5),
        ("request, before it", false, 0),
        ("request, mid-frame", false, 7),
    ];
    for (what, replies, after_bytes) in cases {
        let rig = Rig::new(config()).await;
        let faults = if replies {
            rig.proxy.server_to_client()
        } else {
            rig.proxy.client_to_server()
        };
        let cut = faults.add(Fault::Cut { after_bytes }.once());
        let result = bounded(QUERY, rig.impatient().loop_back(b"cut".to_vec())).await;
        assert_eq!(cut.fired(), 1, "{what}");
        assert_lost(result);
        // Every later call on the broken connection says so too.
        assert_lost(rig.client.system_info().await);
        // A fresh connection works. The simulator saw an unannounced TCP close: FAST STOP
        // (manual 1.4.2), which only the program may acknowledge.
        let fresh = client_to(rig.proxy.local_addr()).await;
        assert_healthy(&fresh, what).await;
        // The simulator handles the old connection's close only eventually: ask until it has.
        let mut state = fresh.system_state().await.unwrap();
        for _ in 0..10_000 {
            if state.contains(SystemState::FAST_STOP) {
                break;
            }
            state = fresh.system_state().await.unwrap();
        }
        assert!(state.contains(SystemState::FAST_STOP), "{what}: {state:?}");
        assert_eq!(
            fresh
                .home(HomingDirection::Default)
                .await
                .unwrap_err()
                .status(),
            Some(Status::AccessDenied)
        );
    }
}

#[tokio::test]
async fn a_cut_during_a_move_fails_it_and_it_is_not_sent_again() {
    let rig = Rig::new(config()).await;
    rig.client.home(HomingDirection::Default).await.unwrap();
    rig.sim.set_time_scale(1000.0);
    let mover = {
        let c = rig.patient();
        tokio::spawn(async move { c.pre_position(20.0, 50.0).await })
    };
    while !rig
        .client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING)
    {}
    rig.proxy.cut_connections();
    assert_lost(bounded(MOTION, mover).await.unwrap());
    assert_eq!(rig.count_received(id::PRE_POSITION), 1);
}

// ---- UDP --------------------------------------------------------------------------------------

/// A UDP relay between one client and the simulator that can drop or duplicate the next datagram
/// in either direction.
struct Relay {
    addr: SocketAddr,
    drop_requests: Arc<AtomicUsize>,
    drop_replies: Arc<AtomicUsize>,
    dup_requests: Arc<AtomicUsize>,
    dup_replies: Arc<AtomicUsize>,
}

/// Takes one from `n` if it is positive.
fn take_one(n: &AtomicUsize) -> bool {
    n.fetch_update(Ordering::AcqRel, Ordering::Acquire, |v| v.checked_sub(1))
        .is_ok()
}

impl Relay {
    async fn start(upstream: SocketAddr) -> Relay {
        let socket = Arc::new(UdpSocket::bind("127.0.0.1:0").await.unwrap());
        let counters: [Arc<AtomicUsize>; 4] = Default::default();
        let relay = Relay {
            addr: socket.local_addr().unwrap(),
            drop_requests: counters[0].clone(),
            drop_replies: counters[1].clone(),
            dup_requests: counters[2].clone(),
            dup_replies: counters[3].clone(),
        };
        tokio::spawn(async move {
            let mut client = None;
            let mut buf = vec![0u8; 65536];
            while let Ok((n, from)) = socket.recv_from(&mut buf).await {
                let (to, drop, dup) = if from == upstream {
                    let Some(to) = client else { continue };
                    (to, &counters[1], &counters[3])
                } else {
                    client = Some(from);
                    (upstream, &counters[0], &counters[2])
                };
                if take_one(drop) {
                    continue;
                }
                let copies = if take_one(dup) { 2 } else { 1 };
                for _ in 0..copies {
                    let _ = socket.send_to(&buf[..n], to).await;
                }
            }
        });
        relay
    }
}

#[tokio::test]
async fn udp_dropped_and_duplicated_datagrams() {
    let sim = SimServer::bind_udp("127.0.0.1:0", config()).await.unwrap();
    let relay = Relay::start(sim.local_addr().unwrap()).await;
    let client = Client::builder()
        .query_timeout(SURE)
        .motion_timeout(SURE)
        .late_reply_grace(Duration::from_millis(100))
        .connect_udp(relay.addr)
        .await
        .unwrap();
    let patient = client.clone();
    let impatient = client.with_timeouts(QUERY, MOTION);
    for drop in [&relay.drop_requests, &relay.drop_replies] {
        drop.store(1, Ordering::Release);
        assert_timeout(
            bounded(QUERY, impatient.loop_back(b"lost".to_vec())).await,
            id::LOOP,
        );
        assert_eq!(drop.load(Ordering::Acquire), 0);
        assert_healthy(&client, "after a lost datagram").await;
    }
    for dup in [&relay.dup_requests, &relay.dup_replies] {
        dup.store(1, Ordering::Release);
        let (a, b) = tokio::join!(echo(&patient, "A"), echo(&patient, "B"));
        assert_eq!((a.unwrap(), b.unwrap()), (b"A".to_vec(), b"B".to_vec()));
        assert_eq!(dup.load(Ordering::Acquire), 0);
        assert_healthy(&client, "after a duplicate").await;
    }
    // The simulator's own fault injection: a reply lost on the way (UDP has no retransmission).
    sim.drop_next_reply(id::SYSTEM_INFO);
    assert_timeout(bounded(QUERY, client.system_info()).await, id::SYSTEM_INFO);
    assert_healthy(&client, "after a lost reply").await;
    // A duplicated motion request over UDP: one result for the call.
    relay.dup_requests.store(1, Ordering::Release);
    bounded(MOTION, client.home(HomingDirection::Default))
        .await
        .unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 110.0);
    // A lost E_CMD_PENDING datagram: the final reply still ends the move.
    sim.drop_next_reply(id::PRE_POSITION);
    bounded(MOTION, client.pre_position(30.0, 100.0))
        .await
        .unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 30.0);
}

/// Issue 29 D (the explorer's `wsg-udp:0xaf073ffc53d9a31d`): on UDP a stop lost while its
/// caller had no timeout counted as unanswered for ever. A reply is taken for the oldest stop
/// unanswered (replies carry nothing else), so each such stop cost every later stop call one
/// more re-send before a reply could be its own: after twenty, a `stop()` with a 1 s timeout
/// timed out on a device that answered each of its stops at once. Such a stop now counts as
/// lost the reply hold (the query timeout) + grace after it was sent, as any request without
/// timeout.
#[tokio::test]
async fn on_udp_stops_lost_while_nobody_had_a_timeout_do_not_hold_up_a_later_stop() {
    let sim = SimServer::bind_udp("127.0.0.1:0", config()).await.unwrap();
    let client = Client::builder()
        .query_timeout(Duration::from_millis(50))
        .late_reply_grace(Duration::from_millis(50))
        .connect_udp(sim.local_addr().unwrap())
        .await
        .unwrap();
    // Twenty stop replies lost in a row: the call without timeout ends on the reply to its
    // twenty-first stop, and twenty stops count as unanswered behind it.
    const LOST: usize = 20;
    for _ in 0..LOST {
        sim.drop_next_reply(id::STOP);
    }
    let patient = client.with_timeouts(Duration::MAX, Duration::MAX);
    bounded(SURE, patient.stop()).await.unwrap();
    let stops = sim
        .received_ids()
        .iter()
        .filter(|i| **i == id::STOP)
        .count();
    assert_eq!(stops, LOST + 1);
    // The device answers every stop now: a stop with a timeout gets its own reply at once, or
    // after a re-send or two, not after twenty.
    let timely = client.with_timeouts(Duration::from_secs(1), MOTION);
    bounded(SURE, timely.stop()).await.unwrap();
    assert_healthy(&client, "after the stops").await;
}
