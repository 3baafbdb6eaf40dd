//! Parsing GCL command lines as the simulator reads them (shared note §6.2, input): names in
//! any case, spaces around commas and at the ends, numbers with or without a fraction, strings
//! quoted with `"` or `'` or bare, `true`/`false`.

use crate::wsg::Status;

/// One argument.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Arg {
    Num(f64),
    Bool(bool),
    Str(String),
}

impl Arg {
    pub(crate) fn num(&self) -> Option<f64> {
        match self {
            Arg::Num(v) => Some(*v),
            _ => None,
        }
    }
}

/// The three shapes of a command line.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Form {
    /// `NAME(args)`.
    Call(Vec<Arg>),
    /// `NAME?`.
    Query,
    /// `NAME=value`.
    Set(Arg),
}

/// A parsed command line; `name` is upper case.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Line {
    pub(crate) name: String,
    pub(crate) form: Form,
}

/// A line that cannot be parsed: what to answer it with (`ERR <name> <code>`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Bad {
    /// The line's leading word upper-cased, or `?`.
    pub(crate) name: String,
    pub(crate) status: Status,
}

fn arg(text: &str) -> Option<Arg> {
    let t = text.trim();
    for q in ['"', '\''] {
        if let Some(inner) = t.strip_prefix(q).and_then(|r| r.strip_suffix(q)) {
            return Some(Arg::Str(inner.to_owned()));
        }
    }
    if t.eq_ignore_ascii_case("true") {
        return Some(Arg::Bool(true));
    }
    if t.eq_ignore_ascii_case("false") {
        return Some(Arg::Bool(false));
    }
    // Decimal numbers only: `f64::from_str` would also take `inf`, `NaN` and exponents.
    let numeric = !t.is_empty()
        && t.bytes().any(|b| b.is_ascii_digit())
        && t.bytes()
            .enumerate()
            .all(|(i, b)| b.is_ascii_digit() || b == b'.' || (i == 0 && b == b'-'));
    if numeric {
        return t.parse().ok().map(Arg::Num);
    }
    let bare = !t.is_empty() && t.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
    bare.then(|| Arg::Str(t.to_owned()))
}

/// Parses one command line (without LF; a trailing CR is ignored).
pub(crate) fn parse(line: &str) -> Result<Line, Bad> {
    let line = line.trim_matches(|c: char| c == ' ' || c == '\r' || c == '\t');
    let end = line
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(line.len());
    let (word, rest) = line.split_at(end);
    let name = word.to_ascii_uppercase();
    let bad = |status| Bad {
        name: if name.is_empty() {
            "?".into()
        } else {
            name.clone()
        },
        status,
    };
    if name.is_empty() || !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
        return Err(bad(Status::CmdUnknown));
    }
    let rest = rest.trim_start();
    let form = if rest == "?" {
        Form::Query
    } else if let Some(value) = rest.strip_prefix('=') {
        Form::Set(arg(value).ok_or_else(|| bad(Status::CmdFormatError))?)
    } else if let Some(inner) = rest.strip_prefix('(').and_then(|r| r.strip_suffix(')')) {
        if inner.trim().is_empty() {
            Form::Call(Vec::new())
        } else {
            let args = inner.split(',').map(arg).collect::<Option<Vec<_>>>();
            Form::Call(args.ok_or_else(|| bad(Status::CmdFormatError))?)
        }
    } else {
        return Err(bad(Status::CmdFormatError));
    };
    Ok(Line { name, form })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_forms_clients_send() {
        let call = |name: &str, args: Vec<Arg>| {
            Ok(Line {
                name: name.into(),
                form: Form::Call(args),
            })
        };
        assert_eq!(parse("HOME()"), call("HOME", vec![]));
        assert_eq!(parse("home()\r"), call("HOME", vec![]));
        assert_eq!(
            parse("MOVE(30, 200)"),
            call("MOVE", vec![Arg::Num(30.0), Arg::Num(200.0)])
        );
        assert_eq!(
            parse("AUTOSEND(\"POS\",50)"),
            call("AUTOSEND", vec![Arg::Str("POS".into()), Arg::Num(50.0)])
        );
        assert_eq!(
            parse("AUTOSEND(POS, 10, true)"),
            call(
                "AUTOSEND",
                vec![Arg::Str("POS".into()), Arg::Num(10.0), Arg::Bool(true)]
            )
        );
        assert_eq!(
            parse("VERBOSE=1    "),
            Ok(Line {
                name: "VERBOSE".into(),
                form: Form::Set(Arg::Num(1.0))
            })
        );
        assert_eq!(
            parse("POS?"),
            Ok(Line {
                name: "POS".into(),
                form: Form::Query
            })
        );
        assert_eq!(
            parse("RELEASE(-2.5)"),
            call("RELEASE", vec![Arg::Num(-2.5)])
        );
    }

    #[test]
    fn what_is_refused() {
        let bad = |name: &str, status| {
            Err(Bad {
                name: name.into(),
                status,
            })
        };
        assert_eq!(parse("VERBOSE=(1)"), bad("VERBOSE", Status::CmdFormatError));
        // Not a number (no exponents, no `nan`): a bare word, which no numeric argument takes,
        // so the command answers E_CMD_FORMAT_ERROR (`TextSession::command`).
        assert_eq!(
            parse("MOVE(1e5)").map(|l| l.form),
            Ok(Form::Call(vec![Arg::Str("1e5".into())]))
        );
        assert_eq!(
            parse("MOVE(nan)").map(|l| l.form),
            Ok(Form::Call(vec![Arg::Str("nan".into())]))
        );
        assert_eq!(parse("MOVE(10"), bad("MOVE", Status::CmdFormatError));
        assert_eq!(parse(""), bad("?", Status::CmdUnknown));
        assert_eq!(parse("(1)"), bad("?", Status::CmdUnknown));
    }
}
