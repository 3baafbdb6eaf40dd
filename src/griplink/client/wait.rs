//! Start a motion and wait for its outcome: [`Port::grip_and_wait`],
//! [`Port::release_and_wait`] and their FLEX forms.
//!
//! The rules are in the [client docs](super#waiting-for-a-motion).

use std::time::Duration;

use tokio::time::Instant;

use super::Port;
use crate::griplink::command::{
    Blocking, Command, FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled, PortNumber,
};
use crate::griplink::error::{Error, Result};
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;

/// How to wait for the end of a motion started without blocking (manual 3.4.4, options 1
/// and 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitBy {
    /// `WSTR[p]?`: the controller answers at the next state transition (or `WAITVAL` on the
    /// position where no transition may come, see the
    /// [client docs](super#waiting-for-a-motion)). Uses one connection slot for the whole
    /// wait: later commands of this connection wait behind it.
    Transition,
    /// `DEVSTATE[p]?` (and `VALUE[p][0]?` where needed) at this interval: other commands can run
    /// in between. An interval below [`MIN_POLL_INTERVAL`] (`Duration::ZERO` included) is taken
    /// as [`MIN_POLL_INTERVAL`], as by [`Port::watch_state`]: reading back to back would flood
    /// the controller.
    Polling(Duration),
}

/// How a grip ended (manual 3.4.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripOutcome {
    /// `DS_HOLDING`: a part was found and is held with the gripping force.
    Holding,
    /// `DS_NO_PART`: the fingers reached the no-part limit without a part.
    NoPart,
    /// `DS_FAULT`: a fault during the motion.
    Fault,
}

/// How a release ended (manual 3.4.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReleaseOutcome {
    /// `DS_RELEASED`: the fingers reached the release position.
    Released,
    /// `DS_FAULT`: a fault during the motion.
    Fault,
}

/// How close (in µm, either side) to its target a finger position counts as arrived, where
/// arrival is the evidence (see the [client docs](super#waiting-for-a-motion)): 0.1 mm. The
/// manual gives no tolerance; this is this crate's choice, well below any part's clearance.
pub const TARGET_TOLERANCE_UM: i32 = 100;

/// How long the finger position must stay unchanged for a motion started in `DS_FAULT` to count
/// as ended in `DS_FAULT` (see the [client docs](super#waiting-for-a-motion)): 200 ms, this
/// crate's choice, many IO-Link cycles long.
pub const STILL_FOR: Duration = Duration::from_millis(200);

/// How long a motion started in `DS_FAULT` may show no sign of the re-enable (the state still
/// `DS_FAULT`, the fingers where they were) before the position may say that it ended: 2 s.
///
/// GRIP and RELEASE re-enable a Weiss gripper (3.4.1), but the manual gives no time for it, and
/// meanwhile the device still reads `DS_FAULT` with its fingers still, which looks exactly like
/// a motion that ended in a fault. So until the device left `DS_FAULT` or moved its fingers, only
/// this window running out makes the position evidence count (see the
/// [client docs](super#waiting-for-a-motion)). 2 s is this crate's choice: many times what an
/// actuator needs to power up and build its force, and short against the motion timeout.
pub const RE_ENABLE_WINDOW: Duration = Duration::from_secs(2);

/// The shortest pause between two reads of [`WaitBy::Polling`] and of a [`Watch`](super::Watch)
/// (a shorter interval, zero included, is taken as this one): 1 ms, this crate's choice, so that
/// a poller never sends back to back (the manual gives no rate; one IO-Link cycle is about this
/// long).
pub const MIN_POLL_INTERVAL: Duration = Duration::from_millis(1);

/// The longest single `WAITVAL` a helper sends: between two, it checks the state for a fault.
const WAITVAL_CHUNK: Duration = Duration::from_secs(1);

/// Pause before asking WSTR again after an answer that is not the outcome.
const WSTR_RETRY_PAUSE: Duration = Duration::from_millis(10);

/// Polling interval when a device refuses WAITVAL ("not available for all devices", 3.4.12).
const FALLBACK_POLL: Duration = Duration::from_millis(10);

fn grip_outcome(state: DeviceState) -> Option<GripOutcome> {
    match state {
        DeviceState::Holding => Some(GripOutcome::Holding),
        DeviceState::NoPart => Some(GripOutcome::NoPart),
        DeviceState::Fault => Some(GripOutcome::Fault),
        _ => None,
    }
}

fn release_outcome(state: DeviceState) -> Option<ReleaseOutcome> {
    match state {
        DeviceState::Released => Some(ReleaseOutcome::Released),
        DeviceState::Fault => Some(ReleaseOutcome::Fault),
        _ => None,
    }
}

/// What a helper knows about the motion it waits for.
struct Awaited<T> {
    /// For the timeout error: `waiting for the grip`.
    what: &'static str,
    outcome: fn(DeviceState) -> Option<T>,
    /// The state read just before the command.
    start: DeviceState,
    /// Where the fingers stop if nothing is in the way (releases), µm.
    target_um: Option<i32>,
    /// The finger position read just before the command, µm: only for a start in `DS_FAULT`,
    /// where the fingers moving away from it is the sign of the re-enable.
    start_um: Option<i32>,
    /// When the command was acknowledged.
    sent_at: Instant,
    deadline: Instant,
    limit: Duration,
}

impl<T> Awaited<T> {
    /// Whether the motion may end without a state transition (3.4.4, 3.4.7).
    fn ambiguous(&self) -> bool {
        (self.outcome)(self.start).is_some()
    }
}

/// Which start state makes a target worth reading before a release.
enum Target {
    /// A recipe's release limit, read only when needed.
    Recipe(u32),
    /// A FLEXRELEASE position, µm.
    Known(i32),
    /// A grip: a part stops the fingers anywhere.
    None,
}

/// The error of a helper whose own deadline passed.
fn wait_timeout(what: &str, port: PortNumber, limit: Duration) -> Error {
    Error::Timeout {
        command: format!("{what} on port {port}"),
        timeout: limit,
    }
}

/// Whether two finger positions are within [`TARGET_TOLERANCE_UM`] of each other.
fn within_tolerance(a_um: i32, b_um: i32) -> bool {
    (i64::from(a_um) - i64::from(b_um)).abs() <= i64::from(TARGET_TOLERANCE_UM)
}

fn mm_to_um(mm: f64) -> Option<i32> {
    let um = (mm * 1000.0).round();
    (um.is_finite() && um >= f64::from(i32::MIN) && um <= f64::from(i32::MAX)).then_some(um as i32)
}

impl Port {
    /// Starts `GRIP(p,index)` and waits for its outcome: holding, no part, or fault, decided as
    /// the [client docs](super#waiting-for-a-motion) describe (manual 3.4.4, 3.4.10). The
    /// whole wait is bounded by the motion timeout (or the handle's timeout); a `WSTR` timeout
    /// within it is asked again.
    ///
    /// Not atomic: dropped after the command was sent, the motion still runs and only the wait is
    /// abandoned (with [`WaitBy::Transition`] a `WSTR` in flight still holds the connection until
    /// the next state change or its timeout). Each step is [cancel-safe](super#cancellation).
    pub async fn grip_and_wait(&self, index: u32, by: WaitBy) -> Result<GripOutcome> {
        self.start_and_wait(
            "waiting for the grip",
            grip_outcome,
            Target::None,
            by,
            Command::Grip {
                port: self.port,
                index,
                blocking: Blocking::Immediate,
            },
        )
        .await
    }

    /// Starts `RELEASE(p,index)` and waits for its outcome: released or fault, decided as the
    /// [client docs](super#waiting-for-a-motion) describe (manual 3.4.5, 3.4.7). From
    /// `DS_RELEASED` or `DS_FAULT` it first reads the recipe's release limit (`GRIPCFG`) and
    /// returns only once the fingers are there.
    ///
    /// Not atomic: dropped after the command was sent, the motion still runs and only the wait is
    /// abandoned (with [`WaitBy::Transition`] a `WSTR` or `WAITVAL` in flight still holds the
    /// connection until it answers). Each step is [cancel-safe](super#cancellation).
    pub async fn release_and_wait(&self, index: u32, by: WaitBy) -> Result<ReleaseOutcome> {
        let target = Target::Recipe(index);
        self.start_and_wait(
            "waiting for the release",
            release_outcome,
            target,
            by,
            Command::Release {
                port: self.port,
                index,
                blocking: Blocking::Immediate,
            },
        )
        .await
    }

    /// Starts `FLEXGRIPF(…)` and waits for its outcome, as [`Port::grip_and_wait`] (manual
    /// 3.4.6).
    pub async fn flex_grip_and_wait(&self, params: FlexGrip, by: WaitBy) -> Result<GripOutcome> {
        self.start_and_wait(
            "waiting for the grip",
            grip_outcome,
            Target::None,
            by,
            Command::FlexGripF(self.port, params, Blocking::Immediate),
        )
        .await
    }

    /// Starts `FLEXGRIP(…)` and waits for its outcome, as [`Port::grip_and_wait`] (manual
    /// 3.4.6).
    pub async fn flex_grip_scaled_and_wait(
        &self,
        params: FlexGripScaled,
        by: WaitBy,
    ) -> Result<GripOutcome> {
        self.start_and_wait(
            "waiting for the grip",
            grip_outcome,
            Target::None,
            by,
            Command::FlexGrip(self.port, params, Blocking::Immediate),
        )
        .await
    }

    /// Starts `FLEXRELEASEF(…)` and waits for its outcome, as [`Port::release_and_wait`], with
    /// `params.position_mm` as the target (manual 3.4.7).
    pub async fn flex_release_and_wait(
        &self,
        params: FlexRelease,
        by: WaitBy,
    ) -> Result<ReleaseOutcome> {
        let target = match mm_to_um(params.position_mm) {
            Some(um) => Target::Known(um),
            // Refused by the command's own checks, before anything moves.
            None => Target::None,
        };
        self.start_and_wait(
            "waiting for the release",
            release_outcome,
            target,
            by,
            Command::FlexReleaseF(self.port, params, Blocking::Immediate),
        )
        .await
    }

    /// Starts `FLEXRELEASE(…)` and waits for its outcome, as [`Port::release_and_wait`], with
    /// `params.position_um` as the target (manual 3.4.7).
    pub async fn flex_release_scaled_and_wait(
        &self,
        params: FlexReleaseScaled,
        by: WaitBy,
    ) -> Result<ReleaseOutcome> {
        let target = Target::Known(params.position_um);
        self.start_and_wait(
            "waiting for the release",
            release_outcome,
            target,
            by,
            Command::FlexRelease(self.port, params, Blocking::Immediate),
        )
        .await
    }

    /// The overall limit of a wait: the handle's timeout if set, else the motion timeout.
    fn motion_limit(&self) -> Duration {
        self.client
            .timeout
            .unwrap_or(self.client.config.motion_timeout)
    }

    /// This port with every call bounded by what is left until `deadline` (and by `cap`).
    fn within(
        &self,
        deadline: Instant,
        cap: Option<Duration>,
        err: &dyn Fn() -> Error,
    ) -> Result<Port> {
        let remaining = deadline.saturating_duration_since(Instant::now());
        if remaining.is_zero() {
            return Err(err());
        }
        Ok(self.with_timeout(cap.map_or(remaining, |c| c.min(remaining))))
    }

    async fn start_and_wait<T>(
        &self,
        what: &'static str,
        outcome: fn(DeviceState) -> Option<T>,
        target: Target,
        by: WaitBy,
        command: Command,
    ) -> Result<T> {
        let limit = self.motion_limit();
        let deadline = crate::deadline::after(Instant::now(), limit);
        let err = || wait_timeout(what, self.port, limit);
        let query = Some(self.client.config.query_timeout);
        let start = self.within(deadline, query, &err)?.state().await?;
        let target_um = match target {
            Target::Recipe(index) if outcome(start).is_some() => Some(
                self.within(deadline, query, &err)?
                    .grip_config(index)
                    .await?
                    .params[1],
            ),
            Target::Known(um) => Some(um),
            Target::Recipe(_) | Target::None => None,
        };
        let start_um = match start {
            DeviceState::Fault => Some(self.within(deadline, query, &err)?.position_um().await?),
            _ => None,
        };
        // Read first: a state read after the command that merely repeats it is no outcome.
        self.within(deadline, query, &err)?
            .client
            .ack(command)
            .await?;
        let awaited = Awaited {
            what,
            outcome,
            start,
            target_um,
            start_um,
            sent_at: Instant::now(),
            deadline,
            limit,
        };
        self.wait_for_end(&awaited, by).await
    }

    async fn wait_for_end<T>(&self, m: &Awaited<T>, mut by: WaitBy) -> Result<T> {
        let err = || wait_timeout(m.what, self.port, m.limit);
        let query = Some(self.client.config.query_timeout);
        // From DS_FAULT: whether the fingers have moved since the command (see `ended_in_place`).
        let mut moved = false;
        // From DS_FAULT: whether a state other than DS_FAULT was read after the command, the
        // documented sign of the re-enable (3.4.1): from then on an outcome state read again,
        // DS_FAULT included, is a transition and ends the wait (see the client docs).
        let mut left_start = false;
        loop {
            // What the controller says, if it says anything: `None` after its own timeout.
            let heard = match (by, m.target_um) {
                (WaitBy::Polling(_), _) => None,
                (WaitBy::Transition, Some(target)) if m.ambiguous() => {
                    // 3.4.7: no transition may come; wait for the position instead.
                    let chunk =
                        WAITVAL_CHUNK.min(m.deadline.saturating_duration_since(Instant::now()));
                    let window = TARGET_TOLERANCE_UM.saturating_mul(2);
                    match self
                        .within(m.deadline, None, &err)?
                        .wait_value(0, target, window, chunk)
                        .await
                    {
                        Ok(())
                        | Err(Error::Device {
                            status: Status::Timeout,
                            ..
                        }) => None,
                        Err(Error::Device { status, .. }) => {
                            tracing::warn!(
                                port = self.port,
                                %status,
                                "WAITVAL refused; polling the position instead"
                            );
                            by = WaitBy::Polling(FALLBACK_POLL);
                            None
                        }
                        Err(e) => return Err(e),
                    }
                }
                (WaitBy::Transition, _) => match self
                    .within(m.deadline, None, &err)?
                    .wait_for_transition()
                    .await
                {
                    Ok(state) => Some(state),
                    // 3.4.10: no transition within the controller's WSTR timeout. Ask again.
                    Err(Error::Device {
                        status: Status::Timeout,
                        ..
                    }) => None,
                    Err(e) => return Err(e),
                },
            };
            let state = match heard {
                Some(state) => state,
                None => self.within(m.deadline, query, &err)?.state().await?,
            };
            if m.start == DeviceState::Fault && state != DeviceState::Fault {
                left_start = true;
            }
            if let Some(done) = (m.outcome)(state) {
                if state != m.start || left_start {
                    return Ok(done);
                }
                if self.ended_in_place(m, &mut moved).await? {
                    // The position was read after the state, and the motion may have ended in
                    // between (DS_FAULT, then DS_RELEASED at the target): the state now is
                    // the outcome.
                    let now = self.within(m.deadline, query, &err)?.state().await?;
                    if let Some(done) = (m.outcome)(now) {
                        return Ok(done);
                    }
                }
            }
            let pause = match by {
                WaitBy::Polling(interval) => interval.max(MIN_POLL_INTERVAL),
                WaitBy::Transition => WSTR_RETRY_PAUSE,
            };
            if tokio::time::timeout_at(m.deadline, tokio::time::sleep(pause))
                .await
                .is_err()
            {
                return Err(err());
            }
        }
    }

    /// Evidence that a motion ended without a transition, the device still in its start state:
    /// the fingers at the target, or, in `DS_FAULT` or with no target, still for [`STILL_FOR`].
    ///
    /// From `DS_FAULT` there is no such evidence before the device re-enabled (3.4.1): it reads
    /// `DS_FAULT`, fingers still, until then. So the position counts only once the fingers moved
    /// away from where they were before the command (`moved`, kept across calls), or once
    /// [`RE_ENABLE_WINDOW`] has passed since the command; and at the target in `DS_FAULT` they
    /// must also stay still (the state may follow the fingers a moment later).
    async fn ended_in_place<T>(&self, m: &Awaited<T>, moved: &mut bool) -> Result<bool> {
        let err = || wait_timeout(m.what, self.port, m.limit);
        let query = Some(self.client.config.query_timeout);
        let before = self.within(m.deadline, query, &err)?.position_um().await?;
        let fault = m.start == DeviceState::Fault;
        if fault {
            *moved |= m.start_um.is_some_and(|s| !within_tolerance(before, s));
            if !*moved && Instant::now() < m.sent_at + RE_ENABLE_WINDOW {
                return Ok(false);
            }
        }
        if let Some(target) = m.target_um {
            if !fault {
                return Ok(within_tolerance(before, target));
            }
        }
        if tokio::time::timeout_at(m.deadline, tokio::time::sleep(STILL_FOR))
            .await
            .is_err()
        {
            return Err(err());
        }
        let after = self.within(m.deadline, query, &err)?.position_um().await?;
        Ok(before == after)
    }
}
