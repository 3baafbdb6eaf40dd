//! SmartGrasp codecs (V3 and V4 frames, told apart by the prefix's version) fed arbitrary bytes,
//! split at points the input chooses.
//!
//! Input: `[n, len_1 .. len_n, stream..]` — the first byte says how many of the next bytes are
//! chunk lengths (`n % 16`); the stream is pushed into the decoder in chunks of those lengths
//! (the rest in one final chunk), calling `decode` until it has nothing more after each chunk,
//! exactly as `FramedRead` does. [`ClientCodec`] as a V3 and as a V4 client, and [`ServerCodec`],
//! read the same stream.
//!
//! Checked, besides "no panic":
//! - a returned frame has the layout of its prefix's version (4: V4, else V3) and re-encodes
//!   (through the opposite codec's encoder) to the 80 bytes it was cut from, except the bytes the
//!   layout calls padding (V3 responses 72–79, V3 requests 17 and 50–79, V4 requests 17 and
//!   48–79; a V4 response has none: its unread bytes are kept raw);
//! - the typed view of either version (`Response::from_any_frame`) never panics, and a V4 grasp
//!   converts to SI units and every format without panicking;
//! - the split does not matter: the frames and the final error are those of decoding the whole
//!   stream at once;
//! - an `Err` comes only for a prefix whose length is not 74 (and, for the client, the empty
//!   "too old" message from a version below the client's), and a decoder never buffers more than
//!   the bytes pushed plus one frame.
#![no_main]

use bytes::BytesMut;
use gripper::smartgrasp::codec::{ClientCodec, ServerCodec};
use gripper::smartgrasp::frame::{
    v4, AnyRequestFrame, AnyResponseFrame, Prefix, FRAME_LEN, PREFIX_LEN, V3_LENGTH,
};
use gripper::smartgrasp::{Error, Malformed, PoseFormat, Response, ResponseBody};
use gripper_fuzz::split_input;
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::{Decoder, Encoder};

/// What a decoder made of a stream: its frames (with the bytes each was cut from) and how it
/// ended (`None`: it ran out of bytes; `Some(text)`: it returned this error).
struct Outcome<T> {
    frames: Vec<(T, [u8; FRAME_LEN])>,
    error: Option<String>,
}

fn run<D>(mut codec: D, chunks: &[&[u8]]) -> Outcome<D::Item>
where
    D: Decoder<Error = Error>,
{
    let mut buf = BytesMut::new();
    let mut pushed = 0usize;
    let mut frames = Vec::new();
    for chunk in chunks {
        buf.extend_from_slice(chunk);
        pushed += chunk.len();
        loop {
            let before = buf.clone();
            match codec.decode(&mut buf) {
                Ok(Some(frame)) => {
                    let used = before.len() - buf.len();
                    assert_eq!(used, FRAME_LEN, "a frame consumes exactly 80 bytes");
                    let mut bytes = [0u8; FRAME_LEN];
                    bytes.copy_from_slice(&before[..FRAME_LEN]);
                    let prefix = Prefix::decode(bytes[..PREFIX_LEN].try_into().unwrap());
                    assert_eq!(
                        prefix.length, V3_LENGTH,
                        "only a length-74 prefix is a frame"
                    );
                    frames.push((frame, bytes));
                }
                Ok(None) => {
                    assert_eq!(&before[..], &buf[..], "waiting consumes nothing");
                    // "never more than one frame, whatever the prefix says": what the decoder
                    // reserves is bounded by the bytes pushed so far plus one frame (times
                    // BytesMut's growth factor), never by a length read from the wire.
                    assert!(
                        buf.capacity() <= 2 * (pushed + FRAME_LEN) + 64,
                        "buffer capacity {} after {} bytes",
                        buf.capacity(),
                        pushed
                    );
                    break;
                }
                Err(e) => {
                    // Only a prefix whose length is neither 74 (nor, for the client, 0) ends
                    // the stream.
                    let prefix = Prefix::decode(before[..PREFIX_LEN].try_into().unwrap());
                    match &e {
                        Error::ServerTooOld {
                            server_version,
                            client_version,
                        } => {
                            assert_eq!(prefix.length, 0);
                            assert_eq!(*server_version, prefix.version);
                            assert!(server_version < client_version);
                        }
                        Error::MalformedReply(Malformed::FrameLength { length }) => {
                            assert_eq!(*length, prefix.length);
                            assert_ne!(prefix.length, V3_LENGTH);
                        }
                        other => panic!("unexpected decoder error {other:?}"),
                    }
                    // An `Err` ends a FramedRead: stop here.
                    return Outcome {
                        frames,
                        error: Some(e.to_string()),
                    };
                }
            }
        }
    }
    Outcome {
        frames,
        error: None,
    }
}

/// The bytes the layout table gives a meaning to (manual 3.2); the rest is padding.
fn masked(mut bytes: [u8; FRAME_LEN], padding: &[(usize, usize)]) -> [u8; FRAME_LEN] {
    for &(start, end) in padding {
        bytes[start..end].fill(0);
    }
    bytes
}

fn same_frames<T: PartialEq + std::fmt::Debug>(a: &Outcome<T>, b: &Outcome<T>) {
    assert_eq!(a.frames.len(), b.frames.len());
    for ((fa, ba), (fb, bb)) in a.frames.iter().zip(&b.frames) {
        assert_eq!(fa, fb);
        assert_eq!(ba, bb);
    }
    assert_eq!(a.error, b.error);
}

fuzz_target!(|data: &[u8]| {
    let (chunks, stream) = split_input(data);

    // Client side: responses in, as a V3 and as a V4 client (the "too old" threshold differs).
    let client = run(ClientCodec::new(3), &chunks);
    let client_v4 = run(ClientCodec::new(v4::PROTOCOL_VERSION), &chunks);
    for (frame, bytes) in &client.frames {
        let mut out = BytesMut::new();
        ServerCodec.encode(*frame, &mut out).unwrap();
        let padding: &[(usize, usize)] = match frame {
            AnyResponseFrame::V3(_) => {
                assert_ne!(frame.version(), v4::PROTOCOL_VERSION);
                // Response padding: bytes 72..80 (manual 3.2).
                &[(72, 80)]
            }
            AnyResponseFrame::V4(_) => {
                assert_eq!(frame.version(), v4::PROTOCOL_VERSION);
                &[]
            }
        };
        assert_eq!(out[..], masked(*bytes, padding)[..], "response re-encodes");
        // What the client does next with a response: the typed view, and the pose in SI units
        // and in every format (float conversions of arbitrary wire integers).
        match Response::from_any_frame(frame) {
            Ok(response) => {
                if let ResponseBody::Grasp(grasp) = response.body {
                    let _ = format!("{}", grasp.pose);
                    let _ = grasp.stroke_m() + grasp.angle_offset_rad().unwrap_or(0.0);
                    let _ = grasp.center_offset_m();
                    if let Ok(si) = grasp.pose.to_si() {
                        assert!(si.position_m.iter().all(|v| v.is_finite()));
                    }
                    for format in [
                        PoseFormat::Quaternion,
                        PoseFormat::AxisAngle,
                        PoseFormat::Wpr,
                        PoseFormat::Abc,
                    ] {
                        let _ = grasp.pose.to_format(format);
                    }
                    // V4 fields only from V4 frames, V3 fields only from V3 frames.
                    let from_v4 = matches!(frame, AnyResponseFrame::V4(_));
                    assert_eq!(grasp.object_offset.is_some(), from_v4);
                    assert_eq!(grasp.tool.is_some(), !from_v4);
                    // A server's encoding of the typed response reads back to it.
                    if from_v4 {
                        let again = response.to_v4_frame().expect("six values fit");
                        assert_eq!(
                            Response::from_v4_frame(&again).expect("reads back"),
                            response
                        );
                    }
                }
                // The typed view keeps what the client's pairing checks.
                let header = frame.header();
                assert_eq!(response.message_type, header.message_type);
                assert_eq!(response.code, header.response_code);
                assert_eq!(response.counter, header.response_counter);
            }
            Err(Malformed::Pose(_)) => {}
            Err(other) => panic!("Response::from_any_frame failed with {other:?}"),
        }
    }
    // The V4 client cuts the same frames; it only ends on "too old" where the V3 one would not.
    assert!(client_v4.frames.len() <= client.frames.len());

    // Server side: requests in.
    let server = run(ServerCodec, &chunks);
    for (frame, bytes) in &server.frames {
        let mut out = BytesMut::new();
        ClientCodec::default().encode(*frame, &mut out).unwrap();
        let padding: &[(usize, usize)] = match frame {
            // The unused offset byte 17 and bytes 50..80 (manual 3.2).
            AnyRequestFrame::V3(_) => &[(17, 18), (50, 80)],
            // Byte 17 and bytes 48..80 (PROTOCOLS.md 2b).
            AnyRequestFrame::V4(_) => &[(17, 18), (48, 80)],
        };
        assert_eq!(out[..], masked(*bytes, padding)[..], "request re-encodes");
    }

    // The split points must not change what is decoded.
    let whole: [&[u8]; 1] = [stream];
    same_frames(&client, &run(ClientCodec::new(3), &whole));
    same_frames(
        &client_v4,
        &run(ClientCodec::new(v4::PROTOCOL_VERSION), &whole),
    );
    same_frames(&server, &run(ServerCodec, &whole));
});
