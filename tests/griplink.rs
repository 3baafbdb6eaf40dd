//! The GRIPLINK client against the simulated controller, over real TCP on loopback.
#![cfg(feature = "sim")]

mod common;

use std::time::Duration;

use futures_util::StreamExt as _;
use gripper::griplink::client::{GripOutcome, ReleaseOutcome, WaitBy};
use gripper::griplink::command::{
    FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled, GripConfig, GripConfigF,
};
use gripper::griplink::sim::{Fault, Role, SimConfig, SimDevice, SimServer};
use gripper::griplink::{Answer, Blocking, Client, ClientConfig, DeviceState, Error, Status};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

/// An ET4: IEG 55-020 with a 12 mm part on port 0, CRG 200-085 without part on port 2,
/// ports 1 and 3 empty; motion takes no time.
async fn sim() -> SimServer {
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .time_scale(0.0);
    SimServer::bind("127.0.0.1:0", config).await.unwrap()
}

#[test]
fn handles_are_clone_send_sync() {
    fn check<T: Clone + Send + Sync + 'static>() {}
    check::<Client>();
    check::<gripper::griplink::Port>();
    check::<Error>();
}

async fn connect(server: &SimServer) -> Client {
    Client::connect(server.local_addr()).await.unwrap()
}

fn device_status<T: std::fmt::Debug>(result: Result<T, Error>) -> Status {
    match result {
        Err(Error::Device { status, .. }) => status,
        other => panic!("expected ERR from the controller, got {other:?}"),
    }
}

/// Waits (bounded) until the simulated device on `port` is in motion.
async fn until_moving(server: &SimServer, port: usize) {
    common::griplink_until(
        server,
        Duration::from_secs(10),
        "the device never started moving",
        |s| s.with_controller(|c, now| c.is_moving(port, now)),
    )
    .await;
}

#[tokio::test]
async fn system_information() {
    let server = sim().await;
    let client = connect(&server).await;
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
    assert_eq!(client.protocol().await.unwrap(), "GRIPLINK-V3");
    client.protocol_assert("GRIPLINK", 2).await.unwrap();
    client.protocol_assert("GRIPLINK", 3).await.unwrap();
    assert_eq!(
        device_status(client.protocol_assert("GRIPLINK", 4).await),
        Status::NotSupported
    );
    assert_eq!(client.serial_number().await.unwrap(), "123456");
    assert_eq!(client.version().await.unwrap(), "4.0.0");
    assert_eq!(client.set_label("Marvin").await.unwrap(), "Marvin");
    assert_eq!(client.label().await.unwrap(), "Marvin");
    assert!(client.set_verbose(true).await.unwrap());
    assert!(!client.set_verbose(false).await.unwrap());
}

/// `Client::from_stream` runs the client over a stream the program connected itself; with a
/// reconnect policy a lost connection is re-opened to the stream's peer address.
#[tokio::test]
async fn from_stream_runs_over_the_given_stream_and_reconnects_to_its_peer() {
    let server = sim().await;
    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let config = ClientConfig {
        reconnect: Some(gripper::reconnect::ReconnectPolicy {
            initial_delay: Duration::from_millis(10),
            max_delay: Duration::from_millis(10),
            factor: 1.0,
            max_attempts: Some(20),
        }),
        ..ClientConfig::default()
    };
    let client = Client::from_stream(stream, config);
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
    // The server closes the connection instead of answering: that call fails, the next runs
    // on a new connection to the same address.
    server.inject(Fault::Close);
    assert!(client.id().await.is_err());
    let again = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            if let Ok(id) = client.id().await {
                return id;
            }
        }
    });
    assert_eq!(again.await.unwrap(), "GRIPLINK-ET4");
    assert!(!client.is_closed());
    client.close().await.unwrap();
}

#[tokio::test]
async fn device_information_on_full_empty_and_missing_ports() {
    let server = sim().await;
    let client = connect(&server).await;
    let ieg = client.port(0);
    assert_eq!(ieg.number(), 0);
    assert_eq!(ieg.vendor_id().await.unwrap(), Some(815));
    assert_eq!(ieg.product_id().await.unwrap(), 20);
    assert_eq!(ieg.name().await.unwrap(), "IEG 55-020");
    assert_eq!(ieg.vendor().await.unwrap(), "WEISS ROBOTICS");
    assert_eq!(ieg.serial_number().await.unwrap(), "000042");
    assert_eq!(ieg.version().await.unwrap(), "1.0.1");
    ieg.assert_device(815, 20).await.unwrap();
    assert_eq!(
        device_status(ieg.assert_device(815, 50).await),
        Status::CmdFailed
    );
    assert_eq!(ieg.set_tag("Device 1").await.unwrap(), "Device 1");
    assert_eq!(ieg.tag().await.unwrap(), "Device 1");
    assert_eq!(client.port(2).product_id().await.unwrap(), 50);

    let empty = client.port(1);
    assert_eq!(empty.vendor_id().await.unwrap(), None);
    assert_eq!(
        device_status(empty.product_id().await),
        Status::NotInitialized
    );
    assert_eq!(
        device_status(empty.assert_device(815, 20).await),
        Status::CmdFailed
    );
    assert_eq!(empty.state().await.unwrap(), DeviceState::NotConnected);

    // An ET4 has ports 0..=3 (manual 2.3).
    let missing = client.port(4);
    assert_eq!(
        device_status(missing.vendor_id().await),
        Status::IndexOutOfBounds
    );
    assert_eq!(
        device_status(missing.home().await),
        Status::IndexOutOfBounds
    );
    assert_eq!(
        device_status(missing.state().await),
        Status::IndexOutOfBounds
    );
}

#[tokio::test]
async fn grip_cycle_with_every_motion_command() {
    let server = sim().await;
    let client = connect(&server).await;
    let g = client.port(0);
    assert_eq!(g.state().await.unwrap(), DeviceState::NotInitialized);
    assert_eq!(
        device_status(g.grip(0, Blocking::Immediate).await),
        Status::NotInitialized
    );
    g.home().await.unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Disabled);
    assert_eq!(g.position_um().await.unwrap(), 20_000);
    assert_eq!(g.position_mm().await.unwrap(), 20.0);

    // ENABLE keeps a gripper in state 2, idle; state 6 is for sensors (manual chapter 5).
    g.enable().await.unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Disabled);
    assert_eq!(device_status(g.clamp(true).await), Status::StateConflict);
    g.disable().await.unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Disabled);
    g.clamp(true).await.unwrap();
    g.clamp(false).await.unwrap();
    g.led(2).await.unwrap();

    // Recipes, integer and float.
    let recipe = GripConfig {
        tag: "tube".into(),
        params: [3500, 18000, 50000, 0, 0, 0, 0, 0],
    };
    assert_eq!(g.set_grip_config(0, &recipe).await.unwrap(), recipe);
    assert_eq!(g.grip_config(0).await.unwrap(), recipe);
    assert_eq!(
        g.grip_config_f(0).await.unwrap(),
        GripConfigF::gripper("tube", 3.5, 18.0, 50.0)
    );
    let other = GripConfigF::gripper("ring", 1.25, 19.5, 80.0);
    assert_eq!(g.set_grip_config_f(1, &other).await.unwrap(), other);
    assert_eq!(g.grip_config(1).await.unwrap().params[0], 1250);
    assert_eq!(
        device_status(g.grip_config(99).await),
        Status::IndexOutOfBounds
    );
    let too_far = GripConfig {
        params: [3500, 99_000, 50000, 0, 0, 0, 0, 0],
        ..recipe.clone()
    };
    assert_eq!(
        device_status(g.set_grip_config(0, &too_far).await),
        Status::RangeError
    );

    // GRIP blocking: the part is 12 mm wide.
    g.grip(0, Blocking::UntilDone).await.unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Holding);
    assert_eq!(g.position_um().await.unwrap(), 12_000);
    assert_eq!(
        device_status(g.grip(0, Blocking::Immediate).await),
        Status::StateConflict
    );
    g.release(0, Blocking::Immediate).await.unwrap();
    assert_eq!(
        g.wait_for_transition().await.unwrap(),
        DeviceState::Released
    );
    assert_eq!(g.position_mm().await.unwrap(), 18.0);
    g.release(0, Blocking::UntilDone).await.unwrap();

    // FLEX commands, float and scaled.
    let flex = FlexGrip {
        position_mm: 2.5,
        force_n: 60.0,
        speed_mm_per_s: 45.5,
        acceleration_mm_per_s2: 0.0,
    };
    g.flex_grip(flex, Blocking::UntilDone).await.unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Holding);
    let rel = FlexRelease {
        position_mm: 19.5,
        ..Default::default()
    };
    g.flex_release(rel, Blocking::UntilDone).await.unwrap();
    assert_eq!(g.position_um().await.unwrap(), 19_500);
    server.set_part(0, None);
    let scaled = FlexGripScaled {
        position_um: 5000,
        force_mn: 100_000,
        speed_um_per_s: 20_000,
        acceleration_um_per_s2: 0,
    };
    g.flex_grip_scaled(scaled, Blocking::Immediate)
        .await
        .unwrap();
    assert_eq!(g.wait_for_transition().await.unwrap(), DeviceState::NoPart);
    assert_eq!(g.position_um().await.unwrap(), 5000);
    let rel = FlexReleaseScaled {
        position_um: 15_000,
        ..Default::default()
    };
    g.flex_release_scaled(rel, Blocking::Immediate)
        .await
        .unwrap();
    assert_eq!(g.state().await.unwrap(), DeviceState::Released);
    let beyond = FlexReleaseScaled {
        position_um: 99_000,
        ..rel
    };
    assert_eq!(
        device_status(g.flex_release_scaled(beyond, Blocking::Immediate).await),
        Status::RangeError
    );

    // SETVAL pre-positions, WAITVAL waits for the window (or times out on the controller).
    g.set_value(0, 8000).await.unwrap();
    g.wait_value(0, 8000, 100, Duration::from_millis(500))
        .await
        .unwrap();
    g.set_value_f(0, 9.5).await.unwrap();
    g.wait_value_f(0, 9.5, 0.1, Duration::from_millis(500))
        .await
        .unwrap();
    assert_eq!(g.value(0).await.unwrap(), 9500);
    assert_eq!(g.value_f(0).await.unwrap(), 9.5);
    assert_eq!(
        device_status(g.wait_value(0, 1000, 100, Duration::from_millis(500)).await),
        Status::Timeout
    );
    assert_eq!(
        device_status(g.wait_value_f(0, 1.0, 0.1, Duration::ZERO).await),
        Status::Timeout
    );
    assert_eq!(device_status(g.value(7).await), Status::IndexOutOfBounds);
}

#[tokio::test]
async fn grip_and_release_helpers_report_outcomes() {
    let server = sim().await;
    let client = connect(&server).await;
    let g = client.port(0);
    g.home().await.unwrap();
    g.set_grip_config_f(0, &GripConfigF::gripper("p", 5.0, 18.0, 50.0))
        .await
        .unwrap();

    assert_eq!(
        g.grip_and_wait(0, WaitBy::Transition).await.unwrap(),
        GripOutcome::Holding
    );
    assert_eq!(
        g.release_and_wait(0, WaitBy::Polling(Duration::from_millis(1)))
            .await
            .unwrap(),
        ReleaseOutcome::Released
    );
    server.set_part(0, None);
    assert_eq!(
        g.grip_and_wait(0, WaitBy::Polling(Duration::from_millis(1)))
            .await
            .unwrap(),
        GripOutcome::NoPart
    );
    g.release_and_wait(0, WaitBy::Transition).await.unwrap();
    server.fault_next_motion(0);
    assert_eq!(
        g.grip_and_wait(0, WaitBy::Transition).await.unwrap(),
        GripOutcome::Fault
    );
    assert_eq!(server.device_state(0), Some(DeviceState::Fault));
    // In DS_FAULT a grip re-enables the gripper (manual 3.4.1); so does HOME.
    assert_eq!(
        g.grip_and_wait(0, WaitBy::Polling(Duration::from_millis(1)))
            .await
            .unwrap(),
        GripOutcome::NoPart
    );
    g.home().await.unwrap();
    server.fault_next_motion(0);
    assert_eq!(
        g.release_and_wait(0, WaitBy::Transition).await.unwrap(),
        ReleaseOutcome::Fault
    );
    // A blocking motion that ends in a fault is refused.
    g.home().await.unwrap();
    server.fault_next_motion(0);
    assert_eq!(
        device_status(g.grip(0, Blocking::UntilDone).await),
        Status::CmdFailed
    );
}

#[tokio::test]
async fn wait_helper_times_out_when_the_motion_never_ends() {
    let server = sim().await;
    let client = connect(&server).await;
    let g = client.port(0);
    g.home().await.unwrap();
    server.with_controller(|c, _| c.set_time_scale(1e9));
    let r = g
        .with_timeout(Duration::from_millis(30))
        .grip_and_wait(0, WaitBy::Polling(Duration::from_millis(5)))
        .await;
    assert!(matches!(r, Err(Error::Timeout { .. })), "{r:?}");
}

#[tokio::test]
async fn watch_state_and_value_streams() {
    let server = sim().await;
    let client = connect(&server).await;
    let g = client.port(0);
    g.home().await.unwrap();
    let states: Vec<_> = g
        .watch_state(Duration::from_millis(1))
        .take(3)
        .collect()
        .await;
    assert_eq!(states.len(), 3);
    for s in states {
        assert_eq!(s.unwrap(), DeviceState::Disabled);
    }
    let mut values = g.watch_value(0, Duration::from_millis(1));
    assert_eq!(values.next().await.unwrap().unwrap(), 20.0);
    drop(values);
    // The stream ends (with the reason) when the connection goes away.
    let mut states = g.watch_state(Duration::from_millis(1));
    assert!(states.next().await.unwrap().is_ok());
    server.inject(Fault::Close);
    let mut last = None;
    while let Some(item) = states.next().await {
        last = Some(item);
    }
    assert!(
        matches!(last, Some(Err(Error::ConnectionLost { .. }))),
        "{last:?}"
    );
}

#[tokio::test]
async fn errors_with_and_without_verbose_text() {
    let server = sim().await;
    let client = connect(&server).await;
    match client.port(0).grip(0, Blocking::Immediate).await {
        Err(Error::Device {
            status: Status::NotInitialized,
            text: None,
            command,
        }) => assert_eq!(command, "GRIP(0,0)"),
        other => panic!("{other:?}"),
    }
    client.set_verbose(true).await.unwrap();
    let err = client
        .port(0)
        .grip(0, Blocking::Immediate)
        .await
        .unwrap_err();
    assert_eq!(err.status(), Some(Status::NotInitialized));
    match &err {
        Error::Device { text, .. } => {
            assert_eq!(text.as_deref(), Some("Device not initialized"))
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        err.to_string(),
        "GRIP(0,0) refused: ERR 04 E_NOT_INITIALIZED: Device not initialized"
    );
    server.inject(Fault::RawReply(
        b"ERR 04 The device is not initialized\n".to_vec(),
    ));
    assert_eq!(
        client.id().await.unwrap_err().to_string(),
        "ID? refused: ERR 04 E_NOT_INITIALIZED: Device not initialized \
         (controller: The device is not initialized)"
    );
    // Unknown codes are kept.
    server.inject(Fault::Error(Status::Unknown(42)));
    let err = client.id().await.unwrap_err();
    assert_eq!(err.status(), Some(Status::Unknown(42)));
    assert_eq!(
        err.to_string(),
        "ID? refused: ERR 42: unknown status code 42"
    );
}

#[tokio::test]
async fn raw_commands() {
    let server = sim().await;
    let client = connect(&server).await;
    match client.command("devstate[0]?").await.unwrap() {
        Answer::Data(d) => {
            assert_eq!(d.key, "DEVSTATE");
            assert_eq!(d.indices, vec![0]);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(client.command("LED(0,1)").await.unwrap(), Answer::Ack);
    assert_eq!(
        device_status(client.command("FOO(1)").await),
        Status::CmdUnknown
    );
    assert_eq!(
        device_status(client.command("GRIP(0").await),
        Status::CmdSyntax
    );
    for bad in ["ID?\nBYE()", "ID?\r", "", "ID?\u{7}", "ÏD?"] {
        assert!(
            matches!(
                client.command(bad).await,
                Err(Error::InvalidArgument { .. })
            ),
            "{bad:?}"
        );
    }
    // The connection is still in step.
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn injection_attempts_are_refused_before_sending() {
    let server = sim().await;
    let client = connect(&server).await;
    client.port(0).home().await.unwrap();
    let attacks = [
        "x\"\nDISABLE(0)\nLABEL=\"y",
        "x'\nDISABLE(0)",
        "x\rDISABLE(0)",
        "back\\slash",
        "quote\"",
        "tab\there",
        "ünïcode",
        "this label is longer than thirty-two characters",
    ];
    for attack in attacks {
        assert!(
            matches!(
                client.set_label(attack).await,
                Err(Error::InvalidArgument { .. })
            ),
            "{attack:?}"
        );
        assert!(
            matches!(
                client.port(0).set_tag(attack).await,
                Err(Error::InvalidArgument { .. })
            ),
            "{attack:?}"
        );
        let recipe = GripConfigF::gripper(attack, 5.0, 18.0, 50.0);
        assert!(matches!(
            client.port(0).set_grip_config_f(0, &recipe).await,
            Err(Error::InvalidArgument { .. })
        ));
        assert!(matches!(
            client.protocol_assert(attack, 2).await,
            Err(Error::InvalidArgument { .. })
        ));
    }
    // Nothing reached the controller: label, tag and state are untouched.
    assert_eq!(client.label().await.unwrap(), "GRIPLINK");
    assert_eq!(client.port(0).tag().await.unwrap(), "");
    assert_eq!(client.port(0).state().await.unwrap(), DeviceState::Disabled);
    // The longest allowed label still goes through.
    let max = "x".repeat(32);
    assert_eq!(client.set_label(&max).await.unwrap(), max);
}

#[tokio::test]
async fn float_arguments_are_plain_decimals_or_refused() {
    let server = sim().await;
    let client = connect(&server).await;
    let g = client.port(0);
    g.home().await.unwrap();
    // 1e-7 mm goes out as 0.0000001 (the simulator refuses scientific notation with ERR 22, so
    // the ACK proves the format); it rounds to 0 µm.
    g.set_value_f(0, 1e-7).await.unwrap();
    assert_eq!(g.position_um().await.unwrap(), 0);
    // 3.4e38 goes out as 39 digits: refused by the range check, not as a syntax error.
    assert_eq!(
        device_status(g.set_value_f(0, 3.4e38).await),
        Status::RangeError
    );
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e39] {
        assert!(matches!(
            g.set_value_f(0, bad).await,
            Err(Error::InvalidArgument { .. })
        ));
        let flex = FlexGrip {
            force_n: bad,
            ..Default::default()
        };
        assert!(matches!(
            g.flex_grip(flex, Blocking::Immediate).await,
            Err(Error::InvalidArgument { .. })
        ));
    }
    assert_eq!(g.position_um().await.unwrap(), 0);
}

#[tokio::test]
async fn timed_out_call_does_not_shift_the_pairing() {
    for depth in [1, 4] {
        let server = sim().await;
        let config = ClientConfig {
            pipeline_depth: depth,
            ..ClientConfig::default()
        };
        let client = Client::connect_with(server.local_addr(), config)
            .await
            .unwrap();
        let gate = server.hold_next_reply();
        let timed_out = client.with_timeout(Duration::from_millis(20)).id().await;
        assert!(
            matches!(timed_out, Err(Error::Timeout { .. })),
            "{timed_out:?}"
        );
        // The next caller waits behind the held ID reply, which is discarded when released.
        let next = tokio::spawn({
            let client = client.clone();
            async move { client.serial_number().await }
        });
        gate.release();
        assert_eq!(next.await.unwrap().unwrap(), "123456");
        assert_eq!(client.version().await.unwrap(), "4.0.0");
    }
}

#[tokio::test]
async fn dropped_call_does_not_shift_the_pairing() {
    let server = sim().await;
    let client = connect(&server).await;
    let gate = server.hold_next_reply();
    let call = tokio::spawn({
        let client = client.clone();
        async move { client.id().await }
    });
    for _ in 0..10 {
        tokio::task::yield_now().await;
    }
    call.abort();
    assert!(call.await.unwrap_err().is_cancelled());
    // Sent or not, the dropped call's reply never reaches another caller.
    gate.release();
    assert_eq!(client.serial_number().await.unwrap(), "123456");
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn queued_command_of_a_caller_that_gave_up_is_never_sent() {
    let server = sim().await;
    let a = connect(&server).await;
    let b = connect(&server).await;
    a.port(0).home().await.unwrap();
    server.with_controller(|c, _| c.set_time_scale(1e9));
    // A blocking GRIP holds A's connection (it never ends by itself)...
    let grip = tokio::spawn({
        let a = a.clone();
        async move {
            a.port(0)
                .with_timeout(Duration::from_secs(600))
                .grip(0, Blocking::UntilDone)
                .await
        }
    });
    until_moving(&server, 0).await;
    // ...so a RELEASE queues behind it (depth 1), and its caller gives up before it is sent.
    let release = a
        .port(0)
        .with_timeout(Duration::from_millis(20))
        .release(0, Blocking::Immediate)
        .await;
    assert!(matches!(release, Err(Error::Timeout { .. })), "{release:?}");
    b.port(0).disable().await.unwrap();
    assert_eq!(device_status(grip.await.unwrap()), Status::CmdAborted);
    // Anything still queued on A would have run before this reply: the RELEASE never did.
    assert_eq!(a.id().await.unwrap(), "GRIPLINK-ET4");
    assert!(!server.with_controller(|c, now| c.is_moving(0, now)));
    assert_eq!(b.port(0).state().await.unwrap(), DeviceState::Disabled);
}

#[tokio::test]
async fn delayed_reply_after_timeout_is_discarded() {
    let server = sim().await;
    let client = connect(&server).await;
    // The reply is held until the caller has given up, then comes: no wall-clock margin, so a
    // loaded machine cannot see the reply before the timeout.
    let gate = server.hold_next_reply();
    let r = client
        .port(0)
        .with_timeout(Duration::from_millis(10))
        .state()
        .await;
    assert!(matches!(r, Err(Error::Timeout { .. })));
    gate.release();
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn many_concurrent_callers_each_get_their_own_reply() {
    let server = sim().await;
    for depth in [1, 8] {
        let config = ClientConfig {
            pipeline_depth: depth,
            ..ClientConfig::default()
        };
        let client = Client::connect_with(server.local_addr(), config)
            .await
            .unwrap();
        let mut tasks = Vec::new();
        for i in 0..64u32 {
            let client = client.clone();
            tasks.push(tokio::spawn(async move {
                match i % 4 {
                    0 => assert_eq!(client.port(0).product_id().await.unwrap(), 20),
                    1 => assert_eq!(client.port(2).product_id().await.unwrap(), 50),
                    2 => assert_eq!(client.port(2).name().await.unwrap(), "CRG 200-085"),
                    _ => assert_eq!(client.port(1).vendor_id().await.unwrap(), None),
                }
            }));
        }
        for t in tasks {
            t.await.unwrap();
        }
    }
}

#[tokio::test]
async fn reply_for_another_key_port_or_garbage_is_an_error() {
    let server = sim().await;
    let client = connect(&server).await;
    server.inject(Fault::RawReply(b"DEVVID[0]=-2\n".to_vec()));
    assert!(matches!(
        client.port(0).vendor_id().await,
        Err(Error::UnexpectedReply { .. })
    ));
    server.inject(Fault::RawReply(b"DEVSTATE[1]=3\n".to_vec()));
    assert!(matches!(
        client.port(0).state().await,
        Err(Error::UnexpectedReply { .. })
    ));
    server.inject(Fault::RawReply(b"ACK\n".to_vec()));
    assert!(matches!(
        client.id().await,
        Err(Error::UnexpectedReply { .. })
    ));
    server.inject(Fault::RawReply(b"DEVSTATE[0]=\"x\"\n".to_vec()));
    assert!(matches!(
        client.port(0).state().await,
        Err(Error::UnexpectedReply { .. })
    ));
    server.inject(Fault::RawReply(b"VALUE[0][0]=1e3\n".to_vec()));
    assert!(matches!(
        client.port(0).value(0).await,
        Err(Error::MalformedReply { .. })
    ));
    // Errata: VALUE[..]= answering VALUEF is accepted.
    server.inject(Fault::RawReply(b"VALUE[0][0]=42.456\n".to_vec()));
    assert_eq!(client.port(0).value_f(0).await.unwrap(), 42.456);
    server.inject(Fault::RawReply(b"VALUEF[0][0]=+INF\n".to_vec()));
    assert_eq!(client.port(0).value_f(0).await.unwrap(), f64::INFINITY);
    server.inject(Fault::RawReply(b"VALUE[0][0]=-2147483648\n".to_vec()));
    assert_eq!(client.port(0).value(0).await.unwrap(), i32::MIN);
    // Two-digit and plain codes.
    server.inject(Fault::RawReply(b"ERR 4\n".to_vec()));
    assert_eq!(device_status(client.id().await), Status::NotInitialized);
    // Over-long and non-ASCII lines are discarded by the codec but still answer their command.
    let mut long = vec![b'X'; 5000];
    long.push(b'\n');
    server.inject(Fault::RawReply(long));
    assert!(matches!(
        client.id().await,
        Err(Error::MalformedReply { .. })
    ));
    server.inject(Fault::RawReply("ID=\"GRIPLINK-ÉT4\"\n".as_bytes().to_vec()));
    assert!(matches!(
        client.id().await,
        Err(Error::MalformedReply { .. })
    ));
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

#[tokio::test]
async fn reply_that_never_comes_breaks_the_connection() {
    let server = sim().await;
    let config = ClientConfig {
        give_up_after: Duration::from_millis(50),
        ..ClientConfig::default()
    };
    let client = Client::connect_with(server.local_addr(), config)
        .await
        .unwrap();
    server.inject(Fault::DropReply);
    let r = client.with_timeout(Duration::from_millis(10)).id().await;
    assert!(matches!(r, Err(Error::Timeout { .. })), "{r:?}");
    // Waits behind the lost reply until the client gives up on the connection.
    assert!(matches!(
        client.serial_number().await,
        Err(Error::ConnectionLost { .. })
    ));
    assert!(matches!(
        client.id().await,
        Err(Error::ConnectionLost { .. })
    ));
}

#[tokio::test]
async fn close_sends_bye_and_later_calls_fail() {
    let server = sim().await;
    let client = connect(&server).await;
    let other = client.clone();
    client.close().await.unwrap();
    assert!(matches!(other.id().await, Err(Error::Closed)));
    assert!(matches!(client.close().await, Err(Error::Closed)));
}

#[tokio::test]
async fn controller_closing_fails_pending_and_later_calls() {
    let server = sim().await;
    let client = connect(&server).await;
    server.inject(Fault::Close);
    assert!(matches!(
        client.id().await,
        Err(Error::ConnectionLost { .. })
    ));
    assert!(matches!(
        client.id().await,
        Err(Error::ConnectionLost { .. })
    ));
    // A new connection works.
    assert_eq!(connect(&server).await.id().await.unwrap(), "GRIPLINK-ET4");
}

/// A caller told the connection is lost (no reconnect) finds the client closed at once: the
/// queue is closed before anyone hears why. On two workers the caller resumes on another
/// thread than the connection task, which used to lose this race now and then.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_connection_is_closed_when_its_callers_hear_of_it() {
    let server = sim().await;
    for round in 0..50 {
        let client = connect(&server).await;
        assert!(!client.is_closed());
        server.inject(Fault::Close);
        assert!(matches!(
            client.id().await,
            Err(Error::ConnectionLost { .. })
        ));
        assert!(
            client.is_closed(),
            "round {round}: not closed after ConnectionLost"
        );
    }
}

#[tokio::test]
async fn blocking_commands_hold_only_their_own_connection() {
    let server = sim().await;
    let a = connect(&server).await;
    let b = connect(&server).await;
    a.port(0).home().await.unwrap();
    // From now on motion never ends by itself: the test decides when it ends.
    server.with_controller(|c, _| c.set_time_scale(1e9));
    let slow = Duration::from_secs(600);

    let grip = tokio::spawn({
        let a = a.clone();
        async move {
            a.port(0)
                .with_timeout(slow)
                .grip(0, Blocking::UntilDone)
                .await
        }
    });
    until_moving(&server, 0).await;
    // B is answered while A's blocking GRIP holds A's connection.
    assert_eq!(b.port(0).state().await.unwrap(), DeviceState::Disabled);
    assert!(!grip.is_finished());
    // DISABLE from B aborts A's motion: A's GRIP reports the abort.
    b.port(0).disable().await.unwrap();
    assert_eq!(device_status(grip.await.unwrap()), Status::CmdAborted);

    // WSTR on A waits for the end of B's grip, which a fault ends.
    b.port(0).grip(0, Blocking::Immediate).await.unwrap();
    let wstr = tokio::spawn({
        let a = a.clone();
        async move { a.port(0).with_timeout(slow).wait_for_transition().await }
    });
    assert_eq!(b.id().await.unwrap(), "GRIPLINK-ET4");
    assert!(!wstr.is_finished());
    server.inject_device_fault(0);
    assert_eq!(wstr.await.unwrap().unwrap(), DeviceState::Fault);
}

async fn raw_exchange(server: &SimServer, lines: &[&str]) -> Vec<String> {
    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read).lines();
    let mut replies = Vec::new();
    for line in lines {
        write.write_all(line.as_bytes()).await.unwrap();
        replies.push(reader.next_line().await.unwrap().unwrap_or_default());
    }
    replies
}

#[tokio::test]
async fn simulator_speaks_the_manuals_syntax() {
    let server = sim().await;
    let long = format!("LABEL=\"{}\"\n", "x".repeat(2000));
    let replies = raw_exchange(
        &server,
        &[
            "id?\r\n",
            "  gRiP(0,1)\r\n",
            "FOO()\n",
            "GRIP(0\n",
            "DEVSTATE[9]?\n",
            "VERBOSE=1\n",
            "GRIP(0,0)\n",
            "\n\nDEVVID[1]?\n",
            "LABEL='Hello World'\n",
            "SETVAL(0, 0, 4230)\n",
            &long,
            "VALUEF[0][0]?\n",
        ],
    )
    .await;
    assert_eq!(
        replies,
        [
            "ID=\"GRIPLINK-ET4\"",
            "ERR 04",
            "ERR 23",
            "ERR 22",
            "ERR 11",
            "VERBOSE=1",
            "ERR 04 Device not initialized",
            "DEVVID[1]=-1",
            "LABEL=\"Hello World\"",
            "ERR 04 Device not initialized",
            "ERR 01 Data overrun",
            "VALUEF[0][0]=0",
        ]
    );
}

#[tokio::test]
async fn simulator_closes_after_bye() {
    let server = sim().await;
    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read).lines();
    write.write_all(b"BYE()\n").await.unwrap();
    assert_eq!(reader.next_line().await.unwrap().as_deref(), Some("ACK"));
    assert_eq!(reader.next_line().await.unwrap(), None);
}

#[tokio::test]
async fn simulator_roles_wpg_and_master() {
    let server = SimServer::bind("127.0.0.1:0", SimConfig::wpg().time_scale(0.0))
        .await
        .unwrap();
    let client = connect(&server).await;
    assert_eq!(client.id().await.unwrap(), "WPG 100-090");
    assert_eq!(client.port(0).product_id().await.unwrap(), 6050);
    assert_eq!(
        device_status(client.port(1).vendor_id().await),
        Status::IndexOutOfBounds
    );
    let master = SimConfig {
        role: Role::Master,
        ..SimConfig::et4().time_scale(0.0)
    }
    .device(4, Some(SimDevice::wpg_300_120()));
    let server = SimServer::bind("127.0.0.1:0", master).await.unwrap();
    let client = connect(&server).await;
    assert_eq!(client.port(4).product_id().await.unwrap(), 6060);
    assert_eq!(client.port(31).vendor_id().await.unwrap(), None);
    assert!(matches!(
        client.port(32).vendor_id().await,
        Err(Error::InvalidArgument { .. })
    ));
}

#[tokio::test]
async fn server_shutdown_closes_connections() {
    let server = sim().await;
    let client = connect(&server).await;
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
    drop(server);
    assert!(matches!(
        client.id().await,
        Err(Error::ConnectionLost { .. })
    ));
}

#[tokio::test]
async fn simulator_reads_split_and_oversized_lines_over_tcp() {
    let server = sim().await;
    let stream = TcpStream::connect(server.local_addr()).await.unwrap();
    stream.set_nodelay(true).unwrap();
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read).lines();
    // One command, one byte per write.
    for b in b"DEVSTATE[0]?\r\n" {
        write.write_all(&[*b]).await.unwrap();
    }
    assert_eq!(
        reader.next_line().await.unwrap().as_deref(),
        Some("DEVSTATE[0]=1")
    );
    // An over-long line in many chunks without LF, then its end and a good command.
    for _ in 0..64 {
        write.write_all(&[b'X'; 500]).await.unwrap();
    }
    write.write_all(b"\nID?\n").await.unwrap();
    assert_eq!(reader.next_line().await.unwrap().as_deref(), Some("ERR 01"));
    assert_eq!(
        reader.next_line().await.unwrap().as_deref(),
        Some("ID=\"GRIPLINK-ET4\"")
    );
    // Non-ASCII is a syntax error; the next command is still understood.
    write.write_all("ÏD?\nSN?\n".as_bytes()).await.unwrap();
    assert_eq!(reader.next_line().await.unwrap().as_deref(), Some("ERR 22"));
    assert_eq!(
        reader.next_line().await.unwrap().as_deref(),
        Some("SN=\"123456\"")
    );
}

/// Strings from third-party IO-Link devices may hold `'` and `\`: accepted up to the closing
/// quote (PROTOCOLS.md errata for seed 004). What this side sends stays strict.
#[tokio::test]
async fn device_strings_with_quotes_and_backslashes_are_read() {
    let device = SimDevice {
        name: "O'Brien \\ Gripper".into(),
        vendor: "ACME 'Robots'".into(),
        serial_number: "SN\\42".into(),
        ..SimDevice::ieg_55_020()
    };
    let config = SimConfig::et4().device(1, Some(device)).time_scale(0.0);
    let server = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let client = connect(&server).await;
    let p = client.port(1);
    assert_eq!(p.name().await.unwrap(), "O'Brien \\ Gripper");
    assert_eq!(p.vendor().await.unwrap(), "ACME 'Robots'");
    assert_eq!(p.serial_number().await.unwrap(), "SN\\42");
    assert!(matches!(
        p.set_tag("O'Brien").await,
        Err(Error::InvalidArgument { .. })
    ));
}

/// Refused before anything is sent: a raw line of only spaces (the controller would trim it to
/// nothing and never answer) and a float whose plain decimal form would need hundreds of digits.
#[tokio::test]
async fn blank_lines_and_endless_floats_are_refused_before_sending() {
    let server = sim().await;
    let client = connect(&server).await;
    for blank in ["", " ", "    "] {
        assert!(
            matches!(
                client.command(blank).await,
                Err(Error::InvalidArgument { .. })
            ),
            "{blank:?}"
        );
    }
    let g = client.port(0);
    let e = g.set_value_f(0, 1e-300).await.unwrap_err();
    assert!(
        matches!(&e, Error::InvalidArgument { reason, .. } if reason.contains("plain")),
        "{e:?}"
    );
    let tiny = GripConfigF::gripper("t", 1e-200, 18.0, 50.0);
    assert!(matches!(
        g.set_grip_config_f(0, &tiny).await,
        Err(Error::InvalidArgument { .. })
    ));
    // The connection is untouched: nothing was sent.
    assert_eq!(client.id().await.unwrap(), "GRIPLINK-ET4");
}

/// Issue 29 O: `queue_len` `usize::MAX` (unbounded in practice) is taken as tokio's largest
/// channel, not a panic in its semaphore.
#[tokio::test]
async fn queue_len_usize_max_serves_calls() {
    let server = sim().await;
    let config = ClientConfig {
        queue_len: usize::MAX,
        ..ClientConfig::default()
    };
    let client = Client::connect_with(server.local_addr(), config)
        .await
        .unwrap();
    client.protocol().await.unwrap();
}

/// A VALUEF reply lost, a VALUE query behind it: the VALUE reply (`VALUE[0][0]=…`, an integer in
/// µm) is next in line for VALUEF. The manual's errata lets the `VALUE` key answer VALUEF, but
/// only with a fraction: an integer is refused, never read as millimetres a thousand times too
/// large (griplink-tcp:0x4aa17c929219b038, found by the explorer's long run).
#[tokio::test]
async fn an_integer_value_reply_never_answers_valuef_behind_a_lost_reply() {
    let server = sim().await;
    let config = ClientConfig {
        pipeline_depth: 2,
        ..ClientConfig::default()
    };
    let client = Client::connect_with(server.local_addr(), config)
        .await
        .unwrap();
    let port = client.port(0);
    let integer = port.value(0).await.unwrap();
    // The next reply the controller sends (VALUEF's) is lost; VALUE's follows it.
    server.inject(Fault::DropReply);
    let (float, _) = tokio::join!(port.value_f(0), port.value(0));
    assert!(
        matches!(float, Err(Error::UnexpectedReply { .. })),
        "VALUEF answered by VALUE's reply ({integer} µm): {float:?}"
    );
}
