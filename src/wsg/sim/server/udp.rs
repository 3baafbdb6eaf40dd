//! UDP: one frame per datagram; a session per peer, forgotten when idle.
//!
//! Where replies go follows the device's "UDP remote port" setting
//! ([`SimConfig::udp_remote_port`](crate::wsg::sim::SimConfig::udp_remote_port)): unset, to the
//! sender's address and port; set, to the sender's IP address at that port, whatever port the
//! request came from (see the WSG field notes in `PROTOCOLS.md`). A session is keyed by where
//! its replies go, so with a remote port every sender on one host is one session.
//!
//! UDP has no connection to close: a session from which nothing came for
//! [`SimConfig::udp_idle_timeout`](crate::wsg::sim::SimConfig::udp_idle_timeout) is forgotten
//! unless a final reply or auto-updates are still due to it. At most
//! [`MAX_UDP_SESSIONS`](crate::wsg::sim::MAX_UDP_SESSIONS) are kept: a new sender beyond that
//! replaces the longest-silent session, so a flood of sender addresses cannot grow memory.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use bytes::BytesMut;
use tokio::net::UdpSocket;
use tokio::sync::{mpsc, oneshot};
use tokio::time::{sleep_until, Instant};

use super::actor::{Event, Inbox, Outbox};
use super::Parts;
use crate::wsg::frame::{self, DEFAULT_MAX_PAYLOAD_LEN};
use crate::wsg::sim::device::{SessionId, SessionKind};
use crate::wsg::sim::MAX_UDP_SESSIONS;

/// How the UDP side is set up (from the [`SimConfig`](crate::wsg::sim::SimConfig)).
#[derive(Clone, Copy, Debug)]
pub(super) struct UdpSettings {
    pub(super) remote_port: Option<u16>,
    pub(super) idle_timeout: Duration,
}

struct Peer {
    session: SessionId,
    expires: Instant,
}

/// Receives datagrams until the server shuts down. The peers are kept ordered (not hashed):
/// they are iterated, and ties (equal expiry times under a paused clock) must break the same
/// way every run.
pub(super) async fn serve_udp(socket: Arc<UdpSocket>, parts: Parts, settings: UdpSettings) {
    let Parts {
        events,
        mut shutdown,
        text: _,
        next_session,
    } = parts;
    let mut peers: BTreeMap<SocketAddr, Peer> = BTreeMap::new();
    let mut buf = vec![0u8; 65536];
    loop {
        let next_expiry = peers.values().map(|p| p.expires).min();
        tokio::select! {
            // A fixed order instead of tokio's random one (runs replay): shutdown and the
            // expiry timer are ready only now and then, so datagrams are not starved, and a
            // flood of datagrams cannot hold off forgetting idle peers.
            biased;
            _ = shutdown.changed() => return,
            _ = sleep_until(next_expiry.unwrap_or_else(Instant::now)), if next_expiry.is_some() => {
                if expire(&mut peers, &events, settings.idle_timeout).await.is_err() {
                    return;
                }
            }
            r = socket.recv_from(&mut buf) => {
                let (n, from) = match r {
                    Ok(r) => r,
                    // E.g. an ICMP "port unreachable" for an earlier reply, reported here.
                    Err(e) => {
                        tracing::debug!(error = %e, "simulator: UDP receive failed");
                        continue;
                    }
                };
                let reply_to = match settings.remote_port {
                    Some(port) => SocketAddr::new(from.ip(), port),
                    None => from,
                };
                let expires = crate::deadline::after(Instant::now(), settings.idle_timeout);
                let session = match peers.get_mut(&reply_to) {
                    Some(peer) => {
                        peer.expires = expires;
                        peer.session
                    }
                    None => {
                        if peers.len() >= MAX_UDP_SESSIONS
                            && evict_longest_silent(&mut peers, &events).await.is_err()
                        {
                            return;
                        }
                        let session = next_session.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let (outbox, inbox) = Outbox::new();
                        tokio::spawn(send_replies(socket.clone(), reply_to, inbox));
                        let kind = SessionKind::Udp;
                        if events.send(Event::Connected { session, kind, outbox }).await.is_err() {
                            return;
                        }
                        tracing::debug!(%from, %reply_to, session, "simulator: UDP session");
                        peers.insert(reply_to, Peer { session, expires });
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
        }
    }
}

/// Asks the actor to forget every peer whose time is up; one still owed a final reply is asked
/// again a little later.
async fn expire(
    peers: &mut BTreeMap<SocketAddr, Peer>,
    events: &mpsc::Sender<Event>,
    idle_timeout: Duration,
) -> Result<(), ()> {
    let now = Instant::now();
    let due: Vec<SocketAddr> = peers
        .iter()
        .filter(|(_, p)| p.expires <= now)
        .map(|(a, _)| *a)
        .collect();
    for addr in due {
        let Some(peer) = peers.get_mut(&addr) else {
            continue;
        };
        let (tx, rx) = oneshot::channel();
        let idle = Event::Idle {
            session: peer.session,
            forgotten: tx,
        };
        events.send(idle).await.map_err(drop)?;
        if rx.await.map_err(drop)? {
            peers.remove(&addr);
        } else {
            peer.expires =
                now + idle_timeout.clamp(Duration::from_millis(10), Duration::from_secs(1));
        }
    }
    Ok(())
}

/// Forgets the session that has been silent longest, whatever it is still owed, to make room
/// for a new sender.
async fn evict_longest_silent(
    peers: &mut BTreeMap<SocketAddr, Peer>,
    events: &mpsc::Sender<Event>,
) -> Result<(), ()> {
    let Some((&addr, _)) = peers.iter().min_by_key(|(_, p)| p.expires) else {
        return Ok(());
    };
    if let Some(peer) = peers.remove(&addr) {
        tracing::warn!(%addr, "simulator: {MAX_UDP_SESSIONS} UDP sessions, the longest-silent one forgotten");
        events
            .send(Event::Disconnected {
                session: peer.session,
            })
            .await
            .map_err(drop)?;
    }
    Ok(())
}

/// Sends one session's replies until the actor forgets it.
async fn send_replies(socket: Arc<UdpSocket>, to: SocketAddr, mut inbox: Inbox) {
    while let Some(b) = inbox.recv().await {
        if let Err(e) = socket.send_to(&b, to).await {
            tracing::warn!(%to, error = %e, "simulator: UDP reply not sent");
        }
    }
}
