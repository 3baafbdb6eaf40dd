//! The opening sequence (manual 6) with the version negotiation, and what the program set up,
//! which a reconnect restores.

use std::time::Duration;

use super::in_flight::CallTimeout;
use super::link::Link;
use super::ClientConfig;
use crate::smartgrasp::error::{Error, Malformed, Result};
use crate::smartgrasp::frame::{v4, AnyRequestFrame, AnyResponseFrame, PROTOCOL_VERSION};
use crate::smartgrasp::message::{Request, Response, ResponseBody};
use crate::smartgrasp::types::{ResponseCode, ServerState};

/// The highest protocol version this client speaks.
pub(crate) const HIGHEST_VERSION: u16 = v4::PROTOCOL_VERSION;

/// What the program told the server: the last REGISTER_CLIENT, SET_PROJECT, SET_TOOL and
/// SET_WORKSPACE the server accepted, from the configuration or from the program's own calls. A
/// reconnect sends them again (a new connection may be a restarted server that forgot them).
/// Kept as typed requests, so that they are sent in whatever version the new connection speaks.
#[derive(Debug, Clone, Default)]
pub(crate) struct Session {
    register: Option<SetUp>,
    project: Option<SetUp>,
    tool: Option<SetUp>,
    workspace: Option<SetUp>,
}

/// One set-up request and the timeout it was answered within.
#[derive(Debug, Clone)]
struct SetUp {
    request: Request,
    /// The program's call's timeout (e.g. [`Client::with_timeout`](super::Client::with_timeout)
    /// for a server that loads a project slowly): the restore waits at least this long, as the
    /// configured timeout may be too short for this server (issue 29 J). `None`: from the
    /// configuration, restored with the configured timeouts.
    answered_within: Option<Duration>,
}

impl SetUp {
    fn from_config(request: Request) -> SetUp {
        SetUp {
            request,
            answered_within: None,
        }
    }
}

impl Session {
    /// The set-up the configuration asks for.
    pub(crate) fn from_config(config: &ClientConfig) -> Session {
        Session {
            register: config
                .robot_system
                .map(|system| SetUp::from_config(Request::RegisterClient(system))),
            project: config
                .project_index
                .map(|project_index| SetUp::from_config(Request::SetProject { project_index })),
            tool: config
                .tool_id
                .map(|tool_id| SetUp::from_config(Request::SetTool { tool_id })),
            workspace: config
                .workspace_id
                .map(|workspace_id| SetUp::from_config(Request::SetWorkspace { workspace_id })),
        }
    }

    /// Remembers a set-up request the server accepted (whoever waited for its answer), with the
    /// timeout of the call it was answered within.
    pub(crate) fn record(
        &mut self,
        request: &AnyRequestFrame,
        response: &AnyResponseFrame,
        timeout: CallTimeout,
    ) {
        if response.header().response_code != ResponseCode::Success {
            return;
        }
        let Ok(request) = Request::from_any_frame(request) else {
            return;
        };
        let slot = match request {
            Request::RegisterClient(_) => &mut self.register,
            Request::SetProject { .. } => &mut self.project,
            Request::SetTool { .. } => &mut self.tool,
            Request::SetWorkspace { .. } => &mut self.workspace,
            _ => return,
        };
        *slot = Some(SetUp {
            request,
            answered_within: Some(timeout.duration()),
        });
    }

    /// Runs the opening sequence on a fresh connection:
    /// 1. GET_PROTOCOL_VERSION, asked as V3: every server since V3 answers it in full (a V4 server
    ///    with 4, manual 1.3 and 3.3.2.1), where a V4 question would get a V3-only server's empty
    ///    message. The link then speaks the highest version both speak, or the pinned one
    ///    ([`ClientConfig::protocol_version`]; a server below it is [`Error::ServerTooOld`]);
    /// 2. GET_STATE (OPERATIONAL);
    /// 3. REGISTER_CLIENT, informational (manual 3.3.2.3): its response code is returned and
    ///    warned about, never fatal;
    /// 4. SET_PROJECT, then (V4 only) SET_TOOL and SET_WORKSPACE as set up. On a V3 connection a
    ///    tool or workspace id is skipped with a warning: V3 chooses the tool in each GET_GRASP.
    ///
    /// Each set-up request the program sent itself is restored with the timeout its call was
    /// answered within, if longer than the configured one: a server that took that long to
    /// load the project before takes as long again.
    pub(crate) async fn open(&self, link: &mut Link, config: &ClientConfig) -> Result<Opened> {
        let timeouts = config.timeouts();
        link.set_version(PROTOCOL_VERSION);
        let server_version = match success(
            link.exchange(&Request::GetProtocolVersion, timeouts)
                .await?,
        )? {
            ResponseBody::ProtocolVersion(v) => v,
            other => return Err(unexpected_body(other)),
        };
        link.set_server_version(server_version);
        let wanted = config.protocol_version.unwrap_or(HIGHEST_VERSION);
        check_pinned(wanted)?;
        let version = if config.protocol_version.is_some() {
            wanted
        } else {
            server_version.min(wanted)
        };
        if server_version < version || server_version < PROTOCOL_VERSION {
            return Err(Error::ServerTooOld {
                server_version,
                client_version: version,
            });
        }
        link.set_version(version);
        match success(link.exchange(&Request::GetState, timeouts).await?)? {
            ResponseBody::State(ServerState::Operational) => {}
            ResponseBody::State(state) => return Err(Error::NotOperational { state }),
            other => return Err(unexpected_body(other)),
        }
        let mut registration = None;
        if let Some(SetUp {
            request,
            answered_within,
        }) = &self.register
        {
            let within = timeouts.at_least(answered_within.unwrap_or_default());
            let code = link.exchange(request, within).await?.code;
            if code != ResponseCode::Success {
                tracing::warn!(%code, ?request, "smartgrasp: REGISTER_CLIENT was not accepted; going on (manual 3.3.2.3: informational)");
            }
            registration = Some(code);
        }
        for SetUp {
            request,
            answered_within,
        } in [&self.project, &self.tool, &self.workspace]
            .into_iter()
            .flatten()
        {
            if !request.exists_in(version) {
                tracing::warn!(
                    ?request,
                    version,
                    "smartgrasp: not a message of the protocol version the server speaks; skipped"
                );
                continue;
            }
            let within = timeouts.at_least(answered_within.unwrap_or_default());
            success(link.exchange(request, within).await?)?;
        }
        Ok(Opened {
            server_version,
            version,
            registration,
        })
    }
}

/// A version this client can speak: 3 or 4.
pub(crate) fn check_pinned(version: u16) -> Result<()> {
    if (PROTOCOL_VERSION..=HIGHEST_VERSION).contains(&version) {
        Ok(())
    } else {
        Err(Error::invalid(
            "ClientConfig::protocol_version",
            "it must be 3, 4 or None",
        ))
    }
}

/// What an opening sequence found out.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Opened {
    /// The server's highest protocol version (GET_PROTOCOL_VERSION).
    pub server_version: u16,
    /// The version the connection speaks.
    pub version: u16,
    /// REGISTER_CLIENT's response code, if it was sent.
    pub registration: Option<ResponseCode>,
}

/// The body of a SUCCESS response; any other code is [`Error::Device`].
pub(crate) fn success(response: Response) -> Result<ResponseBody> {
    if response.code != ResponseCode::Success {
        return Err(Error::Device {
            message_type: response.message_type,
            status: response.code,
        });
    }
    Ok(response.body)
}

/// A SUCCESS response whose body does not fit its message type cannot happen after the pairing
/// checks (the body is read by message type); reported as malformed rather than trusted.
pub(crate) fn unexpected_body(body: ResponseBody) -> Error {
    tracing::error!(?body, "response body does not match its message type");
    Error::MalformedReply(Malformed::MissingBody)
}
