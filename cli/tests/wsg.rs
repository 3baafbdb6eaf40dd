//! `gripctl wsg …` against the WSG simulator, started in this process on free ports (TCP, UDP,
//! a serial pseudo-terminal), and `gripctl sim wsg` as a child process.

mod common;

use common::{gripctl, refused_addr, Run, Simulator};
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{GripState, Status};
use serde_json::Value;

/// A simulated WSG 50 with a 40 mm part, instant motion, on a free TCP port.
async fn tcp(config: SimConfig) -> (SimServer, String) {
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let addr = server.local_addr().expect("TCP address").to_string();
    (server, addr)
}

fn with_part() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

/// `gripctl --timeout 20s wsg --addr ADDR args…`
async fn wsg(addr: &str, args: &[&str]) -> Run {
    let mut all = vec!["--timeout", common::CALL_TIMEOUT, "wsg", "--addr", addr];
    all.extend_from_slice(args);
    gripctl(&all).await
}

fn flags(state: &Value) -> Vec<String> {
    state["flags"]
        .as_array()
        .expect("flags")
        .iter()
        .map(|f| f.as_str().expect("flag name").to_owned())
        .collect()
}

#[tokio::test]
async fn info_as_text_and_json() {
    let (_server, addr) = tcp(with_part()).await;

    let text = wsg(&addr, &["info"]).await;
    let text = text.ok();
    assert!(text.contains("type: WSG 50"), "{text}");
    assert!(text.contains("serial number: 4711"), "{text}");
    assert!(text.contains("limits: stroke 110.0 mm"), "{text}");
    assert!(text.contains("temperature: 23.4 °C"), "{text}");
    assert!(text.contains("grip state: IDLE"), "{text}");

    let json = wsg(&addr, &["info", "--json"]).await.json();
    assert_eq!(json["device_type"]["name"], "WSG 50");
    assert_eq!(json["serial_number"], 4711);
    assert_eq!(json["firmware"], "4.1.2");
    assert_eq!(json["limits"]["stroke_mm"], 110.0);
    assert_eq!(json["temperature_c"], 23.4);
    assert_eq!(json["tag"], Value::Null);
    assert_eq!(json["soft_limits"], Value::Null);
    // Not homed yet.
    assert!(!flags(&json["system_state"]).contains(&"SF_REFERENCED".to_owned()));
}

#[tokio::test]
async fn info_shows_what_older_firmware_lacks_as_not_available() {
    let (server, addr) = tcp(with_part()).await;
    server.force_status(0x46, Status::CmdUnknown);
    server.force_status(0x53, Status::NotAvailable);
    let text = wsg(&addr, &["info"]).await;
    let text = text.ok();
    assert!(text.contains("temperature: n/a"), "{text}");
    assert!(text.contains("limits: n/a"), "{text}");
    server.force_status(0x46, Status::CmdUnknown);
    let json = wsg(&addr, &["info", "--json"]).await.json();
    assert_eq!(json["temperature_c"], Value::Null);
    assert_eq!(json["limits"]["stroke_mm"], 110.0);
    // Any other refusal is still an error.
    server.force_status(0x46, Status::AccessDenied);
    let run = wsg(&addr, &["info"]).await;
    assert!(run.failed().contains("E_ACCESS_DENIED"), "{run:?}");
}

#[tokio::test]
async fn home_grasp_release_report_width_force_and_grip_state() {
    let (server, addr) = tcp(with_part()).await;

    let home = wsg(&addr, &["home"]).await;
    assert_eq!(
        home.ok().trim(),
        "homed: width 110.00 mm, force 0.0 N, grip state IDLE"
    );
    let pre = wsg(&addr, &["move", "60", "--speed", "100", "--json"])
        .await
        .json();
    assert_eq!(pre["width_mm"], 60.0);

    let grasp = wsg(&addr, &["grasp", "40", "--force", "30", "--json"])
        .await
        .json();
    assert_eq!(grasp["done"], "grasped");
    assert_eq!(grasp["grip_state"]["name"], "HOLDING");
    assert_eq!(grasp["grip_state"]["code"], 4);
    assert_eq!(grasp["width_mm"], 40.0);
    assert_eq!(grasp["force_n"], 30.0);
    assert_eq!(server.snapshot().grip_state, GripState::Holding);

    let release = wsg(&addr, &["release", "70"]).await;
    assert_eq!(
        release.ok().trim(),
        "released: width 70.00 mm, force 0.0 N, grip state IDLE"
    );

    let rel = wsg(&addr, &["move", "--relative", "-10", "--json"])
        .await
        .json();
    assert_eq!(rel["width_mm"], 60.0);

    // Every run announced its disconnect: the gripper is not in FAST STOP.
    let info = wsg(&addr, &["info", "--json"]).await.json();
    let flags = flags(&info["system_state"]);
    assert!(flags.contains(&"SF_REFERENCED".to_owned()), "{flags:?}");
    assert!(!flags.contains(&"SF_FAST_STOP".to_owned()), "{flags:?}");
}

#[tokio::test]
async fn device_errors_carry_the_status_name_and_description() {
    let (_server, addr) = tcp(SimConfig::new(Model::Wsg50)).await;

    // Motion before homing.
    let run = wsg(&addr, &["grasp", "40"]).await;
    let line = run.failed();
    assert!(
        line.contains("E_NOT_INITIALIZED (3): device not initialized"),
        "{line}"
    );

    wsg(&addr, &["home"]).await.ok();
    // No part between the fingers.
    let run = wsg(&addr, &["grasp", "40", "--json"]).await;
    let line = run.failed();
    assert!(line.contains(&format!("wsg {addr}:")), "{line}");
    assert!(line.contains("E_CMD_FAILED"), "{line}");
    let error = &run.json()["error"];
    assert_eq!(error["kind"], "device");
    assert_eq!(error["code"], 18);
    assert_eq!(error["name"], "E_CMD_FAILED");
    assert_eq!(error["description"], "error while executing a command");
}

#[tokio::test]
async fn fast_stop_refuses_motion_until_acknowledged() {
    let (_server, addr) = tcp(with_part()).await;
    wsg(&addr, &["home"]).await.ok();
    assert!(wsg(&addr, &["fast-stop"])
        .await
        .ok()
        .starts_with("FAST STOP"));
    let refused = wsg(&addr, &["move", "50", "--json"]).await;
    refused.failed();
    assert_eq!(refused.json()["error"]["name"], "E_ACCESS_DENIED");
    assert_eq!(wsg(&addr, &["ack"]).await.ok().trim(), "acknowledged");
    let moved = wsg(&addr, &["move", "50", "--json"]).await.json();
    assert_eq!(moved["width_mm"], 50.0);
    let stopped = wsg(&addr, &["stop", "--json"]).await.json();
    assert_eq!(stopped["done"], "stopped");
}

#[tokio::test]
async fn settings_report_what_the_gripper_took() {
    let (_server, addr) = tcp(with_part()).await;
    // The WSG 50 clamps the force to its nominal 80 N.
    let force = wsg(&addr, &["set", "force", "1000", "--json"]).await.json();
    assert_eq!(force["grasping_force_n"], 80.0);
    let acc = wsg(&addr, &["set", "acceleration", "2000"]).await;
    assert_eq!(acc.ok().trim(), "acceleration 2000 mm/s²");
    let limits = wsg(&addr, &["set", "soft-limits", "5", "100", "--json"])
        .await
        .json();
    assert_eq!(limits["soft_limits"]["minus_mm"], 5.0);
    assert_eq!(limits["soft_limits"]["plus_mm"], 100.0);
    let cleared = wsg(&addr, &["set", "soft-limits", "--clear"]).await;
    assert_eq!(cleared.ok().trim(), "soft limits: none");
    let tag = wsg(&addr, &["set", "tag", "cell 4 left"]).await;
    assert_eq!(tag.ok().trim(), "tag: cell 4 left");
    let info = wsg(&addr, &["info", "--json"]).await.json();
    assert_eq!(info["tag"], "cell 4 left");
    assert_eq!(info["grasping_force_n"], 80.0);
    assert_eq!(info["acceleration_mm_per_s2"], 2000.0);
}

#[tokio::test]
async fn watch_prints_count_samples() {
    let (_server, addr) = tcp(with_part()).await;
    wsg(&addr, &["home"]).await.ok();
    wsg(&addr, &["grasp", "40"]).await.ok();
    let run = wsg(
        &addr,
        &["watch", "--count", "3", "--period", "10ms", "--json"],
    )
    .await;
    run.ok();
    let samples = run.json_lines();
    assert_eq!(samples.len(), 3, "{run:?}");
    for s in &samples {
        assert_eq!(s["width_mm"], 40.0);
        assert_eq!(s["grip_state"]["name"], "HOLDING");
        assert!(s["force_n"].as_f64().expect("force") > 0.0, "{s}");
    }
    let text = wsg(&addr, &["watch", "--count", "2", "--period", "10ms"]).await;
    let lines: Vec<&str> = text.ok().lines().collect();
    assert_eq!(lines.len(), 2, "{text:?}");
    assert!(
        lines
            .iter()
            .all(|l| l.contains("width   40.00 mm") && l.ends_with("HOLDING")),
        "{lines:?}"
    );
}

#[cfg(unix)]
#[tokio::test]
async fn watch_ends_on_ctrl_c_with_status_zero() {
    use tokio::io::{AsyncBufReadExt, BufReader};
    let (_server, addr) = tcp(with_part()).await;
    let mut child = tokio::process::Command::new(env!("CARGO_BIN_EXE_gripctl"))
        .args(["wsg", "--addr", &addr, "watch", "--period", "10ms"])
        .stdout(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("spawn");
    let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
    // Two samples: the watch (and its Ctrl-C handler) is running.
    for _ in 0..2 {
        let line = tokio::time::timeout(common::PATIENCE, lines.next_line())
            .await
            .expect("a sample")
            .expect("readable")
            .expect("a line");
        assert!(line.contains("width"), "{line}");
    }
    let pid = child.id().expect("running").to_string();
    let sent = std::process::Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    while let Ok(Some(_)) = lines.next_line().await {}
    let status = tokio::time::timeout(common::PATIENCE, child.wait())
        .await
        .expect("gripctl exits")
        .expect("wait");
    assert_eq!(status.code(), Some(0));
}

#[tokio::test]
async fn loop_test_and_raw_commands() {
    let (_server, addr) = tcp(with_part()).await;
    let looped = wsg(&addr, &["loop", "--repeat", "3", "--size", "256"]).await;
    assert!(
        looped
            .ok()
            .starts_with("loop test passed: 3 × 256 bytes echoed"),
        "{looped:?}"
    );

    let info = wsg(&addr, &["raw", "0x50", "--json"]).await.json();
    assert_eq!(info["status"]["name"], "E_SUCCESS");
    assert_eq!(info["decoded"]["serial_number"], 4711);
    assert_eq!(info["decoded"]["device_type"], "WSG 50");

    // 0x43 with flags 0 and period 0: the width once (manual 3.4.4).
    let width = wsg(&addr, &["raw", "67", "00 00 00"]).await;
    assert_eq!(width.ok().trim(), "0x43 E_SUCCESS: [00 00 00 00] = 0 mm");

    // Without its parameters the gripper refuses the command: its status is the error.
    let run = wsg(&addr, &["raw", "0x43", "--json"]).await;
    let line = run.failed();
    assert!(line.contains("E_CMD_FORMAT_ERROR"), "{line}");
    assert_eq!(run.json()["error"]["code"], 15);

    let bad = wsg(&addr, &["raw", "0x43", "0"]).await;
    assert!(bad.failed().contains("two digits per byte"), "{bad:?}");
}

#[tokio::test]
async fn udp_and_serial_transports() {
    let server = SimServer::bind_udp("127.0.0.1:0", with_part())
        .await
        .expect("bind");
    let addr = server.local_addr().expect("UDP address").to_string();
    let info = gripctl(&["wsg", "--udp", "--addr", &addr, "info", "--json"])
        .await
        .json();
    assert_eq!(info["serial_number"], 4711);
    let home = gripctl(&["wsg", "--udp", "--addr", &addr, "home"]).await;
    assert!(home.ok().starts_with("homed"), "{home:?}");

    #[cfg(unix)]
    {
        let pty = SimServer::serial_pty(with_part()).expect("pty");
        let path = pty.serial_path().expect("pty path").to_owned();
        let info = gripctl(&["wsg", "--serial", &path, "--shared", "info", "--json"])
            .await
            .json();
        assert_eq!(info["device_type"]["name"], "WSG 50");
        let grasp = gripctl(&[
            "wsg", "--serial", &path, "--shared", "--baud", "9600", "home",
        ])
        .await;
        assert!(grasp.ok().starts_with("homed"), "{grasp:?}");
    }
}

#[tokio::test]
async fn connection_refused_and_timeout_are_one_line() {
    let addr = refused_addr();
    let run = wsg(&addr, &["info"]).await;
    let line = run.failed();
    assert!(
        line.contains(&format!("wsg {addr}: cannot connect")),
        "{line}"
    );

    let (server, addr) = tcp(with_part()).await;
    server.drop_next_reply(0x50);
    let args = [
        "--timeout",
        "200ms",
        "wsg",
        "--addr",
        &addr,
        "info",
        "--json",
    ];
    gripctl(&args)
        .await
        .failed_with("timeout", "no reply to command 0x50 within 200ms");
}

#[tokio::test]
async fn sim_child_processes_serve_the_chosen_model_and_part() {
    let sim = Simulator::start(&[
        "wsg",
        "--listen",
        "127.0.0.1:0",
        "--model",
        "wsg32",
        "--no-part",
        "--time-scale",
        "0",
    ])
    .await;
    let info = wsg(&sim.addr, &["info", "--json"]).await.json();
    assert_eq!(info["device_type"]["name"], "WSG 32");
    assert_eq!(info["limits"]["stroke_mm"], 68.0);
    wsg(&sim.addr, &["home"]).await.ok();
    let run = wsg(&sim.addr, &["grasp", "20"]).await;
    assert!(run.failed().contains("E_CMD_FAILED"), "{run:?}");

    let udp = Simulator::start(&[
        "wsg",
        "--listen",
        "127.0.0.1:0",
        "--udp",
        "--part",
        "25",
        "--time-scale",
        "0",
    ])
    .await;
    let udp_args = ["wsg", "--udp", "--addr", &udp.addr];
    gripctl(&[&udp_args[..], &["home"]].concat()).await.ok();
    let grasp = gripctl(&[&udp_args[..], &["grasp", "25", "--json"]].concat())
        .await
        .json();
    assert_eq!(grasp["grip_state"]["name"], "HOLDING");
    assert_eq!(grasp["width_mm"], 25.0);
}

/// One status-only reply (10 bytes: preamble, id, length 2, status, checksum) read raw.
async fn raw_status(stream: &mut tokio::net::TcpStream) -> (u8, Status) {
    use tokio::io::AsyncReadExt;
    let mut got = [0u8; 10];
    tokio::time::timeout(common::PATIENCE, stream.read_exact(&mut got))
        .await
        .expect("a reply in time")
        .expect("readable");
    decode_status(&got)
}

fn decode_status(bytes: &[u8]) -> (u8, Status) {
    let mut buf = bytes::BytesMut::from(bytes);
    match gripper::wsg::frame::decode_eof(&mut buf, 64) {
        Some(gripper::wsg::frame::Decoded::Frame(f)) => {
            let reply = gripper::wsg::Reply::from_frame(f).expect("a reply");
            (reply.id, reply.status)
        }
        other => panic!("not a reply frame: {other:?}"),
    }
}

fn encoded(cmd: gripper::wsg::Command) -> Vec<u8> {
    let mut b = bytes::BytesMut::new();
    gripper::wsg::frame::encode(&cmd.to_frame(), &mut b).expect("encodable");
    b.to_vec()
}

/// `gripctl sim wsg` with no options but a free port runs in real time (like the
/// `wsg_simulator` example, both serve `SimConfig::standalone()`): the homing is still running
/// when a second one comes (E_ALREADY_RUNNING), and a stop ends it with E_CMD_ABORTED.
#[tokio::test]
async fn sim_wsg_runs_in_real_time_by_default() {
    use gripper::wsg::{Command, HomingDirection};
    use tokio::io::AsyncWriteExt;
    let sim = Simulator::start(&["wsg", "--listen", "127.0.0.1:0"]).await;
    let mut raw = tokio::net::TcpStream::connect(&sim.addr)
        .await
        .expect("connect");
    let homing = encoded(Command::Homing(HomingDirection::Default));
    raw.write_all(&homing).await.expect("write");
    assert_eq!(raw_status(&mut raw).await, (0x20, Status::CmdPending));
    raw.write_all(&homing).await.expect("write");
    assert_eq!(raw_status(&mut raw).await, (0x20, Status::AlreadyRunning));
    raw.write_all(&encoded(Command::Stop)).await.expect("write");
    assert_eq!(raw_status(&mut raw).await, (0x20, Status::CmdAborted));
    assert_eq!(raw_status(&mut raw).await, (0x22, Status::Success));
    raw.write_all(&encoded(Command::AnnounceDisconnect))
        .await
        .expect("write");
    assert_eq!(raw_status(&mut raw).await, (0x07, Status::Success));
}

/// `gripctl sim wsg --udp --udp-remote-port P`: a client that sends from one socket and
/// listens on port P (as drivers of the real device do) receives every reply there.
#[tokio::test]
async fn sim_wsg_udp_remote_port_sends_every_reply_to_that_port() {
    use gripper::wsg::{Command, HomingDirection};
    let listener = tokio::net::UdpSocket::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let port = listener.local_addr().expect("address").port().to_string();
    let sim = Simulator::start(&[
        "wsg",
        "--listen",
        "127.0.0.1:0",
        "--udp",
        "--udp-remote-port",
        &port,
        "--time-scale",
        "0",
    ])
    .await;
    let sender = tokio::net::UdpSocket::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let mut buf = [0u8; 64];
    let mut recv = async || {
        let (n, _) = tokio::time::timeout(common::PATIENCE, listener.recv_from(&mut buf))
            .await
            .expect("the reply reaches the remote port")
            .expect("readable");
        decode_status(&buf[..n])
    };
    for _ in 0..20 {
        sender
            .send_to(&encoded(Command::Stop), &sim.addr)
            .await
            .expect("send");
        assert_eq!(recv().await, (0x22, Status::Success));
    }
    sender
        .send_to(
            &encoded(Command::Homing(HomingDirection::Default)),
            &sim.addr,
        )
        .await
        .expect("send");
    assert_eq!(recv().await, (0x20, Status::CmdPending));
    assert_eq!(recv().await, (0x20, Status::Success));
    let mut none = [0u8; 64];
    assert!(
        sender.try_recv_from(&mut none).is_err(),
        "nothing goes back to the sending port"
    );
}

/// `gripctl wsg --text …` against the text simulator in this process, and `gripctl sim wsg
/// --text` as a child process.
#[tokio::test]
async fn the_text_interface_subcommands() {
    let (server, addr) = tcp(with_part().text()).await;
    let text = |args: &'static [&'static str]| {
        let addr = addr.clone();
        async move { wsg(&addr, &[&["--text"], args].concat()).await }
    };
    let home = text(&["home"]).await;
    assert_eq!(
        home.ok().trim(),
        "homed: width 110.00 mm, force 0.0 N, grip state IDLE"
    );
    let moved = text(&["move", "60", "--json"]).await.json();
    assert_eq!(moved["width_mm"], 60.0);
    let grasp = text(&["grasp", "40", "--force", "30", "--json"])
        .await
        .json();
    assert_eq!(grasp["grip_state"]["name"], "HOLDING");
    assert_eq!(grasp["force_n"], 30.0);
    // `release WIDTH` opens to WIDTH, though GCL's RELEASE is relative.
    let release = text(&["release", "70", "--json"]).await.json();
    assert_eq!(release["width_mm"], 70.0);
    assert_eq!(release["grip_state"]["name"], "IDLE");
    let info = text(&["info", "--json"]).await.json();
    assert_eq!(info["temperature_c"], 23.4);
    let watch = text(&["watch", "--count", "2", "--period", "10ms"]).await;
    assert_eq!(watch.ok().lines().count(), 2, "{watch:?}");
    let failed = text(&["grasp", "10"]).await;
    assert!(failed.failed().contains("E_CMD_FAILED"), "{failed:?}");
    let no = text(&["loop"]).await;
    assert!(no
        .failed()
        .contains("not available over the text interface"));
    text(&["fast-stop"]).await.ok();
    assert!(text(&["home"]).await.failed().contains("E_ACCESS_DENIED"));
    text(&["ack"]).await.ok();
    // Every run said BYE(): no FAST STOP.
    assert_eq!(server.snapshot().grip_state, GripState::Idle);

    let sim = Simulator::start(&[
        "wsg",
        "--listen",
        "127.0.0.1:0",
        "--text",
        "--time-scale",
        "0",
    ])
    .await;
    let args = ["wsg", "--text", "--addr", &sim.addr];
    let home = gripctl(&[&args[..], &["home", "--json"]].concat())
        .await
        .json();
    assert_eq!(home["width_mm"], 110.0);
}
