//! The WSG frame decoder ([`WsgCodec`], over `frame::decode`) fed bytes split at points the
//! input chooses, in two modes picked by the first byte's low bit.
//!
//! - Arbitrary bytes (`[0bxxxxxxx0, max_payload, split input..]`): whatever arrives, every frame
//!   returned has a correct checksum and was cut, intact, from the stream (the bytes consumed end
//!   with its encoding); its id is not `AA` and its payload is within the maximum; after "need
//!   more" the buffer holds less than one maximal frame; frames and the count of corrupt ones do
//!   not depend on the split.
//! - Valid frames with garbage between them (`[0bxxxxxxx1, split bytes.., (id, len, payload,
//!   garbage)...]`): frames built from the input (ids other than `AA`, garbage without `AA`),
//!   encoded, concatenated with the garbage, then split: the decoder returns exactly those frames,
//!   in order, and counts no corrupt one. Payloads may hold `AA` runs and whole frames.
//!
//! `decode_eof` at the end of the stream in both modes.
#![no_main]

use bytes::BytesMut;
use gripper::wsg::frame::{self, Frame, CHECKSUM_LEN, HEADER_LEN};
use gripper::wsg::{checksum, WsgCodec};
use gripper_fuzz::split_input;
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::{Decoder, Encoder};

struct Run {
    frames: Vec<Frame>,
    corrupt: u64,
}

fn encode(frame: &Frame) -> Vec<u8> {
    let mut out = BytesMut::new();
    WsgCodec::new()
        .encode(frame, &mut out)
        .expect("payload fits");
    out.to_vec()
}

fn run(max_payload: usize, chunks: &[&[u8]]) -> Run {
    let mut codec = WsgCodec::with_max_payload_len(max_payload);
    let mut buf = BytesMut::new();
    let mut frames = Vec::new();
    let check = |before: &[u8], after: &BytesMut, frame: &Frame| {
        let used = before.len() - after.len();
        let bytes = encode(frame);
        assert!(
            before[..used].ends_with(&bytes),
            "frame {frame:?} was not cut intact from the stream"
        );
        assert_eq!(checksum::checksum(&bytes), 0, "checksum");
        assert_ne!(frame.id, 0xAA);
        assert!(frame.payload.len() <= max_payload);
    };
    for chunk in chunks {
        buf.extend_from_slice(chunk);
        loop {
            let before = buf.to_vec();
            match codec.decode(&mut buf).expect("the WSG codec never fails") {
                Some(frame) => {
                    check(&before, &buf, &frame);
                    frames.push(frame);
                }
                None => break,
            }
        }
        // Waiting for the rest of at most one frame: less than a maximal frame is held.
        assert!(
            buf.len() < HEADER_LEN + max_payload + CHECKSUM_LEN,
            "{} bytes held, max payload {max_payload}",
            buf.len()
        );
    }
    loop {
        let before = buf.to_vec();
        match codec
            .decode_eof(&mut buf)
            .expect("the WSG codec never fails")
        {
            Some(frame) => {
                check(&before, &buf, &frame);
                frames.push(frame);
            }
            None => break,
        }
    }
    assert!(buf.is_empty(), "bytes left after the end of the stream");
    Run {
        frames,
        corrupt: codec.corrupt_frames(),
    }
}

/// `[n, lens.., (id, len, payload[len], glen, garbage[glen])...]` → (chunk lengths, stream,
/// frames).
fn valid_stream(data: &[u8]) -> (Vec<usize>, Vec<u8>, Vec<Frame>) {
    let Some((&n, rest)) = data.split_first() else {
        return (Vec::new(), Vec::new(), Vec::new());
    };
    let n = usize::from(n % 16).min(rest.len());
    let (lens, mut rest) = rest.split_at(n);
    let mut stream = Vec::new();
    let mut frames = Vec::new();
    while let [id, len, tail @ ..] = rest {
        let len = usize::from(*len).min(tail.len());
        let (payload, tail) = tail.split_at(len);
        // No WSG command has id AA (the decoder reads the last three of an AA run as preamble).
        let id = if *id == 0xAA { 0xAB } else { *id };
        let frame = Frame::new(id, payload.to_vec());
        stream.extend_from_slice(&encode(&frame));
        frames.push(frame);
        let Some((&glen, tail)) = tail.split_first() else {
            break;
        };
        let glen = usize::from(glen % 16).min(tail.len());
        let (garbage, tail) = tail.split_at(glen);
        // Garbage without AA: a preamble inside the garbage could legitimately start a frame.
        stream.extend(garbage.iter().map(|&b| if b == 0xAA { 0x55 } else { b }));
        rest = tail;
    }
    (
        lens.iter().map(|&l| usize::from(l)).collect(),
        stream,
        frames,
    )
}

fn chunks<'a>(lens: &[usize], stream: &'a [u8]) -> Vec<&'a [u8]> {
    let mut out = Vec::new();
    let mut left = stream;
    for &len in lens {
        let (piece, after) = left.split_at(len.min(left.len()));
        out.push(piece);
        left = after;
    }
    out.push(left);
    out
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    if mode & 1 == 0 {
        let Some((&max, rest)) = rest.split_first() else {
            return;
        };
        // Small maxima make the "length above the limit" path reachable.
        let max_payload = if max == 255 {
            frame::DEFAULT_MAX_PAYLOAD_LEN
        } else {
            usize::from(max)
        };
        let (pieces, stream) = split_input(rest);
        let split = run(max_payload, &pieces);
        let whole = run(max_payload, &[stream]);
        assert_eq!(split.frames, whole.frames, "the split changed the frames");
        assert_eq!(
            split.corrupt, whole.corrupt,
            "the split changed the corrupt count"
        );
    } else {
        let (lens, stream, frames) = valid_stream(rest);
        let got = run(frame::DEFAULT_MAX_PAYLOAD_LEN, &chunks(&lens, &stream));
        assert_eq!(got.frames, frames, "valid frames with garbage between them");
        assert_eq!(got.corrupt, 0);
    }
});
