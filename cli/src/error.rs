//! The one error of `gripctl`: a one-line message for stderr, a kind for scripts, and — when the
//! device said no — its status code with the manual's name and description.
//!
//! Every protocol's library error becomes a [`CliError`] in one place, [`classify`], through the
//! library's own classification ([`gripper::ErrorKind`]); each protocol module only tells how its
//! device's code is named ([`Classify`]). So `main` prints every failure the same way.

use gripper::ErrorKind;
use serde_json::{json, Value};

/// What kind of failure, for the exit path and for `--json` readers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The device answered with an error status code.
    Device,
    /// No answer within the timeout.
    Timeout,
    /// Connecting failed, or the connection broke.
    Connection,
    /// The device sent something the protocol does not allow.
    Malformed,
    /// The command line asked for something that cannot be sent.
    Argument,
    /// Standard output could not be written (e.g. a closed pipe).
    Output,
    /// The simulator could not be started.
    Simulator,
    /// Ctrl-C ended the command.
    Interrupted,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Device => "device",
            Kind::Timeout => "timeout",
            Kind::Connection => "connection",
            Kind::Malformed => "malformed",
            Kind::Argument => "argument",
            Kind::Output => "output",
            Kind::Simulator => "simulator",
            Kind::Interrupted => "interrupted",
        }
    }
}

/// A device status code: its number, the manual's name and its description.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceCode {
    /// The number on the wire.
    pub number: u32,
    /// The manual's name, e.g. `E_CMD_FAILED` or `INVALID_OBJECT_CLASS`.
    pub name: String,
    /// The manual's description (may be empty for a number the manual does not define).
    pub description: String,
}

impl DeviceCode {
    /// Splits a status `Display` of the form `NAME (description)`, as the library's status
    /// enums print themselves; anything else is kept whole as the name.
    pub fn from_display(number: u32, display: &str) -> DeviceCode {
        let (name, description) = crate::common::split_name(display);
        DeviceCode {
            number,
            name: name.to_owned(),
            description: description.to_owned(),
        }
    }
}

/// A failure of a `gripctl` command.
#[derive(Debug, Clone)]
pub struct CliError {
    /// What failed, on one line.
    pub message: String,
    /// Its kind.
    pub kind: Kind,
    /// The device's status code, when the device said no.
    pub code: Option<DeviceCode>,
}

impl CliError {
    /// A failure of `kind`; newlines in `message` are folded so the error stays one line.
    pub fn new(kind: Kind, message: impl Into<String>) -> CliError {
        CliError {
            message: one_line(&message.into()),
            kind,
            code: None,
        }
    }

    /// The device answered with `code`.
    pub fn device(message: impl Into<String>, code: DeviceCode) -> CliError {
        CliError {
            code: Some(code),
            ..CliError::new(Kind::Device, message)
        }
    }

    /// A command-line value that cannot be sent.
    pub fn argument(message: impl Into<String>) -> CliError {
        CliError::new(Kind::Argument, message)
    }

    /// Standard output failed.
    pub fn output(e: &std::io::Error) -> CliError {
        CliError::new(Kind::Output, format!("cannot write the output: {e}"))
    }

    /// The same error with `context` (e.g. the device's address) in front of its message.
    pub fn context(mut self, context: impl std::fmt::Display) -> CliError {
        self.message = one_line(&format!("{context}: {}", self.message));
        self
    }

    /// The error as JSON, for `--json` readers of standard output.
    pub fn to_json(&self) -> Value {
        let mut error = json!({ "kind": self.kind.name(), "message": self.message });
        if let Some(code) = &self.code {
            error["code"] = json!(code.number);
            error["name"] = json!(code.name);
            error["description"] = json!(code.description);
        }
        json!({ "error": error })
    }
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// A library error `gripctl` reports: the library classifies it; the protocol module names the
/// device's code, when the device gave one.
pub trait Classify: std::error::Error + 'static {
    /// The library's classification (each protocol's `Error::kind`).
    fn kind(&self) -> ErrorKind;
    /// The device's code, when the device said no.
    fn code(&self) -> Option<DeviceCode>;
}

impl Classify for gripper::wsg::Error {
    fn kind(&self) -> ErrorKind {
        gripper::wsg::Error::kind(self)
    }
    fn code(&self) -> Option<DeviceCode> {
        self.status().map(crate::wsg::device_code)
    }
}

impl Classify for gripper::wsg::text::Error {
    fn kind(&self) -> ErrorKind {
        gripper::wsg::text::Error::kind(self)
    }
    fn code(&self) -> Option<DeviceCode> {
        self.status().map(crate::wsg::device_code)
    }
}

/// The library's error as a `gripctl` error: its kind, and the device's code where it gave one.
pub fn classify<E: Classify>(e: E) -> CliError {
    let kind = match e.kind() {
        ErrorKind::Device | ErrorKind::Incompatible => Kind::Device,
        ErrorKind::Timeout => Kind::Timeout,
        ErrorKind::MalformedReply => Kind::Malformed,
        ErrorKind::InvalidArgument => Kind::Argument,
        // The link failed, or the device's answer was lost on it (and `ErrorKind` is
        // non-exhaustive: a kind added later still gets its message through).
        _ => Kind::Connection,
    };
    // A transport failure (connecting, or a connect timeout) says what the system said: the
    // protocol's "I/O error:" in front adds nothing to the "cannot connect" the caller puts
    // there. A protocol's own timeout has no source and keeps its message (the command, the
    // time).
    let message = match (e.kind(), std::error::Error::source(&e)) {
        (ErrorKind::Io | ErrorKind::Timeout, Some(io)) => io.to_string(),
        _ => e.to_string(),
    };
    match e.code() {
        Some(code) => CliError {
            code: Some(code),
            ..CliError::new(kind, message)
        },
        None => CliError::new(kind, message),
    }
}

fn one_line(s: &str) -> String {
    s.split(['\n', '\r'])
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_display_splits_into_name_and_description() {
        let code = DeviceCode::from_display(5, "INVALID_OBJECT_CLASS (the class is invalid)");
        assert_eq!(code.name, "INVALID_OBJECT_CLASS");
        assert_eq!(code.description, "the class is invalid");
        let unknown = DeviceCode::from_display(9, "unknown ResponseCode 9");
        assert_eq!(unknown.name, "unknown ResponseCode 9");
        assert_eq!(unknown.description, "");
    }

    #[test]
    fn messages_stay_on_one_line() {
        let e = CliError::argument("first\nsecond\r\n").context("ctx");
        assert_eq!(e.message, "ctx: first second");
        assert_eq!(e.to_json()["error"]["kind"], "argument");
    }
}
