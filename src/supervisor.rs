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

/// What a protocol's connection task supplies to the [`supervise`] loop. The connection itself
/// (`Link`) is held apart: a reconnect attempt borrows the session (from another thread, for
/// all the compiler knows: it must be `Sync`) while a byte stream is only `Send`.
pub(crate) trait Session: Send + Sync + Sized {
    /// A new connection, opened (and restored) by a reconnect.
    type Link: Send;
    /// A call waiting in the queue.
    type Request: Send;
    /// Why a connection was lost, or an attempt to restore one failed.
    type Error: fmt::Display + Send + Sync;
    /// What a close by the program carries to the end.
    type Close: Default + Send;

    /// Serves calls over `link` until it is closed or lost. The calls in flight on it are
    /// answered (or failed) before it returns.
    fn serve(
        &mut self,
        link: &mut Self::Link,
    ) -> impl Future<Output = Served<Self::Close, Self::Error>> + Send;

    /// The queue of calls from the handles.
    fn requests(&mut self) -> &mut mpsc::Receiver<Self::Request>;

    /// Where the connection's events go.
    fn events(&self) -> &EventSender;

    /// The reconnect policy (`None`: a lost connection stays closed).
    fn policy(&self) -> Option<ReconnectPolicy>;

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

    /// What the [`ConnectionEvent::Lost`] event says about `reason`.
    fn loss_report(&self, reason: &Self::Error) -> String {
        reason.to_string()
    }

    /// After a loss is reported, before any reconnect: fail what `serve` left waiting, and
    /// prepare what the new connection restores.
    fn lost(&mut self, _reason: &Self::Error) {}

    /// Opens a new connection (one attempt, bounded by the connect timeout).
    fn connect(&self) -> impl Future<Output = Result<Self::Link, Self::Error>> + Send;

    /// Restores the session on a new connection before any call is served on it.
    fn restore<'a>(
        &'a self,
        link: &'a mut Self::Link,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'a;

    /// The connection restored, before calls are served over it.
    fn restored(&mut self, _link: &mut Self::Link) {}

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
pub(crate) async fn supervise<S: Session>(mut session: S, mut link: S::Link) {
    let end = loop {
        let reason = match session.serve(&mut link).await {
            Served::Closed(close) => break Served::Closed(close),
            Served::Lost(reason) => reason,
        };
        // The old connection is closed before the backoff: the peer sees it go at once.
        drop(link);
        session.events().send(ConnectionEvent::Lost {
            reason: session.loss_report(&reason),
        });
        session.lost(&reason);
        let Some(policy) = session.policy() else {
            break Served::Lost(reason);
        };
        // Calls made meanwhile wait in the queue, within their own timeouts.
        let restored = {
            let session = &session;
            let events = session.events();
            let retry = reconnect::retry(
                &policy,
                events,
                || session.abandoned(),
                |_| async {
                    let mut link = session.connect().await?;
                    events.send(ConnectionEvent::Connected);
                    session.restore(&mut link).await?;
                    Ok::<_, S::Error>(link)
                },
            );
            tokio::select! {
                // Fixed order (a seeded run replays exactly; unbiased select! draws from a
                // per-process random seed): an attempt that completes at the same poll as the
                // close still counts, and the close is seen at the next poll either way.
                biased;
                restored = retry => restored,
                () = session.closing() => None,
            }
        };
        match restored {
            Some(restored) => {
                link = restored;
                session.restored(&mut link);
            }
            None if session.close_requested() => break Served::Closed(S::Close::default()),
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
