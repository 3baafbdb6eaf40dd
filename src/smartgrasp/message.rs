//! Typed requests and responses of both protocol versions, mapped onto the frames of
//! [`frame`](super::frame) (V3, manual 3.3) and [`frame::v4`](super::frame::v4) (V4, PROTOCOLS.md
//! 2b). One [`Request`], one [`Response`] and one [`Grasp`] for both versions, so that code above
//! works with either; what only one version carries is an `Option` (responses) or is ignored by
//! the other version's frame (requests, documented per field). Pure: no I/O.

use super::frame::{v4, AnyRequestFrame, AnyResponseFrame, RequestFrame, ResponseFrame};
use super::malformed::Malformed;
use super::pose::{Pose, PoseError};
use super::types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ReferenceFrame,
    ResponseCode, RobotSystem, SelectionCriterion, ServerState, Tool,
};

/// Parameters of a GET_GRASP request (V3 manual 3.3.3.1; V4 PROTOCOLS.md 2b).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GraspRequest {
    /// Which grasps may be returned (both versions).
    pub grasp_mode: GraspMode,
    /// Class id (V4: object ID) of the target object; 0 = any class (both versions; V4's "0 = any"
    /// is what the example sends, not documented).
    pub object_class: u16,
    /// V3 only: the tool the robot grasps with (byte 14). V4 has no tool in GET_GRASP; the tool
    /// is chosen by id with SET_TOOL ([`Request::SetTool`]).
    pub tool: Tool,
    /// V4 only: the selection criterion (byte 14; values not public). Ignored in V3.
    pub selection_criterion: SelectionCriterion,
    /// The format the grasp pose should come back in (both versions; V4 pins only ABC, 17, and
    /// cannot carry a quaternion).
    pub pose_format: PoseFormat,
}

/// A request, one variant per message type (V3 manual 3.3; V4 PROTOCOLS.md 2b).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// GET_PROTOCOL_VERSION (3.3.2.1).
    GetProtocolVersion,
    /// GET_STATE (3.3.2.2).
    GetState,
    /// REGISTER_CLIENT (3.3.2.3).
    RegisterClient(RobotSystem),
    /// SET_PROJECT (3.3.2.4). V3: the project index, u32 at 46. V4: the project ID seen in the
    /// web frontend, u16 at 18 (a larger number is refused). How V3's index and V4's ID relate
    /// is not public.
    SetProject {
        /// The project's index (V3) or ID (V4).
        project_index: u32,
    },
    /// SET_TOOL (V4 only, type 5): the tool with this id configured on the device.
    SetTool {
        /// The tool ID seen in the web frontend.
        tool_id: u16,
    },
    /// SET_WORKSPACE (V4 only, type 6): the workspace with this id configured on the device.
    SetWorkspace {
        /// The workspace ID seen in the web frontend.
        workspace_id: u16,
    },
    /// GET_GRASP (3.3.3.1).
    GetGrasp(GraspRequest),
    /// GRASP_FEEDBACK (3.3.3.2). In V4 SCHUNK's example says it has no effect ("not yet
    /// supported with V4"), and sends 0.
    GraspFeedback(GraspFeedback),
    /// GET_OBJECT_COUNT (3.3.4.1).
    GetObjectCount {
        /// Class id to count; 0 = all classes.
        object_class: u16,
    },
    /// ROBOT_POSE (3.3.5.1): end effector (TCP) in the robot base frame. V4 carries six values
    /// at 24 and uses it for calibration; a quaternion cannot be sent in V4.
    RobotPose(Pose),
}

/// A request that cannot be read from a frame, or cannot be put into one.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    /// The message type is not one of the version's.
    #[error("unknown message type {0}")]
    UnknownMessageType(MessageType),
    /// The message exists only in another protocol version.
    #[error("{message_type} is not a message of protocol v{version}")]
    NotInVersion {
        /// The message type.
        message_type: MessageType,
        /// The version of the frame.
        version: u16,
    },
    /// A V4 project ID is a u16.
    #[error("project {0} does not fit V4's 16-bit project ID")]
    ProjectOutOfRange(u32),
    /// The header says it is not a request.
    #[error("communication type {0} where a request was expected")]
    NotARequest(CommunicationType),
    /// A pose (ROBOT_POSE, or GET_GRASP's wanted format) that the version cannot carry.
    #[error("robot pose: {0}")]
    Pose(PoseError),
}

impl Request {
    /// The request's message type.
    pub fn message_type(&self) -> MessageType {
        match self {
            Request::GetProtocolVersion => MessageType::GetProtocolVersion,
            Request::GetState => MessageType::GetState,
            Request::RegisterClient(_) => MessageType::RegisterClient,
            Request::SetProject { .. } => MessageType::SetProject,
            Request::SetTool { .. } => MessageType::SetTool,
            Request::SetWorkspace { .. } => MessageType::SetWorkspace,
            Request::GetGrasp(_) => MessageType::GetGrasp,
            Request::GraspFeedback(_) => MessageType::GraspFeedback,
            Request::GetObjectCount { .. } => MessageType::GetObjectCount,
            Request::RobotPose(_) => MessageType::RobotPose,
        }
    }

    /// Whether the message exists in protocol `version` (3 or 4).
    pub fn exists_in(&self, version: u16) -> bool {
        match self {
            Request::SetTool { .. } | Request::SetWorkspace { .. } => {
                version >= v4::PROTOCOL_VERSION
            }
            _ => true,
        }
    }

    /// The V3 frame of this request; fields the message does not use are zero. SET_TOOL and
    /// SET_WORKSPACE are not V3 messages: their frame carries the type and nothing else (V3 has
    /// no field for an id); a client sends them only as V4.
    pub fn to_frame(&self) -> RequestFrame {
        let mut f = RequestFrame::new(self.message_type());
        match *self {
            Request::GetProtocolVersion
            | Request::GetState
            | Request::SetTool { .. }
            | Request::SetWorkspace { .. } => {}
            Request::RegisterClient(client) => f.client = client,
            Request::SetProject { project_index } => f.project_index = project_index,
            Request::GetGrasp(g) => {
                f.grasp_mode = g.grasp_mode;
                f.object_class = g.object_class;
                f.tool = g.tool;
                f.pose_format = g.pose_format;
            }
            Request::GraspFeedback(feedback) => f.grasp_feedback = feedback,
            Request::GetObjectCount { object_class } => f.object_class = object_class,
            Request::RobotPose(pose) => {
                f.pose_format = pose.format();
                f.robot_pose = pose.to_wire();
            }
        }
        f
    }

    /// The V4 frame of this request (PROTOCOLS.md 2b); fields the message does not use are zero.
    /// Fails for a project number over 65535 and a quaternion robot pose, which V4 cannot carry.
    pub fn to_v4_frame(&self) -> Result<v4::RequestFrame, RequestError> {
        let mut f = v4::RequestFrame::new(self.message_type());
        match *self {
            Request::GetProtocolVersion | Request::GetState => {}
            Request::RegisterClient(client) => f.client = client,
            Request::SetProject { project_index } => {
                f.project_id = u16::try_from(project_index)
                    .map_err(|_| RequestError::ProjectOutOfRange(project_index))?;
            }
            Request::SetTool { tool_id } => f.tool_id = tool_id,
            Request::SetWorkspace { workspace_id } => f.workspace_id = workspace_id,
            Request::GetGrasp(g) => {
                if g.pose_format == PoseFormat::Quaternion {
                    return Err(RequestError::Pose(PoseError::SevenValuesInV4(
                        g.pose_format,
                    )));
                }
                f.grasp_mode = g.grasp_mode;
                f.object_id = g.object_class;
                f.selection_criterion = g.selection_criterion;
                f.pose_format = g.pose_format;
            }
            Request::GraspFeedback(feedback) => f.grasp_feedback = feedback,
            Request::GetObjectCount { object_class } => f.object_id = object_class,
            Request::RobotPose(pose) => {
                f.pose_format = pose.format();
                f.robot_pose = pose.to_wire6().map_err(RequestError::Pose)?;
            }
        }
        Ok(f)
    }

    /// The frame of this request in protocol `version`: V4 for 4, V3 otherwise.
    pub fn to_any_frame(&self, version: u16) -> Result<AnyRequestFrame, RequestError> {
        if !self.exists_in(version) {
            return Err(RequestError::NotInVersion {
                message_type: self.message_type(),
                version,
            });
        }
        Ok(if version == v4::PROTOCOL_VERSION {
            AnyRequestFrame::V4(self.to_v4_frame()?)
        } else {
            let mut f = self.to_frame();
            f.version = version;
            AnyRequestFrame::V3(f)
        })
    }

    /// Reads the typed request out of a V3 frame, ignoring the fields its message type does not
    /// use (what a server does). SET_TOOL and SET_WORKSPACE are refused: not V3 messages.
    pub fn from_frame(f: &RequestFrame) -> Result<Request, RequestError> {
        if f.header.communication_type != CommunicationType::Request {
            return Err(RequestError::NotARequest(f.header.communication_type));
        }
        Ok(match f.header.message_type {
            MessageType::GetProtocolVersion => Request::GetProtocolVersion,
            MessageType::GetState => Request::GetState,
            MessageType::RegisterClient => Request::RegisterClient(f.client),
            MessageType::SetProject => Request::SetProject {
                project_index: f.project_index,
            },
            message_type @ (MessageType::SetTool | MessageType::SetWorkspace) => {
                return Err(RequestError::NotInVersion {
                    message_type,
                    version: f.version,
                })
            }
            MessageType::GetGrasp => Request::GetGrasp(GraspRequest {
                grasp_mode: f.grasp_mode,
                object_class: f.object_class,
                tool: f.tool,
                selection_criterion: SelectionCriterion::default(),
                pose_format: f.pose_format,
            }),
            MessageType::GraspFeedback => Request::GraspFeedback(f.grasp_feedback),
            MessageType::GetObjectCount => Request::GetObjectCount {
                object_class: f.object_class,
            },
            MessageType::RobotPose => Request::RobotPose(
                Pose::from_wire(f.pose_format, f.robot_pose).map_err(RequestError::Pose)?,
            ),
            other @ MessageType::Unknown(_) => return Err(RequestError::UnknownMessageType(other)),
        })
    }

    /// Reads the typed request out of a V4 frame, ignoring the fields its message type does not
    /// use. A GET_GRASP's `tool` reads as [`Tool::Unknown(0)`](Tool::Unknown): V4 sends none.
    pub fn from_v4_frame(f: &v4::RequestFrame) -> Result<Request, RequestError> {
        if f.header.communication_type != CommunicationType::Request {
            return Err(RequestError::NotARequest(f.header.communication_type));
        }
        Ok(match f.header.message_type {
            MessageType::GetProtocolVersion => Request::GetProtocolVersion,
            MessageType::GetState => Request::GetState,
            MessageType::RegisterClient => Request::RegisterClient(f.client),
            MessageType::SetProject => Request::SetProject {
                project_index: u32::from(f.project_id),
            },
            MessageType::SetTool => Request::SetTool { tool_id: f.tool_id },
            MessageType::SetWorkspace => Request::SetWorkspace {
                workspace_id: f.workspace_id,
            },
            MessageType::GetGrasp => Request::GetGrasp(GraspRequest {
                grasp_mode: f.grasp_mode,
                object_class: f.object_id,
                tool: Tool::Unknown(0),
                selection_criterion: f.selection_criterion,
                pose_format: f.pose_format,
            }),
            MessageType::GraspFeedback => Request::GraspFeedback(f.grasp_feedback),
            MessageType::GetObjectCount => Request::GetObjectCount {
                object_class: f.object_id,
            },
            MessageType::RobotPose => Request::RobotPose(
                Pose::from_wire6(f.pose_format, f.robot_pose).map_err(RequestError::Pose)?,
            ),
            other @ MessageType::Unknown(_) => return Err(RequestError::UnknownMessageType(other)),
        })
    }

    /// Reads the typed request out of a frame of either version.
    pub fn from_any_frame(f: &AnyRequestFrame) -> Result<Request, RequestError> {
        match f {
            AnyRequestFrame::V3(f) => Request::from_frame(f),
            AnyRequestFrame::V4(f) => Request::from_v4_frame(f),
        }
    }
}

/// V4's object offset (GET_GRASP response bytes 24–35, PROTOCOLS.md 2b). SCHUNK's example scales
/// x, y from µm to mm and rz from µdeg to degrees; what the offset measures, and in which frame,
/// is not public (whether rz replaces V3's angle offset is an open question).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ObjectOffset {
    /// x in µm.
    pub x_um: i32,
    /// y in µm.
    pub y_um: i32,
    /// Rotation about z in µdeg.
    pub rz_udeg: i32,
}

/// A grasp from a successful GET_GRASP response, in either protocol version, wire units kept
/// exact. What only one version delivers is an `Option`: `None` from the other version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grasp {
    /// The kind of grasp returned; may differ from the requested mode. (V4: see
    /// [`v4::ResponseFrame::grasp_mode`] for where it is read.)
    pub grasp_mode: GraspMode,
    /// Class id (V4: object ID) of the target object.
    pub object_class: u16,
    /// Instance id of the target object.
    pub object_instance: u16,
    /// Distance between the fingers in µm to set before approaching (grippers only).
    pub stroke_um: i32,
    /// Translation in µm from the object centre to the grasp point, x and y (V3: robot base
    /// frame; V4: frame not public).
    pub center_offset_um: [i32; 2],
    /// The grasp pose, in the requested format (V4: the format byte of the response).
    pub pose: Pose,
    /// All detected objects, the target included.
    pub object_count: u16,
    /// Detected objects of the requested class, the target included.
    pub candidate_count: u16,
    /// V3 only: the centre offset's z in µm.
    pub center_offset_z_um: Option<i32>,
    /// V3 only: angle offset in µdeg between the object model and the flange at zero.
    pub angle_offset_udeg: Option<i32>,
    /// V3 only: the tool of the request, echoed.
    pub tool: Option<Tool>,
    /// V4 only: the reference frame byte (values not public).
    pub reference_frame: Option<ReferenceFrame>,
    /// V4 only: the object offset.
    pub object_offset: Option<ObjectOffset>,
}

impl Grasp {
    /// The stroke in metres.
    pub fn stroke_m(&self) -> f64 {
        f64::from(self.stroke_um) * 1e-6
    }

    /// The angle offset in radians (V3 only).
    pub fn angle_offset_rad(&self) -> Option<f64> {
        self.angle_offset_udeg
            .map(|udeg| (f64::from(udeg) * 1e-6).to_radians())
    }

    /// The centre offset's x and y in metres.
    pub fn center_offset_m(&self) -> [f64; 2] {
        self.center_offset_um.map(|um| f64::from(um) * 1e-6)
    }
}

/// Counts from a successful GET_OBJECT_COUNT response (manual 3.3.4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectCount {
    /// The class id that was requested (0 = all). V3 responses echo it (and the client checks
    /// the echo); whether V4 does is not public, so a V4 frame's bytes 14–15 are read here and
    /// the client puts in the class it asked for.
    pub object_class: u16,
    /// Detected objects of all classes.
    pub object_count: u16,
    /// Detected objects of the requested class.
    pub candidate_count: u16,
}

/// The body of a response, by message type. Only a SUCCESS response has one (manual 3.2.2.2:
/// otherwise the rest of the message is meaningless).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResponseBody {
    /// No body: REGISTER_CLIENT, SET_PROJECT, SET_TOOL, SET_WORKSPACE, GRASP_FEEDBACK,
    /// ROBOT_POSE, any non-SUCCESS response and unknown message types.
    Empty,
    /// GET_PROTOCOL_VERSION: the server's highest protocol version.
    ProtocolVersion(u16),
    /// GET_STATE.
    State(ServerState),
    /// GET_GRASP.
    Grasp(Grasp),
    /// GET_OBJECT_COUNT.
    ObjectCount(ObjectCount),
}

/// A typed response, of either protocol version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Response {
    /// The message type it answers (GET_OBJECT_COUNT: 32, see the errata of seed 002).
    pub message_type: MessageType,
    /// The response code.
    pub code: ResponseCode,
    /// The response counter.
    pub counter: u8,
    /// The body; [`ResponseBody::Empty`] unless `code` is SUCCESS.
    pub body: ResponseBody,
}

impl Response {
    /// Reads the typed response out of a V3 frame. Fails only for a successful GET_GRASP whose
    /// pose format is unknown; the header checks belong to the client's pairing.
    pub fn from_frame(f: &ResponseFrame) -> Result<Response, Malformed> {
        let body = match success_type(f.header.response_code, f.header.message_type) {
            None => ResponseBody::Empty,
            Some(MessageType::GetProtocolVersion) => {
                ResponseBody::ProtocolVersion(f.server_version)
            }
            Some(MessageType::GetState) => ResponseBody::State(f.server_state),
            Some(MessageType::GetGrasp) => ResponseBody::Grasp(Grasp {
                grasp_mode: f.grasp_mode,
                object_class: f.object_class,
                object_instance: f.object_instance,
                stroke_um: f.stroke_um,
                center_offset_um: [f.center_offset_um[0], f.center_offset_um[1]],
                pose: Pose::from_wire(f.pose_format, f.grasp_pose).map_err(Malformed::Pose)?,
                object_count: f.object_count,
                candidate_count: f.candidate_count,
                center_offset_z_um: Some(f.center_offset_um[2]),
                angle_offset_udeg: Some(f.angle_offset_udeg),
                tool: Some(f.tool),
                reference_frame: None,
                object_offset: None,
            }),
            Some(MessageType::GetObjectCount) => ResponseBody::ObjectCount(ObjectCount {
                object_class: f.object_class,
                object_count: f.object_count,
                candidate_count: f.candidate_count,
            }),
            Some(_) => ResponseBody::Empty,
        };
        Ok(Response::with_body(f.header, body))
    }

    /// Reads the typed response out of a V4 frame (PROTOCOLS.md 2b). Fails only for a successful
    /// GET_GRASP whose pose cannot be read (an unknown format, or a quaternion).
    pub fn from_v4_frame(f: &v4::ResponseFrame) -> Result<Response, Malformed> {
        let body = match success_type(f.header.response_code, f.header.message_type) {
            None => ResponseBody::Empty,
            Some(MessageType::GetProtocolVersion) => {
                ResponseBody::ProtocolVersion(f.server_version())
            }
            Some(MessageType::GetState) => ResponseBody::State(f.server_state()),
            Some(MessageType::GetGrasp) => ResponseBody::Grasp(Grasp {
                grasp_mode: f.grasp_mode(),
                object_class: f.object_id,
                object_instance: f.object_instance,
                stroke_um: f.stroke_um,
                center_offset_um: f.center_offset_um,
                pose: Pose::from_wire6(f.pose_format, f.grasp_pose).map_err(Malformed::Pose)?,
                object_count: f.object_count,
                candidate_count: f.candidate_count,
                center_offset_z_um: None,
                angle_offset_udeg: None,
                tool: None,
                reference_frame: Some(f.reference_frame),
                object_offset: Some(ObjectOffset {
                    x_um: f.object_offset_um[0],
                    y_um: f.object_offset_um[1],
                    rz_udeg: f.object_offset_rz_udeg,
                }),
            }),
            Some(MessageType::GetObjectCount) => ResponseBody::ObjectCount(ObjectCount {
                object_class: f.object_id,
                object_count: f.object_count,
                candidate_count: f.candidate_count,
            }),
            Some(_) => ResponseBody::Empty,
        };
        Ok(Response::with_body(f.header, body))
    }

    /// Reads the typed response out of a frame of either version.
    pub fn from_any_frame(f: &AnyResponseFrame) -> Result<Response, Malformed> {
        match f {
            AnyResponseFrame::V3(f) => Response::from_frame(f),
            AnyResponseFrame::V4(f) => Response::from_v4_frame(f),
        }
    }

    fn with_body(header: super::frame::Header, body: ResponseBody) -> Response {
        Response {
            message_type: header.message_type,
            code: header.response_code,
            counter: header.response_counter,
            body,
        }
    }

    /// The V3 frame of this response, with `version` in its prefix (a server answers with the
    /// version of the request, manual 1.3). V4-only fields are not sent; V3-only fields missing
    /// from a grasp are sent as 0.
    pub fn to_frame(&self, version: u16) -> ResponseFrame {
        let mut f = ResponseFrame::new(self.message_type, self.code, self.counter);
        f.version = version;
        match self.body {
            ResponseBody::Empty => {}
            ResponseBody::ProtocolVersion(v) => f.server_version = v,
            ResponseBody::State(s) => f.server_state = s,
            ResponseBody::Grasp(g) => {
                let [x, y] = g.center_offset_um;
                f.grasp_mode = g.grasp_mode;
                f.object_class = g.object_class;
                f.object_instance = g.object_instance;
                f.stroke_um = g.stroke_um;
                f.angle_offset_udeg = g.angle_offset_udeg.unwrap_or(0);
                f.center_offset_um = [x, y, g.center_offset_z_um.unwrap_or(0)];
                f.tool = g.tool.unwrap_or(Tool::Unknown(0));
                f.pose_format = g.pose.format();
                f.grasp_pose = g.pose.to_wire();
                f.object_count = g.object_count;
                f.candidate_count = g.candidate_count;
            }
            ResponseBody::ObjectCount(c) => {
                f.object_class = c.object_class;
                f.object_count = c.object_count;
                f.candidate_count = c.candidate_count;
            }
        }
        f
    }

    /// The V4 frame of this response (PROTOCOLS.md 2b). The grasp mode goes to byte 10, where
    /// SCHUNK's example reads it, and to 13, where V3 has it, so a client of either reading gets
    /// it; V3-only fields are not sent; a quaternion grasp pose fails (V4 carries six values).
    pub fn to_v4_frame(&self) -> Result<v4::ResponseFrame, PoseError> {
        let mut f = v4::ResponseFrame::new(self.message_type, self.code, self.counter);
        match self.body {
            ResponseBody::Empty => {}
            ResponseBody::ProtocolVersion(v) => f.set_server_version(v),
            ResponseBody::State(s) => f.set_server_state(s),
            ResponseBody::Grasp(g) => {
                let mode = u8::from(g.grasp_mode);
                let offset = g.object_offset.unwrap_or_default();
                f.head = [mode, 0, 0, mode];
                f.object_id = g.object_class;
                f.object_instance = g.object_instance;
                f.pose_format = g.pose.format();
                f.reference_frame = g.reference_frame.unwrap_or_default();
                f.stroke_um = g.stroke_um;
                f.object_offset_um = [offset.x_um, offset.y_um];
                f.object_offset_rz_udeg = offset.rz_udeg;
                f.center_offset_um = g.center_offset_um;
                f.grasp_pose = g.pose.to_wire6()?;
                f.candidate_count = g.candidate_count;
                f.object_count = g.object_count;
            }
            ResponseBody::ObjectCount(c) => {
                f.object_id = c.object_class;
                f.candidate_count = c.candidate_count;
                f.object_count = c.object_count;
            }
        }
        Ok(f)
    }
}

/// The message type whose body a response has: its own when SUCCESS, none otherwise (manual
/// 3.2.2.2: the rest of the message is meaningless).
fn success_type(code: ResponseCode, message_type: MessageType) -> Option<MessageType> {
    (code == ResponseCode::Success).then_some(message_type)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::smartgrasp::frame::PROTOCOL_VERSION;
    use crate::smartgrasp::pose::AbcPose;

    #[test]
    fn every_request_round_trips_through_its_frame_bytes() {
        let requests = [
            Request::GetProtocolVersion,
            Request::GetState,
            Request::RegisterClient(RobotSystem::Kuka),
            Request::SetProject { project_index: 5 },
            Request::GetGrasp(GraspRequest {
                grasp_mode: GraspMode::AutoGrasp,
                object_class: 0,
                tool: Tool::Exterior,
                selection_criterion: SelectionCriterion::default(),
                pose_format: PoseFormat::Quaternion,
            }),
            Request::GraspFeedback(GraspFeedback::Bad),
            Request::GetObjectCount { object_class: 7 },
            Request::RobotPose(Pose::Abc(AbcPose {
                position_um: [1, 2, 3],
                abc_udeg: [4, 5, 6],
            })),
        ];
        for r in requests {
            let bytes = r.to_frame().encode();
            assert_eq!(bytes[9], u8::from(r.message_type()));
            let back = Request::from_frame(&RequestFrame::decode(&bytes)).unwrap();
            assert_eq!(back, r);
        }
    }

    /// Manual 6.5 GET_GRASP request: mode 3, class 0, tool 1, format 1 at bytes 11, 12, 14, 15.
    #[test]
    fn get_grasp_request_matches_manual_6_5() {
        let bytes = Request::GetGrasp(GraspRequest {
            grasp_mode: GraspMode::AutoGrasp,
            object_class: 0,
            tool: Tool::Exterior,
            selection_criterion: SelectionCriterion::default(),
            pose_format: PoseFormat::Quaternion,
        })
        .to_frame()
        .encode();
        assert_eq!(
            bytes[..16],
            [0, 3, 0, 0, 0, 74, 1, 0, 0, 16, 0, 3, 0, 0, 1, 1]
        );
        assert!(bytes[16..].iter().all(|&b| b == 0));
    }

    /// The typed requests give PROTOCOLS.md 2b's frames (bytes written out by hand there, checked
    /// byte for byte in `frame::v4`), and read back to themselves.
    #[test]
    fn typed_v4_requests_match_the_krl_vectors() {
        let head = |t: u8| [0x00, 0x04, 0x00, 0x00, 0x00, 0x4A, 0x01, 0x00, 0x00, t];
        let get_grasp = Request::GetGrasp(GraspRequest {
            grasp_mode: GraspMode::AnyGrasp,
            object_class: 8,
            tool: Tool::Exterior,
            selection_criterion: SelectionCriterion(2),
            pose_format: PoseFormat::Abc,
        });
        let b = get_grasp.to_v4_frame().unwrap().encode();
        assert_eq!(b[..10], head(0x10));
        assert_eq!(b[10..16], [0x00, 0x02, 0x00, 0x08, 0x02, 0x11]);
        assert!(b[16..].iter().all(|&x| x == 0));
        let pose = Request::RobotPose(Pose::Abc(AbcPose {
            position_um: [412_500, -35_250, 120_000],
            abc_udeg: [45_000_000, -500_000, 179_999_000],
        }));
        let b = pose.to_v4_frame().unwrap().encode();
        assert_eq!(b[..10], head(0x30));
        assert_eq!(b[15], 0x11);
        assert_eq!(
            b[24..48],
            [
                0x00, 0x06, 0x4B, 0x54, 0xFF, 0xFF, 0x76, 0x4E, 0x00, 0x01, 0xD4, 0xC0, 0x02, 0xAE,
                0xA5, 0x40, 0xFF, 0xF8, 0x5E, 0xE0, 0x0A, 0xBA, 0x91, 0x18
            ]
        );
        let b = Request::SetProject { project_index: 164 }
            .to_v4_frame()
            .unwrap()
            .encode();
        assert_eq!((b[9], b[18], b[19]), (0x04, 0x00, 0xA4));
        let b = Request::SetTool { tool_id: 32 }
            .to_v4_frame()
            .unwrap()
            .encode();
        assert_eq!((b[9], b[20], b[21]), (0x05, 0x00, 0x20));
        let b = Request::SetWorkspace { workspace_id: 1 }
            .to_v4_frame()
            .unwrap()
            .encode();
        assert_eq!((b[9], b[22], b[23]), (0x06, 0x00, 0x01));
        let b = Request::GetObjectCount { object_class: 1 }
            .to_v4_frame()
            .unwrap()
            .encode();
        assert_eq!((b[9], b[12], b[13]), (0x20, 0x00, 0x01));
        for r in [
            pose,
            Request::SetTool { tool_id: 32 },
            Request::SetWorkspace { workspace_id: 1 },
            Request::SetProject { project_index: 164 },
            Request::GraspFeedback(GraspFeedback::Ok),
            Request::RegisterClient(RobotSystem::Kuka),
        ] {
            let back = Request::from_v4_frame(&v4::RequestFrame::decode(
                &r.to_v4_frame().unwrap().encode(),
            ));
            assert_eq!(back, Ok(r));
        }
    }

    #[test]
    fn what_v4_cannot_carry_is_refused_before_sending() {
        let quaternion = Pose::Quaternion(crate::smartgrasp::pose::QuaternionPose {
            position_um: [0; 3],
            quaternion_e6: [0, 0, 0, 1_000_000],
        });
        assert!(matches!(
            Request::RobotPose(quaternion).to_v4_frame(),
            Err(RequestError::Pose(PoseError::SevenValuesInV4(_)))
        ));
        assert_eq!(
            Request::SetProject {
                project_index: 70_000
            }
            .to_v4_frame(),
            Err(RequestError::ProjectOutOfRange(70_000))
        );
        assert_eq!(
            Request::SetTool { tool_id: 1 }.to_any_frame(3),
            Err(RequestError::NotInVersion {
                message_type: MessageType::SetTool,
                version: 3
            })
        );
    }

    /// A V4 GET_GRASP response read into the one [`Grasp`]: V4's fields `Some`, V3's `None`.
    #[test]
    fn a_v4_grasp_fills_the_v4_options() {
        let mut f = v4::ResponseFrame::new(MessageType::GetGrasp, ResponseCode::Success, 1);
        f.head = [1, 0, 0, 0];
        f.object_id = 8;
        f.pose_format = PoseFormat::Abc;
        f.reference_frame = ReferenceFrame(2);
        f.object_offset_um = [5, -6];
        f.object_offset_rz_udeg = 7;
        f.center_offset_um = [8, 9];
        f.grasp_pose = [1, 2, 3, 4, 5, 6];
        f.candidate_count = 2;
        f.object_count = 3;
        let r = Response::from_v4_frame(&v4::ResponseFrame::decode(&f.encode())).unwrap();
        let ResponseBody::Grasp(g) = r.body else {
            panic!("{r:?}")
        };
        assert_eq!(g.grasp_mode, GraspMode::ActiveGrasp);
        assert_eq!(g.object_class, 8);
        assert_eq!(g.center_offset_um, [8, 9]);
        assert_eq!(g.pose.to_wire(), [1, 2, 3, 4, 5, 6, 0]);
        assert_eq!((g.candidate_count, g.object_count), (2, 3));
        assert_eq!(g.reference_frame, Some(ReferenceFrame(2)));
        assert_eq!(
            g.object_offset,
            Some(ObjectOffset {
                x_um: 5,
                y_um: -6,
                rz_udeg: 7
            })
        );
        assert_eq!(
            (g.tool, g.angle_offset_udeg, g.center_offset_z_um),
            (None, None, None)
        );
        // And back: the response the simulator would send, byte for byte.
        let mut again = r.to_v4_frame().unwrap();
        again.head = f.head;
        assert_eq!(again, f);
    }

    #[test]
    fn a_failed_response_has_no_body() {
        let mut f = ResponseFrame::new(MessageType::GetGrasp, ResponseCode::NoObject, 4);
        f.pose_format = PoseFormat::Unknown(99);
        let r = Response::from_frame(&f).unwrap();
        assert_eq!(r.body, ResponseBody::Empty);
        assert_eq!(r.code, ResponseCode::NoObject);
        f.header.response_code = ResponseCode::Success;
        assert_eq!(
            Response::from_frame(&f),
            Err(Malformed::Pose(PoseError::UnsupportedFormat(
                PoseFormat::Unknown(99)
            )))
        );
    }

    #[test]
    fn object_count_response_is_message_type_32() {
        let r = Response {
            message_type: MessageType::GetObjectCount,
            code: ResponseCode::Success,
            counter: 1,
            body: ResponseBody::ObjectCount(ObjectCount {
                object_class: 2,
                object_count: 5,
                candidate_count: 3,
            }),
        };
        let bytes = r.to_frame(PROTOCOL_VERSION).encode();
        assert_eq!(bytes[9], 32);
        assert_eq!(bytes[14..16], [0, 2]);
        assert_eq!(bytes[68..72], [0, 5, 0, 3]);
        assert_eq!(
            Response::from_frame(&ResponseFrame::decode(&bytes)).unwrap(),
            r
        );
    }
}
