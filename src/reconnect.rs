// Links name their targets in full: rustdoc resolves this module's docs from the crate root too
// (through the doc line on `mod reconnect` there).
//! Reconnecting after a lost connection, the same way in the `smartgrasp`, `griplink` and `wsg`
//! clients (wsg over TCP and serial; over UDP there is no connection to lose): a backoff policy
//! ([`ReconnectPolicy`]), the events a client reports ([`ConnectionEvent`]) and the stream a
//! program reads them from ([`ConnectionEvents`]).
//!
//! What a client restores after reconnecting (subscriptions, registration…) and which calls fail
//! is each protocol's business; see its client's docs:
//! [`smartgrasp::ClientConfig::reconnect`](crate::smartgrasp::ClientConfig::reconnect),
//! [`griplink::ClientConfig::reconnect`](crate::griplink::ClientConfig::reconnect),
//! [`wsg::ClientBuilder::reconnect`](crate::wsg::ClientBuilder::reconnect).
//!
//! Memory bound: the events go through a [`tokio::sync::broadcast`] channel of fixed capacity.
//! A consumer that falls behind does not make it grow: it loses the oldest events and is told so
//! by a [`ConnectionEvent::Missed`] in their place.
//!
//! [`ReconnectPolicy`]: crate::reconnect::ReconnectPolicy
//! [`ConnectionEvent`]: crate::reconnect::ConnectionEvent
//! [`ConnectionEvents`]: crate::reconnect::ConnectionEvents
//! [`ConnectionEvent::Missed`]: crate::reconnect::ConnectionEvent::Missed

use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::task::{ready, Context, Poll};
use std::time::Duration;

use futures_core::Stream;
use tokio::sync::broadcast;
use tokio_util::sync::ReusableBoxFuture;

/// When to try again after a lost connection: exponential backoff.
///
/// Attempt `n` (1 = the first) waits `initial_delay × factor^(n−1)`, at most `max_delay`; after
/// `max_attempts` failed attempts the client gives up (`None`: it never does).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconnectPolicy {
    /// Wait before the first attempt.
    pub initial_delay: Duration,
    /// The longest wait between two attempts.
    pub max_delay: Duration,
    /// Growth of the wait per attempt (values below 1, and NaN, count as 1: a constant wait).
    pub factor: f64,
    /// Attempts before giving up; `None`: try as long as the client is in use.
    pub max_attempts: Option<u32>,
}

impl Default for ReconnectPolicy {
    /// 100 ms, doubling up to 5 s, forever.
    fn default() -> Self {
        ReconnectPolicy {
            initial_delay: Duration::from_millis(100),
            max_delay: Duration::from_secs(5),
            factor: 2.0,
            max_attempts: None,
        }
    }
}

impl ReconnectPolicy {
    /// The wait before attempt `attempt` (1 = the first; 0 is treated as 1). Pure, never panics:
    /// a huge attempt number or factor gives `max_delay`.
    pub fn delay_for(&self, attempt: u32) -> Duration {
        // `max` on a NaN returns the other operand, so a NaN factor is 1.
        let factor = self.factor.max(1.0);
        let exponent = i32::try_from(attempt.saturating_sub(1)).unwrap_or(i32::MAX);
        let secs = self.initial_delay.as_secs_f64() * factor.powi(exponent);
        // An infinite product fails the conversion and is capped like any other long wait.
        Duration::try_from_secs_f64(secs)
            .unwrap_or(self.max_delay)
            .min(self.max_delay)
    }

    /// Whether attempt `attempt` is one too many.
    pub fn gives_up_before(&self, attempt: u32) -> bool {
        self.max_attempts.is_some_and(|max| attempt > max)
    }
}

/// What happened to a client's connection.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum ConnectionEvent {
    /// The connection broke. Calls in flight failed; they are not sent again.
    Lost {
        /// Why, as the client's error describes it.
        reason: String,
    },
    /// The client waits `delay`, then makes attempt `attempt` (1 = the first) to reconnect.
    Reconnecting {
        /// Attempt number, from 1.
        attempt: u32,
        /// The backoff before it.
        delay: Duration,
    },
    /// A new connection is up; the client now restores what the program set up.
    Connected,
    /// The connection is back and restored; calls go through again.
    Restored {
        /// The attempts it took.
        attempts: u32,
    },
    /// The client stopped trying (its policy's `max_attempts`, or every handle was dropped): every
    /// later call fails.
    GaveUp {
        /// The attempts made.
        attempts: u32,
    },
    /// Not a connection event: this stream's reader was too slow, and the `count` oldest events
    /// were dropped to keep the buffer bounded.
    Missed {
        /// Events lost.
        count: u64,
    },
}

impl fmt::Display for ConnectionEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConnectionEvent::Lost { reason } => write!(f, "connection lost: {reason}"),
            ConnectionEvent::Reconnecting { attempt, delay } => {
                write!(f, "reconnecting in {delay:?} (attempt {attempt})")
            }
            ConnectionEvent::Connected => f.write_str("connected, restoring the session"),
            ConnectionEvent::Restored { attempts } => {
                write!(f, "connection restored after {attempts} attempt(s)")
            }
            ConnectionEvent::GaveUp { attempts } => {
                write!(f, "gave up reconnecting after {attempts} attempt(s)")
            }
            ConnectionEvent::Missed { count } => write!(f, "{count} event(s) missed"),
        }
    }
}

/// The sending side, owned by a client's connection task: every event goes to the subscribed
/// [`ConnectionEvents`] and to `tracing` (target this module, with the protocol's name).
#[derive(Debug, Clone)]
pub(crate) struct EventSender {
    tx: broadcast::Sender<ConnectionEvent>,
    protocol: &'static str,
}

impl EventSender {
    /// A sender whose subscribers each buffer at most `capacity` events (at least 1).
    pub fn new(protocol: &'static str, capacity: usize) -> Self {
        EventSender {
            tx: broadcast::Sender::new(capacity.max(1)),
            protocol,
        }
    }

    /// Reports `event`. Never waits: with no subscriber the event only goes to `tracing`.
    pub fn send(&self, event: ConnectionEvent) {
        let protocol = self.protocol;
        match &event {
            ConnectionEvent::Lost { .. } | ConnectionEvent::GaveUp { .. } => {
                tracing::warn!(protocol, %event, "connection event")
            }
            _ => tracing::info!(protocol, %event, "connection event"),
        }
        let _ = self.tx.send(event);
    }

    /// A stream of the events sent from now on (the clients' handles use [`EventSubscriber`]).
    #[cfg(test)]
    pub fn subscribe(&self) -> ConnectionEvents {
        ConnectionEvents::new(self.tx.subscribe())
    }

    /// A handle that subscribes without keeping the sender alive, for a client's handles: their
    /// streams end when the connection task has ended.
    pub fn subscriber(&self) -> EventSubscriber {
        EventSubscriber(self.tx.downgrade())
    }
}

/// Subscribes to an [`EventSender`] while it exists (see [`EventSender::subscriber`]).
#[derive(Debug, Clone)]
pub(crate) struct EventSubscriber(broadcast::WeakSender<ConnectionEvent>);

impl EventSubscriber {
    /// A stream of the events sent from now on; already ended if the sender is gone.
    pub fn subscribe(&self) -> ConnectionEvents {
        match self.0.upgrade() {
            Some(tx) => ConnectionEvents::new(tx.subscribe()),
            None => {
                let (tx, rx) = broadcast::channel(1);
                drop(tx);
                ConnectionEvents::new(rx)
            }
        }
    }
}

type Next = (
    Result<ConnectionEvent, broadcast::error::RecvError>,
    broadcast::Receiver<ConnectionEvent>,
);

/// A [`Stream`] of [`ConnectionEvent`]s, from its subscription on, in order. It ends when the
/// client's connection task has ended.
///
/// Bounded: it buffers a fixed number of events (the client's docs say how many). If the reader
/// falls further behind, the oldest are dropped and a [`ConnectionEvent::Missed`] says how many.
pub struct ConnectionEvents {
    next: ReusableBoxFuture<'static, Next>,
    ended: bool,
}

impl fmt::Debug for ConnectionEvents {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ConnectionEvents")
            .field("ended", &self.ended)
            .finish_non_exhaustive()
    }
}

async fn receive(mut rx: broadcast::Receiver<ConnectionEvent>) -> Next {
    (rx.recv().await, rx)
}

impl ConnectionEvents {
    fn new(rx: broadcast::Receiver<ConnectionEvent>) -> Self {
        ConnectionEvents {
            next: ReusableBoxFuture::new(receive(rx)),
            ended: false,
        }
    }
}

impl Stream for ConnectionEvents {
    type Item = ConnectionEvent;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<ConnectionEvent>> {
        if self.ended {
            return Poll::Ready(None);
        }
        let (result, rx) = ready!(self.next.poll(cx));
        self.next.set(receive(rx));
        Poll::Ready(match result {
            Ok(event) => Some(event),
            Err(broadcast::error::RecvError::Lagged(count)) => {
                Some(ConnectionEvent::Missed { count })
            }
            Err(broadcast::error::RecvError::Closed) => {
                self.ended = true;
                None
            }
        })
    }
}

/// The reconnect loop shared by the clients: reports [`ConnectionEvent::Reconnecting`], waits
/// the policy's delay, calls `attempt`; until an attempt succeeds ([`ConnectionEvent::Restored`],
/// `Some`) or the policy gives up or `abandoned()` says nobody is left to use the connection
/// ([`ConnectionEvent::GaveUp`], `None`). A failed attempt is logged with its error.
pub(crate) async fn retry<T, E, Fut>(
    policy: &ReconnectPolicy,
    events: &EventSender,
    abandoned: impl Fn() -> bool,
    mut attempt: impl FnMut(u32) -> Fut,
) -> Option<T>
where
    E: fmt::Display,
    Fut: Future<Output = Result<T, E>>,
{
    let mut n: u32 = 1;
    loop {
        if policy.gives_up_before(n) || abandoned() {
            events.send(ConnectionEvent::GaveUp { attempts: n - 1 });
            return None;
        }
        let delay = policy.delay_for(n);
        events.send(ConnectionEvent::Reconnecting { attempt: n, delay });
        tokio::time::sleep(delay).await;
        match attempt(n).await {
            Ok(restored) => {
                events.send(ConnectionEvent::Restored { attempts: n });
                return Some(restored);
            }
            Err(error) => {
                tracing::warn!(protocol = events.protocol, attempt = n, %error, "reconnect attempt failed")
            }
        }
        n = n.saturating_add(1);
    }
}

/// A byte stream a client runs over: a socket, or any stream the program opens itself (a
/// tunnel, an in-memory pipe to a simulator).
pub(crate) trait ByteStream:
    tokio::io::AsyncRead + tokio::io::AsyncWrite + Send + Unpin
{
}
impl<T: tokio::io::AsyncRead + tokio::io::AsyncWrite + Send + Unpin> ByteStream for T {}

/// A byte stream, boxed.
pub(crate) type BoxStream = Box<dyn ByteStream>;

/// Opens a byte stream again for a reconnect: the program's own opener (the GRIPLINK and
/// SmartGrasp clients' `open_with`).
pub(crate) type Open =
    Box<dyn Fn() -> Pin<Box<dyn Future<Output = std::io::Result<BoxStream>> + Send>> + Send + Sync>;

/// Boxes a program's opener; returns it with the first stream it opened.
pub(crate) async fn first_open<F, Fut, S>(open: F) -> std::io::Result<(BoxStream, Open)>
where
    F: Fn() -> Fut + Send + Sync + 'static,
    Fut: Future<Output = std::io::Result<S>> + Send + 'static,
    S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Send + Unpin + 'static,
{
    let first = open().await?;
    let open: Open = Box::new(move || {
        let fut = open();
        Box::pin(async move { fut.await.map(|s| Box::new(s) as BoxStream) })
    });
    Ok((Box::new(first), open))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy(factor: f64) -> ReconnectPolicy {
        ReconnectPolicy {
            initial_delay: Duration::from_millis(100),
            max_delay: Duration::from_secs(1),
            factor,
            max_attempts: Some(3),
        }
    }

    #[test]
    fn delays_grow_by_the_factor_up_to_the_cap() {
        let p = policy(2.0);
        let ms = |n| p.delay_for(n).as_millis();
        assert_eq!(
            [ms(0), ms(1), ms(2), ms(3), ms(4), ms(5)],
            [100, 100, 200, 400, 800, 1000]
        );
        assert_eq!(p.delay_for(u32::MAX), Duration::from_secs(1));
        for odd in [0.5, -3.0, f64::NAN] {
            assert_eq!(policy(odd).delay_for(7), Duration::from_millis(100));
        }
        assert_eq!(policy(f64::INFINITY).delay_for(2), Duration::from_secs(1));
        assert_eq!(policy(f64::MAX).delay_for(9), Duration::from_secs(1));
    }

    #[test]
    fn gives_up_after_max_attempts() {
        let p = policy(2.0);
        assert!(!p.gives_up_before(3));
        assert!(p.gives_up_before(4));
        assert!(!ReconnectPolicy::default().gives_up_before(u32::MAX));
    }

    #[tokio::test(start_paused = true)]
    async fn retry_reports_each_attempt_and_gives_up() {
        use std::future::poll_fn;
        let events = EventSender::new("test", 16);
        let mut stream = events.subscribe();
        let failed: Option<()> = retry(
            &policy(2.0),
            &events,
            || false,
            |_| async { Err::<(), _>("refused") },
        )
        .await;
        assert_eq!(failed, None);
        let restored = retry(
            &policy(2.0),
            &events,
            || false,
            |n| async move {
                if n == 2 {
                    Ok(n)
                } else {
                    Err("refused")
                }
            },
        )
        .await;
        assert_eq!(restored, Some(2));
        drop(events);
        let mut got = Vec::new();
        while let Some(e) = poll_fn(|cx| Pin::new(&mut stream).poll_next(cx)).await {
            got.push(e);
        }
        let wait = |attempt, ms| ConnectionEvent::Reconnecting {
            attempt,
            delay: Duration::from_millis(ms),
        };
        assert_eq!(
            got,
            [
                wait(1, 100),
                wait(2, 200),
                wait(3, 400),
                ConnectionEvent::GaveUp { attempts: 3 },
                wait(1, 100),
                wait(2, 200),
                ConnectionEvent::Restored { attempts: 2 },
            ]
        );
    }

    #[tokio::test]
    async fn a_slow_reader_loses_the_oldest_events_not_memory() {
        use std::future::poll_fn;
        let events = EventSender::new("test", 2);
        let mut stream = events.subscribe();
        let subscriber = events.subscriber();
        for attempts in 1..=5 {
            events.send(ConnectionEvent::Restored { attempts });
        }
        drop(events);
        let mut got = Vec::new();
        while let Some(e) = poll_fn(|cx| Pin::new(&mut stream).poll_next(cx)).await {
            got.push(e);
        }
        assert_eq!(
            got,
            [
                ConnectionEvent::Missed { count: 3 },
                ConnectionEvent::Restored { attempts: 4 },
                ConnectionEvent::Restored { attempts: 5 },
            ]
        );
        // The sender is gone: a new subscription is an ended stream.
        let mut late = subscriber.subscribe();
        assert_eq!(poll_fn(|cx| Pin::new(&mut late).poll_next(cx)).await, None);
    }
}
