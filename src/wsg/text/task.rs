//! The background task that owns a GCL connection, the thin shell around its book ([`Book`],
//! where the pairing rules live, without I/O): it writes command lines, reads reply lines and
//! hands them to the book, reads the clock and runs the timers, and does what the book asks
//! (complete a call, deliver a push, write the next request of a freed name or a probe, give the
//! connection up). It owns the callers' reply channels; the book holds them as tokens.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

pub(crate) use super::book::{Answer, Expect};
use super::book::{Book, Handled, WaitingCallers};
use super::error::Error;
use super::push::{Push, PushSubscriber};
use crate::deadline::{is_never, move_timer};
use crate::line::{io_error, peer_closed, restore_wait, Failure, LineConn, LineError, LineTask};
use crate::supervisor::CloseRequest;

/// Where a caller waits for its answer (the book's token for it: closed when the caller timed
/// out or went away).
pub(crate) type Waiter = oneshot::Sender<Result<Answer, Error>>;

/// A caller's command, on its way to the task.
pub(crate) type Request = super::book::Request<Waiter>;

/// A command about to be written: a caller's (`Some` reply channel) or the client's own probe
/// (`None`).
type Outgoing = super::book::Request<Option<Waiter>>;

/// Completes the calls the book answered, in order (a caller that left no longer listens: its
/// answer goes to nobody).
fn complete(book: &mut Book<Waiter>) {
    for (waiter, result) in book.completions() {
        let _ = waiter.send(result);
    }
}

/// Hands a reply line read at `now` to the book, and does what it asks at once: delivers a push,
/// completes the calls it answered. What is left (a name freed, `ACK BYE`) is the loop's.
fn on_line(book: &mut Book<Waiter>, text: &str, now: Instant, shared: &Shared) -> Handled {
    let handled = book.on_line(text, now);
    if let Handled::Push(push) = handled {
        shared.deliver(push);
    }
    complete(book);
    handled
}

/// What the handles and the task share.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    failure: Failure<Error>,
    /// Set by [`Client::close`](super::Client::close) before it queues `BYE()`.
    pub(crate) close: CloseRequest,
    pub(crate) subscribers: Mutex<Vec<PushSubscriber>>,
    /// What the program set up on the connection that a reconnect restores, by what it sets
    /// (`VERBOSE`, `PWT`, `CLT`, one `AUTOSEND` per quantity): the last line the gripper
    /// accepted, in the order first set.
    settings: Mutex<Vec<Setting>>,
}

/// A line the gripper accepted that a new connection needs again.
#[derive(Debug, Clone)]
struct Setting {
    /// What it sets (`"VERBOSE"`, `"PWT"`, `"CLT"`, `"AUTOSEND GRIPSTATE"`).
    key: String,
    /// The command's name in the replies.
    name: &'static str,
    line: String,
    expect: Expect,
}

impl Shared {
    /// Why the connection is gone ([`Error::Closed`] if no reason was recorded).
    pub(crate) fn failure(&self) -> Error {
        self.failure.get()
    }

    fn record(&self, error: &Error) {
        self.failure.record(error);
    }

    /// Remembers `line` (accepted by the gripper) as what sets `key`, for a reconnect.
    pub(crate) fn remember(&self, key: String, name: &'static str, line: String, expect: Expect) {
        if let Ok(mut settings) = self.settings.lock() {
            let setting = Setting {
                key,
                name,
                line,
                expect,
            };
            match settings.iter_mut().find(|s| s.key == setting.key) {
                Some(old) => *old = setting,
                None => settings.push(setting),
            }
        }
    }

    /// Forgets what sets `key` (an `AUTOSEND` switched off).
    pub(crate) fn forget(&self, key: &str) {
        if let Ok(mut settings) = self.settings.lock() {
            settings.retain(|s| s.key != key);
        }
    }

    fn settings(&self) -> Vec<Setting> {
        self.settings.lock().map(|s| s.clone()).unwrap_or_default()
    }

    fn deliver(&self, push: Push) {
        if let Ok(mut subs) = self.subscribers.lock() {
            subs.retain(|s| s.deliver(push));
        }
    }
}

/// Task settings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskConfig {
    pub give_up_after: Duration,
    /// Requests held while a command of their name is on the wire, at most.
    pub waiting_len: usize,
    /// The program's query timeout: with `give_up_after`, how long a command that restores the
    /// session after a reconnect waits for its reply (`restore_wait`).
    pub query_timeout: Duration,
}

/// Everything the task needs besides the connection (and how to open it again: the line
/// session's `LineLink`).
pub(crate) struct Task {
    pub requests: mpsc::Receiver<Request>,
    /// `STOP()` and `FASTSTOP()`, apart from the other calls: a stop must never wait behind
    /// calls that wait for their name (issue 29 K; the manual's STOP/FASTSTOP are answered
    /// during a motion, chapter 2). The task reads it whatever the queue holds.
    pub stops: mpsc::Receiver<Request>,
    pub config: TaskConfig,
    pub shared: Arc<Shared>,
}

pub(crate) use crate::deadline::after;

impl LineError for Error {
    const PEER: &'static str = "gripper";

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

/// Resolves when the caller of `BYE()` has left (its future dropped); never if `BYE()` is not
/// on the wire.
async fn bye_caller_gone(mut bye: Option<&mut Waiter>) {
    std::future::poll_fn(|cx| match &mut bye {
        Some(waiter) => waiter.poll_closed(cx),
        None => std::task::Poll::Pending,
    })
    .await
}

/// Resolves when the caller of a waiting request has left (its future dropped).
async fn any_caller_gone(mut waiting: WaitingCallers<'_, Waiter>) {
    std::future::poll_fn(|cx| {
        if waiting
            .iter_mut()
            .any(|waiter| waiter.poll_closed(cx).is_ready())
        {
            std::task::Poll::Ready(())
        } else {
            std::task::Poll::Pending
        }
    })
    .await
}

/// The text session the supervisor runs: restored with the settings the gripper accepted
/// (`VERBOSE`, `PWT`, `CLT`, `AUTOSEND`), in the order they were first set.
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
            &mut self.stops,
            self.config,
            &self.shared,
            reconnects,
        )
        .await
    }

    async fn restore(&self, conn: &mut LineConn) -> Result<(), Error> {
        // The client's own queries, bounded (`restore_wait`): with a `query_timeout` of
        // `Duration::MAX` (no timeout for the program's calls), a restored setting whose reply
        // arrived damaged held the new connection unrestored for good, and every call behind it
        // (`wsg-text:0xa9a8dc2d69601835`). Unanswered within the bound, the restore fails and
        // the next attempt connects again.
        let timeout = restore_wait(self.config.query_timeout, self.config.give_up_after);
        for setting in self.shared.settings() {
            exchange(conn, setting, timeout, &self.shared).await?;
        }
        Ok(())
    }

    fn ended(&mut self, reason: &Error) {
        self.shared.record(reason);
        // The supervisor refuses what is left in `requests`; the stops are ours to refuse.
        self.stops.close();
        while let Ok(request) = self.stops.try_recv() {
            Self::refuse(request, reason);
        }
        if let Ok(mut subs) = self.shared.subscribers.lock() {
            // Ends every push stream.
            subs.clear();
        }
    }

    fn refuse(request: Request, reason: &Error) {
        let _ = request.waiter.send(Err(reason.clone()));
    }
}

/// The longest a `close()` without timeout waits for `ACK BYE` ([`super::Client::close`]): as
/// long as any reply due at once is waited for before the client asks after it
/// (`book::DOUBT_AFTER`); after `BYE()` nothing may be written to ask.
const BYE_WAIT_MAX: Duration = super::book::DOUBT_AFTER;

/// One setting sent again on a new connection, before any call is served on it: paired by the
/// same rules as a call's reply (pushes that arrive meanwhile go to their subscribers).
async fn exchange(
    conn: &mut LineConn,
    setting: Setting,
    timeout: Duration,
    shared: &Shared,
) -> Result<(), Error> {
    let deadline = after(Instant::now(), timeout);
    let command = setting.line.clone();
    conn.writer.send::<Error>(&setting.line, deadline).await?;
    let (waiter, mut answer) = oneshot::channel();
    let mut book = Book::new(timeout);
    book.on_wire(
        setting.name,
        setting.line,
        setting.expect,
        Some(waiter),
        deadline,
        deadline,
        Instant::now(),
        false,
    );
    loop {
        let line = match tokio::time::timeout_at(deadline, conn.reader.next_line()).await {
            Err(_) => return Err(Error::Timeout { command, timeout }),
            Ok(None) => return Err(peer_closed()),
            Ok(Some(line)) => line.map_err(io_error::<Error>)?,
        };
        let Ok(text) = line.text() else { continue };
        on_line(&mut book, text, Instant::now(), shared);
        if let Ok(result) = answer.try_recv() {
            return result.map(drop);
        }
    }
}

/// Serves calls over one connection until it closes, fails or every handle is dropped; fails
/// the calls in flight and those waiting for their name with the reason, which it returns.
/// When the connection is over for good (closed, or lost with no reconnect to follow), the
/// reason is recorded and the request queue closed before any caller hears why (as GRIPLINK's
/// task does, issue 21).
async fn serve(
    conn: &mut LineConn,
    requests: &mut mpsc::Receiver<Request>,
    stops: &mut mpsc::Receiver<Request>,
    config: TaskConfig,
    shared: &Shared,
    reconnects: bool,
) -> Error {
    let mut book = Book::new(config.give_up_after);
    let timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(timer);
    // While the queue is full: the earliest deadline of a waiting request, when it leaves.
    let queue_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(queue_timer);
    // The requests whose line could not be written: told why at the end.
    let mut unsent = Vec::new();
    // `BYE()` is on the wire (with its call's timeout; `bye_timer` is at its deadline):
    // nothing more is sent.
    let mut closing: Option<Duration> = None;
    let bye_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(bye_timer);
    let end = 'serve: loop {
        let give_up = book.give_up_at();
        if let Some(at) = give_up {
            move_timer(timer.as_mut(), at);
        }
        book.prune(Instant::now());
        complete(&mut book);
        let full = book.waiting_len() >= config.waiting_len;
        let queue_deadline = if full { book.waiting_deadline() } else { None };
        if let Some(at) = queue_deadline {
            move_timer(queue_timer.as_mut(), at);
        }
        let mut to_send: Option<Outgoing> = None;
        let (bye_caller, waiting_callers) = book.watched();
        tokio::select! {
            // Replies first: they free names and callers.
            biased;
            line = conn.reader.next_line() => match line {
                Some(Ok(line)) => match line.text() {
                    Ok(text) => match on_line(&mut book, text, Instant::now(), shared) {
                        Handled::Bye => break Error::Closed,
                        // `BYE()` answered otherwise (`ERR BYE`, a reply of another kind): its
                        // call has its answer, and the program is done with the connection all
                        // the same (issue 29 N).
                        Handled::Freed("BYE") if closing.is_some() => break Error::Closed,
                        // After `BYE()` nothing more is written (issue 29 N).
                        Handled::Freed(_) if closing.is_some() => {}
                        // A name freed: its next waiting request goes out.
                        Handled::Freed(name) => to_send = next_waiting(&mut book, name),
                        Handled::Nothing | Handled::Push(_) => {}
                    },
                    Err(why) => {
                        tracing::warn!(%why, "wsg text: reply line discarded");
                        book.damage(&why.to_string());
                    }
                },
                Some(Err(e)) => break io_error(e),
                None => break peer_closed(),
            },
            () = &mut timer, if give_up.is_some() => {
                match book.overdue(config.query_timeout, config.give_up_after, Instant::now()) {
                    // Not after `BYE()` (issue 29 N): the session ends at its deadline anyway.
                    Ok(probe) if closing.is_none() => to_send = probe,
                    Ok(_) => {}
                    Err(command) => {
                        tracing::error!(%command, "wsg text: reply overdue, giving up on the connection");
                        break Error::lost(format!(
                            "no reply to {command} long after its timeout; replies can no longer be paired"
                        ));
                    }
                }
            },
            // `BYE()`'s call is over without `ACK BYE`: the connection is closed then, so
            // the calls after `close()` fail `Closed` (issue 29 N).
            () = &mut bye_timer, if closing.is_some() => {
                // Its caller is told it timed out (not `Closed`), whichever timer fires first.
                if let Some(timeout) = closing {
                    book.bye_timed_out(timeout);
                    complete(&mut book);
                }
                break Error::Closed;
            }
            // Nobody waits for `ACK BYE` any more and nothing is written after `BYE()`: the
            // session is over (a `BYE()` without timeout whose caller left kept the connection
            // and its task alive for ever).
            () = bye_caller_gone(bye_caller), if closing.is_some() => break Error::Closed,
            // A stop is read whatever the queue holds (issue 29 K).
            request = stops.recv(), if closing.is_none() => {
                let Some(request) = request else { break Error::Closed };
                to_send = admit(&mut book, request);
            }
            request = requests.recv(), if closing.is_none() && !full => {
                let Some(request) = request else { break Error::Closed };
                to_send = admit(&mut book, request);
            }
            // The queue is full: a request leaves it when its time runs out or its caller
            // leaves, and the channel is read again.
            () = &mut queue_timer, if queue_deadline.is_some() => {}
            () = any_caller_gone(waiting_callers), if full => {}
        }
        // `ACK BYE` may have been a line that could not be read, and nothing written after
        // `BYE()` can ever tell (`Book::bye_unreadable`): the session ends as at `BYE()`'s
        // deadline, its caller told why.
        if closing.is_some() && book.bye_lost_in_damage() {
            complete(&mut book);
            break Error::Closed;
        }
        let mut outgoing: VecDeque<_> = to_send.into_iter().collect();
        // Names freed by calls whose reply was damaged: their next waiting requests go out
        // (not after `BYE()`).
        for name in book.take_freed() {
            if closing.is_none() {
                outgoing.extend(next_waiting(&mut book, name));
            }
        }
        // After what there is to send, a probe if a damaged line left calls in doubt (M).
        let mut probed = closing.is_some();
        loop {
            let request = match outgoing.pop_front() {
                Some(request) => request,
                None if !probed => {
                    probed = true;
                    match book.probe(config.query_timeout, Instant::now()) {
                        Some(probe) => {
                            tracing::debug!(command = %probe.line, "wsg text: probe after a damaged reply");
                            probe
                        }
                        None => break,
                    }
                }
                None => break,
            };
            let give_up_at = after(request.deadline, config.give_up_after);
            match conn.writer.send(&request.line, give_up_at).await {
                Ok(()) => {}
                // Refused by the codec, nothing sent (`Client::submit` checks the line first,
                // so this is only a second guard).
                Err(err @ Error::InvalidArgument { .. }) => {
                    if let Some(waiter) = request.waiter {
                        let _ = waiter.send(Err(err));
                    }
                    continue;
                }
                Err(e) => {
                    // Every request taken out for this round, not only the one whose write
                    // failed: dropped unanswered, a caller read `Closed` though nobody closed
                    // the client (`wsg-text:0x13452fa5a4e4eb73`: an `AUTOSEND` freed for the
                    // round behind a write that met a broken pipe).
                    unsent.extend(request.waiter);
                    unsent.extend(outgoing.drain(..).filter_map(|r| r.waiter));
                    break 'serve e;
                }
            }
            tracing::trace!(command = %request.line, "wsg text: sent");
            if request.name == "BYE" {
                // Without timeout, bounded all the same: a `BYE()` damaged on the way may
                // be answered with nothing, and nothing written after it could draw an answer
                // (`wsg-text:0x7af44aab63b7c9f1`: `close()` without timeout waited for ever).
                let (timeout, deadline) = if is_never(request.deadline, Instant::now()) {
                    (BYE_WAIT_MAX, after(Instant::now(), BYE_WAIT_MAX))
                } else {
                    (request.timeout, request.deadline)
                };
                closing = Some(timeout);
                move_timer(bye_timer.as_mut(), deadline);
                // The calls waiting for their name are never sent now.
                book.close_waiting();
                complete(&mut book);
                for waiter in outgoing.drain(..).filter_map(|r| r.waiter) {
                    let _ = waiter.send(Err(Error::Closed));
                }
                probed = true;
            }
            book.on_wire(
                request.name,
                request.line,
                request.expect,
                request.waiter,
                request.deadline,
                give_up_at,
                Instant::now(),
                request.probe,
            );
        }
    };
    if closing.is_some() || matches!(end, Error::Closed) || !reconnects {
        shared.record(&end);
        requests.close();
        stops.close();
    }
    for waiter in unsent {
        let _ = waiter.send(Err(end.clone()));
    }
    book.drain(&end);
    complete(&mut book);
    conn.writer.shutdown().await;
    // After BYE() the program is done with the connection, however it ended: a loss then is
    // not reconnected.
    if closing.is_some() && reconnects {
        Error::Closed
    } else {
        end
    }
}

/// The book's [`Book::admit`] at this moment, its answers told at once.
fn admit(book: &mut Book<Waiter>, request: Request) -> Option<Outgoing> {
    let request = book.admit(request, Instant::now());
    complete(book);
    request.map(super::book::Request::outgoing)
}

/// The book's [`Book::next_waiting`] at this moment, its answers told at once.
fn next_waiting(book: &mut Book<Waiter>, name: &str) -> Option<Outgoing> {
    let request = book.next_waiting(name, Instant::now());
    complete(book);
    request.map(super::book::Request::outgoing)
}
