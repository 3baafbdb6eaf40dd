//! `gripctl smartgrasp …` against the simulator, started in this process on a free port (the
//! server runs on the test's runtime while the binary runs), and `gripctl sim smartgrasp` as a
//! child process.

mod common;

use common::{gripctl, refused_addr, Simulator};
use gripper::smartgrasp::sim::{Fault, SimConfig, SimServer};
use gripper::smartgrasp::{Pose, PoseFormat, RobotSystem, ServerState};

/// A V3-only server (the default speaks V4 too).
fn v3_sim() -> SimConfig {
    SimConfig {
        max_version: 3,
        ..SimConfig::default()
    }
}

async fn server(config: SimConfig) -> (SimServer, String) {
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let addr = server.local_addr().to_string();
    (server, addr)
}

/// `gripctl --timeout 20s smartgrasp --addr ADDR args…`
async fn sg(addr: &str, args: &[&str]) -> common::Run {
    let mut all = vec![
        "--timeout",
        common::CALL_TIMEOUT,
        "smartgrasp",
        "--addr",
        addr,
    ];
    all.extend_from_slice(args);
    gripctl(&all).await
}

#[tokio::test]
async fn version_and_state_as_text_and_json() {
    let (_server, addr) = server(SimConfig::default()).await;

    let version = sg(&addr, &["version"]).await;
    assert_eq!(
        version.ok().trim(),
        "protocol version 4 (this client speaks 3 and 4)"
    );
    let (_v3, v3_addr) = server(v3_sim()).await;
    let version = sg(&v3_addr, &["version"]).await;
    assert_eq!(
        version.ok().trim(),
        "protocol version 3 (this client speaks 3 and 4)"
    );
    let state = sg(&addr, &["state"]).await;
    assert!(state.ok().starts_with("OPERATIONAL"), "{state:?}");

    let version = sg(&addr, &["version", "--json"]).await.json();
    assert_eq!(version["protocol_version"], 4);
    let state = sg(&addr, &["state", "--json"]).await.json();
    assert_eq!(state["state"]["name"], "OPERATIONAL");
    assert_eq!(state["state"]["code"], 2);
}

#[tokio::test]
async fn json_is_accepted_anywhere_on_the_line() {
    let (_server, addr) = server(SimConfig::default()).await;
    for args in [
        vec!["--json", "smartgrasp", "--addr", &addr, "count"],
        vec!["smartgrasp", "--json", "--addr", &addr, "count"],
        vec!["smartgrasp", "--addr", &addr, "count", "--json"],
    ] {
        let count = gripctl(&args).await.json();
        assert_eq!(count["object_count"], 3, "{args:?}");
    }
}

#[tokio::test]
async fn grasp_prints_metres_and_the_robots_format() {
    let (server, addr) = server(SimConfig::default()).await;

    let text = sg(&addr, &["grasp", "--robot", "kuka", "--mode", "active"]).await;
    let text = text.ok();
    // The demo's first part: 450 mm, -120 mm, 50 mm, tool down, turned 30° about z.
    assert!(text.contains("class 1 instance 0"), "{text}");
    assert!(
        text.contains("pose (m): x 0.450000, y -0.120000, z 0.050000"),
        "{text}"
    );
    assert!(
        text.contains("pose (ABC): X 450.000 mm, Y -120.000 mm, Z 50.000 mm, A 30.0000°"),
        "{text}"
    );
    assert!(text.contains("stroke 86.000 mm"), "{text}");
    assert_eq!(server.registered_clients(), [RobotSystem::Kuka]);

    // V3 echoes the tool and has no object offset.
    let json = sg(
        &addr,
        &["--protocol", "3", "grasp", "--format", "wpr", "--json"],
    )
    .await
    .json();
    assert_eq!(json["outcome"], "GRASP");
    assert_eq!(json["object_class"], 1);
    assert_eq!(json["stroke_um"], 86_000);
    assert_eq!(json["stroke_m"], 0.086);
    assert_eq!(json["tool"]["name"], "EXTERIOR");
    assert_eq!(
        json["center_offset_um"],
        serde_json::json!([-911, -310, 68])
    );
    assert!(json["object_offset"].is_null());
    let pose = &json["pose"];
    assert_eq!(pose["format"], "WPR");
    assert_eq!(pose["position_m"], serde_json::json!([0.45, -0.12, 0.05]));
    // WPR is ABC with the angles' names swapped: W = C = 180°, R = A = 30°.
    assert_eq!(
        pose["wire"],
        serde_json::json!([450_000, -120_000, 50_000, 180_000_000, 0, 30_000_000, 0])
    );
    let q: Vec<f64> = pose["orientation_xyzw"]
        .as_array()
        .expect("array")
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect();
    let norm: f64 = q.iter().map(|v| v * v).sum();
    assert!((norm - 1.0).abs() < 1e-9, "{q:?}");
}

#[tokio::test]
async fn picking_until_the_scene_is_empty() {
    // GRASP_FEEDBACK OK stands in for the robot taking the part (a simulator option: SCHUNK's
    // server ignores feedback).
    let (server, addr) = server(SimConfig {
        feedback_removes_objects: true,
        ..SimConfig::default()
    })
    .await;
    for left in (1..=3).rev() {
        let count = sg(&addr, &["count", "--json"]).await.json();
        assert_eq!(count["object_count"], left);
        let grasp = sg(&addr, &["grasp", "--json"]).await.json();
        assert_eq!(grasp["outcome"], "GRASP");
        assert_eq!(grasp["object_count"], left);
        let feedback = sg(&addr, &["feedback", "ok"]).await;
        assert!(
            feedback.ok().starts_with("feedback sent: OK"),
            "{feedback:?}"
        );
    }
    assert!(server.with_state(|s| s.projects()[0].scene.is_empty()));
    // An empty bin is an answer, not a failure.
    let empty = sg(&addr, &["grasp"]).await;
    assert_eq!(empty.ok().trim(), "no object in the scene (NO_OBJECT)");
    let empty = sg(&addr, &["grasp", "--json"]).await.json();
    assert_eq!(empty["outcome"], "NO_OBJECT");
    let count = sg(&addr, &["count"]).await;
    assert_eq!(
        count.ok().trim(),
        "0 objects in the scene, 0 candidates of any class"
    );
}

#[tokio::test]
async fn register_project_and_robot_pose_reach_the_server() {
    let (server, addr) = server(SimConfig::default()).await;

    let register = sg(&addr, &["register", "fanuc"]).await;
    assert_eq!(register.ok().trim(), "registered as FANUC");
    assert_eq!(server.registered_clients(), [RobotSystem::Fanuc]);

    let project = sg(&addr, &["project", "0", "--json"]).await.json();
    assert_eq!(project["project"], 0);

    let pose = sg(
        &addr,
        &[
            "robot-pose",
            "--format",
            "abc",
            "100",
            "-200.5",
            "300",
            "10",
            "-20",
            "30",
        ],
    )
    .await;
    assert!(
        pose.ok()
            .starts_with("robot pose sent: ABC: X 100.000 mm, Y -200.500 mm"),
        "{pose:?}"
    );
    let expected = Pose::from_wire(
        PoseFormat::Abc,
        [
            100_000,
            -200_500,
            300_000,
            10_000_000,
            -20_000_000,
            30_000_000,
            0,
        ],
    )
    .expect("pose");
    assert_eq!(server.robot_poses(), [expected]);

    // A quaternion has four rotation values; three are refused before anything is sent.
    let short = sg(
        &addr,
        &[
            "robot-pose",
            "--format",
            "quaternion",
            "1",
            "2",
            "3",
            "0",
            "0",
            "1",
        ],
    )
    .await;
    let line = short.failed();
    assert!(line.contains("a quaternion pose has 7 values"), "{line}");
    assert_eq!(server.robot_poses().len(), 1);
}

#[tokio::test]
async fn a_refusal_names_the_servers_response_code() {
    // The feedback refusal below needs the simulator option (by default feedback has no effect
    // and is always SUCCESS, as SCHUNK's examples say).
    let (_server, addr) = server(SimConfig {
        feedback_removes_objects: true,
        ..SimConfig::default()
    })
    .await;

    let run = sg(&addr, &["grasp", "--class", "7"]).await;
    let line = run.failed();
    assert!(line.contains(&addr), "{line}");
    assert!(
        line.contains("INVALID_OBJECT_CLASS (the object class is invalid or does not exist)"),
        "{line}"
    );

    let run = sg(&addr, &["count", "--class", "7", "--json"]).await;
    run.failed();
    let error = &run.json()["error"];
    assert_eq!(error["kind"], "device");
    assert_eq!(error["code"], 5);
    assert_eq!(error["name"], "INVALID_OBJECT_CLASS");
    assert_eq!(
        error["description"],
        "the object class is invalid or does not exist"
    );

    // Feedback with no grasp to refer to: the server answers ERROR.
    let run = sg(&addr, &["feedback", "bad", "--json"]).await;
    let line = run.failed();
    assert!(line.contains("refused GRASP_FEEDBACK: ERROR"), "{line}");
    assert_eq!(run.json()["error"]["code"], 2);
}

#[tokio::test]
async fn a_server_that_is_not_ready_is_reported_with_its_state() {
    let config = SimConfig {
        server_state: ServerState::Init,
        ..SimConfig::default()
    };
    let (_server, addr) = server(config).await;
    // GET_STATE itself works and says so.
    assert!(sg(&addr, &["state"]).await.ok().starts_with("INIT"));
    let run = sg(&addr, &["grasp", "--json"]).await;
    let line = run.failed();
    assert!(line.contains("not operational: INIT"), "{line}");
    assert_eq!(run.json()["error"]["name"], "INIT");
}

#[tokio::test]
async fn connection_refused_is_one_line() {
    let addr = refused_addr();
    let run = sg(&addr, &["state"]).await;
    let line = run.failed();
    assert!(
        line.contains(&format!("smartgrasp {addr}: cannot connect")),
        "{line}"
    );
    assert!(run.stdout.is_empty(), "{run:?}");

    let run = sg(&addr, &["--json", "version"]).await;
    run.failed();
    assert_eq!(run.json()["error"]["kind"], "connection");
}

#[tokio::test]
async fn v4_when_offered_with_tool_workspace_and_selection() {
    let (sim, addr) = server(SimConfig::default()).await;
    let json = sg(
        &addr,
        &[
            "grasp",
            "--tool",
            "3",
            "--workspace",
            "1",
            "--selection",
            "2",
            "--class",
            "2",
            "--json",
        ],
    )
    .await
    .json();
    assert_eq!(json["outcome"], "GRASP");
    // Tool 3 is the simulator's contact tool: class 2's model-free grasp.
    assert_eq!(json["grasp_mode"]["name"], "AUTO_GRASP");
    assert!(json["tool"].is_null(), "V4 echoes no tool: {json}");
    assert_eq!(json["center_offset_um"], serde_json::json!([-911, -310]));
    assert_eq!(json["object_offset"]["x_um"], 1_250);
    assert_eq!(json["reference_frame"], 0);
    assert_eq!(
        sim.with_state(|s| (s.active_tool(), s.active_workspace())),
        (Some(3), Some(1))
    );
    let text = sg(&addr, &["tool", "1"]).await;
    assert_eq!(text.ok().trim(), "tool 1 active");
    assert_eq!(sim.with_state(|s| s.active_tool()), Some(1));
    sg(&addr, &["workspace", "9", "--json"])
        .await
        .failed_with("device", "SET_WORKSPACE");
    // A V3 tool name to a V4 server, and V4 messages to a V3 server, are refused.
    sg(&addr, &["grasp", "--tool", "contact", "--json"])
        .await
        .failed_with("argument", "chooses the tool by ID");
    let (_v3, v3_addr) = server(v3_sim()).await;
    sg(&v3_addr, &["tool", "1", "--json"])
        .await
        .failed_with("argument", "SET_TOOL is not a message of protocol v3");
    // Pinning V4 against a V3-only server: "too old".
    sg(&v3_addr, &["--protocol", "4", "state", "--json"])
        .await
        .failed_with("device", "the server is too old: it speaks protocol v3");
}

#[tokio::test]
async fn a_missing_response_times_out() {
    let (server, addr) = server(SimConfig::default()).await;
    server.inject(Fault::DropReply);
    // Pinned to V3: no GET_PROTOCOL_VERSION probe before GET_STATE.
    let args = [
        "--timeout",
        "200ms",
        "smartgrasp",
        "--addr",
        &addr,
        "--protocol",
        "3",
        "state",
        "--json",
    ];
    gripctl(&args)
        .await
        .failed_with("timeout", "no response to GET_STATE within 200ms");
}

#[tokio::test]
async fn sim_child_process_serves_its_scene() {
    let sim = Simulator::start(&["smartgrasp", "--listen", "127.0.0.1:0", "--copies", "2"]).await;
    let count = sg(&sim.addr, &["count", "--class", "1", "--json"])
        .await
        .json();
    assert_eq!(count["object_count"], 6);
    assert_eq!(count["candidate_count"], 4);
    let grasp = sg(&sim.addr, &["grasp", "--robot", "ur"]).await;
    assert!(
        grasp.ok().contains("pose (axis-angle): X 450.000 mm"),
        "{grasp:?}"
    );

    let empty =
        Simulator::start(&["smartgrasp", "--listen", "127.0.0.1:0", "--scene", "empty"]).await;
    let run = sg(&empty.addr, &["grasp", "--json"]).await.json();
    assert_eq!(run["outcome"], "NO_OBJECT");

    let stopped = Simulator::start(&[
        "smartgrasp",
        "--listen",
        "127.0.0.1:0",
        "--state",
        "stopped",
    ])
    .await;
    let state = sg(&stopped.addr, &["state", "--json"]).await.json();
    assert_eq!(state["state"]["name"], "STOPPED");

    // A V2 server answers a V3 frame with the empty "too old" message (manual 1.3).
    let old = Simulator::start(&[
        "smartgrasp",
        "--listen",
        "127.0.0.1:0",
        "--protocol-version",
        "2",
    ])
    .await;
    sg(&old.addr, &["version", "--json"])
        .await
        .failed_with("device", "the server is too old: it speaks protocol v2");
}

#[tokio::test]
async fn sim_on_a_taken_address_fails_with_one_line() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = taken.local_addr().expect("addr").to_string();
    let run = gripctl(&["sim", "smartgrasp", "--listen", &addr]).await;
    let line = run.failed();
    assert!(line.contains(&format!("cannot listen on {addr}")), "{line}");
}
