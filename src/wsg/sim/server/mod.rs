//! Serving the simulated gripper over TCP, UDP, a serial pseudo-terminal or any byte stream.
//!
//! One actor task (`actor.rs`) owns the [`Device`] (no locks around the state machine); every
//! connection is a task (`stream.rs`, `udp.rs`) that forwards decoded frames to it and writes
//! the bytes it gets back. The actor applies the injected faults on the way out. No reply is
//! dropped for want of room: a connection whose client does not read stops being read.

mod actor;
mod memory;
mod record;
mod stream;
mod text;
mod udp;

use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use bytes::Bytes;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::{TcpListener, ToSocketAddrs, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::time::Instant;

use self::actor::{Actor, Control, Event, SimClock};
use self::record::Recorder;
pub use self::record::{SimEvent, SimRecord, SimRecording};
use self::stream::serve_stream;
use self::text::serve_text;
use self::udp::{serve_udp, UdpSettings};
use super::device::{Device, SessionId, SessionKind};
use super::model::SimConfig;
use crate::wsg::{GripState, Status, SystemState};

#[derive(Debug, Default)]
pub(super) struct Faults {
    drop: Vec<u8>,
    corrupt: Vec<u8>,
    delay: Vec<(u8, Duration)>,
    forced: Vec<(u8, Status)>,
}

pub(super) fn take<T>(v: &mut Vec<T>, pred: impl Fn(&T) -> bool) -> Option<T> {
    let i = v.iter().position(pred)?;
    Some(v.remove(i))
}

/// What the simulator looked like after its last step.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSnapshot {
    /// The grip state.
    pub grip_state: GripState,
    /// The system state flags.
    pub system_state: SystemState,
    /// The opening width, mm.
    pub width_mm: f32,
    /// Connections open now.
    pub sessions: usize,
    /// Auto-update streams running now (all sessions).
    pub streams: usize,
}

#[derive(Debug)]
pub(super) struct Shared {
    faults: Faults,
    /// Command ids received, oldest first (the last 4096).
    received: VecDeque<u8>,
    snapshot: SimSnapshot,
    /// What was processed and sent, once [`SimServer::start_recording`] was called.
    recorder: Option<Recorder>,
}

pub(super) fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // A panic elsewhere must not take the simulator down with a poisoned lock.
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

/// A running simulator. Shuts down when [`SimServer::shutdown`] is called or it is dropped.
#[derive(Debug)]
pub struct SimServer {
    local_addr: Option<SocketAddr>,
    serial_path: Option<String>,
    shared: Arc<Mutex<Shared>>,
    control: mpsc::UnboundedSender<Control>,
    shutdown: watch::Sender<bool>,
    /// Held so the pseudo-terminal stays open while the server runs.
    _keep: Option<Box<dyn std::any::Any + Send + Sync>>,
    /// What a new connection needs ([`SimServer::serve_stream`], [`SimServer::serve_datagrams`]).
    parts: Parts,
}

#[derive(Clone, Debug)]
pub(super) struct Parts {
    events: mpsc::Sender<Event>,
    /// Serve GCL (`Some(ACK gap)`) instead of the binary protocol on byte streams.
    text: Option<Duration>,
    shutdown: watch::Receiver<bool>,
    next_session: Arc<AtomicU64>,
}

impl SimServer {
    fn start(config: SimConfig) -> (SimServer, Parts) {
        let (events_tx, events) = mpsc::channel(1024);
        let (control_tx, control) = mpsc::unbounded_channel();
        let (shutdown_tx, shutdown) = watch::channel(false);
        let text = config.text_interface.then_some(config.text_ack_gap);
        let device = Device::new(config);
        let shared = Arc::new(Mutex::new(Shared {
            faults: Faults::default(),
            received: VecDeque::new(),
            snapshot: SimSnapshot {
                grip_state: device.grip_state(),
                system_state: device.system_state(),
                width_mm: 0.0,
                sessions: 0,
                streams: 0,
            },
            recorder: None,
        }));
        let now = Instant::now();
        let actor = Actor {
            clock: SimClock {
                scale: device.config().time_scale,
                base_wall: now,
                base_sim: 0.0,
            },
            device,
            started: now,
            sessions: BTreeMap::new(),
            text: BTreeMap::new(),
            shared: shared.clone(),
            events,
            control,
            shutdown: shutdown.clone(),
        };
        tokio::spawn(actor.run());
        let parts = Parts {
            events: events_tx,
            text,
            shutdown,
            next_session: Arc::new(AtomicU64::new(1)),
        };
        let server = SimServer {
            local_addr: None,
            serial_path: None,
            shared,
            control: control_tx,
            shutdown: shutdown_tx,
            _keep: None,
            parts: parts.clone(),
        };
        (server, parts)
    }

    /// A simulator with no transport of its own: give it connections with
    /// [`SimServer::serve_stream`] and [`SimServer::serve_datagrams`]. With in-memory
    /// transports (`tokio::io::duplex`, channels) and tokio's paused clock, a test runs without
    /// the operating system's sockets or clock, so it replays exactly.
    pub fn in_memory(config: SimConfig) -> SimServer {
        Self::start(config).0
    }

    /// Serves one more byte stream (e.g. one end of `tokio::io::duplex`) as a new session of
    /// this simulator, beside the ones it has (in the text interface if the configuration
    /// says so); returns the session's id.
    pub fn serve_stream(
        &self,
        io: impl AsyncRead + AsyncWrite + Send + 'static,
        kind: SessionKind,
    ) -> SessionId {
        let p = &self.parts;
        let session = p.next_session.fetch_add(1, Ordering::Relaxed);
        let (events, shutdown) = (p.events.clone(), p.shutdown.clone());
        match p.text {
            Some(gap) => tokio::spawn(serve_text(io, session, events, shutdown, gap)),
            None => tokio::spawn(serve_stream(io, session, kind, events, shutdown)),
        };
        session
    }

    /// Serves an in-memory datagram peer as a new UDP session: each message from `incoming`
    /// is one datagram (one frame, manual 1.2), each reply goes to `outgoing` as one message.
    /// The session ends when `incoming` closes. Pairs with
    /// [`ClientBuilder::attach_datagrams`](crate::wsg::ClientBuilder::attach_datagrams).
    pub fn serve_datagrams(
        &self,
        incoming: mpsc::UnboundedReceiver<Bytes>,
        outgoing: mpsc::UnboundedSender<Bytes>,
    ) -> SessionId {
        let p = &self.parts;
        let session = p.next_session.fetch_add(1, Ordering::Relaxed);
        tokio::spawn(memory::serve_datagrams(
            incoming,
            outgoing,
            session,
            p.events.clone(),
            p.shutdown.clone(),
        ));
        session
    }

    /// Starts recording, per session, each request processed and each reply sent (see
    /// [`SimRecording`]); at most `capacity` entries are kept (the oldest give way). Starting
    /// again clears the record.
    pub fn start_recording(&self, capacity: usize) {
        lock(&self.shared).recorder = Some(Recorder::new(capacity));
    }

    /// The record so far (empty if recording was never started).
    pub fn recording(&self) -> SimRecording {
        lock(&self.shared)
            .recorder
            .as_ref()
            .map(Recorder::snapshot)
            .unwrap_or_default()
    }

    /// The gripper restarts (a power cycle): every byte-stream connection is dropped without
    /// warning, the state (position, homing, settings, streams, a motion) is the
    /// configuration's again, and UDP sessions carry on with the fresh device.
    pub fn restart(&self) {
        let _ = self.control.send(Control::Restart);
    }

    /// Serves the simulator over TCP on `addr` (port 0 picks a free port; see
    /// [`SimServer::local_addr`]). Any number of connections share the one simulated gripper.
    pub async fn bind(addr: impl ToSocketAddrs, config: SimConfig) -> io::Result<SimServer> {
        let listener = TcpListener::bind(addr).await?;
        let (mut server, parts) = Self::start(config);
        server.local_addr = Some(listener.local_addr()?);
        tokio::spawn(accept(listener, parts));
        Ok(server)
    }

    /// Serves the simulator over UDP on `addr`: each datagram carries one frame; replies go to
    /// the sender's address, or with [`SimConfig::udp_remote_port`] to the sender's IP address
    /// at that port (the device's "UDP remote port"). A peer silent for
    /// [`SimConfig::udp_idle_timeout`] is forgotten (its auto-updates stop).
    pub async fn bind_udp(addr: impl ToSocketAddrs, config: SimConfig) -> io::Result<SimServer> {
        if config.text_interface {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "the text interface (GCL) is served over TCP only",
            ));
        }
        let socket = Arc::new(UdpSocket::bind(addr).await?);
        let settings = UdpSettings {
            remote_port: config.udp_remote_port,
            idle_timeout: config.udp_idle_timeout,
        };
        let (mut server, parts) = Self::start(config);
        server.local_addr = Some(socket.local_addr()?);
        tokio::spawn(serve_udp(socket, parts, settings));
        Ok(server)
    }

    /// Serves the simulator on a new pseudo-terminal; open [`SimServer::serial_path`] with a
    /// serial client (any baud rate). The simulator keeps the terminal open with a shared lock
    /// (so it survives the client closing it): open it non-exclusively, e.g. with
    /// [`ClientBuilder::serial_exclusive(false)`](crate::wsg::ClientBuilder::serial_exclusive).
    #[cfg(all(unix, feature = "serial"))]
    pub fn serial_pty(config: SimConfig) -> io::Result<SimServer> {
        use tokio_serial::SerialPort;
        let (master, mut slave) = tokio_serial::SerialStream::pair().map_err(io::Error::other)?;
        // The client opens the slave by path; our own handle on it keeps the pty alive.
        slave.set_exclusive(false).map_err(io::Error::other)?;
        let path = slave
            .name()
            .ok_or_else(|| io::Error::other("pseudo-terminal without a path"))?;
        let mut server = Self::attach(config, master, SessionKind::Serial);
        server.serial_path = Some(path);
        server._keep = Some(Box::new(Mutex::new(slave)));
        Ok(server)
    }

    /// Serves the simulator on one byte stream the caller provides (e.g. one end of
    /// `tokio::io::duplex`).
    pub fn attach(
        config: SimConfig,
        io: impl AsyncRead + AsyncWrite + Send + 'static,
        kind: SessionKind,
    ) -> SimServer {
        let (server, parts) = Self::start(config);
        let session = parts.next_session.fetch_add(1, Ordering::Relaxed);
        match parts.text {
            Some(gap) => tokio::spawn(serve_text(io, session, parts.events, parts.shutdown, gap)),
            None => tokio::spawn(serve_stream(
                io,
                session,
                kind,
                parts.events,
                parts.shutdown,
            )),
        };
        server
    }

    /// The bound address (TCP and UDP servers).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.local_addr
    }

    /// The pseudo-terminal to open (serial servers).
    pub fn serial_path(&self) -> Option<&str> {
        self.serial_path.as_deref()
    }

    /// The state after the simulator's last step.
    pub fn snapshot(&self) -> SimSnapshot {
        lock(&self.shared).snapshot.clone()
    }

    /// The command ids received so far (the last 4096), oldest first.
    pub fn received_ids(&self) -> Vec<u8> {
        lock(&self.shared).received.iter().copied().collect()
    }

    /// Fault: the next reply with command id `id` is not sent.
    pub fn drop_next_reply(&self, id: u8) {
        lock(&self.shared).faults.drop.push(id);
    }

    /// Fault: the next reply with command id `id` is sent with a broken checksum.
    pub fn corrupt_next_reply(&self, id: u8) {
        lock(&self.shared).faults.corrupt.push(id);
    }

    /// Fault: the next reply with command id `id` is sent `delay` late (later replies are not
    /// held back, so it may overtake nothing but be overtaken).
    pub fn delay_next_reply(&self, id: u8, delay: Duration) {
        lock(&self.shared).faults.delay.push((id, delay));
    }

    /// Fault: the next command with id `id` is answered with `status` (and not executed).
    pub fn force_status(&self, id: u8, status: Status) {
        lock(&self.shared).faults.forced.push((id, status));
    }

    /// The held part slips out: HOLDING → PART LOST.
    pub fn lose_part(&self) {
        let _ = self.control.send(Control::LosePart);
    }

    /// Changes the time scale (see [`SimConfig::time_scale`]) from now on, e.g. home instantly,
    /// then make moves slow enough to be stopped.
    pub fn set_time_scale(&self, time_scale: f64) {
        let _ = self.control.send(Control::TimeScale(time_scale));
    }

    /// Drops every stream connection (TCP, serial) without warning, like a pulled cable; an
    /// unannounced TCP close puts the gripper into FAST STOP. UDP peers are not affected.
    /// A connection the simulator has not accepted yet (a client's `connect` can return
    /// before that) is not affected: a test that unplugs a new client makes a call first.
    pub fn unplug(&self) {
        let _ = self.control.send(Control::Unplug);
    }

    /// Stops serving and closes every connection.
    pub fn shutdown(self) {
        drop(self);
    }
}

impl Drop for SimServer {
    fn drop(&mut self) {
        let _ = self.shutdown.send(true);
    }
}

async fn accept(listener: TcpListener, parts: Parts) {
    let Parts {
        events,
        text,
        mut shutdown,
        next_session,
    } = parts;
    loop {
        tokio::select! {
            // Shutdown first (it is rarely ready and must not wait behind a flood of accepts);
            // no random branch choice, so that runs replay.
            biased;
            _ = shutdown.changed() => return,
            r = listener.accept() => match r {
                Ok((stream, peer)) => {
                    let _ = stream.set_nodelay(true);
                    let session = next_session.fetch_add(1, Ordering::Relaxed);
                    tracing::debug!(%peer, session, "simulator: TCP connection");
                    match text {
                        Some(gap) => tokio::spawn(serve_text(stream, session, events.clone(), shutdown.clone(), gap)),
                        None => tokio::spawn(serve_stream(stream, session, SessionKind::Tcp, events.clone(), shutdown.clone())),
                    };
                }
                Err(e) => tracing::warn!(error = %e, "simulator: accept failed"),
            },
        }
    }
}
