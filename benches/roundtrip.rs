//! Round-trip latency of one query over loopback TCP against each simulator, through the crate's
//! client, side by side in the same run with the floor: a minimal blocking client on a plain
//! `std::net::TcpStream` that writes the same pre-encoded request bytes and reads the reply.
//!
//! Queries: WSG width (0x43), GRIPLINK `VALUE[0][0]?`, SmartGrasp GET_STATE.
//!
//! ```text
//! cargo bench --bench roundtrip                 # quick: 3 runs of 10 rounds of 100 queries
//! cargo bench --bench roundtrip -- --long       # 5 runs of 100 rounds (10,000 queries each)
//! cargo bench --bench roundtrip -- --runs R --rounds N
//! ```
//!
//! Each run measures the three protocols in turn, each with its variants interleaved; the table
//! gives the median over the runs of each variant's p50 and p99, of its p50 ÷ the floor's p50 in
//! the same run (with the lowest and highest such ratio) and of its p99 − the floor's p99.
//!
//! Runtimes, chosen deliberately:
//! - the three simulators share one multi-thread runtime with **one** worker thread (`sim`),
//!   so the server side costs the same for every variant;
//! - `client current_thread`: the client's background task and the caller share one thread (a
//!   `current_thread` runtime on the bench thread, `client`): no cross-thread wake-ups. This is
//!   the cheapest way to run the client and what a single control loop would use;
//! - `client multi_thread`: a 2-worker runtime (`client-mt`), the `#[tokio::main]` default on
//!   this machine; the caller runs in `block_on` on the bench thread, which tokio's I/O driver
//!   (on a worker) has to wake for every reply — the same as for the bare tokio stream below;
//! - `client multi_thread(2), caller spawned`: the same runtime and client, the calls made from a
//!   task spawned on it (a worker thread), as a program that runs its control loop in a task
//!   does; tokio then often runs the connection task and the caller on the same worker;
//! - `raw std::net`: blocking `write_all` + `read` on the bench thread (the floor every ratio is
//!   taken against);
//! - `raw tokio current_thread` / `raw tokio multi_thread(2)`: the same bytes through a bare
//!   `tokio::net::TcpStream` awaited in `block_on` on each runtime — what any tokio client pays
//!   before it adds a channel, a task or pairing, so the client's own cost is the difference.
//!
//! `--only wsg|griplink|smartgrasp [--raw] [--mt] [--calls N] [--tasks T]` runs one protocol's client (or,
//! with `--raw`, the bare tokio stream) alone from the main thread, N queries (default 10,000), on
//! a `current_thread` runtime (or, with `--mt`, from `block_on` on a `multi_thread(2)` one), and
//! prints the wall time and the main thread's CPU time per query. With `--tasks T` the client is
//! called by T callers at once (joined on the same thread), so requests queue and pipeline in
//! the client as they do under a busy program: GRIPLINK and SmartGrasp keep several on the wire,
//! the WSG client one per command id (its pipelined figure is `wsg_throughput`'s, over 14 ids).
//! It is the program to count a round trip's instructions with, a figure that does not move with
//! the machine's load (the simulators run on other threads, so the main thread's count is the
//! client's):
//!
//! ```text
//! cargo bench --bench roundtrip --no-run     # prints the binary's path
//! valgrind --tool=callgrind --separate-threads=yes <binary> --only wsg --calls 1000
//! valgrind --tool=callgrind --separate-threads=yes <binary> --only wsg --calls 5000
//! # the difference of the two runs' totals in callgrind.out.<pid>-01 (the main thread) ÷ 4000
//! ```
//!
//! The variants alternate in blocks of 100 queries, so a change of the machine's load during the
//! run hits all of them alike. Allocations per round trip are counted on the bench thread for the
//! `current_thread` variant, where the caller and the client's task both run.

#[path = "common/mod.rs"]
mod common;
#[path = "common/counting_alloc.rs"]
mod counting_alloc;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::BytesMut;
use common::{flag_value, has_flag, percentile, us};
use counting_alloc::allocations;
use gripper::{griplink, smartgrasp, wsg};
use tokio::runtime::Runtime;

const BLOCK: usize = 100;

#[derive(Clone, Copy, Debug)]
enum Proto {
    Wsg,
    Griplink,
    SmartGrasp,
}

impl Proto {
    fn query(self) -> &'static str {
        match self {
            Proto::Wsg => "WSG width (0x43)",
            Proto::Griplink => "GRIPLINK VALUE[0][0]?",
            Proto::SmartGrasp => "SmartGrasp GET_STATE",
        }
    }

    /// The request bytes, encoded once by the crate's own frame code.
    fn request_bytes(self) -> Vec<u8> {
        match self {
            Proto::Wsg => {
                let mut b = BytesMut::new();
                wsg::frame::encode(
                    &wsg::Command::Width(wsg::UpdateMode::ONCE).to_frame(),
                    &mut b,
                )
                .expect("encode");
                b.to_vec()
            }
            Proto::Griplink => b"VALUE[0][0]?\n".to_vec(),
            Proto::SmartGrasp => smartgrasp::Request::GetState.to_frame().encode().to_vec(),
        }
    }
}

/// The crate's clients, one query each.
enum AnyClient {
    Wsg(wsg::Client),
    Griplink(griplink::Client),
    SmartGrasp(smartgrasp::Client),
}

impl AnyClient {
    async fn connect(proto: Proto, addr: SocketAddr) -> AnyClient {
        match proto {
            Proto::Wsg => AnyClient::Wsg(wsg::Client::connect_tcp(addr).await.expect("connect")),
            Proto::Griplink => {
                AnyClient::Griplink(griplink::Client::connect(addr).await.expect("connect"))
            }
            Proto::SmartGrasp => AnyClient::SmartGrasp(
                smartgrasp::Client::connect(addr, smartgrasp::ClientConfig::default())
                    .await
                    .expect("connect"),
            ),
        }
    }

    async fn query(&self) {
        match self {
            AnyClient::Wsg(c) => {
                std::hint::black_box(c.width_mm().await.expect("width"));
            }
            AnyClient::Griplink(c) => {
                std::hint::black_box(c.port(0).value(0).await.expect("VALUE"));
            }
            AnyClient::SmartGrasp(c) => {
                std::hint::black_box(c.get_state().await.expect("GET_STATE"));
            }
        }
    }

    async fn close(&self) {
        match self {
            AnyClient::Wsg(c) => c.close().await.expect("close"),
            AnyClient::Griplink(c) => c.close().await.expect("close"),
            AnyClient::SmartGrasp(_) => {}
        }
    }
}

/// The floor: a blocking client that writes the pre-encoded request and reads until the reply is
/// complete (checking just enough to know it is the reply).
struct Raw {
    proto: Proto,
    stream: TcpStream,
    request: Vec<u8>,
    buf: [u8; 512],
}

impl Raw {
    fn connect(proto: Proto, addr: SocketAddr) -> Raw {
        let stream = TcpStream::connect(addr).expect("connect");
        stream.set_nodelay(true).expect("nodelay");
        Raw {
            proto,
            stream,
            request: proto.request_bytes(),
            buf: [0; 512],
        }
    }

    fn query(&mut self) {
        self.stream.write_all(&self.request).expect("write");
        let mut have = 0;
        loop {
            let n = self.stream.read(&mut self.buf[have..]).expect("read");
            assert!(n > 0, "simulator closed the connection");
            have += n;
            if complete(self.proto, &self.buf[..have]) {
                return;
            }
        }
    }

    /// WSG: announce the disconnect first, so the simulated gripper does not go into FAST STOP.
    fn close(mut self) {
        if let Proto::Wsg = self.proto {
            let mut b = BytesMut::new();
            wsg::frame::encode(&wsg::Command::AnnounceDisconnect.to_frame(), &mut b)
                .expect("encode");
            self.request = b.to_vec();
            self.stream.write_all(&self.request).expect("write");
            let _ = self.stream.read(&mut self.buf);
        }
    }
}

/// Whether `b` holds the whole reply to the request of `proto` (checking just enough to know it is
/// the reply).
fn complete(proto: Proto, b: &[u8]) -> bool {
    let have = b.len();
    match proto {
        // AA AA AA | id | len LE | status LE, f32 | crc (manual 1.2.1).
        Proto::Wsg => {
            if have < 6 {
                return false;
            }
            let len = usize::from(u16::from_le_bytes([b[4], b[5]]));
            if have < 6 + len + 2 {
                return false;
            }
            assert_eq!((b[3], b[6], b[7]), (0x43, 0, 0), "width reply, E_SUCCESS");
            true
        }
        Proto::Griplink => {
            if b.last() != Some(&b'\n') {
                return false;
            }
            assert!(b.starts_with(b"VALUE[0][0]="), "VALUE reply");
            true
        }
        Proto::SmartGrasp => have >= smartgrasp::frame::FRAME_LEN,
    }
}

/// The floor of any tokio client: the same bytes through a bare `tokio::net::TcpStream` (no
/// channel, no task, no pairing), awaited on the runtime under test.
struct RawTokio {
    proto: Proto,
    stream: tokio::net::TcpStream,
    request: Vec<u8>,
    buf: [u8; 512],
}

impl RawTokio {
    async fn connect(proto: Proto, addr: SocketAddr) -> RawTokio {
        let stream = tokio::net::TcpStream::connect(addr).await.expect("connect");
        stream.set_nodelay(true).expect("nodelay");
        RawTokio {
            proto,
            stream,
            request: proto.request_bytes(),
            buf: [0; 512],
        }
    }

    async fn block(&mut self, out: &mut Vec<Duration>) {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        for _ in 0..BLOCK {
            let t = Instant::now();
            self.stream.write_all(&self.request).await.expect("write");
            let mut have = 0;
            loop {
                let n = self.stream.read(&mut self.buf[have..]).await.expect("read");
                assert!(n > 0, "simulator closed the connection");
                have += n;
                if complete(self.proto, &self.buf[..have]) {
                    break;
                }
            }
            out.push(t.elapsed());
        }
    }

    /// WSG: announce the disconnect first, so the simulated gripper does not go into FAST STOP.
    async fn close(mut self) {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        if let Proto::Wsg = self.proto {
            let mut b = BytesMut::new();
            wsg::frame::encode(&wsg::Command::AnnounceDisconnect.to_frame(), &mut b)
                .expect("encode");
            self.stream.write_all(&b).await.expect("write");
            let _ = self.stream.read(&mut self.buf).await;
        }
    }
}

struct Samples {
    name: &'static str,
    v: Vec<Duration>,
    allocations: Option<u64>,
}

impl Samples {
    fn new(name: &'static str) -> Samples {
        Samples {
            name,
            v: Vec::new(),
            allocations: None,
        }
    }
}

async fn client_block(c: &AnyClient, out: &mut Vec<Duration>) {
    for _ in 0..BLOCK {
        let t = Instant::now();
        c.query().await;
        out.push(t.elapsed());
    }
}

/// [`client_block`] in a task spawned on the runtime (a worker thread) instead of the thread that
/// calls `block_on`.
async fn spawned_block(c: &Arc<AnyClient>, mut out: Vec<Duration>) -> Vec<Duration> {
    let c = c.clone();
    tokio::spawn(async move {
        client_block(&c, &mut out).await;
        out
    })
    .await
    .expect("caller task")
}

fn measure(proto: Proto, addr: SocketAddr, rounds: usize) -> Vec<Samples> {
    let ct = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let mt: Runtime = common::runtime("client-mt", 2);
    let ct_client = ct.block_on(AnyClient::connect(proto, addr));
    let mt_client = Arc::new(mt.block_on(AnyClient::connect(proto, addr)));
    let mut raw = Raw::connect(proto, addr);
    let mut ct_raw = ct.block_on(RawTokio::connect(proto, addr));
    let mut mt_raw = mt.block_on(RawTokio::connect(proto, addr));

    let mut s_ct = Samples::new("client current_thread");
    let mut s_mt = Samples::new("client multi_thread(2)");
    let mut s_mt_task = Samples::new("client multi_thread(2), caller spawned");
    let mut s_raw = Samples::new("raw std::net (floor)");
    let mut s_ct_raw = Samples::new("raw tokio current_thread");
    let mut s_mt_raw = Samples::new("raw tokio multi_thread(2)");
    // Warm-up: one block each, not recorded.
    let mut scratch = Vec::new();
    ct.block_on(client_block(&ct_client, &mut scratch));
    mt.block_on(client_block(&mt_client, &mut scratch));
    mt.block_on(spawned_block(&mt_client, Vec::new()));
    for _ in 0..BLOCK {
        raw.query();
    }
    ct.block_on(ct_raw.block(&mut scratch));
    mt.block_on(mt_raw.block(&mut scratch));
    let mut ct_allocations = 0;
    for _ in 0..rounds {
        let before = allocations();
        ct.block_on(client_block(&ct_client, &mut s_ct.v));
        ct_allocations += allocations() - before;
        for _ in 0..BLOCK {
            let t = Instant::now();
            raw.query();
            s_raw.v.push(t.elapsed());
        }
        ct.block_on(ct_raw.block(&mut s_ct_raw.v));
        mt.block_on(client_block(&mt_client, &mut s_mt.v));
        mt.block_on(mt_raw.block(&mut s_mt_raw.v));
        s_mt_task.v = mt.block_on(spawned_block(&mt_client, std::mem::take(&mut s_mt_task.v)));
    }
    s_ct.allocations = Some(ct_allocations);
    ct.block_on(ct_client.close());
    mt.block_on(mt_client.close());
    raw.close();
    ct.block_on(ct_raw.close());
    mt.block_on(mt_raw.close());
    vec![s_raw, s_ct_raw, s_ct, s_mt_raw, s_mt, s_mt_task]
}

/// What `--only` measures: the client, or the bare stream.
enum Subject {
    Client(AnyClient),
    Raw(Box<RawTokio>),
}

impl Subject {
    async fn block(&mut self, out: &mut Vec<Duration>) {
        match self {
            Subject::Client(c) => client_block(c, out).await,
            Subject::Raw(r) => r.block(out).await,
        }
    }

    /// `blocks` blocks of queries from `tasks` callers at once (the client's callers share it;
    /// the bare stream has one caller, so it runs them one after the other).
    async fn blocks(&mut self, blocks: usize, tasks: usize, out: &mut Vec<Duration>) {
        match self {
            Subject::Client(c) if tasks > 1 => {
                let c = &*c;
                let callers = (0..tasks).map(|i| async move {
                    let mut times = Vec::new();
                    // Caller i runs blocks i, i + tasks, ...: `blocks` in all.
                    for _ in (i..blocks).step_by(tasks) {
                        client_block(c, &mut times).await;
                    }
                    times
                });
                for times in futures_util::future::join_all(callers).await {
                    out.extend(times);
                }
            }
            _ => {
                for _ in 0..blocks {
                    self.block(out).await;
                }
            }
        }
    }

    async fn close(self) {
        match self {
            Subject::Client(c) => c.close().await,
            Subject::Raw(r) => (*r).close().await,
        }
    }
}

/// `--only`: `calls` queries of one protocol from this thread, on a `current_thread` runtime (or
/// `mt`, a `multi_thread(2)` one), through the client or (`raw`) the bare tokio stream; prints
/// wall and CPU time per query.
fn cost(
    targets: &[(Proto, SocketAddr)],
    only: &str,
    calls: usize,
    tasks: usize,
    raw: bool,
    mt: bool,
) {
    let Some(&(proto, addr)) = targets
        .iter()
        .find(|(p, _)| format!("{p:?}").eq_ignore_ascii_case(only))
    else {
        eprintln!("--only takes wsg, griplink or smartgrasp, not {only:?}");
        std::process::exit(2);
    };
    let rt = if mt {
        common::runtime("client-mt", 2)
    } else {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime")
    };
    let blocks = calls.div_ceil(BLOCK).max(1);
    let mut times = Vec::with_capacity(blocks * BLOCK);
    let (wall, cpu_ns) = rt.block_on(async {
        // Connect and warm up outside the measured part.
        let mut subject = match raw {
            true => Subject::Raw(Box::new(RawTokio::connect(proto, addr).await)),
            false => Subject::Client(AnyClient::connect(proto, addr).await),
        };
        subject.block(&mut Vec::new()).await;
        let (t, cpu) = (Instant::now(), common::this_thread_cpu_ns());
        subject.blocks(blocks, tasks.max(1), &mut times).await;
        let measured = (t.elapsed(), common::this_thread_cpu_ns() - cpu);
        subject.close().await;
        measured
    });
    let n = (blocks * BLOCK) as f64;
    println!(
        "{} through {} on {}, {} caller(s): {} queries, {:.2} µs wall and {:.2} µs CPU on this thread per query ({:.0} queries/s)",
        proto.query(),
        if raw {
            "a bare tokio stream"
        } else {
            "the client"
        },
        if mt {
            "multi_thread(2), from block_on"
        } else {
            "current_thread"
        },
        if raw { 1 } else { tasks.max(1) },
        blocks * BLOCK,
        wall.as_secs_f64() * 1e6 / n,
        cpu_ns as f64 / 1e3 / n,
        n / wall.as_secs_f64(),
    );
}

/// One variant's figures in one run.
#[derive(Clone, Copy)]
struct RunStats {
    p50: Duration,
    p99: Duration,
    /// p50 ÷ the floor's p50 of the same run.
    ratio: f64,
    /// p99 − the floor's p99 of the same run, in µs (negative: below the floor).
    added_p99_us: f64,
    allocations: Option<f64>,
}

fn run_stats(results: Vec<Samples>) -> Vec<(&'static str, RunStats)> {
    let mut floor = None;
    results
        .into_iter()
        .map(|mut s| {
            s.v.sort();
            let p50 = percentile(&s.v, 50.0);
            let p99 = percentile(&s.v, 99.0);
            let (f50, f99) = *floor.get_or_insert((p50, p99));
            let stats = RunStats {
                p50,
                p99,
                ratio: p50.as_secs_f64() / f50.as_secs_f64(),
                added_p99_us: (p99.as_secs_f64() - f99.as_secs_f64()) * 1e6,
                allocations: s.allocations.map(|a| a as f64 / s.v.len() as f64),
            };
            (s.name, stats)
        })
        .collect()
}

/// The median of `v` (the lower middle one for an even count).
fn median<T: Copy + PartialOrd>(v: &[T]) -> T {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.partial_cmp(b).expect("no NaN"));
    v[(v.len() - 1) / 2]
}

fn main() {
    let rounds = flag_value("--rounds").unwrap_or(if has_flag("--long") { 100 } else { 10 });
    let runs: usize = flag_value("--runs")
        .unwrap_or(if has_flag("--long") { 5 } else { 3 })
        .max(1);
    println!(
        "round trip over loopback TCP, {runs} runs of {rounds} rounds of {BLOCK} queries per \
         variant; medians over the runs"
    );
    println!("machine: {}", common::machine());
    println!("load average at the start: {}", common::load());

    let sim_rt = common::runtime("sim", 1);
    let (wsg_sim, griplink_sim, sg_sim) = sim_rt.block_on(async {
        let wsg_sim = wsg::sim::SimServer::bind(
            "127.0.0.1:0",
            wsg::sim::SimConfig::new(wsg::sim::Model::Wsg50),
        )
        .await
        .expect("WSG simulator");
        let griplink_sim = griplink::sim::SimServer::bind(
            "127.0.0.1:0",
            griplink::sim::SimConfig::et4().time_scale(0.0),
        )
        .await
        .expect("GRIPLINK simulator");
        let sg_sim =
            smartgrasp::sim::SimServer::bind("127.0.0.1:0", smartgrasp::sim::SimConfig::default())
                .await
                .expect("SmartGrasp simulator");
        (wsg_sim, griplink_sim, sg_sim)
    });
    let targets = [
        (Proto::Wsg, wsg_sim.local_addr().expect("TCP address")),
        (Proto::Griplink, griplink_sim.local_addr()),
        (Proto::SmartGrasp, sg_sim.local_addr()),
    ];

    if let Some(only) = flag_value::<String>("--only") {
        let calls = flag_value("--calls").unwrap_or(10_000);
        let tasks = flag_value("--tasks").unwrap_or(1);
        cost(
            &targets,
            &only,
            calls,
            tasks,
            has_flag("--raw"),
            has_flag("--mt"),
        );
        return;
    }

    // Every run measures each protocol in turn (its variants interleaved in blocks); the
    // figures reported are the medians over the runs, with the spread of the ratio.
    let mut stats: Vec<Vec<(&'static str, Vec<RunStats>)>> = vec![Vec::new(); targets.len()];
    for run in 0..runs {
        for (i, &(proto, addr)) in targets.iter().enumerate() {
            // A fresh thread per protocol, owning that protocol's client runtimes.
            let results = std::thread::Builder::new()
                .name("client".into())
                .spawn(move || measure(proto, addr, rounds))
                .expect("thread")
                .join()
                .expect("measurement panicked");
            for (j, (name, s)) in run_stats(results).into_iter().enumerate() {
                if run == 0 {
                    stats[i].push((name, Vec::new()));
                }
                stats[i][j].1.push(s);
            }
        }
    }

    println!();
    println!("| query | variant | n per run | p50 µs | p99 µs | p50 / floor p50 (min–max) | p99 − floor p99 µs | allocations per round trip |");
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for (i, &(proto, _)) in targets.iter().enumerate() {
        for (name, runs) in &stats[i] {
            let p50: Vec<Duration> = runs.iter().map(|s| s.p50).collect();
            let p99: Vec<Duration> = runs.iter().map(|s| s.p99).collect();
            let ratio: Vec<f64> = runs.iter().map(|s| s.ratio).collect();
            let added: Vec<f64> = runs.iter().map(|s| s.added_p99_us).collect();
            let allocs: Vec<f64> = runs.iter().filter_map(|s| s.allocations).collect();
            let (lo, hi) = ratio
                .iter()
                .fold((f64::MAX, f64::MIN), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
            println!(
                "| {} | {} | {} | {} | {} | {:.2} ({:.2}–{:.2}) | {:+.2} | {} |",
                proto.query(),
                name,
                rounds * BLOCK,
                us(median(&p50)),
                us(median(&p99)),
                median(&ratio),
                lo,
                hi,
                median(&added),
                if allocs.is_empty() {
                    "–".into()
                } else {
                    format!("{:.1}", median(&allocs))
                },
            );
        }
    }
    println!();
    println!("load average at the end: {}", common::load());
    let _guard = sim_rt.enter();
    drop((wsg_sim, griplink_sim, sg_sim));
}
