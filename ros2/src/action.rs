//! The `control_msgs/action/GripperCommand` server: goals, cancels and results over
//! ros2-client's plain [`ActionServer`], with our own goal bookkeeping.
//!
//! ros2-client's `AsyncActionServer` is not used: in 0.12.1 its `abort_*_goal` never answers a
//! pending `get_result`, `send_result_response` blocks until the client asks for the result, a
//! `get_result` that arrives after the goal finished is never answered, and cancel requests are
//! read only while the application polls for them. Here:
//! - every `get_result` is answered: at once for a finished goal (the last
//!   [`FINISHED_GOALS_KEPT`] are kept), when the goal ends for a running one, and with
//!   STATUS_UNKNOWN for a goal id never seen (as rclcpp_action does);
//! - cancel requests are read all the time, and a cancel of the running goal sends the device's
//!   stop at once, never queued behind the motion;
//! - a new goal **preempts** the running one, as ros2_controllers' gripper_action_controller
//!   does (`preempt_active_goal`): the running goal ends CANCELED at once, the new one is
//!   accepted; its motion starts once the device has stopped the old one (a WSG refuses a motion
//!   while another runs, E_ALREADY_RUNNING, manual 3.2.2). A goal the device cannot carry out
//!   is rejected without disturbing the running one, as rclcpp_action rejects it before the
//!   controller's `accepted_callback` preempts;
//! - a goal ends as the controller's `check_for_success` ends it: SUCCEEDED when the position
//!   was reached; when the fingers stalled short of it (a part held, a blocked axis),
//!   SUCCEEDED with `allow_stalling` and ABORTED without (the controller's parameter and
//!   default); ABORTED when the device failed the command.
//!
//! ros2-client's servers hand out requests through `&mut` accessors or non-blocking reads, so
//! the three services are read every [`POLL_PERIOD`].

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use futures::future::BoxFuture;
use ros2_client::action::{
    ActionServerQosPolicies, CancelGoalRequest, CancelGoalResponse, GetResultResponse, GoalId,
    GoalInfo, GoalStatusEnum, SendGoalResponse,
};
use ros2_client::action_msgs::{CancelGoalResponseEnum, GoalStatus, GoalStatusArray};
use ros2_client::builtin_interfaces::Time;
use ros2_client::{ActionServer, RmwRequestId, ServiceMapping};
use tokio::sync::{oneshot, watch};

use crate::msgs::{GripperCommandFeedback, GripperCommandGoal, GripperCommandResult};
use crate::{qos, rpc};

/// How often the goal, cancel and result services are read.
pub const POLL_PERIOD: Duration = Duration::from_millis(10);
/// How often a running goal publishes feedback.
pub const FEEDBACK_PERIOD: Duration = Duration::from_millis(100);
/// How long a cancelled goal waits, after the device acknowledged the stop, for its motion to
/// report where it ended (the WSG answers the motion with E_CMD_ABORTED at once). A motion
/// still waiting then (GRIPLINK's wait for a state transition that a DISABLE never brings) is
/// abandoned, and the result is the latest reading.
pub const CANCEL_GRACE: Duration = Duration::from_millis(500);
/// Finished goals whose result is kept for a late `get_result`.
pub const FINISHED_GOALS_KEPT: usize = 16;
/// `get_result` requests waiting for one running goal, at most; more are answered
/// STATUS_UNKNOWN at once (a bounded buffer; no client needs this many).
pub const RESULT_WAITERS_MAX: usize = 64;

/// Our server type.
pub type GripperActionServer =
    ActionServer<GripperCommandGoal, GripperCommandResult, GripperCommandFeedback>;

/// The action's servers, one per request/reply mapping served (see [`crate::rpc`]); a request
/// is answered through the server that received it. Feedback and statuses, plain topics, are
/// published through the first.
pub type Servers = [(ServiceMapping, GripperActionServer)];

/// At most this many requests of one kind are read from one server in a round: a reader that
/// keeps failing must not hold the loop.
const READS_PER_ROUND: usize = 64;

/// A request's return address: the server that received it and its id.
#[derive(Clone, Copy, Debug)]
struct Caller {
    server: usize,
    id: RmwRequestId,
}

/// The QoS of the action's services and topics: rcl_action's defaults (services reliable and
/// volatile, keep last 10; status transient-local keep last 1, so a late client sees it).
pub fn action_qos() -> ActionServerQosPolicies {
    ActionServerQosPolicies {
        goal_service: qos::services(),
        result_service: qos::services(),
        cancel_service: qos::services(),
        feedback_publisher: qos::topic(),
        status_publisher: qos::status(),
    }
}

/// How a goal ended on the device.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The device failed the goal (a fault, an error reply, a lost link): ABORTED whatever the
    /// result says. Otherwise [`verdict`] decides from the result.
    pub failed: bool,
    /// The result to send.
    pub result: GripperCommandResult,
    /// Why, for the log.
    pub message: String,
}

/// The status a goal ends with, as gripper_action_controller's `check_for_success` gives it:
/// the position reached is SUCCEEDED; fingers that stalled before it (a part held, a blocked
/// axis) are SUCCEEDED with `allow_stalling`, ABORTED without; anything else, or a device
/// failure, is ABORTED.
pub fn verdict(outcome: &Outcome, allow_stalling: bool) -> GoalStatusEnum {
    let r = &outcome.result;
    if outcome.failed {
        GoalStatusEnum::Aborted
    } else if r.reached_goal || (r.stalled && allow_stalling) {
        GoalStatusEnum::Succeeded
    } else {
        GoalStatusEnum::Aborted
    }
}

/// The checks every device makes before accepting a goal: a position that is an opening
/// (finite, not negative) and a force that is one (finite, not negative; 0 = the default).
pub fn check_command(goal: &GripperCommandGoal) -> Result<(), String> {
    let c = goal.command;
    if !c.position.is_finite() || c.position < 0.0 {
        return Err(format!("position {} m is not an opening", c.position));
    }
    if !c.max_effort.is_finite() || c.max_effort < 0.0 {
        return Err(format!("max_effort {} N is not a force", c.max_effort));
    }
    Ok(())
}

/// What the action needs from a device.
pub trait Actuator: Send + Sync + 'static {
    /// Checks a goal before it is accepted; `Err` rejects it with that reason.
    fn check(&self, goal: &GripperCommandGoal) -> Result<(), String>;
    /// Runs an accepted goal to its end (the device's own timeouts bound it).
    fn execute(&self, goal: GripperCommandGoal) -> BoxFuture<'static, Outcome>;
    /// Stops the fingers now (a cancel).
    fn stop(&self) -> BoxFuture<'static, Result<(), String>>;
    /// The current position, effort and state, for feedback and a cancelled goal's result.
    fn feedback(&self) -> GripperCommandFeedback;
}

/// A goal's task, aborted when dropped: a motion abandoned after a cancel or a preemption must
/// not go on polling the device.
struct Motion(tokio::task::JoinHandle<()>);

impl Drop for Motion {
    fn drop(&mut self) {
        self.0.abort();
    }
}

impl Motion {
    /// Waits up to [`CANCEL_GRACE`] for a stopped motion to end, else abandons it.
    async fn end_within_grace(mut self) {
        if tokio::time::timeout(CANCEL_GRACE, &mut self.0)
            .await
            .is_err()
        {
            tracing::warn!("a stopped motion did not end within {CANCEL_GRACE:?}: abandoned");
        }
    }
}

struct Active {
    info: GoalInfo,
    status: GoalStatusEnum,
    done: oneshot::Receiver<Outcome>,
    /// The task running the motion (aborted when a cancelled motion does not end by itself).
    task: Motion,
    /// The stop of a cancel, while it runs.
    stopping: Option<oneshot::Receiver<Result<(), String>>>,
    /// After a successful stop: when to stop waiting for the motion to report its end.
    give_up_at: Option<tokio::time::Instant>,
    waiters: Vec<Caller>,
}

/// What happened to the running goal.
enum GoalEvent {
    /// Its motion ended (`None`: its task ended without reporting).
    Ended(Option<Outcome>),
    /// The stop of a cancel was answered.
    Stopped(Result<(), String>),
    /// [`CANCEL_GRACE`] passed after the stop without the motion reporting its end.
    GaveUp,
}

impl Active {
    async fn next_event(&mut self) -> GoalEvent {
        let give_up = async {
            match self.give_up_at {
                Some(at) => tokio::time::sleep_until(at).await,
                None => std::future::pending().await,
            }
        };
        let stopping = async {
            match self.stopping.as_mut() {
                Some(rx) => rx
                    .await
                    .unwrap_or_else(|_| Err("the stop task ended".into())),
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            outcome = &mut self.done => GoalEvent::Ended(outcome.ok()),
            result = stopping => GoalEvent::Stopped(result),
            () = give_up => GoalEvent::GaveUp,
        }
    }
}

struct Finished {
    info: GoalInfo,
    status: GoalStatusEnum,
    result: GripperCommandResult,
}

/// The goal bookkeeping of one action server.
pub struct GoalKeeper {
    actuator: Arc<dyn Actuator>,
    /// gripper_action_controller's `allow_stalling`: a stall is SUCCEEDED, not ABORTED.
    allow_stalling: Arc<std::sync::atomic::AtomicBool>,
    active: Option<Active>,
    finished: VecDeque<Finished>,
}

impl GoalKeeper {
    /// A keeper for goals that `actuator` carries out; `allow_stalling` is read when a goal
    /// ends (the parameter can be set while the node runs).
    pub fn new(
        actuator: Arc<dyn Actuator>,
        allow_stalling: Arc<std::sync::atomic::AtomicBool>,
    ) -> Self {
        GoalKeeper {
            actuator,
            allow_stalling,
            active: None,
            finished: VecDeque::new(),
        }
    }

    /// Serves the action until `shutdown` turns true (or its sender is dropped); a goal still
    /// running then is stopped and aborted.
    pub async fn serve(
        mut self,
        servers: Vec<(ServiceMapping, GripperActionServer)>,
        mut shutdown: watch::Receiver<bool>,
    ) {
        let server = &servers[..];
        let mut poll = tokio::time::interval(POLL_PERIOD);
        poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut feedback = tokio::time::interval(FEEDBACK_PERIOD);
        feedback.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = poll.tick() => self.poll(server),
                _ = feedback.tick() => self.publish_feedback(server),
                // Lazy: select! builds every branch's future, disabled ones too.
                event = async { self.active.as_mut().expect("guarded").next_event().await },
                    if self.active.is_some() => match event {
                    GoalEvent::Ended(outcome) => self.finish(server, outcome),
                    GoalEvent::Stopped(result) => self.stopped(result),
                    // Finishing drops the motion's task, which aborts it.
                    GoalEvent::GaveUp => self.finish(server, None),
                },
                _ = shutdown.wait_for(|stop| *stop) => break,
            }
        }
        if let Some(active) = self.active.as_mut() {
            tracing::info!(goal = ?active.info.goal_id, "shutting down: stopping the running goal");
            if let Err(e) = self.actuator.stop().await {
                tracing::warn!("stop at shutdown failed: {e}");
            }
            self.finish(server, None);
        }
    }

    fn poll(&mut self, servers: &Servers) {
        // Cancels first: a cancel and a goal read in the same round must not see the goal
        // started after the cancel was handled.
        self.read_all(
            servers,
            "a cancel request",
            |s| s.receive_cancel_request(),
            Self::cancel,
        );
        self.read_all(
            servers,
            "a goal",
            |s| s.receive_goal(),
            |k, servers, caller, req| k.goal(servers, caller, req.goal_id, req.goal),
        );
        self.read_all(
            servers,
            "a result request",
            |s| s.receive_result_request(),
            |k, servers, caller, req| k.result_request(servers, caller, req.goal_id),
        );
    }

    /// Reads the requests `read` takes from each server (at most [`READS_PER_ROUND`] each) and
    /// hands those this node answers (see [`rpc::answers`]) to `handle`.
    fn read_all<T>(
        &mut self,
        servers: &Servers,
        what: &str,
        read: impl Fn(&GripperActionServer) -> ros2_client::ReadResult<Option<(RmwRequestId, T)>>,
        mut handle: impl FnMut(&mut Self, &Servers, Caller, T),
    ) {
        for (i, (mapping, server)) in servers.iter().enumerate() {
            for _ in 0..READS_PER_ROUND {
                match read(server) {
                    Ok(Some((id, x))) if rpc::answers(*mapping, servers.len(), &id) => {
                        handle(self, servers, Caller { server: i, id }, x)
                    }
                    Ok(Some(_)) => {}
                    Ok(None) => break,
                    // With two mappings served, each request fails to decode in one of them.
                    Err(e) => tracing::debug!("{what} not read: {e:?}"),
                }
            }
        }
    }

    fn goal(
        &mut self,
        server: &Servers,
        caller: Caller,
        goal_id: GoalId,
        goal: GripperCommandGoal,
    ) {
        let stamp = Time::now();
        let verdict = if self.known(&goal_id) {
            Err("a goal with this id was already received".to_owned())
        } else {
            self.actuator.check(&goal)
        };
        let accepted = verdict.is_ok();
        match verdict {
            Ok(()) => tracing::info!(?goal_id, ?goal, "goal accepted"),
            Err(why) => tracing::warn!(?goal_id, ?goal, "goal rejected: {why}"),
        }
        let response = SendGoalResponse { accepted, stamp };
        if let Err(e) = server[caller.server]
            .1
            .send_goal_response(caller.id, response)
        {
            tracing::warn!("answering a goal failed: {e:?}");
        }
        if !accepted {
            return;
        }
        let previous = self.preempt(server);
        let (tx, done) = oneshot::channel();
        let run = self.actuator.execute(goal);
        let task = Motion(tokio::spawn(async move {
            if let Some((stop, motion)) = previous {
                // The device first stops the preempted motion (a WSG refuses a new one while it
                // runs, E_ALREADY_RUNNING, manual 3.2.2), which then reports its end.
                if let Err(e) = stop.await {
                    tracing::error!("the stop of a preempted goal failed: {e}");
                }
                motion.end_within_grace().await;
            }
            let _ = tx.send(run.await);
        }));
        // ACCEPTED and EXECUTING at once: the motion starts now.
        self.active = Some(Active {
            info: GoalInfo { goal_id, stamp },
            status: GoalStatusEnum::Executing,
            done,
            task,
            stopping: None,
            give_up_at: None,
            waiters: Vec::new(),
        });
        self.publish_statuses(server);
    }

    /// A goal was accepted while another runs: that one ends CANCELED now, with where the
    /// fingers are as its result (gripper_action_controller's `preempt_active_goal` cancels it
    /// with an empty result). Returns the stop to send and the motion to wait for, if it still
    /// runs.
    fn preempt(
        &mut self,
        server: &Servers,
    ) -> Option<(BoxFuture<'static, Result<(), String>>, Motion)> {
        let active = self.active.take()?;
        tracing::info!(goal = ?active.info.goal_id, "goal preempted by a new goal: canceled");
        let result = self.actuator.feedback();
        let still_runs = !active.task.0.is_finished();
        let motion = self.conclude(server, active, GoalStatusEnum::Canceled, result);
        still_runs.then(|| (self.actuator.stop(), motion))
    }

    fn known(&self, goal_id: &GoalId) -> bool {
        self.active
            .as_ref()
            .is_some_and(|a| a.info.goal_id == *goal_id)
            || self.finished.iter().any(|f| f.info.goal_id == *goal_id)
    }

    fn cancel(&mut self, server: &Servers, caller: Caller, req: CancelGoalRequest) {
        let response = match cancel_target(&req) {
            Err(e) => {
                tracing::warn!("cancel request not understood: {e}");
                reject(CancelGoalResponseEnum::Rejected)
            }
            Ok(target) => self.cancel_matching(server, &target),
        };
        if let Err(e) = server[caller.server]
            .1
            .send_cancel_response(caller.id, response)
        {
            tracing::warn!("answering a cancel request failed: {e:?}");
        }
    }

    fn cancel_matching(&mut self, server: &Servers, target: &GoalInfo) -> CancelGoalResponse {
        let matches = |info: &GoalInfo| cancel_matches(target, info);
        if let Some(active) = self.active.as_mut().filter(|a| matches(&a.info)) {
            if active.status != GoalStatusEnum::Canceling {
                active.status = GoalStatusEnum::Canceling;
                tracing::info!(goal = ?active.info.goal_id, "cancel: stopping the fingers");
                // Its own task: the answer to the cancel does not wait for the device. The
                // motion's end (E_CMD_ABORTED), or CANCEL_GRACE after the stop, finishes the
                // goal as CANCELED.
                let stop = self.actuator.stop();
                let (tx, stopping) = oneshot::channel();
                tokio::spawn(async move {
                    let _ = tx.send(stop.await);
                });
                active.stopping = Some(stopping);
            }
            let info = active.info.clone();
            self.publish_statuses(server);
            return CancelGoalResponse {
                return_code: CancelGoalResponseEnum::None,
                goals_canceling: vec![info],
            };
        }
        // rcl_action's answers: a named goal that ended is TERMINATED, one never seen UNKNOWN;
        // a request that cancels nothing is REJECTED.
        if target.goal_id != GoalId::ZERO {
            if self
                .finished
                .iter()
                .any(|f| f.info.goal_id == target.goal_id)
            {
                return reject(CancelGoalResponseEnum::GoalTerminated);
            }
            return reject(CancelGoalResponseEnum::UnknownGoal);
        }
        reject(CancelGoalResponseEnum::Rejected)
    }

    fn stopped(&mut self, result: Result<(), String>) {
        let Some(active) = self.active.as_mut() else {
            return;
        };
        active.stopping = None;
        match result {
            Ok(()) => {
                active.give_up_at = Some(tokio::time::Instant::now() + CANCEL_GRACE);
            }
            // The motion goes on: the goal stays CANCELING until it ends.
            Err(e) => tracing::error!("the stop of a cancelled goal failed: {e}"),
        }
    }

    fn result_request(&mut self, server: &Servers, caller: Caller, goal_id: GoalId) {
        if let Some(active) = self.active.as_mut().filter(|a| a.info.goal_id == goal_id) {
            if active.waiters.len() < RESULT_WAITERS_MAX {
                active.waiters.push(caller);
                return;
            }
            tracing::warn!(
                ?goal_id,
                "too many result requests for one goal; answered UNKNOWN"
            );
        }
        let (status, result) = match self.finished.iter().find(|f| f.info.goal_id == goal_id) {
            Some(f) => (f.status, f.result),
            None => (GoalStatusEnum::Unknown, GripperCommandResult::default()),
        };
        send_result(server, caller, status, result);
    }

    /// The running goal ended: `outcome` is `None` when it did not report (shutdown, or its
    /// task ended without an answer).
    fn finish(&mut self, server: &Servers, outcome: Option<Outcome>) {
        let Some(active) = self.active.take() else {
            return;
        };
        let allow_stalling = self
            .allow_stalling
            .load(std::sync::atomic::Ordering::Relaxed);
        let (status, result) = match (active.status, outcome) {
            (GoalStatusEnum::Canceling, o) => {
                // The result of a cancelled goal is where the fingers stopped.
                let result = o.map_or_else(|| self.actuator.feedback(), |o| o.result);
                (GoalStatusEnum::Canceled, result)
            }
            (_, Some(o)) => {
                let status = verdict(&o, allow_stalling);
                tracing::info!(goal = ?active.info.goal_id, ?status, result = ?o.result, "{}", o.message);
                (status, o.result)
            }
            (_, None) => (GoalStatusEnum::Aborted, self.actuator.feedback()),
        };
        if status == GoalStatusEnum::Canceled {
            tracing::info!(goal = ?active.info.goal_id, ?result, "goal cancelled");
        }
        // Dropped: the motion's task, if it still runs, is aborted.
        drop(self.conclude(server, active, status, result));
    }

    /// `active` ended with `status` and `result`: its result requests are answered, it is kept
    /// for late ones, and the statuses are published. Returns its motion's task.
    fn conclude(
        &mut self,
        server: &Servers,
        active: Active,
        status: GoalStatusEnum,
        result: GripperCommandResult,
    ) -> Motion {
        for waiter in active.waiters {
            send_result(server, waiter, status, result);
        }
        if self.finished.len() == FINISHED_GOALS_KEPT {
            self.finished.pop_front();
        }
        self.finished.push_back(Finished {
            info: active.info,
            status,
            result,
        });
        self.publish_statuses(server);
        active.task
    }

    fn publish_feedback(&self, server: &Servers) {
        if let Some(active) = &self.active {
            let feedback = self.actuator.feedback();
            if let Err(e) = server[0].1.send_feedback(active.info.goal_id, feedback) {
                tracing::debug!("feedback not sent: {e:?}");
            }
        }
    }

    fn publish_statuses(&self, server: &Servers) {
        let finished = self.finished.iter().map(|f| GoalStatus {
            goal_info: f.info.clone(),
            status: f.status,
        });
        let active = self.active.iter().map(|a| GoalStatus {
            goal_info: a.info.clone(),
            status: a.status,
        });
        let status_list = finished.chain(active).collect();
        if let Err(e) = server[0]
            .1
            .send_goal_statuses(GoalStatusArray { status_list })
        {
            tracing::debug!("goal statuses not sent: {e:?}");
        }
    }
}

fn send_result(
    server: &Servers,
    caller: Caller,
    status: GoalStatusEnum,
    result: GripperCommandResult,
) {
    let response = GetResultResponse { status, result };
    if let Err(e) = server[caller.server].1.send_result(caller.id, response) {
        tracing::warn!("sending a result failed: {e:?}");
    }
}

fn reject(code: CancelGoalResponseEnum) -> CancelGoalResponse {
    CancelGoalResponse {
        return_code: code,
        goals_canceling: Vec::new(),
    }
}

/// Whether a cancel request for `target` covers the goal `info` (action_msgs/srv/CancelGoal):
/// id and stamp zero cancel all goals; a zero id with a stamp, those accepted at or before it;
/// an id, that goal (and with a stamp, also those accepted at or before it).
pub fn cancel_matches(target: &GoalInfo, info: &GoalInfo) -> bool {
    let all = target.goal_id == GoalId::ZERO && target.stamp == Time::ZERO;
    let by_id = target.goal_id != GoalId::ZERO && target.goal_id == info.goal_id;
    let by_time = target.stamp != Time::ZERO && info.stamp <= target.stamp;
    all || by_id || by_time
}

/// The goal info of a cancel request. ros2-client 0.12.1 keeps the field private
/// (`pub(crate) goal_info`), but the type is serde: a round trip through a serde value reads it.
pub fn cancel_target(req: &CancelGoalRequest) -> Result<GoalInfo, String> {
    #[derive(serde::Deserialize)]
    struct Mirror {
        goal_info: GoalInfo,
    }
    let value = serde_json::to_value(req).map_err(|e| e.to_string())?;
    serde_json::from_value::<Mirror>(value)
        .map(|m| m.goal_info)
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(id: u8, stamp_s: i32) -> GoalInfo {
        let mut bytes = [0u8; 16];
        bytes[15] = id;
        GoalInfo {
            goal_id: GoalId {
                uuid: uuid::Uuid::from_bytes(bytes),
            },
            stamp: Time::new(stamp_s, 0),
        }
    }

    #[test]
    fn verdicts_of_gripper_action_controller() {
        let ended = |reached_goal, stalled, failed| Outcome {
            failed,
            result: GripperCommandResult {
                position: 0.04,
                effort: 20.0,
                stalled,
                reached_goal,
            },
            message: String::new(),
        };
        use GoalStatusEnum::{Aborted, Succeeded};
        for allow in [false, true] {
            assert_eq!(verdict(&ended(true, false, false), allow), Succeeded);
            assert_eq!(verdict(&ended(true, true, false), allow), Succeeded);
            assert_eq!(verdict(&ended(false, false, false), allow), Aborted);
            assert_eq!(verdict(&ended(true, false, true), allow), Aborted);
        }
        assert_eq!(verdict(&ended(false, true, false), true), Succeeded);
        assert_eq!(verdict(&ended(false, true, false), false), Aborted);
    }

    #[test]
    fn cancel_policy_of_action_msgs() {
        let goal = info(7, 100);
        let zero = GoalInfo {
            goal_id: GoalId::ZERO,
            stamp: Time::ZERO,
        };
        assert!(cancel_matches(&zero, &goal), "all goals");
        assert!(cancel_matches(&info(7, 0), &goal), "by id");
        assert!(!cancel_matches(&info(8, 0), &goal), "another id");
        let before = GoalInfo {
            goal_id: GoalId::ZERO,
            stamp: Time::new(100, 0),
        };
        assert!(cancel_matches(&before, &goal), "accepted at the stamp");
        let earlier = GoalInfo {
            goal_id: GoalId::ZERO,
            stamp: Time::new(99, 0),
        };
        assert!(!cancel_matches(&earlier, &goal), "accepted after the stamp");
    }
}
