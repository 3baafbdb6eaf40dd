//! Streams of device states or values polled at a chosen rate.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use futures_core::Stream;
use tokio::sync::mpsc;
use tokio::time::MissedTickBehavior;

use super::{Client, Port};
use crate::griplink::error::{Error, Result};
use crate::griplink::state::DeviceState;

impl Port {
    /// A stream of the device state (`DEVSTATE[p]?`), polled every `interval`. Ends when the
    /// connection is closed for good (with a reconnect policy, a lost connection yields its
    /// error and polling goes on once it is restored); dropping it stops the polling. An
    /// `interval` below [`MIN_POLL_INTERVAL`](super::MIN_POLL_INTERVAL) is taken as that.
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
            let mut ticker = tokio::time::interval(interval.max(super::MIN_POLL_INTERVAL));
            ticker.set_missed_tick_behavior(MissedTickBehavior::Delay);
            loop {
                ticker.tick().await;
                let reading = poll().await;
                // A lost connection that is being restored is not the end.
                let gone = matches!(
                    reading,
                    Err(Error::Closed | Error::ConnectionLost { .. } | Error::Io(_))
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
