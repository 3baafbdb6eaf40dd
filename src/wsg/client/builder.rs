//! [`ClientBuilder`]: the client's settings, and opening a [`Client`] over TCP, UDP, serial or
//! any byte stream (the background task and the handle it returns).

// The builder fills the client's private parts (`Shared`, the task's settings): it is the
// client module's own code, kept in its own room.
use std::net::SocketAddr;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use tokio::net::{ToSocketAddrs, UdpSocket};
use tokio::sync::mpsc;
use tokio::time::{timeout_at, Instant};

use super::connector::{self, Connector, ConnectorKind, Reconnect};
use super::pairing::BARRIER_ECHO_LEN;
use super::task::Task;
use super::{
    Client, Shared, DEFAULT_CONNECT_TIMEOUT, DEFAULT_LATE_REPLY_GRACE, DEFAULT_MOTION_TIMEOUT,
    DEFAULT_PARTIAL_FRAME_TIMEOUT, DEFAULT_QUERY_TIMEOUT, DEFAULT_SUBSCRIPTION_BUFFER,
};
use crate::connection::Connection;
use crate::deadline::after;
use crate::queue::channel_capacity;
use crate::reconnect::ReconnectPolicy;
use crate::wsg::transport::{AsyncReadWrite, Link, TransportKind};
use crate::wsg::Result;

/// Configures and opens a [`Client`].
///
/// Every duration it (or a call, such as [`Client::with_timeouts`]) takes may be
/// `Duration::MAX`, the usual way to say "no timeout": deadlines saturate to "never" instead of
/// overflowing the clock.
#[derive(Clone, Debug)]
pub struct ClientBuilder {
    query_timeout: Duration,
    motion_timeout: Duration,
    late_reply_grace: Duration,
    subscription_buffer: usize,
    request_queue: usize,
    max_payload_len: usize,
    announce_disconnect: Option<bool>,
    serial_exclusive: bool,
    partial_frame_timeout: Duration,
    connect_timeout: Duration,
    reconnect: Option<ReconnectPolicy>,
}

impl Default for ClientBuilder {
    fn default() -> Self {
        Self {
            query_timeout: DEFAULT_QUERY_TIMEOUT,
            motion_timeout: DEFAULT_MOTION_TIMEOUT,
            late_reply_grace: DEFAULT_LATE_REPLY_GRACE,
            subscription_buffer: DEFAULT_SUBSCRIPTION_BUFFER,
            request_queue: 64,
            max_payload_len: crate::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN,
            announce_disconnect: None,
            serial_exclusive: true,
            partial_frame_timeout: DEFAULT_PARTIAL_FRAME_TIMEOUT,
            connect_timeout: DEFAULT_CONNECT_TIMEOUT,
            reconnect: None,
        }
    }
}

impl ClientBuilder {
    /// Timeout of queries and settings (default 1 s). `Duration::MAX`: no timeout; a request
    /// whose reply is lost still gives its command id up (and a call without timeout fails)
    /// [`DEFAULT_QUERY_TIMEOUT`] + grace after it was sent (see [`Client::with_timeouts`]).
    pub fn query_timeout(mut self, t: Duration) -> Self {
        self.query_timeout = t;
        self
    }

    /// Timeout of motion commands (homing, pre-position, grasp, release) up to their final reply
    /// (default 30 s). Past it, the client asks the device whether the move still runs before it
    /// takes the command id back (see [Lost final replies](Client#lost-final-replies)).
    /// `Duration::MAX`: no timeout; a motion whose final reply is lost is then asked about
    /// from the query timeout after it was sent (it ends with [`Error::ReplyLost`](crate::wsg::Error::ReplyLost) only once
    /// the device says twice, a grace period apart, that it does not move).
    pub fn motion_timeout(mut self, t: Duration) -> Self {
        self.motion_timeout = t;
        self
    }

    /// How long after its caller's deadline an unanswered request keeps its command id, so that
    /// its late reply is consumed rather than handed to the next caller (default 2 s); also the
    /// spacing of the two "not moving" answers that release a motion command whose final reply
    /// is lost. See [Lost final replies](Client#lost-final-replies) for the residual risk.
    pub fn late_reply_grace(mut self, t: Duration) -> Self {
        self.late_reply_grace = t;
        self
    }

    /// Updates buffered per subscriber (default 64). Clamped to at least 1 and at most
    /// [`tokio::sync::Semaphore::MAX_PERMITS`] (a tokio channel holds no more; `usize::MAX`
    /// means "as many as that", never a panic).
    pub fn subscription_buffer(mut self, n: usize) -> Self {
        self.subscription_buffer = channel_capacity(n);
        self
    }

    /// Requests buffered between the handles and the task (default 64); callers wait (within
    /// their timeout) when it is full. Clamped to at least 1 and at most
    /// [`tokio::sync::Semaphore::MAX_PERMITS`] (a tokio channel holds no more; `usize::MAX`
    /// means "as many as that", never a panic).
    pub fn request_queue(mut self, n: usize) -> Self {
        self.request_queue = channel_capacity(n);
        self
    }

    /// Largest reply payload accepted (default
    /// [`DEFAULT_MAX_PAYLOAD_LEN`](crate::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN)); longer replies
    /// are dropped as noise. Clamped to at least 26 bytes, the echo of the client's own
    /// loop-back barriers (below it every barrier would go unanswered and a fenced id stay
    /// held), and at most 65535, the largest length the frame's 16-bit length field can carry
    /// (manual 1.2.1; `usize::MAX` means "any", never a panic or an oversized buffer).
    pub fn max_payload_len(mut self, n: usize) -> Self {
        self.max_payload_len = n.clamp(BARRIER_ECHO_LEN, usize::from(u16::MAX));
        self
    }

    /// How long a frame may take from its first byte before the decoder drops it as noise and
    /// looks for a frame after it (default 500 ms). A corrupted length field (below
    /// [`max_payload_len`](Self::max_payload_len) and the longest reply of its command id)
    /// would otherwise hold back every later reply until that many bytes had arrived, however
    /// much traffic (a stream of updates) keeps coming. While a frame is held, no request's
    /// id is released and no probe is sent, so a reply held behind it never reaches a newer
    /// request. Keep it above the longest time a sound link takes for one frame (a TCP
    /// retransmission takes 200 ms or more; at 9600 baud a 4 KiB frame takes over 4 s).
    ///
    /// On TCP and serial it (or [`DEFAULT_PARTIAL_FRAME_TIMEOUT`], if longer) is also the rest
    /// the line gets after a loop-back barrier that went unanswered (see the
    /// [pairing rules](crate::wsg::client#pairing-rules)): the device's decoder is taken to drop
    /// a frame with a corrupted length after no longer silence than that.
    pub fn partial_frame_timeout(mut self, t: Duration) -> Self {
        self.partial_frame_timeout = t;
        self
    }

    /// Timeout of a TCP connect, address resolution included, for the first connect and each
    /// reconnect attempt (default 5 s). Without it a connect to a host that is gone would take
    /// the operating system's retries, minutes.
    pub fn connect_timeout(mut self, t: Duration) -> Self {
        self.connect_timeout = t;
        self
    }

    /// Reconnect after a lost connection, with this backoff (default: off, the client then fails
    /// every later call with [`Error::ConnectionLost`](crate::wsg::Error::ConnectionLost)). TCP and serial only.
    ///
    /// With a policy:
    /// - calls in flight when the link drops fail with [`Error::ConnectionLost`](crate::wsg::Error::ConnectionLost) and are never
    ///   sent again on their own, motion commands included; calls made while the client
    ///   reconnects wait for the new connection within their own timeouts;
    /// - each attempt reopens the same address or port (a TCP connect within
    ///   [`connect_timeout`](Self::connect_timeout));
    /// - the auto-update streams that still have a [`Subscription`](crate::wsg::Subscription) are switched on again, and
    ///   the streams go on; dropped ones are not restored;
    /// - each loss, attempt and recovery is reported through [`Client::connection_events`] and
    ///   `tracing`; after the policy's last attempt the client gives up and later calls fail.
    ///
    /// An unannounced TCP loss puts the gripper into FAST STOP (manual 1.4.2): after a
    /// reconnect, motion is refused (E_ACCESS_DENIED) until the program calls
    /// [`Client::acknowledge_fast_stop`]. The client never acknowledges it on its own; the
    /// `Lost` event says so.
    pub fn reconnect(mut self, policy: ReconnectPolicy) -> Self {
        self.reconnect = Some(policy);
        self
    }

    /// Whether [`Client::close`] sends the disconnect announcement (0x07) first. Default: on for
    /// TCP (manual 1.4.2: an unannounced close puts the gripper into FAST STOP), off otherwise
    /// (other transports answer E_NOT_AVAILABLE).
    pub fn announce_disconnect(mut self, on: bool) -> Self {
        self.announce_disconnect = Some(on);
        self
    }

    /// Whether `open_serial` (feature `serial`) takes the port exclusively (default true; the
    /// simulator's pseudo-terminal, `sim::SimServer::serial_pty`, needs false).
    pub fn serial_exclusive(mut self, exclusive: bool) -> Self {
        self.serial_exclusive = exclusive;
        self
    }

    /// Connects over TCP (the WSG listens on port [`DEFAULT_PORT`](crate::wsg::DEFAULT_PORT),
    /// 1000, by default), within [`connect_timeout`](Self::connect_timeout).
    ///
    /// Cancel-safe: a dropped call leaves nothing behind.
    pub async fn connect_tcp(self, addr: impl ToSocketAddrs) -> Result<Client> {
        let timeout = self.connect_timeout;
        let deadline = after(Instant::now(), timeout);
        // Resolved once: a reconnect goes to the same addresses.
        let addrs: Vec<SocketAddr> = timeout_at(deadline, tokio::net::lookup_host(addr))
            .await
            .map_err(|_| connector::timed_out())??
            .collect();
        let stream =
            connector::tcp(&addrs, deadline.saturating_duration_since(Instant::now())).await?;
        let reconnect = ConnectorKind::Tcp(addrs);
        Ok(self.start(Box::new(stream), TransportKind::Tcp, Some(reconnect)))
    }

    /// Talks over UDP to `remote`, from an ephemeral local port (each datagram is one frame).
    ///
    /// Cancel-safe: a dropped call leaves nothing behind.
    pub async fn connect_udp(self, remote: SocketAddr) -> Result<Client> {
        let local: SocketAddr = if remote.is_ipv4() {
            (std::net::Ipv4Addr::UNSPECIFIED, 0).into()
        } else {
            (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
        };
        self.connect_udp_from(local, remote).await
    }

    /// Talks over UDP to `remote` from the local address `local` (use the port the gripper is
    /// configured to send its replies to). Datagrams are accepted from `remote`'s IP address,
    /// whatever their source port; others are dropped with a trace.
    ///
    /// Cancel-safe: a dropped call leaves nothing behind.
    pub async fn connect_udp_from(self, local: SocketAddr, remote: SocketAddr) -> Result<Client> {
        let socket = UdpSocket::bind(local).await?;
        let link = Link::udp(socket, remote, self.max_payload_len);
        Ok(self.start_link(link, TransportKind::Udp, None))
    }

    /// Opens a serial port (8N1, no flow control) at `baud_rate` (the WSG default is 115200).
    #[cfg(feature = "serial")]
    pub fn open_serial(self, path: &str, baud_rate: u32) -> Result<Client> {
        let port = connector::serial(path, baud_rate, self.serial_exclusive)?;
        let reconnect = ConnectorKind::Serial {
            path: path.to_owned(),
            baud_rate,
            exclusive: self.serial_exclusive,
        };
        Ok(self.start(Box::new(port), TransportKind::Serial, Some(reconnect)))
    }

    /// Uses a byte stream the caller already has (a serial port, a TLS tunnel, a test pipe).
    pub fn attach(self, io: impl AsyncReadWrite) -> Client {
        self.start(Box::new(io), TransportKind::Attached, None)
    }

    /// Uses the byte streams `connect` opens: one now, and with
    /// [`reconnect`](Self::reconnect) a new one after each loss (e.g. in-memory pipes to a
    /// [`SimServer::serve_stream`](crate::wsg::sim::SimServer::serve_stream), so that a test
    /// exercises reconnecting without sockets). The client treats it like an attached stream.
    pub async fn connect_with<F, Fut, S>(self, connect: F) -> Result<Client>
    where
        F: Fn() -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = std::io::Result<S>> + Send + 'static,
        S: AsyncReadWrite,
    {
        let io = connect().await?;
        let open: connector::Open = Box::new(move || {
            let fut = connect();
            Box::pin(async move { fut.await.map(|s| Box::new(s) as Box<dyn AsyncReadWrite>) })
        });
        let reconnect = ConnectorKind::Custom(open);
        Ok(self.start(Box::new(io), TransportKind::Attached, Some(reconnect)))
    }

    /// Talks in datagrams over in-memory channels (feature `sim`): each frame goes to
    /// `outgoing` as one message, each message from `incoming` is one datagram (one frame, as
    /// on UDP, manual 1.2). The client behaves as over UDP. With
    /// [`SimServer::serve_datagrams`](crate::wsg::sim::SimServer::serve_datagrams) on the
    /// other end (possibly through a test's fault layer), a test runs UDP without sockets.
    #[cfg(feature = "sim")]
    pub fn attach_datagrams(
        self,
        outgoing: mpsc::UnboundedSender<bytes::Bytes>,
        incoming: mpsc::UnboundedReceiver<bytes::Bytes>,
    ) -> Client {
        let link = Link::Datagrams {
            tx: outgoing,
            rx: incoming,
            max_payload_len: self.max_payload_len,
        };
        self.start_link(link, TransportKind::Udp, None)
    }

    /// Spawns the task on the current tokio runtime.
    fn start(
        self,
        io: Box<dyn AsyncReadWrite>,
        kind: TransportKind,
        reconnect: Option<ConnectorKind>,
    ) -> Client {
        let link = connector::stream_link(io, self.max_payload_len);
        self.start_link(link, kind, reconnect)
    }

    fn start_link(
        self,
        link: Link,
        kind: TransportKind,
        reconnect: Option<ConnectorKind>,
    ) -> Client {
        let (tx, rx) = mpsc::channel(self.request_queue);
        let (unsub_tx, unsub_rx) = mpsc::unbounded_channel();
        let announce = self
            .announce_disconnect
            .unwrap_or(kind == TransportKind::Tcp);
        let lost = Arc::new(OnceLock::new());
        let mut task = Task::new(
            link,
            rx,
            unsub_rx,
            self.late_reply_grace,
            (self.query_timeout, self.motion_timeout),
            announce,
            lost.clone(),
        );
        task.partial_frame_timeout = self.partial_frame_timeout;
        // A device's decoder is taken to need no longer silence to drop a frame with a
        // corrupted length than the default partial frame timeout, or ours if longer (the
        // manual does not say; the simulator needs the default).
        task.pairing.set_resync(
            self.partial_frame_timeout
                .max(DEFAULT_PARTIAL_FRAME_TIMEOUT),
        );
        task.tcp = kind == TransportKind::Tcp;
        task.reconnect = self
            .reconnect
            .zip(reconnect)
            .map(|(policy, kind)| Reconnect {
                policy,
                connector: Connector {
                    kind,
                    max_payload_len: self.max_payload_len,
                    connect_timeout: self.connect_timeout,
                },
            });
        let events = task.events.subscriber();
        let close = task.close.clone();
        let connection = Connection::spawn(task.run());
        Client {
            shared: Arc::new(Shared {
                connection,
                tx,
                unsubscribe: unsub_tx,
                subscription_buffer: self.subscription_buffer,
                next_key: AtomicU64::new(0),
                kind,
                lost,
                events,
                close,
            }),
            query_timeout: self.query_timeout,
            motion_timeout: self.motion_timeout,
        }
    }
}
