//! `gripper_rs.griplink`: the GRIPLINK client and its ports (blocking and asyncio) and
//! `gripper_rs.griplink.sim.SimServer`.

use std::collections::HashMap;
use std::net::SocketAddr;

use gripper::griplink::{
    self, Blocking, DeviceState, Error, FlexGrip, FlexRelease, GripConfig, GripConfigF,
    GripOutcome, PortNumber, ReleaseOutcome, WaitBy, Watch,
};
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::args::Checked;
use crate::convert::{enum_member, enum_value, field, record, ToPy};
use crate::errors;
use crate::events;
use crate::runtime::{self, seconds};
use crate::sim::Slot;
use crate::stream::Stream;

const PY: &str = "gripper_rs.griplink";

classified!(Error, refusal);

/// A GRIPLINK controller's refusal (`DeviceError`).
fn refusal(e: Error) -> Option<errors::Device> {
    let Error::Device {
        command, status, ..
    } = e
    else {
        return None;
    };
    let d = errors::Device::new(i64::from(status.code()), command).status(PY, "Status");
    Some(match (status.identifier(), status.description()) {
        (Some(name), Some(description)) => d.known(name, description),
        _ => d,
    })
}

// ---- results -------------------------------------------------------------------------------

impl ToPy for DeviceState {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        enum_value(py, PY, "DeviceState", self.code())
    }
}

impl ToPy for GripOutcome {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let member = match self {
            GripOutcome::Holding => "HOLDING",
            GripOutcome::NoPart => "NO_PART",
            GripOutcome::Fault => "FAULT",
        };
        enum_member(py, PY, "GripOutcome", member)
    }
}

impl ToPy for ReleaseOutcome {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let member = match self {
            ReleaseOutcome::Released => "RELEASED",
            ReleaseOutcome::Fault => "FAULT",
        };
        enum_member(py, PY, "ReleaseOutcome", member)
    }
}

impl ToPy for GripConfig {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let params = self.params.to_vec();
        record(
            py,
            PY,
            "GripConfig",
            &[
                ("tag", field(py, self.tag)?),
                ("params", field(py, params)?),
            ],
        )
    }
}

impl ToPy for GripConfigF {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let params = self.params.to_vec();
        record(
            py,
            PY,
            "GripConfigF",
            &[
                ("tag", field(py, self.tag)?),
                ("params", field(py, params)?),
            ],
        )
    }
}

impl ToPy for griplink::reply::Answer {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        match self {
            griplink::reply::Answer::Ack => Ok(py.None()),
            griplink::reply::Answer::Data(d) => {
                let indices = pyo3::types::PyTuple::new(py, d.indices)?.into_any();
                record(
                    py,
                    PY,
                    "Answer",
                    &[
                        ("key", field(py, d.key)?),
                        ("indices", indices),
                        ("value", d.value.to_py(py)?.into_bound(py)),
                    ],
                )
            }
        }
    }
}

impl ToPy for griplink::value::Value {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        use griplink::value::Value;
        match self {
            Value::Int(v) => v.to_py(py),
            Value::Float(v) => v.to_py(py),
            Value::Str(v) => v.to_py(py),
            Value::List(v) => v.to_py(py),
        }
    }
}

/// A polling stream's item: a reading, or the error of that poll (raised by `next()`; the
/// stream goes on).
impl<T: ToPy> ToPy for griplink::Result<T> {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.map_err(error)?.to_py(py)
    }
}

impl<T: ToPy> ToPy for Watch<T> {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Stream::new(self).into_py_any(py)
    }
}

// ---- arguments -----------------------------------------------------------------------------

fn blocking(until_done: bool) -> Blocking {
    if until_done {
        Blocking::UntilDone
    } else {
        Blocking::Immediate
    }
}

/// `None`: wait for the state transition (WSTR); a number: poll DEVSTATE at that interval.
fn wait_by(poll_interval_s: Option<f64>) -> PyResult<WaitBy> {
    match poll_interval_s {
        None => Ok(WaitBy::Transition),
        Some(s) => Ok(WaitBy::Polling(seconds("poll_interval_s", s)?)),
    }
}

fn params<T: Copy + Default>(what: &str, v: Vec<T>) -> PyResult<[T; 8]> {
    let n = v.len();
    <[T; 8]>::try_from(v).map_err(|_| {
        errors::invalid_argument(format!("{what} needs exactly 8 parameters, not {n}"))
    })
}

fn port_number(n: u8) -> PyResult<PortNumber> {
    if n <= griplink::MAX_PORT {
        Ok(n)
    } else {
        Err(errors::invalid_argument(format!(
            "port must be 0..={}, not {n}",
            griplink::MAX_PORT
        )))
    }
}

fn config(
    query_timeout_s: Option<f64>,
    motion_timeout_s: Option<f64>,
    connect_timeout_s: Option<f64>,
) -> PyResult<griplink::ClientConfig> {
    let mut c = griplink::ClientConfig::default();
    if let Some(s) = query_timeout_s {
        c.query_timeout = seconds("query_timeout_s", s)?;
    }
    if let Some(s) = motion_timeout_s {
        c.motion_timeout = seconds("motion_timeout_s", s)?;
    }
    if let Some(s) = connect_timeout_s {
        c.connect_timeout = seconds("connect_timeout_s", s)?;
    }
    Ok(c)
}

// ---- the client ----------------------------------------------------------------------------

/// A GRIPLINK controller (blocking API). `client.port(n)` is the device on port n. `with`
/// closes the connection (BYE).
#[pyclass(module = "gripper_rs.griplink", name = "Client", frozen, weakref)]
pub struct Client {
    inner: griplink::Client,
}

/// A GRIPLINK controller (asyncio API): the methods of `gripper_rs.griplink.Client` as awaitables.
#[pyclass(module = "gripper_rs.aio.griplink", name = "Client", frozen, weakref)]
pub struct AioClient {
    inner: griplink::Client,
}

impl ToPy for AioClient {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Ok(crate::lifecycle::track(py, self)?.into_any())
    }
}

/// `close()` (and leaving a `with` block), idempotent ([`errors::close_for_exit`]).
async fn close_for_exit(c: griplink::Client) -> griplink::Result<()> {
    errors::close_for_exit(c.close(), || c.is_closed()).await
}

twins! {
    Client, AioClient, error;
    closing close_for_exit;
    blocking {
        /// Connects to "host:port".
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None, reconnect=None))]
        fn connect(
            py: Python<'_>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            reconnect: Option<Bound<'_, PyAny>>,
        ) -> PyResult<Py<Client>> {
            let mut c = config(query_timeout_s, motion_timeout_s, connect_timeout_s)?;
            c.reconnect = events::policy(reconnect)?;
            let inner = runtime::block_on(py, griplink::Client::connect_with(addr, c), error)?;
            crate::lifecycle::track(py, Client { inner })
        }

        /// The device on port `n` (0..=31).
        fn port(&self, n: Checked<u8>) -> PyResult<Port> {
            Ok(Port { inner: self.inner.port(port_number(n.0)?) })
        }


        /// A handle on the same connection whose calls use another timeout.
        fn with_timeout(&self, timeout_s: f64) -> PyResult<Client> {
            Ok(Client { inner: self.inner.with_timeout(seconds("timeout_s", timeout_s)?) })
        }

    }
    aio {
        /// Connects to "host:port".
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None, reconnect=None))]
        fn connect<'py>(
            py: Python<'py>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
            reconnect: Option<Bound<'py, PyAny>>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let mut c = config(query_timeout_s, motion_timeout_s, connect_timeout_s)?;
            c.reconnect = events::policy(reconnect)?;
            runtime::awaitable(
                py,
                async move { griplink::Client::connect_with(addr, c).await.map(|inner| AioClient { inner }) },
                error,
            )
        }

        /// The device on port `n` (0..=31).
        fn port(&self, n: Checked<u8>) -> PyResult<AioPort> {
            Ok(AioPort { inner: self.inner.port(port_number(n.0)?) })
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
    }

    /// A raw command line (printable ASCII, without LF) the package has no method for: None for
    /// `ACK`, an `Answer` for `KEY[…]=value`; `ERR` raises `DeviceError` (Rust: `Client::command`).
    fn command(&self, line: String) => |c| c.command(&line);
    /// `ID?`: the controller's identifier.
    fn id(&self) => |c| c.id();
    /// `PROTOCOL?`: the protocol identifier and version.
    fn protocol(&self) => |c| c.protocol();
    /// `PROTOCOL?` checked: `identifier` at version `min_version` or later.
    fn protocol_assert(&self, identifier: String, min_version: Checked<u32>) [let min_version = min_version.0;] => |c| c.protocol_assert(&identifier, min_version);
    /// `SN?`: the controller's serial number.
    fn serial_number(&self) => |c| c.serial_number();
    /// `LABEL?`.
    fn label(&self) => |c| c.label();
    /// `LABEL=`: returns the label the controller stored.
    fn set_label(&self, label: String) => |c| c.set_label(&label);
    /// `VER?`: the firmware version.
    fn version(&self) => |c| c.version();
    /// `VERBOSE=`: error replies with text.
    fn set_verbose(&self, on: bool) => |c| c.set_verbose(on);
    /// `BYE`, then closes the connection.
    fn close(&self) => |c| close_for_exit(c.clone());
}

/// The polling task is spawned on the module's runtime.
fn watch_state(port: &griplink::Port, interval_s: f64) -> PyResult<Stream> {
    let interval = seconds("interval_s", interval_s)?;
    runtime::enter(|| Stream::new(port.watch_state(interval)))
}

fn watch_value(port: &griplink::Port, index: Checked<u32>, interval_s: f64) -> PyResult<Stream> {
    let interval = seconds("interval_s", interval_s)?;
    runtime::enter(|| Stream::new(port.watch_value(index.0, interval)))
}

/// Any `Mapping` (not only a `dict`) as a Rust map; a port number out of range is an
/// `InvalidArgumentError`.
fn mapping<T>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<T>
where
    T: for<'py> pyo3::conversion::FromPyObjectOwned<'py>,
{
    let dict = obj
        .py()
        .import("builtins")?
        .getattr("dict")?
        .call1((obj,))?;
    crate::args::extract(&dict, name)
}

// ---- a port --------------------------------------------------------------------------------

/// The device on one port of a GRIPLINK controller (blocking API).
#[pyclass(module = "gripper_rs.griplink", name = "Port", frozen)]
pub struct Port {
    inner: griplink::Port,
}

/// The device on one port of a GRIPLINK controller (asyncio API).
#[pyclass(module = "gripper_rs.aio.griplink", name = "Port", frozen)]
pub struct AioPort {
    inner: griplink::Port,
}

twins! {
    Port, AioPort, error;
    blocking {
        /// The port number.
        #[getter]
        fn number(&self) -> u8 {
            self.inner.number()
        }

        /// The same port with another timeout for its calls.
        fn with_timeout(&self, timeout_s: f64) -> PyResult<Port> {
            Ok(Port { inner: self.inner.with_timeout(seconds("timeout_s", timeout_s)?) })
        }

        /// Polls DEVSTATE every `interval_s`: a stream of device states.
        fn watch_state(&self, interval_s: f64) -> PyResult<Stream> {
            watch_state(&self.inner, interval_s)
        }

        /// Polls VALUEF[index] every `interval_s`: a stream of values.
        fn watch_value(&self, index: Checked<u32>, interval_s: f64) -> PyResult<Stream> {
            watch_value(&self.inner, index, interval_s)
        }
    }
    aio {
        /// The port number.
        #[getter]
        fn number(&self) -> u8 {
            self.inner.number()
        }

        /// The same port with another timeout for its calls.
        fn with_timeout(&self, timeout_s: f64) -> PyResult<AioPort> {
            Ok(AioPort { inner: self.inner.with_timeout(seconds("timeout_s", timeout_s)?) })
        }

        /// Polls DEVSTATE every `interval_s`: an async stream of device states.
        fn watch_state(&self, interval_s: f64) -> PyResult<Stream> {
            watch_state(&self.inner, interval_s)
        }

        /// Polls VALUEF[index] every `interval_s`: an async stream of values.
        fn watch_value(&self, index: Checked<u32>, interval_s: f64) -> PyResult<Stream> {
            watch_value(&self.inner, index, interval_s)
        }
    }

    /// `VENDORID[p]?` (None: no device).
    fn vendor_id(&self) => |c| c.vendor_id();
    /// `PRODUCTID[p]?`.
    fn product_id(&self) => |c| c.product_id();
    /// Checks the device's vendor and product id.
    fn assert_device(&self, vendor_id: Checked<u32>, product_id: Checked<u32>) [let vendor_id = vendor_id.0; let product_id = product_id.0;] => |c| c.assert_device(vendor_id, product_id);
    /// `DEVNAME[p]?`.
    fn name(&self) => |c| c.name();
    /// `DEVVENDOR[p]?`.
    fn vendor(&self) => |c| c.vendor();
    /// `DEVSN[p]?`.
    fn serial_number(&self) => |c| c.serial_number();
    /// `DEVTAG[p]?`.
    fn tag(&self) => |c| c.tag();
    /// `DEVTAG[p]=`: returns the stored tag.
    fn set_tag(&self, tag: String) => |c| c.set_tag(&tag);
    /// `DEVVER[p]?`.
    fn version(&self) => |c| c.version();
    /// `ENABLE(p)`.
    fn enable(&self) => |c| c.enable();
    /// `DISABLE(p)`.
    fn disable(&self) => |c| c.disable();
    /// `HOME(p)`: the reference drive; waits until done.
    fn home(&self) => |c| c.home();
    /// `GRIP(p, index)` with recipe `index`; `until_done` holds the reply until the motion ends.
    #[pyo3(signature = (index, until_done=false))]
    fn grip(&self, index: Checked<u32>, until_done: bool) [let index = index.0;] => |c| c.grip(index, blocking(until_done));
    /// `RELEASE(p, index)`.
    #[pyo3(signature = (index, until_done=false))]
    fn release(&self, index: Checked<u32>, until_done: bool) [let index = index.0;] => |c| c.release(index, blocking(until_done));
    /// `FLEXGRIPF(p, ...)` in mm, N, mm/s, mm/s².
    #[pyo3(signature = (position_mm, force_n, speed_mm_per_s, acceleration_mm_per_s2, until_done=false))]
    fn flex_grip(&self, position_mm: f64, force_n: f64, speed_mm_per_s: f64, acceleration_mm_per_s2: f64, until_done: bool)
        => |c| c.flex_grip(FlexGrip { position_mm, force_n, speed_mm_per_s, acceleration_mm_per_s2 }, blocking(until_done));
    /// `FLEXRELEASEF(p, ...)` in mm, mm/s, mm/s².
    #[pyo3(signature = (position_mm, speed_mm_per_s, acceleration_mm_per_s2, until_done=false))]
    fn flex_release(&self, position_mm: f64, speed_mm_per_s: f64, acceleration_mm_per_s2: f64, until_done: bool)
        => |c| c.flex_release(FlexRelease { position_mm, speed_mm_per_s, acceleration_mm_per_s2 }, blocking(until_done));
    /// `LED(p, index)`.
    fn led(&self, index: Checked<u32>) [let index = index.0;] => |c| c.led(index);
    /// `CLAMP(p, enable)`.
    fn clamp(&self, enable: bool) => |c| c.clamp(enable);
    /// `WSTR[p]?`: the state after the next transition.
    fn wait_for_transition(&self) => |c| c.wait_for_transition();
    /// `SETVAL(p, index, value)`.
    fn set_value(&self, index: Checked<u32>, value: Checked<i32>) [let index = index.0; let value = value.0;] => |c| c.set_value(index, value);
    /// `SETVALF(p, index, value)`.
    fn set_value_f(&self, index: Checked<u32>, value: f64) [let index = index.0;] => |c| c.set_value_f(index, value);
    /// `DEVSTATE[p]?`.
    fn state(&self) => |c| c.state();
    /// `VALUE[p][index]?`.
    fn value(&self, index: Checked<u32>) [let index = index.0;] => |c| c.value(index);
    /// `VALUEF[p][index]?`.
    fn value_f(&self, index: Checked<u32>) [let index = index.0;] => |c| c.value_f(index);
    /// The position, µm.
    fn position_um(&self) => |c| c.position_um();
    /// The position, mm.
    fn position_mm(&self) => |c| c.position_mm();
    /// `GRIPCFG[p][index]?`.
    fn grip_config(&self, index: Checked<u32>) [let index = index.0;] => |c| c.grip_config(index);
    /// `GRIPCFG[p][index]=`: returns the stored recipe.
    fn set_grip_config(&self, index: Checked<u32>, tag: String, params: Checked<Vec<i32>>)
        [let index = index.0; let config = GripConfig { tag, params: self::params("GRIPCFG", params.0)? };]
        => |c| c.set_grip_config(index, &config);
    /// `GRIPCFGF[p][index]?`.
    fn grip_config_f(&self, index: Checked<u32>) [let index = index.0;] => |c| c.grip_config_f(index);
    /// `GRIPCFGF[p][index]=`: returns the stored recipe.
    fn set_grip_config_f(&self, index: Checked<u32>, tag: String, params: Checked<Vec<f64>>)
        [let index = index.0; let config = GripConfigF { tag, params: self::params("GRIPCFGF", params.0)? };]
        => |c| c.set_grip_config_f(index, &config);
    /// GRIP with recipe `index`, then wait for its end: by the state transition (WSTR), or by
    /// polling DEVSTATE every `poll_interval_s`.
    #[pyo3(signature = (index, poll_interval_s=None))]
    fn grip_and_wait(&self, index: Checked<u32>, poll_interval_s: Option<f64>) [let index = index.0; let by = wait_by(poll_interval_s)?;] => |c| c.grip_and_wait(index, by);
    /// RELEASE with recipe `index`, then wait for its end.
    #[pyo3(signature = (index, poll_interval_s=None))]
    fn release_and_wait(&self, index: Checked<u32>, poll_interval_s: Option<f64>) [let index = index.0; let by = wait_by(poll_interval_s)?;] => |c| c.release_and_wait(index, by);
}

// ---- the simulator -------------------------------------------------------------------------

/// A simulated GRIPLINK controller serving TCP in this process.
#[pyclass(module = "gripper_rs.griplink.sim", name = "SimServer", frozen)]
pub struct SimServer {
    server: Slot<griplink::sim::SimServer>,
    addr: SocketAddr,
}

fn sim_device(name: &str) -> PyResult<griplink::sim::SimDevice> {
    use griplink::sim::SimDevice;
    match name
        .to_ascii_uppercase()
        .replace([' ', '-', '_'], "")
        .as_str()
    {
        "IEG55020" => Ok(SimDevice::ieg_55_020()),
        "CRG200085" => Ok(SimDevice::crg_200_085()),
        "WPG100090" => Ok(SimDevice::wpg_100_090()),
        "WPG300120" => Ok(SimDevice::wpg_300_120()),
        _ => Err(errors::invalid_argument(format!(
            "unknown device {name:?} (IEG 55-020, CRG 200-085, WPG 100-090 or WPG 300-120)"
        ))),
    }
}

impl SimServer {
    fn with<R>(&self, f: impl FnOnce(&griplink::sim::SimServer) -> R) -> PyResult<R> {
        self.server.with(f)
    }

    fn inject(&self, fault: griplink::sim::Fault) -> PyResult<()> {
        self.with(|s| s.inject(fault))
    }
}

// `address`, `port`, `shutdown`, `with` and `repr` come with the macro (crate::sim).
sim_pymethods! { SimServer, "gripper_rs.griplink.sim.SimServer";
    /// Starts a simulated controller on `addr`. `preset` is the Rust `SimConfig` constructor
    /// ("ET4": a GRIPLINK-ET4 with an IEG 55-020 on port 0 and a CRG 200-085 on port 2; "WPG":
    /// a WPG 100-090); `devices` replaces devices by port (a name, or None for an empty port),
    /// `parts` puts a part of that width (mm) between a port's fingers; `time_scale` 1 is real
    /// time, 0 makes motion instant.
    #[new]
    #[pyo3(signature = (*, preset="ET4", devices=None, parts=None, time_scale=1.0, addr="127.0.0.1:0"))]
    fn new(
        py: Python<'_>,
        preset: &str,
        devices: Option<Bound<'_, PyAny>>,
        parts: Option<Bound<'_, PyAny>>,
        time_scale: f64,
        addr: &str,
    ) -> PyResult<Self> {
        use griplink::sim::SimConfig;
        let devices: Option<HashMap<u8, Option<String>>> =
            devices.map(|m| mapping(&m, "devices")).transpose()?;
        let parts: Option<HashMap<u8, f64>> = parts.map(|m| mapping(&m, "parts")).transpose()?;
        if !(time_scale.is_finite() && time_scale >= 0.0) {
            return Err(errors::invalid_argument(format!(
                "time_scale must be finite and non-negative, not {time_scale}"
            )));
        }
        let mut config = match preset.to_ascii_uppercase().as_str() {
            "ET4" => SimConfig::et4(),
            "WPG" => SimConfig::wpg(),
            other => {
                return Err(errors::invalid_argument(format!(
                    "unknown preset {other:?} (ET4 or WPG)"
                )))
            }
        }
        .time_scale(time_scale);
        for (port, device) in devices.unwrap_or_default() {
            let device = device.as_deref().map(sim_device).transpose()?;
            config = config.device(port_number(port)?, device);
        }
        for (port, width_mm) in parts.unwrap_or_default() {
            let slot = config
                .ports
                .get_mut(usize::from(port))
                .and_then(Option::as_mut);
            match slot {
                Some(device) => device.part_width_mm = Some(width_mm),
                None => {
                    return Err(errors::invalid_argument(format!(
                        "a part on port {port}, which has no device"
                    )))
                }
            }
        }
        let addr = addr.to_owned();
        let server = runtime::block_on(py, griplink::sim::SimServer::bind(addr, config), |e| {
            errors::transport(format!("cannot start the GRIPLINK simulator: {e}"))
        })?;
        let addr = server.local_addr();
        Ok(SimServer {
            server: Slot::new(server),
            addr,
        })
    }

    /// The state of the device on `port` (None: no device).
    fn device_state(&self, py: Python<'_>, port: Checked<u8>) -> PyResult<Option<Py<PyAny>>> {
        let port = port_number(port.0)?;
        self.with(|s| s.device_state(port))?
            .map(|state| state.to_py(py))
            .transpose()
    }

    /// Puts a part of `width_mm` between the fingers on `port` (None: takes it away).
    #[pyo3(signature = (port, width_mm))]
    fn set_part(&self, port: Checked<u8>, width_mm: Option<f64>) -> PyResult<()> {
        let port = port_number(port.0)?;
        self.with(|s| s.set_part(port, width_mm))
    }

    /// The device on `port` goes into DS_FAULT now.
    fn inject_device_fault(&self, port: Checked<u8>) -> PyResult<()> {
        let port = port_number(port.0)?;
        self.with(|s| s.inject_device_fault(port))
    }

    /// The next motion on `port` ends in DS_FAULT.
    fn fault_next_motion(&self, port: Checked<u8>) -> PyResult<()> {
        let port = port_number(port.0)?;
        self.with(|s| s.fault_next_motion(port))
    }

    /// The next command is executed but not answered.
    fn drop_next_reply(&self) -> PyResult<()> {
        self.inject(griplink::sim::Fault::DropReply)
    }

    /// The next command's reply comes `delay_s` late.
    fn delay_next_reply(&self, delay_s: f64) -> PyResult<()> {
        let d = seconds("delay_s", delay_s)?;
        self.inject(griplink::sim::Fault::DelayReply(d))
    }

    /// The next command is refused with `ERR <code>`.
    fn fail_next(&self, code: Checked<u32>) -> PyResult<()> {
        self.inject(griplink::sim::Fault::Error(griplink::Status::from_code(
            code.0,
        )))
    }

    /// The next command is executed and answered with `data` (include the LF).
    fn raw_next_reply(&self, data: Vec<u8>) -> PyResult<()> {
        self.inject(griplink::sim::Fault::RawReply(data))
    }

    /// The connection is closed instead of executing the next command.
    fn close_next(&self) -> PyResult<()> {
        self.inject(griplink::sim::Fault::Close)
    }

}

/// Every status code the manual lists, as (code, identifier, description).
#[pyfunction]
fn status_codes() -> Vec<(u32, &'static str, &'static str)> {
    (0..=u32::from(u16::MAX))
        .map(griplink::Status::from_code)
        .filter_map(|s| Some((s.code(), s.identifier()?, s.description()?)))
        .collect()
}

/// `gripper_rs._native.griplink`.
pub fn module(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    let m = PyModule::new(py, "griplink")?;
    m.add_class::<Client>()?;
    m.add_class::<Port>()?;
    // The asyncio classes have the same Python names: one attribute each here.
    m.add("AioClient", py.get_type::<AioClient>())?;
    m.add("AioPort", py.get_type::<AioPort>())?;
    m.add_class::<SimServer>()?;
    m.add("DEFAULT_PORT", griplink::DEFAULT_PORT)?;
    m.add_function(wrap_pyfunction!(status_codes, &m)?)?;
    Ok(m)
}
