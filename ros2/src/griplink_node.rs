//! One port of a Weiss GRIPLINK controller (ASCII over TCP) as a ROS 2 gripper node.
//!
//! - Goals: a goal that closes is `FLEXGRIPF` with the goal's opening as the no-part limit and
//!   `max_effort` (or `default_effort_n`) as the force (manual 3.4.6): the device's own
//!   part-agnostic grip, which closes until contact whatever the part's width (MoveIt's
//!   "close", 0 m, included). One that opens is `FLEXRELEASEF` to that opening (3.4.7). Both
//!   are waited for by polling (`DEVSTATE`, `VALUE`), which keeps the connection free for other
//!   commands. A grip ends HOLDING (`stalled`, the commanded force as `effort`: the controller
//!   reads no force; SUCCEEDED with `allow_stalling`, else ABORTED, as gripper_action_controller
//!   decides) or NO PART (the fingers at the limit: `reached_goal`, SUCCEEDED); DS_FAULT aborts.
//! - A cancel or a preemption: GRIPLINK has no stop command; `DISABLE(p)` aborts a motion and
//!   **frees the fingers** (3.4.2: "disable the actuator thus allowing to move the fingers by
//!   hand"). So a cancel sends it only while a motion runs: during a grip that already holds
//!   (DEVSTATE DS_HOLDING) it sends nothing and the part stays held; during a grip still
//!   closing (no part clamped yet) or a release (letting go anyway) it sends `DISABLE`. The
//!   state is read just before: a grip that clamps within that one round trip is let go. It
//!   goes out behind at most the one command on the wire (the client keeps one unanswered
//!   command at a time). `~/stop` always sends `DISABLE(p)`; `~/acknowledge` sends `ENABLE(p)`
//!   (3.4.1); GRIP, RELEASE and HOME re-enable a Weiss gripper too.
//! - `joint_states` and the diagnostics poll `VALUEF[p][0]` (position) and `DEVSTATE` at the
//!   `joint_states` rate (at most 50 Hz).
//! - A lost link reconnects (the crate's `ReconnectPolicy`): no homing, no goal resumed. At
//!   shutdown the session ends with `BYE()`.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures::future::BoxFuture;
use futures::StreamExt;
use gripper::griplink::{
    Client, ClientConfig, DeviceState, Error, FlexGrip, FlexRelease, GripOutcome, Port,
    ReleaseOutcome, WaitBy,
};
use gripper::reconnect::ReconnectPolicy;
use ros2_client::Node;
use tokio::sync::watch;

use crate::action::{Actuator, Outcome};
use crate::gripper_node::{self, Services};
use crate::msgs::{GripperCommandFeedback, GripperCommandGoal, GripperCommandResult};
use crate::params::Params;
use crate::telemetry::{Shared, Telemetry};

/// How often a motion's end is polled.
const MOTION_POLL: Duration = Duration::from_millis(20);
/// The fastest telemetry polling: each reading is a round trip to the controller.
const FASTEST_POLL: Duration = Duration::from_millis(20);

/// Connects to the GRIPLINK the parameters name.
pub async fn connect(params: &Params) -> Result<Client, String> {
    let mut addr = params.address.clone();
    if !addr.contains(':') {
        addr = format!("{addr}:{}", gripper::griplink::DEFAULT_PORT);
    }
    let config = ClientConfig {
        reconnect: params.reconnect.then(ReconnectPolicy::default),
        ..ClientConfig::default()
    };
    Client::connect_with(addr.as_str(), config)
        .await
        .map_err(|e| format!("GRIPLINK at {addr}: {e}"))
}

/// Serves port `griplink_port` of `client` on `node` until `shutdown`.
pub async fn start(
    node: &mut Node,
    params: &Params,
    client: Client,
    live: &crate::params::Live,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let port = client.port(params.griplink_port);
    let name = port
        .name()
        .await
        .map_err(|e| format!("port {}: {e}", params.griplink_port))?;
    let serial = port
        .serial_number()
        .await
        .map_err(|e| format!("serial number: {e}"))?;
    let controller = client
        .id()
        .await
        .map_err(|e| format!("controller id: {e}"))?;
    let hardware_id = format!(
        "{name} serial {serial} on {controller} port {} at {}",
        params.griplink_port, params.address
    );
    let telemetry = Shared::new(&name, &hardware_id);
    telemetry.lock().connected = true;
    let every = Duration::from_secs_f64(1.0 / params.joint_states_rate_hz).max(FASTEST_POLL);
    tokio::spawn(feed_position(
        port.clone(),
        every,
        telemetry.clone(),
        shutdown.clone(),
    ));
    tokio::spawn(feed_state(
        port.clone(),
        every,
        telemetry.clone(),
        shutdown.clone(),
    ));
    let events = client.connection_events();
    let t = telemetry.clone();
    tokio::spawn(async move {
        crate::link::follow(events, "GRIPLINK", t, || async {}).await;
    });

    let griplink = Griplink(Arc::new(Inner {
        port: port.clone(),
        telemetry: telemetry.clone(),
        params: params.clone(),
        target_mm: Mutex::new(None),
        force_n: Mutex::new(0.0),
        gripping: Mutex::new(false),
    }));
    let services = Services {
        home: handler(&griplink, |p| Box::pin(async move { p.home().await })),
        stop: handler(&griplink, |p| Box::pin(async move { p.disable().await })),
        acknowledge: handler(&griplink, |p| Box::pin(async move { p.enable().await })),
    };
    gripper_node::serve(
        node,
        params,
        &telemetry,
        Arc::new(griplink),
        services,
        live,
        shutdown,
    )
}

type Call = fn(Port) -> BoxFuture<'static, gripper::griplink::Result<()>>;

fn handler(g: &Griplink, call: Call) -> crate::trigger::Handler {
    let g = g.clone();
    Arc::new(move || {
        let g = g.clone();
        Box::pin(async move {
            let r = call(g.0.port.clone()).await;
            g.record(r).map(|()| "done".to_owned())
        })
    })
}

async fn feed_position(
    port: Port,
    every: Duration,
    telemetry: Shared,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut watch = port.watch_value(0, every);
    loop {
        let reading = tokio::select! {
            r = watch.next() => r,
            _ = shutdown.wait_for(|s| *s) => return,
        };
        match reading {
            Some(Ok(mm)) => telemetry.lock().width_mm = Some(mm),
            Some(Err(e)) => telemetry.note_error(e.kind(), e.to_string()),
            None => return,
        }
    }
}

async fn feed_state(
    port: Port,
    every: Duration,
    telemetry: Shared,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut watch = port.watch_state(every);
    loop {
        let reading = tokio::select! {
            r = watch.next() => r,
            _ = shutdown.wait_for(|s| *s) => return,
        };
        match reading {
            Some(Ok(s)) => apply_state(&mut telemetry.lock(), s),
            Some(Err(e)) => telemetry.note_error(e.kind(), e.to_string()),
            None => return,
        }
    }
}

/// Takes a device state (manual chapter 5) into the telemetry.
pub fn apply_state(t: &mut Telemetry, s: DeviceState) {
    t.holding = s == DeviceState::Holding;
    t.faults = if s == DeviceState::Fault {
        vec!["DS_FAULT".to_owned()]
    } else {
        Vec::new()
    };
    t.warnings = match s {
        DeviceState::NotInitialized => vec!["DS_NOT_INITIALIZED: call ~/home".to_owned()],
        DeviceState::NotConnected => vec!["DS_NOT_CONNECTED: no device on the port".to_owned()],
        _ => Vec::new(),
    };
    t.set_state("device_state", format!("{s:?}"));
}

/// A GRIPLINK port as the action's actuator.
#[derive(Clone)]
struct Griplink(Arc<Inner>);

struct Inner {
    port: Port,
    telemetry: Shared,
    params: Params,
    /// The running goal's opening, mm.
    target_mm: Mutex<Option<f64>>,
    /// The force of the last grip, N (the effort while it holds).
    force_n: Mutex<f64>,
    /// The running goal is a grip (not a release): a cancel finding DS_HOLDING leaves it held.
    gripping: Mutex<bool>,
}

impl Griplink {
    fn record<T>(&self, r: gripper::griplink::Result<T>) -> Result<T, String> {
        r.map_err(|e| {
            self.0.telemetry.note_error(e.kind(), e.to_string());
            e.to_string()
        })
    }

    fn force(&self, goal: &GripperCommandGoal) -> f64 {
        if goal.command.max_effort > 0.0 {
            goal.command.max_effort
        } else {
            self.0.params.default_effort_n
        }
    }

    async fn run(&self, goal: GripperCommandGoal) -> Outcome {
        let inner = &self.0;
        let conv = inner.params.position_convention;
        let target = conv.to_width_mm(goal.command.position);
        *inner.target_mm.lock().unwrap_or_else(|e| e.into_inner()) = Some(target);
        let speed = inner.params.speed_m_per_s * 1000.0;
        let by = WaitBy::Polling(MOTION_POLL);
        let width = match inner.port.position_mm().await {
            Ok(w) => w,
            Err(e) => return self.failed(e),
        };
        let tolerance = inner.params.goal_tolerance_m * 1000.0;
        let closing = target < width - tolerance;
        *inner.gripping.lock().unwrap_or_else(|e| e.into_inner()) = closing;
        // A grip in DS_HOLDING is a state conflict (3.4.4 GRIP, 3.4.6 FLEXGRIP): a close of a
        // part already held is that stall, reported without a command.
        let held = closing
            && match inner.port.state().await {
                Ok(s) => s == DeviceState::Holding,
                Err(e) => return self.failed(e),
            };
        let (ok, stalled, what) = if held {
            (true, true, "grip: the part is already held")
        } else if closing {
            let force = self.force(&goal);
            *inner.force_n.lock().unwrap_or_else(|e| e.into_inner()) = force;
            let grip = FlexGrip {
                position_mm: target,
                force_n: force,
                speed_mm_per_s: speed,
                acceleration_mm_per_s2: 0.0,
            };
            match inner.port.flex_grip_and_wait(grip, by).await {
                Ok(GripOutcome::Holding) => (true, true, "grip: holding a part"),
                Ok(GripOutcome::NoPart) => (true, false, "grip: no part, at the limit"),
                Ok(GripOutcome::Fault) => (false, false, "grip: DS_FAULT"),
                Err(e) => return self.failed(e),
            }
        } else {
            let release = FlexRelease {
                position_mm: target,
                speed_mm_per_s: speed,
                acceleration_mm_per_s2: 0.0,
            };
            match inner.port.flex_release_and_wait(release, by).await {
                Ok(ReleaseOutcome::Released) => (true, false, "release: at the position"),
                Ok(ReleaseOutcome::Fault) => (false, false, "release: DS_FAULT"),
                Err(e) => return self.failed(e),
            }
        };
        let width = match inner.port.position_mm().await {
            Ok(w) => w,
            Err(e) => return self.failed(e),
        };
        let force = *inner.force_n.lock().unwrap_or_else(|e| e.into_inner());
        let reached_goal = (width - target).abs() <= tolerance;
        Outcome {
            failed: !ok,
            result: GripperCommandResult {
                position: conv.from_width_mm(width),
                effort: if stalled { force } else { 0.0 },
                stalled: stalled && !reached_goal,
                reached_goal,
            },
            message: format!("{what}; {width:.2} mm for {target:.2} mm"),
        }
    }

    fn failed(&self, e: Error) -> Outcome {
        let message = self.record::<()>(Err(e)).err().unwrap_or_default();
        Outcome {
            failed: true,
            result: self.feedback(),
            message,
        }
    }
}

impl Actuator for Griplink {
    fn check(&self, goal: &GripperCommandGoal) -> Result<(), String> {
        crate::action::check_command(goal)?;
        let c = goal.command;
        let width = self.0.params.position_convention.to_width_mm(c.position);
        let closing = self
            .0
            .telemetry
            .lock()
            .width_mm
            .is_some_and(|w| width < w - self.0.params.goal_tolerance_m * 1000.0);
        if closing && self.force(goal) <= 0.0 {
            return Err(
                "a grip needs a force: give max_effort, or set the default_effort_n parameter"
                    .to_owned(),
            );
        }
        // The device checks the range against its stroke (ERR RANGE): such a goal aborts.
        Ok(())
    }

    fn execute(&self, goal: GripperCommandGoal) -> BoxFuture<'static, Outcome> {
        let this = self.clone();
        Box::pin(async move { this.run(goal).await })
    }

    fn stop(&self) -> BoxFuture<'static, Result<(), String>> {
        let this = self.clone();
        Box::pin(async move {
            let gripping = *this.0.gripping.lock().unwrap_or_else(|e| e.into_inner());
            if gripping {
                let state = this.0.port.state().await;
                if this.record(state)? == DeviceState::Holding {
                    tracing::info!("stop: the grip holds a part; nothing sent, it stays held");
                    return Ok(());
                }
            }
            let r = this.0.port.disable().await;
            this.record(r)
        })
    }

    fn feedback(&self) -> GripperCommandFeedback {
        let t = self.0.telemetry.get();
        let width = t.width_mm.unwrap_or(0.0);
        let target = *self.0.target_mm.lock().unwrap_or_else(|e| e.into_inner());
        let force = *self.0.force_n.lock().unwrap_or_else(|e| e.into_inner());
        let tolerance = self.0.params.goal_tolerance_m * 1000.0;
        let reached_goal = target.is_some_and(|g| (width - g).abs() <= tolerance);
        GripperCommandFeedback {
            position: self.0.params.position_convention.from_width_mm(width),
            effort: if t.holding { force } else { 0.0 },
            stalled: t.holding && !reached_goal,
            reached_goal,
        }
    }
}
