//! The background task that owns the connection: it writes commands in the order callers
//! submit them and pairs each reply line with the oldest outstanding command. When the
//! connection is lost it either closes for good or, with [`ClientConfig::reconnect`], connects
//! again with backoff and restores the session before serving the calls that queued meanwhile.
//!
//! [`ClientConfig::reconnect`]: super::ClientConfig::reconnect

use std::future::poll_fn;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::BytesMut;
use futures_core::Stream;
use tokio::io::{AsyncWriteExt, ReadHalf, WriteHalf};
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio::time::Instant;
use tokio_util::codec::{Encoder, FramedRead};

use super::pipeline::{Delivery, Pipeline, Slot, Waiter};
use crate::deadline::move_timer;
use crate::griplink::codec::{LineCodec, RawLine, RawLineCodec};
use crate::griplink::command::{Command, Expect};
use crate::griplink::error::Error;
use crate::griplink::reply::interpret;
use crate::reconnect::{self, BoxStream, ConnectionEvent, EventSender, Open, ReconnectPolicy};

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
    failure: Mutex<Option<Error>>,
    /// The last `VERBOSE` mode the controller accepted.
    verbose: Mutex<Option<bool>>,
}

impl Shared {
    /// The reason the connection is gone ([`Error::Closed`] if none was recorded).
    pub(crate) fn failure(&self) -> Error {
        self.failure
            .lock()
            .ok()
            .and_then(|f| f.clone())
            .unwrap_or(Error::Closed)
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
        if let Ok(mut f) = self.failure.lock() {
            f.get_or_insert_with(|| error.clone());
        }
    }
}

/// Task settings taken from the client configuration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskConfig {
    pub pipeline_depth: usize,
    pub give_up_after: Duration,
    pub max_line_len: usize,
    /// How long a resynchronisation probe may take before the connection is given up.
    pub probe_timeout: Duration,
    /// Timeout of the commands that restore the session after a reconnect.
    pub query_timeout: Duration,
    pub connect_timeout: Duration,
}

/// Everything the task needs besides the first connection.
pub(crate) struct Task {
    pub requests: mpsc::Receiver<Request>,
    pub config: TaskConfig,
    pub shared: Arc<Shared>,
    pub events: EventSender,
    /// Reconnect with this backoff (`None`: a lost connection stays closed).
    pub reconnect: Option<ReconnectPolicy>,
    /// How to reconnect.
    pub opener: Opener,
}

/// How a reconnect opens a new connection.
pub(crate) enum Opener {
    /// The addresses resolved once, when the client connected (tried in order).
    Tcp(Vec<SocketAddr>),
    /// The program's own opener ([`Client::open_with`](super::Client::open_with)).
    Custom(Open),
}

impl Opener {
    /// One attempt, bounded by `timeout` (a TCP connect would otherwise take the operating
    /// system's minutes; a program's opener is bounded the same way).
    async fn open(&self, timeout: Duration) -> Result<BoxStream, Error> {
        match self {
            Opener::Tcp(addrs) => Ok(Box::new(connect_any(addrs, timeout).await?)),
            Opener::Custom(open) => match tokio::time::timeout(timeout, open()).await {
                Ok(opened) => Ok(opened?),
                Err(_) => Err(timed_out("opening the connection")),
            },
        }
    }
}

/// One connection: the reply reader and the command writer.
struct Conn {
    reader: FramedRead<ReadHalf<BoxStream>, RawLineCodec>,
    writer: Writer,
}

/// The command side of a connection.
struct Writer {
    half: WriteHalf<BoxStream>,
    encoder: LineCodec,
    /// The line being written, kept from one command to the next so that a command does not
    /// allocate a buffer.
    out: BytesMut,
}

impl Writer {
    /// Writes one command line, giving up on the connection if the controller stops reading
    /// until `limit`.
    async fn send(&mut self, line: &str, limit: Instant) -> Result<(), Error> {
        self.out.clear();
        self.encoder
            .encode(line, &mut self.out)
            .map_err(|e| Error::invalid("command line", e.to_string()))?;
        // Not cancel-safe, and need not be: when the limit passes the connection is given up.
        match tokio::time::timeout_at(limit, self.half.write_all(&self.out)).await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(io_error(e)),
            Err(_) => Err(Error::lost("the controller stopped reading commands")),
        }
    }
}

impl Conn {
    fn new(stream: BoxStream, max_line_len: usize) -> Conn {
        let (read, write) = tokio::io::split(stream);
        // A line cut off by the end of the connection is not a reply: `VALUE[0][0]=12` may be
        // the first half of `VALUE[0][0]=12345`.
        let codec = RawLineCodec(LineCodec::new(max_line_len).reject_unterminated());
        Conn {
            reader: FramedRead::new(read, codec),
            writer: Writer {
                half: write,
                encoder: LineCodec::new(max_line_len),
                out: BytesMut::new(),
            },
        }
    }

    /// Opens a new connection.
    async fn connect(opener: &Opener, config: &TaskConfig) -> Result<Conn, Error> {
        let stream = opener.open(config.connect_timeout).await?;
        Ok(Conn::new(stream, config.max_line_len))
    }

    /// One command and its reply, before any caller's command is served (restoring the
    /// session on a new connection).
    async fn exchange(&mut self, command: Command, timeout: Duration) -> Result<(), Error> {
        let line = command.encode()?;
        let deadline = crate::deadline::after(Instant::now(), timeout);
        self.writer.send(&line, deadline).await?;
        let reply = match tokio::time::timeout_at(deadline, next_line(&mut self.reader)).await {
            Err(_) => {
                return Err(Error::Timeout {
                    command: line,
                    timeout,
                })
            }
            Ok(None) => return Err(controller_closed()),
            Ok(Some(reply)) => reply.map_err(io_error)?,
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
}

/// Connects to the first of `addrs` that answers, each within `timeout`, with Nagle off:
/// lines are small and each waits for an answer.
pub(crate) async fn connect_any(
    addrs: &[SocketAddr],
    timeout: Duration,
) -> Result<TcpStream, Error> {
    let mut last = Error::from(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        "the address resolved to nothing",
    ));
    for addr in addrs {
        match tokio::time::timeout(timeout, TcpStream::connect(addr)).await {
            Ok(Ok(stream)) => {
                stream.set_nodelay(true)?;
                return Ok(stream);
            }
            Ok(Err(e)) => last = Error::from(e),
            Err(_) => {
                last = Error::from(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    "connecting to the controller timed out",
                ))
            }
        }
    }
    Err(last)
}

/// `what` ran out of its time (the connect timeout).
pub(crate) fn timed_out(what: &str) -> Error {
    Error::from(std::io::Error::new(
        std::io::ErrorKind::TimedOut,
        format!("{what} timed out"),
    ))
}

/// The controller ended the connection (EOF after it was open): the connection is lost, not
/// closed by this client.
fn controller_closed() -> Error {
    Error::lost("the controller closed the connection")
}

/// An I/O error on an open connection. The peer ending it — an EOF (the codec reports a line
/// cut off by it as `UnexpectedEof`), a reset, a broken pipe — is a lost connection, whichever
/// way the socket happened to see it; anything else is the socket's own error.
fn io_error(e: std::io::Error) -> Error {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
    match e.kind() {
        UnexpectedEof | ConnectionReset | ConnectionAborted | BrokenPipe => {
            Error::lost(format!("the controller closed the connection: {e}"))
        }
        _ => Error::from(e),
    }
}

async fn next_line(
    reader: &mut FramedRead<ReadHalf<BoxStream>, RawLineCodec>,
) -> Option<std::io::Result<RawLine>> {
    poll_fn(|cx| Pin::new(&mut *reader).poll_next(cx)).await
}

/// Runs until every handle is dropped, the program closes the connection, or it is lost for
/// good.
pub(crate) async fn run(stream: BoxStream, mut task: Task) {
    let mut conn = Conn::new(stream, task.config.max_line_len);
    let end = loop {
        let reconnects = task.reconnect.is_some();
        let end = serve(
            conn,
            &mut task.requests,
            &task.config,
            &task.shared,
            reconnects,
        )
        .await;
        // `Closed`: BYE, or nobody left to call; nothing to report or restore.
        if matches!(end, Error::Closed) {
            break end;
        }
        task.events.send(ConnectionEvent::Lost {
            reason: end.to_string(),
        });
        let Some(policy) = task.reconnect else {
            break end;
        };
        // Calls made meanwhile wait in the queue, within their own timeouts.
        let Task {
            requests,
            config,
            shared,
            events,
            opener,
            ..
        } = &task;
        let restored = reconnect::retry(
            &policy,
            events,
            || requests.is_closed(),
            |_| async {
                let mut conn = Conn::connect(opener, config).await?;
                events.send(ConnectionEvent::Connected);
                if let Some(on) = shared.verbose() {
                    conn.exchange(Command::SetVerbose(on), config.query_timeout)
                        .await?;
                }
                Ok::<_, Error>(conn)
            },
        )
        .await;
        match restored {
            Some(restored) => conn = restored,
            None => break end,
        }
    };
    task.shared.record(&end);
    task.requests.close();
    // `recv`, not `try_recv`: a call that took its place in the queue before it closed puts
    // its request in afterwards, and `recv` waits for it where `try_recv` reports the queue
    // empty; that request would then never be answered (its caller waited out its timeout).
    while let Some(request) = task.requests.recv().await {
        let _ = request.waiter.send(Err(end.clone()));
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
    conn: Conn,
    requests: &mut mpsc::Receiver<Request>,
    config: &TaskConfig,
    shared: &Shared,
    reconnects: bool,
) -> Error {
    let Conn {
        mut reader,
        mut writer,
    } = conn;
    let mut pipeline =
        Pipeline::new(config.pipeline_depth).with_probe_timeout(config.probe_timeout);
    let mut closing = false;
    // A request whose write failed: told why after the queue is closed (below).
    let mut unsent = None;

    // One give-up timer for the connection, moved to the oldest outstanding reply's limit
    // whenever that changes. When no reply is outstanding it is not polled (and may still fire
    // once, unseen).
    let give_up_timer = tokio::time::sleep_until(Instant::now());
    tokio::pin!(give_up_timer);
    let end: Error = loop {
        let give_up = pipeline.give_up_at();
        if let Some(at) = give_up {
            move_timer(give_up_timer.as_mut(), at);
        }
        tokio::select! {
            // Replies first: they free slots and callers.
            biased;
            line = next_line(&mut reader) => match line {
                Some(Ok(line)) => match pipeline.on_line(line.text()) {
                    Delivery::Resync(probe) if !closing => {
                        tracing::warn!(%probe, "griplink: a reply was out of step, resynchronising");
                        let limit = pipeline.give_up_at().unwrap_or_else(Instant::now);
                        if let Err(e) = writer.send(probe, limit).await {
                            break e;
                        }
                    }
                    Delivery::Lost => break Error::lost(
                        "a reply did not answer its command while others were on the wire; \
                         replies can no longer be paired",
                    ),
                    _ if closing && pipeline.is_empty() => break Error::Closed,
                    _ => {}
                },
                Some(Err(e)) => break io_error(e),
                None if closing => break Error::Closed,
                None => break controller_closed(),
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
                let give_up_at = crate::deadline::after(request.deadline, config.give_up_after);
                match writer.send(&request.line, give_up_at).await {
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
                pipeline.push(Slot {
                    line: request.line,
                    expect: request.expect,
                    waiter: request.waiter,
                    give_up_at,
                    probe: None,
                });
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
    pipeline.fail_all(&end);
    let _ = writer.half.shutdown().await;
    // After BYE the program is done with the connection, however it ended.
    if closing {
        Error::Closed
    } else {
        end
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncReadExt;
    use tokio::net::TcpListener;

    /// A writer connected to a peer that has not read anything yet.
    async fn writer_to_a_silent_peer() -> (Writer, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let client = TcpStream::connect(listener.local_addr().unwrap());
        let (client, accepted) = tokio::join!(client, listener.accept());
        let conn = Conn::new(Box::new(client.unwrap()), 1024);
        (conn.writer, accepted.unwrap().0)
    }

    #[tokio::test]
    async fn a_write_the_socket_cannot_take_gives_up_at_its_limit() {
        let (mut writer, _peer) = writer_to_a_silent_peer().await;
        let line = "X".repeat(1000);
        // Lines go out at once until the socket buffers are full; then one waits, and gives up
        // at its limit instead of hanging.
        let mut sent = 0usize;
        let err = loop {
            let limit = Instant::now() + Duration::from_millis(100);
            match writer.send(&line, limit).await {
                Ok(()) => sent += 1,
                Err(e) => break e,
            }
            assert!(sent < 1_000_000, "the socket never filled up");
        };
        assert!(sent > 0);
        assert!(
            matches!(&err, Error::ConnectionLost { reason: why } if why.contains("stopped reading")),
            "{err:?}"
        );
    }

    #[tokio::test]
    async fn lines_are_written_whole_and_in_order() {
        let (mut writer, mut peer) = writer_to_a_silent_peer().await;
        let far = Instant::now() + Duration::from_secs(5);
        writer.send("VALUE[0][0]?", far).await.unwrap();
        writer.send("ID?", far).await.unwrap();
        assert!(writer.send("ID?\nBYE()", far).await.is_err());
        drop(writer);
        let mut got = String::new();
        peer.read_to_string(&mut got).await.unwrap();
        assert_eq!(got, "VALUE[0][0]?\nID?\n");
    }
}
