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
async fn close_until_contact_on_a_part_of_unknown_width_and_a_late_result_request() {
    // Instant motion: the moves cost no wall time. The 40 mm part sits between the fingers.
    let (wsg, addr) = sim(SimConfig::default()
        .with_part(40.0, 2.0)
        .with_blocking_part())
    .await;
    let mut p = params(DeviceKind::Wsg, addr, domain(), Mapping::Enhanced);
    // auto, the default: this RustDDS peer is answered in the Enhanced mapping (a Cyclone DDS
    // peer in the Cyclone one: .ci/ros2_peer.py).
    p.service_mapping = None;
    p.allow_stalling = true;
    let (node, _me, gripper) = homed_gripper(p).await;

    // MoveIt's "close": 0 m. The fingers stop on the part (E_AXIS_BLOCKED), grasp it there and
    // hold it with the goal's force; reported as gripper_action_controller reports a stall,
    // SUCCEEDED with allow_stalling.
    let (id, status, result) = run_goal(&gripper, 0.0, 30.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.stalled && !result.reached_goal, "{result:?}");
    assert_eq!((result.position, result.effort), (0.04, 30.0));
    let ids = wsg.received_ids();
    let pre = ids
        .iter()
        .rposition(|&i| i == 0x21)
        .expect("a pre-position");
    assert!(
        ids[pre..].contains(&0x25),
        "no grasp after the contact: {ids:02x?}"
    );
    assert_eq!(
        wsg.snapshot().grip_state,
        gripper::wsg::GripState::Holding,
        "the part is held"
    );

    // "Close" again while holding it: the fingers are on the part, blocked at once, and hold.
    let (_, status, again) = run_goal(&gripper, 0.0, 30.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{again:?}");
    assert!(again.stalled && again.position == 0.04, "{again:?}");

    // Asked again long after the goal ended: answered from the kept results (ros2-client's
    // AsyncActionServer never answers this one).
    let (status, again) = bounded("late get_result", gripper.async_request_result(id))
        .await
        .unwrap();
    assert_eq!((status, again), (GoalStatusEnum::Succeeded, result));

    // Open (a release, the part is held): the position is reached.
    let (_, status, result) = run_goal(&gripper, 0.07, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded);
    assert!(result.reached_goal && !result.stalled, "{result:?}");

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
async fn a_new_goal_preempts_the_running_one_and_a_cancel_stops_the_fingers() {
    let (sim, addr) = sim(SimConfig::default()
        .with_part(40.0, 2.0)
        .with_blocking_part())
    .await;
    let mut p = params(DeviceKind::Wsg, addr, domain(), Mapping::Cyclone);
    p.speed_m_per_s = 0.05;
    let (node, _me, gripper) = homed_gripper(p).await;
    // Five times slower than real time from here: 110 -> 60 mm at 50 mm/s takes 5 s, so the
    // second goal finds the first one running even on a loaded machine (at real time, 1 s).
    sim.set_time_scale(5.0);
    let (first, accepted) = bounded("send_goal", gripper.async_send_goal(goal(0.06, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted);
    let (second, accepted) = bounded("second goal", gripper.async_send_goal(goal(0.09, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted, "a new goal preempts, it is not rejected");
    // The first ends CANCELED (as gripper_action_controller's preempt_active_goal ends it),
    // short of its position; the second runs to its own.
    let (status, result) = bounded("first result", gripper.async_request_result(first))
        .await
        .unwrap();
    assert_eq!(status, GoalStatusEnum::Canceled, "{result:?}");
    assert!(
        !result.reached_goal && result.position > 0.061,
        "{result:?}"
    );
    let (status, result) = bounded("second result", gripper.async_request_result(second))
        .await
        .unwrap();
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(
        result.reached_goal && (result.position - 0.09).abs() < 1e-3,
        "{result:?}"
    );
    // The device stopped the first motion (0x22) before the second started.
    let ids = sim.received_ids();
    let stop = ids.iter().position(|&i| i == 0x22).expect("a stop");
    assert!(ids[stop..].contains(&0x21), "{ids:02x?}");

    // A cancel: the fingers stop where they are. 90 -> 100 mm takes 0.2 s of motion, 4 s here:
    // at real time a loaded machine let the move end before the cancel came (the result was
    // CANCELED at 100 mm, reached).
    sim.set_time_scale(20.0);
    let (id, accepted) = bounded("send_goal", gripper.async_send_goal(goal(0.1, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted);
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
        result.position < 0.099 && !result.reached_goal,
        "{result:?}"
    );
    assert!(sim
        .snapshot()
        .system_state
        .contains(gripper::wsg::SystemState::AXIS_STOPPED));

    // Without allow_stalling (the controller's default), closing on the part is a stall that
    // ABORTS, reported all the same: stalled at the part, holding it.
    sim.set_time_scale(0.0);
    let (_, status, result) = run_goal(&gripper, 0.0, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Aborted, "{result:?}");
    assert!(result.stalled && !result.reached_goal, "{result:?}");
    assert_eq!(result.position, 0.04);
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

/// The parameter services of a node with `service_mapping: auto` answer this RustDDS peer in
/// the Enhanced mapping (.ci/ros2_peer.py checks the Cyclone one against the same default),
/// and a set of `allow_stalling` changes how the next stall ends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameter_services_and_a_live_allow_stalling() {
    use ros2_client::parameters::{raw, ParameterValue};
    use ros2_client::rcl_interfaces::{
        ListParametersRequest, ListParametersResponse, SetParametersRequest, SetParametersResponse,
    };

    let (_wsg, addr) = sim(SimConfig::default()
        .with_part(40.0, 2.0)
        .with_blocking_part())
    .await;
    let mut p = params(DeviceKind::Wsg, addr, domain(), Mapping::Enhanced);
    p.service_mapping = None;
    let (node, mut me, gripper) = homed_gripper(p).await;
    let list = param_client::<ListParametersRequest, ListParametersResponse>(
        &mut me,
        "list_parameters",
        "ListParameters",
    );
    let set = param_client::<SetParametersRequest, SetParametersResponse>(
        &mut me,
        "set_parameters",
        "SetParameters",
    );
    me.wait_for_service("gripper/list_parameters").await;
    me.wait_for_service("gripper/set_parameters").await;
    let listed = ping("list_parameters", || {
        list.async_call_service(ListParametersRequest {
            prefixes: Vec::new(),
            depth: 0,
        })
    })
    .await;
    assert!(listed.result.names.contains(&"allow_stalling".to_owned()));

    // The default, false: a stall on the part ABORTS.
    let (_, status, _) = run_goal(&gripper, 0.0, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Aborted);
    let (_, status, _) = run_goal(&gripper, 0.07, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded);
    let set_to = |v: bool| SetParametersRequest {
        parameter: vec![raw::Parameter {
            name: "allow_stalling".into(),
            value: ParameterValue::Boolean(v).into(),
        }],
    };
    // Idempotent: repeated until answered.
    let r = ping("set_parameters", || set.async_call_service(set_to(true))).await;
    assert!(r.results[0].successful, "{:?}", r.results);
    let (_, status, result) = run_goal(&gripper, 0.0, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.stalled);
    node.stop().await.unwrap();
}

/// A client (Enhanced mapping) of the node's parameter service `/gripper/<name>`.
fn param_client<Q, P>(me: &mut TestNode, name: &str, type_name: &str) -> ros2_client::Client<Q, P>
where
    Q: ros2_client::Message + Clone + 'static,
    P: ros2_client::Message + 'static,
{
    me.node
        .create_client::<Q, P>(
            ServiceMapping::Enhanced,
            &ros2_client::Name::new("/gripper", name).unwrap(),
            &ros2_client::ServiceTypeName::new("rcl_interfaces", type_name),
            gripper_ros2::qos::services(),
            gripper_ros2::qos::services(),
        )
        .unwrap()
}
