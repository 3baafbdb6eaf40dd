//! The simulator's text mode: GCL (the WSG's text interface) served from the same [`Device`]
//! as the binary protocol — one motion model, one state — following the reading of the shared
//! note `WSG-TEXT-INTERFACE.md` §6 (cited as §).
//!
//! Each GCL command is carried out by the binary command that does the same on the device
//! model (HOME → homing, MOVE → pre-position, GRIP → grasp, RELEASE → release to the current
//! width plus the pull-back, STOP, FASTSTOP, FSACK → 0x22–0x24, BYE → announce disconnect
//! 0x07, AUTOSEND → the auto-update streams of 0x41–0x45), and the binary replies are written
//! as GCL: `E_CMD_PENDING` → `ACK <NAME>`, the final `E_SUCCESS` → `FIN <NAME>`, any other code
//! → `ERR <NAME> <code>` (with the symbol after it in verbose mode). Queries read the model.
//!
//! Choices where no source says (all [G] in the note): a second motion while one runs is
//! refused with `ERR <NAME> 4` (E_ALREADY_RUNNING, no ACK); a line that is no GCL answers
//! `ERR <NAME> 15` (E_CMD_FORMAT_ERROR), an unknown command (`GETSTATE()` among them)
//! `ERR <NAME> 14`, a line over 256 bytes `ERR ? 27` (E_OVERRUN); GRIP while HOLDING and
//! RELEASE without a grip answer `ERR <NAME> 16`; `MOVE` without a speed and `GRIP` without
//! one use half the model's top speed; `RELEASE()` pulls back 10 mm; a connection starts with
//! PWT = twice the simulated part's tolerance (10 mm without a part) and CLT = twice
//! [`SimConfig::clamping_travel_mm`]; AUTOSEND names POS, SPEED, FORCE
//! and GRIPSTATE (TEMP is constant in the simulator and is refused with `ERR AUTOSEND 5`),
//! interval 0 stops, below 10 ms runs at 10 ms; a line cut off by the end of the stream (no LF)
//! is not a command and is not run (`MOVE(10` of a `MOVE(100)` whose connection broke).
//!
//! With [`SimServer::start_recording`](super::SimServer::start_recording) every line a text
//! session sends and gets is recorded ([`SimEvent::TextRequest`](super::SimEvent::TextRequest),
//! [`SimEvent::TextReply`](super::SimEvent::TextReply)), for a test's oracle.
//!
//! Not modelled: E_AXIS_BLOCKED (a contact before the tolerance zone) is never reported. The
//! injected
//! reply faults of [`SimServer`](super::SimServer) (drop, corrupt, delay, force a status) act on
//! binary sessions only: use the fault proxy (`crate::fault`) for a text session's wire.

mod parse;

use self::parse::{parse, Arg, Form, Line};
use super::device::{Device, Out, SessionId};
use super::model::{Part, SimConfig};
use crate::wsg::command::{id, Command, HomingDirection, UpdateMode};
use crate::wsg::frame::Decoded;
use crate::wsg::{GripState, Reply, Status};

/// The longest command line the simulator reads, bytes (§6.2).
pub(crate) const MAX_LINE_LEN: usize = 256;

/// The pull-back of a `RELEASE()` without arguments, mm (the web interface's setting, [G]).
const DEFAULT_PULL_BACK_MM: f32 = 10.0;

/// The part width tolerance a connection starts with when the simulator has no part, mm (a
/// web-interface setting, [G]); with a part, twice its tolerance, so that text and binary grasps
/// find it alike.
const DEFAULT_PWT_MM: f32 = 10.0;

/// What one command line produces, in order.
#[derive(Debug)]
pub(crate) enum Emit {
    /// A line for the session that sent the command.
    Line(String),
    /// A binary reply to route (to this or another session; a text session gets it through
    /// [`TextSession::translate`]).
    Out(Out),
}

/// One GCL connection's own state: VERBOSE, PWT and CLT last for the connection (manual
/// chapter 2 for PWT and CLT; per connection for VERBOSE is our reading).
#[derive(Debug)]
pub(crate) struct TextSession {
    verbose: bool,
    pwt_mm: f32,
    clt_mm: f32,
}

fn fmt1(v: f32) -> String {
    // One decimal, as the manual's examples (`POS=20.0`); never an exponent.
    format!("{v:.1}")
}

fn motion_name(id: u8) -> Option<&'static str> {
    match id {
        id::HOMING => Some("HOME"),
        id::PRE_POSITION => Some("MOVE"),
        id::GRASP => Some("GRIP"),
        id::RELEASE => Some("RELEASE"),
        _ => None,
    }
}

fn push_name(id: u8) -> Option<&'static str> {
    match id {
        id::WIDTH => Some("POS"),
        id::SPEED => Some("SPEED"),
        id::FORCE => Some("FORCE"),
        id::GRIP_STATE => Some("GRIPSTATE"),
        _ => None,
    }
}

impl TextSession {
    pub(crate) fn new(cfg: &SimConfig) -> Self {
        // PWT and CLT are whole widths around the nominal one (figure 5 marks PWT/2 and
        // CLT/2); the simulator's tolerance and clamping travel are the halves.
        TextSession {
            verbose: false,
            pwt_mm: cfg.part.map_or(DEFAULT_PWT_MM, |p| 2.0 * p.tolerance_mm),
            clt_mm: 2.0 * cfg.clamping_travel_mm,
        }
    }

    fn err(&self, name: &str, status: Status) -> String {
        if self.verbose {
            format!("ERR {name} {} {}", status.code(), status.symbol())
        } else {
            format!("ERR {name} {}", status.code())
        }
    }

    /// A binary reply for this session that came later than its command (a motion's final
    /// reply, E_CMD_ABORTED, an auto-update), as a GCL line.
    pub(crate) fn translate(&self, reply: &Reply) -> Option<String> {
        if let Some(name) = motion_name(reply.id) {
            return Some(match reply.status {
                Status::Success => format!("FIN {name}"),
                Status::CmdPending => format!("ACK {name}"),
                other => self.err(name, other),
            });
        }
        let name = push_name(reply.id)?;
        if reply.status != Status::Success {
            return None;
        }
        let value = if reply.id == id::GRIP_STATE {
            reply.data.first()?.to_string()
        } else {
            fmt1(crate::wsg::types::decode_f32(&reply.data).ok()?)
        };
        Some(format!("@{name}={value}"))
    }

    /// Handles one command line at simulated time `now` (wall clock `wall`, for auto-updates).
    /// `line` is `None` for a line over [`MAX_LINE_LEN`].
    pub(crate) fn handle(
        &mut self,
        device: &mut Device,
        now: f64,
        wall: f64,
        session: SessionId,
        line: Option<&str>,
    ) -> Vec<Emit> {
        // What finished before this line first, so the command's own replies are told apart.
        let mut emit: Vec<Emit> = device.advance(now).into_iter().map(Emit::Out).collect();
        let Some(line) = line else {
            emit.push(Emit::Line(self.err("?", Status::Overrun)));
            return emit;
        };
        let parsed = match parse(line) {
            Ok(parsed) => parsed,
            Err(bad) => {
                emit.push(Emit::Line(self.err(&bad.name, bad.status)));
                return emit;
            }
        };
        // After BYE() the binary device refuses everything with E_ACCESS_DENIED (§6.2), also
        // what is answered here without it.
        if device.announced(session) {
            emit.push(Emit::Line(self.err(&parsed.name, Status::AccessDenied)));
            return emit;
        }
        self.command(device, now, wall, session, parsed, &mut emit);
        emit
    }

    /// Runs a binary command on the device: its immediate reply is returned, everything else it
    /// caused (an aborted motion's reply) is emitted.
    fn run(
        device: &mut Device,
        now: f64,
        wall: f64,
        session: SessionId,
        cmd: Command,
        emit: &mut Vec<Emit>,
    ) -> Status {
        let cmd_id = cmd.id();
        let mut status = Status::CmdUnknown;
        for out in device.handle_at(now, Some(wall), session, &Decoded::Frame(cmd.to_frame())) {
            if out.session == session && out.reply.id == cmd_id {
                status = out.reply.status;
            } else {
                emit.push(Emit::Out(out));
            }
        }
        status
    }

    /// `GRIP(…)` on the binary grasp. Where GCL decides differently from a binary grasp, the
    /// simulator's part and clamping travel are set for this one grasp (its outcome is fixed
    /// when it starts) and restored at once:
    /// - `GRIP()`/`GRIP(f)` grip inward until something is found: the part if one lies inward,
    ///   else the fingers themselves at 0 mm, and the state is HOLDING either way (manual
    ///   chapter 2);
    /// - `GRIP(f,w[,v])` finds its part within this connection's part width tolerance around `w`
    ///   (±PWT/2) and travels CLT/2 past `w` before reporting no part (manual chapter 2,
    ///   figure 5).
    fn grip(
        &self,
        device: &mut Device,
        args: &[f64],
        default_speed: f32,
        run: &mut impl FnMut(&mut Device, Command) -> Status,
    ) -> Status {
        let here = device.width_mm();
        let saved = (device.cfg.part, device.cfg.clamping_travel_mm);
        let width_mm = match args.get(1) {
            Some(w) => {
                if let Some(part) = &mut device.cfg.part {
                    part.tolerance_mm = self.pwt_mm / 2.0;
                }
                device.cfg.clamping_travel_mm = self.clt_mm / 2.0;
                *w as f32
            }
            None => {
                let inward = saved.0.map(|p| p.width_mm).filter(|w| *w <= here);
                let found_at = inward.unwrap_or(0.0);
                device.cfg.part = Some(Part {
                    width_mm: found_at,
                    tolerance_mm: 0.0,
                });
                found_at
            }
        };
        let speed_mm_per_s = args.get(2).map_or(default_speed, |v| *v as f32);
        // The force of this grip (clamped to the model's range like 0x32), set before the
        // grasp starts: set after it, the command ran the device up to now, which ended an
        // instant grasp at once, and its `FIN GRIP` was written before its `ACK GRIP`
        // (`wsg-text:0x53236ba78b027b2d`; the manual: `ACK` at once, `FIN` when done). A grasp
        // refused keeps the force the gripper had.
        let force_before = device.force_limit;
        if let Some(force) = args.first() {
            let _ = run(device, Command::SetForce(*force as f32));
        }
        let status = run(
            device,
            Command::Grasp {
                width_mm,
                speed_mm_per_s,
            },
        );
        (device.cfg.part, device.cfg.clamping_travel_mm) = saved;
        if status != Status::CmdPending {
            device.force_limit = force_before;
        }
        status
    }

    fn command(
        &mut self,
        device: &mut Device,
        now: f64,
        wall: f64,
        session: SessionId,
        line: Line,
        emit: &mut Vec<Emit>,
    ) {
        let Line { name, form } = line;
        let nums: Option<Vec<f64>> = match &form {
            Form::Call(args) => args.iter().map(Arg::num).collect(),
            _ => None,
        };
        let default_speed = device.cfg.limits.max_speed_mm_per_s / 2.0;
        let mut run = |device: &mut Device, cmd| Self::run(device, now, wall, session, cmd, emit);
        // The reply of a command answered at once: `ok` on E_SUCCESS.
        let ack = |s: &Self, status: Status| match status {
            Status::Success => format!("ACK {name}"),
            other => s.err(&name, other),
        };
        // A motion: `ACK` on E_CMD_PENDING; its FIN or ERR comes later through `translate`.
        let motion = |s: &Self, status: Status| match status {
            Status::CmdPending => format!("ACK {name}"),
            other => s.err(&name, other),
        };
        let line = match (name.as_str(), &form, nums.as_deref()) {
            // `ACK FSACK` also with nothing pending (§3.7, [H]).
            ("FSACK", _, Some([])) => ack(self, run(device, Command::AckFastStop)),
            ("FASTSTOP", _, Some([])) => ack(self, run(device, Command::FastStop)),
            ("STOP", _, Some([])) => ack(self, run(device, Command::Stop)),
            ("BYE", _, Some([])) => ack(self, run(device, Command::AnnounceDisconnect)),
            ("HOME", _, Some(args)) if args.len() <= 1 => {
                // GCL: 1 = positive, 0 = negative (manual chapter 2; binary: 1 and 2).
                let dir = match args.first() {
                    None => Some(HomingDirection::Default),
                    Some(v) if *v == 1.0 => Some(HomingDirection::Positive),
                    Some(v) if *v == 0.0 => Some(HomingDirection::Negative),
                    Some(_) => None,
                };
                match dir {
                    Some(dir) => motion(self, run(device, Command::Homing(dir))),
                    None => self.err(&name, Status::RangeError),
                }
            }
            ("MOVE", _, Some(args)) if (1..=2).contains(&args.len()) => {
                let cmd = Command::PrePosition {
                    relative: false,
                    stop_on_block: true,
                    width_mm: args[0] as f32,
                    speed_mm_per_s: args.get(1).map_or(default_speed, |v| *v as f32),
                };
                motion(self, run(device, cmd))
            }
            ("GRIP", _, Some(args)) if args.len() <= 3 => {
                if device.grip == GripState::Holding {
                    // "It is not possible to send a grip command while holding a part."
                    self.err(&name, Status::AccessDenied)
                } else {
                    let status = self.grip(device, args, default_speed, &mut run);
                    motion(self, status)
                }
            }
            ("RELEASE", _, Some(args)) if args.len() <= 2 => {
                let gripped = matches!(
                    device.grip,
                    GripState::Holding | GripState::NoPartFound | GripState::PartLost
                );
                if !gripped && device.motion.is_none() {
                    // "Release commands are only allowed if the gripper has gripped a part
                    // before" (manual chapter 2).
                    self.err(&name, Status::AccessDenied)
                } else {
                    // Relative to where the fingers are (manual chapter 2).
                    let pull_back = args.first().map_or(DEFAULT_PULL_BACK_MM, |d| *d as f32);
                    let cmd = Command::Release {
                        width_mm: device.width_mm() + pull_back,
                        speed_mm_per_s: args.get(1).map_or(default_speed, |v| *v as f32),
                    };
                    motion(self, run(device, cmd))
                }
            }
            ("VERBOSE", Form::Set(Arg::Num(v)), _) if *v == 0.0 || *v == 1.0 => {
                self.verbose = *v == 1.0;
                format!("VERBOSE={}", u8::from(self.verbose))
            }
            ("VERBOSE", Form::Query, _) => format!("VERBOSE={}", u8::from(self.verbose)),
            ("PWT" | "CLT", Form::Set(Arg::Num(v)), _) if *v >= 0.0 && (*v as f32).is_finite() => {
                let slot = if name == "PWT" {
                    &mut self.pwt_mm
                } else {
                    &mut self.clt_mm
                };
                *slot = *v as f32;
                format!("{name}={}", fmt1(*slot))
            }
            ("PWT", Form::Query, _) => format!("PWT={}", fmt1(self.pwt_mm)),
            ("CLT", Form::Query, _) => format!("CLT={}", fmt1(self.clt_mm)),
            ("POS", Form::Query, _) => format!("POS={}", fmt1(device.width_mm())),
            ("SPEED", Form::Query, _) => format!("SPEED={}", fmt1(device.speed_mm_per_s())),
            ("FORCE", Form::Query, _) => {
                let force = if device.grip == GripState::Holding {
                    device.force_limit
                } else {
                    0.0
                };
                format!("FORCE={}", fmt1(force))
            }
            ("GRIPSTATE", Form::Query, _) => format!("GRIPSTATE={}", device.grip.to_u8()),
            ("TEMP", Form::Query, _) => format!("TEMP={}", fmt1(device.cfg.temperature_c)),
            ("AUTOSEND", Form::Call(args), _) => match autosend_args(args) {
                Err(status) => self.err(&name, status),
                Ok((push_id, period_ms, on_change)) => {
                    emit.push(Emit::Line(format!("ACK {name}")));
                    if period_ms == 0 {
                        device.sessions.stop_stream(session, push_id);
                    } else {
                        let mode = UpdateMode {
                            auto: true,
                            on_change,
                            period_ms,
                        };
                        // The value at once, then every period (§6.2).
                        emit.push(Emit::Out(device.auto_update(session, push_id, mode, wall)));
                    }
                    return;
                }
            },
            // Known names in another form or with other arguments.
            (
                "FSACK" | "FASTSTOP" | "STOP" | "BYE" | "HOME" | "MOVE" | "GRIP" | "RELEASE"
                | "VERBOSE" | "PWT" | "CLT" | "POS" | "SPEED" | "FORCE" | "GRIPSTATE" | "TEMP",
                _,
                _,
            ) => self.err(&name, Status::CmdFormatError),
            // Anything else, `GETSTATE()` among them (§3.9).
            _ => self.err(&name, Status::CmdUnknown),
        };
        emit.push(Emit::Line(line));
    }
}

/// `AUTOSEND("NAME",ms[,flag])`: the binary auto-update id, the period (0 = off) and whether
/// only changes are sent (§3.10, our reading).
fn autosend_args(args: &[Arg]) -> Result<(u8, u16, bool), Status> {
    let (what, ms, flag) = match args {
        [Arg::Str(what), Arg::Num(ms)] => (what, *ms, false),
        [Arg::Str(what), Arg::Num(ms), Arg::Bool(flag)] => (what, *ms, *flag),
        _ => return Err(Status::CmdFormatError),
    };
    let push_id = match what.to_ascii_uppercase().as_str() {
        "POS" => id::WIDTH,
        "SPEED" => id::SPEED,
        "FORCE" => id::FORCE,
        "GRIPSTATE" => id::GRIP_STATE,
        // Constant in the simulator: nothing to stream.
        "TEMP" => return Err(Status::FeatureNotSupported),
        _ => return Err(Status::InvalidParameter),
    };
    if !(0.0..=65535.0).contains(&ms) || ms.fract() != 0.0 {
        return Err(Status::RangeError);
    }
    Ok((push_id, ms as u16, flag))
}
