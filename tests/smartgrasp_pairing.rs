//! SmartGrasp client findings of issue 21, section 2, over loopback against the simulator or a
//! scripted server: a call's own timeout bounds its give-up, no legitimate answer is dropped as
//! a "repeat", a V3 GET_GRASP response may declare another pose format, and calls queued across
//! a reconnect speak the version that reconnect negotiated.
//!
//! Real clock (a paused one would fire the client's timeouts while the runtime waits on the
//! sockets); every wait is bounded by [`LIMIT`], which only a failing test reaches.
#![cfg(feature = "sim")]

mod common;

use std::future::Future;
use std::time::Duration;

use std::net::SocketAddr;

use futures_util::StreamExt;
use gripper::reconnect::{ConnectionEvent, ReconnectPolicy};
use gripper::smartgrasp::message::{Grasp, GraspRequest, Request, Response, ResponseBody};
use gripper::smartgrasp::sim::{Fault, SimConfig, SimServer};
use gripper::smartgrasp::{
    Client, ClientConfig, GetGraspOutcome, GraspMode, MessageType, Pose, PoseFormat, ResponseCode,
    RobotSystem, SelectionCriterion, ServerState, Tool,
};

/// Only reached when something hangs (a bug).
const LIMIT: Duration = Duration::from_secs(10);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

/// A V3 server that answers every request with `answer(request, n)` (`n` counts the responses
/// of the connection from 0, wrapping), in order, for as long as the connection lasts.
async fn scripted_v3(
    answer: impl Fn(&Request, u8) -> Response + Send + Sync + 'static,
) -> SocketAddr {
    common::smartgrasp_peer(move |_, i, frame| {
        let request = Request::from_frame(&frame).expect("a request the client can send");
        Some(answer(&request, i as u8).to_frame(3).encode().to_vec())
    })
    .await
}

/// The response a V3 server gives to GET_STATE and GET_PROTOCOL_VERSION (SUCCESS), with
/// `counter`.
fn plain_answer(request: &Request, counter: u8) -> Response {
    let (message_type, body) = match request {
        Request::GetState => (
            MessageType::GetState,
            ResponseBody::State(ServerState::Operational),
        ),
        Request::GetProtocolVersion => (
            MessageType::GetProtocolVersion,
            ResponseBody::ProtocolVersion(3),
        ),
        other => panic!("not scripted: {other:?}"),
    };
    Response {
        message_type,
        code: ResponseCode::Success,
        counter,
        body,
    }
}

// ---- 2.1: a call's own timeout bounds its give-up --------------------------------------------

/// A handle with a longer timeout (`with_timeout`) for a slow request: the connection is not
/// given up at the configured timeout plus `give_up_after`, but at the call's own timeout plus
/// `give_up_after`, as GRIPLINK does; with reconnect on, the session is not re-opened under it.
#[tokio::test]
async fn a_longer_call_timeout_is_not_cut_short_by_the_configured_one() {
    for reconnect in [None, Some(ReconnectPolicy::default())] {
        let server = SimServer::bind("127.0.0.1:0", SimConfig::default())
            .await
            .unwrap();
        let config = ClientConfig {
            robot_system: Some(RobotSystem::Ur),
            query_timeout: Duration::from_millis(50),
            detection_timeout: Duration::from_millis(50),
            give_up_after: Duration::from_millis(50),
            reconnect,
            ..ClientConfig::default()
        };
        let client = within("connect", Client::connect(server.local_addr(), config))
            .await
            .unwrap();
        // Three times the configured timeout plus give_up_after.
        server.inject(Fault::DelayReply(Duration::from_millis(300)));
        let slow = client.with_timeout(Duration::from_secs(5));
        let state = within("slow call", slow.get_state()).await;
        assert_eq!(state.unwrap(), ServerState::Operational, "{reconnect:?}");
        assert_eq!(
            server.registered_clients(),
            [RobotSystem::Ur],
            "{reconnect:?}: the session was opened again"
        );
        assert_eq!(
            within("next", client.get_state()).await.unwrap(),
            ServerState::Operational
        );
    }
}

// ---- 2.2: no legitimate answer dropped as a "repeat" -----------------------------------------

/// A server whose response counter never moves (SCHUNK's KRL never reads it, and manual 3.2.2.3
/// does not say what it counts) answers two GET_STATEs with byte-identical responses; so does a
/// server counting across its clients when 255 other responses went out in between. Both are
/// answers, not copies: each call gets its own, and the counter is only recorded as a gap.
#[tokio::test]
async fn identical_responses_of_a_server_with_a_constant_counter_are_answers() {
    let addr = scripted_v3(|request, _| plain_answer(request, 7)).await;
    let config = ClientConfig {
        query_timeout: Duration::from_secs(2),
        ..ClientConfig::default()
    };
    let client = within("connect", Client::connect(addr, config))
        .await
        .unwrap();
    for call in 0..4 {
        let state = within("get_state", client.get_state()).await;
        assert_eq!(state.unwrap(), ServerState::Operational, "call {call}");
    }
    assert!(client.counter_gaps() > 0);
}

// ---- 2.3: a V3 GET_GRASP response in another pose format --------------------------------------

/// The grasp pose a scripted server sends, in quaternion format: 450 mm, -120 mm, 50 mm, tool
/// pointing down (180° about x).
fn quaternion_pose() -> Pose {
    Pose::from_wire(
        PoseFormat::Quaternion,
        [450_000, -120_000, 50_000, 1_000_000, 0, 0, 0],
    )
    .unwrap()
}

/// Manual 3.3.3.1: the response's pose format is the format "used for the pose field", and the
/// pose's type "depends on the value in the field": not an echo of the request. A server that
/// answers a request for ABC with a quaternion pose gives a grasp, read as declared and converted
/// to the format the caller asked for; the connection stays up.
#[tokio::test]
async fn a_v3_grasp_in_another_pose_format_is_read_as_declared() {
    let addr = scripted_v3(|request, n| match request {
        Request::GetGrasp(asked) => Response {
            message_type: MessageType::GetGrasp,
            code: ResponseCode::Success,
            counter: n,
            body: ResponseBody::Grasp(Grasp {
                grasp_mode: GraspMode::AutoGrasp,
                object_class: 1,
                object_instance: 0,
                stroke_um: 86_000,
                center_offset_um: [0, 0],
                pose: quaternion_pose(),
                object_count: 1,
                candidate_count: 1,
                center_offset_z_um: Some(0),
                angle_offset_udeg: Some(0),
                tool: Some(asked.tool),
                reference_frame: None,
                object_offset: None,
            }),
        },
        other => plain_answer(other, n),
    })
    .await;
    let client = within("connect", Client::connect(addr, ClientConfig::default()))
        .await
        .unwrap();
    for format in [PoseFormat::Abc, PoseFormat::Wpr, PoseFormat::Quaternion] {
        let request = GraspRequest {
            grasp_mode: GraspMode::AutoGrasp,
            object_class: 0,
            tool: Tool::Exterior,
            selection_criterion: SelectionCriterion::default(),
            pose_format: format,
        };
        let outcome = within("get_grasp", client.get_grasp(request)).await;
        let Ok(GetGraspOutcome::Grasp(grasp)) = outcome else {
            panic!("{format:?}: {outcome:?}");
        };
        assert_eq!(grasp.pose, quaternion_pose().to_format(format).unwrap());
    }
    assert_eq!(
        within("get_state", client.get_state()).await.unwrap(),
        ServerState::Operational
    );
    assert!(!client.is_closed());
}

// ---- 2.5: calls queued across a reconnect speak the version it negotiated ---------------------

/// A firmware rollback: the client spoke V4; the connection is lost and the reconnect negotiates
/// V3. A call made while the client waits to reconnect goes out after it, in V3, and gets its
/// answer (not the server's "too old" empty message read as a broken frame).
#[tokio::test]
async fn a_call_queued_across_a_reconnect_speaks_the_version_it_negotiated() {
    let server = SimServer::bind("127.0.0.1:0", SimConfig::default())
        .await
        .unwrap();
    let config = ClientConfig {
        reconnect: Some(ReconnectPolicy {
            // Long enough to queue a call before the reconnect; never reached otherwise.
            initial_delay: Duration::from_millis(300),
            ..ReconnectPolicy::default()
        }),
        ..ClientConfig::default()
    };
    let client = within("connect", Client::connect(server.local_addr(), config))
        .await
        .unwrap();
    assert_eq!(client.protocol_version(), 4);
    let mut events = client.connection_events();
    server.with_state(|s| s.set_max_version(3));
    server.inject(Fault::Close);
    assert!(within("cut", client.get_state()).await.is_err());
    loop {
        match within("loss", events.next()).await {
            Some(ConnectionEvent::Lost { .. }) => break,
            Some(_) => {}
            None => panic!("the client closed"),
        }
    }
    // Made while the client still speaks V4, sent after the reconnect negotiated V3.
    let count = within("queued call", client.get_object_count(0)).await;
    assert_eq!(count.unwrap().object_count, 3);
    assert_eq!(client.protocol_version(), 3);
    assert_eq!(
        within("next", client.get_state()).await.unwrap(),
        ServerState::Operational
    );
}
