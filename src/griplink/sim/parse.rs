//! The simulated controller's command parser: one line in, a typed [`Command`] or the status
//! code the controller would answer. Pure, total, never panics (fuzz targets call it).
//!
//! As the controller does (manual 2.1, 2.2): control characters 0x01–0x1F become spaces and the
//! line is trimmed (so a trailing CR is ignored), command names are case-insensitive, strings
//! may be in `'…'` or `"…"`, spaces around arguments are allowed (`SETVAL(0, 1, 42300)`).

use std::time::Duration;

use crate::griplink::command::{
    Blocking, Command, FlexGrip, FlexGripScaled, FlexRelease, FlexReleaseScaled, GripConfig,
    GripConfigF, PortNumber,
};
use crate::griplink::status::Status;
use crate::griplink::value::{Cursor, Value, MAX_TEXT_LEN};

/// The shape of a command line after its name and bracketed indices.
enum Form {
    /// `NAME[…]?`
    Query,
    /// `NAME[…]=value`
    Assign(Value),
    /// `NAME(args)`
    Call(Vec<Value>),
}

/// Replaces control characters by spaces and trims, as the controller does (manual 2.1).
pub fn clean_line(line: &str) -> String {
    line.chars()
        .map(|c| {
            if ('\u{1}'..='\u{1f}').contains(&c) {
                ' '
            } else {
                c
            }
        })
        .collect::<String>()
        .trim_matches(|c| c == ' ' || c == '\0')
        .to_owned()
}

fn split(line: &str) -> Result<(String, Vec<i64>, Form), Status> {
    let syntax = |_| Status::CmdSyntax;
    let mut c = Cursor::new(line);
    c.skip_spaces();
    let name = c.name().map_err(syntax)?.to_ascii_uppercase();
    let mut indices = Vec::new();
    loop {
        c.skip_spaces();
        if c.peek() != Some(b'[') {
            break;
        }
        if indices.len() == 2 {
            return Err(Status::CmdSyntax);
        }
        indices.push(c.index().map_err(syntax)?);
    }
    let form = match c.peek() {
        Some(b'?') => {
            c.eat(b'?');
            Form::Query
        }
        Some(b'=') => {
            c.eat(b'=');
            c.skip_spaces();
            Form::Assign(c.value().map_err(syntax)?)
        }
        Some(b'(') => {
            c.eat(b'(');
            let mut args = Vec::new();
            c.skip_spaces();
            if !c.eat(b')') {
                loop {
                    c.skip_spaces();
                    args.push(c.value().map_err(syntax)?);
                    c.skip_spaces();
                    if c.eat(b')') {
                        break;
                    }
                    c.expect(b',', "',' or ')'").map_err(syntax)?;
                }
            }
            Form::Call(args)
        }
        _ => {
            return Err(if is_known(&name) {
                Status::CmdSyntax
            } else {
                Status::CmdUnknown
            })
        }
    };
    c.skip_spaces();
    if !c.at_end() {
        return Err(Status::CmdSyntax);
    }
    Ok((name, indices, form))
}

const KNOWN: &[&str] = &[
    "ID",
    "PROTOCOL",
    "PROTASSERT",
    "SN",
    "LABEL",
    "VER",
    "VERBOSE",
    "DEVVID",
    "DEVPID",
    "DEVASSERT",
    "DEVNAME",
    "DEVVENDOR",
    "DEVSN",
    "DEVTAG",
    "DEVVER",
    "BYE",
    "ENABLE",
    "DISABLE",
    "HOME",
    "GRIP",
    "RELEASE",
    "FLEXGRIP",
    "FLEXGRIPF",
    "FLEXRELEASE",
    "FLEXRELEASEF",
    "LED",
    "CLAMP",
    "WSTR",
    "SETVAL",
    "SETVALF",
    "WAITVAL",
    "WAITVALF",
    "DEVSTATE",
    "VALUE",
    "VALUEF",
    "GRIPCFG",
    "GRIPCFGF",
];

fn is_known(name: &str) -> bool {
    KNOWN.contains(&name)
}

fn port(v: i64) -> Result<PortNumber, Status> {
    PortNumber::try_from(v).map_err(|_| Status::IndexOutOfBounds)
}

fn index(v: i64) -> Result<u32, Status> {
    u32::try_from(v).map_err(|_| Status::IndexOutOfBounds)
}

fn int(v: &Value) -> Result<i64, Status> {
    match v {
        Value::Int(i) => Ok(*i),
        // Digits too many for any integer: a value out of range, not a syntax error.
        Value::Float(f) if f.fract() == 0.0 && f.abs() >= 9.0e18 => Err(Status::RangeError),
        _ => Err(Status::CmdSyntax),
    }
}

fn int32(v: &Value) -> Result<i32, Status> {
    i32::try_from(int(v)?).map_err(|_| Status::RangeError)
}

fn uint32(v: &Value) -> Result<u32, Status> {
    u32::try_from(int(v)?).map_err(|_| Status::RangeError)
}

fn float(v: &Value) -> Result<f64, Status> {
    match v.as_f64() {
        Some(f) if f.is_finite() => Ok(f),
        Some(_) => Err(Status::RangeError),
        None => Err(Status::CmdSyntax),
    }
}

fn flag(v: &Value) -> Result<bool, Status> {
    match int(v)? {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(Status::InvalidParameter),
    }
}

fn text(v: &Value) -> Result<String, Status> {
    match v {
        Value::Str(s) if s.len() <= MAX_TEXT_LEN => Ok(s.clone()),
        Value::Str(_) => Err(Status::RangeError),
        _ => Err(Status::CmdSyntax),
    }
}

fn blocking(v: Option<&Value>) -> Result<Blocking, Status> {
    match v {
        None => Ok(Blocking::Immediate),
        Some(v) if flag(v)? => Ok(Blocking::UntilDone),
        Some(_) => Ok(Blocking::Immediate),
    }
}

fn millis(v: &Value) -> Result<Duration, Status> {
    u64::try_from(int(v)?)
        .map(Duration::from_millis)
        .map_err(|_| Status::InvalidParameter)
}

/// `[<tag>, 8 params]` (manual 3.6.1).
fn recipe(v: &Value) -> Result<(String, &[Value]), Status> {
    match v {
        Value::List(items) if items.len() == 9 => match items.split_first() {
            Some((tag, params)) => Ok((text(tag)?, params)),
            None => Err(Status::CmdSyntax),
        },
        Value::List(_) => Err(Status::InvalidParameter),
        _ => Err(Status::CmdSyntax),
    }
}

/// Parses one command line as the controller would. `Err` carries the status of the `ERR`
/// reply: [`Status::CmdUnknown`] for an unknown command, [`Status::CmdSyntax`] for a known one
/// written wrongly, [`Status::IndexOutOfBounds`] for a port or index that cannot exist,
/// [`Status::RangeError`] / [`Status::InvalidParameter`] for bad values.
pub fn parse_command(line: &str) -> Result<Command, Status> {
    let line = clean_line(line);
    let (name, idx, form) = split(&line)?;
    if !is_known(&name) {
        return Err(Status::CmdUnknown);
    }
    use Form::*;
    let cmd = match (name.as_str(), idx.as_slice(), &form) {
        ("ID", [], Query) => Command::Id,
        ("PROTOCOL", [], Query) => Command::Protocol,
        ("SN", [], Query) => Command::SerialNumber,
        ("LABEL", [], Query) => Command::Label,
        ("LABEL", [], Assign(v)) => Command::SetLabel(text(v)?),
        ("VER", [], Query) => Command::Version,
        ("VERBOSE", [], Assign(v)) => Command::SetVerbose(flag(v)?),
        ("DEVVID", [p], Query) => Command::DevVid(port(*p)?),
        ("DEVPID", [p], Query) => Command::DevPid(port(*p)?),
        ("DEVNAME", [p], Query) => Command::DevName(port(*p)?),
        ("DEVVENDOR", [p], Query) => Command::DevVendor(port(*p)?),
        ("DEVSN", [p], Query) => Command::DevSn(port(*p)?),
        ("DEVTAG", [p], Query) => Command::DevTag(port(*p)?),
        ("DEVTAG", [p], Assign(v)) => Command::SetDevTag(port(*p)?, text(v)?),
        ("DEVVER", [p], Query) => Command::DevVer(port(*p)?),
        ("WSTR", [p], Query) => Command::Wstr(port(*p)?),
        ("DEVSTATE", [p], Query) => Command::DevState(port(*p)?),
        ("VALUE", [p, i], Query) => Command::Value {
            port: port(*p)?,
            index: index(*i)?,
        },
        ("VALUEF", [p, i], Query) => Command::ValueF {
            port: port(*p)?,
            index: index(*i)?,
        },
        ("GRIPCFG", [p, i], Query) => Command::GripCfg {
            port: port(*p)?,
            index: index(*i)?,
        },
        ("GRIPCFGF", [p, i], Query) => Command::GripCfgF {
            port: port(*p)?,
            index: index(*i)?,
        },
        ("GRIPCFG", [p, i], Assign(v)) => {
            let (tag, values) = recipe(v)?;
            let mut params = [0i32; 8];
            for (slot, v) in params.iter_mut().zip(values) {
                *slot = int32(v)?;
            }
            Command::SetGripCfg {
                port: port(*p)?,
                index: index(*i)?,
                config: GripConfig { tag, params },
            }
        }
        ("GRIPCFGF", [p, i], Assign(v)) => {
            let (tag, values) = recipe(v)?;
            let mut params = [0f64; 8];
            for (slot, v) in params.iter_mut().zip(values) {
                *slot = float(v)?;
            }
            Command::SetGripCfgF {
                port: port(*p)?,
                index: index(*i)?,
                config: GripConfigF { tag, params },
            }
        }
        (_, [], Call(args)) => call(&name, args)?,
        _ => return Err(Status::CmdSyntax),
    };
    Ok(cmd)
}

fn call(name: &str, args: &[Value]) -> Result<Command, Status> {
    let cmd = match (name, args) {
        ("BYE", []) => Command::Bye,
        ("PROTASSERT", [id, v]) => Command::ProtAssert {
            identifier: text(id)?,
            min_version: uint32(v)?,
        },
        ("DEVASSERT", [p, vid, pid]) => Command::DevAssert {
            port: port(int(p)?)?,
            vendor_id: uint32(vid)?,
            product_id: uint32(pid)?,
        },
        ("ENABLE", [p]) => Command::Enable(port(int(p)?)?),
        ("DISABLE", [p]) => Command::Disable(port(int(p)?)?),
        ("HOME", [p]) => Command::Home(port(int(p)?)?),
        ("GRIP", [p, i, rest @ ..]) | ("RELEASE", [p, i, rest @ ..]) if rest.len() <= 1 => {
            let (port, index, blocking) =
                (port(int(p)?)?, index(int(i)?)?, blocking(rest.first())?);
            if name == "GRIP" {
                Command::Grip {
                    port,
                    index,
                    blocking,
                }
            } else {
                Command::Release {
                    port,
                    index,
                    blocking,
                }
            }
        }
        ("FLEXGRIP", [p, pos, force, speed, acc, rest @ ..]) if rest.len() <= 1 => {
            Command::FlexGrip(
                port(int(p)?)?,
                FlexGripScaled {
                    position_um: int32(pos)?,
                    force_mn: int32(force)?,
                    speed_um_per_s: int32(speed)?,
                    acceleration_um_per_s2: int32(acc)?,
                },
                blocking(rest.first())?,
            )
        }
        ("FLEXGRIPF", [p, pos, force, speed, acc, rest @ ..]) if rest.len() <= 1 => {
            Command::FlexGripF(
                port(int(p)?)?,
                FlexGrip {
                    position_mm: float(pos)?,
                    force_n: float(force)?,
                    speed_mm_per_s: float(speed)?,
                    acceleration_mm_per_s2: float(acc)?,
                },
                blocking(rest.first())?,
            )
        }
        // Errata: FLEXRELEASE's syntax line shows four parameters, its examples a fifth.
        ("FLEXRELEASE", [p, pos, speed, acc, rest @ ..]) if rest.len() <= 1 => {
            Command::FlexRelease(
                port(int(p)?)?,
                FlexReleaseScaled {
                    position_um: int32(pos)?,
                    speed_um_per_s: int32(speed)?,
                    acceleration_um_per_s2: int32(acc)?,
                },
                blocking(rest.first())?,
            )
        }
        ("FLEXRELEASEF", [p, pos, speed, acc, rest @ ..]) if rest.len() <= 1 => {
            Command::FlexReleaseF(
                port(int(p)?)?,
                FlexRelease {
                    position_mm: float(pos)?,
                    speed_mm_per_s: float(speed)?,
                    acceleration_mm_per_s2: float(acc)?,
                },
                blocking(rest.first())?,
            )
        }
        ("LED", [p, i]) => Command::Led {
            port: port(int(p)?)?,
            index: index(int(i)?)?,
        },
        ("CLAMP", [p, on]) => Command::Clamp {
            port: port(int(p)?)?,
            enable: flag(on)?,
        },
        ("SETVAL", [p, i, v]) => Command::SetVal {
            port: port(int(p)?)?,
            index: index(int(i)?)?,
            value: int32(v)?,
        },
        ("SETVALF", [p, i, v]) => Command::SetValF {
            port: port(int(p)?)?,
            index: index(int(i)?)?,
            value: float(v)?,
        },
        ("WAITVAL", [p, i, t, w, ms]) => Command::WaitVal {
            port: port(int(p)?)?,
            index: index(int(i)?)?,
            threshold: int32(t)?,
            window: int32(w)?,
            timeout: millis(ms)?,
        },
        ("WAITVALF", [p, i, t, w, ms]) => Command::WaitValF {
            port: port(int(p)?)?,
            index: index(int(i)?)?,
            threshold: float(t)?,
            window: float(w)?,
            timeout: millis(ms)?,
        },
        _ => return Err(Status::CmdSyntax),
    };
    Ok(cmd)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_spellings() {
        assert_eq!(parse_command("ID?\r"), Ok(Command::Id));
        assert_eq!(parse_command("grip(0,1)"), parse_command("GRIP(0,1)"));
        assert_eq!(parse_command("gRiP(0,1)"), parse_command("GRIP(0,1,0)"));
        assert_eq!(
            parse_command("SETVAL(0, 1, 42300)"),
            Ok(Command::SetVal {
                port: 0,
                index: 1,
                value: 42300
            })
        );
        assert_eq!(
            parse_command("LABEL='Marvin'"),
            Ok(Command::SetLabel("Marvin".into()))
        );
        assert_eq!(parse_command("DEVVER [3]?"), Ok(Command::DevVer(3)));
        assert!(matches!(
            parse_command("FLEXRELEASEF(2,19.5,0,0,1)"),
            Ok(Command::FlexReleaseF(2, _, Blocking::UntilDone))
        ));
        assert!(matches!(
            parse_command("GRIPCFGF[1][0]=[\"tube\",3.5,10.8,50,0,0,0,0,0]"),
            Ok(Command::SetGripCfgF {
                port: 1,
                index: 0,
                ..
            })
        ));
    }

    #[test]
    fn errors_are_the_controllers() {
        assert_eq!(parse_command("FOO?"), Err(Status::CmdUnknown));
        assert_eq!(parse_command("FOO(1)"), Err(Status::CmdUnknown));
        assert_eq!(parse_command("GRIP(0)"), Err(Status::CmdSyntax));
        assert_eq!(parse_command("GRIP"), Err(Status::CmdSyntax));
        assert_eq!(parse_command("ID? x"), Err(Status::CmdSyntax));
        assert_eq!(
            parse_command("DEVSTATE[300]?"),
            Err(Status::IndexOutOfBounds)
        );
        assert_eq!(
            parse_command("DEVSTATE[-1]?"),
            Err(Status::IndexOutOfBounds)
        );
        assert_eq!(
            parse_command(&format!("LABEL=\"{}\"", "x".repeat(33))),
            Err(Status::RangeError)
        );
        assert_eq!(parse_command("VERBOSE=2"), Err(Status::InvalidParameter));
        assert_eq!(parse_command("SETVALF(0,0,1e5)"), Err(Status::CmdSyntax));
        assert_eq!(parse_command(""), Err(Status::CmdSyntax));
        assert_eq!(parse_command("\u{7f}"), Err(Status::CmdSyntax));
    }

    #[test]
    fn control_characters_become_spaces() {
        assert_eq!(parse_command("\tHOME(0)\r"), Ok(Command::Home(0)));
        assert_eq!(clean_line("A\x01B\r"), "A B");
    }
}
