//! The actor: one task owns the [`Device`] (no locks around the state machine), takes the
//! connections' events in order, and queues each reply for the session it belongs to, applying
//! the injected faults on the way out.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use tokio::sync::{mpsc, oneshot, watch};
use tokio::time::{sleep_until, Instant};

use super::record::{SimEvent, SimRecord};
use super::{lock, take, Shared, SimSnapshot};
use crate::wsg::frame::{self, Decoded};
use crate::wsg::sim::device::{Device, Out, SessionId, SessionKind};
use crate::wsg::sim::text::TextSession;
use crate::wsg::Reply;

/// Replies queued for one connection above which the simulator stops reading that
/// connection's requests (and pauses its auto-updates) until the client has read some: the
/// backpressure of a device whose send buffer is full, instead of dropping replies.
pub(super) const HIGH_WATER: usize = 256;

/// Where the replies of one session go: an unbounded queue whose length is bounded by the
/// connection, which stops reading at [`HIGH_WATER`] queued replies (each request has at most
/// a few replies).
#[derive(Clone, Debug)]
pub(super) struct Outbox {
    tx: mpsc::UnboundedSender<Bytes>,
    queued: Arc<AtomicUsize>,
}

impl Outbox {
    /// A new outbox and its receiving end, for the connection's writer.
    pub(super) fn new() -> (Outbox, Inbox) {
        let (tx, rx) = mpsc::unbounded_channel();
        let queued = Arc::new(AtomicUsize::new(0));
        let inbox = Inbox {
            rx,
            queued: queued.clone(),
        };
        (Outbox { tx, queued }, inbox)
    }

    pub(super) fn send(&self, bytes: Bytes) -> bool {
        self.queued.fetch_add(1, Ordering::Relaxed);
        if self.tx.send(bytes).is_ok() {
            true
        } else {
            self.queued.fetch_sub(1, Ordering::Relaxed);
            false
        }
    }

    fn full(&self) -> bool {
        self.queued.load(Ordering::Relaxed) >= HIGH_WATER
    }
}

/// Tells the actor that session `session` opened; returns where its replies arrive, or `None`
/// if the actor is gone (the server shut down).
pub(super) async fn connect(
    events: &mpsc::Sender<Event>,
    session: SessionId,
    kind: SessionKind,
) -> Option<Inbox> {
    let (outbox, inbox) = Outbox::new();
    let connected = Event::Connected {
        session,
        kind,
        outbox,
    };
    events.send(connected).await.ok().map(|()| inbox)
}

/// The connection's end of an [`Outbox`].
#[derive(Debug)]
pub(super) struct Inbox {
    rx: mpsc::UnboundedReceiver<Bytes>,
    queued: Arc<AtomicUsize>,
}

impl Inbox {
    /// The next reply to write; `None` once the actor has let the session go and everything
    /// queued was taken.
    pub(super) async fn recv(&mut self) -> Option<Bytes> {
        let b = self.rx.recv().await?;
        self.queued.fetch_sub(1, Ordering::Relaxed);
        Some(b)
    }

    /// Whether the client has fallen [`HIGH_WATER`] replies behind.
    pub(super) fn full(&self) -> bool {
        self.queued.load(Ordering::Relaxed) >= HIGH_WATER
    }
}

/// What the connections tell the actor, in the order they received it.
pub(super) enum Event {
    Connected {
        session: SessionId,
        kind: SessionKind,
        outbox: Outbox,
    },
    Received {
        session: SessionId,
        decoded: Decoded,
    },
    /// A text (GCL) connection opened (`text.rs`).
    TextConnected { session: SessionId, outbox: Outbox },
    /// One command line of a text connection (`None`: too long to read).
    Line {
        session: SessionId,
        line: Option<String>,
    },
    /// The connection ended (or, for UDP, nothing more will come): what is still owed to it is
    /// queued, then its outbox is dropped, which ends its writer once everything is written.
    Disconnected { session: SessionId },
    /// A UDP session was silent for its idle timeout: forget it unless something is still due
    /// to it (a final reply, auto-updates). The answer says whether it was forgotten.
    Idle {
        session: SessionId,
        forgotten: oneshot::Sender<bool>,
    },
}

/// Requests from the [`SimServer`](super::SimServer) handle.
pub(super) enum Control {
    LosePart,
    Unplug,
    Restart,
    TimeScale(f64),
}

/// Added to every wake-up time computed from seconds in `f64`: the conversion to `Duration`
/// truncates to whole nanoseconds, so without it the timer could fire a hair before the due
/// time, find nothing due, and be set to the same instant again. Under tokio's paused clock
/// (which only moves when every task waits) that loop never ends: the explorer found it.
const WAKE_MARGIN: Duration = Duration::from_micros(1);

/// Simulated seconds from the wall clock and a time scale.
pub(super) struct SimClock {
    pub(super) scale: f64,
    pub(super) base_wall: Instant,
    pub(super) base_sim: f64,
}

impl SimClock {
    pub(super) fn now(&self) -> f64 {
        if self.scale > 0.0 {
            self.base_sim + self.base_wall.elapsed().as_secs_f64() / self.scale
        } else {
            self.base_sim
        }
    }

    fn wall_at(&self, sim: f64) -> Instant {
        let far = Instant::now() + Duration::from_secs(365 * 24 * 3600);
        if self.scale <= 0.0 {
            return Instant::now();
        }
        let secs = ((sim - self.base_sim) * self.scale).clamp(0.0, 1e9);
        self.base_wall
            .checked_add(Duration::from_secs_f64(secs) + WAKE_MARGIN)
            .map_or(far, |t| t.min(far))
    }
}

pub(super) struct Actor {
    pub(super) device: Device,
    pub(super) clock: SimClock,
    pub(super) started: Instant,
    /// Ordered (not hashed): it is iterated (unplug, restart), and a seeded run must drop the
    /// connections in the same order every time to replay exactly.
    pub(super) sessions: BTreeMap<SessionId, Outbox>,
    /// The text (GCL) sessions' own state (`text.rs`). Ordered like `sessions`.
    pub(super) text: BTreeMap<SessionId, TextSession>,
    pub(super) shared: Arc<Mutex<Shared>>,
    pub(super) events: mpsc::Receiver<Event>,
    pub(super) control: mpsc::UnboundedReceiver<Control>,
    pub(super) shutdown: watch::Receiver<bool>,
}

impl Actor {
    pub(super) fn wall(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    pub(super) async fn run(mut self) {
        loop {
            self.settle();
            let motion = self.device.next_event().map(|t| self.clock.wall_at(t));
            let update = self
                .device
                .next_update_due()
                .map(|w| self.started + Duration::from_secs_f64(w.clamp(0.0, 1e9)) + WAKE_MARGIN);
            let wake = match (motion, update) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            tokio::select! {
                // A fixed order, not tokio's random one, so that a seeded run replays exactly.
                // It is fair: shutdown and control are rare; a steady flow of events cannot
                // starve the timer, because `settle` above delivers what became due on every
                // turn of the loop whichever branch woke it.
                biased;
                _ = self.shutdown.changed() => return,
                Some(c) = self.control.recv() => match c {
                    Control::LosePart => self.device.lose_part(),
                    Control::TimeScale(scale) => {
                        // Rebase so simulated time stays continuous across the change.
                        self.clock.base_sim = self.clock.now();
                        self.clock.base_wall = Instant::now();
                        self.clock.scale = scale;
                    }
                    // Dropping the outboxes ends the connection tasks, which close their
                    // sockets and report the disconnect. UDP has no connection to pull.
                    Control::Unplug => {
                        let device = &self.device;
                        self.sessions.retain(|s, _| device.session_kind(*s) == Some(SessionKind::Udp));
                    }
                    Control::Restart => self.restart(),
                },
                ev = self.events.recv() => match ev {
                    Some(ev) => self.on_event(ev),
                    None => return,
                },
                _ = sleep_until(wake.unwrap_or_else(Instant::now)), if wake.is_some() => {}
            }
        }
    }

    /// Delivers what became due: finished motions (all at once with time scale 0) and
    /// auto-updates.
    fn settle(&mut self) {
        let outs = self.device.advance(self.clock.now());
        self.dispatch(outs);
        if self.clock.scale <= 0.0 {
            while let Some(t) = self.device.next_event() {
                self.clock.base_sim = t.max(self.clock.base_sim);
                let outs = self.device.advance(t);
                self.dispatch(outs);
            }
        }
        let sessions = &self.sessions;
        let paused = |s: SessionId| sessions.get(&s).is_some_and(Outbox::full);
        let outs = self.device.updates_due(self.wall(), paused);
        self.dispatch(outs);
        let snapshot = SimSnapshot {
            grip_state: self.device.grip_state(),
            system_state: self.device.system_state(),
            width_mm: self.device.width_mm(),
            sessions: self.sessions.len(),
            streams: self.device.active_streams(),
        };
        lock(&self.shared).snapshot = snapshot;
    }

    /// Adds to the record, if recording was started.
    pub(super) fn record(&self, session: SessionId, event: SimEvent) {
        let mut shared = lock(&self.shared);
        if let Some(r) = shared.recorder.as_mut() {
            r.push(SimRecord {
                session,
                at: self.started.elapsed(),
                event,
            });
        }
    }

    /// A power cycle: stream connections are dropped (their tasks see the outbox close), the
    /// device starts from its configuration, UDP sessions carry on with it.
    fn restart(&mut self) {
        let cfg = self.device.config().clone();
        let old = std::mem::replace(&mut self.device, Device::new(cfg));
        self.sessions
            .retain(|s, _| old.session_kind(*s) == Some(SessionKind::Udp));
        // Text (GCL) sessions are byte streams: they went with the rest.
        self.text.clear();
        for &s in self.sessions.keys() {
            self.device.connect(s, SessionKind::Udp);
        }
        self.clock.base_sim = 0.0;
        self.clock.base_wall = Instant::now();
        self.record(0, SimEvent::Restarted);
    }

    fn on_event(&mut self, ev: Event) {
        match ev {
            Event::Connected {
                session,
                kind,
                outbox,
            } => {
                self.sessions.insert(session, outbox);
                self.device.connect(session, kind);
                self.record(session, SimEvent::Connected { kind });
            }
            Event::TextConnected { session, outbox } => self.on_text_connected(session, outbox),
            Event::Line { session, line } => self.on_text_line(session, line),
            Event::Disconnected { session } => self.forget(session),
            Event::Idle { session, forgotten } => {
                let forget = !self.device.owes_session(session);
                if forget {
                    tracing::debug!(session, "simulator: idle UDP session forgotten");
                    self.forget(session);
                }
                let _ = forgotten.send(forget);
            }
            Event::Received { session, decoded } => {
                let forced = {
                    let mut shared = lock(&self.shared);
                    let id = match &decoded {
                        Decoded::Frame(f) => f.id,
                        Decoded::Corrupt { id, .. } => *id,
                    };
                    if shared.received.len() >= 4096 {
                        shared.received.pop_front();
                    }
                    shared.received.push_back(id);
                    if let Some(r) = shared.recorder.as_mut() {
                        let (payload, corrupt) = match &decoded {
                            Decoded::Frame(f) => (f.payload.clone(), false),
                            Decoded::Corrupt { .. } => (Bytes::new(), true),
                        };
                        r.push(SimRecord {
                            session,
                            at: self.started.elapsed(),
                            event: SimEvent::Request {
                                id,
                                payload,
                                corrupt,
                            },
                        });
                    }
                    match &decoded {
                        Decoded::Frame(f) => take(&mut shared.faults.forced, |(i, _)| *i == f.id),
                        Decoded::Corrupt { .. } => None,
                    }
                };
                let outs = match forced {
                    Some((id, status)) => vec![Out {
                        session,
                        reply: Reply::new(id, status, Bytes::new()),
                    }],
                    None => {
                        let (now, wall) = (self.clock.now(), self.wall());
                        self.device.handle_at(now, Some(wall), session, &decoded)
                    }
                };
                self.dispatch(outs);
            }
        }
    }

    /// The session ends: the device learns it (an unannounced TCP close is a FAST STOP, whose
    /// E_CMD_ABORTED goes to the move's owner, manual 1.3 and 1.4.2), what it is still owed is
    /// queued (a half-closed client still reads), then its outbox is let go.
    fn forget(&mut self, session: SessionId) {
        let outs = self.device.disconnect(session, self.clock.now());
        self.dispatch(outs);
        if self.sessions.remove(&session).is_some() {
            self.record(session, SimEvent::Disconnected);
        }
        self.text.remove(&session);
    }

    pub(super) fn dispatch(&mut self, outs: Vec<Out>) {
        for out in outs {
            let id = out.reply.id;
            let Some(outbox) = self.sessions.get(&out.session) else {
                tracing::debug!(
                    id,
                    session = out.session,
                    "simulator: reply for a session that is gone"
                );
                continue;
            };
            if self.dispatch_text(&out, outbox) {
                continue;
            }
            let (drop, corrupt, delay) = {
                let mut shared = lock(&self.shared);
                let f = &mut shared.faults;
                (
                    take(&mut f.drop, |i| *i == id).is_some(),
                    take(&mut f.corrupt, |i| *i == id).is_some(),
                    take(&mut f.delay, |(i, _)| *i == id).map(|(_, d)| d),
                )
            };
            if drop {
                tracing::debug!(id, "simulator: reply dropped (injected fault)");
                continue;
            }
            let mut b = BytesMut::new();
            if let Err(e) = frame::encode(&out.reply.to_frame(), &mut b) {
                tracing::warn!(id, error = %e, "simulator: reply cannot be encoded");
                continue;
            }
            if corrupt {
                if let Some(last) = b.last_mut() {
                    *last ^= 0xFF;
                }
            }
            let bytes = b.freeze();
            let moving = self.device.fingers_moving();
            self.record(
                out.session,
                SimEvent::Reply {
                    id,
                    status: out.reply.status,
                    data: out.reply.data.clone(),
                    moving,
                },
            );
            match delay {
                Some(d) => {
                    let outbox = outbox.clone();
                    tokio::spawn(async move {
                        tokio::time::sleep(d).await;
                        outbox.send(bytes);
                    });
                }
                None => {
                    if !outbox.send(bytes) {
                        tracing::debug!(id, "simulator: connection closed; reply not sent");
                    }
                }
            }
        }
    }
}
