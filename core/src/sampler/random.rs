//! pbrt-v3's `RandomSampler`: independent uniform values, here from a PCG32 stream derived
//! from (pixel, seed) and advanced by the sample index, so each pixel sample is reproducible.

use super::Sampler;
use crate::rng::{pixel_stream, Rng};
use glam::{IVec2, Vec2};

const SALT: u64 = 0x7261_6e64; // "rand"

#[derive(Clone, Debug)]
pub struct RandomSampler {
    spp: u32,
    seed: u64,
    rng: Rng,
    sizes_1d: Vec<u32>,
    sizes_2d: Vec<u32>,
    arrays_1d: Vec<Vec<f32>>,
    arrays_2d: Vec<Vec<Vec2>>,
    array_1d: usize,
    array_2d: usize,
}

impl RandomSampler {
    pub fn new(spp: u32, seed: u64) -> Self {
        RandomSampler {
            spp: spp.max(1),
            seed,
            rng: Rng::default(),
            sizes_1d: vec![],
            sizes_2d: vec![],
            arrays_1d: vec![],
            arrays_2d: vec![],
            array_1d: 0,
            array_2d: 0,
        }
    }
}

impl Sampler for RandomSampler {
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
        self.rng = Rng::new(pixel_stream(pixel, self.seed, SALT));
        self.rng.advance((index as u64) << 32);
        for a in &mut self.arrays_1d {
            for v in a.iter_mut() {
                *v = self.rng.uniform_f32();
            }
        }
        for a in &mut self.arrays_2d {
            for v in a.iter_mut() {
                *v = Vec2::new(self.rng.uniform_f32(), self.rng.uniform_f32());
            }
        }
        self.array_1d = 0;
        self.array_2d = 0;
    }
    fn get_1d(&mut self) -> f32 {
        self.rng.uniform_f32()
    }
    fn get_2d(&mut self) -> Vec2 {
        Vec2::new(self.rng.uniform_f32(), self.rng.uniform_f32())
    }
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]> {
        if self.sizes_1d.get(self.array_1d) != Some(&n) {
            return None;
        }
        self.array_1d += 1;
        Some(&self.arrays_1d[self.array_1d - 1])
    }
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]> {
        if self.sizes_2d.get(self.array_2d) != Some(&n) {
            return None;
        }
        self.array_2d += 1;
        Some(&self.arrays_2d[self.array_2d - 1])
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(self.clone())
    }
    fn name(&self) -> &'static str {
        "random"
    }
    fn samples_independent_of_count(&self) -> bool {
        true
    }
}
