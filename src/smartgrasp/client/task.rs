//! The background task behind the handles: serves calls over a [`Link`] until it breaks, then
//! either closes for good or, with [`ClientConfig::reconnect`], reconnects with backoff and runs
//! the opening sequence again before serving the calls that queued meanwhile.
//!
//! When it closes for good, every queued call gets the reason, and so does every later call
//! (through `closed`). [`Client::close`](super::Client::close) ends it at any point, reconnecting
//! included: the reason is then [`Error::Closed`].

use std::sync::{Arc, OnceLock};

use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use super::link::{closed_error, Call, Link, Opener};
use super::session::Session;
use super::{ClientConfig, Shared};
use crate::reconnect::{self, ConnectionEvent, EventSender};
use crate::smartgrasp::error::Error;

/// Everything the task needs besides the first connection.
pub(crate) struct Task {
    pub calls: mpsc::Receiver<Call>,
    pub closed: Arc<OnceLock<Error>>,
    pub session: Session,
    pub config: ClientConfig,
    /// How to reconnect: the addresses resolved once by the first connect, or the program's
    /// opener.
    pub opener: Opener,
    pub events: EventSender,
    /// Cancelled by `Client::close`.
    pub shutdown: CancellationToken,
    /// Counters the handles read.
    pub shared: Arc<Shared>,
}

/// Runs until every handle is dropped, the program closes the client, or the connection is lost
/// for good.
pub(crate) async fn run(mut link: Link, mut task: Task) {
    let reason = loop {
        let session = &mut task.session;
        let served = link
            .serve(
                &mut task.calls,
                &mut |request, response| session.record(request, response),
                &task.shutdown,
            )
            .await;
        let Some(reason) = served else {
            return;
        };
        drop(link);
        // Closed by the program: nothing to report or restore.
        if matches!(reason, Error::Closed) {
            break reason;
        }
        task.events.send(ConnectionEvent::Lost {
            reason: reason.to_string(),
        });
        let Some(policy) = task.config.reconnect else {
            break reason;
        };
        // Calls made meanwhile wait in the channel, within their own timeouts.
        let Task {
            calls,
            session,
            config,
            opener,
            events,
            shutdown,
            shared,
            ..
        } = &task;
        let retry = reconnect::retry(
            &policy,
            events,
            || calls.is_closed(),
            |_| async {
                let mut link = Link::connect(opener, config, shared).await?;
                events.send(ConnectionEvent::Connected);
                let opened = session.open(&mut link, config).await?;
                shared.set_opened(&opened);
                Ok::<_, Error>(link)
            },
        );
        // `close()` stops reconnecting, in a backoff wait or in the middle of an attempt.
        let restored = tokio::select! {
            // Fixed order (a seeded run replays exactly; unbiased select! draws from a
            // per-process random seed): an attempt that completes at the same poll as the
            // cancellation still counts, and `close()` is seen at the next poll either way.
            biased;
            restored = retry => restored,
            () = shutdown.cancelled() => None,
        };
        match restored {
            Some(restored) => link = restored,
            None if shutdown.is_cancelled() => break Error::Closed,
            None => break reason,
        }
    };
    let _ = task.closed.set(reason.clone());
    task.calls.close();
    // `recv`, not `try_recv`: a call that took its place in the queue before it closed puts
    // its request in afterwards, and `recv` waits for it where `try_recv` reports the queue
    // empty; that request would then never be answered (its caller waited out its timeout).
    while let Some(call) = task.calls.recv().await {
        let _ = call.reply.send(Err(closed_error(Some(&reason))));
    }
}
