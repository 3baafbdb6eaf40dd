//! Shared test parts: a node run in process on a ROS domain of its own, on loopback only, and
//! ros2-client clients on the same domain.

#![allow(dead_code)] // each test file uses a part of this

use std::future::Future;
use std::net::IpAddr;
use std::sync::atomic::{AtomicU16, Ordering};
use std::time::Duration;

use gripper_ros2::action::action_qos;
use gripper_ros2::msgs::{
    gripper_command_type, trigger_type, GripperCommand, GripperCommandFeedback, GripperCommandGoal,
    GripperCommandResult, TriggerRequest, TriggerResponse,
};
use gripper_ros2::params::{Cli, DeviceKind, Mapping, Params};
use gripper_ros2::qos;
use ros2_client::action::{ActionClient, ActionClientQosPolicies, GoalId, GoalStatusEnum};
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::{Client, Context, Name, Node, NodeName, NodeOptions, ServiceMapping};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// Every wait in these tests is bounded by this.
pub const WAIT: Duration = Duration::from_secs(30);

/// A ROS domain no other test (of this process or, by the process id, of another) uses:
/// 0..=232 are the valid ROS domain ids.
pub fn domain() -> u16 {
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let pid = u16::try_from(std::process::id() % 233).unwrap_or(0);
    (pid.wrapping_mul(17).wrapping_add(n.wrapping_mul(31))) % 233
}

/// Parameters for a node that drives the device at `address` over TCP, on `domain`, loopback
/// only.
pub fn params(device: DeviceKind, address: String, domain: u16, mapping: Mapping) -> Params {
    Params {
        device,
        address,
        domain_id: domain,
        dds_interfaces: vec![IpAddr::from([127, 0, 0, 1])],
        service_mapping: Some(mapping),
        ..Params::default()
    }
}

/// The node, running in process until [`Running::stop`].
pub struct Running {
    stop: Option<oneshot::Sender<()>>,
    task: JoinHandle<Result<(), String>>,
}

impl Running {
    /// Starts the node.
    pub fn start(params: Params) -> Self {
        Running::start_cli(Cli::for_params(params))
    }

    /// Starts the node of a command line (e.g. one with `--sim`).
    pub fn start_cli(cli: Cli) -> Self {
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(gripper_ros2::run(cli, async {
            let _ = stopped.await;
        }));
        Running {
            stop: Some(stop),
            task,
        }
    }

    /// Stops it (as SIGINT does) and returns how it ended.
    pub async fn stop(mut self) -> Result<(), String> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        bounded("the node's shutdown", &mut self.task)
            .await
            .map_err(|e| e.to_string())?
    }
}

/// `f`, or a panic naming `what` after [`WAIT`].
pub async fn bounded<T>(what: &str, f: impl Future<Output = T>) -> T {
    tokio::time::timeout(WAIT, f)
        .await
        .unwrap_or_else(|_| panic!("{what}: nothing within {WAIT:?}"))
}

/// A test's own node on a domain (loopback only), with its spinner running.
pub struct TestNode {
    /// The node.
    pub node: Node,
    context: Context,
}

impl TestNode {
    /// A node named `name` on `domain`.
    pub fn new(domain: u16, name: &str) -> Self {
        let participant = DomainParticipantBuilder::new(domain)
            .with_only_networks([IpAddr::from([127, 0, 0, 1])])
            .build()
            .expect("participant");
        let context = Context::from_domain_participant(participant).expect("context");
        let mut node = context
            .new_node(NodeName::new("/", name).unwrap(), NodeOptions::new())
            .expect("node");
        let spinner = node.spinner().expect("spinner");
        tokio::spawn(spinner.spin());
        TestNode { node, context }
    }

    /// Waits until the service `name` (e.g. `gripper/home`) has a discovered request reader
    /// and reply writer. Polled: ros2-client 0.12.1's `wait_for_service` waits for discovery
    /// events on a channel of 8 that drops events when full, so under load it can miss the one
    /// it waits for and never return (seen here: 1 run in 5 hung).
    pub async fn wait_for_service(&self, name: &str) {
        let (rq, rr) = (format!("rq/{name}Request"), format!("rr/{name}Reply"));
        let found = || {
            let dp = self.context.domain_participant();
            dp.discovered_readers()
                .iter()
                .any(|r| r.subscription_topic_data.topic_name == rq)
                && dp
                    .discovered_writers()
                    .iter()
                    .any(|w| w.publication_topic_data.topic_name == rr)
        };
        bounded(name, async {
            while !found() {
                tokio::time::sleep(POLL).await;
            }
        })
        .await;
    }
}

/// How often a condition is polled.
pub const POLL: Duration = Duration::from_millis(20);
/// One attempt of a side-effect-free call that proves a service answers: the server may not
/// have discovered our reply reader when we discovered its endpoints, and a reply sent before
/// then is lost (volatile).
pub const PING: Duration = Duration::from_secs(2);

/// Retries a side-effect-free call until it is answered, each attempt within [`PING`], all
/// within [`WAIT`].
pub async fn ping<T, E: std::fmt::Debug, F: Future<Output = Result<T, E>>>(
    what: &str,
    call: impl Fn() -> F,
) -> T {
    bounded(what, async {
        loop {
            if let Ok(r) = tokio::time::timeout(PING, call()).await {
                return r.unwrap_or_else(|e| panic!("{what}: {e:?}"));
            }
        }
    })
    .await
}

/// The GripperCommand client of `/gripper/gripper_cmd`.
pub type GripperClient =
    ActionClient<GripperCommandGoal, GripperCommandResult, GripperCommandFeedback>;

/// The mapping a test's clients use with a node of `params`: its own, or with `auto` (each
/// peer's), the Enhanced one, which the node answers a RustDDS peer in.
pub fn client_mapping(params: &Params) -> ServiceMapping {
    params
        .service_mapping
        .map_or(ServiceMapping::Enhanced, Mapping::to_ros2)
}

/// Starts the node for `params`, a test node beside it, homes the gripper through `~/home` and
/// returns an action client (all with [`client_mapping`]).
pub async fn homed_gripper(params: Params) -> (Running, TestNode, GripperClient) {
    let mapping = client_mapping(&params);
    let domain = params.domain_id;
    let node = Running::start(params);
    let mut me = TestNode::new(domain, "test_client");
    let home = trigger_client(&mut me, mapping, "home").await;
    assert!(trigger_retrying(&home).await.success);
    let gripper = action_client(&mut me, mapping).await;
    (node, me, gripper)
}

/// Sends a goal, which must be accepted, and waits for its result.
pub async fn run_goal(
    gripper: &GripperClient,
    position: f64,
    max_effort: f64,
) -> (GoalId, GoalStatusEnum, GripperCommandResult) {
    let (id, accepted) = bounded(
        "send_goal",
        gripper.async_send_goal(goal(position, max_effort)),
    )
    .await
    .unwrap();
    assert!(
        accepted.accepted,
        "goal {position} m, {max_effort} N rejected"
    );
    let (status, result) = bounded("get_result", gripper.async_request_result(id))
        .await
        .unwrap();
    (id, status, result)
}

/// A GripperCommand goal.
pub fn goal(position: f64, max_effort: f64) -> GripperCommandGoal {
    GripperCommandGoal {
        command: GripperCommand {
            position,
            max_effort,
        },
    }
}

/// An action client of `/gripper/gripper_cmd`, its three services matched and answering (a
/// goal with a NaN position is rejected, a result and a cancel of an unknown goal are
/// answered: none of them moves anything).
pub async fn action_client(me: &mut TestNode, mapping: ServiceMapping) -> GripperClient {
    let q = action_qos();
    let client = me
        .node
        .create_action_client(
            mapping,
            &Name::new("/gripper", "gripper_cmd").unwrap(),
            &gripper_command_type(),
            ActionClientQosPolicies {
                goal_service: q.goal_service,
                result_service: q.result_service,
                cancel_service: q.cancel_service,
                feedback_subscription: q.feedback_publisher,
                status_subscription: q.status_publisher,
            },
        )
        .expect("action client");
    for service in ["send_goal", "get_result", "cancel_goal"] {
        me.wait_for_service(&format!("gripper/gripper_cmd/_action/{service}"))
            .await;
    }
    let nan = GripperCommandGoal {
        command: GripperCommand {
            position: f64::NAN,
            max_effort: 0.0,
        },
    };
    let (_, response) = ping("send_goal", || client.async_send_goal(nan)).await;
    assert!(!response.accepted);
    let unknown = GoalId::new_random();
    ping("get_result", || client.async_request_result(unknown)).await;
    ping("cancel_goal", || {
        client.async_cancel_goal(unknown, Time::ZERO)
    })
    .await;
    client
}

/// A client of the Trigger service `/gripper/<name>`, its endpoints discovered. The first call
/// should be made with [`trigger_retrying`] when repeating it does no harm.
pub async fn trigger_client(
    me: &mut TestNode,
    mapping: ServiceMapping,
    name: &str,
) -> Client<TriggerRequest, TriggerResponse> {
    let client = me
        .node
        .create_client(
            mapping,
            &Name::new("/gripper", name).unwrap(),
            &trigger_type(),
            qos::services(),
            qos::services(),
        )
        .expect("service client");
    me.wait_for_service(&format!("gripper/{name}")).await;
    client
}

/// Calls a Trigger service whose repetition does no harm (homing) until it answers.
pub async fn trigger_retrying(client: &Client<TriggerRequest, TriggerResponse>) -> TriggerResponse {
    ping("a Trigger reply", || {
        client.async_call_service(TriggerRequest::default())
    })
    .await
}

/// Calls a Trigger service.
pub async fn trigger(client: &Client<TriggerRequest, TriggerResponse>) -> TriggerResponse {
    bounded(
        "a Trigger reply",
        client.async_call_service(TriggerRequest::default()),
    )
    .await
    .expect("Trigger call")
}
