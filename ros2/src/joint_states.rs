//! `sensor_msgs/msg/JointState` on `joint_states`, at the `joint_states_rate_hz` parameter.

use std::time::Duration;

use ros2_client::{Node, Publisher};
use tokio::sync::watch;

use crate::msgs::{joint_state_type, Header, JointState};
use crate::params::Params;
use crate::telemetry::{Shared, Telemetry};
use crate::{periodic, qos, ros};

/// The joint state for `t`: with one joint name, the opening in the `position_convention`;
/// with two, each finger's distance from the centre (half the opening), as the public URDFs'
/// finger joints have it. Velocity in m/s, effort in N. `None` before the first width reading.
pub fn joint_state(params: &Params, t: &Telemetry) -> Option<JointState> {
    let width_mm = t.width_mm?;
    let one = params.joint_names.len() == 1;
    let scale = |mm: f64| {
        if one {
            params.position_convention.from_width_mm(mm)
        } else {
            mm / 2000.0
        }
    };
    let n = params.joint_names.len();
    Some(JointState {
        header: Header::now(""),
        name: params.joint_names.clone(),
        position: vec![scale(width_mm); n],
        velocity: vec![scale(t.speed_mm_per_s.unwrap_or(0.0)); n],
        effort: vec![t.force_n.unwrap_or(0.0); n],
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
    let period = Duration::from_secs_f64(1.0 / params.joint_states_rate_hz);
    let (params, telemetry) = (params.clone(), telemetry.clone());
    tokio::spawn(periodic::every(period, shutdown.clone(), move || {
        if let Some(msg) = joint_state(&params, &telemetry.get()) {
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
    use crate::params::PositionConvention;

    #[test]
    fn one_width_joint_or_two_finger_joints() {
        let t = Telemetry {
            width_mm: Some(40.0),
            speed_mm_per_s: Some(10.0),
            force_n: Some(20.0),
            ..Telemetry::default()
        };
        let mut p = Params::default();
        let js = joint_state(&p, &t).unwrap();
        assert_eq!(
            (js.position[0], js.velocity[0], js.effort[0]),
            (0.04, 0.01, 20.0)
        );
        p.position_convention = PositionConvention::Finger;
        assert_eq!(joint_state(&p, &t).unwrap().position, vec![0.02]);
        p.joint_names = vec!["l".into(), "r".into()];
        assert_eq!(joint_state(&p, &t).unwrap().position, vec![0.02, 0.02]);
        assert!(joint_state(&p, &Telemetry::default()).is_none());
    }
}
