//! The sockets: accept clients, connect each to the upstream server, and pump bytes both ways
//! through the framer and the fault rules of `plan.rs`.
//!
//! One task accepts; each connection is one task that owns both sockets and runs the two
//! directions side by side, so that cutting a connection is dropping that task's futures. All
//! shared state (rules, stall gates, statistics) sits behind one mutex that is never held across
//! an `.await`; every change bumps a `watch` counter, which is how waiting code (a stalled write, a
//! test waiting for a statistic) learns that it should look again, without polling or sleeping.

use std::fmt;
use std::io;
use std::net::{Ipv4Addr, SocketAddr};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use bytes::Bytes;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio::task::{JoinHandle, JoinSet};
use tokio::time::Instant;

use super::framing::{Framer, Framing, UnitKind};
use super::plan::{Gate, Pipeline, Rule, RuleCounter, RuleSet, Step};

/// Bytes read from a socket at a time (at most `max_frame_len`). With [`Framing::Bytes`] a read is
/// a unit, so this is also the largest unit.
const READ_CHUNK: usize = 8 * 1024;

/// One of the two directions of a proxied connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Bytes the client sends to the server (requests).
    ClientToServer,
    /// Bytes the server sends to the client (replies).
    ServerToClient,
}

impl Direction {
    fn index(self) -> usize {
        match self {
            Direction::ClientToServer => 0,
            Direction::ServerToClient => 1,
        }
    }
}

/// How a [`FaultProxy`] listens, frames and draws random numbers.
#[derive(Debug, Clone)]
pub struct ProxyConfig {
    listen: SocketAddr,
    framing: Framing,
    max_frame_len: usize,
    seed: u64,
    connect_timeout: Option<Duration>,
}

impl Default for ProxyConfig {
    fn default() -> Self {
        ProxyConfig {
            listen: SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
            framing: Framing::Bytes,
            max_frame_len: 64 * 1024,
            seed: 0x5EED_F00D,
            connect_timeout: None,
        }
    }
}

impl ProxyConfig {
    /// Listen on `127.0.0.1:0`, no framing, frames up to 64 KiB, a fixed seed, no upstream
    /// connect timeout of its own.
    pub fn new() -> Self {
        Self::default()
    }

    /// The address to listen on (port 0 picks a free port; see [`FaultProxy::local_addr`]).
    pub fn listen(mut self, addr: SocketAddr) -> Self {
        self.listen = addr;
        self
    }

    /// How frames are found in both directions (default [`Framing::Bytes`]).
    pub fn framing(mut self, framing: Framing) -> Self {
        self.framing = framing;
        self
    }

    /// The longest frame the proxy holds (default 64 KiB). Longer frames, and bytes that do not
    /// make a frame within this many bytes, are forwarded as they are, with no fault applied. This
    /// also bounds a merge group and the size of one read.
    ///
    /// Memory bound, per connection and direction: a partial frame and one read (each at most
    /// this many bytes), a merge group (at most this many bytes plus one frame and its
    /// duplicates), and the frame being written. While the proxy cannot write (a stall, a delay, a
    /// slow receiver) it stops reading, so the sender's TCP window closes instead of memory growing.
    pub fn max_frame_len(mut self, len: usize) -> Self {
        self.max_frame_len = len.max(1);
        self
    }

    /// Seed of the generator behind [`Fault::randomly`](super::Fault::randomly) and
    /// [`At::Random`](super::At::Random): the same seed and traffic give the same faults. Each
    /// direction draws from its own stream, shared by that direction's connections (so with
    /// several connections at once, which connection gets which draw depends on their timing).
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// How long the proxy tries to reach the upstream server for each client; when it cannot, it
    /// closes the client's connection.
    ///
    /// By default only the operating system's limit applies (a refused loopback port fails at
    /// once): a tokio timer here would fire at once under a paused test clock, which advances
    /// whenever the runtime waits on a socket.
    pub fn connect_timeout(mut self, timeout: Duration) -> Self {
        self.connect_timeout = Some(timeout);
        self
    }
}

/// Counters of one direction, summed over all connections.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct DirectionStats {
    /// Bytes read from the sending side.
    pub bytes_read: u64,
    /// Bytes written to the receiving side.
    pub bytes_written: u64,
    /// Frames seen by the fault rules (with [`Framing::Bytes`]: reads).
    pub frames: u64,
    /// Bytes forwarded without framing: garbage between frames, frames over the bound, a partial
    /// frame at the end of the stream.
    pub passthrough_bytes: u64,
    /// Writes to the receiving side (a split frame takes several, a merged group one).
    pub writes: u64,
    /// How many times a rule fired.
    pub faults_fired: u64,
    /// Bytes ready to be written but not written yet: waiting at a stall, or for a slow receiver.
    pub held_bytes: u64,
    /// Whether this direction is stalled.
    pub stalled: bool,
}

/// A snapshot of the proxy's counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Stats {
    /// Client connections accepted.
    pub connections_accepted: u64,
    /// Client connections being served now.
    pub connections_open: u64,
    /// Connections the proxy closed because of a cut (a rule or [`FaultProxy::cut_connections`]).
    pub connections_cut: u64,
    /// Clients whose upstream connection could not be made (their connection was closed).
    pub upstream_connect_failures: u64,
    /// Requests, client to server.
    pub client_to_server: DirectionStats,
    /// Replies, server to client.
    pub server_to_client: DirectionStats,
}

impl Stats {
    /// The counters of one direction.
    pub fn direction(&self, direction: Direction) -> &DirectionStats {
        match direction {
            Direction::ClientToServer => &self.client_to_server,
            Direction::ServerToClient => &self.server_to_client,
        }
    }
}

#[derive(Debug)]
struct DirState {
    rules: RuleSet,
    gate: Gate,
    stats: DirectionStats,
}

#[derive(Debug)]
struct State {
    dirs: [DirState; 2],
    accepted: u64,
    open: u64,
    cut: u64,
    upstream_failures: u64,
    /// Incremented by [`FaultProxy::cut_connections`]; a connection accepted under an older value
    /// closes.
    cut_epoch: u64,
    closing: bool,
}

impl State {
    fn snapshot(&self) -> Stats {
        let dir = |d: &DirState| DirectionStats {
            stalled: d.gate.is_stalled(),
            ..d.stats
        };
        Stats {
            connections_accepted: self.accepted,
            connections_open: self.open,
            connections_cut: self.cut,
            upstream_connect_failures: self.upstream_failures,
            client_to_server: dir(&self.dirs[0]),
            server_to_client: dir(&self.dirs[1]),
        }
    }
}

#[derive(Debug)]
struct Shared {
    upstream: SocketAddr,
    config: ProxyConfig,
    state: Mutex<State>,
    /// Bumped after every change of `state`.
    version: watch::Sender<u64>,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // Nothing panics while holding the lock; if something did, the counters are still usable.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Changes the state and wakes everything waiting on it.
    fn update<T>(&self, change: impl FnOnce(&mut State) -> T) -> T {
        let out = change(&mut self.lock());
        self.version.send_modify(|v| *v = v.wrapping_add(1));
        out
    }

    fn read<T>(&self, read: impl FnOnce(&State) -> T) -> T {
        read(&self.lock())
    }

    /// Waits until `ready` returns `Some`, looking again after every change.
    async fn wait_until<T>(&self, mut ready: impl FnMut(&mut State) -> Option<T>) -> T {
        // Subscribe before looking, so that a change between the look and the wait is not missed.
        let mut changes = self.version.subscribe();
        loop {
            if let Some(out) = ready(&mut self.lock()) {
                return out;
            }
            // The sender lives in `self`, so this cannot fail while we borrow it.
            let _ = changes.changed().await;
        }
    }

    /// Waits `duration`, or less if the rules of `dir` change from `generation`.
    async fn pause(&self, dir: Direction, duration: Duration, generation: u64) {
        let changed = self
            .wait_until(|s| (s.dirs[dir.index()].rules.generation() != generation).then_some(()));
        match Instant::now().checked_add(duration) {
            Some(deadline) => {
                tokio::select! {
                    () = tokio::time::sleep_until(deadline) => {}
                    () = changed => {}
                }
            }
            None => changed.await,
        }
    }
}

/// Controls the faults of one direction of a [`FaultProxy`]; cheap to clone, usable from any task
/// while traffic flows.
///
/// Rules, their counts and the stall switch are shared by all connections of the proxy: a change
/// applies to the next frame of every connection, and a rule added with [`Fault::once`] fires once
/// in total, on whichever connection sends the next frame.
///
/// Delays, pauses and merge waits run on tokio's clock: under a paused clock (`start_paused`)
/// they pass as soon as the runtime is idle.
///
/// [`Fault::once`]: super::Fault::once
#[derive(Clone)]
pub struct Faults {
    shared: Arc<Shared>,
    direction: Direction,
}

impl fmt::Debug for Faults {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Faults")
            .field("direction", &self.direction)
            .finish()
    }
}

impl Faults {
    /// The direction these faults apply to.
    pub fn direction(&self) -> Direction {
        self.direction
    }

    /// Adds a rule; it counts frames from now. The handle tells how often it fired.
    pub fn add(&self, rule: Rule) -> FaultHandle {
        let i = self.direction.index();
        let counter = self.shared.update(|s| s.dirs[i].rules.add(rule));
        FaultHandle {
            shared: Arc::clone(&self.shared),
            direction: self.direction,
            rule,
            counter,
        }
    }

    /// Removes every rule of this direction (their handles keep their counts). Does not release a
    /// stall: see [`release`](Self::release).
    pub fn clear(&self) {
        let i = self.direction.index();
        self.shared.update(|s| s.dirs[i].rules.clear());
    }

    /// Stops forwarding in this direction now, without closing anything: bytes already read wait,
    /// and once the proxy's buffers are full the sender's TCP window closes.
    pub fn stall(&self) {
        let i = self.direction.index();
        self.shared.update(|s| s.dirs[i].gate.stall());
    }

    /// Ends a stall: everything held is forwarded.
    pub fn release(&self) {
        let i = self.direction.index();
        self.shared.update(|s| s.dirs[i].gate.release());
    }

    /// Lets exactly `n` more bytes through a stall, which stays in force for the bytes after them.
    pub fn release_bytes(&self, n: usize) {
        let i = self.direction.index();
        self.shared.update(|s| s.dirs[i].gate.release_bytes(n));
    }

    /// Whether this direction is stalled.
    pub fn is_stalled(&self) -> bool {
        let i = self.direction.index();
        self.shared.read(|s| s.dirs[i].gate.is_stalled())
    }

    /// This direction's counters.
    pub fn stats(&self) -> DirectionStats {
        let direction = self.direction;
        self.shared.read(|s| *s.snapshot().direction(direction))
    }

    /// Waits until this direction's counters satisfy `ready`, and returns them.
    pub async fn wait_for(&self, mut ready: impl FnMut(&DirectionStats) -> bool) -> DirectionStats {
        let direction = self.direction;
        self.shared
            .wait_until(|s| {
                let stats = *s.snapshot().direction(direction);
                ready(&stats).then_some(stats)
            })
            .await
    }
}

/// One rule added with [`Faults::add`]: how often it fired, and a way to remove it. Dropping the
/// handle leaves the rule in force.
pub struct FaultHandle {
    shared: Arc<Shared>,
    direction: Direction,
    rule: Rule,
    counter: Arc<RuleCounter>,
}

impl fmt::Debug for FaultHandle {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FaultHandle")
            .field("direction", &self.direction)
            .field("rule", &self.rule)
            .field("fired", &self.fired())
            .field("active", &self.is_active())
            .finish()
    }
}

impl FaultHandle {
    /// The rule.
    pub fn rule(&self) -> Rule {
        self.rule
    }

    /// How many frames the fault was applied to so far.
    pub fn fired(&self) -> u64 {
        self.counter.fired()
    }

    /// Whether the rule is still in force (not done, not removed).
    pub fn is_active(&self) -> bool {
        !self.counter.is_finished()
    }

    /// Removes the rule (if it is still there). Also ends pauses and delays in progress in this
    /// direction, like any change of its faults.
    pub fn remove(&self) {
        let i = self.direction.index();
        self.shared
            .update(|s| s.dirs[i].rules.remove(&self.counter));
    }

    /// Waits until the fault has fired at least `n` times; returns the count. It waits as long as
    /// it takes (also after the rule is done or removed): wrap it in a timeout.
    pub async fn wait_fired(&self, n: u64) -> u64 {
        self.shared
            .wait_until(|_| {
                let fired = self.counter.fired();
                (fired >= n).then_some(fired)
            })
            .await
    }
}

/// A TCP proxy between a client and a server that injects faults on request.
///
/// Dropping it closes the listener and every proxied connection (both sides); [`shutdown`](
/// Self::shutdown) does the same and waits until it is done.
pub struct FaultProxy {
    shared: Arc<Shared>,
    local_addr: SocketAddr,
    task: Option<JoinHandle<()>>,
}

impl fmt::Debug for FaultProxy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FaultProxy")
            .field("local_addr", &self.local_addr)
            .field("upstream", &self.shared.upstream)
            .finish()
    }
}

impl FaultProxy {
    /// Starts a proxy on `127.0.0.1:0` to `upstream`, with no framing (each read is a unit).
    pub async fn start(upstream: SocketAddr) -> io::Result<FaultProxy> {
        Self::start_with(upstream, ProxyConfig::default()).await
    }

    /// Starts a proxy to `upstream` with this configuration.
    pub async fn start_with(upstream: SocketAddr, config: ProxyConfig) -> io::Result<FaultProxy> {
        let listener = TcpListener::bind(config.listen).await?;
        let local_addr = listener.local_addr()?;
        let dir = |seed: u64| DirState {
            rules: RuleSet::new(seed),
            gate: Gate::default(),
            stats: DirectionStats::default(),
        };
        let state = State {
            // Different streams per direction, both from the one seed.
            dirs: [dir(config.seed), dir(config.seed ^ 0xD1B5_4A32_D192_ED03)],
            accepted: 0,
            open: 0,
            cut: 0,
            upstream_failures: 0,
            cut_epoch: 0,
            closing: false,
        };
        let shared = Arc::new(Shared {
            upstream,
            config,
            state: Mutex::new(state),
            version: watch::Sender::new(0),
        });
        let task = tokio::spawn(accept_loop(Arc::clone(&shared), listener));
        Ok(FaultProxy {
            shared,
            local_addr,
            task: Some(task),
        })
    }

    /// The address clients connect to.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The server the proxy forwards to.
    pub fn upstream(&self) -> SocketAddr {
        self.shared.upstream
    }

    /// The faults of one direction.
    pub fn faults(&self, direction: Direction) -> Faults {
        Faults {
            shared: Arc::clone(&self.shared),
            direction,
        }
    }

    /// The faults applied to requests.
    pub fn client_to_server(&self) -> Faults {
        self.faults(Direction::ClientToServer)
    }

    /// The faults applied to replies.
    pub fn server_to_client(&self) -> Faults {
        self.faults(Direction::ServerToClient)
    }

    /// Closes every connection open now, both sides, at once (a pulled cable). Connections made
    /// afterwards are served normally.
    pub fn cut_connections(&self) {
        self.shared.update(|s| s.cut_epoch += 1);
    }

    /// The counters so far.
    pub fn stats(&self) -> Stats {
        self.shared.read(State::snapshot)
    }

    /// Waits until the counters satisfy `ready` (e.g. "2 connections accepted", "a frame is held at
    /// the stall"), and returns them. Wrap it in a timeout: it waits as long as it takes.
    pub async fn wait_for_stats(&self, mut ready: impl FnMut(&Stats) -> bool) -> Stats {
        self.shared
            .wait_until(|s| {
                let stats = s.snapshot();
                ready(&stats).then_some(stats)
            })
            .await
    }

    /// Closes the listener and every connection, and waits until all of it is gone.
    pub async fn shutdown(mut self) {
        self.shared.update(|s| s.closing = true);
        if let Some(task) = self.task.take() {
            // The accept task only ends by itself, after closing its connections; a panic in it
            // has nothing left to clean up.
            let _ = task.await;
        }
    }
}

impl Drop for FaultProxy {
    fn drop(&mut self) {
        self.shared.update(|s| s.closing = true);
        if let Some(task) = self.task.take() {
            // Aborting drops the listener and the set of connection tasks, which aborts them all.
            task.abort();
        }
    }
}

/// Counts a connection as open until dropped, even if its task is aborted before it starts.
struct OpenGuard(Arc<Shared>);

impl OpenGuard {
    fn new(shared: Arc<Shared>) -> (Self, u64) {
        let epoch = shared.update(|s| {
            s.accepted += 1;
            s.open += 1;
            s.cut_epoch
        });
        (OpenGuard(shared), epoch)
    }
}

impl Drop for OpenGuard {
    fn drop(&mut self) {
        self.0.update(|s| s.open -= 1);
    }
}

async fn accept_loop(shared: Arc<Shared>, listener: TcpListener) {
    let mut connections = JoinSet::new();
    let closing = shared.wait_until(|s| s.closing.then_some(()));
    tokio::pin!(closing);
    loop {
        tokio::select! {
            () = &mut closing => break,
            accepted = listener.accept() => match accepted {
                Ok((client, peer)) => {
                    tracing::debug!(%peer, "fault proxy: client connected");
                    let (guard, epoch) = OpenGuard::new(Arc::clone(&shared));
                    let shared = Arc::clone(&shared);
                    connections.spawn(async move {
                        let _open = guard;
                        serve(&shared, client, epoch).await;
                    });
                }
                Err(error) => {
                    // E.g. out of file descriptors: back off instead of spinning on the error.
                    tracing::warn!(%error, "fault proxy: accept failed");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            },
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
    drop(listener);
    connections.shutdown().await;
}

/// How one direction of a connection ended.
#[derive(Debug)]
enum End {
    /// The sender closed; the receiver was told (FIN).
    Eof,
    /// A fault cut the connection.
    Cut,
    /// A socket failed.
    Failed(io::Error),
}

async fn serve(shared: &Shared, client: TcpStream, epoch: u64) {
    let connect = TcpStream::connect(shared.upstream);
    let connected = match shared.config.connect_timeout {
        Some(limit) => tokio::time::timeout(limit, connect).await,
        None => Ok(connect.await),
    };
    let upstream = match connected {
        Ok(Ok(upstream)) => upstream,
        Ok(Err(error)) => {
            tracing::warn!(%error, upstream = %shared.upstream, "fault proxy: cannot reach upstream");
            shared.update(|s| s.upstream_failures += 1);
            return;
        }
        Err(_) => {
            tracing::warn!(upstream = %shared.upstream, "fault proxy: upstream connect timed out");
            shared.update(|s| s.upstream_failures += 1);
            return;
        }
    };
    // Each write must leave as its own segment, or a split would be undone by Nagle's algorithm.
    // Failing to set it only makes splits less visible, so it is not fatal.
    let _ = client.set_nodelay(true);
    let _ = upstream.set_nodelay(true);
    let (client_read, client_write) = client.into_split();
    let (upstream_read, upstream_write) = upstream.into_split();

    let requests = pump(
        shared,
        Direction::ClientToServer,
        client_read,
        upstream_write,
    );
    let replies = pump(
        shared,
        Direction::ServerToClient,
        upstream_read,
        client_write,
    );
    // `Cut` when the test pulled the cable, `Eof` (not counted as a cut) when the proxy shuts down.
    let cut = shared.wait_until(|s| {
        if s.cut_epoch != epoch {
            Some(End::Cut)
        } else {
            s.closing.then_some(End::Eof)
        }
    });
    tokio::pin!(requests, replies, cut);
    let (mut requests_done, mut replies_done) = (false, false);
    // One direction may end (half-close) while the other still flows; a cut or a failure ends both,
    // by dropping both sockets when this function returns.
    let end = loop {
        tokio::select! {
            end = &mut requests, if !requests_done => match end {
                End::Eof => requests_done = true,
                end => break end,
            },
            end = &mut replies, if !replies_done => match end {
                End::Eof => replies_done = true,
                end => break end,
            },
            end = &mut cut => break end,
        }
        if requests_done && replies_done {
            break End::Eof;
        }
    };
    match end {
        End::Eof => tracing::debug!("fault proxy: connection closed"),
        End::Cut => {
            tracing::debug!("fault proxy: connection cut");
            shared.update(|s| s.cut += 1);
        }
        End::Failed(error) => tracing::debug!(%error, "fault proxy: connection failed"),
    }
}

/// Forwards one direction until the sender closes, a fault cuts, or a socket fails.
async fn pump(
    shared: &Shared,
    dir: Direction,
    mut reader: OwnedReadHalf,
    mut writer: OwnedWriteHalf,
) -> End {
    let i = dir.index();
    let mut framer = Framer::new(shared.config.framing, shared.config.max_frame_len);
    let mut pipeline = Pipeline::new(shared.config.max_frame_len);
    // While a merge group is held: how long it may wait, and the rules' generation it began under.
    let mut merge: Option<(Duration, Instant, u64)> = None;
    let mut buf = vec![0u8; READ_CHUNK.min(shared.config.max_frame_len)];
    loop {
        let read = match merge {
            Some((max_wait, since, generation)) => {
                let left = max_wait.saturating_sub(since.elapsed());
                tokio::select! {
                    read = reader.read(&mut buf) => read,
                    () = shared.pause(dir, left, generation) => {
                        merge = None;
                        let steps: Vec<Step> = pipeline.flush().into_iter().collect();
                        if let Err(end) = execute(shared, dir, &mut writer, steps, generation).await {
                            return end;
                        }
                        continue;
                    }
                }
            }
            None => reader.read(&mut buf).await,
        };
        let n = match read {
            Ok(0) => break,
            Ok(n) => n,
            Err(error) => return End::Failed(error),
        };
        shared.update(|s| s.dirs[i].stats.bytes_read += n as u64);
        framer.push(buf.get(..n).unwrap_or_default());
        while let Some(unit) = framer.next_unit() {
            let (steps, generation) = match unit.kind {
                UnitKind::Frame => {
                    let (decision, generation) = shared.update(|s| {
                        let d = &mut s.dirs[i];
                        d.stats.frames += 1;
                        let decision = d.rules.decide(unit.bytes.len());
                        d.stats.faults_fired += decision.fired;
                        // Read after deciding: a one-shot rule that is done now must not end
                        // the pauses it has just planned.
                        (decision, d.rules.generation())
                    });
                    (pipeline.frame(unit.bytes, &decision), generation)
                }
                UnitKind::Passthrough => {
                    let generation = shared.update(|s| {
                        let d = &mut s.dirs[i];
                        d.stats.passthrough_bytes += unit.bytes.len() as u64;
                        d.rules.generation()
                    });
                    (pipeline.passthrough(unit.bytes), generation)
                }
            };
            merge = match (merge, pipeline.merge_wait()) {
                (_, None) => None,
                (Some(held), Some(_)) => Some(held),
                (None, Some(max_wait)) => Some((max_wait, Instant::now(), generation)),
            };
            if let Err(end) = execute(shared, dir, &mut writer, steps, generation).await {
                return end;
            }
        }
    }
    // The sender closed: forward what is left, then close the receiver's side (half-close).
    let mut steps = Vec::new();
    if let Some(tail) = framer.finish() {
        shared.update(|s| s.dirs[i].stats.passthrough_bytes += tail.bytes.len() as u64);
        steps.extend(pipeline.passthrough(tail.bytes));
    }
    steps.extend(pipeline.flush());
    let generation = shared.read(|s| s.dirs[i].rules.generation());
    if let Err(end) = execute(shared, dir, &mut writer, steps, generation).await {
        return end;
    }
    match writer.shutdown().await {
        Ok(()) => End::Eof,
        Err(error) => End::Failed(error),
    }
}

/// Carries out the steps planned for one unit.
async fn execute(
    shared: &Shared,
    dir: Direction,
    writer: &mut OwnedWriteHalf,
    steps: Vec<Step>,
    generation: u64,
) -> Result<(), End> {
    let i = dir.index();
    for step in steps {
        match step {
            Step::Stall => shared.update(|s| s.dirs[i].gate.stall()),
            Step::Wait(duration) => shared.pause(dir, duration, generation).await,
            Step::Write { bytes, split: None } => write(shared, dir, writer, bytes).await?,
            Step::Write {
                mut bytes,
                split: Some((piece_len, pause)),
            } => {
                let mut first = true;
                while !bytes.is_empty() {
                    if !first && !pause.is_zero() {
                        shared.pause(dir, pause, generation).await;
                    }
                    first = false;
                    let piece = bytes.split_to(piece_len.clamp(1, bytes.len()));
                    write(shared, dir, writer, piece).await?;
                }
            }
            Step::Cut => return Err(End::Cut),
        }
    }
    Ok(())
}

/// Takes bytes off `held_bytes` as they are written, and the rest if the write is abandoned.
struct Held<'a> {
    shared: &'a Shared,
    i: usize,
    left: usize,
}

impl Drop for Held<'_> {
    fn drop(&mut self) {
        if self.left > 0 {
            let (i, left) = (self.i, self.left as u64);
            self.shared.update(|s| s.dirs[i].stats.held_bytes -= left);
        }
    }
}

/// Writes `bytes` through the direction's stall gate, as soon and as far as it lets them pass.
async fn write(
    shared: &Shared,
    dir: Direction,
    writer: &mut OwnedWriteHalf,
    mut bytes: Bytes,
) -> Result<(), End> {
    let i = dir.index();
    shared.update(|s| s.dirs[i].stats.held_bytes += bytes.len() as u64);
    let mut held = Held {
        shared,
        i,
        left: bytes.len(),
    };
    while !bytes.is_empty() {
        let want = bytes.len();
        let n = shared
            .wait_until(|s| {
                let n = s.dirs[i].gate.take(want);
                (n > 0).then_some(n)
            })
            .await;
        let chunk = bytes.split_to(n);
        writer.write_all(&chunk).await.map_err(End::Failed)?;
        held.left -= n;
        shared.update(|s| {
            let stats = &mut s.dirs[i].stats;
            stats.held_bytes -= n as u64;
            stats.bytes_written += n as u64;
            stats.writes += 1;
        });
    }
    Ok(())
}
