//! The background task behind the handles: serves calls over a [`Link`] until it breaks, then
//! either closes for good or, with [`ClientConfig::reconnect`], reconnects with backoff and runs
//! the opening sequence again before serving the calls that queued meanwhile.
//!
//! When it closes for good, every queued call gets the reason, and so does every later call
//! (through `closed`). [`Client::close`](super::Client::close) ends it at any point, reconnecting
//! included: the reason is then [`Error::Closed`].

use std::sync::{Arc, OnceLock};

use tokio::sync::mpsc;

use super::in_flight::closed_error;
use super::link::{Call, Link, Opener};
use super::session::Session;
use super::{ClientConfig, Shared};
use crate::reconnect::{EventSender, ReconnectPolicy};
use crate::smartgrasp::error::Error;
use crate::supervisor::{supervise, CloseRequest, Restore, Served, Session as Supervised};

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
    pub shutdown: CloseRequest,
    /// Counters the handles read.
    pub shared: Arc<Shared>,
}

/// Runs until every handle is dropped, the program closes the client, or the connection is lost
/// for good (the loop is the shared supervisor's, `crate::supervisor`).
pub(crate) async fn run(link: Link, task: Task) {
    supervise(SmartGrasp {
        task,
        link: Some(link),
    })
    .await;
}

/// The SmartGrasp session the supervisor runs: restored by the opening sequence again
/// (`session.rs`).
struct SmartGrasp {
    task: Task,
    /// `None` from a loss until a reconnect: the lost connection is closed at once.
    link: Option<Link>,
}

/// The reason a client ended, as its calls read it.
fn reason(end: &Served<(), Error>) -> Error {
    match end {
        Served::Closed(()) => Error::Closed,
        Served::Lost(reason) => reason.clone(),
    }
}

impl Restore for Task {
    type Link = Link;
    type Error = Error;

    fn events(&self) -> &EventSender {
        &self.events
    }

    fn abandoned(&self) -> bool {
        self.calls.is_closed()
    }

    fn close_request(&self) -> &CloseRequest {
        &self.shutdown
    }

    async fn connect(&self) -> Result<Link, Error> {
        Link::connect(&self.opener, &self.config, &self.shared).await
    }

    async fn restore(&self, link: &mut Link) -> Result<(), Error> {
        let opened = self.session.open(link, &self.config).await?;
        self.shared.set_opened(&opened);
        Ok(())
    }
}

impl Supervised for SmartGrasp {
    type Restore<'a> = &'a Task;
    type Link = Link;
    type Error = Error;
    type Request = Call;
    type Close = ();

    async fn serve(&mut self) -> Served<(), Error> {
        let task = &mut self.task;
        let Some(link) = self.link.as_mut() else {
            // Not reached: the supervisor serves only after a connect or a reconnect.
            return Served::Lost(Error::ConnectionLost {
                reason: "not connected".into(),
            });
        };
        let session = &mut task.session;
        let served = link
            .serve(
                &mut task.calls,
                &mut |request, response, timeout| session.record(request, response, timeout),
                task.shutdown.token(),
            )
            .await;
        match served {
            // `None`: every handle is gone. `Closed`: closed by the program.
            None | Some(Error::Closed) => Served::Closed(()),
            Some(reason) => Served::Lost(reason),
        }
    }

    fn requests(&mut self) -> &mut mpsc::Receiver<Call> {
        &mut self.task.calls
    }

    fn restorer(&self) -> &Task {
        &self.task
    }

    fn policy(&self) -> Option<ReconnectPolicy> {
        self.task.config.reconnect
    }

    fn lost(&mut self, _reason: &Error) {
        self.link = None;
    }

    fn restored(&mut self, link: Link) {
        self.link = Some(link);
    }

    fn ended(&mut self, end: &Served<(), Error>) {
        let _ = self.task.closed.set(reason(end));
    }

    fn refuse(call: Call, end: &Served<(), Error>) {
        let _ = call.reply.send(Err(closed_error(Some(&reason(end)))));
    }
}
