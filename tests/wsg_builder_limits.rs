//! The WSG client builder's sizes at their extremes (issue 29 C and the queue panics): each is
//! clamped as documented, never a panic and never a client that cannot read its own replies.
//! Over loopback sockets against the in-process simulator.
#![cfg(feature = "sim")]

mod common;

use common::within;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, UpdateOptions};

fn config() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

/// `request_queue(usize::MAX)` panicked as the client started and `subscription_buffer(usize::MAX)`
/// at the first subscribe (tokio's channels take at most `Semaphore::MAX_PERMITS`); the
/// explorer's wsg-tcp:0x97bd3790f9bd2a07 and wsg-tcp:0x9e54f17d3c924c05.
#[tokio::test]
async fn usize_max_queue_and_subscription_buffer_are_clamped() {
    let sim = SimServer::bind("127.0.0.1:0", config()).await.unwrap();
    let client = Client::builder()
        .request_queue(usize::MAX)
        .subscription_buffer(usize::MAX)
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let echo = within("loop", client.loop_back(&b"q"[..])).await.unwrap();
    assert_eq!(&echo[..], b"q");
    let mut widths = within(
        "subscribe",
        client.subscribe_width_mm(UpdateOptions::periodic(Duration::from_millis(10))),
    )
    .await
    .unwrap();
    assert!(within("update", widths.next()).await.is_some());
}

/// `max_payload_len(usize::MAX)` over UDP overflowed the receive buffer's size (a panic in
/// debug builds, every datagram dropped in release): it means "any length the frame can carry".
#[tokio::test]
async fn usize_max_payload_len_over_udp_is_clamped() {
    let sim = SimServer::bind_udp("127.0.0.1:0", config()).await.unwrap();
    let client = Client::builder()
        .max_payload_len(usize::MAX)
        .connect_udp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let echo = within("udp loop", client.loop_back(&b"max"[..]))
        .await
        .unwrap();
    assert_eq!(&echo[..], b"max");
}

/// A `max_payload_len` below the echo of the client's own loop-back barriers (26 bytes) made
/// the client drop every echo, and a status-only reply (a stop's) below 2 bytes: it is raised
/// to 26, so such replies are read.
#[tokio::test]
async fn a_tiny_max_payload_len_still_reads_barrier_sized_replies() {
    let sim = SimServer::bind("127.0.0.1:0", config()).await.unwrap();
    let client = Client::builder()
        .max_payload_len(0)
        .query_timeout(Duration::from_secs(2))
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    within("stop", client.stop()).await.unwrap();
    // 24 bytes of payload: the length of a barrier's (prefix + token).
    let echo = within("loop", client.loop_back(&[7u8; 24][..]))
        .await
        .unwrap();
    assert_eq!(&echo[..], &[7u8; 24]);
}
