//! Device status codes (manual, Anhang A).

use std::fmt;

macro_rules! statuses {
    ($( $code:literal => $variant:ident, $sym:literal, $text:literal; )*) => {
        /// A status code the device returns in every reply (manual, Anhang A).
        ///
        /// Codes outside the manual's list keep their number in [`Status::Unknown`]. `Display`
        /// prints the manual's symbol and description.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Status {
            $(
                #[doc = concat!($code, " ", $sym, ": ", $text)]
                $variant,
            )*
            /// A code the manual does not list.
            Unknown(u16),
        }

        impl Status {
            /// The status with wire code `code`.
            pub const fn from_code(code: u16) -> Self {
                match code {
                    $( $code => Status::$variant, )*
                    other => Status::Unknown(other),
                }
            }

            /// The wire code.
            pub const fn code(self) -> u16 {
                match self {
                    $( Status::$variant => $code, )*
                    Status::Unknown(c) => c,
                }
            }

            /// The manual's symbolic name, e.g. `E_CMD_PENDING`.
            pub const fn symbol(self) -> &'static str {
                match self {
                    $( Status::$variant => $sym, )*
                    Status::Unknown(_) => "E_UNKNOWN",
                }
            }

            /// The manual's description (translated from Anhang A).
            pub const fn description(self) -> &'static str {
                match self {
                    $( Status::$variant => $text, )*
                    Status::Unknown(_) => "status code not listed in the manual",
                }
            }
        }
    };
}

statuses! {
    0 => Success, "E_SUCCESS", "no error, command successful";
    1 => NotAvailable, "E_NOT_AVAILABLE", "function or data not available";
    2 => NoSensor, "E_NO_SENSOR", "no measuring converter connected";
    3 => NotInitialized, "E_NOT_INITIALIZED", "device not initialized";
    4 => AlreadyRunning, "E_ALREADY_RUNNING", "already running";
    5 => FeatureNotSupported, "E_FEATURE_NOT_SUPPORTED", "the function is not supported";
    6 => InconsistentData, "E_INCONSISTENT_DATA", "one or more parameters are inconsistent";
    7 => Timeout, "E_TIMEOUT", "timeout";
    8 => ReadError, "E_READ_ERROR", "error while reading data";
    9 => WriteError, "E_WRITE_ERROR", "error while writing data";
    10 => InsufficientResources, "E_INSUFFICIENT_RESOURCES", "not enough memory";
    11 => ChecksumError, "E_CHECKSUM_ERROR", "checksum error";
    12 => NoParamExpected, "E_NO_PARAM_EXPECTED", "parameter given although none expected";
    13 => NotEnoughParams, "E_NOT_ENOUGH_PARAMS", "too few parameters for the command";
    14 => CmdUnknown, "E_CMD_UNKNOWN", "unknown command";
    15 => CmdFormatError, "E_CMD_FORMAT_ERROR", "command format error";
    16 => AccessDenied, "E_ACCESS_DENIED", "access denied";
    17 => AlreadyOpen, "E_ALREADY_OPEN", "interface already open";
    18 => CmdFailed, "E_CMD_FAILED", "error while executing a command";
    19 => CmdAborted, "E_CMD_ABORTED", "command execution aborted by the user";
    20 => InvalidHandle, "E_INVALID_HANDLE", "invalid handle";
    21 => NotFound, "E_NOT_FOUND", "device or file not found";
    22 => NotOpen, "E_NOT_OPEN", "device or file not open";
    23 => IoError, "E_IO_ERROR", "input/output error";
    24 => InvalidParameter, "E_INVALID_PARAMETER", "invalid parameter";
    25 => IndexOutOfBounds, "E_INDEX_OUT_OF_BOUNDS", "index out of bounds";
    26 => CmdPending, "E_CMD_PENDING", "command not yet completed; a reply with the result follows";
    27 => Overrun, "E_OVERRUN", "data overrun";
    28 => RangeError, "E_RANGE_ERROR", "range error";
    29 => AxisBlocked, "E_AXIS_BLOCKED", "axis blocked";
    30 => FileExists, "E_FILE_EXISTS", "file already exists";
}

impl From<u16> for Status {
    fn from(code: u16) -> Self {
        Status::from_code(code)
    }
}

impl From<Status> for u16 {
    fn from(s: Status) -> u16 {
        s.code()
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} ({}): {}",
            self.symbol(),
            self.code(),
            self.description()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_round_trips_and_unknown_keeps_its_number() {
        for code in 0..=40u16 {
            let s = Status::from_code(code);
            assert_eq!(s.code(), code);
            assert_eq!(matches!(s, Status::Unknown(_)), code > 30, "{code}");
        }
        assert_eq!(Status::from_code(26), Status::CmdPending);
        assert_eq!(Status::from_code(14), Status::CmdUnknown);
        assert_eq!(Status::from_code(0xBEEF), Status::Unknown(0xBEEF));
        assert_eq!(
            Status::CmdFailed.to_string(),
            "E_CMD_FAILED (18): error while executing a command"
        );
        assert!(Status::Unknown(99).to_string().contains("99"));
    }
}
