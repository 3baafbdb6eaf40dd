//! A WSG gripper (binary protocol over TCP, UDP or serial) as a ROS 2 gripper node.
//!
//! - Goals: opening (the goal's position, see `position_convention`) within the stroke, and
//!   `max_effort` 0 (keep the grasping force) or within the gripper's force limits (the
//!   grasping force, 0x32, is set before the move). A goal that opens, or closes by less than
//!   the goal tolerance, is a pre-position (0x21), or a release (0x26) while a part is held.
//! - A goal that closes **closes until contact**, whatever the part's width (MoveIt's "close" is
//!   0 m): a pre-position with "stop on block" (0x21, flag D1, manual 3.2.2) towards the goal;
//!   a part in the way stops it with E_AXIS_BLOCKED, and a grasp (0x25) at the width measured
//!   there then holds the part with the grasping force (`max_effort`). The result is the
//!   controller's: `stalled`, `reached_goal: false`, the position of the contact, the measured
//!   force as `effort`; the `allow_stalling` parameter makes that SUCCEEDED (else ABORTED, as
//!   gripper_action_controller does). With no part in the way the fingers reach the goal
//!   (`reached_goal`, SUCCEEDED). With `grasp_on_close: false` the blocked fingers are left
//!   where they stopped, without the grasp.
//! - `joint_states` and the diagnostics come from the WSG's auto-update streams (manual 3.4.1):
//!   width, speed and force at the `joint_states` rate, system and grip state on change, and
//!   the temperature once a second.
//! - A lost TCP or serial link reconnects (the crate's `ReconnectPolicy`): no homing, no goal
//!   resumed. An unannounced TCP loss leaves the WSG in FAST STOP (manual 1.4.2), which the
//!   diagnostics report; `auto_acknowledge_fast_stop` acknowledges it after a reconnect.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures::future::BoxFuture;
use futures::StreamExt;
use gripper::reconnect::ReconnectPolicy;
use gripper::wsg::{
    Client, Error, GripState, HomingDirection, Status, SystemLimits, SystemState, UpdateOptions,
};
use ros2_client::Node;
use tokio::sync::watch;

use crate::action::{Actuator, Outcome};
use crate::gripper_node::{self, Services};
use crate::msgs::{GripperCommandFeedback, GripperCommandGoal, GripperCommandResult};
use crate::params::Params;
use crate::periodic;
use crate::telemetry::{Shared, Telemetry};

/// Connects to the WSG the parameters name.
pub async fn connect(params: &Params) -> Result<Client, String> {
    let mut builder = Client::builder();
    if params.reconnect && params.transport != "udp" {
        builder = builder.reconnect(ReconnectPolicy::default());
    }
    let what = format!("WSG over {} at {}", params.transport, params.address);
    let client = match params.transport.as_str() {
        "tcp" => {
            let mut addr = params.address.clone();
            if !addr.contains(':') {
                addr = format!("{addr}:{}", gripper::wsg::DEFAULT_PORT);
            }
            builder.connect_tcp(addr.as_str()).await
        }
        "udp" => {
            let addr = params
                .address
                .parse()
                .map_err(|e| format!("address {:?}: {e}", params.address))?;
            builder.connect_udp(addr).await
        }
        "serial" => builder.open_serial(&params.serial_port, params.baud_rate),
        other => {
            return Err(format!(
                "transport {other:?}: expected tcp, udp, serial or text"
            ))
        }
    };
    client.map_err(|e| format!("{what}: {e}"))
}

/// Serves `client` on `node` until `shutdown`.
pub async fn start(
    node: &mut Node,
    params: &Params,
    client: Client,
    live: &crate::params::Live,
    shutdown: &watch::Receiver<bool>,
) -> Result<(), String> {
    let info = client
        .system_info()
        .await
        .map_err(|e| format!("system info: {e}"))?;
    let limits = client
        .system_limits()
        .await
        .map_err(|e| format!("system limits: {e}"))?;
    let device = format!("{:?}", info.device_type);
    let hardware_id = format!(
        "{device} serial {} at {}",
        info.serial_number,
        where_(params)
    );
    let telemetry = Shared::new(&device, &hardware_id);
    telemetry.lock().connected = true;
    feed(&client, params, &telemetry).await?;
    tokio::spawn(watch_link(
        client.clone(),
        params.clone(),
        telemetry.clone(),
    ));
    tokio::spawn(poll_temperature(
        client.clone(),
        telemetry.clone(),
        shutdown.clone(),
    ));

    let wsg = Wsg(Arc::new(Inner {
        client: client.clone(),
        telemetry: telemetry.clone(),
        params: params.clone(),
        limits,
        target_mm: Mutex::new(None),
        stops: AtomicU64::new(0),
    }));
    let services = Services {
        home: handler(&wsg, |c| {
            Box::pin(async move { c.home(HomingDirection::Default).await })
        }),
        stop: handler(&wsg, |c| Box::pin(async move { c.stop().await })),
        acknowledge: handler(&wsg, |c| {
            Box::pin(async move { c.acknowledge_fast_stop().await })
        }),
    };
    gripper_node::serve(
        node,
        params,
        &telemetry,
        Arc::new(wsg),
        services,
        live,
        shutdown,
    )
}

fn where_(params: &Params) -> String {
    match params.transport.as_str() {
        "serial" => params.serial_port.clone(),
        _ => params.address.clone(),
    }
}

type Call = fn(Client) -> BoxFuture<'static, gripper::wsg::Result<()>>;

fn handler(wsg: &Wsg, call: Call) -> crate::trigger::Handler {
    let wsg = wsg.clone();
    Arc::new(move || {
        let wsg = wsg.clone();
        Box::pin(async move {
            let r = call(wsg.0.client.clone()).await;
            wsg.record(r)
                .map(|()| "done".to_owned())
                .map_err(|e| e.to_string())
        })
    })
}

/// The auto-update streams into the telemetry.
async fn feed(client: &Client, params: &Params, telemetry: &Shared) -> Result<(), String> {
    // The device's range: 10..=65535 ms (manual 3.4.1).
    let period_ms = (1000.0 / params.joint_states_rate_hz).clamp(10.0, 65_535.0);
    let every = UpdateOptions::periodic(Duration::from_millis(period_ms as u64));
    let on_change = UpdateOptions::on_change(Duration::from_millis(10));
    let e = |what: &str, e: Error| format!("auto-update of the {what}: {e}");
    let width = client
        .subscribe_width_mm(every)
        .await
        .map_err(|x| e("width", x))?;
    let speed = client
        .subscribe_speed_mm_per_s(every)
        .await
        .map_err(|x| e("speed", x))?;
    let force = client
        .subscribe_force_n(every)
        .await
        .map_err(|x| e("force", x))?;
    let system = client
        .subscribe_system_state(on_change)
        .await
        .map_err(|x| e("system state", x))?;
    let grip = client
        .subscribe_grip_state(on_change)
        .await
        .map_err(|x| e("grip state", x))?;
    spawn_feed(width, telemetry, |t, v| t.width_mm = Some(f64::from(v)));
    spawn_feed(speed, telemetry, |t, v| {
        t.speed_mm_per_s = Some(f64::from(v))
    });
    spawn_feed(force, telemetry, |t, v| t.force_n = Some(f64::from(v)));
    spawn_feed(system, telemetry, apply_system_state);
    spawn_feed(grip, telemetry, apply_grip_state);
    Ok(())
}

fn spawn_feed<T: Send + 'static>(
    mut stream: gripper::wsg::Subscription<T>,
    telemetry: &Shared,
    apply: fn(&mut Telemetry, T),
) {
    let telemetry = telemetry.clone();
    tokio::spawn(async move {
        // Ends when the client closes or gives up reconnecting.
        while let Some(v) = stream.next().await {
            apply(&mut telemetry.lock(), v);
        }
    });
}

/// Faults and warnings of the system state (manual, Anhang B), under the crate's flag names.
const FAULTS: [(SystemState, &str); 5] = [
    (SystemState::TEMP_FAULT, "TEMP_FAULT"),
    (SystemState::POWER_FAULT, "POWER_FAULT"),
    (SystemState::CURR_FAULT, "CURR_FAULT"),
    (SystemState::FINGER_FAULT, "FINGER_FAULT"),
    (SystemState::SCRIPT_FAILURE, "SCRIPT_FAILURE"),
];
const WARNINGS: [(SystemState, &str); 2] = [
    (SystemState::TEMP_WARNING, "TEMP_WARNING"),
    (SystemState::CMD_FAILURE, "CMD_FAILURE"),
];

/// Takes a system state into the telemetry.
pub fn apply_system_state(t: &mut Telemetry, s: SystemState) {
    let named = |list: &[(SystemState, &str)]| {
        list.iter()
            .filter(|(f, _)| s.contains(*f))
            .map(|(_, n)| (*n).to_owned())
            .collect::<Vec<_>>()
    };
    t.fast_stop = s.contains(SystemState::FAST_STOP);
    t.faults = named(&FAULTS);
    t.warnings = named(&WARNINGS);
    let flags = format!("{s:?}");
    let flags = flags
        .strip_prefix("SystemState(")
        .and_then(|f| f.strip_suffix(')'))
        .unwrap_or(&flags)
        .to_owned();
    t.set_state("system_state", flags);
    t.set_state(
        "referenced",
        s.contains(SystemState::REFERENCED).to_string(),
    );
}

fn apply_grip_state(t: &mut Telemetry, g: GripState) {
    t.holding = g == GripState::Holding;
    t.set_state("grip_state", format!("{g:?}"));
}

/// Follows the link. A FAST STOP found after a reconnect is acknowledged only with
/// `auto_acknowledge_fast_stop`.
async fn watch_link(client: Client, params: Params, telemetry: Shared) {
    let events = client.connection_events();
    let t = telemetry.clone();
    crate::link::follow(events, "WSG", telemetry, || async {
        if params.auto_acknowledge_fast_stop {
            acknowledge_after_reconnect(&client, &t).await;
        }
    })
    .await;
}

async fn acknowledge_after_reconnect(client: &Client, telemetry: &Shared) {
    match client.system_state().await {
        Ok(s) if s.contains(SystemState::FAST_STOP) => {
            tracing::warn!(
                "FAST STOP after the reconnect: acknowledged (auto_acknowledge_fast_stop)"
            );
            if let Err(e) = client.acknowledge_fast_stop().await {
                telemetry.note_error(e.kind(), format!("acknowledge after reconnect: {e}"));
            }
        }
        Ok(_) => {}
        Err(e) => telemetry.note_error(e.kind(), format!("system state after reconnect: {e}")),
    }
}

/// The temperature (0x46) once a second into the diagnostics.
async fn poll_temperature(client: Client, telemetry: Shared, shutdown: watch::Receiver<bool>) {
    periodic::every(crate::diagnostics::PERIOD, shutdown, move || {
        let (client, telemetry) = (client.clone(), telemetry.clone());
        async move {
            if !telemetry.lock().connected {
                return;
            }
            match client.temperature_c().await {
                Ok(c) => telemetry.lock().temperature_c = Some(f64::from(c)),
                Err(e) => telemetry.note_error(e.kind(), e.to_string()),
            }
        }
    })
    .await;
}

/// The WSG as the action's actuator.
#[derive(Clone)]
struct Wsg(Arc<Inner>);

struct Inner {
    client: Client,
    telemetry: Shared,
    params: Params,
    limits: SystemLimits,
    /// The running goal's opening, mm (for the feedback's `reached_goal`).
    target_mm: Mutex<Option<f64>>,
    /// Stops sent for a cancel or a preemption: a goal that sees this change sends no further
    /// motion (no grasp after its closing move was stopped).
    stops: AtomicU64,
}

impl Wsg {
    fn record<T>(&self, r: gripper::wsg::Result<T>) -> gripper::wsg::Result<T> {
        if let Err(e) = &r {
            self.0.telemetry.note_error(e.kind(), e.to_string());
        }
        r
    }

    fn tolerance_mm(&self) -> f64 {
        self.0.params.goal_tolerance_m * 1000.0
    }

    fn position(&self, width_mm: f64) -> f64 {
        self.0.params.position_convention.from_width_mm(width_mm)
    }

    async fn run(&self, goal: GripperCommandGoal) -> Outcome {
        match self.motion(goal).await {
            Ok(outcome) => outcome,
            Err(e) => {
                let r = self.record::<()>(Err(e));
                let message = r.err().map(|e| e.to_string()).unwrap_or_default();
                Outcome {
                    failed: true,
                    result: self.feedback(),
                    message,
                }
            }
        }
    }

    async fn motion(&self, goal: GripperCommandGoal) -> gripper::wsg::Result<Outcome> {
        let inner = &self.0;
        let client = &inner.client;
        let stops = inner.stops.load(Ordering::SeqCst);
        let target = inner
            .params
            .position_convention
            .to_width_mm(goal.command.position);
        *inner.target_mm.lock().unwrap_or_else(|e| e.into_inner()) = Some(target);
        let speed = (inner.params.speed_m_per_s * 1000.0) as f32;
        let speed = speed.clamp(
            inner.limits.min_speed_mm_per_s,
            inner.limits.max_speed_mm_per_s,
        );
        if goal.command.max_effort > 0.0 {
            client
                .set_grasping_force(goal.command.max_effort as f32)
                .await?;
        }
        let width = f64::from(client.width_mm().await?);
        let holding = client.grip_state().await? == GripState::Holding;
        let closing = target < width - self.tolerance_mm();
        let (kind, moved) = if closing {
            // Stops on a part in the way (stop on block), wherever it is.
            ("close", client.pre_position(target as f32, speed).await)
        } else if holding {
            ("release", client.release(target as f32, speed).await)
        } else {
            (
                "pre-position",
                client.pre_position(target as f32, speed).await,
            )
        };
        let blocked = matches!(&moved, Err(e) if e.status() == Some(Status::AxisBlocked));
        // Contact: grasp the part where the fingers stopped, so that it is held with the
        // grasping force (a blocked pre-position does not keep pressing, 3.2.2) and the WSG
        // watches it (grip state HOLDING, PART LOST). Not after a stop of this goal.
        let mut grasped = None;
        if closing
            && blocked
            && inner.params.grasp_on_close
            && inner.stops.load(Ordering::SeqCst) == stops
        {
            let contact = client.width_mm().await?;
            grasped = Some((contact, client.grasp(contact, speed).await));
        }
        // Where the fingers ended, whatever the motion's status.
        let width = f64::from(client.width_mm().await?);
        let force = f64::from(client.force_n().await?);
        let holding = client.grip_state().await? == GripState::Holding;
        let reached_goal = (width - target).abs() <= self.tolerance_mm();
        let result = GripperCommandResult {
            position: self.position(width),
            effort: force,
            stalled: (holding || blocked) && !reached_goal,
            reached_goal,
        };
        let (failed, message) = match (moved, grasped) {
            (Ok(()), _) => (
                false,
                format!("{kind} to {target:.2} mm ended at {width:.2} mm"),
            ),
            (Err(_), Some((contact, Ok(())))) => (
                false,
                format!("{kind} to {target:.2} mm: contact at {contact:.2} mm, holding with {force:.1} N"),
            ),
            (Err(_), Some((contact, Err(e)))) => {
                let _ = self.record::<()>(Err(e));
                let why = self.last_error();
                (true, format!("{kind} to {target:.2} mm: grasp at the contact, {contact:.2} mm: {why}"))
            }
            (Err(_), None) if blocked => (
                false,
                format!("{kind} to {target:.2} mm blocked at {width:.2} mm"),
            ),
            (Err(e), None) => {
                let _ = self.record::<()>(Err(e));
                let why = self.last_error();
                (true, format!("{kind} to {target:.2} mm: {why}"))
            }
        };
        Ok(Outcome {
            failed,
            result,
            message,
        })
    }

    fn last_error(&self) -> String {
        self.0
            .telemetry
            .lock()
            .last_error
            .clone()
            .unwrap_or_default()
    }
}

impl Actuator for Wsg {
    fn check(&self, goal: &GripperCommandGoal) -> Result<(), String> {
        crate::action::check_command(goal)?;
        let c = goal.command;
        let limits = &self.0.limits;
        let width = self.0.params.position_convention.to_width_mm(c.position);
        if width > f64::from(limits.stroke_mm) {
            return Err(format!(
                "an opening of {width:.2} mm exceeds the stroke of {} mm",
                limits.stroke_mm
            ));
        }
        let (min, max) = (
            f64::from(limits.min_force_n),
            f64::from(limits.nominal_force_n),
        );
        if c.max_effort > 0.0 && !(min..=max).contains(&c.max_effort) {
            return Err(format!(
                "max_effort {} N: 0 (keep the setting) or {min}..={max} N",
                c.max_effort
            ));
        }
        Ok(())
    }

    fn execute(&self, goal: GripperCommandGoal) -> BoxFuture<'static, Outcome> {
        let this = self.clone();
        Box::pin(async move { this.run(goal).await })
    }

    fn stop(&self) -> BoxFuture<'static, Result<(), String>> {
        let this = self.clone();
        this.0.stops.fetch_add(1, Ordering::SeqCst);
        Box::pin(async move {
            let r = this.0.client.stop().await;
            this.record(r).map_err(|e| e.to_string())
        })
    }

    fn feedback(&self) -> GripperCommandFeedback {
        let t = self.0.telemetry.get();
        let width = t.width_mm.unwrap_or(0.0);
        let target = *self.0.target_mm.lock().unwrap_or_else(|e| e.into_inner());
        let reached_goal = target.is_some_and(|g| (width - g).abs() <= self.tolerance_mm());
        GripperCommandFeedback {
            position: self.position(width),
            effort: t.force_n.unwrap_or(0.0),
            stalled: t.holding && !reached_goal,
            reached_goal,
        }
    }
}
