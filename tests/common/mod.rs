//! Helpers shared by the integration tests (`mod common;` in each file that uses them).

/// xorshift64: a small seeded generator, so randomised tests are reproducible without a
/// dependency. Seed with a non-zero value (zero stays zero).
pub struct Rng(pub u64);

impl Rng {
    /// The next draw in `0..n` (`0` when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % n.max(1)
    }
}
