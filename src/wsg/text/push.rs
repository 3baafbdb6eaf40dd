//! `AUTOSEND` pushes (`@NAME=value`, shared note §3.10) as a [`Stream`].

use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};

use futures_core::Stream;
use tokio::sync::mpsc;

use crate::wsg::GripState;

/// A value the gripper can push with `AUTOSEND` (the four names a hardware-run driver
/// subscribes to, plus `TEMP`, which a student client pushes; shared note §3.10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Quantity {
    /// `POS`: the opening width, mm.
    Position,
    /// `SPEED`: the finger speed, mm/s.
    Speed,
    /// `FORCE`: the grip force, N.
    Force,
    /// `GRIPSTATE`: the grip state number (shared note §4.4).
    GripState,
    /// `TEMP`: the temperature, °C (our reading: the unit is not in the text we have).
    Temperature,
}

impl Quantity {
    /// The GCL name.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Position => "POS",
            Quantity::Speed => "SPEED",
            Quantity::Force => "FORCE",
            Quantity::GripState => "GRIPSTATE",
            Quantity::Temperature => "TEMP",
        }
    }

    /// The quantity a GCL name stands for (any case).
    pub fn from_name(name: &str) -> Option<Quantity> {
        [
            Quantity::Position,
            Quantity::Speed,
            Quantity::Force,
            Quantity::GripState,
            Quantity::Temperature,
        ]
        .into_iter()
        .find(|q| q.name().eq_ignore_ascii_case(name))
    }
}

/// One pushed value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// What it is.
    pub quantity: Quantity,
    /// Its value, in the quantity's unit.
    pub value: f64,
}

impl Push {
    /// The grip state, for a [`Quantity::GripState`] push with a whole number 0–255.
    pub fn grip_state(&self) -> Option<GripState> {
        let whole = self.value.fract() == 0.0 && (0.0..=255.0).contains(&self.value);
        (self.quantity == Quantity::GripState && whole)
            .then(|| GripState::from_u8(self.value as u8))
    }
}

/// What the connection task keeps of one [`Pushes`] stream.
#[derive(Debug)]
pub(crate) struct PushSubscriber {
    filter: Option<Quantity>,
    tx: mpsc::Sender<Push>,
    missed: Arc<AtomicU64>,
}

impl PushSubscriber {
    /// Whether its [`Pushes`] stream was dropped.
    pub(crate) fn is_closed(&self) -> bool {
        self.tx.is_closed()
    }

    /// Hands a push over; false when the stream is gone.
    pub(crate) fn deliver(&self, push: Push) -> bool {
        if self.filter.is_some_and(|q| q != push.quantity) {
            return !self.tx.is_closed();
        }
        match self.tx.try_send(push) {
            Ok(()) => true,
            Err(mpsc::error::TrySendError::Full(_)) => {
                self.missed.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(mpsc::error::TrySendError::Closed(_)) => false,
        }
    }
}

/// A stream of pushed values. It buffers a bounded number of pushes (the client's
/// `push_buffer`); while it is full, newer pushes are dropped and counted by
/// [`Pushes::missed`]. It ends when the connection does.
#[derive(Debug)]
pub struct Pushes {
    rx: mpsc::Receiver<Push>,
    missed: Arc<AtomicU64>,
}

impl Pushes {
    pub(crate) fn new(filter: Option<Quantity>, buffer: usize) -> (Pushes, PushSubscriber) {
        let (tx, rx) = mpsc::channel(crate::queue::channel_capacity(buffer));
        let missed = Arc::new(AtomicU64::new(0));
        (
            Pushes {
                rx,
                missed: missed.clone(),
            },
            PushSubscriber { filter, tx, missed },
        )
    }

    /// Pushes dropped so far because this stream's buffer was full.
    pub fn missed(&self) -> u64 {
        self.missed.load(Ordering::Relaxed)
    }

    /// The next push; `None` once the connection has ended.
    pub async fn recv(&mut self) -> Option<Push> {
        self.rx.recv().await
    }
}

impl Stream for Pushes {
    type Item = Push;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Push>> {
        self.rx.poll_recv(cx)
    }
}
