//! Text mode (GCL) on a byte stream: one connection's reader and writer, and the actor's side
//! (`impl Actor`): lines in, GCL lines out, from the same device model as the binary protocol
//! (`crate::wsg::sim::text` holds what each command does).
//!
//! The writer keeps the rules public GCL clients need (shared note §6.2, §6.3): replies end in
//! LF only, each line is written on its own (with TCP_NODELAY, one segment each), and after an
//! `ACK` nothing more is written for [`SimConfig::text_ack_gap`](crate::wsg::sim::SimConfig)
//! so that a client reading one line per `recv` gets `ACK` and `FIN` apart. Backpressure as
//! for binary connections: a client that does not read stops being read.

use std::time::Duration;

use bytes::Bytes;
use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio::sync::{mpsc, watch};
use tokio::time::{sleep_until, Instant};
use tokio_util::codec::FramedRead;

use super::actor::{Actor, Event, Outbox};
use super::record::SimEvent;
use crate::line::codec::{Line, LineCodec};
use crate::wsg::sim::device::{Out, SessionId, SessionKind};
use crate::wsg::sim::text::{Emit, TextSession, MAX_LINE_LEN};

fn line_bytes(line: String) -> Bytes {
    let mut bytes = line.into_bytes();
    bytes.push(b'\n');
    Bytes::from(bytes)
}

impl Actor {
    /// A text connection opened: a TCP session of the device, with its own GCL state.
    pub(super) fn on_text_connected(&mut self, session: SessionId, outbox: Outbox) {
        self.sessions.insert(session, outbox);
        self.device.connect(session, SessionKind::Tcp);
        self.record(
            session,
            SimEvent::Connected {
                kind: SessionKind::Tcp,
            },
        );
        self.text
            .insert(session, TextSession::new(self.device.config()));
    }

    /// One command line of a text connection (`None`: a line too long to read).
    pub(super) fn on_text_line(&mut self, session: SessionId, line: Option<String>) {
        let (now, wall) = (self.clock.now(), self.wall());
        if !self.text.contains_key(&session) {
            return;
        }
        // What finished before this line goes out first, recorded with the fingers as they
        // were then: a `FIN` queued after the command started a new motion would be recorded
        // as sent while the fingers moved.
        let finished = self.device.advance(now);
        self.dispatch(finished);
        self.record(session, SimEvent::TextRequest { line: line.clone() });
        let Some(text) = self.text.get_mut(&session) else {
            return;
        };
        let emits = text.handle(&mut self.device, now, wall, session, line.as_deref());
        for emit in emits {
            match emit {
                Emit::Line(line) => self.send_text(session, line),
                Emit::Out(out) => self.dispatch(vec![out]),
            }
        }
    }

    fn send_text(&self, session: SessionId, line: String) {
        if let Some(outbox) = self.sessions.get(&session) {
            self.record_text(session, &line);
            if !outbox.send(line_bytes(line)) {
                tracing::debug!(session, "simulator: connection closed; line not sent");
            }
        }
    }

    /// Records a line queued for a text session, with whether the fingers were moving then.
    fn record_text(&self, session: SessionId, line: &str) {
        let moving = self.device.fingers_moving();
        let line = line.to_owned();
        self.record(session, SimEvent::TextReply { line, moving });
    }

    /// A binary reply for a text session, written as GCL; false if `out` is not for one.
    pub(super) fn dispatch_text(&self, out: &Out, outbox: &Outbox) -> bool {
        let Some(text) = self.text.get(&out.session) else {
            return false;
        };
        match text.translate(&out.reply) {
            Some(line) => {
                self.record_text(out.session, &line);
                outbox.send(line_bytes(line));
            }
            None => tracing::debug!(
                id = out.reply.id,
                "simulator: binary reply with no GCL form, not sent"
            ),
        }
        true
    }
}

/// Serves one text connection as session `session` until it ends, the actor lets it go or the
/// server shuts down.
pub(super) async fn serve_text(
    io: impl AsyncRead + AsyncWrite + Send + 'static,
    session: SessionId,
    events: mpsc::Sender<Event>,
    mut shutdown: watch::Receiver<bool>,
    ack_gap: Duration,
) {
    let (outbox, mut inbox) = Outbox::new();
    let connected = Event::TextConnected { session, outbox };
    if events.send(connected).await.is_err() {
        return;
    }
    let (rd, mut wr) = tokio::io::split(io);
    // `split`'s halves are `Unpin` whatever `io` is.
    // A line cut off by the end of the stream is not a command (its LF ends a command, §2):
    // `MOVE(10` of a `MOVE(100)` whose connection broke must not move the fingers.
    let mut reader = FramedRead::new(rd, LineCodec::new(MAX_LINE_LEN).reject_unterminated());
    let mut reading = true;
    let mut writable = true;
    // After an `ACK`: nothing is written before this.
    let mut quiet_until: Option<Instant> = None;
    loop {
        let may_read = reading && !(writable && inbox.full());
        tokio::select! {
            biased;
            () = sleep_until(quiet_until.unwrap_or_else(Instant::now)), if quiet_until.is_some() => {
                quiet_until = None;
            }
            line = inbox.recv(), if quiet_until.is_none() => match line {
                Some(b) if writable => {
                    let ack = b.starts_with(b"ACK ");
                    if let Err(e) = write(&mut wr, &b).await {
                        tracing::debug!(session, error = %e, "simulator: write failed");
                        writable = false;
                    } else if ack && !ack_gap.is_zero() {
                        quiet_until = Instant::now().checked_add(ack_gap);
                    }
                }
                Some(_) => {}
                None => break,
            },
            line = next(&mut reader), if may_read => {
                let line = match line {
                    Some(Ok(Line::Text(text))) => Some(text),
                    Some(Ok(Line::Discarded(why))) => {
                        tracing::debug!(session, %why, "simulator: text line discarded");
                        None
                    }
                    Some(Err(_)) | None => {
                        reading = false;
                        if events.send(Event::Disconnected { session }).await.is_err() {
                            return;
                        }
                        continue;
                    }
                };
                if events.send(Event::Line { session, line }).await.is_err() {
                    return;
                }
            }
            _ = shutdown.changed() => break,
        }
    }
    if reading {
        let _ = events.send(Event::Disconnected { session }).await;
    }
    let _ = wr.shutdown().await;
}

async fn next<R: AsyncRead + Unpin>(
    reader: &mut FramedRead<R, LineCodec>,
) -> Option<std::io::Result<Line>> {
    std::future::poll_fn(|cx| std::pin::Pin::new(&mut *reader).poll_next(cx)).await
}

async fn write(wr: &mut (impl AsyncWrite + Unpin), bytes: &[u8]) -> std::io::Result<()> {
    wr.write_all(bytes).await?;
    wr.flush().await
}
