//! The opening sequence (manual 6) and what the program set up, which a reconnect restores.

use super::link::Link;
use super::ClientConfig;
use crate::smartgrasp::error::{Error, Malformed, Result};
use crate::smartgrasp::frame::{RequestFrame, ResponseFrame, PROTOCOL_VERSION};
use crate::smartgrasp::message::{Request, Response, ResponseBody};
use crate::smartgrasp::types::{MessageType, ResponseCode, ServerState};

/// What the program told the server: the last REGISTER_CLIENT and SET_PROJECT the server
/// accepted, from the configuration or from the program's own calls. A reconnect sends them again
/// (a new connection may be a restarted server that forgot them).
#[derive(Debug, Clone, Default)]
pub(crate) struct Session {
    register: Option<RequestFrame>,
    project: Option<RequestFrame>,
}

impl Session {
    /// The set-up the configuration asks for.
    pub(crate) fn from_config(config: &ClientConfig) -> Session {
        Session {
            register: config
                .robot_system
                .map(|robot| Request::RegisterClient(robot).to_frame()),
            project: config
                .project_index
                .map(|project_index| Request::SetProject { project_index }.to_frame()),
        }
    }

    /// Remembers a set-up request the server accepted (whoever waited for its answer).
    pub(crate) fn record(&mut self, request: &RequestFrame, response: &ResponseFrame) {
        if response.header.response_code != ResponseCode::Success {
            return;
        }
        match request.header.message_type {
            MessageType::RegisterClient => self.register = Some(*request),
            MessageType::SetProject => self.project = Some(*request),
            _ => {}
        }
    }

    /// Runs the opening sequence on a fresh connection: GET_PROTOCOL_VERSION (v3 or newer),
    /// GET_STATE (OPERATIONAL), then REGISTER_CLIENT and SET_PROJECT as set up. REGISTER_CLIENT
    /// is informational (manual 3.3.2.3): its response code is returned and warned about, never
    /// fatal.
    pub(crate) async fn open(&self, link: &mut Link, config: &ClientConfig) -> Result<Opened> {
        let server_version = match success(
            link.exchange(Request::GetProtocolVersion.to_frame(), config)
                .await?,
        )? {
            ResponseBody::ProtocolVersion(v) => v,
            other => return Err(unexpected_body(other)),
        };
        if server_version < PROTOCOL_VERSION {
            return Err(Error::ServerTooOld {
                server_version,
                client_version: PROTOCOL_VERSION,
            });
        }
        match success(link.exchange(Request::GetState.to_frame(), config).await?)? {
            ResponseBody::State(ServerState::Operational) => {}
            ResponseBody::State(state) => return Err(Error::NotOperational { state }),
            other => return Err(unexpected_body(other)),
        }
        let mut registration = None;
        if let Some(request) = self.register {
            let code = link.exchange(request, config).await?.code;
            if code != ResponseCode::Success {
                tracing::warn!(%code, robot = %request.client, "smartgrasp: REGISTER_CLIENT was not accepted; going on (manual 3.3.2.3: informational)");
            }
            registration = Some(code);
        }
        if let Some(request) = self.project {
            success(link.exchange(request, config).await?)?;
        }
        Ok(Opened {
            server_version,
            registration,
        })
    }
}

/// What an opening sequence found out.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Opened {
    /// The server's highest protocol version (GET_PROTOCOL_VERSION).
    pub server_version: u16,
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
