//! pbrt-v3's `GlobalSampler` design (halton, sobol): a pixel's samples are the points of
//! one global low-discrepancy sequence that fall in that pixel. `index_for_sample` maps the
//! i-th sample of a pixel to its global index; dimension d of a sample is dimension d of that
//! global point. Dimensions 0–1 are the film position; dimensions 2–4 are kept for the
//! camera (time, lens), and arrays take the dimensions after them, element k of pixel sample s
//! being global sample `s * n + k` of the pixel (as pbrt-v3). pbrt-v3 fills every array in
//! `StartPixelSample`; here an array is filled when it is fetched (the same values), so the
//! arrays an integrator requests for deeper bounces cost nothing at the samples that stop early.

use super::lowdiscrepancy::{
    inverse_radical_inverse, radical_inverse, sobol_column, sobol_sample_bits, FastDiv, ScrambledRadicalInverses,
    NUM_SOBOL_DIMENSIONS, PRIME_TABLE_SIZE,
};
use super::Sampler;
use crate::rng::{hash_words, mix_bits, Rng, ONE_MINUS_EPSILON_F32};
use glam::{IVec2, Vec2};

/// Dimensions 0..ARRAY_START_DIM are reserved for the camera sample (pbrt-v3's `arrayStartDim`).
pub const ARRAY_START_DIM: u32 = 5;

/// A global sequence seen through pixels.
pub trait GlobalPattern: Clone + Send + Sync + 'static {
    const NAME: &'static str;
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2);
    /// The global index of the `sample`-th sample of `pixel`.
    fn index_for_sample(&self, pixel: IVec2, sample: u64) -> u64;
    /// The part of `index_for_sample` that depends only on the pixel, computed once per pixel.
    fn pixel_offset(&self, _pixel: IVec2) -> u64 {
        0
    }
    /// `index_for_sample(pixel, sample)`, given `offset = pixel_offset(pixel)`.
    fn index_with_offset(&self, pixel: IVec2, _offset: u64, sample: u64) -> u64 {
        self.index_for_sample(pixel, sample)
    }
    /// Dimension `dim` of global sample `index`, in `[0, 1)`; for dimensions 0 and 1, the
    /// offset within `pixel`.
    fn sample_dimension(&self, pixel: IVec2, index: u64, dim: u32) -> f32;
}

/// Independent uniform values for dimensions a sequence does not have.
fn hashed_uniform(seed: u64, index: u64, dim: u32) -> f32 {
    let h = hash_words(&[seed, index, dim as u64]);
    ((h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)).min(ONE_MINUS_EPSILON_F32)
}

#[derive(Clone, Debug)]
pub struct GlobalSampler<P: GlobalPattern> {
    pattern: P,
    spp: u32,
    sizes_1d: Vec<u32>,
    sizes_2d: Vec<u32>,
    arrays_1d: Vec<Vec<f32>>,
    arrays_2d: Vec<Vec<Vec2>>,
    pixel: IVec2,
    /// `pattern.pixel_offset(pixel)` for `offset_pixel`.
    offset_pixel: Option<IVec2>,
    offset: u64,
    sample: u32,
    index: u64,
    dimension: u32,
    array_end_dim: u32,
    array_1d: usize,
    array_2d: usize,
}

impl<P: GlobalPattern> GlobalSampler<P> {
    pub fn new(pattern: P, spp: u32) -> Self {
        GlobalSampler {
            pattern,
            spp: spp.max(1),
            sizes_1d: vec![],
            sizes_2d: vec![],
            arrays_1d: vec![],
            arrays_2d: vec![],
            pixel: IVec2::ZERO,
            offset_pixel: None,
            offset: 0,
            sample: 0,
            index: 0,
            dimension: 0,
            array_end_dim: ARRAY_START_DIM,
            array_1d: 0,
            array_2d: 0,
        }
    }

    pub fn pattern(&self) -> &P {
        &self.pattern
    }

    /// The next `width` (1 or 2) dimensions, skipping those reserved for arrays (as pbrt-v3,
    /// a 2D sample never straddles the start of the array dimensions).
    fn next_dimensions(&mut self, width: u32) -> u32 {
        if self.dimension + width > ARRAY_START_DIM && self.dimension < self.array_end_dim {
            self.dimension = self.array_end_dim;
        }
        self.dimension += width;
        self.dimension - width
    }
}

impl<P: GlobalPattern> Sampler for GlobalSampler<P> {
    fn samples_per_pixel(&self) -> u32 {
        self.spp
    }
    fn request_1d_array(&mut self, n: u32) {
        self.sizes_1d.push(n);
        self.arrays_1d.push(vec![0.0; n as usize]);
    }
    fn request_2d_array(&mut self, n: u32) {
        self.sizes_2d.push(n);
        self.arrays_2d.push(vec![Vec2::ZERO; n as usize]);
    }
    fn start_pixel_sample(&mut self, pixel: IVec2, index: u32) {
        self.pixel = pixel;
        self.sample = index;
        if self.offset_pixel != Some(pixel) {
            self.offset = self.pattern.pixel_offset(pixel);
            self.offset_pixel = Some(pixel);
        }
        let offset = self.offset;
        self.index = self.pattern.index_with_offset(pixel, offset, index as u64);
        self.dimension = 0;
        self.array_1d = 0;
        self.array_2d = 0;
        self.array_end_dim = ARRAY_START_DIM + self.sizes_1d.len() as u32 + 2 * self.sizes_2d.len() as u32;
    }
    fn get_1d(&mut self) -> f32 {
        let d = self.next_dimensions(1);
        self.pattern.sample_dimension(self.pixel, self.index, d)
    }
    fn get_2d(&mut self) -> Vec2 {
        let d = self.next_dimensions(2);
        Vec2::new(
            self.pattern.sample_dimension(self.pixel, self.index, d),
            self.pattern.sample_dimension(self.pixel, self.index, d + 1),
        )
    }
    fn skip_1d(&mut self) {
        self.next_dimensions(1);
    }
    fn skip_2d(&mut self) {
        self.next_dimensions(2);
    }
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]> {
        let i = self.array_1d;
        if self.sizes_1d.get(i) != Some(&n) {
            return None;
        }
        self.array_1d += 1;
        let dim = ARRAY_START_DIM + i as u32;
        let (pattern, pixel, base) = (&self.pattern, self.pixel, self.sample as u64 * n as u64);
        for (k, v) in self.arrays_1d[i].iter_mut().enumerate() {
            let gi = pattern.index_with_offset(pixel, self.offset, base + k as u64);
            *v = pattern.sample_dimension(pixel, gi, dim);
        }
        Some(&self.arrays_1d[i])
    }
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]> {
        let i = self.array_2d;
        if self.sizes_2d.get(i) != Some(&n) {
            return None;
        }
        self.array_2d += 1;
        let dim = ARRAY_START_DIM + self.sizes_1d.len() as u32 + 2 * i as u32;
        let (pattern, pixel, base) = (&self.pattern, self.pixel, self.sample as u64 * n as u64);
        for (k, v) in self.arrays_2d[i].iter_mut().enumerate() {
            let gi = pattern.index_with_offset(pixel, self.offset, base + k as u64);
            *v = Vec2::new(pattern.sample_dimension(pixel, gi, dim), pattern.sample_dimension(pixel, gi, dim + 1));
        }
        Some(&self.arrays_2d[i])
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2) {
        self.pattern.set_sample_bounds(min, max);
        self.offset_pixel = None;
    }
    fn name(&self) -> &'static str {
        P::NAME
    }
    fn samples_independent_of_count(&self) -> bool {
        true
    }
}

/// pbrt-v3's largest Halton pixel tile: pixels repeat the sequence every 128 pixels.
const HALTON_MAX_RESOLUTION: i32 = 128;

/// pbrt-v3's `HaltonSampler`: the base-2/base-3 digits of the first two dimensions select
/// the pixel (within a 128×128 tile), found through the Chinese remainder theorem; dimensions
/// ≥ 2 use randomly digit-permuted radical inverses. With `seed` 0 the permutations are
/// pbrt-v3's (its default-seeded RNG); other seeds draw other permutations. Dimensions beyond
/// the 1000th prime base get independent hashed uniform values (pbrt-v3 aborts there).
#[derive(Clone, Debug)]
pub struct HaltonPattern {
    radical_inverses: ScrambledRadicalInverses,
    base_scales: [u64; 2],
    /// Division by `base_scales[1]` (every camera sample's second dimension).
    scale_div: FastDiv,
    base_exponents: [u32; 2],
    sample_stride: u64,
    mult_inverse: [u64; 2],
    sample_at_pixel_center: bool,
    seed: u64,
}

fn multiplicative_inverse(a: i64, n: i64) -> u64 {
    // Extended Euclid: x with a x ≡ 1 (mod n).
    let (mut old_r, mut r) = (a, n);
    let (mut old_s, mut s) = (1i64, 0i64);
    while r != 0 {
        let q = old_r / r;
        (old_r, r) = (r, old_r - q * r);
        (old_s, s) = (s, old_s - q * s);
    }
    old_s.rem_euclid(n.max(1)) as u64
}

impl HaltonPattern {
    pub fn new(sample_at_pixel_center: bool, seed: u64) -> Self {
        let mut rng = if seed == 0 { Rng::default() } else { Rng::new(mix_bits(seed)) };
        let mut p = HaltonPattern {
            radical_inverses: ScrambledRadicalInverses::new(&mut rng),
            base_scales: [1, 1],
            scale_div: FastDiv::new(1),
            base_exponents: [0, 0],
            sample_stride: 1,
            mult_inverse: [0, 0],
            sample_at_pixel_center,
            seed,
        };
        p.set_sample_bounds(IVec2::ZERO, IVec2::splat(HALTON_MAX_RESOLUTION));
        p
    }

    pub fn base_scales(&self) -> [u64; 2] {
        self.base_scales
    }
}

impl GlobalPattern for HaltonPattern {
    const NAME: &'static str = "halton";
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2) {
        let res = (max.as_i64vec2() - min.as_i64vec2()).max(glam::I64Vec2::ZERO);
        for i in 0..2 {
            let base = if i == 0 { 2 } else { 3 };
            let (mut scale, mut exp) = (1u64, 0u32);
            while scale < res[i].min(HALTON_MAX_RESOLUTION as i64) as u64 {
                scale *= base;
                exp += 1;
            }
            self.base_scales[i] = scale;
            self.base_exponents[i] = exp;
        }
        self.sample_stride = self.base_scales[0] * self.base_scales[1];
        self.scale_div = FastDiv::new(self.base_scales[1] as u32);
        self.mult_inverse = [
            multiplicative_inverse(self.base_scales[1] as i64, self.base_scales[0] as i64),
            multiplicative_inverse(self.base_scales[0] as i64, self.base_scales[1] as i64),
        ];
    }
    fn index_for_sample(&self, pixel: IVec2, sample: u64) -> u64 {
        self.index_with_offset(pixel, self.pixel_offset(pixel), sample)
    }
    fn index_with_offset(&self, _pixel: IVec2, offset: u64, sample: u64) -> u64 {
        offset.wrapping_add(sample.wrapping_mul(self.sample_stride))
    }
    fn pixel_offset(&self, pixel: IVec2) -> u64 {
        let mut offset = 0u64;
        if self.sample_stride > 1 {
            let pm = [pixel.x.rem_euclid(HALTON_MAX_RESOLUTION), pixel.y.rem_euclid(HALTON_MAX_RESOLUTION)];
            for (i, (&p, base)) in pm.iter().zip([2u64, 3]).enumerate() {
                let dim_offset = inverse_radical_inverse(base, p as u64, self.base_exponents[i]);
                offset += dim_offset * (self.sample_stride / self.base_scales[i]) * self.mult_inverse[i];
            }
            offset %= self.sample_stride;
        }
        offset
    }
    fn sample_dimension(&self, _pixel: IVec2, index: u64, dim: u32) -> f32 {
        if self.sample_at_pixel_center && dim < 2 {
            return 0.5;
        }
        match dim {
            0 => radical_inverse(0, index >> self.base_exponents[0]),
            1 => radical_inverse(1, if self.base_scales[1] > 1 { self.scale_div.div_rem(index).0 } else { index }),
            d if (d as usize) < PRIME_TABLE_SIZE => self.radical_inverses.eval(d as usize, index),
            d => hashed_uniform(self.seed ^ 0x4841_4c54, index, d),
        }
    }
}

pub type HaltonSampler = GlobalSampler<HaltonPattern>;

impl HaltonSampler {
    pub fn halton(spp: u32, sample_at_pixel_center: bool, seed: u64) -> Self {
        GlobalSampler::new(HaltonPattern::new(sample_at_pixel_center, seed), spp)
    }
}

/// pbrt-v3's `SobolSampler`: the image's sample bounds are covered by a 2^m × 2^m grid
/// (2^m ≥ the larger extent); the first two Sobol' dimensions, scaled by 2^m, pick the pixel,
/// and a pixel's i-th sample is the i-th global index whose point falls in it. Unscrambled
/// with `seed` 0 (as pbrt-v3); other seeds XOR-scramble dimensions ≥ 2 with per-dimension
/// hashes of the seed. Dimensions ≥ 1024 get independent hashed uniform values.
#[derive(Clone, Debug)]
pub struct SobolPattern {
    log2_resolution: u32,
    bounds_min: IVec2,
    /// Row `j` of the inverse of the 2m×2m system (low index bit j from the target pixel bits).
    inverse_rows: Vec<u64>,
    /// For index bit 2m + c: its contribution to the 2m pixel bits.
    high_columns: Vec<u64>,
    seed: u64,
}

impl SobolPattern {
    pub fn new(seed: u64) -> Self {
        let mut p = SobolPattern {
            log2_resolution: 0,
            bounds_min: IVec2::ZERO,
            inverse_rows: vec![],
            high_columns: vec![],
            seed,
        };
        p.set_sample_bounds(IVec2::ZERO, IVec2::splat(1024));
        p
    }

    pub fn log2_resolution(&self) -> u32 {
        self.log2_resolution
    }

    /// The pixel bits (x in the high m bits, y in the low m bits) selected by index bit `j`.
    fn pixel_bits_of_column(&self, j: usize) -> u64 {
        let m = self.log2_resolution;
        if m == 0 {
            return 0;
        }
        let top = |v: u32| (v >> (32 - m)) as u64;
        (top(sobol_column(0, j)) << m) | top(sobol_column(1, j))
    }

    fn build_tables(&mut self) {
        let m = self.log2_resolution as usize;
        let n = 2 * m;
        // rows[r] has bit j set when index bit j flips pixel bit r; augmented with the identity.
        let mut rows: Vec<(u64, u64)> = (0..n)
            .map(|r| {
                let mut bits = 0u64;
                for j in 0..n {
                    if self.pixel_bits_of_column(j) >> r & 1 == 1 {
                        bits |= 1 << j;
                    }
                }
                (bits, 1u64 << r)
            })
            .collect();
        // Gauss–Jordan over GF(2). The first two Sobol' dimensions form a (0,2)-sequence, so
        // the system is always invertible.
        for col in 0..n {
            let Some(p) = (col..n).find(|&r| rows[r].0 >> col & 1 == 1) else { continue };
            rows.swap(col, p);
            let pivot = rows[col];
            for (r, row) in rows.iter_mut().enumerate() {
                if r != col && row.0 >> col & 1 == 1 {
                    row.0 ^= pivot.0;
                    row.1 ^= pivot.1;
                }
            }
        }
        self.inverse_rows = rows.iter().map(|r| r.1).collect();
        self.high_columns = (n..64).map(|j| self.pixel_bits_of_column(j)).collect();
    }
}

impl GlobalPattern for SobolPattern {
    const NAME: &'static str = "sobol";
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2) {
        let extent = (max.as_i64vec2() - min.as_i64vec2()).max_element().clamp(1, 1 << 20) as u32;
        // 2^m ≥ the extent, with 2m ≤ 40 so that index bits remain for each pixel's samples.
        self.log2_resolution = extent.next_power_of_two().ilog2();
        self.bounds_min = min;
        self.build_tables();
    }
    fn index_for_sample(&self, pixel: IVec2, sample: u64) -> u64 {
        let m = self.log2_resolution;
        if m == 0 {
            return sample;
        }
        let mask = (1i64 << m) - 1;
        let p = pixel.as_i64vec2() - self.bounds_min.as_i64vec2();
        let target = (((p.x & mask) as u64) << m) | (p.y & mask) as u64;
        let mut delta = 0u64;
        let mut s = sample;
        let mut c = 0;
        while s != 0 && c < self.high_columns.len() {
            if s & 1 == 1 {
                delta ^= self.high_columns[c];
            }
            s >>= 1;
            c += 1;
        }
        let b = target ^ delta;
        let mut low = 0u64;
        for (j, row) in self.inverse_rows.iter().enumerate() {
            low |= (((row & b).count_ones() & 1) as u64) << j;
        }
        sample.checked_shl(2 * m).unwrap_or(0) ^ low
    }
    fn sample_dimension(&self, _pixel: IVec2, index: u64, dim: u32) -> f32 {
        if dim >= NUM_SOBOL_DIMENSIONS {
            return hashed_uniform(self.seed ^ 0x53_4f42_4f4c, index, dim);
        }
        let v = sobol_sample_bits(index, dim);
        if dim < 2 {
            // The bits below the pixel-selecting ones are the offset within the pixel.
            let frac = ((v as u64) << self.log2_resolution) as u32;
            return (frac as f32 * (1.0 / 4_294_967_296.0)).min(ONE_MINUS_EPSILON_F32);
        }
        let scramble = if self.seed == 0 { 0 } else { mix_bits(self.seed ^ mix_bits(dim as u64)) as u32 };
        ((v ^ scramble) as f32 * (1.0 / 4_294_967_296.0)).min(ONE_MINUS_EPSILON_F32)
    }
}

pub type SobolSampler = GlobalSampler<SobolPattern>;

impl SobolSampler {
    /// `spp` should be a power of two (the factory rounds it up).
    pub fn sobol(spp: u32, seed: u64) -> Self {
        GlobalSampler::new(SobolPattern::new(seed), spp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pattern whose value is its dimension, to observe which dimensions are drawn.
    #[derive(Clone)]
    struct DimPattern;
    impl GlobalPattern for DimPattern {
        const NAME: &'static str = "dims";
        fn set_sample_bounds(&mut self, _: IVec2, _: IVec2) {}
        fn index_for_sample(&self, _: IVec2, sample: u64) -> u64 {
            sample
        }
        fn sample_dimension(&self, _: IVec2, _: u64, dim: u32) -> f32 {
            dim as f32
        }
    }

    #[test]
    fn dimensions_skip_the_array_block() {
        let mut s = GlobalSampler::new(DimPattern, 4);
        s.request_1d_array(3);
        s.request_2d_array(2);
        s.start_pixel_sample(IVec2::ZERO, 1);
        assert_eq!(s.get_1d_array(3).unwrap(), &[5.0; 3]);
        assert_eq!(s.get_2d_array(2).unwrap(), &[Vec2::new(6.0, 7.0); 2]);
        // Camera: film (0,1), time 2, lens (3,4); then past the arrays (5..8).
        assert_eq!(s.get_2d(), Vec2::new(0.0, 1.0));
        assert_eq!(s.get_1d(), 2.0);
        assert_eq!(s.get_2d(), Vec2::new(3.0, 4.0));
        assert_eq!(s.get_1d(), 8.0);
        s.start_pixel_sample(IVec2::ZERO, 2);
        s.get_2d();
        s.get_2d();
        // A 2D sample starting at dimension 4 would straddle the array block: it skips it.
        assert_eq!(s.get_2d(), Vec2::new(8.0, 9.0));
    }

    #[test]
    fn arrays_are_the_global_points_of_their_dimensions() {
        // Arrays are filled when fetched: element k of pixel sample s is global sample
        // s * n + k of the pixel, in the array's own dimensions (as pbrt-v3 fills them eagerly).
        let mut s = HaltonSampler::halton(8, false, 0);
        s.request_1d_array(3);
        s.request_2d_array(2);
        s.request_2d_array(4);
        let h = s.pattern().clone();
        let pixel = IVec2::new(13, 7);
        for sample in [0u32, 5] {
            s.start_pixel_sample(pixel, sample);
            let a1 = s.get_1d_array(3).unwrap().to_vec();
            let a2 = s.get_2d_array(2).unwrap().to_vec();
            let a3 = s.get_2d_array(4).unwrap().to_vec();
            let at = |n: u64, k: usize, dim: u32| {
                h.sample_dimension(pixel, h.index_for_sample(pixel, sample as u64 * n + k as u64), dim)
            };
            for (k, v) in a1.iter().enumerate() {
                assert_eq!(v.to_bits(), at(3, k, 5).to_bits());
            }
            for (k, v) in a2.iter().enumerate() {
                assert_eq!([v.x, v.y].map(f32::to_bits), [at(2, k, 6), at(2, k, 7)].map(f32::to_bits));
            }
            for (k, v) in a3.iter().enumerate() {
                assert_eq!([v.x, v.y].map(f32::to_bits), [at(4, k, 8), at(4, k, 9)].map(f32::to_bits));
            }
        }
    }

    #[test]
    fn halton_pixel_mapping() {
        let h = HaltonPattern::new(false, 0);
        assert_eq!(h.base_scales(), [128, 243]);
        for pixel in [IVec2::new(0, 0), IVec2::new(5, 77), IVec2::new(127, 100), IVec2::new(-3, 300)] {
            for s in 0..4u64 {
                let gi = h.index_for_sample(pixel, s);
                // The leading digits of the radical inverses of the global index (its low digits,
                // reversed) pick the pixel (mod 128).
                assert_eq!(inverse_radical_inverse(2, gi, 7) as i32, pixel.x.rem_euclid(128), "{pixel} {s}");
                assert_eq!(inverse_radical_inverse(3, gi, 5) as i32, pixel.y.rem_euclid(128), "{pixel} {s}");
                assert_eq!(gi / (128 * 243), s);
            }
        }
        let mut small = HaltonPattern::new(false, 0);
        small.set_sample_bounds(IVec2::new(-2, -2), IVec2::new(30, 8));
        assert_eq!(small.base_scales(), [32, 27]);
    }

    #[test]
    fn extreme_bounds_do_not_panic() {
        for (min, max) in [(IVec2::MIN, IVec2::MAX), (IVec2::MAX, IVec2::MIN), (IVec2::ZERO, IVec2::ZERO)] {
            let mut s = SobolPattern::new(0);
            s.set_sample_bounds(min, max);
            let mut h = HaltonPattern::new(false, 0);
            h.set_sample_bounds(min, max);
            for p in [IVec2::MIN, IVec2::MAX, IVec2::ZERO] {
                let i = s.index_for_sample(p, 3);
                assert!((0.0..1.0).contains(&s.sample_dimension(p, i, 0)));
                let i = h.index_for_sample(p, 3);
                assert!((0.0..1.0).contains(&h.sample_dimension(p, i, 1)));
            }
        }
    }

    #[test]
    fn sobol_pixel_mapping() {
        for (min, max) in [(IVec2::ZERO, IVec2::new(40, 30)), (IVec2::new(-3, -3), IVec2::new(700, 300))] {
            let mut p = SobolPattern::new(0);
            p.set_sample_bounds(min, max);
            let res = 1u64 << p.log2_resolution();
            assert!(res >= (max - min).max_element() as u64);
            for pixel in [min, IVec2::new(7, 19), max - IVec2::ONE] {
                let mut seen = std::collections::HashSet::new();
                for s in 0..64u64 {
                    let gi = p.index_for_sample(pixel, s);
                    assert!(seen.insert(gi));
                    assert_eq!(gi >> (2 * p.log2_resolution()), s);
                    let x = (sobol_sample_bits(gi, 0) as u64 * res) >> 32;
                    let y = (sobol_sample_bits(gi, 1) as u64 * res) >> 32;
                    assert_eq!((x as i32, y as i32), ((pixel - min).x, (pixel - min).y), "{pixel} {s}");
                }
            }
        }
    }
}
