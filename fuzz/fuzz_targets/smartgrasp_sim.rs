//! The SmartGrasp simulator's request parser and state machine fed arbitrary bytes.
//!
//! Input: `[config, stream..]`. The first byte picks the simulator's configuration (highest
//! protocol version 2, 3 or 4, server state, first response counter, an injected fault every so
//! often); the
//! stream is parsed with `parse_request` frame after frame, exactly as the server's connection
//! loop does, and every frame goes through one `SimState::handle` (the state persists across the
//! frames of one input, so the fuzzer can build sequences: SET_PROJECT, GET_GRASP, GRASP_FEEDBACK).
//!
//! Checked, besides "no panic":
//! - `parse_request` agrees with the server codec, consumes exactly 80 bytes per frame and fails
//!   only on a prefix length other than 74;
//! - a response has the request's message type and version, is a response, carries the next
//!   response counter (+1 per answered request, wrapping), is in the layout of the request's
//!   version (V4 for 4), and is something the client can read (`Response::from_any_frame`, the
//!   pose of a grasp convertible to SI units);
//! - the "too old" answer only when the request's version is above the server's.
#![no_main]

use std::collections::VecDeque;
use std::time::Duration;

use bytes::BytesMut;
use gripper::smartgrasp::codec::ServerCodec;
use gripper::smartgrasp::frame::{AnyRequestFrame, AnyResponseFrame, Prefix, FRAME_LEN, PREFIX_LEN};
use gripper::smartgrasp::sim::{parse_request, Action, Fault, SimConfig, SimState};
use gripper::smartgrasp::{CommunicationType, Response, ResponseBody, ServerState};
use gripper_fuzz as _; // the bounded allocator
use libfuzzer_sys::fuzz_target;
use tokio_util::codec::Decoder;

fuzz_target!(|data: &[u8]| {
    let Some((&config, mut rest)) = data.split_first() else {
        return;
    };
    let protocol_version = match config & 0x03 {
        0 => 2,
        1 => 3,
        _ => 4,
    };
    let server_state = match (config >> 2) & 0x01 {
        0 => ServerState::Operational,
        _ => ServerState::Init,
    };
    let first_response_counter = if config & 0x08 != 0 { 254 } else { 0 };
    // Bits 4..8: inject a fault before every n-th frame (0: never).
    let fault_every = usize::from(config >> 4);
    let mut state = SimState::new(SimConfig {
        max_version: protocol_version,
        server_state,
        first_response_counter,
        ..SimConfig::default()
    });
    let mut conn = state.connect();
    let mut expected_counter = first_response_counter;
    let mut codec_buf = BytesMut::from(rest);
    let mut handled = 0usize;
    let mut queued = VecDeque::new();

    loop {
        let parsed = parse_request(rest);
        let decoded = ServerCodec.decode(&mut codec_buf);
        match (&parsed, &decoded) {
            (Ok(Some((a, _))), Ok(Some(b))) => assert_eq!(a, b),
            (Ok(None), Ok(None)) | (Err(_), Err(_)) => {}
            _ => panic!("parse_request {parsed:?} and ServerCodec {decoded:?} disagree"),
        }
        let frame = match parsed {
            Ok(Some((frame, used))) => {
                assert_eq!(used, FRAME_LEN);
                rest = &rest[used..];
                frame
            }
            Ok(None) => {
                assert!(rest.len() < FRAME_LEN);
                return;
            }
            Err(_) => {
                let prefix = Prefix::decode(rest[..PREFIX_LEN].try_into().unwrap());
                assert_ne!(prefix.length, 74);
                return;
            }
        };

        handled += 1;
        if fault_every != 0 && handled.is_multiple_of(fault_every) {
            let fault = match handled % 4 {
                0 => Fault::DropReply,
                1 => Fault::DelayReply(Duration::from_millis(1)),
                2 => Fault::CorruptLength(u32::from(config)),
                _ => Fault::Close,
            };
            state.inject(fault);
            queued.push_back(fault);
        }
        let action = state.handle(&mut conn, &frame);
        if frame.version() > protocol_version {
            assert_eq!(
                action,
                Action::RespondEmpty(Prefix {
                    version: protocol_version,
                    length: 0
                })
            );
            // Queued faults stay queued for the next answered request.
            continue;
        }
        let counter = expected_counter;
        expected_counter = expected_counter.wrapping_add(1);
        // Each injected fault replaces the next answered request's response, in order.
        let response = match (queued.pop_front(), action) {
            (None, Action::Respond(r)) => r,
            (Some(Fault::DelayReply(d)), Action::Delay(e, r)) if d == e => r,
            (Some(Fault::CorruptLength(n)), Action::SendRaw(bytes)) => {
                assert_eq!(bytes[2..6], n.to_be_bytes());
                continue;
            }
            (Some(Fault::DropReply), Action::Skip) | (Some(Fault::Close), Action::Close) => {
                continue
            }
            (fault, action) => panic!("fault {fault:?} queued, action {action:?}"),
        };
        let header = response.header();
        assert_eq!(header.communication_type, CommunicationType::Response);
        assert_eq!(header.message_type, frame.header().message_type);
        assert_eq!(header.response_counter, counter);
        assert_eq!(response.version(), frame.version());
        assert_eq!(
            matches!(response, AnyResponseFrame::V4(_)),
            matches!(frame, AnyRequestFrame::V4(_))
        );
        let typed = Response::from_any_frame(&response)
            .unwrap_or_else(|e| panic!("the client cannot read {response:?}: {e}"));
        if let ResponseBody::Grasp(grasp) = typed.body {
            grasp
                .pose
                .to_si()
                .expect("a simulated grasp pose has an orientation");
        }
    }
});
