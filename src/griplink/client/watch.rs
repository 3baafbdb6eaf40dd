//! What a robot program wants on top of single commands: grip or release and wait for the
//! outcome, and streams of device states or values polled at a chosen rate.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use futures_core::Stream;
use tokio::sync::mpsc;
use tokio::time::{Instant, MissedTickBehavior};

use super::{Client, Port};
use crate::griplink::command::Blocking;
use crate::griplink::error::{Error, Result};
use crate::griplink::state::DeviceState;

/// How to wait for the end of a motion started without blocking (manual 3.4.4, options 1
/// and 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitBy {
    /// `WSTR[p]?`: the controller answers at the next state transition. Uses one connection
    /// slot for the whole wait: later commands of this connection wait behind it.
    Transition,
    /// `DEVSTATE[p]?` at this interval: other commands can run in between.
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

/// Pause before asking WSTR again after it reported a state that is not an outcome (WSTR
/// answers at once when nothing changed since the last WSTR, manual 3.4.10).
const WSTR_RETRY_PAUSE: Duration = Duration::from_millis(10);

impl Port {
    /// The overall limit of a wait: the handle's timeout if set, else the motion timeout.
    fn motion_limit(&self) -> Duration {
        self.client
            .timeout
            .unwrap_or(self.client.config.motion_timeout)
    }

    async fn wait_until<T>(
        &self,
        what: &str,
        by: WaitBy,
        outcome: fn(DeviceState) -> Option<T>,
    ) -> Result<T> {
        let limit = self.motion_limit();
        let deadline = Instant::now() + limit;
        let timeout = || Error::Timeout {
            command: format!("{what} on port {}", self.port),
            timeout: limit,
        };
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(timeout());
            }
            let state = match by {
                WaitBy::Transition => self.with_timeout(remaining).wait_for_transition().await?,
                WaitBy::Polling(_) => self.with_timeout(remaining).state().await?,
            };
            if let Some(done) = outcome(state) {
                return Ok(done);
            }
            let pause = match by {
                WaitBy::Transition => WSTR_RETRY_PAUSE,
                WaitBy::Polling(interval) => interval,
            };
            if tokio::time::timeout_at(deadline, tokio::time::sleep(pause))
                .await
                .is_err()
            {
                return Err(timeout());
            }
        }
    }

    /// Starts `GRIP(p,index)` and waits for its outcome: holding, no part, or fault. The whole
    /// wait is bounded by the motion timeout (or the handle's timeout).
    ///
    /// Not atomic: dropped after the command was sent, the motion still runs and only the wait is
    /// abandoned (with [`WaitBy::Transition`] a `WSTR` in flight still holds the connection until
    /// the next state change). Each step is [cancel-safe](super#cancellation).
    pub async fn grip_and_wait(&self, index: u32, by: WaitBy) -> Result<GripOutcome> {
        self.grip(index, Blocking::Immediate).await?;
        self.wait_until("waiting for the grip", by, grip_outcome)
            .await
    }

    /// Starts `RELEASE(p,index)` and waits for its outcome: released or fault.
    ///
    /// Not atomic: dropped after the command was sent, the motion still runs and only the wait is
    /// abandoned (with [`WaitBy::Transition`] a `WSTR` in flight still holds the connection until
    /// the next state change). Each step is [cancel-safe](super#cancellation).
    pub async fn release_and_wait(&self, index: u32, by: WaitBy) -> Result<ReleaseOutcome> {
        self.release(index, Blocking::Immediate).await?;
        self.wait_until("waiting for the release", by, release_outcome)
            .await
    }

    /// A stream of the device state (`DEVSTATE[p]?`), polled every `interval`. Ends when the
    /// connection is closed for good (with a reconnect policy, a lost connection yields its
    /// error and polling goes on once it is restored); dropping it stops the polling.
    pub fn watch_state(&self, interval: Duration) -> Watch<DeviceState> {
        let port = self.clone();
        Watch::spawn(self.client.clone(), interval, move || {
            let port = port.clone();
            async move { port.state().await }
        })
    }

    /// A stream of value `index` in the device's unit (`VALUEF[p][index]?`; index 0 is a
    /// gripper's finger position in mm), polled every `interval`.
    pub fn watch_value(&self, index: u32, interval: Duration) -> Watch<f64> {
        let port = self.clone();
        Watch::spawn(self.client.clone(), interval, move || {
            let port = port.clone();
            async move { port.value_f(index).await }
        })
    }
}

/// A [`Stream`] of polled readings. Errors are yielded as items; the stream ends when the
/// connection is closed for good. Dropping it stops the polling task.
#[derive(Debug)]
pub struct Watch<T> {
    readings: mpsc::Receiver<Result<T>>,
    poller: tokio::task::JoinHandle<()>,
}

impl<T: Send + 'static> Watch<T> {
    fn spawn<F, Fut>(client: Client, interval: Duration, mut poll: F) -> Watch<T>
    where
        F: FnMut() -> Fut + Send + 'static,
        Fut: Future<Output = Result<T>> + Send,
    {
        // One reading buffered: a slow consumer slows the polling instead of piling readings up.
        let (tx, readings) = mpsc::channel(1);
        let poller = tokio::spawn(async move {
            let mut ticker = tokio::time::interval(interval.max(Duration::from_millis(1)));
            ticker.set_missed_tick_behavior(MissedTickBehavior::Delay);
            loop {
                ticker.tick().await;
                let reading = poll().await;
                // A lost connection that is being restored is not the end.
                let gone = matches!(
                    reading,
                    Err(Error::Closed | Error::ConnectionLost(_) | Error::Io(_))
                ) && client.is_closed();
                if tx.send(reading).await.is_err() || gone {
                    break;
                }
            }
        });
        Watch { readings, poller }
    }
}

impl<T> Stream for Watch<T> {
    type Item = Result<T>;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Result<T>>> {
        self.get_mut().readings.poll_recv(cx)
    }
}

impl<T> Drop for Watch<T> {
    fn drop(&mut self) {
        self.poller.abort();
    }
}
