//! `ClientConfig::reconnect`: after a lost connection the client reconnects with backoff,
//! restores VERBOSE, reports each step through `connection_events()`, and never sends a call
//! that was in flight again.
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use common::{cut_and_restored, events_until, policy, restored_after, within};
use futures_util::StreamExt as _;
use gripper::fault::{FaultProxy, Framing, ProxyConfig};
use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
use gripper::griplink::{Blocking, Client, ClientConfig, DeviceState, Error, Status};
use gripper::reconnect::ConnectionEvent;

async fn sim() -> SimServer {
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .time_scale(0.0);
    SimServer::bind("127.0.0.1:0", config).await.unwrap()
}

fn reconnecting(max_attempts: Option<u32>) -> ClientConfig {
    ClientConfig {
        reconnect: Some(policy(max_attempts)),
        ..ClientConfig::default()
    }
}

/// A simulator, a proxy to pull the cable with, and a reconnecting client through it.
async fn proxied() -> (SimServer, FaultProxy, Client) {
    let server = sim().await;
    let lines = ProxyConfig::new().framing(Framing::Delimited(b'\n'));
    let proxy = FaultProxy::start_with(server.local_addr(), lines)
        .await
        .unwrap();
    let client = Client::connect_with(proxy.local_addr(), reconnecting(None))
        .await
        .unwrap();
    (server, proxy, client)
}

#[tokio::test]
async fn reconnects_after_a_cut_restores_verbose_and_reports_each_step() {
    let (_server, proxy, client) = proxied().await;
    assert!(client.set_verbose(true).await.unwrap());
    let mut events = client.connection_events();
    let commands = proxy.client_to_server().stats().frames;

    cut_and_restored(&proxy, &mut events).await;
    // Restoring sent exactly one line: VERBOSE=1.
    assert_eq!(proxy.client_to_server().stats().frames, commands + 1);
    assert_eq!(proxy.stats().connections_accepted, 2);

    // The new connection is verbose: an ERR carries the controller's text.
    let err = client
        .port(0)
        .grip(0, Blocking::Immediate)
        .await
        .unwrap_err();
    match err {
        Error::Device { status, text, .. } => {
            assert_eq!(status, Status::NotInitialized);
            assert_eq!(text.as_deref(), Some("Device not initialized"));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn a_call_in_flight_when_the_link_drops_fails_and_is_never_sent_again() {
    let (server, proxy, client) = proxied().await;
    let mut events = client.connection_events();
    let g = client.port(0);
    g.home().await.unwrap();
    // The GRIP runs on the controller, its ACK is held, and then the cable is pulled.
    let gate = server.hold_next_reply();
    let grip = tokio::spawn({
        let g = g.clone();
        async move { g.grip(0, Blocking::Immediate).await }
    });
    within("grip", async {
        while server.device_state(0) != Some(DeviceState::Holding) {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await;
    let commands = proxy.client_to_server().stats().frames;
    proxy.cut_connections();
    let r = within("grip result", grip).await.unwrap();
    assert!(matches!(r, Err(Error::ConnectionLost { .. })), "{r:?}");
    gate.release();
    events_until(&mut events, |e| {
        matches!(e, ConnectionEvent::Restored { .. })
    })
    .await;
    // Nothing was sent on the new connection (VERBOSE was never set): the GRIP was not
    // repeated. The device holds the part from the one GRIP that ran.
    assert_eq!(proxy.client_to_server().stats().frames, commands);
    assert_eq!(g.state().await.unwrap(), DeviceState::Holding);
}

#[tokio::test]
async fn close_does_not_reconnect() {
    let server = sim().await;
    let client = Client::connect_with(server.local_addr(), reconnecting(None))
        .await
        .unwrap();
    let mut events = client.connection_events();
    client.close().await.unwrap();
    // No loss, no attempt: the stream just ends.
    assert_eq!(within("end", events.next()).await, None);
    assert!(matches!(client.id().await, Err(Error::Closed)));
}

#[tokio::test]
async fn a_watch_goes_on_across_a_reconnect() {
    let (_server, proxy, client) = proxied().await;
    let mut events = client.connection_events();
    let mut states = client.port(0).watch_state(Duration::from_millis(1));
    assert_eq!(
        within("first", states.next()).await.unwrap().unwrap(),
        DeviceState::NotInitialized
    );
    proxy.cut_connections();
    events_until(&mut events, |e| {
        matches!(e, ConnectionEvent::Restored { .. })
    })
    .await;
    // Whatever the loss cost (a failed poll), readings come again.
    loop {
        match within("reading", states.next()).await {
            Some(Ok(state)) => {
                assert_eq!(state, DeviceState::NotInitialized);
                break;
            }
            Some(Err(_)) => continue,
            None => panic!("the watch ended although the client reconnected"),
        }
    }
    assert!(!client.is_closed());
}

/// The restored `VERBOSE` is the client's own command, bounded (`give_up_after` past the query
/// timeout, at most 10 s) even when the program's calls have no timeout
/// (`query_timeout(Duration::MAX)`): a new connection whose controller never answers it is
/// given up, and the next attempt restores the session. Before the fix the restore waited for
/// ever on it, and every call behind it. In-memory pipes, so the paused clock runs the bound's
/// seconds at once.
#[tokio::test(start_paused = true)]
async fn a_restored_verbose_left_unanswered_is_bounded_without_a_query_timeout() {
    use gripper::griplink::sim::Fault;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    let sim = Arc::new(SimServer::in_memory(
        SimConfig::et4()
            .device(0, Some(SimDevice::ieg_55_020()))
            .time_scale(0.0),
    ));
    let opened = Arc::new(AtomicUsize::new(0));
    let open = {
        let (sim, opened) = (sim.clone(), opened.clone());
        move || {
            let (near, far) = tokio::io::duplex(4096);
            opened.fetch_add(1, Ordering::SeqCst);
            sim.serve_stream(far);
            std::future::ready(Ok(near))
        }
    };
    let config = ClientConfig {
        query_timeout: Duration::MAX,
        ..reconnecting(None)
    };
    let client = Client::open_with(open, config).await.unwrap();
    assert!(client.set_verbose(true).await.unwrap());
    let mut events = client.connection_events();

    // The next line closes the connection; the restored VERBOSE on the next one goes unanswered.
    sim.inject(Fault::Close);
    sim.inject(Fault::DropReply);
    let lost = client.port(0).state().await;
    assert!(
        matches!(lost, Err(Error::ConnectionLost { .. })),
        "{lost:?}"
    );
    assert_eq!(restored_after(&mut events).await, 2);
    assert_eq!(opened.load(Ordering::SeqCst), 3);
    // The session works again.
    assert_eq!(
        client.port(0).state().await.unwrap(),
        DeviceState::NotInitialized
    );
    client.close().await.unwrap();
}
