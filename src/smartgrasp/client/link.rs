//! One TCP connection to the server: sends requests in arrival order, reads responses, pairs them
//! (see [`pairing`](super::pairing)) and answers each waiting call. A call whose caller timed out
//! or went away keeps its place; its reply is consumed and discarded.

use std::collections::VecDeque;
use std::future::poll_fn;
use std::net::SocketAddr;
use std::pin::{pin, Pin};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use futures_core::Stream;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;

use super::pairing::{ambiguous, check_response, Counted, Pairing};
use super::shutdown::Shutdown;
use super::{ClientConfig, Shared, Timeouts};
use crate::client_stream::ClientStream;
use crate::deadline::{after, move_timer, write_all_by};
use crate::give_up::GiveUp;
use crate::reconnect::Open;
use crate::smartgrasp::codec::ClientCodec;
use crate::smartgrasp::error::{Error, Malformed, Result};
use crate::smartgrasp::frame::{
    AnyRequestFrame as RequestFrame, AnyResponseFrame as ResponseFrame,
};
use crate::smartgrasp::message::{Request, Response};
use crate::smartgrasp::types::MessageType;

/// Requests sent and not yet answered, at most (plus one marker, see `marker_before`). Bounds the
/// waiting queue when a server stops answering; further calls wait in the channel and run into
/// their timeouts.
pub(crate) const MAX_IN_FLIGHT: usize = 16;

/// One call from a handle to the task.
pub(crate) struct Call {
    /// The request, to encode it again if the link speaks another version by the time it is
    /// sent (see `in_link_version`).
    pub request: Request,
    /// The request encoded in the version the client spoke when the call was made.
    pub frame: RequestFrame,
    pub reply: oneshot::Sender<Result<ResponseFrame>>,
    /// When the caller stops waiting: its own timeout ([`Client::with_timeout`] or the
    /// configured one) from the call's start. The give-up limit is counted from here.
    ///
    /// [`Client::with_timeout`]: super::Client::with_timeout
    pub deadline: Instant,
    /// The caller's timeout that `deadline` was counted with: a set-up request answered within
    /// it is restored after a reconnect with (at least) this timeout (`Session::record`).
    pub timeout: Duration,
}

/// A request on the wire, waiting for its response.
struct Waiting {
    request: RequestFrame,
    reply: oneshot::Sender<Result<ResponseFrame>>,
    /// Its call's deadline plus [`ClientConfig::give_up_after`], counted again from when it
    /// reaches the front (`crate::give_up`): a server that has not answered by then is not
    /// answering, and the connection is given up.
    give_up: GiveUp,
    /// Its call's timeout (see [`Call::timeout`]), for `on_paired`.
    timeout: Duration,
}

/// What [`Link::serve`] tells its owner about each response it pairs: the request, its
/// response and its call's timeout (the session records the set-up requests the server accepted,
/// with the timeout they were answered within). A callback rather
/// than the session itself, so that the link does not depend on the session that drives it.
pub(crate) type OnPaired<'a> = dyn FnMut(&RequestFrame, &ResponseFrame, Duration) + Send + 'a;

/// A connection and its pairing state.
pub(crate) struct Link {
    /// The stream, read through the codec and written through `get_mut`. Not split in halves:
    /// the link alone reads and writes it, one at a time, so the lock `tokio::io::split` takes
    /// around every read and write would buy nothing, at about 200 instructions per call
    /// (BENCHMARKS.md, "SmartGrasp: the stream unsplit, TCP unboxed").
    stream: FramedRead<ClientStream, ClientCodec>,
    /// At most [`MAX_IN_FLIGHT`].
    waiting: VecDeque<Waiting>,
    pairing: Pairing,
    /// The last response paired, to recognise an exact repeat of it in strict counter mode
    /// (see `on_response`).
    last_response: Option<ResponseFrame>,
    /// The configured timeouts, for the marker queries this link sends on its own (see
    /// `marker_before`); a caller's request is bounded by its call's own deadline (see `send`).
    timeouts: Timeouts,
    /// See [`ClientConfig::give_up_after`].
    give_up_after: Duration,
    /// Counters the handles read (counter gaps).
    shared: Arc<Shared>,
}

/// How a link (the first one, and each reconnect) opens its byte stream.
pub(crate) enum Opener {
    /// The addresses resolved once, when the client connected.
    Tcp(Vec<SocketAddr>),
    /// The program's own opener ([`Client::open_with`](super::Client::open_with)).
    Custom(Open),
}

impl Opener {
    /// One attempt, within `timeout`.
    async fn open(&self, timeout: Duration) -> Result<ClientStream> {
        within_connect_timeout(timeout, async {
            match self {
                Opener::Tcp(addrs) => {
                    let stream = TcpStream::connect(&addrs[..]).await?;
                    // Requests are single 80-byte writes waiting for an answer: do not let
                    // Nagle hold them.
                    stream.set_nodelay(true)?;
                    Ok(ClientStream::Tcp(stream))
                }
                Opener::Custom(open) => Ok(ClientStream::Boxed(open().await?)),
            }
        })
        .await
    }
}

impl Link {
    /// Opens a connection through `opener` within the configured connect timeout.
    pub(crate) async fn connect(
        opener: &Opener,
        config: &ClientConfig,
        shared: &Arc<Shared>,
    ) -> Result<Link> {
        let stream = opener.open(config.connect_timeout).await?;
        Ok(Link::over(stream, config, shared))
    }

    /// A link over a stream already open.
    pub(crate) fn over(stream: ClientStream, config: &ClientConfig, shared: &Arc<Shared>) -> Link {
        Link {
            // V3 until the opening sequence chose a version (see `set_version`).
            stream: FramedRead::new(stream, ClientCodec::default()),
            waiting: VecDeque::with_capacity(MAX_IN_FLIGHT),
            pairing: if config.strict_response_counter {
                Pairing::strict()
            } else {
                Pairing::default()
            },
            last_response: None,
            timeouts: config.timeouts(),
            give_up_after: config.give_up_after,
            shared: Arc::clone(shared),
        }
    }

    /// The protocol version requests on this link are sent in.
    pub(crate) fn version(&self) -> u16 {
        self.stream.decoder().version
    }

    /// Sends every later request in protocol `version` (the opening sequence negotiated it).
    pub(crate) fn set_version(&mut self, version: u16) {
        self.stream.decoder_mut().version = version;
    }

    /// One request with nothing else in flight (the opening sequence), in the link's version,
    /// answered within the configured timeout of its type. After an error the link must be
    /// dropped.
    pub(crate) async fn exchange(
        &mut self,
        request: &Request,
        timeouts: Timeouts,
    ) -> Result<Response> {
        let request = request.to_any_frame(self.version())?;
        let answer = async {
            self.stream.get_mut().write_all(&request.encode()).await?;
            let frame = match self.next_response().await {
                None => return Err(server_closed()),
                Some(frame) => frame?,
            };
            let counted = self.pairing.counter(frame.header().response_counter, 1)?;
            self.record_gap(&counted, &frame);
            check_response(&request, &frame)?;
            self.last_response = Some(frame);
            Ok(normalised(&request, &frame))
        };
        let frame = timeouts.run(request.header().message_type, answer).await?;
        Ok(Response::from_any_frame(&frame)?)
    }

    async fn next_response(&mut self) -> Option<Result<ResponseFrame>> {
        poll_fn(|cx| Pin::new(&mut self.stream).poll_next(cx)).await
    }

    /// Serves calls until the connection breaks (`Some(reason)`; every call that was waiting on
    /// it has been answered with an error), the program closes the client (`shutdown`, then the
    /// reason is [`Error::Closed`]) or every handle is gone (`None`). Hands every paired request
    /// and response to `on_paired`.
    ///
    /// A response that stays away [`ClientConfig::give_up_after`] beyond its call's timeout
    /// breaks the connection ([`Error::ConnectionLost`]): a server that stays connected but stops
    /// answering would otherwise hold every slot for ever, and every later call would time out.
    pub(crate) async fn serve(
        &mut self,
        calls: &mut mpsc::Receiver<Call>,
        on_paired: &mut OnPaired<'_>,
        shutdown: &CancellationToken,
    ) -> Option<Error> {
        // The shutdown wait and the give-up timer live across iterations rather than being made
        // anew by each `select!`: registering and deregistering a waiter and a timer on every
        // iteration was a large part of a round trip's CPU cost (issue 14). The timer is moved
        // only when the oldest request changes (it is never polled before: its branch needs a
        // waiting request).
        let mut shutdown = Shutdown::new(shutdown);
        let mut give_up = pin!(tokio::time::sleep_until(Instant::now()));
        let reason = loop {
            let give_up_at = self
                .waiting
                .front_mut()
                .map(|w| w.give_up.at_front(Instant::now));
            if let Some(at) = give_up_at {
                move_timer(give_up.as_mut(), at);
            }
            tokio::select! {
                // Closing first: `close()` must not wait behind a busy connection. Then
                // responses: each frees a slot.
                biased;
                () = &mut shutdown => break Error::Closed,
                item = self.next_response() => match item {
                    None => break server_closed(),
                    Some(Err(e)) => break e,
                    Some(Ok(frame)) => {
                        if let Err(e) = self.on_response(on_paired, &frame) {
                            break e;
                        }
                    }
                },
                () = give_up.as_mut(), if give_up_at.is_some() => {
                    let request = self.waiting.front().map(|w| w.request.header().message_type);
                    tracing::error!(?request, give_up_after = ?self.give_up_after, "smartgrasp: response overdue, giving up on the connection");
                    break Error::ConnectionLost {
                        reason: format!(
                            "no response to {} within its timeout and {:?} more: the server stopped answering",
                            request.unwrap_or(MessageType::Unknown(0)),
                            self.give_up_after
                        )
                        .into(),
                    };
                },
                call = calls.recv(), if self.waiting.len() < MAX_IN_FLIGHT => match call {
                    // Every handle is gone, so no call can be waiting: nothing left to do.
                    None => return None,
                    Some(mut call) => {
                        if call.reply.is_closed() {
                            // Its caller gave up before it was sent: sending it would only
                            // create a reply to discard.
                            continue;
                        }
                        if let Err(e) = self.in_link_version(&mut call) {
                            // Nothing was sent: the call alone fails.
                            let _ = call.reply.send(Err(e));
                            continue;
                        }
                        if let Some(marker) = self.marker_before(&call.frame) {
                            // Its reply goes to nobody: the receiver is dropped at once. A query,
                            // within the configured timeout of its type.
                            let (reply, _) = oneshot::channel();
                            let limit = self.timeouts.for_type(marker.header().message_type);
                            let deadline = after(Instant::now(), limit);
                            if let Err(e) = self.send(marker, reply, deadline, limit).await {
                                let _ = call.reply.send(Err(e.clone()));
                                break e;
                            }
                        }
                        let sent = self.send(call.frame, call.reply, call.deadline, call.timeout);
                        if let Err(e) = sent.await {
                            break e;
                        }
                    }
                },
            }
        };
        for w in self.waiting.drain(..) {
            let _ = w.reply.send(Err(waiting_error(&reason)));
        }
        Some(reason)
    }

    /// Writes a request and queues its reply slot. On a write error the call gets it too.
    ///
    /// The response is awaited until the call's `deadline` plus [`ClientConfig::give_up_after`]
    /// (the call's own timeout, not the configured one of its type: a handle made with
    /// [`Client::with_timeout`](super::Client::with_timeout) for a slow detection must not lose
    /// a healthy connection at the configured timeout; issue 21). The write is bounded by the
    /// same limit: a server that stops reading (its receive window full) must not wedge the
    /// task, which also reads the responses and serves `close()`. A write cut short leaves part
    /// of a frame on the wire, so on expiry the connection is given up as lost.
    async fn send(
        &mut self,
        request: RequestFrame,
        reply: oneshot::Sender<Result<ResponseFrame>>,
        deadline: Instant,
        timeout: Duration,
    ) -> Result<()> {
        // Behind other requests its clock starts again when it reaches the front, with the
        // time its caller had left when it was sent (`crate::give_up`).
        let give_up = GiveUp::new(
            deadline,
            self.give_up_after,
            self.waiting.is_empty(),
            || deadline.saturating_duration_since(Instant::now()),
        );
        if let Err(error) =
            write_within(self.stream.get_mut(), give_up.limit(), &request.encode()).await
        {
            let _ = reply.send(Err(error.clone()));
            return Err(error);
        }
        self.waiting.push_back(Waiting {
            request,
            reply,
            give_up,
            timeout,
        });
        Ok(())
    }

    /// Makes `call`'s frame speak the link's version. A call is encoded when it is made, in the
    /// version the client spoke then; one that waited in the queue across a reconnect goes out
    /// on a link whose opening sequence may have negotiated another version (a firmware update or
    /// rollback), so it is encoded again from its request (issue 21). `Err`: the request does not
    /// exist in that version (SET_TOOL on V3), and nothing is sent.
    fn in_link_version(&self, call: &mut Call) -> Result<()> {
        let version = self.version();
        if call.frame.version() != version {
            tracing::debug!(
                from = call.frame.version(),
                to = version,
                request = %call.request.message_type(),
                "smartgrasp: a queued request is sent in the version the reconnect negotiated"
            );
            call.frame = call.request.to_any_frame(version)?;
        }
        Ok(())
    }

    /// Responses carry no request id. Right behind a request whose caller gave up, the response
    /// to a request of the same type could be either's: the abandoned one's, late, or this one's
    /// if the abandoned request never reached the server. A request of another type in between
    /// (a side-effect-free query) tells them apart: whichever way the abandoned request went, its
    /// slot is settled by the time the marker's response arrives (see `on_response`), and the
    /// next response is this request's. Costs one query, only after a call was given up.
    fn marker_before(&self, next: &RequestFrame) -> Option<RequestFrame> {
        let back = self.waiting.back()?;
        let ambiguous = ambiguous(
            back.request.header().message_type,
            next.header().message_type,
        );
        if !ambiguous || !back.reply.is_closed() {
            return None;
        }
        let marker = match next.header().message_type {
            MessageType::GetProtocolVersion => Request::GetState,
            _ => Request::GetProtocolVersion,
        };
        marker.to_any_frame(self.version()).ok()
    }

    /// Records a counter gap: a warning and the count the handles read
    /// ([`Client::counter_gaps`](super::Client::counter_gaps)).
    fn record_gap(&self, counted: &Counted, frame: &ResponseFrame) {
        if counted.gap == 0 {
            return;
        }
        let gaps = self.shared.counter_gaps.fetch_add(1, Ordering::Relaxed) + 1;
        tracing::warn!(
            expected = counted.expected,
            received = frame.header().response_counter,
            message_type = %frame.header().message_type,
            gaps,
            "smartgrasp: the response counter skipped (manual 3.2.2.3 does not say whether it counts per connection)"
        );
    }

    /// Pairs one response; `Err` breaks the connection (the paired call, if any, gets the error
    /// too).
    fn on_response(&mut self, on_paired: &mut OnPaired<'_>, frame: &ResponseFrame) -> Result<()> {
        if self.pairing.is_strict() && self.last_response.as_ref() == Some(frame) {
            // The same bytes again, counter included, from a server known to count its responses
            // per connection (strict mode): a copy, not a new answer. Skipped. Only in strict
            // mode: a server whose counter never moves (SCHUNK's KRL never reads it) or counts
            // across its clients (the same value after 256 responses) sends identical responses
            // that are real answers (issue 21), and TCP itself never duplicates a segment.
            tracing::warn!(
                counter = frame.header().response_counter,
                "repeated response skipped"
            );
            return Ok(());
        }
        let received = frame.header().response_counter;
        let counted = self.pairing.counter(received, self.waiting.len())?;
        self.record_gap(&counted, frame);
        for i in 0..counted.lost {
            if let Some(w) = self.waiting.pop_front() {
                let expected = counted.expected.wrapping_add(i as u8);
                tracing::warn!(expected, received, request = %w.request.header().message_type, "response lost");
                let _ = w
                    .reply
                    .send(Err(Error::ResponseLost { expected, received }));
            }
        }
        let Some(mut w) = self.waiting.pop_front() else {
            // `counter` guarantees one is left; treat it as unsolicited all the same.
            return Err(Malformed::Unsolicited { counter: received }.into());
        };
        if let Err(e) = check_response(&w.request, frame) {
            // The server answers in order, so a response that does not fit the oldest request
            // but fits the next one means the oldest was never answered: it was lost before it
            // reached the server (no counter gap), or the server answered nothing (the counter
            // skipped). If its caller has already given up, nobody is owed anything: drop its
            // slot and go on. A caller still waiting gets [`Error::ResponseLost`] when the
            // counter skipped too (two signs agree); otherwise the error, and the connection is
            // closed.
            let fits_next = counted.lost == 0
                && self
                    .waiting
                    .front()
                    .is_some_and(|next| check_response(&next.request, frame).is_ok());
            if !fits_next || !(w.reply.is_closed() || counted.gap != 0) {
                let e = Error::from(e);
                let _ = w.reply.send(Err(e.clone()));
                return Err(e);
            }
            tracing::warn!(request = %w.request.header().message_type, "a request was never answered; its slot is dropped");
            let _ = w.reply.send(Err(Error::ResponseLost {
                expected: counted.expected,
                received,
            }));
            match self.waiting.pop_front() {
                Some(next) => w = next,
                None => return Err(Malformed::Unsolicited { counter: received }.into()),
            }
        }
        self.last_response = Some(*frame);
        let frame = normalised(&w.request, frame);
        on_paired(&w.request, &frame, w.timeout);
        if w.reply.send(Ok(frame)).is_err() {
            tracing::debug!(request = %w.request.header().message_type, counter = received, "late reply discarded");
        }
        Ok(())
    }
}

/// A paired response with the message type of its request: a GET_OBJECT_COUNT answered as type
/// 17 (see [`answers`](super::pairing::answers)) is read as the count it is.
fn normalised(request: &RequestFrame, frame: &ResponseFrame) -> ResponseFrame {
    let mut frame = *frame;
    if frame.header().message_type != request.header().message_type {
        tracing::warn!(
            request = %request.header().message_type,
            response = %frame.header().message_type,
            "smartgrasp: response with the manual's erratum message type accepted"
        );
        frame.header_mut().message_type = request.header().message_type;
    }
    frame
}

/// Writes `bytes` by `limit`; on expiry the connection is lost (see [`Link::send`]).
async fn write_within(
    write: &mut (impl tokio::io::AsyncWrite + Unpin),
    limit: Instant,
    bytes: &[u8],
) -> Result<()> {
    let started = Instant::now();
    match write_all_by(write, bytes, || limit).await {
        Ok(written) => Ok(written?),
        Err(_) => Err(Error::ConnectionLost {
            reason: format!(
                "the server stopped reading requests (a write took over {:?})",
                limit.saturating_duration_since(started)
            )
            .into(),
        }),
    }
}

/// Runs a step of connecting (resolving the address, the TCP connect) within `timeout`.
pub(crate) async fn within_connect_timeout<T>(
    timeout: Duration,
    step: impl std::future::Future<Output = Result<T>>,
) -> Result<T> {
    tokio::time::timeout(timeout, step).await.map_err(|_| {
        Error::from(std::io::Error::new(
            std::io::ErrorKind::TimedOut,
            "connecting to the Smart Grasping server timed out",
        ))
    })?
}

fn server_closed() -> Error {
    Error::ConnectionLost {
        reason: "the server closed the connection".into(),
    }
}

/// What a call that was sent and still waits gets when the connection breaks. A header error
/// was already given to the call whose response carried it; the others only lost the connection.
fn waiting_error(reason: &Error) -> Error {
    match reason {
        Error::MalformedReply(
            Malformed::MessageType { .. }
            | Malformed::CommunicationType(_)
            | Malformed::Version { .. }
            | Malformed::Echo { .. }
            | Malformed::Unsolicited { .. },
        ) => closed_error(Some(reason)),
        // Stream-level reasons (I/O, bad length, too old, lost responses) concern every call.
        other => other.clone(),
    }
}

/// What a call gets on a connection that is already gone (or never got to send its request).
pub(crate) fn closed_error(reason: Option<&Error>) -> Error {
    match reason {
        Some(Error::ConnectionLost { reason }) => Error::ConnectionLost {
            reason: Arc::clone(reason),
        },
        // Still the answer to every later call, and typed so a program can tell the user.
        Some(e @ (Error::ServerTooOld { .. } | Error::Closed)) => e.clone(),
        Some(reason) => Error::ConnectionLost {
            reason: reason.to_string().into(),
        },
        None => Error::ConnectionLost {
            reason: "the connection task has ended".into(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::client_stream::tests::tcp_pair as pair;
    use tokio::io::AsyncReadExt;

    #[tokio::test]
    async fn a_write_that_fits_goes_out_whole() {
        let (mut server, mut write) = pair().await;
        let frame = [7u8; crate::smartgrasp::frame::FRAME_LEN];
        write_within(&mut write, Instant::now() + Duration::from_secs(5), &frame)
            .await
            .unwrap();
        let mut got = [0u8; crate::smartgrasp::frame::FRAME_LEN];
        server.read_exact(&mut got).await.unwrap();
        assert_eq!(got, frame);
    }

    #[tokio::test]
    async fn a_write_the_server_does_not_read_is_given_up_after_its_limit() {
        let (_server, mut write) = pair().await;
        // Far more than the socket buffers hold: the first attempt writes part of it, and the
        // rest waits for a server that never reads.
        let bytes = vec![0u8; 64 << 20];
        let write = write_within(
            &mut write,
            Instant::now() + Duration::from_millis(50),
            &bytes,
        );
        // A failure here must not hang the test run.
        let err = tokio::time::timeout(Duration::from_secs(10), write)
            .await
            .expect("the write's own limit ends it")
            .unwrap_err();
        assert!(
            matches!(&err, Error::ConnectionLost { reason } if reason.contains("stopped reading")),
            "{err}"
        );
    }
}
