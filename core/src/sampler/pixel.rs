//! pbrt-v3's `PixelSampler` family (stratified, 02sequence, maxmindist): all of a pixel's
//! samples for the first `dimensions` 1D and 2D dimensions and for every requested array are
//! generated together, from a random stream derived from (pixel, seed); dimensions beyond
//! those fall back to independent uniform values from a stream derived from (pixel, index, seed).

use super::lowdiscrepancy::{bits_to_unit, multiply_generator, sobol_2d, van_der_corput};
use super::maxmin_matrices::C_MAX_MIN_DIST;
use super::Sampler;
use crate::rng::{pixel_stream, Rng};
use crate::sampling::{latin_hypercube_2d, shuffle, stratified_sample_1d, stratified_sample_2d};
use glam::{IVec2, Vec2};

const SALT_TABLES: u64 = 0x7461_626c_6573; // "tables"
const SALT_FALLBACK: u64 = 0x6661_6c6c; // "fall"

/// A pixel's pre-generated values: `samples_*[dim][sample]`, `arrays_*[i][sample * size + k]`.
#[derive(Clone, Debug, Default)]
pub struct PixelTables {
    pub samples_1d: Vec<Vec<f32>>,
    pub samples_2d: Vec<Vec<Vec2>>,
    pub arrays_1d: Vec<Vec<f32>>,
    pub arrays_2d: Vec<Vec<Vec2>>,
}

/// How a [`PixelSampler`] fills a pixel's tables (already sized) from `rng`.
pub trait PixelPattern: Clone + Send + Sync + 'static {
    const NAME: &'static str;
    fn round_count(&self, n: u32) -> u32 {
        n
    }
    fn fill(&self, spp: usize, sizes_1d: &[u32], sizes_2d: &[u32], t: &mut PixelTables, rng: &mut Rng);
}

#[derive(Clone, Debug)]
pub struct PixelSampler<P: PixelPattern> {
    pattern: P,
    spp: u32,
    n_dims: usize,
    seed: u64,
    sizes_1d: Vec<u32>,
    sizes_2d: Vec<u32>,
    tables: PixelTables,
    cached_pixel: Option<IVec2>,
    pixel: IVec2,
    index: u32,
    dim_1d: usize,
    dim_2d: usize,
    array_1d: usize,
    array_2d: usize,
    fallback: Rng,
}

impl<P: PixelPattern> PixelSampler<P> {
    pub fn new(pattern: P, spp: u32, n_sampled_dimensions: u32, seed: u64) -> Self {
        PixelSampler {
            pattern,
            spp: spp.max(1),
            n_dims: n_sampled_dimensions as usize,
            seed,
            sizes_1d: vec![],
            sizes_2d: vec![],
            tables: PixelTables::default(),
            cached_pixel: None,
            pixel: IVec2::ZERO,
            index: 0,
            dim_1d: 0,
            dim_2d: 0,
            array_1d: 0,
            array_2d: 0,
            fallback: Rng::default(),
        }
    }

    fn generate(&mut self, pixel: IVec2) {
        let spp = self.spp as usize;
        let t = &mut self.tables;
        t.samples_1d = vec![vec![0.0; spp]; self.n_dims];
        t.samples_2d = vec![vec![Vec2::ZERO; spp]; self.n_dims];
        t.arrays_1d = self.sizes_1d.iter().map(|&n| vec![0.0; n as usize * spp]).collect();
        t.arrays_2d = self.sizes_2d.iter().map(|&n| vec![Vec2::ZERO; n as usize * spp]).collect();
        let mut rng = Rng::new(pixel_stream(pixel, self.seed, SALT_TABLES));
        self.pattern.fill(spp, &self.sizes_1d, &self.sizes_2d, t, &mut rng);
        self.cached_pixel = Some(pixel);
    }

    fn in_tables(&self) -> bool {
        self.cached_pixel == Some(self.pixel) && self.index < self.spp
    }
}

impl<P: PixelPattern> Sampler for PixelSampler<P> {
    fn samples_per_pixel(&self) -> u32 {
        self.spp
    }
    fn round_count(&self, n: u32) -> u32 {
        self.pattern.round_count(n)
    }
    fn request_1d_array(&mut self, n: u32) {
        self.sizes_1d.push(n);
        self.cached_pixel = None;
    }
    fn request_2d_array(&mut self, n: u32) {
        self.sizes_2d.push(n);
        self.cached_pixel = None;
    }
    fn start_pixel_sample(&mut self, pixel: IVec2, index: u32) {
        if self.cached_pixel != Some(pixel) && index < self.spp {
            self.generate(pixel);
        }
        self.pixel = pixel;
        self.index = index;
        self.dim_1d = 0;
        self.dim_2d = 0;
        self.array_1d = 0;
        self.array_2d = 0;
        self.fallback = Rng::new(pixel_stream(pixel, self.seed, SALT_FALLBACK));
        self.fallback.advance((index as u64) << 32);
    }
    fn get_1d(&mut self) -> f32 {
        if self.in_tables() && self.dim_1d < self.tables.samples_1d.len() {
            self.dim_1d += 1;
            return self.tables.samples_1d[self.dim_1d - 1][self.index as usize];
        }
        self.fallback.uniform_f32()
    }
    fn get_2d(&mut self) -> Vec2 {
        if self.in_tables() && self.dim_2d < self.tables.samples_2d.len() {
            self.dim_2d += 1;
            return self.tables.samples_2d[self.dim_2d - 1][self.index as usize];
        }
        Vec2::new(self.fallback.uniform_f32(), self.fallback.uniform_f32())
    }
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]> {
        if !self.in_tables() || self.sizes_1d.get(self.array_1d) != Some(&n) {
            return None;
        }
        self.array_1d += 1;
        let start = self.index as usize * n as usize;
        self.tables.arrays_1d[self.array_1d - 1].get(start..start + n as usize)
    }
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]> {
        if !self.in_tables() || self.sizes_2d.get(self.array_2d) != Some(&n) {
            return None;
        }
        self.array_2d += 1;
        let start = self.index as usize * n as usize;
        self.tables.arrays_2d[self.array_2d - 1].get(start..start + n as usize)
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
    fn name(&self) -> &'static str {
        P::NAME
    }
}

/// pbrt-v3's `StratifiedSampler`: jittered `xsamples × ysamples` strata per 2D dimension,
/// `xsamples · ysamples` strata per 1D dimension, each independently shuffled across the
/// pixel's samples; 1D arrays stratified per pixel sample, 2D arrays by Latin hypercube.
#[derive(Clone, Debug)]
pub struct StratifiedPattern {
    pub x_samples: u32,
    pub y_samples: u32,
    pub jitter: bool,
}

impl PixelPattern for StratifiedPattern {
    const NAME: &'static str = "stratified";
    fn fill(&self, spp: usize, sizes_1d: &[u32], sizes_2d: &[u32], t: &mut PixelTables, rng: &mut Rng) {
        for s in &mut t.samples_1d {
            stratified_sample_1d(s, rng, self.jitter);
            shuffle(s, 1, rng);
        }
        for s in &mut t.samples_2d {
            stratified_sample_2d(s, self.x_samples as usize, self.y_samples as usize, rng, self.jitter);
            shuffle(s, 1, rng);
        }
        for (a, &n) in t.arrays_1d.iter_mut().zip(sizes_1d) {
            for block in a.chunks_mut(n.max(1) as usize).take(spp) {
                stratified_sample_1d(block, rng, self.jitter);
                shuffle(block, 1, rng);
            }
        }
        for (a, &n) in t.arrays_2d.iter_mut().zip(sizes_2d) {
            for block in a.chunks_mut(n.max(1) as usize).take(spp) {
                latin_hypercube_2d(block, rng);
            }
        }
    }
}

pub type StratifiedSampler = PixelSampler<StratifiedPattern>;

impl StratifiedSampler {
    pub fn stratified(x_samples: u32, y_samples: u32, jitter: bool, n_sampled_dimensions: u32, seed: u64) -> Self {
        let (x, y) = (x_samples.max(1), y_samples.max(1));
        PixelSampler::new(StratifiedPattern { x_samples: x, y_samples: y, jitter }, x * y, n_sampled_dimensions, seed)
    }
}

/// pbrt-v3's `ZeroTwoSequenceSampler` ("02sequence"/"lowdiscrepancy"): per pixel, randomly
/// XOR-scrambled van der Corput (1D) and Sobol' (0,2) (2D) points, shuffled across samples;
/// arrays take consecutive blocks of the same sequences, so each array is itself stratified.
#[derive(Clone, Debug)]
pub struct ZeroTwoSequencePattern;

fn fill_zero_two(skip_2d: usize, spp: usize, sizes_1d: &[u32], sizes_2d: &[u32], t: &mut PixelTables, rng: &mut Rng) {
    for s in &mut t.samples_1d {
        van_der_corput(1, spp, s, rng);
    }
    for s in t.samples_2d.iter_mut().skip(skip_2d) {
        sobol_2d(1, spp, s, rng);
    }
    for (a, &n) in t.arrays_1d.iter_mut().zip(sizes_1d) {
        van_der_corput(n as usize, spp, a, rng);
    }
    for (a, &n) in t.arrays_2d.iter_mut().zip(sizes_2d) {
        sobol_2d(n as usize, spp, a, rng);
    }
}

impl PixelPattern for ZeroTwoSequencePattern {
    const NAME: &'static str = "02sequence";
    fn round_count(&self, n: u32) -> u32 {
        n.checked_next_power_of_two().unwrap_or(n)
    }
    fn fill(&self, spp: usize, sizes_1d: &[u32], sizes_2d: &[u32], t: &mut PixelTables, rng: &mut Rng) {
        fill_zero_two(0, spp, sizes_1d, sizes_2d, t, rng);
    }
}

pub type ZeroTwoSequenceSampler = PixelSampler<ZeroTwoSequencePattern>;

impl ZeroTwoSequenceSampler {
    /// `spp` should be a power of two (the factory rounds it up).
    pub fn zero_two(spp: u32, n_sampled_dimensions: u32, seed: u64) -> Self {
        PixelSampler::new(ZeroTwoSequencePattern, spp, n_sampled_dimensions, seed)
    }
}

/// pbrt-v3's `MaxMinDistSampler`: the first 2D dimension (the film position) uses the points
/// (i / spp, C·i) of a (0, log2 spp, 2)-net with large minimum distance, shuffled; everything
/// else as [`ZeroTwoSequencePattern`]. See [`C_MAX_MIN_DIST`] for where the matrices come from.
#[derive(Clone, Debug)]
pub struct MaxMinDistPattern;

impl PixelPattern for MaxMinDistPattern {
    const NAME: &'static str = "maxmindist";
    fn round_count(&self, n: u32) -> u32 {
        n.checked_next_power_of_two().unwrap_or(n)
    }
    fn fill(&self, spp: usize, sizes_1d: &[u32], sizes_2d: &[u32], t: &mut PixelTables, rng: &mut Rng) {
        let log2 = (spp.max(1).ilog2() as usize).min(C_MAX_MIN_DIST.len() - 1);
        let c = &C_MAX_MIN_DIST[log2];
        if let Some(first) = t.samples_2d.first_mut() {
            let inv = 1.0 / spp as f32;
            for (i, s) in first.iter_mut().enumerate() {
                *s = Vec2::new(i as f32 * inv, bits_to_unit(multiply_generator(c, i as u32)));
            }
            shuffle(first, 1, rng);
        }
        fill_zero_two(1, spp, sizes_1d, sizes_2d, t, rng);
    }
}

pub type MaxMinDistSampler = PixelSampler<MaxMinDistPattern>;

impl MaxMinDistSampler {
    /// `spp` should be a power of two of at most 2^16 (the factory enforces both).
    pub fn max_min_dist(spp: u32, n_sampled_dimensions: u32, seed: u64) -> Self {
        PixelSampler::new(MaxMinDistPattern, spp, n_sampled_dimensions, seed)
    }
}
