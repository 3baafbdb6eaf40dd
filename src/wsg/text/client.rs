//! The async GCL client: a cheap, clonable handle to the connection task (`task.rs`).

use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::{TcpStream, ToSocketAddrs};
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

use super::error::{Error, Result};
use super::line::{encode_call, encode_set, parse_number, BadArgument, DEFAULT_MAX_LINE_LEN};
use super::push::{Pushes, Quantity};
use super::task::{after, Answer, Expect, Request, Shared, Task, TaskConfig};
use crate::connection::Connection;
use crate::line::{LineLink, Opener};
use crate::queue::channel_capacity;
use crate::reconnect::{
    BoxStream, ConnectionEvents, EventSender, EventSubscriber, ReconnectPolicy,
};
use crate::wsg::{GripState, HomingDirection};

/// Connection events each [`Client::connection_events`] stream buffers, at most.
const EVENT_BUFFER: usize = 32;

/// Client settings. `ClientConfig::default()` suits a gripper on a local network.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Timeout of commands answered at once (queries, setters, STOP, FSACK, BYE). Default 2 s.
    pub query_timeout: Duration,
    /// Timeout of motions (HOME, MOVE, GRIP, RELEASE) up to their `FIN` or `ERR`. Default 30 s.
    pub motion_timeout: Duration,
    /// How long past a call's timeout a missing reply is tolerated before the connection is
    /// declared broken (replies carry only a name, so a reply that comes later than this could
    /// be taken for the next command of that name). Default 30 s. An acknowledged motion
    /// (`ACK` read) whose `FIN` is that late is not given up on time alone: the client asks
    /// `GRIPSTATE?`, and keeps waiting (asking again every `give_up_after`, at least 100 ms)
    /// while the gripper reports it running; reported over, its `FIN` has one more
    /// `give_up_after` to come before the connection is given up. (A report of "over" with no
    /// `FIN` before it and nothing unreadable since the `ACK` is asked once more first: the
    /// gripper answers in order, so such a report may be a value damaged on the way.)
    pub give_up_after: Duration,
    /// Timeout of the TCP connect. Default 5 s.
    pub connect_timeout: Duration,
    /// Longest reply line accepted; longer ones are discarded. Default 256 bytes.
    pub max_line_len: usize,
    /// How many calls may wait to be sent (in the channel, and again in the task while a
    /// command of their name is on the wire). A call whose caller gave up leaves the queue then.
    /// [`Client::stop`] and [`Client::fast_stop`] never wait behind it. Default 64; 0 is taken as 1, and anything above
    /// tokio's `Semaphore::MAX_PERMITS` (e.g. `usize::MAX`) as that.
    pub queue_len: usize,
    /// Pushes each [`Pushes`] stream buffers. Default 64; 0 is taken as 1, and anything above
    /// tokio's `Semaphore::MAX_PERMITS` (e.g. `usize::MAX`) as that.
    pub push_buffer: usize,
    /// Reconnect after a lost connection (`None`, the default: a lost connection stays closed
    /// and every later call fails with the reason). Not for [`Client::from_io`], whose stream
    /// cannot be opened again.
    ///
    /// With a policy, when the connection is lost (the gripper closed it, I/O failed, or the
    /// client gave up on it, [`Error::ConnectionLost`]):
    /// - the calls in flight, and those waiting behind a command of their name, fail with the
    ///   reason; they are **never sent again** by the client: a GRIP may have run, and only the
    ///   program can tell whether to repeat it;
    /// - the client reconnects to the same address with the policy's backoff and restores what
    ///   the program set up on the connection, in the order first set: the last
    ///   [`Client::set_verbose`], [`Client::set_part_width_tolerance_mm`] and
    ///   [`Client::set_clamping_travel_mm`] the gripper accepted, and each [`Client::autosend`]
    ///   still on (its [`Pushes`] streams go on). Each restored line's reply is awaited
    ///   `query_timeout` plus `give_up_after` (as long as a reply may stay away on a served
    ///   connection), at least 1 s and at most 10 s; unanswered, the attempt fails and the next one connects again;
    /// - calls still queued and calls made meanwhile **wait** in the queue within their own
    ///   timeouts and go out once the session is restored; a call that times out while
    ///   waiting was never sent;
    /// - each step is reported through [`Client::connection_events`] and `tracing`.
    ///
    /// After [`Client::close`] (`BYE()`), or when every handle is dropped, nothing reconnects.
    /// When the policy gives up, the client is closed like one without a policy. An unannounced
    /// loss puts the gripper into FAST STOP (manual chapter 2, `BYE`): the client never
    /// acknowledges it on its own.
    pub reconnect: Option<ReconnectPolicy>,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            query_timeout: Duration::from_secs(2),
            motion_timeout: Duration::from_secs(30),
            give_up_after: Duration::from_secs(30),
            connect_timeout: Duration::from_secs(5),
            max_line_len: DEFAULT_MAX_LINE_LEN,
            queue_len: 64,
            push_buffer: 64,
            reconnect: None,
        }
    }
}

/// A handle to a WSG connection in text mode (GCL). Cheap to clone; every clone talks over the
/// same connection, which closes when the last handle is dropped or [`Client::close`] is called.
///
/// Dropping the last handle without [`Client::close`] closes the socket **without `BYE()`**: the
/// gripper then raises FAST STOP (manual chapter 2, `BYE`), unless that is switched off in its
/// web interface.
#[derive(Debug, Clone)]
pub struct Client {
    connection: Connection,
    requests: mpsc::Sender<Request>,
    /// `STOP()` and `FASTSTOP()`: read by the task whatever the queue holds (issue 29 K).
    stops: mpsc::Sender<Request>,
    shared: Arc<Shared>,
    events: EventSubscriber,
    config: Arc<ClientConfig>,
    timeout: Option<Duration>,
}

impl From<BadArgument> for Error {
    fn from(b: BadArgument) -> Self {
        Error::InvalidArgument {
            what: b.what,
            reason: b.reason,
        }
    }
}

impl Client {
    /// Connects to a gripper (`"192.168.1.20:1000"`) with the default configuration.
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
        Ok(Client::spawn(stream, Some(opener), config))
    }

    /// Runs the client over an already connected stream. Must be called inside a tokio runtime.
    /// A reconnect ([`ClientConfig::reconnect`]) goes to the stream's peer address.
    pub fn from_stream(stream: TcpStream, config: ClientConfig) -> Client {
        let (stream, opener) = Opener::from_tcp(stream);
        Client::spawn(stream, Some(opener), config)
    }

    /// Runs the client over any connected byte stream: one end of `tokio::io::duplex` (a
    /// simulator served in memory with [`SimServer::serve_stream`], as the explorer does), a
    /// TLS stream, a tunnel. The stream is the whole session: this client does not reconnect
    /// ([`ClientConfig::reconnect`] is ignored; [`Client::open_with`] reconnects), so a lost
    /// stream fails every later call with [`Error::ConnectionLost`]. Must be called inside a
    /// tokio runtime.
    ///
    /// [`SimServer::serve_stream`]: crate::wsg::sim::SimServer::serve_stream
    pub fn from_io<S>(io: S, config: ClientConfig) -> Client
    where
        S: AsyncRead + AsyncWrite + Send + 'static,
    {
        let config = ClientConfig {
            reconnect: None,
            ..config
        };
        Client::spawn(Box::new(Box::pin(io)), None, config)
    }

    /// Runs the client over the byte streams `open` opens: one now, and with
    /// [`ClientConfig::reconnect`] a new one after each loss, each attempt bounded by
    /// [`ClientConfig::connect_timeout`] (e.g. a tunnel, or in-memory pipes to
    /// [`SimServer::serve_stream`](crate::wsg::sim::SimServer::serve_stream)). A failure of the
    /// first open is returned whatever the reconnect policy says. Must be called inside a tokio
    /// runtime.
    pub async fn open_with<F, Fut, S>(open: F, config: ClientConfig) -> Result<Client>
    where
        F: Fn() -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = std::io::Result<S>> + Send + 'static,
        S: AsyncRead + AsyncWrite + Send + Unpin + 'static,
    {
        let (stream, opener) =
            Opener::first::<Error, _, _, _>(open, config.connect_timeout).await?;
        Ok(Client::spawn(stream, Some(opener), config))
    }

    fn spawn(stream: BoxStream, opener: Option<Opener>, config: ClientConfig) -> Client {
        let (requests, rx) = mpsc::channel(channel_capacity(config.queue_len));
        let (stops, stops_rx) = mpsc::channel(channel_capacity(config.queue_len));
        let shared = Arc::new(Shared::default());
        let events = EventSender::new("wsg text", EVENT_BUFFER);
        let task = Task {
            requests: rx,
            stops: stops_rx,
            config: TaskConfig {
                give_up_after: config.give_up_after,
                waiting_len: channel_capacity(config.queue_len),
                query_timeout: config.query_timeout,
            },
            shared: shared.clone(),
        };
        let link = LineLink {
            events: events.clone(),
            policy: config.reconnect,
            opener,
            connect_timeout: config.connect_timeout,
            max_line_len: config.max_line_len,
            close: shared.close.clone(),
        };
        Client {
            connection: Connection::spawn(crate::line::run(stream, task, link)),
            requests,
            stops,
            shared,
            events: events.subscriber(),
            config: Arc::new(config),
            timeout: None,
        }
    }

    /// The connection's events from now on: each loss, reconnect attempt and recovery (see
    /// [`ClientConfig::reconnect`]); without a reconnect policy, only the loss. The stream ends
    /// when the connection is closed for good. It buffers at most 32 events: a reader that falls
    /// further behind loses the oldest and gets a
    /// [`ConnectionEvent::Missed`](crate::reconnect::ConnectionEvent::Missed) instead.
    pub fn connection_events(&self) -> ConnectionEvents {
        self.events.subscribe()
    }

    /// Whether the connection is closed for good (every call fails).
    pub fn is_closed(&self) -> bool {
        self.requests.is_closed()
    }

    /// A handle whose calls all use `timeout` instead of the defaults. Shares the connection.
    ///
    /// `Duration::MAX` means no timeout: such a call still ends on the gripper's evidence. A
    /// reply due at once (a query, a setter, an `ACK`) that stays away 10 s makes the client
    /// write a probe; the gripper answers in order, so once the probe is answered the call's
    /// reply is lost and it fails [`Error::MalformedReply`] (its request may have been damaged
    /// on the way). An acknowledged motion is asked `GRIPSTATE?` 10 s after its `ACK` and every
    /// 10 s after; reported over with a line that could not be read since its `ACK`, it fails
    /// [`Error::MalformedReply`] too.
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

    async fn submit(&self, name: &'static str, line: String, expect: Expect) -> Result<Answer> {
        if line.len() > self.config.max_line_len || line.bytes().any(|b| b.is_ascii_control()) {
            return Err(Error::invalid(
                "command line",
                "too long, or with control characters",
            ));
        }
        let timeout = self.timeout.unwrap_or(match expect {
            Expect::Fin => self.config.motion_timeout,
            Expect::Ack | Expect::Value => self.config.query_timeout,
        });
        let start = Instant::now();
        let deadline = after(start, timeout);
        let (waiter, answer) = oneshot::channel();
        // The line goes to the task; a timeout error needs it too, rarely.
        let line_again = line.clone();
        let request = Request {
            name,
            line,
            expect,
            deadline,
            timeout,
            waiter,
            start,
            probe: false,
        };
        let channel = match name {
            "STOP" | "FASTSTOP" => &self.stops,
            _ => &self.requests,
        };
        let exchange = async {
            channel
                .send(request)
                .await
                .map_err(|_| self.shared.failure())?;
            answer.await.map_err(|_| self.shared.failure())?
        };
        let exchange = std::pin::pin!(tokio::time::timeout_at(deadline, exchange));
        match self.connection.call(exchange).await {
            Ok(result) => result,
            Err(_) => Err(Error::Timeout {
                command: line_again,
                timeout,
            }),
        }
    }

    async fn motion(&self, name: &'static str, line: String) -> Result<()> {
        self.submit(name, line, Expect::Fin).await.map(drop)
    }

    async fn ack(&self, name: &'static str, line: String) -> Result<()> {
        self.submit(name, line, Expect::Ack).await.map(drop)
    }

    async fn number(&self, name: &'static str, line: String) -> Result<f64> {
        let command = line.clone();
        match self.submit(name, line, Expect::Value).await? {
            Answer::Value(v) => parse_number(&v).ok_or_else(|| Error::MalformedReply {
                command,
                line: format!("{name}={v}"),
                reason: "not a finite number".into(),
            }),
            // `Expect::Value` takes only `NAME=value` (task.rs).
            Answer::Done => Err(Error::UnexpectedReply {
                command,
                line: format!("ACK {name}"),
            }),
        }
    }

    /// `HOME()`, `HOME(1)` (positive, outward) or `HOME(0)` (negative): references the fingers;
    /// resolves on `FIN HOME`. Needed before any other motion (manual chapter 2). **Differs from
    /// the binary protocol**, whose homing takes 0 = default, 1 = positive, 2 = negative; this
    /// method takes the same [`HomingDirection`] and writes GCL's form.
    ///
    /// Cancel-safe for the connection: dropped after it was sent, the gripper still homes and
    /// its `FIN` is consumed when it comes (the name `HOME` stays busy until then).
    pub async fn home(&self, direction: HomingDirection) -> Result<()> {
        let line = match direction {
            HomingDirection::Default => "HOME()",
            HomingDirection::Positive => "HOME(1)",
            HomingDirection::Negative => "HOME(0)",
        };
        self.motion("HOME", line.to_owned()).await
    }

    /// `MOVE(p)` or `MOVE(p,v)`: moves the fingers to an opening width, with an optional speed
    /// limit; resolves on `FIN MOVE`. The manual says not to grip or release with it; labs use
    /// it to open a gripper that holds a part (shared note §3.4).
    pub async fn move_to(&self, width_mm: f64, speed_mm_per_s: Option<f64>) -> Result<()> {
        let mut args = vec![("width_mm", width_mm)];
        args.extend(speed_mm_per_s.map(|v| ("speed_mm_per_s", v)));
        self.motion("MOVE", encode_call("MOVE", &args)?).await
    }

    /// `GRIP()` or `GRIP(f)`: grips inward until a part is found, with the default or the given
    /// force. Without a part the fingers grip each other and the state is still HOLDING (manual
    /// chapter 2). Resolves on `FIN GRIP`.
    pub async fn grip(&self, force_n: Option<f64>) -> Result<()> {
        let args: Vec<_> = force_n.map(|f| ("force_n", f)).into_iter().collect();
        self.motion("GRIP", encode_call("GRIP", &args)?).await
    }

    /// `GRIP(f,w)` or `GRIP(f,w,v)`: grips a part expected at `part_width_mm` (inward or
    /// outward, from where the fingers are), within the part width tolerance (PWT) and clamping
    /// travel (CLT). Resolves on `FIN GRIP`; no part fails with E_CMD_FAILED, a collision
    /// before the tolerance zone with E_AXIS_BLOCKED (manual chapter 2).
    pub async fn grip_part(
        &self,
        force_n: f64,
        part_width_mm: f64,
        speed_mm_per_s: Option<f64>,
    ) -> Result<()> {
        let mut args = vec![("force_n", force_n), ("part_width_mm", part_width_mm)];
        args.extend(speed_mm_per_s.map(|v| ("speed_mm_per_s", v)));
        self.motion("GRIP", encode_call("GRIP", &args)?).await
    }

    /// `RELEASE()`, `RELEASE(d)` or `RELEASE(d,v)`: opens **by** `pull_back_mm` from where the
    /// fingers are (the web interface's default without it). **Differs from the binary
    /// protocol**, whose release takes an absolute opening width. Only after a `GRIP` (manual
    /// chapter 2). Resolves on `FIN RELEASE`.
    pub async fn release(
        &self,
        pull_back_mm: Option<f64>,
        speed_mm_per_s: Option<f64>,
    ) -> Result<()> {
        let args: Vec<_> = match (pull_back_mm, speed_mm_per_s) {
            (None, None) => vec![],
            (Some(d), None) => vec![("pull_back_mm", d)],
            (Some(d), Some(v)) => vec![("pull_back_mm", d), ("speed_mm_per_s", v)],
            (None, Some(_)) => {
                return Err(Error::invalid(
                    "speed_mm_per_s",
                    "RELEASE takes a speed only after a pull-back distance",
                ))
            }
        };
        self.motion("RELEASE", encode_call("RELEASE", &args)?).await
    }

    /// `STOP()`: stops a motion at once; resolves on `ACK STOP`. The motion's own call then
    /// fails with `ERR <NAME> …`, and the grip state returns to IDLE (shared note §3.7).
    ///
    /// Never waits behind other calls: it is written as soon as no other `STOP()` is on the
    /// wire, even while the queue ([`ClientConfig::queue_len`]) is full of calls waiting for a
    /// busy name.
    pub async fn stop(&self) -> Result<()> {
        self.ack("STOP", "STOP()".into()).await
    }

    /// `FASTSTOP()`: stops at once and enters FAST STOP; motions are refused until
    /// [`Client::ack_fast_stop`]. Like [`Client::stop`], never waits behind other calls.
    pub async fn fast_stop(&self) -> Result<()> {
        self.ack("FASTSTOP", "FASTSTOP()".into()).await
    }

    /// `FSACK()`: acknowledges FAST STOP; answered `ACK FSACK` also with none pending (§3.7).
    pub async fn ack_fast_stop(&self) -> Result<()> {
        self.ack("FSACK", "FSACK()".into()).await
    }

    /// `BYE()`: announces the disconnect, so closing does not raise FAST STOP; waits for
    /// `ACK BYE`, then closes the connection. Calls made afterwards, on any clone, fail with
    /// [`Error::Closed`], and so do calls still waiting for a busy name: nothing is written
    /// after `BYE()`. Answered otherwise (`ERR BYE …`, returned as [`Error::Device`]), not
    /// within its timeout ([`Error::Timeout`]), or with a line that could not be read where
    /// `ACK BYE` was due ([`Error::MalformedReply`]: nothing written after `BYE()` could tell
    /// whether it was `ACK BYE`, so a `close()` without timeout would wait for ever), the
    /// connection is closed all the same (the gripper may then raise FAST STOP). So it is
    /// when the future of `close()` is dropped after `BYE()` was written, before `ACK BYE`.
    /// Without timeout (`Duration::MAX`) it waits for `ACK BYE` at most 10 s, then fails
    /// [`Error::Timeout`] with that bound: a `BYE()` damaged on the way may be answered with
    /// nothing at all, and nothing written after it could draw an answer.
    ///
    /// While the client reconnects ([`ClientConfig::reconnect`]), in a backoff wait or an
    /// attempt, it stops at once and this returns `Ok(())` without any `BYE()`: there is no
    /// connection to send it on (the loss itself, unannounced, may have raised FAST STOP). The
    /// client is closed; calls still queued fail with [`Error::Closed`], and so does every
    /// later call. A second `close()` fails with [`Error::Closed`], as after any close. From
    /// its first poll the client no longer reconnects: dropped before `BYE()` was sent, the
    /// connection is still served, but a loss closes the client.
    pub async fn close(&self) -> Result<()> {
        // Seen by a reconnecting task at once (it reads no queue in a backoff wait).
        let first = self.shared.close.request();
        let asked = self.ack("BYE", "BYE()".into()).await;
        self.shared.close.outcome(first, asked)
    }

    /// `VERBOSE=0|1`: whether `ERR` lines carry a text besides the code (per connection, our
    /// reading). Returns the mode the gripper reports back.
    pub async fn set_verbose(&self, on: bool) -> Result<bool> {
        let line = format!("VERBOSE={}", u8::from(on));
        Ok(self.setting("VERBOSE", line).await? != 0.0)
    }

    /// A setter of this connection (`NAME=value`): sent, and remembered once the gripper
    /// accepted it, for a reconnect to restore ([`ClientConfig::reconnect`]).
    async fn setting(&self, name: &'static str, line: String) -> Result<f64> {
        let value = self.number(name, line.clone()).await?;
        self.shared
            .remember(name.to_owned(), name, line, Expect::Value);
        Ok(value)
    }

    /// `PWT?`: the part width tolerance of this connection's grips, mm.
    pub async fn part_width_tolerance_mm(&self) -> Result<f64> {
        self.number("PWT", "PWT?".into()).await
    }

    /// `PWT=x`: sets the part width tolerance for this connection's grips (reset when the
    /// connection closes, manual chapter 2); returns the value the gripper reports back.
    pub async fn set_part_width_tolerance_mm(&self, mm: f64) -> Result<f64> {
        let line = encode_set("PWT", "part width tolerance", mm)?;
        self.setting("PWT", line).await
    }

    /// `CLT?`: the clamping travel of this connection's grips, mm.
    pub async fn clamping_travel_mm(&self) -> Result<f64> {
        self.number("CLT", "CLT?".into()).await
    }

    /// `CLT=x`: sets the clamping travel for this connection's grips (reset when the
    /// connection closes); returns the value the gripper reports back.
    pub async fn set_clamping_travel_mm(&self, mm: f64) -> Result<f64> {
        let line = encode_set("CLT", "clamping travel", mm)?;
        self.setting("CLT", line).await
    }

    /// `POS?`: the opening width, mm. Answered during motion too.
    pub async fn position_mm(&self) -> Result<f64> {
        self.number("POS", "POS?".into()).await
    }

    /// `SPEED?`: the finger speed, mm/s.
    pub async fn speed_mm_per_s(&self) -> Result<f64> {
        self.number("SPEED", "SPEED?".into()).await
    }

    /// `FORCE?`: the grip force, N.
    pub async fn force_n(&self) -> Result<f64> {
        self.number("FORCE", "FORCE?".into()).await
    }

    /// `TEMP?`: the temperature, °C (chapter 3, not in our text: the form `TEMP=<float>` is
    /// our reading, shared note §3.9).
    pub async fn temperature_c(&self) -> Result<f64> {
        self.number("TEMP", "TEMP?".into()).await
    }

    /// `GRIPSTATE?`: the grip state (numbering: shared note §4.4, the binary Anhang C).
    pub async fn grip_state(&self) -> Result<GripState> {
        let v = self.number("GRIPSTATE", "GRIPSTATE?".into()).await?;
        if v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
            Ok(GripState::from_u8(v as u8))
        } else {
            Err(Error::MalformedReply {
                command: "GRIPSTATE?".into(),
                line: format!("GRIPSTATE={v}"),
                reason: "not a whole number 0–255".into(),
            })
        }
    }

    /// Every push from now on (`@NAME=value`), whatever `AUTOSEND` switched it on.
    pub fn pushes(&self) -> Pushes {
        self.subscribe(None)
    }

    fn subscribe(&self, filter: Option<Quantity>) -> Pushes {
        let (pushes, subscriber) = Pushes::new(filter, self.config.push_buffer);
        if let Ok(mut subs) = self.shared.subscribers.lock() {
            // Streams already dropped go now, not only when a push arrives: a program that
            // retries a refused `AUTOSEND` (its stream dropped with the error) on a gripper
            // that pushes nothing would otherwise grow this list without bound.
            subs.retain(|s| !s.is_closed());
            if !self.is_closed() {
                subs.push(subscriber);
            }
        }
        pushes
    }

    /// `AUTOSEND("NAME",ms)` or `AUTOSEND("NAME",ms,true)`: asks the gripper to push
    /// `quantity` every `interval_ms` (or, with `only_on_change`, when it changes), and
    /// returns the stream of those pushes, subscribed before the command went out. Resolves on
    /// `ACK AUTOSEND`. AUTOSEND is in chapter 3, which we do not have: the quoted name and the
    /// pushes' form are pinned by a hardware-run driver; the interval in ms, the flag and the
    /// `ACK` are our reading (shared note §3.10).
    pub async fn autosend(
        &self,
        quantity: Quantity,
        interval_ms: u16,
        only_on_change: bool,
    ) -> Result<Pushes> {
        let pushes = self.subscribe(Some(quantity));
        let flag = if only_on_change { ",true" } else { "" };
        let line = format!("AUTOSEND(\"{}\",{interval_ms}{flag})", quantity.name());
        self.ack("AUTOSEND", line.clone()).await?;
        let key = format!("AUTOSEND {}", quantity.name());
        if interval_ms == 0 {
            self.shared.forget(&key);
        } else {
            self.shared.remember(key, "AUTOSEND", line, Expect::Ack);
        }
        Ok(pushes)
    }

    /// `AUTOSEND("NAME",0)`: stops pushing `quantity` (interval 0 = off is our reading).
    pub async fn stop_autosend(&self, quantity: Quantity) -> Result<()> {
        let line = format!("AUTOSEND(\"{}\",0)", quantity.name());
        self.ack("AUTOSEND", line).await?;
        self.shared.forget(&format!("AUTOSEND {}", quantity.name()));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

    /// Issue 29 O: a program retrying an `AUTOSEND` the gripper refuses drops a stream each
    /// time; with no push ever arriving, only `subscribe` can remove them, and must, or the
    /// list grows for as long as the program retries.
    #[tokio::test]
    async fn refused_autosend_retries_leave_no_subscribers_behind() {
        let (ours, theirs) = tokio::io::duplex(4096);
        let client = Client::from_io(ours, ClientConfig::default());
        let gripper = tokio::spawn(async move {
            let (read, mut write) = tokio::io::split(theirs);
            let mut lines = BufReader::new(read).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                let name = line.split('(').next().unwrap_or_default().to_owned();
                let _ = write.write_all(format!("ERR {name} 2\n").as_bytes()).await;
            }
        });
        for _ in 0..100 {
            let refused = client.autosend(Quantity::Position, 50, false).await;
            assert!(refused.is_err(), "{refused:?}");
        }
        let left = client.shared.subscribers.lock().unwrap().len();
        assert!(left <= 1, "{left} subscribers kept for dropped streams");
        drop(client);
        gripper.await.unwrap();
    }
}
