//! Auto-update streams (manual 3.4.1: FLAGS bit0 = automatic updates, bit1 = only on change).

use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use bytes::Bytes;
use futures_core::Stream;
use tokio::sync::mpsc;

use super::command::{UpdateMode, MIN_UPDATE_PERIOD};

/// How a subscription asks the device to send updates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UpdateOptions {
    /// The period (and, with `on_change`, the minimum spacing) of updates; at least 10 ms,
    /// at most 65535 ms.
    pub period: Duration,
    /// Send only when the value changes (manual: width by ≥ 0.01 mm, speed by ≥ 0.05 mm/s,
    /// force by ≥ 0.05 N, any flag or state change).
    pub on_change: bool,
}

impl UpdateOptions {
    /// Updates every `period`.
    pub fn periodic(period: Duration) -> Self {
        Self {
            period,
            on_change: false,
        }
    }

    /// Updates on change, at most one per `period`.
    pub fn on_change(period: Duration) -> Self {
        Self {
            period,
            on_change: true,
        }
    }

    /// The options an auto-update mode stands for.
    pub(crate) fn from_mode(mode: UpdateMode) -> Self {
        Self {
            period: Duration::from_millis(u64::from(mode.period_ms)),
            on_change: mode.on_change,
        }
    }

    pub(crate) fn to_mode(self) -> Result<UpdateMode, String> {
        if self.period < MIN_UPDATE_PERIOD {
            return Err(format!(
                "update period {:?} is below the minimum of 10 ms",
                self.period
            ));
        }
        let period_ms = u16::try_from(self.period.as_millis())
            .map_err(|_| format!("update period {:?} exceeds 65535 ms", self.period))?;
        Ok(UpdateMode {
            auto: true,
            on_change: self.on_change,
            period_ms,
        })
    }
}

/// What the task keeps of one subscriber.
#[derive(Debug)]
pub(crate) struct Subscriber {
    pub(crate) key: u64,
    pub(crate) tx: mpsc::Sender<Bytes>,
    pub(crate) missed: Arc<AtomicU64>,
}

impl Subscriber {
    /// Hands one update over; returns false when the subscription is gone.
    pub(crate) fn deliver(&self, data: &Bytes) -> bool {
        match self.tx.try_send(data.clone()) {
            Ok(()) => true,
            Err(mpsc::error::TrySendError::Full(_)) => {
                self.missed.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(mpsc::error::TrySendError::Closed(_)) => false,
        }
    }
}

/// A stream of auto-update values of one kind (system state, grip state, width, speed or
/// force), created by the `subscribe_*` methods of [`Client`](super::Client).
///
/// The first item is the value the device sent in answer to the subscription. The device keeps
/// one update stream per value (manual 3.4.1: sending the command again re-configures it), so all
/// subscribers of one value share it and must agree on its options: a subscription asking for
/// other [`UpdateOptions`] than the live ones is refused with
/// [`Error::SubscriptionConflict`](super::Error::SubscriptionConflict) (it would otherwise change
/// the period or the on-change mode under the first subscriber). Subscribing with the same
/// options joins the stream. Once the last subscriber of a value is dropped, its updates are
/// turned off on the device (the command is sent again with FLAGS bit0 clear), and the next
/// subscription may choose new options.
///
/// Each subscriber has a bounded buffer (see
/// [`ClientBuilder::subscription_buffer`](super::ClientBuilder::subscription_buffer)). A consumer
/// that falls behind **misses the newest updates** while its buffer is full (counted by
/// [`Subscription::missed`]) and then reads the buffered, older values first: poll it at least as
/// often as the period when it matters.
///
/// The stream ends when the connection is lost or the client is closed.
pub struct Subscription<T> {
    pub(crate) rx: mpsc::Receiver<Bytes>,
    pub(crate) id: u8,
    pub(crate) key: u64,
    pub(crate) unsubscribe: mpsc::UnboundedSender<(u8, u64)>,
    pub(crate) missed: Arc<AtomicU64>,
    pub(crate) decode: fn(&[u8]) -> Result<T, String>,
}

impl<T> std::fmt::Debug for Subscription<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscription")
            .field("id", &self.id)
            .field("missed", &self.missed())
            .finish()
    }
}

impl<T> Subscription<T> {
    /// How many updates this subscriber missed because its buffer was full.
    pub fn missed(&self) -> u64 {
        self.missed.load(Ordering::Relaxed)
    }

    /// The command id of the value (0x40, 0x41, 0x43, 0x44 or 0x45).
    pub fn command_id(&self) -> u8 {
        self.id
    }
}

impl<T> Stream for Subscription<T> {
    type Item = T;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<T>> {
        loop {
            match self.rx.poll_recv(cx) {
                Poll::Ready(Some(data)) => match (self.decode)(&data) {
                    Ok(v) => return Poll::Ready(Some(v)),
                    Err(reason) => {
                        tracing::warn!(id = self.id, %reason, "malformed auto-update: skipped");
                    }
                },
                Poll::Ready(None) => return Poll::Ready(None),
                Poll::Pending => return Poll::Pending,
            }
        }
    }
}

impl<T> Drop for Subscription<T> {
    fn drop(&mut self) {
        // Unbounded on purpose: Drop cannot wait, and each subscription sends exactly one
        // message, so the channel never holds more than the number of live subscriptions.
        let _ = self.unsubscribe.send((self.id, self.key));
    }
}
