//! The background task that owns the connection: sends requests in arrival order, reads
//! responses, pairs them (see [`pairing`](super::pairing)) and answers each waiting call. A call
//! whose caller timed out or went away keeps its place; its reply is consumed and discarded.
//! When the connection breaks, every waiting and queued call gets the reason, and so does every
//! later call (through `closed`).

use std::collections::VecDeque;
use std::future::poll_fn;
use std::sync::{Arc, OnceLock};

use futures_core::Stream;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;
use tokio::sync::{mpsc, oneshot};
use tokio_util::codec::FramedRead;

use super::pairing::{check_header, Pairing};
use crate::smartgrasp::codec::ClientCodec;
use crate::smartgrasp::error::{Error, Malformed, Result};
use crate::smartgrasp::frame::{RequestFrame, ResponseFrame};
use crate::smartgrasp::types::MessageType;

/// Requests sent and not yet answered, at most. Bounds the waiting queue when a server stops
/// answering; further calls wait in the channel and run into their timeouts.
pub(crate) const MAX_IN_FLIGHT: usize = 16;

/// One call from a handle to the task.
pub(crate) struct Call {
    pub frame: RequestFrame,
    pub reply: oneshot::Sender<Result<ResponseFrame>>,
}

struct Waiting {
    message_type: MessageType,
    reply: oneshot::Sender<Result<ResponseFrame>>,
}

/// Runs the connection until it breaks or every handle is dropped.
pub(crate) async fn run(
    stream: TcpStream,
    mut calls: mpsc::Receiver<Call>,
    closed: Arc<OnceLock<Error>>,
) {
    let (read, mut write) = stream.into_split();
    let mut responses = FramedRead::new(read, ClientCodec);
    let mut waiting: VecDeque<Waiting> = VecDeque::with_capacity(MAX_IN_FLIGHT);
    let mut pairing = Pairing::default();

    let reason = loop {
        tokio::select! {
            // Responses first: each frees a slot.
            biased;
            item = poll_fn(|cx| std::pin::Pin::new(&mut responses).poll_next(cx)) => match item {
                None => break Error::ConnectionClosed {
                    reason: "the server closed the connection".into(),
                },
                Some(Err(e)) => break e,
                Some(Ok(frame)) => {
                    if let Err(e) = on_response(&mut pairing, &mut waiting, &frame) {
                        break e;
                    }
                }
            },
            call = calls.recv(), if waiting.len() < MAX_IN_FLIGHT => match call {
                // Every handle is gone, so no call can be waiting: nothing left to do.
                None => return,
                Some(call) => {
                    if call.reply.is_closed() {
                        // Its caller gave up before it was sent: sending it would only create a
                        // reply to discard.
                        continue;
                    }
                    let message_type = call.frame.header.message_type;
                    if let Err(e) = write.write_all(&call.frame.encode()).await {
                        let e = Error::from(e);
                        let _ = call.reply.send(Err(e.clone()));
                        break e;
                    }
                    waiting.push_back(Waiting { message_type, reply: call.reply });
                }
            },
        }
    };

    tracing::warn!(error = %reason, "smartgrasp connection broken");
    let _ = closed.set(reason.clone());
    calls.close();
    for w in waiting.drain(..) {
        let _ = w.reply.send(Err(waiting_error(&reason)));
    }
    while let Ok(call) = calls.try_recv() {
        let _ = call.reply.send(Err(closed_error(Some(&reason))));
    }
}

/// What a call that was sent and still waits gets when the connection breaks. A header error
/// was already given to the call whose response carried it; the others only lost the connection.
fn waiting_error(reason: &Error) -> Error {
    match reason {
        Error::Malformed(
            Malformed::MessageType { .. }
            | Malformed::CommunicationType(_)
            | Malformed::Version { .. }
            | Malformed::Unsolicited { .. },
        ) => closed_error(Some(reason)),
        // Stream-level reasons (I/O, bad length, too old, lost responses) concern every call.
        other => other.clone(),
    }
}

/// What a call gets on a connection that is already gone (or never got to send its request).
pub(crate) fn closed_error(reason: Option<&Error>) -> Error {
    match reason {
        Some(Error::ConnectionClosed { reason }) => Error::ConnectionClosed {
            reason: Arc::clone(reason),
        },
        // Still the answer to every later call, and typed so a program can tell the user.
        Some(e @ Error::ServerTooOld { .. }) => e.clone(),
        Some(reason) => Error::ConnectionClosed {
            reason: reason.to_string().into(),
        },
        None => Error::ConnectionClosed {
            reason: "the connection task has ended".into(),
        },
    }
}

/// Pairs one response; `Err` breaks the connection (the paired call, if any, gets the error too).
fn on_response(
    pairing: &mut Pairing,
    waiting: &mut VecDeque<Waiting>,
    frame: &ResponseFrame,
) -> Result<()> {
    let received = frame.header.response_counter;
    let lost = pairing.counter(received, waiting.len())?;
    for i in 0..lost.count {
        if let Some(w) = waiting.pop_front() {
            let expected = lost.first_expected.wrapping_add(i as u8);
            tracing::warn!(expected, received, request = %w.message_type, "response lost");
            let _ = w
                .reply
                .send(Err(Error::ResponseLost { expected, received }));
        }
    }
    let Some(w) = waiting.pop_front() else {
        // `counter` guarantees one is left; treat it as unsolicited all the same.
        return Err(Malformed::Unsolicited { counter: received }.into());
    };
    if let Err(e) = check_header(w.message_type, frame) {
        let e = Error::from(e);
        let _ = w.reply.send(Err(e.clone()));
        return Err(e);
    }
    if w.reply.send(Ok(*frame)).is_err() {
        tracing::debug!(request = %w.message_type, counter = received, "late reply discarded");
    }
    Ok(())
}
