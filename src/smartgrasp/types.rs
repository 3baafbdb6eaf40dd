//! The protocol's enumerations (manual 3.2.2 and 3.3), each keeping numbers the manual does not
//! define as `Unknown(n)` so a newer server never makes a frame undecodable.
//!
//! Build a value from the wire with `From<u8>`: it always yields the named variant for a number the
//! manual defines, so `Unknown(n)` only ever holds undefined numbers when it came from the wire.

use std::fmt;

/// Defines a `u8` wire enumeration with an `Unknown(u8)` fallback, conversions both ways and the
/// manual's name and meaning as `Display`. One macro so the nine enumerations cannot drift apart.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $value:literal => $label:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name {
            $( $(#[$vmeta])* $variant, )+
            /// A number the manual does not define, kept as received.
            Unknown(u8),
        }

        impl From<u8> for $name {
            fn from(value: u8) -> Self {
                match value {
                    $( $value => Self::$variant, )+
                    other => Self::Unknown(other),
                }
            }
        }

        impl From<$name> for u8 {
            fn from(value: $name) -> u8 {
                match value {
                    $( $name::$variant => $value, )+
                    $name::Unknown(other) => other,
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                match self {
                    $( Self::$variant => f.write_str($label), )+
                    Self::Unknown(other) => {
                        write!(f, "unknown {} {}", stringify!($name), other)
                    }
                }
            }
        }
    };
}

wire_enum! {
    /// Communication type, header byte 6 (manual 3.2.2.1).
    pub enum CommunicationType {
        /// `01`: a request from the robot.
        Request = 1 => "request",
        /// `02`: a response from the server.
        Response = 2 => "response",
    }
}

wire_enum! {
    /// Response code, header byte 7 (manual 3.2.2.2). Ignored in requests.
    pub enum ResponseCode {
        /// 1 `SUCCESS`.
        Success = 1 => "SUCCESS (the server processed the request successfully)",
        /// 2 `ERROR`.
        Error = 2 => "ERROR (the server ran into an error processing the request)",
        /// 3 `NO_OBJECT`.
        NoObject = 3 => "NO_OBJECT (no object found)",
        /// 4 `NO_GRASP`.
        NoGrasp = 4 => "NO_GRASP (no grasp found)",
        /// 5 `INVALID_OBJECT_CLASS`.
        InvalidObjectClass =
            5 => "INVALID_OBJECT_CLASS (the object class is invalid or does not exist)",
    }
}

wire_enum! {
    /// Message type, header byte 9 (manual 3.3.1).
    pub enum MessageType {
        /// 1: query the server's highest protocol version.
        GetProtocolVersion = 1 => "GET_PROTOCOL_VERSION",
        /// 2: query the server's state.
        GetState = 2 => "GET_STATE",
        /// 3: register the client's robot system.
        RegisterClient = 3 => "REGISTER_CLIENT",
        /// 4: set the active project.
        SetProject = 4 => "SET_PROJECT",
        /// 5 (V4 only): choose the tool by the id configured on the device.
        SetTool = 5 => "SET_TOOL",
        /// 6 (V4 only): choose the workspace by the id configured on the device.
        SetWorkspace = 6 => "SET_WORKSPACE",
        /// 16: get a grasp for the current scene.
        GetGrasp = 16 => "GET_GRASP",
        /// 17: report the result of the last grasp.
        GraspFeedback = 17 => "GRASP_FEEDBACK",
        /// 32: count the objects in the current scene.
        GetObjectCount = 32 => "GET_OBJECT_COUNT",
        /// 48: tell the server the robot's current pose.
        RobotPose = 48 => "ROBOT_POSE",
    }
}

wire_enum! {
    /// Server state, GET_STATE response byte 12 (manual 3.3.2.2).
    pub enum ServerState {
        /// 1 `INIT`.
        Init = 1 => "INIT (the server is initialising)",
        /// 2 `OPERATIONAL`.
        Operational = 2 => "OPERATIONAL (the server is ready to process requests)",
        /// 3 `STOPPED`.
        Stopped = 3 => "STOPPED (the server has stopped operating)",
        /// 4 `ERROR`.
        Error = 4 => "ERROR (a critical error occurred on the server)",
    }
}

wire_enum! {
    /// The robot system a client registers as: the manual's *Client* field, REGISTER_CLIENT
    /// request byte 10 (manual 3.3.2.3). Named `RobotSystem` so it is not confused with the
    /// [`Client`](super::Client) handle.
    pub enum RobotSystem {
        /// 1 Universal Robots.
        Ur = 1 => "UR (Universal Robots)",
        /// 2 KUKA.
        Kuka = 2 => "KUKA",
        /// 3 Yaskawa.
        Yaskawa = 3 => "Yaskawa",
        /// 4 FANUC.
        Fanuc = 4 => "FANUC",
        /// 5 ABB.
        Abb = 5 => "ABB",
        /// 6 HORST (fruitcore robotics).
        Horst = 6 => "HORST (fruitcore robotics)",
        /// 128 Siemens PLC.
        SiemensPlc = 128 => "Siemens PLC",
    }
}

wire_enum! {
    /// Grasp mode, GET_GRASP request byte 11 / response byte 13 (manual 3.3.3.1). The response's
    /// mode says which kind of grasp was returned and may differ from the requested one.
    pub enum GraspMode {
        /// 1 `ACTIVE_GRASP`: the grasp must match the object's user-defined active grasp.
        ActiveGrasp = 1 => "ACTIVE_GRASP",
        /// 2 `ANY_GRASP`: the grasp must match any user-defined grasp of the object.
        AnyGrasp = 2 => "ANY_GRASP",
        /// 3 `AUTO_GRASP`: `ANY_GRASP`, with model-free grasp planning as a fallback.
        AutoGrasp = 3 => "AUTO_GRASP",
    }
}

wire_enum! {
    /// Tool used for the grasp, GET_GRASP request byte 14 / response byte 38 (manual 3.3.3.1).
    pub enum Tool {
        /// 1 `EXTERIOR`: two-finger parallel gripper, gripping from outside.
        Exterior = 1 => "EXTERIOR (2-finger parallel gripper, outer grip)",
        /// 2 `INTERIOR`: two-finger parallel gripper, gripping from inside.
        Interior = 2 => "INTERIOR (2-finger parallel gripper, inner grip)",
        /// 3 `CONTACT`: suction, magnet or adhesion through a contact surface.
        Contact = 3 => "CONTACT (suction, magnet or adhesion)",
    }
}

wire_enum! {
    /// Result of the last grasp, GRASP_FEEDBACK request byte 16 (manual 3.3.3.2).
    pub enum GraspFeedback {
        /// 1 `OK`: the grasp was fine.
        Ok = 1 => "OK (the grasp was fine)",
        /// 2 `BAD`: the grasp was not fine.
        Bad = 2 => "BAD (the grasp was not fine)",
    }
}

wire_enum! {
    /// Pose format, the layout of a seven-integer pose (manual 5).
    pub enum PoseFormat {
        /// 1: position µm, quaternion qx qy qz qw scaled by 10^6 (not normalised).
        Quaternion = 1 => "quaternion",
        /// 2: position µm, rotation vector µrad (Universal Robots).
        AxisAngle = 2 => "axis-angle",
        /// 16: position µm, W P R µdeg about the fixed x, y, z axes (FANUC, Yaskawa).
        Wpr = 16 => "WPR",
        /// 17: position µm, A about z, B about y', C about x'' in µdeg (KUKA).
        Abc = 17 => "ABC",
    }
}

/// Defines a raw `u8` field of V4 whose values no public source pins: kept as received, shown as
/// its number.
macro_rules! raw_u8 {
    ($(#[$meta:meta])* pub struct $name:ident;) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub u8);

        impl From<u8> for $name {
            fn from(value: u8) -> Self {
                $name(value)
            }
        }

        impl From<$name> for u8 {
            fn from(value: $name) -> u8 {
                value.0
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{} {}", stringify!($name), self.0)
            }
        }
    };
}

raw_u8! {
    /// V4 GET_GRASP request byte 14: which candidate the server picks (PROTOCOLS.md 2b). SCHUNK's
    /// KUKA example sends 1, 2 and 3; no public source says what they mean, so the number is
    /// passed through as given. Not sent in V3 (byte 14 is the tool there).
    pub struct SelectionCriterion;
}

raw_u8! {
    /// V4 GET_GRASP response byte 19: the frame the grasp pose refers to (PROTOCOLS.md 2b). No
    /// public source gives its values: kept as received.
    pub struct ReferenceFrame;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_round_trips_and_known_numbers_are_named() {
        for n in 0..=u8::MAX {
            assert_eq!(u8::from(MessageType::from(n)), n);
            assert_eq!(u8::from(ResponseCode::from(n)), n);
            assert_eq!(u8::from(PoseFormat::from(n)), n);
            assert_eq!(u8::from(RobotSystem::from(n)), n);
        }
        assert_eq!(MessageType::from(32), MessageType::GetObjectCount);
        assert_eq!(MessageType::from(48), MessageType::RobotPose);
        assert_eq!(RobotSystem::from(128), RobotSystem::SiemensPlc);
        assert_eq!(PoseFormat::from(17), PoseFormat::Abc);
        assert_eq!(ResponseCode::from(5), ResponseCode::InvalidObjectClass);
        assert_eq!(MessageType::from(0), MessageType::Unknown(0));
        assert_eq!(ServerState::from(9).to_string(), "unknown ServerState 9");
        assert_eq!(
            ResponseCode::NoGrasp.to_string(),
            "NO_GRASP (no grasp found)"
        );
    }
}
