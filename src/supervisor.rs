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
//!   backoff wait or in the middle of an attempt ([`Session::close_requested`]);
//! - when it ends, the reason is recorded first, then the queue is closed, and every call still
//!   in it gets the reason: drained with `recv`, not `try_recv` (a call that took its place in
//!   the queue before it closed puts its request in afterwards; `try_recv` would report the
//!   queue empty and that call would wait out its timeout unanswered).

use std::fmt;
use std::future::Future;

use tokio::sync::mpsc;

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

    /// Whether the program asked to close: a reconnect stopped then ends as closed, not lost.
    fn close_requested(&self) -> bool {
        false
    }

    /// Completes when the program asks to close, to stop a backoff wait or an attempt at once.
    /// A protocol whose close goes through the queue (`BYE()`) never completes it.
    fn closing(&self) -> impl Future<Output = ()> + Send {
        std::future::pending()
    }

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

    fn close_requested(&self) -> bool {
        (**self).close_requested()
    }

    fn closing(&self) -> impl Future<Output = ()> + Send {
        (**self).closing()
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
    /// What a close by the program carries to the end.
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
                () = restorer.closing() => None,
            };
            (restored, restorer.close_requested())
        };
        match restored {
            Some(link) => session.restored(link),
            None if close_requested => break Served::Closed(S::Close::default()),
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
