//! The simulated server's state machine, pure: a request frame in, an [`Action`] out. No sockets,
//! no clocks (a delay is an action the server carries out), so every rule is tested directly and
//! fuzz targets can call [`parse_request`] and [`SimState::handle`].

use std::collections::VecDeque;
use std::time::Duration;

use crate::smartgrasp::codec::{peek_frame, Peeked};
use crate::smartgrasp::frame::{v4, AnyRequestFrame, AnyResponseFrame, Prefix, FRAME_LEN};
use crate::smartgrasp::message::{
    Grasp, GraspRequest, ObjectCount, ObjectOffset, Request, Response, ResponseBody,
};
use crate::smartgrasp::pose::{Pose, SiPose, UnitQuaternion};
use crate::smartgrasp::types::{
    GraspFeedback, GraspMode, PoseFormat, ReferenceFrame, ResponseCode, RobotSystem, ServerState,
    Tool,
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
    /// Offset from the object centre to the grasp point, µm, robot base frame (V4 sends x, y).
    pub center_offset_um: [i32; 3],
    /// V4's object offset (sent in V4 responses only).
    pub object_offset: ObjectOffset,
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
    /// Do not carry the request out; answer it with this response code and no payload (a
    /// refusal the program must handle, e.g. a code newer than the manual's,
    /// `ResponseCode::Unknown`).
    Refuse(ResponseCode),
}

/// How the simulated server starts.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The highest protocol version the server speaks (default 4). It answers every request of
    /// a higher version with the empty "too old" message carrying this number (manual 1.3),
    /// whatever the request's length: 3 makes it a V3-only server that answers V4 that way.
    /// Every request of this version or lower is answered in the layout and with the version the
    /// request used (V4 for 4, V3's otherwise).
    pub max_version: u16,
    /// What GET_STATE reports. Detection calls fail with ERROR unless OPERATIONAL.
    pub server_state: ServerState,
    /// The projects, by index (V3's SET_PROJECT) or ID (V4's: the simulator takes the ID as the
    /// index; how a real server relates them is not public).
    pub projects: Vec<SimProject>,
    /// The project active before any SET_PROJECT.
    pub active_project: Option<u32>,
    /// The tool IDs V4's SET_TOOL accepts, and the kind of tool each is (which of an object's
    /// grasps it takes). Default: 1 exterior, 2 interior, 3 contact. Before any SET_TOOL, a V4
    /// GET_GRASP grasps with an exterior tool.
    pub tools: Vec<(u16, Tool)>,
    /// The workspace IDs V4's SET_WORKSPACE accepts (default 0 and 1, what SCHUNK's example
    /// sends). The simulator records the choice; it does not change the scene.
    pub workspaces: Vec<u16>,
    /// What V4 GET_GRASP responses carry as reference frame (byte 19; values not public).
    pub reference_frame: ReferenceFrame,
    /// The response counter of each connection's first response (to cross 255 quickly in tests).
    pub first_response_counter: u8,
    /// Whether GRASP_FEEDBACK stands in for the robot taking the part out of the bin (default
    /// `false`).
    ///
    /// SCHUNK's own clients say the message has no effect: its V3 KRL file says "Has no effect on
    /// Version 3", its V4 one "no effect in V4" and sends feedback 0 (PROTOCOLS.md 2b). So by
    /// default every GRASP_FEEDBACK, whatever its value and with or without a grasp before it, is
    /// answered SUCCESS and changes nothing; a real bin empties because the robot takes the parts,
    /// which the camera then no longer sees.
    ///
    /// With `true` (the simulator's behaviour before issue 21, for picking loops and demos against
    /// the simulator alone): OK removes the last GET_GRASP's object from the scene, BAD keeps it,
    /// and a feedback with no grasp to refer to, or a value the manual does not list (3.3.3.2: 1
    /// OK, 2 BAD), is answered ERROR.
    pub feedback_removes_objects: bool,
}

impl Default for SimConfig {
    /// An operational v4 server with [`SimConfig::demo_project`] as project 0, active.
    fn default() -> Self {
        SimConfig {
            max_version: v4::PROTOCOL_VERSION,
            server_state: ServerState::Operational,
            projects: vec![SimConfig::demo_project()],
            active_project: Some(0),
            tools: vec![(1, Tool::Exterior), (2, Tool::Interior), (3, Tool::Contact)],
            workspaces: vec![0, 1],
            reference_frame: ReferenceFrame(0),
            first_response_counter: 0,
            feedback_removes_objects: false,
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
            object_offset: ObjectOffset {
                x_um: 1_250,
                y_um: -640,
                rz_udeg: -25_210_142,
            },
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
    Respond(AnyResponseFrame),
    /// Send the empty "too old" message: a prefix with length 0 and the server's version.
    RespondEmpty(Prefix),
    /// Send nothing (an injected [`Fault::DropReply`]).
    Skip,
    /// Send this response after the delay.
    Delay(Duration, AnyResponseFrame),
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
    active_tool: Option<u16>,
    active_workspace: Option<u16>,
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
pub fn parse_request(bytes: &[u8]) -> Result<Option<(AnyRequestFrame, usize)>, Malformed> {
    match peek_frame(bytes) {
        Ok(Peeked::Incomplete { .. }) => Ok(None),
        Ok(Peeked::Frame(frame)) => Ok(Some((AnyRequestFrame::decode(&frame), FRAME_LEN))),
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
            active_tool: None,
            active_workspace: None,
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

    /// Drops the faults no response has taken yet; returns how many.
    pub fn clear_faults(&mut self) -> usize {
        let queued = self.faults.len();
        self.faults.clear();
        queued
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

    /// Sets the highest protocol version the server speaks from the next request on (a firmware
    /// update or rollback, see [`SimConfig::max_version`]).
    pub fn set_max_version(&mut self, version: u16) {
        self.config.max_version = version;
    }

    /// The "too old" empty message for the bytes of a message this server cannot read (a length
    /// other than 74), if its prefix carries a version newer than the server's: manual 1.3 says
    /// a server older than the client always answers with it, whatever the rest of the message.
    /// `None` for an incomplete prefix or a version the server speaks (a plain bad length).
    pub fn too_old_for(&self, bytes: &[u8]) -> Option<Prefix> {
        let prefix = Prefix::decode(bytes.first_chunk()?);
        (prefix.version > self.config.max_version).then_some(Prefix {
            version: self.config.max_version,
            length: 0,
        })
    }

    /// The tool ID V4's SET_TOOL chose last (`None` before any).
    pub fn active_tool(&self) -> Option<u16> {
        self.active_tool
    }

    /// The workspace ID V4's SET_WORKSPACE chose last (`None` before any).
    pub fn active_workspace(&self) -> Option<u16> {
        self.active_workspace
    }

    /// Handles one request frame of either version.
    pub fn handle(&mut self, conn: &mut SimConnection, frame: &AnyRequestFrame) -> Action {
        let version = frame.version();
        // Manual 1.3: a server older than the client answers with an empty message carrying its
        // highest version; it never answers a frame of a version it does not speak.
        if version > self.config.max_version {
            return Action::RespondEmpty(Prefix {
                version: self.config.max_version,
                length: 0,
            });
        }
        let counter = conn.next_counter;
        conn.next_counter = counter.wrapping_add(1);
        // A refusal injected for this request replaces carrying it out.
        let refusal = match self.faults.front() {
            Some(&Fault::Refuse(code)) => {
                self.faults.pop_front();
                Some(code)
            }
            _ => None,
        };
        let (code, body) = match (refusal, Request::from_any_frame(frame)) {
            (Some(code), _) => (code, ResponseBody::Empty),
            (None, Ok(request)) => self.process(request, version),
            (None, Err(e)) => {
                tracing::debug!(error = %e, "simulator refused a request");
                (ResponseCode::Error, ResponseBody::Empty)
            }
        };
        let message_type = frame.header().message_type;
        let respond = |code, body| Response {
            message_type,
            code,
            counter,
            body,
        };
        // The server answers with the version the request used (manual 1.3), in its layout.
        let response: AnyResponseFrame = match frame {
            AnyRequestFrame::V3(_) => respond(code, body).to_frame(version).into(),
            AnyRequestFrame::V4(_) => match respond(code, body).to_v4_frame() {
                Ok(f) => f.into(),
                // A pose V4 cannot carry (never built: GET_GRASP refuses a quaternion first).
                Err(_) => v4::ResponseFrame::new(message_type, ResponseCode::Error, counter).into(),
            },
        };
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
            // Taken before the request was carried out (above); not reached.
            Some(Fault::Refuse(_)) => Action::Respond(response),
        }
    }

    /// Carries out a request of protocol `version`.
    fn process(&mut self, request: Request, version: u16) -> (ResponseCode, ResponseBody) {
        const OK: ResponseCode = ResponseCode::Success;
        const EMPTY: ResponseBody = ResponseBody::Empty;
        const ERROR: (ResponseCode, ResponseBody) = (ResponseCode::Error, ResponseBody::Empty);
        match request {
            Request::GetProtocolVersion => {
                (OK, ResponseBody::ProtocolVersion(self.config.max_version))
            }
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
            Request::SetTool { tool_id } => {
                if !self.config.tools.iter().any(|&(id, _)| id == tool_id) {
                    return ERROR;
                }
                self.active_tool = Some(tool_id);
                (OK, EMPTY)
            }
            Request::SetWorkspace { workspace_id } => {
                if !self.config.workspaces.contains(&workspace_id) {
                    return ERROR;
                }
                self.active_workspace = Some(workspace_id);
                (OK, EMPTY)
            }
            Request::RobotPose(pose) => {
                record(&mut self.robot_poses, pose);
                (OK, EMPTY)
            }
            Request::GetGrasp(mut g) => {
                let Some(p) = self.operational_project() else {
                    return ERROR;
                };
                if version >= v4::PROTOCOL_VERSION {
                    // V4 chooses the tool with SET_TOOL, not in the request.
                    g.tool = self.v4_tool();
                }
                let (code, mut body) = self.get_grasp(p, g);
                if let ResponseBody::Grasp(grasp) = &mut body {
                    if version >= v4::PROTOCOL_VERSION {
                        grasp.tool = None;
                        grasp.angle_offset_udeg = None;
                        grasp.center_offset_z_um = None;
                    } else {
                        grasp.reference_frame = None;
                        grasp.object_offset = None;
                    }
                }
                (code, body)
            }
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
            // No effect, as SCHUNK's examples say (see `SimConfig::feedback_removes_objects`).
            Request::GraspFeedback(_) if !self.config.feedback_removes_objects => (OK, EMPTY),
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

    /// The kind of tool the last SET_TOOL chose; exterior before any.
    fn v4_tool(&self) -> Tool {
        self.active_tool
            .and_then(|id| self.config.tools.iter().find(|&&(t, _)| t == id))
            .map_or(Tool::Exterior, |&(_, tool)| tool)
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
        // Both layouts' fields are filled; `process` keeps those of the request's version.
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
            center_offset_um: [
                definition.center_offset_um[0],
                definition.center_offset_um[1],
            ],
            pose,
            object_count: count(project.scene.len()),
            candidate_count,
            center_offset_z_um: Some(definition.center_offset_um[2]),
            angle_offset_udeg: Some(definition.angle_offset_udeg),
            tool: Some(request.tool),
            reference_frame: Some(self.config.reference_frame),
            object_offset: Some(definition.object_offset),
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
    use crate::smartgrasp::frame::{RequestFrame, PROTOCOL_VERSION};
    use crate::smartgrasp::types::{MessageType, SelectionCriterion};

    fn respond(state: &mut SimState, conn: &mut SimConnection, request: Request) -> Response {
        respond_in(state, conn, request, PROTOCOL_VERSION)
    }

    fn respond_in(
        state: &mut SimState,
        conn: &mut SimConnection,
        request: Request,
        version: u16,
    ) -> Response {
        match state.handle(conn, &request.to_any_frame(version).unwrap()) {
            Action::Respond(f) => {
                assert_eq!(f.version(), version, "answered in the request's version");
                Response::from_any_frame(&f).unwrap()
            }
            other => panic!("expected a response, got {other:?}"),
        }
    }

    fn get_grasp(class: u16, mode: GraspMode, tool: Tool) -> Request {
        Request::GetGrasp(GraspRequest {
            grasp_mode: mode,
            object_class: class,
            tool,
            selection_criterion: SelectionCriterion::default(),
            pose_format: PoseFormat::Abc,
        })
    }

    /// A fault a test queued and no response took is gone once cleared: the next response is
    /// plain (a test that ends its faulty part must not have a queued delay land in what
    /// follows; the explorer's quiet phase, smartgrasp-v4:0xc668e9dd97aab966).
    #[test]
    fn cleared_faults_touch_no_later_response() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        s.inject(Fault::DelayReply(Duration::from_secs(3)));
        s.inject(Fault::DropReply);
        assert_eq!(s.clear_faults(), 2);
        assert_eq!(s.clear_faults(), 0);
        let frame = Request::GetState.to_any_frame(PROTOCOL_VERSION).unwrap();
        assert!(matches!(s.handle(&mut c, &frame), Action::Respond(_)));
    }

    /// An injected refusal answers the next request with its code and no payload, and the
    /// request is not carried out (no client registered); the one after is served as ever.
    #[test]
    fn a_refusal_answers_the_next_request_with_its_code_and_does_nothing() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        s.inject(Fault::Refuse(ResponseCode::Unknown(200)));
        let refused = respond(&mut s, &mut c, Request::RegisterClient(RobotSystem::Kuka));
        assert_eq!(refused.code, ResponseCode::Unknown(200));
        assert_eq!(refused.body, ResponseBody::Empty);
        assert!(s.registered_clients().is_empty(), "not carried out");
        let served = respond(&mut s, &mut c, Request::RegisterClient(RobotSystem::Kuka));
        assert_eq!(served.code, ResponseCode::Success);
        assert_eq!(s.registered_clients(), [RobotSystem::Kuka]);
    }

    #[test]
    fn picking_empties_the_scene_then_no_object() {
        let mut s = SimState::new(SimConfig {
            feedback_removes_objects: true,
            ..SimConfig::default()
        });
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
        let mut s = SimState::new(SimConfig {
            feedback_removes_objects: true,
            ..SimConfig::default()
        });
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
            max_version: 2,
            ..SimConfig::default()
        });
        let mut c = old.connect();
        assert_eq!(
            old.handle(&mut c, &Request::GetState.to_frame().into()),
            Action::RespondEmpty(Prefix {
                version: 2,
                length: 0
            })
        );
    }

    #[test]
    fn a_newer_message_of_any_length_gets_too_old_and_a_plain_bad_length_nothing() {
        let s = SimState::new(SimConfig {
            max_version: 3,
            ..SimConfig::default()
        });
        // A V4 frame of a length that is not V4's, and a V5 one.
        for version in [4, 5] {
            let newer = Prefix {
                version,
                length: 200,
            }
            .encode();
            assert_eq!(
                s.too_old_for(&newer),
                Some(Prefix {
                    version: 3,
                    length: 0
                })
            );
        }
        let newer = Prefix {
            version: 4,
            length: 200,
        }
        .encode();
        assert_eq!(s.too_old_for(&newer[..5]), None);
        let bad_length = Prefix {
            version: PROTOCOL_VERSION,
            length: 200,
        }
        .encode();
        assert_eq!(s.too_old_for(&bad_length), None);
    }

    #[test]
    fn v4_requests_get_v4_answers_and_choose_tool_and_workspace() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        let v4 = v4::PROTOCOL_VERSION;
        let r = respond_in(
            &mut s,
            &mut c,
            Request::GetProtocolVersion,
            PROTOCOL_VERSION,
        );
        assert_eq!(r.body, ResponseBody::ProtocolVersion(4));
        assert_eq!(
            respond_in(&mut s, &mut c, Request::SetTool { tool_id: 9 }, v4).code,
            ResponseCode::Error
        );
        // Tool 3 is a contact tool: class 2's model-free suction grasp.
        let r = respond_in(&mut s, &mut c, Request::SetTool { tool_id: 3 }, v4);
        assert_eq!(r.code, ResponseCode::Success);
        assert_eq!(s.active_tool(), Some(3));
        let r = respond_in(
            &mut s,
            &mut c,
            Request::SetWorkspace { workspace_id: 1 },
            v4,
        );
        assert_eq!(r.code, ResponseCode::Success);
        assert_eq!(s.active_workspace(), Some(1));
        let mut request = get_grasp(2, GraspMode::AutoGrasp, Tool::Unknown(0));
        if let Request::GetGrasp(g) = &mut request {
            g.selection_criterion = SelectionCriterion(2);
        }
        let r = respond_in(&mut s, &mut c, request, v4);
        let ResponseBody::Grasp(g) = r.body else {
            panic!("{r:?}")
        };
        assert_eq!(g.grasp_mode, GraspMode::AutoGrasp);
        assert_eq!(
            (g.tool, g.angle_offset_udeg, g.center_offset_z_um),
            (None, None, None)
        );
        assert!(g.object_offset.is_some() && g.reference_frame.is_some());
        // The same request as V3 names its tool, and gets V3's fields.
        let r = respond_in(
            &mut s,
            &mut c,
            get_grasp(2, GraspMode::AutoGrasp, Tool::Contact),
            3,
        );
        let ResponseBody::Grasp(g) = r.body else {
            panic!("{r:?}")
        };
        assert_eq!(g.tool, Some(Tool::Contact));
        assert_eq!((g.object_offset, g.reference_frame), (None, None));
        // SET_TOOL is no V3 message.
        let r = respond_in(&mut s, &mut c, Request::GetState, 3);
        assert_eq!(r.code, ResponseCode::Success);
        let frame = RequestFrame::new(MessageType::SetTool);
        let Action::Respond(r) = s.handle(&mut c, &frame.into()) else {
            panic!()
        };
        assert_eq!(r.header().response_code, ResponseCode::Error);
    }

    #[test]
    fn a_server_pinned_to_v3_answers_v4_with_too_old() {
        let mut s = SimState::new(SimConfig {
            max_version: 3,
            ..SimConfig::default()
        });
        let mut c = s.connect();
        let v4_frame = Request::GetState.to_any_frame(4).unwrap();
        assert_eq!(
            s.handle(&mut c, &v4_frame),
            Action::RespondEmpty(Prefix {
                version: 3,
                length: 0
            })
        );
        let r = respond_in(&mut s, &mut c, Request::GetProtocolVersion, 3);
        assert_eq!(r.body, ResponseBody::ProtocolVersion(3));
    }

    #[test]
    fn unknown_message_type_gets_error_with_the_same_type() {
        let mut s = SimState::new(SimConfig::default());
        let mut c = s.connect();
        let frame = RequestFrame::new(MessageType::Unknown(99));
        let Action::Respond(r) = s.handle(&mut c, &frame.into()) else {
            panic!()
        };
        assert_eq!(r.header().response_code, ResponseCode::Error);
        assert_eq!(r.header().message_type, MessageType::Unknown(99));
    }

    #[test]
    fn parse_request_needs_80_bytes_and_refuses_other_lengths() {
        let bytes = Request::GetState.to_frame().encode();
        assert_eq!(parse_request(&bytes[..79]), Ok(None));
        assert_eq!(
            parse_request(&bytes)
                .unwrap()
                .map(|(f, n)| (f.header().message_type, n)),
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
                    proptest::prop_assert_eq!(r.header().message_type, frame.header().message_type);
                    proptest::prop_assert_eq!(r.version(), frame.version());
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
            state.handle(&mut conn, &frame.into());
        }
        assert!(state.registered_clients().len() <= RECORD_LIMIT);
        assert!(state.registered_clients().len() >= RECORD_LIMIT * 3 / 4);
    }
}
