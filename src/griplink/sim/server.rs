//! Serves the simulated controller over TCP. Each connection reads its lines in order and
//! answers each before reading the next, so a blocking command (HOME, GRIP with do_block=1,
//! WSTR, WAITVAL) holds back only that connection's later commands, as on the device
//! (manual 2.1); all connections share one [`Controller`].

use std::collections::VecDeque;
use std::future::poll_fn;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use futures_core::Stream;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, ToSocketAddrs};
use tokio::sync::{watch, Notify, Semaphore};
use tokio::task::JoinSet;
use tokio::time::Instant;
use tokio_util::codec::FramedRead;

use super::controller::{error_line, Controller, Outcome, Session, SimConfig, Wait};
use super::parse::{clean_line, parse_command};
use crate::griplink::command::{Command, PortNumber};
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;
use crate::line::codec::{Discarded, Line, LineCodec, DEFAULT_MAX_LINE_LEN};

/// A fault injected into the handling of the next command line the server receives (on any
/// connection), for testing how a client copes.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum Fault {
    /// Execute the command but send no reply.
    DropReply,
    /// Execute the command, then wait this long (wall time) before replying.
    DelayReply(Duration),
    /// Hold the reply until [`ReplyGate::release`] is called.
    HoldReply(ReplyGate),
    /// Do not execute the command; answer `ERR <status>`.
    Error(Status),
    /// Execute the command, but send these bytes instead of its reply (include the LF).
    RawReply(Vec<u8>),
    /// Close the connection instead of executing the command.
    Close,
}

/// Releases a reply held by [`Fault::HoldReply`].
#[derive(Debug, Clone)]
pub struct ReplyGate(Arc<Semaphore>);

impl ReplyGate {
    /// A closed gate.
    pub fn new() -> Self {
        ReplyGate(Arc::new(Semaphore::new(0)))
    }

    /// Lets the held reply go (also if it is not held yet: it will pass at once).
    pub fn release(&self) {
        self.0.add_permits(1);
    }

    async fn pass(&self) {
        if let Ok(permit) = self.0.acquire().await {
            permit.forget();
        }
    }
}

impl Default for ReplyGate {
    fn default() -> Self {
        ReplyGate::new()
    }
}

struct Shared {
    controller: Mutex<Controller>,
    /// Woken after every command, so held replies (WSTR, blocking motion) re-check at once when
    /// another connection changed something.
    changed: Notify,
    faults: Mutex<VecDeque<Fault>>,
    epoch: Instant,
    max_line_len: usize,
    /// Each request processed and the reply sent, per session (off until
    /// [`SimServer::start_recording`]).
    recording: Mutex<Option<Recording>>,
    /// How many connections hold a reply until a blocking command is done
    /// ([`SimServer::held_replies`]).
    held: AtomicUsize,
}

/// One command line a session processed and the reply line it sent (a test's oracle checks
/// that a client's answer is the controller's answer to that request).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimExchange {
    /// The connection (numbered from 1 in the order they were served).
    pub session: u64,
    /// The command line as received, without its LF.
    pub request: String,
    /// The reply line sent, without its LF (for a [`Fault::RawReply`], the raw bytes, lossy).
    pub reply: String,
    /// When the reply was written (tokio's clock).
    pub sent_at: Instant,
}

/// The bounded record: the oldest entries give way.
#[derive(Debug)]
struct Recording {
    capacity: usize,
    entries: VecDeque<SimExchange>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock cannot leave the state half-updated in a way that matters
    // more than stopping the simulator; keep serving.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Shared {
    fn now(&self) -> Duration {
        Instant::now().duration_since(self.epoch)
    }
}

/// A running simulated GRIPLINK controller. Shuts down when dropped.
///
/// ```
/// # #[tokio::main(flavor = "current_thread")]
/// # async fn main() -> std::io::Result<()> {
/// use gripper::griplink::sim::{SimConfig, SimServer};
/// let server = SimServer::bind("127.0.0.1:0", SimConfig::et4().time_scale(0.0)).await?;
/// println!("controller at {}", server.local_addr());
/// # Ok(()) }
/// ```
pub struct SimServer {
    addr: SocketAddr,
    shared: Arc<Shared>,
    shutdown: watch::Sender<bool>,
    /// Ends the in-memory connections ([`SimServer::serve_stream`]). Not the watch channel:
    /// its waiters are spread over shards picked at random, so two connections ended at one
    /// instant woke in a different order from run to run, and a seeded explorer run did not
    /// replay (`griplink-tcp:0x8db5896e0e3c67e2`). A cancellation token wakes its waiters in
    /// the order they came.
    stop: tokio_util::sync::CancellationToken,
    /// Numbers the connections (the record's `session`).
    next_session: Arc<std::sync::atomic::AtomicU64>,
}

impl std::fmt::Debug for SimServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimServer")
            .field("addr", &self.addr)
            .finish()
    }
}

impl SimServer {
    /// Binds `addr` (port 0 picks a free port) and serves `config` until shut down.
    pub async fn bind(addr: impl ToSocketAddrs, config: SimConfig) -> io::Result<SimServer> {
        let listener = TcpListener::bind(addr).await?;
        let mut server = SimServer::in_memory(config);
        server.addr = listener.local_addr()?;
        tokio::spawn(accept_loop(
            listener,
            Arc::clone(&server.shared),
            server.shutdown.subscribe(),
            Arc::clone(&server.next_session),
        ));
        Ok(server)
    }

    /// A controller with no listener of its own: give it connections with
    /// [`SimServer::serve_stream`] (e.g. ends of `tokio::io::duplex`). With in-memory streams
    /// and tokio's paused clock a test runs without the operating system's sockets or clock,
    /// so it replays exactly. Its [`local_addr`](Self::local_addr) is the unspecified
    /// `0.0.0.0:0`. Must be called inside a tokio runtime.
    pub fn in_memory(config: SimConfig) -> SimServer {
        let shared = Arc::new(Shared {
            controller: Mutex::new(Controller::new(config)),
            changed: Notify::new(),
            faults: Mutex::new(VecDeque::new()),
            epoch: Instant::now(),
            max_line_len: DEFAULT_MAX_LINE_LEN,
            recording: Mutex::new(None),
            held: AtomicUsize::new(0),
        });
        let (shutdown, _) = watch::channel(false);
        SimServer {
            addr: SocketAddr::from(([0, 0, 0, 0], 0)),
            shared,
            shutdown,
            stop: tokio_util::sync::CancellationToken::new(),
            next_session: Arc::new(std::sync::atomic::AtomicU64::new(1)),
        }
    }

    /// Serves one more byte stream as a new connection of this controller, beside the ones it
    /// has, until the stream ends or the server is shut down; returns the session number.
    pub fn serve_stream(&self, io: impl AsyncRead + AsyncWrite + Send + 'static) -> u64 {
        let session = self
            .next_session
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let shared = Arc::clone(&self.shared);
        let stop = self.stop.clone();
        tokio::spawn(async move {
            tokio::select! {
                // The shutdown first: a dropped server ends its connections whatever they do.
                biased;
                () = stop.cancelled() => {}
                () = serve(io, &shared, session) => {}
            }
        });
        session
    }

    /// Starts recording, per session, each command line processed and the reply sent (see
    /// [`SimExchange`]); at most `capacity` entries are kept (the oldest give way). Starting
    /// again clears the record.
    pub fn start_recording(&self, capacity: usize) {
        *lock(&self.shared.recording) = Some(Recording {
            capacity,
            entries: VecDeque::new(),
        });
    }

    /// The record so far, oldest first (empty if recording was never started).
    pub fn recording(&self) -> Vec<SimExchange> {
        lock(&self.shared.recording)
            .as_ref()
            .map(|r| r.entries.iter().cloned().collect())
            .unwrap_or_default()
    }

    /// The bound address (`0.0.0.0:0` for [`SimServer::in_memory`]).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops accepting and closes every connection (dropping the server does the same).
    pub fn shutdown(self) {
        // Drop does it.
    }

    /// Queues a fault for the next command line received (faults apply in queue order, one
    /// per line).
    pub fn inject(&self, fault: Fault) {
        lock(&self.shared.faults).push_back(fault);
    }

    /// Holds the reply to the next command until the returned gate is released.
    pub fn hold_next_reply(&self) -> ReplyGate {
        let gate = ReplyGate::new();
        self.inject(Fault::HoldReply(gate.clone()));
        gate
    }

    /// Runs `f` on the controller state at the current simulated time (inspect or change it).
    pub fn with_controller<R>(&self, f: impl FnOnce(&mut Controller, Duration) -> R) -> R {
        let now = self.shared.now();
        let result = f(&mut lock(&self.shared.controller), now);
        self.shared.changed.notify_waiters();
        result
    }

    /// The device state on `port` (`None` if the port does not exist).
    pub fn device_state(&self, port: PortNumber) -> Option<DeviceState> {
        self.with_controller(|c, now| c.state(usize::from(port), now))
    }

    /// Puts a part of `width_mm` between the fingers on `port` (`None`: take it away).
    pub fn set_part(&self, port: PortNumber, width_mm: Option<f64>) {
        self.with_controller(|c, _| c.set_part(usize::from(port), width_mm));
    }

    /// How many connections are held by a blocking command (HOME, a GRIP/RELEASE/FLEX… with
    /// do_block=1, WSTR, WAITVAL) whose reply is not due yet: the controller reads nothing
    /// else from such a connection until it answers (manual 2.1). A test that needs the
    /// controller to have answered everything it was given waits for 0 (commands still on
    /// their way to the controller, or queued behind a held one, are not counted; one read
    /// from a connection whose client has left since is, until it ends).
    pub fn held_replies(&self) -> usize {
        self.shared.held.load(Ordering::SeqCst)
    }

    /// Faults the device on `port` now.
    pub fn inject_device_fault(&self, port: PortNumber) {
        self.with_controller(|c, now| c.inject_fault(usize::from(port), now));
    }

    /// Makes the next motion on `port` end in `DS_FAULT`.
    pub fn fault_next_motion(&self, port: PortNumber) {
        self.with_controller(|c, _| c.fault_next_motion(usize::from(port)));
    }
}

impl Drop for SimServer {
    fn drop(&mut self) {
        let _ = self.shutdown.send(true);
        self.stop.cancel();
    }
}

async fn accept_loop(
    listener: TcpListener,
    shared: Arc<Shared>,
    mut stop: watch::Receiver<bool>,
    next_session: Arc<std::sync::atomic::AtomicU64>,
) {
    // Dropping the set when the loop ends aborts every connection.
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            // Fixed order (replay): a shutdown ends the loop whatever else is ready; accepting
            // and reaping cannot starve each other (a reap is instant, accepts are rare).
            biased;
            _ = stop.changed() => break,
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    tracing::debug!(%peer, "griplink sim: connection");
                    let _ = stream.set_nodelay(true);
                    let session = next_session.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let shared = Arc::clone(&shared);
                    connections.spawn(async move { serve(stream, &shared, session).await });
                }
                Err(e) => {
                    // E.g. out of file descriptors: back off instead of spinning.
                    tracing::warn!(error = %e, "griplink sim: accept failed");
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
            },
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

async fn serve(stream: impl AsyncRead + AsyncWrite, shared: &Shared, session: u64) {
    if let Err(e) = serve_lines(stream, shared, session).await {
        tracing::debug!(error = %e, "griplink sim: connection ended");
    }
}

async fn serve_lines(
    stream: impl AsyncRead + AsyncWrite,
    shared: &Shared,
    number: u64,
) -> io::Result<()> {
    let (read, mut write) = tokio::io::split(stream);
    // A command is a line ended by LF (manual 2.1): one cut off by a lost connection is not
    // executed (`GRIP(0,1)` without its LF must not grip).
    let codec = LineCodec::new(shared.max_line_len).reject_unterminated();
    let mut reader = FramedRead::new(read, codec);
    let mut session = Session::default();
    while let Some(line) = poll_fn(|cx| Pin::new(&mut reader).poll_next(cx)).await {
        let mut request = String::new();
        let command = match line? {
            Line::Text(text) => {
                let clean = clean_line(&text);
                if clean.is_empty() {
                    continue; // an empty line is no command and gets no reply
                }
                request = text.clone();
                Ok(clean)
            }
            Line::Discarded(Discarded::TooLong) => Err(Status::Overrun),
            Line::Discarded(Discarded::NotAscii) => Err(Status::CmdSyntax),
        };
        let fault = lock(&shared.faults).pop_front();
        let (reply, close) = match (&fault, command) {
            (Some(Fault::Close), _) => return Ok(()),
            (Some(Fault::Error(status)), _) => (error_line(*status, session.verbose), false),
            (_, Err(status)) => (error_line(status, session.verbose), false),
            (_, Ok(line)) => match parse_command(&line) {
                Err(status) => (error_line(status, session.verbose), false),
                Ok(cmd) => execute(shared, &mut session, &cmd).await,
            },
        };
        let mut bytes = reply.into_bytes();
        bytes.push(b'\n');
        match fault {
            Some(Fault::DropReply) => continue,
            Some(Fault::DelayReply(d)) => tokio::time::sleep(d).await,
            Some(Fault::HoldReply(gate)) => gate.pass().await,
            Some(Fault::RawReply(raw)) => bytes = raw,
            _ => {}
        }
        write.write_all(&bytes).await?;
        record(shared, number, request, &bytes);
        if close {
            write.shutdown().await?;
            return Ok(());
        }
    }
    Ok(())
}

/// Adds a sent reply to the record, if recording.
fn record(shared: &Shared, session: u64, request: String, reply: &[u8]) {
    let mut recording = lock(&shared.recording);
    let Some(r) = recording.as_mut() else { return };
    if r.entries.len() >= r.capacity {
        r.entries.pop_front();
    }
    if r.capacity == 0 {
        return;
    }
    let reply = String::from_utf8_lossy(reply.strip_suffix(b"\n").unwrap_or(reply)).into_owned();
    r.entries.push_back(SimExchange {
        session,
        request,
        reply,
        sent_at: Instant::now(),
    });
}

/// Runs one command; returns its reply line and whether to close the connection after it.
async fn execute(shared: &Shared, session: &mut Session, command: &Command) -> (String, bool) {
    let outcome = lock(&shared.controller).execute(session, command, shared.now());
    shared.changed.notify_waiters();
    match outcome {
        Outcome::Reply(line) => (line, false),
        Outcome::Bye => ("ACK".to_owned(), true),
        Outcome::Wait(wait) => {
            let _held = Held::count(&shared.held);
            let line = hold(shared, session, &wait).await;
            shared.changed.notify_waiters();
            (line, false)
        }
    }
}

/// A connection counted in [`SimServer::held_replies`] while its blocking command waits. The
/// count drops when the wait ends (or the server stops): a command the controller read before
/// its client left still runs to its end and is counted until then, as a real
/// controller finishes what it was given (a 13 µm/s `FLEXGRIP` buffered on a connection the
/// client had given up held the count for about 5,156 s: `griplink-tcp:0xde5f21a5f5ca4acb`).
struct Held<'a>(&'a AtomicUsize);

impl<'a> Held<'a> {
    fn count(held: &'a AtomicUsize) -> Self {
        held.fetch_add(1, Ordering::SeqCst);
        Held(held)
    }
}

impl Drop for Held<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Waits until the held reply is due: at the simulated time the controller names, or earlier
/// when another connection changed the state.
async fn hold(shared: &Shared, session: &Session, wait: &Wait) -> String {
    loop {
        let changed = shared.changed.notified();
        tokio::pin!(changed);
        changed.as_mut().enable();
        let wake = {
            let mut controller = lock(&shared.controller);
            let now = shared.now();
            if let Some(line) = controller.poll(session, wait, now) {
                return line;
            }
            controller.next_wake(wait, now)
        };
        tokio::select! {
            // Fixed order (replay): either branch only leads to the same re-check of the state.
            biased;
            () = &mut changed => {}
            () = tokio::time::sleep_until(shared.epoch + wake) => {}
        }
    }
}
