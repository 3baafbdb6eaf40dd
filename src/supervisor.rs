//! The connection supervisor: the outer loop of every client's connection task, written once
//! (rodbus's split of the session loop from the channel task).
//!
//! A protocol supplies its [`Session`]: how to serve one connection (pairing replies with calls,
//! the timers, the protocol's own rules) and how to open and restore a new one (streams,
//! `VERBOSE`, the opening sequence). The supervisor keeps the rules that are the same for every
//! protocol:
//!
//! - a loss is reported ([`ConnectionEvent::Lost`]) and the calls in flight fail with it; they
//!   are never sent again on their own;
//! - with a [`ReconnectPolicy`] it reconnects with the policy's backoff, and the calls made
//!   meanwhile wait in the queue within their own timeouts; without one, or when the policy
//!   gives up, the connection is closed for good;
//! - it stops reconnecting when every handle is gone or the program closes the client, in a
//!   backoff wait or in the middle of an attempt, at once ([`CloseRequest`], set by every
//!   protocol's `close()` before it asks its task: a close that goes through the queue would
//!   wait out the backoff behind it); the client then ends as closed, and that `close()`
//!   succeeds ([`CloseRequest::outcome`]);
//! - when it ends, the reason is recorded first, then the queue is closed, and every call still
//!   in it gets the reason: drained with `recv`, not `try_recv` (a call that took its place in
//!   the queue before it closed puts its request in afterwards; `try_recv` would report the
//!   queue empty and that call would wait out its timeout unanswered).

use std::fmt;
use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use crate::reconnect::{self, ConnectionEvent, EventSender, ReconnectPolicy};

/// How a connection (or the whole client) ended.
#[derive(Debug)]
pub(crate) enum Served<C, E> {
    /// Closed by the program (`close()`, `BYE()`, every handle dropped): nothing to report or
    /// restore. `C` is what the close carries to the end (whom to answer).
    Closed(C),
    /// Lost (the peer closed it, I/O failed, or the client gave up on it), for this reason.
    Lost(E),
}

/// The program's request to close a client, shared by its handles and its connection task: set
/// by `close()` before it asks the task (which may be waiting out a reconnect backoff and read
/// no queue), so the supervisor stops a backoff wait or an attempt at once. Cheap to clone.
#[derive(Debug, Clone, Default)]
pub(crate) struct CloseRequest(Arc<CloseState>);

#[derive(Debug, Default)]
struct CloseState {
    /// Set by the first request (before `token` is cancelled).
    requested: AtomicBool,
    /// Cancelled by the first request: wakes whoever waits for it.
    token: CancellationToken,
    /// Set by the supervisor when the request stopped a reconnect (before the queue closes):
    /// the client ended with no connection, so what `close()` asked its task never ran.
    stopped_reconnect: AtomicBool,
}

impl CloseRequest {
    /// Asks to close; whether this was the first request.
    pub(crate) fn request(&self) -> bool {
        let first = !self.0.requested.swap(true, Ordering::SeqCst);
        self.0.token.cancel();
        first
    }

    /// The request stopped a reconnect: the client ends closed without a connection.
    fn stopped_reconnect(&self) {
        self.0.stopped_reconnect.store(true, Ordering::SeqCst);
    }

    /// Whether the program asked to close.
    pub(crate) fn is_requested(&self) -> bool {
        self.0.requested.load(Ordering::SeqCst)
    }

    /// Completes when the program asks to close.
    pub(crate) fn requested(&self) -> impl Future<Output = ()> + Send + '_ {
        self.0.token.cancelled()
    }

    /// The token cancelled by the request, for a serve loop that waits on it itself.
    pub(crate) fn token(&self) -> &CancellationToken {
        &self.0.token
    }

    /// What a `close()` returns that made the `first` request and then asked its task
    /// (`asked`). If the request stopped a reconnect, the client is closed and nothing was
    /// left to send (no connection: no `BYE()`, no disconnect announcement), and what it asked
    /// was refused with the client's end: the close did what it was for, and succeeds. Otherwise
    /// (a connection served it, or another `close()` came first) what the task answered.
    pub(crate) fn outcome<E>(&self, first: bool, asked: Result<(), E>) -> Result<(), E> {
        if first && self.0.stopped_reconnect.load(Ordering::SeqCst) {
            Ok(())
        } else {
            asked
        }
    }
}

/// What a reconnect attempt needs of a session: a view of it that may be shared with the
/// attempt's future (`Sync`), apart from the connection the session serves (a byte stream is
/// only `Send`).
pub(crate) trait Restore: Sync {
    /// A new connection.
    type Link: Send;
    /// Why a connection was lost, or an attempt to restore one failed.
    type Error: fmt::Display + Send + Sync;

    /// Where the connection's events go.
    fn events(&self) -> &EventSender;

    /// Nobody is left to serve (every handle dropped, or the program is closing): stop
    /// reconnecting.
    fn abandoned(&self) -> bool;

    /// The program's request to close: it stops a backoff wait or an attempt at once, and the
    /// client then ends as closed, not lost.
    fn close_request(&self) -> &CloseRequest;

    /// Opens a new connection (one attempt, bounded by the connect timeout).
    fn connect(&self) -> impl Future<Output = Result<Self::Link, Self::Error>> + Send;

    /// Restores the session on a new connection before any call is served on it.
    fn restore<'a>(
        &'a self,
        link: &'a mut Self::Link,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'a;
}

impl<R: Restore> Restore for &R {
    type Link = R::Link;
    type Error = R::Error;

    fn events(&self) -> &EventSender {
        (**self).events()
    }

    fn abandoned(&self) -> bool {
        (**self).abandoned()
    }

    fn close_request(&self) -> &CloseRequest {
        (**self).close_request()
    }

    fn connect(&self) -> impl Future<Output = Result<Self::Link, Self::Error>> + Send {
        (**self).connect()
    }

    fn restore<'a>(
        &'a self,
        link: &'a mut Self::Link,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'a {
        (**self).restore(link)
    }
}

/// What a protocol's connection task supplies to the [`supervise`] loop: it owns its current
/// connection and serves it.
pub(crate) trait Session: Send + Sized + 'static {
    /// The view a reconnect attempt borrows.
    type Restore<'a>: Restore<Link = Self::Link, Error = Self::Error>
    where
        Self: 'a;
    /// A connection.
    type Link: Send;
    /// Why a connection was lost.
    type Error: fmt::Display + Send + Sync;
    /// A call waiting in the queue.
    type Request: Send;
    /// What a close by the program carries to the end (`Default`: a close that stopped a
    /// reconnect, whose caller learns it from [`CloseRequest::outcome`]).
    type Close: Default + Send;

    /// Serves calls over the current connection until it is closed or lost. The calls in flight
    /// on it are answered (or failed) before it returns.
    fn serve(&mut self) -> impl Future<Output = Served<Self::Close, Self::Error>> + Send;

    /// The queue of calls from the handles.
    fn requests(&mut self) -> &mut mpsc::Receiver<Self::Request>;

    /// The view a reconnect attempt borrows.
    fn restorer(&self) -> Self::Restore<'_>;

    /// The reconnect policy (`None`: a lost connection stays closed).
    fn policy(&self) -> Option<ReconnectPolicy>;

    /// What the [`ConnectionEvent::Lost`] event says about `reason`.
    fn loss_report(&self, reason: &Self::Error) -> String {
        reason.to_string()
    }

    /// After a loss is reported, before any reconnect: close the old connection, fail what
    /// `serve` left waiting, prepare what a new connection restores.
    fn lost(&mut self, reason: &Self::Error);

    /// The connection restored: serve calls over it from now on.
    fn restored(&mut self, link: Self::Link);

    /// The client ends (for good) this way: record the reason for the handles, fail the calls
    /// the session holds. Runs before the queue is closed.
    fn ended(&mut self, end: &Served<Self::Close, Self::Error>);

    /// A call still in the queue when the client ended gets the reason.
    fn refuse(request: Self::Request, end: &Served<Self::Close, Self::Error>);

    /// The last step, after the queue is drained (answer the caller of `close()`).
    fn finish(self, _end: Served<Self::Close, Self::Error>) -> impl Future<Output = ()> + Send {
        async {}
    }
}

/// Runs a client's connection task: serves, reports a loss, reconnects with the policy and
/// restores, until the client ends; then fails what is waiting (see the module docs).
pub(crate) async fn supervise<S: Session>(mut session: S) {
    let end = loop {
        let reason = match session.serve().await {
            Served::Closed(close) => break Served::Closed(close),
            Served::Lost(reason) => reason,
        };
        session.restorer().events().send(ConnectionEvent::Lost {
            reason: session.loss_report(&reason),
        });
        session.lost(&reason);
        let Some(policy) = session.policy() else {
            break Served::Lost(reason);
        };
        // Calls made meanwhile wait in the queue, within their own timeouts.
        let (restored, close_requested) = {
            let restorer = session.restorer();
            let restorer = &restorer;
            let events = restorer.events();
            let retry = reconnect::retry(
                &policy,
                events,
                || restorer.abandoned(),
                |_| async {
                    let mut link = restorer.connect().await?;
                    events.send(ConnectionEvent::Connected);
                    restorer.restore(&mut link).await?;
                    Ok::<_, S::Error>(link)
                },
            );
            let restored = tokio::select! {
                // Fixed order (a seeded run replays exactly; unbiased select! draws from a
                // per-process random seed): an attempt that completes at the same poll as the
                // close still counts, and the close is seen at the next poll either way.
                biased;
                restored = retry => restored,
                () = restorer.close_request().requested() => None,
            };
            (restored, restorer.close_request().is_requested())
        };
        match restored {
            Some(link) => session.restored(link),
            None if close_requested => {
                // Before the queue closes: the `close()` refused with it reads it.
                session.restorer().close_request().stopped_reconnect();
                break Served::Closed(S::Close::default());
            }
            None => break Served::Lost(reason),
        }
    };
    session.ended(&end);
    let requests = session.requests();
    requests.close();
    while let Some(request) = requests.recv().await {
        S::refuse(request, &end);
    }
    session.finish(end).await;
}
