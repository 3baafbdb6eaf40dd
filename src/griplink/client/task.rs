//! The background task that owns the connection, the thin shell around its pipeline
//! ([`Pipeline`], where the pairing rules live, without I/O): it writes commands in the order
//! callers submit them, reads reply lines and hands them to the pipeline, reads the clock and
//! runs the give-up timer, and does what the pipeline asks (answer a call, send a probe, give
//! the connection up). It owns the callers' reply channels; the pipeline holds them only as
//! tokens. When the connection is lost it either closes for good or, with
//! [`ClientConfig::reconnect`], connects again with backoff and restores the session before
//! serving the calls that queued meanwhile.
//!
//! [`ClientConfig::reconnect`]: super::ClientConfig::reconnect

use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

use super::pipeline::{Delivery, Pipeline};
use crate::deadline::move_timer;
use crate::griplink::command::{Command, Expect};
use crate::griplink::error::{Error, Result};
use crate::griplink::reply::{interpret, Checked};
use crate::line::{io_error, peer_closed, restore_wait, Failure, LineConn, LineError, LineTask};
use crate::supervisor::CloseRequest;

/// Where a caller waits for its result (the pipeline's token for it: closed when the caller
/// timed out or went away).
pub(crate) type Waiter = oneshot::Sender<Result<Checked>>;

/// Completes a call (a caller that has gone no longer listens: its result goes to nobody).
#[inline]
fn complete(waiter: Waiter, result: Result<Checked>) {
    let _ = waiter.send(result);
}

/// A caller's command, on its way to the task.
#[derive(Debug)]
pub(crate) struct Request {
    pub line: String,
    pub expect: Expect,
    /// The caller stops waiting here; a request still queued at that point is never sent.
    pub deadline: Instant,
    /// The timeout the caller chose (for the error message).
    pub timeout: Duration,
    pub waiter: Waiter,
    /// `BYE()`: after it, accept nothing more and end when its reply is in.
    pub bye: bool,
}

/// What the handles and the task share: why the connection ended, and what the program set up
/// that a reconnect restores.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    failure: Failure<Error>,
    /// Set by [`Client::close`](super::Client::close) before it queues `BYE()`.
    pub(crate) close: CloseRequest,
    /// The last `VERBOSE` mode the controller accepted.
    verbose: Mutex<Option<bool>>,
}

impl Shared {
    /// The reason the connection is gone ([`Error::Closed`] if none was recorded).
    pub(crate) fn failure(&self) -> Error {
        self.failure.get()
    }

    pub(crate) fn set_verbose(&self, on: bool) {
        if let Ok(mut v) = self.verbose.lock() {
            *v = Some(on);
        }
    }

    fn verbose(&self) -> Option<bool> {
        self.verbose.lock().ok().and_then(|v| *v)
    }

    fn record(&self, error: &Error) {
        self.failure.record(error);
    }
}

/// Task settings taken from the client configuration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskConfig {
    pub pipeline_depth: usize,
    pub give_up_after: Duration,
    /// How long a resynchronisation probe may take before the connection is given up.
    pub probe_timeout: Duration,
    /// The program's query timeout: with `give_up_after`, how long a command that restores the
    /// session after a reconnect waits for its reply (`restore_wait`).
    pub query_timeout: Duration,
}

/// Everything the task needs besides the connection (and how to open it again: the line
/// session's `LineLink`).
pub(crate) struct Task {
    pub requests: mpsc::Receiver<Request>,
    pub config: TaskConfig,
    pub shared: Arc<Shared>,
}

impl LineError for Error {
    const PEER: &'static str = "controller";

    fn connection_lost(why: String) -> Self {
        Error::lost(why)
    }

    fn invalid_line(reason: String) -> Self {
        Error::invalid("command line", reason)
    }

    fn closed() -> Self {
        Error::Closed
    }

    fn is_closed(&self) -> bool {
        matches!(self, Error::Closed)
    }
}

/// One command and its reply, before any caller's command is served (restoring the session
/// on a new connection).
async fn exchange(conn: &mut LineConn, command: Command, timeout: Duration) -> Result<()> {
    let line = command.encode()?;
    let deadline = crate::deadline::after(Instant::now(), timeout);
    conn.writer.send::<Error>(&line, deadline).await?;
    let reply = match tokio::time::timeout_at(deadline, conn.reader.next_line()).await {
        Err(_) => {
            return Err(Error::Timeout {
                command: line,
                timeout,
            })
        }
        Ok(None) => return Err(peer_closed()),
        Ok(Some(reply)) => reply.map_err(io_error::<Error>)?,
    };
    match reply.text() {
        Ok(text) => interpret(&line, command.expect(), text).map(drop),
        Err(why) => Err(Error::MalformedReply {
            command: line,
            line: String::new(),
            reason: why.to_string(),
        }),
    }
}

/// The GRIPLINK session the supervisor runs: one connection at a time, restored with the
/// last `VERBOSE` the controller accepted.
impl LineTask for Task {
    type Error = Error;
    type Request = Request;

    fn requests(&mut self) -> &mut mpsc::Receiver<Request> {
        &mut self.requests
    }

    fn abandoned(&self) -> bool {
        self.requests.is_closed()
    }

    async fn serve(&mut self, conn: &mut LineConn, reconnects: bool) -> Error {
        serve(
            conn,
            &mut self.requests,
            &self.config,
            &self.shared,
            reconnects,
        )
        .await
    }

    async fn restore(&self, conn: &mut LineConn) -> Result<()> {
        if let Some(on) = self.shared.verbose() {
            // Bounded (`restore_wait`): a program's `query_timeout` of `Duration::MAX` must not
            // hold a new connection whose reply never comes unrestored for good.
            let wait = restore_wait(self.config.query_timeout, self.config.give_up_after);
            exchange(conn, Command::SetVerbose(on), wait).await?;
        }
        Ok(())
    }

    fn ended(&mut self, reason: &Error) {
        self.shared.record(reason);
    }

    fn refuse(request: Request, reason: &Error) {
        let _ = request.waiter.send(Err(reason.clone()));
    }
}

/// Serves calls over one connection until it closes, fails or every handle is dropped; fails
/// the calls in flight with the reason, which it returns. When the connection is over for good
/// (closed, or lost with no reconnect to follow), the request queue is closed before any caller
/// hears why, so a caller that got the error finds [`Client::is_closed`](super::Client::is_closed)
/// already true; and the reason is recorded in `shared` before the queue is closed, so a call
/// refused by the closed queue reads the same reason (`ConnectionLost`, never a `Closed` that
/// nobody asked for; issue 21).
async fn serve(
    conn: &mut LineConn,
    requests: &mut mpsc::Receiver<Request>,
    config: &TaskConfig,
    shared: &Shared,
    reconnects: bool,
) -> Error {
    let LineConn { reader, writer } = conn;
    let mut pipeline: Pipeline<Waiter> = Pipeline::new(config.pipeline_depth, config.give_up_after)
        .with_probe_timeout(config.probe_timeout);
    let mut closing = false;
    // A request whose write failed: told why after the queue is closed (below).
    let mut unsent = None;

    // One give-up timer for the connection, moved to the oldest outstanding reply's limit
    // whenever that changes. When no reply is outstanding it is not polled (and may still fire
    // once, unseen).
    let give_up_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(give_up_timer);
    let end: Error = loop {
        let give_up = pipeline.give_up_at(Instant::now);
        if let Some(at) = give_up {
            move_timer(give_up_timer.as_mut(), at);
        }
        tokio::select! {
            // Replies first: they free slots and callers.
            biased;
            line = reader.next_line() => match line {
                Some(Ok(line)) => match pipeline.on_line(line.text(), Instant::now, complete) {
                    Delivery::Resync(probe) if !closing => {
                        tracing::warn!(%probe, "griplink: a reply was out of step, resynchronising");
                        let limit = pipeline.give_up_at(Instant::now).unwrap_or_else(Instant::now);
                        if let Err(e) = writer.send(probe, limit).await {
                            break e;
                        }
                    }
                    Delivery::Lost => break Error::lost("a reply did not answer its command while others were on the wire; \
                         replies can no longer be paired"),
                    _ if closing && pipeline.is_empty() => break Error::Closed,
                    _ => {}
                },
                Some(Err(e)) => break io_error(e),
                None if closing => break Error::Closed,
                None => break peer_closed(),
            },
            () = &mut give_up_timer, if give_up.is_some() => {
                let command = pipeline.oldest().unwrap_or_default().to_owned();
                tracing::error!(%command, "griplink: reply overdue, giving up on the connection");
                break Error::lost(format!(
                    "no reply to {command} long after its timeout; replies can no longer be paired"
                ));
            },
            request = requests.recv(), if !closing && pipeline.has_room() => {
                let Some(request) = request else { break Error::Closed };
                // A command whose caller has gone is never sent: a GRIP nobody waits for any
                // more must not move the fingers later.
                if request.waiter.is_closed() {
                    tracing::debug!(command = %request.line, "griplink: caller gone before sending, dropped");
                    continue;
                }
                if Instant::now() >= request.deadline {
                    let _ = request.waiter.send(Err(Error::Timeout {
                        command: request.line,
                        timeout: request.timeout,
                    }));
                    continue;
                }
                let give_up = pipeline.give_up_for(request.deadline, request.timeout);
                match writer.send(&request.line, give_up.limit()).await {
                    Ok(()) => {}
                    Err(err @ Error::InvalidArgument { .. }) => {
                        let _ = request.waiter.send(Err(err));
                        continue;
                    }
                    Err(err) => {
                        unsent = Some(request.waiter);
                        break err;
                    }
                }
                tracing::trace!(command = %request.line, "griplink: sent");
                closing |= request.bye;
                pipeline.push(request.line, request.expect, request.waiter, give_up);
            }
        }
    };

    if closing || matches!(end, Error::Closed) || !reconnects {
        // After BYE the program is done with the connection, however it ended (see below).
        shared.record(if closing { &Error::Closed } else { &end });
        requests.close();
    }
    if let Some(waiter) = unsent {
        let _ = waiter.send(Err(end.clone()));
    }
    pipeline.drain(&end, |waiter, error| complete(waiter, Err(error)));
    writer.shutdown().await;
    // After BYE the program is done with the connection, however it ended.
    if closing {
        Error::Closed
    } else {
        end
    }
}
