//! What the client's end of a stream link saw (TCP, serial): when its reads first ended (end of
//! stream or an error) or a write failed, the evidence that the link ended (promise 6: a lost
//! connection only for cause), and every byte the client wrote, when (promise 9: a stop is sent
//! at once). A thin wrapper over the client's end of the pipe; it draws nothing, so a seed keeps
//! its path.

use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Instant;

/// What one connection's client end saw.
#[derive(Clone, Debug)]
pub struct TapLog {
    /// When the connection was opened.
    pub opened: Instant,
    /// When the link first ended for the client: a read returned end of stream or an error,
    /// or a write failed.
    pub ended: Option<Instant>,
    /// Every write the client made: when, and the bytes the link took.
    pub writes: Vec<(Instant, Vec<u8>)>,
}

impl TapLog {
    /// The log of a connection opened now.
    pub fn new() -> SharedTap {
        Arc::new(Mutex::new(TapLog {
            opened: Instant::now(),
            ended: None,
            writes: Vec::new(),
        }))
    }
}

/// A [`TapLog`] shared with its wrapper.
pub type SharedTap = Arc<Mutex<TapLog>>;

/// The client's end of a link, logging into a [`TapLog`].
pub struct Tap<S> {
    inner: S,
    log: SharedTap,
}

impl<S> Tap<S> {
    /// Wraps `inner`.
    pub fn new(inner: S, log: SharedTap) -> Self {
        Tap { inner, log }
    }

    fn ended(&self) {
        let mut log = self.log.lock().unwrap_or_else(|e| e.into_inner());
        log.ended.get_or_insert_with(Instant::now);
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for Tap<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.inner).poll_read(cx, buf);
        match &r {
            Poll::Ready(Ok(())) if buf.filled().len() == before && buf.remaining() > 0 => {
                self.ended()
            }
            Poll::Ready(Err(_)) => self.ended(),
            _ => {}
        }
        r
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for Tap<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write(cx, data);
        match &r {
            Poll::Ready(Ok(n)) => {
                let mut log = self.log.lock().unwrap_or_else(|e| e.into_inner());
                log.writes.push((Instant::now(), data[..*n].to_vec()));
            }
            Poll::Ready(Err(_)) => self.ended(),
            Poll::Pending => {}
        }
        r
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

/// The frames in the bytes a client wrote, each with when its last byte was written (the
/// client writes whole, well-formed frames; a link that ended may have cut the last one).
pub fn written_frames(log: &TapLog) -> Vec<(Instant, gripper::wsg::Frame)> {
    let mut buf = bytes::BytesMut::new();
    let mut out = Vec::new();
    for (at, bytes) in &log.writes {
        buf.extend_from_slice(bytes);
        while let Some(decoded) =
            gripper::wsg::frame::decode(&mut buf, gripper::wsg::frame::DEFAULT_MAX_PAYLOAD_LEN)
        {
            if let gripper::wsg::frame::Decoded::Frame(f) = decoded {
                out.push((*at, f));
            }
        }
    }
    out
}
