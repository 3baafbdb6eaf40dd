//! A faulty byte-stream link (TCP or serial) in memory: two `tokio::io::duplex` pipes joined by
//! one pump per direction, which applies the seeded faults to each chunk it forwards.
//!
//! Faults (issue 20, TCP and serial): delay, split into pieces written apart, merge with the
//! next chunk, corruption of any byte (the length field included: any byte can be hit), stalls,
//! cuts (both directions end: each end reads end-of-stream), half-close (one direction ends,
//! the other goes on) and, on serial, line noise (random bytes inserted). A restarting device
//! is the scenario's business (`SimServer::restart`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream, ReadHalf, WriteHalf};
use tokio::sync::watch;
use tokio::time::Instant;

use super::{note, Prng, SharedTrace};

/// Bytes each pipe buffers.
const PIPE_BUFFER: usize = 64 * 1024;

/// Input bytes a [`Carried`] log keeps at most (a run's replies stay far below); beyond it
/// the bytes are counted, not kept, and the oracle cannot vouch for them.
const CARRIED_CAPACITY: usize = 4 << 20;

/// What one direction of a link did with the bytes it carried: the oracle's evidence that a
/// reply reached its reader intact (an ordered stream loses a reply only with its connection,
/// or by a fault that damaged it). Offsets count the bytes the writer wrote, before any fault.
#[derive(Clone, Debug, Default)]
pub struct Carried {
    /// The bytes the writer wrote, in order (the first [`CARRIED_CAPACITY`]).
    pub input: Vec<u8>,
    /// Offsets of damaged bytes: a flipped bit, or noise inserted before that byte (for noise
    /// after the last byte read: the offset of the next one).
    pub damaged: Vec<u64>,
    /// `(when, end)`: by `when`, every byte before offset `end` had been written to the
    /// reader's end of the pipe (which hands buffered bytes over even after a cut).
    pub delivered: Vec<(Instant, u64)>,
    /// What the reader's end received, faults included, in order (the first
    /// [`CARRIED_CAPACITY`] bytes): the frames the client's decoder saw.
    pub output: Vec<u8>,
    /// Positions in `output` of damaged bytes: inserted noise, or a byte that differs from the
    /// input byte it carries (a flipped bit).
    pub output_damaged: Vec<u64>,
    /// `(when, end)`: by `when`, the first `end` bytes of `output` had been written.
    pub output_delivered: Vec<(Instant, u64)>,
}

/// A [`Carried`] log shared with the pump that fills it.
pub type CarriedLog = Arc<Mutex<Carried>>;

/// Marks an inserted noise byte among the offsets of the bytes a pump holds.
const NOISE: u64 = u64::MAX;

/// The longest stall of a byte stream: a stall that began before the faults were turned off
/// still runs its course afterwards (the quiet phase's recovery bound allows for it).
pub const MAX_STALL: Duration = Duration::from_millis(3000);

/// How often each fault hits a chunk: one in `n` (0: never).
#[derive(Clone, Copy, Debug, Default)]
pub struct StreamProfile {
    /// Hold the chunk 1–100 ms.
    pub delay: u64,
    /// Write it in pieces, 1–20 ms apart.
    pub split: u64,
    /// Hold it until the next chunk (at most 50 ms) and write both at once.
    pub merge: u64,
    /// Flip one bit of one byte.
    pub corrupt: u64,
    /// Hold it 0.3–3 s.
    pub stall: u64,
    /// Cut the connection before it.
    pub cut: u64,
    /// End this direction before it (the other goes on).
    pub half_close: u64,
    /// Insert 1–4 random bytes (serial line noise).
    pub noise: u64,
}

impl StreamProfile {
    /// A random profile of intensity `level` (0: no faults).
    pub fn random(rng: &mut Prng, level: u32, serial: bool) -> Self {
        if level == 0 {
            return StreamProfile::default();
        }
        // Higher levels make each fault more likely (smaller `n`).
        let mut pick = |base: u64| rng.fault_rate(level, base, 3);
        StreamProfile {
            delay: pick(6),
            split: pick(8),
            merge: pick(8),
            corrupt: pick(60),
            stall: pick(80),
            cut: pick(200),
            half_close: pick(400),
            noise: if serial { pick(60) } else { 0 },
        }
    }
}

/// Creates a faulty link; returns (client end, server end). Faults apply while `on` is set.
pub fn faulty_pipe(
    rng: &mut Prng,
    profile: StreamProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
    label: String,
) -> (DuplexStream, DuplexStream) {
    faulty_pipe_logged(rng, profile, on, trace, label, None)
}

/// [`faulty_pipe`], logging what the server-to-client direction did with its bytes in `down`
/// (the generator's draws are the same with or without a log: a seed keeps its path).
pub fn faulty_pipe_logged(
    rng: &mut Prng,
    profile: StreamProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
    label: String,
    down: Option<CarriedLog>,
) -> (DuplexStream, DuplexStream) {
    let (client, client_net) = tokio::io::duplex(PIPE_BUFFER);
    let (server, server_net) = tokio::io::duplex(PIPE_BUFFER);
    let (c_rd, c_wr) = tokio::io::split(client_net);
    let (s_rd, s_wr) = tokio::io::split(server_net);
    let (cut_tx, cut_rx) = watch::channel(false);
    let cut_tx = Arc::new(cut_tx);
    let up = Pump {
        dir: format!("{label} c>s"),
        rng: rng.fork(),
        profile,
        on: on.clone(),
        cut_tx: cut_tx.clone(),
        cut: cut_rx.clone(),
        trace: trace.clone(),
        carried: None,
    };
    let down = Pump {
        dir: format!("{label} s>c"),
        rng: rng.fork(),
        profile,
        on,
        cut_tx,
        cut: cut_rx,
        trace,
        carried: down,
    };
    tokio::spawn(up.run(c_rd, s_wr));
    tokio::spawn(down.run(s_rd, c_wr));
    (client, server)
}

struct Pump {
    dir: String,
    rng: Prng,
    profile: StreamProfile,
    on: Arc<AtomicBool>,
    cut_tx: Arc<watch::Sender<bool>>,
    cut: watch::Receiver<bool>,
    trace: SharedTrace,
    carried: Option<CarriedLog>,
}

impl Pump {
    async fn run(mut self, mut rd: ReadHalf<DuplexStream>, mut wr: WriteHalf<DuplexStream>) {
        let mut buf = vec![0u8; 512];
        let mut held: Vec<u8> = Vec::new();
        // The input offset of each held byte (`NOISE` for inserted noise), and of the next
        // byte to be read: the log's evidence (`Carried`).
        let mut held_from: Vec<u64> = Vec::new();
        let mut read_total = 0u64;
        loop {
            let chunk = self.rng.between(1, 512) as usize;
            let mut cut = self.cut.clone();
            let read = tokio::select! {
                // Fixed order (replay): a cut ends the pump whatever else is ready; a merged
                // chunk is written after its wait even while nothing new comes.
                biased;
                _ = cut.wait_for(|c| *c) => return,
                _ = tokio::time::sleep(Duration::from_millis(50)), if !held.is_empty() => None,
                r = rd.read(&mut buf[..chunk]) => Some(r),
            };
            let data = match read {
                None => {
                    let (out, from) = (std::mem::take(&mut held), std::mem::take(&mut held_from));
                    if !self.write(&mut wr, &out, &from).await {
                        return;
                    }
                    continue;
                }
                Some(Ok(0)) | Some(Err(_)) => {
                    // The writer ended its side: pass the half-close on.
                    let (out, from) = (std::mem::take(&mut held), std::mem::take(&mut held_from));
                    if self.write(&mut wr, &out, &from).await {
                        let _ = wr.shutdown().await;
                    }
                    return;
                }
                Some(Ok(n)) => buf[..n].to_vec(),
            };
            log(&self.carried, |c| {
                let room = CARRIED_CAPACITY.saturating_sub(c.input.len());
                c.input.extend_from_slice(&data[..data.len().min(room)]);
            });
            let mut out = std::mem::take(&mut held);
            let mut from = std::mem::take(&mut held_from);
            out.extend_from_slice(&data);
            from.extend(read_total..read_total + data.len() as u64);
            read_total += data.len() as u64;
            if !self.on.load(Ordering::Relaxed) {
                if !self.write(&mut wr, &out, &from).await {
                    return;
                }
                continue;
            }
            let p = self.profile;
            let r = &mut self.rng;
            if r.one_in(p.cut) {
                note(&self.trace, format!("fault {}: cut", self.dir));
                let _ = self.cut_tx.send(true);
                return;
            }
            if r.one_in(p.half_close) {
                note(&self.trace, format!("fault {}: half-close", self.dir));
                let _ = wr.shutdown().await;
                // Keep reading (and discarding) so the writer is not blocked.
                let mut cut = self.cut.clone();
                loop {
                    tokio::select! {
                        biased;
                        _ = cut.wait_for(|c| *c) => return,
                        r = rd.read(&mut buf) => if !matches!(r, Ok(n) if n > 0) { return },
                    }
                }
            }
            if r.one_in(p.corrupt) {
                let i = r.below(out.len() as u64) as usize;
                let bit = 1u8 << r.below(8);
                out[i] ^= bit;
                if from[i] != NOISE {
                    log(&self.carried, |c| c.damaged.push(from[i]));
                }
                note(
                    &self.trace,
                    format!("fault {}: byte {i} of {} ^ {bit:#04x}", self.dir, out.len()),
                );
            }
            if r.one_in(p.noise) {
                let at = r.below(out.len() as u64 + 1) as usize;
                let n = r.between(1, 4) as usize;
                let noise: Vec<u8> = (0..n).map(|_| r.below(256) as u8).collect();
                note(
                    &self.trace,
                    format!("fault {}: noise {noise:02x?} at {at}", self.dir),
                );
                let before = from[at..]
                    .iter()
                    .copied()
                    .find(|&o| o != NOISE)
                    .unwrap_or(read_total);
                log(&self.carried, |c| c.damaged.push(before));
                out.splice(at..at, noise);
                from.splice(at..at, std::iter::repeat_n(NOISE, n));
            }
            let hold = if r.one_in(p.stall) {
                Some(r.millis(300, MAX_STALL.as_millis() as u64))
            } else if r.one_in(p.delay) {
                Some(r.millis(1, 100))
            } else {
                None
            };
            let merge = r.one_in(p.merge);
            let split = r.one_in(p.split);
            if let Some(d) = hold {
                note(&self.trace, format!("fault {}: hold {d:?}", self.dir));
                if !self.pause(d).await {
                    return;
                }
            }
            if merge {
                note(&self.trace, format!("fault {}: merge", self.dir));
                held = out;
                held_from = from;
                continue;
            }
            if split && out.len() > 1 {
                let at = self.rng.between(1, out.len() as u64 - 1) as usize;
                let gap = self.rng.millis(1, 20);
                note(
                    &self.trace,
                    format!("fault {}: split at {at}, {gap:?}", self.dir),
                );
                if !self.write(&mut wr, &out[..at], &from[..at]).await || !self.pause(gap).await {
                    return;
                }
                out.drain(..at);
                from.drain(..at);
            }
            if !self.write(&mut wr, &out, &from).await {
                return;
            }
        }
    }

    /// Waits `d`; false if the link was cut meanwhile.
    async fn pause(&self, d: Duration) -> bool {
        let mut cut = self.cut.clone();
        tokio::select! {
            biased;
            _ = cut.wait_for(|c| *c) => false,
            _ = tokio::time::sleep(d) => true,
        }
    }

    /// Writes `bytes` (whose input offsets are `from`) and logs them delivered; false if the
    /// link was cut or the reader is gone.
    async fn write(&self, wr: &mut WriteHalf<DuplexStream>, bytes: &[u8], from: &[u64]) -> bool {
        if bytes.is_empty() {
            return true;
        }
        let mut cut = self.cut.clone();
        let written = tokio::select! {
            biased;
            _ = cut.wait_for(|c| *c) => false,
            r = wr.write_all(bytes) => r.is_ok(),
        };
        if let (true, Some(&last)) = (written, from.iter().rev().find(|&&o| o != NOISE)) {
            log(&self.carried, |c| {
                c.delivered.push((Instant::now(), last + 1))
            });
        }
        if written {
            log(&self.carried, |c| log_output(c, bytes, from));
        }
        written
    }
}

/// Adds to a direction's log, if it keeps one.
fn log(carried: &Option<CarriedLog>, f: impl FnOnce(&mut Carried)) {
    if let Some(c) = carried {
        f(&mut c.lock().unwrap_or_else(|e| e.into_inner()));
    }
}

/// Logs `bytes` (input offsets `from`) as written to the reader's end: what the decoder saw, and
/// which of those bytes the faults made (noise) or changed (a flipped bit). A byte beyond what
/// the log kept of the input counts as intact (the oracle then vouches for nothing more).
fn log_output(c: &mut Carried, bytes: &[u8], from: &[u64]) {
    let room = CARRIED_CAPACITY.saturating_sub(c.output.len());
    for (&b, &o) in bytes.iter().zip(from).take(room) {
        let damaged = o == NOISE || c.input.get(o as usize).is_some_and(|&i| i != b);
        if damaged {
            c.output_damaged.push(c.output.len() as u64);
        }
        c.output.push(b);
    }
    let end = c.output.len() as u64;
    c.output_delivered.push((Instant::now(), end));
}
