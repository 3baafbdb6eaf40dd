//! Property tests of the pure GRIPLINK layers: float formatting, command encoding against the
//! simulator's parser, reply parsing and the line codec.
#![cfg(feature = "sim")]

use std::time::Duration;

use bytes::BytesMut;
use gripper::griplink::codec::{Discarded, Line, LineCodec};
use gripper::griplink::command::{
    Blocking, Command, FlexGrip, FlexGripScaled, FlexRelease, GripConfig, GripConfigF,
    MAX_FLOAT_ARG_LEN,
};
use gripper::griplink::reply::{parse_reply, Reply};
use gripper::griplink::sim::parse::parse_command;
use gripper::griplink::value::{format_float, Value};
use gripper::griplink::Error;
use proptest::prelude::*;
use tokio_util::codec::Decoder;

fn any_finite() -> impl Strategy<Value = f64> {
    prop::num::f64::POSITIVE
        | prop::num::f64::NEGATIVE
        | prop::num::f64::ZERO
        | prop::num::f64::SUBNORMAL
        | prop::num::f64::NORMAL
}

/// Finite values the controller's 32-bit floats can hold.
fn f32_range() -> impl Strategy<Value = f64> {
    // 0, or a magnitude between f32::MIN_POSITIVE and f32::MAX: smaller magnitudes are refused
    // (hundreds of digits as a plain decimal, and 0 or a subnormal in the controller).
    any_finite().prop_filter("fits f32", |v| {
        *v == 0.0 || (f64::from(f32::MIN_POSITIVE)..=f64::from(f32::MAX)).contains(&v.abs())
    })
}

/// Strings the protocol can carry (manual 2.1.1).
fn text() -> impl Strategy<Value = String> {
    "[ !#-&(-\\[\\]-~]{0,32}"
}

fn blocking() -> impl Strategy<Value = Blocking> {
    prop_oneof![Just(Blocking::Immediate), Just(Blocking::UntilDone)]
}

fn command() -> impl Strategy<Value = Command> {
    let port = 0u8..=31;
    prop_oneof![
        Just(Command::Id),
        Just(Command::Bye),
        text().prop_map(Command::SetLabel),
        (text(), any::<u32>()).prop_map(|(identifier, min_version)| Command::ProtAssert {
            identifier,
            min_version
        }),
        (port.clone(), text()).prop_map(|(p, t)| Command::SetDevTag(p, t)),
        (port.clone(), any::<u32>(), any::<u32>()).prop_map(|(port, vendor_id, product_id)| {
            Command::DevAssert {
                port,
                vendor_id,
                product_id,
            }
        }),
        (port.clone(), any::<u32>(), blocking()).prop_map(|(port, index, blocking)| {
            Command::Grip {
                port,
                index,
                blocking,
            }
        }),
        (port.clone(), any::<[i32; 4]>(), blocking()).prop_map(|(p, a, b)| Command::FlexGrip(
            p,
            FlexGripScaled {
                position_um: a[0],
                force_mn: a[1],
                speed_um_per_s: a[2],
                acceleration_um_per_s2: a[3]
            },
            b
        )),
        (
            port.clone(),
            [f32_range(), f32_range(), f32_range(), f32_range()],
            blocking()
        )
            .prop_map(|(p, a, b)| Command::FlexGripF(
                p,
                FlexGrip {
                    position_mm: a[0],
                    force_n: a[1],
                    speed_mm_per_s: a[2],
                    acceleration_mm_per_s2: a[3]
                },
                b
            )),
        (
            port.clone(),
            [f32_range(), f32_range(), f32_range()],
            blocking()
        )
            .prop_map(|(p, a, b)| Command::FlexReleaseF(
                p,
                FlexRelease {
                    position_mm: a[0],
                    speed_mm_per_s: a[1],
                    acceleration_mm_per_s2: a[2]
                },
                b
            )),
        (port.clone(), any::<u32>(), f32_range())
            .prop_map(|(port, index, value)| { Command::SetValF { port, index, value } }),
        (
            port.clone(),
            any::<u32>(),
            any::<i32>(),
            any::<i32>(),
            0u64..=i32::MAX as u64
        )
            .prop_map(|(port, index, threshold, window, ms)| Command::WaitVal {
                port,
                index,
                threshold,
                window,
                timeout: Duration::from_millis(ms),
            }),
        (
            port.clone(),
            any::<u32>(),
            f32_range(),
            f32_range(),
            0u64..100_000
        )
            .prop_map(|(port, index, threshold, window, ms)| Command::WaitValF {
                port,
                index,
                threshold,
                window,
                timeout: Duration::from_millis(ms),
            }),
        (port.clone(), any::<u32>()).prop_map(|(port, index)| Command::ValueF { port, index }),
        (port.clone(), any::<u32>(), text(), any::<[i32; 8]>()).prop_map(
            |(port, index, tag, params)| Command::SetGripCfg {
                port,
                index,
                config: GripConfig { tag, params }
            }
        ),
        (
            port,
            any::<u32>(),
            text(),
            prop::array::uniform8(f32_range())
        )
            .prop_map(|(port, index, tag, params)| Command::SetGripCfgF {
                port,
                index,
                config: GripConfigF { tag, params }
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Any finite f64 formats as a plain decimal (no exponent) that reads back as exactly the
    /// same value, with Rust's parser and with the reply parser.
    #[test]
    fn floats_format_as_plain_decimals_that_round_trip(v in any_finite()) {
        let s = format_float(v).unwrap();
        prop_assert!(s.bytes().all(|b| b.is_ascii_digit() || b == b'-' || b == b'.'), "{}", s);
        prop_assert_eq!(s.parse::<f64>().unwrap(), v);
        match parse_reply(&format!("VALUEF[0][0]={s}")).unwrap() {
            Reply::Data(d) => prop_assert_eq!(d.value.as_f64(), Some(v)),
            other => prop_assert!(false, "{:?}", other),
        }
    }

    /// A float the controller's 32-bit float cannot hold is refused before anything is sent;
    /// every accepted one is at most `MAX_FLOAT_ARG_LEN` characters.
    #[test]
    fn float_arguments_are_bounded_or_refused(v in any_finite()) {
        let cmd = Command::SetValF { port: 0, index: 0, value: v };
        let fits = v == 0.0
            || (f64::from(f32::MIN_POSITIVE)..=f64::from(f32::MAX)).contains(&v.abs());
        match cmd.encode() {
            Ok(line) => {
                prop_assert!(fits, "{}", line);
                let arg = line.trim_start_matches("SETVALF(0,0,").trim_end_matches(')');
                prop_assert!(arg.len() <= MAX_FLOAT_ARG_LEN, "{}", line);
            }
            Err(Error::InvalidArgument { .. }) => prop_assert!(!fits, "{}", v),
            Err(e) => prop_assert!(false, "{:?}", e),
        }
    }

    /// What the client encodes, the simulated controller parses back to the same command.
    #[test]
    fn encoded_commands_parse_back(cmd in command()) {
        let line = cmd.encode().unwrap();
        prop_assert!(line.bytes().all(|b| (0x20..=0x7e).contains(&b)), "{}", line);
        prop_assert_eq!(parse_command(&line), Ok(cmd));
    }

    /// No string, whatever it holds, puts a line break or control character on the wire.
    #[test]
    fn any_label_is_one_clean_line_or_refused(s in any::<String>()) {
        for cmd in [Command::SetLabel(s.clone()), Command::SetDevTag(0, s.clone())] {
            if let Ok(line) = cmd.encode() {
                prop_assert!(line.bytes().all(|b| (0x20..=0x7e).contains(&b)), "{}", line);
                prop_assert_eq!(parse_command(&line), Ok(cmd));
            }
        }
    }

    /// The simulator's parser and the reply parser are total: no input makes them panic.
    #[test]
    fn parsers_never_panic(s in any::<String>()) {
        let _ = parse_command(&s);
        let _ = parse_reply(&s);
    }

    #[test]
    fn parsers_never_panic_on_near_misses(s in "[A-Z]{1,10}(\\[[-0-9]{0,3}\\]){0,3}[?=(]?[-+0-9.,\"'\\[\\] a-zA-Z]{0,30}\\)?") {
        let _ = parse_command(&s);
        let _ = parse_reply(&s);
    }

    /// `KEY[p][i]=value` as the controller writes it parses back to the same parts.
    #[test]
    fn data_replies_round_trip(
        key in "[A-Z]{1,12}",
        indices in prop::collection::vec(0i64..=1000, 0..=2),
        value in prop_oneof![
            any::<i64>().prop_map(Value::Int),
            f32_range().prop_filter("has a fraction", |f| f.fract() != 0.0).prop_map(Value::Float),
            text().prop_map(Value::Str),
        ],
    ) {
        prop_assume!(key != "ACK" && key != "ERR");
        let data = gripper::griplink::reply::Data { key, indices, value };
        prop_assert_eq!(parse_reply(&data.to_string()), Ok(Reply::Data(data)));
    }

    /// Any split of a stream of valid lines, over-long lines and non-ASCII lines decodes to the
    /// same lines, with each bad line reported in its place; memory stays bounded.
    #[test]
    fn codec_any_split_same_lines(
        items in prop::collection::vec(
            prop_oneof![
                "[ -~]{0,24}".prop_map(|s| (s, 0u8)),
                "[ -~]{40,120}".prop_map(|s| (s, 1u8)),
                "[ -~]{0,5}é[ -~]{0,5}".prop_map(|s| (s, 2u8)),
            ],
            0..20,
        ),
        crlf in any::<bool>(),
        cuts in prop::collection::vec(1usize..16, 0..64),
    ) {
        const MAX: usize = 32;
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        for (s, kind) in &items {
            stream.extend_from_slice(s.as_bytes());
            stream.extend_from_slice(if crlf { b"\r\n" } else { b"\n" });
            expected.push(match kind {
                0 => Line::Text(s.clone()),
                1 => Line::Discarded(Discarded::TooLong),
                _ if s.len() > MAX => Line::Discarded(Discarded::TooLong),
                _ => Line::Discarded(Discarded::NotAscii),
            });
        }
        let mut codec = LineCodec::new(MAX);
        let mut buf = BytesMut::new();
        let mut got = Vec::new();
        let mut rest: &[u8] = &stream;
        let mut cuts = cuts.into_iter();
        while !rest.is_empty() {
            let n = cuts.next().unwrap_or(rest.len()).min(rest.len());
            buf.extend_from_slice(&rest[..n]);
            rest = &rest[n..];
            while let Some(line) = codec.decode(&mut buf).unwrap() {
                got.push(line);
            }
            prop_assert!(buf.len() <= MAX + 2 + 16, "buffer {}", buf.len());
        }
        prop_assert_eq!(got, expected);
    }
}
