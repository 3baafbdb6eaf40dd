//! The WSG client against the in-process simulator over real loopback sockets and a pty.
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{
    Client, DeviceType, Error, GripState, HomingDirection, SoftLimits, Status, SystemState,
    UpdateOptions,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

fn with_part() -> SimConfig {
    SimConfig::new(Model::Wsg50).with_part(40.0, 2.0)
}

async fn tcp(config: SimConfig) -> (SimServer, Client) {
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let client = Client::connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    (sim, client)
}

/// The pick sequence of the example, asserting each answer.
async fn pick(client: &Client) {
    let info = client.system_info().await.unwrap();
    assert_eq!(info.device_type, DeviceType::Wsg50);
    let limits = client.system_limits().await.unwrap();
    assert_eq!(limits.stroke_mm, 110.0);
    let err = client.pre_position(50.0, 100.0).await.unwrap_err();
    assert_eq!(err.status(), Some(Status::NotInitialized), "{err}");
    client.home(HomingDirection::Default).await.unwrap();
    assert!(client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::REFERENCED));
    client.pre_position(60.0, 100.0).await.unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 60.0);
    client.grasp(40.0, 50.0).await.unwrap();
    assert_eq!(client.grip_state().await.unwrap(), GripState::Holding);
    assert_eq!(client.width_mm().await.unwrap(), 40.0);
    assert!(client.force_n().await.unwrap() > 0.0);
    client.release(70.0, 100.0).await.unwrap();
    assert_eq!(client.grip_state().await.unwrap(), GripState::Idle);
    // No part at 10 mm: the grasp fails with E_CMD_FAILED and the state says so.
    let err = client.grasp(10.0, 50.0).await.unwrap_err();
    assert_eq!(err.status(), Some(Status::CmdFailed), "{err}");
    assert_eq!(client.grip_state().await.unwrap(), GripState::NoPartFound);
    let stats = client.grasping_statistics(true).await.unwrap();
    assert_eq!((stats.total, stats.no_part), (2, 1));
}

#[tokio::test]
async fn pick_over_tcp_and_close_gracefully() {
    let (sim, client) = tcp(with_part()).await;
    pick(&client).await;
    assert!(!client.is_closed());
    client.close().await.unwrap();
    assert!(client.is_closed(), "closed once close() returned");
    assert_eq!(sim.received_ids().last(), Some(&id::ANNOUNCE_DISCONNECT));
    // Once the simulator has seen the close, it did not go into FAST STOP.
    let client2 = Client::connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let state = client2.system_state().await.unwrap();
    assert!(!state.contains(SystemState::FAST_STOP), "{state:?}");
    assert!(matches!(client.width_mm().await, Err(Error::Closed)));
}

#[tokio::test]
async fn an_unannounced_tcp_close_puts_the_simulator_into_fast_stop() {
    let sim = SimServer::bind("127.0.0.1:0", with_part()).await.unwrap();
    let addr = sim.local_addr().unwrap();
    let raw = tokio::net::TcpStream::connect(addr).await.unwrap();
    drop(raw);
    let client = Client::connect_tcp(addr).await.unwrap();
    // The disconnect is processed before any later frame of the new connection only
    // eventually: ask until the simulator has counted the first connection out.
    let mut state = client.system_state().await.unwrap();
    for _ in 0..10_000 {
        if state.contains(SystemState::FAST_STOP) {
            break;
        }
        tokio::task::yield_now().await;
        state = client.system_state().await.unwrap();
    }
    assert!(state.contains(SystemState::FAST_STOP), "{state:?}");
    let err = client.home(HomingDirection::Default).await.unwrap_err();
    assert_eq!(err.status(), Some(Status::AccessDenied));
    client.acknowledge_fast_stop().await.unwrap();
    client.home(HomingDirection::Default).await.unwrap();
}

#[tokio::test]
async fn close_sends_the_disconnect_announcement_to_a_raw_peer() {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let client = Client::connect_tcp(addr).await.unwrap();
    let (mut peer, _) = listener.accept().await.unwrap();
    let closing = tokio::spawn(async move { client.close().await });
    let mut got = [0u8; 8];
    peer.read_exact(&mut got).await.unwrap();
    assert_eq!(got, [0xAA, 0xAA, 0xAA, 0x07, 0x00, 0x00, 0x35, 0x4C]);
    // E_SUCCESS for 0x07.
    let mut ok = bytes::BytesMut::new();
    let reply = gripper::wsg::Reply::new(id::ANNOUNCE_DISCONNECT, Status::Success, vec![]);
    gripper::wsg::frame::encode(&reply.to_frame(), &mut ok).unwrap();
    peer.write_all(&ok).await.unwrap();
    let mut rest = Vec::new();
    peer.read_to_end(&mut rest).await.unwrap();
    assert!(
        rest.is_empty(),
        "nothing after the announcement: {rest:02X?}"
    );
    let result = closing.await.unwrap();
    assert!(result.is_ok(), "{result:?}");
}

#[tokio::test]
async fn pick_over_udp() {
    let sim = SimServer::bind_udp("127.0.0.1:0", with_part())
        .await
        .unwrap();
    let client = Client::builder()
        .connect_udp(sim.local_addr().unwrap())
        .await
        .unwrap();
    pick(&client).await;
    // 0x07 is TCP-only: UDP answers E_NOT_AVAILABLE.
    let err = client
        .command(gripper::wsg::Command::AnnounceDisconnect)
        .await
        .unwrap_err();
    assert_eq!(err.status(), Some(Status::NotAvailable));
    client.close().await.unwrap();
}

#[cfg(all(unix, feature = "serial"))]
#[tokio::test]
async fn pick_over_a_serial_pseudo_terminal() {
    let sim = SimServer::serial_pty(with_part()).unwrap();
    let path = sim.serial_path().unwrap().to_owned();
    let client = Client::builder()
        .serial_exclusive(false)
        .open_serial(&path, 115_200)
        .unwrap();
    pick(&client).await;
    client.close().await.unwrap();
}

#[tokio::test]
async fn unknown_commands_and_raw_requests() {
    let (_sim, client) = tcp(with_part()).await;
    let reply = client.request(0x90, vec![]).await.unwrap();
    assert_eq!(reply.status, Status::CmdUnknown);
    let echo = client.loop_back(vec![1u8, 2, 3]).await.unwrap();
    assert_eq!(&echo[..], &[1, 2, 3]);
    assert!(matches!(
        client.loop_back(vec![0u8; 257]).await,
        Err(Error::InvalidArgument { .. })
    ));
    assert!(matches!(
        client.request(0xAA, vec![]).await,
        Err(Error::InvalidArgument { .. })
    ));
    assert_eq!(client.temperature_c().await.unwrap(), 23.4);
    assert_eq!(client.device_tag().await.unwrap(), None);
    client.set_device_tag("cell 4").await.unwrap();
    assert_eq!(
        client.device_tag().await.unwrap().as_deref(),
        Some("cell 4")
    );
    let err = client.set_device_tag("semi;colon").await.unwrap_err();
    assert_eq!(err.status(), Some(Status::InvalidParameter));
    assert_eq!(client.soft_limits().await.unwrap(), None);
    let limits = SoftLimits {
        minus_mm: 5.0,
        plus_mm: 100.0,
    };
    client.set_soft_limits(limits).await.unwrap();
    assert_eq!(client.soft_limits().await.unwrap(), Some(limits));
    client.home(HomingDirection::Default).await.unwrap();
    let err = client.pre_position(2.0, 50.0).await.unwrap_err();
    assert_eq!(err.status(), Some(Status::RangeError));
    client.clear_soft_limits().await.unwrap();
    client.set_grasping_force(1000.0).await.unwrap();
    assert_eq!(client.grasping_force_n().await.unwrap(), 80.0);
    client.set_acceleration(1.0).await.unwrap();
    assert_eq!(client.acceleration_mm_per_s2().await.unwrap(), 100.0);
}

#[tokio::test]
async fn many_concurrent_callers_with_mixed_ids_get_their_own_replies() {
    let (_sim, client) = tcp(with_part()).await;
    concurrent_callers(client).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn callers_that_find_the_request_queue_full_wait_and_get_their_own_replies() {
    let sim = SimServer::bind("127.0.0.1:0", with_part()).await.unwrap();
    // A queue of one, and callers on two threads: while one thread polls the connection, the
    // other's callers find the queue full and wait for room.
    let client = Client::builder()
        .request_queue(1)
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    for _ in 0..10 {
        concurrent_callers(client.clone()).await;
    }
}

/// Sixty callers on one client at once, with mixed command ids, each checking its own reply.
async fn concurrent_callers(client: Client) {
    client.home(HomingDirection::Default).await.unwrap();
    let mut tasks = Vec::new();
    for i in 0..60u32 {
        let c = client.clone();
        tasks.push(tokio::spawn(async move {
            match i % 4 {
                // The loop payload identifies the caller: a reply handed to the wrong caller
                // would show.
                0 | 1 => {
                    let payload = i.to_le_bytes().to_vec();
                    let echo = c.loop_back(payload.clone()).await.unwrap();
                    assert_eq!(&echo[..], &payload[..], "caller {i}");
                }
                2 => assert_eq!(c.width_mm().await.unwrap(), 110.0),
                _ => assert_eq!(c.system_info().await.unwrap().serial_number, 4711),
            }
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }
}

#[tokio::test]
async fn stop_during_a_move_aborts_it() {
    // 1000 wall seconds per simulated second: the move is still running when the stop comes.
    let (sim, client) = tcp(with_part().with_time_scale(1000.0)).await;
    let fast = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    // The homing move itself (about 1 simulated second, so 1000 wall seconds) is stopped.
    let mover = {
        let c = client.clone();
        tokio::spawn(async move { c.home(HomingDirection::Default).await })
    };
    let mut moving = false;
    for _ in 0..10_000 {
        if fast
            .system_state()
            .await
            .unwrap()
            .contains(SystemState::MOVING)
        {
            moving = true;
            break;
        }
    }
    assert!(moving, "the homing move never started");
    // The stop is not queued behind the pending move.
    fast.stop().await.unwrap();
    let err = mover.await.unwrap().unwrap_err();
    assert_eq!(err.status(), Some(Status::CmdAborted), "{err}");
    let state = fast.system_state().await.unwrap();
    assert!(state.contains(SystemState::AXIS_STOPPED) && !state.contains(SystemState::MOVING));
    drop(sim);
}

#[tokio::test]
async fn fast_stop_during_a_move_aborts_it_and_locks_motion() {
    let (_sim, client) = tcp(with_part().with_time_scale(1000.0)).await;
    let mover = {
        let c = client.clone();
        tokio::spawn(async move { c.home(HomingDirection::Default).await })
    };
    while !client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING)
    {}
    client.fast_stop().await.unwrap();
    assert_eq!(
        mover.await.unwrap().unwrap_err().status(),
        Some(Status::CmdAborted)
    );
    assert_eq!(client.grip_state().await.unwrap(), GripState::Error);
    let err = client.home(HomingDirection::Default).await.unwrap_err();
    assert_eq!(err.status(), Some(Status::AccessDenied));
    client.acknowledge_fast_stop().await.unwrap();
    assert_eq!(client.grip_state().await.unwrap(), GripState::Idle);
}

#[tokio::test]
async fn a_late_reply_never_reaches_the_next_caller() {
    let (sim, client) = tcp(with_part()).await;
    let impatient = client.with_timeouts(Duration::from_millis(50), Duration::from_millis(50));
    sim.delay_next_reply(id::LOOP, Duration::from_millis(300));
    let err = impatient.loop_back(b"first".to_vec()).await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::Timeout {
                command: id::LOOP,
                ..
            }
        ),
        "{err}"
    );
    // The next loop waits for the late "first" reply to be consumed, then gets its own.
    let echo = client.loop_back(b"second".to_vec()).await.unwrap();
    assert_eq!(&echo[..], b"second");
}

#[tokio::test]
async fn a_dropped_call_does_not_desync_the_connection() {
    let (sim, client) = tcp(with_part()).await;
    sim.delay_next_reply(id::LOOP, Duration::from_millis(200));
    let c = client.clone();
    let dropped = tokio::spawn(async move { c.loop_back(b"dropped".to_vec()).await });
    // Make sure the request went out before cancelling it.
    while !sim.received_ids().contains(&id::LOOP) {
        tokio::task::yield_now().await;
    }
    dropped.abort();
    let echo = client.loop_back(b"mine".to_vec()).await.unwrap();
    assert_eq!(&echo[..], b"mine");
}

#[tokio::test]
async fn a_lost_reply_releases_its_id_after_the_grace_period() {
    let sim = SimServer::bind("127.0.0.1:0", with_part()).await.unwrap();
    let client = Client::builder()
        .query_timeout(Duration::from_millis(50))
        .late_reply_grace(Duration::from_millis(50))
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    sim.drop_next_reply(id::LOOP);
    let err = client.loop_back(b"lost".to_vec()).await.unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    assert_eq!(
        &patient.loop_back(b"next".to_vec()).await.unwrap()[..],
        b"next"
    );
}

#[tokio::test]
async fn a_corrupted_reply_is_dropped_not_misread() {
    let sim = SimServer::bind("127.0.0.1:0", with_part()).await.unwrap();
    // The dropped reply never comes: the id is released after timeout + grace.
    let client = Client::builder()
        .late_reply_grace(Duration::from_millis(100))
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let impatient = client.with_timeouts(Duration::from_millis(100), Duration::from_millis(100));
    sim.corrupt_next_reply(id::SYSTEM_INFO);
    assert!(matches!(
        impatient.system_info().await,
        Err(Error::Timeout { .. })
    ));
    let patient = client.with_timeouts(Duration::from_secs(5), Duration::from_secs(5));
    assert_eq!(patient.system_info().await.unwrap().serial_number, 4711);
}

#[tokio::test]
async fn a_forced_status_is_reported_as_a_device_error() {
    let (sim, client) = tcp(with_part()).await;
    sim.force_status(id::TEMPERATURE, Status::Unknown(77));
    let err = client.temperature_c().await.unwrap_err();
    assert!(
        matches!(
            err,
            Error::Device {
                command: 0x46,
                status: Status::Unknown(77)
            }
        ),
        "{err}"
    );
    assert_eq!(client.temperature_c().await.unwrap(), 23.4);
}

#[tokio::test]
async fn connection_loss_fails_calls_and_later_calls() {
    let (sim, client) = tcp(with_part().with_time_scale(1000.0)).await;
    let c = client.clone();
    let mover = tokio::spawn(async move { c.home(HomingDirection::Default).await });
    while !client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING)
    {}
    sim.unplug();
    let err = mover.await.unwrap().unwrap_err();
    assert!(matches!(err, Error::ConnectionLost { .. }), "{err}");
    let later = client.width_mm().await.unwrap_err();
    assert!(matches!(later, Error::ConnectionLost { .. }), "{later}");
}

#[tokio::test]
async fn auto_update_stream_one_off_query_and_unsubscribe() {
    // A small buffer (4), so that reading more items than it holds proves new updates arrived.
    let (sim, client, mut widths) = common::wsg_width_subscription(with_part()).await;
    assert_eq!(
        widths.next().await,
        Some(0.0),
        "not referenced yet: width 0 (3.4.4)"
    );
    client.home(HomingDirection::Default).await.unwrap();
    // Updates keep coming; eventually one shows the homed width.
    let mut seen = Vec::new();
    while let Some(w) = widths.next().await {
        seen.push(w);
        if w == 110.0 {
            break;
        }
    }
    assert_eq!(seen.last(), Some(&110.0));
    // A one-off query of the streamed value works and does not end the stream.
    client.pre_position(30.0, 100.0).await.unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 30.0);
    assert_eq!(
        sim.snapshot().streams,
        1,
        "the one-off query left the device's updates on"
    );
    // More values than the buffer holds: at least some were sent after the query.
    for _ in 0..10 {
        assert_eq!(widths.next().await, Some(30.0));
    }
    assert_eq!(sim.snapshot().sessions, 1);
    // Dropping the last subscriber turns the device's updates off.
    drop(widths);
    let mut off = false;
    for _ in 0..10_000 {
        client.width_mm().await.unwrap();
        if sim.snapshot().streams == 0 {
            off = true;
            break;
        }
    }
    assert!(off, "updates still on after the last subscriber went");
}

#[tokio::test]
async fn grip_state_stream_follows_a_grasp() {
    let (_sim, client) = tcp(with_part()).await;
    client.home(HomingDirection::Default).await.unwrap();
    let mut states = client
        .subscribe_grip_state(UpdateOptions::on_change(Duration::from_millis(10)))
        .await
        .unwrap();
    assert_eq!(states.next().await, Some(GripState::Idle));
    client.grasp(40.0, 50.0).await.unwrap();
    // On-change updates: the next value differs from Idle and the stream reaches Holding.
    let mut last = None;
    while let Some(s) = states.next().await {
        assert_ne!(Some(s), last, "on-change stream repeated a value");
        last = Some(s);
        if s == GripState::Holding {
            break;
        }
    }
    assert_eq!(last, Some(GripState::Holding));
    assert!(matches!(
        client
            .subscribe_width_mm(UpdateOptions::periodic(Duration::from_millis(5)))
            .await,
        Err(Error::InvalidArgument { .. })
    ));
}

/// Only when configured to: by default a frame with a bad checksum is discarded (manual 1.2.1;
/// see `SimConfig::answer_bad_checksum` and tests/wsg_sim_field.rs).
#[tokio::test]
async fn the_simulator_answers_a_bad_checksum_with_e_checksum_error() {
    let config = SimConfig {
        answer_bad_checksum: true,
        ..with_part()
    };
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let mut raw = tokio::net::TcpStream::connect(sim.local_addr().unwrap())
        .await
        .unwrap();
    // Homing with a broken checksum (the right one is 8F 83).
    raw.write_all(&[0xAA, 0xAA, 0xAA, 0x20, 0x01, 0x00, 0x00, 0x8F, 0x84])
        .await
        .unwrap();
    let mut got = [0u8; 10];
    raw.read_exact(&mut got).await.unwrap();
    let mut buf = bytes::BytesMut::from(&got[..]);
    let frame = match gripper::wsg::frame::decode(&mut buf, 64) {
        Some(gripper::wsg::frame::Decoded::Frame(f)) => f,
        other => panic!("{other:?}"),
    };
    let reply = gripper::wsg::Reply::from_frame(frame).unwrap();
    assert_eq!((reply.id, reply.status), (0x20, Status::ChecksumError));
    // The unknown-command reply of the manual (1.2.2 Beispiel 2), byte for byte.
    let mut unknown = bytes::BytesMut::new();
    gripper::wsg::frame::encode(&gripper::wsg::Frame::new(0x90, vec![]), &mut unknown).unwrap();
    raw.write_all(&unknown).await.unwrap();
    raw.read_exact(&mut got).await.unwrap();
    assert_eq!(
        got,
        [0xAA, 0xAA, 0xAA, 0x90, 0x02, 0x00, 0x0E, 0x00, 0xFD, 0x02]
    );
}

/// A scripted device on an in-memory pipe: frames nobody asked for are dropped, and the
/// answer to the question asked still arrives.
#[tokio::test]
async fn unsolicited_frames_are_dropped_not_misattributed() {
    let (ours, mut device) = tokio::io::duplex(4096);
    let client = Client::builder().attach(ours);
    let encode = |r: gripper::wsg::Reply| {
        let mut b = bytes::BytesMut::new();
        gripper::wsg::frame::encode(&r.to_frame(), &mut b).unwrap();
        b
    };
    // An auto-update left running by an earlier program, and a stray system-info reply.
    device
        .write_all(&encode(gripper::wsg::Reply::new(
            0x43,
            Status::Success,
            1.5f32.to_le_bytes().to_vec(),
        )))
        .await
        .unwrap();
    device
        .write_all(&encode(gripper::wsg::Reply::new(
            0x50,
            Status::Success,
            vec![2, 0, 0, 0, 1, 0, 0, 0],
        )))
        .await
        .unwrap();
    // Let the client read them before it asks (a round trip on another id orders it).
    let echo = {
        let c = client.clone();
        tokio::spawn(async move { c.loop_back(vec![9u8]).await })
    };
    let mut req = [0u8; 9];
    device.read_exact(&mut req).await.unwrap();
    assert_eq!(req[3], 0x06);
    device
        .write_all(&encode(gripper::wsg::Reply::new(
            0x06,
            Status::Success,
            vec![9],
        )))
        .await
        .unwrap();
    assert_eq!(&echo.await.unwrap().unwrap()[..], &[9]);
    // Now ask for the system info: the stray 0x50 reply above must not be the answer.
    let info = {
        let c = client.clone();
        tokio::spawn(async move { c.system_info().await })
    };
    let mut req = [0u8; 8];
    device.read_exact(&mut req).await.unwrap();
    assert_eq!(req[3], 0x50);
    device
        .write_all(&encode(gripper::wsg::Reply::new(
            0x50,
            Status::Success,
            vec![1, 3, 0x20, 0x41, 0x39, 0x30, 0, 0],
        )))
        .await
        .unwrap();
    let info = info.await.unwrap().unwrap();
    assert_eq!(info.device_type, DeviceType::Wsg50);
    assert_eq!(info.hardware_revision, 3);
    assert_eq!(info.firmware.to_string(), "4.1.2");
    assert_eq!(info.serial_number, 0x3039);
}

#[tokio::test]
async fn finger_interface_overdrive_and_tare() {
    use gripper::wsg::{Finger, FingerFlags, FingerType};
    let mut config = with_part();
    config.force_sensor = true;
    config.fingers[1].finger_type = FingerType::Fmf;
    config.fingers[1].data = vec![1, 2, 3, 4];
    let (_sim, client) = tcp(config).await;
    let one = client.finger_info(Finger::One).await.unwrap();
    assert_eq!((one.finger_type, one.data_size), (FingerType::Generic, 0));
    let two = client.finger_info(Finger::Two).await.unwrap();
    assert_eq!((two.finger_type, two.data_size), (FingerType::Fmf, 4));
    assert_eq!(
        &client.finger_data(Finger::Two).await.unwrap()[..],
        &[1, 2, 3, 4]
    );
    assert_eq!(
        client.finger_data(Finger::One).await.unwrap_err().status(),
        Some(Status::NotAvailable)
    );
    client.set_finger_power(Finger::One, false).await.unwrap();
    assert!(!client
        .finger_flags(Finger::One)
        .await
        .unwrap()
        .contains(FingerFlags::POWER_ON));
    // Power on is asynchronous: E_CMD_PENDING, then E_SUCCESS.
    client.set_finger_power(Finger::One, true).await.unwrap();
    assert!(client
        .finger_flags(Finger::One)
        .await
        .unwrap()
        .contains(FingerFlags::POWER_ON));
    assert!(client
        .finger_flags(Finger::Two)
        .await
        .unwrap()
        .contains(FingerFlags::CONFIG_AVAIL));

    client.set_grasping_force(200.0).await.unwrap();
    assert_eq!(
        client.grasping_force_n().await.unwrap(),
        80.0,
        "nominal limit"
    );
    client.set_overdrive(true).await.unwrap();
    assert!(client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::OVERDRIVE_MODE));
    client.tare_force_sensor().await.unwrap();
    client.home(HomingDirection::Default).await.unwrap();
    client.grasp(40.0, 50.0).await.unwrap();
    assert_eq!(
        client.tare_force_sensor().await.unwrap_err().status(),
        Some(Status::AccessDenied)
    );
}

#[tokio::test]
async fn streams_end_when_the_connection_is_lost() {
    let (sim, client) = tcp(with_part()).await;
    let mut states = client
        .subscribe_system_state(UpdateOptions::on_change(Duration::from_millis(10)))
        .await
        .unwrap();
    assert!(states.next().await.is_some());
    sim.unplug();
    // Updates may still be buffered; the stream then ends.
    while states.next().await.is_some() {}
    assert_eq!(states.missed(), 0);
}

#[tokio::test]
async fn a_lost_part_shows_in_the_grip_state() {
    let (sim, client) = tcp(with_part()).await;
    client.home(HomingDirection::Default).await.unwrap();
    client.grasp(41.0, 50.0).await.unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 40.0);
    sim.lose_part();
    let mut state = client.grip_state().await.unwrap();
    for _ in 0..10_000 {
        if state == GripState::PartLost {
            break;
        }
        state = client.grip_state().await.unwrap();
    }
    assert_eq!(state, GripState::PartLost);
    assert_eq!(
        client.grasping_statistics(false).await.unwrap().lost_part,
        1
    );
}

#[tokio::test]
async fn a_second_motion_during_a_move_is_refused_like_the_device_refuses_it() {
    // Issue 10 item 4 (this test replaces `same_id_motion_calls_queue_behind_the_pending_one`,
    // which pinned the old queuing). Manual 3.2.2: while a motion command runs, another one gets
    // E_ALREADY_RUNNING. The device answers that for a grasp (0x25) during a pre-position; the
    // client must answer the same for a second pre-position (0x21), which it cannot send.
    let (sim, client) = tcp(with_part()).await;
    let first = common::wsg_start_moving(&sim, &client).await;
    let count = |ids: Vec<u8>, which: u8| ids.iter().filter(|i| **i == which).count();
    let same_id = client.pre_position(90.0, 10.0).await.unwrap_err();
    let other_id = client.grasp(40.0, 10.0).await.unwrap_err();
    for err in [&same_id, &other_id] {
        assert_eq!(err.status(), Some(Status::AlreadyRunning), "{err}");
    }
    assert!(
        matches!(
            same_id,
            Error::Device {
                command: id::PRE_POSITION,
                ..
            }
        ),
        "{same_id}"
    );
    assert!(
        matches!(
            other_id,
            Error::Device {
                command: id::GRASP,
                ..
            }
        ),
        "{other_id}"
    );
    assert_eq!(
        count(sim.received_ids(), id::PRE_POSITION),
        1,
        "the refused pre-position was sent"
    );
    assert_eq!(
        count(sim.received_ids(), id::GRASP),
        1,
        "the device refused it"
    );
    client.stop().await.unwrap();
    assert_eq!(
        first.await.unwrap().unwrap_err().status(),
        Some(Status::CmdAborted)
    );
    // Refused means never run later: after the abort nothing moves, and the id is free again.
    client.temperature_c().await.unwrap();
    assert_eq!(count(sim.received_ids(), id::PRE_POSITION), 1);
    assert!(!client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING));
    sim.set_time_scale(0.0);
    client.pre_position(70.0, 100.0).await.unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 70.0);
}

#[tokio::test]
async fn a_second_subscriber_with_other_options_is_refused_not_imposed_on_the_first() {
    // Issue 10 item 5: the device keeps one stream per value (3.4.1); re-configuring it for a
    // second subscriber would change the first one's period behind its back.
    let sim = SimServer::bind("127.0.0.1:0", with_part()).await.unwrap();
    let client = Client::connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    let fast = UpdateOptions::periodic(Duration::from_millis(10));
    let slow = UpdateOptions::periodic(Duration::from_millis(50));
    let mut first = client.subscribe_width_mm(fast).await.unwrap();
    for other in [slow, UpdateOptions::on_change(Duration::from_millis(10))] {
        match client.subscribe_width_mm(other).await {
            Err(Error::SubscriptionConflict { command, active }) => {
                assert_eq!((command, active), (id::WIDTH, fast));
            }
            other => panic!("expected a conflict, got {other:?}"),
        }
    }
    // Only the first subscription's command reached the device: its stream is unchanged.
    let widths = sim
        .received_ids()
        .iter()
        .filter(|i| **i == id::WIDTH)
        .count();
    assert_eq!(widths, 1);
    // The same options join the stream; another value is independent.
    let mut second = client.subscribe_width_mm(fast).await.unwrap();
    let _state = client.subscribe_system_state(slow).await.unwrap();
    assert_eq!(first.next().await, Some(0.0));
    assert_eq!(second.next().await, Some(0.0));
    // Once every subscriber of the value is gone, new options are free to choose.
    drop((first, second));
    let mut again = client.subscribe_width_mm(slow).await.unwrap();
    assert_eq!(again.next().await, Some(0.0));
}
