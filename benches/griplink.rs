//! GRIPLINK command formatting, reply parsing and line decoding, each beside a floor: a plain
//! copy of the same bytes, the least any implementation must spend.
//!
//! `griplink/codec_steady` decodes from one reused receive buffer, as a `Framed` reader does;
//! its only allocation per line is the `String` the decoded line owns (counted by
//! `tests/alloc_steady_state.rs`), and its floor is the same copy into an owned `String`.
//!
//! `cargo bench --bench griplink -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;

use bytes::BytesMut;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use gripper::griplink::codec::LineCodec;
use gripper::griplink::command::{Blocking, Command, FlexGrip};
use gripper::griplink::reply::parse_reply;
use tokio_util::codec::Decoder;

fn format(c: &mut Criterion) {
    let cmd = Command::FlexGripF(
        2,
        FlexGrip {
            position_mm: 15.0,
            force_n: 60.0,
            speed_mm_per_s: 45.5,
            acceleration_mm_per_s2: 0.0,
        },
        Blocking::UntilDone,
    );
    let line = cmd.encode().unwrap();
    let mut g = c.benchmark_group("griplink/format");
    g.throughput(Throughput::Bytes(line.len() as u64));
    g.bench_function("FLEXGRIPF", |b| b.iter(|| black_box(&cmd).encode()));
    g.bench_function("floor: copy", |b| {
        b.iter(|| black_box(line.as_str()).to_owned())
    });
    g.finish();
}

fn parse(c: &mut Criterion) {
    let mut g = c.benchmark_group("griplink/parse");
    for (name, line) in [
        ("ACK", "ACK"),
        ("VALUEF", "VALUEF[0][0]=42.456"),
        (
            "GRIPCFG",
            "GRIPCFG[1][0]=[\"tube\",3500,10800,50000,0,0,0,0,0]",
        ),
    ] {
        g.throughput(Throughput::Bytes(line.len() as u64));
        g.bench_function(name, |b| b.iter(|| parse_reply(black_box(line))));
        g.bench_function(format!("floor: copy {name}"), |b| {
            b.iter(|| black_box(line).to_owned())
        });
    }
    g.finish();
}

fn decode(c: &mut Criterion) {
    let bytes: &[u8] = b"VALUEF[0][0]=42.456\n";
    let mut g = c.benchmark_group("griplink/codec");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    let mut codec = LineCodec::default();
    g.bench_function("decode line", |b| {
        b.iter(|| {
            let mut buf = BytesMut::from(black_box(bytes));
            codec.decode(&mut buf)
        })
    });
    g.bench_function("floor: copy", |b| {
        b.iter(|| BytesMut::from(black_box(bytes)))
    });
    g.finish();
}

/// Line decoding in the steady state of a `Framed` reader: bytes appended to one reused buffer.
fn decode_steady(c: &mut Criterion) {
    let mut g = c.benchmark_group("griplink/codec_steady");
    for (name, bytes) in [
        ("ACK", &b"ACK\n"[..]),
        ("VALUEF", &b"VALUEF[0][0]=42.456\n"[..]),
    ] {
        g.throughput(Throughput::Bytes(bytes.len() as u64));
        let mut codec = LineCodec::default();
        let mut buf = BytesMut::with_capacity(4096);
        g.bench_function(format!("decode {name}"), |b| {
            b.iter(|| {
                buf.extend_from_slice(black_box(bytes));
                black_box(codec.decode(&mut buf).unwrap())
            })
        });
        g.bench_function(format!("floor: copy {name} into a String"), |b| {
            b.iter(|| {
                buf.extend_from_slice(black_box(bytes));
                let s = String::from_utf8_lossy(&buf[..bytes.len() - 1]).into_owned();
                buf.clear();
                black_box(s)
            })
        });
        g.bench_function(format!("decode + parse {name}"), |b| {
            b.iter(|| {
                buf.extend_from_slice(black_box(bytes));
                match codec.decode(&mut buf).unwrap() {
                    Some(gripper::griplink::codec::Line::Text(t)) => {
                        black_box(parse_reply(&t).is_ok())
                    }
                    _ => unreachable!("a valid line"),
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, format, parse, decode, decode_steady);
criterion_main!(benches);
