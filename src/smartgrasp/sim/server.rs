//! The simulator's TCP server: accepts connections, feeds request frames to the shared
//! [`SimState`], carries out its [`Action`]s. Each connection answers its requests in order.

use std::collections::VecDeque;
use std::future::poll_fn;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, ToSocketAddrs};
use tokio::task::{JoinHandle, JoinSet};
use tokio::time::Instant;
use tokio_util::codec::FramedRead;
use tokio_util::sync::CancellationToken;

use super::state::{Action, Fault, SimConfig, SimState};
use crate::smartgrasp::codec::ServerCodec;
use crate::smartgrasp::frame::AnyRequestFrame;
use crate::smartgrasp::pose::Pose;
use crate::smartgrasp::types::RobotSystem;

/// A running simulated Smart Grasping server. Dropping it (or [`shutdown`](Self::shutdown))
/// stops the server and closes every connection.
#[derive(Debug)]
pub struct SimServer {
    local_addr: SocketAddr,
    state: Arc<Mutex<SimState>>,
    /// The TCP accept loop ([`bind`](Self::bind) only).
    accept: Option<JoinHandle<()>>,
    /// Ends the connections [`serve_stream`](Self::serve_stream) serves (on drop).
    shutdown: CancellationToken,
    /// Numbers the connections (the record's `session`), from 1.
    next_session: Arc<AtomicU64>,
    /// Off until [`start_recording`](Self::start_recording).
    recording: Arc<Mutex<Option<Recording>>>,
}

/// One request a connection processed and the bytes it sent for it (a test's oracle checks
/// that a client's answer is the server's answer to that request).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimExchange {
    /// The connection (numbered from 1 in the order they were served).
    pub session: u64,
    /// The request frame as received.
    pub request: AnyRequestFrame,
    /// The bytes sent for it (a response frame, the "too old" empty message, or a
    /// [`Fault::CorruptLength`]'s bytes); a request answered with nothing is not recorded.
    pub response: Vec<u8>,
    /// When the response was written (tokio's clock).
    pub sent_at: Instant,
}

/// The bounded record: the oldest entries give way.
#[derive(Debug)]
struct Recording {
    capacity: usize,
    entries: VecDeque<SimExchange>,
}

impl SimServer {
    /// Binds `addr` (port 0 picks a free port) and serves in the background. Cancel-safe: a
    /// dropped future has bound nothing or drops the listener it bound.
    pub async fn bind(addr: impl ToSocketAddrs, config: SimConfig) -> std::io::Result<SimServer> {
        let listener = TcpListener::bind(addr).await?;
        let mut server = SimServer::in_memory(config);
        server.local_addr = listener.local_addr()?;
        server.accept = Some(tokio::spawn(accept_loop(listener, server.conn())));
        tracing::info!(local_addr = %server.local_addr, "smartgrasp simulator listening");
        Ok(server)
    }

    /// A server with no listener of its own: give it connections with
    /// [`serve_stream`](Self::serve_stream) (e.g. ends of `tokio::io::duplex`). With in-memory
    /// streams and tokio's paused clock a test runs without the operating system's sockets or
    /// clock, so it replays exactly. Its [`local_addr`](Self::local_addr) is `0.0.0.0:0`.
    pub fn in_memory(config: SimConfig) -> SimServer {
        SimServer {
            local_addr: SocketAddr::from(([0, 0, 0, 0], 0)),
            state: Arc::new(Mutex::new(SimState::new(config))),
            accept: None,
            shutdown: CancellationToken::new(),
            next_session: Arc::new(AtomicU64::new(1)),
            recording: Arc::new(Mutex::new(None)),
        }
    }

    /// What a connection task needs.
    fn conn(&self) -> Conn {
        Conn {
            state: Arc::clone(&self.state),
            next_session: Arc::clone(&self.next_session),
            recording: Arc::clone(&self.recording),
        }
    }

    /// Serves one more byte stream as a new connection, beside the ones the server has, until
    /// the stream ends or the server is dropped; returns its session number. Must be called
    /// inside a tokio runtime.
    pub fn serve_stream(&self, io: impl AsyncRead + AsyncWrite + Send + 'static) -> u64 {
        let conn = self.conn();
        let session = conn.next_session.fetch_add(1, Ordering::Relaxed);
        let stop = self.shutdown.clone();
        tokio::spawn(async move {
            tokio::select! {
                // The shutdown first: a dropped server ends its connections whatever they do.
                biased;
                () = stop.cancelled() => {}
                () = serve(io, conn, session) => {}
            }
        });
        session
    }

    /// Starts recording, per connection, each request processed and the bytes sent for it (see
    /// [`SimExchange`]); at most `capacity` entries are kept (the oldest give way). Starting
    /// again clears the record. Off by default.
    pub fn start_recording(&self, capacity: usize) {
        *lock_record(&self.recording) = Some(Recording {
            capacity,
            entries: VecDeque::new(),
        });
    }

    /// The record so far, oldest first (empty if recording was never started).
    pub fn recording(&self) -> Vec<SimExchange> {
        lock_record(&self.recording)
            .as_ref()
            .map(|r| r.entries.iter().cloned().collect())
            .unwrap_or_default()
    }

    /// The bound address (`0.0.0.0:0` for [`in_memory`](Self::in_memory)).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Queues a fault; each replaces one upcoming response (on whichever connection answers
    /// next), in order.
    pub fn inject(&self, fault: Fault) {
        self.with_state(|s| s.inject(fault));
    }

    /// Drops the faults [`inject`](Self::inject) queued that no response has taken yet (a test
    /// ending its faulty part); returns how many.
    pub fn clear_faults(&self) -> usize {
        self.with_state(|s| s.clear_faults())
    }

    /// The robot systems REGISTER_CLIENT reported so far.
    pub fn registered_clients(&self) -> Vec<RobotSystem> {
        self.with_state(|s| s.registered_clients().to_vec())
    }

    /// The poses ROBOT_POSE reported so far.
    pub fn robot_poses(&self) -> Vec<Pose> {
        self.with_state(|s| s.robot_poses().to_vec())
    }

    /// Runs `f` on the state to inspect or change it (scenes, server state, faults). The server
    /// waits while `f` runs, so no lock can be held across an `.await`.
    pub fn with_state<R>(&self, f: impl FnOnce(&mut SimState) -> R) -> R {
        f(&mut lock(&self.state))
    }

    /// The shared state, for the monitor page (`http.rs`).
    pub(super) fn shared_state(&self) -> &Arc<Mutex<SimState>> {
        &self.state
    }

    /// Stops the server and closes every connection.
    pub fn shutdown(self) {
        // Drop does it.
    }
}

impl Drop for SimServer {
    fn drop(&mut self) {
        // The accept task owns the TCP connections' JoinSet: aborting it aborts them all.
        if let Some(accept) = &self.accept {
            accept.abort();
        }
        self.shutdown.cancel();
    }
}

/// What a connection task shares with the server.
struct Conn {
    state: Arc<Mutex<SimState>>,
    next_session: Arc<AtomicU64>,
    recording: Arc<Mutex<Option<Recording>>>,
}

fn lock_record(r: &Mutex<Option<Recording>>) -> MutexGuard<'_, Option<Recording>> {
    r.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Adds a sent response to the record, if recording.
fn record(conn: &Conn, session: u64, request: &AnyRequestFrame, response: &[u8]) {
    let mut recording = lock_record(&conn.recording);
    let Some(r) = recording.as_mut() else { return };
    if r.capacity == 0 {
        return;
    }
    if r.entries.len() >= r.capacity {
        r.entries.pop_front();
    }
    r.entries.push_back(SimExchange {
        session,
        request: *request,
        response: response.to_vec(),
        sent_at: Instant::now(),
    });
}

/// A panic elsewhere must not make the simulator unusable: the state is plain data.
pub(super) fn lock(state: &Mutex<SimState>) -> MutexGuard<'_, SimState> {
    state
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

async fn accept_loop(listener: TcpListener, conn: Conn) {
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            // Fixed order (replay): reaping is instant and accepts are rare, so neither
            // branch can starve the other.
            biased;
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    tracing::debug!(%peer, "simulator: client connected");
                    let _ = stream.set_nodelay(true);
                    let session = conn.next_session.fetch_add(1, Ordering::Relaxed);
                    let conn = Conn {
                        state: Arc::clone(&conn.state),
                        next_session: Arc::clone(&conn.next_session),
                        recording: Arc::clone(&conn.recording),
                    };
                    connections.spawn(serve(stream, conn, session));
                }
                Err(e) => tracing::warn!(error = %e, "simulator: accept failed"),
            },
            // Reap finished connections so the set does not grow.
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

async fn serve(stream: impl AsyncRead + AsyncWrite, conn_shared: Conn, session: u64) {
    let state = &conn_shared.state;
    let (read, mut write) = tokio::io::split(stream);
    let mut requests = FramedRead::new(read, ServerCodec);
    let mut conn = lock(state).connect();
    while let Some(item) = poll_fn(|cx| Pin::new(&mut requests).poll_next(cx)).await {
        let frame = match item {
            Ok(frame) => frame,
            Err(e) => {
                // No start marker: after a bad length the next frame cannot be found. But a
                // newer client's frame may have another length: it first gets the "too old"
                // empty message the manual says a server always sends (1.3), then the close.
                let too_old = lock(state).too_old_for(requests.read_buffer());
                if let Some(prefix) = too_old {
                    let _ = write.write_all(&prefix.encode()).await;
                }
                tracing::debug!(error = %e, "simulator: closing a connection");
                return;
            }
        };
        let action = lock(state).handle(&mut conn, &frame);
        let bytes: Vec<u8> = match action {
            Action::Respond(response) => response.encode().to_vec(),
            Action::RespondEmpty(prefix) => prefix.encode().to_vec(),
            Action::Skip => continue,
            Action::Delay(delay, response) => {
                tokio::time::sleep(delay).await;
                response.encode().to_vec()
            }
            Action::SendRaw(bytes) => bytes.to_vec(),
            Action::Close => return,
        };
        if write.write_all(&bytes).await.is_err() {
            return;
        }
        record(&conn_shared, session, &frame, &bytes);
    }
}
