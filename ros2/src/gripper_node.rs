//! What every gripper node offers, whatever the device: the GripperCommand action,
//! `joint_states`, `/diagnostics` and the `~/home`, `~/stop`, `~/acknowledge` services.

use std::sync::Arc;

use ros2_client::Node;
use tokio::sync::watch;

use crate::action::{action_qos, Actuator, GoalKeeper};
use crate::msgs::gripper_command_type;
use crate::params::{Live, Params};
use crate::telemetry::Shared;
use crate::trigger::{self, Handler};
use crate::{diagnostics, joint_states, ros};

/// The device-specific parts of the three services.
pub struct Services {
    /// `~/home`: reference the fingers.
    pub home: Handler,
    /// `~/stop`: stop the fingers now.
    pub stop: Handler,
    /// `~/acknowledge`: acknowledge a FAST STOP or fault.
    pub acknowledge: Handler,
}

/// Creates the action, topics and services on `node` and serves them until `shutdown`.
pub fn serve(
    node: &mut Node,
    params: &Params,
    telemetry: &Shared,
    actuator: Arc<dyn Actuator>,
    services: Services,
    live: &Live,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let name = ros::private_name(params, "gripper_cmd")?;
    let servers = crate::rpc::mappings(params)
        .into_iter()
        .map(|m| {
            node.create_action_server(m, &name, &gripper_command_type(), action_qos())
                .map(|s| (m, s))
                .map_err(|e| format!("action ~/gripper_cmd: {e:?}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    tokio::spawn(
        GoalKeeper::new(actuator, live.allow_stalling.clone()).serve(servers, shutdown.clone()),
    );

    joint_states::spawn(node, params, telemetry, shutdown)?;
    diagnostics::spawn(node, params, telemetry, shutdown)?;

    for (name, handler) in [
        ("home", services.home),
        ("stop", services.stop),
        ("acknowledge", services.acknowledge),
    ] {
        trigger::spawn(node, params, name, handler, shutdown.clone())?;
    }
    Ok(())
}
