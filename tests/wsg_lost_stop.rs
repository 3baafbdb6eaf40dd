//! A stop whose request was damaged on the wire (issue 29 E): the real WSG client over TCP
//! through the fault proxy to the simulator. A stop the program asked for is a safety command
//! (manual 3.2.3: it stops every finger movement "unmittelbar"): a barrier proves it lost and it
//! is sent again even after its caller stopped waiting, unless the program has sent a motion
//! command since that the device accepted (the late stop would abort that newer motion); a
//! motion the device refused ran nothing.
//!
//! Real sockets, so the real clock: the stop calls' timeout (`SHORT`) is below the client's
//! re-send interval, so no stop is sent again while its caller waits; every other wait is
//! bounded by `common::within`, only reached when a test fails. Nothing sleeps.
#![cfg(feature = "sim")]

mod common;

use common::within;

use std::time::Duration;

use gripper::fault::{At, Fault, FaultProxy};
use gripper::wsg::client::RESEND_STOP_AFTER;
use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Error, HomingDirection, Status, SystemState};

/// The stop calls' timeout: over before the client would send the stop again for its caller.
const SHORT: Duration = Duration::from_millis(30);
/// Everything else: generous for a loaded machine.
const SURE: Duration = Duration::from_secs(60);
/// The simulator, the proxy before it, and a client through the proxy.
async fn rig() -> (SimServer, FaultProxy, Client) {
    let (sim, proxy) = common::wsg_sim_behind_proxy(SimConfig::new(Model::Wsg50)).await;
    let client = Client::builder()
        .query_timeout(SURE)
        .motion_timeout(SURE)
        .late_reply_grace(Duration::from_millis(100))
        .connect_tcp(proxy.local_addr())
        .await
        .unwrap();
    (sim, proxy, client)
}

/// Sends a stop whose request the proxy damages (its checksum: the device discards it
/// unanswered, manual 1.2.1); the call times out. Nothing else is on the wire when it goes.
async fn lost_stop(proxy: &FaultProxy, client: &Client) {
    let damaged = proxy.client_to_server().add(
        Fault::Corrupt {
            at: At::End(0),
            xor: 0x01,
        }
        .once(),
    );
    let result = client.with_timeouts(SHORT, SHORT).stop().await;
    assert!(
        matches!(result, Err(Error::Timeout { command, .. }) if command == id::STOP),
        "the damaged stop's call: {result:?}"
    );
    assert_eq!(damaged.fired(), 1, "the stop's request was damaged");
}

/// Waits for the move's call and checks the device stopped it: E_CMD_ABORTED (3.2.3), which only
/// a stop that reached the device gives.
async fn aborted(mover: tokio::task::JoinHandle<gripper::wsg::Result<()>>) {
    let moved = within("the device stops the move", mover).await.unwrap();
    assert!(
        matches!(
            moved,
            Err(Error::Device {
                status: Status::CmdAborted,
                ..
            })
        ),
        "the move ended with {moved:?}, not aborted"
    );
}

#[tokio::test]
async fn a_lost_stop_reaches_the_device_after_its_caller_timed_out() {
    assert!(SHORT < RESEND_STOP_AFTER);
    let (sim, proxy, client) = rig().await;
    let mover = common::wsg_start_moving(&sim, &client).await;
    lost_stop(&proxy, &client).await;
    // The move's call ends only when the device stops it: E_CMD_ABORTED (3.2.3). Before the
    // fix the stop was never sent again, and the fingers moved on for half an hour.
    let moved = within("the device stops the move", mover).await.unwrap();
    match moved {
        Err(Error::Device { command, status }) => {
            assert_eq!((command, status), (id::PRE_POSITION, Status::CmdAborted))
        }
        other => panic!("the move ended with {other:?}, not aborted"),
    }
    let state = client.system_state().await.unwrap();
    assert!(!state.contains(SystemState::MOVING), "{state:?}");
    // The stop sent again was answered: the next stop works at once.
    within("the next stop", client.stop()).await.unwrap();
}

#[tokio::test]
async fn a_motion_sent_after_a_lost_stop_is_not_aborted_by_it() {
    let (sim, proxy, client) = rig().await;
    client.home(HomingDirection::Default).await.unwrap();
    // 2 wall seconds per simulated second: the move below takes about a second, well past
    // the barrier that proves the stop lost (RESEND_STOP_AFTER after it was sent).
    sim.set_time_scale(2.0);
    lost_stop(&proxy, &client).await;
    // The program moves on at once.
    let result = within("the move", client.pre_position(60.0, 100.0)).await;
    assert!(result.is_ok(), "the move after the lost stop: {result:?}");
    sim.set_time_scale(0.0);
    assert_eq!(client.width_mm().await.unwrap(), 60.0);
    // No stop reached the device after the move's request (the damaged one came before it).
    let ids = sim.received_ids();
    let moved = ids.iter().rposition(|i| *i == id::PRE_POSITION).unwrap();
    assert!(
        !ids[moved..].contains(&id::STOP),
        "a stop reached the device after the move: {ids:x?}"
    );
}

#[tokio::test]
async fn a_motion_the_device_refused_after_a_lost_stop_does_not_drop_it() {
    let (sim, proxy, client) = rig().await;
    let mover = common::wsg_start_moving(&sim, &client).await;
    lost_stop(&proxy, &client).await;
    // The program tries another motion: the device refuses it while the move runs (3.2.6:
    // E_ALREADY_RUNNING). It started nothing, so the lost stop is still owed.
    let grasp = within("the refused grasp", client.grasp(40.0, 50.0)).await;
    assert!(
        matches!(grasp, Err(Error::Device { command, status: Status::AlreadyRunning }) if command == id::GRASP),
        "{grasp:?}"
    );
    aborted(mover).await;
}

/// As above, but the refusal comes late: after the grasp's caller gave up and the client
/// released the request (fenced: the next frame of its id waits for a barrier's echo), and
/// before that echo. It is the released request's own answer (one request of an id is on the
/// wire at a time, and motions are not streamed), so the grasp ran nothing and the lost stop
/// is still owed. Before the fix the refusal was dropped as a reply of a fenced id, the stop's
/// decision waited for an answer that had already come, and the stop went out only when a
/// later motion was refused (27 s later in the explorer's `wsg-tcp:0x701cd76bbfcd92f7`, found
/// by the long run).
#[tokio::test]
async fn a_refusal_that_comes_after_its_motion_was_released_does_not_drop_a_lost_stop() {
    let (sim, proxy, client) = rig().await;
    let mover = common::wsg_start_moving(&sim, &client).await;
    lost_stop(&proxy, &client).await;
    // The grasp's refusal (the next frame the device sends) is held well past the grasp's
    // deadline and grace (`rig`: 100 ms), so the client releases the request first.
    let held = proxy
        .server_to_client()
        .add(Fault::Delay(Duration::from_millis(500)).once());
    let grasp = within(
        "the grasp's timeout",
        client.with_timeouts(SHORT, SHORT).grasp(40.0, 50.0),
    )
    .await;
    assert!(
        matches!(grasp, Err(Error::Timeout { command, .. }) if command == id::GRASP),
        "{grasp:?}"
    );
    aborted(mover).await;
    assert_eq!(held.fired(), 1, "the refusal was held");
}
