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
