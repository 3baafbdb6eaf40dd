//! Runs the built `gripctl` binary: one-shot commands, and `gripctl sim …` as a child process
//! whose `listening on <address>` line is read. Children are killed when dropped, so a failing
//! assertion never leaves a simulator running.
#![allow(dead_code)] // each test file uses its own part of this

use std::process::Stdio;
use std::time::Duration;

use serde_json::Value;
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::{Child, Command};

/// Generous bound on anything the tests wait for; a healthy run takes milliseconds. It only turns
/// a hang into a failure; nothing is timed.
pub const PATIENCE: Duration = Duration::from_secs(60);

/// `--timeout` of the tests' calls: far above what a loopback simulator needs, so that a loaded
/// CI machine cannot turn the library's short query defaults (1–2 s) into failures.
pub const CALL_TIMEOUT: &str = "20s";

/// What a `gripctl` run left behind.
#[derive(Debug)]
pub struct Run {
    /// Exit code (`None`: killed by a signal).
    pub code: Option<i32>,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Run {
    /// Asserts exit status 0 and returns stdout.
    pub fn ok(&self) -> &str {
        assert_eq!(self.code, Some(0), "gripctl failed: {self:#?}");
        &self.stdout
    }

    /// Asserts exit status 1 and exactly one line on stderr, `gripctl: …`; returns that line.
    pub fn failed(&self) -> &str {
        assert_eq!(self.code, Some(1), "gripctl should have failed: {self:#?}");
        let lines: Vec<&str> = self.stderr.lines().collect();
        assert_eq!(lines.len(), 1, "one error line expected: {self:#?}");
        assert!(lines[0].starts_with("gripctl: "), "{self:#?}");
        lines[0]
    }

    /// Asserts a failure (see [`Run::failed`]) run with `--json`: its line contains `text`, and
    /// the JSON error on stdout has `kind`. Returns the JSON error.
    pub fn failed_with(&self, kind: &str, text: &str) -> Value {
        let line = self.failed();
        assert!(line.contains(text), "{text:?} not in {line:?}");
        let error = self.json()["error"].clone();
        assert_eq!(error["kind"], kind, "{self:#?}");
        error
    }

    /// Stdout as one JSON document (asserts it is exactly one line).
    pub fn json(&self) -> Value {
        let lines: Vec<&str> = self.stdout.lines().collect();
        assert_eq!(lines.len(), 1, "one JSON line expected: {self:#?}");
        serde_json::from_str(lines[0]).unwrap_or_else(|e| panic!("{e}: {self:#?}"))
    }

    /// Every stdout line as JSON.
    pub fn json_lines(&self) -> Vec<Value> {
        self.stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
            .collect()
    }
}

/// Runs `gripctl args…` to completion.
pub async fn gripctl(args: &[&str]) -> Run {
    let child = Command::new(env!("CARGO_BIN_EXE_gripctl"))
        .args(args)
        .stdin(Stdio::null())
        .kill_on_drop(true)
        .output();
    let output = tokio::time::timeout(PATIENCE, child)
        .await
        .unwrap_or_else(|_| panic!("gripctl {args:?} did not finish"))
        .expect("gripctl runs");
    Run {
        code: output.status.code(),
        stdout: String::from_utf8(output.stdout).expect("stdout is UTF-8"),
        stderr: String::from_utf8(output.stderr).expect("stderr is UTF-8"),
    }
}

/// A `gripctl sim …` child process; killed on drop.
pub struct Simulator {
    /// The address from its `listening on` line.
    pub addr: String,
    _child: Child,
}

impl Simulator {
    /// Starts `gripctl sim args…` and reads its first line, which must be
    /// `listening on <address>`.
    pub async fn start(args: &[&str]) -> Simulator {
        let mut child = Command::new(env!("CARGO_BIN_EXE_gripctl"))
            .arg("sim")
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .kill_on_drop(true)
            .spawn()
            .expect("gripctl sim starts");
        let stdout = child.stdout.take().expect("stdout is piped");
        let mut lines = BufReader::new(stdout).lines();
        let first = tokio::time::timeout(PATIENCE, lines.next_line())
            .await
            .expect("the simulator prints its address")
            .expect("stdout is readable")
            .expect("the simulator printed a line before exiting");
        let addr = first
            .strip_prefix("listening on ")
            .unwrap_or_else(|| panic!("first line is not `listening on …`: {first:?}"))
            .to_owned();
        // Keep draining stdout so the child never blocks on a full pipe.
        tokio::spawn(async move { while let Ok(Some(_)) = lines.next_line().await {} });
        Simulator {
            addr,
            _child: child,
        }
    }
}

/// An address where nothing listens: a port bound and released (the OS does not hand it out
/// again at once).
pub fn refused_addr() -> String {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr");
    drop(listener);
    addr.to_string()
}
