//! The WSG node in process against the crate's WSG simulator, through ros2-client's own action
//! and service clients, each test on a ROS domain of its own.

mod common;

use common::*;
use gripper::wsg::sim::{SimConfig, SimServer};
use gripper_ros2::params::{DeviceKind, Mapping};
use ros2_client::action::GoalStatusEnum;
use ros2_client::action_msgs::CancelGoalResponseEnum;
use ros2_client::builtin_interfaces::Time;
use ros2_client::ServiceMapping;

async fn sim(config: SimConfig) -> (SimServer, String) {
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let addr = sim.local_addr().unwrap().to_string();
    (sim, addr)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn goals_results_and_a_late_result_request_with_the_enhanced_mapping() {
    // Instant motion: the moves cost no wall time.
    let (wsg, addr) = sim(SimConfig::default().with_part(40.0, 2.0)).await;
    let (node, _me, gripper) =
        homed_gripper(params(DeviceKind::Wsg, addr, domain(), Mapping::Enhanced)).await;

    let (id, status, result) = run_goal(&gripper, 0.04, 30.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded);
    assert!(result.stalled && result.reached_goal, "{result:?}");
    assert_eq!((result.position, result.effort), (0.04, 30.0));

    // Asked again long after the goal ended: answered from the kept results (ros2-client's
    // AsyncActionServer never answers this one).
    let (status, again) = bounded("late get_result", gripper.async_request_result(id))
        .await
        .unwrap();
    assert_eq!((status, again), (GoalStatusEnum::Succeeded, result));

    // Open (a release, the part is held), then close where no part is: the grasp finds none
    // (E_CMD_FAILED) and the goal is ABORTED, its result answered all the same (ros2-client's
    // abort_*_goal never answers a pending get_result).
    let (_, status, result) = run_goal(&gripper, 0.07, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded);
    assert!(result.reached_goal && !result.stalled, "{result:?}");
    let (_, status, result) = run_goal(&gripper, 0.02, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Aborted, "{result:?}");
    assert!(!result.stalled && !result.reached_goal, "{result:?}");

    // A goal id never sent: STATUS_UNKNOWN, as rclcpp_action answers.
    let (status, _) = bounded(
        "get_result of an unknown goal",
        gripper.async_request_result(ros2_client::action::GoalId::new_random()),
    )
    .await
    .unwrap();
    assert_eq!(status, GoalStatusEnum::Unknown);

    // Beyond the stroke, a negative effort, NaN: rejected, never sent to the gripper.
    for bad in [goal(0.5, 0.0), goal(0.05, -1.0), goal(f64::NAN, 0.0)] {
        let (_, response) = bounded("send_goal", gripper.async_send_goal(bad))
            .await
            .unwrap();
        assert!(!response.accepted, "{bad:?} was accepted");
    }
    // A cancel of a goal that has ended.
    let response = bounded("cancel", gripper.async_cancel_goal(id, Time::ZERO))
        .await
        .unwrap();
    assert_eq!(response.return_code, CancelGoalResponseEnum::GoalTerminated);
    node.stop().await.unwrap();
    // A clean shutdown announces the disconnect (0x07), so the WSG does not go into FAST STOP.
    assert_eq!(wsg.received_ids().last(), Some(&0x07));
    assert!(!wsg
        .snapshot()
        .system_state
        .contains(gripper::wsg::SystemState::FAST_STOP));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_stops_the_fingers_and_a_second_goal_is_rejected_meanwhile() {
    let (sim, addr) = sim(SimConfig::default()).await;
    let mut p = params(DeviceKind::Wsg, addr, domain(), Mapping::Cyclone);
    p.speed_m_per_s = 0.01;
    let (node, _me, gripper) = homed_gripper(p).await;
    // Real time from here: a 100 mm move at 10 mm/s takes 10 s, so the cancel finds it running.
    sim.set_time_scale(1.0);
    let (id, accepted) = bounded("send_goal", gripper.async_send_goal(goal(0.005, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted);
    let (_, second) = bounded("second goal", gripper.async_send_goal(goal(0.05, 0.0)))
        .await
        .unwrap();
    assert!(
        !second.accepted,
        "a goal while another runs must be rejected"
    );

    let response = bounded("cancel", gripper.async_cancel_goal(id, Time::ZERO))
        .await
        .unwrap();
    assert_eq!(response.return_code, CancelGoalResponseEnum::None);
    assert_eq!(response.goals_canceling.len(), 1);
    let (status, result) = bounded("get_result", gripper.async_request_result(id))
        .await
        .unwrap();
    assert_eq!(status, GoalStatusEnum::Canceled);
    assert!(
        result.position > 0.006 && !result.reached_goal,
        "{result:?}"
    );
    // The stop (0x22) reached the gripper.
    assert!(sim.received_ids().contains(&0x22));
    assert!(sim
        .snapshot()
        .system_state
        .contains(gripper::wsg::SystemState::AXIS_STOPPED));
    node.stop().await.unwrap();
}

/// The latest diagnostics of the node until `check` holds (bounded).
async fn diagnostics_until(
    sub: &ros2_client::Subscription<gripper_ros2::msgs::DiagnosticArray>,
    what: &str,
    check: impl Fn(&std::collections::HashMap<String, String>) -> bool,
) -> std::collections::HashMap<String, String> {
    bounded(what, async {
        loop {
            let (msg, _) = sub.async_take().await.expect("diagnostics");
            let values: std::collections::HashMap<String, String> = msg.status[0]
                .values
                .iter()
                .map(|kv| (kv.key.clone(), kv.value.clone()))
                .collect();
            if check(&values) {
                return values;
            }
        }
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_link_reconnects_without_motion_and_reports_the_fast_stop() {
    let (sim, addr) = sim(SimConfig::default()).await;
    let d = domain();
    let node = Running::start(params(DeviceKind::Wsg, addr, d, Mapping::Enhanced));
    let mut me = TestNode::new(d, "test_client");
    let topic = me
        .node
        .create_topic(
            &ros2_client::Name::new("/", "diagnostics").unwrap(),
            gripper_ros2::msgs::diagnostic_array_type(),
            &gripper_ros2::qos::topic(),
        )
        .unwrap();
    let sub = me.node.create_subscription(&topic, None).unwrap();
    let home = trigger_client(&mut me, ServiceMapping::Enhanced, "home").await;
    assert!(trigger_retrying(&home).await.success);
    diagnostics_until(&sub, "connected", |v| v["connected"] == "true").await;

    let before = sim.received_ids().len();
    // A pulled cable: the WSG goes into FAST STOP (manual 1.4.2).
    sim.unplug();
    let v = diagnostics_until(&sub, "the reconnect with FAST STOP", |v| {
        v["reconnects"] == "1" && v["fast_stop"] == "true" && v["connected"] == "true"
    })
    .await;
    assert!(v["system_state"].contains("FAST_STOP"), "{v:?}");
    // Nothing that moves the fingers was sent after the loss: no homing (0x20), no
    // pre-position, grasp or release (0x21, 0x25, 0x26), and no acknowledge (0x24).
    let after: Vec<u8> = sim.received_ids()[before..].to_vec();
    for id in [0x20, 0x21, 0x24, 0x25, 0x26] {
        assert!(
            !after.contains(&id),
            "{id:#04x} sent after the loss: {after:02x?}"
        );
    }
    // The operator acknowledges it.
    let ack = trigger_client(&mut me, ServiceMapping::Enhanced, "acknowledge").await;
    assert!(trigger_retrying(&ack).await.success);
    diagnostics_until(&sub, "FAST STOP cleared", |v| v["fast_stop"] == "false").await;
    node.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn auto_acknowledge_clears_the_fast_stop_after_a_reconnect() {
    let (sim, addr) = sim(SimConfig::default()).await;
    let d = domain();
    let mut p = params(DeviceKind::Wsg, addr, d, Mapping::Enhanced);
    p.auto_acknowledge_fast_stop = true;
    let node = Running::start(p);
    let mut me = TestNode::new(d, "test_client");
    let home = trigger_client(&mut me, ServiceMapping::Enhanced, "home").await;
    assert!(trigger_retrying(&home).await.success);
    let before = sim.received_ids().len();
    sim.unplug();
    bounded("the acknowledge after the reconnect", async {
        while !sim.received_ids()[before..].contains(&0x24) {
            tokio::time::sleep(POLL).await;
        }
    })
    .await;
    bounded("FAST STOP cleared", async {
        while sim
            .snapshot()
            .system_state
            .contains(gripper::wsg::SystemState::FAST_STOP)
        {
            tokio::time::sleep(POLL).await;
        }
    })
    .await;
    node.stop().await.unwrap();
}
