//! The byte transports a client (or the simulator) talks over: TCP, UDP, serial, or any
//! `AsyncRead + AsyncWrite` the user already has.

use std::io;
use std::net::SocketAddr;

use bytes::BytesMut;
use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::UdpSocket;
use tokio_util::codec::{Decoder, Framed};

use super::codec::WsgCodec;
use super::frame::{self, Decoded, Frame};

/// Default TCP port of a WSG's command interface.
pub const DEFAULT_TCP_PORT: u16 = 1000;
/// Default serial baud rate (8N1).
pub const DEFAULT_BAUD_RATE: u32 = 115_200;

/// Anything a client can be attached to.
pub trait AsyncReadWrite: AsyncRead + AsyncWrite + Send + Unpin + 'static {}
impl<T: AsyncRead + AsyncWrite + Send + Unpin + 'static> AsyncReadWrite for T {}

/// Which kind of transport a client uses (decides whether closing announces it, manual 3.1.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportKind {
    /// TCP: closing sends the disconnect announcement (0x07) first.
    Tcp,
    /// UDP, one frame per datagram.
    Udp,
    /// RS-232.
    Serial,
    /// A stream given to [`ClientBuilder::attach`](super::ClientBuilder::attach).
    Attached,
}

/// A framed link: one frame in, one frame out.
pub(crate) enum Link {
    Stream(Framed<Box<dyn AsyncReadWrite>, WsgCodec>),
    Udp {
        socket: UdpSocket,
        peer: SocketAddr,
        max_payload_len: usize,
        /// One datagram: a frame of `max_payload_len` (longer datagrams are cut to this and fail
        /// their checksum). Allocated once per client.
        buf: Vec<u8>,
    },
    /// In-memory datagrams (one frame per message, like UDP) without the operating system:
    /// see [`ClientBuilder::attach_datagrams`](super::ClientBuilder::attach_datagrams).
    #[cfg(feature = "sim")]
    Datagrams {
        tx: tokio::sync::mpsc::UnboundedSender<bytes::Bytes>,
        rx: tokio::sync::mpsc::UnboundedReceiver<bytes::Bytes>,
        max_payload_len: usize,
    },
}

impl Link {
    /// A UDP link to `peer`, accepting replies of up to `max_payload_len` bytes.
    pub(crate) fn udp(socket: UdpSocket, peer: SocketAddr, max_payload_len: usize) -> Link {
        Link::Udp {
            socket,
            peer,
            max_payload_len,
            buf: vec![0u8; frame::HEADER_LEN + max_payload_len + frame::CHECKSUM_LEN],
        }
    }
}

impl Link {
    /// The next frame; `None` at end of stream. Cancel-safe (used in `select!`).
    pub(crate) async fn recv(&mut self) -> Option<io::Result<Frame>> {
        match self {
            Link::Stream(framed) => {
                std::future::poll_fn(|cx| std::pin::Pin::new(&mut *framed).poll_next(cx)).await
            }
            Link::Udp {
                socket,
                peer,
                max_payload_len,
                buf,
            } => {
                loop {
                    let (n, from) = match socket.recv_from(&mut buf[..]).await {
                        Ok(x) => x,
                        // An ICMP error (port or host unreachable: the gripper rebooting, say)
                        // for a datagram sent earlier, reported by this receive: UDP has no
                        // connection to lose, so it is logged and the link goes on. Each such
                        // error answers a datagram this side sent, so this cannot spin.
                        Err(e) if is_icmp_error(&e) => {
                            tracing::warn!(error = %e, "WSG UDP: the gripper did not receive an earlier datagram");
                            continue;
                        }
                        Err(e) => return Some(Err(e)),
                    };
                    // Everything after the await is synchronous: a cancelled recv loses nothing.
                    if from.ip() != peer.ip() {
                        tracing::warn!(%from, "UDP datagram from a stranger: dropped");
                        continue;
                    }
                    if let Some(f) = decode_datagram(&buf[..n], *max_payload_len) {
                        return Some(Ok(f));
                    }
                }
            }
            #[cfg(feature = "sim")]
            Link::Datagrams {
                rx,
                max_payload_len,
                ..
            } => loop {
                // `recv` is cancel safe and the rest is synchronous, as for UDP above.
                let d = rx.recv().await?;
                if let Some(f) = decode_datagram(&d, *max_payload_len) {
                    return Some(Ok(f));
                }
            },
        }
    }

    /// Like [`Link::recv`], but when `watching` is false also returns (with `None`) as soon as
    /// the decoder holds the start of a frame, so the caller can start that frame's timer
    /// (issue 20.2 #2: a frame must complete within a bound from its first byte). Cancel-safe.
    pub(crate) async fn recv_or_partial(
        &mut self,
        watching: bool,
    ) -> Option<Option<io::Result<Frame>>> {
        match self {
            Link::Stream(framed) if !watching => {
                std::future::poll_fn(|cx| match std::pin::Pin::new(&mut *framed).poll_next(cx) {
                    std::task::Poll::Pending if !framed.read_buffer().is_empty() => {
                        std::task::Poll::Ready(None)
                    }
                    other => other.map(Some),
                })
                .await
            }
            _ => Some(self.recv().await),
        }
    }

    /// Sends one frame (and flushes it).
    pub(crate) async fn send(&mut self, f: &Frame) -> io::Result<()> {
        match self {
            Link::Stream(framed) => {
                // Only the read half of `Framed` is used: encode here and write through.
                use tokio::io::AsyncWriteExt;
                use tokio_util::codec::Encoder;
                // Encoded into `Framed`'s own write buffer (unused otherwise), so a steady state
                // does not allocate per frame; it keeps the capacity of the largest frame sent
                // (bounded by the u16 length field). Taken out for the write and put back empty:
                // a write cancelled by its timeout drops it, and the next frame allocates anew.
                let mut buf = std::mem::take(framed.write_buffer_mut());
                buf.clear();
                framed.codec_mut().encode(f, &mut buf)?;
                let io = framed.get_mut();
                let written = async {
                    io.write_all(&buf).await?;
                    io.flush().await
                }
                .await;
                buf.clear();
                *framed.write_buffer_mut() = buf;
                written
            }
            Link::Udp { socket, peer, .. } => {
                let mut b = BytesMut::with_capacity(f.encoded_len());
                frame::encode(f, &mut b)
                    .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
                socket.send_to(&b, *peer).await.map(drop)
            }
            #[cfg(feature = "sim")]
            Link::Datagrams { tx, .. } => {
                let mut b = BytesMut::with_capacity(f.encoded_len());
                frame::encode(f, &mut b)
                    .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
                tx.send(b.freeze())
                    .map_err(|_| io::Error::new(io::ErrorKind::BrokenPipe, "datagram peer gone"))
            }
        }
    }

    /// How many times the decoder dropped something that may have been a frame
    /// ([`WsgCodec::damage`]); always 0 on UDP, where a damaged datagram is lost as a whole.
    pub(crate) fn damage(&self) -> u64 {
        match self {
            Link::Stream(framed) => framed.codec().damage(),
            _ => 0,
        }
    }

    /// Bytes received but not decoded yet: the start of a frame still arriving (or a corrupted
    /// header waiting for bytes that will never come). Always 0 on UDP.
    pub(crate) fn partial_len(&self) -> usize {
        match self {
            Link::Stream(framed) => framed.read_buffer().len(),
            _ => 0,
        }
    }

    /// Gives up on the partial frame held by the decoder (called after a silence on the line):
    /// skips its header as noise and returns the frames found in the bytes after it. Without
    /// this, a corrupted length field (below the maximum) would hold every later reply until
    /// that many bytes had arrived.
    pub(crate) fn resync(&mut self) -> Vec<Frame> {
        let Link::Stream(framed) = self else {
            return Vec::new();
        };
        let mut buf = std::mem::take(framed.read_buffer_mut());
        let mut frames = Vec::new();
        while let Ok(Some(f)) = framed.codec_mut().decode_eof(&mut buf) {
            frames.push(f);
        }
        tracing::warn!(
            frames = frames.len(),
            "WSG partial frame stalled: dropped as noise"
        );
        frames
    }

    /// Flushes and shuts down the write side.
    pub(crate) async fn shutdown(&mut self) {
        if let Link::Stream(framed) = self {
            use tokio::io::AsyncWriteExt;
            let _ = framed.get_mut().shutdown().await;
        }
    }
}

/// Whether a UDP receive error reports an ICMP error for an earlier datagram (Linux:
/// ECONNREFUSED and EHOSTUNREACH/ENETUNREACH on a connected socket; Windows: WSAECONNRESET
/// even unconnected) rather than a failure of the socket itself.
fn is_icmp_error(e: &io::Error) -> bool {
    use io::ErrorKind::*;
    matches!(
        e.kind(),
        ConnectionRefused | ConnectionReset | HostUnreachable | NetworkUnreachable
    )
}

/// Decodes the single frame a datagram carries (each UDP datagram is one frame); anything else
/// in it is noise, traced and dropped.
pub(crate) fn decode_datagram(datagram: &[u8], max_payload_len: usize) -> Option<Frame> {
    let mut b = BytesMut::from(datagram);
    let mut found = None;
    while let Some(d) = frame::decode_eof(&mut b, max_payload_len) {
        match d {
            Decoded::Frame(f) if found.is_none() => found = Some(f),
            Decoded::Frame(f) => {
                tracing::warn!(id = f.id, "extra frame in a UDP datagram: dropped")
            }
            Decoded::Corrupt { id, .. } => {
                tracing::warn!(id, "UDP datagram with a bad checksum: dropped")
            }
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ICMP "port unreachable" for an earlier datagram surfaces as an error of the next
    /// receive (ECONNREFUSED on Linux for a connected socket, WSAECONNRESET on Windows even
    /// unconnected). UDP has no connection to lose: the link goes on receiving.
    #[tokio::test]
    async fn an_icmp_error_does_not_end_a_udp_link() {
        // A port nobody listens on (taken from the OS, then freed).
        let gone = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let peer = gone.local_addr().unwrap();
        drop(gone);
        let socket = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let me = socket.local_addr().unwrap();
        // Connected, so that Linux reports the ICMP error to it.
        socket.connect(peer).await.unwrap();
        let mut link = Link::udp(socket, peer, 64);
        link.send(&Frame::new(0x06, &b"lost"[..])).await.unwrap();
        // The peer comes back on the same port and answers.
        let back = UdpSocket::bind(peer).await.unwrap();
        let mut b = BytesMut::new();
        frame::encode(&Frame::new(0x06, &b"back"[..]), &mut b).unwrap();
        back.send_to(&b, me).await.unwrap();
        let got = tokio::time::timeout(std::time::Duration::from_secs(10), link.recv())
            .await
            .expect("the link answers")
            .expect("the link goes on");
        assert_eq!(got.unwrap(), Frame::new(0x06, &b"back"[..]));
    }
}
