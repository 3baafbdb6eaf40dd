//! Reconnecting (`ClientBuilder::reconnect`): after a lost connection the client reconnects with
//! backoff, restores the auto-update streams that still have subscribers, reports each step, and
//! never re-sends a command that was in flight. The gripper's FAST STOP after an unannounced TCP
//! loss is left for the program to acknowledge.
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use common::{next_event, policy, LIMIT};
use futures_util::StreamExt;
use gripper::reconnect::{ConnectionEvent, ReconnectPolicy};
use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Error, HomingDirection, Status, SystemState, UpdateOptions};

fn count(sim: &SimServer, command: u8) -> usize {
    sim.received_ids().iter().filter(|i| **i == command).count()
}

#[tokio::test]
async fn a_cut_connection_is_restored_with_its_streams_and_the_move_is_not_resent() {
    let (sim, proxy) =
        common::wsg_sim_behind_proxy(SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)).await;
    let client = Client::builder()
        .reconnect(policy(None))
        .connect_tcp(proxy.local_addr())
        .await
        .unwrap();
    let mut events = client.connection_events();
    let mut widths = client
        .subscribe_width_mm(UpdateOptions::periodic(Duration::from_millis(10)))
        .await
        .unwrap();
    let mut grip = client
        .subscribe_grip_state(UpdateOptions::on_change(Duration::from_millis(10)))
        .await
        .unwrap();
    // Subscribed, then dropped: not restored.
    drop(
        client
            .subscribe_force_n(UpdateOptions::periodic(Duration::from_millis(10)))
            .await
            .unwrap(),
    );
    let mover = common::wsg_start_moving(&sim, &client).await;

    proxy.cut_connections();
    // The move in flight fails and is never sent again.
    let err = tokio::time::timeout(LIMIT, mover).await.unwrap().unwrap();
    assert!(matches!(err, Err(Error::ConnectionLost { .. })), "{err:?}");
    match next_event(&mut events)
        .await
        .expect("the event stream ended")
    {
        ConnectionEvent::Lost { reason } => assert!(reason.contains("FAST STOP"), "{reason}"),
        other => panic!("expected Lost, got {other:?}"),
    }
    assert!(matches!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::Reconnecting { attempt: 1, .. }
    ));
    assert_eq!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::Connected
    );
    assert_eq!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::Restored { attempts: 1 }
    );

    // Calls work again. The gripper is in FAST STOP (the cut was an unannounced close) and the
    // client did not acknowledge it.
    let mut state = client.system_state().await.unwrap();
    for _ in 0..10_000 {
        if state.contains(SystemState::FAST_STOP) {
            break;
        }
        state = client.system_state().await.unwrap();
    }
    assert!(state.contains(SystemState::FAST_STOP), "{state:?}");
    assert_eq!(count(&sim, id::ACK_FAST_STOP), 0);
    assert_eq!(
        count(&sim, id::PRE_POSITION),
        1,
        "the cut-off move was re-sent"
    );
    assert_eq!(
        client
            .home(HomingDirection::Default)
            .await
            .unwrap_err()
            .status(),
        Some(Status::AccessDenied)
    );

    // Both live streams were switched on again on the new connection and keep delivering.
    assert_eq!(sim.snapshot().streams, 2);
    let widths_before = count(&sim, id::WIDTH);
    assert!(widths_before >= 2);
    // Drain what was buffered before the cut; then a value from the new connection arrives.
    while let Some(Some(_)) = futures_util::FutureExt::now_or_never(widths.next()) {}
    let w = tokio::time::timeout(LIMIT, widths.next()).await.unwrap();
    assert!(w.is_some());
    // FAST STOP made the grip state change to ERROR: the on-change stream reports it.
    let mut last = None;
    while last != Some(gripper::wsg::GripState::Error) {
        last = tokio::time::timeout(LIMIT, grip.next()).await.unwrap();
    }
    // The program decides to go on.
    client.acknowledge_fast_stop().await.unwrap();
    sim.set_time_scale(0.0);
    client.home(HomingDirection::Default).await.unwrap();
    client.close().await.unwrap();
}

#[tokio::test]
async fn the_client_gives_up_after_its_attempts_and_later_calls_fail() {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50))
        .await
        .unwrap();
    let client = Client::builder()
        .reconnect(policy(Some(2)))
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let mut events = client.connection_events();
    let mut states = client
        .subscribe_system_state(UpdateOptions::on_change(Duration::from_millis(10)))
        .await
        .unwrap();
    client.system_info().await.unwrap();
    // The simulator goes away for good: every attempt is refused.
    sim.shutdown();
    assert!(matches!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::Lost { .. }
    ));
    for attempt in 1..=2 {
        assert!(matches!(
            next_event(&mut events).await.expect("the event stream ended"),
            ConnectionEvent::Reconnecting { attempt: a, .. } if a == attempt
        ));
    }
    assert_eq!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::GaveUp { attempts: 2 }
    );
    // The events and the stream end; calls fail with the loss.
    assert_eq!(
        tokio::time::timeout(LIMIT, events.next()).await.unwrap(),
        None
    );
    while tokio::time::timeout(LIMIT, states.next())
        .await
        .unwrap()
        .is_some()
    {}
    assert!(matches!(
        client.system_info().await,
        Err(Error::ConnectionLost { .. })
    ));
}

/// `close()` while the client reconnects stops it at once (issue 30; the contract's
/// `close_during_a_backoff_returns_promptly` holds every protocol to it with a long backoff):
/// `Ok`, nothing to announce without a connection, and the client is closed, not lost.
#[tokio::test]
async fn close_while_reconnecting_closes() {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50))
        .await
        .unwrap();
    let client = Client::builder()
        .reconnect(ReconnectPolicy {
            initial_delay: Duration::from_millis(20),
            max_delay: Duration::from_millis(20),
            factor: 1.0,
            max_attempts: None,
        })
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let mut events = client.connection_events();
    sim.shutdown();
    assert!(matches!(
        next_event(&mut events)
            .await
            .expect("the event stream ended"),
        ConnectionEvent::Lost { .. }
    ));
    assert!(!client.is_closed(), "a reconnecting client is not closed");
    let closed = tokio::time::timeout(LIMIT, client.close()).await.unwrap();
    assert!(closed.is_ok(), "{closed:?}");
    assert!(client.is_closed());
    let query = client.width_mm().await;
    assert!(matches!(query, Err(Error::Closed)), "{query:?}");
    // The events end: no attempt is made after the close.
    while let Some(e) = tokio::time::timeout(LIMIT, events.next()).await.unwrap() {
        assert!(
            matches!(
                e,
                ConnectionEvent::Reconnecting { .. } | ConnectionEvent::GaveUp { .. }
            ),
            "{e:?}"
        );
    }
}
