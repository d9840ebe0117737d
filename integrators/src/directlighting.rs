//! `directlighting`: pbrt-v3's direct lighting integrator, the reference every
//! other integrator is judged against.
//!
//! Same estimator as pbrt-v3: at the first non-specular surface, every light
//! (strategy "all", each with its own sample count) or one uniformly chosen
//! light (strategy "one") is estimated by light sampling and BSDF sampling
//! combined with the power heuristic; perfectly specular surfaces recurse up
//! to `maxdepth`; emission seen directly is included. The QMC dimensions are
//! laid out as pbrt-v3 lays them out — for "all", two 2D sample arrays per
//! light per depth, requested up front — so that halton/sobol keep their
//! stratification across the per-light samples.

use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::film::Film;
use penumbra_core::geometry::Ray;
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, ThreadStats,
};
use penumbra_core::light::{Light, LightContext};
use penumbra_core::sampler::Sampler;
use penumbra_core::sampling::power_heuristic;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit, SurfaceInteraction};
use penumbra_core::{Rgb, Vec2};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    All,
    One,
}

pub struct DirectLighting {
    pub strategy: Strategy,
    pub max_depth: u32,
}

impl DirectLighting {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let max_depth = params.get_one_int("maxdepth", 5);
        if !(0..=1024).contains(&max_depth) {
            return Err(Diagnostic::error(
                params.loc_of("maxdepth").cloned(),
                format!("\"maxdepth\" must be in 0..=1024, got {max_depth}"),
            ));
        }
        let st = params.get_one_string("strategy", "all");
        let strategy = match st.as_str() {
            "all" => Strategy::All,
            "one" => Strategy::One,
            other => {
                warnings.warn(
                    params.loc_of("strategy").cloned(),
                    format!("strategy \"{other}\" for direct lighting unknown: using \"all\""),
                );
                Strategy::All
            }
        };
        // pbrt-v3 reads "pixelbounds" here; penumbra takes crops from the film or --crop.
        params.get_ints("pixelbounds");
        Ok(Box::new(DirectLighting { strategy, max_depth: max_depth as u32 }))
    }
}

struct Estimator<'a> {
    dl: &'a DirectLighting,
    /// Per-light sample counts after the sampler's rounding (strategy "all").
    n_light_samples: Vec<u32>,
}

impl Estimator<'_> {
    fn li(&self, ray: &Ray, scene: &Scene, sampler: &mut dyn Sampler, stats: &mut ThreadStats, depth: u32) -> Rgb {
        let lights = scene.light_list();
        // Surfaces without a material are passed through without counting depth, as pbrt-v3 does.
        let (first, queries) = scene.first_surface(ray);
        stats.rays += queries - 1;
        let SurfaceHit { si, bsdf, le, .. } = match first {
            Ok(h) => h,
            Err(escaped) => return escaped,
        };
        let mut l = le;
        if !lights.is_empty() {
            l += match self.dl.strategy {
                Strategy::All => self.sample_all_lights(&si, &bsdf, scene, sampler, stats),
                Strategy::One => self.sample_one_light(&si, &bsdf, scene, sampler, stats),
            };
        }
        if depth + 1 < self.dl.max_depth {
            l += self.specular(&si, &bsdf, scene, sampler, stats, depth, BxdfFlags::REFLECTION);
            l += self.specular(&si, &bsdf, scene, sampler, stats, depth, BxdfFlags::TRANSMISSION);
        }
        l
    }

    #[allow(clippy::too_many_arguments)]
    fn specular(
        &self,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
        kind: BxdfFlags,
    ) -> Rgb {
        let u = sampler.get_2d();
        let Some(s) = bsdf.sample_f(si.wo, u, kind | BxdfFlags::SPECULAR) else { return Rgb::ZERO };
        let cos = s.wi.dot(si.shading.z).abs();
        if !(s.pdf > 0.0) || s.f == Rgb::ZERO || cos == 0.0 {
            return Rgb::ZERO;
        }
        stats.rays += 1;
        let r = si.spawn_ray(s.wi);
        s.f * self.li(&r, scene, sampler, stats, depth + 1) * (cos / s.pdf)
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
        let mut ul = Vec::new();
        for (i, light) in scene.light_list().iter().enumerate() {
            let n = self.n_light_samples[i];
            // pbrt-v3 takes the light array first, then the scattering array;
            // when either is exhausted, one sample from the plain 2D dimensions.
            ul.clear();
            if let Some(a) = sampler.get_2d_array(n) {
                ul.extend_from_slice(a);
            }
            match sampler.get_2d_array(n) {
                Some(us) if ul.len() == n as usize => {
                    let mut ld = Rgb::ZERO;
                    for (u_scatter, u_light) in us.iter().zip(&ul) {
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

    fn sample_one_light(
        &self,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let lights = scene.light_list();
        let n = lights.len();
        let k = ((sampler.get_1d() * n as f32) as usize).min(n - 1);
        let ul = sampler.get_2d();
        let us = sampler.get_2d();
        estimate_direct(si, bsdf, us, k, &lights[k], ul, scene, stats) * n as f32
    }
}

/// pbrt-v3's `EstimateDirect`: one light sample and one BSDF sample, MIS-weighted.
/// `light_index` is `light`'s index in `scene.lights` (to recognise its surface).
#[allow(clippy::too_many_arguments)]
pub fn estimate_direct(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    u_scatter: Vec2,
    light_index: usize,
    light: &Light,
    u_light: Vec2,
    scene: &Scene,
    stats: &mut ThreadStats,
) -> Rgb {
    let flags = BxdfFlags::NON_SPECULAR;
    let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
    let mut ld = Rgb::ZERO;
    if let Some(ls) = light.sample_li(&ctx, u_light, &scene.meshes) {
        if ls.pdf > 0.0 && ls.li != Rgb::ZERO {
            let (f, scatter_pdf) = bsdf.f_pdf(si.wo, ls.wi, flags);
            let f = f * ls.wi.dot(si.shading.z).abs();
            if f != Rgb::ZERO {
                let shadow = if ls.n_light == penumbra_core::Vec3::ZERO {
                    si.spawn_ray_to(ls.p_light)
                } else {
                    si.spawn_ray_to_surface(ls.p_light, ls.p_light_error, ls.n_light)
                };
                stats.shadow_rays += 1;
                if !scene.occluded(&shadow) {
                    if ls.delta {
                        ld += f * ls.li / ls.pdf;
                    } else {
                        let w = power_heuristic(1, ls.pdf, 1, scatter_pdf);
                        ld += f * ls.li * (w / ls.pdf);
                    }
                }
            }
        }
    }
    if !light.is_delta() {
        if let Some(bs) = bsdf.sample_f(si.wo, u_scatter, flags) {
            let f = bs.f * bs.wi.dot(si.shading.z).abs();
            if f != Rgb::ZERO && bs.pdf > 0.0 {
                let specular = bs.flags.contains(BxdfFlags::SPECULAR);
                let ray = si.spawn_ray(bs.wi);
                stats.rays += 1;
                let hit = scene.intersect(&ray);
                let mut light_hit = None;
                let li = match &hit {
                    Some(h) => {
                        if scene.area_light_at(h) == Some(light_index) {
                            let lsi = scene.interaction(&ray, h);
                            light_hit = Some((lsi.p, lsi.n));
                            light.l(lsi.n, -bs.wi)
                        } else {
                            Rgb::ZERO
                        }
                    }
                    None => light.le(&ray),
                };
                if li != Rgb::ZERO {
                    let weight = if specular {
                        1.0
                    } else {
                        let light_pdf = light.pdf_li(&ctx, bs.wi, light_hit);
                        if light_pdf == 0.0 {
                            return ld;
                        }
                        power_heuristic(1, bs.pdf, 1, light_pdf)
                    };
                    ld += f * li * (weight / bs.pdf);
                }
            }
        }
    }
    ld
}

impl PixelEstimator for Estimator<'_> {
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
    fn li(
        &self,
        ray: &Ray,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        _aov: &mut [f32],
    ) -> Rgb {
        self.li(ray, scene, sampler, stats, 0)
    }
}

impl Integrator for DirectLighting {
    fn name(&self) -> &str {
        "directlighting"
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
