//! Cancellation: calls dropped at every await point (after exactly `n` polls, and at seeded
//! random times) while other tasks keep calling with mixed ids; every call that survives gets
//! its own answer. Cancelled motion commands keep the fingers moving until a stop.
#![cfg(feature = "sim")]

mod common;

use common::Rng;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use gripper::wsg::command::id;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, HomingDirection, Status, SystemState};

/// Polls `call` at most `polls` times, one scheduler turn apart (it wakes itself), then
/// resolves to `None`, dropping `call` at whichever await point it had reached.
struct PollLimit<F> {
    call: Pin<Box<F>>,
    polls: u32,
}

impl<F: Future> Future for PollLimit<F> {
    type Output = Option<F::Output>;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        if self.polls == 0 {
            return Poll::Ready(None);
        }
        self.polls -= 1;
        let polled = self.call.as_mut().poll(cx).map(Some);
        if polled.is_pending() {
            cx.waker().wake_by_ref();
        }
        polled
    }
}

/// One kind of question whose answer identifies it.
#[derive(Clone, Copy, Debug)]
enum Ask {
    Echo,
    Tag,
    Info,
    Force,
    Temperature,
}

const ASKS: [Ask; 5] = [Ask::Echo, Ask::Tag, Ask::Info, Ask::Force, Ask::Temperature];

/// Asks and checks the answer is the one to this question. `unique` makes each echo payload
/// different from every other call's.
async fn ask_and_check(client: Client, ask: Ask, unique: u64) {
    match ask {
        Ask::Echo => {
            let payload = unique.to_le_bytes().to_vec();
            let echo = client.loop_back(payload.clone()).await.unwrap();
            assert_eq!(&echo[..], &payload[..], "echo {unique}");
        }
        Ask::Tag => assert_eq!(
            client.device_tag().await.unwrap().as_deref(),
            Some("cancel-test")
        ),
        Ask::Info => assert_eq!(client.system_info().await.unwrap().serial_number, 4711),
        Ask::Force => assert_eq!(client.grasping_force_n().await.unwrap(), 33.0),
        Ask::Temperature => assert_eq!(client.temperature_c().await.unwrap(), 23.4),
    }
}

async fn setup() -> (SimServer, Client) {
    let sim = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50))
        .await
        .unwrap();
    let client = Client::builder()
        .query_timeout(Duration::from_secs(5))
        .connect_tcp(sim.local_addr().unwrap())
        .await
        .unwrap();
    client.set_device_tag("cancel-test").await.unwrap();
    client.set_grasping_force(33.0).await.unwrap();
    (sim, client)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calls_dropped_at_any_await_point_never_disturb_the_others() {
    let (_sim, client) = setup().await;
    let mut tasks = Vec::new();
    // Steady callers: every call must succeed with its own answer.
    for t in 0..4u64 {
        let c = client.clone();
        tasks.push(tokio::spawn(async move {
            let mut rng = Rng(0x5EED + t);
            for i in 0..60 {
                let ask = ASKS[rng.below(5) as usize];
                ask_and_check(c.clone(), ask, (t << 32) | i).await;
            }
        }));
    }
    // Cancellers: each call is dropped after a random number of polls or a random short time,
    // unless it finished first; a call that finished is checked like any other.
    let mut cancellers = Vec::new();
    for t in 0..4u64 {
        let c = client.clone();
        cancellers.push(tokio::spawn(async move {
            let mut rng = Rng(0xCA7 + t);
            let mut finished = 0;
            for i in 0..150 {
                let ask = ASKS[rng.below(5) as usize];
                let unique = (1 << 40) | (t << 32) | i;
                let call = ask_and_check(c.clone(), ask, unique);
                if rng.below(2) == 0 {
                    let polls = rng.below(6) as u32;
                    let limited = PollLimit {
                        call: Box::pin(call),
                        polls,
                    };
                    finished += u32::from(limited.await.is_some());
                } else {
                    let after = Duration::from_micros(rng.below(1500));
                    tokio::select! {
                        () = call => finished += 1,
                        () = tokio::time::sleep(after) => {}
                    }
                }
            }
            finished
        }));
    }
    for task in tasks {
        task.await.unwrap();
    }
    let mut finished = 0;
    for task in cancellers {
        finished += task.await.unwrap();
    }
    // Both outcomes happened (600 calls in all): the test is not vacuous.
    assert!(finished > 0 && finished < 600, "{finished} of 600 finished");
    // Afterwards the connection is in order: every kind of question, with fresh payloads.
    for (i, ask) in ASKS.into_iter().enumerate() {
        ask_and_check(client.clone(), ask, 1 << 50 | i as u64).await;
    }
}

#[tokio::test]
async fn a_cancelled_move_keeps_moving_until_stopped() {
    let (sim, client) = setup().await;
    client.home(HomingDirection::Default).await.unwrap();
    // 20 wall seconds per simulated second: the move to 20 mm takes about half a minute.
    sim.set_time_scale(20.0);
    let moving = |state: SystemState| state.contains(SystemState::MOVING);
    tokio::select! {
        r = client.pre_position(20.0, 50.0) => panic!("the move ended early: {r:?}"),
        () = async {
            while !moving(client.system_state().await.unwrap()) {}
        } => {}
    }
    // The call is gone; the fingers are not stopped by that.
    let width = client.width_mm().await.unwrap();
    let mut later = width;
    for _ in 0..100_000 {
        later = client.width_mm().await.unwrap();
        if later < width {
            break;
        }
    }
    assert!(
        later < width,
        "the fingers stopped when the call was dropped"
    );
    assert!(moving(client.system_state().await.unwrap()));
    // A stop still works; the abort reply of the dropped call is consumed, not misdelivered.
    client.stop().await.unwrap();
    let state = client.system_state().await.unwrap();
    assert!(!moving(state) && state.contains(SystemState::AXIS_STOPPED));
    sim.set_time_scale(0.0);
    client.pre_position(60.0, 100.0).await.unwrap();
    assert_eq!(client.width_mm().await.unwrap(), 60.0);
}

#[tokio::test]
async fn a_move_cancelled_before_it_was_sent_is_never_sent() {
    let (sim, client) = setup().await;
    let first = common::wsg_start_moving(&sim, &client).await;
    // A second move of the same id while the first runs is refused unsent (E_ALREADY_RUNNING,
    // manual 3.2.2); dropped before or after that answer, it must never go out.
    let second = PollLimit {
        call: Box::pin(client.pre_position(90.0, 50.0)),
        polls: 3,
    };
    if let Some(result) = second.await {
        assert_eq!(result.unwrap_err().status(), Some(Status::AlreadyRunning));
    }
    client.stop().await.unwrap();
    assert!(first.await.unwrap().is_err());
    // A round trip after the first's abort: had the second been sent, the device has it now.
    client.temperature_c().await.unwrap();
    let sent = sim
        .received_ids()
        .iter()
        .filter(|i| **i == id::PRE_POSITION)
        .count();
    assert_eq!(sent, 1, "the cancelled, unsent move went out");
    assert!(!client
        .system_state()
        .await
        .unwrap()
        .contains(SystemState::MOVING));
}

#[tokio::test]
async fn a_dropped_subscribe_call_leaves_no_stream_behind() {
    let (sim, client) = setup().await;
    let options = gripper::wsg::UpdateOptions::periodic(Duration::from_millis(10));
    let mut cancelled = 0;
    for polls in 1..8 {
        let call = PollLimit {
            call: Box::pin(client.subscribe_width_mm(options)),
            polls,
        };
        match call.await {
            // Subscribed before the limit: dropping the subscription ends it too.
            Some(subscription) => drop(subscription.unwrap()),
            None => cancelled += 1,
        }
    }
    assert!(
        cancelled > 0,
        "every subscribe finished within its poll limit"
    );
    let asked = |sim: &SimServer| {
        sim.received_ids()
            .iter()
            .filter(|i| **i == id::WIDTH)
            .count()
    };
    assert!(asked(&sim) > 0, "no subscription reached the device");
    // Whatever point each call was dropped at, the device ends up sending no updates.
    let mut streams = sim.snapshot().streams;
    for _ in 0..10_000 {
        if streams == 0 {
            break;
        }
        client.temperature_c().await.unwrap();
        streams = sim.snapshot().streams;
    }
    assert_eq!(
        streams, 0,
        "a cancelled subscription left the device streaming"
    );
    // And a new subscription works.
    let mut widths = client.subscribe_width_mm(options).await.unwrap();
    assert_eq!(futures_util::StreamExt::next(&mut widths).await, Some(0.0));
}
