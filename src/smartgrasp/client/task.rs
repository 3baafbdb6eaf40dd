//! The background task behind the handles: serves calls over a [`Link`] until it breaks, then
//! either closes for good or, with [`ClientConfig::reconnect`], reconnects with backoff and runs
//! the opening sequence again before serving the calls that queued meanwhile.
//!
//! When it closes for good, every queued call gets the reason, and so does every later call
//! (through `closed`).

use std::net::SocketAddr;
use std::sync::{Arc, OnceLock};

use tokio::sync::mpsc;

use super::link::{closed_error, Call, Link};
use super::session::Session;
use super::ClientConfig;
use crate::reconnect::{self, ConnectionEvent, EventSender};
use crate::smartgrasp::error::Error;

/// Everything the task needs besides the first connection.
pub(crate) struct Task {
    pub calls: mpsc::Receiver<Call>,
    pub closed: Arc<OnceLock<Error>>,
    pub session: Session,
    pub config: ClientConfig,
    /// Where to reconnect to (resolved once, by the first connect).
    pub addrs: Vec<SocketAddr>,
    pub events: EventSender,
}

/// Runs until every handle is dropped, or the connection is lost for good.
pub(crate) async fn run(mut link: Link, mut task: Task) {
    let reason = loop {
        let Some(reason) = link.serve(&mut task.calls, &mut task.session).await else {
            return;
        };
        drop(link);
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
            addrs,
            events,
            ..
        } = &task;
        let restored = reconnect::retry(
            &policy,
            events,
            || calls.is_closed(),
            |_| async {
                let mut link = Link::connect(addrs, config.connect_timeout).await?;
                events.send(ConnectionEvent::Connected);
                session.open(&mut link, config).await?;
                Ok::<_, Error>(link)
            },
        )
        .await;
        match restored {
            Some(restored) => link = restored,
            None => break reason,
        }
    };
    let _ = task.closed.set(reason.clone());
    task.calls.close();
    while let Ok(call) = task.calls.try_recv() {
        let _ = call.reply.send(Err(closed_error(Some(&reason))));
    }
}
