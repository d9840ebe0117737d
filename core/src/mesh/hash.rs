//! A fast, deterministic hasher for the mesh builders' integer keys (welded vertex bits, vertex
//! index pairs): one multiply–rotate per word and splitmix64's finaliser, instead of std's
//! SipHash, which is built to resist chosen keys (a scene's own vertex data does not attack
//! its renderer) and was 14 % of the instructions of `penumbra info killeroo-simple.pbrt -i
//! silhouette`. Its value does not depend on the process, unlike `RandomState`'s.

use crate::rng::mix_bits;
use std::hash::{BuildHasherDefault, Hasher};

/// [`WordHasher`] for `HashMap`s.
pub type WordHash = BuildHasherDefault<WordHasher>;

#[derive(Clone, Copy, Debug, Default)]
pub struct WordHasher(u64);

impl WordHasher {
    #[inline]
    fn add(&mut self, w: u64) {
        self.0 = (self.0.rotate_left(26) ^ w).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

impl Hasher for WordHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut b = [0u8; 8];
            b[..chunk.len()].copy_from_slice(chunk);
            self.add(u64::from_le_bytes(b));
        }
    }
    #[inline]
    fn write_u32(&mut self, v: u32) {
        self.add(v as u64);
    }
    #[inline]
    fn write_u64(&mut self, v: u64) {
        self.add(v);
    }
    #[inline]
    fn write_usize(&mut self, v: usize) {
        self.add(v as u64);
    }
    #[inline]
    fn finish(&self) -> u64 {
        mix_bits(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::hash::{BuildHasher, Hash};

    fn h<T: Hash>(v: T) -> u64 {
        WordHash::default().hash_one(v)
    }

    /// Nearby keys spread over every bit (hashbrown indexes with the low bits and tags with the
    /// top 7), and the value is the same in every process.
    #[test]
    fn nearby_keys_spread_over_low_and_high_bits() {
        let mut low = std::collections::HashSet::new();
        let mut high = std::collections::HashSet::new();
        for a in 0u32..64 {
            for b in 0u32..64 {
                let v = h((a, b));
                low.insert(v & 0xfff);
                high.insert(v >> 57);
            }
        }
        assert!(low.len() > 2500, "{} distinct low 12-bit values of 4096 keys", low.len());
        assert_eq!(high.len(), 128);
        assert_eq!(h((1u32, 2u32)), h((1u32, 2u32)));
        assert_ne!(h((1u32, 2u32)), h((2u32, 1u32)));
        assert_ne!(h([0u32, 0, 1]), h([0u32, 1, 0]));
    }
}
