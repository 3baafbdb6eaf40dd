//! A client's byte stream: a TCP socket the client opened, or a stream the program opened itself
//! (boxed). One type for both, so that a client's connection code is written once, while TCP,
//! the common case, is called directly instead of through the box. Measured on the SmartGrasp
//! round trip in BENCHMARKS.md ("SmartGrasp: the stream unsplit, TCP unboxed").

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;

use crate::reconnect::BoxStream;

/// A TCP socket, or a program's own stream.
pub(crate) enum ClientStream {
    /// A socket the client connected itself.
    Tcp(TcpStream),
    /// A stream from the program's opener (a tunnel, an in-memory pipe to a simulator).
    Boxed(BoxStream),
}

impl AsyncRead for ClientStream {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        match self.get_mut() {
            ClientStream::Tcp(s) => Pin::new(s).poll_read(cx, buf),
            ClientStream::Boxed(s) => Pin::new(s).poll_read(cx, buf),
        }
    }
}

impl AsyncWrite for ClientStream {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bytes: &[u8],
    ) -> Poll<io::Result<usize>> {
        match self.get_mut() {
            // `try_write` first. A request is one short write that the socket nearly always
            // takes at once, and then no waker is needed; `poll_write` would first register
            // one with the reactor, which costs about 100 instructions per request. Only a
            // socket that takes nothing now (`WouldBlock`, its readiness cleared) is polled,
            // which registers the waker as `poll_write`'s `Pending` promises.
            ClientStream::Tcp(s) => match s.try_write(bytes) {
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    Pin::new(s).poll_write(cx, bytes)
                }
                done => Poll::Ready(done),
            },
            ClientStream::Boxed(s) => Pin::new(s).poll_write(cx, bytes),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            ClientStream::Tcp(s) => Pin::new(s).poll_flush(cx),
            ClientStream::Boxed(s) => Pin::new(s).poll_flush(cx),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            ClientStream::Tcp(s) => Pin::new(s).poll_shutdown(cx),
            ClientStream::Boxed(s) => Pin::new(s).poll_shutdown(cx),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::time::Duration;

    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    use tokio::net::TcpListener;

    use super::*;

    /// A loopback connection (port 0): the server's end, and the client's as a client holds it.
    pub(crate) async fn tcp_pair() -> (TcpStream, ClientStream) {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let client = TcpStream::connect(listener.local_addr().unwrap());
        let (client, accepted) = tokio::join!(client, listener.accept());
        (accepted.unwrap().0, ClientStream::Tcp(client.unwrap()))
    }

    /// Far more than the socket buffers hold, so that `try_write` runs into `WouldBlock` and
    /// the write must wait; numbered bytes, so that a lost or repeated chunk shows.
    fn big() -> Vec<u8> {
        (0..16u32 << 20).map(|i| (i % 251) as u8).collect()
    }

    #[tokio::test]
    async fn a_tcp_write_that_has_to_wait_is_woken_when_the_peer_reads() {
        let (mut server, mut client) = tcp_pair().await;
        let bytes = big();
        let len = bytes.len();
        // The reader is another task: only the write's own waker can wake this one.
        let reader = tokio::spawn(async move {
            let mut got = vec![0u8; len];
            server.read_exact(&mut got).await.map(|_| got)
        });
        // A write that registered no waker would hang here; the limit keeps the run from it.
        tokio::time::timeout(Duration::from_secs(20), client.write_all(&bytes))
            .await
            .expect("the waiting write is woken")
            .unwrap();
        let got = reader.await.unwrap().unwrap();
        assert!(got == bytes, "the bytes arrive whole and in order");
    }

    #[tokio::test]
    async fn both_kinds_carry_bytes_both_ways() {
        let (server, client) = tcp_pair().await;
        let (far, near) = tokio::io::duplex(64);
        let streams: [(Box<dyn crate::reconnect::ByteStream>, ClientStream); 2] = [
            (Box::new(server), client),
            (Box::new(far), ClientStream::Boxed(Box::new(near))),
        ];
        for (mut far, mut near) in streams {
            near.write_all(b"request").await.unwrap();
            near.flush().await.unwrap();
            let mut got = [0u8; 7];
            far.read_exact(&mut got).await.unwrap();
            assert_eq!(&got, b"request");
            far.write_all(b"reply").await.unwrap();
            let mut got = [0u8; 5];
            near.read_exact(&mut got).await.unwrap();
            assert_eq!(&got, b"reply");
            near.shutdown().await.unwrap();
            assert_eq!(far.read(&mut got).await.unwrap(), 0, "end of stream");
        }
    }
}
