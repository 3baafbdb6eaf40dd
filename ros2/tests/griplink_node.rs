//! The GRIPLINK node in process against the crate's GRIPLINK simulator, through ros2-client's
//! own action and service clients, each test on a ROS domain of its own.

mod common;

use common::*;
use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
use gripper::griplink::DeviceState;
use gripper_ros2::params::{DeviceKind, Mapping};
use ros2_client::action::GoalStatusEnum;
use ros2_client::action_msgs::CancelGoalResponseEnum;
use ros2_client::builtin_interfaces::Time;

/// A GRIPLINK-ET4 with an IEG 55-020 (20 mm stroke) holding nothing yet on port 0.
async fn sim(time_scale: f64) -> (SimServer, String) {
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020()))
        .time_scale(time_scale);
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let addr = sim.local_addr().to_string();
    (sim, addr)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grip_on_a_part_release_and_a_grip_without_force_rejected() {
    let (sim, addr) = sim(0.0).await;
    sim.set_part(0, Some(10.0));
    let mut p = params(DeviceKind::Griplink, addr, domain(), Mapping::Enhanced);
    p.allow_stalling = true;
    let (node, _me, gripper) = homed_gripper(p).await;

    // "Close" (0 m) on a part the goal does not know: the grip stops on it and holds it,
    // a stall that allow_stalling makes SUCCEEDED.
    let (_, status, result) = run_goal(&gripper, 0.0, 15.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.stalled && !result.reached_goal, "{result:?}");
    assert_eq!(result.effort, 15.0);
    assert!((result.position - 0.010).abs() < 0.0005, "{result:?}");
    assert_eq!(sim.device_state(0), Some(DeviceState::Holding));

    // "Close" again: the part is already held (a grip now would be a state conflict): the
    // same stall, nothing sent.
    sim.start_recording(1024);
    let (_, status, again) = run_goal(&gripper, 0.0, 15.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{again:?}");
    assert!(
        again.stalled && (again.position - 0.010).abs() < 0.0005,
        "{again:?}"
    );
    assert!(!sim
        .recording()
        .iter()
        .any(|x| x.request.starts_with("FLEXGRIP")));

    // Closing needs a force: max_effort 0 with no default_effort_n is rejected, unsent.
    let (_, response) = bounded("send_goal", gripper.async_send_goal(goal(0.002, 0.0)))
        .await
        .unwrap();
    assert!(!response.accepted);

    let (_, status, result) = run_goal(&gripper, 0.018, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.reached_goal && !result.stalled, "{result:?}");
    assert_eq!(sim.device_state(0), Some(DeviceState::Released));
    node.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_disables_the_port_and_the_goal_ends_canceled() {
    // Real time: 20 mm at 2 mm/s takes 10 s, so the cancel finds the grip running.
    let (sim, addr) = sim(1.0).await;
    let mut p = params(DeviceKind::Griplink, addr, domain(), Mapping::Cyclone);
    p.speed_m_per_s = 0.002;
    p.default_effort_n = 10.0;
    let (node, _me, gripper) = homed_gripper(p).await;
    let (id, accepted) = bounded("send_goal", gripper.async_send_goal(goal(0.0, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted);
    let response = bounded("cancel", gripper.async_cancel_goal(id, Time::ZERO))
        .await
        .unwrap();
    assert_eq!(response.return_code, CancelGoalResponseEnum::None);
    // Promptly: DISABLE brings no state transition the grip's wait would take as its end, so
    // the goal must not wait for the motion timeout (30 s).
    let (status, result) = tokio::time::timeout(
        std::time::Duration::from_secs(5),
        gripper.async_request_result(id),
    )
    .await
    .expect("the cancelled goal's result within 5 s")
    .unwrap();
    assert_eq!(status, GoalStatusEnum::Canceled, "{result:?}");
    assert!(!result.reached_goal && !result.stalled, "{result:?}");
    assert_eq!(sim.device_state(0), Some(DeviceState::Disabled));
    node.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_of_a_grip_that_already_holds_leaves_the_part_held() {
    // Real time: 20 -> 10 mm at 20 mm/s takes 0.5 s.
    let (sim, addr) = sim(1.0).await;
    sim.set_part(0, Some(10.0));
    let mut p = params(DeviceKind::Griplink, addr, domain(), Mapping::Enhanced);
    p.speed_m_per_s = 0.02;
    p.default_effort_n = 10.0;
    let (node, _me, gripper) = homed_gripper(p).await;
    sim.start_recording(4096);
    let (id, accepted) = bounded("send_goal", gripper.async_send_goal(goal(0.0, 0.0)))
        .await
        .unwrap();
    assert!(accepted.accepted);
    bounded("the grip sent", async {
        while !sim
            .recording()
            .iter()
            .any(|x| x.request.starts_with("FLEXGRIP"))
        {
            tokio::time::sleep(POLL).await;
        }
    })
    .await;
    // The node sees nothing of the device until the gate opens: the goal still runs when the
    // part is clamped.
    let gate = sim.hold_next_reply();
    bounded("the part held", async {
        while sim.device_state(0) != Some(DeviceState::Holding) {
            tokio::time::sleep(POLL).await;
        }
    })
    .await;
    let response = bounded("cancel", gripper.async_cancel_goal(id, Time::ZERO))
        .await
        .unwrap();
    assert_eq!(response.return_code, CancelGoalResponseEnum::None);
    gate.release();
    let (status, result) = bounded("get_result", gripper.async_request_result(id))
        .await
        .unwrap();
    assert_eq!(status, GoalStatusEnum::Canceled, "{result:?}");
    // No DISABLE, which would have let go of it (manual 3.4.2).
    assert_eq!(sim.device_state(0), Some(DeviceState::Holding));
    assert!(
        !sim.recording()
            .iter()
            .any(|x| x.request.starts_with("DISABLE")),
        "DISABLE sent"
    );
    assert!(
        result.stalled && (result.position - 0.010).abs() < 0.0005,
        "{result:?}"
    );
    node.stop().await.unwrap();
}
