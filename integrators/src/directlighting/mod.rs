//! `directlighting`: pbrt-v3's direct lighting integrator (`integrators/directlighting.cpp`
//! is the specification), the reference every other integrator is judged against.
//!
//! Same estimator as pbrt-v3: at the first non-specular surface, every light
//! (strategy "all", each with its own sample count) or one uniformly chosen
//! light (strategy "one") is estimated by light sampling and BSDF sampling
//! combined with the power heuristic; perfectly specular surfaces recurse up
//! to `maxdepth`; emission seen directly is included. The QMC dimensions are
//! laid out as pbrt-v3 lays them out — for "all", two 2D sample arrays per
//! light per depth, requested up front — so that halton/sobol keep their
//! stratification across the per-light samples.

use crate::common::direct::{estimate_direct, sample_one_light, specular};
use crate::common::params::{ParamSpec, Params};
use crate::common::{max_depth, max_depth_param, pixel_bounds_param, PIXEL_BOUNDS};
use glam::Vec2;
use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds2i, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, SampleContext, ThreadStats,
};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene};
use penumbra_core::Rgb;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    All,
    One,
}

pub struct DirectLighting {
    pub strategy: Strategy,
    pub max_depth: u32,
    /// pbrt-v3's `"pixelbounds"`: only these pixels are sampled.
    pub pixel_bounds: Option<Bounds2i>,
}

/// The parameters `directlighting` reads (pbrt-v3's).
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::choice(
        "strategy",
        &["all", "one"],
        "every light with its own nsamples, or one light chosen uniformly per sample (pbrt-v3)",
    ),
    max_depth(1024),
    PIXEL_BOUNDS,
];

impl DirectLighting {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("directlighting", PARAMS, params, warnings);
        let strategy = p.choice("strategy", [Strategy::All, Strategy::One])?;
        let max_depth = max_depth_param(&p)?;
        let pixel_bounds = pixel_bounds_param(&p)?;
        Ok(Box::new(DirectLighting { strategy, max_depth, pixel_bounds }))
    }
}

struct Estimator<'a> {
    dl: &'a DirectLighting,
    /// Per-light sample counts after the sampler's rounding (strategy "all").
    n_light_samples: Vec<u32>,
}

impl Estimator<'_> {
    fn li(
        &self,
        ray: &RayDifferential,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let lights = scene.light_list();
        // Surfaces without a material are passed through without counting depth, as pbrt-v3 does.
        // (`first_point` and the BSDF built here rather than `first_surface`: the same surface,
        // without moving the BSDF through two more return values.)
        let (first, queries) = scene.first_point(ray);
        stats.add_continued(queries);
        let (si, le) = match first {
            Ok(p) => (p.si, p.le),
            Err(escaped) => return escaped,
        };
        let Some(bsdf) = scene.bsdf(&si) else { return Rgb::ZERO };
        let mut l = le;
        if !lights.is_empty() {
            l += match self.dl.strategy {
                Strategy::All => self.sample_all_lights(&si, &bsdf, scene, sampler, stats),
                Strategy::One => sample_one_light(&si, &bsdf, scene, sampler, stats, None),
            };
        }
        if depth + 1 < self.dl.max_depth {
            for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                l += specular(&si, &bsdf, ray, sampler, stats, kind, |r, sampler, stats| {
                    self.li(r, scene, sampler, stats, depth + 1)
                });
            }
        }
        l
    }

    fn sample_all_lights(
        &self,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let mut l = Rgb::ZERO;
        // The light array, copied out of the sampler before the scattering array is asked for:
        // on the stack for the usual few samples, else on the heap.
        let mut ul_small = [Vec2::ZERO; 16];
        let mut ul_large = Vec::new();
        for (i, light) in scene.light_list().iter().enumerate() {
            let n = self.n_light_samples[i];
            // pbrt-v3 takes the light array first, then the scattering array;
            // when either is exhausted, one sample from the plain 2D dimensions.
            let ul: &[Vec2] = match sampler.get_2d_array(n) {
                Some(a) if a.len() <= ul_small.len() => {
                    ul_small[..a.len()].copy_from_slice(a);
                    &ul_small[..a.len()]
                }
                Some(a) => {
                    ul_large.clear();
                    ul_large.extend_from_slice(a);
                    &ul_large
                }
                None => &[],
            };
            match sampler.get_2d_array(n) {
                Some(us) if ul.len() == n as usize => {
                    let mut ld = Rgb::ZERO;
                    for (u_scatter, u_light) in us.iter().zip(ul) {
                        ld += estimate_direct(si, bsdf, *u_scatter, i, light, *u_light, scene, stats);
                    }
                    l += ld / n as f32;
                }
                _ => {
                    let u_light = sampler.get_2d();
                    let u_scatter = sampler.get_2d();
                    l += estimate_direct(si, bsdf, u_scatter, i, light, u_light, scene, stats);
                }
            }
        }
        l
    }
}

impl PixelEstimator for Estimator<'_> {
    type Shared = ();
    fn request_samples(&self, sampler: &mut dyn Sampler) {
        if self.dl.strategy == Strategy::All {
            for _ in 0..self.dl.max_depth {
                for &n in &self.n_light_samples {
                    sampler.request_2d_array(n);
                    sampler.request_2d_array(n);
                }
            }
        }
    }
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        self.li(ray, scene, sampler, stats, 0)
    }
    fn pixel_bounds(&self) -> Option<Bounds2i> {
        self.dl.pixel_bounds
    }
}

impl Integrator for DirectLighting {
    fn merges_sample_ranges(&self) -> bool {
        true
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        let n_light_samples = scene
            .lights
            .as_ref()
            .map(|l| l.lights.iter().map(|x| scene.sampler.round_count(x.n_samples().max(1))).collect())
            .unwrap_or_default();
        render_pixels(&Estimator { dl: self, n_light_samples }, scene, ctx, film)
    }
}
