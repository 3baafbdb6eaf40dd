//! A WSG over its text interface (GCL, `transport: text`) as a ROS 2 gripper node.
//!
//! - Goals: a goal that closes is GCL's part-agnostic `GRIP()` (`GRIP(f)` with the goal's
//!   `max_effort`): it grips inward until something is found, whatever the part's width
//!   (MoveIt's "close", 0 m, included), and holds it (HOLDING: `stalled` at the part, the
//!   measured force as `effort`; SUCCEEDED with `allow_stalling`, else ABORTED, as
//!   gripper_action_controller decides). Without a part the fingers grip each other and the
//!   state is HOLDING all the same (GCL manual, chapter 2): the result's position, about 0,
//!   tells the two apart. A goal that opens is `RELEASE(d,v)` by the difference while a part is
//!   held (GCL's release is relative), else `MOVE(p,v)`.
//! - A cancel, a preemption and `~/stop` send `STOP()`, which returns the grip state to IDLE
//!   (shared note §3.7); `~/home` sends `HOME()`, `~/acknowledge` `FSACK()`.
//! - `joint_states` and the diagnostics poll `POS?`, `FORCE?` and `GRIPSTATE?` at the
//!   `joint_states` rate (at most 50 Hz). The text client does not reconnect: a lost link is
//!   reported in the diagnostics. At shutdown `BYE()` announces the disconnect.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures::future::BoxFuture;
use gripper::wsg::text::{Client, ClientConfig};
use gripper::wsg::{GripState, HomingDirection};
use ros2_client::Node;
use tokio::sync::watch;

use crate::action::{Actuator, Outcome};
use crate::gripper_node::{self, Services};
use crate::msgs::{GripperCommandFeedback, GripperCommandGoal, GripperCommandResult};
use crate::params::{Live, Params};
use crate::periodic;
use crate::telemetry::Shared;

/// The fastest telemetry polling: each reading is a round trip to the gripper.
const FASTEST_POLL: Duration = Duration::from_millis(20);

/// Connects to the WSG's text interface at the parameters' address.
pub async fn connect(params: &Params) -> Result<Client, String> {
    let mut addr = params.address.clone();
    if !addr.contains(':') {
        addr = format!("{addr}:{}", gripper::wsg::DEFAULT_PORT);
    }
    Client::connect_with(addr.as_str(), ClientConfig::default())
        .await
        .map_err(|e| format!("WSG text interface at {addr}: {e}"))
}

/// Serves `client` on `node` until `shutdown`.
pub async fn start(
    node: &mut Node,
    params: &Params,
    client: Client,
    live: &Live,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let telemetry = Shared::new("WSG (text interface)", &params.address);
    telemetry.lock().connected = true;
    let every = Duration::from_secs_f64(1.0 / params.joint_states_rate_hz).max(FASTEST_POLL);
    tokio::spawn(poll(
        client.clone(),
        every,
        telemetry.clone(),
        shutdown.clone(),
    ));
    let text = Text(Arc::new(Inner {
        client: client.clone(),
        telemetry: telemetry.clone(),
        params: params.clone(),
        target_mm: Mutex::new(None),
    }));
    type Call = fn(Client) -> BoxFuture<'static, gripper::wsg::text::Result<()>>;
    let handler = |call: Call| -> crate::trigger::Handler {
        let text = text.clone();
        Arc::new(move || {
            let text = text.clone();
            Box::pin(async move {
                let r = call(text.0.client.clone()).await;
                text.record(r).map(|()| "done".to_owned())
            })
        })
    };
    let services = Services {
        home: handler(|c| Box::pin(async move { c.home(HomingDirection::Default).await })),
        stop: handler(|c| Box::pin(async move { c.stop().await })),
        acknowledge: handler(|c| Box::pin(async move { c.ack_fast_stop().await })),
    };
    gripper_node::serve(
        node,
        params,
        &telemetry,
        Arc::new(text),
        services,
        live,
        shutdown,
    )
}

/// Width, force and grip state into the telemetry, every `every`.
async fn poll(client: Client, every: Duration, telemetry: Shared, shutdown: watch::Receiver<bool>) {
    periodic::every(every, shutdown, move || {
        let (client, telemetry) = (client.clone(), telemetry.clone());
        async move {
            let readings = async {
                Ok::<_, gripper::wsg::text::Error>((
                    client.position_mm().await?,
                    client.force_n().await?,
                    client.grip_state().await?,
                ))
            };
            match readings.await {
                Ok((width, force, grip)) => {
                    let mut t = telemetry.lock();
                    t.connected = true;
                    t.width_mm = Some(width);
                    t.force_n = Some(force);
                    t.holding = grip == GripState::Holding;
                    t.set_state("grip_state", format!("{grip:?}"));
                }
                Err(e) => {
                    telemetry.lock().connected = !client.is_closed();
                    telemetry.note_error(e.kind(), e.to_string());
                }
            }
        }
    })
    .await;
}

/// The text interface as the action's actuator.
#[derive(Clone)]
struct Text(Arc<Inner>);

struct Inner {
    client: Client,
    telemetry: Shared,
    params: Params,
    /// The running goal's opening, mm.
    target_mm: Mutex<Option<f64>>,
}

impl Text {
    fn record<T>(&self, r: gripper::wsg::text::Result<T>) -> Result<T, String> {
        r.map_err(|e| {
            self.0.telemetry.note_error(e.kind(), e.to_string());
            e.to_string()
        })
    }

    async fn run(&self, goal: GripperCommandGoal) -> Result<Outcome, gripper::wsg::text::Error> {
        let inner = &self.0;
        let client = &inner.client;
        let conv = inner.params.position_convention;
        let target = conv.to_width_mm(goal.command.position);
        *inner.target_mm.lock().unwrap_or_else(|e| e.into_inner()) = Some(target);
        let speed = inner.params.speed_m_per_s * 1000.0;
        let tolerance = inner.params.goal_tolerance_m * 1000.0;
        let width = client.position_mm().await?;
        let holding = client.grip_state().await? == GripState::Holding;
        let force = (goal.command.max_effort > 0.0).then_some(goal.command.max_effort);
        let (kind, moved) = if target < width - tolerance {
            ("grip", client.grip(force).await)
        } else if holding {
            let by = (target - width).max(0.0);
            ("release", client.release(Some(by), Some(speed)).await)
        } else {
            ("move", client.move_to(target, Some(speed)).await)
        };
        let width = client.position_mm().await?;
        let force = client.force_n().await?;
        let holding = client.grip_state().await? == GripState::Holding;
        let reached_goal = (width - target).abs() <= tolerance;
        let (failed, message) = match moved {
            Ok(()) => (
                false,
                format!("{kind} for {target:.2} mm ended at {width:.2} mm"),
            ),
            Err(e) => (true, format!("{kind} for {target:.2} mm: {e}")),
        };
        Ok(Outcome {
            failed,
            result: GripperCommandResult {
                position: conv.from_width_mm(width),
                effort: force,
                stalled: holding && !reached_goal,
                reached_goal,
            },
            message,
        })
    }
}

impl Actuator for Text {
    fn check(&self, goal: &GripperCommandGoal) -> Result<(), String> {
        // The gripper checks the range (E_RANGE_ERROR): such a goal aborts.
        crate::action::check_command(goal)
    }

    fn execute(&self, goal: GripperCommandGoal) -> BoxFuture<'static, Outcome> {
        let this = self.clone();
        Box::pin(async move {
            match this.run(goal).await {
                Ok(outcome) => outcome,
                Err(e) => {
                    let message = this.record::<()>(Err(e)).err().unwrap_or_default();
                    Outcome {
                        failed: true,
                        result: this.feedback(),
                        message,
                    }
                }
            }
        })
    }

    fn stop(&self) -> BoxFuture<'static, Result<(), String>> {
        let this = self.clone();
        Box::pin(async move {
            let r = this.0.client.stop().await;
            this.record(r)
        })
    }

    fn feedback(&self) -> GripperCommandFeedback {
        let t = self.0.telemetry.get();
        let width = t.width_mm.unwrap_or(0.0);
        let target = *self.0.target_mm.lock().unwrap_or_else(|e| e.into_inner());
        let tolerance = self.0.params.goal_tolerance_m * 1000.0;
        let reached_goal = target.is_some_and(|g| (width - g).abs() <= tolerance);
        GripperCommandFeedback {
            position: self.0.params.position_convention.from_width_mm(width),
            effort: t.force_n.unwrap_or(0.0),
            stalled: t.holding && !reached_goal,
            reached_goal,
        }
    }
}
