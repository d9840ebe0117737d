//! `ambientocclusion`: pbrt-v3's AO integrator (`integrators/ao.cpp` is the specification),
//! plus pbrt-v4's `maxdistance`.
//!
//! Like pbrt-v3 it returns the unnormalised integral of V·cosθ over the
//! hemisphere around the *geometric* normal (π × the cosine-weighted
//! unoccluded fraction), skips surfaces without a material, and takes
//! `nsamples` directions per camera sample from one 2D sample array.
//!
//! With `"bool sh" "true"` it also writes SH transfer channels (`core::sh`'s convention) at
//! order `"integer shorder"` (3): the Monte Carlo estimate of `∫ V max(0, n·ω) Y_i(ω) dω`
//! from the same occlusion rays and weights as the AO value (cosine sampling: `π·mean(V·Y_i)`;
//! uniform: `2π·mean(V·cos·Y_i)`), with `n` the AO's face-forwarded geometric normal and
//! `Y_i` in world space, plus the diffuse albedo of the first surface with a material (matte's
//! `Kd` — Oren–Nayar too —, plastic's, substrate's and uber's diffuse part; 0 for materials
//! without a diffuse lobe). The AO image itself is unchanged, bit for bit.

use crate::common::params::{ParamSpec, Params, Range};
use crate::common::{SH_ORDER, SH_TRANSFER};
use penumbra_core::film::Film;
use penumbra_core::geometry::{face_forward, Frame, Ray, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RadianceBound, RenderContext, RenderError, RenderStats, SampleContext,
};
use penumbra_core::sampler::Sampler;
use penumbra_core::sampling::{cosine_sample_hemisphere, uniform_sample_hemisphere};
use penumbra_core::scene::{Requirements, Scene};
use penumbra_core::sh::{basis, transfer::TransferChannels, ShOrder};
use penumbra_core::Rgb;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use std::f32::consts::{FRAC_1_PI, PI};

pub struct AmbientOcclusion {
    pub nsamples: u32,
    pub cos_sample: bool,
    pub max_distance: f32,
    /// The order of the SH transfer channels, when they are written (`"bool sh"`).
    pub sh: Option<ShOrder>,
    /// Occlusion rays start this far (absolute, world units) along the normal instead of at
    /// pbrt-v3's error-bounded offset: the classic fixed ray epsilon, which breaks at small
    /// scales (it steps over contact occluders) and far from the origin (it is below the
    /// rounding of the hit point). Only the hidden integrator [`FIXED_EPSILON_NAME`] sets it,
    /// so that `penumbra stability` can be shown to catch what it claims to.
    pub fixed_epsilon: Option<f32>,
}

/// The hidden, deliberately unstable integrator: `ambientocclusion` with a fixed ray epsilon.
pub const FIXED_EPSILON_NAME: &str = "ambientocclusion-fixed-epsilon";
/// Its epsilon: 1e-3 world units, a common choice in renderers tuned at unit scale.
pub const FIXED_EPSILON: f32 = 1e-3;

/// The parameters `ambientocclusion` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::int("nsamples", 64, "occlusion rays per camera sample, as pbrt-v3").range(1, 1 << 20),
    ParamSpec::bool("cossample", true, "cosine-weighted directions (else uniform over the hemisphere), as pbrt-v3"),
    ParamSpec::float("maxdistance", f32::INFINITY, "occluders farther than this are ignored (pbrt-v4)")
        .within(Range::Positive),
    SH_TRANSFER,
    SH_ORDER,
];

impl AmbientOcclusion {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        Ok(Box::new(Self::from_params(params, warnings)?))
    }

    /// [`FIXED_EPSILON_NAME`]'s constructor (same parameters).
    pub fn create_fixed_epsilon(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        Ok(Box::new(AmbientOcclusion { fixed_epsilon: Some(FIXED_EPSILON), ..Self::from_params(params, warnings)? }))
    }

    fn from_params(params: &ParamSet, warnings: &DiagSink) -> Result<AmbientOcclusion, Diagnostic> {
        let p = Params::new("ambientocclusion", PARAMS, params, warnings);
        let nsamples = p.count("nsamples")?;
        let max_distance = p.float("maxdistance")?;
        let sh = if p.bool("sh")? {
            Some(ShOrder::new(p.count("shorder")? as usize).map_err(|e| Diagnostic::error(None, e.to_string()))?)
        } else {
            None
        };
        Ok(AmbientOcclusion { nsamples, cos_sample: p.bool("cossample")?, max_distance, sh, fixed_epsilon: None })
    }
}

struct Estimator<'a> {
    ao: &'a AmbientOcclusion,
    n: u32,
}

impl PixelEstimator for Estimator<'_> {
    type Shared = ();
    fn request_samples(&self, sampler: &mut dyn Sampler) {
        sampler.request_2d_array(self.n);
    }

    fn li(&self, camera_ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov } = cx;
        let mut ray = camera_ray.ray;
        // Pass through surfaces without a material, as pbrt-v3 does (bounded, in case of a degenerate loop).
        for pass in 0..64 {
            let Some(hit) = scene.intersect(&ray) else { return Rgb::ZERO };
            let mut si = scene.interaction(&ray, &hit);
            if scene.objects[hit.mesh as usize].material.is_none() {
                ray = si.spawn_ray(ray.d);
                stats.rays += 1;
                continue;
            }
            // The camera ray's differentials, for the albedo channel's texture lookups.
            if pass == 0 {
                si.compute_differentials(camera_ray);
            }
            let n = face_forward(si.n, -ray.d);
            let frame = Frame::from_zx(n, si.dpdu);
            let Some(us) = sampler.get_2d_array(self.n) else { return Rgb::ZERO };
            let mut sum = 0.0f32;
            // The SH transfer accumulators only when asked for (zeroing two arrays of
            // MAX_ORDER² doubles per camera sample was a fifth of a 1-sample AO render).
            let k = self.ao.sh.map_or(0, |o| o.coeffs());
            let (mut transfer, mut y) = (vec![0.0f64; k], vec![0.0f64; k]);
            for &u in us {
                let (w, pdf) = if self.ao.cos_sample {
                    let w = cosine_sample_hemisphere(u);
                    (w, w.z * FRAC_1_PI)
                } else {
                    (uniform_sample_hemisphere(u), 0.5 * FRAC_1_PI)
                };
                if pdf <= 0.0 {
                    continue;
                }
                let wi = frame.from_local(w);
                let mut r = match self.ao.fixed_epsilon {
                    Some(eps) => Ray::new(si.p + n * eps, wi, f32::INFINITY).at_time(si.time),
                    None => si.spawn_ray(wi),
                };
                r.t_max = self.ao.max_distance;
                stats.shadow_rays += 1;
                if !scene.occluded(&r) {
                    let weight = wi.dot(n) / (pdf * self.n as f32);
                    sum += weight;
                    if let Some(order) = self.ao.sh {
                        basis::eval(order, wi.as_dvec3(), &mut y[..k]);
                        transfer[..k].iter_mut().zip(&y[..k]).for_each(|(t, yi)| *t += weight as f64 * yi);
                    }
                }
            }
            if let Some(order) = self.ao.sh {
                TransferChannels::new(order, 0).write(aov, &transfer[..k], crate::common::diffuse_albedo(scene, &si));
            }
            return Rgb::splat(sum);
        }
        Rgb::ZERO
    }

    /// The SH transfer is weighted as the AO value is (the albedo is not).
    fn weight_channels(&self, aov: &mut [f32], w: f32) {
        if let Some(order) = self.ao.sh {
            TransferChannels::new(order, 0).weight(aov, w);
        }
    }
}

impl Integrator for AmbientOcclusion {
    fn merges_sample_ranges(&self) -> bool {
        true
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, materials: self.sh.is_some(), ..Default::default() }
    }
    fn extra_channels(&self) -> Vec<String> {
        self.sh.map(|o| TransferChannels::new(o, 0).names()).unwrap_or_default()
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        let n = scene.sampler.round_count(self.nsamples);
        if n != self.nsamples {
            ctx.warnings
                .warn(None, format!("ambientocclusion: taking {n} samples, not {} as specified", self.nsamples));
        }
        render_pixels(&Estimator { ao: self, n }, scene, ctx, film)
    }
    /// Each unoccluded sample adds `cos θ / (pdf · n)`: π/n with cosine sampling, at most 2π/n
    /// with uniform sampling.
    fn radiance_bound(&self) -> Option<RadianceBound> {
        Some(RadianceBound::Constant(if self.cos_sample { PI } else { 2.0 * PI }))
    }
}

/// Seconds `ambientocclusion` at its defaults (64 cosine-weighted rays) takes for the first
/// camera sample of each of `pixels` (the lower of two runs each, so a thread switch does not
/// count), for [`crate::silhouette::cost`]'s estimate of how much faster ray tracing would be.
pub(crate) fn time_first_samples(scene: &Scene, pixels: &[glam::IVec2]) -> Vec<f64> {
    let ao =
        AmbientOcclusion { nsamples: 64, cos_sample: true, max_distance: f32::INFINITY, sh: None, fixed_epsilon: None };
    let est = Estimator { ao: &ao, n: scene.sampler.round_count(ao.nsamples) };
    let mut sampler = scene.sampler.clone_box();
    est.request_samples(sampler.as_mut());
    let full = scene.film.sample_bounds(scene.filter.radius());
    sampler.set_sample_bounds(full.min, full.max);
    let mut stats = penumbra_core::integrator::ThreadStats::default();
    pixels
        .iter()
        .map(|&p| {
            let mut best = f64::INFINITY;
            for _ in 0..2 {
                let t = std::time::Instant::now();
                sampler.start_pixel_sample(p, 0);
                let cs = penumbra_core::integrator::draw_camera_sample(sampler.as_mut(), p, true, true);
                let ray = scene.camera.generate_ray_differential(&cs);
                let cx = SampleContext { scene, sampler: sampler.as_mut(), stats: &mut stats, aov: &mut [] };
                std::hint::black_box(est.li(&ray, cx));
                best = best.min(t.elapsed().as_secs_f64());
            }
            best
        })
        .collect()
}
