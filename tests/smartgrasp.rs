//! The smartgrasp client against the simulator (and against raw TCP peers where the simulator
//! would be too polite), over real loopback sockets.
#![cfg(feature = "sim")]

use std::net::SocketAddr;
use std::time::Duration;

use gripper::smartgrasp::frame::{Prefix, RequestFrame, ResponseFrame, FRAME_LEN};
use gripper::smartgrasp::sim::{Fault, SimConfig, SimServer};
use gripper::smartgrasp::{
    AbcPose, AxisAnglePose, Client, ClientConfig, Error, GetGraspOutcome, GraspFeedback, GraspMode,
    GraspRequest, Malformed, MessageType, ObjectCount, Pose, PoseFormat, QuaternionPose, Request,
    ResponseCode, RobotSystem, ServerState, Tool, WprPose,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

/// The V3 simulator these tests were written for (the default speaks V4 too; V4 is
/// `tests/smartgrasp_v4.rs`).
fn v3_sim() -> SimConfig {
    SimConfig {
        max_version: 3,
        ..SimConfig::default()
    }
}

/// [`v3_sim`] whose GRASP_FEEDBACK OK takes the object out of the scene (the simulator option;
/// SCHUNK's server ignores feedback).
fn v3_picking_sim() -> SimConfig {
    SimConfig {
        feedback_removes_objects: true,
        ..v3_sim()
    }
}

async fn sim(config: SimConfig) -> SimServer {
    SimServer::bind("127.0.0.1:0", config).await.expect("bind")
}

async fn open(server: &SimServer) -> Client {
    Client::connect(server.local_addr(), ClientConfig::default())
        .await
        .expect("opening sequence")
}

fn grasp_request(class: u16, mode: GraspMode, format: PoseFormat) -> GraspRequest {
    GraspRequest {
        grasp_mode: mode,
        object_class: class,
        tool: Tool::Exterior,
        selection_criterion: gripper::smartgrasp::SelectionCriterion::default(),
        pose_format: format,
    }
}

fn expect_grasp(outcome: GetGraspOutcome) -> gripper::smartgrasp::Grasp {
    match outcome {
        GetGraspOutcome::Grasp(g) => g,
        other => panic!("expected a grasp, got {other:?}"),
    }
}

#[test]
fn the_handle_is_clone_send_sync() {
    fn shareable<T: Clone + Send + Sync + 'static>() {}
    shareable::<Client>();
    shareable::<Error>();
}

#[tokio::test]
async fn opening_sequence_registers_and_sets_the_project() {
    let server = sim(v3_sim()).await;
    let config = ClientConfig {
        robot_system: Some(RobotSystem::SiemensPlc),
        project_index: Some(0),
        ..ClientConfig::default()
    };
    let client = Client::connect(server.local_addr(), config).await.unwrap();
    assert_eq!(server.registered_clients(), [RobotSystem::SiemensPlc]);
    assert_eq!(server.with_state(|s| s.active_project()), Some(0));
    assert_eq!(client.get_protocol_version().await.unwrap(), 3);
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
}

#[tokio::test]
async fn every_message_type() {
    let server = sim(v3_picking_sim()).await;
    let client = open(&server).await;

    client.register_client(RobotSystem::Ur).await.unwrap();
    client.set_project(0).await.unwrap();
    assert_eq!(server.registered_clients(), [RobotSystem::Ur]);

    assert_eq!(
        client.get_object_count(0).await.unwrap(),
        ObjectCount {
            object_class: 0,
            object_count: 3,
            candidate_count: 3
        }
    );
    assert_eq!(client.get_object_count(2).await.unwrap().candidate_count, 1);

    // ROBOT_POSE in all four formats, recorded exactly as sent.
    let poses = [
        Pose::Quaternion(QuaternionPose {
            position_um: [1, -2, 3],
            quaternion_e6: [0, 0, 707_107, 707_107],
        }),
        Pose::AxisAngle(AxisAnglePose {
            position_um: [4, 5, -6],
            rotation_vector_urad: [0, 3_141_593, 0],
        }),
        Pose::Wpr(WprPose {
            position_um: [7, 8, 9],
            wpr_udeg: [180_000_000, -45_000_000, 1],
        }),
        Pose::Abc(AbcPose {
            position_um: [i32::MAX, i32::MIN, 0],
            abc_udeg: [-1, 2, -3],
        }),
    ];
    for pose in poses {
        client.robot_pose(pose).await.unwrap();
    }
    assert_eq!(server.robot_poses(), poses);

    // The same grasp in each pose format is the same pose.
    let reference = expect_grasp(
        client
            .get_grasp(grasp_request(
                1,
                GraspMode::ActiveGrasp,
                PoseFormat::Quaternion,
            ))
            .await
            .unwrap(),
    );
    assert_eq!(reference.grasp_mode, GraspMode::ActiveGrasp);
    assert_eq!((reference.object_class, reference.object_instance), (1, 0));
    assert_eq!(reference.stroke_um, 86_000);
    assert_eq!(reference.angle_offset_udeg, Some(-25_210_142));
    assert_eq!(reference.center_offset_um, [-911, -310]);
    assert_eq!(reference.center_offset_z_um, Some(68));
    assert_eq!(reference.tool, Some(Tool::Exterior));
    assert_eq!(
        (reference.reference_frame, reference.object_offset),
        (None, None)
    );
    assert_eq!((reference.object_count, reference.candidate_count), (3, 2));
    let reference_si = reference.pose.to_si().unwrap();
    for format in [PoseFormat::AxisAngle, PoseFormat::Wpr, PoseFormat::Abc] {
        let g = expect_grasp(
            client
                .get_grasp(grasp_request(1, GraspMode::ActiveGrasp, format))
                .await
                .unwrap(),
        );
        assert_eq!(g.pose.format(), format);
        let si = g.pose.to_si().unwrap();
        assert_eq!(g.pose.position_um(), reference.pose.position_um());
        assert!(si.orientation.angle_to_rad(&reference_si.orientation) < 5e-6);
    }

    // With the simulator option, GRASP_FEEDBACK OK takes the object out of the scene; BAD
    // leaves it.
    client.grasp_feedback(GraspFeedback::Bad).await.unwrap();
    assert_eq!(client.get_object_count(0).await.unwrap().object_count, 3);
    let _ = client
        .get_grasp(grasp_request(0, GraspMode::AnyGrasp, PoseFormat::Abc))
        .await
        .unwrap();
    client.grasp_feedback(GraspFeedback::Ok).await.unwrap();
    assert_eq!(client.get_object_count(0).await.unwrap().object_count, 2);
}

#[tokio::test]
async fn every_response_code() {
    let server = sim(v3_picking_sim()).await;
    let client = open(&server).await;

    // ERROR: no such project; feedback with no grasp to refer to (the simulator option).
    assert!(matches!(
        client.set_project(99).await,
        Err(Error::Device {
            message_type: MessageType::SetProject,
            status: ResponseCode::Error
        })
    ));
    assert!(matches!(
        client.grasp_feedback(GraspFeedback::Ok).await,
        Err(Error::Device {
            status: ResponseCode::Error,
            ..
        })
    ));
    // NO_GRASP: class 2 has no active grasp.
    assert_eq!(
        client
            .get_grasp(grasp_request(2, GraspMode::ActiveGrasp, PoseFormat::Abc))
            .await
            .unwrap(),
        GetGraspOutcome::NoGrasp
    );
    // INVALID_OBJECT_CLASS, as an outcome of GET_GRASP and a refusal of GET_OBJECT_COUNT.
    assert_eq!(
        client
            .get_grasp(grasp_request(9, GraspMode::AnyGrasp, PoseFormat::Abc))
            .await
            .unwrap(),
        GetGraspOutcome::InvalidObjectClass
    );
    assert!(matches!(
        client.get_object_count(9).await,
        Err(Error::Device {
            message_type: MessageType::GetObjectCount,
            status: ResponseCode::InvalidObjectClass
        })
    ));
    // NO_OBJECT once the scene is empty.
    server.with_state(|s| s.projects_mut()[0].scene.clear());
    assert_eq!(
        client
            .get_grasp(grasp_request(0, GraspMode::AutoGrasp, PoseFormat::Abc))
            .await
            .unwrap(),
        GetGraspOutcome::NoObject
    );
    // ERROR from a stopped server.
    server.with_state(|s| s.set_server_state(ServerState::Stopped));
    assert!(matches!(
        client
            .get_grasp(grasp_request(0, GraspMode::AutoGrasp, PoseFormat::Abc))
            .await,
        Err(Error::Device {
            status: ResponseCode::Error,
            ..
        })
    ));
    // A pose format the client cannot read is refused before sending.
    assert!(matches!(
        client
            .get_grasp(grasp_request(
                0,
                GraspMode::AutoGrasp,
                PoseFormat::Unknown(5)
            ))
            .await,
        Err(Error::InvalidArgument { .. })
    ));
    // The connection survived all of it.
    assert_eq!(client.get_state().await.unwrap(), ServerState::Stopped);
}

#[tokio::test]
async fn a_stopped_server_fails_the_opening_sequence() {
    let server = sim(SimConfig {
        server_state: ServerState::Init,
        ..v3_sim()
    })
    .await;
    let err = Client::connect(server.local_addr(), ClientConfig::default())
        .await
        .unwrap_err();
    assert!(matches!(
        err,
        Error::NotOperational {
            state: ServerState::Init
        }
    ));
}

#[tokio::test]
async fn response_counter_wraps_past_255() {
    let server = sim(SimConfig {
        first_response_counter: 250,
        ..v3_sim()
    })
    .await;
    let client = open(&server).await;
    // Two responses in the opening sequence, then across 255 → 0 and beyond.
    for _ in 0..12 {
        assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
    }
    let raw = client
        .call(gripper::smartgrasp::Request::GetState)
        .await
        .unwrap();
    assert_eq!(raw.counter, 8, "250 + 14 responses, modulo 256");
}

#[tokio::test]
async fn server_too_old_is_a_typed_error() {
    let server = sim(SimConfig {
        max_version: 2,
        ..v3_sim()
    })
    .await;
    let err = Client::connect(server.local_addr(), ClientConfig::default())
        .await
        .unwrap_err();
    assert!(
        matches!(
            err,
            Error::ServerTooOld {
                server_version: 2,
                client_version: 3
            }
        ),
        "{err}"
    );
    // A newer server serves a v3 client.
    let newer = sim(SimConfig {
        max_version: 4,
        ..v3_sim()
    })
    .await;
    let client = open(&newer).await;
    assert_eq!(client.get_protocol_version().await.unwrap(), 4);
}

#[tokio::test]
async fn a_skipped_response_is_reported_to_its_caller_not_handed_to_the_next() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    // Two calls in flight; the server processes the first and never answers it, so the second's
    // response arrives with a gap in the counter.
    server.inject(Fault::DropReply);
    let (first, second) = tokio::join!(client.get_protocol_version(), client.get_object_count(0));
    assert!(
        matches!(first, Err(Error::ResponseLost { expected, received }) if received == expected.wrapping_add(1)),
        "{first:?}"
    );
    assert_eq!(second.unwrap().object_count, 3);
    // The connection is fine afterwards.
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
}

#[tokio::test]
async fn a_skipped_response_after_a_timeout_is_charged_to_the_abandoned_call() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    server.inject(Fault::DropReply);
    let err = client
        .with_timeout(Duration::from_millis(100))
        .get_state()
        .await
        .unwrap_err();
    assert!(
        matches!(
            err,
            Error::Timeout {
                message_type: MessageType::GetState,
                ..
            }
        ),
        "{err}"
    );
    // The next call's response shows the gap; the abandoned slot takes the loss.
    assert_eq!(client.get_object_count(1).await.unwrap().candidate_count, 2);
}

#[tokio::test]
async fn a_late_reply_is_discarded_not_handed_to_the_next_caller() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    server.inject(Fault::DelayReply(Duration::from_millis(300)));
    let err = client
        .with_timeout(Duration::from_millis(50))
        .get_protocol_version()
        .await
        .unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    // The GET_PROTOCOL_VERSION reply arrives after this request went out: it must be discarded.
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
    assert_eq!(client.get_object_count(2).await.unwrap().candidate_count, 1);
}

#[tokio::test]
async fn dropped_calls_never_shift_the_pairing() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    for _ in 0..20 {
        // Dropped after its first poll: sent or not, its reply must never reach anyone.
        let _ = tokio::time::timeout(Duration::ZERO, client.get_object_count(0)).await;
        assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
        assert_eq!(client.get_protocol_version().await.unwrap(), 3);
    }
}

#[tokio::test]
async fn concurrent_callers_each_get_their_own_answer() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    let mut tasks = Vec::new();
    for task in 0..8u16 {
        let client = client.clone();
        tasks.push(tokio::spawn(async move {
            for i in 0..25u16 {
                match (task + i) % 3 {
                    0 => assert_eq!(client.get_state().await.unwrap(), ServerState::Operational),
                    1 => assert_eq!(client.get_protocol_version().await.unwrap(), 3),
                    _ => {
                        let class = 1 + (task + i) % 2;
                        let count = client.get_object_count(class).await.unwrap();
                        assert_eq!(count.object_class, class);
                        assert_eq!(count.candidate_count, 3 - class);
                    }
                }
            }
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }
}

#[tokio::test]
async fn more_callers_than_the_queue_holds_each_get_their_own_answer() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    // Far more than the 16 requests in flight and the 32 queued calls: the rest wait for room
    // in the queue.
    let mut tasks = tokio::task::JoinSet::new();
    for task in 0..120u16 {
        let client = client.clone();
        tasks.spawn(async move {
            let class = 1 + task % 2;
            let count = client.get_object_count(class).await.unwrap();
            assert_eq!(count.object_class, class);
            assert_eq!(count.candidate_count, 3 - class);
        });
    }
    let mut done = 0;
    while let Some(task) = tasks.join_next().await {
        task.unwrap();
        done += 1;
    }
    assert_eq!(done, 120);
}

#[tokio::test]
async fn a_corrupt_length_breaks_the_connection() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    server.inject(Fault::CorruptLength(75));
    let err = client.get_state().await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: 75 })
        ),
        "{err}"
    );
    assert!(matches!(
        client.get_state().await,
        Err(Error::ConnectionLost { .. })
    ));
    assert!(client.is_closed());
}

#[tokio::test]
async fn the_server_closing_fails_the_call() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    server.inject(Fault::Close);
    assert!(matches!(
        client.get_state().await,
        Err(Error::ConnectionLost { .. })
    ));
    assert!(matches!(
        client.get_state().await,
        Err(Error::ConnectionLost { .. })
    ));
}

/// A raw TCP peer: accepts one connection, reads 80-byte requests and writes whatever `respond`
/// returns for the i-th one.
async fn raw_peer(
    mut respond: impl FnMut(usize, RequestFrame) -> Vec<u8> + Send + 'static,
) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (mut stream, _) = listener.accept().await.unwrap();
        let mut buf = [0u8; FRAME_LEN];
        let mut i = 0;
        while stream.read_exact(&mut buf).await.is_ok() {
            let out = respond(i, RequestFrame::decode(&buf));
            i += 1;
            if stream.write_all(&out).await.is_err() {
                break;
            }
        }
    });
    addr
}

/// A well-formed answer to `request` with counter `counter`.
fn answer(request: &RequestFrame, counter: u8) -> ResponseFrame {
    let mut f = ResponseFrame::new(request.header.message_type, ResponseCode::Success, counter);
    f.server_version = 3;
    f.server_state = ServerState::Operational;
    f
}

async fn bare(addr: SocketAddr) -> Client {
    Client::connect_without_opening(addr, ClientConfig::default())
        .await
        .unwrap()
}

#[tokio::test]
async fn a_hostile_4gb_length_is_refused() {
    let addr = raw_peer(|_, _| {
        Prefix {
            version: 3,
            length: u32::MAX,
        }
        .encode()
        .to_vec()
    })
    .await;
    let client = bare(addr).await;
    let err = client.get_state().await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: u32::MAX })
        ),
        "{err}"
    );
    assert!(matches!(
        client.get_state().await,
        Err(Error::ConnectionLost { .. })
    ));
}

#[tokio::test]
async fn wrong_message_type_or_communication_type_breaks_the_connection() {
    // Every response says GET_STATE. (A count answered as 17, the manual's erratum, is accepted:
    // tests/smartgrasp_tolerance.rs.)
    let addr = raw_peer(|i, req| {
        let mut f = answer(&req, i as u8);
        f.header.message_type = MessageType::GetState;
        f.encode().to_vec()
    })
    .await;
    let client = bare(addr).await;
    let (err, other) = tokio::join!(client.get_object_count(0), client.get_protocol_version());
    let err = err.unwrap_err();
    // The call that received the wrong type learns why; the other only lost the connection.
    assert!(
        matches!(other, Err(Error::ConnectionLost { .. })),
        "{other:?}"
    );
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::MessageType {
                expected: MessageType::GetObjectCount,
                received: MessageType::GetState
            })
        ),
        "{err}"
    );
    assert!(client.get_state().await.is_err());

    let addr = raw_peer(|i, req| {
        let mut f = answer(&req, i as u8);
        f.header.communication_type = gripper::smartgrasp::CommunicationType::Request;
        f.encode().to_vec()
    })
    .await;
    let err = bare(addr).await.get_state().await.unwrap_err();
    assert!(
        matches!(err, Error::MalformedReply(Malformed::CommunicationType(_))),
        "{err}"
    );
}

#[tokio::test]
async fn in_strict_mode_a_gap_with_nobody_to_charge_it_to_is_reported() {
    // Counters 10, then 12: the second response's predecessor was lost, and only one call waits.
    // (By default the gap is only recorded: tests/smartgrasp_tolerance.rs.)
    let addr =
        raw_peer(|i, req| answer(&req, if i == 0 { 10 } else { 12 }).encode().to_vec()).await;
    let config = ClientConfig {
        strict_response_counter: true,
        ..ClientConfig::default()
    };
    let client = Client::connect_without_opening(addr, config).await.unwrap();
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
    let err = client.get_state().await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::ResponseLost {
                expected: 11,
                received: 12
            }
        ),
        "{err}"
    );
    assert!(client.get_state().await.is_err());
}

#[tokio::test]
async fn split_and_merged_segments() {
    // Answers nothing until three requests are in, then writes the three responses as one
    // buffer cut at odd places, each piece flushed on its own.
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let (mut stream, _) = listener.accept().await.unwrap();
        stream.set_nodelay(true).unwrap();
        let mut all = Vec::new();
        let mut buf = [0u8; FRAME_LEN];
        for counter in 0..3u8 {
            stream.read_exact(&mut buf).await.unwrap();
            all.extend_from_slice(&answer(&RequestFrame::decode(&buf), 200 + counter).encode());
        }
        for piece in [
            &all[..1],
            &all[1..7],
            &all[7..79],
            &all[79..161],
            &all[161..],
        ] {
            stream.write_all(piece).await.unwrap();
            stream.flush().await.unwrap();
            tokio::task::yield_now().await;
        }
        // Keep the connection open until the client is done.
        let _ = stream.read(&mut buf).await;
    });
    let client = bare(addr).await;
    let (a, b, c) = tokio::join!(
        client.get_protocol_version(),
        client.get_state(),
        client.get_protocol_version()
    );
    assert_eq!(a.unwrap(), 3);
    assert_eq!(b.unwrap(), ServerState::Operational);
    assert_eq!(c.unwrap(), 3);
}

/// SCHUNK's own clients say GRASP_FEEDBACK has no effect ("Has no effect on Version 3"; V4:
/// "no effect", and it sends feedback 0): by default the simulator answers every feedback,
/// 0 included and with no grasp before it, with SUCCESS and changes nothing (issue 21).
#[tokio::test]
async fn grasp_feedback_has_no_effect_by_default_as_schunks_examples_say() {
    for max_version in [3, 4] {
        let server = sim(SimConfig {
            max_version,
            ..SimConfig::default()
        })
        .await;
        let client = open(&server).await;
        assert_eq!(client.protocol_version(), max_version);
        // No grasp to refer to yet.
        client.grasp_feedback(GraspFeedback::Bad).await.unwrap();
        for feedback in [
            GraspFeedback::Ok,
            GraspFeedback::Bad,
            GraspFeedback::Unknown(0),
        ] {
            expect_grasp(
                client
                    .get_grasp(grasp_request(0, GraspMode::AnyGrasp, PoseFormat::Abc))
                    .await
                    .unwrap(),
            );
            let response = client.call(Request::GraspFeedback(feedback)).await.unwrap();
            assert_eq!(
                response.code,
                ResponseCode::Success,
                "v{max_version} {feedback:?}"
            );
            assert_eq!(
                client.get_object_count(0).await.unwrap().object_count,
                3,
                "v{max_version} {feedback:?}: the scene changed"
            );
        }
    }
}

/// `Duration::MAX` is the common way to say "no timeout": it must not panic (the call's
/// deadline and its give-up limit overflowed `Instant`; found by the explorer, issue 21 §3).
#[tokio::test]
async fn a_call_without_timeout_does_not_panic() {
    let server = sim(v3_sim()).await;
    let client = open(&server).await;
    let forever = client.with_timeout(Duration::MAX);
    assert_eq!(forever.get_state().await.unwrap(), ServerState::Operational);
    assert_eq!(
        forever.get_object_count(2).await.unwrap().candidate_count,
        1
    );
}

/// The same server over an in-memory stream, through `Client::open_with`; a reconnect calls
/// the opener again, and the record holds each request with the bytes sent for it.
#[tokio::test]
async fn open_with_over_in_memory_streams_reconnects_through_the_opener() {
    let server = std::sync::Arc::new(SimServer::in_memory(v3_sim()));
    server.start_recording(64);
    let opens = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let (srv, n) = (server.clone(), opens.clone());
    let config = ClientConfig {
        reconnect: Some(gripper::reconnect::ReconnectPolicy {
            initial_delay: Duration::from_millis(1),
            max_delay: Duration::from_millis(10),
            factor: 2.0,
            max_attempts: Some(5),
        }),
        ..ClientConfig::default()
    };
    let client = Client::open_with(
        move || {
            n.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            let (a, b) = tokio::io::duplex(1024);
            srv.serve_stream(b);
            std::future::ready(Ok::<_, std::io::Error>(a))
        },
        config,
    )
    .await
    .unwrap();
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
    server.inject(Fault::Close);
    assert!(client.get_state().await.is_err());
    assert_eq!(client.get_state().await.unwrap(), ServerState::Operational);
    assert_eq!(opens.load(std::sync::atomic::Ordering::SeqCst), 2);
    let record = server.recording();
    assert!(record.iter().any(|e| e.session == 2), "{record:?}");
    assert!(record
        .iter()
        .all(|e| e.response.len() == gripper::smartgrasp::frame::FRAME_LEN));
}
