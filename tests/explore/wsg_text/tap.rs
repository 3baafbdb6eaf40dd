//! What the text client itself wrote and read, line by line, with when (issue 29): a tap between
//! the client and the fault layer. The simulator's record says what the device got and sent; the
//! tap says what the client put on the wire and what reached its reader, faults included, so the
//! oracle can judge a `Timeout` (rule 7: was a reply of its name read in time?), a lost
//! connection (rule 6: was the device answering?) and a stop (rule 9: was it written at once?).
//!
//! A tap can also be cut ([`Cut`]): the client's reader then sees the end of the stream, as when
//! a cable is pulled on the client's side (the quiet phase's deliberate loss of a reconnecting
//! client, `restore.rs`).
//!
//! A line is the bytes up to an LF, as the client's line codec splits them (`griplink::codec`,
//! which the text client uses); its time is when the byte with the LF went through.

use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Waker};

use tokio::io::{AsyncRead, AsyncWrite, DuplexStream, ReadBuf};
use tokio::time::Instant;

/// One line the client wrote or read.
#[derive(Debug, Clone)]
pub struct Line {
    /// When its LF went through.
    pub at: Instant,
    /// Its place among every line of the connection, both directions (several pass at one
    /// simulated instant: a reply read, then the command it let go written).
    pub seq: u64,
    /// The text, without its LF (a trailing CR removed).
    pub text: String,
}

/// Lines one direction carried, and the bytes of the line not yet ended.
#[derive(Debug, Default)]
pub struct Lines {
    /// Every complete line.
    pub lines: Vec<Line>,
    partial: Vec<u8>,
}

impl Lines {
    fn push(&mut self, bytes: &[u8], seq: &mut u64) {
        for &b in bytes {
            if b == b'\n' {
                let mut line = std::mem::take(&mut self.partial);
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                *seq += 1;
                self.lines.push(Line {
                    at: Instant::now(),
                    seq: *seq,
                    text: String::from_utf8_lossy(&line).into_owned(),
                });
            } else {
                self.partial.push(b);
            }
        }
    }
}

/// What a connection's client wrote and read.
#[derive(Debug, Default)]
pub struct TapLog {
    /// Command lines the client wrote.
    pub written: Lines,
    /// Reply lines the client's reader got (after the faults).
    pub read: Lines,
    seq: u64,
}

/// A shared [`TapLog`].
pub type SharedTap = Arc<Mutex<TapLog>>;

/// Cuts a [`Tap`]: from then on its reader sees the end of the stream and its writes fail.
#[derive(Debug, Default)]
pub struct Cut {
    cut: AtomicBool,
    /// The reader waiting for bytes, woken by the cut.
    reader: Mutex<Option<Waker>>,
}

impl Cut {
    /// Cuts the link now.
    pub fn cut(&self) {
        self.cut.store(true, Ordering::SeqCst);
        if let Some(w) = self.reader.lock().unwrap().take() {
            w.wake();
        }
    }

    fn is_cut(&self) -> bool {
        self.cut.load(Ordering::SeqCst)
    }
}

/// The client's end of a link, logging what passes.
pub struct Tap {
    io: DuplexStream,
    log: SharedTap,
    cut: Arc<Cut>,
}

impl Tap {
    /// Wraps the client's end `io`; the log is shared with the oracle, the cut with the run.
    pub fn new(io: DuplexStream) -> (Tap, SharedTap, Arc<Cut>) {
        let log = SharedTap::default();
        let cut = Arc::new(Cut::default());
        (
            Tap {
                io,
                log: log.clone(),
                cut: cut.clone(),
            },
            log,
            cut,
        )
    }
}

impl AsyncRead for Tap {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        if self.cut.is_cut() {
            return Poll::Ready(Ok(())); // The end of the stream.
        }
        *self.cut.reader.lock().unwrap() = Some(cx.waker().clone());
        let before = buf.filled().len();
        let r = Pin::new(&mut self.io).poll_read(cx, buf);
        if let Poll::Ready(Ok(())) = r {
            let new = &buf.filled()[before..];
            let log = &mut *self.log.lock().unwrap();
            log.read.push(new, &mut log.seq);
        }
        r
    }
}

impl AsyncWrite for Tap {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        if self.cut.is_cut() {
            return Poll::Ready(Err(io::ErrorKind::BrokenPipe.into()));
        }
        let r = Pin::new(&mut self.io).poll_write(cx, buf);
        if let Poll::Ready(Ok(n)) = r {
            let log = &mut *self.log.lock().unwrap();
            log.written.push(&buf[..n], &mut log.seq);
        }
        r
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_shutdown(cx)
    }
}
