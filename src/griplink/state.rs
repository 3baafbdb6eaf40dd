//! Device states as returned by `DEVSTATE` and `WSTR` (manual chapter 5).

use std::fmt;

/// The state of the device on a port (manual chapter 5), as `DEVSTATE[p]?` and `WSTR[p]?`
/// return it.
///
/// Numbers the manual does not list are kept in [`DeviceState::Unknown`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DeviceState {
    /// 0 `DS_NOT_CONNECTED`: no device connected (the DEVSTATE note calls it `DS_INVALID`).
    NotConnected,
    /// 1 `DS_NOT_INITIALIZED`: e.g. a gripper that needs a reference drive (HOME) first.
    NotInitialized,
    /// 2 `DS_DISABLED`: idle, operable and waiting for a command (the GRIP examples call it
    /// `DS_IDLE`).
    Disabled,
    /// 3 `DS_RELEASED`: a RELEASE finished at the release position.
    Released,
    /// 4 `DS_NO_PART`: a GRIP reached the no-part limit without finding a part.
    NoPart,
    /// 5 `DS_HOLDING`: a GRIP found a part and holds it with the gripping force.
    Holding,
    /// 6 `DS_ENABLED`: in operation (sensors).
    Enabled,
    /// 7 `DS_FAULT`: fault state; see the device manual for recovery.
    Fault,
    /// A state number the manual does not list.
    Unknown(i64),
}

impl DeviceState {
    /// The state for a number as it appears on the wire; unknown numbers are kept.
    pub fn from_code(code: i64) -> DeviceState {
        match code {
            0 => DeviceState::NotConnected,
            1 => DeviceState::NotInitialized,
            2 => DeviceState::Disabled,
            3 => DeviceState::Released,
            4 => DeviceState::NoPart,
            5 => DeviceState::Holding,
            6 => DeviceState::Enabled,
            7 => DeviceState::Fault,
            other => DeviceState::Unknown(other),
        }
    }

    /// The number on the wire.
    pub fn code(self) -> i64 {
        match self {
            DeviceState::NotConnected => 0,
            DeviceState::NotInitialized => 1,
            DeviceState::Disabled => 2,
            DeviceState::Released => 3,
            DeviceState::NoPart => 4,
            DeviceState::Holding => 5,
            DeviceState::Enabled => 6,
            DeviceState::Fault => 7,
            DeviceState::Unknown(code) => code,
        }
    }

    /// The manual's identifier (`DS_HOLDING`), or `None` for an unknown state.
    pub fn identifier(self) -> Option<&'static str> {
        Some(match self {
            DeviceState::NotConnected => "DS_NOT_CONNECTED",
            DeviceState::NotInitialized => "DS_NOT_INITIALIZED",
            DeviceState::Disabled => "DS_DISABLED",
            DeviceState::Released => "DS_RELEASED",
            DeviceState::NoPart => "DS_NO_PART",
            DeviceState::Holding => "DS_HOLDING",
            DeviceState::Enabled => "DS_ENABLED",
            DeviceState::Fault => "DS_FAULT",
            DeviceState::Unknown(_) => return None,
        })
    }
}

impl fmt::Display for DeviceState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.identifier() {
            Some(name) => f.write_str(name),
            None => write!(f, "unknown device state {}", self.code()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_round_trip_and_unknown_is_kept() {
        for code in -2..12 {
            assert_eq!(DeviceState::from_code(code).code(), code);
        }
        assert_eq!(DeviceState::from_code(5), DeviceState::Holding);
        assert_eq!(DeviceState::from_code(9), DeviceState::Unknown(9));
        assert_eq!(DeviceState::Holding.to_string(), "DS_HOLDING");
    }
}
