//! `gripper_rs.wsg.text`: the WSG text-interface (GCL) client, blocking and asyncio (its `aio`
//! view), over `gripper::wsg::text`. The simulator's text mode is `gripper_rs.wsg.sim.SimServer(
//! text=True)`.

use gripper::wsg::text::{self, Error, Push, Pushes, Quantity};
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use crate::args::Checked;
use crate::convert::{field, record, ToPy};
use crate::errors;
use crate::runtime::{self, seconds};
use crate::stream::{Ended, Ending, Stream};
use crate::wsg::homing_direction;

classified!(Error, refusal);

/// A GCL refusal (`DeviceError`): a device error without a numeral code has code -1 (the
/// whole `ERR` line is in the message).
fn refusal(e: Error) -> Option<errors::Device> {
    match e {
        Error::Device {
            command,
            status: Some(status),
            ..
        } => Some(crate::wsg::device(command, status)),
        Error::Device { command, .. } => Some(errors::Device::new(-1, command)),
        _ => None,
    }
}

impl ToPy for Push {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        record(
            py,
            "gripper_rs.wsg.text",
            "Push",
            &[
                ("quantity", field(py, self.quantity.name())?),
                ("value", field(py, self.value)?),
            ],
        )
    }
}

impl ToPy for Pushes {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Stream::new(self).into_py_any(py)
    }
}

fn quantity(name: &str) -> PyResult<Quantity> {
    Quantity::from_name(name).ok_or_else(|| {
        errors::invalid_argument(format!(
            "unknown AUTOSEND quantity {name:?} (POS, SPEED, FORCE, GRIPSTATE or TEMP)"
        ))
    })
}

fn config(
    query_timeout_s: Option<f64>,
    motion_timeout_s: Option<f64>,
    connect_timeout_s: Option<f64>,
) -> PyResult<text::ClientConfig> {
    let mut c = text::ClientConfig::default();
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

/// A WSG in text mode (blocking API): every method waits for the gripper's reply with the GIL
/// released; any number of threads may share one client. `with` closes it with `BYE()`, so
/// the gripper does not FAST STOP.
#[pyclass(module = "gripper_rs.wsg.text", name = "Client", frozen, weakref)]
pub struct Client {
    inner: text::Client,
}

/// A WSG in text mode (asyncio API): the same methods as `gripper_rs.wsg.text.Client`, as
/// awaitables.
#[pyclass(module = "gripper_rs.wsg.text", name = "AioClient", frozen, weakref)]
pub struct AioClient {
    inner: text::Client,
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
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None))]
        fn connect(
            py: Python<'_>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
        ) -> PyResult<Py<Client>> {
            let c = config(query_timeout_s, motion_timeout_s, connect_timeout_s)?;
            let inner = runtime::block_on(py, text::Client::connect_with(addr, c), error)?;
            crate::lifecycle::track(py, Client { inner })
        }

        fn __repr__(&self) -> String {
            "<gripper_rs.wsg.text.Client>".into()
        }
    }
    aio {
        /// Connects over TCP to "host:port".
        #[staticmethod]
        #[pyo3(signature = (addr, *, query_timeout_s=None, motion_timeout_s=None, connect_timeout_s=None))]
        fn connect<'py>(
            py: Python<'py>,
            addr: String,
            query_timeout_s: Option<f64>,
            motion_timeout_s: Option<f64>,
            connect_timeout_s: Option<f64>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let c = config(query_timeout_s, motion_timeout_s, connect_timeout_s)?;
            runtime::awaitable(
                py,
                async move { text::Client::connect_with(addr, c).await.map(|inner| AioClient { inner }) },
                error,
            )
        }

        fn __repr__(&self) -> String {
            "<gripper_rs.wsg.text.AioClient>".into()
        }
    }

    /// `HOME()` (direction 0, the default), `HOME(1)` (1, positive) or `HOME(0)` (2, negative):
    /// the same numbers as `gripper_rs.wsg.HomingDirection`, written in GCL's form.
    #[pyo3(signature = (direction=Checked(0)))]
    fn home(&self, direction: Checked<u8>) [let direction = direction.0; let direction = homing_direction(direction)?;] => |c| c.home(direction);
    /// `MOVE(p[,v])`: move to `width_mm`, with an optional speed limit.
    #[pyo3(signature = (width_mm, speed_mm_per_s=None))]
    fn move_to(&self, width_mm: f64, speed_mm_per_s: Option<f64>) => |c| c.move_to(width_mm, speed_mm_per_s);
    /// `GRIP()` or `GRIP(f)`: grip inward until a part is found.
    #[pyo3(signature = (force_n=None))]
    fn grip(&self, force_n: Option<f64>) => |c| c.grip(force_n);
    /// `GRIP(f,w[,v])`: grip a part expected at `part_width_mm`.
    #[pyo3(signature = (force_n, part_width_mm, speed_mm_per_s=None))]
    fn grip_part(&self, force_n: f64, part_width_mm: f64, speed_mm_per_s: Option<f64>) => |c| c.grip_part(force_n, part_width_mm, speed_mm_per_s);
    /// `RELEASE([d[,v]])`: open BY `pull_back_mm` from where the fingers are (relative, unlike
    /// the binary protocol's release).
    #[pyo3(signature = (pull_back_mm=None, speed_mm_per_s=None))]
    fn release(&self, pull_back_mm: Option<f64>, speed_mm_per_s: Option<f64>) => |c| c.release(pull_back_mm, speed_mm_per_s);
    /// `STOP()`: stop the running motion (its call raises with E_CMD_ABORTED).
    fn stop(&self) => |c| c.stop();
    /// `FASTSTOP()`: stop and refuse motion until `ack_fast_stop()`.
    fn fast_stop(&self) => |c| c.fast_stop();
    /// `FSACK()`: acknowledge FAST STOP (answered also with none pending).
    fn ack_fast_stop(&self) => |c| c.ack_fast_stop();
    /// `VERBOSE=0|1`: returns the mode the gripper reports.
    fn set_verbose(&self, on: bool) => |c| c.set_verbose(on);
    /// `PWT?`: the part width tolerance of this connection, mm.
    fn part_width_tolerance_mm(&self) => |c| c.part_width_tolerance_mm();
    /// `PWT=x`: returns the value the gripper reports.
    fn set_part_width_tolerance_mm(&self, mm: f64) => |c| c.set_part_width_tolerance_mm(mm);
    /// `CLT?`: the clamping travel of this connection, mm.
    fn clamping_travel_mm(&self) => |c| c.clamping_travel_mm();
    /// `CLT=x`: returns the value the gripper reports.
    fn set_clamping_travel_mm(&self, mm: f64) => |c| c.set_clamping_travel_mm(mm);
    /// `POS?`: the opening width, mm.
    fn position_mm(&self) => |c| c.position_mm();
    /// `SPEED?`: the finger speed, mm/s.
    fn speed_mm_per_s(&self) => |c| c.speed_mm_per_s();
    /// `FORCE?`: the grip force, N.
    fn force_n(&self) => |c| c.force_n();
    /// `TEMP?`: the temperature, °C.
    fn temperature_c(&self) => |c| c.temperature_c();
    /// `GRIPSTATE?`: the grip state (`gripper_rs.wsg.GripState`).
    fn grip_state(&self) => |c| c.grip_state();
    /// `AUTOSEND("NAME",ms[,true])`: a stream of `Push(quantity, value)` for `quantity` ("POS",
    /// "SPEED", "FORCE", "GRIPSTATE", "TEMP").
    #[pyo3(signature = (quantity, interval_ms, only_on_change=false))]
    fn autosend(&self, quantity: &str, interval_ms: Checked<u16>, only_on_change: bool) [let interval_ms = interval_ms.0; let q = self::quantity(quantity)?;] => |c| autosend(c, q, interval_ms, only_on_change);
    /// `AUTOSEND("NAME",0)`: stop pushing `quantity`.
    fn stop_autosend(&self, quantity: &str) [let q = self::quantity(quantity)?;] => |c| c.stop_autosend(q);
    /// `BYE()`: announce the disconnect and close.
    fn close(&self) => |c| close_for_exit(c.clone());
}

/// `AUTOSEND`, its stream telling a lost connection (`ConnectionLostError`) from a closed client:
/// the pushes end when the connection does, and a call then fails at once, unsent, with
/// `ConnectionLost` or `Closed`, which tells which.
async fn autosend(
    c: &text::Client,
    q: Quantity,
    interval_ms: u16,
    only_on_change: bool,
) -> text::Result<Ended<Pushes>> {
    let pushes = c.autosend(q, interval_ms, only_on_change).await?;
    let c = c.clone();
    let ending: Ending = Box::new(move || {
        Box::pin(async move {
            match c.part_width_tolerance_mm().await {
                Err(Error::ConnectionLost { reason }) => Some(reason.to_string()),
                _ => None,
            }
        })
    });
    Ok(Ended(pushes, ending))
}

/// `close()` (and leaving a `with` block), idempotent ([`errors::close_for_exit`]).
async fn close_for_exit(c: text::Client) -> text::Result<()> {
    errors::close_for_exit(c.close(), || c.is_closed()).await
}

/// `gripper_rs._native.wsg_text`.
pub fn module(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    let m = PyModule::new(py, "wsg_text")?;
    m.add_class::<Client>()?;
    m.add_class::<AioClient>()?;
    Ok(m)
}
