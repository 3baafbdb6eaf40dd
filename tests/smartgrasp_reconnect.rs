//! `ClientConfig::reconnect`: the client through the fault proxy to the simulator; the proxy pulls
//! the cable (`cut_connections`) and its stall switch holds the new connection's opening sequence
//! where a test needs to act in between. Every wait is on an event or a proxy counter, bounded by
//! `within`; the real clock runs (short backoff).
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use gripper::fault::{FaultProxy, Framing, ProxyConfig};
use gripper::reconnect::{ConnectionEvent, ConnectionEvents, ReconnectPolicy};
use gripper::smartgrasp::codec;
use gripper::smartgrasp::sim::{Fault, SimConfig, SimProject, SimServer};

/// The V3 simulator these tests were written for (the default speaks V4 too; V4 is
/// `tests/smartgrasp_v4.rs`).
fn v3_sim() -> SimConfig {
    SimConfig {
        max_version: 3,
        ..SimConfig::default()
    }
}
use common::{events_until, next_event, policy, within};
use gripper::smartgrasp::{
    AbcPose, Client, ClientConfig, Error, GetGraspOutcome, GraspMode, GraspRequest, Pose,
    PoseFormat, RobotSystem, Tool,
};

/// The demo project, and an empty one as project 1.
async fn sim() -> SimServer {
    let config = SimConfig {
        projects: vec![
            SimConfig::demo_project(),
            SimProject::from_scene(Vec::new()),
        ],
        ..v3_sim()
    };
    SimServer::bind("127.0.0.1:0", config).await.unwrap()
}

async fn proxy(server: &SimServer) -> FaultProxy {
    let config = ProxyConfig::new().framing(Framing::Custom(codec::proxy_frame_len));
    FaultProxy::start_with(server.local_addr(), config)
        .await
        .unwrap()
}

fn config(reconnect: Option<ReconnectPolicy>) -> ClientConfig {
    ClientConfig {
        query_timeout: Duration::from_secs(2),
        detection_timeout: Duration::from_secs(2),
        robot_system: Some(RobotSystem::Kuka),
        project_index: Some(0),
        reconnect,
        ..ClientConfig::default()
    }
}

/// The simulator, the proxy to it, a client through the proxy and its event stream.
async fn setup(
    reconnect: Option<ReconnectPolicy>,
) -> (SimServer, FaultProxy, Client, ConnectionEvents) {
    let server = sim().await;
    let proxy = proxy(&server).await;
    let client = Client::connect(proxy.local_addr(), config(reconnect))
        .await
        .unwrap();
    let events = client.connection_events();
    (server, proxy, client, events)
}

/// Reads events up to and including the first `Restored`.
async fn until_restored(events: &mut ConnectionEvents) -> Vec<ConnectionEvent> {
    events_until(events, |e| matches!(e, ConnectionEvent::Restored { .. })).await
}

fn grasp_request() -> GraspRequest {
    GraspRequest {
        grasp_mode: GraspMode::AnyGrasp,
        object_class: 1,
        tool: Tool::Exterior,
        selection_criterion: gripper::smartgrasp::SelectionCriterion::default(),
        pose_format: PoseFormat::Abc,
    }
}

async fn assert_grasp_works(client: &Client) {
    let outcome = within("get_grasp", client.get_grasp(grasp_request()))
        .await
        .unwrap();
    assert!(
        matches!(outcome, GetGraspOutcome::Grasp(g) if g.object_class == 1),
        "{outcome:?}"
    );
}

#[tokio::test]
async fn a_cut_is_reported_and_the_session_restored() {
    let (server, proxy, client, mut events) = setup(Some(policy(None))).await;
    // The program switches project and registers as another robot itself: a reconnect must
    // restore that, not the configuration's.
    client.set_project(1).await.unwrap();
    client.register_client(RobotSystem::Ur).await.unwrap();

    // Hold the new connection's requests, so a restarted server can "forget" the project first.
    let requests = proxy.client_to_server();
    requests.stall();
    proxy.cut_connections();
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Lost { .. })
    ));
    within(
        "opening sequence held",
        requests.wait_for(|s| s.held_bytes >= 80),
    )
    .await;
    let other = Client::connect(server.local_addr(), config(None))
        .await
        .unwrap();
    assert_eq!(
        server.with_state(|s| s.active_project()),
        Some(0),
        "set by the other client"
    );
    requests.release();

    let seen = until_restored(&mut events).await;
    assert_eq!(
        seen,
        [
            ConnectionEvent::Reconnecting {
                attempt: 1,
                delay: policy(None).initial_delay
            },
            ConnectionEvent::Connected,
            ConnectionEvent::Restored { attempts: 1 },
        ]
    );
    assert_eq!(
        server.registered_clients(),
        [
            RobotSystem::Kuka,
            RobotSystem::Ur,
            RobotSystem::Kuka,
            RobotSystem::Ur
        ],
        "config, program, other client, restored"
    );
    assert_eq!(
        server.with_state(|s| s.active_project()),
        Some(1),
        "restored"
    );
    // Project 1 is empty; back to the bin and pick.
    client.set_project(0).await.unwrap();
    assert_grasp_works(&client).await;
    assert!(!client.is_closed());
    drop(other);
}

#[tokio::test]
async fn calls_in_flight_fail_and_are_never_sent_again() {
    let (server, proxy, client, mut events) = setup(Some(policy(None))).await;
    let replies = proxy.server_to_client();
    replies.stall();
    let pose = Pose::Abc(AbcPose {
        position_um: [1, 2, 3],
        abc_udeg: [4, 5, 6],
    });
    let call = tokio::spawn({
        let client = client.clone();
        async move { client.robot_pose(pose).await }
    });
    // The server has the request and answered; the answer is held at the stall.
    within("reply held", replies.wait_for(|s| s.held_bytes == 80)).await;
    proxy.cut_connections();
    let err = within("call", call).await.unwrap().unwrap_err();
    assert!(matches!(err, Error::ConnectionLost { .. }), "{err}");
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Lost { .. })
    ));
    replies.release();
    until_restored(&mut events).await;
    assert_grasp_works(&client).await;
    assert_eq!(server.robot_poses(), [pose], "received once, never re-sent");
}

#[tokio::test]
async fn calls_made_while_reconnecting_wait_for_the_restored_session() {
    let (_server, proxy, client, mut events) = setup(Some(policy(None))).await;
    let requests = proxy.client_to_server();
    requests.stall();
    proxy.cut_connections();
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Lost { .. })
    ));
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Reconnecting { attempt: 1, .. })
    ));
    assert_eq!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Connected)
    );
    // The opening sequence is held at the stall: this call waits for it.
    let call = tokio::spawn({
        let client = client.clone();
        async move { client.get_grasp(grasp_request()).await }
    });
    within(
        "opening sequence held",
        requests.wait_for(|s| s.held_bytes >= 80),
    )
    .await;
    assert!(!call.is_finished());
    requests.release();
    let outcome = within("call", call).await.unwrap().unwrap();
    assert!(matches!(outcome, GetGraspOutcome::Grasp(_)), "{outcome:?}");
    assert_eq!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Restored { attempts: 1 })
    );
}

#[tokio::test]
async fn gives_up_after_max_attempts_and_closes() {
    let policy = policy(Some(2));
    let (server, _proxy, client, mut events) = setup(Some(policy)).await;
    // The server goes away for good: the proxy still accepts, but closes each connection.
    drop(server);
    let mut seen = Vec::new();
    while let Some(event) = next_event(&mut events).await {
        seen.push(event);
    }
    assert!(
        matches!(seen.first(), Some(ConnectionEvent::Lost { .. })),
        "{seen:?}"
    );
    assert_eq!(
        &seen[1..],
        [
            ConnectionEvent::Reconnecting {
                attempt: 1,
                delay: policy.initial_delay
            },
            ConnectionEvent::Connected,
            ConnectionEvent::Reconnecting {
                attempt: 2,
                delay: policy.initial_delay * 2
            },
            ConnectionEvent::Connected,
            ConnectionEvent::GaveUp { attempts: 2 },
        ]
    );
    let err = client.get_state().await.unwrap_err();
    assert!(matches!(err, Error::ConnectionLost { .. }), "{err}");
    assert!(client.is_closed());
}

#[tokio::test]
async fn close_ends_the_connection_and_fails_pending_and_later_calls() {
    let (server, proxy, client, mut events) = setup(None).await;
    let other = client.clone();
    let opening = proxy.client_to_server().stats().frames;
    // A request the server never answers is waiting when the client closes.
    server.inject(Fault::DropReply);
    let pending = tokio::spawn({
        let client = client.clone();
        async move { client.get_state().await }
    });
    within("the request reaches the server", async {
        while proxy.client_to_server().stats().frames == opening {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await;
    within("close", client.close()).await.unwrap();
    let r = within("pending call", pending).await.unwrap();
    assert!(matches!(r, Err(Error::Closed)), "{r:?}");
    let r = other.get_state().await;
    assert!(matches!(r, Err(Error::Closed)), "{r:?}");
    assert!(matches!(client.close().await, Err(Error::Closed)));
    assert!(client.is_closed());
    // Closing is not a loss: no event, the stream just ends.
    assert_eq!(next_event(&mut events).await, None);
    within("the connection is closed", async {
        while proxy.stats().connections_open != 0 {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await;
}

#[tokio::test]
async fn close_stops_reconnecting() {
    // A backoff far longer than the test: close() must not wait for it.
    let policy = ReconnectPolicy {
        initial_delay: Duration::from_secs(3600),
        max_delay: Duration::from_secs(3600),
        ..policy(None)
    };
    let (_server, proxy, client, mut events) = setup(Some(policy)).await;
    proxy.cut_connections();
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Lost { .. })
    ));
    assert!(matches!(
        next_event(&mut events).await,
        Some(ConnectionEvent::Reconnecting { attempt: 1, .. })
    ));
    within("close", client.close()).await.unwrap();
    assert_eq!(
        next_event(&mut events).await,
        None,
        "no attempt after close"
    );
    let r = client.get_state().await;
    assert!(matches!(r, Err(Error::Closed)), "{r:?}");
    assert!(client.is_closed());
    assert_eq!(proxy.stats().connections_accepted, 1, "no reconnect");
}

/// A SET_PROJECT the program made with a longer timeout than the configured detection timeout
/// (a server slow to load the project) is restored after a reconnect with that timeout, not the
/// configured one, under which it would time out attempt after attempt and the session would
/// never come back (issue 29 J, smartgrasp-v4:0xac95614eb8ec7a96).
#[tokio::test]
async fn a_slow_set_project_is_restored_with_the_timeout_that_worked() {
    let server = sim().await;
    let proxy = proxy(&server).await;
    let config = ClientConfig {
        detection_timeout: Duration::from_millis(200),
        ..config(Some(policy(None)))
    };
    let client = Client::connect(proxy.local_addr(), config).await.unwrap();
    let mut events = client.connection_events();
    let slow = Duration::from_millis(400);
    server.inject(Fault::DelayReply(slow));
    client
        .with_timeout(Duration::from_secs(2))
        .set_project(1)
        .await
        .unwrap();
    // Every opening sequence from now: GET_PROTOCOL_VERSION, GET_STATE and REGISTER_CLIENT at
    // once, SET_PROJECT after `slow`.
    for _ in 0..20 {
        for _ in 0..3 {
            server.inject(Fault::DelayReply(Duration::ZERO));
        }
        server.inject(Fault::DelayReply(slow));
    }
    proxy.cut_connections();
    let seen = until_restored(&mut events).await;
    assert!(
        matches!(seen.last(), Some(ConnectionEvent::Restored { attempts: 1 })),
        "{seen:?}"
    );
    assert_eq!(server.with_state(|s| s.active_project()), Some(1));
}

/// `connect_without_opening` speaks the configured version, V3 if none, on every connection: a
/// reconnect to a server that speaks V4 too must not negotiate V4 (issue 29 I), where a V3
/// GET_GRASP's tool would be silently dropped.
#[tokio::test]
async fn without_opening_a_reconnect_keeps_speaking_v3() {
    let server = SimServer::bind(
        "127.0.0.1:0",
        SimConfig {
            max_version: 4,
            ..SimConfig::default()
        },
    )
    .await
    .unwrap();
    let proxy = proxy(&server).await;
    let config = ClientConfig {
        reconnect: Some(policy(None)),
        ..ClientConfig::default()
    };
    let client = Client::connect_without_opening(proxy.local_addr(), config)
        .await
        .unwrap();
    let mut events = client.connection_events();
    assert_eq!(client.protocol_version(), 3);
    // A first call: the proxy has the connection by then, and cuts it.
    within("get_state", client.get_state()).await.unwrap();
    proxy.cut_connections();
    let seen = until_restored(&mut events).await;
    assert!(
        matches!(seen.last(), Some(ConnectionEvent::Restored { .. })),
        "{seen:?}"
    );
    assert_eq!((client.protocol_version(), client.server_version()), (3, 4));
    let GetGraspOutcome::Grasp(g) = within("get_grasp", client.get_grasp(grasp_request()))
        .await
        .unwrap()
    else {
        panic!("no grasp")
    };
    assert_eq!(g.tool, Some(Tool::Exterior));
}
