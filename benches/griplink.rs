//! GRIPLINK command formatting, reply parsing and line decoding, each beside a floor: a plain
//! copy of the same bytes, the least any implementation must spend.

use std::hint::black_box;

use bytes::BytesMut;
use criterion::{criterion_group, criterion_main, Criterion};
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

criterion_group!(benches, format, parse, decode);
criterion_main!(benches);
