//! `whitted`: pbrt-v3's Whitted-style ray tracer (`integrators/whitted.cpp` is the specification).
//!
//! At the first surface with a material: its emission, plus every light with one light sample
//! each (no BSDF sampling, no MIS; a shadow ray per sample), plus — up to `maxdepth` — perfect
//! specular reflection and transmission, each followed recursively with one 2D sample. A ray
//! leaving the scene sees the infinite lights. Surfaces without a material are passed through
//! without counting depth. Sampler dimensions: one 2D sample per light, in the scene's light
//! order, then the reflection's and the transmission's 2D samples (pbrt-v3's order).
//!
//! Parameters (pbrt-v3's): `"integer maxdepth"` (5), `"integer pixelbounds"` (pixels outside
//! are not sampled).

use crate::common::direct::{shadow_ray, specular};
use crate::common::params::{ParamSpec, Params};
use crate::common::{max_depth, max_depth_param, pixel_bounds_param, PIXEL_BOUNDS};
use penumbra_core::bxdf::BxdfFlags;
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds2i, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, SampleContext, ThreadStats,
};
use penumbra_core::light::LightContext;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit};
use penumbra_core::Rgb;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub struct Whitted {
    pub max_depth: u32,
    pub pixel_bounds: Option<Bounds2i>,
}

/// The parameters `whitted` reads (pbrt-v3's).
pub const PARAMS: &[ParamSpec] = &[max_depth(1024), PIXEL_BOUNDS];

impl Whitted {
    /// Reads [`PARAMS`] (see the module doc).
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("whitted", PARAMS, params, warnings);
        let max_depth = max_depth_param(&p)?;
        let pixel_bounds = pixel_bounds_param(&p)?;
        Ok(Box::new(Whitted { max_depth, pixel_bounds }))
    }

    fn li(
        &self,
        ray: &RayDifferential,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let (first, queries) = scene.first_surface(ray);
        stats.add_continued(queries);
        let SurfaceHit { si, bsdf, le, .. } = match first {
            Ok(h) => h,
            Err(escaped) => return escaped,
        };
        let mut l = le;
        let ns = bsdf.shading_normal();
        let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
        for light in scene.light_list() {
            let u = sampler.get_2d();
            let Some(ls) = light.sample_li(&ctx, u, &scene.meshes) else { continue };
            if ls.li == Rgb::ZERO || !(ls.pdf > 0.0) {
                continue;
            }
            let f = bsdf.f(si.wo, ls.wi, BxdfFlags::ALL);
            if f != Rgb::ZERO {
                stats.shadow_rays += 1;
                if !scene.occluded(&shadow_ray(&si, &ls)) {
                    l += f * ls.li * (ls.wi.dot(ns).abs() / ls.pdf);
                }
            }
        }
        if depth + 1 < self.max_depth {
            for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                l += specular(&si, &bsdf, ray, sampler, stats, kind, |r, sampler, stats| {
                    self.li(r, scene, sampler, stats, depth + 1)
                });
            }
        }
        l
    }
}

impl PixelEstimator for Whitted {
    type Shared = ();
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        Whitted::li(self, ray, scene, sampler, stats, 0)
    }

    fn pixel_bounds(&self) -> Option<Bounds2i> {
        self.pixel_bounds
    }
}

impl Integrator for Whitted {
    fn merges_sample_ranges(&self) -> bool {
        true
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        render_pixels(self, scene, ctx, film)
    }
}
