//! Steady-state decoding allocates nothing per frame beyond what the returned value owns
//! (issue 6): counted with a global allocator that counts the allocations of the calling
//! thread only, so tests running in parallel do not disturb each other.
//!
//! The receive buffer is reused as a `Framed` reader reuses it: bytes arrive in chunks of several
//! frames, each decoded frame is dropped before the next chunk arrives (as the client's task
//! does once it has handed the value on). Counts are exact, not timings.
//!
//! `cargo test --test alloc_steady_state -- --nocapture` prints the allocations per frame.

use bytes::BytesMut;
use tokio_util::codec::Decoder;

#[path = "../benches/common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::allocations;

/// Frames per chunk handed to the decoder (a TCP read often carries several).
const CHUNK_FRAMES: usize = 4;
/// Chunks decoded before counting (the buffer grows to its working size).
const WARM_UP_CHUNKS: usize = 16;
/// Chunks counted.
const COUNTED_CHUNKS: usize = 256;

/// Allocations per decoded frame, in total and those the consumer says the returned values own.
#[derive(Debug, PartialEq)]
struct PerFrame {
    total: f64,
    owned_by_value: f64,
}

impl PerFrame {
    /// What the decoding itself allocated per frame, beyond what the values own.
    fn beyond_value(&self) -> f64 {
        self.total - self.owned_by_value
    }
}

/// Feeds `wire` (one encoded frame) `CHUNK_FRAMES` at a time into one reused buffer and hands
/// every decoded item to `consume`, which drops it and returns how many allocations the item
/// owned; counts allocations over the counted chunks.
fn allocations_per_frame<D: Decoder>(
    mut decoder: D,
    wire: &[u8],
    mut consume: impl FnMut(D::Item) -> u64,
) -> PerFrame
where
    D::Error: std::fmt::Debug,
{
    let chunk: Vec<u8> = wire.repeat(CHUNK_FRAMES);
    let mut buf = BytesMut::with_capacity(8 * 1024);
    let mut run = |buf: &mut BytesMut, decoded: &mut u64| -> u64 {
        buf.extend_from_slice(&chunk);
        let mut owned = 0;
        while let Some(item) = decoder.decode(buf).expect("valid frames") {
            *decoded += 1;
            owned += consume(item);
        }
        owned
    };
    let mut warm_up_frames = 0;
    for _ in 0..WARM_UP_CHUNKS {
        run(&mut buf, &mut warm_up_frames);
    }
    let mut frames = 0;
    let mut owned = 0;
    let before = allocations();
    for _ in 0..COUNTED_CHUNKS {
        owned += run(&mut buf, &mut frames);
    }
    let total = allocations() - before;
    assert_eq!(frames, (COUNTED_CHUNKS * CHUNK_FRAMES) as u64);
    PerFrame {
        total: total as f64 / frames as f64,
        owned_by_value: owned as f64 / frames as f64,
    }
}

#[test]
fn wsg_decoding_allocates_nothing_per_frame() {
    use gripper::wsg::{frame, Frame, Reply, Status, WsgCodec};
    // The width reply (0x43): status E_SUCCESS and an f32.
    let reply = Reply::new(0x43, Status::Success, 12.5f32.to_le_bytes().to_vec());
    let mut wire = BytesMut::new();
    frame::encode(&reply.to_frame(), &mut wire).unwrap();

    // The frame's payload is a view into the receive buffer: it owns no allocation of its own.
    let per_frame = allocations_per_frame(WsgCodec::new(), &wire, |f: Frame| {
        drop(f);
        0
    });
    println!("wsg width reply, codec decode: {per_frame:?} allocations per frame");
    assert_eq!(per_frame.beyond_value(), 0.0);

    // Typed as the client's task types it: status code and data, still a view.
    let per_reply = allocations_per_frame(WsgCodec::new(), &wire, |f: Frame| {
        let r = Reply::from_frame(f).expect("well-formed reply");
        assert_eq!(r.status, Status::Success);
        0
    });
    println!(
        "wsg width reply, codec decode + Reply::from_frame: {per_reply:?} allocations per frame"
    );
    assert_eq!(per_reply.beyond_value(), 0.0);
}

#[test]
fn smartgrasp_decoding_allocates_nothing_per_frame() {
    use gripper::smartgrasp::codec::ClientCodec;
    use gripper::smartgrasp::frame::{AnyResponseFrame, ResponseFrame};
    use gripper::smartgrasp::{MessageType, Response, ResponseCode, ServerState};
    let mut f = ResponseFrame::new(MessageType::GetState, ResponseCode::Success, 1);
    f.server_state = ServerState::Operational;
    let wire = f.encode();

    let per_frame = allocations_per_frame(ClientCodec::default(), &wire, |f: AnyResponseFrame| {
        assert!(matches!(f, AnyResponseFrame::V3(f) if f.server_state == ServerState::Operational));
        0
    });
    println!("smartgrasp GET_STATE response, codec decode: {per_frame:?} allocations per frame");
    assert_eq!(per_frame.beyond_value(), 0.0);

    let per_response =
        allocations_per_frame(ClientCodec::default(), &wire, |f: AnyResponseFrame| {
            let r = Response::from_any_frame(&f).expect("well-formed response");
            assert_eq!(r.code, ResponseCode::Success);
            0
        });
    println!(
        "smartgrasp GET_STATE response, codec decode + Response::from_frame: {per_response:?} \
         allocations per frame"
    );
    assert_eq!(per_response.beyond_value(), 0.0);
}

#[test]
fn griplink_decoding_allocates_only_the_line_it_returns() {
    use gripper::griplink::codec::{Line, LineCodec};
    use gripper::griplink::reply::{parse_reply, Reply};

    // The decoded line owns one allocation, its `String`; the decoder adds none. (The counts
    // claimed by the closures are checked both ways: too few or too many leaves a difference
    // from the total, which fails the assertion.)
    let per_line = allocations_per_frame(
        LineCodec::default(),
        b"VALUEF[0][0]=42.456\n",
        |l| match l {
            Line::Text(t) => {
                assert_eq!(t, "VALUEF[0][0]=42.456");
                1
            }
            Line::Discarded(d) => panic!("valid line discarded: {d}"),
        },
    );
    println!("griplink VALUEF line, codec decode: {per_line:?} allocations per line");
    assert_eq!(per_line.beyond_value(), 0.0);

    // Parsing owns the key `String` and the indices `Vec` of the returned `Data`.
    let per_parse = allocations_per_frame(LineCodec::default(), b"VALUEF[0][0]=42.456\n", |l| {
        let Line::Text(t) = l else {
            panic!("valid line discarded")
        };
        match parse_reply(&t).expect("valid reply") {
            Reply::Data(d) => {
                assert_eq!(d.key, "VALUEF");
                // The line's String, the key's String, the indices' Vec.
                3
            }
            other => panic!("unexpected reply {other:?}"),
        }
    });
    println!(
        "griplink VALUEF line, codec decode + parse_reply: {per_parse:?} allocations per line"
    );
    assert_eq!(per_parse.beyond_value(), 0.0);

    // `ACK` owns nothing once parsed; only the decoded line's String was allocated.
    let per_ack = allocations_per_frame(LineCodec::default(), b"ACK\n", |l| {
        let Line::Text(t) = l else {
            panic!("valid line discarded")
        };
        assert_eq!(parse_reply(&t).expect("valid reply"), Reply::Ack);
        1
    });
    println!("griplink ACK line, codec decode + parse_reply: {per_ack:?} allocations per line");
    assert_eq!(per_ack.beyond_value(), 0.0);
}
