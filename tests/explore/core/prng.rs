//! The explorer's one source of randomness: SplitMix64 (Steele, Lea, Flood 2014), small and
//! good enough for choosing schedules; no dependency.

/// A seeded generator.
#[derive(Clone, Debug)]
pub struct Prng(u64);

impl Prng {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        Prng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 if `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next_u64() % n
        }
    }

    /// A number in `lo..=hi`.
    pub fn between(&mut self, lo: u64, hi: u64) -> u64 {
        lo + self.below(hi.saturating_sub(lo) + 1)
    }

    /// True with probability `1 / n` (never for 0).
    pub fn one_in(&mut self, n: u64) -> bool {
        n != 0 && self.below(n) == 0
    }

    /// A float in `lo..hi`.
    pub fn float(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    /// A duration of `lo_ms..=hi_ms` milliseconds.
    pub fn millis(&mut self, lo_ms: u64, hi_ms: u64) -> std::time::Duration {
        std::time::Duration::from_millis(self.between(lo_ms, hi_ms))
    }

    /// How often a fault hits, as "one in `n`", for fault intensity `level` (1–3): never with
    /// probability `1 / off_one_in`, else `base / level` to `4 × base / level` (at least 2).
    pub fn fault_rate(&mut self, level: u32, base: u64, off_one_in: u64) -> u64 {
        if level == 0 || self.one_in(off_one_in) {
            return 0;
        }
        let level = u64::from(level);
        self.between(base / level, 4 * base / level).max(2)
    }

    /// An independent generator for one component (a fixed number of draws from this one).
    pub fn fork(&mut self) -> Prng {
        Prng::new(self.next_u64())
    }
}
