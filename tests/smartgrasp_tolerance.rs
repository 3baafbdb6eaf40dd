//! The client is tolerant where the manual is silent or contradicts itself (issue 12), and each
//! tolerance is pinned here against a raw TCP peer that behaves the way a real server may:
//! - a response counter that skips (a server counting across all its clients, manual 3.2.2.3);
//! - GET_OBJECT_COUNT answered as message type 17 (the manual's table, an erratum for 32);
//! - a REGISTER_CLIENT refused (3.3.2.3 calls the message informational);
//! - a server that stays connected and stops answering (given up after `give_up_after`);
//! - and the simulator answers a newer client's message of another length with the "too old"
//!   empty message before closing (1.3).
//!
//! Real clock; every wait is bounded by `within`.

#![cfg(feature = "sim")]

mod common;

use std::future::Future;
use std::net::SocketAddr;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::reconnect::{ConnectionEvent, ReconnectPolicy};
use gripper::smartgrasp::frame::{Prefix, RequestFrame, ResponseFrame, PREFIX_LEN};
use gripper::smartgrasp::sim::{SimConfig, SimServer};
use gripper::smartgrasp::{
    Client, ClientConfig, Error, MessageType, ResponseCode, RobotSystem, ServerState,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const LIMIT: Duration = Duration::from_secs(10);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

/// A well-formed SUCCESS answer to `request` with `counter`, as a v3 operational server.
fn answer(request: &RequestFrame, counter: u8) -> ResponseFrame {
    let mut f = ResponseFrame::new(request.header.message_type, ResponseCode::Success, counter);
    f.server_version = 3;
    f.server_state = ServerState::Operational;
    f.object_class = request.object_class;
    f.object_count = 4;
    f.candidate_count = 2;
    f
}

fn bytes(frame: ResponseFrame) -> Option<Vec<u8>> {
    Some(frame.encode().to_vec())
}

#[tokio::test]
async fn a_server_counting_across_clients_is_served_and_its_gaps_counted() {
    // Every response skips one counter value, as if another client's responses were in between.
    let addr = common::smartgrasp_peer(|_, i, req| bytes(answer(&req, (2 * i) as u8))).await;
    let client = within("connect", Client::connect(addr, ClientConfig::default()))
        .await
        .unwrap();
    // The opening sequence (two responses) already saw one gap.
    assert_eq!(client.counter_gaps(), 1);
    for _ in 0..3 {
        let count = within("count", client.get_object_count(7)).await.unwrap();
        assert_eq!(
            (count.object_count, count.candidate_count),
            (4, 2),
            "{count:?}"
        );
    }
    assert_eq!(client.counter_gaps(), 4);

    // The same server with a client that trusts the counter: the first gap fails.
    let strict = ClientConfig {
        strict_response_counter: true,
        ..ClientConfig::default()
    };
    let err = within("connect", Client::connect(addr, strict))
        .await
        .unwrap_err();
    assert!(matches!(err, Error::ResponseLost { .. }), "{err}");
}

#[tokio::test]
async fn an_object_count_answered_as_type_17_is_read_as_a_count() {
    let addr = common::smartgrasp_peer(|_, i, req| {
        let mut f = answer(&req, i as u8);
        if req.header.message_type == MessageType::GetObjectCount {
            f.header.message_type = MessageType::GraspFeedback;
        }
        bytes(f)
    })
    .await;
    let client = within("connect", Client::connect(addr, ClientConfig::default()))
        .await
        .unwrap();
    let count = within("count", client.get_object_count(3)).await.unwrap();
    assert_eq!(count.object_count, 4);
    assert_eq!(count.candidate_count, 2);
    // 17 still answers nothing but a count: a GET_STATE answered 17 breaks the connection.
    let addr = common::smartgrasp_peer(|_, i, req| {
        let mut f = answer(&req, i as u8);
        f.header.message_type = MessageType::GraspFeedback;
        bytes(f)
    })
    .await;
    let client = Client::connect_without_opening(addr, ClientConfig::default())
        .await
        .unwrap();
    let err = within("state", client.get_state()).await.unwrap_err();
    assert!(matches!(err, Error::MalformedReply(_)), "{err}");
}

#[tokio::test]
async fn a_refused_registration_is_reported_not_fatal() {
    let addr = common::smartgrasp_peer(|_, i, req| {
        let mut f = answer(&req, i as u8);
        if req.header.message_type == MessageType::RegisterClient {
            f.header.response_code = ResponseCode::Error;
        }
        bytes(f)
    })
    .await;
    let config = ClientConfig {
        robot_system: Some(RobotSystem::Horst),
        ..ClientConfig::default()
    };
    let client = within("connect", Client::connect(addr, config))
        .await
        .unwrap();
    assert_eq!(client.registration(), Some(ResponseCode::Error));
    assert_eq!(
        within("state", client.get_state()).await.unwrap(),
        ServerState::Operational
    );
    // Accepted: reported as SUCCESS; not sent: None.
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let config = ClientConfig {
        robot_system: Some(RobotSystem::Kuka),
        ..ClientConfig::default()
    };
    let client = Client::connect(sim.local_addr(), config).await.unwrap();
    assert_eq!(client.registration(), Some(ResponseCode::Success));
    let client = Client::connect(sim.local_addr(), ClientConfig::default())
        .await
        .unwrap();
    assert_eq!(client.registration(), None);
}

/// Answers the opening sequence (two requests) on every connection, then only on connections
/// after the first: the first connection's server goes mute.
async fn mute_after_opening() -> SocketAddr {
    common::smartgrasp_peer(|connection, i, req| {
        (connection > 0 || i < 2).then(|| answer(&req, i as u8).encode().to_vec())
    })
    .await
}

fn mute_config(reconnect: Option<ReconnectPolicy>) -> ClientConfig {
    ClientConfig {
        query_timeout: Duration::from_millis(100),
        detection_timeout: Duration::from_millis(100),
        give_up_after: Duration::from_millis(200),
        reconnect,
        ..ClientConfig::default()
    }
}

#[tokio::test]
async fn a_mute_server_is_given_up_after_the_configured_time() {
    let addr = mute_after_opening().await;
    let client = within("connect", Client::connect(addr, mute_config(None)))
        .await
        .unwrap();
    let mut events = client.connection_events();
    // Far more calls than slots: without giving up, every one after the 16th would wait for a
    // slot that never frees.
    for _ in 0..20 {
        let err = within("state", client.get_state()).await.unwrap_err();
        if matches!(err, Error::ConnectionLost { .. }) {
            break;
        }
        assert!(matches!(err, Error::Timeout { .. }), "{err}");
    }
    let lost = within("the loss", events.next()).await;
    assert!(
        matches!(&lost, Some(ConnectionEvent::Lost { reason }) if reason.contains("stopped answering")),
        "{lost:?}"
    );
    let err = within("state", client.get_state()).await.unwrap_err();
    assert!(matches!(err, Error::ConnectionLost { .. }), "{err}");
}

#[tokio::test]
async fn a_mute_server_is_reconnected_to() {
    let addr = mute_after_opening().await;
    let policy = ReconnectPolicy {
        initial_delay: Duration::from_millis(10),
        max_delay: Duration::from_millis(40),
        factor: 2.0,
        max_attempts: None,
    };
    let client = within("connect", Client::connect(addr, mute_config(Some(policy))))
        .await
        .unwrap();
    let mut events = client.connection_events();
    let err = within("state", client.get_state()).await.unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    loop {
        match within("restored", events.next()).await {
            Some(ConnectionEvent::Restored { .. }) => break,
            Some(_) => {}
            None => panic!("the events ended without a reconnect"),
        }
    }
    assert_eq!(
        within("state", client.get_state()).await.unwrap(),
        ServerState::Operational
    );
}

#[tokio::test]
async fn the_simulator_answers_a_newer_message_of_any_length_with_too_old_then_closes() {
    let server = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let mut stream = TcpStream::connect(server.local_addr()).await.unwrap();
    // A hypothetical v9 message with 200 bytes after the prefix.
    let mut message = Prefix {
        version: 9,
        length: 200,
    }
    .encode()
    .to_vec();
    message.resize(PREFIX_LEN + 200, 0);
    stream.write_all(&message).await.unwrap();
    let mut answer = Vec::new();
    within("answer and close", stream.read_to_end(&mut answer))
        .await
        .unwrap();
    assert_eq!(
        answer,
        Prefix {
            version: SimConfig::default().max_version,
            length: 0
        }
        .encode()
    );

    // A bad length at a version the server speaks: closed without an answer.
    let mut stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let bad = Prefix {
        version: 3,
        length: 200,
    }
    .encode();
    stream.write_all(&bad).await.unwrap();
    let mut answer = Vec::new();
    within("close", stream.read_to_end(&mut answer))
        .await
        .unwrap();
    assert!(answer.is_empty(), "{answer:?}");
}
