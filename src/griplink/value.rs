//! Data types on the wire (manual 2.1.1) and the small lexer shared by the reply parser and the
//! simulator's command parser.
//!
//! - strings: `'…'` or `"…"` when sent, always `"…"` when received; printable ASCII 0x20–0x7E
//!   except `'`, `"` and `\`;
//! - integers: 32-bit, decimal only;
//! - floats: decimal with an optional fraction, **no scientific notation**; out-of-range sensor
//!   values read back as `+INF` / `-INF` (manual 3.5.2);
//! - GRIPCFG recipes: `[<tag>,<p0>,…,<p7>]` (manual 3.6.1).

use std::fmt;

/// Most characters a LABEL, DEVTAG or GRIPCFG tag may hold (manual 3.1.5, 3.2.7, 3.6.1).
pub const MAX_TEXT_LEN: usize = 32;

/// One value of a reply (or of a command's argument list, in the simulator).
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A decimal integer without a fraction (`-1`, `42456`).
    Int(i64),
    /// A decimal number with a fraction (`42.456`), or `+INF` / `-INF`.
    Float(f64),
    /// A quoted string, without its quotes.
    Str(String),
    /// A bracketed list (`["tube",3500,…]`), as GRIPCFG uses.
    List(Vec<Value>),
}

impl Value {
    /// The value as an integer, if it is one.
    pub fn as_int(&self) -> Option<i64> {
        match self {
            Value::Int(v) => Some(*v),
            _ => None,
        }
    }

    /// The value as a float; an integer (`42`, a float without fraction) counts too.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Int(v) => Some(*v as f64),
            Value::Float(v) => Some(*v),
            _ => None,
        }
    }

    /// The value as a string, if it is one.
    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::Str(s) => Some(s),
            _ => None,
        }
    }
}

impl fmt::Display for Value {
    /// The value as the controller writes it (strings in double quotes).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Int(v) => write!(f, "{v}"),
            Value::Float(v) if v.is_infinite() => {
                f.write_str(if *v > 0.0 { "+INF" } else { "-INF" })
            }
            Value::Float(v) => match format_float(*v) {
                Some(text) => f.write_str(&text),
                None => f.write_str("NAN"),
            },
            Value::Str(s) => write!(f, "\"{s}\""),
            Value::List(items) => {
                f.write_str("[")?;
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        f.write_str(",")?;
                    }
                    write!(f, "{item}")?;
                }
                f.write_str("]")
            }
        }
    }
}

/// Formats a finite float as a plain decimal the controller accepts: never scientific notation
/// (manual 2.1.1), the shortest digits that read back as exactly `value`. `None` for NaN and
/// infinities, which the protocol cannot carry in a command.
///
/// Rust's `Display` for floats never uses an exponent (`1e-7` prints `0.0000001`, `3.4e38`
/// prints all 39 digits) and prints the shortest round-trip digits, which is exactly the
/// contract; `-0` is sent as `0`.
pub fn format_float(value: f64) -> Option<String> {
    if !value.is_finite() {
        return None;
    }
    if value == 0.0 {
        return Some("0".to_owned());
    }
    Some(value.to_string())
}

/// Why a string cannot be sent as a GRIPLINK string (manual 2.1.1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TextError {
    /// Longer than allowed.
    TooLong {
        /// Characters given.
        len: usize,
        /// Most characters allowed.
        max: usize,
    },
    /// A character outside printable ASCII, or one of `'` `"` `\`.
    Forbidden {
        /// The character.
        ch: char,
        /// Its position (in characters).
        at: usize,
    },
}

impl fmt::Display for TextError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TextError::TooLong { len, max } => {
                write!(f, "{len} characters, at most {max} allowed")
            }
            TextError::Forbidden { ch, at } => write!(
                f,
                "character {ch:?} at {at} is not allowed (printable ASCII except ' \" \\ only)"
            ),
        }
    }
}

/// Whether `byte` may appear inside a GRIPLINK string (manual 2.1.1).
pub fn is_text_byte(byte: u8) -> bool {
    (0x20..=0x7E).contains(&byte) && !matches!(byte, b'\'' | b'"' | b'\\')
}

/// Checks a string against the manual's rules: printable ASCII except `'`, `"`, `\`, and at most
/// `max` characters. A newline can therefore never reach the wire inside a string.
pub fn check_text(text: &str, max: usize) -> Result<(), TextError> {
    for (at, ch) in text.chars().enumerate() {
        if !ch.is_ascii() || !is_text_byte(ch as u8) {
            return Err(TextError::Forbidden { ch, at });
        }
    }
    // All characters are ASCII here, so bytes == characters.
    if text.len() > max {
        return Err(TextError::TooLong {
            len: text.len(),
            max,
        });
    }
    Ok(())
}

/// A syntax error found while parsing a line: what was expected and where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyntaxError {
    /// Byte offset in the line.
    pub at: usize,
    /// What the lexer wanted there.
    pub expected: &'static str,
}

impl fmt::Display for SyntaxError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "expected {} at byte {}", self.expected, self.at)
    }
}

/// A cursor over one line. Never panics: every access is checked.
#[derive(Debug, Clone)]
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// A line the controller sent: strings hold any printable character up to the closing
    /// quote (see [`Cursor::received`]).
    received: bool,
}

impl<'a> Cursor<'a> {
    /// A cursor over a line this side checks strictly (a command).
    pub(crate) fn new(line: &'a str) -> Self {
        Cursor {
            bytes: line.as_bytes(),
            pos: 0,
            received: false,
        }
    }

    /// A cursor over a reply line. Strings in replies may carry `'` and `\`: DEVNAME,
    /// DEVVENDOR and DEVSN come from third-party IO-Link devices, which do not follow the rules
    /// of manual 2.1.1 for what a client sends. So a received string is any printable ASCII up
    /// to its closing quote (PROTOCOLS.md, errata for seed 004).
    pub(crate) fn received(line: &'a str) -> Self {
        Cursor {
            received: true,
            ..Cursor::new(line)
        }
    }

    pub(crate) fn pos(&self) -> usize {
        self.pos
    }

    pub(crate) fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    pub(crate) fn at_end(&self) -> bool {
        self.pos >= self.bytes.len()
    }

    pub(crate) fn rest(&self) -> &'a [u8] {
        self.bytes.get(self.pos..).unwrap_or(&[])
    }

    pub(crate) fn fail<T>(&self, expected: &'static str) -> Result<T, SyntaxError> {
        Err(SyntaxError {
            at: self.pos,
            expected,
        })
    }

    /// Skips spaces (the controller turns control characters into spaces, manual 2.1).
    pub(crate) fn skip_spaces(&mut self) {
        while self.peek() == Some(b' ') {
            self.pos += 1;
        }
    }

    /// Consumes `byte` if it comes next.
    pub(crate) fn eat(&mut self, byte: u8) -> bool {
        if self.peek() == Some(byte) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    pub(crate) fn expect(&mut self, byte: u8, expected: &'static str) -> Result<(), SyntaxError> {
        if self.eat(byte) {
            Ok(())
        } else {
            self.fail(expected)
        }
    }

    /// A command or key name: letters, then letters or digits. Returned as written.
    pub(crate) fn name(&mut self) -> Result<&'a str, SyntaxError> {
        let start = self.pos;
        while let Some(b) = self.peek() {
            let ok = b.is_ascii_alphabetic() || (self.pos > start && b.is_ascii_digit());
            if !ok {
                break;
            }
            self.pos += 1;
        }
        if self.pos == start {
            return self.fail("a name");
        }
        // Only ASCII letters and digits were consumed, so this is valid UTF-8.
        std::str::from_utf8(self.bytes.get(start..self.pos).unwrap_or(&[]))
            .or_else(|_| self.fail("a name"))
    }

    /// `[<int>]`, with optional spaces inside.
    pub(crate) fn index(&mut self) -> Result<i64, SyntaxError> {
        self.expect(b'[', "'['")?;
        self.skip_spaces();
        let value = self.integer()?;
        self.skip_spaces();
        self.expect(b']', "']'")?;
        Ok(value)
    }

    /// A signed decimal integer.
    pub(crate) fn integer(&mut self) -> Result<i64, SyntaxError> {
        match self.number()? {
            Value::Int(v) => Ok(v),
            _ => self.fail("an integer"),
        }
    }

    /// A number: `[+-]digits[.digits]`, `[+-]digits.`, or `+INF` / `-INF` / `INF`.
    /// Scientific notation is not part of the protocol and is refused.
    pub(crate) fn number(&mut self) -> Result<Value, SyntaxError> {
        let start = self.pos;
        let negative = if self.eat(b'-') {
            true
        } else {
            self.eat(b'+');
            false
        };
        if self.rest().len() >= 3 && self.rest()[..3].eq_ignore_ascii_case(b"INF") {
            self.pos += 3;
            return Ok(Value::Float(if negative {
                f64::NEG_INFINITY
            } else {
                f64::INFINITY
            }));
        }
        let digits_start = self.pos;
        while self.peek().is_some_and(|b| b.is_ascii_digit()) {
            self.pos += 1;
        }
        let mut is_float = false;
        if self.eat(b'.') {
            is_float = true;
            while self.peek().is_some_and(|b| b.is_ascii_digit()) {
                self.pos += 1;
            }
        }
        let all_digits = self.pos - digits_start - usize::from(is_float);
        if all_digits == 0 {
            self.pos = start;
            return self.fail("a number");
        }
        if matches!(self.peek(), Some(b'e' | b'E')) {
            return self.fail("no scientific notation");
        }
        if !is_float {
            // Only digits after the sign: summed here, as `str::parse::<i64>` would, without
            // checking the text again (this runs for every index and value of every reply).
            let digits = self.bytes.get(digits_start..self.pos).unwrap_or(&[]);
            let int = digits.iter().try_fold(0i64, |v, digit| {
                let digit = i64::from(digit - b'0');
                let v = v.checked_mul(10)?;
                if negative {
                    v.checked_sub(digit)
                } else {
                    v.checked_add(digit)
                }
            });
            if let Some(v) = int {
                return Ok(Value::Int(v));
            }
            // Floats may omit the fraction (manual 2.1.1): digits beyond i64 are a float.
        }
        // Only sign, digits and at most one dot: Rust's parser accepts all of these ("1.", ".5").
        std::str::from_utf8(self.bytes.get(start..self.pos).unwrap_or(&[]))
            .ok()
            .and_then(|text| text.parse::<f64>().ok())
            .map(Value::Float)
            .map_or_else(|| self.fail("a number"), Ok)
    }

    /// A quoted string (`"…"` or `'…'`). In a command its content obeys the manual's character
    /// rules (2.1.1); in a reply it is any printable ASCII but the quote that opened it.
    pub(crate) fn string(&mut self) -> Result<String, SyntaxError> {
        let quote = match self.peek() {
            Some(q @ (b'"' | b'\'')) => q,
            _ => return self.fail("a quoted string"),
        };
        self.pos += 1;
        let start = self.pos;
        loop {
            match self.peek() {
                Some(b) if b == quote => break,
                Some(b) if is_text_byte(b) => self.pos += 1,
                Some(b) if self.received && (0x20..=0x7E).contains(&b) => self.pos += 1,
                Some(_) if self.received => return self.fail("a printable ASCII character"),
                Some(_) => return self.fail("a printable character other than ' \" \\"),
                None => return self.fail("a closing quote"),
            }
        }
        let text = std::str::from_utf8(self.bytes.get(start..self.pos).unwrap_or(&[]))
            .or_else(|_| self.fail("ASCII text"))?
            .to_owned();
        self.pos += 1; // the closing quote
        Ok(text)
    }

    /// One value: a string, a number, or a flat list of strings and numbers.
    pub(crate) fn value(&mut self) -> Result<Value, SyntaxError> {
        match self.peek() {
            Some(b'"' | b'\'') => self.string().map(Value::Str),
            Some(b'[') => {
                self.pos += 1;
                let mut items = Vec::new();
                self.skip_spaces();
                if self.eat(b']') {
                    return Ok(Value::List(items));
                }
                loop {
                    self.skip_spaces();
                    let item = match self.peek() {
                        Some(b'"' | b'\'') => Value::Str(self.string()?),
                        _ => self.number()?,
                    };
                    items.push(item);
                    self.skip_spaces();
                    if self.eat(b']') {
                        return Ok(Value::List(items));
                    }
                    self.expect(b',', "',' or ']'")?;
                }
            }
            _ => self.number(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(text: &str) -> Result<Value, SyntaxError> {
        let mut c = Cursor::new(text);
        let v = c.value()?;
        if !c.at_end() {
            return c.fail("end");
        }
        Ok(v)
    }

    #[test]
    fn numbers() {
        assert_eq!(value("42456"), Ok(Value::Int(42456)));
        assert_eq!(value("-1"), Ok(Value::Int(-1)));
        assert_eq!(value("+7"), Ok(Value::Int(7)));
        assert_eq!(value("42.456"), Ok(Value::Float(42.456)));
        assert_eq!(value("3."), Ok(Value::Float(3.0)));
        assert_eq!(value("-.5"), Ok(Value::Float(-0.5)));
        assert_eq!(value("+INF"), Ok(Value::Float(f64::INFINITY)));
        assert_eq!(value("-INF"), Ok(Value::Float(f64::NEG_INFINITY)));
        assert!(value("1e5").is_err());
        assert!(value("0x10").is_err());
        assert!(value("-").is_err());
        assert!(value(".").is_err());
        assert_eq!(value("99999999999999999999"), Ok(Value::Float(1e20)));
        assert_eq!(value("-0"), Ok(Value::Int(0)));
        assert_eq!(value("9223372036854775807"), Ok(Value::Int(i64::MAX)));
        assert_eq!(value("-9223372036854775808"), Ok(Value::Int(i64::MIN)));
        assert_eq!(
            value("9223372036854775808"),
            Ok(Value::Float(9223372036854775808.0))
        );
    }

    #[test]
    fn strings_and_lists() {
        assert_eq!(value("\"Marvin\""), Ok(Value::Str("Marvin".into())));
        assert_eq!(value("'Marvin'"), Ok(Value::Str("Marvin".into())));
        assert_eq!(value("\"\""), Ok(Value::Str(String::new())));
        assert!(value("\"a'b\"").is_err());
        assert!(value("\"a\\b\"").is_err());
        assert!(value("\"open").is_err());
        // A reply's strings may hold ' and \ (device names from IO-Link devices).
        let mut c = Cursor::received("\"O'Brien \\ Co.\"");
        assert_eq!(c.value(), Ok(Value::Str("O'Brien \\ Co.".into())));
        assert!(c.at_end());
        assert!(Cursor::received("\"tab\there\"").value().is_err());
        assert_eq!(
            value("[\"tube\",3500, -1 ,2.5]"),
            Ok(Value::List(vec![
                Value::Str("tube".into()),
                Value::Int(3500),
                Value::Int(-1),
                Value::Float(2.5)
            ]))
        );
        assert!(value("[1,[2]]").is_err());
        assert!(value("[1,2").is_err());
    }

    #[test]
    fn float_formatting_is_plain_decimal() {
        assert_eq!(format_float(1e-7).as_deref(), Some("0.0000001"));
        assert_eq!(
            format_float(3.4e38).as_deref(),
            Some("340000000000000000000000000000000000000")
        );
        assert_eq!(format_float(-0.0).as_deref(), Some("0"));
        assert_eq!(format_float(45.5).as_deref(), Some("45.5"));
        assert_eq!(format_float(15.0).as_deref(), Some("15"));
        assert_eq!(format_float(f64::NAN), None);
        assert_eq!(format_float(f64::INFINITY), None);
        assert_eq!(format_float(f64::NEG_INFINITY), None);
    }

    #[test]
    fn text_rules() {
        assert_eq!(check_text("Device 1", 32), Ok(()));
        assert!(matches!(
            check_text("a\nb", 32),
            Err(TextError::Forbidden { ch: '\n', at: 1 })
        ));
        assert!(check_text("it's", 32).is_err());
        assert!(check_text("say \"hi\"", 32).is_err());
        assert!(check_text("back\\slash", 32).is_err());
        assert!(check_text("Grüße", 32).is_err());
        assert!(check_text("\x7f", 32).is_err());
        assert_eq!(check_text(&"x".repeat(32), 32), Ok(()));
        assert_eq!(
            check_text(&"x".repeat(33), 32),
            Err(TextError::TooLong { len: 33, max: 32 })
        );
    }
}
