//! The per-port handle: every device command of chapter 3 for one port.

use std::time::Duration;

use super::Client;
use crate::griplink::command::{
    Blocking, Command, FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled, GripConfig,
    GripConfigF, PortNumber,
};
use crate::griplink::error::{Error, Result};
use crate::griplink::state::DeviceState;

/// The device on one port of the controller (`client.port(2)`). Cheap to clone; shares the
/// client's connection.
#[derive(Debug, Clone)]
pub struct Port {
    pub(crate) client: Client,
    pub(crate) port: PortNumber,
}

impl Port {
    pub(crate) fn new(client: Client, port: PortNumber) -> Self {
        Port { client, port }
    }

    /// The port number.
    pub fn number(&self) -> PortNumber {
        self.port
    }

    /// The client this handle uses.
    pub fn client(&self) -> &Client {
        &self.client
    }

    /// The same port, with every call using `timeout` instead of the defaults.
    pub fn with_timeout(&self, timeout: Duration) -> Port {
        Port::new(self.client.with_timeout(timeout), self.port)
    }

    /// `DEVVID[p]?`: the IO-Link vendor id, `None` when no device is connected (the controller
    /// answers -1) (manual 3.2.1). Weiss Robotics is 815.
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn vendor_id(&self) -> Result<Option<u32>> {
        let vid: i64 = self.client.read_int(Command::DevVid(self.port)).await?;
        match vid {
            -1 => Ok(None),
            vid => u32::try_from(vid)
                .map(Some)
                .map_err(|_| Error::UnexpectedReply {
                    command: format!("DEVVID[{}]?", self.port),
                    line: format!("DEVVID[{}]={vid}", self.port),
                    expected: "a vendor id, or -1 for no device".into(),
                }),
        }
    }

    /// `DEVPID[p]?`: the product id (manual 3.2.2, chapter 7).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn product_id(&self) -> Result<u32> {
        self.client.read_int(Command::DevPid(self.port)).await
    }

    /// `DEVASSERT(p,vid,pid)`: fails with `E_CMD_FAILED` unless that device is connected
    /// (manual 3.2.3).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn assert_device(&self, vendor_id: u32, product_id: u32) -> Result<()> {
        self.client
            .ack(Command::DevAssert {
                port: self.port,
                vendor_id,
                product_id,
            })
            .await
    }

    /// `DEVNAME[p]?`: the product name, e.g. `IEG 55-020` (manual 3.2.4).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn name(&self) -> Result<String> {
        self.client.read_string(Command::DevName(self.port)).await
    }

    /// `DEVVENDOR[p]?`: the vendor name (manual 3.2.5).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn vendor(&self) -> Result<String> {
        self.client.read_string(Command::DevVendor(self.port)).await
    }

    /// `DEVSN[p]?`: the device's serial number (manual 3.2.6).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn serial_number(&self) -> Result<String> {
        self.client.read_string(Command::DevSn(self.port)).await
    }

    /// `DEVTAG[p]?`: the application tag (manual 3.2.7).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn tag(&self) -> Result<String> {
        self.client.read_string(Command::DevTag(self.port)).await
    }

    /// `DEVTAG[p]="…"`: at most 32 printable ASCII characters without `'` `"` `\` (checked
    /// before sending). Returns the tag the controller reports back (manual 3.2.7).
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_tag(&self, tag: &str) -> Result<String> {
        self.client
            .read_string(Command::SetDevTag(self.port, tag.to_owned()))
            .await
    }

    /// `DEVVER[p]?`: the device's firmware version (manual 3.2.8).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn version(&self) -> Result<String> {
        self.client.read_string(Command::DevVer(self.port)).await
    }

    /// `ENABLE(p)` (manual 3.4.1). What it does depends on the device; Weiss grippers are also
    /// (re-)enabled by GRIP, RELEASE and HOME, and an enabled idle gripper reports state 2
    /// ([`DeviceState::Disabled`], "idle" in chapter 5; state 6, `DS_ENABLED`, is for sensors).
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn enable(&self) -> Result<()> {
        self.client.ack(Command::Enable(self.port)).await
    }

    /// `DISABLE(p)`: on grippers, frees the fingers (manual 3.4.2).
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn disable(&self) -> Result<()> {
        self.client.ack(Command::Disable(self.port)).await
    }

    /// `HOME(p)`: reference drive; returns when it is done (motion timeout) (manual 3.4.3).
    ///
    /// [Cancel-safe](super#cancellation) for the connection, but once sent the homing runs to its
    /// end even if the call is dropped, and the controller holds this connection until then: later
    /// calls on it wait.
    pub async fn home(&self) -> Result<()> {
        self.client.ack(Command::Home(self.port)).await
    }

    /// `GRIP(p,index[,1])` with grip recipe `index` (manual 3.4.4). With
    /// [`Blocking::Immediate`] it returns when the motion starts; see
    /// [`Port::grip_and_wait`] for the outcome.
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled GRIP still grips), and with `Blocking::UntilDone` it holds this
    /// connection until it ends.
    pub async fn grip(&self, index: u32, blocking: Blocking) -> Result<()> {
        self.client
            .ack(Command::Grip {
                port: self.port,
                index,
                blocking,
            })
            .await
    }

    /// `RELEASE(p,index[,1])` with grip recipe `index` (manual 3.4.5).
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled release still opens the fingers), and with `Blocking::UntilDone` it
    /// holds this connection until it ends.
    pub async fn release(&self, index: u32, blocking: Blocking) -> Result<()> {
        self.client
            .ack(Command::Release {
                port: self.port,
                index,
                blocking,
            })
            .await
    }

    /// `FLEXGRIPF(…)`: grip with explicit parameters in mm, N, mm/s, mm/s² (manual 3.4.6).
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled GRIP still grips), and with `Blocking::UntilDone` it holds this
    /// connection until it ends.
    pub async fn flex_grip(&self, params: FlexGrip, blocking: Blocking) -> Result<()> {
        self.client
            .ack(Command::FlexGripF(self.port, params, blocking))
            .await
    }

    /// `FLEXGRIP(…)`: grip with explicit parameters in µm, mN, µm/s, µm/s² (manual 3.4.6).
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled GRIP still grips), and with `Blocking::UntilDone` it holds this
    /// connection until it ends.
    pub async fn flex_grip_scaled(&self, params: FlexGripScaled, blocking: Blocking) -> Result<()> {
        self.client
            .ack(Command::FlexGrip(self.port, params, blocking))
            .await
    }

    /// `FLEXRELEASEF(…)`: release or pre-position, in mm, mm/s, mm/s² (manual 3.4.7).
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled release still opens the fingers), and with `Blocking::UntilDone` it
    /// holds this connection until it ends.
    pub async fn flex_release(&self, params: FlexRelease, blocking: Blocking) -> Result<()> {
        self.client
            .ack(Command::FlexReleaseF(self.port, params, blocking))
            .await
    }

    /// `FLEXRELEASE(…)`: release or pre-position, in µm, µm/s, µm/s² (manual 3.4.7).
    ///
    /// [Cancel-safe](super#cancellation), but once sent the motion runs even if the call is
    /// dropped (a cancelled release still opens the fingers), and with `Blocking::UntilDone` it
    /// holds this connection until it ends.
    pub async fn flex_release_scaled(
        &self,
        params: FlexReleaseScaled,
        blocking: Blocking,
    ) -> Result<()> {
        self.client
            .ack(Command::FlexRelease(self.port, params, blocking))
            .await
    }

    /// `LED(p,index)`: show LED animation `index` (manual 3.4.8).
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn led(&self, index: u32) -> Result<()> {
        self.client
            .ack(Command::Led {
                port: self.port,
                index,
            })
            .await
    }

    /// `CLAMP(p,0|1)`: force retention on or off (manual 3.4.9).
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn clamp(&self, enable: bool) -> Result<()> {
        self.client
            .ack(Command::Clamp {
                port: self.port,
                enable,
            })
            .await
    }

    /// `WSTR[p]?`: waits for the next device state transition and returns the new state
    /// (motion timeout) (manual 3.4.10).
    ///
    /// "If no state transition occurs, the query returns with a timeout error": the controller
    /// answers `ERR 05`, here [`Error::Device`] with [`Status::Timeout`](crate::griplink::Status),
    /// after a time the manual does not give. That says nothing about a motion; ask again or
    /// decide otherwise. A motion that ends in the state it started in (RELEASE from
    /// `DS_RELEASED`, 3.4.7) causes no transition. "When issuing the same command twice, WSTR
    /// immediately returns with the current device state." [`Port::grip_and_wait`] and
    /// [`Port::release_and_wait`] handle all of this.
    ///
    /// [Cancel-safe](super#cancellation) for the connection, but once sent the controller holds
    /// this connection until it answers, even if the call is dropped: later calls on it wait.
    pub async fn wait_for_transition(&self) -> Result<DeviceState> {
        self.client.read_state(Command::Wstr(self.port)).await
    }

    /// `SETVAL(p,index,value)` with a scaled integer (manual 3.4.11). May move an actuator.
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_value(&self, index: u32, value: i32) -> Result<()> {
        self.client
            .ack(Command::SetVal {
                port: self.port,
                index,
                value,
            })
            .await
    }

    /// `SETVALF(p,index,value)` in the device's unit (manual 3.4.11). May move an actuator.
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_value_f(&self, index: u32, value: f64) -> Result<()> {
        self.client
            .ack(Command::SetValF {
                port: self.port,
                index,
                value,
            })
            .await
    }

    /// `WAITVAL(…)`: waits until value `index` reaches or crosses the window `threshold ±
    /// window/2` (scaled integers); the controller answers `E_TIMEOUT` after `timeout` (manual
    /// 3.4.12).
    ///
    /// Reach/cross, not "inside": a value that approaches from below is ACKed once it is above
    /// `threshold − window/2`, one from above once it is below `threshold + window/2`, so a value
    /// that steps over a narrow window (even `window` 0) between two of the controller's samples
    /// is ACKed too. The manual adds that for non-steady values the sampling time matters.
    ///
    /// [Cancel-safe](super#cancellation) for the connection, but once sent the controller holds
    /// this connection until it answers, even if the call is dropped: later calls on it wait.
    pub async fn wait_value(
        &self,
        index: u32,
        threshold: i32,
        window: i32,
        timeout: Duration,
    ) -> Result<()> {
        self.client
            .ack(Command::WaitVal {
                port: self.port,
                index,
                threshold,
                window,
                timeout,
            })
            .await
    }

    /// `WAITVALF(…)`: as [`Port::wait_value`], in the device's unit (manual 3.4.12).
    ///
    /// [Cancel-safe](super#cancellation) for the connection, but once sent the controller holds
    /// this connection until it answers, even if the call is dropped: later calls on it wait.
    pub async fn wait_value_f(
        &self,
        index: u32,
        threshold: f64,
        window: f64,
        timeout: Duration,
    ) -> Result<()> {
        self.client
            .ack(Command::WaitValF {
                port: self.port,
                index,
                threshold,
                window,
                timeout,
            })
            .await
    }

    /// `DEVSTATE[p]?` (manual 3.5.1).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn state(&self) -> Result<DeviceState> {
        self.client.read_state(Command::DevState(self.port)).await
    }

    /// `VALUE[p][index]?`: a scaled integer; out of range reads as `i32::MAX`/`i32::MIN`
    /// (manual 3.5.2).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn value(&self, index: u32) -> Result<i32> {
        self.client
            .read_int(Command::Value {
                port: self.port,
                index,
            })
            .await
    }

    /// `VALUEF[p][index]?`: in the device's unit; out of range reads as ±infinity (manual
    /// 3.5.2).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn value_f(&self, index: u32) -> Result<f64> {
        self.client
            .read_float(Command::ValueF {
                port: self.port,
                index,
            })
            .await
    }

    /// A gripper's finger position in µm (`VALUE[p][0]?`).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn position_um(&self) -> Result<i32> {
        self.value(0).await
    }

    /// A gripper's finger position in mm (`VALUEF[p][0]?`).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn position_mm(&self) -> Result<f64> {
        self.value_f(0).await
    }

    /// `GRIPCFG[p][index]?`: grip recipe `index`, scaled integers (manual 3.6.1).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn grip_config(&self, index: u32) -> Result<GripConfig> {
        self.client
            .read_grip_config(Command::GripCfg {
                port: self.port,
                index,
            })
            .await
    }

    /// `GRIPCFG[p][index]=[…]`: writes a recipe; returns what the controller reports back.
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_grip_config(&self, index: u32, config: &GripConfig) -> Result<GripConfig> {
        self.client
            .read_grip_config(Command::SetGripCfg {
                port: self.port,
                index,
                config: config.clone(),
            })
            .await
    }

    /// `GRIPCFGF[p][index]?`: grip recipe `index`, floats (manual 3.6.1).
    ///
    /// [Cancel-safe](super#cancellation): dropped, its reply is discarded when it comes.
    pub async fn grip_config_f(&self, index: u32) -> Result<GripConfigF> {
        self.client
            .read_grip_config_f(Command::GripCfgF {
                port: self.port,
                index,
            })
            .await
    }

    /// `GRIPCFGF[p][index]=[…]`: writes a recipe; returns what the controller reports back.
    ///
    /// [Cancel-safe](super#cancellation) for the connection; dropped after it was sent, the change
    /// still takes effect on the controller.
    pub async fn set_grip_config_f(&self, index: u32, config: &GripConfigF) -> Result<GripConfigF> {
        self.client
            .read_grip_config_f(Command::SetGripCfgF {
                port: self.port,
                index,
                config: config.clone(),
            })
            .await
    }
}
