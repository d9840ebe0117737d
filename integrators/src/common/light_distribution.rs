//! pbrt-v3's light-sampling distributions (`lightdistrib.cpp`): which light a path vertex
//! samples. `uniform`: every light alike; `power`: in proportion to its emitted power;
//! `spatial`: per voxel of a grid over the scene bounds (64 voxels along the widest axis), in
//! proportion to an estimate of each light's unoccluded contribution inside the voxel (128
//! Halton points in the voxel, one light sample each, luminance / pdf, every light at least
//! 1/1000 of the mean). Voxels are computed when first looked up, as in pbrt-v3; each voxel's
//! distribution depends on its index alone, so images do not depend on which thread or tile got
//! there first.

use penumbra_core::geometry::Bounds3;
use penumbra_core::light::LightContext;
use penumbra_core::sampler::lowdiscrepancy::radical_inverse;
use penumbra_core::sampling::Distribution1D;
use penumbra_core::scene::Scene;
use penumbra_core::spectrum::luminance;
use penumbra_core::{Vec2, Vec3};
use std::sync::OnceLock;

/// pbrt-v3's `lightsamplestrategy`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSampleStrategy {
    Uniform,
    Power,
    Spatial,
}

impl LightSampleStrategy {
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "uniform" => Some(Self::Uniform),
            "power" => Some(Self::Power),
            "spatial" => Some(Self::Spatial),
            _ => None,
        }
    }
}

/// A built light distribution ([`LightDistribution::lookup`] gives the one for a point).
pub enum LightDistribution {
    /// One distribution everywhere (uniform or by power).
    Global(Distribution1D),
    Spatial(SpatialLightDistribution),
}

impl LightDistribution {
    /// As pbrt-v3's `CreateLightSampleDistribution`: uniform when asked or when there is one light.
    pub fn new(strategy: LightSampleStrategy, scene: &Scene) -> Self {
        let lights = scene.light_list();
        match strategy {
            _ if lights.len() <= 1 => Self::Global(Distribution1D::new(&vec![1.0; lights.len()])),
            LightSampleStrategy::Uniform => Self::Global(Distribution1D::new(&vec![1.0; lights.len()])),
            LightSampleStrategy::Power => {
                let power: Vec<f32> = lights.iter().map(|l| luminance(l.power())).collect();
                Self::Global(Distribution1D::new(&power))
            }
            LightSampleStrategy::Spatial => Self::Spatial(SpatialLightDistribution::new(scene, 64)),
        }
    }

    /// The distribution over `scene.light_list()` to sample at `p`.
    pub fn lookup(&self, p: Vec3, scene: &Scene) -> &Distribution1D {
        match self {
            Self::Global(d) => d,
            Self::Spatial(s) => s.lookup(p, scene),
        }
    }
}

/// pbrt-v3's `SpatialLightDistribution`, with a slot per voxel instead of its hash table.
pub struct SpatialLightDistribution {
    bounds: Bounds3,
    n_voxels: [usize; 3],
    voxels: Vec<OnceLock<Box<Distribution1D>>>,
}

/// Halton points per voxel (pbrt-v3's `nSamples`).
const VOXEL_SAMPLES: u64 = 128;

impl SpatialLightDistribution {
    pub fn new(scene: &Scene, max_voxels: usize) -> Self {
        let bounds = scene.bounds;
        let diag = bounds.diagonal();
        let bmax = diag.max_element();
        let n_voxels = [diag.x, diag.y, diag.z].map(|d| {
            let n = (d / bmax * max_voxels as f32).round();
            if n.is_finite() {
                (n as usize).clamp(1, max_voxels)
            } else {
                1
            }
        });
        let count = n_voxels.iter().product();
        SpatialLightDistribution { bounds, n_voxels, voxels: (0..count).map(|_| OnceLock::new()).collect() }
    }

    fn voxel_of(&self, p: Vec3) -> [usize; 3] {
        let (lo, hi) = (self.bounds.min, self.bounds.max);
        let mut v = [0; 3];
        for i in 0..3 {
            let extent = hi[i] - lo[i];
            let offset = if extent > 0.0 { (p[i] - lo[i]) / extent } else { p[i] - lo[i] };
            // The clamp keeps points a rounding error outside the bounds in the edge voxel.
            let n = self.n_voxels[i];
            v[i] = if offset.is_finite() { ((offset * n as f32).max(0.0) as usize).min(n - 1) } else { 0 };
        }
        v
    }

    pub fn lookup(&self, p: Vec3, scene: &Scene) -> &Distribution1D {
        let v = self.voxel_of(p);
        let index = (v[2] * self.n_voxels[1] + v[1]) * self.n_voxels[0] + v[0];
        self.voxels[index].get_or_init(|| Box::new(self.compute(v, scene)))
    }

    /// pbrt-v3's `ComputeDistribution` for voxel `v`.
    fn compute(&self, v: [usize; 3], scene: &Scene) -> Distribution1D {
        let lerp = |t: Vec3| (Vec3::ONE - t) * self.bounds.min + t * self.bounds.max;
        let n = Vec3::new(self.n_voxels[0] as f32, self.n_voxels[1] as f32, self.n_voxels[2] as f32);
        let corner = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        let (p0, p1) = (lerp(corner / n), lerp((corner + Vec3::ONE) / n));
        let lights = scene.light_list();
        let mut contrib = vec![0.0f32; lights.len()];
        for i in 0..VOXEL_SAMPLES {
            let t = Vec3::new(radical_inverse(0, i), radical_inverse(1, i), radical_inverse(2, i));
            let p = (Vec3::ONE - t) * p0 + t * p1;
            let ctx = LightContext { p, p_error: Vec3::ZERO, n: Vec3::ZERO };
            let u = Vec2::new(radical_inverse(3, i), radical_inverse(4, i));
            for (c, light) in contrib.iter_mut().zip(lights) {
                if let Some(ls) = light.sample_li(&ctx, u, &scene.meshes) {
                    if ls.pdf > 0.0 {
                        *c += luminance(ls.li) / ls.pdf;
                    }
                }
            }
        }
        // No light may get probability 0: it may light the voxel where no sample saw it.
        let avg = contrib.iter().sum::<f32>() / (VOXEL_SAMPLES as f32 * contrib.len() as f32);
        let min = if avg > 0.0 { 0.001 * avg } else { 1.0 };
        for c in &mut contrib {
            *c = c.max(min);
        }
        Distribution1D::new(&contrib)
    }
}
