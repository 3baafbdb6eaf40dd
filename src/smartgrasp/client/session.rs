//! The opening sequence (manual 6) with the version negotiation, and what the program set up,
//! which a reconnect restores.

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
    register: Option<Request>,
    project: Option<Request>,
    tool: Option<Request>,
    workspace: Option<Request>,
}

impl Session {
    /// The set-up the configuration asks for.
    pub(crate) fn from_config(config: &ClientConfig) -> Session {
        Session {
            register: config.robot_system.map(Request::RegisterClient),
            project: config
                .project_index
                .map(|project_index| Request::SetProject { project_index }),
            tool: config.tool_id.map(|tool_id| Request::SetTool { tool_id }),
            workspace: config
                .workspace_id
                .map(|workspace_id| Request::SetWorkspace { workspace_id }),
        }
    }

    /// Remembers a set-up request the server accepted (whoever waited for its answer).
    pub(crate) fn record(&mut self, request: &AnyRequestFrame, response: &AnyResponseFrame) {
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
        *slot = Some(request);
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
    pub(crate) async fn open(&self, link: &mut Link, config: &ClientConfig) -> Result<Opened> {
        link.set_version(PROTOCOL_VERSION);
        let server_version =
            match success(link.exchange(&Request::GetProtocolVersion, config).await?)? {
                ResponseBody::ProtocolVersion(v) => v,
                other => return Err(unexpected_body(other)),
            };
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
        match success(link.exchange(&Request::GetState, config).await?)? {
            ResponseBody::State(ServerState::Operational) => {}
            ResponseBody::State(state) => return Err(Error::NotOperational { state }),
            other => return Err(unexpected_body(other)),
        }
        let mut registration = None;
        if let Some(request) = &self.register {
            let code = link.exchange(request, config).await?.code;
            if code != ResponseCode::Success {
                tracing::warn!(%code, ?request, "smartgrasp: REGISTER_CLIENT was not accepted; going on (manual 3.3.2.3: informational)");
            }
            registration = Some(code);
        }
        for request in [&self.project, &self.tool, &self.workspace]
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
            success(link.exchange(request, config).await?)?;
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
