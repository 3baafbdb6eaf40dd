//! Serving the simulated gripper over TCP, UDP, a serial pseudo-terminal or any byte stream.
//!
//! One actor task owns the [`Device`] (no locks around the state machine); every connection is
//! a task that forwards decoded frames to it and writes the bytes it gets back. The actor
//! applies the injected faults on the way out.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use bytes::{Bytes, BytesMut};
use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, ToSocketAddrs, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::time::{sleep_until, Instant};
use tokio_util::codec::{Decoder, FramedRead};

use super::device::{Device, Out, SessionId, SessionKind};
use super::model::SimConfig;
use crate::wsg::frame::{self, Decoded, DEFAULT_MAX_PAYLOAD_LEN};
use crate::wsg::{GripState, Status, SystemState};

/// Decodes what a device receives: frames, and frames with a bad checksum (which a device
/// answers with E_CHECKSUM_ERROR). Never fails.
#[derive(Debug, Default)]
struct DeviceCodec;

impl Decoder for DeviceCodec {
    type Item = Decoded;
    type Error = io::Error;

    fn decode(&mut self, src: &mut BytesMut) -> io::Result<Option<Decoded>> {
        Ok(frame::decode(src, DEFAULT_MAX_PAYLOAD_LEN))
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> io::Result<Option<Decoded>> {
        Ok(frame::decode_eof(src, DEFAULT_MAX_PAYLOAD_LEN))
    }
}

enum Event {
    Connected {
        session: SessionId,
        kind: SessionKind,
        tx: mpsc::Sender<Bytes>,
    },
    Received {
        session: SessionId,
        decoded: Decoded,
    },
    Disconnected {
        session: SessionId,
    },
}

enum Control {
    LosePart,
    Unplug,
    TimeScale(f64),
}

#[derive(Debug, Default)]
struct Faults {
    drop: Vec<u8>,
    corrupt: Vec<u8>,
    delay: Vec<(u8, Duration)>,
    forced: Vec<(u8, Status)>,
}

fn take<T>(v: &mut Vec<T>, pred: impl Fn(&T) -> bool) -> Option<T> {
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
struct Shared {
    faults: Faults,
    /// Command ids received, oldest first (the last 4096).
    received: VecDeque<u8>,
    snapshot: SimSnapshot,
}

/// Simulated seconds from the wall clock and a time scale.
struct SimClock {
    scale: f64,
    base_wall: Instant,
    base_sim: f64,
}

impl SimClock {
    fn now(&self) -> f64 {
        if self.scale > 0.0 {
            self.base_sim + self.base_wall.elapsed().as_secs_f64() / self.scale
        } else {
            self.base_sim
        }
    }

    fn wall_at(&self, sim: f64) -> Instant {
        let far = Instant::now() + Duration::from_secs(365 * 24 * 3600);
        if self.scale <= 0.0 {
            return Instant::now();
        }
        let secs = ((sim - self.base_sim) * self.scale).clamp(0.0, 1e9);
        self.base_wall
            .checked_add(Duration::from_secs_f64(secs))
            .map_or(far, |t| t.min(far))
    }
}

struct Actor {
    device: Device,
    clock: SimClock,
    started: Instant,
    sessions: HashMap<SessionId, mpsc::Sender<Bytes>>,
    shared: Arc<Mutex<Shared>>,
    events: mpsc::Receiver<Event>,
    control: mpsc::UnboundedReceiver<Control>,
    shutdown: watch::Receiver<bool>,
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // A panic elsewhere must not take the simulator down with a poisoned lock.
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

impl Actor {
    fn wall(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    async fn run(mut self) {
        loop {
            self.settle();
            let motion = self.device.next_event().map(|t| self.clock.wall_at(t));
            let update = self
                .device
                .next_update_due()
                .map(|w| self.started + Duration::from_secs_f64(w.clamp(0.0, 1e9)));
            let wake = match (motion, update) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            tokio::select! {
                ev = self.events.recv() => match ev {
                    Some(ev) => self.on_event(ev),
                    None => return,
                },
                Some(c) = self.control.recv() => match c {
                    Control::LosePart => self.device.lose_part(),
                    Control::TimeScale(scale) => {
                        // Rebase so simulated time stays continuous across the change.
                        self.clock.base_sim = self.clock.now();
                        self.clock.base_wall = Instant::now();
                        self.clock.scale = scale;
                    }
                    // Dropping the senders ends the connection tasks, which close their sockets.
                    // UDP has no connection to pull.
                    Control::Unplug => {
                        let device = &self.device;
                        self.sessions.retain(|s, _| device.session_kind(*s) == Some(SessionKind::Udp));
                    }
                },
                _ = sleep_until(wake.unwrap_or_else(Instant::now)), if wake.is_some() => {}
                _ = self.shutdown.changed() => return,
            }
        }
    }

    /// Delivers what became due: finished motions (all at once with time scale 0) and
    /// auto-updates.
    fn settle(&mut self) {
        let outs = self.device.advance(self.clock.now());
        self.dispatch(outs);
        if self.clock.scale <= 0.0 {
            while let Some(t) = self.device.next_event() {
                self.clock.base_sim = t.max(self.clock.base_sim);
                let outs = self.device.advance(t);
                self.dispatch(outs);
            }
        }
        let outs = self.device.updates_due(self.wall());
        self.dispatch(outs);
        let snapshot = SimSnapshot {
            grip_state: self.device.grip_state(),
            system_state: self.device.system_state(),
            width_mm: self.device.width_mm(),
            sessions: self.sessions.len(),
            streams: self.device.active_streams(),
        };
        lock(&self.shared).snapshot = snapshot;
    }

    fn on_event(&mut self, ev: Event) {
        match ev {
            Event::Connected { session, kind, tx } => {
                self.sessions.insert(session, tx);
                self.device.connect(session, kind);
            }
            Event::Disconnected { session } => {
                self.sessions.remove(&session);
                self.device.disconnect(session, self.clock.now());
            }
            Event::Received { session, decoded } => {
                let forced = {
                    let mut shared = lock(&self.shared);
                    let id = match &decoded {
                        Decoded::Frame(f) => f.id,
                        Decoded::Corrupt { id, .. } => *id,
                    };
                    if shared.received.len() >= 4096 {
                        shared.received.pop_front();
                    }
                    shared.received.push_back(id);
                    match &decoded {
                        Decoded::Frame(f) => take(&mut shared.faults.forced, |(i, _)| *i == f.id),
                        Decoded::Corrupt { .. } => None,
                    }
                };
                let outs = match forced {
                    Some((id, status)) => vec![Out {
                        session,
                        reply: crate::wsg::Reply::new(id, status, Bytes::new()),
                    }],
                    None => {
                        let (now, wall) = (self.clock.now(), self.wall());
                        self.device.handle_at(now, Some(wall), session, &decoded)
                    }
                };
                self.dispatch(outs);
            }
        }
    }

    fn dispatch(&mut self, outs: Vec<Out>) {
        for out in outs {
            let Some(tx) = self.sessions.get(&out.session) else {
                continue;
            };
            let id = out.reply.id;
            let (drop, corrupt, delay) = {
                let mut shared = lock(&self.shared);
                let f = &mut shared.faults;
                (
                    take(&mut f.drop, |i| *i == id).is_some(),
                    take(&mut f.corrupt, |i| *i == id).is_some(),
                    take(&mut f.delay, |(i, _)| *i == id).map(|(_, d)| d),
                )
            };
            if drop {
                tracing::debug!(id, "simulator: reply dropped (injected fault)");
                continue;
            }
            let mut b = BytesMut::new();
            if frame::encode(&out.reply.to_frame(), &mut b).is_err() {
                continue;
            }
            if corrupt {
                if let Some(last) = b.last_mut() {
                    *last ^= 0xFF;
                }
            }
            let bytes = b.freeze();
            match delay {
                Some(d) => {
                    let tx = tx.clone();
                    tokio::spawn(async move {
                        tokio::time::sleep(d).await;
                        let _ = tx.send(bytes).await;
                    });
                }
                None => {
                    if tx.try_send(bytes).is_err() {
                        tracing::warn!(id, "simulator: connection not reading; reply dropped");
                    }
                }
            }
        }
    }
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
}

struct Parts {
    events: mpsc::Sender<Event>,
    shutdown: watch::Receiver<bool>,
    next_session: Arc<AtomicU64>,
}

impl SimServer {
    fn start(config: SimConfig) -> (SimServer, Parts) {
        let (events_tx, events) = mpsc::channel(1024);
        let (control_tx, control) = mpsc::unbounded_channel();
        let (shutdown_tx, shutdown) = watch::channel(false);
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
            sessions: HashMap::new(),
            shared: shared.clone(),
            events,
            control,
            shutdown: shutdown.clone(),
        };
        tokio::spawn(actor.run());
        let server = SimServer {
            local_addr: None,
            serial_path: None,
            shared,
            control: control_tx,
            shutdown: shutdown_tx,
            _keep: None,
        };
        (
            server,
            Parts {
                events: events_tx,
                shutdown,
                next_session: Arc::new(AtomicU64::new(1)),
            },
        )
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
    /// the sender's address.
    pub async fn bind_udp(addr: impl ToSocketAddrs, config: SimConfig) -> io::Result<SimServer> {
        let socket = Arc::new(UdpSocket::bind(addr).await?);
        let (mut server, parts) = Self::start(config);
        server.local_addr = Some(socket.local_addr()?);
        tokio::spawn(serve_udp(socket, parts));
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
        tokio::spawn(serve_stream(
            io,
            session,
            kind,
            parts.events,
            parts.shutdown,
        ));
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
        mut shutdown,
        next_session,
    } = parts;
    loop {
        tokio::select! {
            r = listener.accept() => match r {
                Ok((stream, peer)) => {
                    let _ = stream.set_nodelay(true);
                    let session = next_session.fetch_add(1, Ordering::Relaxed);
                    tracing::debug!(%peer, session, "simulator: TCP connection");
                    tokio::spawn(serve_stream(stream, session, SessionKind::Tcp, events.clone(), shutdown.clone()));
                }
                Err(e) => tracing::warn!(error = %e, "simulator: accept failed"),
            },
            _ = shutdown.changed() => return,
        }
    }
}

async fn serve_stream(
    io: impl AsyncRead + AsyncWrite + Send + 'static,
    session: SessionId,
    kind: SessionKind,
    events: mpsc::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
) {
    let (tx, mut out) = mpsc::channel::<Bytes>(256);
    if events
        .send(Event::Connected { session, kind, tx })
        .await
        .is_err()
    {
        return;
    }
    let (rd, mut wr) = tokio::io::split(io);
    let mut reader = FramedRead::new(rd, DeviceCodec);
    loop {
        tokio::select! {
            item = std::future::poll_fn(|cx| std::pin::Pin::new(&mut reader).poll_next(cx)) => match item {
                Some(Ok(decoded)) => {
                    if events.send(Event::Received { session, decoded }).await.is_err() {
                        break;
                    }
                }
                _ => break,
            },
            bytes = out.recv() => match bytes {
                Some(b) => {
                    if wr.write_all(&b).await.is_err() || wr.flush().await.is_err() {
                        break;
                    }
                }
                None => break,
            },
            _ = shutdown.changed() => break,
        }
    }
    let _ = wr.shutdown().await;
    let _ = events.send(Event::Disconnected { session }).await;
}

async fn serve_udp(socket: Arc<UdpSocket>, parts: Parts) {
    let Parts {
        events,
        mut shutdown,
        next_session,
    } = parts;
    let mut peers: HashMap<SocketAddr, SessionId> = HashMap::new();
    let mut buf = vec![0u8; 65536];
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let Ok((n, from)) = r else { continue };
                let session = match peers.get(&from) {
                    Some(s) => *s,
                    None => {
                        let session = next_session.fetch_add(1, Ordering::Relaxed);
                        let (tx, mut out) = mpsc::channel::<Bytes>(256);
                        let socket = socket.clone();
                        tokio::spawn(async move {
                            while let Some(b) = out.recv().await {
                                let _ = socket.send_to(&b, from).await;
                            }
                        });
                        let kind = SessionKind::Udp;
                        if events.send(Event::Connected { session, kind, tx }).await.is_err() {
                            return;
                        }
                        peers.insert(from, session);
                        session
                    }
                };
                let mut b = BytesMut::from(&buf[..n]);
                while let Some(decoded) = frame::decode_eof(&mut b, DEFAULT_MAX_PAYLOAD_LEN) {
                    if events.send(Event::Received { session, decoded }).await.is_err() {
                        return;
                    }
                }
            }
            _ = shutdown.changed() => return,
        }
    }
}
