//! Samplers with pbrt-v3's semantics, deterministic per (pixel, sample index, seed):
//! an image is bit-identical whatever the thread count, tiling or crop.

use glam::{IVec2, Vec2};

/// A sample generator. One instance is cloned per tile/thread (`clone_box`) after
/// the integrator has requested its arrays; then, for each pixel sample,
/// `start_pixel_sample` is called and the integrator draws dimensions in a
/// fixed order with `get_1d`/`get_2d` and its arrays with `get_*_array`.
pub trait Sampler: Send + Sync {
    /// Samples per pixel.
    fn samples_per_pixel(&self) -> u32;
    /// The array size this sampler prefers for a request of `n` (pbrt-v3's `RoundCount`).
    fn round_count(&self, n: u32) -> u32 {
        n
    }
    /// Ask for an array of `n` 1D samples per pixel sample (before rendering starts).
    fn request_1d_array(&mut self, n: u32);
    /// Ask for an array of `n` 2D samples per pixel sample (before rendering starts).
    fn request_2d_array(&mut self, n: u32);
    /// Begin sample `index` (< `samples_per_pixel`) of `pixel` (absolute raster coordinates).
    fn start_pixel_sample(&mut self, pixel: IVec2, index: u32);
    fn get_1d(&mut self) -> f32;
    fn get_2d(&mut self) -> Vec2;
    /// The next requested 1D array, in request order; `None` if none (or not of size `n`) was requested.
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]>;
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]>;
    fn clone_box(&self) -> Box<dyn Sampler>;
}

/// Stub factory (replaced by the full set of samplers): an independent hash-based sampler.
pub fn create_sampler(
    entity: &penumbra_parser::Entity,
    spp_override: Option<u32>,
    seed: u64,
    _warnings: &penumbra_parser::DiagSink,
) -> Result<Box<dyn Sampler>, String> {
    let spp = spp_override.unwrap_or(entity.params.get_one_int("pixelsamples", 16).max(1) as u32);
    Ok(Box::new(StubSampler {
        spp,
        seed,
        state: 0,
        a1: vec![],
        a2: vec![],
        buf1: vec![],
        buf2: vec![],
        next1: 0,
        next2: 0,
    }))
}

#[derive(Clone)]
struct StubSampler {
    spp: u32,
    seed: u64,
    state: u64,
    a1: Vec<u32>,
    a2: Vec<u32>,
    buf1: Vec<f32>,
    buf2: Vec<Vec2>,
    next1: usize,
    next2: usize,
}

impl StubSampler {
    fn next(&mut self) -> f32 {
        self.state = self.state.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^= z >> 31;
        ((z >> 40) as f32) * (1.0 / (1u64 << 24) as f32)
    }
}

impl Sampler for StubSampler {
    fn samples_per_pixel(&self) -> u32 {
        self.spp
    }
    fn request_1d_array(&mut self, n: u32) {
        self.a1.push(n);
    }
    fn request_2d_array(&mut self, n: u32) {
        self.a2.push(n);
    }
    fn start_pixel_sample(&mut self, pixel: IVec2, index: u32) {
        self.state = self.seed ^ ((pixel.x as u64) << 40) ^ ((pixel.y as u64) << 20) ^ index as u64;
        self.state = self.state.wrapping_mul(0x2545F4914F6CDD1D);
        self.next1 = 0;
        self.next2 = 0;
    }
    fn get_1d(&mut self) -> f32 {
        self.next()
    }
    fn get_2d(&mut self) -> Vec2 {
        Vec2::new(self.next(), self.next())
    }
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]> {
        if self.next1 >= self.a1.len() || self.a1[self.next1] != n {
            return None;
        }
        self.next1 += 1;
        self.buf1 = (0..n).map(|_| self.next()).collect();
        Some(&self.buf1)
    }
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]> {
        if self.next2 >= self.a2.len() || self.a2[self.next2] != n {
            return None;
        }
        self.next2 += 1;
        self.buf2 = (0..n).map(|_| Vec2::new(self.next(), self.next())).collect();
        Some(&self.buf2)
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
}
