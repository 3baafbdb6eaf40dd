//! One in-memory datagram peer: UDP without the operating system, for deterministic tests
//! (the explorer, issue 20). Each message is one datagram, so one frame, as on UDP (manual
//! 1.2); the peer is one session, from its first datagram until its channel closes.
//!
//! Unlike `udp.rs` there is no idle timeout and no session limit: the peer is the test's own
//! channel, and closing it is its "connection" ending.

use bytes::{Bytes, BytesMut};
use tokio::sync::{mpsc, watch};

use super::actor::{self, Event};
use crate::wsg::frame::{self, DEFAULT_MAX_PAYLOAD_LEN};
use crate::wsg::sim::device::{SessionId, SessionKind};

/// Serves datagrams from `incoming` as session `session`, sending its replies to `outgoing`,
/// until `incoming` closes (then what is still queued is sent), the actor lets the session go,
/// or the server shuts down.
pub(super) async fn serve_datagrams(
    mut incoming: mpsc::UnboundedReceiver<Bytes>,
    outgoing: mpsc::UnboundedSender<Bytes>,
    session: SessionId,
    events: mpsc::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
) {
    let Some(mut inbox) = actor::connect(&events, session, SessionKind::Udp).await else {
        return;
    };
    let mut reading = true;
    loop {
        tokio::select! {
            // Deterministic order (a seeded run must replay exactly, so no random branch
            // choice): shutdown is rarely ready; replies before requests so that a peer
            // flooding requests still gets its answers (the requests are bounded by the peer,
            // the replies by the requests, so neither branch starves the other for good).
            biased;
            _ = shutdown.changed() => return,
            reply = inbox.recv() => match reply {
                // A peer that went away loses the reply, as a UDP datagram would be.
                Some(b) => { let _ = outgoing.send(b); }
                // The actor let the session go (a restart, or after the disconnect).
                None => return,
            },
            datagram = incoming.recv(), if reading => match datagram {
                Some(d) => {
                    let mut b = BytesMut::from(&d[..]);
                    while let Some(decoded) = frame::decode_eof(&mut b, DEFAULT_MAX_PAYLOAD_LEN) {
                        if events.send(Event::Received { session, decoded }).await.is_err() {
                            return;
                        }
                    }
                }
                None => {
                    reading = false;
                    if events.send(Event::Disconnected { session }).await.is_err() {
                        return;
                    }
                }
            },
        }
    }
}
