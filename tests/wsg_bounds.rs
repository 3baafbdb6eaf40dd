//! Memory bounds of the WSG decoder and subscriptions (see "Memory bounds" in the `wsg` module
//! docs): a flood of garbage does not grow the decoder's buffer, and a slow stream consumer
//! misses updates (counted) instead of buffering them.
#![cfg(feature = "sim")]

mod common;

use bytes::BytesMut;
use futures_util::{FutureExt, StreamExt};
use gripper::wsg::frame::{self, Frame, CHECKSUM_LEN, DEFAULT_MAX_PAYLOAD_LEN, HEADER_LEN};
use gripper::wsg::sim::{Model, SimConfig};
use gripper::wsg::WsgCodec;
use proptest::prelude::*;
use tokio::io::AsyncWriteExt;
use tokio_util::codec::FramedRead;

const MAX_FRAME: usize = HEADER_LEN + DEFAULT_MAX_PAYLOAD_LEN + CHECKSUM_LEN;

fn encode(f: &Frame) -> Vec<u8> {
    let mut b = BytesMut::new();
    frame::encode(f, &mut b).unwrap();
    b.to_vec()
}

/// Garbage without valid frames: random bytes (no `AA`), `AA` runs, and bogus headers whose
/// length (up to the maximum) makes the decoder wait for a frame that then fails its checksum.
fn garbage(rng: &mut u64, len: usize) -> Vec<u8> {
    let mut next = move || {
        *rng ^= *rng << 13;
        *rng ^= *rng >> 7;
        *rng ^= *rng << 17;
        *rng
    };
    let mut out = Vec::with_capacity(len + 16);
    while out.len() < len {
        match next() % 64 {
            0 => out.extend(std::iter::repeat_n(0xAA, (next() % 8) as usize)),
            1 => {
                let claimed = (next() % (DEFAULT_MAX_PAYLOAD_LEN as u64 + 1)) as u16;
                out.extend_from_slice(&[0xAA, 0xAA, 0xAA, 0x06]);
                out.extend_from_slice(&claimed.to_le_bytes());
            }
            _ => out.push((next() % 0xAA) as u8),
        }
    }
    out
}

#[tokio::test]
async fn a_garbage_flood_does_not_grow_the_decoder_buffer() {
    let (reader, mut writer) = tokio::io::duplex(64 * 1024);
    let frames: Vec<Frame> = (0..64u32)
        .map(|i| Frame::new(0x06, i.to_le_bytes().to_vec()))
        .collect();
    let sent = frames.clone();
    let feeder = tokio::spawn(async move {
        let mut rng = 0x0BAD_5EED_u64;
        for f in &sent {
            // 16 KiB of garbage before each frame: 1 MiB in all.
            writer
                .write_all(&garbage(&mut rng, 16 * 1024))
                .await
                .unwrap();
            writer.write_all(&encode(f)).await.unwrap();
        }
        // A bogus header at the very end, then the end of the stream.
        writer
            .write_all(&[0xAA, 0xAA, 0xAA, 0x06, 0xFF, 0x0F])
            .await
            .unwrap();
    });
    let mut framed = FramedRead::new(reader, WsgCodec::new());
    let mut got = Vec::new();
    let mut largest = (0, 0);
    while let Some(f) = framed.next().await {
        got.push(f.unwrap());
        let buf = framed.read_buffer();
        largest = (largest.0.max(buf.len()), largest.1.max(buf.capacity()));
    }
    feeder.await.unwrap();
    // Every frame came through the garbage, in order. Garbage itself passes the 16-bit checksum
    // now and then (about one bogus header in 65536; this stream has tens of thousands), which
    // is why the client also checks what a reply can answer (see the module docs).
    let mut wanted = frames.iter().peekable();
    for f in &got {
        if wanted.peek() == Some(&f) {
            wanted.next();
        }
    }
    assert_eq!(wanted.next(), None, "a frame was lost in the garbage");
    assert!(got.len() <= frames.len() + 3, "{} frames", got.len());
    assert!(
        framed.decoder().corrupt_frames() > 0,
        "the bogus headers were checked"
    );
    // The buffer holds at most one partial frame plus one read (tokio-util reads into the
    // spare capacity of an 8 KiB buffer).
    assert!(largest.0 <= 8 * 1024, "buffer length {}", largest.0);
    assert!(largest.1 <= 16 * 1024, "buffer capacity {}", largest.1);
    assert!(framed.read_buffer().is_empty());
}

proptest! {
    /// Whatever arrives, in whatever chunks, `decode` leaves at most one frame of the maximum
    /// length (less one byte) in the buffer once it needs more bytes.
    #[test]
    fn decode_never_holds_more_than_one_frame(
        chunks in proptest::collection::vec(
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..600),
                proptest::collection::vec(Just(0xAAu8), 0..8),
                (any::<u16>()).prop_map(|len| {
                    let [lo, hi] = len.to_le_bytes();
                    vec![0xAA, 0xAA, 0xAA, 0x06, lo, hi]
                }),
            ],
            1..40,
        ),
        max in 0usize..5000,
    ) {
        let mut buf = BytesMut::new();
        for chunk in chunks {
            buf.extend_from_slice(&chunk);
            while frame::decode(&mut buf, max).is_some() {}
            prop_assert!(buf.len() < HEADER_LEN + max + CHECKSUM_LEN, "{} bytes held", buf.len());
        }
    }
}

#[tokio::test]
async fn a_slow_subscriber_misses_the_newest_updates_and_counts_them() {
    let (_sim, client, mut widths) =
        common::wsg_width_subscription(SimConfig::new(Model::Wsg50)).await;
    // Do not read the stream; let round trips pass the time until updates have been missed.
    for _ in 0..100_000 {
        if widths.missed() >= 3 {
            break;
        }
        client.temperature_c().await.unwrap();
    }
    assert!(widths.missed() >= 3, "no update was missed");
    // Exactly the buffer's worth is waiting: the rest were dropped, not queued.
    let mut waiting = 0;
    while let Some(Some(w)) = widths.next().now_or_never() {
        assert_eq!(w, 0.0);
        waiting += 1;
    }
    assert_eq!(waiting, 4);
    // The stream goes on with new updates.
    assert_eq!(widths.next().await, Some(0.0));
    // The frame bound itself, for the docs' arithmetic.
    assert_eq!(MAX_FRAME, 4104);
}
