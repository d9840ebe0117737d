//! `path`: pbrt-v3's unidirectional path tracer (`integrators/path.cpp` is the specification).
//!
//! At every vertex with a non-specular lobe one light is sampled — chosen by the
//! `lightsamplestrategy` distribution ([`crate::common::light_distribution`]) — with light and
//! BSDF sampling combined by the power heuristic ([`estimate_direct`]); the path then continues
//! in a direction sampled from the whole BSDF. Emission is added where the camera ray or a
//! perfectly specular bounce reaches a light (elsewhere the light-sampling step has counted it).
//! After four bounces, a path whose throughput (with the radiance scaling of refraction
//! factored out, pbrt-v3's `etaScale`) is below `rrthreshold` in every channel is ended with
//! probability max(0.05, 1 − max channel) by Russian roulette. Glass is one
//! Fresnel-weighted specular lobe (pbrt-v3's `allowMultipleLobes`). Surfaces without a material
//! are passed through without counting a bounce. Sampler dimensions per vertex are pbrt-v3's:
//! light choice (1D), light point (2D), BSDF sample for the light estimate (2D) — only at
//! vertices with a non-specular lobe —, the continuation (2D), and the roulette (1D) when it
//! is played.
//!
//! Under a surface with a BSSRDF (`subsurface`, `kdsubsurface`, `disney` with a scatter
//! distance), a sampled transmission continues from where the BSSRDF lets the light out, as
//! pbrt-v3's path tracer does ([`subsurface`]).
//!
//! Parameters (pbrt-v3's): `"integer maxdepth"` (5), `"float rrthreshold"` (1),
//! `"string lightsamplestrategy"` `"spatial"` (default), `"uniform"` or `"power"`,
//! `"integer pixelbounds"` (pixels outside are not sampled).

mod subsurface;

use crate::common::direct::sample_one_light;
use crate::common::light_distribution::{LightDistribution, LightSampleStrategy};
use crate::common::params::{ParamSpec, Params, Range};
use crate::common::{max_depth_param, pixel_bounds_param, PIXEL_BOUNDS};
use penumbra_core::bxdf::BxdfFlags;
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds2i, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, SampleContext,
};
use penumbra_core::material::BsdfOptions;
use penumbra_core::scene::{Requirements, Scene};
use penumbra_core::Rgb;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub struct PathIntegrator {
    pub max_depth: u32,
    pub rr_threshold: f32,
    pub strategy: LightSampleStrategy,
    pub pixel_bounds: Option<Bounds2i>,
}

/// The parameters `path` reads (pbrt-v3's).
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::int("maxdepth", 5, "bounces before the path ends, as pbrt-v3's maxdepth").range(0, 1 << 16),
    ParamSpec::float("rrthreshold", 1.0, "Russian roulette starts below this throughput (after 4 bounces), as pbrt-v3")
        .within(Range::Finite),
    ParamSpec::choice(
        "lightsamplestrategy",
        &["spatial", "uniform", "power"],
        "how each vertex picks its light: per-voxel estimated contribution, uniformly, or by power (pbrt-v3)",
    ),
    PIXEL_BOUNDS,
];

impl PathIntegrator {
    /// Reads [`PARAMS`] (see the module doc).
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("path", PARAMS, params, warnings);
        let max_depth = max_depth_param(&p)?;
        let rr_threshold = p.float("rrthreshold")?;
        let strategy = p.choice(
            "lightsamplestrategy",
            [LightSampleStrategy::Spatial, LightSampleStrategy::Uniform, LightSampleStrategy::Power],
        )?;
        let pixel_bounds = pixel_bounds_param(&p)?;
        Ok(Box::new(PathIntegrator { max_depth, rr_threshold, strategy, pixel_bounds }))
    }
}

struct Estimator<'a> {
    path: &'a PathIntegrator,
    lights: LightDistribution,
}

/// pbrt-v3's `path` asks for glass as one Fresnel-weighted lobe.
const BSDF_OPTIONS: BsdfOptions =
    BsdfOptions { mode: penumbra_core::bxdf::TransportMode::Radiance, allow_multiple_lobes: true };

impl PixelEstimator for Estimator<'_> {
    type Shared = ();
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        let (mut l, mut beta) = (Rgb::ZERO, Rgb::ONE);
        let mut ray = *ray;
        let mut specular_bounce = false;
        // Radiance scaling by refraction so far, factored out of the roulette's throughput.
        let mut eta_scale = 1.0f32;
        for bounces in 0.. {
            // Surfaces without a material are passed through (not counted as bounces).
            let (first, queries) = scene.first_point(&ray);
            // The camera ray is the driver's to count, a bounce ray this loop's.
            if bounces > 0 {
                stats.rays += 1;
            }
            stats.add_continued(queries);
            let point = match first {
                Ok(p) => p,
                Err(escaped) => {
                    if bounces == 0 || specular_bounce {
                        l += beta * escaped;
                    }
                    break;
                }
            };
            if bounces == 0 || specular_bounce {
                l += beta * point.le;
            }
            if bounces >= self.path.max_depth {
                break;
            }
            let si = &point.si;
            let Some(bsdf) = scene.bsdf_with(si, BSDF_OPTIONS) else { break };
            if bsdf.num_components(BxdfFlags::NON_SPECULAR) > 0 {
                let distribution = self.lights.lookup(si.p, scene);
                l += beta * sample_one_light(si, &bsdf, scene, sampler, stats, Some(distribution));
            }
            let u = sampler.get_2d();
            let Some(s) = bsdf.sample_f(si.wo, u, BxdfFlags::ALL) else { break };
            if s.f == Rgb::ZERO || !(s.pdf > 0.0) {
                break;
            }
            beta *= s.f * (s.wi.dot(bsdf.shading_normal()).abs() / s.pdf);
            specular_bounce = s.flags.contains(BxdfFlags::SPECULAR);
            if specular_bounce && s.flags.contains(BxdfFlags::TRANSMISSION) {
                let eta2 = bsdf.eta * bsdf.eta;
                eta_scale *= if si.wo.dot(si.n) > 0.0 { eta2 } else { 1.0 / eta2 };
            }
            // pbrt-v3's `path` spawns bounce rays without differentials.
            ray = si.spawn_ray(s.wi).into();
            if s.flags.contains(BxdfFlags::TRANSMISSION) {
                if let Some(bssrdf) = scene.bssrdf(si, &bsdf, BSDF_OPTIONS) {
                    let exit = subsurface::exit(&bssrdf, scene, sampler, stats, &self.lights, &mut beta, &mut l);
                    let Some(exit) = exit else { break };
                    ray = exit.ray.into();
                    specular_bounce = exit.specular;
                }
            }
            let rr_beta = (beta * eta_scale).max_element();
            if rr_beta < self.path.rr_threshold && bounces > 3 {
                let q = (1.0 - rr_beta).max(0.05);
                if sampler.get_1d() < q {
                    break;
                }
                beta /= 1.0 - q;
            }
        }
        l
    }

    fn pixel_bounds(&self) -> Option<Bounds2i> {
        self.path.pixel_bounds
    }
}

impl Integrator for PathIntegrator {
    fn merges_sample_ranges(&self) -> bool {
        true
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, subsurface: true, ..Default::default() }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        let lights = LightDistribution::new(self.strategy, scene);
        render_pixels(&Estimator { path: self, lights }, scene, ctx, film)
    }
}
