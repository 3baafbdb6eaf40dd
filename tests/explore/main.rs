//! The seeded fault-schedule explorer (issue 20): runs workloads against the simulators through
//! faulty in-memory networks, each run a pure function of its seed, and checks an oracle on
//! every run. See `docs/EXPLORER.md`.
//!
//! `cargo test --test explore` runs the regression seeds (`tests/explore/regressions.txt`), the
//! determinism seeds (`tests/explore/determinism.txt`, each replayed several times), a few fresh
//! seeds per variant and the determinism check. Options (after `--`):
//!
//! - `--replay KEY` — run one seed (e.g. `wsg-udp:0x1f2e3d4c5b6a7988`) and print its trace;
//! - `--seeds N` — fresh seeds per variant (default 4);
//! - `--budget-secs S` — fresh seeds, round robin over the variants, for `S` seconds of wall
//!   time (instead of `--seeds`);
//! - `--start HEX` — the first fresh seed (default: from the system clock, printed);
//! - `--only NAME[,NAME…]` — only variants whose name starts with one of the `NAME`s (`wsg`
//!   includes `wsg-text`: `--only wsg-tcp,wsg-serial,wsg-udp` is the binary protocol alone);
//! - `--determinism N` — seeds per variant run twice and compared (default 1);
//! - `--until-fail N` — fresh seeds until one fails, at most `N` runs per variant; exits 0 and
//!   says after how many runs if one did (for the planted-bug table), 1 if none did;
//! - `--kind TEXT` — only a violation containing `TEXT` and not a known finding (unless
//!   `--strict`) counts (with `--until-fail`), or count the fresh runs with such a violation
//!   (with `--seeds`/`--budget-secs`);
//! - `--no-regressions` — skip the regression seeds and the determinism seeds;
//! - `--strict` — known open findings (`tests/explore/known.txt`) fail a run too;
//! - `--no-shrink` — do not shrink failures (long runs); failures are summarised by kind, with
//!   the first three keys of each kind.

mod core;
mod griplink;
mod smartgrasp;
mod wsg;
mod wsg_text;

use std::process::ExitCode;
use std::time::Instant;

use crate::core::{determinism_check, run_one, Caps, Outcome, Scenario};

/// Every protocol plugged in.
fn scenarios() -> Vec<&'static dyn Scenario> {
    vec![
        &wsg::Wsg,
        &griplink::Griplink,
        &smartgrasp::SmartGrasp,
        &wsg_text::WsgText,
    ]
}

struct Opts {
    replay: Option<String>,
    seeds: u64,
    budget_secs: Option<f64>,
    start: Option<u64>,
    only: Option<String>,
    determinism: u64,
    until_fail: Option<u64>,
    regressions: bool,
    shrink: bool,
    strict: bool,
    kind: Option<String>,
}

fn parse() -> Result<Opts, String> {
    let mut o = Opts {
        replay: None,
        seeds: 4,
        budget_secs: None,
        start: None,
        only: None,
        determinism: 1,
        until_fail: None,
        regressions: true,
        shrink: true,
        strict: false,
        kind: None,
    };
    let mut args = std::env::args().skip(1);
    let num = |s: Option<String>| -> Result<u64, String> {
        let s = s.ok_or("a number is missing")?;
        let (digits, radix) = match s.strip_prefix("0x") {
            Some(h) => (h.to_owned(), 16),
            None => (s.clone(), 10),
        };
        u64::from_str_radix(&digits, radix).map_err(|e| format!("{s}: {e}"))
    };
    while let Some(a) = args.next() {
        match a.as_str() {
            "--replay" => o.replay = args.next(),
            "--seeds" => o.seeds = num(args.next())?,
            "--budget-secs" => o.budget_secs = Some(num(args.next())? as f64),
            "--start" => o.start = Some(num(args.next())?),
            "--only" => o.only = args.next(),
            "--determinism" => o.determinism = num(args.next())?,
            "--until-fail" => o.until_fail = Some(num(args.next())?),
            "--no-regressions" => o.regressions = false,
            "--no-shrink" => o.shrink = false,
            "--strict" => o.strict = true,
            "--kind" => o.kind = args.next(),
            // What `cargo test` passes on to every test binary.
            "--nocapture" | "--quiet" | "-q" | "--color" | "--test-threads" | "--show-output" => {}
            other if other.starts_with("--") => return Err(format!("unknown option {other}")),
            _ => {}
        }
    }
    Ok(o)
}

/// `variant:0xseed[:cNoNfN]`.
fn parse_key(key: &str) -> Result<(&'static dyn Scenario, &'static str, u64, Caps), String> {
    let mut parts = key.trim().split(':');
    let name = parts.next().unwrap_or_default();
    let seed = parts.next().ok_or(format!("{key}: no seed"))?;
    let seed = u64::from_str_radix(seed.trim_start_matches("0x"), 16)
        .map_err(|e| format!("{key}: {e}"))?;
    let mut caps = Caps::FULL;
    if let Some(c) = parts.next() {
        let nums: Vec<u32> = c
            .split(|ch: char| !ch.is_ascii_digit())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap_or(0))
            .collect();
        if let [callers, ops, faults] = nums[..] {
            caps = Caps {
                callers: callers.max(1),
                ops: ops.max(1),
                faults,
            };
        }
    }
    for s in scenarios() {
        if let Some(v) = s.variants().iter().find(|v| **v == name) {
            return Ok((s, v, seed, caps));
        }
    }
    Err(format!("{key}: no variant {name}"))
}

fn key(variant: &str, seed: u64, caps: Caps) -> String {
    format!("{variant}:{seed:#018x}{}", caps.suffix())
}

fn replay_command(key: &str) -> String {
    format!("cargo test --release --test explore -- --replay {key}")
}

/// The promise a violation names (the text before its first colon).
fn promise(violation: &str) -> &str {
    violation.split(':').next().unwrap_or_default()
}

/// Tries smaller caps from the same seed while the run still breaks the promise `first`
/// names; returns the smallest failing key found.
fn shrink(s: &dyn Scenario, variant: &'static str, seed: u64, first: &str) -> Option<String> {
    let mut best = None;
    let mut caps = Caps::FULL;
    for _ in 0..12 {
        let mut tried = false;
        for smaller in [
            Caps {
                faults: caps.faults.saturating_sub(1),
                ..caps
            },
            Caps {
                callers: (caps.callers - 1).max(1),
                ..caps
            },
            Caps {
                ops: (caps.ops / 2).max(1),
                ..caps
            },
        ] {
            if smaller == caps {
                continue;
            }
            let out = run_one(s, variant, seed, smaller);
            if out.violations.iter().any(|v| promise(v) == promise(first)) {
                caps = smaller;
                best = Some(key(variant, seed, caps));
                tried = true;
                break;
            }
        }
        if !tried {
            break;
        }
    }
    best
}

/// A violation with its numbers blanked out: failures of one kind read the same.
fn kind(violation: &str) -> String {
    let mut out = String::new();
    let mut prev_hash = false;
    for ch in violation.chars() {
        let blank =
            ch.is_ascii_digit() && !out.is_empty() && !out.ends_with('(') || ch == '.' && prev_hash;
        if blank {
            if !prev_hash {
                out.push('#');
            }
            prev_hash = true;
        } else {
            out.push(ch);
            prev_hash = false;
        }
    }
    out.chars().take(160).collect()
}

/// How many failed fresh runs a long run reports in full (all of them while shrinking).
const REPORT_FAILURES: u64 = 50;

fn report_failure(k: &str, o: &Outcome) {
    report(k, o, "FAILED");
}

fn report(k: &str, o: &Outcome, label: &str) {
    eprintln!(
        "{label} {k} (simulated {:.1} s):",
        o.simulated.as_secs_f64()
    );
    for v in &o.violations {
        eprintln!("  - {v}");
    }
    eprintln!("  replay: {}", replay_command(k));
}

/// One known open finding (`tests/explore/known.txt`): `VARIANTS | TEXT && TEXT ... # why`.
struct Known {
    /// The variants it applies to (names or prefixes, comma separated in the file).
    variants: Vec<String>,
    /// Texts a violation must all contain.
    texts: Vec<String>,
}

impl Known {
    /// Whether violation `v` of a run of `variant` is this known finding.
    fn covers(&self, variant: &str, v: &str) -> bool {
        self.variants
            .iter()
            .any(|p| variant.starts_with(p.as_str()))
            && self.texts.iter().all(|t| v.contains(t.as_str()))
    }
}

/// The known open findings (`tests/explore/known.txt`). A line without `VARIANTS |` or without
/// a text is an error: a finding known on every variant, or a line matching every violation,
/// would make a promise unable to fail.
fn known_findings() -> Result<Vec<Known>, String> {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/explore/known.txt");
    let text = std::fs::read_to_string(file).unwrap_or_default();
    let mut out = Vec::new();
    for l in text.lines() {
        let l = l.split(" # ").next().unwrap_or_default().trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let (variants, texts) = l
            .split_once(" | ")
            .ok_or(format!("known.txt: no `VARIANTS | ` in {l:?}"))?;
        let variants: Vec<String> = variants
            .split(',')
            .map(|v| v.trim().to_owned())
            .filter(|v| !v.is_empty())
            .collect();
        let texts: Vec<String> = texts
            .split("&&")
            .map(|t| t.trim().to_owned())
            .filter(|t| !t.is_empty())
            .collect();
        if variants.is_empty() || texts.is_empty() {
            return Err(format!(
                "known.txt: a variant and a text are needed in {l:?}"
            ));
        }
        out.push(Known { variants, texts });
    }
    Ok(out)
}

/// The seeds that once did not replay (`tests/explore/determinism.txt`, `KEY RUNS # why`): each
/// is run `RUNS` times in this process and every run must give the same digest. CI's
/// determinism check draws fresh seeds, so a source of nondeterminism it caught once would
/// otherwise go untested after its fix. Returns false if one differed (or a line is bad).
fn replay_determinism_seeds(variants: &[(&'static dyn Scenario, &'static str)]) -> bool {
    let mut ok = true;
    let (mut n, mut total) = (0, 0);
    for l in seed_file("determinism.txt", variants, &mut ok) {
        let Some(Ok(runs)) = l.word.as_deref().map(str::parse::<u64>) else {
            eprintln!("determinism.txt: no number of runs after {}", l.key);
            ok = false;
            continue;
        };
        n += 1;
        total += runs.max(2);
        if let Err(e) = determinism_check(l.scenario, l.variant, l.seed, l.caps, runs) {
            eprintln!("{e}");
            eprintln!("  (a seed of tests/explore/determinism.txt)");
            ok = false;
        }
    }
    println!("determinism seeds: {n} seeds, {total} runs");
    ok
}

/// A line of a seed file: `KEY WORD # why`.
struct SeedLine {
    key: String,
    scenario: &'static dyn Scenario,
    variant: &'static str,
    seed: u64,
    caps: Caps,
    /// The word after the key, if any.
    word: Option<String>,
}

/// The seeds of `tests/explore/NAME` whose variant is one of `variants` (comments and blank
/// lines left out); a line whose key does not parse is reported and clears `ok`.
fn seed_file(
    name: &str,
    variants: &[(&'static dyn Scenario, &'static str)],
    ok: &mut bool,
) -> Vec<SeedLine> {
    let file = format!("{}/tests/explore/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(file).unwrap_or_default();
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or_default().trim();
        if line.is_empty() {
            continue;
        }
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default();
        let Ok((scenario, variant, seed, caps)) = parse_key(key) else {
            eprintln!("{name}: bad line {line}");
            *ok = false;
            continue;
        };
        if variants.iter().any(|(_, x)| *x == variant) {
            let word = words.next().map(str::to_owned);
            out.push(SeedLine {
                key: key.to_owned(),
                scenario,
                variant,
                seed,
                caps,
                word,
            });
        }
    }
    out
}

fn fresh_base(o: &Opts) -> u64 {
    o.start.unwrap_or_else(|| {
        let t = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        core::Prng::new(t.as_nanos() as u64).next_u64()
    })
}

/// With `RUST_LOG` set (`RUST_LOG=gripper=trace`), a replay also prints the library's own
/// tracing to stderr, stamped with the simulated clock so that it lines up with the trace.
fn log_library_on_replay() {
    struct Simulated;
    impl tracing_subscriber::fmt::time::FormatTime for Simulated {
        fn format_time(
            &self,
            w: &mut tracing_subscriber::fmt::format::Writer<'_>,
        ) -> std::fmt::Result {
            static T0: std::sync::OnceLock<tokio::time::Instant> = std::sync::OnceLock::new();
            let now = tokio::time::Instant::now();
            let t0 = *T0.get_or_init(|| now);
            write!(w, "{:>11}us", (now - t0).as_micros())
        }
    }
    if std::env::var_os("RUST_LOG").is_some() {
        let _ = tracing_subscriber::fmt()
            .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
            .with_timer(Simulated)
            .with_writer(std::io::stderr)
            .try_init();
    }
}

fn main() -> ExitCode {
    let o = match parse() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("explore: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(k) = &o.replay {
        log_library_on_replay();
        return match parse_key(k) {
            Ok((s, v, seed, caps)) => {
                let out = run_one(s, v, seed, caps);
                for line in &out.trace {
                    println!("{line}");
                }
                println!(
                    "digest {:#018x}, simulated {:.3} s",
                    out.digest,
                    out.simulated.as_secs_f64()
                );
                if out.violations.is_empty() {
                    println!("PASSED {k}");
                    ExitCode::SUCCESS
                } else {
                    report_failure(k, &out);
                    ExitCode::FAILURE
                }
            }
            Err(e) => {
                eprintln!("explore: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let variants: Vec<(&'static dyn Scenario, &'static str)> = scenarios()
        .into_iter()
        .flat_map(|s| s.variants().iter().map(move |v| (s, *v)))
        .filter(|(_, v)| {
            o.only
                .as_ref()
                .is_none_or(|p| p.split(',').any(|p| v.starts_with(p)))
        })
        .collect();
    let mut failed = false;
    let base = fresh_base(&o);
    let known = if o.strict {
        Vec::new()
    } else {
        match known_findings() {
            Ok(k) => k,
            Err(e) => {
                eprintln!("explore: {e}");
                return ExitCode::FAILURE;
            }
        }
    };
    // With `--kind`, the violations that count: of that kind and, unless `--strict`, not a
    // known finding (a planted bug is caught only by a violation the explorer fails on).
    let of_kind = |variant: &str, out: &Outcome| match &o.kind {
        Some(k) => out
            .violations
            .iter()
            .find(|v| v.contains(k.as_str()) && !known.iter().any(|kn| kn.covers(variant, v)))
            .cloned(),
        None => None,
    };
    let is_known = |variant: &str, out: &Outcome| {
        !out.violations.is_empty()
            && out
                .violations
                .iter()
                .all(|v| known.iter().any(|k| k.covers(variant, v)))
    };

    if let Some(max) = o.until_fail {
        let mut any = false;
        for (s, v) in &variants {
            let wall = Instant::now();
            let found = (0..max).find_map(|i| {
                let seed = core::Prng::new(base ^ i).next_u64();
                let out = run_one(*s, v, seed, Caps::FULL);
                let hit = match &o.kind {
                    Some(_) => of_kind(v, &out).is_some(),
                    None => !out.violations.is_empty() && !is_known(v, &out),
                };
                hit.then(|| (i + 1, seed, out))
            });
            match found {
                Some((runs, seed, out)) => {
                    any = true;
                    let k = key(v, seed, Caps::FULL);
                    println!(
                        "{v}: caught after {runs} runs ({:.1} s wall): {k}",
                        wall.elapsed().as_secs_f64()
                    );
                    let first = match &o.kind {
                        Some(_) => of_kind(v, &out),
                        None => out.violations.first().cloned(),
                    };
                    println!("  violation: {}", first.unwrap_or_default());
                }
                None => println!(
                    "{v}: nothing found in {max} runs ({:.1} s wall)",
                    wall.elapsed().as_secs_f64()
                ),
            }
        }
        return if any {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        };
    }

    if o.regressions {
        let (mut n, mut open, mut ok) = (0, 0, true);
        for l in seed_file("regressions.txt", &variants, &mut ok) {
            let (k, state) = (l.key.as_str(), l.word.as_deref().unwrap_or("fixed"));
            n += 1;
            let out = run_one(l.scenario, l.variant, l.seed, l.caps);
            match (state, out.violations.is_empty()) {
                ("fixed", false) => {
                    report_failure(k, &out);
                    failed = true;
                }
                ("open", true) => println!("regression {k} (open) passes now: mark it fixed"),
                ("open", false) => open += 1,
                _ => {}
            }
        }
        println!("regressions: {n} seeds, {open} still failing on known open findings");
        failed |= !ok || !replay_determinism_seeds(&variants);
    }

    for (s, v) in variants
        .iter()
        .take(o.determinism.max(1) as usize * variants.len())
    {
        for i in 0..o.determinism {
            let seed = core::Prng::new(base ^ 0xD5 ^ i).next_u64();
            match determinism_check(*s, v, seed, Caps::FULL, 2) {
                Ok(d) => println!("determinism {v}:{seed:#018x}: digest {d:#018x} twice"),
                Err(e) => {
                    eprintln!("{e}");
                    failed = true;
                }
            }
        }
    }

    let wall = Instant::now();
    let (mut runs, mut simulated, mut failures, mut known_runs) = (0u64, 0f64, 0u64, 0u64);
    let mut runs_of_kind = 0u64;
    let mut kinds: std::collections::BTreeMap<String, (u64, Vec<String>)> = Default::default();
    println!("fresh seeds from {base:#018x}");
    let mut i = 0u64;
    loop {
        let done = match o.budget_secs {
            Some(b) => wall.elapsed().as_secs_f64() >= b,
            None => i >= o.seeds * variants.len() as u64,
        };
        if done || variants.is_empty() {
            break;
        }
        let (s, v) = variants[(i % variants.len() as u64) as usize];
        let seed = core::Prng::new(base ^ i).next_u64();
        i += 1;
        let out = run_one(s, v, seed, Caps::FULL);
        runs += 1;
        simulated += out.simulated.as_secs_f64();
        runs_of_kind += u64::from(of_kind(v, &out).is_some());
        if !out.violations.is_empty() {
            if is_known(v, &out) {
                known_runs += 1;
            } else {
                failures += 1;
                failed = true;
            }
            let k = key(v, seed, Caps::FULL);
            let mut first_of_kind = false;
            for violation in &out.violations {
                let e = kinds.entry(kind(violation)).or_insert((0, Vec::new()));
                e.0 += 1;
                if e.1.len() < 3 && !e.1.contains(&k) {
                    e.1.push(k.clone());
                    first_of_kind = true;
                }
            }
            if is_known(v, &out) {
                if first_of_kind {
                    report(&k, &out, "KNOWN (open finding)");
                }
            } else if o.shrink || first_of_kind || failures <= REPORT_FAILURES {
                // Every failure up to a bound, whatever its kind: the summary by kind names only
                // the first three runs of each kind, known or not.
                report_failure(&k, &out);
            }
            if o.shrink && !is_known(v, &out) {
                if let Some(small) = shrink(s, v, seed, &out.violations[0]) {
                    eprintln!("  shrunk: {}", replay_command(&small));
                }
            }
        }
    }
    if !kinds.is_empty() {
        println!("failures by kind:");
        for (k, (n, keys)) in &kinds {
            println!("  {n:>8} × {k}");
            for key in keys {
                println!("             e.g. {}", replay_command(key));
            }
        }
    }
    let secs = wall.elapsed().as_secs_f64();
    if let Some(k) = &o.kind {
        println!("kind {k:?}: in {runs_of_kind} of {runs} runs");
    }
    println!(
        "explore: {runs} runs in {secs:.1} s ({:.1} seeds/s), {:.3} simulated hours, {failures} failed, {known_runs} failed only on known open findings",
        runs as f64 / secs.max(1e-9),
        simulated / 3600.0
    );
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
