//! `gripper_rs.wsg`: the WSG client (blocking and asyncio) and `gripper_rs.wsg.sim.SimServer`.

use std::net::SocketAddr;

use gripper::wsg::{
    self, Error, Finger, FingerFlags, FingerInfo, GraspingStatistics, GripState, HomingDirection,
    SoftLimits, Subscription, SystemInfo, SystemLimits, SystemState, UpdateOptions,
};
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::args::Checked;
use crate::convert::{enum_value, f32_to_f64, field, record, ToPy};
use crate::errors;
use crate::events;
use crate::runtime::{self, seconds};
use crate::sim::Slot;
use crate::stream::{ending_from_events, Ended, Stream};

const PY: &str = "gripper_rs.wsg";

classified!(Error, refusal);

/// A WSG device's refusal (`DeviceError`).
fn refusal(e: Error) -> Option<errors::Device> {
    match e {
        Error::Device { command, status } => Some(device(command, status)),
        _ => None,
    }
}

/// A WSG status code (binary and text interface: one table, manual Anhang A) as a refusal of
/// `command`: `name` and `description` only for a code the manual lists.
pub(crate) fn device<C>(command: C, status: wsg::Status) -> errors::Device
where
    C: for<'py> IntoPyObject<'py> + Send + 'static,
{
    let d = errors::Device::new(i64::from(status.code()), command).status(PY, "Status");
    match status {
        wsg::Status::Unknown(_) => d,
        known => d.known(known.symbol(), known.description()),
    }
}

// ---- results -------------------------------------------------------------------------------

impl ToPy for GripState {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        enum_value(py, PY, "GripState", i64::from(self.to_u8()))
    }
}

impl ToPy for SystemState {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        enum_value(py, PY, "SystemState", i64::from(self.bits()))
    }
}

impl ToPy for FingerFlags {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        enum_value(py, PY, "FingerFlags", i64::from(self.bits()))
    }
}

impl ToPy for SoftLimits {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        record(
            py,
            PY,
            "SoftLimits",
            &[
                ("minus_mm", field(py, f32_to_f64(self.minus_mm))?),
                ("plus_mm", field(py, f32_to_f64(self.plus_mm))?),
            ],
        )
    }
}

impl ToPy for Option<SoftLimits> {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        match self {
            Some(l) => l.to_py(py),
            None => Ok(py.None()),
        }
    }
}

impl ToPy for GraspingStatistics {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        record(
            py,
            PY,
            "GraspingStatistics",
            &[
                ("total", field(py, self.total)?),
                ("no_part", field(py, self.no_part)?),
                ("lost_part", field(py, self.lost_part)?),
            ],
        )
    }
}

impl ToPy for SystemInfo {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let device_type = enum_value(py, PY, "DeviceType", i64::from(self.device_type.to_u8()))?;
        record(
            py,
            PY,
            "SystemInfo",
            &[
                ("device_type", device_type.into_bound(py)),
                ("hardware_revision", field(py, self.hardware_revision)?),
                ("firmware_version", field(py, self.firmware.0)?),
                ("firmware", field(py, self.firmware.to_string())?),
                ("serial_number", field(py, self.serial_number)?),
            ],
        )
    }
}

impl ToPy for SystemLimits {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        record(
            py,
            PY,
            "SystemLimits",
            &[
                ("stroke_mm", field(py, f32_to_f64(self.stroke_mm))?),
                (
                    "min_speed_mm_per_s",
                    field(py, f32_to_f64(self.min_speed_mm_per_s))?,
                ),
                (
                    "max_speed_mm_per_s",
                    field(py, f32_to_f64(self.max_speed_mm_per_s))?,
                ),
                (
                    "min_acceleration_mm_per_s2",
                    field(py, f32_to_f64(self.min_acceleration_mm_per_s2))?,
                ),
                (
                    "max_acceleration_mm_per_s2",
                    field(py, f32_to_f64(self.max_acceleration_mm_per_s2))?,
                ),
                ("min_force_n", field(py, f32_to_f64(self.min_force_n))?),
                (
                    "nominal_force_n",
                    field(py, f32_to_f64(self.nominal_force_n))?,
                ),
                (
                    "overdrive_force_n",
                    field(py, f32_to_f64(self.overdrive_force_n))?,
                ),
            ],
        )
    }
}

impl ToPy for FingerInfo {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let finger_type = enum_value(py, PY, "FingerType", i64::from(self.finger_type.to_u8()))?;
        record(
            py,
            PY,
            "FingerInfo",
            &[
                ("finger_type", finger_type.into_bound(py)),
                ("data_size", field(py, self.data_size)?),
            ],
        )
    }
}

impl<T: ToPy> ToPy for Subscription<T> {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Stream::new(self).into_py_any(py)
    }
}

/// A subscription whose stream tells a lost connection (`ConnectionLostError`) from a closed
/// client: `events` is taken before the subscription is made, so that no loss is missed.
async fn subscribed<T: ToPy>(
    events: gripper::reconnect::ConnectionEvents,
    subscribe: impl std::future::Future<Output = wsg::Result<Subscription<T>>>,
) -> wsg::Result<Ended<Subscription<T>>> {
    Ok(Ended(subscribe.await?, ending_from_events(events)))
}

// ---- arguments -----------------------------------------------------------------------------

pub(crate) fn homing_direction(direction: u8) -> PyResult<HomingDirection> {
    match direction {
        0 => Ok(HomingDirection::Default),
        1 => Ok(HomingDirection::Positive),
        2 => Ok(HomingDirection::Negative),
        other => Err(errors::invalid_argument(format!(
            "homing direction must be 0 (default), 1 (positive) or 2 (negative), not {other}"
        ))),
    }
}

fn finger(n: u8) -> PyResult<Finger> {
    match n {
        1 => Ok(Finger::One),
        2 => Ok(Finger::Two),
        other => Err(errors::invalid_argument(format!(
            "finger must be 1 or 2, not {other}"
        ))),
    }
}

fn update_options(period_s: f64, on_change: bool) -> PyResult<UpdateOptions> {
    Ok(UpdateOptions {
        period: seconds("period_s", period_s)?,
        on_change,
    })
}

/// The client builder from the keyword options both `connect_*` share.
fn builder(
    query_timeout_s: Option<f64>,
    motion_timeout_s: Option<f64>,
    connect_timeout_s: Option<f64>,
    late_reply_grace_s: Option<f64>,
) -> PyResult<wsg::ClientBuilder> {
    let mut b = wsg::Client::builder();
    if let Some(s) = late_reply_grace_s {
        b = b.late_reply_grace(seconds("late_reply_grace_s", s)?);
    }
    if let Some(s) = query_timeout_s {
        b = b.query_timeout(seconds("query_timeout_s", s)?);
    }
    if let Some(s) = motion_timeout_s {
        b = b.motion_timeout(seconds("motion_timeout_s", s)?);
    }
    if let Some(s) = connect_timeout_s {
        b = b.connect_timeout(seconds("connect_timeout_s", s)?);
    }
    Ok(b)
}

/// "host:port" to one socket address (UDP needs exactly one).
async fn resolve(addr: &str) -> wsg::Result<SocketAddr> {
    tokio::net::lookup_host(addr)
        .await?
        .next()
        .ok_or_else(|| Error::InvalidArgument {
            what: "address",
            reason: format!("{addr:?} resolves to no address"),
        })
}

// ---- the clients ---------------------------------------------------------------------------

/// A WSG gripper (blocking API): every method waits for the device's reply with the GIL
/// released; any number of threads may share one client. `with` closes it (announcing the
/// disconnect, command 0x07, so the gripper does not FAST STOP).
#[pyclass(module = "gripper_rs.wsg", name = "Client", frozen, weakref)]
pub struct Client {
    inner: wsg::Client,
}

/// A WSG gripper (asyncio API): the same methods as `gripper_rs.wsg.Client`, as awaitables.
/// Cancelling one leaves the client usable and its replies correctly paired.
#[pyclass(module = "gripper_rs.aio.wsg", name = "Client", frozen, weakref)]
pub struct AioClient {
    inner: wsg::Client,
}

impl ToPy for AioClient {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Ok(crate::lifecycle::track(py, self)?.into_any())
    }
}

twins! {
    Client, AioClient, error;
    closing close_for_exit;
    blocking {
        /// Connects over TCP to "host:port".
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None, late_reply_grace_s=None, reconnect=None))]
        fn connect_tcp(
            py: Python<'_>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            late_reply_grace_s: Option<f64>,
            reconnect: Option<Bound<'_, PyAny>>,
        ) -> PyResult<Py<Client>> {
            let mut b = builder(query_timeout_s, motion_timeout_s, connect_timeout_s, late_reply_grace_s)?;
            if let Some(p) = events::policy(reconnect)? {
                b = b.reconnect(p);
            }
            let inner = runtime::block_on(py, b.connect_tcp(addr), error)?;
            crate::lifecycle::track(py, Client { inner })
        }

        /// Talks UDP to "host:port" (one frame per datagram).
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, late_reply_grace_s=None))]
        fn connect_udp(
            py: Python<'_>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            late_reply_grace_s: Option<f64>,
        ) -> PyResult<Py<Client>> {
            let b = builder(query_timeout_s, motion_timeout_s, None, late_reply_grace_s)?;
            let connect = async move { b.connect_udp(resolve(&addr).await?).await };
            let inner = runtime::block_on(py, connect, error)?;
            crate::lifecycle::track(py, Client { inner })
        }

        /// Opens the serial port `path` (RS-232) at `baud_rate`.
        #[staticmethod]
        #[pyo3(signature = (path, baud_rate=Checked(115200), *, query_timeout_s=None, motion_timeout_s=None, late_reply_grace_s=None))]
        fn open_serial(
            py: Python<'_>,
            path: String,
            baud_rate: Checked<u32>,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            late_reply_grace_s: Option<f64>,
        ) -> PyResult<Py<Client>> {
            let b = builder(query_timeout_s, motion_timeout_s, None, late_reply_grace_s)?;
            let inner = runtime::enter(|| b.open_serial(&path, baud_rate.0))?.map_err(error)?;
            crate::lifecycle::track(py, Client { inner })
        }


        /// A handle on the same connection whose calls use other timeouts.
        fn with_timeouts(&self, query_s: f64, motion_s: f64) -> PyResult<Client> {
            Ok(Client {
                inner: self.inner.with_timeouts(seconds("query_s", query_s)?, seconds("motion_s", motion_s)?),
            })
        }


        fn __repr__(&self) -> String {
            format!("<gripper_rs.wsg.Client over {:?}>", self.inner.transport())
        }
    }
    aio {
        /// Connects over TCP to "host:port".
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None, late_reply_grace_s=None, reconnect=None))]
        fn connect_tcp<'py>(
            py: Python<'py>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            late_reply_grace_s: Option<f64>,
            reconnect: Option<Bound<'py, PyAny>>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let mut b = builder(query_timeout_s, motion_timeout_s, connect_timeout_s, late_reply_grace_s)?;
            if let Some(p) = events::policy(reconnect)? {
                b = b.reconnect(p);
            }
            runtime::awaitable(py, async move { b.connect_tcp(addr).await.map(|inner| AioClient { inner }) }, error)
        }

        /// Talks UDP to "host:port" (one frame per datagram).
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, late_reply_grace_s=None))]
        fn connect_udp<'py>(
            py: Python<'py>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            late_reply_grace_s: Option<f64>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let b = builder(query_timeout_s, motion_timeout_s, None, late_reply_grace_s)?;
            runtime::awaitable(
                py,
                async move { b.connect_udp(resolve(&addr).await?).await.map(|inner| AioClient { inner }) },
                error,
            )
        }

        /// A handle on the same connection whose calls use other timeouts.
        fn with_timeouts(&self, query_s: f64, motion_s: f64) -> PyResult<AioClient> {
            Ok(AioClient {
                inner: self.inner.with_timeouts(seconds("query_s", query_s)?, seconds("motion_s", motion_s)?),
            })
        }



        fn __repr__(&self) -> String {
            format!("<gripper_rs.aio.wsg.Client over {:?}>", self.inner.transport())
        }
    }
    both {
        /// The connection's events from now on (`gripper_rs.reconnect.ConnectionEvent`): each
        /// loss, and with a reconnect policy each attempt and recovery. The stream ends when the
        /// client has closed or given up.
        fn connection_events(&self) -> PyResult<Stream> {
            events::stream(self.inner.connection_events())
        }
    }

    /// Command 0x20: reference the fingers (direction 0 = the device's default, 1 = positive,
    /// 2 = negative).
    #[pyo3(signature = (direction=Checked(0)))]
    fn home(&self, direction: Checked<u8>) [let direction = direction.0; let direction = homing_direction(direction)?;] => |c| c.home(direction);
    /// Command 0x21: move to `width_mm` at `speed_mm_per_s` (absolute). Blocked on the way, the
    /// fingers stop, or with `clamp_on_block` clamp with 50 % of the nominal force (flag D1).
    #[pyo3(signature = (width_mm, speed_mm_per_s, *, clamp_on_block=false))]
    fn pre_position(&self, width_mm: f32, speed_mm_per_s: f32, clamp_on_block: bool) => |c| pre_position(c, false, clamp_on_block, width_mm, speed_mm_per_s);
    /// Command 0x21: move by `distance_mm` (relative); `clamp_on_block` as for `pre_position`.
    #[pyo3(signature = (distance_mm, speed_mm_per_s, *, clamp_on_block=false))]
    fn pre_position_relative(&self, distance_mm: f32, speed_mm_per_s: f32, clamp_on_block: bool) => |c| pre_position(c, true, clamp_on_block, distance_mm, speed_mm_per_s);
    /// Any command by id (0x00..=0xFF) with `payload`: its final reply, whatever its status
    /// (`Reply`), within the query timeout or `timeout_s` (Rust: `Client::request`).
    #[pyo3(signature = (id, payload=Vec::new(), *, timeout_s=None))]
    fn request(&self, id: Checked<u8>, payload: Vec<u8>, timeout_s: Option<f64>) [let id = id.0; let timeout = timeout_s.map(|s| seconds("timeout_s", s)).transpose()?;] => |c| request(c, id, payload, timeout);
    /// Command 0x22: stop the current motion.
    fn stop(&self) => |c| c.stop();
    /// Command 0x23: FAST STOP (must be acknowledged before the next motion).
    fn fast_stop(&self) => |c| c.fast_stop();
    /// Command 0x24: acknowledge a FAST STOP.
    fn acknowledge_fast_stop(&self) => |c| c.acknowledge_fast_stop();
    /// Command 0x25: grasp a part of nominal `width_mm` at `speed_mm_per_s`.
    fn grasp(&self, width_mm: f32, speed_mm_per_s: f32) => |c| c.grasp(width_mm, speed_mm_per_s);
    /// Command 0x26: release the part, opening to `width_mm`.
    fn release(&self, width_mm: f32, speed_mm_per_s: f32) => |c| c.release(width_mm, speed_mm_per_s);
    /// Command 0x30: set the acceleration, mm/s².
    fn set_acceleration(&self, mm_per_s2: f32) => |c| c.set_acceleration(mm_per_s2);
    /// Command 0x31: the acceleration, mm/s².
    fn acceleration_mm_per_s2(&self) => |c| c.acceleration_mm_per_s2();
    /// Command 0x32: set the grasping force, N.
    fn set_grasping_force(&self, force_n: f32) => |c| c.set_grasping_force(force_n);
    /// Command 0x33: the grasping force, N.
    fn grasping_force_n(&self) => |c| c.grasping_force_n();
    /// Command 0x34: set the soft limits, mm.
    fn set_soft_limits(&self, minus_mm: f32, plus_mm: f32) => |c| c.set_soft_limits(SoftLimits { minus_mm, plus_mm });
    /// Command 0x35: the soft limits, or None when none are set.
    fn soft_limits(&self) => |c| c.soft_limits();
    /// Command 0x36: clear the soft limits.
    fn clear_soft_limits(&self) => |c| c.clear_soft_limits();
    /// Command 0x37: overdrive mode on or off.
    fn set_overdrive(&self, on: bool) => |c| c.set_overdrive(on);
    /// Command 0x38: tare the force sensor.
    fn tare_force_sensor(&self) => |c| c.tare_force_sensor();
    /// Command 0x40: the system state flags.
    fn system_state(&self) => |c| c.system_state();
    /// Command 0x41: the grip state.
    fn grip_state(&self) => |c| c.grip_state();
    /// Command 0x42: the grasping statistics (and reset them when `reset`).
    #[pyo3(signature = (reset=false))]
    fn grasping_statistics(&self, reset: bool) => |c| c.grasping_statistics(reset);
    /// Command 0x43: the opening width, mm.
    fn width_mm(&self) => |c| c.width_mm();
    /// Command 0x44: the finger speed, mm/s.
    fn speed_mm_per_s(&self) => |c| c.speed_mm_per_s();
    /// Command 0x45: the grasping force, N.
    fn force_n(&self) => |c| c.force_n();
    /// Command 0x46: the temperature inside the gripper, °C.
    fn temperature_c(&self) => |c| c.temperature_c();
    /// Command 0x50: device type, revision, firmware, serial number.
    fn system_info(&self) => |c| c.system_info();
    /// Command 0x51: set the device tag.
    fn set_device_tag(&self, tag: String) => |c| c.set_device_tag(&tag);
    /// Command 0x52: the device tag, or None when none is set.
    fn device_tag(&self) => |c| c.device_tag();
    /// Command 0x53: the system limits.
    fn system_limits(&self) => |c| c.system_limits();
    /// Commands 0x60 / 0x70: finger 1 or 2's type and data size.
    fn finger_info(&self, finger: Checked<u8>) [let finger = finger.0; let finger = self::finger(finger)?;] => |c| c.finger_info(finger);
    /// Commands 0x61 / 0x71: finger 1 or 2's flags.
    fn finger_flags(&self, finger: Checked<u8>) [let finger = finger.0; let finger = self::finger(finger)?;] => |c| c.finger_flags(finger);
    /// Commands 0x62 / 0x72: finger 1 or 2's power.
    fn set_finger_power(&self, finger: Checked<u8>, on: bool) [let finger = finger.0; let finger = self::finger(finger)?;] => |c| c.set_finger_power(finger, on);
    /// Commands 0x63 / 0x73: finger 1 or 2's data.
    fn finger_data(&self, finger: Checked<u8>) [let finger = finger.0; let finger = self::finger(finger)?;] => |c| c.finger_data(finger);
    /// Command 0x06: the device echoes `data`.
    fn loop_back(&self, data: Vec<u8>) => |c| c.loop_back(data);
    /// Stream of the system state flags (0x40 auto-update) every `period_s` (or on change).
    #[pyo3(signature = (period_s, on_change=false))]
    fn subscribe_system_state(&self, period_s: f64, on_change: bool) [let o = update_options(period_s, on_change)?;] => |c| subscribed(c.connection_events(), c.subscribe_system_state(o));
    /// Stream of the grip state (0x41 auto-update).
    #[pyo3(signature = (period_s, on_change=false))]
    fn subscribe_grip_state(&self, period_s: f64, on_change: bool) [let o = update_options(period_s, on_change)?;] => |c| subscribed(c.connection_events(), c.subscribe_grip_state(o));
    /// Stream of the opening width, mm (0x43 auto-update).
    #[pyo3(signature = (period_s, on_change=false))]
    fn subscribe_width_mm(&self, period_s: f64, on_change: bool) [let o = update_options(period_s, on_change)?;] => |c| subscribed(c.connection_events(), c.subscribe_width_mm(o));
    /// Stream of the finger speed, mm/s (0x44 auto-update).
    #[pyo3(signature = (period_s, on_change=false))]
    fn subscribe_speed_mm_per_s(&self, period_s: f64, on_change: bool) [let o = update_options(period_s, on_change)?;] => |c| subscribed(c.connection_events(), c.subscribe_speed_mm_per_s(o));
    /// Stream of the finger force, N (0x45 auto-update).
    #[pyo3(signature = (period_s, on_change=false))]
    fn subscribe_force_n(&self, period_s: f64, on_change: bool) [let o = update_options(period_s, on_change)?;] => |c| subscribed(c.connection_events(), c.subscribe_force_n(o));
    /// Closes the connection (TCP: announces the disconnect, 0x07, first).
    fn close(&self) => |c| close_for_exit(c.clone());
}

/// Command 0x21 with the stop-on-block flag (D1) as asked; the typed `pre_position` always
/// stops.
async fn pre_position(
    c: &wsg::Client,
    relative: bool,
    clamp_on_block: bool,
    width_mm: f32,
    speed_mm_per_s: f32,
) -> wsg::Result<()> {
    c.command(wsg::Command::PrePosition {
        relative,
        stop_on_block: !clamp_on_block,
        width_mm,
        speed_mm_per_s,
    })
    .await
    .map(drop)
}

/// A raw request with the client's query timeout or `timeout`.
async fn request(
    c: &wsg::Client,
    id: u8,
    payload: Vec<u8>,
    timeout: Option<std::time::Duration>,
) -> wsg::Result<wsg::Reply> {
    match timeout {
        Some(t) => c.request_with_timeout(id, payload, t).await,
        None => c.request(id, payload).await,
    }
}

impl ToPy for wsg::Reply {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let status = enum_value(py, PY, "Status", i64::from(self.status.code()))?;
        record(
            py,
            PY,
            "Reply",
            &[
                ("id", field(py, self.id)?),
                ("status", status.into_bound(py)),
                ("data", self.data.to_py(py)?.into_bound(py)),
            ],
        )
    }
}

/// `close()` (and leaving a `with` block), idempotent ([`errors::close_for_exit`]).
async fn close_for_exit(c: wsg::Client) -> wsg::Result<()> {
    errors::close_for_exit(c.close(), || c.is_closed()).await
}

// ---- the simulator -------------------------------------------------------------------------

/// A simulated WSG gripper serving TCP (or UDP) in this process, for tests and examples.
/// `with SimServer() as sim:` stops it at the end of the block.
#[pyclass(module = "gripper_rs.wsg.sim", name = "SimServer", frozen)]
pub struct SimServer {
    server: Slot<wsg::sim::SimServer>,
    addr: SocketAddr,
}

fn model(name: &str) -> PyResult<wsg::sim::Model> {
    use wsg::sim::Model;
    match name
        .to_ascii_uppercase()
        .replace([' ', '-', '_'], "")
        .as_str()
    {
        "WSG50" => Ok(Model::Wsg50),
        "WSG32" => Ok(Model::Wsg32),
        "WSG25" => Ok(Model::Wsg25),
        "WSG70" => Ok(Model::Wsg70),
        _ => Err(errors::invalid_argument(format!(
            "unknown WSG model {name:?} (WSG50, WSG32, WSG25 or WSG70)"
        ))),
    }
}

impl SimServer {
    fn with<R>(&self, f: impl FnOnce(&wsg::sim::SimServer) -> R) -> PyResult<R> {
        self.server.with(f)
    }
}

// `address`, `port`, `shutdown`, `with` and `repr` come with the macro (crate::sim).
sim_pymethods! { SimServer, "gripper_rs.wsg.sim.SimServer";
    /// Starts a simulator on `addr` (port 0: a free port; see `address`). The options are the
    /// Rust `SimConfig`'s: the model, a part of `part_width_mm` found by a grasp within
    /// `part_tolerance_mm`, the time scale (0: motion is instant; 1: real time), the force
    /// sensor, the temperature.
    #[new]
    /// `text=True` serves the text interface (GCL, `gripper_rs.wsg.text`) instead of the binary
    /// protocol; `fast_stop_on_close=False` keeps a close without 0x07 / `BYE()` from raising
    /// FAST STOP.
    #[pyo3(signature = (*, model="WSG50", part_width_mm=None, part_tolerance_mm=2.0, time_scale=0.0, force_sensor=false, temperature_c=None, addr="127.0.0.1:0", udp=false, text=false, fast_stop_on_close=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        model: &str,
        part_width_mm: Option<f32>,
        part_tolerance_mm: f32,
        time_scale: f64,
        force_sensor: bool,
        temperature_c: Option<f32>,
        addr: &str,
        udp: bool,
        text: bool,
        fast_stop_on_close: bool,
    ) -> PyResult<Self> {
        if !(time_scale.is_finite() && time_scale >= 0.0) {
            return Err(errors::invalid_argument(format!(
                "time_scale must be finite and non-negative, not {time_scale}"
            )));
        }
        let mut config = wsg::sim::SimConfig::new(self::model(model)?).with_time_scale(time_scale);
        if let Some(w) = part_width_mm {
            config = config.with_part(w, part_tolerance_mm);
        }
        config.force_sensor = force_sensor;
        config.text_interface = text;
        config.fast_stop_on_close = fast_stop_on_close;
        if let Some(t) = temperature_c {
            config.temperature_c = t;
        }
        let addr = addr.to_owned();
        let server = runtime::block_on(
            py,
            async move {
                if udp {
                    wsg::sim::SimServer::bind_udp(addr, config).await
                } else {
                    wsg::sim::SimServer::bind(addr, config).await
                }
            },
            |e| errors::transport(format!("cannot start the WSG simulator: {e}")),
        )?;
        let addr = server
            .local_addr()
            .ok_or_else(|| errors::transport("the simulator has no address".into()))?;
        Ok(SimServer {
            server: Slot::new(server),
            addr,
        })
    }

    /// The simulated gripper now: grip state, system state, width, connections, streams.
    fn snapshot(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let s = self.with(|s| s.snapshot())?;
        let grip_state = s.grip_state.to_py(py)?;
        let system_state = s.system_state.to_py(py)?;
        record(
            py,
            "gripper_rs.wsg.sim",
            "SimSnapshot",
            &[
                ("grip_state", grip_state.into_bound(py)),
                ("system_state", system_state.into_bound(py)),
                ("width_mm", field(py, f32_to_f64(s.width_mm))?),
                ("sessions", field(py, s.sessions)?),
                ("streams", field(py, s.streams)?),
            ],
        )
    }

    /// Command ids received, oldest first.
    fn received_ids(&self) -> PyResult<Vec<u16>> {
        // u16, not u8: PyO3 makes a Vec<u8> `bytes`, and this is a list of ids.
        self.with(|s| s.received_ids().into_iter().map(u16::from).collect())
    }

    /// The next reply to command `id` is not sent.
    fn drop_next_reply(&self, id: Checked<u8>) -> PyResult<()> {
        self.with(|s| s.drop_next_reply(id.0))
    }

    /// The next reply to command `id` has a wrong checksum.
    fn corrupt_next_reply(&self, id: Checked<u8>) -> PyResult<()> {
        self.with(|s| s.corrupt_next_reply(id.0))
    }

    /// The next reply to command `id` is sent `delay_s` late.
    fn delay_next_reply(&self, id: Checked<u8>, delay_s: f64) -> PyResult<()> {
        let d = seconds("delay_s", delay_s)?;
        self.with(|s| s.delay_next_reply(id.0, d))
    }

    /// The next reply to command `id` carries status `code` instead.
    fn force_status(&self, id: Checked<u8>, code: Checked<u16>) -> PyResult<()> {
        self.with(|s| s.force_status(id.0, wsg::Status::from_code(code.0)))
    }

    /// The held part slips out of the fingers.
    fn lose_part(&self) -> PyResult<()> {
        self.with(|s| s.lose_part())
    }

    /// Changes the time scale (0: instant motion, 1: real time).
    fn set_time_scale(&self, time_scale: f64) -> PyResult<()> {
        self.with(|s| s.set_time_scale(time_scale))
    }

    /// Cuts every connection (the cable is pulled).
    fn unplug(&self) -> PyResult<()> {
        self.with(|s| s.unplug())
    }

}

/// `gripper_rs._native.wsg`.
pub fn module(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    let m = PyModule::new(py, "wsg")?;
    m.add_class::<Client>()?;
    // Both are named `Client` (in `gripper_rs.wsg` and `gripper_rs.aio.wsg`): one attribute each
    // here.
    m.add("AioClient", py.get_type::<AioClient>())?;
    m.add_class::<SimServer>()?;
    m.add("DEFAULT_PORT", wsg::DEFAULT_PORT)?;
    m.add_function(wrap_pyfunction!(status_codes, &m)?)?;
    m.add_function(wrap_pyfunction!(_width_request, &m)?)?;
    Ok(m)
}

/// Every status code the manual lists, as (code, symbol, description): the Python `Status`
/// enum is tested against this so the two cannot drift apart.
#[pyfunction]
fn status_codes() -> Vec<(u16, &'static str, &'static str)> {
    (0..=u16::MAX)
        .map(wsg::Status::from_code)
        .take_while(|s| !matches!(s, wsg::Status::Unknown(_)))
        .map(|s| (s.code(), s.symbol(), s.description()))
        .collect()
}

/// The bytes of a width query (0x43, no auto-update), encoded by the crate's own frame code: the
/// benchmark's raw-socket floor sends exactly what the client sends.
#[pyfunction]
fn _width_request() -> PyResult<Vec<u8>> {
    let mut b = bytes::BytesMut::new();
    wsg::frame::encode(
        &wsg::Command::Width(wsg::UpdateMode::ONCE).to_frame(),
        &mut b,
    )
    .map_err(|e| errors::invalid_argument(e.to_string()))?;
    Ok(b.to_vec())
}
