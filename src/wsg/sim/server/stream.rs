//! One byte-stream connection (TCP, serial, any `AsyncRead + AsyncWrite`): forwards decoded
//! frames to the actor and writes the replies it queues.
//!
//! Three rules keep every reply (issue #10):
//! - **Backpressure, not loss**: while [`HIGH_WATER`](super::actor::HIGH_WATER) replies wait
//!   for a client that does not read, its requests are not read either (TCP then pushes back
//!   on the client).
//! - **Half-close**: when the client's byte stream ends, the session ends (manual 1.4.2), but
//!   everything answered up to then, and the E_CMD_ABORTED of a move the end aborts, is written
//!   before the simulator closes its side.
//! - **Received means counted**: a failed write (the client is gone, e.g. reset) does not end
//!   the session at once; every frame the client sent before it went is read and handled first,
//!   so a 0x07 sent before closing always counts and never turns the close into a FAST STOP.
//!
//! A partial frame that gets no new byte for the client's
//! [`DEFAULT_PARTIAL_FRAME_TIMEOUT`](crate::wsg::client::DEFAULT_PARTIAL_FRAME_TIMEOUT) is
//! dropped as noise and the frames behind it are decoded (the client is stricter: it times a
//! frame from its first byte): a corrupted length field must not swallow the requests that
//! follow.

use std::io;

use bytes::{Buf, BytesMut};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::sync::{mpsc, watch};
use tokio::time::{sleep_until, Instant};

use super::actor::{self, Event};
use crate::wsg::client::DEFAULT_PARTIAL_FRAME_TIMEOUT;
use crate::wsg::frame::{self, DEFAULT_MAX_PAYLOAD_LEN};
use crate::wsg::sim::device::{SessionId, SessionKind};

/// Bytes asked of one read.
const READ_CHUNK: usize = 8192;

/// Serves one byte stream as session `session` until it ends, the actor lets it go (unplug) or
/// the server shuts down.
pub(super) async fn serve_stream(
    io: impl AsyncRead + AsyncWrite + Send + 'static,
    session: SessionId,
    kind: SessionKind,
    events: mpsc::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
) {
    let Some(mut inbox) = actor::connect(&events, session, kind).await else {
        return;
    };
    let (mut rd, mut wr) = tokio::io::split(io);
    // What was read and not decoded yet: at most one partial frame plus one read, since every
    // complete frame is taken out before the next read (and `frame::decode` drops garbage).
    let mut received = BytesMut::with_capacity(READ_CHUNK);
    // Until the client's stream ends (then the actor has been told).
    let mut reading = true;
    // Until a write fails; after that replies are discarded while the rest is read.
    let mut writable = true;
    // Bytes of the partial frame held, and since when that count is unchanged.
    let mut partial = (0usize, Instant::now());
    loop {
        let may_read = reading && !(writable && inbox.full());
        if may_read {
            // Frames already read go first, one at a time, so backpressure applies to each.
            if let Some(decoded) = frame::decode(&mut received, DEFAULT_MAX_PAYLOAD_LEN) {
                if events
                    .send(Event::Received { session, decoded })
                    .await
                    .is_err()
                {
                    return;
                }
                continue;
            }
        }
        if received.len() != partial.0 {
            partial = (received.len(), Instant::now());
        }
        let stall =
            (may_read && !received.is_empty()).then(|| partial.1 + DEFAULT_PARTIAL_FRAME_TIMEOUT);
        if received.capacity() - received.len() < READ_CHUNK / 2 {
            received.reserve(READ_CHUNK);
        }
        tokio::select! {
            // Replies first: a client flooding requests still gets its answers.
            biased;
            bytes = inbox.recv() => match bytes {
                Some(b) if writable => {
                    if let Err(e) = write(&mut wr, &b).await {
                        tracing::debug!(session, error = %e,
                            "simulator: write failed; reading what the client sent before it went");
                        writable = false;
                    }
                }
                Some(_) => tracing::debug!(session, "simulator: client gone; reply not sent"),
                // The actor let the session go: after the disconnect, or an unplug.
                None => break,
            },
            // `read_buf` is cancel safe: nothing is lost when another branch wins.
            r = rd.read_buf(&mut received), if may_read => {
                let ended = match r {
                    Ok(0) => true,
                    Ok(_) => false,
                    Err(e) => {
                        tracing::debug!(session, error = %e, "simulator: read failed");
                        true
                    }
                };
                if ended {
                    // The frames read before the end still count (a 0x07 among them).
                    while let Some(decoded) = frame::decode_eof(&mut received, DEFAULT_MAX_PAYLOAD_LEN) {
                        if events.send(Event::Received { session, decoded }).await.is_err() {
                            return;
                        }
                    }
                    reading = false;
                    if events.send(Event::Disconnected { session }).await.is_err() {
                        return;
                    }
                }
            }
            _ = sleep_until(stall.unwrap_or_else(Instant::now)), if stall.is_some() => {
                tracing::warn!(session, bytes = received.len(),
                    "simulator: partial frame stalled; dropped as noise");
                // Skip the stalled header; the frames behind it are decoded as usual.
                received.advance(1);
            }
            _ = shutdown.changed() => break,
        }
    }
    if reading {
        let _ = events.send(Event::Disconnected { session }).await;
    }
    let _ = wr.shutdown().await;
}

async fn write(wr: &mut (impl AsyncWrite + Unpin), bytes: &[u8]) -> io::Result<()> {
    wr.write_all(bytes).await?;
    wr.flush().await
}
