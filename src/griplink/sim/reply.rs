//! What the simulated controller does with a command's reply: answers at once, holds it back
//! (a blocking motion, WSTR, WAITVAL: [`Wait`]) or ends the connection (`BYE()`); and the `ERR`
//! line it answers a refusal with. The vocabulary the controller's parts share (dispatch, the
//! finger moves, the held replies, the server), below all of them.

use std::time::Duration;

use crate::griplink::status::Status;

/// Per-connection settings.
#[derive(Debug, Clone, Default)]
pub struct Session {
    /// `VERBOSE=1`: `ERR` replies carry the manual's description. Kept per connection, so one
    /// client's choice does not change another's replies.
    pub verbose: bool,
}

/// What the controller does with a command.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Answer at once with this line.
    Reply(String),
    /// Hold the answer (and this connection's later commands) until
    /// [`Controller::poll`](super::Controller::poll)
    /// gives one.
    Wait(Wait),
    /// `BYE()`: answer `ACK`, then close the connection.
    Bye,
}

/// An `ERR` reply line, with two-digit codes as the manual prints them (`ERR 04`).
pub fn error_line(status: Status, verbose: bool) -> String {
    if verbose {
        format!("ERR {:02} {status}", status.code())
    } else {
        format!("ERR {:02}", status.code())
    }
}

/// What a command does, or the status it is refused with.
pub(super) type Step = Result<Outcome, Status>;

/// Answers at once with `line`.
pub(super) fn reply(line: String) -> Step {
    Ok(Outcome::Reply(line))
}

/// Answers `ACK` at once.
pub(super) fn ack() -> Step {
    reply("ACK".to_owned())
}

/// Where the value was when a WAITVAL started, relative to its window (3.4.12, cases 1 and 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Approach {
    /// Below `threshold − window/2`: ACK once the value reaches that bound.
    FromBelow,
    /// Above `threshold + window/2`: ACK once the value reaches that bound.
    FromAbove,
}

/// A reply being held back.
#[derive(Debug, Clone, PartialEq)]
pub enum Wait {
    /// A blocking motion command: ACK when motion `id` ends.
    Motion {
        /// Port index.
        port: usize,
        /// The motion.
        id: u64,
    },
    /// WSTR: the new state after the port's transition number `after`, `E_TIMEOUT` at
    /// `deadline`.
    Transition {
        /// Port index.
        port: usize,
        /// The port's transition count when the WSTR arrived.
        after: u64,
        /// When to give up.
        deadline: Duration,
    },
    /// WAITVAL(F): ACK when the position reaches `bound_um` from where it started,
    /// `E_TIMEOUT` at `deadline`.
    Value {
        /// Port index.
        port: usize,
        /// The window bound the value approaches, µm.
        bound_um: f64,
        /// The side it approaches from.
        approach: Approach,
        /// When to give up.
        deadline: Duration,
    },
}
