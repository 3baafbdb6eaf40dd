//! Cancellation: calls dropped at every await point and after random delays, while other tasks
//! keep calling; every call that survives must get the answer to its own request.
//!
//! The scene has classes 1..=12, with `class` objects of each, each object's grasp having a
//! stroke of `class` mm: a GET_OBJECT_COUNT or GET_GRASP answer names the request it belongs to
//! (object class, candidate count, stroke), so a reply handed to the wrong caller is caught.
//! Random choices come from a seeded generator: a failure reproduces.
#![cfg(feature = "sim")]

mod common;

use common::Rng;
use std::future::Future;
use std::pin::pin;
use std::task::Poll;
use std::time::Duration;

use gripper::fault::{Fault, FaultProxy, Framing, ProxyConfig};
use gripper::smartgrasp::codec;
use gripper::smartgrasp::sim::{SimConfig, SimGrasp, SimObject, SimProject, SimServer};

/// The V3 simulator these tests were written for (the default speaks V4 too; V4 is
/// `tests/smartgrasp_v4.rs`).
fn v3_sim() -> SimConfig {
    SimConfig {
        max_version: 3,
        ..SimConfig::default()
    }
}
use gripper::smartgrasp::{
    Client, ClientConfig, GetGraspOutcome, GraspMode, GraspRequest, PoseFormat, SiPose, Tool,
    UnitQuaternion,
};

const CLASSES: u16 = 12;
const LIMIT: Duration = Duration::from_secs(20);

async fn within<F: Future>(what: &str, future: F) -> F::Output {
    tokio::time::timeout(LIMIT, future)
        .await
        .unwrap_or_else(|_| panic!("hung: {what}"))
}

fn scene() -> SimConfig {
    let mut objects = Vec::new();
    for class in 1..=CLASSES {
        for instance in 0..class {
            objects.push(SimObject {
                class_id: class,
                instance,
                grasps: vec![SimGrasp {
                    tool: Tool::Exterior,
                    active: true,
                    stroke_um: i32::from(class) * 1000,
                    angle_offset_udeg: 0,
                    center_offset_um: [0; 3],
                    object_offset: gripper::smartgrasp::ObjectOffset::default(),
                    pose: SiPose {
                        position_m: [0.4, f64::from(class) / 100.0, 0.05],
                        orientation: UnitQuaternion::from_rpy(std::f64::consts::PI, 0.0, 0.0),
                    },
                }],
                auto_grasp: None,
            });
        }
    }
    SimConfig {
        projects: vec![SimProject::from_scene(objects)],
        ..v3_sim()
    }
}

/// One call whose answer identifies its request; panics if it got another request's answer.
async fn identified_call(client: &Client, class: u16, grasp: bool) {
    if grasp {
        let request = GraspRequest {
            grasp_mode: GraspMode::ActiveGrasp,
            object_class: class,
            tool: Tool::Exterior,
            selection_criterion: gripper::smartgrasp::SelectionCriterion::default(),
            pose_format: PoseFormat::Wpr,
        };
        match client.get_grasp(request).await {
            Ok(GetGraspOutcome::Grasp(g)) => {
                assert_eq!(g.object_class, class);
                assert_eq!(g.stroke_um, i32::from(class) * 1000);
                assert_eq!(g.candidate_count, class);
            }
            other => panic!("GET_GRASP for class {class}: {other:?}"),
        }
    } else {
        match client.get_object_count(class).await {
            Ok(count) => {
                assert_eq!(count.object_class, class);
                assert_eq!(count.candidate_count, class);
            }
            Err(e) => panic!("GET_OBJECT_COUNT for class {class}: {e}"),
        }
    }
}

#[derive(Default, Debug)]
struct Tally {
    completed: u32,
    cancelled: u32,
}

/// Drops calls after `k` polls (k = 0, 1, 2, … covers every await point of a call: queued,
/// sent, waiting for the reply) or after a random delay, and checks those that complete.
async fn canceller(client: Client, seed: u64, rounds: u32, max_delay: Duration) -> Tally {
    let mut rng = Rng(seed);
    let mut tally = Tally::default();
    for _ in 0..rounds {
        let class = 1 + rng.below(u64::from(CLASSES)) as u16;
        let grasp = rng.below(2) == 0;
        let call = identified_call(&client, class, grasp);
        let finished = if rng.below(2) == 0 {
            // Poll it `polls` times, yielding between polls, then drop it.
            let polls = rng.below(6);
            let mut call = pin!(call);
            let mut finished = false;
            for _ in 0..polls {
                if let Poll::Ready(()) = futures_util::poll!(call.as_mut()) {
                    finished = true;
                    break;
                }
                tokio::task::yield_now().await;
            }
            finished
        } else {
            let delay = max_delay.mul_f64(rng.below(1000) as f64 / 1000.0);
            tokio::select! {
                () = call => true,
                () = tokio::time::sleep(delay) => false,
            }
        };
        if finished {
            tally.completed += 1;
        } else {
            tally.cancelled += 1;
        }
    }
    tally
}

/// Calls that are never cancelled, alongside the cancellers.
async fn steady(client: Client, seed: u64, rounds: u32) {
    let mut rng = Rng(seed);
    for _ in 0..rounds {
        let class = 1 + rng.below(u64::from(CLASSES)) as u16;
        identified_call(&client, class, rng.below(2) == 0).await;
    }
}

/// `max_delay`: about two round trips, so that random delays cancel some calls and not others.
async fn run(client: Client, max_delay: Duration) {
    let mut tasks = tokio::task::JoinSet::new();
    for seed in 1..=4u64 {
        tasks.spawn(canceller(
            client.clone(),
            seed * 0x9E37_79B9,
            150,
            max_delay,
        ));
    }
    let mut steady_tasks = tokio::task::JoinSet::new();
    for seed in 11..=13u64 {
        steady_tasks.spawn(steady(client.clone(), seed, 100));
    }
    let mut total = Tally::default();
    while let Some(tally) = within("cancellers", tasks.join_next()).await {
        let tally = tally.expect("a canceller saw a wrong answer");
        total.completed += tally.completed;
        total.cancelled += tally.cancelled;
    }
    while let Some(done) = within("steady callers", steady_tasks.join_next()).await {
        done.expect("a steady caller saw a wrong answer");
    }
    eprintln!("{total:?}");
    // The test means something only if both happened (the split between them depends on the
    // machine's speed, so only their presence is asserted).
    assert!(total.completed > 0, "{total:?}");
    assert!(total.cancelled > 0, "{total:?}");
    // And the connection is still in step.
    for class in 1..=CLASSES {
        within("after", identified_call(&client, class, class % 2 == 0)).await;
    }
    assert!(!client.is_closed());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dropped_calls_never_hand_a_reply_to_another_caller() {
    let server = SimServer::bind("127.0.0.1:0", scene()).await.unwrap();
    let client = Client::connect(server.local_addr(), ClientConfig::default())
        .await
        .unwrap();
    run(client, Duration::from_micros(400)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dropped_calls_through_a_wire_that_splits_and_delays() {
    // More await points: frames arrive in pieces and some late, so calls are dropped with
    // part of their reply read.
    let server = SimServer::bind("127.0.0.1:0", scene()).await.unwrap();
    let proxy = FaultProxy::start_with(
        server.local_addr(),
        ProxyConfig::new()
            .framing(Framing::Custom(codec::proxy_frame_len))
            .seed(7),
    )
    .await
    .unwrap();
    let replies = proxy.server_to_client();
    let split = replies.add(
        Fault::Split {
            piece_len: 30,
            pause: Duration::from_micros(200),
        }
        .randomly(3),
    );
    let delay = replies.add(Fault::Delay(Duration::from_micros(500)).randomly(5));
    let client = Client::connect(proxy.local_addr(), ClientConfig::default())
        .await
        .unwrap();
    run(client, Duration::from_millis(20)).await;
    assert!(split.fired() > 0 && delay.fired() > 0);
}
