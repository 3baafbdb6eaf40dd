//! WSG client throughput and auto-update streams against the simulator over loopback TCP.
//!
//! 1. **Queries in flight from many tasks**: `--tasks` tasks (default 64) each loop over one of
//!    fourteen queries with different command ids (the client pairs replies by id, so at most
//!    fourteen are on the wire at once; tasks sharing an id queue in the client). Reports round
//!    trips per second, latency percentiles, and CPU time per round trip of the client's threads
//!    and of the simulator's thread.
//! 2. **Five auto-update streams at 10 ms** (system state, grip state, width, speed, force: every
//!    value the WSG streams) on one connection, each read by its own task, held for the stated
//!    duration. Reports updates received against those due, updates the client dropped
//!    (`Subscription::missed()`: the only place the client can drop one; TCP loses nothing), the
//!    longest gap between two updates, and the client's CPU % of one core.
//!
//! ```text
//! cargo bench --bench wsg_throughput                  # 3 s of queries, 5 s of streams
//! cargo bench --bench wsg_throughput -- --long        # 20 s of queries, 60 s of streams
//! cargo bench --bench wsg_throughput -- --seconds 10 --stream-seconds 60 --tasks 128
//! ```
//!
//! Runtimes: the simulator runs on a multi-thread runtime with one worker (`sim`). The client runs
//! once on a `current_thread` runtime (thread `client`; caller tasks and the connection task
//! share it) and once on a 2-worker multi-thread runtime (`client-mt`, the `#[tokio::main]`
//! default here). The streams run on a `current_thread` runtime (thread `client`).

#[path = "common/mod.rs"]
mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{flag_value, has_flag, percentile, thread_cpu_ns, us};
use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{Client, Finger, UpdateOptions};
use tokio::task::JoinSet;

/// Fourteen queries, fourteen command ids.
const QUERIES: [(u8, &str); 14] = [
    (0x31, "acceleration"),
    (0x33, "grasping force"),
    (0x40, "system state"),
    (0x41, "grip state"),
    (0x42, "grasping statistics"),
    (0x43, "width"),
    (0x44, "speed"),
    (0x45, "force"),
    (0x46, "temperature"),
    (0x50, "system info"),
    (0x53, "system limits"),
    (0x60, "finger 1 info"),
    (0x61, "finger 1 flags"),
    (0x70, "finger 2 info"),
];

async fn query(c: &Client, id: u8) {
    let ok = match id {
        0x31 => c.acceleration_mm_per_s2().await.map(drop),
        0x33 => c.grasping_force_n().await.map(drop),
        0x40 => c.system_state().await.map(drop),
        0x41 => c.grip_state().await.map(drop),
        0x42 => c.grasping_statistics(false).await.map(drop),
        0x43 => c.width_mm().await.map(drop),
        0x44 => c.speed_mm_per_s().await.map(drop),
        0x45 => c.force_n().await.map(drop),
        0x46 => c.temperature_c().await.map(drop),
        0x50 => c.system_info().await.map(drop),
        0x53 => c.system_limits().await.map(drop),
        0x60 => c.finger_info(Finger::One).await.map(drop),
        0x61 => c.finger_flags(Finger::One).await.map(drop),
        0x70 => c.finger_info(Finger::Two).await.map(drop),
        _ => unreachable!("not in QUERIES"),
    };
    if let Err(e) = ok {
        panic!("query 0x{id:02x} failed: {e}");
    }
}

struct Throughput {
    requests: usize,
    wall: Duration,
    latencies: Vec<Duration>,
    client_cpu_ns: u64,
    sim_cpu_ns: u64,
}

/// Runs `tasks` query loops for `seconds` on the current runtime.
async fn throughput(
    addr: std::net::SocketAddr,
    tasks: usize,
    seconds: f64,
    cpu: &str,
) -> Throughput {
    let client = Client::connect_tcp(addr).await.expect("connect");
    // Warm-up: every query once.
    for (id, _) in QUERIES {
        query(&client, id).await;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let (cpu0, sim0) = (thread_cpu_ns(cpu), thread_cpu_ns("sim"));
    let start = Instant::now();
    let mut set = JoinSet::new();
    for t in 0..tasks {
        let (client, stop) = (client.clone(), stop.clone());
        let id = QUERIES[t % QUERIES.len()].0;
        set.spawn(async move {
            let mut lat = Vec::with_capacity(1 << 12);
            while !stop.load(Ordering::Relaxed) {
                let t0 = Instant::now();
                query(&client, id).await;
                lat.push(t0.elapsed());
            }
            lat
        });
    }
    tokio::time::sleep(Duration::from_secs_f64(seconds)).await;
    stop.store(true, Ordering::Relaxed);
    let mut latencies = Vec::new();
    while let Some(r) = set.join_next().await {
        latencies.extend(r.expect("query task"));
    }
    let wall = start.elapsed();
    let (cpu1, sim1) = (thread_cpu_ns(cpu), thread_cpu_ns("sim"));
    client.close().await.expect("close");
    latencies.sort();
    Throughput {
        requests: latencies.len(),
        wall,
        latencies,
        client_cpu_ns: cpu1 - cpu0,
        sim_cpu_ns: sim1 - sim0,
    }
}

fn report(variant: &str, tasks: usize, t: &Throughput) {
    let n = t.requests as f64;
    println!(
        "| {variant} | {tasks} | {} | {:.1} | {:.0} | {} | {} | {:.2} | {:.2} |",
        t.requests,
        t.wall.as_secs_f64(),
        n / t.wall.as_secs_f64(),
        us(percentile(&t.latencies, 50.0)),
        us(percentile(&t.latencies, 99.0)),
        t.client_cpu_ns as f64 / n / 1000.0,
        t.sim_cpu_ns as f64 / n / 1000.0,
    );
}

struct StreamStats {
    name: &'static str,
    received: u64,
    due: u64,
    missed: u64,
    max_gap: Duration,
    gaps_over_1_5_periods: u64,
}

/// Reads one subscription until `until`; records what arrived after the first (the reply to the
/// subscription) and how far apart.
async fn drain<T>(
    name: &'static str,
    mut sub: gripper::wsg::Subscription<T>,
    period: Duration,
    until: Instant,
) -> StreamStats {
    let first = sub.next().await.expect("first update");
    drop(first);
    let started = Instant::now();
    let mut last = started;
    let (mut received, mut max_gap, mut gaps) = (0u64, Duration::ZERO, 0u64);
    while let Ok(Some(v)) = tokio::time::timeout_at(until.into(), sub.next()).await {
        drop(v);
        let now = Instant::now();
        let gap = now - last;
        max_gap = max_gap.max(gap);
        if gap > period * 3 / 2 {
            gaps += 1;
        }
        last = now;
        received += 1;
    }
    let elapsed = last - started;
    StreamStats {
        name,
        received,
        due: (elapsed.as_secs_f64() / period.as_secs_f64()).round() as u64,
        missed: sub.missed(),
        max_gap,
        gaps_over_1_5_periods: gaps,
    }
}

async fn streams(addr: std::net::SocketAddr, seconds: f64) {
    let period = Duration::from_millis(10);
    let opts = UpdateOptions::periodic(period);
    let client = Client::connect_tcp(addr).await.expect("connect");
    let until = Instant::now() + Duration::from_secs_f64(seconds) + Duration::from_millis(200);
    let (cpu0, sim0, t0) = (
        thread_cpu_ns("client"),
        thread_cpu_ns("sim"),
        Instant::now(),
    );
    let canary = common::Canary::start();
    let mut set = JoinSet::new();
    set.spawn(drain(
        "system state",
        client
            .subscribe_system_state(opts)
            .await
            .expect("subscribe"),
        period,
        until,
    ));
    set.spawn(drain(
        "grip state",
        client.subscribe_grip_state(opts).await.expect("subscribe"),
        period,
        until,
    ));
    set.spawn(drain(
        "width",
        client.subscribe_width_mm(opts).await.expect("subscribe"),
        period,
        until,
    ));
    set.spawn(drain(
        "speed",
        client
            .subscribe_speed_mm_per_s(opts)
            .await
            .expect("subscribe"),
        period,
        until,
    ));
    set.spawn(drain(
        "force",
        client.subscribe_force_n(opts).await.expect("subscribe"),
        period,
        until,
    ));
    let mut stats = Vec::new();
    while let Some(s) = set.join_next().await {
        stats.push(s.expect("stream task"));
    }
    let wall = t0.elapsed();
    let (cpu1, sim1) = (thread_cpu_ns("client"), thread_cpu_ns("sim"));
    let canary = canary.stop();
    client.close().await.expect("close");
    stats.sort_by_key(|s| s.name);
    println!("| stream | received | due (elapsed / 10 ms) | dropped by client (missed) | gaps > 15 ms | longest gap ms |");
    println!("|---|---:|---:|---:|---:|---:|");
    for s in &stats {
        println!(
            "| {} | {} | {} | {} | {} | {:.2} |",
            s.name,
            s.received,
            s.due,
            s.missed,
            s.gaps_over_1_5_periods,
            s.max_gap.as_secs_f64() * 1e3
        );
    }
    let received: u64 = stats.iter().map(|s| s.received).sum();
    println!();
    println!(
        "five streams for {:.1} s: {received} updates, {} dropped by the client; client threads \
         {:.2} % of one core ({:.1} µs per update), simulator thread {:.2} % of one core",
        wall.as_secs_f64(),
        stats.iter().map(|s| s.missed).sum::<u64>(),
        (cpu1 - cpu0) as f64 / wall.as_nanos() as f64 * 100.0,
        (cpu1 - cpu0) as f64 / received.max(1) as f64 / 1000.0,
        (sim1 - sim0) as f64 / wall.as_nanos() as f64 * 100.0,
    );
    println!("{canary}");
}

fn main() {
    let long = has_flag("--long");
    let seconds: f64 = flag_value("--seconds").unwrap_or(if long { 20.0 } else { 3.0 });
    let stream_seconds: f64 =
        flag_value("--stream-seconds").unwrap_or(if long { 60.0 } else { 5.0 });
    let tasks: usize = flag_value("--tasks").unwrap_or(64);
    println!("machine: {}", common::machine());

    let sim_rt = common::runtime("sim", 1);
    let sim = sim_rt
        .block_on(SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50)))
        .expect("WSG simulator");
    let addr = sim.local_addr().expect("TCP address");

    println!();
    println!(
        "queries with {} different command ids from {tasks} tasks, {seconds} s per variant",
        QUERIES.len()
    );
    println!();
    println!("| client runtime | tasks | round trips | s | round trips/s | p50 µs | p99 µs | client CPU µs/round trip | simulator CPU µs/round trip |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let ct =
        common::on_current_thread("client", move || throughput(addr, tasks, seconds, "client"));
    report("current_thread", tasks, &ct);
    let mt_rt = common::runtime("client-mt", 2);
    let mt = mt_rt.block_on(throughput(addr, tasks, seconds, "client-mt"));
    drop(mt_rt);
    report("multi_thread(2)", tasks, &mt);

    println!();
    println!("five auto-update streams at 10 ms on one connection, {stream_seconds} s");
    println!();
    common::on_current_thread("client", move || streams(addr, stream_seconds));
    println!();
    println!("load average at the end: {}", common::load());
    let _guard = sim_rt.enter();
    drop(sim);
}
