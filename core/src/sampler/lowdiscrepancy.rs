//! Low-discrepancy building blocks: radical inverses (plain and digit-permuted),
//! Sobol' generator matrices, and pbrt-v3's scrambled, shuffled (0,2)-sequence
//! and van der Corput pixel patterns.

use crate::rng::{Rng, ONE_MINUS_EPSILON_F32};
use crate::sampling::shuffle;
use glam::Vec2;
use std::sync::{Arc, OnceLock};

/// Number of prime bases (and so Halton dimensions) supported, as pbrt-v3.
pub const PRIME_TABLE_SIZE: usize = 1000;

/// Sobol' dimensions available (Joe–Kuo new-joe-kuo-6.21201, via SciPy; see tools/gen_sobol_matrices.py).
pub const NUM_SOBOL_DIMENSIONS: u32 = 1024;
/// Generator-matrix columns per dimension: indices below 2^52 are supported.
pub const SOBOL_MATRIX_SIZE: usize = 52;

const SOBOL_BYTES: &[u8] = include_bytes!("sobol_matrices.bin");

/// Columns per dimension in [`SOBOL_MATRICES`]: the `SOBOL_MATRIX_SIZE` columns, then zeros,
/// so that any index bit (0–63) addresses its column without a bounds check.
const SOBOL_ROW: usize = 64;

/// The generator matrices as words, dimension `d`'s column `j` at `d * SOBOL_ROW + j`.
static SOBOL_MATRICES: [[u32; SOBOL_ROW]; NUM_SOBOL_DIMENSIONS as usize] = {
    let mut out = [[0u32; SOBOL_ROW]; NUM_SOBOL_DIMENSIONS as usize];
    let mut d = 0;
    while d < NUM_SOBOL_DIMENSIONS as usize {
        let mut j = 0;
        while j < SOBOL_MATRIX_SIZE {
            let k = 4 * (d * SOBOL_MATRIX_SIZE + j);
            if k + 4 <= SOBOL_BYTES.len() {
                let b = [SOBOL_BYTES[k], SOBOL_BYTES[k + 1], SOBOL_BYTES[k + 2], SOBOL_BYTES[k + 3]];
                out[d][j] = u32::from_le_bytes(b);
            }
            j += 1;
        }
        d += 1;
    }
    out
};

/// Column `j` (contribution of index bit `j`, most significant output bit first) of dimension `dim`'s
/// Sobol' generator matrix; 0 out of range.
pub fn sobol_column(dim: u32, j: usize) -> u32 {
    if dim >= NUM_SOBOL_DIMENSIONS || j >= SOBOL_MATRIX_SIZE {
        return 0;
    }
    SOBOL_MATRICES[dim as usize][j]
}

/// The 32-bit fixed-point Sobol' sample (numerator over 2^32) of `index` in `dim`: the XOR of
/// the columns of the index's set bits (bits from `SOBOL_MATRIX_SIZE` on have zero columns).
#[inline]
pub fn sobol_sample_bits(index: u64, dim: u32) -> u32 {
    let Some(columns) = SOBOL_MATRICES.get(dim as usize) else { return 0 };
    let (mut v, mut a) = (0u32, index);
    while a != 0 {
        v ^= columns[a.trailing_zeros() as usize & (SOBOL_ROW - 1)];
        a &= a - 1;
    }
    v
}

/// 32-bit fixed point to `[0, 1)`.
pub fn bits_to_unit(v: u32) -> f32 {
    (v as f32 * (1.0 / 4_294_967_296.0)).min(ONE_MINUS_EPSILON_F32)
}

/// Multiplies a 32×32 generator matrix (columns `c`) by the bits of `a`.
pub fn multiply_generator(c: &[u32; 32], a: u32) -> u32 {
    let mut v = 0u32;
    let mut a = a;
    let mut i = 0;
    while a != 0 {
        if a & 1 == 1 {
            v ^= c[i];
        }
        a >>= 1;
        i += 1;
    }
    v
}

/// The first `PRIME_TABLE_SIZE` primes, by a sieve of Eratosthenes at compile time (the 1000th is 7919).
static PRIMES: [u32; PRIME_TABLE_SIZE] = {
    const LIMIT: usize = 7920;
    let mut composite = [false; LIMIT];
    let mut out = [0u32; PRIME_TABLE_SIZE];
    let mut count = 0;
    let mut n = 2;
    while n < LIMIT && count < PRIME_TABLE_SIZE {
        if !composite[n] {
            out[count] = n as u32;
            count += 1;
            let mut k = n * n;
            while k < LIMIT {
                composite[k] = true;
                k += n;
            }
        }
        n += 1;
    }
    out
};

/// `PRIME_SUMS[i]` = sum of the first `i` primes.
static PRIME_SUMS: [usize; PRIME_TABLE_SIZE] = {
    let mut out = [0usize; PRIME_TABLE_SIZE];
    let mut i = 1;
    while i < PRIME_TABLE_SIZE {
        out[i] = out[i - 1] + PRIMES[i - 1] as usize;
        i += 1;
    }
    out
};

/// The first `PRIME_TABLE_SIZE` primes.
pub fn primes() -> &'static [u32] {
    &PRIMES
}

/// `prime_sums()[i]` = sum of the first `i` primes (offsets of each base's permutation).
pub fn prime_sums() -> &'static [usize] {
    &PRIME_SUMS
}

/// Division of 32-bit numerators by a fixed divisor without a divide instruction
/// (Lemire, Kaser & Kurz 2019: with `m = ⌊(2⁶⁴ − 1) / d⌋ + 1`, `⌊a / d⌋ = ⌊a m / 2⁶⁴⌋` for every
/// 32-bit `a` and divisor `d` ≥ 2). Larger numerators fall back to plain division.
#[derive(Clone, Copy, Debug)]
pub struct FastDiv {
    d: u64,
    m: u64,
}

impl FastDiv {
    pub const fn new(d: u32) -> Self {
        let d = if d < 2 { 2 } else { d as u64 };
        FastDiv { d, m: u64::MAX / d + 1 }
    }
    /// `(a / d, a % d)`.
    #[inline(always)]
    pub fn div_rem(self, a: u64) -> (u64, u64) {
        let q = if a <= u32::MAX as u64 { ((a as u128 * self.m as u128) >> 64) as u64 } else { a / self.d };
        (q, a - q * self.d)
    }
    /// [`FastDiv::div_rem`] for `a` ≤ `u32::MAX` (larger values give wrong results).
    #[inline(always)]
    fn div_rem_u32(self, a: u64) -> (u64, u64) {
        debug_assert!(a <= u32::MAX as u64);
        let q = ((a as u128 * self.m as u128) >> 64) as u64;
        (q, a - q * self.d)
    }
}

/// Per prime base: the divisor and `1 / base` (the same f64 `radical_inverse` computes).
#[derive(Clone, Copy, Debug)]
pub struct PrimeBase {
    pub div: FastDiv,
    pub inv_base: f64,
}

static PRIME_BASES: [PrimeBase; PRIME_TABLE_SIZE] = {
    let mut out = [PrimeBase { div: FastDiv::new(2), inv_base: 0.5 }; PRIME_TABLE_SIZE];
    let mut i = 0;
    while i < PRIME_TABLE_SIZE {
        out[i] = PrimeBase { div: FastDiv::new(PRIMES[i]), inv_base: 1.0 / PRIMES[i] as f64 };
        i += 1;
    }
    out
};

/// The radical inverse of `a` in the `base_index`-th prime base (0 → base 2), in `[0, 1)`.
pub fn radical_inverse(base_index: usize, a: u64) -> f32 {
    if base_index == 0 {
        return ((a.reverse_bits() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)).min(ONE_MINUS_EPSILON_F32 as f64)
            as f32;
    }
    if base_index == 1 && a < POW3_40 {
        return radical_inverse_3(a);
    }
    let pb = PRIME_BASES[base_index.min(PRIME_TABLE_SIZE - 1)];
    let (mut a, mut inv_base_n, mut result) = (a, 1.0f64, 0.0f64);
    while a > 0 {
        let (next, digit) = pb.div.div_rem(a);
        inv_base_n *= pb.inv_base;
        result += digit as f64 * inv_base_n;
        a = next;
    }
    (result as f32).min(ONE_MINUS_EPSILON_F32)
}

/// 3⁴⁰: below it, [`radical_inverse_3`]'s reversed digits fit in a `u64`.
const POW3_40: u64 = 12_157_665_459_056_928_801;

/// The five base-3 digits of each value below 3⁵, reversed.
static REVERSED_3_5: [u8; 243] = {
    let mut t = [0u8; 243];
    let mut i = 0;
    while i < 243 {
        let (mut a, mut r, mut k) = (i, 0, 0);
        while k < 5 {
            r = r * 3 + a % 3;
            a /= 3;
            k += 1;
        }
        t[i] = r as u8;
        i += 1;
    }
    t
};

/// The base-3 radical inverse of `a < 3⁴⁰` (the Halton sampler's second dimension, drawn for
/// every camera sample), five digits at a time: the reversed digits as an exact integer, scaled
/// once (a leading zero digit of `a` is a trailing zero of the inverse, so whole chunks of five
/// give the same value).
fn radical_inverse_3(a: u64) -> f32 {
    let (mut a, mut reversed, mut scale) = (a, 0u64, 1.0f64);
    while a > 0 {
        reversed = reversed * 243 + REVERSED_3_5[(a % 243) as usize] as u64;
        a /= 243;
        scale *= 243.0;
    }
    ((reversed as f64 / scale) as f32).min(ONE_MINUS_EPSILON_F32)
}

/// The radical inverse with each digit (including the infinitely many trailing zeros) mapped by `perm`.
pub fn scrambled_radical_inverse(base_index: usize, a: u64, perm: &[u16]) -> f32 {
    let base_index = base_index.min(PRIME_TABLE_SIZE - 1);
    if perm.len() < PRIMES[base_index] as usize {
        return radical_inverse(base_index, a);
    }
    scrambled_radical_inverse_in(&PRIME_BASES[base_index], a, perm)
}

/// [`scrambled_radical_inverse`] for a base given by its table entry; `perm` must hold at least
/// `base` entries (digits index it; a shorter table panics).
#[inline]
fn scrambled_radical_inverse_in(pb: &PrimeBase, a: u64, perm: &[u16]) -> f32 {
    scrambled_digits(pb, a, perm, 1.0, 0.0)
}

/// The digit loop of [`scrambled_radical_inverse_in`] from a state it reaches after some low
/// digits: `a` the remaining digits, `inv_base_n` and `result` its running values.
#[inline(always)]
fn scrambled_digits(pb: &PrimeBase, a: u64, perm: &[u16], inv_base_n: f64, result: f64) -> f32 {
    let inv_base = pb.inv_base;
    let (mut a, mut inv_base_n, mut result) = (a, inv_base_n, result);
    // The same digits, low first, in two loops: those of a value beyond 32 bits by division,
    // then (the values every sampler index takes) by the multiplication alone.
    while a > u32::MAX as u64 {
        let (next, digit) = pb.div.div_rem(a);
        inv_base_n *= inv_base;
        result += perm[digit as usize] as f64 * inv_base_n;
        a = next;
    }
    while a > 0 {
        let (next, digit) = pb.div.div_rem_u32(a);
        inv_base_n *= inv_base;
        result += perm[digit as usize] as f64 * inv_base_n;
        a = next;
    }
    result += perm[0] as f64 * inv_base_n * inv_base / (1.0 - inv_base);
    (result as f32).min(ONE_MINUS_EPSILON_F32)
}

/// Bases (the first `PAIR_BASES`) whose two lowest digits are looked up together: the running
/// sum after two digits is a function of those digits alone (it starts from 0), so a table of
/// `base²` entries holds it exactly; the digits after it are summed one by one as before.
const PAIR_BASES: usize = 16;

/// `PAIR_OFFSETS[i]`: where base `i`'s pair table starts (the sum of the squares of the primes before it).
const PAIR_OFFSETS: [usize; PAIR_BASES + 1] = {
    let mut out = [0usize; PAIR_BASES + 1];
    let mut i = 0;
    while i < PAIR_BASES {
        out[i + 1] = out[i] + PRIMES_HEAD[i] * PRIMES_HEAD[i];
        i += 1;
    }
    out
};

/// The first primes, for the constants above (`PRIMES` is a static).
const PRIMES_HEAD: [usize; PAIR_BASES] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];

/// Division by `base²` for the pair bases.
static PAIR_DIVS: [FastDiv; PAIR_BASES] = {
    let mut out = [FastDiv::new(2); PAIR_BASES];
    let mut i = 0;
    while i < PAIR_BASES {
        out[i] = FastDiv::new((PRIMES_HEAD[i] * PRIMES_HEAD[i]) as u32);
        i += 1;
    }
    out
};

/// The running sum of [`scrambled_digits`] after the two lowest digits `r % b`, `r / b`, for
/// every `r < b²` of each pair base, computed by the same two steps.
fn pair_tables(head: &[u16]) -> Vec<f64> {
    let mut out = Vec::with_capacity(PAIR_OFFSETS[PAIR_BASES]);
    for i in 0..PAIR_BASES {
        let (p, inv_base) = (PRIMES[i] as usize, PRIME_BASES[i].inv_base);
        let perm = &head[PRIME_SUMS[i]..PRIME_SUMS[i] + p];
        for r in 0..p * p {
            let (mut inv_base_n, mut result) = (1.0f64, 0.0f64);
            for digit in [r % p, r / p] {
                inv_base_n *= inv_base;
                result += perm[digit] as f64 * inv_base_n;
            }
            out.push(result);
        }
    }
    out
}

/// Bases whose permutations are drawn when a [`ScrambledRadicalInverses`] is made; the
/// others (a table of 3.7 M digits) only when a dimension past them is first used.
const EAGER_BASES: usize = 128;

/// Digit-permuted radical inverses in every prime base, with the permutations that
/// [`radical_inverse_permutations`] draws from the same generator (bit-identical values).
#[derive(Clone, Debug)]
pub struct ScrambledRadicalInverses {
    /// Permutations of the first `EAGER_BASES` bases, concatenated.
    head: Arc<Vec<u16>>,
    /// [`pair_tables`] of `head`.
    pairs: Arc<Vec<f64>>,
    /// The generator after `head`, and the remaining permutations drawn from it on demand.
    tail: Arc<(Rng, OnceLock<Vec<u16>>)>,
}

fn append_permutations(perms: &mut Vec<u16>, bases: &[u32], rng: &mut Rng) {
    for &p in bases {
        let start = perms.len();
        perms.extend(0..p as u16);
        shuffle(&mut perms[start..], 1, rng);
    }
}

impl ScrambledRadicalInverses {
    pub fn new(rng: &mut Rng) -> Self {
        let mut head = Vec::with_capacity(PRIME_SUMS[EAGER_BASES]);
        append_permutations(&mut head, &PRIMES[..EAGER_BASES], rng);
        let tail = Arc::new((rng.clone(), OnceLock::new()));
        let pairs = Arc::new(pair_tables(&head));
        ScrambledRadicalInverses { head: Arc::new(head), pairs, tail }
    }

    /// The permuted radical inverse of `a` in base `primes()[base_index]` (`base_index` < `PRIME_TABLE_SIZE`).
    #[inline]
    pub fn eval(&self, base_index: usize, a: u64) -> f32 {
        let i = base_index.min(PRIME_TABLE_SIZE - 1);
        if i < PAIR_BASES && a >= PRIMES_HEAD[i] as u64 && a <= u32::MAX as u64 {
            // Two digits or more: the first two from the table.
            let pb = &PRIME_BASES[i];
            let (rest, low) = PAIR_DIVS[i].div_rem_u32(a);
            let result = self.pairs[PAIR_OFFSETS[i] + low as usize];
            return scrambled_digits(pb, rest, &self.head[PRIME_SUMS[i]..], pb.inv_base * pb.inv_base, result);
        }
        // (The digits index the permutation; the slice's end is only bounded by the table's.)
        let perm = if i < EAGER_BASES {
            &self.head[PRIME_SUMS[i]..]
        } else {
            let tail = self.tail.1.get_or_init(|| {
                let mut rng = self.tail.0.clone();
                let mut t = Vec::new();
                append_permutations(&mut t, &PRIMES[EAGER_BASES..], &mut rng);
                t
            });
            &tail[PRIME_SUMS[i] - PRIME_SUMS[EAGER_BASES]..]
        };
        scrambled_radical_inverse_in(&PRIME_BASES[i], a, perm)
    }
}

/// One random digit permutation per prime base, concatenated (base i at `prime_sums()[i]`).
pub fn radical_inverse_permutations(rng: &mut Rng) -> Arc<Vec<u16>> {
    let mut perms = Vec::with_capacity(PRIME_SUMS[PRIME_TABLE_SIZE - 1] + PRIMES[PRIME_TABLE_SIZE - 1] as usize);
    append_permutations(&mut perms, &PRIMES, rng);
    Arc::new(perms)
}

/// The `n_digits`-digit index whose base-`base` radical inverse digits are those of `inverse` (reversed).
pub fn inverse_radical_inverse(base: u64, inverse: u64, n_digits: u32) -> u64 {
    let (mut inverse, mut index) = (inverse, 0u64);
    for _ in 0..n_digits {
        let digit = inverse % base;
        inverse /= base;
        index = index.wrapping_mul(base).wrapping_add(digit);
    }
    index
}

/// pbrt-v3's generator matrix of the van der Corput sequence (identity, bit-reversed).
pub const C_VAN_DER_CORPUT: [u32; 32] = {
    let mut c = [0u32; 32];
    let mut i = 0;
    while i < 32 {
        c[i] = 1 << (31 - i);
        i += 1;
    }
    c
};

/// The second dimension of the Sobol' (0,2)-sequence (Pascal's matrix mod 2).
pub const C_SOBOL_1: [u32; 32] = {
    let mut c = [0u32; 32];
    c[0] = 1 << 31;
    let mut i = 1;
    while i < 32 {
        c[i] = c[i - 1] ^ (c[i - 1] >> 1);
        i += 1;
    }
    c
};

/// `count = n_per_sample * n_pixel_samples` van der Corput points in Gray-code order, XOR-scrambled,
/// shuffled within each pixel sample's block and then block-wise (pbrt-v3's `VanDerCorput`).
pub fn van_der_corput(n_per_sample: usize, n_pixel_samples: usize, samples: &mut [f32], rng: &mut Rng) {
    let scramble = rng.uniform_u32();
    let total = (n_per_sample * n_pixel_samples).min(samples.len());
    let mut v = scramble;
    for (i, s) in samples.iter_mut().take(total).enumerate() {
        *s = bits_to_unit(v);
        v ^= C_VAN_DER_CORPUT[((i + 1).trailing_zeros() as usize).min(31)];
    }
    shuffle_blocks(&mut samples[..total], n_per_sample, n_pixel_samples, rng);
}

/// The 2D analogue with the first two Sobol' dimensions (pbrt-v3's `Sobol2D`).
pub fn sobol_2d(n_per_sample: usize, n_pixel_samples: usize, samples: &mut [Vec2], rng: &mut Rng) {
    let scramble = [rng.uniform_u32(), rng.uniform_u32()];
    let total = (n_per_sample * n_pixel_samples).min(samples.len());
    let mut v = scramble;
    for (i, s) in samples.iter_mut().take(total).enumerate() {
        *s = Vec2::new(bits_to_unit(v[0]), bits_to_unit(v[1]));
        let c = ((i + 1).trailing_zeros() as usize).min(31);
        v[0] ^= C_VAN_DER_CORPUT[c];
        v[1] ^= C_SOBOL_1[c];
    }
    shuffle_blocks(&mut samples[..total], n_per_sample, n_pixel_samples, rng);
}

fn shuffle_blocks<T>(samples: &mut [T], n_per_sample: usize, n_pixel_samples: usize, rng: &mut Rng) {
    if n_per_sample == 0 {
        return;
    }
    for block in samples.chunks_mut(n_per_sample).take(n_pixel_samples) {
        shuffle(block, 1, rng);
    }
    shuffle(samples, n_per_sample, rng);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primes_and_sums() {
        assert_eq!(&primes()[..6], &[2, 3, 5, 7, 11, 13]);
        assert_eq!(primes()[999], 7919);
        assert_eq!(prime_sums()[3], 10);
    }

    #[test]
    fn radical_inverse_values() {
        let cases: [(usize, u64, f64); 8] = [
            (0, 1, 0.5),
            (0, 2, 0.25),
            (0, 3, 0.75),
            (0, 6, 0.375),
            (1, 1, 1.0 / 3.0),
            (1, 5, 2.0 / 3.0 + 1.0 / 9.0),
            (2, 7, 2.0 / 5.0 + 1.0 / 25.0),
            (3, 50, 1.0 / 7.0 + 1.0 / 343.0),
        ];
        for (b, a, e) in cases {
            assert!((radical_inverse(b, a) as f64 - e).abs() < 1e-7, "base {b} a {a}");
        }
        assert!(radical_inverse(0, u64::MAX) < 1.0);
        // Base 3 five digits at a time: the digit-by-digit value within one f32 rounding, for
        // small values, chunk boundaries and the largest below 3⁴⁰ (and the digit loop past it).
        let by_digits = |mut a: u64| {
            let (mut r, mut f) = (0.0f64, 1.0f64);
            while a > 0 {
                f /= 3.0;
                r += (a % 3) as f64 * f;
                a /= 3;
            }
            r
        };
        let mut rng = crate::rng::Rng::new(3);
        let samples = (0..2000u64)
            .chain([242, 243, 244, 59_048, 59_049, POW3_40 - 1, POW3_40, u64::MAX])
            .chain((0..2000).map(|_| ((rng.uniform_u32() as u64) << 32 | rng.uniform_u32() as u64) % POW3_40));
        for a in samples {
            let (got, want) = (radical_inverse(1, a) as f64, by_digits(a));
            assert!((got - want).abs() <= 6e-8 * want.max(1e-30) + 1e-300 && got < 1.0, "{a}: {got} vs {want}");
        }
        // Identity permutation = plain radical inverse (the zero tail adds nothing).
        let id: Vec<u16> = (0..5).collect();
        assert_eq!(scrambled_radical_inverse(2, 123, &id), radical_inverse(2, 123));
        // A permutation sending 0 to 1 adds the tail Σ b^-k beyond the last digit.
        let p: Vec<u16> = vec![1, 0, 2];
        let e = 0.0 / 3.0 + 1.0 / 9.0 * 0.0 + (1.0 / 9.0) * (1.0 / 3.0) / (1.0 - 1.0 / 3.0);
        // 3 = 10_3: digits (low first) 0, 1 → permuted 1, 0.
        let e = e + 1.0 / 3.0;
        assert!((scrambled_radical_inverse(1, 3, &p) as f64 - e).abs() < 1e-7);
        assert_eq!(inverse_radical_inverse(2, 0b0011, 4), 0b1100);
        assert_eq!(inverse_radical_inverse(3, 5, 3), 21);
    }

    #[test]
    fn sobol_samples_are_the_matrix_product() {
        // Bit by bit over the little-endian file, as the matrices are stored.
        let by_bits = |index: u64, dim: u32| {
            let mut v = 0u32;
            for j in 0..SOBOL_MATRIX_SIZE {
                let k = 4 * (dim as usize * SOBOL_MATRIX_SIZE + j);
                if index >> j & 1 == 1 && dim < NUM_SOBOL_DIMENSIONS {
                    v ^= u32::from_le_bytes(SOBOL_BYTES[k..k + 4].try_into().unwrap());
                }
            }
            v
        };
        let mut rng = Rng::new(11);
        for dim in [0u32, 1, 2, 3, 100, 1022, 1023, 1024, 5000] {
            for index in [0u64, 1, 2, 3, 255, 1 << 51, (1 << 52) - 1, 1 << 52, u64::MAX] {
                assert_eq!(sobol_sample_bits(index, dim), by_bits(index, dim), "dim {dim} index {index}");
            }
            for _ in 0..500 {
                let index = (rng.uniform_u32() as u64) << 32 | rng.uniform_u32() as u64;
                let index = index >> (rng.uniform_u32() % 64);
                assert_eq!(sobol_sample_bits(index, dim), by_bits(index, dim), "dim {dim} index {index}");
            }
        }
    }

    #[test]
    fn sobol_first_dimensions() {
        for j in 0..32 {
            assert_eq!(sobol_column(0, j), C_VAN_DER_CORPUT[j]);
            assert_eq!(sobol_column(1, j), C_SOBOL_1[j], "column {j}");
        }
        assert_eq!(sobol_column(5000, 0), 0);
        // Direction numbers m_j are odd and below 2^(j+1): column j's lowest bit sits on the
        // diagonal and nothing is below it (upper-triangular matrices).
        for d in [2, 17, 500, 1023] {
            for j in 0..32 {
                assert_eq!(sobol_column(d, j).trailing_zeros() as usize, 31 - j, "dim {d} col {j}");
            }
        }
    }

    #[test]
    fn permutations_are_permutations() {
        let perms = radical_inverse_permutations(&mut Rng::default());
        for i in [0usize, 1, 10, 999] {
            let p = primes()[i] as usize;
            let mut s: Vec<u16> = perms[prime_sums()[i]..prime_sums()[i] + p].to_vec();
            s.sort();
            assert_eq!(s, (0..p as u16).collect::<Vec<_>>());
        }
    }

    #[test]
    fn fast_division_is_exact() {
        let mut rng = Rng::default();
        for &d in primes().iter().chain(&[2u32, 3, 128, 243, u32::MAX]) {
            let f = FastDiv::new(d);
            let check = |a: u64| assert_eq!(f.div_rem(a), (a / d as u64, a % d as u64), "{a} / {d}");
            for a in [0, 1, d as u64 - 1, d as u64, d as u64 + 1, u32::MAX as u64, u32::MAX as u64 + 1, u64::MAX] {
                check(a);
            }
            for _ in 0..200 {
                check(rng.uniform_u32() as u64);
                check((rng.uniform_u32() as u64 * d as u64).saturating_sub(1));
            }
        }
    }

    #[test]
    fn pair_tables_give_the_digit_by_digit_values() {
        // Every pair base, values with one digit, exactly two, many, at the table's ends and
        // beyond 32 bits: bit-equal to the digit loop over the full permutation table.
        assert!(PRIMES_HEAD.iter().zip(primes()).all(|(&a, &b)| a == b as usize));
        let perms = radical_inverse_permutations(&mut Rng::new(3));
        let lazy = ScrambledRadicalInverses::new(&mut Rng::new(3));
        let mut rng = Rng::new(4);
        for i in 0..PAIR_BASES + 2 {
            let p = primes()[i] as u64;
            let perm = &perms[prime_sums()[i]..prime_sums()[i] + p as usize];
            let mut values = vec![0, 1, p - 1, p, p + 1, p * p - 1, p * p, p * p + 1, u32::MAX as u64];
            values.extend([u32::MAX as u64 + 1, u64::MAX, 31_104 * 15 + 77]);
            values.extend((0..3000).map(|_| rng.uniform_u32() as u64 >> (rng.uniform_u32() % 32)));
            for a in values {
                let want = scrambled_radical_inverse(i, a, perm);
                assert_eq!(lazy.eval(i, a).to_bits(), want.to_bits(), "base {p} a {a}");
            }
        }
    }

    #[test]
    fn lazy_permutations_match_the_full_table() {
        let perms = radical_inverse_permutations(&mut Rng::new(7));
        let lazy = ScrambledRadicalInverses::new(&mut Rng::new(7));
        for i in [0usize, 1, 5, EAGER_BASES - 1, EAGER_BASES, 500, 999] {
            let p = &perms[prime_sums()[i]..prime_sums()[i] + primes()[i] as usize];
            for a in [0u64, 1, 12345, 987_654_321, 1 << 40] {
                assert_eq!(lazy.eval(i, a), scrambled_radical_inverse(i, a, p), "base {i} a {a}");
            }
        }
    }
}
