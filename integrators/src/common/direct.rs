//! pbrt-v3's direct-lighting building blocks (`integrator.cpp`): `EstimateDirect` (one light
//! sample and one BSDF sample combined with the power heuristic), `UniformSampleOneLight`, and
//! the perfect specular reflection/transmission step of `SamplerIntegrator`. Used by
//! `directlighting`, `path` and `whitted`.

use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::geometry::Ray;
use penumbra_core::integrator::ThreadStats;
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::{Light, LightContext, LightLiSample};
use penumbra_core::sampler::Sampler;
use penumbra_core::sampling::{power_heuristic, Distribution1D};
use penumbra_core::scene::Scene;
use penumbra_core::{Rgb, Vec2, Vec3};

/// The shadow ray from `si` to the point a light sample chose (both ends offset when the
/// light point is on a surface).
pub fn shadow_ray(si: &SurfaceInteraction, ls: &LightLiSample) -> Ray {
    if ls.n_light == Vec3::ZERO {
        si.spawn_ray_to(ls.p_light)
    } else {
        si.spawn_ray_to_surface(ls.p_light, ls.p_light_error, ls.n_light)
    }
}

/// pbrt-v3's `EstimateDirect`: one light sample and one BSDF sample, MIS-weighted.
/// `light_index` is `light`'s index in `scene.lights` (to recognise its surface). The cosine
/// is taken with the BSDF's shading normal (after bump mapping, as pbrt-v3's `shading.n`).
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
    estimate_direct_with(si, bsdf, BxdfFlags::NON_SPECULAR, u_scatter, light_index, light, u_light, scene, stats)
}

/// [`estimate_direct`] with the BSDF's lobes restricted to those matching `flags` (pbrt-v3's
/// `bsdfFlags` argument; `NON_SPECULAR` there).
#[allow(clippy::too_many_arguments)]
pub fn estimate_direct_with(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    flags: BxdfFlags,
    u_scatter: Vec2,
    light_index: usize,
    light: &Light,
    u_light: Vec2,
    scene: &Scene,
    stats: &mut ThreadStats,
) -> Rgb {
    let ns = bsdf.shading_normal();
    let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
    let mut ld = Rgb::ZERO;
    if let Some(ls) = light.sample_li(&ctx, u_light, &scene.meshes) {
        if ls.pdf > 0.0 && ls.li != Rgb::ZERO {
            let (f, scatter_pdf) = bsdf.f_pdf(si.wo, ls.wi, flags);
            let f = f * ls.wi.dot(ns).abs();
            if f != Rgb::ZERO {
                stats.shadow_rays += 1;
                if !scene.occluded(&shadow_ray(si, &ls)) {
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
            let f = bs.f * bs.wi.dot(ns).abs();
            if f != Rgb::ZERO && bs.pdf > 0.0 {
                let specular = bs.flags.contains(BxdfFlags::SPECULAR);
                let ray = si.spawn_ray(bs.wi);
                stats.rays += 1;
                let hit = scene.intersect(&ray);
                let mut light_hit = None;
                // An escaping ray's radiance and the light's pdf of its direction at once.
                let mut escaped_pdf = None;
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
                    None => {
                        let (le, pdf) = light.le_and_pdf(&ray);
                        escaped_pdf = Some(pdf);
                        le
                    }
                };
                if li != Rgb::ZERO {
                    let weight = if specular {
                        1.0
                    } else {
                        let light_pdf = escaped_pdf.unwrap_or_else(|| light.pdf_li(&ctx, bs.wi, light_hit));
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

/// pbrt-v3's `UniformSampleOneLight`: one light chosen by `distribution` (one probability per
/// light; `None`: uniformly), estimated by [`estimate_direct`] and divided by its probability.
/// Draws a 1D sample, then (unless the chosen light has probability 0) two 2D samples.
pub fn sample_one_light(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    scene: &Scene,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    distribution: Option<&Distribution1D>,
) -> Rgb {
    let lights = scene.light_list();
    let n = lights.len();
    if n == 0 {
        return Rgb::ZERO;
    }
    let u = sampler.get_1d();
    let (k, pdf) = match distribution {
        Some(d) => {
            let (k, pdf, _) = d.sample_discrete(u);
            if !(pdf > 0.0) || k >= n {
                return Rgb::ZERO;
            }
            (k, Some(pdf))
        }
        None => (((u * n as f32) as usize).min(n - 1), None),
    };
    let ul = sampler.get_2d();
    let us = sampler.get_2d();
    let ld = estimate_direct(si, bsdf, us, k, &lights[k], ul, scene, stats);
    match pdf {
        Some(pdf) => ld / pdf,
        None => ld * n as f32,
    }
}

/// pbrt-v3's `SamplerIntegrator::SpecularReflect`/`SpecularTransmit` (`kind` is
/// `REFLECTION` or `TRANSMISSION`): samples the perfectly specular lobes of that kind with one
/// 2D sample and weights the radiance `trace` returns along the new ray.
pub fn specular(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    kind: BxdfFlags,
    trace: impl FnOnce(&Ray, &mut dyn Sampler, &mut ThreadStats) -> Rgb,
) -> Rgb {
    let Some(s) = specular_ray(si, bsdf, sampler, stats, kind) else { return Rgb::ZERO };
    s.f * trace(&s.ray, sampler, stats) * s.scale
}

/// The step of [`specular`] before tracing: the new ray and its weight `f · scale` (`f` the
/// BSDF value, `scale` = |cos θ| / pdf), counted as a ray; `None` when the lobes of that kind
/// give nothing. For an integrator whose radiance along the ray is more than one value.
pub fn specular_ray(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    kind: BxdfFlags,
) -> Option<SpecularRay> {
    let u = sampler.get_2d();
    let s = bsdf.sample_f(si.wo, u, kind | BxdfFlags::SPECULAR)?;
    let cos = s.wi.dot(bsdf.shading_normal()).abs();
    if !(s.pdf > 0.0) || s.f == Rgb::ZERO || cos == 0.0 {
        return None;
    }
    stats.rays += 1;
    Some(SpecularRay { ray: si.spawn_ray(s.wi), f: s.f, scale: cos / s.pdf })
}

/// A ray [`specular_ray`] sampled, and its weight `f · scale`.
pub struct SpecularRay {
    pub ray: Ray,
    pub f: Rgb,
    pub scale: f32,
}

/// Whether `bsdf` has a perfectly specular lobe (one [`specular`] can follow).
pub fn has_specular(bsdf: &Bsdf) -> bool {
    bsdf.bxdfs().iter().any(|b| b.flags().is_specular())
}
