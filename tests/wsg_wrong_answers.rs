//! The WSG client's wrong answers found in issue 20 (part 2), each pinned by a test that failed
//! before its fix: over loopback sockets against the in-process simulator.
#![cfg(feature = "sim")]

use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Error, HomingDirection, Status, SystemState};

fn config() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

/// Bounds a call that must end by itself well before this (a hang fails the test, it does not
/// block the suite).
async fn bounded<F: std::future::Future>(what: &str, call: F) -> F::Output {
    tokio::time::timeout(Duration::from_secs(20), call)
        .await
        .unwrap_or_else(|_| panic!("{what}: no answer within 20 s"))
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
    bounded("loop", client.loop_back(&b"max"[..]))
        .await
        .unwrap();
    bounded("home", client.home(HomingDirection::Default))
        .await
        .unwrap();
    bounded(
        "power on",
        client.set_finger_power(gripper::wsg::Finger::One, false),
    )
    .await
    .unwrap();
    bounded("width", client.width_mm()).await.unwrap();
    bounded(
        "raw",
        client.request_with_timeout(0x06, &b"raw"[..], Duration::MAX),
    )
    .await
    .unwrap();
    let short = client.with_timeouts(Duration::MAX, Duration::MAX);
    bounded("stop", short.stop()).await.unwrap();
    bounded("width", short.width_mm()).await.unwrap();
    // Finger power on waits the query timeout plus 500 ms: that sum saturates too.
    bounded(
        "power on",
        short.set_finger_power(gripper::wsg::Finger::One, true),
    )
    .await
    .unwrap();
    bounded("close", client.close()).await.unwrap();

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
    bounded("udp loop", client.loop_back(&b"max"[..]))
        .await
        .unwrap();
    bounded("udp close", client.close()).await.unwrap();
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
    bounded("home", client.home(HomingDirection::Default))
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
    bounded("moving", async {
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
    bounded("idle", async {
        while client
            .system_state()
            .await
            .unwrap()
            .contains(SystemState::MOVING)
        {}
    })
    .await;
    bounded("second move", client.pre_position(60.0, 100.0))
        .await
        .expect("the device is idle: the move must be sent and answered by it");
    assert_eq!(bounded("width", client.width_mm()).await.unwrap(), 60.0);
    assert_eq!(count(&sim, id::PRE_POSITION), 2);
    // The first call learns that its answer is lost, not a status the device never sent.
    let first = bounded("first move", first).await.unwrap().unwrap_err();
    assert!(
        matches!(
            first,
            Error::ReplyLost {
                command: id::PRE_POSITION
            }
        ),
        "{first}"
    );
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
    bounded("stop", client.stop()).await.unwrap();
    sim.set_time_scale(0.0);
    bounded("next move", client.pre_position(60.0, 100.0))
        .await
        .expect("the device stopped: the next move must be sent and answered by it");
    assert_eq!(bounded("width", client.width_mm()).await.unwrap(), 60.0);
    let first = bounded("first move", first).await.unwrap().unwrap_err();
    assert_eq!(first.status(), Some(Status::CmdAborted), "{first}");
}
