//! Helpers shared by the measurement benches (`roundtrip`, `wsg_throughput`, `wsg_sim_scale`):
//! arguments, percentiles, CPU time per named thread, and the machine's load.
//!
//! These benches are plain `main`s (`harness = false`), not criterion: they report percentiles
//! and CPU time, which criterion does not. They run quickly by default (so `cargo bench` with no
//! arguments stays short) and take `--long` for the durations the issue asks for.
//!
//! CPU time comes from `/proc/self/task/<tid>/schedstat` (nanoseconds on a CPU, per thread),
//! falling back to `utime + stime` of `/proc/self/task/<tid>/stat` (10 ms ticks). Threads are
//! picked by name: the benches name their runtimes' threads (`client…`, `sim…`), so the cost of
//! the client and of the simulator serving it can be told apart inside one process.

#![allow(dead_code)] // each bench uses a different subset

use std::fs;
use std::time::Duration;

/// Whether `flag` was given (cargo passes `--bench` and criterion-style flags too: ignored).
pub fn has_flag(flag: &str) -> bool {
    std::env::args().any(|a| a == flag)
}

/// The value after `flag`, parsed.
pub fn flag_value<T: std::str::FromStr>(flag: &str) -> Option<T> {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == flag)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
}

/// The `p`-th percentile (0..=100) of sorted `v`, nearest rank.
pub fn percentile(sorted: &[Duration], p: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// Microseconds with two decimals.
pub fn us(d: Duration) -> String {
    format!("{:.2}", d.as_secs_f64() * 1e6)
}

/// CPU nanoseconds used so far by this process's threads whose name starts with `prefix`
/// (`""`: all live threads).
pub fn thread_cpu_ns(prefix: &str) -> u64 {
    let Ok(dir) = fs::read_dir("/proc/self/task") else {
        return 0;
    };
    let mut total = 0;
    for entry in dir.flatten() {
        let path = entry.path();
        let name = fs::read_to_string(path.join("comm")).unwrap_or_default();
        if !name.trim_end().starts_with(prefix) {
            continue;
        }
        total += match fs::read_to_string(path.join("schedstat")) {
            Ok(s) => s
                .split_whitespace()
                .next()
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0),
            Err(_) => ticks_ns(&path.join("stat")),
        };
    }
    total
}

/// `utime + stime` of a `stat` file, in nanoseconds (assumes the usual 100 ticks per second).
fn ticks_ns(stat: &std::path::Path) -> u64 {
    let s = fs::read_to_string(stat).unwrap_or_default();
    // The command name is in parentheses and may hold spaces: count fields after the last ')'.
    let rest = s.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<u64> = rest
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0))
        .collect();
    // After ')': state(0) ppid(1) … utime(11) stime(12).
    (f.get(11).copied().unwrap_or(0) + f.get(12).copied().unwrap_or(0)) * 10_000_000
}

/// CPU nanoseconds used so far by the calling thread (`/proc/thread-self/schedstat`; 0 where
/// there is none).
pub fn this_thread_cpu_ns() -> u64 {
    fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// CPU nanoseconds of the whole process (all threads, including exited ones), from
/// `/proc/self/stat` (10 ms ticks).
pub fn process_cpu_ns() -> u64 {
    ticks_ns(std::path::Path::new("/proc/self/stat"))
}

/// The machine: cores, CPU model and load averages, for the report.
pub fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = fs::read_to_string("/proc/cpuinfo")
        .unwrap_or_default()
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, m)| m.trim().to_owned())
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{cores} cores, {model}, load average {}", load())
}

/// The 1, 5 and 15 minute load averages.
pub fn load() -> String {
    fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

/// A multi-thread tokio runtime whose worker threads are named `name` (for [`thread_cpu_ns`]).
pub fn runtime(name: &str, workers: usize) -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(workers)
        .thread_name(name)
        .enable_all()
        .build()
        .expect("tokio runtime")
}

/// Runs `f` on a new thread named `name` inside a current-thread tokio runtime, and waits for it.
pub fn on_current_thread<F, Fut, T>(name: &str, f: F) -> T
where
    F: FnOnce() -> Fut + Send + 'static,
    Fut: std::future::Future<Output = T>,
    T: Send + 'static,
{
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("tokio runtime")
                .block_on(f())
        })
        .expect("spawn thread")
        .join()
        .expect("bench thread panicked")
}

/// Measures how late the machine lets a thread run: a thread (`canary`) sleeps 1 ms in a loop
/// and records by how much each sleep overran. It does nothing else, so its oversleep is the
/// scheduling delay the machine imposes (other processes' load), independent of the code
/// under test: a stall seen by the bench and by the canary at once is the machine's.
pub struct Canary {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: std::thread::JoinHandle<CanaryReport>,
}

/// What the canary saw.
#[derive(Clone, Copy, Debug)]
pub struct CanaryReport {
    /// Sleeps of 1 ms taken.
    pub sleeps: u64,
    /// The longest overrun of a 1 ms sleep.
    pub max_oversleep: Duration,
    /// Sleeps that overran by more than 10 ms.
    pub over_10ms: u64,
}

impl Canary {
    /// Starts the canary thread.
    pub fn start() -> Canary {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("canary".into())
            .spawn(move || {
                let tick = Duration::from_millis(1);
                let mut r = CanaryReport {
                    sleeps: 0,
                    max_oversleep: Duration::ZERO,
                    over_10ms: 0,
                };
                while !flag.load(std::sync::atomic::Ordering::Relaxed) {
                    let t = std::time::Instant::now();
                    std::thread::sleep(tick);
                    let over = t.elapsed().saturating_sub(tick);
                    r.sleeps += 1;
                    r.max_oversleep = r.max_oversleep.max(over);
                    if over > Duration::from_millis(10) {
                        r.over_10ms += 1;
                    }
                }
                r
            })
            .expect("spawn canary");
        Canary { stop, thread }
    }

    /// Stops the canary and returns what it saw.
    pub fn stop(self) -> CanaryReport {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        self.thread.join().expect("canary panicked")
    }
}

impl std::fmt::Display for CanaryReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "scheduling canary (a thread sleeping 1 ms in a loop): {} sleeps, longest overrun \
             {:.2} ms, {} overran by more than 10 ms",
            self.sleeps,
            self.max_oversleep.as_secs_f64() * 1e3,
            self.over_10ms
        )
    }
}
