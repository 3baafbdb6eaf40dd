//! Opening a transport again, for reconnecting (TCP and serial; UDP has no connection to lose
//! and an attached stream cannot be reopened), and the link over a byte stream the builder and
//! a reconnect both make.

use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use tokio::net::TcpStream;
use tokio_util::codec::Framed;

use crate::reconnect::ReconnectPolicy;
use crate::wsg::transport::{AsyncReadWrite, Link};
use crate::wsg::WsgCodec;

/// What the task needs to reconnect.
#[derive(Debug)]
pub(crate) struct Reconnect {
    pub(crate) policy: ReconnectPolicy,
    pub(crate) connector: Connector,
}

/// How to open the transport again.
#[derive(Debug)]
pub(crate) struct Connector {
    pub(crate) kind: ConnectorKind,
    pub(crate) max_payload_len: usize,
    /// Bounds a TCP connect (a host that is gone would otherwise take the operating system's
    /// minutes).
    pub(crate) connect_timeout: Duration,
}

/// Opens a byte stream (see [`ClientBuilder::connect_with`](super::ClientBuilder::connect_with)).
pub(crate) type Open = Box<
    dyn Fn() -> std::pin::Pin<
            Box<dyn std::future::Future<Output = io::Result<Box<dyn AsyncReadWrite>>> + Send>,
        > + Send
        + Sync,
>;

pub(crate) enum ConnectorKind {
    /// The addresses the first connect resolved (tried in order).
    Tcp(Vec<SocketAddr>),
    #[cfg(feature = "serial")]
    Serial {
        path: String,
        baud_rate: u32,
        exclusive: bool,
    },
    /// The caller's own way to open a stream.
    Custom(Open),
}

impl std::fmt::Debug for ConnectorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConnectorKind::Tcp(addrs) => f.debug_tuple("Tcp").field(addrs).finish(),
            #[cfg(feature = "serial")]
            ConnectorKind::Serial {
                path,
                baud_rate,
                exclusive,
            } => f
                .debug_struct("Serial")
                .field("path", path)
                .field("baud_rate", baud_rate)
                .field("exclusive", exclusive)
                .finish(),
            ConnectorKind::Custom(_) => f.write_str("Custom"),
        }
    }
}

impl Connector {
    /// One attempt; a TCP connect is bounded by `connect_timeout`.
    pub(crate) async fn connect(&self) -> io::Result<Link> {
        let io: Box<dyn AsyncReadWrite> = match &self.kind {
            ConnectorKind::Tcp(addrs) => Box::new(tcp(addrs, self.connect_timeout).await?),
            #[cfg(feature = "serial")]
            ConnectorKind::Serial {
                path,
                baud_rate,
                exclusive,
            } => Box::new(serial(path, *baud_rate, *exclusive)?),
            // Bounded like a TCP connect.
            ConnectorKind::Custom(open) => tokio::time::timeout(self.connect_timeout, open())
                .await
                .map_err(|_| timed_out())??,
        };
        Ok(stream_link(io, self.max_payload_len))
    }
}

pub(crate) async fn tcp(addrs: &[SocketAddr], timeout: Duration) -> io::Result<TcpStream> {
    let stream = tokio::time::timeout(timeout, TcpStream::connect(addrs))
        .await
        .map_err(|_| timed_out())??;
    stream.set_nodelay(true)?;
    Ok(stream)
}

/// The error of a TCP connect (or its address resolution) that ran out of time.
pub(crate) fn timed_out() -> io::Error {
    io::Error::new(io::ErrorKind::TimedOut, "TCP connect timed out")
}

/// Opens a serial port 8N1 without flow control (the WSG's settings).
#[cfg(feature = "serial")]
pub(crate) fn serial(
    path: &str,
    baud_rate: u32,
    exclusive: bool,
) -> io::Result<tokio_serial::SerialStream> {
    use tokio_serial::SerialPortBuilderExt;
    tokio_serial::new(path, baud_rate)
        .data_bits(tokio_serial::DataBits::Eight)
        .parity(tokio_serial::Parity::None)
        .stop_bits(tokio_serial::StopBits::One)
        .flow_control(tokio_serial::FlowControl::None)
        .exclusive(exclusive)
        .open_native_async()
        .map_err(io::Error::other)
}

/// The link over a byte stream (TCP, serial, the program's own): replies of up to
/// `max_payload_len` bytes of payload decoded.
pub(super) fn stream_link(io: Box<dyn AsyncReadWrite>, max_payload_len: usize) -> Link {
    Link::Stream(Framed::new(io, WsgCodec::for_replies(max_payload_len)))
}
