//! What a line-protocol client's connection task needs whatever the protocol: opening the
//! connection (TCP, or the program's own opener), writing a command line within a time limit,
//! reading reply lines, and telling a peer that ended the connection from a socket error.
//! GRIPLINK (`griplink/client/task.rs`) and the WSG text interface (`wsg/text/task.rs`) both
//! run on it; how replies pair with commands (by order, by name) stays theirs.

use std::future::poll_fn;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Mutex;
use std::time::Duration;

use bytes::BytesMut;
use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt, ReadHalf, WriteHalf};
use tokio::net::{TcpStream, ToSocketAddrs};
use tokio::time::Instant;
use tokio_util::codec::{Encoder, FramedRead};

use super::codec::{LineCodec, RawLine, RawLineCodec};
use crate::deadline::write_all_by;
use crate::reconnect::{BoxStream, Open};

/// What the line core reports through a protocol's own error enum (one enum per protocol: the
/// core never returns an error type of its own).
pub(crate) trait LineError: From<std::io::Error> + Clone {
    /// What the peer is called in the messages ("controller", "gripper").
    const PEER: &'static str;

    /// The connection is lost ([`ConnectionLost`](crate::griplink::Error::ConnectionLost)).
    fn connection_lost(why: String) -> Self;

    /// A command line the codec refuses (a LF or CR in it, or too long): nothing was sent.
    fn invalid_line(reason: String) -> Self;

    /// The connection was closed by this client.
    fn closed() -> Self;
}

/// Why a connection ended, as the handles read it: the first reason recorded, or
/// [`LineError::closed`] if none was.
#[derive(Debug)]
pub(crate) struct Failure<E>(Mutex<Option<E>>);

impl<E> Default for Failure<E> {
    fn default() -> Self {
        Failure(Mutex::new(None))
    }
}

impl<E: LineError> Failure<E> {
    /// The reason the connection is gone.
    pub(crate) fn get(&self) -> E {
        self.0
            .lock()
            .ok()
            .and_then(|f| f.clone())
            .unwrap_or_else(E::closed)
    }

    /// Records `error` unless a reason is recorded already (the first one is the cause).
    pub(crate) fn record(&self, error: &E) {
        if let Ok(mut f) = self.0.lock() {
            f.get_or_insert_with(|| error.clone());
        }
    }
}

/// How a (re)connect opens a new connection.
pub(crate) enum Opener {
    /// The addresses resolved once, when the client connected (tried in order).
    Tcp(Vec<SocketAddr>),
    /// The program's own opener (`Client::open_with`).
    Custom(Open),
}

impl Opener {
    /// One attempt, bounded by `timeout` (a TCP connect would otherwise take the operating
    /// system's minutes; a program's opener is bounded the same way).
    pub(crate) async fn open<E: LineError>(&self, timeout: Duration) -> Result<BoxStream, E> {
        match self {
            Opener::Tcp(addrs) => Ok(Box::new(connect_any::<E>(addrs, timeout).await?)),
            Opener::Custom(open) => match tokio::time::timeout(timeout, open()).await {
                Ok(opened) => Ok(opened?),
                Err(_) => Err(timed_out("opening the connection")),
            },
        }
    }

    /// Resolves `addr` within `timeout` and connects to the first address that answers: the
    /// stream, and the opener that reconnects to the same addresses.
    pub(crate) async fn resolve_and_connect<E: LineError>(
        addr: impl ToSocketAddrs,
        timeout: Duration,
    ) -> Result<(BoxStream, Opener), E> {
        let addrs: Vec<SocketAddr> = tokio::time::timeout(timeout, tokio::net::lookup_host(addr))
            .await
            .map_err(|_| timed_out::<E>(&format!("resolving the {}'s address", E::PEER)))??
            .collect();
        let stream = connect_any::<E>(&addrs, timeout).await?;
        Ok((Box::new(stream), Opener::Tcp(addrs)))
    }

    /// The stream of an already connected socket, and the opener that reconnects to its peer.
    pub(crate) fn from_tcp(stream: TcpStream) -> (BoxStream, Opener) {
        let addrs = stream.peer_addr().into_iter().collect();
        (Box::new(stream), Opener::Tcp(addrs))
    }

    /// The program's opener: its first stream, opened within `timeout`, and the opener.
    pub(crate) async fn first<E, F, Fut, S>(
        open: F,
        timeout: Duration,
    ) -> Result<(BoxStream, Opener), E>
    where
        E: LineError,
        F: Fn() -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = std::io::Result<S>> + Send + 'static,
        S: AsyncRead + AsyncWrite + Send + Unpin + 'static,
    {
        let (stream, open) = tokio::time::timeout(timeout, crate::reconnect::first_open(open))
            .await
            .map_err(|_| timed_out::<E>("opening the connection"))??;
        Ok((stream, Opener::Custom(open)))
    }
}

/// Connects to the first of `addrs` that answers, each within `timeout`, with Nagle off:
/// lines are small and each waits for an answer.
pub(crate) async fn connect_any<E: LineError>(
    addrs: &[SocketAddr],
    timeout: Duration,
) -> Result<TcpStream, E> {
    let mut last = E::from(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        "the address resolved to nothing",
    ));
    for addr in addrs {
        match tokio::time::timeout(timeout, TcpStream::connect(addr)).await {
            Ok(Ok(stream)) => {
                stream.set_nodelay(true)?;
                return Ok(stream);
            }
            Ok(Err(e)) => last = E::from(e),
            Err(_) => last = timed_out(&format!("connecting to the {}", E::PEER)),
        }
    }
    Err(last)
}

/// `what` ran out of its time (the connect timeout).
pub(crate) fn timed_out<E: LineError>(what: &str) -> E {
    E::from(std::io::Error::new(
        std::io::ErrorKind::TimedOut,
        format!("{what} timed out"),
    ))
}

/// The peer ended the connection (EOF after it was open): the connection is lost, not closed
/// by this client.
pub(crate) fn peer_closed<E: LineError>() -> E {
    E::connection_lost(format!("the {} closed the connection", E::PEER))
}

/// An I/O error on an open connection. The peer ending it — an EOF (the codec reports a line
/// cut off by it as `UnexpectedEof`), a reset, a broken pipe — is a lost connection, whichever
/// way the socket happened to see it; anything else is the socket's own error.
pub(crate) fn io_error<E: LineError>(e: std::io::Error) -> E {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
    match e.kind() {
        UnexpectedEof | ConnectionReset | ConnectionAborted | BrokenPipe => {
            E::connection_lost(format!("the {} closed the connection: {e}", E::PEER))
        }
        _ => E::from(e),
    }
}

/// The reply side of a connection.
pub(crate) struct LineReader<R>(FramedRead<R, RawLineCodec>);

impl<R: AsyncRead + Unpin> LineReader<R> {
    /// The next line; `None` at the end of the stream.
    pub(crate) async fn next_line(&mut self) -> Option<std::io::Result<RawLine>> {
        poll_fn(|cx| Pin::new(&mut self.0).poll_next(cx)).await
    }
}

/// The command side of a connection.
pub(crate) struct LineWriter<W> {
    half: W,
    encoder: LineCodec,
    /// The line being written, kept from one command to the next so that a command does not
    /// allocate a buffer.
    out: BytesMut,
}

impl<W: AsyncWrite + Unpin> LineWriter<W> {
    /// Writes one command line, giving up on the connection if the peer stops reading until
    /// `limit`. A line the codec refuses is [`LineError::invalid_line`], and nothing is sent.
    pub(crate) async fn send<E: LineError>(&mut self, line: &str, limit: Instant) -> Result<(), E> {
        self.out.clear();
        self.encoder
            .encode(line, &mut self.out)
            .map_err(|e| E::invalid_line(e.to_string()))?;
        // Not cancel-safe, and need not be: when the limit passes the connection is given up.
        match write_all_by(&mut self.half, &self.out, || limit).await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(io_error(e)),
            Err(_) => Err(E::connection_lost(format!(
                "the {} stopped reading commands",
                E::PEER
            ))),
        }
    }

    /// Shuts the write half down (the peer reads an EOF); errors are of no use any more.
    pub(crate) async fn shutdown(&mut self) {
        let _ = self.half.shutdown().await;
    }
}

/// One connection of a line protocol: the reply reader and the command writer.
pub(crate) struct LineConn<R = ReadHalf<BoxStream>, W = WriteHalf<BoxStream>> {
    /// Reply lines.
    pub(crate) reader: LineReader<R>,
    /// Command lines.
    pub(crate) writer: LineWriter<W>,
}

impl LineConn {
    /// The connection over `stream`, lines of at most `max_line_len` bytes each way.
    pub(crate) fn new(stream: BoxStream, max_line_len: usize) -> LineConn {
        let (read, write) = tokio::io::split(stream);
        LineConn::from_halves(read, write, max_line_len)
    }

    /// Opens a new connection with `opener` within `timeout`.
    pub(crate) async fn open<E: LineError>(
        opener: &Opener,
        timeout: Duration,
        max_line_len: usize,
    ) -> Result<LineConn, E> {
        Ok(LineConn::new(
            opener.open::<E>(timeout).await?,
            max_line_len,
        ))
    }
}

impl<R: AsyncRead + Unpin, W: AsyncWrite + Unpin> LineConn<R, W> {
    /// The connection over a read and a write half.
    pub(crate) fn from_halves(read: R, write: W, max_line_len: usize) -> Self {
        // A line cut off by the end of the connection is not a reply: `VALUE[0][0]=12` may be
        // the first half of `VALUE[0][0]=12345`.
        let codec = RawLineCodec(LineCodec::new(max_line_len).reject_unterminated());
        LineConn {
            reader: LineReader(FramedRead::new(read, codec)),
            writer: LineWriter {
                half: write,
                encoder: LineCodec::new(max_line_len),
                out: BytesMut::new(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncReadExt;
    use tokio::net::TcpListener;

    /// The errors of a protocol, for the tests.
    #[derive(Debug, Clone)]
    enum TestError {
        Lost(String),
        Invalid,
        Io,
        Closed,
    }

    impl From<std::io::Error> for TestError {
        fn from(_: std::io::Error) -> Self {
            TestError::Io
        }
    }

    impl LineError for TestError {
        const PEER: &'static str = "peer";
        fn connection_lost(why: String) -> Self {
            TestError::Lost(why)
        }
        fn invalid_line(_: String) -> Self {
            TestError::Invalid
        }
        fn closed() -> Self {
            TestError::Closed
        }
    }

    /// A writer connected to a peer that has not read anything yet.
    async fn writer_to_a_silent_peer() -> (LineWriter<WriteHalf<BoxStream>>, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let client = TcpStream::connect(listener.local_addr().unwrap());
        let (client, accepted) = tokio::join!(client, listener.accept());
        let conn = LineConn::new(Box::new(client.unwrap()), 1024);
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
            match writer.send::<TestError>(&line, limit).await {
                Ok(()) => sent += 1,
                Err(e) => break e,
            }
            assert!(sent < 1_000_000, "the socket never filled up");
        };
        assert!(sent > 0);
        assert!(
            matches!(&err, TestError::Lost(why) if why.contains("stopped reading")),
            "{err:?}"
        );
    }

    #[tokio::test]
    async fn lines_are_written_whole_and_in_order() {
        let (mut writer, mut peer) = writer_to_a_silent_peer().await;
        let far = Instant::now() + Duration::from_secs(5);
        writer.send::<TestError>("VALUE[0][0]?", far).await.unwrap();
        writer.send::<TestError>("ID?", far).await.unwrap();
        let refused = writer.send::<TestError>("ID?\nBYE()", far).await;
        assert!(matches!(refused, Err(TestError::Invalid)), "{refused:?}");
        drop(writer);
        let mut got = String::new();
        peer.read_to_string(&mut got).await.unwrap();
        assert_eq!(got, "VALUE[0][0]?\nID?\n");
    }

    #[test]
    fn a_peer_ending_the_connection_is_a_loss_other_errors_are_the_sockets() {
        use std::io::{Error, ErrorKind};
        for kind in [
            ErrorKind::UnexpectedEof,
            ErrorKind::ConnectionReset,
            ErrorKind::ConnectionAborted,
            ErrorKind::BrokenPipe,
        ] {
            let e: TestError = io_error(Error::new(kind, "x"));
            assert!(matches!(&e, TestError::Lost(why) if why.starts_with("the peer closed")));
        }
        let e: TestError = io_error(Error::new(ErrorKind::PermissionDenied, "x"));
        assert!(matches!(e, TestError::Io));
        assert!(matches!(
            Failure::<TestError>::default().get(),
            TestError::Closed
        ));
        let failure = Failure::default();
        failure.record(&TestError::Invalid);
        failure.record(&TestError::Io);
        assert!(matches!(failure.get(), TestError::Invalid));
    }
}
