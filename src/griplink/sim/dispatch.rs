//! Command dispatch: what the simulated controller does with each command of chapter 3.

use std::time::Duration;

use super::controller::Controller;
use super::device::{mm_text, um};
use super::reply::{ack, error_line, reply, Outcome, Session, Step};
use crate::griplink::command::{Command, GripConfig, GripConfigF, PortNumber};
use crate::griplink::state::DeviceState;
use crate::griplink::status::Status;

impl Controller {
    /// Executes one command at time `now` for a connection with `session`.
    pub fn execute(&mut self, session: &mut Session, command: &Command, now: Duration) -> Outcome {
        self.advance(now);
        match self.run(session, command, now) {
            Ok(outcome) => outcome,
            Err(status) => Outcome::Reply(error_line(status, session.verbose)),
        }
    }

    fn run(&mut self, session: &mut Session, command: &Command, now: Duration) -> Step {
        use Command::*;
        match command {
            Id => reply(format!("ID=\"{}\"", self.config.id)),
            Protocol => reply(format!(
                "PROTOCOL=\"GRIPLINK-V{}\"",
                self.config.protocol_version
            )),
            ProtAssert {
                identifier,
                min_version,
            } => {
                if identifier.eq_ignore_ascii_case("GRIPLINK")
                    && *min_version <= self.config.protocol_version
                {
                    ack()
                } else {
                    Err(Status::NotSupported)
                }
            }
            SerialNumber => reply(format!("SN=\"{}\"", self.config.serial_number)),
            Label => reply(format!("LABEL=\"{}\"", self.label)),
            SetLabel(label) => {
                self.label = label.clone();
                reply(format!("LABEL=\"{}\"", self.label))
            }
            Version => reply(format!("VER=\"{}\"", self.config.version)),
            SetVerbose(on) => {
                session.verbose = *on;
                reply(format!("VERBOSE={}", u8::from(*on)))
            }
            DevVid(p) => {
                let i = self.port(*p)?;
                let vid = self
                    .ports
                    .get(i)
                    .and_then(|s| s.device.as_ref())
                    .map_or(-1, |d| i64::from(d.vendor_id));
                reply(format!("DEVVID[{p}]={vid}"))
            }
            DevPid(p) => reply(format!("DEVPID[{p}]={}", self.device(*p)?.1.product_id)),
            DevAssert {
                port,
                vendor_id,
                product_id,
            } => {
                self.port(*port)?;
                match self.device(*port) {
                    Ok((_, d)) if d.vendor_id == *vendor_id && d.product_id == *product_id => ack(),
                    _ => Err(Status::CmdFailed),
                }
            }
            DevName(p) => reply(format!("DEVNAME[{p}]=\"{}\"", self.device(*p)?.1.name)),
            DevVendor(p) => reply(format!("DEVVENDOR[{p}]=\"{}\"", self.device(*p)?.1.vendor)),
            DevSn(p) => reply(format!(
                "DEVSN[{p}]=\"{}\"",
                self.device(*p)?.1.serial_number
            )),
            DevVer(p) => reply(format!("DEVVER[{p}]=\"{}\"", self.device(*p)?.1.version)),
            DevTag(p) => {
                let (i, _) = self.device(*p)?;
                reply(format!("DEVTAG[{p}]=\"{}\"", self.port_sim(i)?.tag))
            }
            SetDevTag(p, tag) => {
                let (i, _) = self.device(*p)?;
                self.port_sim(i)?.tag = tag.clone();
                reply(format!("DEVTAG[{p}]=\"{tag}\""))
            }
            Bye => Ok(Outcome::Bye),
            Enable(p) => self.enable(*p),
            Disable(p) => {
                let (i, _) = self.device(*p)?;
                let port = self.port_sim(i)?;
                port.transitions.command();
                port.abort_motion();
                port.actuator_on = false;
                if port.state() != DeviceState::NotInitialized {
                    port.set_state(DeviceState::Disabled);
                }
                ack()
            }
            Home(p) => self.home(*p, now),
            Grip {
                port,
                index,
                blocking,
            } => {
                let (_, r) = self.recipe(*port, *index)?;
                let (limit, speed) = (i64::from(r.params[0]), f64::from(r.params[3]));
                self.grip(*port, limit, speed, *blocking, true, now)
            }
            Release {
                port,
                index,
                blocking,
            } => {
                let (_, r) = self.recipe(*port, *index)?;
                let (limit, speed) = (i64::from(r.params[1]), f64::from(r.params[5]));
                self.release(*port, limit, speed, *blocking, true, now)
            }
            FlexGrip(p, a, b) => {
                if a.force_mn < 0 || a.speed_um_per_s < 0 || a.acceleration_um_per_s2 < 0 {
                    return Err(Status::RangeError);
                }
                let speed = f64::from(a.speed_um_per_s);
                self.grip(*p, i64::from(a.position_um), speed, *b, false, now)
            }
            FlexGripF(p, a, b) => {
                if a.force_n < 0.0 || a.speed_mm_per_s < 0.0 || a.acceleration_mm_per_s2 < 0.0 {
                    return Err(Status::RangeError);
                }
                let speed = a.speed_mm_per_s * 1000.0;
                self.grip(*p, um(a.position_mm), speed, *b, false, now)
            }
            FlexRelease(p, a, b) => {
                if a.speed_um_per_s < 0 || a.acceleration_um_per_s2 < 0 {
                    return Err(Status::RangeError);
                }
                let speed = f64::from(a.speed_um_per_s);
                self.release(*p, i64::from(a.position_um), speed, *b, false, now)
            }
            FlexReleaseF(p, a, b) => {
                if a.speed_mm_per_s < 0.0 || a.acceleration_mm_per_s2 < 0.0 {
                    return Err(Status::RangeError);
                }
                let speed = a.speed_mm_per_s * 1000.0;
                self.release(*p, um(a.position_mm), speed, *b, false, now)
            }
            Led { port, index } => {
                let (i, _) = self.device(*port)?;
                self.port_sim(i)?.led = *index;
                ack()
            }
            Clamp { port, enable } => {
                let (i, _) = self.device(*port)?;
                let p = self.port_sim(i)?;
                // Weiss grippers: controlled by hand only while disabled (3.4.9).
                if p.actuator_on {
                    return Err(Status::StateConflict);
                }
                p.clamp = *enable;
                ack()
            }
            Wstr(p) => self.wstr(*p, now),
            SetVal { port, index, value } => self.set_value(*port, *index, i64::from(*value), now),
            SetValF { port, index, value } => self.set_value(*port, *index, um(*value), now),
            WaitVal {
                port,
                index,
                threshold,
                window,
                timeout,
            } => self.wait_value(
                *port,
                *index,
                f64::from(*threshold),
                f64::from(*window),
                *timeout,
                now,
            ),
            WaitValF {
                port,
                index,
                threshold,
                window,
                timeout,
            } => self.wait_value(
                *port,
                *index,
                threshold * 1000.0,
                window * 1000.0,
                *timeout,
                now,
            ),
            DevState(p) => {
                let i = self.port(*p)?;
                let state = self.port_sim(i)?.state();
                reply(format!("DEVSTATE[{p}]={}", state.code()))
            }
            Value { port, index } | ValueF { port, index } => {
                let (i, _) = self.device(*port)?;
                if *index != 0 {
                    return Err(Status::IndexOutOfBounds);
                }
                let pos = self.port_sim(i)?.position_um;
                if matches!(command, ValueF { .. }) {
                    reply(format!("VALUEF[{port}][{index}]={}", mm_text(pos)))
                } else {
                    let pos = pos.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
                    reply(format!("VALUE[{port}][{index}]={pos}"))
                }
            }
            GripCfg { port, index } => reply(self.recipe_line(*port, *index, false)?),
            GripCfgF { port, index } => reply(self.recipe_line(*port, *index, true)?),
            SetGripCfg {
                port,
                index,
                config,
            } => {
                self.set_recipe(*port, *index, config.clone())?;
                reply(self.recipe_line(*port, *index, false)?)
            }
            SetGripCfgF {
                port,
                index,
                config,
            } => {
                let scaled = scale_recipe(config)?;
                self.set_recipe(*port, *index, scaled)?;
                reply(self.recipe_line(*port, *index, true)?)
            }
        }
    }

    /// `ENABLE(p)` on a Weiss gripper (3.4.1, chapter 5): powers the actuator; a gripper in
    /// `DS_FAULT` is re-enabled into state 2, idle. State 6 (`DS_ENABLED`) is for sensors.
    fn enable(&mut self, port: PortNumber) -> Step {
        let (i, _) = self.device(port)?;
        let p = self.port_sim(i)?;
        if p.state() == DeviceState::NotInitialized {
            return Err(Status::NotInitialized);
        }
        p.transitions.command();
        p.actuator_on = true;
        if matches!(p.state(), DeviceState::Fault | DeviceState::Disabled) {
            p.set_state(DeviceState::Disabled);
        }
        ack()
    }

    fn recipe(&self, port: PortNumber, index: u32) -> Result<(usize, &GripConfig), Status> {
        let (i, _) = self.device(port)?;
        self.ports
            .get(i)
            .and_then(|p| p.recipes.get(index as usize))
            .map(|r| (i, r))
            .ok_or(Status::IndexOutOfBounds)
    }

    fn recipe_line(&self, port: PortNumber, index: u32, float: bool) -> Result<String, Status> {
        let (_, r) = self.recipe(port, index)?;
        let key = if float { "GRIPCFGF" } else { "GRIPCFG" };
        let mut line = format!("{key}[{port}][{index}]=[\"{}\"", r.tag);
        for p in r.params {
            line.push(',');
            if float {
                line.push_str(&mm_text(i64::from(p)));
            } else {
                line.push_str(&p.to_string());
            }
        }
        line.push(']');
        Ok(line)
    }

    fn set_recipe(
        &mut self,
        port: PortNumber,
        index: u32,
        config: GripConfig,
    ) -> Result<(), Status> {
        let (i, device) = self.device(port)?;
        let stroke = device.stroke_um();
        let p = config.params;
        let in_stroke = |v: i32| (0..=stroke).contains(&i64::from(v));
        if !in_stroke(p[0]) || !in_stroke(p[1]) || !(0..=100_000).contains(&p[2]) {
            return Err(Status::RangeError);
        }
        if p[3..].iter().any(|v| *v < 0) {
            return Err(Status::RangeError);
        }
        let slot = self
            .port_sim(i)?
            .recipes
            .get_mut(index as usize)
            .ok_or(Status::IndexOutOfBounds)?;
        *slot = config;
        Ok(())
    }
}

fn scale_recipe(config: &GripConfigF) -> Result<GripConfig, Status> {
    let mut params = [0i32; 8];
    for (slot, v) in params.iter_mut().zip(config.params) {
        *slot = i32::try_from(um(v)).map_err(|_| Status::RangeError)?;
    }
    Ok(GripConfig {
        tag: config.tag.clone(),
        params,
    })
}
