//! The async client: a cheap, cloneable handle to a background task that owns the TCP connection
//! (calls poll it inline to send their requests, see
//! [Where a client's work runs](crate#where-a-clients-work-runs)).

mod in_flight;
mod link;
mod pairing;
mod session;
mod shutdown;
mod task;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU16, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use tokio::net::ToSocketAddrs;
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Timeout;

use super::error::{Error, Result};
use super::frame::AnyResponseFrame;
use super::message::{Grasp, GraspRequest, ObjectCount, Request, Response, ResponseBody};
use super::pose::Pose;
use super::types::{
    GraspFeedback, MessageType, PoseFormat, ResponseCode, RobotSystem, ServerState,
};
use crate::client_stream::ClientStream;
use crate::connection::Connection;
use crate::reconnect::{ConnectionEvents, EventSender, EventSubscriber, ReconnectPolicy};
use crate::supervisor::CloseRequest;
use in_flight::CallTimeout;
use link::{Call, Link, Opener};
use session::{success, unexpected_body, Opened, Session};

/// The server's TCP port (manual 1.1).
pub const DEFAULT_PORT: u16 = 42001;

/// Calls queued towards the task, at most; more callers wait (within their timeouts).
const CALL_QUEUE: usize = 32;

/// Connection events each [`Client::connection_events`] stream buffers, at most.
const EVENT_BUFFER: usize = 32;

/// How to connect and what the opening sequence of [`Client::connect`] does.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Timeout of the TCP connect.
    pub connect_timeout: Duration,
    /// Timeout of the quick calls: GET_PROTOCOL_VERSION, GET_STATE, REGISTER_CLIENT,
    /// GRASP_FEEDBACK, ROBOT_POSE.
    pub query_timeout: Duration,
    /// Timeout of the calls that may wait for image capture, detection or loading a project:
    /// GET_GRASP, GET_OBJECT_COUNT, SET_PROJECT.
    pub detection_timeout: Duration,
    /// Robot system to register in the opening sequence (`None`: skip REGISTER_CLIENT, which the
    /// manual allows for systems it does not list).
    pub robot_system: Option<RobotSystem>,
    /// Project to activate in the opening sequence (`None`: keep the server's active project).
    /// V3: the project index; V4: the project ID seen in the web frontend (see
    /// [`Request::SetProject`]).
    pub project_index: Option<u32>,
    /// V4 only: the tool ID to choose with SET_TOOL in the opening sequence (`None`: keep the
    /// server's). Skipped, with a warning, on a V3 connection, where each GET_GRASP names its
    /// tool ([`GraspRequest::tool`]).
    pub tool_id: Option<u16>,
    /// V4 only: the workspace ID to choose with SET_WORKSPACE in the opening sequence (`None`:
    /// keep the server's). Skipped, with a warning, on a V3 connection.
    pub workspace_id: Option<u16>,
    /// The protocol version to speak: `None` (the default) negotiates the highest version both
    /// speak (3 or 4; GET_PROTOCOL_VERSION first, asked as V3, which every server since V3
    /// answers); `Some(3)` or `Some(4)` pins it, and a server below the pinned version fails the
    /// connect with [`Error::ServerTooOld`]. V4's layout is known only from SCHUNK's public KUKA
    /// example (see the module docs).
    pub protocol_version: Option<u16>,
    /// Reconnect after a lost connection (`None`, the default: a lost connection stays closed
    /// and every later call fails with [`Error::ConnectionLost`]).
    ///
    /// With a policy, when the connection breaks (the server closed it, I/O failed, or a reply
    /// broke the protocol):
    /// - the calls in flight fail ([`Error::ConnectionLost`], or the error that broke it); they
    ///   are **never sent again** by the client: a GET_GRASP or GRASP_FEEDBACK may have been
    ///   acted on by the server, and only the program can tell whether to repeat it;
    /// - the client reconnects with the policy's backoff and runs the opening sequence again:
    ///   GET_PROTOCOL_VERSION, GET_STATE, and the last REGISTER_CLIENT and SET_PROJECT the server
    ///   accepted (from this configuration or from the program's own calls);
    /// - calls that were still queued (not yet sent) and calls made meanwhile **wait** in the
    ///   queue, within their own timeouts, and go out once the session is restored, in the
    ///   protocol version that reconnect negotiated (a call is encoded again if the server's
    ///   version changed, e.g. a firmware rollback to V3; one whose request does not exist in
    ///   the new version fails with [`Error::Request`], unsent); a call that times out while
    ///   waiting was never sent;
    /// - each step is reported through [`Client::connection_events`] and `tracing`.
    ///
    /// When the policy gives up, the client is closed like one without a policy. After
    /// [`Client::close`], nothing reconnects.
    pub reconnect: Option<ReconnectPolicy>,
    /// How long past a call's own timeout (the configured one of its type, or
    /// [`Client::with_timeout`]'s) a missing response is tolerated before the connection is
    /// given up as lost ([`Error::ConnectionLost`]; then reconnected if [`reconnect`] is set).
    /// A server that stays connected but stops answering would otherwise keep every slot busy,
    /// and every later call would time out for ever. Default 30 s, like GRIPLINK's.
    ///
    /// [`reconnect`]: ClientConfig::reconnect
    pub give_up_after: Duration,
    /// Trust the response counter (default `false`). Manual 3.2.2.3 only says the counter rises
    /// with every response and wraps at 256, not whether it counts per connection or across all
    /// of a server's clients. By default a gap is recorded ([`Client::counter_gaps`] and a
    /// `tracing` warning) and the call gets its response. With `true`, a gap of `k` fails the
    /// `k` oldest waiting calls with [`Error::ResponseLost`], and a gap no waiting call explains
    /// breaks the connection, and a response byte-identical to the previous one is skipped as a
    /// copy: only for a server known to count per connection.
    pub strict_response_counter: bool,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            connect_timeout: Duration::from_secs(5),
            query_timeout: Duration::from_secs(2),
            detection_timeout: Duration::from_secs(30),
            robot_system: None,
            project_index: None,
            tool_id: None,
            workspace_id: None,
            protocol_version: None,
            reconnect: None,
            give_up_after: Duration::from_secs(30),
            strict_response_counter: false,
        }
    }
}

/// What the task shares with the handles besides the call channel.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    /// Responses whose counter skipped (see [`Client::counter_gaps`]).
    pub counter_gaps: AtomicU64,
    /// The response code of the last REGISTER_CLIENT of an opening sequence (see
    /// [`Client::registration`]).
    pub registration: Mutex<Option<ResponseCode>>,
    /// The protocol version the connection speaks (see [`Client::protocol_version`]).
    pub version: AtomicU16,
    /// The server's highest version (see [`Client::server_version`]).
    pub server_version: AtomicU16,
}

impl Shared {
    /// A connection that has not negotiated yet speaks `version`.
    fn new(version: u16) -> Shared {
        Shared {
            version: AtomicU16::new(version),
            ..Shared::default()
        }
    }

    /// Records what an opening sequence found out.
    pub(crate) fn set_opened(&self, opened: &Opened) {
        *self
            .registration
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = opened.registration;
        self.version.store(opened.version, Ordering::SeqCst);
        self.server_version
            .store(opened.server_version, Ordering::SeqCst);
    }
}

impl ClientConfig {
    pub(crate) fn timeouts(&self) -> Timeouts {
        Timeouts {
            query: self.query_timeout,
            detection: self.detection_timeout,
        }
    }
}

/// The two call timeouts, and where a call is bounded by its timeout.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Timeouts {
    query: Duration,
    detection: Duration,
}

impl Timeouts {
    pub(crate) fn for_type(self, message_type: MessageType) -> Duration {
        match message_type {
            MessageType::GetGrasp
            | MessageType::GetObjectCount
            | MessageType::SetProject
            | MessageType::SetTool
            | MessageType::SetWorkspace => self.detection,
            _ => self.query,
        }
    }

    /// `exchange` (send `message_type`'s request, get its checked response frame) bounded by
    /// its timeout; on expiry the call fails with [`expired`](Self::expired).
    fn bound<F: std::future::Future>(self, message_type: MessageType, exchange: F) -> Timeout<F> {
        tokio::time::timeout(self.for_type(message_type), exchange)
    }

    /// These timeouts, none shorter than `at_least` (a set-up request restored with the timeout
    /// it was once answered within, see `Session::open`).
    pub(crate) fn at_least(self, at_least: Duration) -> Timeouts {
        Timeouts {
            query: self.query.max(at_least),
            detection: self.detection.max(at_least),
        }
    }

    /// The error of a `message_type` call that ran out of time.
    fn expired(self, message_type: MessageType) -> Error {
        Error::Timeout {
            message_type,
            timeout: self.for_type(message_type),
        }
    }

    /// Runs `exchange` within its timeout (see [`bound`](Self::bound)).
    async fn run(
        self,
        message_type: MessageType,
        exchange: impl std::future::Future<Output = Result<AnyResponseFrame>>,
    ) -> Result<AnyResponseFrame> {
        let answered = self.bound(message_type, exchange).await;
        answered.map_err(|_| self.expired(message_type))?
    }
}

/// The outcome of GET_GRASP. NO_OBJECT and NO_GRASP are normal results in a picking loop (the
/// bin is empty, or nothing is graspable right now), so they are values, not errors; ERROR and
/// undefined codes are [`Error::Device`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[must_use]
pub enum GetGraspOutcome {
    /// SUCCESS: a grasp.
    Grasp(Grasp),
    /// NO_OBJECT: no object (of the requested class) was found.
    NoObject,
    /// NO_GRASP: objects were found, but no grasp for them.
    NoGrasp,
    /// INVALID_OBJECT_CLASS: the requested class is invalid or does not exist.
    InvalidObjectClass,
}

/// Handle to a Smart Grasping server connection. `Clone + Send + Sync`: clone it into as many
/// tasks as needed; calls are sent in order (pipelined, at most 16 unanswered) and each gets its
/// own response. Dropping the last handle closes the connection.
///
/// Every call has a timeout ([`ClientConfig`], or [`Client::with_timeout`] per call). A call that
/// times out or is dropped keeps its place in the pairing: its late reply is discarded, never
/// handed to the next caller.
///
/// # Cancellation
///
/// Every call is cancel-safe in the sense that dropping its future (a `select!`, a timeout, an
/// aborted task) never disturbs the connection or another call. What a dropped call did on the
/// server depends on how far it got, which its caller cannot know:
/// - dropped while queued (before the task sent it): nothing was sent, and nothing will be;
/// - dropped after its request went out: the server receives it and **acts on it** (REGISTER_CLIENT
///   registers, SET_PROJECT switches the project, GET_GRASP makes its grasp the one the next
///   feedback refers to, GRASP_FEEDBACK is recorded for whatever the server does with it); its
///   reply is discarded.
///
/// A timed-out call ([`Error::Timeout`]) means the same: it may or may not have been acted on.
#[derive(Debug, Clone)]
pub struct Client {
    /// The background task; calls poll it inline to send their requests (see
    /// `crate::connection`).
    connection: Connection,
    calls: mpsc::Sender<Call>,
    closed: Arc<OnceLock<Error>>,
    events: EventSubscriber,
    timeouts: Timeouts,
    /// Set by the first `close()` (later calls fail with [`Error::Closed`]); tells the task to
    /// end (see `task.rs`).
    close: CloseRequest,
    shared: Arc<Shared>,
}

impl Client {
    /// Connects and runs the manual's opening sequence (manual 6): GET_PROTOCOL_VERSION (the
    /// server must speak v3 or newer), GET_STATE (must be OPERATIONAL), REGISTER_CLIENT and
    /// SET_PROJECT when configured. After it, the robot program is one call away from
    /// [`get_grasp`](Self::get_grasp).
    ///
    /// A failure here is returned, whatever [`ClientConfig::reconnect`] says: reconnecting is for
    /// a session that was open. Cancel-safe: dropping the future closes the new connection.
    pub async fn connect(addr: impl ToSocketAddrs, config: ClientConfig) -> Result<Client> {
        let addrs = link::within_connect_timeout(config.connect_timeout, resolve(addr)).await?;
        let shared = Arc::new(Shared::new(crate::smartgrasp::frame::PROTOCOL_VERSION));
        let opener = Opener::Tcp(addrs);
        let mut link = Link::connect(&opener, &config, &shared).await?;
        let session = Session::from_config(&config);
        let opened = session.open(&mut link, &config).await?;
        shared.set_opened(&opened);
        tracing::info!(
            server_version = opened.server_version,
            version = opened.version,
            "smartgrasp session open"
        );
        Ok(Client::spawn(link, opener, session, config, shared))
    }

    /// As [`connect`](Self::connect), over the byte streams `open` opens instead of TCP: one
    /// now, and with [`ClientConfig::reconnect`] a new one after each loss (e.g. a tunnel, or
    /// in-memory pipes to
    /// [`SimServer::serve_stream`](crate::smartgrasp::sim::SimServer::serve_stream), so that a
    /// test exercises reconnecting without sockets). Each open is bounded by
    /// [`ClientConfig::connect_timeout`]; the opening sequence runs as with `connect`. A failure
    /// here is returned whatever the reconnect policy says.
    pub async fn open_with<F, Fut, S>(open: F, config: ClientConfig) -> Result<Client>
    where
        F: Fn() -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = std::io::Result<S>> + Send + 'static,
        S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Send + Unpin + 'static,
    {
        let (stream, open) = link::within_connect_timeout(config.connect_timeout, async {
            Ok(crate::reconnect::first_open(open).await?)
        })
        .await?;
        let shared = Arc::new(Shared::new(crate::smartgrasp::frame::PROTOCOL_VERSION));
        let mut link = Link::over(ClientStream::Boxed(stream), &config, &shared);
        let session = Session::from_config(&config);
        let opened = session.open(&mut link, &config).await?;
        shared.set_opened(&opened);
        Ok(Client::spawn(
            link,
            Opener::Custom(open),
            session,
            config,
            shared,
        ))
    }

    /// Connects without sending anything (`config`'s opening-sequence fields are not used; a
    /// reconnect runs GET_PROTOCOL_VERSION and GET_STATE, then restores what the program set up
    /// with its own calls). Speaks [`ClientConfig::protocol_version`], V3 if `None` (nothing is
    /// negotiated), on every connection: a reconnect pins that version as if configured (a
    /// server that no longer speaks it is [`Error::ServerTooOld`]), so the calls' shapes never
    /// change under the program (a V3 GET_GRASP's tool). Cancel-safe like
    /// [`connect`](Self::connect).
    pub async fn connect_without_opening(
        addr: impl ToSocketAddrs,
        mut config: ClientConfig,
    ) -> Result<Client> {
        let addrs = link::within_connect_timeout(config.connect_timeout, resolve(addr)).await?;
        let version = config
            .protocol_version
            .unwrap_or(crate::smartgrasp::frame::PROTOCOL_VERSION);
        session::check_pinned(version)?;
        // The reconnect's opening sequence negotiates unless a version is pinned: pin the one
        // this connection speaks (issue 29 I).
        config.protocol_version = Some(version);
        let shared = Arc::new(Shared::new(version));
        let opener = Opener::Tcp(addrs);
        let mut link = Link::connect(&opener, &config, &shared).await?;
        link.set_version(version);
        Ok(Client::spawn(
            link,
            opener,
            Session::default(),
            config,
            shared,
        ))
    }

    fn spawn(
        link: Link,
        opener: Opener,
        session: Session,
        config: ClientConfig,
        shared: Arc<Shared>,
    ) -> Client {
        let (calls, rx) = mpsc::channel(CALL_QUEUE);
        let closed = Arc::new(OnceLock::new());
        let events = EventSender::new("smartgrasp", EVENT_BUFFER);
        let close = CloseRequest::default();
        let (subscriber, timeouts) = (events.subscriber(), config.timeouts());
        let task = task::Task {
            calls: rx,
            closed: Arc::clone(&closed),
            session,
            config,
            opener,
            events,
            shutdown: close.clone(),
            shared: Arc::clone(&shared),
        };
        Client {
            connection: Connection::spawn(task::run(link, task)),
            calls,
            closed,
            events: subscriber,
            timeouts,
            close,
            shared,
        }
    }

    /// A handle to the same connection whose calls all use `timeout`. The connection is given
    /// up only when a response stays away [`ClientConfig::give_up_after`] beyond the call's own
    /// timeout, so a longer `timeout` for a slow SET_PROJECT or detection keeps a healthy
    /// connection (and, with [`ClientConfig::reconnect`], does not re-open the session).
    pub fn with_timeout(&self, timeout: Duration) -> Client {
        Client {
            timeouts: Timeouts {
                query: timeout,
                detection: timeout,
            },
            ..self.clone()
        }
    }

    /// The protocol version the connection speaks (3 or 4), as the last opening sequence
    /// negotiated it (see [`ClientConfig::protocol_version`]).
    pub fn protocol_version(&self) -> u16 {
        self.shared.version.load(Ordering::SeqCst)
    }

    /// The server's highest protocol version, from the last opening sequence's
    /// GET_PROTOCOL_VERSION (0 after [`connect_without_opening`](Self::connect_without_opening)
    /// until a reconnect).
    pub fn server_version(&self) -> u16 {
        self.shared.server_version.load(Ordering::SeqCst)
    }

    /// How many responses so far carried a response counter other than the one due (one more
    /// than the last response's, manual 3.2.2.3), over every connection of this client. By
    /// default such a gap is only recorded (see [`ClientConfig::strict_response_counter`]); a
    /// rising count with a server shared by several clients suggests the server counts across
    /// them.
    pub fn counter_gaps(&self) -> u64 {
        self.shared.counter_gaps.load(Ordering::Relaxed)
    }

    /// The response code the server gave the REGISTER_CLIENT of the last opening sequence (the
    /// connect, or the last reconnect); `None` if none was sent. Manual 3.3.2.3 calls the
    /// message informational, so a code other than SUCCESS is reported here and in a `tracing`
    /// warning, and does not fail the connect.
    pub fn registration(&self) -> Option<ResponseCode> {
        *self
            .shared
            .registration
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Whether the connection is closed for good (every call would fail). While the client
    /// reconnects it is not closed.
    pub fn is_closed(&self) -> bool {
        self.calls.is_closed()
    }

    /// Ends the connection for every clone of this handle, and stops any reconnecting. Calls
    /// waiting for a response and calls queued fail with [`Error::Closed`], and so does every
    /// later call. No message type of V3 or V4 ends a session (manual 3.3): the TCP
    /// connection is simply closed. Returns once the connection is released; [`Error::Closed`]
    /// if the client was already closed with `close()`.
    ///
    /// Cancel-safe: dropping the future after its first poll does not undo the close.
    pub async fn close(&self) -> Result<()> {
        if !self.close.request() {
            return Err(Error::Closed);
        }
        // The task closes the channel (or drops it) when it ends, and the socket with it.
        self.calls.closed().await;
        Ok(())
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
    /// use gripper::reconnect::{ConnectionEvent, ReconnectPolicy};
    /// use gripper::smartgrasp::sim::{SimConfig, SimServer};
    /// use gripper::smartgrasp::{codec, Client, ClientConfig, RobotSystem};
    ///
    /// let server = SimServer::bind("127.0.0.1:0", SimConfig::default()).await?;
    /// // A proxy to pull the cable with.
    /// let framing = Framing::Custom(codec::proxy_frame_len);
    /// let proxy = FaultProxy::start_with(server.local_addr(), ProxyConfig::new().framing(framing)).await?;
    /// let config = ClientConfig {
    ///     robot_system: Some(RobotSystem::Ur),
    ///     reconnect: Some(ReconnectPolicy::default()),
    ///     ..ClientConfig::default()
    /// };
    /// let client = Client::connect(proxy.local_addr(), config).await?;
    /// let mut events = client.connection_events();
    ///
    /// proxy.cut_connections();
    /// while let Some(event) = events.next().await {
    ///     println!("{event}");
    ///     if let ConnectionEvent::Restored { .. } = event {
    ///         break;
    ///     }
    /// }
    /// // Registered again on the new connection.
    /// assert_eq!(server.registered_clients(), [RobotSystem::Ur, RobotSystem::Ur]);
    /// client.get_state().await?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn connection_events(&self) -> ConnectionEvents {
        self.events.subscribe()
    }

    /// GET_PROTOCOL_VERSION: the server's highest protocol version (manual 3.3.2.1).
    /// Cancel-safe; a cancelled call has no effect on the server.
    pub async fn get_protocol_version(&self) -> Result<u16> {
        match self.expect_success(Request::GetProtocolVersion).await? {
            ResponseBody::ProtocolVersion(v) => Ok(v),
            other => Err(unexpected_body(other)),
        }
    }

    /// GET_STATE: the server's state (manual 3.3.2.2).
    /// Cancel-safe; a cancelled call has no effect on the server.
    pub async fn get_state(&self) -> Result<ServerState> {
        match self.expect_success(Request::GetState).await? {
            ResponseBody::State(s) => Ok(s),
            other => Err(unexpected_body(other)),
        }
    }

    /// REGISTER_CLIENT: tells the server which robot system this is (manual 3.3.2.3). A reconnect
    /// registers again with the last system the server accepted.
    /// Cancel-safe (see [`Client`]); a cancelled call may still have registered.
    pub async fn register_client(&self, robot: RobotSystem) -> Result<()> {
        self.expect_success(Request::RegisterClient(robot)).await?;
        Ok(())
    }

    /// SET_PROJECT: activates the project with `project_index` (manual 3.3.2.4). A reconnect
    /// activates the last project the server accepted again.
    /// Cancel-safe (see [`Client`]); a cancelled call may still have switched the project.
    pub async fn set_project(&self, project_index: u32) -> Result<()> {
        self.expect_success(Request::SetProject { project_index })
            .await?;
        Ok(())
    }

    /// SET_TOOL (V4 only): chooses the tool with `tool_id`, as configured on the device
    /// (PROTOCOLS.md 2b). A reconnect chooses the last tool the server accepted again. On a V3
    /// connection [`Error::Request`], nothing sent: V3 names the tool in each GET_GRASP.
    /// Cancel-safe (see [`Client`]); a cancelled call may still have switched the tool.
    pub async fn set_tool(&self, tool_id: u16) -> Result<()> {
        self.expect_success(Request::SetTool { tool_id }).await?;
        Ok(())
    }

    /// SET_WORKSPACE (V4 only): chooses the workspace with `workspace_id`, as configured on the
    /// device (PROTOCOLS.md 2b). A reconnect chooses it again. On a V3 connection
    /// [`Error::Request`], nothing sent.
    /// Cancel-safe (see [`Client`]); a cancelled call may still have switched the workspace.
    pub async fn set_workspace(&self, workspace_id: u16) -> Result<()> {
        self.expect_success(Request::SetWorkspace { workspace_id })
            .await?;
        Ok(())
    }

    /// GET_GRASP: a grasp for the current scene (manual 3.3.3.1). The pose comes back in
    /// `request.pose_format` (with V4, a quaternion is asked for in ABC and converted: V4 poses
    /// have six values). The response's pose format is the format the server used for the pose,
    /// not an echo (3.3.3.1): a pose in another format is read as the response declares and
    /// converted.
    /// Cancel-safe (see [`Client`]); a cancelled call may still have made the server pick a grasp,
    /// which the next GRASP_FEEDBACK then refers to.
    pub async fn get_grasp(&self, request: GraspRequest) -> Result<GetGraspOutcome> {
        if let PoseFormat::Unknown(_) = request.pose_format {
            return Err(Error::invalid(
                "pose format",
                "GET_GRASP needs one of the manual's pose formats to read the grasp pose",
            ));
        }
        // A V4 pose has six values (PROTOCOLS.md 2b): a quaternion is asked for in ABC, the
        // format SCHUNK's example uses, and converted here, so that cell code works with either
        // version.
        let wanted = request.pose_format;
        let mut request = request;
        if self.speaks_v4() && wanted == PoseFormat::Quaternion {
            request.pose_format = PoseFormat::Abc;
        }
        let response = self.call(Request::GetGrasp(request)).await?;
        match (response.code, response.body) {
            (ResponseCode::Success, ResponseBody::Grasp(mut grasp)) => {
                grasp.pose = grasp.pose.to_format(wanted)?;
                Ok(GetGraspOutcome::Grasp(grasp))
            }
            (ResponseCode::NoObject, _) => Ok(GetGraspOutcome::NoObject),
            (ResponseCode::NoGrasp, _) => Ok(GetGraspOutcome::NoGrasp),
            (ResponseCode::InvalidObjectClass, _) => Ok(GetGraspOutcome::InvalidObjectClass),
            (ResponseCode::Success, other) => Err(unexpected_body(other)),
            (code, _) => Err(Error::Device {
                message_type: MessageType::GetGrasp,
                status: code,
            }),
        }
    }

    /// GRASP_FEEDBACK: reports the result of the last grasp (manual 3.3.3.2). SCHUNK's own KUKA
    /// examples say the message has no effect: "Has no effect on Version 3", and in V4 "no
    /// effect" / "not yet supported with V4" (PROTOCOLS.md 2b). It is sent all the same, so that
    /// cell code works with either version and with a server that starts to use it. The scene
    /// empties because the robot takes the parts out, which the next detection sees; nothing
    /// here removes an object (the simulator can stand in for the robot, see
    /// `sim::SimConfig::feedback_removes_objects`).
    /// Cancel-safe (see [`Client`]); a cancelled call may still have reached the server.
    pub async fn grasp_feedback(&self, feedback: GraspFeedback) -> Result<()> {
        self.expect_success(Request::GraspFeedback(feedback))
            .await?;
        Ok(())
    }

    /// GET_OBJECT_COUNT: counts the objects of the scene, and those of `object_class` (0 = all)
    /// (manual 3.3.4.1). INVALID_OBJECT_CLASS is [`Error::Device`].
    /// Cancel-safe; a cancelled call has no effect on the server.
    pub async fn get_object_count(&self, object_class: u16) -> Result<ObjectCount> {
        match self
            .expect_success(Request::GetObjectCount { object_class })
            .await?
        {
            // V3 echoes the class (checked by the pairing); V4 may not (PROTOCOLS.md 2b).
            ResponseBody::ObjectCount(c) => Ok(ObjectCount { object_class, ..c }),
            other => Err(unexpected_body(other)),
        }
    }

    /// ROBOT_POSE: tells the server the end effector's pose in the robot base frame, in any of
    /// the four formats (manual 3.3.5.1). V4 carries six values (PROTOCOLS.md 2b): there a
    /// quaternion is sent as ABC, the format SCHUNK's example uses (rounded to the wire's µm and
    /// µdeg).
    /// Cancel-safe (see [`Client`]); a cancelled call may still have been recorded.
    pub async fn robot_pose(&self, pose: Pose) -> Result<()> {
        let pose = match pose {
            Pose::Quaternion(_) if self.speaks_v4() => pose.to_format(PoseFormat::Abc)?,
            _ => pose,
        };
        self.expect_success(Request::RobotPose(pose)).await?;
        Ok(())
    }

    fn speaks_v4(&self) -> bool {
        self.protocol_version() >= crate::smartgrasp::frame::v4::PROTOCOL_VERSION
    }

    /// Sends any request and returns the checked, typed response whatever its response code.
    /// Header, message type, counter and the fields a response repeats from its request are
    /// checked; the response code is left to the caller.
    /// Cancel-safe (see [`Client`]): a cancelled request may have been acted on.
    pub async fn call(&self, request: Request) -> Result<Response> {
        let message_type = request.message_type();
        let frame = request.to_any_frame(self.protocol_version())?;
        let (reply, answer) = oneshot::channel();
        let timeout = self.timeouts.for_type(message_type);
        let deadline = crate::deadline::after(tokio::time::Instant::now(), timeout);
        let exchange = async {
            let call = Call {
                request,
                frame,
                reply,
                deadline,
                timeout: CallTimeout::new(timeout),
            };
            // The queue nearly always has room: `try_send` skips building and polling a permit
            // future (issue 14). Fair all the same: a released permit goes to a waiting sender
            // before `try_send` can take it.
            match self.calls.try_send(call) {
                Ok(()) => {}
                Err(TrySendError::Full(call)) => {
                    self.calls.send(call).await.map_err(|_| self.closed())?
                }
                Err(TrySendError::Closed(_)) => return Err(self.closed()),
            }
            answer.await.map_err(|_| self.closed())?
        };
        // Bounded here rather than through `Timeouts::run` (one more `async fn` layer moved and
        // polled on every call, issue 14), by the call's own deadline (the clock read once, not
        // again for a `timeout`), and pinned in place as GRIPLINK's is: handed on by value, the
        // future (a `Call`, a timer) was copied twice more into the connection's call, about
        // 250 instructions per query together (BENCHMARKS.md, "Issue 30: the last of
        // SmartGrasp's cost").
        let exchange = std::pin::pin!(tokio::time::timeout_at(deadline, exchange));
        let answered = self.connection.call(exchange).await;
        let frame = answered.map_err(|_| self.timeouts.expired(message_type))??;
        Ok(Response::from_any_frame(&frame)?)
    }

    async fn expect_success(&self, request: Request) -> Result<ResponseBody> {
        success(self.call(request).await?)
    }

    /// The error of a call on a connection that is gone.
    fn closed(&self) -> Error {
        if self.close.is_requested() {
            return Error::Closed;
        }
        in_flight::closed_error(self.closed.get())
    }
}

/// Resolves `addr` once; a reconnect goes to the same addresses.
async fn resolve(addr: impl ToSocketAddrs) -> Result<Vec<SocketAddr>> {
    let addrs: Vec<SocketAddr> = tokio::net::lookup_host(addr).await?.collect();
    if addrs.is_empty() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the address resolved to nothing",
        )
        .into());
    }
    Ok(addrs)
}
