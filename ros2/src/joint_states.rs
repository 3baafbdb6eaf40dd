//! `sensor_msgs/msg/JointState` on `joint_states`, at the `joint_states_rate_hz` parameter.

use std::time::Duration;

use ros2_client::{Node, Publisher};
use tokio::sync::watch;

use crate::joint_map::JointMap;
use crate::msgs::{joint_state_type, Header, JointState};
use crate::params::Params;
use crate::telemetry::{Shared, Telemetry};
use crate::{periodic, qos, ros};

/// The joint state for `t`: each joint of `map` at its position for the opening (see
/// [`crate::joint_map`]), velocity likewise, the gripping force (N) as every joint's effort.
/// `None` before the first width reading.
pub fn joint_state(map: &JointMap, t: &Telemetry) -> Option<JointState> {
    let width_mm = t.width_mm?;
    Some(JointState {
        header: Header::now(""),
        name: map.names.clone(),
        position: map.positions(width_mm),
        velocity: map.velocities(t.speed_mm_per_s.unwrap_or(0.0)),
        effort: vec![t.force_n.unwrap_or(0.0); map.names.len()],
    })
}

fn publisher(node: &mut Node, params: &Params) -> Result<Publisher<JointState>, String> {
    let name = ros::namespaced_name(params, "joint_states")?;
    let topic = node
        .create_topic(&name, joint_state_type(), &qos::topic())
        .map_err(|e| format!("joint_states topic: {e:?}"))?;
    node.create_publisher(&topic, None)
        .map_err(|e| format!("joint_states publisher: {e:?}"))
}

/// Creates the publisher and publishes `telemetry` until `shutdown` turns true.
pub fn spawn(
    node: &mut Node,
    params: &Params,
    telemetry: &Shared,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let publisher = publisher(node, params)?;
    let map = JointMap::new(params).map_err(|e| e.to_string())?;
    let period = Duration::from_secs_f64(1.0 / params.joint_states_rate_hz);
    let telemetry = telemetry.clone();
    tokio::spawn(periodic::every(period, shutdown.clone(), move || {
        if let Some(msg) = joint_state(&map, &telemetry.get()) {
            if let Err(e) = publisher.publish(msg) {
                tracing::debug!("joint state not sent: {e:?}");
            }
        }
        std::future::ready(())
    }));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fingers_of_the_shipped_description_left_negative() {
        let t = Telemetry {
            width_mm: Some(40.0),
            speed_mm_per_s: Some(10.0),
            force_n: Some(20.0),
            ..Telemetry::default()
        };
        let map = JointMap::new(&Params::default()).unwrap();
        let js = joint_state(&map, &t).unwrap();
        assert_eq!(
            js.name,
            vec!["base_joint_gripper_left", "base_joint_gripper_right"]
        );
        assert_eq!(js.position, vec![-0.02, 0.02]);
        assert_eq!(js.velocity, vec![-0.005, 0.005]);
        assert_eq!(js.effort, vec![20.0, 20.0]);
        assert!(joint_state(&map, &Telemetry::default()).is_none());
    }
}
