//! The WSG client's wrong answers found in issue 20 (part 2), each pinned by a test that failed
//! before its fix: over loopback sockets against the in-process simulator.
#![cfg(feature = "sim")]

use std::time::Duration;

use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, HomingDirection};

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
