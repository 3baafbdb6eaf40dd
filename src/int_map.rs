//! Hash maps keyed by the crate's own small integers (call tokens, command ids) on a client's
//! hot path.
//!
//! std's default hasher (SipHash) guards against keys chosen to collide; these keys are a
//! counter the client increments or a one-byte command id, so there is nothing to guard, and
//! SipHash was about a tenth of the instructions of a WSG round trip (issue 14, callgrind). One
//! multiplication by an odd constant (Fibonacci hashing) spreads consecutive keys over both the
//! high bits (the table's tags) and the low bits (its buckets).

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A `HashMap` keyed by an integer the crate chose.
pub(crate) type IntMap<K, V> = HashMap<K, V, BuildHasherDefault<IntHasher>>;

/// 2^64 ÷ the golden ratio, odd: multiplying by it permutes the 64-bit values.
const SPREAD: u64 = 0x9E37_79B9_7F4A_7C15;

/// The hasher of [`IntMap`]: integer keys only (any other key is still hashed correctly, a
/// byte at a time).
#[derive(Default)]
pub(crate) struct IntHasher(u64);

impl Hasher for IntHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u8(&mut self, n: u8) {
        self.write_u64(n.into());
    }

    fn write_u16(&mut self, n: u16) {
        self.write_u64(n.into());
    }

    fn write_u32(&mut self, n: u32) {
        self.write_u64(n.into());
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(SPREAD);
    }

    fn write_usize(&mut self, n: usize) {
        self.write_u64(n as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::hash::BuildHasher;

    #[test]
    fn consecutive_keys_differ_in_the_high_and_the_low_bits() {
        let build = BuildHasherDefault::<IntHasher>::default();
        let hashes: Vec<u64> = (0u64..256).map(|k| build.hash_one(k)).collect();
        let tags: std::collections::HashSet<u64> = hashes.iter().map(|h| h >> 57).collect();
        let buckets: std::collections::HashSet<u64> = hashes.iter().map(|h| h & 0xFF).collect();
        // 256 keys over 128 tags and 256 buckets: a hash that kept consecutive keys together
        // (the identity, say) would give one tag.
        assert!(tags.len() > 100, "{} tags", tags.len());
        assert_eq!(buckets.len(), 256);
    }

    #[test]
    fn works_as_a_map() {
        let mut m: IntMap<u8, u32> = IntMap::default();
        for k in 0..=u8::MAX {
            m.insert(k, u32::from(k) * 3);
        }
        assert!((0..=u8::MAX).all(|k| m.get(&k) == Some(&(u32::from(k) * 3))));
        assert_eq!(m.remove(&7), Some(21));
        assert_eq!(m.len(), 255);
    }
}
