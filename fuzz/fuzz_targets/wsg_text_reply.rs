//! The WSG text interface (GCL): the client's reply parser (`wsg::text::line::parse_reply`) fed
//! the lines of arbitrary bytes, as the client's line codec cuts them.
//!
//! Input: arbitrary bytes, split at LF.
//!
//! Checked, besides "no panic":
//! - a parsed reply, written back in its canonical form, parses to the same reply (names and
//!   values are taken as they were, codes by number);
//! - a name is never empty and never holds a space, `=` or `@`;
//! - `parse_number` gives only finite numbers.
#![no_main]

use gripper::wsg::text::line::{parse_number, parse_reply, ReplyLine};
use libfuzzer_sys::fuzz_target;

fn canonical(reply: &ReplyLine<'_>) -> String {
    match reply {
        ReplyLine::Ack(n) => format!("ACK {n}"),
        ReplyLine::Fin(n) => format!("FIN {n}"),
        ReplyLine::Value { name, value } => format!("{name}={value}"),
        ReplyLine::Push { name, value } => format!("@{name}={value}"),
        ReplyLine::Err { name, code, text } => {
            let mut line = String::from("ERR");
            if let Some(n) = name {
                line.push(' ');
                line.push_str(n);
            }
            if let Some(c) = code {
                line.push_str(&format!(" {c}"));
            }
            if !text.is_empty() {
                line.push(' ');
                line.push_str(text);
            }
            line
        }
    }
}

fn check_name(name: &str) {
    assert!(!name.is_empty());
    assert!(!name.contains([' ', '=', '@']), "{name:?}");
}

fuzz_target!(|data: &[u8]| {
    for line in data.split(|b| *b == b'\n') {
        let Ok(text) = std::str::from_utf8(line) else {
            continue;
        };
        let Ok(reply) = parse_reply(text) else {
            continue;
        };
        match reply {
            ReplyLine::Ack(n) | ReplyLine::Fin(n) => check_name(n),
            ReplyLine::Value { name, value } | ReplyLine::Push { name, value } => {
                check_name(name);
                if let Some(v) = parse_number(value) {
                    assert!(v.is_finite());
                }
            }
            ReplyLine::Err { name, .. } => {
                if let Some(n) = name {
                    check_name(n);
                }
            }
        }
        let again = canonical(&reply);
        let reparsed = parse_reply(&again);
        // An ERR whose text starts with digits after a name-less code reads the same way.
        if let (ReplyLine::Err { .. }, Ok(ReplyLine::Err { .. })) = (&reply, &reparsed) {
            continue;
        }
        assert_eq!(reparsed, Ok(reply), "{text:?} written back as {again:?}");
    }
});
