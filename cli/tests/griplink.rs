//! `gripctl griplink …` against the GRIPLINK simulator, started in this process on a free port,
//! and `gripctl sim griplink` as a child process.

mod common;

use common::{gripctl, refused_addr, Run, Simulator};
use gripper::griplink::sim::{Fault, SimConfig, SimDevice, SimServer};
use gripper::griplink::DeviceState;

/// A GRIPLINK-ET4 with an IEG 55-020 holding a 12 mm part on port 0 and a CRG 200-085 without
/// a part on port 2; motion takes no time.
async fn et4() -> (SimServer, String) {
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .time_scale(0.0);
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let addr = server.local_addr().to_string();
    (server, addr)
}

/// `gripctl --timeout 20s griplink --addr ADDR args…`
async fn gl(addr: &str, args: &[&str]) -> Run {
    let mut all = vec![
        "--timeout",
        common::CALL_TIMEOUT,
        "griplink",
        "--addr",
        addr,
    ];
    all.extend_from_slice(args);
    gripctl(&all).await
}

#[tokio::test]
async fn info_lists_the_controller_and_each_ports_device() {
    let (_server, addr) = et4().await;

    let text = gl(&addr, &["info"]).await;
    let text = text.ok();
    assert!(
        text.starts_with("ID: GRIPLINK-ET4\nprotocol: GRIPLINK-V3\nversion: 4.0.0"),
        "{text}"
    );
    assert!(
        text.contains("port 0: IEG 55-020 (WEISS ROBOTICS, vendor 815, product 20)"),
        "{text}"
    );
    assert!(text.contains("port 2: CRG 200-085"), "{text}");
    assert!(text.contains("no device on port 1, 3"), "{text}");

    let json = gl(&addr, &["info", "--json"]).await.json();
    assert_eq!(json["id"], "GRIPLINK-ET4");
    assert_eq!(json["protocol"], "GRIPLINK-V3");
    let ports = json["ports"].as_array().expect("ports");
    // The ET4 has four ports; the fifth answers E_INDEX_OUT_OF_BOUNDS and ends the list.
    assert_eq!(ports.len(), 4, "{json}");
    assert_eq!(ports[0]["device"]["product_id"], 20);
    assert_eq!(ports[0]["device"]["state"]["name"], "DS_NOT_INITIALIZED");
    assert_eq!(ports[1]["device"], serde_json::Value::Null);
    assert_eq!(ports[2]["device"]["name"], "CRG 200-085");
}

#[tokio::test]
async fn home_recipe_grip_release() {
    let (server, addr) = et4().await;

    let home = gl(&addr, &["home"]).await;
    assert_eq!(home.ok().trim(), "homed: position 20.000 mm, DS_DISABLED");

    let set = gl(
        &addr,
        &["recipe", "set", "1", "part", "5", "18", "50", "--json"],
    )
    .await
    .json();
    assert_eq!(set["tag"], "part");
    assert_eq!(set["no_part_limit_mm"], 5.0);
    assert_eq!(set["release_limit_mm"], 18.0);
    assert_eq!(set["force_percent"], 50.0);
    let get = gl(&addr, &["recipe", "get", "1"]).await;
    assert!(
        get.ok()
            .starts_with("recipe 1 \"part\": no-part limit 5 mm, release limit 18 mm, force 50 %"),
        "{get:?}"
    );

    let grip = gl(&addr, &["grip", "1", "--json"]).await.json();
    assert_eq!(grip["done"], "gripped");
    assert_eq!(grip["position_mm"], 12.0);
    assert_eq!(grip["state"]["name"], "DS_HOLDING");
    assert_eq!(server.device_state(0), Some(DeviceState::Holding));

    let state = gl(&addr, &["state"]).await;
    assert_eq!(state.ok().trim(), "DS_HOLDING");
    let value = gl(&addr, &["value", "0", "--json"]).await.json();
    assert_eq!(value["value"], 12.0);

    let release = gl(&addr, &["release", "1"]).await;
    assert_eq!(
        release.ok().trim(),
        "released: position 18.000 mm, DS_RELEASED"
    );
}

#[tokio::test]
async fn flexgrip_and_flexrelease_on_another_port() {
    let (server, addr) = et4().await;
    // --port is accepted before and after the subcommand.
    gl(&addr, &["--port", "2", "home"]).await.ok();
    let moved = gl(&addr, &["flexrelease", "40", "--port", "2", "--json"])
        .await
        .json();
    assert_eq!(moved["position_mm"], 40.0);
    assert_eq!(moved["state"]["name"], "DS_RELEASED");

    // Port 2 holds no part: the grip ends in DS_NO_PART, which is the device's answer.
    let run = gl(&addr, &["--port", "2", "flexgrip", "10", "50", "--json"]).await;
    let line = run.failed();
    assert!(
        line.contains(&format!(
            "griplink {addr} port 2: the grip found no part: DS_NO_PART"
        )),
        "{line}"
    );
    assert_eq!(run.json()["error"]["name"], "DS_NO_PART");
    assert_eq!(run.json()["error"]["code"], 4);

    // A part goes in; after DS_NO_PART the fingers open again before the next grip.
    server.set_part(2, Some(30.0));
    gl(&addr, &["--port", "2", "flexrelease", "40"]).await.ok();
    let grip = gl(&addr, &["--port", "2", "flexgrip", "10", "50"]).await;
    assert_eq!(grip.ok().trim(), "gripped: position 30.000 mm, DS_HOLDING");
}

#[tokio::test]
async fn controller_errors_carry_the_status_name_and_description() {
    let (server, addr) = et4().await;
    // Gripping before homing.
    let run = gl(&addr, &["grip", "--json"]).await;
    let line = run.failed();
    assert!(
        line.contains("GRIP(0,0) refused: ERR 04 E_NOT_INITIALIZED"),
        "{line}"
    );
    let error = &run.json()["error"];
    assert_eq!(error["kind"], "device");
    assert_eq!(error["code"], 4);
    assert_eq!(error["name"], "E_NOT_INITIALIZED");
    assert_eq!(error["description"], "Device not initialized");

    // A fault during the motion: the device's state is the answer.
    gl(&addr, &["home"]).await.ok();
    server.fault_next_motion(0);
    let run = gl(&addr, &["grip", "--json"]).await;
    let error = run.failed_with("device", "the grip ended in a fault: DS_FAULT");
    assert_eq!(error["name"], "DS_FAULT");
    assert_eq!(error["code"], 7);

    let run = gl(&addr, &["--port", "7", "state"]).await;
    assert!(run.failed().contains("E_INDEX_OUT_OF_BOUNDS"), "{run:?}");
}

#[tokio::test]
async fn raw_lines_and_watch() {
    let (_server, addr) = et4().await;
    let name = gl(&addr, &["raw", "DEVNAME[0]?"]).await;
    assert_eq!(name.ok().trim(), "DEVNAME[0]=\"IEG 55-020\"");
    let name = gl(&addr, &["raw", "DEVNAME[0]?", "--json"]).await.json();
    assert_eq!(name["key"], "DEVNAME");
    assert_eq!(name["indices"], serde_json::json!([0]));
    assert_eq!(name["value"], "IEG 55-020");
    let ack = gl(&addr, &["raw", "HOME(0)"]).await;
    assert_eq!(ack.ok().trim(), "ACK");
    let unknown = gl(&addr, &["raw", "FOO()", "--json"]).await;
    unknown.failed();
    assert_eq!(unknown.json()["error"]["name"], "E_CMD_UNKNOWN");

    let run = gl(
        &addr,
        &["watch", "--count", "3", "--period", "10ms", "--json"],
    )
    .await;
    run.ok();
    let samples = run.json_lines();
    assert_eq!(samples.len(), 3, "{run:?}");
    for s in samples {
        assert_eq!(s["position_mm"], 20.0);
        assert_eq!(s["state"]["name"], "DS_DISABLED");
    }
}

#[tokio::test]
async fn connection_refused_and_timeout_are_one_line() {
    let addr = refused_addr();
    let run = gl(&addr, &["info"]).await;
    assert!(
        run.failed()
            .contains(&format!("griplink {addr}: cannot connect")),
        "{run:?}"
    );

    let (server, addr) = et4().await;
    let _held = server.hold_next_reply();
    let args = [
        "--timeout",
        "200ms",
        "griplink",
        "--addr",
        &addr,
        "state",
        "--json",
    ];
    gripctl(&args)
        .await
        .failed_with("timeout", "no reply to DEVSTATE[0]? within 200ms");

    // The controller hangs up instead of answering.
    server.inject(Fault::Close);
    let run = gl(&addr, &["state", "--json"]).await;
    run.failed();
    assert_eq!(run.json()["error"]["kind"], "connection");
}

#[tokio::test]
async fn sim_child_process_serves_the_chosen_device_and_part() {
    let sim = Simulator::start(&["griplink", "--listen", "127.0.0.1:0", "--part", "8"]).await;
    gl(&sim.addr, &["home"]).await.ok();
    gl(&sim.addr, &["recipe", "set", "0", "small", "2", "18", "40"])
        .await
        .ok();
    let grip = gl(&sim.addr, &["grip", "--json"]).await.json();
    assert_eq!(grip["position_mm"], 8.0);

    let wpg =
        Simulator::start(&["griplink", "--listen", "127.0.0.1:0", "--wpg", "--no-part"]).await;
    let info = gl(&wpg.addr, &["info", "--json"]).await.json();
    assert_eq!(info["ports"].as_array().expect("ports").len(), 1);
    assert_eq!(info["ports"][0]["device"]["name"], "WPG 100-090");
    gl(&wpg.addr, &["home"]).await.ok();
    let run = gl(&wpg.addr, &["grip"]).await;
    assert!(run.failed().contains("DS_NO_PART"), "{run:?}");
}
