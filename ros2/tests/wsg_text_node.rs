//! The WSG node over the text interface (GCL, `transport: text`) in process against the
//! crate's WSG simulator in text mode, through ros2-client's own action client.

mod common;

use common::*;
use gripper::wsg::sim::{SimConfig, SimServer};
use gripper::wsg::GripState;
use gripper_ros2::params::{DeviceKind, Mapping};
use ros2_client::action::GoalStatusEnum;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn close_with_the_part_agnostic_grip_then_open() {
    // Instant motion; a 40 mm part between the fingers.
    let sim = SimServer::bind(
        "127.0.0.1:0",
        SimConfig::default().text().with_part(40.0, 2.0),
    )
    .await
    .unwrap();
    let addr = sim.local_addr().unwrap().to_string();
    let mut p = params(DeviceKind::Wsg, addr, domain(), Mapping::Enhanced);
    p.transport = "text".into();
    p.allow_stalling = true;
    let (node, _me, gripper) = homed_gripper(p).await;

    // MoveIt's "close" (0 m): GRIP(f) grips inward until it finds the part, whose width the
    // goal does not know, and holds it: a stall, SUCCEEDED with allow_stalling.
    let (_, status, result) = run_goal(&gripper, 0.0, 30.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.stalled && !result.reached_goal, "{result:?}");
    assert!((result.position - 0.04).abs() < 1e-3, "{result:?}");
    assert_eq!(sim.snapshot().grip_state, GripState::Holding);

    // Open to 70 mm: a release (GCL's is relative: by 30 mm) while the part is held.
    let (_, status, result) = run_goal(&gripper, 0.07, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Succeeded, "{result:?}");
    assert!(result.reached_goal && !result.stalled, "{result:?}");
    assert!((result.position - 0.07).abs() < 1e-3, "{result:?}");
    node.stop().await.unwrap();
}

/// `--sim wsg -p transport:=text`: the node's own simulator serves GCL.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_in_process_simulator_speaks_the_text_interface_when_asked() {
    let mut p = params(DeviceKind::Wsg, String::new(), domain(), Mapping::Enhanced);
    p.transport = "text".into();
    p.speed_m_per_s = 0.2;
    let mut cli = gripper_ros2::params::Cli::for_params(p.clone());
    cli.sim = Some(DeviceKind::Wsg);
    let node = Running::start_cli(cli);
    let mut me = TestNode::new(p.domain_id, "test_client");
    let home = trigger_client(&mut me, ros2_client::ServiceMapping::Enhanced, "home").await;
    assert!(trigger_retrying(&home).await.success);
    let gripper = action_client(&mut me, ros2_client::ServiceMapping::Enhanced).await;
    // Real time: 110 -> 40 mm at 200 mm/s; the part stops GRIP, a stall (ABORTED by default).
    let (_, status, result) = run_goal(&gripper, 0.0, 0.0).await;
    assert_eq!(status, GoalStatusEnum::Aborted, "{result:?}");
    assert!(
        result.stalled && (result.position - 0.04).abs() < 1e-3,
        "{result:?}"
    );
    node.stop().await.unwrap();
}
