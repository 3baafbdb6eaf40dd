//! The simulator's TCP server: accepts connections, feeds request frames to the shared
//! [`SimState`], carries out its [`Action`]s. Each connection answers its requests in order.

use std::future::poll_fn;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};

use futures_core::Stream;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream, ToSocketAddrs};
use tokio::task::{JoinHandle, JoinSet};
use tokio_util::codec::FramedRead;

use super::state::{Action, Fault, SimConfig, SimState};
use crate::smartgrasp::codec::ServerCodec;
use crate::smartgrasp::pose::Pose;
use crate::smartgrasp::types::RobotSystem;

/// A running simulated Smart Grasping server. Dropping it (or [`shutdown`](Self::shutdown))
/// stops the server and closes every connection.
#[derive(Debug)]
pub struct SimServer {
    local_addr: SocketAddr,
    state: Arc<Mutex<SimState>>,
    accept: JoinHandle<()>,
}

impl SimServer {
    /// Binds `addr` (port 0 picks a free port) and serves in the background. Cancel-safe: a
    /// dropped future has bound nothing or drops the listener it bound.
    pub async fn bind(addr: impl ToSocketAddrs, config: SimConfig) -> std::io::Result<SimServer> {
        let listener = TcpListener::bind(addr).await?;
        let local_addr = listener.local_addr()?;
        let state = Arc::new(Mutex::new(SimState::new(config)));
        let accept = tokio::spawn(accept_loop(listener, Arc::clone(&state)));
        tracing::info!(%local_addr, "smartgrasp simulator listening");
        Ok(SimServer {
            local_addr,
            state,
            accept,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Queues a fault; each replaces one upcoming response (on whichever connection answers
    /// next), in order.
    pub fn inject(&self, fault: Fault) {
        self.with_state(|s| s.inject(fault));
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
        // The accept task owns the connections' JoinSet: aborting it aborts them all.
        self.accept.abort();
    }
}

/// A panic elsewhere must not make the simulator unusable: the state is plain data.
pub(super) fn lock(state: &Mutex<SimState>) -> MutexGuard<'_, SimState> {
    state
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

async fn accept_loop(listener: TcpListener, state: Arc<Mutex<SimState>>) {
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            // Fixed order (replay): reaping is instant and accepts are rare, so neither
            // branch can starve the other.
            biased;
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    tracing::debug!(%peer, "simulator: client connected");
                    connections.spawn(serve(stream, Arc::clone(&state)));
                }
                Err(e) => tracing::warn!(error = %e, "simulator: accept failed"),
            },
            // Reap finished connections so the set does not grow.
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

async fn serve(stream: TcpStream, state: Arc<Mutex<SimState>>) {
    let _ = stream.set_nodelay(true);
    let (read, mut write) = stream.into_split();
    let mut requests = FramedRead::new(read, ServerCodec);
    let mut conn = lock(&state).connect();
    while let Some(item) = poll_fn(|cx| Pin::new(&mut requests).poll_next(cx)).await {
        let frame = match item {
            Ok(frame) => frame,
            Err(e) => {
                // No start marker: after a bad length the next frame cannot be found. But a
                // newer client's frame may have another length: it first gets the "too old"
                // empty message the manual says a server always sends (1.3), then the close.
                let too_old = lock(&state).too_old_for(requests.read_buffer());
                if let Some(prefix) = too_old {
                    let _ = write.write_all(&prefix.encode()).await;
                }
                tracing::debug!(error = %e, "simulator: closing a connection");
                return;
            }
        };
        let action = lock(&state).handle(&mut conn, &frame);
        let written = match action {
            Action::Respond(response) => write.write_all(&response.encode()).await,
            Action::RespondEmpty(prefix) => write.write_all(&prefix.encode()).await,
            Action::Skip => Ok(()),
            Action::Delay(delay, response) => {
                tokio::time::sleep(delay).await;
                write.write_all(&response.encode()).await
            }
            Action::SendRaw(bytes) => write.write_all(&bytes).await,
            Action::Close => return,
        };
        if written.is_err() {
            return;
        }
    }
}
