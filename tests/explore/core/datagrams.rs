//! A faulty datagram link (UDP) in memory: a channel per direction and a pump that loses,
//! duplicates, delays and so reorders datagrams, from the seeded generator.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use bytes::Bytes;
use tokio::sync::mpsc;
use tokio::time::{sleep_until, Instant};

use super::{note, Prng, SharedTrace};

/// The longest delay of a datagram (a delayed copy sent before the faults stopped may still
/// come this long afterwards: the quiet phase waits for it).
pub const MAX_DELAY_MS: u64 = 5000;

/// How often each fault hits a datagram: one in `n` (0: never).
#[derive(Clone, Copy, Debug, Default)]
pub struct DatagramProfile {
    /// Lose it.
    pub loss: u64,
    /// Deliver it twice (each copy delayed on its own).
    pub duplicate: u64,
    /// Delay it 1–`max_delay_ms` ms (later datagrams may overtake it).
    pub delay: u64,
    /// The longest delay.
    pub max_delay_ms: u64,
}

impl DatagramProfile {
    /// A random profile of intensity `level` (0: no faults).
    pub fn random(rng: &mut Prng, level: u32) -> Self {
        if level == 0 {
            return DatagramProfile::default();
        }
        let mut pick = |base: u64| rng.fault_rate(level, base, 4);
        DatagramProfile {
            loss: pick(20),
            duplicate: pick(20),
            delay: pick(6),
            // Now and then several seconds (issue 29): a reply that late is far past every
            // deadline and grace a client draws.
            max_delay_ms: if rng.one_in(6) {
                1000 + rng.below(MAX_DELAY_MS - 1000)
            } else {
                1 + rng.below(300)
            },
        }
    }
}

/// One copy of a datagram that a link duplicated or delayed, as it was delivered.
#[derive(Clone, Debug)]
pub struct Faulted {
    /// When it was delivered.
    pub at: Instant,
    /// When it was sent into the link.
    pub sent: Instant,
    /// The link delivered the datagram twice (this is one of the two copies).
    pub duplicated: bool,
    /// The datagram.
    pub bytes: Bytes,
}

/// The datagrams a link delivered as a duplicate or after a delay: the oracle attributes a wrong
/// answer to such a datagram (a documented residual risk of UDP, which has no sequence numbers)
/// only if one was actually delivered, and only where the client's pairing rule could not have
/// kept it from the call (when it was sent tells which request it answers and how long that
/// request held its id). Every other datagram was delivered at the instant it was sent.
pub type FaultedLog = Arc<Mutex<Vec<Faulted>>>;

/// A faulty one-way datagram link: returns (sender's end, receiver's end). Every copy the link
/// duplicated or delayed is logged in `faulted` when it is delivered.
pub fn faulty_datagrams(
    rng: &mut Prng,
    profile: DatagramProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
    label: String,
    faulted: FaultedLog,
) -> (mpsc::UnboundedSender<Bytes>, mpsc::UnboundedReceiver<Bytes>) {
    let (in_tx, in_rx) = mpsc::unbounded_channel();
    let (out_tx, out_rx) = mpsc::unbounded_channel();
    let link = Link {
        label,
        rng: rng.fork(),
        p: profile,
        on,
        trace,
        faulted,
    };
    tokio::spawn(pump(link, in_rx, out_tx));
    (in_tx, out_rx)
}

/// For a duplicated or delayed copy in flight: when it was sent, and whether it was duplicated.
type Origin = (Instant, bool);

/// What a pump needs besides its channels.
struct Link {
    label: String,
    rng: Prng,
    p: DatagramProfile,
    on: Arc<AtomicBool>,
    trace: SharedTrace,
    faulted: FaultedLog,
}

async fn pump(
    link: Link,
    mut input: mpsc::UnboundedReceiver<Bytes>,
    output: mpsc::UnboundedSender<Bytes>,
) {
    let Link {
        label,
        mut rng,
        p,
        on,
        trace,
        faulted,
    } = link;
    // Datagrams in flight, by delivery time (then by arrival, so ties keep their order), each
    // with, for a duplicated or delayed copy, when it was sent and whether it was duplicated.
    let mut flight: BTreeMap<(Instant, u64), (Bytes, Option<Origin>)> = BTreeMap::new();
    let mut n = 0u64;
    loop {
        let next = flight.keys().next().map(|k| k.0);
        tokio::select! {
            // Fixed order (replay): deliveries that are due go first; new datagrams are read
            // only when none is due, and a due one is due only once, so neither starves.
            biased;
            _ = sleep_until(next.unwrap_or_else(Instant::now)), if next.is_some() => {
                let now = Instant::now();
                while let Some(entry) = flight.first_entry() {
                    if entry.key().0 > now {
                        break;
                    }
                    let (d, origin) = entry.remove();
                    if let Some((sent, duplicated)) = origin {
                        faulted.lock().unwrap_or_else(|e| e.into_inner()).push(Faulted {
                            at: now,
                            sent,
                            duplicated,
                            bytes: d.clone(),
                        });
                    }
                    if output.send(d).is_err() {
                        return;
                    }
                }
            }
            d = input.recv() => {
                // The sender is gone: what is in flight is lost with it.
                let Some(d) = d else { return };
                n += 1;
                if !on.load(Ordering::Relaxed) {
                    flight.insert((Instant::now(), n * 2), (d, None));
                    continue;
                }
                if rng.one_in(p.loss) {
                    note(&trace, format!("fault {label}: datagram {n} lost"));
                    continue;
                }
                let copies = if rng.one_in(p.duplicate) { 2 } else { 1 };
                for copy in 0..copies {
                    let delay = if rng.one_in(p.delay) { rng.millis(1, p.max_delay_ms.max(1)) } else { std::time::Duration::ZERO };
                    let was_faulted = copies > 1 || !delay.is_zero();
                    if was_faulted {
                        note(&trace, format!("fault {label}: datagram {n} copy {copy} delayed {delay:?}"));
                    }
                    let origin = was_faulted.then(|| (Instant::now(), copies > 1));
                    flight.insert((Instant::now() + delay, n * 2 + copy), (d.clone(), origin));
                }
            }
        }
    }
}
