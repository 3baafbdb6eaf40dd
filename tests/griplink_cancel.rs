//! Cancellation: calls dropped at every await point (a `select!` against a short sleep of a
//! seeded random length, or a call polled once and dropped) while other tasks keep calling.
//! Every call that survives gets its own reply: each query's answer names the request (a tag,
//! a product id or a name per port), so a reply handed to the wrong caller cannot go unnoticed.
#![cfg(feature = "sim")]

mod common;

use common::Rng;
use std::pin::pin;
use std::time::Duration;

use futures_util::poll;
use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
use gripper::griplink::{Blocking, Client, ClientConfig, DeviceState, Error};

/// Upper bound for anything that should happen promptly; only reached when a test fails.
const LIMIT: Duration = Duration::from_secs(20);

/// Four different devices, so that every port answers differently; motion takes no time.
async fn sim() -> SimServer {
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .device(1, Some(SimDevice::wpg_100_090()))
        .device(3, Some(SimDevice::wpg_300_120()))
        .time_scale(0.0);
    SimServer::bind("127.0.0.1:0", config).await.unwrap()
}

const PRODUCT_IDS: [u32; 4] = [20, 6050, 50, 6060];

/// One query whose answer identifies it, checked.
async fn query(client: &Client, kind: u64, port: u8) {
    let p = client.port(port);
    match kind {
        0 => assert_eq!(p.tag().await.unwrap(), format!("tag-{port}")),
        1 => assert_eq!(p.product_id().await.unwrap(), PRODUCT_IDS[port as usize]),
        2 => assert_eq!(p.vendor_id().await.unwrap(), Some(815)),
        _ => assert_eq!(client.label().await.unwrap(), "cell-7"),
    }
}

async fn run_cancel_storm(depth: usize, seed: u64) {
    let server = sim().await;
    let config = ClientConfig {
        pipeline_depth: depth,
        ..ClientConfig::default()
    };
    let client = Client::connect_with(server.local_addr(), config)
        .await
        .unwrap();
    for port in 0..4 {
        client
            .port(port)
            .set_tag(&format!("tag-{port}"))
            .await
            .unwrap();
    }
    client.set_label("cell-7").await.unwrap();

    let mut tasks = Vec::new();
    // Cancelling callers.
    for t in 0..4u64 {
        let client = client.clone();
        tasks.push(tokio::spawn(async move {
            let mut rng = Rng(seed.wrapping_mul(31).wrapping_add(t) | 1);
            let (mut done, mut dropped) = (0u32, 0u32);
            for i in 0..150u32 {
                let (kind, port) = (rng.below(4), rng.below(4) as u8);
                let call = query(&client, kind, port);
                if i % 5 == 0 {
                    // Dropped at its first await point, after it was queued (unless the OS
                    // paused this thread long enough for the whole exchange to happen: then
                    // the call is done, and checked).
                    let mut call = pin!(call);
                    match poll!(&mut call) {
                        std::task::Poll::Ready(()) => done += 1,
                        std::task::Poll::Pending => dropped += 1,
                    }
                    continue;
                }
                // A seeded random moment: a sleep (tokio's timer counts whole milliseconds), or
                // a number of scheduler turns, which lands between the finer await points
                // (queued, on the wire, reply read).
                let (sleep, turns) = (rng.below(1500), rng.below(40));
                let moment = async move {
                    if i % 2 == 0 {
                        tokio::time::sleep(Duration::from_micros(sleep)).await;
                    } else {
                        for _ in 0..turns {
                            tokio::task::yield_now().await;
                        }
                    }
                };
                tokio::select! {
                    biased;
                    () = call => done += 1,
                    () = moment => dropped += 1,
                }
            }
            (done, dropped)
        }));
    }
    // Callers that never cancel.
    for t in 0..2u64 {
        let client = client.clone();
        tasks.push(tokio::spawn(async move {
            let mut rng = Rng(seed ^ (0x9e37_79b9 + t));
            for _ in 0..100 {
                query(&client, rng.below(4), rng.below(4) as u8).await;
            }
            (100, 0)
        }));
    }
    let (mut done, mut dropped) = (0, 0);
    for task in tasks {
        let (d, x) = tokio::time::timeout(LIMIT, task)
            .await
            .expect("a caller hung")
            .unwrap();
        done += d;
        dropped += x;
    }
    // Calls were really dropped, and really answered (each answer checked in `query`).
    assert!(dropped > 0 && done > 0, "done {done}, dropped {dropped}");
    // Still in step afterwards.
    for port in 0..4 {
        for kind in 0..4 {
            query(&client, kind, port).await;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dropped_calls_never_hand_their_reply_to_another_caller() {
    for (depth, seed) in [(1, 1), (1, 0x5eed), (4, 2), (4, 0xdead_beef)] {
        run_cancel_storm(depth, seed).await;
    }
}

/// Waits (bounded) until `cond` holds on the simulator.
async fn until(server: &SimServer, cond: impl Fn(&SimServer) -> bool) {
    common::griplink_until(server, LIMIT, "the simulator never got there", cond).await;
}

#[tokio::test]
async fn a_cancelled_grip_already_sent_still_grips() {
    let server = sim().await;
    let client = Client::connect(server.local_addr()).await.unwrap();
    let g = client.port(0);
    g.home().await.unwrap();
    // The reply is held, so the call is still waiting when it is cancelled.
    let gate = server.hold_next_reply();
    let grip = tokio::spawn({
        let g = g.clone();
        async move { g.grip(0, Blocking::Immediate).await }
    });
    until(&server, |s| s.device_state(0) == Some(DeviceState::Holding)).await;
    grip.abort();
    assert!(grip.await.unwrap_err().is_cancelled());
    gate.release();
    // The device did grip; the cancelled call's ACK went to nobody.
    assert_eq!(g.state().await.unwrap(), DeviceState::Holding);
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn a_cancelled_blocking_call_still_holds_the_line_until_the_motion_ends() {
    let server = sim().await;
    let a = Client::connect(server.local_addr()).await.unwrap();
    let b = Client::connect(server.local_addr()).await.unwrap();
    a.port(0).home().await.unwrap();
    server.with_controller(|c, _| c.set_time_scale(1e9)); // motion never ends by itself
    let grip = tokio::spawn({
        let a = a.clone();
        async move {
            a.port(0)
                .with_timeout(Duration::from_secs(600))
                .grip(0, Blocking::UntilDone)
                .await
        }
    });
    until(&server, |s| s.with_controller(|c, now| c.is_moving(0, now))).await;
    grip.abort();
    assert!(grip.await.unwrap_err().is_cancelled());
    // The controller still holds A's line: A's next call waits behind the GRIP.
    let r = a.with_timeout(Duration::from_millis(50)).id().await;
    assert!(matches!(r, Err(Error::Timeout { .. })), "{r:?}");
    // Stopping the motion (from another connection) ends the GRIP; its reply goes to nobody.
    b.port(0).disable().await.unwrap();
    assert_eq!(a.id().await.unwrap(), "GRIPLINK-ET4");
    assert_eq!(a.port(0).state().await.unwrap(), DeviceState::Disabled);
}
