//! The SCHUNK 2D Grasping-Kit as a ROS 2 node: what standard messages carry.
//!
//! - `~/next_grasp` (`std_srvs/srv/Trigger`): GET_GRASP (manual 3.3.3.1) for the
//!   `object_class` parameter (0: any). A grasp is published, before the reply, as
//!   `~/grasp_pose` (`geometry_msgs/msg/PoseStamped`: metres and a unit quaternion, in the
//!   `frame_id` parameter's frame), `~/grasp_stroke` (`std_msgs/msg/Float64`, the opening to
//!   set before the approach, m) and `~/grasp_object_class` (`std_msgs/msg/UInt16`), each
//!   reliable and transient-local (a late subscriber gets the last grasp). The reply's message
//!   repeats them as text; "no object" and "no grasp" are `success: false`.
//! - `~/grasp_ok`, `~/grasp_bad` (`std_srvs/srv/Trigger`): GRASP_FEEDBACK OK or BAD (3.3.3.2).
//! - `/diagnostics`: the link, the server state (GET_STATE once a second), reconnects.
//!
//! No standard service returns a pose, a stroke and a class in one typed reply. A user who
//! wants one needs a message package of their own (e.g. a `NextGrasp.srv` with
//! `geometry_msgs/PoseStamped pose`, `float64 stroke`, `uint16 object_class`), or
//! `vision_msgs/msg/Detection3D` for class and pose (not a core package; it has no stroke). We
//! did not invent a package: a node built with ros2-client would have to ship its `.srv` for
//! every user's workspace to build.

use std::sync::Arc;

use gripper::reconnect::ReconnectPolicy;
use gripper::smartgrasp::{
    Client, ClientConfig, GetGraspOutcome, GraspFeedback, GraspMode, GraspRequest, PoseFormat,
    RobotSystem, SelectionCriterion, Tool,
};
use ros2_client::{MessageTypeName, Node, Publisher};
use tokio::sync::watch;

use crate::msgs::{
    pose_stamped_type, Float64, Header, Point, Pose, PoseStamped, Quaternion, UInt16,
};
use crate::params::Params;
use crate::telemetry::Shared;
use crate::{diagnostics, periodic, qos, ros, trigger};

/// Connects to the Grasping-Kit the parameters name and opens the session (protocol version,
/// state, registration, project 0).
pub async fn connect(params: &Params) -> Result<Client, String> {
    let mut addr = params.address.clone();
    if !addr.contains(':') {
        addr = format!("{addr}:{}", gripper::smartgrasp::DEFAULT_PORT);
    }
    let config = ClientConfig {
        robot_system: Some(RobotSystem::Kuka),
        project_index: Some(0),
        reconnect: params.reconnect.then(ReconnectPolicy::default),
        ..ClientConfig::default()
    };
    Client::connect(addr.as_str(), config)
        .await
        .map_err(|e| format!("Grasping-Kit at {addr}: {e}"))
}

struct Grasps {
    pose: Publisher<PoseStamped>,
    stroke: Publisher<Float64>,
    class: Publisher<UInt16>,
}

fn publisher<M: serde::Serialize>(
    node: &mut Node,
    params: &Params,
    name: &str,
    type_name: MessageTypeName,
) -> Result<Publisher<M>, String> {
    let topic = node
        .create_topic(&ros::private_name(params, name)?, type_name, &qos::status())
        .map_err(|e| format!("topic ~/{name}: {e:?}"))?;
    node.create_publisher(&topic, None)
        .map_err(|e| format!("publisher ~/{name}: {e:?}"))
}

/// Serves `client` on `node` until `shutdown`.
pub fn start(
    node: &mut Node,
    params: &Params,
    client: Client,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let telemetry = Shared::new(
        "SCHUNK 2D Grasping-Kit",
        &format!(
            "{} (protocol V{})",
            params.address,
            client.protocol_version()
        ),
    );
    telemetry.lock().connected = true;
    let events = client.connection_events();
    let t = telemetry.clone();
    tokio::spawn(async move {
        crate::link::follow(events, "Grasping-Kit", t, || async {}).await;
    });
    tokio::spawn(poll_state(
        client.clone(),
        telemetry.clone(),
        shutdown.clone(),
    ));
    diagnostics::spawn(node, params, &telemetry, shutdown)?;

    let grasps = Arc::new(Grasps {
        pose: publisher(node, params, "grasp_pose", pose_stamped_type())?,
        stroke: publisher(
            node,
            params,
            "grasp_stroke",
            MessageTypeName::new("std_msgs", "Float64"),
        )?,
        class: publisher(
            node,
            params,
            "grasp_object_class",
            MessageTypeName::new("std_msgs", "UInt16"),
        )?,
    });
    let next = {
        let (client, params, telemetry) = (client.clone(), params.clone(), telemetry.clone());
        let handler: trigger::Handler = Arc::new(move || {
            let (client, params, grasps, telemetry) = (
                client.clone(),
                params.clone(),
                grasps.clone(),
                telemetry.clone(),
            );
            Box::pin(async move { next_grasp(&client, &params, &grasps, &telemetry).await })
        });
        handler
    };
    trigger::spawn(node, params, "next_grasp", next, shutdown.clone())?;
    for (name, feedback) in [
        ("grasp_ok", GraspFeedback::Ok),
        ("grasp_bad", GraspFeedback::Bad),
    ] {
        let (client, telemetry) = (client.clone(), telemetry.clone());
        let handler: trigger::Handler = Arc::new(move || {
            let (client, telemetry) = (client.clone(), telemetry.clone());
            Box::pin(async move {
                client.grasp_feedback(feedback).await.map_err(|e| {
                    telemetry.note_error(e.kind(), e.to_string());
                    e.to_string()
                })?;
                Ok(format!("GRASP_FEEDBACK {feedback:?} sent"))
            })
        });
        trigger::spawn(node, params, name, handler, shutdown.clone())?;
    }
    Ok(())
}

async fn next_grasp(
    client: &Client,
    params: &Params,
    grasps: &Grasps,
    telemetry: &Shared,
) -> Result<String, String> {
    let request = GraspRequest {
        grasp_mode: GraspMode::AutoGrasp,
        object_class: params.object_class,
        tool: Tool::Exterior,
        selection_criterion: SelectionCriterion(1),
        pose_format: PoseFormat::Quaternion,
    };
    let outcome = client.get_grasp(request).await.map_err(|e| {
        telemetry.note_error(e.kind(), e.to_string());
        format!("GET_GRASP: {e}")
    })?;
    let grasp = match outcome {
        GetGraspOutcome::Grasp(g) => g,
        GetGraspOutcome::NoObject => return Err("no object in the scene".into()),
        GetGraspOutcome::NoGrasp => return Err("objects, but no grasp for them".into()),
        GetGraspOutcome::InvalidObjectClass => {
            return Err(format!(
                "the server knows no object class {}",
                params.object_class
            ))
        }
    };
    let si = grasp.pose.to_si().map_err(|e| format!("grasp pose: {e}"))?;
    let [x, y, z] = si.position_m;
    let [qx, qy, qz, qw] = si.orientation.xyzw();
    let stroke_m = f64::from(grasp.stroke_um) / 1e6;
    let pose = PoseStamped {
        header: Header::now(&params.frame_id),
        pose: Pose {
            position: Point { x, y, z },
            orientation: Quaternion {
                x: qx,
                y: qy,
                z: qz,
                w: qw,
            },
        },
    };
    // Published before the reply: a caller that subscribed first has them when it is answered.
    let sent = [
        grasps.pose.publish(pose).map_err(|e| format!("{e:?}")),
        grasps
            .stroke
            .publish(Float64 { data: stroke_m })
            .map_err(|e| format!("{e:?}")),
        grasps
            .class
            .publish(UInt16 {
                data: grasp.object_class,
            })
            .map_err(|e| format!("{e:?}")),
    ];
    if let Some(Err(e)) = sent.into_iter().find(Result::is_err) {
        return Err(format!("publishing the grasp failed: {e}"));
    }
    Ok(format!(
        "object_class: {}, object_instance: {}, stroke_m: {stroke_m}, position_m: [{x}, {y}, {z}], \
         orientation_xyzw: [{qx}, {qy}, {qz}, {qw}], frame_id: {}",
        grasp.object_class, grasp.object_instance, params.frame_id
    ))
}

/// GET_STATE once a second into the diagnostics.
async fn poll_state(client: Client, telemetry: Shared, shutdown: watch::Receiver<bool>) {
    periodic::every(diagnostics::PERIOD, shutdown, move || {
        let (client, telemetry) = (client.clone(), telemetry.clone());
        async move {
            if !telemetry.lock().connected {
                return;
            }
            match client.get_state().await {
                Ok(s) => {
                    let mut t = telemetry.lock();
                    t.set_state("server_state", s.to_string());
                    t.warnings = if s == gripper::smartgrasp::ServerState::Operational {
                        Vec::new()
                    } else {
                        vec![format!("server state {s}")]
                    };
                }
                Err(e) => telemetry.note_error(e.kind(), format!("GET_STATE: {e}")),
            }
        }
    })
    .await;
}
