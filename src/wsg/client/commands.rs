//! The typed commands of the manual's chapter 3, one method each, as thin wrappers over
//! [`Client::command`]: how a request is sent, paired and timed is in the parent module.

use bytes::Bytes;

use super::{not_available_as_none, Client};
use crate::wsg::command::{Command, HomingDirection, UpdateMode};
use crate::wsg::types::{self, decode_f32};
use crate::wsg::{
    Finger, FingerFlags, FingerInfo, GraspingStatistics, GripState, Result, SoftLimits, SystemInfo,
    SystemLimits, SystemState,
};

impl Client {
    /// Loop (0x06): the device echoes up to 256 bytes.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn loop_back(&self, data: impl Into<Bytes>) -> Result<Bytes> {
        self.command(Command::Loop(data.into())).await
    }

    /// Homing (0x20): references the fingers; needed before any other motion.
    ///
    /// While a move of the same command is on the wire, the call waits for the device: it is
    /// sent when that move ends, or refused with E_ALREADY_RUNNING, unsent, when a system-state
    /// query sent after the call finds the fingers moving (manual 3.2.2; see [`Client`]).
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn home(&self, direction: HomingDirection) -> Result<()> {
        self.no_data(Command::Homing(direction)).await
    }

    /// Pre-position (0x21) to an absolute width, stopping if blocked.
    ///
    /// While a move of the same command is on the wire, the call waits for the device: it is
    /// sent when that move ends, or refused with E_ALREADY_RUNNING, unsent, when a system-state
    /// query sent after the call finds the fingers moving (manual 3.2.2; see [`Client`]).
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn pre_position(&self, width_mm: f32, speed_mm_per_s: f32) -> Result<()> {
        self.no_data(Command::PrePosition {
            relative: false,
            stop_on_block: true,
            width_mm,
            speed_mm_per_s,
        })
        .await
    }

    /// Pre-position (0x21) by a distance relative to the current width, stopping if blocked.
    ///
    /// While a move of the same command is on the wire, the call waits for the device: it is
    /// sent when that move ends, or refused with E_ALREADY_RUNNING, unsent, when a system-state
    /// query sent after the call finds the fingers moving (manual 3.2.2; see [`Client`]).
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn pre_position_relative(&self, distance_mm: f32, speed_mm_per_s: f32) -> Result<()> {
        self.no_data(Command::PrePosition {
            relative: true,
            stop_on_block: true,
            width_mm: distance_mm,
            speed_mm_per_s,
        })
        .await
    }

    /// Stop (0x22): stops any motion (a pending motion fails with E_CMD_ABORTED).
    ///
    /// Sent at once, never queued behind anything, even an earlier stop whose reply is
    /// outstanding or lost; `Ok` only on a reply to a stop sent at or after the call, sent again
    /// if none comes within [`RESEND_STOP_AFTER`](super::RESEND_STOP_AFTER) (see [`Client`]).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn stop(&self) -> Result<()> {
        self.no_data(Command::Stop).await
    }

    /// Fast stop (0x23): stops and refuses motion until [`Client::acknowledge_fast_stop`].
    ///
    /// Sent at once, never queued behind anything, even an earlier FAST STOP whose reply is
    /// outstanding or lost; `Ok` only on a reply to a FAST STOP sent at or after the call, sent
    /// again if none comes within [`RESEND_STOP_AFTER`](super::RESEND_STOP_AFTER) (see [`Client`]).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn fast_stop(&self) -> Result<()> {
        self.no_data(Command::FastStop).await
    }

    /// Acknowledge a fast stop or fault (0x24).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn acknowledge_fast_stop(&self) -> Result<()> {
        self.no_data(Command::AckFastStop).await
    }

    /// Grasp a part (0x25) of nominal width `width_mm`. No part found is
    /// `Error::Device { status: Status::CmdFailed, .. }`.
    ///
    /// While a move of the same command is on the wire, the call waits for the device: it is
    /// sent when that move ends, or refused with E_ALREADY_RUNNING, unsent, when a system-state
    /// query sent after the call finds the fingers moving (manual 3.2.2; see [`Client`]).
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn grasp(&self, width_mm: f32, speed_mm_per_s: f32) -> Result<()> {
        self.no_data(Command::Grasp {
            width_mm,
            speed_mm_per_s,
        })
        .await
    }

    /// Release the part (0x26), opening to `width_mm`.
    ///
    /// While a move of the same command is on the wire, the call waits for the device: it is
    /// sent when that move ends, or refused with E_ALREADY_RUNNING, unsent, when a system-state
    /// query sent after the call finds the fingers moving (manual 3.2.2; see [`Client`]).
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn release(&self, width_mm: f32, speed_mm_per_s: f32) -> Result<()> {
        self.no_data(Command::Release {
            width_mm,
            speed_mm_per_s,
        })
        .await
    }

    /// Set the acceleration (0x30); the device clamps it to its limits.
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn set_acceleration(&self, mm_per_s2: f32) -> Result<()> {
        self.no_data(Command::SetAcceleration(mm_per_s2)).await
    }

    /// The acceleration (0x31), mm/s².
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn acceleration_mm_per_s2(&self) -> Result<f32> {
        self.query(Command::GetAcceleration, decode_f32).await
    }

    /// Set the grasping force (0x32); the device clamps it to its limits.
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn set_grasping_force(&self, force_n: f32) -> Result<()> {
        self.no_data(Command::SetForce(force_n)).await
    }

    /// The grasping force limit (0x33), N.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn grasping_force_n(&self) -> Result<f32> {
        self.query(Command::GetForce, decode_f32).await
    }

    /// Set soft limits (0x34).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn set_soft_limits(&self, limits: SoftLimits) -> Result<()> {
        self.no_data(Command::SetSoftLimits(limits)).await
    }

    /// The soft limits (0x35); `None` when none are set (E_NOT_AVAILABLE).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn soft_limits(&self) -> Result<Option<SoftLimits>> {
        not_available_as_none(self.query(Command::GetSoftLimits, SoftLimits::decode).await)
    }

    /// Clear the soft limits (0x36).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn clear_soft_limits(&self) -> Result<()> {
        self.no_data(Command::ClearSoftLimits).await
    }

    /// Overdrive mode on or off (0x37).
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn set_overdrive(&self, on: bool) -> Result<()> {
        self.no_data(Command::Overdrive(on)).await
    }

    /// Tare the force sensor (0x38); refused (E_ACCESS_DENIED) while holding a part.
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn tare_force_sensor(&self) -> Result<()> {
        self.no_data(Command::Tare).await
    }

    /// The system state flags (0x40).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn system_state(&self) -> Result<SystemState> {
        self.query(Command::SystemState(UpdateMode::ONCE), SystemState::decode)
            .await
    }

    /// The grip state (0x41).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn grip_state(&self) -> Result<GripState> {
        self.query(Command::GripState(UpdateMode::ONCE), GripState::decode)
            .await
    }

    /// The grasping statistics (0x42), reset after reading when `reset`.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn grasping_statistics(&self, reset: bool) -> Result<GraspingStatistics> {
        self.query(
            Command::GraspingStatistics { reset },
            GraspingStatistics::decode,
        )
        .await
    }

    /// The opening width (0x43), mm.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn width_mm(&self) -> Result<f32> {
        self.query(Command::Width(UpdateMode::ONCE), decode_f32)
            .await
    }

    /// The finger speed (0x44), mm/s.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn speed_mm_per_s(&self) -> Result<f32> {
        self.query(Command::Speed(UpdateMode::ONCE), decode_f32)
            .await
    }

    /// The finger force (0x45), N.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn force_n(&self) -> Result<f32> {
        self.query(Command::Force(UpdateMode::ONCE), decode_f32)
            .await
    }

    /// The temperature inside the gripper (0x46), °C.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn temperature_c(&self) -> Result<f32> {
        self.query(Command::Temperature, types::decode_temperature_c)
            .await
    }

    /// System information (0x50).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn system_info(&self) -> Result<SystemInfo> {
        self.query(Command::SystemInfo, SystemInfo::decode).await
    }

    /// Set the device tag (0x51): printable ASCII, at most 64 characters.
    ///
    /// Cancel-safe for the connection; once sent, the command takes effect even if the call is
    /// dropped (see [Cancellation](Client#cancellation)).
    pub async fn set_device_tag(&self, tag: &str) -> Result<()> {
        self.no_data(Command::SetTag(tag.to_owned())).await
    }

    /// The device tag (0x52); `None` when none is set (E_NOT_AVAILABLE).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn device_tag(&self) -> Result<Option<String>> {
        let decode = |d: &[u8]| -> std::result::Result<String, String> {
            std::str::from_utf8(d)
                .map(str::to_owned)
                .map_err(|e| e.to_string())
        };
        not_available_as_none(self.query(Command::GetTag, decode).await)
    }

    /// The system limits (0x53).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn system_limits(&self) -> Result<SystemLimits> {
        self.query(Command::SystemLimits, SystemLimits::decode)
            .await
    }

    /// Finger information (0x60 / 0x70).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn finger_info(&self, finger: Finger) -> Result<FingerInfo> {
        self.query(Command::FingerInfo(finger), FingerInfo::decode)
            .await
    }

    /// Finger flags (0x61 / 0x71).
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn finger_flags(&self, finger: Finger) -> Result<FingerFlags> {
        self.query(Command::FingerFlags(finger), FingerFlags::decode)
            .await
    }

    /// Finger power (0x62 / 0x72); switching on waits for the final reply, which comes after
    /// about 500 ms (manual 3.6.3), for [`FINGER_POWER_ON_DURATION`](super::FINGER_POWER_ON_DURATION) plus the query timeout.
    ///
    /// Cancel-safe for the connection, but dropping the call does **not** stop the fingers: once
    /// sent, the move runs to its end; send [`Client::stop`] (see [Cancellation](Client#cancellation)).
    pub async fn set_finger_power(&self, finger: Finger, on: bool) -> Result<()> {
        self.no_data(Command::FingerPower(finger, on)).await
    }

    /// Finger data (0x63 / 0x73), finger-specific bytes.
    ///
    /// Cancel-safe (see [Cancellation](Client#cancellation)).
    pub async fn finger_data(&self, finger: Finger) -> Result<Bytes> {
        self.command(Command::FingerData(finger)).await
    }
}
