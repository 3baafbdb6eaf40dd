//! The async client: a cheap, cloneable handle to a background task that owns the TCP connection.

mod pairing;
mod task;

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use tokio::net::{TcpStream, ToSocketAddrs};
use tokio::sync::{mpsc, oneshot};

use super::error::{Error, Malformed, Result};
use super::frame::PROTOCOL_VERSION;
use super::message::{Grasp, GraspRequest, ObjectCount, Request, Response, ResponseBody};
use super::pose::Pose;
use super::types::{
    GraspFeedback, MessageType, PoseFormat, ResponseCode, RobotSystem, ServerState,
};
use task::Call;

/// The server's TCP port (manual 1.1).
pub const DEFAULT_PORT: u16 = 42001;

/// Calls queued towards the task, at most; more callers wait (within their timeouts).
const CALL_QUEUE: usize = 32;

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
    pub project_index: Option<u32>,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            connect_timeout: Duration::from_secs(5),
            query_timeout: Duration::from_secs(2),
            detection_timeout: Duration::from_secs(30),
            robot_system: None,
            project_index: None,
        }
    }
}

/// The outcome of GET_GRASP. NO_OBJECT and NO_GRASP are normal results in a picking loop (the
/// bin is empty, or nothing is graspable right now), so they are values, not errors; ERROR and
/// undefined codes are [`Error::Refused`].
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
#[derive(Debug, Clone)]
pub struct Client {
    calls: mpsc::Sender<Call>,
    closed: Arc<OnceLock<Error>>,
    query_timeout: Duration,
    detection_timeout: Duration,
}

impl Client {
    /// Connects and runs the manual's opening sequence (manual 6): GET_PROTOCOL_VERSION (the
    /// server must speak v3 or newer), GET_STATE (must be OPERATIONAL), REGISTER_CLIENT and
    /// SET_PROJECT when configured. After it, the robot program is one call away from
    /// [`get_grasp`](Self::get_grasp).
    pub async fn connect(addr: impl ToSocketAddrs, config: ClientConfig) -> Result<Client> {
        let client = Client::connect_without_opening(addr, config.clone()).await?;
        let server_version = client.get_protocol_version().await?;
        if server_version < PROTOCOL_VERSION {
            return Err(Error::ServerTooOld {
                server_version,
                client_version: PROTOCOL_VERSION,
            });
        }
        let state = client.get_state().await?;
        if state != ServerState::Operational {
            return Err(Error::NotOperational { state });
        }
        if let Some(robot) = config.robot_system {
            client.register_client(robot).await?;
        }
        if let Some(project) = config.project_index {
            client.set_project(project).await?;
        }
        tracing::info!(server_version, "smartgrasp session open");
        Ok(client)
    }

    /// Connects without sending anything (`config`'s opening-sequence fields are not used).
    pub async fn connect_without_opening(
        addr: impl ToSocketAddrs,
        config: ClientConfig,
    ) -> Result<Client> {
        let stream = tokio::time::timeout(config.connect_timeout, TcpStream::connect(addr))
            .await
            .map_err(|_| {
                Error::from(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    "connecting to the Smart Grasping server timed out",
                ))
            })??;
        // Requests are single 80-byte writes waiting for an answer: do not let Nagle hold them.
        stream.set_nodelay(true)?;
        let (calls, rx) = mpsc::channel(CALL_QUEUE);
        let closed = Arc::new(OnceLock::new());
        tokio::spawn(task::run(stream, rx, Arc::clone(&closed)));
        Ok(Client {
            calls,
            closed,
            query_timeout: config.query_timeout,
            detection_timeout: config.detection_timeout,
        })
    }

    /// A handle to the same connection whose calls all use `timeout`.
    pub fn with_timeout(&self, timeout: Duration) -> Client {
        Client {
            query_timeout: timeout,
            detection_timeout: timeout,
            ..self.clone()
        }
    }

    /// Whether the connection is closed (every call would fail).
    pub fn is_closed(&self) -> bool {
        self.calls.is_closed()
    }

    /// GET_PROTOCOL_VERSION: the server's highest protocol version (manual 3.3.2.1).
    pub async fn get_protocol_version(&self) -> Result<u16> {
        match self.expect_success(Request::GetProtocolVersion).await? {
            ResponseBody::ProtocolVersion(v) => Ok(v),
            other => Err(unexpected_body(other)),
        }
    }

    /// GET_STATE: the server's state (manual 3.3.2.2).
    pub async fn get_state(&self) -> Result<ServerState> {
        match self.expect_success(Request::GetState).await? {
            ResponseBody::State(s) => Ok(s),
            other => Err(unexpected_body(other)),
        }
    }

    /// REGISTER_CLIENT: tells the server which robot system this is (manual 3.3.2.3).
    pub async fn register_client(&self, robot: RobotSystem) -> Result<()> {
        self.expect_success(Request::RegisterClient(robot)).await?;
        Ok(())
    }

    /// SET_PROJECT: activates the project with `project_index` (manual 3.3.2.4).
    pub async fn set_project(&self, project_index: u32) -> Result<()> {
        self.expect_success(Request::SetProject { project_index })
            .await?;
        Ok(())
    }

    /// GET_GRASP: a grasp for the current scene (manual 3.3.3.1). The pose comes back in
    /// `request.pose_format`.
    pub async fn get_grasp(&self, request: GraspRequest) -> Result<GetGraspOutcome> {
        if let PoseFormat::Unknown(_) = request.pose_format {
            return Err(Error::InvalidArgument(
                "GET_GRASP needs one of the manual's pose formats to read the grasp pose",
            ));
        }
        let response = self.call(Request::GetGrasp(request)).await?;
        match (response.code, response.body) {
            (ResponseCode::Success, ResponseBody::Grasp(grasp)) => {
                Ok(GetGraspOutcome::Grasp(grasp))
            }
            (ResponseCode::NoObject, _) => Ok(GetGraspOutcome::NoObject),
            (ResponseCode::NoGrasp, _) => Ok(GetGraspOutcome::NoGrasp),
            (ResponseCode::InvalidObjectClass, _) => Ok(GetGraspOutcome::InvalidObjectClass),
            (ResponseCode::Success, other) => Err(unexpected_body(other)),
            (code, _) => Err(Error::Refused {
                message_type: MessageType::GetGrasp,
                code,
            }),
        }
    }

    /// GRASP_FEEDBACK: reports the result of the last grasp (manual 3.3.3.2).
    pub async fn grasp_feedback(&self, feedback: GraspFeedback) -> Result<()> {
        self.expect_success(Request::GraspFeedback(feedback))
            .await?;
        Ok(())
    }

    /// GET_OBJECT_COUNT: counts the objects of the scene, and those of `object_class` (0 = all)
    /// (manual 3.3.4.1). INVALID_OBJECT_CLASS is [`Error::Refused`].
    pub async fn get_object_count(&self, object_class: u16) -> Result<ObjectCount> {
        match self
            .expect_success(Request::GetObjectCount { object_class })
            .await?
        {
            ResponseBody::ObjectCount(c) => Ok(c),
            other => Err(unexpected_body(other)),
        }
    }

    /// ROBOT_POSE: tells the server the end effector's pose in the robot base frame, in any of
    /// the four formats (manual 3.3.5.1).
    pub async fn robot_pose(&self, pose: Pose) -> Result<()> {
        self.expect_success(Request::RobotPose(pose)).await?;
        Ok(())
    }

    /// Sends any request and returns the checked, typed response whatever its response code.
    /// Header, message type and counter are checked; the response code is left to the caller.
    pub async fn call(&self, request: Request) -> Result<Response> {
        let message_type = request.message_type();
        let timeout = match message_type {
            MessageType::GetGrasp | MessageType::GetObjectCount | MessageType::SetProject => {
                self.detection_timeout
            }
            _ => self.query_timeout,
        };
        let (reply, answer) = oneshot::channel();
        let exchange = async {
            let call = Call {
                frame: request.to_frame(),
                reply,
            };
            self.calls.send(call).await.map_err(|_| self.closed())?;
            answer.await.map_err(|_| self.closed())?
        };
        let frame = tokio::time::timeout(timeout, exchange)
            .await
            .map_err(|_| Error::Timeout {
                message_type,
                timeout,
            })??;
        Ok(Response::from_frame(&frame)?)
    }

    async fn expect_success(&self, request: Request) -> Result<ResponseBody> {
        let response = self.call(request).await?;
        if response.code != ResponseCode::Success {
            return Err(Error::Refused {
                message_type: response.message_type,
                code: response.code,
            });
        }
        Ok(response.body)
    }

    /// The error of a call on a connection that is gone.
    fn closed(&self) -> Error {
        task::closed_error(self.closed.get())
    }
}

/// A SUCCESS response whose body does not fit its message type cannot happen after the pairing
/// checks (the body is read by message type); reported as malformed rather than trusted.
fn unexpected_body(body: ResponseBody) -> Error {
    tracing::error!(?body, "response body does not match its message type");
    Error::Malformed(Malformed::MissingBody)
}
