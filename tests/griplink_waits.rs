//! The wait helpers and the simulator's waiting rules over real TCP on loopback: completion
//! decided from evidence that the motion ended (manual 3.4.4, 3.4.7), WSTR timeouts (3.4.10),
//! WAITVAL reach/cross (3.4.12) and the automatic re-enable (3.4.1).
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use gripper::griplink::client::{
    GripOutcome, ReleaseOutcome, WaitBy, MIN_POLL_INTERVAL, RE_ENABLE_WINDOW, STILL_FOR,
    TARGET_TOLERANCE_UM,
};
use gripper::griplink::command::{FlexGrip, FlexRelease};
use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
use gripper::griplink::{Client, DeviceState, Error, Port, Status};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::time::Instant;

const POLL: WaitBy = WaitBy::Polling(Duration::from_millis(1));

/// An ET4 whose IEG 55-020 on port 0 has a 12 mm part between its fingers, homed (fingers at
/// 20 mm); motion takes no time until a test slows it down.
async fn homed(config: SimConfig) -> (SimServer, Client) {
    let config = config
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .time_scale(0.0);
    let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let client = Client::connect(server.local_addr()).await.unwrap();
    client.port(0).home().await.unwrap();
    (server, client)
}

fn slow_down(server: &SimServer, scale: f64) {
    server.with_controller(|c, _| c.set_time_scale(scale));
}

/// Releases to the release limit (20 mm) in no time, then faults the device: DS_FAULT there.
async fn faulted_at_the_release_limit(server: &SimServer, g: &Port) {
    slow_down(server, 0.0);
    g.release_and_wait(0, POLL).await.unwrap();
    server.inject_device_fault(0);
    assert_eq!(g.state().await.unwrap(), DeviceState::Fault);
}

fn at_target(position_um: i32, target_um: i32) -> bool {
    (position_um - target_um).abs() <= TARGET_TOLERANCE_UM
}

/// RELEASE from DS_RELEASED causes no transition (3.4.7): the helpers must wait for the
/// fingers to reach the release limit, not report the state read right after the ACK.
#[tokio::test]
async fn release_from_released_returns_only_at_the_target() {
    let (server, client) = homed(SimConfig::et4()).await;
    let g = client.port(0);
    // The default recipe releases to the open end, 20 mm.
    assert_eq!(
        g.release_and_wait(0, POLL).await.unwrap(),
        ReleaseOutcome::Released
    );
    // From DS_RELEASED, and from DS_FAULT: RELEASE re-enables the gripper (3.4.1) and the
    // state stays DS_FAULT while the fingers move.
    for start in [DeviceState::Released, DeviceState::Fault] {
        for by in [POLL, WaitBy::Transition] {
            slow_down(&server, 0.0);
            g.set_value(0, 5000).await.unwrap();
            if start == DeviceState::Fault {
                server.inject_device_fault(0);
            }
            assert_eq!(g.position_um().await.unwrap(), 5000);
            assert_eq!(g.state().await.unwrap(), start);
            // 15 mm at 50 mm/s: 300 ms simulated, 60 ms of wall time.
            slow_down(&server, 0.2);
            assert_eq!(
                g.release_and_wait(0, by).await.unwrap(),
                ReleaseOutcome::Released
            );
            let position = g.position_um().await.unwrap();
            assert!(
                at_target(position, 20_000),
                "{start:?} {by:?}: returned at {position} µm"
            );
        }
    }
    // FLEXRELEASE to its own position, from DS_RELEASED too.
    for by in [POLL, WaitBy::Transition] {
        slow_down(&server, 0.0);
        g.set_value(0, 2000).await.unwrap();
        slow_down(&server, 0.2);
        let params = FlexRelease {
            position_mm: 17.5,
            ..Default::default()
        };
        assert_eq!(
            g.flex_release_and_wait(params, by).await.unwrap(),
            ReleaseOutcome::Released
        );
        let position = g.position_um().await.unwrap();
        assert!(
            at_target(position, 17_500),
            "{by:?}: returned at {position} µm"
        );
    }
}

/// A WSTR that answers ERR 05 (no transition within the controller's WSTR timeout, 3.4.10)
/// inside the helper's own deadline is asked again; the wait completes with the outcome.
#[tokio::test]
async fn wstr_timeout_inside_the_deadline_is_asked_again() {
    let config = SimConfig::et4().wstr_timeout(Duration::from_millis(20));
    let (server, client) = homed(config).await;
    let g = client.port(0);
    slow_down(&server, 1.0);
    // 20 mm to the part at 12 mm at 1 mm/s: 8 s, far longer than the WSTR timeout.
    let grip = tokio::spawn({
        let g = g.clone();
        async move {
            let params = FlexGrip {
                position_mm: 0.0,
                force_n: 10.0,
                speed_mm_per_s: 1.0,
                acceleration_mm_per_s2: 0.0,
            };
            g.flex_grip_and_wait(params, WaitBy::Transition).await
        }
    });
    common::griplink_until(&server, Duration::from_secs(10), "no WSTR timed out", |s| {
        s.with_controller(|c, _| c.wstr_timeouts(0) >= 1)
    })
    .await;
    assert!(!grip.is_finished());
    server.with_controller(|c, now| c.finish_motion(0, now));
    assert_eq!(grip.await.unwrap().unwrap(), GripOutcome::Holding);
    assert_eq!(g.position_um().await.unwrap(), 12_000);
}

/// WAITVAL is reach/cross (3.4.12): a window of size 0 over a moving position is ACKed, from
/// above and from below.
#[tokio::test]
async fn waitval_with_window_0_over_a_moving_position_acks() {
    let (server, client) = homed(SimConfig::et4()).await;
    let g = client.port(0);
    // 20 mm to 0 at 50 mm/s: 400 ms simulated, 40 ms of wall time; sampled every 0.5 ms.
    slow_down(&server, 0.1);
    g.set_value(0, 0).await.unwrap();
    g.wait_value(0, 10_013, 0, Duration::from_secs(5))
        .await
        .unwrap();
    assert!(g.position_um().await.unwrap() < 10_013);
    server.with_controller(|c, now| c.finish_motion(0, now));
    g.set_value_f(0, 20.0).await.unwrap();
    g.wait_value_f(0, 7.0071, 0.0, Duration::from_secs(5))
        .await
        .unwrap();
    assert!(g.position_um().await.unwrap() > 7007);
}

/// GRIP from DS_FAULT re-enables the gripper (3.4.1) and grips; the state stays DS_FAULT while
/// the fingers move, so the helpers must not take it for the outcome.
#[tokio::test]
async fn grip_from_fault_succeeds() {
    let (server, client) = homed(SimConfig::et4()).await;
    let g = client.port(0);
    for by in [POLL, WaitBy::Transition] {
        faulted_at_the_release_limit(&server, &g).await;
        // 8 mm at 50 mm/s: 160 ms simulated, 32 ms of wall time.
        slow_down(&server, 0.2);
        assert_eq!(
            g.grip_and_wait(0, by).await.unwrap(),
            GripOutcome::Holding,
            "{by:?}"
        );
        assert_eq!(g.position_um().await.unwrap(), 12_000);
    }
}

/// A RELEASE from DS_FAULT with the fingers at the release limit already: WAITVAL and the
/// position say "there" at once, but the gripper is still re-enabling (3.4.1) and reads
/// DS_FAULT for a moment before it ends in DS_RELEASED. The helpers must not report the fault
/// the device is leaving (issue 21).
#[tokio::test]
async fn release_from_fault_at_the_limit_waits_for_the_re_enable() {
    let (server, client) = homed(SimConfig::et4()).await;
    let g = client.port(0);
    for by in [POLL, WaitBy::Transition] {
        faulted_at_the_release_limit(&server, &g).await;
        // The re-enable: 100 ms simulated, 20 ms of wall time.
        slow_down(&server, 0.2);
        assert_eq!(
            g.release_and_wait(0, by).await.unwrap(),
            ReleaseOutcome::Released,
            "{by:?}"
        );
        assert_eq!(g.state().await.unwrap(), DeviceState::Released);
    }
}

/// A GRIP from DS_FAULT whose re-enable takes longer than [`STILL_FOR`]: the fingers stand
/// still meanwhile, and that is no evidence that the grip ended in DS_FAULT (issue 21).
#[tokio::test]
async fn grip_from_fault_with_a_slow_re_enable_is_not_a_fault() {
    // 1 s simulated at time scale 0.5: 500 ms of wall time, well over STILL_FOR.
    let config = SimConfig::et4().enable_time(Duration::from_secs(1));
    let (server, client) = homed(config).await;
    let g = client.port(0);
    for by in [POLL, WaitBy::Transition] {
        slow_down(&server, 0.0);
        g.release_and_wait(0, POLL).await.unwrap();
        // Just outside the part: the grip itself is short.
        g.set_value(0, 12_500).await.unwrap();
        server.inject_device_fault(0);
        slow_down(&server, 0.5);
        assert!(Duration::from_millis(500) > STILL_FOR * 2);
        assert_eq!(
            g.grip_and_wait(0, by).await.unwrap(),
            GripOutcome::Holding,
            "{by:?}"
        );
    }
}

/// A GRIP from DS_FAULT on a gripper that never re-enables (neither leaves DS_FAULT nor moves):
/// the wait ends with the fault once [`RE_ENABLE_WINDOW`] has passed and the fingers stood still,
/// not at the motion timeout.
#[tokio::test]
async fn grip_from_fault_that_never_re_enables_reports_the_fault_after_the_window() {
    let config = SimConfig::et4().enable_time(Duration::from_secs(3600));
    let (server, client) = homed(config).await;
    let g = client.port(0);
    server.inject_device_fault(0);
    slow_down(&server, 1.0);
    let started = Instant::now();
    assert_eq!(g.grip_and_wait(0, POLL).await.unwrap(), GripOutcome::Fault);
    let took = started.elapsed();
    assert!(took >= RE_ENABLE_WINDOW, "{took:?}");
    assert!(took < RE_ENABLE_WINDOW + Duration::from_secs(5), "{took:?}");
    assert_eq!(g.position_um().await.unwrap(), 20_000);
}

/// A grip from DS_FAULT that faults again ends with no transition at all: the helpers report
/// the fault once the fingers stand still, not while they move.
#[tokio::test]
async fn grip_from_fault_that_faults_again_reports_the_fault_once_still() {
    let config = SimConfig::et4().wstr_timeout(Duration::from_millis(100));
    let (server, client) = homed(config).await;
    let g = client.port(0);
    for by in [POLL, WaitBy::Transition] {
        slow_down(&server, 0.0);
        g.release_and_wait(0, POLL).await.unwrap();
        server.inject_device_fault(0);
        server.fault_next_motion(0);
        slow_down(&server, 0.2);
        assert_eq!(g.grip_and_wait(0, by).await.unwrap(), GripOutcome::Fault);
        assert_eq!(g.position_um().await.unwrap(), 12_000, "{by:?}");
    }
}

/// A grip from DS_FAULT whose re-enable shows as a state other than DS_FAULT (here ENABLE:
/// DS_DISABLED) and that then faults again without moving its fingers: the DS_FAULT read after
/// the re-enable is a transition and ends the wait with the fault at once, neither a `Timeout`
/// nor a wait for [`RE_ENABLE_WINDOW`] (issue 29 G, griplink-tcp:0x00000000000091a8).
#[tokio::test]
async fn grip_from_fault_that_re_enables_and_faults_again_in_place_reports_the_fault() {
    let (server, client) = homed(SimConfig::et4()).await;
    let g = client.port(0);
    // No part: the fingers close fully, and a grip from there moves nothing.
    server.set_part(0, None);
    assert_eq!(g.grip_and_wait(0, POLL).await.unwrap(), GripOutcome::NoPart);
    server.inject_device_fault(0);
    server.fault_next_motion(0);
    let limit = Duration::from_millis(1500);
    assert!(limit < RE_ENABLE_WINDOW);
    let waiter = client.with_timeout(limit).port(0);
    let started = Instant::now();
    let enable = async {
        tokio::time::sleep(Duration::from_millis(20)).await;
        g.enable().await.unwrap();
        assert_eq!(g.state().await.unwrap(), DeviceState::Disabled);
        tokio::time::sleep(Duration::from_millis(100)).await;
        server.inject_device_fault(0);
    };
    let (outcome, ()) = tokio::join!(
        waiter.grip_and_wait(0, WaitBy::Polling(Duration::from_millis(10))),
        enable
    );
    assert_eq!(outcome.unwrap(), GripOutcome::Fault);
    let took = started.elapsed();
    assert!(took < Duration::from_millis(1000), "{took:?}");
}

/// WSTR on an idle port waits for a transition and answers ERR 05 after the controller's WSTR
/// timeout (3.4.10); only a WSTR right after a reported transition answers at once.
#[tokio::test]
async fn wstr_on_an_idle_port_answers_err_05_after_its_timeout() {
    // 2 s at time scale 0.01: 20 ms of wall time.
    let config = SimConfig::et4().wstr_timeout(Duration::from_secs(2));
    let (server, client) = homed(config).await;
    slow_down(&server, 0.01);
    let g = client.port(0);
    // HOME's transition, not yet reported by a WSTR, then the same state again ("issued
    // twice").
    assert_eq!(
        g.wait_for_transition().await.unwrap(),
        DeviceState::Disabled
    );
    assert_eq!(
        g.wait_for_transition().await.unwrap(),
        DeviceState::Disabled
    );

    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    let sent = Instant::now();
    write.write_all(b"WSTR[0]?\n").await.unwrap();
    // `next_line` is cancel-safe: the line, when it comes, is read below.
    let early = tokio::time::timeout(Duration::from_millis(10), lines.next_line()).await;
    assert!(
        early.is_err(),
        "WSTR answered within its timeout: {early:?}"
    );
    let line = lines.next_line().await.unwrap();
    assert_eq!(line.as_deref(), Some("ERR 05"));
    assert!(sent.elapsed() >= Duration::from_millis(20));

    // Through the client: a device error with E_TIMEOUT, and the connection stays usable.
    match g.wait_for_transition().await {
        Err(Error::Device { status, .. }) => assert_eq!(status, Status::Timeout),
        other => panic!("expected ERR 05, got {other:?}"),
    }
    assert_eq!(g.state().await.unwrap(), DeviceState::Disabled);
}

/// `WaitBy::Polling(Duration::ZERO)` pauses [`MIN_POLL_INTERVAL`] between reads, as `Watch`
/// does, instead of polling back to back: under a paused clock a grip of 160 ms simulated takes
/// at most one state read per millisecond. Back to back, the clock never moved again (no read
/// ever waits for a timer) and the wait spun for ever (the explorer hung,
/// griplink-tcp:0x2726fa0c478ed35b); the watchdog turns that into a failure.
#[test]
fn polling_with_a_zero_interval_pauses_the_minimum_between_reads() {
    let (done, finished) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(true)
            .build()
            .unwrap();
        rt.block_on(async {
            let (server, client) = homed(SimConfig::et4()).await;
            let g = client.port(0);
            // 8 mm at 50 mm/s: 160 ms simulated.
            slow_down(&server, 1.0);
            server.start_recording(1 << 20);
            let started = Instant::now();
            let outcome = g.grip_and_wait(0, WaitBy::Polling(Duration::ZERO)).await;
            let took = started.elapsed();
            let reads = server
                .recording()
                .iter()
                .filter(|e| e.request.starts_with("DEVSTATE"))
                .count();
            done.send((outcome, took, reads)).unwrap();
        });
    });
    let (outcome, took, reads) = finished
        .recv_timeout(Duration::from_secs(60))
        .expect("the zero-interval wait never ended");
    assert_eq!(outcome.unwrap(), GripOutcome::Holding);
    // One read per pause at most, plus the start state and the first read after the ACK.
    let bound = took.as_micros() / MIN_POLL_INTERVAL.as_micros() + 2;
    assert!(
        (reads as u128) <= bound,
        "{reads} state reads in {took:?} (bound {bound})"
    );
}

/// `SimServer::held_replies` counts a connection whose blocking command (here WSTR, manual
/// 3.4.10) holds its reply, and stops counting it once the reply is sent: the explorer's quiet
/// phase waits for 0 before it judges calls that queue behind such a command.
#[tokio::test]
async fn held_replies_counts_a_connection_held_by_wstr_until_it_answers() {
    // Time scale 1: the WSTR timeout (60 s) cannot end the wait during the test.
    let config = SimConfig::et4().wstr_timeout(Duration::from_secs(60));
    let (server, client) = homed(config).await;
    slow_down(&server, 1.0);
    let g = client.port(0);
    // Report HOME's transition, then the same state again ("issued twice"), so that the next
    // WSTR waits for a new one.
    g.wait_for_transition().await.unwrap();
    g.wait_for_transition().await.unwrap();
    assert_eq!(server.held_replies(), 0);

    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut lines = BufReader::new(read).lines();
    write.write_all(b"WSTR[0]?\n").await.unwrap();
    // Bounded: the simulator reads the line as soon as it is scheduled.
    let held = async {
        while server.held_replies() == 0 {
            tokio::task::yield_now().await;
        }
    };
    tokio::time::timeout(Duration::from_secs(5), held)
        .await
        .expect("the WSTR was never counted as held");
    assert_eq!(server.held_replies(), 1);

    // A transition (the device faults) answers the WSTR (3.4.10).
    server.inject_device_fault(0);
    let line = lines.next_line().await.unwrap();
    assert_eq!(line.as_deref(), Some("WSTR[0]=7"));
    assert_eq!(server.held_replies(), 0);
}
