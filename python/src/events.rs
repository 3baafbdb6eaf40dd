//! Reconnect policies and connection events (`gripper::reconnect`) for Python:
//! `gripper_rs.ReconnectPolicy` in, `gripper_rs.ConnectionEvent` out (issue 32: parity).

use gripper::reconnect::{ConnectionEvent, ConnectionEvents, ReconnectPolicy};
use pyo3::prelude::*;

use crate::convert::{enum_member, field, record, ToPy};
use crate::runtime::seconds;
use crate::stream::{Source, Stream};

const PY: &str = "gripper_rs.reconnect";

/// A `gripper_rs.ReconnectPolicy` (any object with its attributes) as the Rust policy; None:
/// no reconnecting (the default).
pub fn policy(obj: Option<Bound<'_, PyAny>>) -> PyResult<Option<ReconnectPolicy>> {
    let Some(obj) = obj else { return Ok(None) };
    let secs = |name: &str| -> PyResult<std::time::Duration> {
        seconds(name, crate::args::extract(&obj.getattr(name)?, name)?)
    };
    Ok(Some(ReconnectPolicy {
        initial_delay: secs("initial_delay_s")?,
        max_delay: secs("max_delay_s")?,
        factor: crate::args::extract(&obj.getattr("factor")?, "factor")?,
        max_attempts: crate::args::extract(&obj.getattr("max_attempts")?, "max_attempts")?,
    }))
}

impl ToPy for ConnectionEvent {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let none = || py.None().into_bound(py);
        let (kind, reason, attempt, delay_s, count) = match self {
            ConnectionEvent::Lost { reason } => {
                ("LOST", field(py, reason)?, none(), none(), none())
            }
            ConnectionEvent::Reconnecting { attempt, delay } => (
                "RECONNECTING",
                none(),
                field(py, attempt)?,
                field(py, delay.as_secs_f64())?,
                none(),
            ),
            ConnectionEvent::Connected => ("CONNECTED", none(), none(), none(), none()),
            ConnectionEvent::Restored { attempts } => {
                ("RESTORED", none(), field(py, attempts)?, none(), none())
            }
            ConnectionEvent::GaveUp { attempts } => {
                ("GAVE_UP", none(), field(py, attempts)?, none(), none())
            }
            ConnectionEvent::Missed { count } => {
                ("MISSED", none(), none(), none(), field(py, count)?)
            }
            // A newer crate's event: its text, as a loss would carry it.
            other => (
                "OTHER",
                field(py, other.to_string())?,
                none(),
                none(),
                none(),
            ),
        };
        let kind = enum_member(py, PY, "EventKind", kind)?.into_bound(py);
        record(
            py,
            PY,
            "ConnectionEvent",
            &[
                ("kind", kind),
                ("reason", reason),
                ("attempt", attempt),
                ("delay_s", delay_s),
                ("count", count),
            ],
        )
    }
}

impl Source for ConnectionEvents {}

/// A client's `connection_events()`: a stream of `ConnectionEvent`s that ends when the client has
/// closed or given up.
pub fn stream(events: ConnectionEvents) -> PyResult<Stream> {
    crate::runtime::enter(|| Stream::new(events))
}
