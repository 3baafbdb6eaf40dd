//! The fault schedule and what it does to each frame: pure decisions, no I/O and no clock.
//!
//! A test adds [`Rule`]s (a [`Fault`] and [`When`] it applies) to one direction of the proxy. For
//! every frame that passes, [`RuleSet::decide`] says which rules fire (counting them), and
//! [`Pipeline`] turns the frame and that [`Decision`] into [`Step`]s (write these bytes, pause,
//! stall, cut) that the socket code in `proxy.rs` carries out. Keeping this apart from the sockets
//! lets every fault be tested here byte for byte.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bytes::{Bytes, BytesMut};

/// A byte position inside a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum At {
    /// This many bytes from the first byte (0 = the first byte); past the end means the last byte.
    Start(usize),
    /// This many bytes before the last byte (0 = the last byte, e.g. a WSG checksum byte); past the
    /// beginning means the first byte.
    End(usize),
    /// A position drawn from the proxy's seeded generator (reproducible for a given seed).
    Random,
}

/// What to do to a frame (or, with [`Framing::Bytes`](super::Framing::Bytes), to one read).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Fault {
    /// Hold the frame this long before forwarding it (later frames queue behind it). Ends early when
    /// the faults of this direction change.
    Delay(Duration),
    /// Deliver the frame in pieces of at most `piece_len` bytes, each written and flushed on its
    /// own, with `pause` between pieces. Pauses end early when the faults of this direction change,
    /// so a test can hold pieces apart with a long pause and then let the rest through. (A receiver
    /// slower than the pause may still get several pieces in one read: that is TCP.)
    Split {
        /// Bytes per piece (0 is treated as 1).
        piece_len: usize,
        /// Time between two pieces.
        pause: Duration,
    },
    /// Hold this frame and the following ones until `frames` of them are collected, then write them
    /// in one write. The group is written early after `max_wait`, when the faults of this direction
    /// change, when it reaches the proxy's `max_frame_len` bytes, or at the end of the stream.
    Merge {
        /// Frames per write, counting the one that triggered the rule.
        frames: usize,
        /// Longest time the first frame of the group is held.
        max_wait: Duration,
    },
    /// Flip bits of one byte: XOR the byte at `at` with `xor` (0 is treated as 0xFF, so the byte
    /// always changes).
    Corrupt {
        /// Which byte.
        at: At,
        /// Bits to flip.
        xor: u8,
    },
    /// Drop the whole frame.
    Drop,
    /// Remove `len` bytes starting at `at` (fewer if the frame ends first).
    DropBytes {
        /// First byte removed.
        at: At,
        /// How many bytes.
        len: usize,
    },
    /// Forward the frame twice.
    Duplicate,
    /// Stop forwarding in this direction before this frame, without closing, until the test calls
    /// [`Faults::release`](super::Faults::release) (or
    /// [`release_bytes`](super::Faults::release_bytes)).
    Stall,
    /// Forward the first `after_bytes` bytes of this frame, then close the connection (both sides).
    /// `after_bytes: 0` cuts the connection when the frame arrives, before any of it is sent.
    Cut {
        /// Bytes of the frame delivered before the cut.
        after_bytes: usize,
    },
}

impl Fault {
    /// This fault on the next frame only.
    pub fn once(self) -> Rule {
        Rule::new(self, When::Nth(1))
    }

    /// This fault on the `n`-th frame from now (1 = the next one), once.
    pub fn nth(self, n: u64) -> Rule {
        Rule::new(self, When::Nth(n))
    }

    /// This fault on every `n`-th frame from now on (`n`, `2n`, …).
    pub fn every(self, n: u64) -> Rule {
        Rule::new(self, When::Every(n))
    }

    /// This fault on every frame from now on.
    pub fn always(self) -> Rule {
        Rule::new(self, When::Every(1))
    }

    /// This fault on each frame with probability `1 / one_in`, drawn from the proxy's seeded
    /// generator so that a run is reproducible.
    pub fn randomly(self, one_in: u32) -> Rule {
        Rule::new(self, When::Randomly { one_in })
    }
}

/// Which frames a rule applies to, counted from when the rule was added.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum When {
    /// The `n`-th frame (1 = the next one), then the rule is done. `Nth(0)` is treated as `Nth(1)`.
    Nth(u64),
    /// Every `n`-th frame (`n`, `2n`, …). `Every(0)` is treated as `Every(1)`.
    Every(u64),
    /// Each frame with probability `1 / one_in` (0 is treated as 1).
    Randomly {
        /// One frame in this many, on average.
        one_in: u32,
    },
}

/// A fault and when it applies; build one with [`Fault::once`], [`Fault::every`]…
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rule {
    fault: Fault,
    when: When,
    limit: Option<u64>,
}

impl Rule {
    /// A rule that applies `fault` to the frames selected by `when`.
    pub fn new(fault: Fault, when: When) -> Self {
        Rule {
            fault,
            when,
            limit: None,
        }
    }

    /// Stop after the fault has been applied `n` times.
    pub fn times(mut self, n: u64) -> Self {
        self.limit = Some(n);
        self
    }

    /// The fault.
    pub fn fault(&self) -> Fault {
        self.fault
    }

    /// When it applies.
    pub fn when(&self) -> When {
        self.when
    }
}

/// A rule's counters, shared with the test's handle so they outlive the rule.
#[derive(Debug, Default)]
pub(crate) struct RuleCounter {
    fired: AtomicU64,
    finished: AtomicBool,
}

impl RuleCounter {
    pub(crate) fn fired(&self) -> u64 {
        self.fired.load(Ordering::Acquire)
    }

    pub(crate) fn is_finished(&self) -> bool {
        self.finished.load(Ordering::Acquire)
    }
}

#[derive(Debug)]
struct Entry {
    rule: Rule,
    /// Frames this rule has seen since it was added.
    seen: u64,
    counter: Arc<RuleCounter>,
}

/// A small xorshift64 generator: reproducible runs without a dependency.
#[derive(Debug, Clone)]
pub(crate) struct XorShift64(u64);

impl XorShift64 {
    pub(crate) fn new(seed: u64) -> Self {
        // xorshift never leaves 0, so 0 is replaced by a fixed odd constant.
        XorShift64(if seed == 0 {
            0x9E37_79B9_7F4A_7C15
        } else {
            seed
        })
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }

    /// A number in `0..n` (`n > 0`); the modulo bias is irrelevant for fault injection.
    pub(crate) fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n.max(1)
    }
}

/// What happens to one frame: the combined effect of every rule that fired on it, with byte
/// positions already resolved against the frame's length.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Decision {
    pub(crate) stall: bool,
    pub(crate) delay: Duration,
    pub(crate) drop: bool,
    /// (index, xor mask) pairs.
    pub(crate) corrupt: Vec<(usize, u8)>,
    /// (start, len) ranges to remove, in the frame's original positions.
    pub(crate) drop_bytes: Vec<(usize, usize)>,
    pub(crate) duplicates: usize,
    pub(crate) split: Option<(usize, Duration)>,
    pub(crate) merge: Option<(usize, Duration)>,
    pub(crate) cut_after: Option<usize>,
    /// How many rules fired.
    pub(crate) fired: u64,
}

/// The rules of one direction.
#[derive(Debug)]
pub(crate) struct RuleSet {
    entries: Vec<Entry>,
    rng: XorShift64,
    /// Changes whenever rules are added or removed; pauses planned under an older generation end.
    generation: u64,
}

impl RuleSet {
    pub(crate) fn new(seed: u64) -> Self {
        RuleSet {
            entries: Vec::new(),
            rng: XorShift64::new(seed),
            generation: 0,
        }
    }

    pub(crate) fn generation(&self) -> u64 {
        self.generation
    }

    pub(crate) fn add(&mut self, rule: Rule) -> Arc<RuleCounter> {
        let counter = Arc::new(RuleCounter::default());
        self.entries.push(Entry {
            rule,
            seen: 0,
            counter: Arc::clone(&counter),
        });
        self.generation += 1;
        counter
    }

    pub(crate) fn remove(&mut self, counter: &Arc<RuleCounter>) {
        counter.finished.store(true, Ordering::Release);
        self.entries.retain(|e| !Arc::ptr_eq(&e.counter, counter));
        self.generation += 1;
    }

    pub(crate) fn clear(&mut self) {
        for entry in self.entries.drain(..) {
            entry.counter.finished.store(true, Ordering::Release);
        }
        self.generation += 1;
    }

    /// Decides what happens to the next frame, which is `len` bytes long, and counts the rules
    /// that fire. Rules that are done are removed (their handles keep the counts).
    pub(crate) fn decide(&mut self, len: usize) -> Decision {
        let mut decision = Decision::default();
        let rng = &mut self.rng;
        for entry in &mut self.entries {
            entry.seen += 1;
            let fires = match entry.rule.when {
                When::Nth(n) => entry.seen == n.max(1),
                When::Every(n) => entry.seen % n.max(1) == 0,
                When::Randomly { one_in } => rng.below(u64::from(one_in.max(1))) == 0,
            };
            if !fires {
                continue;
            }
            decision.fired += 1;
            let fired = entry.counter.fired.fetch_add(1, Ordering::AcqRel) + 1;
            let once = matches!(entry.rule.when, When::Nth(_));
            if once || entry.rule.limit.is_some_and(|limit| fired >= limit) {
                entry.counter.finished.store(true, Ordering::Release);
            }
            apply(&mut decision, entry.rule.fault, len, rng);
        }
        let before = self.entries.len();
        self.entries.retain(|e| !e.counter.is_finished());
        if self.entries.len() != before {
            // A finished rule changes what is in force: pauses it caused end.
            self.generation += 1;
        }
        decision
    }
}

fn position(at: At, len: usize, rng: &mut XorShift64) -> usize {
    let last = len.saturating_sub(1);
    match at {
        At::Start(i) => i.min(last),
        At::End(i) => last - i.min(last),
        At::Random => rng.below(len as u64) as usize,
    }
}

/// Adds one fault's effect to a decision. How several faults on one frame combine: delays add up,
/// corruptions and removed ranges all apply, duplicates add up, the shortest cut wins, the last
/// split or merge wins.
fn apply(decision: &mut Decision, fault: Fault, len: usize, rng: &mut XorShift64) {
    match fault {
        Fault::Delay(d) => decision.delay = decision.delay.saturating_add(d),
        Fault::Split { piece_len, pause } => decision.split = Some((piece_len.max(1), pause)),
        Fault::Merge { frames, max_wait } => decision.merge = Some((frames.max(1), max_wait)),
        Fault::Corrupt { at, xor } => {
            if len > 0 {
                let mask = if xor == 0 { 0xFF } else { xor };
                decision.corrupt.push((position(at, len, rng), mask));
            }
        }
        Fault::Drop => decision.drop = true,
        Fault::DropBytes { at, len: n } => {
            if len > 0 && n > 0 {
                decision.drop_bytes.push((position(at, len, rng), n));
            }
        }
        Fault::Duplicate => decision.duplicates += 1,
        Fault::Stall => decision.stall = true,
        Fault::Cut { after_bytes } => {
            decision.cut_after = Some(
                decision
                    .cut_after
                    .map_or(after_bytes, |c| c.min(after_bytes)),
            );
        }
    }
}

/// One thing for the socket code to do, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Step {
    /// Close this direction's gate: nothing more is written until the test releases it.
    Stall,
    /// Wait this long (ends early when this direction's faults change).
    Wait(Duration),
    /// Write these bytes (through the gate), in pieces of `split.0` bytes with `split.1` between
    /// them if `split` is set, else in one write.
    Write {
        bytes: Bytes,
        split: Option<(usize, Duration)>,
    },
    /// Close the connection, both sides.
    Cut,
}

/// Frames being held to be written together.
#[derive(Debug)]
struct MergeGroup {
    frames_left: usize,
    max_wait: Duration,
    held: BytesMut,
}

/// Per connection and direction: turns frames and decisions into steps, holding merge groups.
///
/// Memory bound: a merge group holds at most `max_held` bytes plus one frame.
#[derive(Debug)]
pub(crate) struct Pipeline {
    max_held: usize,
    merge: Option<MergeGroup>,
}

impl Pipeline {
    pub(crate) fn new(max_held: usize) -> Self {
        Pipeline {
            max_held: max_held.max(1),
            merge: None,
        }
    }

    /// If a merge group is being held: the longest it may be held.
    pub(crate) fn merge_wait(&self) -> Option<Duration> {
        self.merge.as_ref().map(|g| g.max_wait)
    }

    /// Ends the merge group now (deadline, fault change, end of stream).
    pub(crate) fn flush(&mut self) -> Option<Step> {
        let group = self.merge.take()?;
        (!group.held.is_empty()).then(|| Step::Write {
            bytes: group.held.freeze(),
            split: None,
        })
    }

    /// Bytes that are not a frame: forwarded untouched, in order (inside a merge group if one is
    /// being held, without counting as one of its frames).
    pub(crate) fn passthrough(&mut self, bytes: Bytes) -> Vec<Step> {
        match &mut self.merge {
            Some(group) => {
                group.held.extend_from_slice(&bytes);
                if group.held.len() >= self.max_held {
                    return self.flush().into_iter().collect();
                }
                Vec::new()
            }
            None => vec![Step::Write { bytes, split: None }],
        }
    }

    /// A frame and what the rules decided for it.
    pub(crate) fn frame(&mut self, frame: Bytes, decision: &Decision) -> Vec<Step> {
        let mut steps = Vec::new();
        if decision.stall {
            steps.push(Step::Stall);
        }
        if !decision.delay.is_zero() {
            steps.push(Step::Wait(decision.delay));
        }
        if decision.drop {
            return steps;
        }
        let body = alter(frame, decision);
        if let Some(after) = decision.cut_after {
            // Frames held for a merge came first: deliver them, then the start of this frame.
            steps.extend(self.flush());
            let part = body.slice(..after.min(body.len()));
            if !part.is_empty() {
                steps.push(Step::Write {
                    bytes: part,
                    split: decision.split,
                });
            }
            steps.push(Step::Cut);
            return steps;
        }
        if self.merge.is_none() {
            if let Some((frames, max_wait)) = decision.merge {
                self.merge = Some(MergeGroup {
                    frames_left: frames,
                    max_wait,
                    held: BytesMut::new(),
                });
            }
        }
        let copies = 1 + decision.duplicates;
        match &mut self.merge {
            Some(group) => {
                for _ in 0..copies {
                    group.held.extend_from_slice(&body);
                }
                group.frames_left = group.frames_left.saturating_sub(1);
                if group.frames_left == 0 || group.held.len() >= self.max_held {
                    steps.extend(self.flush());
                }
            }
            None => {
                for _ in 0..copies {
                    steps.push(Step::Write {
                        bytes: body.clone(),
                        split: decision.split,
                    });
                }
            }
        }
        steps
    }
}

/// The frame with its corruptions and removed ranges applied.
fn alter(frame: Bytes, decision: &Decision) -> Bytes {
    if decision.corrupt.is_empty() && decision.drop_bytes.is_empty() {
        return frame;
    }
    let mut bytes = frame.to_vec();
    for &(index, mask) in &decision.corrupt {
        if let Some(byte) = bytes.get_mut(index) {
            *byte ^= mask;
        }
    }
    if !decision.drop_bytes.is_empty() {
        let mut keep = vec![true; bytes.len()];
        for &(start, len) in &decision.drop_bytes {
            let end = start.saturating_add(len).min(keep.len());
            if let Some(range) = keep.get_mut(start..end) {
                range.fill(false);
            }
        }
        let mut keep = keep.into_iter();
        bytes.retain(|_| keep.next().unwrap_or(true));
    }
    Bytes::from(bytes)
}

/// This direction's stall switch, with byte credits so a test can let exact amounts through.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Gate {
    stalled: bool,
    credit: usize,
}

impl Gate {
    pub(crate) fn is_stalled(&self) -> bool {
        self.stalled
    }

    pub(crate) fn stall(&mut self) {
        self.stalled = true;
        self.credit = 0;
    }

    pub(crate) fn release(&mut self) {
        self.stalled = false;
        self.credit = 0;
    }

    pub(crate) fn release_bytes(&mut self, n: usize) {
        self.credit = self.credit.saturating_add(n);
    }

    /// How many of `want` bytes may be written now (0 = wait), taking them from the credit.
    pub(crate) fn take(&mut self, want: usize) -> usize {
        if !self.stalled {
            return want;
        }
        let n = self.credit.min(want);
        self.credit -= n;
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decide_n(rules: &mut RuleSet, n: usize) -> Vec<bool> {
        (0..n).map(|_| rules.decide(4).fired > 0).collect()
    }

    fn writes(steps: &[Step]) -> Vec<Vec<u8>> {
        steps
            .iter()
            .filter_map(|s| match s {
                Step::Write { bytes, .. } => Some(bytes.to_vec()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn nth_fires_once_then_the_rule_is_gone() {
        let mut rules = RuleSet::new(1);
        let counter = rules.add(Fault::Drop.nth(2));
        assert_eq!(decide_n(&mut rules, 4), [false, true, false, false]);
        assert_eq!(counter.fired(), 1);
        assert!(counter.is_finished());
        assert!(rules.entries.is_empty());
    }

    #[test]
    fn every_third_with_a_limit() {
        let mut rules = RuleSet::new(1);
        let counter = rules.add(Fault::Drop.every(3).times(2));
        let fired = decide_n(&mut rules, 12);
        assert_eq!(
            fired,
            [false, false, true, false, false, true, false, false, false, false, false, false]
        );
        assert_eq!(counter.fired(), 2);
        assert!(counter.is_finished());
    }

    #[test]
    fn rules_count_frames_from_when_they_were_added() {
        let mut rules = RuleSet::new(1);
        let _ = decide_n(&mut rules, 5);
        let counter = rules.add(Fault::Duplicate.once());
        assert!(rules.decide(4).duplicates == 1);
        assert_eq!(counter.fired(), 1);
    }

    #[test]
    fn random_rules_are_reproducible_per_seed() {
        let run = |seed| {
            let mut rules = RuleSet::new(seed);
            rules.add(Fault::Drop.randomly(3));
            decide_n(&mut rules, 64)
        };
        let a = run(42);
        assert_eq!(a, run(42));
        assert_ne!(a, run(43));
        let hits = a.iter().filter(|&&f| f).count();
        assert!((5..=40).contains(&hits), "{hits} of 64");
    }

    #[test]
    fn remove_and_clear_bump_the_generation_and_finish_handles() {
        let mut rules = RuleSet::new(1);
        let a = rules.add(Fault::Drop.always());
        let b = rules.add(Fault::Duplicate.always());
        let generation = rules.generation();
        rules.remove(&a);
        assert!(a.is_finished() && !b.is_finished());
        assert!(rules.generation() > generation);
        rules.clear();
        assert!(b.is_finished());
        assert_eq!(rules.decide(4), Decision::default());
    }

    #[test]
    fn positions_clamp_to_the_frame() {
        let mut rng = XorShift64::new(7);
        assert_eq!(position(At::Start(0), 5, &mut rng), 0);
        assert_eq!(position(At::Start(9), 5, &mut rng), 4);
        assert_eq!(position(At::End(0), 5, &mut rng), 4);
        assert_eq!(position(At::End(9), 5, &mut rng), 0);
        for _ in 0..100 {
            assert!(position(At::Random, 5, &mut rng) < 5);
        }
    }

    #[test]
    fn corrupt_and_drop_bytes_change_the_frame() {
        let mut rules = RuleSet::new(1);
        rules.add(
            Fault::Corrupt {
                at: At::End(0),
                xor: 0,
            }
            .once(),
        );
        rules.add(
            Fault::DropBytes {
                at: At::Start(1),
                len: 2,
            }
            .once(),
        );
        let decision = rules.decide(5);
        let steps = Pipeline::new(64).frame(Bytes::from_static(b"abcde"), &decision);
        assert_eq!(writes(&steps), [vec![b'a', b'd', b'e' ^ 0xFF]]);
    }

    #[test]
    fn drop_writes_nothing_and_duplicate_writes_twice() {
        let mut pipeline = Pipeline::new(64);
        let dropped = Decision {
            drop: true,
            ..Decision::default()
        };
        assert!(pipeline
            .frame(Bytes::from_static(b"x"), &dropped)
            .is_empty());
        let twice = Decision {
            duplicates: 1,
            ..Decision::default()
        };
        assert_eq!(
            writes(&pipeline.frame(Bytes::from_static(b"x"), &twice)),
            [b"x", b"x"]
        );
    }

    #[test]
    fn stall_and_delay_come_before_the_write() {
        let decision = Decision {
            stall: true,
            delay: Duration::from_secs(1),
            split: Some((2, Duration::ZERO)),
            ..Decision::default()
        };
        let steps = Pipeline::new(64).frame(Bytes::from_static(b"abc"), &decision);
        assert_eq!(
            steps,
            [
                Step::Stall,
                Step::Wait(Duration::from_secs(1)),
                Step::Write {
                    bytes: Bytes::from_static(b"abc"),
                    split: Some((2, Duration::ZERO))
                },
            ]
        );
    }

    #[test]
    fn merge_holds_frames_and_garbage_in_order_until_the_group_is_full() {
        let mut pipeline = Pipeline::new(64);
        let merge = Decision {
            merge: Some((3, Duration::from_secs(1))),
            ..Decision::default()
        };
        let none = Decision::default();
        assert!(pipeline.frame(Bytes::from_static(b"a;"), &merge).is_empty());
        assert_eq!(pipeline.merge_wait(), Some(Duration::from_secs(1)));
        assert!(pipeline.passthrough(Bytes::from_static(b"~")).is_empty());
        assert!(pipeline.frame(Bytes::from_static(b"b;"), &merge).is_empty());
        assert_eq!(
            writes(&pipeline.frame(Bytes::from_static(b"c;"), &none)),
            [b"a;~b;c;"]
        );
        assert_eq!(pipeline.merge_wait(), None);
        assert_eq!(
            writes(&pipeline.frame(Bytes::from_static(b"d;"), &none)),
            [b"d;"]
        );
    }

    #[test]
    fn merge_is_bounded_and_flushes_on_demand() {
        let mut pipeline = Pipeline::new(4);
        let merge = Decision {
            merge: Some((10, Duration::from_secs(1))),
            ..Decision::default()
        };
        assert!(pipeline.frame(Bytes::from_static(b"ab"), &merge).is_empty());
        assert_eq!(
            writes(&pipeline.frame(Bytes::from_static(b"cd"), &merge)),
            [b"abcd"]
        );
        assert!(pipeline.frame(Bytes::from_static(b"ef"), &merge).is_empty());
        assert_eq!(
            writes(&pipeline.flush().into_iter().collect::<Vec<_>>()),
            [b"ef"]
        );
        assert_eq!(pipeline.flush(), None);
    }

    #[test]
    fn cut_delivers_held_frames_then_part_of_this_one() {
        let mut pipeline = Pipeline::new(64);
        let merge = Decision {
            merge: Some((3, Duration::from_secs(1))),
            ..Decision::default()
        };
        let cut = Decision {
            cut_after: Some(2),
            ..Decision::default()
        };
        assert!(pipeline
            .frame(Bytes::from_static(b"one;"), &merge)
            .is_empty());
        let steps = pipeline.frame(Bytes::from_static(b"two;"), &cut);
        assert_eq!(writes(&steps), [b"one;".to_vec(), b"tw".to_vec()]);
        assert_eq!(steps.last(), Some(&Step::Cut));
        let cut_now = Decision {
            cut_after: Some(0),
            ..Decision::default()
        };
        assert_eq!(
            pipeline.frame(Bytes::from_static(b"x"), &cut_now),
            [Step::Cut]
        );
    }

    #[test]
    fn several_cuts_take_the_shortest() {
        let mut rules = RuleSet::new(1);
        rules.add(Fault::Cut { after_bytes: 5 }.once());
        rules.add(Fault::Cut { after_bytes: 2 }.once());
        assert_eq!(rules.decide(8).cut_after, Some(2));
    }

    #[test]
    fn gate_credits_let_exact_amounts_through() {
        let mut gate = Gate::default();
        assert_eq!(gate.take(10), 10);
        gate.stall();
        assert_eq!(gate.take(10), 0);
        gate.release_bytes(3);
        assert_eq!(gate.take(10), 3);
        assert_eq!(gate.take(10), 0);
        assert!(gate.is_stalled());
        gate.release();
        assert_eq!(gate.take(10), 10);
    }
}
