//! Status and error codes of the GRIPLINK controller (manual chapter 4).
//!
//! These are **not** the WSG status codes: the same number means different things in the two
//! protocols.

use std::fmt;

macro_rules! statuses {
    ($($code:literal => $variant:ident, $ident:literal, $text:literal;)*) => {
        /// A GRIPLINK status code, as carried by `ERR <code>` (manual chapter 4).
        ///
        /// Numbers the manual does not list are kept in [`Status::Unknown`], so a newer controller
        /// never turns into a parse error.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[non_exhaustive]
        pub enum Status {
            $(
                #[doc = concat!("`", $ident, "` (", stringify!($code), "): ", $text, ".")]
                $variant,
            )*
            /// A code the manual does not list.
            Unknown(u32),
        }

        impl Status {
            /// The status for a numeric code; unknown numbers are kept.
            pub fn from_code(code: u32) -> Status {
                match code {
                    $($code => Status::$variant,)*
                    other => Status::Unknown(other),
                }
            }

            /// The numeric code.
            pub fn code(self) -> u32 {
                match self {
                    $(Status::$variant => $code,)*
                    Status::Unknown(code) => code,
                }
            }

            /// The manual's identifier (`E_STATE_CONFLICT`), or `None` for an unknown code.
            pub fn identifier(self) -> Option<&'static str> {
                match self {
                    $(Status::$variant => Some($ident),)*
                    Status::Unknown(_) => None,
                }
            }

            /// The manual's description ("Invalid state"), or `None` for an unknown code.
            pub fn description(self) -> Option<&'static str> {
                match self {
                    $(Status::$variant => Some($text),)*
                    Status::Unknown(_) => None,
                }
            }
        }
    };
}

statuses! {
    0 => Success, "E_SUCCESS", "No error. Command successfully executed";
    1 => Overrun, "E_OVERRUN", "Data overrun";
    2 => RangeError, "E_RANGE_ERROR", "Value out of range";
    3 => NotAvailable, "E_NOT_AVAILABLE", "Function or data not available";
    4 => NotInitialized, "E_NOT_INITIALIZED", "Device not initialized";
    5 => Timeout, "E_TIMEOUT", "Timeout";
    6 => InsufficientResources, "E_INSUFFICIENT_RESOURCES", "Not enough memory available";
    7 => ChecksumError, "E_CHECKSUM_ERROR", "Checksum error";
    8 => AccessDenied, "E_ACCESS_DENIED", "Access denied";
    9 => InvalidHandle, "E_INVALID_HANDLE", "Invalid handle";
    10 => InvalidParameter, "E_INVALID_PARAMETER", "Invalid parameter";
    11 => IndexOutOfBounds, "E_INDEX_OUT_OF_BOUNDS", "Index out of bounds";
    12 => IoError, "E_IO_ERROR", "Generic I/O error";
    13 => ReadError, "E_READ_ERROR", "Read error";
    14 => WriteError, "E_WRITE_ERROR", "Write error";
    15 => NotFound, "E_NOT_FOUND", "Resource not found";
    16 => NotOpen, "E_NOT_OPEN", "File or device not open";
    17 => Exists, "E_EXISTS", "Resource already exists";
    18 => NoComm, "E_NO_COMM", "Connection error";
    19 => StateConflict, "E_STATE_CONFLICT", "Invalid state";
    20 => NotSupported, "E_NOT_SUPPORTED", "Command or function not supported";
    21 => InconsistentData, "E_INCONSISTENT_DATA", "Data inconsistent";
    22 => CmdSyntax, "E_CMD_SYNTAX", "Syntax error";
    23 => CmdUnknown, "E_CMD_UNKNOWN", "Unknown command";
    24 => CmdAborted, "E_CMD_ABORTED", "Command aborted";
    25 => CmdFailed, "E_CMD_FAILED", "Command failed";
    26 => AxisBlocked, "E_AXIS_BLOCKED", "Axis is blocked";
    27 => Pending, "E_PENDING", "Pending action / Not yet finished";
}

impl fmt::Display for Status {
    /// The manual's description, e.g. `Invalid state`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.description() {
            Some(text) => f.write_str(text),
            None => write!(f, "unknown status code {}", self.code()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_unknown_is_kept() {
        for code in 0..=40 {
            assert_eq!(Status::from_code(code).code(), code);
        }
        assert_eq!(Status::from_code(19), Status::StateConflict);
        assert_eq!(Status::from_code(99), Status::Unknown(99));
        assert_eq!(Status::from_code(27).identifier(), Some("E_PENDING"));
    }

    #[test]
    fn display_is_the_manual_text() {
        assert_eq!(Status::NotInitialized.to_string(), "Device not initialized");
        assert_eq!(Status::CmdUnknown.to_string(), "Unknown command");
        assert_eq!(Status::Unknown(77).to_string(), "unknown status code 77");
    }
}
