//! WSG checksum, frame encode and frame decode, each beside a plain copy of the same bytes as a
//! floor (what moving the bytes costs at all).
//!
//! The checksum is also measured beside a byte-wise table loop written the obvious way (the
//! floor for a table CRC), and decoding is measured twice: from a freshly allocated buffer (the
//! first group) and in the steady state of a `Framed` reader, where bytes are appended to one
//! reused receive buffer and the codec splits each frame off it (`wsg/codec_decode`).
//!
//! `cargo bench --bench wsg -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;

use bytes::BytesMut;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gripper::wsg::checksum;
use gripper::wsg::command::Command;
use gripper::wsg::frame::{self, Frame};
use gripper::wsg::{Reply, Status, WsgCodec};
use tokio_util::codec::Decoder;

/// The manual's update rule (Anhang D) written the obvious way, independent of the crate's code:
/// the floor any table-driven implementation is compared with.
fn bytewise_obvious(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc = checksum::TABLE[((crc ^ b as u16) & 0xFF) as usize] ^ (crc >> 8);
    }
    crc
}

fn checksums(c: &mut Criterion) {
    let mut g = c.benchmark_group("wsg/checksum");
    for len in [8usize, 64, 1024] {
        let data: Vec<u8> = (0..len).map(|i| (i * 31 + 7) as u8).collect();
        // The variants must agree before their speed means anything (the crate's property test
        // `slice8_equals_bytewise` proves it on random input; this guards the bench's own data).
        assert_eq!(checksum::checksum(&data), bytewise_obvious(&data));
        assert_eq!(
            checksum::update(checksum::INIT, &data),
            bytewise_obvious(&data)
        );
        g.throughput(Throughput::Bytes(len as u64));
        // The crate's implementation of the manual's byte-wise rule (Anhang D).
        g.bench_with_input(BenchmarkId::new("manual_bytewise", len), &data, |b, d| {
            b.iter(|| checksum::update(checksum::INIT, black_box(d)))
        });
        g.bench_with_input(
            BenchmarkId::new("floor_bytewise_obvious", len),
            &data,
            |b, d| b.iter(|| bytewise_obvious(black_box(d))),
        );
        // What frames use: `checksum()`, eight bytes per step.
        g.bench_with_input(BenchmarkId::new("slicing_by_8", len), &data, |b, d| {
            b.iter(|| checksum::checksum(black_box(d)))
        });
        let mut dst = vec![0u8; len];
        g.bench_with_input(BenchmarkId::new("copy_floor", len), &data, |b, d| {
            b.iter(|| {
                dst.copy_from_slice(black_box(d));
                black_box(&dst);
            })
        });
    }
    g.finish();
}

fn samples() -> Vec<(&'static str, Frame)> {
    vec![
        (
            "status_reply",
            Reply::new(0x20, Status::Success, Vec::new()).to_frame(),
        ),
        (
            "width_reply",
            Reply::new(0x43, Status::Success, 12.5f32.to_le_bytes().to_vec()).to_frame(),
        ),
        (
            "grasp_command",
            Command::Grasp {
                width_mm: 20.0,
                speed_mm_per_s: 50.0,
            }
            .to_frame(),
        ),
        (
            "loop_256",
            Command::Loop((0..=255u8).collect::<Vec<u8>>().into()).to_frame(),
        ),
    ]
}

fn encode(c: &mut Criterion) {
    let mut g = c.benchmark_group("wsg/frame_encode");
    for (name, f) in samples() {
        let mut wire = BytesMut::new();
        frame::encode(&f, &mut wire).unwrap();
        g.throughput(Throughput::Bytes(wire.len() as u64));
        let mut dst = BytesMut::with_capacity(1024);
        g.bench_function(BenchmarkId::new("encode", name), |b| {
            b.iter(|| {
                dst.clear();
                frame::encode(black_box(&f), &mut dst).unwrap();
                black_box(&dst);
            })
        });
        g.bench_function(BenchmarkId::new("copy_floor", name), |b| {
            b.iter(|| {
                dst.clear();
                dst.extend_from_slice(black_box(&wire));
                black_box(&dst);
            })
        });
    }
    g.finish();
}

fn decode(c: &mut Criterion) {
    let mut g = c.benchmark_group("wsg/frame_decode");
    for (name, f) in samples() {
        let mut wire = BytesMut::new();
        frame::encode(&f, &mut wire).unwrap();
        let wire = wire.freeze();
        g.throughput(Throughput::Bytes(wire.len() as u64));
        // Both variants copy the bytes into a fresh receive buffer; decode then parses it.
        g.bench_function(BenchmarkId::new("decode", name), |b| {
            b.iter(|| {
                let mut buf = BytesMut::from(black_box(&wire[..]));
                black_box(frame::decode(&mut buf, frame::DEFAULT_MAX_PAYLOAD_LEN))
            })
        });
        g.bench_function(BenchmarkId::new("copy_floor", name), |b| {
            b.iter(|| black_box(BytesMut::from(black_box(&wire[..]))))
        });
    }
    g.finish();
}

/// Steady-state decoding: the bytes of one frame are appended to a receive buffer that is reused
/// (as `Framed` does), then the codec splits the frame off. Once the previous frame is dropped the
/// buffer's storage is reclaimed, so no allocation happens per frame (checked by
/// `tests/alloc_steady_state.rs`). The floor appends the same bytes and clears them.
fn codec_decode(c: &mut Criterion) {
    let mut g = c.benchmark_group("wsg/codec_decode");
    for (name, f) in samples() {
        let mut wire = BytesMut::new();
        frame::encode(&f, &mut wire).unwrap();
        let wire = wire.freeze();
        g.throughput(Throughput::Bytes(wire.len() as u64));
        let mut codec = WsgCodec::new();
        let mut buf = BytesMut::with_capacity(8192);
        g.bench_function(BenchmarkId::new("decode", name), |b| {
            b.iter(|| {
                buf.extend_from_slice(black_box(&wire));
                black_box(codec.decode(&mut buf).unwrap())
            })
        });
        g.bench_function(BenchmarkId::new("copy_floor", name), |b| {
            b.iter(|| {
                buf.extend_from_slice(black_box(&wire));
                black_box(&buf);
                buf.clear();
            })
        });
    }
    g.finish();
}

criterion_group!(benches, checksums, encode, decode, codec_decode);
criterion_main!(benches);
