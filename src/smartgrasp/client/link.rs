//! One TCP connection to the server, the thin shell around its requests in flight
//! ([`InFlight`], where the pairing rules live, without I/O): sends requests in arrival order,
//! reads responses and hands them to the queue, reads the clock and runs its give-up timer, and
//! does what the queue asks (answer a call, record a counter gap, give the connection up).

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

use super::in_flight::{CallTimeout, Event, InFlight};
use super::shutdown::Shutdown;
use super::{ClientConfig, Shared, Timeouts};
use crate::client_stream::ClientStream;
use crate::deadline::{after, move_timer, write_all_by};
use crate::reconnect::Open;
use crate::smartgrasp::codec::ClientCodec;
use crate::smartgrasp::error::{Error, Result};
use crate::smartgrasp::frame::{
    AnyRequestFrame as RequestFrame, AnyResponseFrame as ResponseFrame,
};
use crate::smartgrasp::message::{Request, Response};
use crate::smartgrasp::types::MessageType;

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
    /// it is restored after a reconnect with (at least) this timeout (`Session::record`). Kept
    /// in eight bytes (`a_call_is_moved_inline`).
    pub timeout: CallTimeout,
}

/// The caller of a call in flight: its reply channel, closed when the caller timed out or went
/// away.
type Reply = oneshot::Sender<Result<ResponseFrame>>;

/// What [`Link::serve`] tells its owner about each response it pairs: the request, its
/// response and its call's timeout (the session records the set-up requests the server accepted,
/// with the timeout they were answered within). A callback rather
/// than the session itself, so that the link does not depend on the session that drives it.
pub(crate) type OnPaired<'a> = dyn FnMut(&RequestFrame, &ResponseFrame, CallTimeout) + Send + 'a;

/// A connection and its pairing state.
pub(crate) struct Link {
    /// The stream, read through the codec and written through `get_mut`. Not split in halves:
    /// the link alone reads and writes it, one at a time, so the lock `tokio::io::split` takes
    /// around every read and write would buy nothing, at about 200 instructions per call
    /// (BENCHMARKS.md, "SmartGrasp: the stream unsplit, TCP unboxed").
    stream: FramedRead<ClientStream, ClientCodec>,
    /// The requests in flight and the pairing rules.
    in_flight: InFlight<Reply>,
    /// The configured timeouts, for the marker queries this link sends on its own (see
    /// `marker_before`); a caller's request is bounded by its call's own deadline (see `send`).
    timeouts: Timeouts,
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
            in_flight: InFlight::new(config.strict_response_counter, config.give_up_after),
            timeouts: config.timeouts(),
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

    /// Records the version the server answered GET_PROTOCOL_VERSION with: an empty message
    /// below it is a damaged frame from then on, not the server's "too old" answer (see
    /// [`ClientCodec::server_version`]).
    pub(crate) fn set_server_version(&mut self, server_version: u16) {
        self.stream.decoder_mut().server_version = Some(server_version);
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
            let shared = &self.shared;
            self.in_flight
                .on_exchange(&request, &frame, &mut |event| on_event(shared, None, event))
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
        // Where the next call lands (see `recv_into`).
        let mut next_call = None;
        let reason = loop {
            let give_up_at = self.in_flight.give_up_at(Instant::now);
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
                    if let Some(overdue) = self.in_flight.on_timeout(Instant::now()) {
                        break overdue;
                    }
                },
                () = recv_into(calls, &mut next_call), if self.in_flight.has_room() => match next_call.take() {
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
                        if let Some(marker) = self.in_flight.marker_before(&call.frame, self.version()) {
                            // Its reply goes to nobody: the receiver is dropped at once. A query,
                            // within the configured timeout of its type.
                            let (reply, _) = oneshot::channel();
                            let limit = self.timeouts.for_type(marker.header().message_type);
                            let deadline = after(Instant::now(), limit);
                            if let Err(e) = self.send(marker, reply, deadline, CallTimeout::new(limit)).await {
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
        self.in_flight.drain(&reason, |reply, error| {
            let _ = reply.send(Err(error));
        });
        Some(reason)
    }

    /// Writes a request and queues it in flight. On a write error the call gets it too.
    ///
    /// The write is bounded by the request's give-up limit
    /// ([`InFlight::give_up_for`]): a server that stops reading (its receive window full) must
    /// not wedge the task, which also reads the responses and serves `close()`. A write cut
    /// short leaves part of a frame on the wire, so on expiry the connection is given up as lost.
    async fn send(
        &mut self,
        request: RequestFrame,
        reply: Reply,
        deadline: Instant,
        timeout: CallTimeout,
    ) -> Result<()> {
        let give_up = self.in_flight.give_up_for(deadline, Instant::now);
        if let Err(error) =
            write_within(self.stream.get_mut(), give_up.limit(), &request.encode()).await
        {
            let _ = reply.send(Err(error.clone()));
            return Err(error);
        }
        self.in_flight.push(request, reply, give_up, timeout);
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

    /// Hands one response to the queue in flight and does what it asks; `Err` breaks the
    /// connection (the paired call, if any, got the error too).
    fn on_response(&mut self, on_paired: &mut OnPaired<'_>, frame: &ResponseFrame) -> Result<()> {
        let shared = &self.shared;
        self.in_flight.on_response(frame, &mut |event| {
            on_event(shared, Some(&mut *on_paired), event)
        })
    }
}

/// Receives the next call into `slot` (`None`: every handle is gone). Not `calls.recv()` as a
/// `select!` branch: `select!` keeps every branch's output in one enum, and a [`Call`] of 128
/// bytes made it larger than the 128 bytes x86-64 moves inline, so each round trip moved it twice
/// by `memcpy` (+58 instructions per query, BENCHMARKS.md, "Issue 30: the last of SmartGrasp's
/// cost").
fn recv_into<'a>(
    calls: &'a mut mpsc::Receiver<Call>,
    slot: &'a mut Option<Call>,
) -> impl std::future::Future<Output = ()> + 'a {
    poll_fn(move |cx| calls.poll_recv(cx).map(|call| *slot = call))
}

/// Does what the queue in flight asks of the link: records a counter gap, answers a call (a
/// paired response goes to `on_paired` first). Inlined into the callback the queue calls: a
/// round trip passes here once (BENCHMARKS.md, "Issue 30: SmartGrasp's queue in flight").
#[inline(always)]
fn on_event(shared: &Shared, on_paired: Option<&mut OnPaired<'_>>, event: Event<'_, Reply>) {
    match event {
        Event::Gap {
            expected,
            received,
            message_type,
        } => record_gap(shared, expected, received, message_type),
        Event::Paired {
            caller,
            request,
            response,
            timeout,
        } => {
            if let Some(on_paired) = on_paired {
                on_paired(request, response, timeout);
            }
            if caller.send(Ok(*response)).is_err() {
                tracing::debug!(request = %request.header().message_type, counter = response.header().response_counter, "late reply discarded");
            }
        }
        Event::Failed { caller, error } => {
            let _ = caller.send(Err(error));
        }
    }
}

/// Records a counter gap: a warning and the count the handles read
/// ([`Client::counter_gaps`](super::Client::counter_gaps)).
fn record_gap(shared: &Shared, expected: u8, received: u8, message_type: MessageType) {
    let gaps = shared.counter_gaps.fetch_add(1, Ordering::Relaxed) + 1;
    tracing::warn!(
        expected,
        received,
        %message_type,
        gaps,
        "smartgrasp: the response counter skipped (manual 3.2.2.3 does not say whether it counts per connection)"
    );
}

/// Writes `bytes` by `limit`; on expiry the connection is lost (see [`Link::send`]).
async fn write_within(
    write: &mut (impl tokio::io::AsyncWrite + Unpin),
    limit: Instant,
    bytes: &[u8],
) -> Result<()> {
    // When the write began to wait, read only if it had to: a write the socket takes at once
    // (every round trip) reads no clock (an `Instant::now()` is about 45 instructions per query,
    // BENCHMARKS.md, "Issue 30: the last of SmartGrasp's cost").
    let mut waited_from = None;
    let wait_limit = || {
        waited_from = Some(Instant::now());
        limit
    };
    let written = write_all_by(write, bytes, wait_limit).await;
    match written {
        Ok(written) => Ok(written?),
        Err(_) => Err(Error::ConnectionLost {
            reason: format!(
                "the server stopped reading requests (a write waited over {:?})",
                waited_from.map_or(Duration::ZERO, |from| limit.saturating_duration_since(from))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::client_stream::tests::tcp_pair as pair;
    use tokio::io::AsyncReadExt;

    /// A call is moved several times on its way to the wire (the handle's `try_send`, the
    /// channel's `pop` and `recv`, the task): within 128 bytes x86-64 moves it inline, above it
    /// each move is a `memcpy` call (+385 instructions per query at 136 bytes, BENCHMARKS.md).
    #[test]
    fn a_call_is_moved_inline() {
        assert!(
            std::mem::size_of::<Call>() <= 128,
            "{}",
            std::mem::size_of::<Call>()
        );
    }

    #[test]
    fn a_call_keeps_its_timeout_and_no_timeout_saturates() {
        let ms = Duration::from_millis(1500);
        assert_eq!(CallTimeout::new(ms).duration(), ms);
        assert_eq!(
            CallTimeout::new(Duration::MAX).duration(),
            Duration::from_nanos(u64::MAX)
        );
    }

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
