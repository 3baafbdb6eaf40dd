//! `gripper_rs.smartgrasp`: the Grasping-Kit client (blocking and asyncio) and
//! `gripper_rs.smartgrasp.sim.SimServer`.

use std::net::SocketAddr;

use gripper::smartgrasp::{
    self, Error, GetGraspOutcome, Grasp, GraspFeedback, GraspMode, GraspRequest, ObjectCount, Pose,
    PoseFormat, RobotSystem, SelectionCriterion, ServerState, Tool,
};
use pyo3::prelude::*;

use crate::args::Checked;
use crate::convert::{enum_member, enum_value, field, record, ToPy};
use crate::errors;
use crate::events;
use crate::runtime::{self, seconds};
use crate::sim::Slot;
use crate::stream::Stream;

const PY: &str = "gripper_rs.smartgrasp";

classified!(Error, refusal);

/// A SmartGrasp server's refusal (`DeviceError`). A server that is not OPERATIONAL (kind
/// `Device`) sent no response code: no refusal, a `ProtocolError`.
fn refusal(e: Error) -> Option<errors::Device> {
    let Error::Device {
        message_type,
        status,
    } = e
    else {
        return None;
    };
    let d = errors::Device::new(i64::from(u8::from(status)), message_type.to_string())
        .status(PY, "ResponseCode");
    Some(match status {
        smartgrasp::ResponseCode::Unknown(_) => d,
        known => {
            // Display is "SYMBOL (text)" (manual 3.2).
            let text = known.to_string();
            let (name, description) = text.split_once(' ').unwrap_or((&text, ""));
            let description = description.trim_start_matches('(').trim_end_matches(')');
            d.known(name, description)
        }
    })
}

// ---- results -------------------------------------------------------------------------------

impl ToPy for ServerState {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        enum_value(py, PY, "ServerState", i64::from(u8::from(self)))
    }
}

fn pose_record(py: Python<'_>, pose: &Pose) -> PyResult<Py<PyAny>> {
    let format = enum_value(py, PY, "PoseFormat", i64::from(u8::from(pose.format())))?;
    let si = pose.to_si().ok();
    record(
        py,
        PY,
        "Pose",
        &[
            ("format", format.into_bound(py)),
            ("wire", field(py, pose.to_wire())?),
            // µm / 1e6 rather than the crate's µm * 1e-6: the division is correctly rounded, so
            // Python shows 0.45, not 0.44999999999999996.
            (
                "position_m",
                field(py, pose.position_um().map(|um| f64::from(um) / 1e6))?,
            ),
            (
                "orientation_xyzw",
                field(py, si.map(|s| s.orientation.xyzw()))?,
            ),
        ],
    )
}

impl ToPy for Grasp {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let grasp_mode = enum_value(py, PY, "GraspMode", i64::from(u8::from(self.grasp_mode)))?;
        let tool = self
            .tool
            .map(|t| enum_value(py, PY, "Tool", i64::from(u8::from(t))))
            .transpose()?;
        let pose = pose_record(py, &self.pose)?;
        let object_offset = self
            .object_offset
            .map(|o| {
                record(
                    py,
                    PY,
                    "ObjectOffset",
                    &[
                        ("x_um", field(py, o.x_um)?),
                        ("y_um", field(py, o.y_um)?),
                        ("rz_udeg", field(py, o.rz_udeg)?),
                    ],
                )
            })
            .transpose()?;
        record(
            py,
            PY,
            "Grasp",
            &[
                ("grasp_mode", grasp_mode.into_bound(py)),
                ("object_class", field(py, self.object_class)?),
                ("object_instance", field(py, self.object_instance)?),
                ("stroke_um", field(py, self.stroke_um)?),
                ("center_offset_um", field(py, self.center_offset_um)?),
                ("pose", pose.into_bound(py)),
                ("object_count", field(py, self.object_count)?),
                ("candidate_count", field(py, self.candidate_count)?),
                // What only one protocol version delivers is None from the other.
                ("center_offset_z_um", field(py, self.center_offset_z_um)?),
                ("angle_offset_udeg", field(py, self.angle_offset_udeg)?),
                ("tool", field(py, tool)?),
                (
                    "reference_frame",
                    field(py, self.reference_frame.map(u8::from))?,
                ),
                ("object_offset", field(py, object_offset)?),
            ],
        )
    }
}

/// A grasp, or `None` when the server found none; why not is `outcome`-specific: the Python
/// `GetGraspOutcome` enum says which.
impl ToPy for GetGraspOutcome {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let (member, grasp) = match self {
            GetGraspOutcome::Grasp(g) => ("GRASP", Some(g.to_py(py)?)),
            GetGraspOutcome::NoObject => ("NO_OBJECT", None),
            GetGraspOutcome::NoGrasp => ("NO_GRASP", None),
            GetGraspOutcome::InvalidObjectClass => ("INVALID_OBJECT_CLASS", None),
        };
        let outcome = enum_member(py, PY, "GetGraspOutcome", member)?;
        record(
            py,
            PY,
            "GraspResult",
            &[
                ("outcome", outcome.into_bound(py)),
                ("grasp", field(py, grasp)?),
            ],
        )
    }
}

impl ToPy for ObjectCount {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        record(
            py,
            PY,
            "ObjectCount",
            &[
                ("object_class", field(py, self.object_class)?),
                ("object_count", field(py, self.object_count)?),
                ("candidate_count", field(py, self.candidate_count)?),
            ],
        )
    }
}

// ---- arguments -----------------------------------------------------------------------------

/// A wire enum from its number: numbers the manual does not list (`is_unknown`) are refused
/// before sending.
fn known<T: From<u8>>(what: &str, n: u8, is_unknown: fn(&T) -> bool) -> PyResult<T> {
    let v = T::from(n);
    if is_unknown(&v) {
        Err(errors::invalid_argument(format!("unknown {what} {n}")))
    } else {
        Ok(v)
    }
}

#[allow(clippy::too_many_arguments)]
fn config(
    query_timeout_s: Option<f64>,
    detection_timeout_s: Option<f64>,
    connect_timeout_s: Option<f64>,
    robot_system: Option<Checked<u8>>,
    project_index: Option<Checked<u32>>,
    v4: V4Options,
) -> PyResult<smartgrasp::ClientConfig> {
    let mut c = smartgrasp::ClientConfig::default();
    if let Some(s) = query_timeout_s {
        c.query_timeout = seconds("query_timeout_s", s)?;
    }
    if let Some(s) = detection_timeout_s {
        c.detection_timeout = seconds("detection_timeout_s", s)?;
    }
    if let Some(s) = connect_timeout_s {
        c.connect_timeout = seconds("connect_timeout_s", s)?;
    }
    c.robot_system = robot_system
        .map(|n| {
            known("robot system", n.0, |v| {
                matches!(v, RobotSystem::Unknown(_))
            })
        })
        .transpose()?;
    c.project_index = project_index.map(|v| v.0);
    c.protocol_version = v4.protocol_version.map(|v| v.0);
    c.tool_id = v4.tool_id.map(|v| v.0);
    c.workspace_id = v4.workspace_id.map(|v| v.0);
    Ok(c)
}

/// The connect options protocol V4 added: a pinned version (3 or 4; None negotiates), and the
/// tool and workspace IDs to choose after opening (V4 only).
struct V4Options {
    protocol_version: Option<Checked<u16>>,
    tool_id: Option<Checked<u16>>,
    workspace_id: Option<Checked<u16>>,
}

fn grasp_request(
    grasp_mode: u8,
    object_class: u16,
    tool: u8,
    pose_format: u8,
    selection_criterion: u8,
) -> PyResult<GraspRequest> {
    Ok(GraspRequest {
        grasp_mode: known("grasp mode", grasp_mode, |v| {
            matches!(v, GraspMode::Unknown(_))
        })?,
        object_class,
        tool: known("tool", tool, |v| matches!(v, Tool::Unknown(_)))?,
        selection_criterion: SelectionCriterion(selection_criterion),
        pose_format: known("pose format", pose_format, |v| {
            matches!(v, PoseFormat::Unknown(_))
        })?,
    })
}

fn feedback(ok: bool) -> GraspFeedback {
    if ok {
        GraspFeedback::Ok
    } else {
        GraspFeedback::Bad
    }
}

fn pose(format: u8, wire: [i32; 7]) -> PyResult<Pose> {
    let format = known("pose format", format, |v| {
        matches!(v, PoseFormat::Unknown(_))
    })?;
    Pose::from_wire(format, wire).map_err(|e| errors::invalid_argument(format!("pose: {e}")))
}

// ---- the client ----------------------------------------------------------------------------

/// A SCHUNK 2D Grasping-Kit (blocking API). `with` closes the connection.
#[pyclass(module = "gripper_rs.smartgrasp", name = "Client", frozen, weakref)]
pub struct Client {
    inner: smartgrasp::Client,
}

/// A SCHUNK 2D Grasping-Kit (asyncio API).
#[pyclass(module = "gripper_rs.aio.smartgrasp", name = "Client", frozen, weakref)]
pub struct AioClient {
    inner: smartgrasp::Client,
}

impl ToPy for AioClient {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Ok(crate::lifecycle::track(py, self)?.into_any())
    }
}

/// `close()` (and leaving a `with` block), idempotent ([`errors::close_for_exit`]).
async fn close_for_exit(c: smartgrasp::Client) -> smartgrasp::Result<()> {
    errors::close_for_exit(c.close(), || c.is_closed()).await
}

twins! {
    Client, AioClient, error;
    closing close_for_exit;
    blocking {
        /// Connects to "host:port" and opens the session (protocol version, state, and the
        /// `robot_system` registration and `project_index` when given).
        #[staticmethod]
        // Python's keyword-only arguments mirror the fields of the Rust `ClientConfig`.
        #[allow(clippy::too_many_arguments)]
        #[pyo3(signature = (addr, *, query_timeout_s=None, detection_timeout_s=None, connect_timeout_s=None, robot_system=None, project_index=None, protocol_version=None, tool_id=None, workspace_id=None, reconnect=None))]
        fn connect(
            py: Python<'_>,
            addr: String,
            query_timeout_s: Option<f64>,
            detection_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            robot_system: Option<Checked<u8>>,
            project_index: Option<Checked<u32>>,
            protocol_version: Option<Checked<u16>>,
            tool_id: Option<Checked<u16>>,
            workspace_id: Option<Checked<u16>>,
            reconnect: Option<Bound<'_, PyAny>>,
        ) -> PyResult<Py<Client>> {
            let v4 = V4Options { protocol_version, tool_id, workspace_id };
            let mut c = config(query_timeout_s, detection_timeout_s, connect_timeout_s, robot_system, project_index, v4)?;
            c.reconnect = events::policy(reconnect)?;
            let inner = runtime::block_on(py, smartgrasp::Client::connect(addr, c), error)?;
            crate::lifecycle::track(py, Client { inner })
        }


        /// A handle on the same connection whose calls use another timeout.
        fn with_timeout(&self, timeout_s: f64) -> PyResult<Client> {
            Ok(Client { inner: self.inner.with_timeout(seconds("timeout_s", timeout_s)?) })
        }

    }
    aio {
        /// Connects to "host:port" and opens the session.
        #[staticmethod]
        // Python's keyword-only arguments mirror the fields of the Rust `ClientConfig`.
        #[allow(clippy::too_many_arguments)]
        #[pyo3(signature = (addr, *, query_timeout_s=None, detection_timeout_s=None, connect_timeout_s=None, robot_system=None, project_index=None, protocol_version=None, tool_id=None, workspace_id=None, reconnect=None))]
        fn connect<'py>(
            py: Python<'py>,
            addr: String,
            query_timeout_s: Option<f64>,
            detection_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            robot_system: Option<Checked<u8>>,
            project_index: Option<Checked<u32>>,
            protocol_version: Option<Checked<u16>>,
            tool_id: Option<Checked<u16>>,
            workspace_id: Option<Checked<u16>>,
            reconnect: Option<Bound<'py, PyAny>>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let v4 = V4Options { protocol_version, tool_id, workspace_id };
            let mut c = config(query_timeout_s, detection_timeout_s, connect_timeout_s, robot_system, project_index, v4)?;
            c.reconnect = events::policy(reconnect)?;
            runtime::awaitable(
                py,
                async move { smartgrasp::Client::connect(addr, c).await.map(|inner| AioClient { inner }) },
                error,
            )
        }

        /// A handle on the same connection whose calls use another timeout.
        fn with_timeout(&self, timeout_s: f64) -> PyResult<AioClient> {
            Ok(AioClient { inner: self.inner.with_timeout(seconds("timeout_s", timeout_s)?) })
        }


    }
    both {
        /// The connection's events from now on (`gripper_rs.reconnect.ConnectionEvent`): each
        /// loss, and with a reconnect policy each attempt and recovery. The stream ends when the
        /// connection is closed for good.
        fn connection_events(&self) -> PyResult<Stream> {
            events::stream(self.inner.connection_events())
        }

        /// The protocol version this connection speaks (3 or 4).
        fn protocol_version(&self) -> u16 {
            self.inner.protocol_version()
        }

        /// The server's highest protocol version, as it answered when connecting.
        fn server_version(&self) -> u16 {
            self.inner.server_version()
        }

        /// How many gaps in the response counter were seen (recorded, not fatal by default).
        fn counter_gaps(&self) -> u64 {
            self.inner.counter_gaps()
        }
    }

    /// GET_PROTOCOL_VERSION.
    fn get_protocol_version(&self) => |c| c.get_protocol_version();
    /// GET_STATE.
    fn get_state(&self) => |c| c.get_state();
    /// REGISTER_CLIENT (a `RobotSystem`).
    fn register_client(&self, robot: Checked<u8>) [let robot = robot.0; let robot = known("robot system", robot, |v| matches!(v, RobotSystem::Unknown(_)))?;] => |c| c.register_client(robot);
    /// SET_PROJECT (V3: the project index; V4: the project ID).
    fn set_project(&self, project_index: Checked<u32>) [let project_index = project_index.0;] => |c| c.set_project(project_index);
    /// SET_TOOL (V4 only): the tool ID seen in the web frontend.
    fn set_tool(&self, tool_id: Checked<u16>) [let tool_id = tool_id.0;] => |c| c.set_tool(tool_id);
    /// SET_WORKSPACE (V4 only): the workspace ID seen in the web frontend.
    fn set_workspace(&self, workspace_id: Checked<u16>) [let workspace_id = workspace_id.0;] => |c| c.set_workspace(workspace_id);
    /// GET_GRASP: a `GraspResult` (its `grasp` is None when the outcome is not GRASP).
    /// `tool` is sent in V3 only, `selection_criterion` in V4 only (its values are not public;
    /// SCHUNK's example sends 1 to 3).
    #[pyo3(signature = (grasp_mode, object_class, tool, pose_format, selection_criterion=Checked(1)))]
    fn get_grasp(&self, grasp_mode: Checked<u8>, object_class: Checked<u16>, tool: Checked<u8>, pose_format: Checked<u8>, selection_criterion: Checked<u8>)
        [let request = grasp_request(grasp_mode.0, object_class.0, tool.0, pose_format.0, selection_criterion.0)?;]
        => |c| c.get_grasp(request);
    /// GRASP_FEEDBACK: whether the last grasp was fine.
    fn grasp_feedback(&self, ok: bool) => |c| c.grasp_feedback(feedback(ok));
    /// GET_OBJECT_COUNT (class 0: all).
    fn get_object_count(&self, object_class: Checked<u16>) [let object_class = object_class.0;] => |c| c.get_object_count(object_class);
    /// ROBOT_POSE: the robot's pose, in `format` with the seven wire values.
    fn robot_pose(&self, format: Checked<u8>, wire: Checked<[i32; 7]>) [let format = format.0; let wire = wire.0; let p = pose(format, wire)?;] => |c| c.robot_pose(p);
    /// Closes the connection.
    fn close(&self) => |c| close_for_exit(c.clone());
}

// ---- the simulator -------------------------------------------------------------------------

/// A simulated Grasping-Kit serving TCP in this process (the Rust `SimConfig::default()`: the
/// demo project, operational).
#[pyclass(module = "gripper_rs.smartgrasp.sim", name = "SimServer", frozen)]
pub struct SimServer {
    server: Slot<smartgrasp::sim::SimServer>,
    addr: SocketAddr,
}

impl SimServer {
    fn with<R>(&self, f: impl FnOnce(&smartgrasp::sim::SimServer) -> R) -> PyResult<R> {
        self.server.with(f)
    }

    fn inject(&self, fault: smartgrasp::sim::Fault) -> PyResult<()> {
        self.with(|s| s.inject(fault))
    }
}

// `address`, `port`, `shutdown`, `with` and `repr` come with the macro (crate::sim).
sim_pymethods! { SimServer, "gripper_rs.smartgrasp.sim.SimServer";
    /// Starts a simulated Grasping-Kit on `addr`; `server_state` and `max_version` are the
    /// Rust `SimConfig`'s (defaults: OPERATIONAL, 4; 3 acts as a V3-only server).
    #[new]
    #[pyo3(signature = (*, server_state=None, max_version=None, addr="127.0.0.1:0"))]
    fn new(
        py: Python<'_>,
        server_state: Option<Checked<u8>>,
        max_version: Option<Checked<u16>>,
        addr: &str,
    ) -> PyResult<Self> {
        let mut config = smartgrasp::sim::SimConfig::default();
        if let Some(s) = server_state {
            config.server_state = ServerState::from(s.0);
        }
        if let Some(v) = max_version {
            config.max_version = v.0;
        }
        let addr = addr.to_owned();
        let server = runtime::block_on(py, smartgrasp::sim::SimServer::bind(addr, config), |e| {
            errors::transport(format!("cannot start the SmartGrasp simulator: {e}"))
        })?;
        let addr = server.local_addr();
        Ok(SimServer {
            server: Slot::new(server),
            addr,
        })
    }

    /// The robot systems registered so far (numbers of `RobotSystem`).
    fn registered_clients(&self, py: Python<'_>) -> PyResult<Vec<Py<PyAny>>> {
        self.with(|s| s.registered_clients())?
            .into_iter()
            .map(|r| enum_value(py, PY, "RobotSystem", i64::from(u8::from(r))))
            .collect()
    }

    /// The robot poses received so far.
    fn robot_poses(&self, py: Python<'_>) -> PyResult<Vec<Py<PyAny>>> {
        self.with(|s| s.robot_poses())?
            .iter()
            .map(|p| pose_record(py, p))
            .collect()
    }

    /// The server goes into `state` (a `ServerState`).
    fn set_server_state(&self, state: Checked<u8>) -> PyResult<()> {
        self.with(|s| s.with_state(|st| st.set_server_state(ServerState::from(state.0))))
    }

    /// The next request is processed but not answered.
    fn drop_next_reply(&self) -> PyResult<()> {
        self.inject(smartgrasp::sim::Fault::DropReply)
    }

    /// The next response comes `delay_s` late.
    fn delay_next_reply(&self, delay_s: f64) -> PyResult<()> {
        let d = seconds("delay_s", delay_s)?;
        self.inject(smartgrasp::sim::Fault::DelayReply(d))
    }

    /// The next response has `length` in its length field.
    fn corrupt_next_length(&self, length: Checked<u32>) -> PyResult<()> {
        self.inject(smartgrasp::sim::Fault::CorruptLength(length.0))
    }

    /// The connection is closed instead of the next response.
    fn close_next(&self) -> PyResult<()> {
        self.inject(smartgrasp::sim::Fault::Close)
    }

    /// The next request is not carried out but answered with response code `code` (a
    /// `ResponseCode`, or a number the manual does not define).
    fn refuse_next(&self, code: Checked<u8>) -> PyResult<()> {
        let code = smartgrasp::ResponseCode::from(code.0);
        self.inject(smartgrasp::sim::Fault::Refuse(code))
    }

}

/// `gripper_rs._native.smartgrasp`.
pub fn module(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    let m = PyModule::new(py, "smartgrasp")?;
    m.add_class::<Client>()?;
    m.add("AioClient", py.get_type::<AioClient>())?;
    m.add_class::<SimServer>()?;
    m.add("DEFAULT_PORT", smartgrasp::DEFAULT_PORT)?;
    Ok(m)
}
