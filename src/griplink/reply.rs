//! Reply lines (manual 2.1, 2.4 and the response message of every command in chapter 3). Pure:
//! no I/O.
//!
//! A reply is `ACK`, `ERR <code>[ <description>]`, or `KEY[p][i]=value`. [`interpret`] checks a
//! reply against the command it answers: a key, port or index that does not match is an error,
//! never a silent success.

use std::borrow::Cow;
use std::fmt;

use super::command::Expect;
use super::error::{Error, Result};
use super::status::Status;
use super::value::{Cursor, SyntaxError, Value};

/// One reply line, parsed.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `ACK`.
    Ack,
    /// `ERR <code>` or, in verbose mode, `ERR <code> <description>` (manual 2.4).
    Err {
        /// The status code (printed with two digits by the manual: `ERR 04`).
        status: Status,
        /// The verbose description, if any.
        text: Option<String>,
    },
    /// `KEY=value`, `KEY[p]=value` or `KEY[p][i]=value`.
    Data(Data),
}

/// A successful reply, as [`interpret`] hands it on: `ERR` has become [`Error::Device`].
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// `ACK`.
    Ack,
    /// `KEY[…]=value`.
    Data(Data),
}

/// The parts of a `KEY[p][i]=value` reply.
#[derive(Debug, Clone, PartialEq)]
pub struct Data {
    /// The key, as received (`VALUEF`).
    pub key: String,
    /// The indices in brackets, in order (port, then value/recipe index).
    pub indices: Vec<i64>,
    /// The value after `=`.
    pub value: Value,
}

impl fmt::Display for Data {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_data(f, &self.key, &self.indices, &self.value)
    }
}

/// `KEY[p][i]=value`, as received (modulo spaces).
fn write_data(
    f: &mut fmt::Formatter<'_>,
    key: &str,
    indices: &[i64],
    value: &Value,
) -> fmt::Result {
    f.write_str(key)?;
    for i in indices {
        write!(f, "[{i}]")?;
    }
    write!(f, "={value}")
}

/// Most bracketed indices a key carries (`VALUE[p][i]`).
const MAX_INDICES: usize = 2;

/// The indices of a key, held without allocating (there are at most [`MAX_INDICES`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Indices {
    len: usize,
    items: [i64; MAX_INDICES],
}

impl Indices {
    pub(crate) fn as_slice(&self) -> &[i64] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// Appends `index`; the parser checks first that there is room (a third index is dropped).
    fn push(&mut self, index: i64) {
        if let Some(slot) = self.items.get_mut(self.len) {
            *slot = index;
            self.len += 1;
        }
    }
}

/// A `KEY[p][i]=value` reply as the client hands it on internally: the public [`Data`] without
/// its two allocations, which a typed read (`VALUE[0][0]?` for an `i32`) never needs. The key
/// is the expected one, borrowed, when it was received exactly so (the usual case).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Datum {
    pub(crate) key: Cow<'static, str>,
    pub(crate) indices: Indices,
    pub(crate) value: Value,
}

impl fmt::Display for Datum {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_data(f, &self.key, self.indices.as_slice(), &self.value)
    }
}

impl From<Datum> for Data {
    fn from(datum: Datum) -> Data {
        Data {
            key: datum.key.into_owned(),
            indices: datum.indices.as_slice().to_vec(),
            value: datum.value,
        }
    }
}

/// [`Answer`] with a [`Datum`]: what [`interpret_datum`] gives the client.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Checked {
    /// `ACK`.
    Ack,
    /// `KEY[…]=value`.
    Data(Datum),
}

impl From<Checked> for Answer {
    fn from(checked: Checked) -> Answer {
        match checked {
            Checked::Ack => Answer::Ack,
            Checked::Data(datum) => Answer::Data(datum.into()),
        }
    }
}

/// [`Reply`] borrowing its key from the line.
enum ReplyRef<'a> {
    Ack,
    Err {
        status: Status,
        text: Option<String>,
    },
    Data {
        key: &'a str,
        indices: Indices,
        value: Value,
    },
}

/// Parses one reply line (without its LF).
pub fn parse_reply(line: &str) -> std::result::Result<Reply, SyntaxError> {
    Ok(match parse_reply_ref(line)? {
        ReplyRef::Ack => Reply::Ack,
        ReplyRef::Err { status, text } => Reply::Err { status, text },
        ReplyRef::Data {
            key,
            indices,
            value,
        } => Reply::Data(Data {
            key: key.to_owned(),
            indices: indices.as_slice().to_vec(),
            value,
        }),
    })
}

fn parse_reply_ref(line: &str) -> std::result::Result<ReplyRef<'_>, SyntaxError> {
    let mut c = Cursor::received(line);
    let key = c.name()?;
    if key == "ACK" {
        c.skip_spaces();
        if !c.at_end() {
            return c.fail("end of line after ACK");
        }
        return Ok(ReplyRef::Ack);
    }
    if key == "ERR" {
        return parse_err(&mut c);
    }
    let mut indices = Indices::default();
    while c.peek() == Some(b'[') {
        if indices.as_slice().len() == MAX_INDICES {
            return c.fail("'=' (at most two indices)");
        }
        indices.push(c.index()?);
    }
    c.expect(b'=', "'='")?;
    let value = c.value()?;
    c.skip_spaces();
    if !c.at_end() {
        return c.fail("end of line");
    }
    Ok(ReplyRef::Data {
        key,
        indices,
        value,
    })
}

fn parse_err<'a>(c: &mut Cursor<'_>) -> std::result::Result<ReplyRef<'a>, SyntaxError> {
    if !c.eat(b' ') {
        return c.fail("' ' and an error code after ERR");
    }
    c.skip_spaces();
    let start = c.pos();
    let mut code: u32 = 0;
    while let Some(b) = c.peek().filter(u8::is_ascii_digit) {
        code = match code
            .checked_mul(10)
            .and_then(|v| v.checked_add(u32::from(b - b'0')))
        {
            Some(v) => v,
            None => return c.fail("an error code in range"),
        };
        c.eat(b);
    }
    if c.pos() == start {
        return c.fail("a decimal error code");
    }
    let status = Status::from_code(code);
    if c.at_end() {
        return Ok(ReplyRef::Err { status, text: None });
    }
    if !c.eat(b' ') {
        return c.fail("' ' before the error description");
    }
    // The description is free text to the end of the line (the codec only lets ASCII through).
    let text = String::from_utf8_lossy(c.rest()).trim().to_owned();
    Ok(ReplyRef::Err {
        status,
        text: (!text.is_empty()).then_some(text),
    })
}

/// Whether a reply key (and its value) answers the expected one. Errata (seed 004): the
/// manual's VALUEF example answers `VALUE[0][0]=42.456`, so `VALUE` is accepted for `VALUEF` --
/// but only with a fraction (or `±INF`, VALUEF's out-of-range value): `VALUE`'s own replies are
/// integers (µm for a finger position), so an integer `VALUE` line where a VALUEF reply is due
/// is the reply of a `VALUE` query, the pairing out of step behind a lost reply. Taken as
/// VALUEF's, it was a reading a thousand times too large (`VALUE[0][0]=20000` µm read as mm:
/// griplink-tcp:0x4aa17c929219b038). Where a firmware prints a whole VALUEF without a fraction
/// under the `VALUE` key, the read fails `UnexpectedReply` instead (module docs of `griplink`).
fn key_matches(expected: &str, got: &str, value: &Value) -> bool {
    got.eq_ignore_ascii_case(expected)
        || (expected == "VALUEF"
            && got.eq_ignore_ascii_case("VALUE")
            && matches!(value, Value::Float(_)))
}

fn describe(expect: Expect) -> String {
    match expect {
        Expect::Ack => "ACK".to_owned(),
        Expect::Any => "a reply".to_owned(),
        Expect::Data { key, port, index } => {
            let mut s = key.to_owned();
            if let Some(p) = port {
                s.push_str(&format!("[{p}]"));
            }
            if let Some(i) = index {
                s.push_str(&format!("[{i}]"));
            }
            s.push_str("=…");
            s
        }
    }
}

/// Checks `line`, the reply to `command` (its line, for error messages), against what the
/// command expects. `ERR` becomes [`Error::Device`]; anything else that does not answer the
/// command becomes [`Error::MalformedReply`] or [`Error::UnexpectedReply`].
pub fn interpret(command: &str, expect: Expect, line: &str) -> Result<Answer> {
    interpret_datum(command, expect, line).map(Answer::from)
}

/// [`interpret`], for the client: a `KEY[…]=value` reply as a [`Datum`].
pub(crate) fn interpret_datum(command: &str, expect: Expect, line: &str) -> Result<Checked> {
    let reply = parse_reply_ref(line).map_err(|e| Error::MalformedReply {
        command: command.to_owned(),
        line: line.to_owned(),
        reason: e.to_string(),
    })?;
    let unexpected = || Error::UnexpectedReply {
        command: command.to_owned(),
        line: line.to_owned(),
        expected: describe(expect),
    };
    match (reply, expect) {
        (ReplyRef::Err { status, text }, _) => Err(Error::Device {
            command: command.to_owned(),
            status,
            text,
        }),
        (ReplyRef::Ack, Expect::Ack | Expect::Any) => Ok(Checked::Ack),
        (
            ReplyRef::Data {
                key,
                indices,
                value,
            },
            Expect::Any,
        ) => Ok(Checked::Data(Datum {
            key: Cow::Owned(key.to_owned()),
            indices,
            value,
        })),
        (
            ReplyRef::Data {
                key: got,
                indices,
                value,
            },
            Expect::Data { key, port, index },
        ) => {
            // Compared in place: collecting the expected indices would allocate on every reply.
            let want = port.map(i64::from).into_iter().chain(index.map(i64::from));
            if !key_matches(key, got, &value) || !indices.as_slice().iter().copied().eq(want) {
                return Err(unexpected());
            }
            let key = if got == key {
                Cow::Borrowed(key)
            } else {
                Cow::Owned(got.to_owned())
            };
            Ok(Checked::Data(Datum {
                key,
                indices,
                value,
            }))
        }
        (ReplyRef::Ack, Expect::Data { .. }) | (ReplyRef::Data { .. }, Expect::Ack) => {
            Err(unexpected())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(key: &str, indices: &[i64], value: Value) -> Reply {
        Reply::Data(Data {
            key: key.into(),
            indices: indices.to_vec(),
            value,
        })
    }

    #[test]
    fn manual_replies_parse() {
        assert_eq!(parse_reply("ACK"), Ok(Reply::Ack));
        assert_eq!(
            parse_reply("ID=\"GRIPLINK-ET4\""),
            Ok(data("ID", &[], Value::Str("GRIPLINK-ET4".into())))
        );
        assert_eq!(
            parse_reply("DEVVID[2]=-1"),
            Ok(data("DEVVID", &[2], Value::Int(-1)))
        );
        assert_eq!(
            parse_reply("VALUEF[0][0]=42.456"),
            Ok(data("VALUEF", &[0, 0], Value::Float(42.456)))
        );
        assert_eq!(
            parse_reply("VALUEF[0][1]=-INF"),
            Ok(data("VALUEF", &[0, 1], Value::Float(f64::NEG_INFINITY)))
        );
        assert_eq!(
            parse_reply("GRIPCFG[1][0]=[\"tube\",3500,10800,50000,0,0,0,0,0]"),
            Ok(data(
                "GRIPCFG",
                &[1, 0],
                Value::List(
                    std::iter::once(Value::Str("tube".into()))
                        .chain(
                            [3500, 10800, 50000, 0, 0, 0, 0, 0]
                                .into_iter()
                                .map(Value::Int)
                        )
                        .collect()
                )
            ))
        );
    }

    #[test]
    fn errors_parse_with_and_without_text() {
        assert_eq!(
            parse_reply("ERR 04"),
            Ok(Reply::Err {
                status: Status::NotInitialized,
                text: None
            })
        );
        assert_eq!(
            parse_reply("ERR 4 The device is not initialized"),
            Ok(Reply::Err {
                status: Status::NotInitialized,
                text: Some("The device is not initialized".into())
            })
        );
        assert_eq!(
            parse_reply("ERR 99"),
            Ok(Reply::Err {
                status: Status::Unknown(99),
                text: None
            })
        );
        assert!(parse_reply("ERR").is_err());
        assert!(parse_reply("ERR x").is_err());
        assert!(parse_reply("ERR 99999999999").is_err());
    }

    #[test]
    fn garbage_is_refused() {
        for bad in [
            "",
            "ACK!",
            "ACKX",
            "=1",
            "ID=",
            "ID=\"x",
            "VALUE[0][0][0]=1",
            "VALUE[a]=1",
            "DEVSTATE[0]=1e3",
            "X=[1,[2]]",
            "ID=\"a\" b",
        ] {
            assert!(parse_reply(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn interpret_checks_key_port_and_index() {
        let exp = Expect::Data {
            key: "VALUEF",
            port: Some(0),
            index: Some(0),
        };
        assert!(interpret("VALUEF[0][0]?", exp, "VALUEF[0][0]=1.5").is_ok());
        // Errata: the manual's example answers VALUE for VALUEF.
        assert!(interpret("VALUEF[0][0]?", exp, "VALUE[0][0]=42.456").is_ok());
        assert!(interpret("VALUEF[0][0]?", exp, "VALUE[0][0]=+INF").is_ok());
        // But an integer VALUE line is a VALUE query's reply (µm), never VALUEF's (mm): the
        // pairing out of step behind a lost reply (griplink-tcp:0x4aa17c929219b038).
        assert!(matches!(
            interpret("VALUEF[0][0]?", exp, "VALUE[0][0]=20000"),
            Err(Error::UnexpectedReply { .. })
        ));
        assert!(matches!(
            interpret("VALUEF[0][0]?", exp, "VALUEF[1][0]=1.5"),
            Err(Error::UnexpectedReply { .. })
        ));
        assert!(matches!(
            interpret("VALUEF[0][0]?", exp, "DEVSTATE[0]=3"),
            Err(Error::UnexpectedReply { .. })
        ));
        assert!(matches!(
            interpret("VALUEF[0][0]?", exp, "ACK"),
            Err(Error::UnexpectedReply { .. })
        ));
        assert!(matches!(
            interpret("HOME(0)", Expect::Ack, "DEVSTATE[0]=3"),
            Err(Error::UnexpectedReply { .. })
        ));
        assert!(matches!(
            interpret("HOME(0)", Expect::Ack, "ERR 04"),
            Err(Error::Device {
                status: Status::NotInitialized,
                ..
            })
        ));
        assert!(matches!(
            interpret("HOME(0)", Expect::Ack, "huh"),
            Err(Error::MalformedReply { .. })
        ));
    }

    #[test]
    fn the_clients_datum_is_the_reply_as_received() {
        let exp = Expect::Data {
            key: "VALUEF",
            port: Some(0),
            index: Some(0),
        };
        for line in [
            "VALUEF[0][0]=42.5",
            "value[0][0]=42.5",
            "VALUE[0][ 0 ]=42.5",
        ] {
            let Ok(Checked::Data(datum)) = interpret_datum("VALUEF[0][0]?", exp, line) else {
                panic!("{line} answers VALUEF[0][0]?");
            };
            let Ok(Answer::Data(data)) = interpret("VALUEF[0][0]?", exp, line) else {
                panic!("{line} answers VALUEF[0][0]?");
            };
            assert_eq!(datum.to_string(), data.to_string());
            assert_eq!(Data::from(datum), data);
        }
        assert_eq!(
            parse_reply("value[0][0]=42.5"),
            Ok(data("value", &[0, 0], Value::Float(42.5)))
        );
        assert!(parse_reply("VALUE[0][0][0]=1")
            .unwrap_err()
            .to_string()
            .contains("at most two indices"));
    }
}
