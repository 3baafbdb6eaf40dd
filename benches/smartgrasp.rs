//! GET_GRASP request encode and response decode, plain and through the codec, each beside a
//! floor: a plain copy of the same 80 bytes.
//!
//! `cargo bench --bench smartgrasp -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;

use bytes::BytesMut;
use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion, Throughput};
use gripper::smartgrasp::codec::ClientCodec;
use gripper::smartgrasp::frame::{ResponseFrame, FRAME_LEN};
use gripper::smartgrasp::{
    Grasp, GraspMode, GraspRequest, MessageType, Pose, PoseFormat, QuaternionPose, Request,
    Response, ResponseBody, ResponseCode, Tool,
};
use tokio_util::codec::{Decoder, Encoder};

fn request() -> Request {
    Request::GetGrasp(GraspRequest {
        grasp_mode: GraspMode::AutoGrasp,
        object_class: 0,
        tool: Tool::Exterior,
        selection_criterion: gripper::smartgrasp::SelectionCriterion::default(),
        pose_format: PoseFormat::Quaternion,
    })
}

/// The manual's 6.5 example response.
fn response_bytes() -> [u8; FRAME_LEN] {
    Response {
        message_type: MessageType::GetGrasp,
        code: ResponseCode::Success,
        counter: 3,
        body: ResponseBody::Grasp(Grasp {
            grasp_mode: GraspMode::AnyGrasp,
            object_class: 3,
            object_instance: 0,
            stroke_um: 86_000,
            angle_offset_udeg: Some(-25_210_142),
            center_offset_um: [-911, -310],
            center_offset_z_um: Some(68),
            tool: Some(Tool::Exterior),
            reference_frame: None,
            object_offset: None,
            pose: Pose::Quaternion(QuaternionPose {
                position_um: [853_798, 111_998, 502_790],
                quaternion_e6: [775_990, 630_744, 0, 0],
            }),
            object_count: 2,
            candidate_count: 2,
        }),
    }
    .to_frame(3)
    .encode()
}

/// The floors: copying the 80 bytes, and copying them into a `BytesMut` as a codec does.
fn copy_floors(g: &mut BenchmarkGroup<'_, WallTime>, bytes: &[u8; FRAME_LEN], buf: &mut BytesMut) {
    g.bench_function("floor_copy_80_bytes", |b| {
        b.iter(|| black_box(*black_box(bytes)))
    });
    g.bench_function("floor_copy_into_bytesmut", |b| {
        b.iter(|| {
            buf.clear();
            buf.extend_from_slice(black_box(bytes));
            black_box(&*buf);
        })
    });
}

fn encode(c: &mut Criterion) {
    let mut g = c.benchmark_group("smartgrasp/get_grasp_request_encode");
    g.throughput(Throughput::Bytes(FRAME_LEN as u64));
    let request = request();
    let bytes = request.to_frame().encode();
    g.bench_function("frame_encode", |b| {
        b.iter(|| black_box(black_box(&request).to_frame().encode()))
    });
    let mut buf = BytesMut::with_capacity(FRAME_LEN);
    copy_floors(&mut g, &bytes, &mut buf);
    g.bench_function("codec_encode", |b| {
        b.iter(|| {
            buf.clear();
            ClientCodec::default()
                .encode(black_box(&request).to_frame(), &mut buf)
                .unwrap();
            black_box(&buf);
        })
    });
    g.finish();
}

fn decode(c: &mut Criterion) {
    let mut g = c.benchmark_group("smartgrasp/get_grasp_response_decode");
    g.throughput(Throughput::Bytes(FRAME_LEN as u64));
    let bytes = response_bytes();
    g.bench_function("frame_decode", |b| {
        b.iter(|| black_box(ResponseFrame::decode(black_box(&bytes))))
    });
    g.bench_function("typed_response", |b| {
        b.iter(|| {
            black_box(Response::from_frame(&ResponseFrame::decode(black_box(
                &bytes,
            ))))
        })
    });
    let mut buf = BytesMut::with_capacity(FRAME_LEN);
    copy_floors(&mut g, &bytes, &mut buf);
    g.bench_function("codec_decode", |b| {
        b.iter(|| {
            buf.extend_from_slice(black_box(&bytes));
            black_box(ClientCodec::default().decode(&mut buf).unwrap())
        })
    });
    g.finish();
}

criterion_group!(benches, encode, decode);
criterion_main!(benches);
