//! The GRIPLINK line codec and reply parser (what the client does with every byte a controller
//! sends) fed arbitrary bytes, split at points the input chooses.
//!
//! Input: `[max_line_len, split input..]` (the split input as in [`split_input`]); a small
//! maximum line length makes the over-long-line paths reachable.
//!
//! Checked, besides "no panic":
//! - one decoded line per LF, plus one for an unterminated tail at the end of the stream (a line
//!   that vanished would hand every later reply to the wrong caller);
//! - the split does not matter: the same lines as decoding the whole stream at once;
//! - memory bound: after `decode` says "need more", the buffer holds at most `max_len + 1` bytes;
//! - a text line is ASCII, without LF, at most `max_len` bytes, and encodes back to a line that
//!   decodes to itself (when it has no CR, which the encoder refuses);
//! - `parse_reply`: a data reply prints (`Display`) as a line that parses to the same reply
//!   (numbers compared by value: `1.0` prints as `1`); `interpret` agrees with `parse_reply`.
#![no_main]

use bytes::BytesMut;
use gripper::griplink::codec::{Discarded, Line, LineCodec};
use gripper::griplink::command::Expect;
use gripper::griplink::reply::{interpret, parse_reply, Answer, Reply};
use gripper::griplink::value::Value;
use gripper::griplink::Error;
use gripper_fuzz::split_input;
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::{Decoder, Encoder};

fn decode(max_len: usize, chunks: &[&[u8]]) -> Vec<Line> {
    let mut codec = LineCodec::new(max_len);
    let mut buf = BytesMut::new();
    let mut lines = Vec::new();
    for chunk in chunks {
        buf.extend_from_slice(chunk);
        while let Some(line) = codec.decode(&mut buf).expect("the line codec never fails") {
            lines.push(line);
        }
        assert!(
            buf.len() <= max_len + 1,
            "{} bytes buffered, max line {max_len}",
            buf.len()
        );
    }
    while let Some(line) = codec
        .decode_eof(&mut buf)
        .expect("the line codec never fails")
    {
        lines.push(line);
    }
    assert!(buf.is_empty(), "bytes left after the end of the stream");
    lines
}

/// Values equal as the protocol means them: numbers by value.
fn same_value(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::List(x), Value::List(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(a, b)| same_value(a, b))
        }
        (Value::Str(x), Value::Str(y)) => x == y,
        (Value::Str(_), _) | (_, Value::Str(_)) | (Value::List(_), _) | (_, Value::List(_)) => {
            false
        }
        _ => {
            a.as_f64() == b.as_f64()
                || (a.as_f64().unwrap().is_nan() && b.as_f64().unwrap().is_nan())
        }
    }
}

fn check_reply(text: &str) {
    let parsed = parse_reply(text);
    if let Ok(Reply::Data(data)) = &parsed {
        let printed = data.to_string();
        match parse_reply(&printed) {
            Ok(Reply::Data(again)) => {
                assert!(again.key == data.key && again.indices == data.indices);
                assert!(
                    same_value(&again.value, &data.value),
                    "{text:?} printed as {printed:?} reads back as {again:?}"
                );
            }
            other => panic!("{text:?} printed as {printed:?} reads back as {other:?}"),
        }
    }
    for expect in [
        Expect::Ack,
        Expect::Any,
        Expect::Data {
            key: "POS",
            port: Some(0),
            index: None,
        },
        Expect::Data {
            key: "VALUEF",
            port: Some(1),
            index: Some(0),
        },
    ] {
        let answer = interpret("TEST", expect, text);
        match (&parsed, &answer) {
            (Err(_), Err(Error::MalformedReply { .. })) => {}
            (Ok(Reply::Err { status, .. }), Err(Error::Device { status: s, .. })) => {
                assert_eq!(status, s)
            }
            (Ok(Reply::Ack), Ok(Answer::Ack)) => assert!(
                expect
                    != Expect::Data {
                        key: "POS",
                        port: Some(0),
                        index: None
                    }
            ),
            (Ok(Reply::Data(d)), Ok(Answer::Data(a))) => assert_eq!(d, a),
            (Ok(_), Err(Error::UnexpectedReply { .. })) => assert!(expect != Expect::Any),
            _ => panic!("{text:?}: parse_reply {parsed:?}, interpret {answer:?}"),
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let max_len = if sel == 255 {
        gripper::griplink::codec::DEFAULT_MAX_LINE_LEN
    } else {
        usize::from(sel)
    };
    let (chunks, stream) = split_input(rest);
    let lines = decode(max_len, &chunks);

    let newlines = stream.iter().filter(|&&b| b == b'\n').count();
    let tail = usize::from(stream.last().is_some_and(|&b| b != b'\n'));
    assert_eq!(lines.len(), newlines + tail, "one line per LF: {lines:?}");
    assert_eq!(
        lines,
        decode(max_len, &[stream]),
        "the split changed the lines"
    );

    for line in &lines {
        match line {
            Line::Text(text) => {
                assert!(text.is_ascii() && !text.contains('\n') && text.len() <= max_len);
                if !text.contains('\r') {
                    let mut out = BytesMut::new();
                    LineCodec::new(max_len)
                        .encode(text.as_str(), &mut out)
                        .expect("a decoded line encodes");
                    assert_eq!(decode(max_len, &[&out]), std::slice::from_ref(line));
                }
                check_reply(text);
            }
            Line::Discarded(Discarded::TooLong | Discarded::NotAscii) => {}
        }
    }
});
