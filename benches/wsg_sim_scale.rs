//! Simulator scale: one WSG simulator serving 100 TCP connections, each streaming the width
//! (0x43 with auto-update) every 10 ms, for the stated duration. Reports how late updates are:
//! per connection, the longest interval between two updates minus the period, and over all
//! connections the distribution of intervals and how many exceeded two periods (an update late
//! by more than a period).
//!
//! ```text
//! cargo bench --bench wsg_sim_scale                        # 100 connections, 5 s
//! cargo bench --bench wsg_sim_scale -- --long              # 100 connections, 60 s
//! cargo bench --bench wsg_sim_scale -- --connections 100 --seconds 30 --sim-workers 2
//! cargo bench --bench wsg_sim_scale -- --long --grippers  # 100 simulated grippers instead
//! ```
//!
//! By default the 100 connections go to one simulated gripper (one `SimServer`: one device,
//! one actor task serving every session). With `--grippers`, the process serves one simulated
//! gripper per connection instead (100 `SimServer`s on the same runtime), the other reading of
//! "one simulator process serving 100 simulated grippers".
//!
//! The simulator runs on its own multi-thread runtime (`sim`, `--sim-workers`, default 2: the
//! `#[tokio::main]` default on this machine, as in `examples/wsg_simulator.rs`). The receivers are
//! deliberately light so that they measure the simulator, not a client: one task per connection
//! on a `current_thread` runtime (thread `clients`) reading frames with the crate's `WsgCodec`
//! and taking a timestamp per update. Their timestamps include their own scheduling delay, so
//! the lateness reported is an upper bound on the simulator's.

#[path = "common/mod.rs"]
mod common;

use std::time::{Duration, Instant};

use bytes::BytesMut;
use common::{flag_value, has_flag, percentile, thread_cpu_ns};
use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SimConfig, SimServer};
use gripper::wsg::{frame, Command, UpdateMode, WsgCodec};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;
use tokio::task::JoinSet;
use tokio_util::codec::FramedRead;

const PERIOD: Duration = Duration::from_millis(10);

struct Connection {
    intervals: Vec<Duration>,
}

/// Connects, turns width updates on, and records the interval between consecutive updates from
/// `from` until `until` (updates before `from` only warm the connection up).
async fn receive(addr: std::net::SocketAddr, from: Instant, until: Instant) -> Connection {
    let stream = TcpStream::connect(addr).await.expect("connect");
    stream.set_nodelay(true).expect("nodelay");
    let (read, mut write) = stream.into_split();
    let mut wire = BytesMut::new();
    let mode = UpdateMode {
        auto: true,
        on_change: false,
        period_ms: PERIOD.as_millis() as u16,
    };
    frame::encode(&Command::Width(mode).to_frame(), &mut wire).expect("encode");
    write.write_all(&wire).await.expect("subscribe");
    let mut frames = FramedRead::new(read, WsgCodec::new());
    let mut intervals = Vec::with_capacity(8192);
    let mut last: Option<Instant> = None;
    loop {
        let next = tokio::time::timeout_at(until.into(), frames.next()).await;
        let Ok(Some(Ok(f))) = next else { break };
        assert_eq!(f.id, 0x43, "width updates only");
        let now = Instant::now();
        if now >= from {
            if let Some(l) = last {
                intervals.push(now - l);
            }
            last = Some(now);
        }
    }
    // Announce the disconnect (manual 3.1.2), so the simulated gripper does not go into FAST
    // STOP when the connection closes.
    wire.clear();
    frame::encode(&Command::AnnounceDisconnect.to_frame(), &mut wire).expect("encode");
    let _ = write.write_all(&wire).await;
    Connection { intervals }
}

fn main() {
    let long = has_flag("--long");
    let seconds: f64 = flag_value("--seconds").unwrap_or(if long { 60.0 } else { 5.0 });
    let connections: usize = flag_value("--connections").unwrap_or(100);
    let sim_workers: usize = flag_value("--sim-workers").unwrap_or(2);
    let grippers = has_flag("--grippers");
    println!("machine: {}", common::machine());
    println!(
        "{} ({sim_workers} worker threads), {connections} connections streaming width every \
         {} ms, {seconds} s measured after 1 s of warm-up",
        if grippers {
            "one simulated WSG gripper per connection, one process"
        } else {
            "one simulated WSG gripper"
        },
        PERIOD.as_millis()
    );

    let sim_rt = common::runtime("sim", sim_workers);
    let servers: Vec<SimServer> = sim_rt.block_on(async {
        let mut servers = Vec::new();
        for _ in 0..if grippers { connections } else { 1 } {
            let server = SimServer::bind("127.0.0.1:0", SimConfig::new(Model::Wsg50))
                .await
                .expect("WSG simulator");
            servers.push(server);
        }
        servers
    });
    let addrs: Vec<std::net::SocketAddr> = servers
        .iter()
        .map(|s| s.local_addr().expect("TCP address"))
        .collect();

    let (results, wall, sim_cpu, clients_cpu, canary) =
        common::on_current_thread("clients", move || async move {
            let from = Instant::now() + Duration::from_secs(1);
            let until = from + Duration::from_secs_f64(seconds);
            let mut set = JoinSet::new();
            for i in 0..connections {
                set.spawn(receive(addrs[i % addrs.len()], from, until));
            }
            // CPU is measured over the measured window only.
            tokio::time::sleep_until(from.into()).await;
            let (sim0, c0) = (thread_cpu_ns("sim"), thread_cpu_ns("clients"));
            let canary = common::Canary::start();
            tokio::time::sleep_until(until.into()).await;
            let canary = canary.stop();
            let (sim1, c1) = (thread_cpu_ns("sim"), thread_cpu_ns("clients"));
            let mut results = Vec::new();
            while let Some(r) = set.join_next().await {
                results.push(r.expect("receiver"));
            }
            (results, until - from, (sim0, sim1), c1 - c0, canary)
        });

    let mut all: Vec<Duration> = results
        .iter()
        .flat_map(|c| c.intervals.iter().copied())
        .collect();
    all.sort();
    let updates = all.len() + results.len();
    let due = (connections as f64 * wall.as_secs_f64() / PERIOD.as_secs_f64()).round() as usize;
    let mut lateness: Vec<Duration> = results
        .iter()
        .map(|c| {
            c.intervals
                .iter()
                .max()
                .copied()
                .unwrap_or_default()
                .saturating_sub(PERIOD)
        })
        .collect();
    lateness.sort();
    let late_by_more_than_a_period = all.iter().filter(|d| **d > PERIOD * 2).count();
    let silent = results.iter().filter(|c| c.intervals.is_empty()).count();

    println!();
    println!("| connections | s | updates received | updates due | interval p50 ms | p99 ms | p99.9 ms | max ms | worst lateness (max interval − period) ms | median per-connection lateness ms | intervals > 2 periods | simulator CPU % of one core | receivers CPU % |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let ms = |d: Duration| format!("{:.2}", d.as_secs_f64() * 1e3);
    println!(
        "| {connections} | {:.0} | {updates} | {due} | {} | {} | {} | {} | {} | {} | {late_by_more_than_a_period} | {:.1} | {:.1} |",
        wall.as_secs_f64(),
        ms(percentile(&all, 50.0)),
        ms(percentile(&all, 99.0)),
        ms(percentile(&all, 99.9)),
        ms(all.last().copied().unwrap_or_default()),
        ms(lateness.last().copied().unwrap_or_default()),
        ms(percentile(&lateness, 50.0)),
        (sim_cpu.1 - sim_cpu.0) as f64 / wall.as_nanos() as f64 * 100.0,
        clients_cpu as f64 / wall.as_nanos() as f64 * 100.0,
    );
    println!();
    println!("{canary}");
    if silent > 0 {
        println!("{silent} connections received no update in the measured window");
    }
    println!();
    println!("load average at the end: {}", common::load());
    let _guard = sim_rt.enter();
    drop(servers);
}
