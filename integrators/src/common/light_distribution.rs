//! pbrt-v3's light-sampling distributions (`lightdistrib.cpp`): which light a path vertex
//! samples. `uniform`: every light alike; `power`: in proportion to its emitted power;
//! `spatial`: per voxel of a grid over the scene bounds (64 voxels along the widest axis), in
//! proportion to an estimate of each light's unoccluded contribution inside the voxel (128
//! Halton points in the voxel, one light sample each, luminance / pdf, every light at least
//! 1/1000 of the mean). Voxels are computed when first looked up, as in pbrt-v3; each voxel's
//! distribution depends on its index alone, so images do not depend on which thread or tile got
//! there first.

use penumbra_core::geometry::Bounds3;
use penumbra_core::light::{AreaLightPoint, Light, LightContext};
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
    /// The voxel's Halton points: the same in every voxel, so computed once.
    points: Vec<VoxelPoint>,
    /// The point each area light's sample chooses for each of [`Self::points`] (it depends on
    /// the sample alone), light by light; `None` when there are too many lights to keep them.
    area_points: OnceLock<Option<Vec<Prepared>>>,
}

/// One of a voxel's Halton points: position within the voxel (`t`) and light sample (`u`).
struct VoxelPoint {
    t: Vec3,
    u: Vec2,
}

/// What a light's sample at one [`VoxelPoint`] needs beyond the receiving point.
#[derive(Clone, Copy)]
enum Prepared {
    /// An area light's point (`None`: the sample chose none).
    Area(Option<AreaLightPoint>),
    /// Any other light: sampled at each receiving point.
    Other,
}

/// The most lights × points whose area-light samples are kept (about 40 bytes each).
const MAX_PREPARED: usize = 1 << 18;

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
        let points = (0..VOXEL_SAMPLES)
            .map(|i| VoxelPoint {
                t: Vec3::new(radical_inverse(0, i), radical_inverse(1, i), radical_inverse(2, i)),
                u: Vec2::new(radical_inverse(3, i), radical_inverse(4, i)),
            })
            .collect();
        SpatialLightDistribution {
            bounds,
            n_voxels,
            voxels: (0..count).map(|_| OnceLock::new()).collect(),
            points,
            area_points: OnceLock::new(),
        }
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

    /// The area lights' points for [`Self::points`], light-major (see `area_points`).
    fn prepare(&self, lights: &[Light]) -> Option<Vec<Prepared>> {
        if lights.len().saturating_mul(self.points.len()) > MAX_PREPARED {
            return None;
        }
        let one = |light: &Light, pt: &VoxelPoint| match light {
            Light::Area(a) if a.samples_by_area() => Prepared::Area(a.sample_point(pt.u)),
            _ => Prepared::Other,
        };
        Some(lights.iter().flat_map(|l| self.points.iter().map(move |pt| one(l, pt))).collect())
    }

    /// pbrt-v3's `ComputeDistribution` for voxel `v`.
    fn compute(&self, v: [usize; 3], scene: &Scene) -> Distribution1D {
        let lerp = |t: Vec3| (Vec3::ONE - t) * self.bounds.min + t * self.bounds.max;
        let n = Vec3::new(self.n_voxels[0] as f32, self.n_voxels[1] as f32, self.n_voxels[2] as f32);
        let corner = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        let (p0, p1) = (lerp(corner / n), lerp((corner + Vec3::ONE) / n));
        let lights = scene.light_list();
        let prepared = self.area_points.get_or_init(|| self.prepare(lights)).as_deref();
        let mut contrib = vec![0.0f32; lights.len()];
        let at: Vec<Vec3> = self.points.iter().map(|pt| (Vec3::ONE - pt.t) * p0 + pt.t * p1).collect();
        // Light by light, each light's points in order (so each sum adds in the order it
        // always did); an area light's kept points without `Light::sample_li_from`'s dispatch
        // and sample record, the same numbers (a tenth of the instructions).
        for (k, (c, light)) in contrib.iter_mut().zip(lights).enumerate() {
            let kept = prepared.map(|v| &v[k * self.points.len()..(k + 1) * self.points.len()]);
            if let (Light::Area(area), Some(kept), true) = (light, kept, light.area_samples_by_area()) {
                for (p, point) in at.iter().zip(kept) {
                    if let Prepared::Area(Some(point)) = point {
                        if let Some((_, pdf, li)) = area.li_from(*p, point) {
                            *c += luminance(li) / pdf;
                        }
                    }
                }
                continue;
            }
            for (p, pt) in at.iter().zip(&self.points) {
                let ctx = LightContext { p: *p, p_error: Vec3::ZERO, n: Vec3::ZERO };
                if let Some(ls) = light.sample_li(&ctx, pt.u, &scene.meshes) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::scene::{BuildOptions, Requirements};
    use penumbra_parser::DiagSink;

    /// The area lights' points kept across voxels give each voxel the distribution that
    /// sampling every light at every point gives, bit for bit (triangle-mesh lights, a
    /// one-sided quad, a tessellated sphere, and a point light that is sampled as before).
    #[test]
    fn kept_area_light_points_give_the_same_distributions() {
        let text = "Camera \"perspective\" Film \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4
            WorldBegin
            AttributeBegin AreaLightSource \"diffuse\" \"rgb L\" [4 3 2] Translate 0 3 0
              Shape \"sphere\" \"float radius\" 0.5 AttributeEnd
            AttributeBegin AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]
              Shape \"trianglemesh\" \"point3 P\" [-1 2 -1 1 2 -1 1 2 1 -1 2 1] \"integer indices\" [0 1 2 0 2 3]
            AttributeEnd
            AttributeBegin AreaLightSource \"diffuse\" \"rgb L\" [2 2 2] \"bool twosided\" \"true\"
              Shape \"trianglemesh\" \"point3 P\" [-3 0 -1 -3 2 -1 -3 2 1] \"integer indices\" [0 1 2]
            AttributeEnd
            LightSource \"point\" \"point from\" [1 1 1] \"rgb I\" [3 3 3]
            Shape \"trianglemesh\" \"point3 P\" [-4 0 -4 4 0 -4 4 0 4 -4 0 4] \"integer indices\" [0 1 2 0 2 3]
            WorldEnd";
        let parsed = penumbra_parser::parse_str(text, "<test>", None).unwrap();
        let warnings = DiagSink::new();
        let req = Requirements { accel: true, lights: true, materials: true, ..Default::default() };
        let scene = Scene::build(&parsed.scene, req, &BuildOptions::default(), &warnings).unwrap();
        assert!(scene.light_list().len() >= 5);
        let kept = SpatialLightDistribution::new(&scene, 8);
        let sampled = SpatialLightDistribution::new(&scene, 8);
        sampled.area_points.set(None).ok().unwrap();
        let n = kept.n_voxels;
        let mut checked = 0;
        for x in 0..n[0] {
            for y in 0..n[1] {
                for z in 0..n[2] {
                    assert_eq!(
                        kept.compute([x, y, z], &scene),
                        sampled.compute([x, y, z], &scene),
                        "voxel {x} {y} {z}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 10);
        assert!(kept.area_points.get().unwrap().is_some());
    }
}
