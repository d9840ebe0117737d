//! Samplers with pbrt-v3's semantics, deterministic per (pixel, sample index, seed):
//! an image is bit-identical whatever the thread count, tiling or crop.

use glam::{IVec2, Vec2};
use penumbra_parser::{DiagSink, Entity, FileLoc};

mod global;
pub mod lowdiscrepancy;
mod maxmin_matrices;
mod pixel;
mod random;
#[cfg(test)]
mod tests;

pub use global::{GlobalSampler, HaltonPattern, HaltonSampler, SobolPattern, SobolSampler};
pub use maxmin_matrices::{search_maxmin_matrix, C_MAX_MIN_DIST};
pub use pixel::{
    MaxMinDistPattern, MaxMinDistSampler, PixelSampler, StratifiedPattern, StratifiedSampler, ZeroTwoSequencePattern,
    ZeroTwoSequenceSampler,
};
pub use random::RandomSampler;

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
    /// Consume the next 1D dimension without using it: afterwards the sampler is where
    /// `get_1d` would have left it (samplers that can skip the computation do).
    fn skip_1d(&mut self) {
        self.get_1d();
    }
    /// Consume the next 2D dimension without using it (see [`Sampler::skip_1d`]).
    fn skip_2d(&mut self) {
        self.get_2d();
    }
    /// The next requested 1D array, in request order; `None` if none (or not of size `n`) was requested.
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]>;
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]>;
    fn clone_box(&self) -> Box<dyn Sampler>;
    /// The pixel bounds `[min, max)` that samples will be requested for (pbrt-v3's film
    /// "sample bounds"). The halton and sobol samplers map pixels to their global sequence
    /// from its extent (and sobol from its origin), as pbrt-v3 does; the other samplers ignore
    /// it. Call it before `clone_box`, with the bounds of the *whole* image (not a crop), so
    /// that crops and shards reproduce the full render. Without a call, halton assumes an
    /// image of at least 128×128 pixels (its pbrt-v3 maximum) and sobol a 1024×1024 grid
    /// anchored at (0, 0) (pixels outside wrap around).
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2) {
        let _ = (min, max);
    }
    /// The sampler's name as written in scene files.
    fn name(&self) -> &'static str {
        "sampler"
    }
    /// Whether a pixel's sample `index` is the same whatever `samples_per_pixel` is, for any
    /// index (halton, sobol, random: a function of pixel, index and seed alone), so that
    /// renders of disjoint sample ranges ([`OffsetSampler`], `render --spp-offset`) take the
    /// samples of one render of their union. Pixel samplers (stratified, 02sequence,
    /// maxmindist) lay one pattern over all of a pixel's samples: `false`.
    fn samples_independent_of_count(&self) -> bool {
        false
    }
}

/// Samples `offset … offset + spp − 1` of `inner`'s sequences: sample `i` of a pixel is the
/// inner sampler's sample `offset + i` (for a progressive reference split into jobs). Only
/// meaningful for samplers whose [`Sampler::samples_independent_of_count`].
pub struct OffsetSampler {
    inner: Box<dyn Sampler>,
    offset: u32,
}

impl OffsetSampler {
    /// `None` when sample `offset + spp − 1` would overflow the sample index.
    pub fn new(inner: Box<dyn Sampler>, offset: u32) -> Option<OffsetSampler> {
        offset.checked_add(inner.samples_per_pixel())?;
        Some(OffsetSampler { inner, offset })
    }
}

impl Sampler for OffsetSampler {
    fn samples_per_pixel(&self) -> u32 {
        self.inner.samples_per_pixel()
    }
    fn round_count(&self, n: u32) -> u32 {
        self.inner.round_count(n)
    }
    fn request_1d_array(&mut self, n: u32) {
        self.inner.request_1d_array(n)
    }
    fn request_2d_array(&mut self, n: u32) {
        self.inner.request_2d_array(n)
    }
    fn start_pixel_sample(&mut self, pixel: IVec2, index: u32) {
        self.inner.start_pixel_sample(pixel, self.offset + index)
    }
    fn get_1d(&mut self) -> f32 {
        self.inner.get_1d()
    }
    fn get_2d(&mut self) -> Vec2 {
        self.inner.get_2d()
    }
    fn skip_1d(&mut self) {
        self.inner.skip_1d()
    }
    fn skip_2d(&mut self) {
        self.inner.skip_2d()
    }
    fn get_1d_array(&mut self, n: u32) -> Option<&[f32]> {
        self.inner.get_1d_array(n)
    }
    fn get_2d_array(&mut self, n: u32) -> Option<&[Vec2]> {
        self.inner.get_2d_array(n)
    }
    fn clone_box(&self) -> Box<dyn Sampler> {
        Box::new(OffsetSampler { inner: self.inner.clone_box(), offset: self.offset })
    }
    fn set_sample_bounds(&mut self, min: IVec2, max: IVec2) {
        self.inner.set_sample_bounds(min, max)
    }
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn samples_independent_of_count(&self) -> bool {
        self.inner.samples_independent_of_count()
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SamplerError {
    #[error("sampler \"{name}\" unknown (valid samplers: {valid})")]
    Unknown { name: String, loc: FileLoc, valid: String },
    #[error("sampler \"{sampler}\": invalid \"{param}\" {value}: {reason}")]
    InvalidParameter { sampler: String, param: String, value: i64, reason: String, loc: FileLoc },
}

impl SamplerError {
    /// Where the bad value was written: the scene, or `<command line>` for `--spp`.
    pub fn loc(&self) -> &FileLoc {
        match self {
            SamplerError::Unknown { loc, .. } | SamplerError::InvalidParameter { loc, .. } => loc,
        }
    }
}

/// The names `create_sampler` accepts (pbrt-v3's; "lowdiscrepancy" is an alias of "02sequence").
pub const SAMPLER_NAMES: [&str; 7] =
    ["02sequence", "halton", "lowdiscrepancy", "maxmindist", "random", "sobol", "stratified"];

/// The largest sample count accepted per pixel (and per array dimension).
pub const MAX_SAMPLES: i64 = 1 << 24;

/// Builds the sampler of a `Sampler` directive. `spp_override` (the command line's `--spp`)
/// replaces `pixelsamples` (for stratified, it is split into `xsamples × ysamples` as evenly as
/// its divisors allow). Warnings (e.g. counts rounded up to a power of two) go to `warnings`.
/// Unused parameters are not reported here: the caller does that.
pub fn create_sampler(
    entity: &Entity,
    spp_override: Option<u32>,
    seed: u64,
    warnings: &DiagSink,
) -> Result<Box<dyn Sampler>, SamplerError> {
    let kind = entity.kind.as_str();
    let name: &'static str = match kind {
        "02sequence" | "lowdiscrepancy" => "02sequence",
        "halton" => "halton",
        "maxmindist" => "maxmindist",
        "random" => "random",
        "sobol" => "sobol",
        "stratified" => "stratified",
        _ => {
            return Err(SamplerError::Unknown {
                name: kind.to_string(),
                loc: entity.loc.clone(),
                valid: SAMPLER_NAMES.join(", "),
            })
        }
    };
    let ps = &entity.params;
    let loc_of = |key: &str| ps.loc_of(key).cloned().unwrap_or_else(|| entity.loc.clone());
    let count = |key: &str, default: i64, max: i64| -> Result<u32, SamplerError> {
        let v = ps.get_one_int(key, default as i32) as i64;
        if v <= 0 || v > max {
            return Err(SamplerError::InvalidParameter {
                sampler: kind.to_string(),
                param: key.to_string(),
                value: v,
                reason: format!("must be between 1 and {max}"),
                loc: loc_of(key),
            });
        }
        Ok(v as u32)
    };
    let spp = |default: i64| -> Result<u32, SamplerError> {
        let from_scene = count("pixelsamples", default, MAX_SAMPLES)?;
        match spp_override {
            Some(n) if n == 0 || n as i64 > MAX_SAMPLES => Err(SamplerError::InvalidParameter {
                sampler: kind.to_string(),
                param: "spp".into(),
                value: n as i64,
                reason: format!("must be between 1 and {MAX_SAMPLES}"),
                loc: FileLoc::command_line(),
            }),
            Some(n) => Ok(n),
            None => Ok(from_scene),
        }
    };
    let pow2 = |n: u32, what: &str| -> u32 {
        if n.is_power_of_two() {
            n
        } else {
            let r = n.next_power_of_two();
            warnings.warn(
                Some(entity.loc.clone()),
                format!("{what}: pixel samples being rounded up to power of 2 (from {n} to {r})"),
            );
            r
        }
    };
    Ok(match name {
        "random" => {
            let spp = spp(4)?;
            let local_seed = ps.get_one_int("seed", 0);
            Box::new(RandomSampler::new(spp, seed ^ crate::rng::mix_bits(local_seed as i64 as u64)))
        }
        "stratified" => {
            let jitter = ps.get_one_bool("jitter", true);
            let mut xs = count("xsamples", 4, MAX_SAMPLES)?;
            let mut ys = count("ysamples", 4, MAX_SAMPLES)?;
            let dims = count("dimensions", 4, 1 << 16)?;
            if let Some(n) = spp_override {
                if n == 0 || n as i64 > MAX_SAMPLES {
                    return Err(SamplerError::InvalidParameter {
                        sampler: kind.to_string(),
                        param: "spp".into(),
                        value: n as i64,
                        reason: format!("must be between 1 and {MAX_SAMPLES}"),
                        loc: FileLoc::command_line(),
                    });
                }
                let mut x = (n as f64).sqrt() as u32;
                while x > 1 && n % x != 0 {
                    x -= 1;
                }
                xs = n / x.max(1);
                ys = x.max(1);
            }
            if xs as i64 * ys as i64 > MAX_SAMPLES {
                return Err(SamplerError::InvalidParameter {
                    sampler: kind.to_string(),
                    param: "xsamples".into(),
                    value: xs as i64 * ys as i64,
                    reason: format!("xsamples × ysamples must not exceed {MAX_SAMPLES}"),
                    loc: loc_of("xsamples"),
                });
            }
            Box::new(StratifiedSampler::stratified(xs, ys, jitter, dims, seed))
        }
        "halton" => {
            let spp = spp(16)?;
            let center = ps.get_one_bool("samplepixelcenter", false);
            Box::new(HaltonSampler::halton(spp, center, seed))
        }
        "sobol" => {
            let spp = pow2(spp(16)?, "sobol");
            Box::new(SobolSampler::sobol(spp, seed))
        }
        "02sequence" => {
            let spp = pow2(spp(16)?, "02sequence");
            let dims = count("dimensions", 4, 1 << 16)?;
            Box::new(ZeroTwoSequenceSampler::zero_two(spp, dims, seed))
        }
        _ => {
            let mut spp = spp(16)?;
            let max = 1u32 << (C_MAX_MIN_DIST.len() - 1);
            if spp > max {
                warnings.warn(
                    Some(entity.loc.clone()),
                    format!("maxmindist: no more than {max} samples per pixel are supported; using {max}"),
                );
                spp = max;
            }
            let spp = pow2(spp, "maxmindist");
            let dims = count("dimensions", 4, 1 << 16)?;
            Box::new(MaxMinDistSampler::max_min_dist(spp, dims, seed))
        }
    })
}
