//! The fault matrix: the real smartgrasp client, through the fault-injecting proxy, to the
//! simulator, over loopback. Every fault ends in the right answer or the right typed error, never
//! a hang (every call is bounded by its client timeout; `within` only catches a hang), and the
//! next call on a healthy link — a fresh connection where the old one is broken — works.
//!
//! V3 frames carry no checksum: a corrupted byte that still reads as a valid value cannot be
//! detected by any client. Those cases are tested too, and named as such (`undetectable_…`), so
//! that the limit is documented rather than hidden.
//!
//! Real clock (a paused one would fire the client's timeouts while the runtime waits on the
//! sockets); calls meant to time out get a short timeout, so the suite stays fast.
#![cfg(feature = "sim")]

use std::future::Future;
use std::time::Duration;

use futures_util::StreamExt;
use gripper::fault::{At, Fault, FaultHandle, FaultProxy, Faults, Framing, ProxyConfig, Rule};
use gripper::reconnect::ConnectionEvent;
use gripper::smartgrasp::codec;
use gripper::smartgrasp::sim::{SimConfig, SimServer};

/// The V3 simulator these tests were written for (the default speaks V4 too; V4 is
/// `tests/smartgrasp_v4.rs`).
fn v3_sim() -> SimConfig {
    SimConfig {
        max_version: 3,
        ..SimConfig::default()
    }
}
use gripper::smartgrasp::{
    Client, ClientConfig, Error, GetGraspOutcome, GraspMode, GraspRequest, Malformed, MessageType,
    ObjectCount, Pose, PoseFormat, ResponseCode, RobotSystem, ServerState, Tool,
};

/// The timeout of a call meant to time out: short, so that those faults cost little.
const SHORT: Duration = Duration::from_millis(200);
/// The client's timeouts otherwise: ample for a loopback round trip on a loaded machine.
const CALL_TIMEOUT: Duration = Duration::from_secs(2);
/// Only reached when something hangs (a bug): far above any call's timeout.
const LIMIT: Duration = Duration::from_secs(10);
/// A delay or pause a test ends by changing the faults, never by waiting it out.
const LONG: Duration = Duration::from_secs(3600);

/// Byte offsets in a V3 response (PROTOCOLS.md §2, manual 3.2).
mod at {
    pub const VERSION_LOW: usize = 1;
    pub const LENGTH_HIGH: usize = 2;
    pub const LENGTH_LOW: usize = 5;
    pub const COMMUNICATION_TYPE: usize = 6;
    pub const RESPONSE_CODE: usize = 7;
    pub const RESPONSE_COUNTER: usize = 8;
    pub const MESSAGE_TYPE: usize = 9;
    pub const OBJECT_CLASS_LOW: usize = 15;
    pub const POSE_FORMAT: usize = 39;
    pub const GRASP_POSE_X_LOW: usize = 43;
    pub const OBJECT_COUNT_LOW: usize = 69;
    pub const PADDING: usize = 75;
    /// In a request: the object class of GET_OBJECT_COUNT.
    pub const REQ_OBJECT_CLASS_LOW: usize = 13;
}

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

struct Rig {
    /// Kept alive for the proxy.
    _server: SimServer,
    proxy: FaultProxy,
}

async fn rig() -> Rig {
    let server = SimServer::bind("127.0.0.1:0", v3_sim()).await.unwrap();
    let config = ProxyConfig::new().framing(Framing::Custom(codec::proxy_frame_len));
    let proxy = FaultProxy::start_with(server.local_addr(), config)
        .await
        .unwrap();
    Rig {
        _server: server,
        proxy,
    }
}

fn config() -> ClientConfig {
    ClientConfig {
        query_timeout: CALL_TIMEOUT,
        detection_timeout: CALL_TIMEOUT,
        robot_system: Some(RobotSystem::Kuka),
        project_index: Some(0),
        ..ClientConfig::default()
    }
}

impl Rig {
    /// A client through the proxy, its opening sequence done before any fault is added.
    async fn client(&self) -> Client {
        within(
            "connect",
            Client::connect(self.proxy.local_addr(), config()),
        )
        .await
        .expect("opening sequence through the proxy")
    }

    /// A client through the proxy that trusts the response counter.
    async fn strict_client(&self) -> Client {
        let strict = ClientConfig {
            strict_response_counter: true,
            ..config()
        };
        within("connect", Client::connect(self.proxy.local_addr(), strict))
            .await
            .expect("opening sequence through the proxy")
    }
}

/// GET_OBJECT_COUNT of class 1 in the demo scene: 3 objects, 2 of class 1.
const CLASS_1: ObjectCount = ObjectCount {
    object_class: 1,
    object_count: 3,
    candidate_count: 2,
};

async fn count(client: &Client, class: u16) -> Result<ObjectCount, Error> {
    within("get_object_count", client.get_object_count(class)).await
}

async fn state(client: &Client) -> Result<ServerState, Error> {
    within("get_state", client.get_state()).await
}

fn any_grasp(class: u16) -> GraspRequest {
    GraspRequest {
        grasp_mode: GraspMode::AnyGrasp,
        object_class: class,
        tool: Tool::Exterior,
        selection_criterion: gripper::smartgrasp::SelectionCriterion::default(),
        pose_format: PoseFormat::Abc,
    }
}

/// The link works: answers that tell the requests apart, each to its own call.
async fn assert_healthy(client: &Client) {
    assert_eq!(count(client, 1).await.unwrap(), CLASS_1);
    assert_eq!(count(client, 2).await.unwrap().candidate_count, 1);
    assert_eq!(state(client).await.unwrap(), ServerState::Operational);
}

/// The old connection is broken for good, and a fresh one through the same proxy works.
async fn assert_broken_then_fresh_works(rig: &Rig, client: &Client) {
    let err = state(client).await.unwrap_err();
    assert!(matches!(err, Error::ConnectionLost { .. }), "{err}");
    assert!(client.is_closed());
    assert_healthy(&rig.client().await).await;
}

/// Where a fault case starts: a rig, a client whose opening sequence is done, and `rule` added
/// to the faults `direction` picks.
async fn with_fault(
    direction: fn(&FaultProxy) -> Faults,
    rule: Rule,
) -> (Rig, Client, FaultHandle) {
    let rig = rig().await;
    let client = rig.client().await;
    let handle = direction(&rig.proxy).add(rule);
    (rig, client, handle)
}

/// GET_OBJECT_COUNT(1) under `rule` fails; the fault fired, the connection is broken for good,
/// a fresh one works. Returns the call's error.
async fn count_breaks(direction: fn(&FaultProxy) -> Faults, rule: Rule) -> Error {
    let (rig, client, handle) = with_fault(direction, rule).await;
    let err = count(&client, 1).await.unwrap_err();
    assert_eq!(handle.fired(), 1);
    assert_broken_then_fresh_works(&rig, &client).await;
    err
}

/// GET_OBJECT_COUNT(1) under `rule` times out, and the fault fired.
async fn count_times_out(
    direction: fn(&FaultProxy) -> Faults,
    rule: Rule,
) -> (Rig, Client, FaultHandle) {
    let (rig, client, handle) = with_fault(direction, rule).await;
    let first = count(&client.with_timeout(SHORT), 1).await;
    assert!(is_timeout(&first, MessageType::GetObjectCount), "{first:?}");
    assert_eq!(handle.fired(), 1);
    (rig, client, handle)
}

const REPLIES: fn(&FaultProxy) -> Faults = FaultProxy::server_to_client;
const REQUESTS: fn(&FaultProxy) -> Faults = FaultProxy::client_to_server;

fn is_timeout(result: &Result<ObjectCount, Error>, message_type: MessageType) -> bool {
    matches!(result, Err(Error::Timeout { message_type: m, .. }) if *m == message_type)
}

// ---- delay -----------------------------------------------------------------------------------

#[tokio::test]
async fn delay_within_the_timeout_gives_the_right_answer() {
    let rig = rig().await;
    let client = rig.client().await;
    let delay = Fault::Delay(Duration::from_millis(30));
    let reply = rig.proxy.server_to_client().add(delay.once());
    let request = rig.proxy.client_to_server().add(delay.once());
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!((reply.fired(), request.fired()), (1, 1));
    assert_healthy(&client).await;
}

#[tokio::test]
async fn reply_delayed_beyond_the_timeout_times_out_and_the_late_reply_is_discarded() {
    let (_rig, client, delay) = count_times_out(REPLIES, Fault::Delay(LONG).once()).await;
    // End the delay: the held reply arrives after its caller gave up, and must reach nobody.
    delay.remove();
    assert_eq!(count(&client, 2).await.unwrap().object_class, 2);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn request_delayed_beyond_the_timeout_times_out_and_its_late_reply_is_discarded() {
    let (_rig, client, delay) = count_times_out(REQUESTS, Fault::Delay(LONG).once()).await;
    delay.remove();
    assert_eq!(count(&client, 2).await.unwrap().object_class, 2);
    assert_healthy(&client).await;
}

// ---- split and merge -------------------------------------------------------------------------

#[tokio::test]
async fn split_frames_in_both_directions_give_the_right_answers() {
    let rig = rig().await;
    let client = rig.client().await;
    let split = |piece_len| Fault::Split {
        piece_len,
        pause: Duration::from_millis(1),
    };
    // Pieces cutting the prefix, the header and the body apart.
    let requests = rig.proxy.client_to_server().add(split(7).always().times(2));
    let replies = rig.proxy.server_to_client().add(split(5).always().times(2));
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!(state(&client).await.unwrap(), ServerState::Operational);
    assert_eq!((requests.fired(), replies.fired()), (2, 2));
    assert_healthy(&client).await;
}

#[tokio::test]
async fn merged_frames_in_both_directions_give_each_call_its_own_answer() {
    let rig = rig().await;
    let client = rig.client().await;
    let merge = Fault::Merge {
        frames: 3,
        max_wait: LONG,
    };
    let requests = rig.proxy.client_to_server().add(merge.once());
    let replies = rig.proxy.server_to_client().add(merge.once());
    let (a, b, c) = within("three calls", async {
        tokio::join!(count(&client, 1), count(&client, 2), state(&client))
    })
    .await;
    assert_eq!(a.unwrap(), CLASS_1);
    assert_eq!(b.unwrap().object_class, 2);
    assert_eq!(c.unwrap(), ServerState::Operational);
    assert_eq!((requests.fired(), replies.fired()), (1, 1));
    let stats = rig.proxy.stats();
    assert!(stats.server_to_client.writes < stats.server_to_client.frames);
    assert_healthy(&client).await;
}

// ---- corrupt: prefix -------------------------------------------------------------------------

/// Flip the bits `xor` of byte `byte` of the next frame.
fn corrupt(byte: usize, xor: u8) -> Rule {
    Fault::Corrupt {
        at: At::Start(byte),
        xor,
    }
    .once()
}

#[tokio::test]
async fn corrupt_length_byte_is_malformed_and_breaks_the_connection() {
    let err = count_breaks(REPLIES, corrupt(at::LENGTH_LOW, 0x01)).await;
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: 75 })
        ),
        "{err}"
    );
}

#[tokio::test]
async fn corrupt_length_to_a_hostile_size_is_refused_without_reading_it() {
    let err = count_breaks(REPLIES, corrupt(at::LENGTH_HIGH, 0x80)).await;
    assert!(
        matches!(err, Error::MalformedReply(Malformed::FrameLength { length }) if length == 0x8000_004A),
        "{err}"
    );
}

#[tokio::test]
async fn corrupt_length_to_zero_is_malformed_not_server_too_old() {
    // Found by this matrix: an empty message from a server that claims v3 was reported as
    // "server too old (speaks v3)". Only an older server sends one (manual 1.3).
    let err = count_breaks(REPLIES, corrupt(at::LENGTH_LOW, 74)).await;
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: 0 })
        ),
        "{err}"
    );
}

#[tokio::test]
async fn an_empty_message_below_the_version_the_server_said_is_malformed_not_server_too_old() {
    // smartgrasp-v3:0xd2a532f64f1247cd: a damaged request drew the server's empty message, and a
    // damaged byte of it claimed v2. This server answered GET_PROTOCOL_VERSION with 3 on this
    // very connection: the "too old" answer would contradict it, so it is a damaged frame (the
    // connection is lost, a fresh one works), never the terminal ServerTooOld.
    let (rig, client, length) = with_fault(REPLIES, corrupt(at::LENGTH_LOW, 74)).await;
    let version = REPLIES(&rig.proxy).add(corrupt(at::VERSION_LOW, 0x01));
    let err = count(&client, 1).await.unwrap_err();
    assert_eq!((length.fired(), version.fired()), (1, 1));
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::FrameLength { length: 0 })
        ),
        "{err}"
    );
    assert_broken_then_fresh_works(&rig, &client).await;
}

#[tokio::test]
async fn corrupt_version_byte_is_malformed() {
    let err = count_breaks(REPLIES, corrupt(at::VERSION_LOW, 0x04)).await;
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::Version { version: 7 })
        ),
        "{err}"
    );
}

// ---- corrupt: header -------------------------------------------------------------------------

#[tokio::test]
async fn corrupt_communication_type_is_malformed() {
    let err = count_breaks(REPLIES, corrupt(at::COMMUNICATION_TYPE, 0x03)).await;
    assert!(
        matches!(err, Error::MalformedReply(Malformed::CommunicationType(_))),
        "{err}"
    );
}

#[tokio::test]
async fn corrupt_message_type_is_malformed() {
    // 32 (GET_OBJECT_COUNT) ^ 0x10 = 48 (ROBOT_POSE).
    let err = count_breaks(REPLIES, corrupt(at::MESSAGE_TYPE, 0x10)).await;
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::MessageType {
                expected: MessageType::GetObjectCount,
                received: MessageType::RobotPose
            })
        ),
        "{err}"
    );
}

#[tokio::test]
async fn corrupt_response_counter_is_recorded_and_the_call_gets_its_answer() {
    // Four responses in the opening sequence: the next counter is 4; 4 ^ 1 = 5 is a gap. The
    // manual does not pin the counter's scope (3.2.2.3), so by default a gap is recorded, not
    // fatal.
    let (_rig, client, handle) = with_fault(REPLIES, corrupt(at::RESPONSE_COUNTER, 0x01)).await;
    assert_eq!(client.counter_gaps(), 0);
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!(handle.fired(), 1);
    assert_eq!(client.counter_gaps(), 1);
    // The server's next counter is 5 again: a gap of 255, recorded too. (Another class: the same
    // request would get the very bytes of the corrupted response, which the client skips as a
    // repeated segment.)
    assert_eq!(count(&client, 2).await.unwrap().candidate_count, 1);
    assert_eq!(client.counter_gaps(), 2);
    // Then 6 follows 5 without a gap.
    assert_healthy(&client).await;
    assert_eq!(client.counter_gaps(), 2);
}

#[tokio::test]
async fn in_strict_mode_corrupt_response_counter_is_a_lost_response() {
    // The same gap with a client that trusts the counter: the one waiting call cannot explain it.
    let rig = rig().await;
    let client = rig.strict_client().await;
    let handle = REPLIES(&rig.proxy).add(corrupt(at::RESPONSE_COUNTER, 0x01));
    let err = count(&client, 1).await.unwrap_err();
    assert_eq!(handle.fired(), 1);
    assert!(
        matches!(
            err,
            Error::ResponseLost {
                expected: 4,
                received: 5
            }
        ),
        "{err}"
    );
    assert_broken_then_fresh_works(&rig, &client).await;
}

#[tokio::test]
async fn corrupt_response_code_is_a_refusal_where_the_call_expects_success() {
    // SUCCESS (1) ^ 2 = NO_OBJECT (3).
    let (_rig, client, _) = with_fault(REPLIES, corrupt(at::RESPONSE_CODE, 0x02)).await;
    let err = count(&client, 1).await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::Device {
                message_type: MessageType::GetObjectCount,
                status: ResponseCode::NoObject
            }
        ),
        "{err}"
    );
    // A refusal is an answer: the connection stays.
    assert_healthy(&client).await;
}

#[tokio::test]
async fn undetectable_corrupt_response_code_turns_a_grasp_into_no_object() {
    // LIMIT OF THE PROTOCOL (documented in the smartgrasp module docs): the response code is one
    // byte with no checksum, and NO_OBJECT is a normal GET_GRASP outcome. The client cannot tell
    // this from an empty bin. A picking loop should confirm "empty" with GET_OBJECT_COUNT.
    let (_rig, client, _) = with_fault(REPLIES, corrupt(at::RESPONSE_CODE, 0x02)).await;
    let outcome = within("get_grasp", client.get_grasp(any_grasp(0)))
        .await
        .unwrap();
    assert_eq!(
        outcome,
        GetGraspOutcome::NoObject,
        "the corruption reached the caller"
    );
    assert_eq!(
        count(&client, 0).await.unwrap().object_count,
        3,
        "yet the bin is full"
    );
    assert_healthy(&client).await;
}

// ---- corrupt: body ---------------------------------------------------------------------------

#[tokio::test]
async fn corrupt_echoed_object_class_is_caught() {
    let err = count_breaks(REPLIES, corrupt(at::OBJECT_CLASS_LOW, 0x01)).await;
    assert!(
        matches!(
            err,
            Error::MalformedReply(Malformed::Echo {
                request: MessageType::GetObjectCount,
                field: "object class"
            })
        ),
        "{err}"
    );
}

#[tokio::test]
async fn corrupt_request_object_class_is_caught_by_the_echo() {
    // The server reads class 1 ^ 3 = 2, answers for it and repeats it in the response: the
    // client sees that the answer is not for its request.
    let err = count_breaks(REQUESTS, corrupt(at::REQ_OBJECT_CLASS_LOW, 0x03)).await;
    assert!(
        matches!(err, Error::MalformedReply(Malformed::Echo { .. })),
        "{err}"
    );
}

#[tokio::test]
async fn undetectable_corrupt_grasp_pose_format_is_read_as_declared() {
    // ABC (17) ^ 1 = WPR (16): a valid format. The response's pose format is the format used for
    // the pose (manual 3.3.3.1), not an echo of the request, so the client reads the pose as WPR
    // and converts it to the ABC asked for: a wrong pose no V3 client can tell from a right one.
    let rig = rig().await;
    let client = rig.client().await;
    let grasp = |outcome| match outcome {
        Ok(GetGraspOutcome::Grasp(grasp)) => grasp,
        other => panic!("{other:?}"),
    };
    let sent = grasp(within("get_grasp", client.get_grasp(any_grasp(0))).await);
    let fault = REPLIES(&rig.proxy).add(corrupt(at::POSE_FORMAT, 0x01));
    let read = grasp(within("get_grasp", client.get_grasp(any_grasp(0))).await);
    assert_eq!(fault.fired(), 1);
    let as_wpr = Pose::from_wire(PoseFormat::Wpr, sent.pose.to_wire()).unwrap();
    assert_eq!(read.pose, as_wpr.to_format(PoseFormat::Abc).unwrap());
    assert_ne!(read.pose, sent.pose);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn corrupt_padding_is_ignored() {
    let (_rig, client, padding) = with_fault(REPLIES, corrupt(at::PADDING, 0xFF)).await;
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!(padding.fired(), 1);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn undetectable_corrupt_counts_and_poses_reach_the_caller() {
    // LIMIT OF THE PROTOCOL (documented in the smartgrasp module docs): V3 has no checksum, so a
    // flipped bit in a count or a pose coordinate is a different valid value. Over TCP this only
    // happens through faulty equipment (TCP's own checksum guards the wire); a cell that must
    // rule it out needs a plausibility check of its own (e.g. the pose inside the bin).
    let (rig, client, _) = with_fault(REPLIES, corrupt(at::OBJECT_COUNT_LOW, 0x04)).await;
    assert_eq!(count(&client, 1).await.unwrap().object_count, 3 ^ 0x04);

    let grasp = || async {
        match within("grasp", client.get_grasp(any_grasp(1)))
            .await
            .unwrap()
        {
            GetGraspOutcome::Grasp(g) => g.pose.position_um()[0],
            other => panic!("{other:?}"),
        }
    };
    let clean_x = grasp().await;
    REPLIES(&rig.proxy).add(corrupt(at::GRASP_POSE_X_LOW, 0x01));
    assert_eq!(
        grasp().await,
        clean_x ^ 0x01,
        "one micrometre off, undetectably"
    );
    assert_healthy(&client).await;
}

// ---- drop ------------------------------------------------------------------------------------

#[tokio::test]
async fn dropped_reply_times_out_then_the_gap_is_charged_to_it() {
    let (_rig, client, _) = count_times_out(REPLIES, Fault::Drop.once()).await;
    // The next reply shows a counter gap: the abandoned call's slot takes the loss.
    assert_eq!(count(&client, 2).await.unwrap().object_class, 2);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn dropped_reply_among_pipelined_calls_is_a_lost_response_for_its_own_call() {
    let rig = rig().await;
    let client = rig.client().await;
    rig.proxy.server_to_client().add(Fault::Drop.once());
    let (first, second) = within("two calls", async {
        tokio::join!(count(&client, 1), count(&client, 2))
    })
    .await;
    assert!(
        matches!(
            first,
            Err(Error::ResponseLost {
                expected: 4,
                received: 5
            })
        ),
        "{first:?}"
    );
    assert_eq!(second.unwrap().object_class, 2);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn dropped_request_times_out_and_the_next_different_request_resynchronises() {
    // Found by this matrix: the server never saw the request, so no counter gap shows; the next
    // reply was paired with the abandoned call and every later call was one reply off (timing
    // out, or breaking the connection on the type mismatch). Now a reply that fits the next
    // request but not the abandoned one drops the abandoned slot.
    let (rig, client, _) = count_times_out(REQUESTS, Fault::Drop.once()).await;
    // Another message type, and the same type for another class, both tell the slots apart.
    assert_eq!(state(&client).await.unwrap(), ServerState::Operational);
    REQUESTS(&rig.proxy).add(Fault::Drop.once());
    let first = count(&client.with_timeout(SHORT), 1).await;
    assert!(is_timeout(&first, MessageType::GetObjectCount), "{first:?}");
    assert_eq!(count(&client, 2).await.unwrap().object_class, 2);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn dropped_request_then_the_identical_request_gets_its_own_answer() {
    // Found by this matrix: responses carry no request id, so after a lost request the reply to
    // an identical request could not be told from the lost one's late reply: the identical call
    // timed out, and so did every identical call after it. Now a marker query of another type
    // goes out between an abandoned request and the next one of its type, and settles the
    // abandoned slot before the new request's reply arrives.
    let (rig, client, _) = count_times_out(REQUESTS, Fault::Drop.once()).await;
    let requests_before = rig.proxy.stats().client_to_server.frames;
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    let sent = rig.proxy.stats().client_to_server.frames - requests_before;
    assert_eq!(sent, 2, "the marker and the request");
    assert_healthy(&client).await;
}

#[tokio::test]
async fn a_reply_delayed_past_its_timeout_then_the_identical_request_gets_its_own_answer() {
    // The other way the abandoned request can go: answered, late. The marker keeps the late
    // answer from reaching the identical request that follows it.
    let (rig, client, delay) = count_times_out(REPLIES, Fault::Delay(LONG).once()).await;
    let requests = REQUESTS(&rig.proxy);
    let before = requests.stats().frames;
    let second = tokio::spawn({
        let client = client.clone();
        async move { client.get_object_count(1).await }
    });
    // Both on the wire behind the abandoned request before its late reply is let go.
    within(
        "marker and request sent",
        requests.wait_for(|s| s.frames == before + 2),
    )
    .await;
    delay.remove();
    assert_eq!(
        within("second call", second).await.unwrap().unwrap(),
        CLASS_1
    );
    assert_healthy(&client).await;
}

// ---- duplicate -------------------------------------------------------------------------------

#[tokio::test]
async fn duplicated_reply_is_skipped_with_a_strict_counter() {
    // Found by this matrix: the copy arrived with nobody waiting (unsolicited) or paired with
    // the next call (a counter gap of 255), and broke the connection. With a server known to
    // count per connection (strict mode), a byte-identical repeat of the last response (same
    // counter, which such a server never repeats) is a copy, and skipped.
    let rig = rig().await;
    let client = rig.strict_client().await;
    let dup = REPLIES(&rig.proxy).add(Fault::Duplicate.once());
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!(dup.fired(), 1);
    assert_healthy(&client).await;
    assert!(!client.is_closed());
}

#[tokio::test]
async fn duplicated_reply_breaks_the_connection_by_default() {
    // By default identical responses are answers (a server whose counter never moves, or counts
    // across its clients, sends them; issue 21), so a copy with nobody waiting is unsolicited:
    // the call got its answer, the connection is given up, never a wrong answer.
    let (rig, client, dup) = with_fault(REPLIES, Fault::Duplicate.once()).await;
    let mut events = client.connection_events();
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    assert_eq!(dup.fired(), 1);
    match within("loss reported", events.next()).await {
        Some(ConnectionEvent::Lost { reason }) => {
            assert!(reason.contains("unsolicited"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    assert_broken_then_fresh_works(&rig, &client).await;
}

#[tokio::test]
async fn duplicated_request_is_answered_twice_and_the_extra_answer_breaks_the_connection() {
    // The server acts on the copy (for GRASP_FEEDBACK or GET_GRASP that has effects no client
    // can undo); its second answer is one nobody asked for, so the pairing cannot be trusted.
    let rig = rig().await;
    let client = rig.client().await;
    let mut events = client.connection_events();
    rig.proxy.client_to_server().add(Fault::Duplicate.once());
    assert_eq!(count(&client, 1).await.unwrap(), CLASS_1);
    match within("loss reported", events.next()).await {
        Some(ConnectionEvent::Lost { reason }) => {
            assert!(reason.contains("unsolicited"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    assert_broken_then_fresh_works(&rig, &client).await;
}

// ---- stall -----------------------------------------------------------------------------------

#[tokio::test]
async fn stalled_reply_released_in_time_gives_the_right_answer() {
    let rig = rig().await;
    let client = rig.client().await;
    let faults = rig.proxy.server_to_client();
    faults.stall();
    let call = tokio::spawn({
        let client = client.clone();
        async move { client.get_object_count(1).await }
    });
    within(
        "reply held at the stall",
        faults.wait_for(|s| s.held_bytes == 80),
    )
    .await;
    faults.release();
    assert_eq!(within("call", call).await.unwrap().unwrap(), CLASS_1);
    assert_healthy(&client).await;
}

#[tokio::test]
async fn stall_past_the_timeout_times_out_then_release_recovers() {
    let rig = rig().await;
    let client = rig.client().await;
    let faults = rig.proxy.server_to_client();
    faults.stall();
    let first = count(&client.with_timeout(SHORT), 1).await;
    assert!(is_timeout(&first, MessageType::GetObjectCount), "{first:?}");
    faults.release();
    assert_healthy(&client).await;
}

// ---- cut -------------------------------------------------------------------------------------

fn cut(after_bytes: usize) -> Rule {
    Fault::Cut { after_bytes }.once()
}

fn is_lost_connection(err: &Error) -> bool {
    matches!(err, Error::ConnectionLost { .. } | Error::Io(_))
}

#[tokio::test]
async fn cut_before_the_request_fails_the_call_as_a_lost_connection() {
    let err = count_breaks(REQUESTS, cut(0)).await;
    assert!(is_lost_connection(&err), "{err}");
}

#[tokio::test]
async fn cut_inside_the_request_fails_the_call_as_a_lost_connection() {
    let err = count_breaks(REQUESTS, cut(40)).await;
    assert!(is_lost_connection(&err), "{err}");
}

#[tokio::test]
async fn cut_before_the_reply_fails_the_call_as_a_lost_connection() {
    let err = count_breaks(REPLIES, cut(0)).await;
    assert!(is_lost_connection(&err), "{err}");
}

#[tokio::test]
async fn cut_inside_the_reply_says_the_connection_closed_mid_frame() {
    // Found by this matrix: this was tokio-util's opaque "bytes remaining on stream" I/O error.
    let err = count_breaks(REPLIES, cut(40)).await;
    assert!(
        matches!(&err, Error::ConnectionLost { reason } if reason.contains("middle of a frame")),
        "{err}"
    );
}

// ---- bounds ----------------------------------------------------------------------------------

#[tokio::test]
async fn many_more_callers_than_the_queue_and_in_flight_limits_all_get_their_answers() {
    // 16 requests in flight and 32 queued at most: 300 callers at once wait their turn.
    let rig = rig().await;
    let client = rig.client().await;
    let mut calls = tokio::task::JoinSet::new();
    for i in 0..300u16 {
        let client = client.clone();
        calls.spawn(async move {
            let class = i % 3;
            let answer = client.get_object_count(class).await.unwrap();
            assert_eq!(answer.object_class, class);
            assert_eq!(answer.candidate_count, [3, 2, 1][usize::from(class)]);
        });
    }
    while let Some(done) = within("300 callers", calls.join_next()).await {
        done.unwrap();
    }
    assert_healthy(&client).await;
}

#[tokio::test]
async fn a_server_that_stops_answering_gets_at_most_16_requests_and_every_caller_times_out() {
    let rig = rig().await;
    let client = rig.client().await;
    let requests_before = rig.proxy.stats().client_to_server.frames;
    let replies = rig.proxy.server_to_client();
    replies.stall();
    let mut calls = tokio::task::JoinSet::new();
    for i in 0..100u16 {
        let client = client.with_timeout(SHORT);
        calls.spawn(async move { client.get_object_count(i % 3).await });
    }
    let requests = rig.proxy.client_to_server();
    within(
        "16 requests on the wire",
        requests.wait_for(|s| s.frames >= requests_before + 16),
    )
    .await;
    while let Some(done) = within("100 callers", calls.join_next()).await {
        let result = done.unwrap();
        assert!(
            is_timeout(&result, MessageType::GetObjectCount),
            "{result:?}"
        );
    }
    // The documented in-flight bound (`Client`: at most 16 unanswered), seen on the wire.
    let sent = rig.proxy.stats().client_to_server.frames - requests_before;
    assert_eq!(sent, 16);
    // The held replies reach nobody; the callers that gave up while queued are never sent.
    replies.release();
    assert_healthy(&client).await;
    let sent = rig.proxy.stats().client_to_server.frames - requests_before;
    assert!(
        sent <= 16 + 3 + 1,
        "{sent}: the 3 calls of assert_healthy and at most one marker, nothing else"
    );
}
