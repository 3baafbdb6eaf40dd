//! The simulated server's state machine, pure: a request frame in, an [`Action`] out. No sockets,
//! no clocks (a delay is an action the server carries out), so every rule is tested directly and
//! fuzz targets can call [`parse_request`] and [`SimState::handle`].

use std::collections::VecDeque;
use std::time::Duration;

use crate::smartgrasp::codec::{peek_frame, Peeked};
use crate::smartgrasp::frame::{Prefix, RequestFrame, ResponseFrame, FRAME_LEN, PROTOCOL_VERSION};
use crate::smartgrasp::message::{
    Grasp, GraspRequest, ObjectCount, Request, Response, ResponseBody,
};
use crate::smartgrasp::pose::{Pose, SiPose, UnitQuaternion};
use crate::smartgrasp::types::{
    GraspFeedback, GraspMode, PoseFormat, ResponseCode, RobotSystem, ServerState, Tool,
};
use crate::smartgrasp::Malformed;

/// A user-defined grasp of an object, or the model-free planner's grasp of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimGrasp {
    /// The tool this grasp is for.
    pub tool: Tool,
    /// Whether this is the object's *active* grasp (the one ACTIVE_GRASP returns).
    pub active: bool,
    /// Finger distance to set before approaching, µm.
    pub stroke_um: i32,
    /// Angle offset between object model and flange, µdeg.
    pub angle_offset_udeg: i32,
    /// Offset from the object centre to the grasp point, µm, robot base frame.
    pub center_offset_um: [i32; 3],
    /// The grasp pose in the robot base frame; sent in whatever format the request asks for.
    pub pose: SiPose,
}

/// An object in a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SimObject {
    /// Class id (never 0: 0 means "any" in requests).
    pub class_id: u16,
    /// Instance id, unique within the class.
    pub instance: u16,
    /// User-defined grasps, in order of preference.
    pub grasps: Vec<SimGrasp>,
    /// What model-free planning (AUTO_GRASP) finds when no user-defined grasp fits; `None`:
    /// nothing.
    pub auto_grasp: Option<SimGrasp>,
}

/// A project: the object classes it knows and the scene the camera sees.
#[derive(Debug, Clone, PartialEq)]
pub struct SimProject {
    /// Valid class ids; a request for another class gets INVALID_OBJECT_CLASS.
    pub classes: Vec<u16>,
    /// The objects currently in the scene; an object leaves it when GRASP_FEEDBACK says OK.
    pub scene: Vec<SimObject>,
}

impl SimProject {
    /// A project whose classes are those of the objects in `scene`.
    pub fn from_scene(scene: Vec<SimObject>) -> SimProject {
        let mut classes: Vec<u16> = scene.iter().map(|o| o.class_id).collect();
        classes.sort_unstable();
        classes.dedup();
        SimProject { classes, scene }
    }
}

/// A fault to inject in place of the next response, for users' tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Fault {
    /// Process the request but send no response; the response counter still advances, so the
    /// next response shows a gap.
    DropReply,
    /// Send the response after this wall-clock delay (responses stay in order).
    DelayReply(Duration),
    /// Send the response with this value in the prefix's length field.
    CorruptLength(u32),
    /// Close the connection instead of answering.
    Close,
}

/// How the simulated server starts.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The highest protocol version the server speaks. Below 3, it answers every V3 request with
    /// the empty "too old" message (manual 1.3).
    pub protocol_version: u16,
    /// What GET_STATE reports. Detection calls fail with ERROR unless OPERATIONAL.
    pub server_state: ServerState,
    /// The projects, by index.
    pub projects: Vec<SimProject>,
    /// The project active before any SET_PROJECT.
    pub active_project: Option<u32>,
    /// The response counter of each connection's first response (to cross 255 quickly in tests).
    pub first_response_counter: u8,
}

impl Default for SimConfig {
    /// An operational v3 server with [`SimConfig::demo_project`] as project 0, active.
    fn default() -> Self {
        SimConfig {
            protocol_version: PROTOCOL_VERSION,
            server_state: ServerState::Operational,
            projects: vec![SimConfig::demo_project()],
            active_project: Some(0),
            first_response_counter: 0,
        }
    }
}

impl SimConfig {
    /// A bin with three parts: two of class 1 (a user-defined exterior grasp, active, and a
    /// suction grasp) and one of class 2 (an exterior grasp, not active, and a model-free grasp).
    pub fn demo_project() -> SimProject {
        let pose = |x_mm: f64, y_mm: f64, yaw_deg: f64| SiPose {
            position_m: [x_mm / 1000.0, y_mm / 1000.0, 0.05],
            // Tool pointing down (180° about x), turned about the base's z axis.
            orientation: UnitQuaternion::from_rpy(std::f64::consts::PI, 0.0, yaw_deg.to_radians()),
        };
        let grasp = |tool, active, stroke_um, p| SimGrasp {
            tool,
            active,
            stroke_um,
            angle_offset_udeg: -25_210_142,
            center_offset_um: [-911, -310, 68],
            pose: p,
        };
        SimProject::from_scene(vec![
            SimObject {
                class_id: 1,
                instance: 0,
                grasps: vec![
                    grasp(Tool::Exterior, true, 86_000, pose(450.0, -120.0, 30.0)),
                    grasp(Tool::Contact, false, 0, pose(452.0, -118.0, 30.0)),
                ],
                auto_grasp: None,
            },
            SimObject {
                class_id: 1,
                instance: 1,
                grasps: vec![grasp(
                    Tool::Exterior,
                    true,
                    86_000,
                    pose(520.0, 40.0, -60.0),
                )],
                auto_grasp: None,
            },
            SimObject {
                class_id: 2,
                instance: 0,
                grasps: vec![grasp(
                    Tool::Exterior,
                    false,
                    40_000,
                    pose(380.0, 90.0, 90.0),
                )],
                auto_grasp: Some(grasp(Tool::Contact, false, 0, pose(380.0, 90.0, 0.0))),
            },
        ])
    }
}

/// What the server does with one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Send this response.
    Respond(ResponseFrame),
    /// Send the empty "too old" message: a prefix with length 0 and the server's version.
    RespondEmpty(Prefix),
    /// Send nothing (an injected [`Fault::DropReply`]).
    Skip,
    /// Send this response after the delay.
    Delay(Duration, ResponseFrame),
    /// Send these 80 bytes: a response whose length field was corrupted.
    SendRaw([u8; FRAME_LEN]),
    /// Close the connection.
    Close,
}

/// Per-connection state: the response counter counts the responses on its connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimConnection {
    next_counter: u8,
}

/// The grasp handed out last, which GRASP_FEEDBACK refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct LastGrasp {
    project: usize,
    class_id: u16,
    instance: u16,
}

/// The simulated server: projects, scenes, what clients told it, faults to inject.
#[derive(Debug, Clone)]
pub struct SimState {
    config: SimConfig,
    active_project: Option<usize>,
    last_grasp: Option<LastGrasp>,
    registered_clients: Vec<RobotSystem>,
    robot_poses: Vec<Pose>,
    faults: VecDeque<Fault>,
}

/// How many REGISTER_CLIENT and ROBOT_POSE reports the simulator keeps for inspection. A client
/// that sends them forever (a robot streaming its pose) must not grow the simulator's memory
/// without limit: past this, the oldest are forgotten.
pub const RECORD_LIMIT: usize = 1024;

/// Keeps `item`, forgetting the oldest entries once `log` holds [`RECORD_LIMIT`].
fn record<T>(log: &mut Vec<T>, item: T) {
    if log.len() >= RECORD_LIMIT {
        // Drop a batch, not one entry per push: the shift is paid once per many reports.
        log.drain(..RECORD_LIMIT / 4);
    }
    log.push(item);
}

/// Reads one request frame from the front of `bytes`: `Ok(None)` until 80 bytes are there,
/// `Ok(Some((frame, 80)))` then. Any prefix length but 74 is an error: a server cannot find the
/// next frame after it. Pure, for fuzzing.
pub fn parse_request(bytes: &[u8]) -> Result<Option<(RequestFrame, usize)>, Malformed> {
    match peek_frame(bytes) {
        Ok(Peeked::Incomplete { .. }) => Ok(None),
        Ok(Peeked::Frame(frame)) => Ok(Some((RequestFrame::decode(&frame), FRAME_LEN))),
        Ok(Peeked::Empty { .. }) => Err(Malformed::FrameLength { length: 0 }),
        Err(prefix) => Err(Malformed::FrameLength {
            length: prefix.length,
        }),
    }
}

impl SimState {
    /// A server as configured.
    pub fn new(config: SimConfig) -> SimState {
        SimState {
            active_project: config.active_project.map(|i| i as usize),
            config,
            last_grasp: None,
            registered_clients: Vec::new(),
            robot_poses: Vec::new(),
            faults: VecDeque::new(),
        }
    }

    /// State for a new connection.
    pub fn connect(&self) -> SimConnection {
        SimConnection {
            next_counter: self.config.first_response_counter,
        }
    }

    /// Queues a fault; each replaces one upcoming response, in order.
    pub fn inject(&mut self, fault: Fault) {
        self.faults.push_back(fault);
    }

    /// The robot systems REGISTER_CLIENT reported, oldest first (at most the last
    /// [`RECORD_LIMIT`]).
    pub fn registered_clients(&self) -> &[RobotSystem] {
        &self.registered_clients
    }

    /// The poses ROBOT_POSE reported, oldest first, as sent (at most the last
    /// [`RECORD_LIMIT`]).
    pub fn robot_poses(&self) -> &[Pose] {
        &self.robot_poses
    }

    /// The active project's index.
    pub fn active_project(&self) -> Option<u32> {
        self.active_project.and_then(|i| u32::try_from(i).ok())
    }

    /// The projects, their scenes as they are now.
    pub fn projects(&self) -> &[SimProject] {
        &self.config.projects
    }

    /// Mutable access to the projects, e.g. to put objects back into a scene.
    pub fn projects_mut(&mut self) -> &mut Vec<SimProject> {
        &mut self.config.projects
    }

    /// Sets what GET_STATE reports.
    pub fn set_server_state(&mut self, state: ServerState) {
        self.config.server_state = state;
    }

    /// The "too old" empty message for the bytes of a message this server cannot read (a length
    /// other than 74), if its prefix carries a version newer than the server's: manual 1.3 says
    /// a server older than the client always answers with it, whatever the rest of the message.
    /// `None` for an incomplete prefix or a version the server speaks (a plain bad length).
    pub fn too_old_for(&self, bytes: &[u8]) -> Option<Prefix> {
        let prefix = Prefix::decode(bytes.first_chunk()?);
        (prefix.version > self.config.protocol_version).then_some(Prefix {
            version: self.config.protocol_version,
            length: 0,
        })
    }

    /// Handles one request frame.
    pub fn handle(&mut self, conn: &mut SimConnection, frame: &RequestFrame) -> Action {
        // Manual 1.3: a server older than the client answers with an empty message carrying its
        // highest version; it never answers a V3 frame it does not speak.
        if frame.version > self.config.protocol_version {
            return Action::RespondEmpty(Prefix {
                version: self.config.protocol_version,
                length: 0,
            });
        }
        let counter = conn.next_counter;
        conn.next_counter = counter.wrapping_add(1);
        let (code, body) = match Request::from_frame(frame) {
            Ok(request) => self.process(request),
            Err(e) => {
                tracing::debug!(error = %e, "simulator refused a request");
                (ResponseCode::Error, ResponseBody::Empty)
            }
        };
        let response = Response {
            message_type: frame.header.message_type,
            code,
            counter,
            body,
        }
        // The server answers with the version the request used (manual 1.3).
        .to_frame(frame.version);
        match self.faults.pop_front() {
            None => Action::Respond(response),
            Some(Fault::DropReply) => Action::Skip,
            Some(Fault::DelayReply(d)) => Action::Delay(d, response),
            Some(Fault::CorruptLength(length)) => {
                let mut bytes = response.encode();
                bytes[2..6].copy_from_slice(&length.to_be_bytes());
                Action::SendRaw(bytes)
            }
            Some(Fault::Close) => Action::Close,
        }
    }

    fn process(&mut self, request: Request) -> (ResponseCode, ResponseBody) {
        const OK: ResponseCode = ResponseCode::Success;
        const EMPTY: ResponseBody = ResponseBody::Empty;
        const ERROR: (ResponseCode, ResponseBody) = (ResponseCode::Error, ResponseBody::Empty);
        match request {
            Request::GetProtocolVersion => (
                OK,
                ResponseBody::ProtocolVersion(self.config.protocol_version),
            ),
            Request::GetState => (OK, ResponseBody::State(self.config.server_state)),
            Request::RegisterClient(robot) => {
                record(&mut self.registered_clients, robot);
                (OK, EMPTY)
            }
            Request::SetProject { project_index } => match usize::try_from(project_index) {
                Ok(i) if i < self.config.projects.len() => {
                    self.active_project = Some(i);
                    self.last_grasp = None;
                    (OK, EMPTY)
                }
                _ => ERROR,
            },
            Request::RobotPose(pose) => {
                record(&mut self.robot_poses, pose);
                (OK, EMPTY)
            }
            Request::GetGrasp(g) => match self.operational_project() {
                Some(p) => self.get_grasp(p, g),
                None => ERROR,
            },
            Request::GetObjectCount { object_class } => {
                let Some(p) = self.operational_project() else {
                    return ERROR;
                };
                let Some(project) = self.config.projects.get(p) else {
                    return ERROR;
                };
                if object_class != 0 && !project.classes.contains(&object_class) {
                    return (ResponseCode::InvalidObjectClass, EMPTY);
                }
                (
                    OK,
                    ResponseBody::ObjectCount(ObjectCount {
                        object_class,
                        object_count: count(project.scene.len()),
                        candidate_count: count(candidates(project, object_class).count()),
                    }),
                )
            }
            Request::GraspFeedback(feedback) => {
                let Some(last) = self.last_grasp.take() else {
                    // Feedback without a grasp to refer to.
                    return ERROR;
                };
                match feedback {
                    GraspFeedback::Ok => {
                        if let Some(project) = self.config.projects.get_mut(last.project) {
                            project.scene.retain(|o| {
                                (o.class_id, o.instance) != (last.class_id, last.instance)
                            });
                        }
                        (OK, EMPTY)
                    }
                    // The part is still in the bin.
                    GraspFeedback::Bad => (OK, EMPTY),
                    GraspFeedback::Unknown(_) => ERROR,
                }
            }
        }
    }

    /// The active project's index when the server is operational.
    fn operational_project(&self) -> Option<usize> {
        if self.config.server_state != ServerState::Operational {
            return None;
        }
        self.active_project
            .filter(|&i| i < self.config.projects.len())
    }

    fn get_grasp(&mut self, p: usize, request: GraspRequest) -> (ResponseCode, ResponseBody) {
        let Some(project) = self.config.projects.get(p) else {
            return (ResponseCode::Error, ResponseBody::Empty);
        };
        if let PoseFormat::Unknown(_) = request.pose_format {
            return (ResponseCode::Error, ResponseBody::Empty);
        }
        let class = request.object_class;
        if class != 0 && !project.classes.contains(&class) {
            return (ResponseCode::InvalidObjectClass, ResponseBody::Empty);
        }
        let candidate_count = count(candidates(project, class).count());
        if candidate_count == 0 {
            return (ResponseCode::NoObject, ResponseBody::Empty);
        }
        let Some((object, definition, mode)) = candidates(project, class)
            .find_map(|o| choose_grasp(o, request).map(|(g, mode)| (o, g, mode)))
        else {
            return (ResponseCode::NoGrasp, ResponseBody::Empty);
        };
        let Ok(pose) = definition.pose.to_pose(request.pose_format) else {
            return (ResponseCode::Error, ResponseBody::Empty);
        };
        let grasp = Grasp {
            grasp_mode: mode,
            object_class: object.class_id,
            object_instance: object.instance,
            stroke_um: definition.stroke_um,
            angle_offset_udeg: definition.angle_offset_udeg,
            center_offset_um: definition.center_offset_um,
            tool: request.tool,
            pose,
            object_count: count(project.scene.len()),
            candidate_count,
        };
        self.last_grasp = Some(LastGrasp {
            project: p,
            class_id: object.class_id,
            instance: object.instance,
        });
        (ResponseCode::Success, ResponseBody::Grasp(grasp))
    }
}

fn candidates(project: &SimProject, class: u16) -> impl Iterator<Item = &SimObject> {
    project
        .scene
        .iter()
        .filter(move |o| class == 0 || o.class_id == class)
}

/// Picks the grasp the requested mode allows, and the mode to report (manual 3.3.3.1: the
/// response's mode says what kind of grasp it is).
fn choose_grasp(object: &SimObject, request: GraspRequest) -> Option<(&SimGrasp, GraspMode)> {
    let for_tool = |g: &&SimGrasp| g.tool == request.tool;
    let active = object.grasps.iter().filter(for_tool).find(|g| g.active);
    let any = || active.or_else(|| object.grasps.iter().find(for_tool));
    match request.grasp_mode {
        GraspMode::ActiveGrasp => active.map(|g| (g, GraspMode::ActiveGrasp)),
        GraspMode::AnyGrasp => any().map(|g| (g, GraspMode::AnyGrasp)),
        // User-defined grasps first; model-free planning only when none fits.
        GraspMode::AutoGrasp => any().map(|g| (g, GraspMode::AnyGrasp)).or_else(|| {
            object
                .auto_grasp
                .as_ref()
                .filter(|g| g.tool == request.tool)
                .map(|g| (g, GraspMode::AutoGrasp))
        }),
        GraspMode::Unknown(_) => None,
    }
}

/// Counts are u16 on the wire; a scene that large saturates rather than wraps.
fn count(n: usize) -> u16 {
    u16::try_from(n).unwrap_or(u16::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::smartgrasp::types::MessageType;

    fn respond(state: &mut SimState, conn: &mut SimConnection, request: Request) -> Response {
        match state.handle(conn, &request.to_frame()) {
            Action::Respond(f) => Response::from_frame(&f).unwrap(),
            other => panic!("expected a response, got {other:?}"),
        }
    }

    fn get_grasp(class: u16, mode: GraspMode, tool: Tool) -> Request {
        Request::GetGrasp(GraspRequest {
            grasp_mode: mode,
            object_class: class,
            tool,
            pose_format: PoseFormat::Abc,
        })
    }

    #[test]
    fn picking_empties_the_scene_then_no_object() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        let mut picked = Vec::new();
        loop {
            let r = respond(
                &mut s,
                &mut c,
                get_grasp(0, GraspMode::AutoGrasp, Tool::Exterior),
            );
            if r.code == ResponseCode::NoObject {
                break;
            }
            let ResponseBody::Grasp(g) = r.body else {
                panic!("{r:?}")
            };
            assert_eq!(usize::from(g.object_count), 3 - picked.len());
            picked.push((g.object_class, g.object_instance));
            let fb = respond(&mut s, &mut c, Request::GraspFeedback(GraspFeedback::Ok));
            assert_eq!(fb.code, ResponseCode::Success);
        }
        assert_eq!(picked, [(1, 0), (1, 1), (2, 0)]);
    }

    #[test]
    fn modes_tools_and_classes() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        // Class 2 has no active grasp.
        let r = respond(
            &mut s,
            &mut c,
            get_grasp(2, GraspMode::ActiveGrasp, Tool::Exterior),
        );
        assert_eq!(r.code, ResponseCode::NoGrasp);
        let r = respond(
            &mut s,
            &mut c,
            get_grasp(2, GraspMode::AnyGrasp, Tool::Exterior),
        );
        assert!(matches!(r.body, ResponseBody::Grasp(g) if g.grasp_mode == GraspMode::AnyGrasp));
        // Model-free fallback for suction on class 2.
        let r = respond(
            &mut s,
            &mut c,
            get_grasp(2, GraspMode::AutoGrasp, Tool::Contact),
        );
        assert!(matches!(r.body, ResponseBody::Grasp(g) if g.grasp_mode == GraspMode::AutoGrasp));
        let r = respond(
            &mut s,
            &mut c,
            get_grasp(7, GraspMode::AnyGrasp, Tool::Exterior),
        );
        assert_eq!(r.code, ResponseCode::InvalidObjectClass);
        let r = respond(&mut s, &mut c, Request::GetObjectCount { object_class: 1 });
        assert_eq!(
            r.body,
            ResponseBody::ObjectCount(ObjectCount {
                object_class: 1,
                object_count: 3,
                candidate_count: 2
            })
        );
    }

    #[test]
    fn bad_feedback_keeps_the_object_and_feedback_needs_a_grasp() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        let r = respond(&mut s, &mut c, Request::GraspFeedback(GraspFeedback::Ok));
        assert_eq!(r.code, ResponseCode::Error);
        respond(
            &mut s,
            &mut c,
            get_grasp(0, GraspMode::AnyGrasp, Tool::Exterior),
        );
        respond(&mut s, &mut c, Request::GraspFeedback(GraspFeedback::Bad));
        assert_eq!(s.projects()[0].scene.len(), 3);
    }

    #[test]
    fn counter_wraps_and_too_old_answers_empty() {
        let mut s = SimState::new(SimConfig {
            first_response_counter: 255,
            ..SimConfig::default()
        });
        let mut c = s.connect();
        assert_eq!(respond(&mut s, &mut c, Request::GetState).counter, 255);
        assert_eq!(respond(&mut s, &mut c, Request::GetState).counter, 0);

        let mut old = SimState::new(SimConfig {
            protocol_version: 2,
            ..SimConfig::default()
        });
        let mut c = old.connect();
        assert_eq!(
            old.handle(&mut c, &Request::GetState.to_frame()),
            Action::RespondEmpty(Prefix {
                version: 2,
                length: 0
            })
        );
    }

    #[test]
    fn a_newer_message_of_any_length_gets_too_old_and_a_plain_bad_length_nothing() {
        let s = SimState::new(SimConfig::default());
        let newer = Prefix {
            version: PROTOCOL_VERSION + 2,
            length: 200,
        }
        .encode();
        assert_eq!(
            s.too_old_for(&newer),
            Some(Prefix {
                version: PROTOCOL_VERSION,
                length: 0
            })
        );
        assert_eq!(s.too_old_for(&newer[..5]), None);
        let bad_length = Prefix {
            version: PROTOCOL_VERSION,
            length: 200,
        }
        .encode();
        assert_eq!(s.too_old_for(&bad_length), None);
    }

    #[test]
    fn unknown_message_type_gets_error_with_the_same_type() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        let frame = RequestFrame::new(MessageType::Unknown(99));
        let Action::Respond(r) = s.handle(&mut c, &frame) else {
            panic!()
        };
        assert_eq!(r.header.response_code, ResponseCode::Error);
        assert_eq!(r.header.message_type, MessageType::Unknown(99));
    }

    #[test]
    fn parse_request_needs_80_bytes_and_refuses_other_lengths() {
        let bytes = Request::GetState.to_frame().encode();
        assert_eq!(parse_request(&bytes[..79]), Ok(None));
        assert_eq!(
            parse_request(&bytes)
                .unwrap()
                .map(|(f, n)| (f.header.message_type, n)),
            Some((MessageType::GetState, 80))
        );
        let mut bad = bytes;
        bad[2..6].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(parse_request(&bad).is_err());
    }

    proptest::proptest! {
        /// Whatever arrives, the simulator answers (or refuses the length) without panicking,
        /// and a response always carries the request's message type.
        #[test]
        fn arbitrary_requests_never_panic(
            head in proptest::array::uniform32(proptest::prelude::any::<u8>()),
            tail in proptest::array::uniform32(proptest::prelude::any::<u8>()),
            rest in proptest::array::uniform16(proptest::prelude::any::<u8>()),
            keep_prefix in proptest::prelude::any::<bool>(),
        ) {
            let mut bytes: Vec<u8> = head.iter().chain(&tail).chain(&rest).copied().collect();
            if keep_prefix {
                bytes[..6].copy_from_slice(&Prefix::V3.encode());
            }
            let mut s = SimState::new(SimConfig::default());
            let mut c = s.connect();
            if let Ok(Some((frame, used))) = parse_request(&bytes) {
                proptest::prop_assert_eq!(used, FRAME_LEN);
                if let Action::Respond(r) = s.handle(&mut c, &frame) {
                    proptest::prop_assert_eq!(r.header.message_type, frame.header.message_type);
                }
            }
        }
    }

    #[test]
    fn reports_kept_for_inspection_are_bounded() {
        let mut state = SimState::new(SimConfig::default());
        let mut conn = state.connect();
        for _ in 0..3 * RECORD_LIMIT {
            let frame = Request::RegisterClient(RobotSystem::Kuka).to_frame();
            state.handle(&mut conn, &frame);
        }
        assert!(state.registered_clients().len() <= RECORD_LIMIT);
        assert!(state.registered_clients().len() >= RECORD_LIMIT * 3 / 4);
    }
}
