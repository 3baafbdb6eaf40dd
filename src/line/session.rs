//! A line protocol's connection task as the supervisor (`crate::supervisor`) runs it: one
//! connection at a time, closed at once when it is lost, opened again as its [`LineLink`] says
//! and restored by the task. GRIPLINK and the WSG text client differ only in how they serve a
//! connection and what they restore ([`LineTask`]).

use std::future::Future;
use std::time::Duration;

use tokio::sync::mpsc;

use super::client::{LineConn, LineError, Opener};
use crate::reconnect::{BoxStream, EventSender, ReconnectPolicy};
use crate::supervisor::{supervise, CloseRequest, Restore, Served, Session};

/// What a line protocol's task supplies: how it serves a connection and what it restores.
pub(crate) trait LineTask: Send + Sync + Sized + 'static {
    /// The protocol's error.
    type Error: LineError + std::fmt::Display + Send + Sync;
    /// A call waiting in the queue.
    type Request: Send;

    /// The queue of calls from the handles.
    fn requests(&mut self) -> &mut mpsc::Receiver<Self::Request>;
    /// Every handle is gone (the queue is closed).
    fn abandoned(&self) -> bool;
    /// Serves calls over `conn` until it closes (the reason is then [`LineError::closed`]) or
    /// is lost; fails the calls in flight with the reason, which it returns. `reconnects`: a
    /// loss is followed by a reconnect (the client is not over with it).
    fn serve(
        &mut self,
        conn: &mut LineConn,
        reconnects: bool,
    ) -> impl Future<Output = Self::Error> + Send;
    /// Restores the session on a new connection before any call is served on it.
    fn restore<'a>(
        &'a self,
        conn: &'a mut LineConn,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'a;
    /// The client ends with `reason`: record it for the handles (before the queue closes).
    fn ended(&mut self, reason: &Self::Error);
    /// A call still in the queue when the client ended gets the reason.
    fn refuse(request: Self::Request, reason: &Self::Error);
}

/// The least and the most a line client waits for the reply to a line it restores.
const RESTORE_WAIT: (Duration, Duration) = (Duration::from_secs(1), Duration::from_secs(10));

/// How long a line client waits for the reply to a line it restores on a new connection (its
/// own call, with no caller to answer): as long as a reply of the program's calls may stay away
/// before the connection is given up, the query's timeout plus `give_up_after`, and within
/// [`RESTORE_WAIT`]. Not the query's timeout alone: the WSG simulator, like a gripper that
/// writes nothing for a while after an `ACK`, held the restored `VERBOSE=1` behind
/// `ACK AUTOSEND` to the very instant a 50 ms query timeout expired, and the client, which gave
/// every attempt up there, reconnected for ever (`wsg-text:0x527e90827099e930`). At least a
/// second, whatever the program's timeouts: with a `give_up_after` of zero the same gap failed
/// every attempt again (`wsg-text:0x6fb78146710d7e6a`), while a reply that comes is a healthy
/// device's, and waiting longer costs only an attempt that fails anyway. At most ten seconds, so
/// that a program's `Duration::MAX` (no timeout for its calls) never holds a new connection
/// unrestored for good.
pub(crate) fn restore_wait(query_timeout: Duration, give_up_after: Duration) -> Duration {
    let (least, most) = RESTORE_WAIT;
    query_timeout
        .saturating_add(give_up_after)
        .clamp(least, most)
}

/// How a line client's connection is reported, opened again and closed: the same for both
/// protocols, so the session holds it, not the protocol's task.
pub(crate) struct LineLink {
    /// Where the connection's events go.
    pub events: EventSender,
    /// The reconnect policy (`None`: a lost connection stays closed).
    pub policy: Option<ReconnectPolicy>,
    /// How to open a new connection (`None`: a stream the program handed over, which cannot be
    /// opened again; it takes no reconnect policy).
    pub opener: Option<Opener>,
    /// Within which time a new connection must be open.
    pub connect_timeout: Duration,
    /// The longest line read.
    pub max_line_len: usize,
    /// Set by `close()` before it queues its `BYE()`: a reconnect stops at once (a `BYE()`
    /// waiting in the queue would wait out the backoff, and there is no connection to send it
    /// on).
    pub close: CloseRequest,
}

/// Runs a line client's connection task over `stream` until the client ends (the loop is the
/// shared supervisor's, `crate::supervisor`).
pub(crate) async fn run<T: LineTask>(stream: BoxStream, task: T, link: LineLink) {
    let conn = LineConn::new(stream, link.max_line_len);
    supervise(LineSession {
        task,
        conn: Some(conn),
        link,
    })
    .await;
}

/// A line task, its connection (`None` from a loss until a reconnect) and how to open another.
struct LineSession<T> {
    task: T,
    conn: Option<LineConn>,
    link: LineLink,
}

/// What a reconnect attempt borrows: the task (to restore) and how to open a connection.
struct LineRestore<'a, T> {
    task: &'a T,
    link: &'a LineLink,
}

impl<T: LineTask> Restore for LineRestore<'_, T> {
    type Link = LineConn;
    type Error = T::Error;

    fn events(&self) -> &EventSender {
        &self.link.events
    }

    fn abandoned(&self) -> bool {
        self.task.abandoned()
    }

    fn close_request(&self) -> &CloseRequest {
        &self.link.close
    }

    async fn connect(&self) -> Result<LineConn, T::Error> {
        let link = self.link;
        match &link.opener {
            Some(opener) => LineConn::open(opener, link.connect_timeout, link.max_line_len).await,
            // Not reached: a task without an opener takes no reconnect policy.
            None => Err(T::Error::connection_lost(
                "the stream cannot be opened again".into(),
            )),
        }
    }

    fn restore<'a>(
        &'a self,
        conn: &'a mut LineConn,
    ) -> impl Future<Output = Result<(), T::Error>> + Send + 'a {
        self.task.restore(conn)
    }
}

/// The reason a client ended, as its calls read it.
fn reason<E: LineError>(end: &Served<(), E>) -> E {
    match end {
        Served::Closed(()) => E::closed(),
        Served::Lost(reason) => reason.clone(),
    }
}

impl<T: LineTask> Session for LineSession<T> {
    type Restore<'a> = LineRestore<'a, T>;
    type Link = LineConn;
    type Error = T::Error;
    type Request = T::Request;
    type Close = ();

    async fn serve(&mut self) -> Served<(), T::Error> {
        let Some(conn) = self.conn.as_mut() else {
            // Not reached: the supervisor serves only after a connect or a reconnect.
            return Served::Lost(T::Error::connection_lost("not connected".into()));
        };
        // Closed: `BYE()`, or nobody left to call; nothing to report or restore.
        let reconnects = self.link.policy.is_some();
        match self.task.serve(conn, reconnects).await {
            end if end.is_closed() => Served::Closed(()),
            lost => Served::Lost(lost),
        }
    }

    fn requests(&mut self) -> &mut mpsc::Receiver<T::Request> {
        self.task.requests()
    }

    fn restorer(&self) -> LineRestore<'_, T> {
        LineRestore {
            task: &self.task,
            link: &self.link,
        }
    }

    fn policy(&self) -> Option<ReconnectPolicy> {
        self.link.policy
    }

    fn lost(&mut self, _reason: &T::Error) {
        // The lost connection is closed at once, not at the reconnect.
        self.conn = None;
    }

    fn restored(&mut self, conn: LineConn) {
        self.conn = Some(conn);
    }

    fn ended(&mut self, end: &Served<(), T::Error>) {
        self.task.ended(&reason(end));
    }

    fn refuse(request: T::Request, end: &Served<(), T::Error>) {
        T::refuse(request, &reason(end));
    }
}
