//! The async GRIPLINK client.
//!
//! One background task owns the TCP connection (`task.rs`; calls poll it inline to send their
//! lines, see [Where a client's work runs](crate#where-a-clients-work-runs)); [`Client`] is a
//! cheap handle to it (`Clone + Send + Sync`) that any number of tasks use at once. Replies are
//! paired with commands strictly in order (`pipeline.rs`), as the controller answers every line
//! exactly once, in order (manual 2.1).
//!
//! # Timeouts and late replies
//! Every call has a timeout: [`ClientConfig::query_timeout`] for commands answered at once,
//! [`ClientConfig::motion_timeout`] for commands that hold their reply until a motion is done
//! (HOME, GRIP/RELEASE/FLEX… with [`Blocking::UntilDone`], WSTR), and a WAITVAL's own timeout
//! plus [`ClientConfig::wait_margin`]. [`Client::with_timeout`] overrides it for the calls made
//! through the returned handle.
//!
//! A call that times out (or whose future is dropped) keeps its place in the FIFO: its reply,
//! when it comes, is consumed and discarded, so the next caller gets its own. A command still
//! queued when its caller gives up is never sent.
//!
//! While a blocking command holds the connection, the controller reads nothing else from it
//! (manual 2.1): other calls wait behind it and may time out. To watch a gripper during a long
//! blocking motion, start the motion with [`Blocking::Immediate`] and wait with
//! [`WaitBy::Polling`], or open a second [`Client`].
//!
//! If a reply stays away [`ClientConfig::give_up_after`] beyond its call's timeout, the
//! controller is not answering the way the protocol promises, and no later reply could be
//! paired with confidence: the client then reports [`Error::ConnectionLost`] to every pending and
//! future call and closes the connection. It then reconnects if [`ClientConfig::reconnect`] is
//! set; otherwise reconnecting is left to the caller (connect a new [`Client`]).
//!
//! # Replies out of step
//! GRIPLINK replies carry no request id and no checksum (manual 2.1): order is the only
//! pairing. An extra line on the wire (a duplicated reply, a command duplicated by the network
//! and answered twice, a byte corrupted into LF) would hand every later caller the reply of the
//! call before it. So a reply that does not answer its command (another key, port or index,
//! `ACK` for a query, a value for a command that answers `ACK`, or not GRIPLINK at all) is
//! never skipped silently: the call fails with [`Error::UnexpectedReply`] or
//! [`Error::MalformedReply`], and before it returns the client resynchronises: it sends a
//! harmless probe (`ID?`, or `SN?` after an `ID?`), skips every line until the probe's answer,
//! and only then sends the next command. If other commands were on the wire at that moment
//! (pipelining), their replies could be anyone's: the connection is given up
//! ([`Error::ConnectionLost`]).
//!
//! What cannot be detected at the protocol level: a changed digit in a value or in a command's
//! argument (`DEVPID[0]=20` read as 30, `LED(0,1)` run as `LED(0,3)`), and an extra reply taken
//! by a next command that expects the same shape (two identical `ACK`s: a blocking `HOME` may
//! then return at once; two replies to the same query: the second caller gets the first's
//! value). The shift is detected, and repaired as above, at the first later command that
//! expects another shape. A reply cut off by a lost connection is never taken for a whole one
//! (it fails with [`Error::ConnectionLost`]).
//!
//! # Waiting for a motion
//! A helper reads the device state before it sends the command (the start state), then
//! decides that the motion ended only from evidence that it did:
//! 1. **A state transition after the command.** The manual's two ways (3.4.4, options 1 and 2):
//!    an outcome state that differs from the start state, read by polling `DEVSTATE`
//!    ([`WaitBy::Polling`]), or answered by `WSTR` ([`WaitBy::Transition`]).
//! 2. **The fingers at the target** when no transition may come. "The start state can be
//!    different to DS_IDLE" (3.4.4), and "if the device is already in state DS_RELEASED when the
//!    command is issued, a state transition may not occur. In this case, use the WAITVAL command"
//!    (3.4.7). So a release that starts in `DS_RELEASED` or `DS_FAULT` ends when the finger
//!    position is within [`TARGET_TOLERANCE_UM`] of the release limit (the recipe's, read
//!    with `GRIPCFG` before the command, or the FLEX command's own): with `WaitBy::Transition`
//!    by `WAITVAL` on value 0 (3.4.12, one second at a time), with `WaitBy::Polling` by reading
//!    `VALUE`.
//! 3. **The fingers still, in `DS_FAULT`.** A motion started in `DS_FAULT` (the gripper is
//!    re-enabled by GRIP and RELEASE, 3.4.1) that faults again ends with no transition, and a
//!    grip has no target (a part stops it anywhere). Such a motion counts as ended in
//!    `DS_FAULT` once the finger position has not changed for [`STILL_FOR`]. (The same holds
//!    for a grip from any other outcome state a device might accept; Weiss grippers refuse GRIP
//!    in `DS_HOLDING` and `DS_NO_PART`, 3.4.4.)
//!
//! **From `DS_FAULT`, evidence only after the re-enable.** Until the gripper has re-enabled
//! (3.4.1; the manual gives no time for it) it still reads `DS_FAULT` with its fingers still, the
//! very picture of a motion that ended in a fault; a release whose fingers are at the release
//! limit already even passes `WAITVAL` at once. So for a motion started in `DS_FAULT` the
//! position (rules 2 and 3) counts only once the device shows that it re-enabled: a state other
//! than `DS_FAULT` read after the command (then any outcome state read later, `DS_FAULT`
//! included, is a transition and ends the wait), or the fingers more than
//! [`TARGET_TOLERANCE_UM`] away from where they were before the command. Without either sign it
//! counts only after [`RE_ENABLE_WINDOW`] from the command's `ACK` (a device that has neither
//! moved nor left `DS_FAULT` by then is taken not to have re-enabled). And from `DS_FAULT` the
//! fingers at the target are not enough for a `DS_FAULT` outcome: they must also stand still for
//! [`STILL_FOR`], as the state may follow the fingers a moment later.
//!
//! Evidence from the position is followed by a fresh state read, which gives the outcome (the
//! motion may have ended between the two reads).
//!
//! A state read right after the command's `ACK` that merely repeats the start state is never
//! taken as the outcome: the fingers may still be moving.
//!
//! A `WSTR` answered with `ERR 05` ("if no state transition occurs, the query returns with a
//! timeout error", 3.4.10) is no failure: the helper checks the state (and position) and asks
//! again, until the helper's own deadline. Only that deadline ends the wait with
//! [`Error::Timeout`]. `HOME` needs no helper: it always blocks until the homing is done
//! (3.4.3), so [`Port::home`]'s `ACK` is the evidence.
//!
//! # Cancellation
//! Every async method is cancel-safe for the connection: dropping its future (a `select!`,
//! a timeout, an aborted task) at any await point never hands its reply to another caller. A
//! command still queued when its call is dropped is never sent. A command already sent,
//! though, runs on the controller: a cancelled GRIP still grips, a cancelled HOME still homes
//! (a motion keeps moving until it ends or is stopped, e.g. with [`Port::disable`]); and a
//! cancelled blocking call (HOME, [`Blocking::UntilDone`], WSTR, WAITVAL) still holds this
//! connection on the controller until it answers, so later calls wait behind it. Nothing is
//! ever re-sent by the library.

mod pipeline;
mod port;
mod task;
mod wait;
mod watch;

use std::sync::Arc;
use std::time::Duration;

use tokio::net::{TcpStream, ToSocketAddrs};
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

pub use port::Port;
pub use wait::{
    GripOutcome, ReleaseOutcome, WaitBy, MIN_POLL_INTERVAL, RE_ENABLE_WINDOW, STILL_FOR,
    TARGET_TOLERANCE_UM,
};
pub use watch::Watch;

use self::task::{Request, Shared, Task, TaskConfig};
#[cfg(doc)]
use super::command::Blocking;
use super::command::{check_raw_line, Command, Duty, Expect, GripConfig, GripConfigF, PortNumber};
use super::error::{Error, Result};
use super::reply::{Answer, Checked, Datum};
use super::state::DeviceState;
use super::value::Value;
use crate::connection::Connection;
use crate::line::codec::DEFAULT_MAX_LINE_LEN;
use crate::line::{LineLink, Opener};
use crate::reconnect::{
    BoxStream, ConnectionEvents, EventSender, EventSubscriber, ReconnectPolicy,
};

/// Connection events each [`Client::connection_events`] stream buffers, at most.
const EVENT_BUFFER: usize = 32;

/// The controller's default TCP port (manual 2.5.1).
pub const DEFAULT_PORT: u16 = 10001;

/// Client settings. `ClientConfig::default()` suits a controller on a local network.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Timeout of commands the controller answers at once. Default 2 s.
    pub query_timeout: Duration,
    /// Timeout of commands that hold their reply until a motion or state transition is done,
    /// and the overall limit of the grip/release-and-wait helpers. Default 30 s.
    pub motion_timeout: Duration,
    /// Added to a WAITVAL's own timeout to get the call's timeout. Default 2 s.
    pub wait_margin: Duration,
    /// How long past a call's timeout a missing reply is tolerated before the connection is
    /// declared broken (see the module docs). Default 30 s.
    pub give_up_after: Duration,
    /// Timeout of the TCP connect. Default 5 s.
    pub connect_timeout: Duration,
    /// Longest reply line accepted; longer ones are discarded. Default 1024 bytes.
    pub max_line_len: usize,
    /// How many calls may wait to be sent. Default 64; 0 is taken as 1, and anything above
    /// tokio's `Semaphore::MAX_PERMITS` (e.g. `usize::MAX`) as that.
    pub queue_len: usize,
    /// How many commands may be on the wire unanswered. Default 1: the controller's input
    /// buffer is not documented, and a command still in our queue can be withdrawn when its
    /// caller gives up, one already sent cannot.
    pub pipeline_depth: usize,
    /// Reconnect after a lost connection (`None`, the default: a lost connection stays closed
    /// and every later call fails with the reason).
    ///
    /// With a policy, when the connection is lost (the controller closed it, I/O failed, or
    /// the client gave up on it, [`Error::ConnectionLost`]):
    /// - the calls in flight fail with the reason; they are **never sent again** by the client:
    ///   a GRIP may have run, and only the program can tell whether to repeat it;
    /// - the client reconnects to the same address with the policy's backoff and restores what
    ///   the program set up: the last [`Client::set_verbose`] the controller accepted (a
    ///   `VERBOSE=` sent with [`Client::command`] is not tracked). Its reply is awaited
    ///   `query_timeout` plus `give_up_after` (as long as a reply may stay away on a served
    ///   connection), at least 1 s and at most 10 s; unanswered, the attempt fails and the next one connects again;
    /// - calls still queued (not yet sent) and calls made meanwhile **wait** in the queue within
    ///   their own timeouts and go out once the session is restored; a call that times out
    ///   while waiting was never sent;
    /// - each step is reported through [`Client::connection_events`] and `tracing`.
    ///
    /// After [`Client::close`], or when every handle is dropped, nothing reconnects. When the
    /// policy gives up, the client is closed like one without a policy.
    pub reconnect: Option<ReconnectPolicy>,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            query_timeout: Duration::from_secs(2),
            motion_timeout: Duration::from_secs(30),
            wait_margin: Duration::from_secs(2),
            give_up_after: Duration::from_secs(30),
            connect_timeout: Duration::from_secs(5),
            max_line_len: DEFAULT_MAX_LINE_LEN,
            queue_len: 64,
            pipeline_depth: 1,
            reconnect: None,
        }
    }
}

impl ClientConfig {
    fn timeout_for(&self, duty: Duty) -> Duration {
        match duty {
            Duty::Query => self.query_timeout,
            Duty::Motion => self.motion_timeout,
            Duty::Wait(t) => t.saturating_add(self.wait_margin),
        }
    }
}

/// A handle to a GRIPLINK controller connection. Cheap to clone; every clone talks over the
/// same connection, which closes when the last handle is dropped or [`Client::close`] is called.
///
/// Controller-wide commands are methods here; device commands are on [`Port`]
/// (`client.port(2).home()`).
#[derive(Debug, Clone)]
pub struct Client {
    /// The background task; calls poll it inline to send their lines (see `crate::connection`).
    connection: Connection,
    requests: mpsc::Sender<Request>,
    shared: Arc<Shared>,
    events: EventSubscriber,
    config: Arc<ClientConfig>,
    timeout: Option<Duration>,
}

/// A `KEY[…]=value` reply together with the command it answers, for typed extraction.
struct Reading {
    /// Encoded again only for an error message, so a read encodes its line once.
    command: Command,
    data: Datum,
}

/// `command`'s line, for an error message. A call encodes its line once, for the wire, and an
/// error (rare) encodes it again rather than every call keeping a copy; it encoded before, so
/// it encodes again.
fn line_for_error(command: &Command) -> String {
    command.encode().unwrap_or_default()
}

impl Reading {
    fn wrong(&self, expected: &str) -> Error {
        Error::UnexpectedReply {
            command: line_for_error(&self.command),
            line: self.data.to_string(),
            expected: expected.to_owned(),
        }
    }

    fn string(self) -> Result<String> {
        match self.data.value {
            Value::Str(s) => Ok(s),
            _ => Err(self.wrong("a string")),
        }
    }

    fn int<T: TryFrom<i64>>(&self) -> Result<T> {
        self.data
            .value
            .as_int()
            .and_then(|v| T::try_from(v).ok())
            .ok_or_else(|| self.wrong("an integer in range"))
    }

    fn float(&self) -> Result<f64> {
        self.data
            .value
            .as_f64()
            .ok_or_else(|| self.wrong("a number"))
    }

    fn state(&self) -> Result<DeviceState> {
        Ok(DeviceState::from_code(self.int::<i64>()?))
    }

    /// `[<tag>,<p0>,…,<p7>]` (manual 3.6.1).
    fn recipe(&self) -> Result<(String, Vec<Value>)> {
        match &self.data.value {
            Value::List(items) if items.len() == 9 => match items.split_first() {
                Some((Value::Str(tag), params)) => Ok((tag.clone(), params.to_vec())),
                _ => Err(self.wrong("a recipe [\"tag\",p0,…,p7]")),
            },
            _ => Err(self.wrong("a recipe [\"tag\",p0,…,p7]")),
        }
    }

    fn grip_config(&self) -> Result<GripConfig> {
        let (tag, values) = self.recipe()?;
        let mut params = [0i32; 8];
        for (slot, v) in params.iter_mut().zip(&values) {
            *slot = v
                .as_int()
                .and_then(|v| i32::try_from(v).ok())
                .ok_or_else(|| self.wrong("32-bit integer recipe parameters"))?;
        }
        Ok(GripConfig { tag, params })
    }

    fn grip_config_f(&self) -> Result<GripConfigF> {
        let (tag, values) = self.recipe()?;
        let mut params = [0f64; 8];
        for (slot, v) in params.iter_mut().zip(&values) {
            *slot = v
                .as_f64()
                .ok_or_else(|| self.wrong("numeric recipe parameters"))?;
        }
        Ok(GripConfigF { tag, params })
    }
}

impl Client {
    /// Connects to a controller (`"192.168.1.40:10001"`) with the default configuration.
    ///
    /// Cancel-safe: dropped, nothing is left running.
    pub async fn connect(addr: impl ToSocketAddrs) -> Result<Client> {
        Client::connect_with(addr, ClientConfig::default()).await
    }

    /// Connects with the given configuration. A reconnect ([`ClientConfig::reconnect`]) goes
    /// to the addresses `addr` resolved to now. A failure here is returned whatever the
    /// reconnect policy says.
    ///
    /// Cancel-safe: dropped, nothing is left running.
    pub async fn connect_with(addr: impl ToSocketAddrs, config: ClientConfig) -> Result<Client> {
        let (stream, opener) =
            Opener::resolve_and_connect::<Error>(addr, config.connect_timeout).await?;
        Ok(Client::spawn(stream, opener, config))
    }

    /// Runs the client over an already connected stream. Must be called inside a tokio runtime.
    /// A reconnect ([`ClientConfig::reconnect`]) goes to the stream's peer address.
    pub fn from_stream(stream: TcpStream, config: ClientConfig) -> Client {
        let (stream, opener) = Opener::from_tcp(stream);
        Client::spawn(stream, opener, config)
    }

    /// Runs the client over the byte streams `open` opens: one now, and with
    /// [`ClientConfig::reconnect`] a new one after each loss, each attempt bounded by
    /// [`ClientConfig::connect_timeout`] (e.g. a tunnel, or in-memory pipes to
    /// [`SimServer::serve_stream`](crate::griplink::sim::SimServer::serve_stream) so that a
    /// test exercises reconnecting without sockets). A failure of the first open is returned
    /// whatever the reconnect policy says. Must be called inside a tokio runtime.
    pub async fn open_with<F, Fut, S>(open: F, config: ClientConfig) -> Result<Client>
    where
        F: Fn() -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = std::io::Result<S>> + Send + 'static,
        S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Send + Unpin + 'static,
    {
        let (stream, opener) =
            Opener::first::<Error, _, _, _>(open, config.connect_timeout).await?;
        Ok(Client::spawn(stream, opener, config))
    }

    fn spawn(stream: BoxStream, opener: Opener, config: ClientConfig) -> Client {
        let (requests, rx) = mpsc::channel(crate::queue::channel_capacity(config.queue_len));
        let shared = Arc::new(Shared::default());
        let events = EventSender::new("griplink", EVENT_BUFFER);
        let task = Task {
            requests: rx,
            config: TaskConfig {
                pipeline_depth: config.pipeline_depth,
                give_up_after: config.give_up_after,
                probe_timeout: config.query_timeout.saturating_add(config.give_up_after),
                query_timeout: config.query_timeout,
            },
            shared: Arc::clone(&shared),
        };
        let link = LineLink {
            events: events.clone(),
            policy: config.reconnect,
            opener: Some(opener),
            connect_timeout: config.connect_timeout,
            max_line_len: config.max_line_len,
            close: shared.close.clone(),
        };
        Client {
            connection: Connection::spawn(crate::line::run(stream, task, link)),
            requests,
            shared,
            events: events.subscriber(),
            config: Arc::new(config),
            timeout: None,
        }
    }

    /// Whether the connection is closed for good (every call fails). While the client
    /// reconnects it is not closed.
    pub fn is_closed(&self) -> bool {
        self.requests.is_closed()
    }

    /// The connection's events from now on: each loss, reconnect attempt and recovery (see
    /// [`ClientConfig::reconnect`]); without a reconnect policy, only the loss. The stream ends
    /// when the connection is closed for good. It buffers at most 32 events: a reader that falls
    /// further behind loses the oldest and gets a
    /// [`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed) instead.
    ///
    /// ```
    /// # #[cfg(not(feature = "sim"))]
    /// # fn main() {}
    /// # #[cfg(feature = "sim")]
    /// # #[tokio::main(flavor = "current_thread")]
    /// # async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// use futures_util::StreamExt;
    /// use gripper::fault::{FaultProxy, Framing, ProxyConfig};
    /// use gripper::griplink::sim::{SimConfig, SimServer};
    /// use gripper::griplink::{Client, ClientConfig};
    /// use gripper::reconnect::{ConnectionEvent, ReconnectPolicy};
    ///
    /// let server = SimServer::bind("127.0.0.1:0", SimConfig::et4().time_scale(0.0)).await?;
    /// // A proxy to pull the cable with.
    /// let lines = ProxyConfig::new().framing(Framing::Delimited(b'\n'));
    /// let proxy = FaultProxy::start_with(server.local_addr(), lines).await?;
    /// let config = ClientConfig {
    ///     reconnect: Some(ReconnectPolicy::default()),
    ///     ..ClientConfig::default()
    /// };
    /// let client = Client::connect_with(proxy.local_addr(), config).await?;
    /// client.set_verbose(true).await?;
    /// let mut events = client.connection_events();
    ///
    /// proxy.cut_connections();
    /// while let Some(event) = events.next().await {
    ///     println!("{event}");
    ///     if let ConnectionEvent::Restored { .. } = event {
    ///         break;
    ///     }
    /// }
    /// // A new connection, verbose again.
    /// assert_eq!(client.id().await?, "GRIPLINK-ET4");
    /// # Ok(())
    /// # }
    /// ```
    pub fn connection_events(&self) -> ConnectionEvents {
        self.events.subscribe()
    }

    /// A handle whose calls all use `timeout` instead of the defaults. Shares the connection.
    pub fn with_timeout(&self, timeout: Duration) -> Client {
        Client {
            timeout: Some(timeout),
            ..self.clone()
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ClientConfig {
        &self.config
    }

    /// A handle for the device on `port`, so port code does not repeat the number.
    pub fn port(&self, port: PortNumber) -> Port {
        Port::new(self.clone(), port)
    }

    fn timeout_for(&self, duty: Duty) -> Duration {
        self.timeout
            .unwrap_or_else(|| self.config.timeout_for(duty))
    }

    /// Queues `line` and waits for its reply. `line_again` gives the line for a timeout error:
    /// `line` itself goes to the task, and copying it for an error that rarely happens would
    /// cost an allocation on every call.
    async fn submit(
        &self,
        line: String,
        line_again: impl FnOnce() -> String,
        expect: Expect,
        duty: Duty,
        bye: bool,
    ) -> Result<Checked> {
        let timeout = self.timeout_for(duty);
        let deadline = crate::deadline::after(Instant::now(), timeout);
        let (waiter, answer) = oneshot::channel();
        let request = Request {
            line,
            expect,
            deadline,
            timeout,
            waiter,
            bye,
        };
        let exchange = async {
            self.requests
                .send(request)
                .await
                .map_err(|_| self.shared.failure())?;
            answer.await.map_err(|_| self.shared.failure())?
        };
        // Pinned in place: handing the future (a Request, a timer) on by value would copy it
        // at every layer.
        let exchange = std::pin::pin!(tokio::time::timeout_at(deadline, exchange));
        match self.connection.call(exchange).await {
            Ok(result) => result,
            Err(_) => Err(Error::Timeout {
                command: line_again(),
                timeout,
            }),
        }
    }

    /// Sends a typed command and returns its checked reply.
    ///
    /// [Cancel-safe](self#cancellation) for the connection; once sent, the command runs on the
    /// controller even if the call is dropped (a motion keeps moving).
    pub async fn execute(&self, command: &Command) -> Result<Answer> {
        self.execute_checked(command).await.map(Answer::from)
    }

    /// [`Client::execute`], with the reply's data in the form that costs no allocation.
    async fn execute_checked(&self, command: &Command) -> Result<Checked> {
        let line = command.encode()?;
        let bye = matches!(command, Command::Bye);
        let line_again = || line_for_error(command);
        let answer = self
            .submit(line, line_again, command.expect(), command.duty(), bye)
            .await?;
        // What a reconnect restores: the mode the controller reports.
        if let (Command::SetVerbose(_), Checked::Data(data)) = (command, &answer) {
            if let Some(mode) = data.value.as_int() {
                self.shared.set_verbose(mode != 0);
            }
        }
        Ok(answer)
    }

    /// Sends a raw command line (without LF) the crate has no type for, and returns its reply:
    /// `ACK` or `KEY[…]=value`; `ERR` becomes [`Error::Device`]. The line must be printable
    /// ASCII without control characters. Uses the query timeout unless overridden with
    /// [`Client::with_timeout`]; do not send `BYE()` this way, use [`Client::close`].
    ///
    /// [Cancel-safe](self#cancellation) for the connection; once sent, the command runs on the
    /// controller even if the call is dropped (a motion keeps moving).
    pub async fn command(&self, line: &str) -> Result<Answer> {
        check_raw_line(line)?;
        let line_again = || line.to_owned();
        self.submit(line.to_owned(), line_again, Expect::Any, Duty::Query, false)
            .await
            .map(Answer::from)
    }

    pub(crate) async fn ack(&self, command: Command) -> Result<()> {
        match self.execute_checked(&command).await? {
            Checked::Ack => Ok(()),
            // `execute` checked the reply against `Expect::Ack` already.
            Checked::Data(data) => Err(Error::UnexpectedReply {
                command: line_for_error(&command),
                line: data.to_string(),
                expected: "ACK".into(),
            }),
        }
    }

    async fn read(&self, command: Command) -> Result<Reading> {
        match self.execute_checked(&command).await? {
            Checked::Data(data) => Ok(Reading { command, data }),
            Checked::Ack => Err(Error::UnexpectedReply {
                command: line_for_error(&command),
                line: "ACK".into(),
                expected: "a value".into(),
            }),
        }
    }

    pub(crate) async fn read_string(&self, command: Command) -> Result<String> {
        self.read(command).await?.string()
    }

    pub(crate) async fn read_int<T: TryFrom<i64>>(&self, command: Command) -> Result<T> {
        self.read(command).await?.int()
    }

    pub(crate) async fn read_float(&self, command: Command) -> Result<f64> {
        self.read(command).await?.float()
    }

    pub(crate) async fn read_state(&self, command: Command) -> Result<DeviceState> {
        self.read(command).await?.state()
    }

    pub(crate) async fn read_grip_config(&self, command: Command) -> Result<GripConfig> {
        self.read(command).await?.grip_config()
    }

    pub(crate) async fn read_grip_config_f(&self, command: Command) -> Result<GripConfigF> {
        self.read(command).await?.grip_config_f()
    }

    /// `ID?`: the controller's identification, e.g. `GRIPLINK-ET4` (manual 3.1.1).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn id(&self) -> Result<String> {
        self.read_string(Command::Id).await
    }

    /// `PROTOCOL?`: the protocol version string, e.g. `GRIPLINK-V3` (manual 3.1.2).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn protocol(&self) -> Result<String> {
        self.read_string(Command::Protocol).await
    }

    /// `PROTASSERT`: fails with [`Status::NotSupported`](super::Status::NotSupported) unless the
    /// controller runs `identifier` in at least `min_version` (manual 3.1.3).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn protocol_assert(&self, identifier: &str, min_version: u32) -> Result<()> {
        self.ack(Command::ProtAssert {
            identifier: identifier.to_owned(),
            min_version,
        })
        .await
    }

    /// `SN?`: the controller's serial number (manual 3.1.4).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn serial_number(&self) -> Result<String> {
        self.read_string(Command::SerialNumber).await
    }

    /// `LABEL?` (manual 3.1.5).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn label(&self) -> Result<String> {
        self.read_string(Command::Label).await
    }

    /// `LABEL="…"`: at most 32 printable ASCII characters without `'` `"` `\` (checked before
    /// sending). Returns the label the controller reports back (manual 3.1.5).
    ///
    /// [Cancel-safe](self#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_label(&self, label: &str) -> Result<String> {
        self.read_string(Command::SetLabel(label.to_owned())).await
    }

    /// `VER?`: the controller's firmware version (manual 3.1.6).
    ///
    /// [Cancel-safe](self#cancellation): dropped, its reply is discarded when it comes.
    pub async fn version(&self) -> Result<String> {
        self.read_string(Command::Version).await
    }

    /// `VERBOSE=0|1`: whether `ERR` replies carry a description (manual 3.1.7). Returns the
    /// mode the controller reports back.
    ///
    /// [Cancel-safe](self#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_verbose(&self, on: bool) -> Result<bool> {
        Ok(self.read_int::<i64>(Command::SetVerbose(on)).await? != 0)
    }

    /// `BYE()`: ends the session gracefully; waits for the `ACK` (manual 3.3.1). The connection
    /// is closed once the reply is in, whatever it says; calls made afterwards, on any clone,
    /// fail with [`Error::Closed`].
    ///
    /// While the client reconnects ([`ClientConfig::reconnect`]), in a backoff wait or an
    /// attempt, it stops at once and this returns `Ok(())` without any `BYE()`: there is no
    /// connection to send it on (the controller saw the old one end already). The client is
    /// closed; calls still queued fail with [`Error::Closed`], and so does every later call. A
    /// second `close()` fails with [`Error::Closed`], as after any close.
    ///
    /// [Cancel-safe](self#cancellation): once `BYE()` was sent the connection closes whether or not
    /// the call is still waiting. From its first poll the client no longer reconnects: dropped
    /// before `BYE()` was sent, the connection is still served, but a loss closes the client.
    pub async fn close(&self) -> Result<()> {
        // Seen by a reconnecting task at once (it reads no queue in a backoff wait).
        let first = self.shared.close.request();
        let asked = self.ack(Command::Bye).await;
        self.shared.close.outcome(first, asked)
    }
}
