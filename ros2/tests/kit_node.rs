//! The Grasping-Kit node in process against the crate's Grasping-Kit simulator, through
//! ros2-client's own service client and subscriptions, on a ROS domain of its own.

mod common;

use common::*;
use gripper::smartgrasp::sim::{SimConfig, SimServer};
use gripper_ros2::msgs::{pose_stamped_type, Float64, PoseStamped};
use gripper_ros2::params::{DeviceKind, Mapping};
use gripper_ros2::qos;
use ros2_client::{MessageTypeName, Name, ServiceMapping};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn next_grasp_publishes_pose_stroke_and_class_until_the_bin_is_empty() {
    // OK takes the part out of the bin (a real Grasping-Kit's feedback changes nothing).
    let config = SimConfig {
        feedback_removes_objects: true,
        ..SimConfig::default()
    };
    let sim = SimServer::bind("127.0.0.1:0", config).await.unwrap();
    let d = domain();
    let mut p = params(
        DeviceKind::SmartGrasp,
        sim.local_addr().to_string(),
        d,
        Mapping::Enhanced,
    );
    p.frame_id = "bin_camera".into();
    p.service_mapping = None;
    let node = Running::start(p);
    let mut me = TestNode::new(d, "test_client");
    let pose_topic = me
        .node
        .create_topic(
            &Name::new("/gripper", "grasp_pose").unwrap(),
            pose_stamped_type(),
            &qos::status(),
        )
        .unwrap();
    let poses = me
        .node
        .create_subscription::<PoseStamped>(&pose_topic, None)
        .unwrap();
    let stroke_topic = me
        .node
        .create_topic(
            &Name::new("/gripper", "grasp_stroke").unwrap(),
            MessageTypeName::new("std_msgs", "Float64"),
            &qos::status(),
        )
        .unwrap();
    let strokes = me
        .node
        .create_subscription::<Float64>(&stroke_topic, None)
        .unwrap();
    let next = trigger_client(&mut me, ServiceMapping::Enhanced, "next_grasp").await;
    let ok = trigger_client(&mut me, ServiceMapping::Enhanced, "grasp_ok").await;

    // GET_GRASP changes nothing on the server: repeating it is harmless.
    let first = trigger_retrying(&next).await;
    assert!(first.success, "{first:?}");
    assert!(first.message.contains("object_class: 1"), "{first:?}");
    let (pose, _) = bounded("a grasp pose", poses.async_take()).await.unwrap();
    assert_eq!(pose.header.frame_id, "bin_camera");
    let q = pose.pose.orientation;
    let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    assert!((norm - 1.0).abs() < 1e-6, "{pose:?}");
    // The demo bin's parts lie 5 cm above the base, in metres.
    assert!((pose.pose.position.z - 0.05).abs() < 1e-6, "{pose:?}");
    let (stroke, _) = bounded("a stroke", strokes.async_take()).await.unwrap();
    assert!(stroke.data > 0.0 && stroke.data < 0.2, "{stroke:?}");

    // Each OK takes the part out of the bin; the demo bin holds three.
    assert!(trigger(&ok).await.success);
    let mut picked = 1;
    loop {
        let r = trigger(&next).await;
        if !r.success {
            assert_eq!(r.message, "no object in the scene", "{r:?}");
            break;
        }
        assert!(trigger(&ok).await.success);
        picked += 1;
        assert!(picked <= 3, "more picks than parts");
    }
    assert_eq!(picked, 3);
    node.stop().await.unwrap();
}
