//! Typed requests and responses for the eight message types (manual 3.3), mapped onto the frames
//! of [`frame`](super::frame). Pure: no I/O.

use super::error::Malformed;
use super::frame::{RequestFrame, ResponseFrame};
use super::pose::{Pose, PoseError};
use super::types::{
    CommunicationType, GraspFeedback, GraspMode, MessageType, PoseFormat, ResponseCode,
    RobotSystem, ServerState, Tool,
};

/// Parameters of a GET_GRASP request (manual 3.3.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GraspRequest {
    /// Which grasps may be returned.
    pub grasp_mode: GraspMode,
    /// Class id of the target object; 0 = any class.
    pub object_class: u16,
    /// The tool the robot grasps with.
    pub tool: Tool,
    /// The format the grasp pose should come back in.
    pub pose_format: PoseFormat,
}

/// A request, one variant per message type (manual 3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// GET_PROTOCOL_VERSION (3.3.2.1).
    GetProtocolVersion,
    /// GET_STATE (3.3.2.2).
    GetState,
    /// REGISTER_CLIENT (3.3.2.3).
    RegisterClient(RobotSystem),
    /// SET_PROJECT (3.3.2.4).
    SetProject {
        /// Index of the project to activate.
        project_index: u32,
    },
    /// GET_GRASP (3.3.3.1).
    GetGrasp(GraspRequest),
    /// GRASP_FEEDBACK (3.3.3.2).
    GraspFeedback(GraspFeedback),
    /// GET_OBJECT_COUNT (3.3.4.1).
    GetObjectCount {
        /// Class id to count; 0 = all classes.
        object_class: u16,
    },
    /// ROBOT_POSE (3.3.5.1): end effector (TCP) in the robot base frame.
    RobotPose(Pose),
}

/// A request frame whose message type or pose format this module does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    /// The message type is not one of the manual's eight.
    #[error("unknown message type {0}")]
    UnknownMessageType(MessageType),
    /// The header says it is not a request.
    #[error("communication type {0} where a request was expected")]
    NotARequest(CommunicationType),
    /// ROBOT_POSE with a pose format that cannot be read.
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
            Request::GetGrasp(_) => MessageType::GetGrasp,
            Request::GraspFeedback(_) => MessageType::GraspFeedback,
            Request::GetObjectCount { .. } => MessageType::GetObjectCount,
            Request::RobotPose(_) => MessageType::RobotPose,
        }
    }

    /// The V3 frame of this request; fields the message does not use are zero.
    pub fn to_frame(&self) -> RequestFrame {
        let mut f = RequestFrame::new(self.message_type());
        match *self {
            Request::GetProtocolVersion | Request::GetState => {}
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

    /// Reads the typed request out of a frame, ignoring the fields its message type does not use
    /// (what a server does).
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
            MessageType::GetGrasp => Request::GetGrasp(GraspRequest {
                grasp_mode: f.grasp_mode,
                object_class: f.object_class,
                tool: f.tool,
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
}

/// A grasp from a successful GET_GRASP response (manual 3.3.3.1), wire units kept exact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grasp {
    /// The kind of grasp returned; may differ from the requested mode.
    pub grasp_mode: GraspMode,
    /// Class id of the target object.
    pub object_class: u16,
    /// Instance id of the target object.
    pub object_instance: u16,
    /// Distance between the fingers in µm to set before approaching (grippers only).
    pub stroke_um: i32,
    /// Angle offset in µdeg between the object model and the flange at zero.
    pub angle_offset_udeg: i32,
    /// Translation in µm from the object centre to the grasp point, robot base frame.
    pub center_offset_um: [i32; 3],
    /// The tool of the request.
    pub tool: Tool,
    /// The grasp pose in the robot base frame, in the requested format.
    pub pose: Pose,
    /// All detected objects, the target included.
    pub object_count: u16,
    /// Detected objects of the requested class, the target included.
    pub candidate_count: u16,
}

impl Grasp {
    /// The stroke in metres.
    pub fn stroke_m(&self) -> f64 {
        f64::from(self.stroke_um) * 1e-6
    }

    /// The angle offset in radians.
    pub fn angle_offset_rad(&self) -> f64 {
        (f64::from(self.angle_offset_udeg) * 1e-6).to_radians()
    }

    /// The center offset in metres.
    pub fn center_offset_m(&self) -> [f64; 3] {
        self.center_offset_um.map(|um| f64::from(um) * 1e-6)
    }
}

/// Counts from a successful GET_OBJECT_COUNT response (manual 3.3.4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectCount {
    /// The class id that was requested (0 = all).
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
    /// No body: REGISTER_CLIENT, SET_PROJECT, GRASP_FEEDBACK, ROBOT_POSE, any non-SUCCESS
    /// response and unknown message types.
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

/// A typed response.
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
    /// Reads the typed response out of a frame. Fails only for a successful GET_GRASP whose pose
    /// format is unknown; the header checks belong to the client's pairing.
    pub fn from_frame(f: &ResponseFrame) -> Result<Response, Malformed> {
        let code = f.header.response_code;
        let body = if code != ResponseCode::Success {
            ResponseBody::Empty
        } else {
            match f.header.message_type {
                MessageType::GetProtocolVersion => ResponseBody::ProtocolVersion(f.server_version),
                MessageType::GetState => ResponseBody::State(f.server_state),
                MessageType::GetGrasp => ResponseBody::Grasp(Grasp {
                    grasp_mode: f.grasp_mode,
                    object_class: f.object_class,
                    object_instance: f.object_instance,
                    stroke_um: f.stroke_um,
                    angle_offset_udeg: f.angle_offset_udeg,
                    center_offset_um: f.center_offset_um,
                    tool: f.tool,
                    pose: Pose::from_wire(f.pose_format, f.grasp_pose).map_err(Malformed::Pose)?,
                    object_count: f.object_count,
                    candidate_count: f.candidate_count,
                }),
                MessageType::GetObjectCount => ResponseBody::ObjectCount(ObjectCount {
                    object_class: f.object_class,
                    object_count: f.object_count,
                    candidate_count: f.candidate_count,
                }),
                _ => ResponseBody::Empty,
            }
        };
        Ok(Response {
            message_type: f.header.message_type,
            code,
            counter: f.header.response_counter,
            body,
        })
    }

    /// The V3 frame of this response, with `version` in its prefix (a server answers with the
    /// version of the request, manual 1.3).
    pub fn to_frame(&self, version: u16) -> ResponseFrame {
        let mut f = ResponseFrame::new(self.message_type, self.code, self.counter);
        f.version = version;
        match self.body {
            ResponseBody::Empty => {}
            ResponseBody::ProtocolVersion(v) => f.server_version = v,
            ResponseBody::State(s) => f.server_state = s,
            ResponseBody::Grasp(g) => {
                f.grasp_mode = g.grasp_mode;
                f.object_class = g.object_class;
                f.object_instance = g.object_instance;
                f.stroke_um = g.stroke_um;
                f.angle_offset_udeg = g.angle_offset_udeg;
                f.center_offset_um = g.center_offset_um;
                f.tool = g.tool;
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
