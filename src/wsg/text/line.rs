//! Pure encoding of GCL command lines and parsing of reply lines: no I/O.
//!
//! Reply forms (shared note `WSG-TEXT-INTERFACE.md` §3, §4): `ACK <NAME>`, `FIN <NAME>`,
//! `ERR <NAME> <code>[ <text>]`, `<NAME>=<value>` and the pushes `@<NAME>=<value>`. `<NAME>` is
//! the bare command name, upper case, without arguments (pinned by a hardware-run client that
//! compares it with the command it sent, §3).

use std::fmt::Write as _;

/// The longest line the client sends or accepts by default, in bytes without the LF. The manual
/// text we have gives no limit (§6.1 item 7); public clients read with buffers of 20 to 4096
/// bytes, and the simulator refuses command lines over 256 bytes (§6.2).
pub const DEFAULT_MAX_LINE_LEN: usize = 256;

/// One reply line, borrowed from the received text.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplyLine<'a> {
    /// `ACK <NAME>`: the command was accepted (a motion then runs until its `FIN` or `ERR`).
    Ack(&'a str),
    /// `FIN <NAME>`: a motion command is done.
    Fin(&'a str),
    /// `ERR …`: the command failed or was refused.
    Err {
        /// The command's name (second token), when the line has one. Three public clients
        /// rely on it being there (§4.3); a line without it cannot be paired.
        name: Option<&'a str>,
        /// The numeral code, when the line has one (the WSG binary table is our reading,
        /// §4.3).
        code: Option<u16>,
        /// What follows the code (a description in verbose mode, §4.2), possibly empty.
        text: &'a str,
    },
    /// `<NAME>=<value>`: the answer to a query `NAME?` or a setter `NAME=v`.
    Value {
        /// The name before `=`.
        name: &'a str,
        /// The text after `=`.
        value: &'a str,
    },
    /// `@<NAME>=<value>`: a value pushed by `AUTOSEND` (§3.10).
    Push {
        /// The name between `@` and `=`.
        name: &'a str,
        /// The text after `=`.
        value: &'a str,
    },
}

/// Why a reply line is not GCL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Malformed {
    /// The line is empty.
    Empty,
    /// `ACK`/`FIN` without a command name.
    MissingName,
    /// A name with characters other than `A–Z`, `a–z`, `0–9`, `_`, `[`, `]`.
    BadName,
    /// None of the reply forms.
    Unknown,
}

impl std::fmt::Display for Malformed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Malformed::Empty => "empty line",
            Malformed::MissingName => "ACK or FIN without a command name",
            Malformed::BadName => "invalid command name",
            Malformed::Unknown => "not a GCL reply",
        })
    }
}

fn is_name(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'[' | b']'))
}

fn name(s: &str) -> Result<&str, Malformed> {
    match s {
        "" => Err(Malformed::MissingName),
        s if is_name(s) => Ok(s),
        _ => Err(Malformed::BadName),
    }
}

/// Parses one reply line (without its LF; a trailing CR and surrounding spaces are ignored).
/// Never panics, whatever the input (fuzzed: `fuzz/fuzz_targets/wsg_text_reply.rs`).
pub fn parse_reply(line: &str) -> Result<ReplyLine<'_>, Malformed> {
    let line = line.trim_matches(|c: char| c == ' ' || c == '\r' || c == '\t');
    if line.is_empty() {
        return Err(Malformed::Empty);
    }
    // GCL replies are printable ASCII (§2). A control character inside a line is a damaged
    // byte, most often the LF between two replies with a bit flipped (0x0A read as 0x0B, 0x08,
    // 0x0E, 0x02 or 0x1A): the line then holds two replies, and taken for the first one's it
    // swallows the second unseen (`ERR HOME 4\u{b}ERR MOVE 19` ended HOME's call and lost
    // MOVE's ERR, wsg-text:0xaa891d063fc824a5). Such a line is none of the forms: the client
    // counts it as a reply it could not read (issue 29 M, L).
    if line.chars().any(|c| c.is_ascii_control()) {
        return Err(Malformed::Unknown);
    }
    if let Some(rest) = line.strip_prefix('@') {
        let (n, value) = rest.split_once('=').ok_or(Malformed::Unknown)?;
        return Ok(ReplyLine::Push {
            name: name(n.trim())?,
            value: value.trim(),
        });
    }
    let mut words = line.splitn(2, ' ');
    let first = words.next().unwrap_or_default();
    let rest = words.next().unwrap_or_default().trim_start();
    // The manual's replies are upper case (§2); a lower-case keyword reads the same.
    let is = |keyword: &str| first.eq_ignore_ascii_case(keyword);
    if is("ACK") {
        Ok(ReplyLine::Ack(name(rest)?))
    } else if is("FIN") {
        Ok(ReplyLine::Fin(name(rest)?))
    } else if is("ERR") {
        if runs_into_another_reply(rest) {
            return Err(Malformed::Unknown);
        }
        Ok(parse_err(rest))
    } else {
        let (n, value) = line.split_once('=').ok_or(Malformed::Unknown)?;
        Ok(ReplyLine::Value {
            name: name(n.trim())?,
            value: value.trim(),
        })
    }
}

/// Whether the words after `ERR` hold a second reply, run in by an LF with a bit flipped to a
/// printable character (0x0A read as `*` or `J`): `ERR GRIP 19*ACK HOME`. Every other reply form
/// refuses it (a name takes no `*` or space, a value is a number), but an `ERR` line's text is
/// free, so it took the line for GRIP's and swallowed `ACK HOME` unseen, and HOME's `FIN` then
/// came with no `ACK` before it (`wsg-text:0xea94665dbf03df00`). GCL's texts are status symbols
/// (`E_CMD_ABORTED`): a `*` or `J` followed by a reply's start is damage, counted as a reply
/// that could not be read.
///
/// The keyword may carry a flipped bit of its own (`ERR MOVE 3 E_NOT_INITIALIZEDJQCK HOME`:
/// HOME's `ACK` swallowed, its `FIN` then refused as another motion's, and the connection given
/// up: `wsg-text:0x485486c387f4d074`): three letters one byte from `ACK`, `FIN` or `ERR`, then
/// a space.
fn runs_into_another_reply(rest: &str) -> bool {
    let near = |w: &[u8], k: &[u8]| {
        w.iter()
            .zip(k)
            .filter(|(a, b)| !a.eq_ignore_ascii_case(b))
            .count()
            <= 1
    };
    rest.match_indices(['*', 'J']).any(|(at, _)| {
        let next = &rest[at + 1..];
        let keyword = ["ACK", "FIN", "ERR"].iter().any(|k| {
            next.as_bytes()
                .get(..4)
                .is_some_and(|w| w[3] == b' ' && near(&w[..3], k.as_bytes()))
        });
        let value = next
            .strip_prefix('@')
            .unwrap_or(next)
            .split_once('=')
            .is_some_and(|(n, _)| is_name(n));
        keyword || value
    })
}

/// The tokens after `ERR`: `<NAME> <code> <text>`, or (not seen, but GRIPLINK's form, §4.3)
/// `<code> <text>` without a name.
fn parse_err(rest: &str) -> ReplyLine<'_> {
    let mut tokens = rest.splitn(2, ' ');
    let first = tokens.next().unwrap_or_default();
    let after = tokens.next().unwrap_or_default().trim_start();
    let code = |t: &str| -> Option<u16> {
        (!t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()))
            .then(|| t.parse().ok())
            .flatten()
    };
    if let Some(c) = code(first) {
        return ReplyLine::Err {
            name: None,
            code: Some(c),
            text: after,
        };
    }
    let name = is_name(first).then_some(first);
    let mut tokens = after.splitn(2, ' ');
    let second = tokens.next().unwrap_or_default();
    match code(second) {
        Some(c) => ReplyLine::Err {
            name,
            code: Some(c),
            text: tokens.next().unwrap_or_default().trim_start(),
        },
        None => ReplyLine::Err {
            name,
            code: None,
            text: after,
        },
    }
}

/// Parses a reply value as a finite number (the manual's examples: `POS=20.0`, §3.9).
pub fn parse_number(value: &str) -> Option<f64> {
    // `f64::from_str` also takes `inf` and `NaN`: no gripper value.
    value.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Why an argument cannot be sent.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadArgument {
    /// Which argument.
    pub what: &'static str,
    /// Why.
    pub reason: String,
}

/// Appends `NAME(a, b, …)` for finite numbers, written without exponent (Rust's `Display` of
/// `f64` never uses one; S6's regex `[-+]?\d*\.?\d+` would break on it, §2).
pub fn encode_call(name: &str, args: &[(&'static str, f64)]) -> Result<String, BadArgument> {
    let mut line = String::with_capacity(name.len() + 2 + args.len() * 8);
    line.push_str(name);
    line.push('(');
    for (i, (what, v)) in args.iter().enumerate() {
        if !v.is_finite() {
            return Err(BadArgument {
                what,
                reason: format!("{v} is not a finite number"),
            });
        }
        if i > 0 {
            line.push(',');
        }
        let _ = write!(line, "{v}");
    }
    line.push(')');
    Ok(line)
}

/// `NAME=v` for a finite number.
pub fn encode_set(name: &str, what: &'static str, v: f64) -> Result<String, BadArgument> {
    if !v.is_finite() {
        return Err(BadArgument {
            what,
            reason: format!("{v} is not a finite number"),
        });
    }
    Ok(format!("{name}={v}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reply_forms() {
        assert_eq!(parse_reply("ACK MOVE"), Ok(ReplyLine::Ack("MOVE")));
        assert_eq!(parse_reply("FIN HOME\r"), Ok(ReplyLine::Fin("HOME")));
        assert_eq!(
            parse_reply("POS=20.0"),
            Ok(ReplyLine::Value {
                name: "POS",
                value: "20.0"
            })
        );
        assert_eq!(
            parse_reply("@GRIPSTATE=4"),
            Ok(ReplyLine::Push {
                name: "GRIPSTATE",
                value: "4"
            })
        );
        assert_eq!(
            parse_reply("ERR GRIP 18 E_CMD_FAILED"),
            Ok(ReplyLine::Err {
                name: Some("GRIP"),
                code: Some(18),
                text: "E_CMD_FAILED"
            })
        );
        assert_eq!(
            parse_reply("ERR 04"),
            Ok(ReplyLine::Err {
                name: None,
                code: Some(4),
                text: ""
            })
        );
        assert_eq!(
            parse_reply("ERR MOVE"),
            Ok(ReplyLine::Err {
                name: Some("MOVE"),
                code: None,
                text: ""
            })
        );
        assert_eq!(parse_reply("ACK"), Err(Malformed::MissingName));
        assert_eq!(parse_reply("ACK MO VE"), Err(Malformed::BadName));
        assert_eq!(parse_reply("hello"), Err(Malformed::Unknown));
        assert_eq!(parse_reply("  "), Err(Malformed::Empty));
        // Two replies run together by a damaged LF are neither.
        assert_eq!(
            parse_reply("ERR HOME 4\u{b}ERR MOVE 19"),
            Err(Malformed::Unknown)
        );
        assert_eq!(parse_reply("POS=1\u{8}POS=2"), Err(Malformed::Unknown));
        // An LF flipped to `*` or `J` (printable) runs a reply into an ERR's free text.
        for damaged in [
            "ERR GRIP 19*ACK HOME",
            "ERR GRIP 19JACK HOME",
            "ERR MOVE 19 E_CMD_ABORTED*FIN HOME",
            "ERR GRIP 4JERR MOVE 4",
            "ERR GRIP 19*POS=12.5",
            "ERR GRIP 19J@POS=12.5",
            // The keyword damaged too (wsg-text:0x485486c387f4d074).
            "ERR MOVE 3 E_NOT_INITIALIZEDJQCK HOME",
            "ERR GRIP 19*FIM MOVE",
        ] {
            assert_eq!(parse_reply(damaged), Err(Malformed::Unknown), "{damaged}");
        }
        // A text with a J in it is still an ERR's.
        assert_eq!(
            parse_reply("ERR GRIP 18 E_JAMMED"),
            Ok(ReplyLine::Err {
                name: Some("GRIP"),
                code: Some(18),
                text: "E_JAMMED"
            })
        );
    }

    #[test]
    fn numbers_are_finite_and_written_without_exponent() {
        assert_eq!(parse_number("20.0"), Some(20.0));
        assert_eq!(parse_number("nan"), None);
        assert_eq!(parse_number("inf"), None);
        assert_eq!(
            encode_call("MOVE", &[("position", 1e-7), ("speed", 1e21)]).unwrap(),
            "MOVE(0.0000001,1000000000000000000000)"
        );
        assert!(encode_call("MOVE", &[("position", f64::NAN)]).is_err());
        assert_eq!(encode_call("HOME", &[]).unwrap(), "HOME()");
        assert_eq!(encode_set("PWT", "pwt", 2.5).unwrap(), "PWT=2.5");
    }
}
