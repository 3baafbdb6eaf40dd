//! The simulator's monitor page: `GET /monitor/latest_result` over plain HTTP/1.1 answers the
//! scene picture ([`scene_svg`]), as the real kit answers its latest detection result at that path
//! (PROTOCOLS.md, seed 002).
//!
//! A deliberately small responder: one request per connection (`Connection: close`), a request
//! head of at most [`MAX_REQUEST_BYTES`] read within [`REQUEST_TIMEOUT`], `GET` and `HEAD` only;
//! any other path is 404, any other method 405, a head too large 431, one that does not parse 400.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, Weak};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, ToSocketAddrs};
use tokio::task::{JoinHandle, JoinSet};

use super::scene_svg::scene_svg;
use super::server::{lock, SimServer};
use super::state::SimState;

/// The path the kit serves its latest detection result at.
pub const MONITOR_PATH: &str = "/monitor/latest_result";

/// The longest request head read (request line and headers); a body is never read.
pub const MAX_REQUEST_BYTES: usize = 8 * 1024;

/// How long a client may take to send its request head, and the answer to be written.
pub const REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

/// A running monitor page of a [`SimServer`]. Dropping it stops it; it also answers 503 once the
/// simulator itself is gone.
#[derive(Debug)]
pub struct MonitorServer {
    local_addr: SocketAddr,
    accept: JoinHandle<()>,
}

impl MonitorServer {
    /// The bound address; the picture is at `http://<local_addr>/monitor/latest_result`.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Stops serving.
    pub fn shutdown(self) {
        // Drop does it.
    }
}

impl Drop for MonitorServer {
    fn drop(&mut self) {
        // The accept task owns the connections' JoinSet: aborting it aborts them all.
        self.accept.abort();
    }
}

impl SimServer {
    /// Serves the scene picture at [`MONITOR_PATH`] over HTTP/1.1 on `addr` (port 0 picks a free
    /// port), as SVG (`image/svg+xml`), until the returned [`MonitorServer`] is dropped.
    pub async fn serve_monitor(&self, addr: impl ToSocketAddrs) -> std::io::Result<MonitorServer> {
        let listener = TcpListener::bind(addr).await?;
        let local_addr = listener.local_addr()?;
        let state = Arc::downgrade(self.shared_state());
        let accept = tokio::spawn(accept_loop(listener, state));
        tracing::info!(%local_addr, "smartgrasp simulator monitor listening");
        Ok(MonitorServer { local_addr, accept })
    }
}

async fn accept_loop(listener: TcpListener, state: Weak<Mutex<SimState>>) {
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            // Fixed order (replay): reaping is instant and accepts are rare, so neither
            // branch can starve the other.
            biased;
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => {
                    connections.spawn(serve(stream, state.clone()));
                }
                Err(e) => tracing::warn!(error = %e, "simulator monitor: accept failed"),
            },
            // Reap finished connections so the set does not grow.
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

/// What the responder answers.
#[derive(Debug, PartialEq, Eq)]
struct Answer {
    status: &'static str,
    content_type: &'static str,
    body: String,
    /// HEAD: the headers of the answer, without its body.
    head_only: bool,
}

impl Answer {
    fn text(status: &'static str, body: &str) -> Answer {
        Answer {
            status,
            content_type: "text/plain; charset=utf-8",
            body: format!("{body}\n"),
            head_only: false,
        }
    }
}

async fn serve(mut stream: TcpStream, state: Weak<Mutex<SimState>>) {
    let answer = match tokio::time::timeout(REQUEST_TIMEOUT, read_head(&mut stream)).await {
        Ok(Ok(Some(head))) => respond(&head, || {
            // Render from a copy, so the protocol server never waits on the drawing.
            let state = state.upgrade()?;
            let snapshot = lock(&state).clone();
            Some(scene_svg(&snapshot))
        }),
        Ok(Ok(None)) => Answer::text("431 Request Header Fields Too Large", "request too large"),
        // The client went away, or never finished its request: nothing to answer.
        Ok(Err(_)) | Err(_) => return,
    };
    let mut bytes = format!(
        "HTTP/1.1 {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        answer.status,
        answer.content_type,
        answer.body.len()
    )
    .into_bytes();
    if !answer.head_only {
        bytes.extend_from_slice(answer.body.as_bytes());
    }
    let _ = tokio::time::timeout(REQUEST_TIMEOUT, async {
        stream.write_all(&bytes).await?;
        stream.shutdown().await
    })
    .await;
}

/// Reads up to the blank line ending the request head: `Ok(None)` when it does not fit in
/// [`MAX_REQUEST_BYTES`].
async fn read_head(stream: &mut TcpStream) -> std::io::Result<Option<Vec<u8>>> {
    let mut head = Vec::with_capacity(512);
    let mut chunk = [0u8; 1024];
    loop {
        if let Some(end) = find(&head, b"\r\n\r\n").or_else(|| find(&head, b"\n\n")) {
            head.truncate(end);
            return Ok(Some(head));
        }
        if head.len() >= MAX_REQUEST_BYTES {
            return Ok(None);
        }
        let n = stream.read(&mut chunk).await?;
        if n == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        head.extend_from_slice(&chunk[..n]);
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The answer to a request head; `picture` draws the scene (`None`: the simulator is gone).
fn respond(head: &[u8], picture: impl FnOnce() -> Option<String>) -> Answer {
    let Some(request_line) = std::str::from_utf8(head)
        .ok()
        .and_then(|h| h.lines().next())
    else {
        return Answer::text("400 Bad Request", "bad request");
    };
    let mut words = request_line.split_whitespace();
    let (Some(method), Some(target), Some(version), None) =
        (words.next(), words.next(), words.next(), words.next())
    else {
        return Answer::text("400 Bad Request", "bad request line");
    };
    if !version.starts_with("HTTP/1.") {
        return Answer::text("505 HTTP Version Not Supported", "HTTP/1.x only");
    }
    let path = target.split(['?', '#']).next().unwrap_or(target);
    if path != MONITOR_PATH {
        return Answer::text("404 Not Found", "not found");
    }
    let head_only = match method {
        "GET" => false,
        "HEAD" => true,
        _ => return Answer::text("405 Method Not Allowed", "GET or HEAD only"),
    };
    match picture() {
        Some(svg) => Answer {
            status: "200 OK",
            content_type: "image/svg+xml",
            body: svg,
            head_only,
        },
        None => Answer::text("503 Service Unavailable", "the simulator has stopped"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn picture() -> Option<String> {
        Some("<svg/>".to_owned())
    }

    #[test]
    fn the_monitor_path_answers_the_picture() {
        let a = respond(b"GET /monitor/latest_result HTTP/1.1\r\nHost: x", picture);
        assert_eq!((a.status, a.content_type), ("200 OK", "image/svg+xml"));
        assert_eq!(a.body, "<svg/>");
        let a = respond(b"GET /monitor/latest_result?t=1 HTTP/1.0", picture);
        assert_eq!(a.status, "200 OK");
        let a = respond(b"HEAD /monitor/latest_result HTTP/1.1", picture);
        assert!(a.head_only);
    }

    #[test]
    fn everything_else_is_refused_with_its_status() {
        let status = |head: &[u8]| respond(head, picture).status;
        assert_eq!(status(b"GET / HTTP/1.1"), "404 Not Found");
        assert_eq!(status(b"GET /monitor HTTP/1.1"), "404 Not Found");
        assert_eq!(
            status(b"POST /monitor/latest_result HTTP/1.1"),
            "405 Method Not Allowed"
        );
        assert_eq!(status(b"GET /monitor/latest_result"), "400 Bad Request");
        assert_eq!(status(b"\xff\xfe"), "400 Bad Request");
        assert_eq!(
            status(b"GET /monitor/latest_result HTTP/2"),
            "505 HTTP Version Not Supported"
        );
        let gone = respond(b"GET /monitor/latest_result HTTP/1.1", || None);
        assert_eq!(gone.status, "503 Service Unavailable");
    }
}
