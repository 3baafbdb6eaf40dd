//! A line protocol's connection task as the supervisor (`crate::supervisor`) runs it: one
//! connection at a time, closed at once when it is lost, opened again by the task's opener and
//! restored by the task. GRIPLINK and the WSG text client differ only in how they serve a
//! connection and what they restore ([`LineTask`]).

use std::future::Future;
use std::time::Duration;

use tokio::sync::mpsc;

use super::client::{LineConn, LineError, Opener};
use crate::reconnect::{EventSender, ReconnectPolicy};
use crate::supervisor::{CloseRequest, Restore, Served, Session};

/// What a line protocol's task supplies.
pub(crate) trait LineTask: Send + Sync + Sized + 'static {
    /// The protocol's error.
    type Error: LineError + std::fmt::Display + Send + Sync;
    /// A call waiting in the queue.
    type Request: Send;

    /// The queue of calls from the handles.
    fn requests(&mut self) -> &mut mpsc::Receiver<Self::Request>;
    /// Every handle is gone (the queue is closed).
    fn abandoned(&self) -> bool;
    /// Set by `close()` before it queues its `BYE()`: a reconnect stops at once (a `BYE()`
    /// waiting in the queue would wait out the backoff, and there is no connection to send it
    /// on).
    fn close_request(&self) -> &CloseRequest;
    /// Where the connection's events go.
    fn events(&self) -> &EventSender;
    /// The reconnect policy (`None`: a lost connection stays closed).
    fn policy(&self) -> Option<ReconnectPolicy>;
    /// How to open a new connection (`None`: a stream that cannot be opened again), within
    /// which time, and its longest line.
    fn opener(&self) -> (Option<&Opener>, Duration, usize);
    /// Serves calls over `conn` until it closes (the reason is then [`LineError::closed`]) or
    /// is lost; fails the calls in flight with the reason, which it returns.
    fn serve(&mut self, conn: &mut LineConn) -> impl Future<Output = Self::Error> + Send;
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

/// A line task and its connection (`None` from a loss until a reconnect).
pub(crate) struct LineSession<T> {
    task: T,
    conn: Option<LineConn>,
}

impl<T> LineSession<T> {
    /// The session serving `conn` first.
    pub(crate) fn new(task: T, conn: LineConn) -> Self {
        LineSession {
            task,
            conn: Some(conn),
        }
    }
}

/// What a reconnect attempt borrows: the task.
pub(crate) struct LineRestore<'a, T>(&'a T);

impl<T: LineTask> Restore for LineRestore<'_, T> {
    type Link = LineConn;
    type Error = T::Error;

    fn events(&self) -> &EventSender {
        self.0.events()
    }

    fn abandoned(&self) -> bool {
        self.0.abandoned()
    }

    fn close_request(&self) -> &CloseRequest {
        self.0.close_request()
    }

    async fn connect(&self) -> Result<LineConn, T::Error> {
        match self.0.opener() {
            (Some(opener), timeout, max_line_len) => {
                LineConn::open(opener, timeout, max_line_len).await
            }
            // Not reached: a task without an opener takes no reconnect policy.
            (None, ..) => Err(T::Error::connection_lost(
                "the stream cannot be opened again".into(),
            )),
        }
    }

    fn restore<'a>(
        &'a self,
        conn: &'a mut LineConn,
    ) -> impl Future<Output = Result<(), T::Error>> + Send + 'a {
        self.0.restore(conn)
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
        match self.task.serve(conn).await {
            end if end.is_closed() => Served::Closed(()),
            lost => Served::Lost(lost),
        }
    }

    fn requests(&mut self) -> &mut mpsc::Receiver<T::Request> {
        self.task.requests()
    }

    fn restorer(&self) -> LineRestore<'_, T> {
        LineRestore(&self.task)
    }

    fn policy(&self) -> Option<ReconnectPolicy> {
        self.task.policy()
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
