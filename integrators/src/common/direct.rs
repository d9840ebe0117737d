//! pbrt-v3's direct-lighting building blocks (`integrator.cpp`): `EstimateDirect` (one light
//! sample and one BSDF sample combined with the power heuristic), `UniformSampleOneLight`, and
//! the perfect specular reflection/transmission step of `SamplerIntegrator`. Used by
//! `directlighting`, `path` and `whitted`.

use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::geometry::{Ray, RayDifferential, RayOffsets};
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
/// 2D sample and weights the radiance `trace` returns along the new ray, which carries offset
/// rays when `ray` (the ray that reached `si`) did ([`specular_ray`]).
pub fn specular(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    ray: &RayDifferential,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    kind: BxdfFlags,
    trace: impl FnOnce(&RayDifferential, &mut dyn Sampler, &mut ThreadStats) -> Rgb,
) -> Rgb {
    let Some(s) = specular_ray(si, bsdf, ray, sampler, stats, kind) else { return Rgb::ZERO };
    s.f * trace(&s.ray, sampler, stats) * s.scale
}

/// The step of [`specular`] before tracing: the new ray and its weight `f · scale` (`f` the
/// BSDF value, `scale` = |cos θ| / pdf), counted as a ray; `None` when the lobes of that kind
/// give nothing. For an integrator whose radiance along the ray is more than one value.
/// When `ray` has offset rays, the new ray's are pbrt-v3's: reflected or refracted about the
/// shading normal as it turns over the pixel footprint (`∂n/∂x = ∂n/∂u ∂u/∂x + ∂n/∂v ∂v/∂x`).
pub fn specular_ray(
    si: &SurfaceInteraction,
    bsdf: &Bsdf,
    ray: &RayDifferential,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    kind: BxdfFlags,
) -> Option<SpecularRay> {
    let u = sampler.get_2d();
    let s = bsdf.sample_f(si.wo, u, kind | BxdfFlags::SPECULAR)?;
    let ns = bsdf.shading_normal();
    let cos = s.wi.dot(ns).abs();
    if !(s.pdf > 0.0) || s.f == Rgb::ZERO || cos == 0.0 {
        return None;
    }
    stats.rays += 1;
    let offsets = ray.offsets.and_then(|o| specular_offsets(si, ns, bsdf.eta, &o, s.wi, kind));
    Some(SpecularRay { ray: RayDifferential { ray: si.spawn_ray(s.wi), offsets }, f: s.f, scale: cos / s.pdf })
}

/// pbrt-v3's ray differentials of a perfectly specular reflection or transmission to `wi`
/// at `si` (shading normal `ns`, the BSDF's relative index of refraction `eta`), from the
/// offset rays `o` of the ray that arrived.
fn specular_offsets(
    si: &SurfaceInteraction,
    ns: Vec3,
    eta: f32,
    o: &RayOffsets,
    wi: Vec3,
    kind: BxdfFlags,
) -> Option<RayOffsets> {
    let d = &si.diff;
    let wo = si.wo;
    let mut dndx = si.dndu * d.dudx + si.dndv * d.dvdx;
    let mut dndy = si.dndu * d.dudy + si.dndv * d.dvdy;
    let (dwodx, dwody) = (-o.rx_d - wo, -o.ry_d - wo);
    let (rx_d, ry_d) = if kind.contains(BxdfFlags::TRANSMISSION) {
        // pbrt-v3 assumes the ray enters (relative index 1/eta) and flips the normal and its
        // derivatives when it leaves.
        let (mut eta, mut ns) = (1.0 / eta, ns);
        if wo.dot(ns) < 0.0 {
            eta = 1.0 / eta;
            ns = -ns;
            dndx = -dndx;
            dndy = -dndy;
        }
        let ddn_dx = dwodx.dot(ns) + wo.dot(dndx);
        let ddn_dy = dwody.dot(ns) + wo.dot(dndy);
        let mu = eta * wo.dot(ns) - wi.dot(ns).abs();
        let k = eta - (eta * eta * wo.dot(ns)) / wi.dot(ns).abs();
        (wi - eta * dwodx + (mu * dndx + k * ddn_dx * ns), wi - eta * dwody + (mu * dndy + k * ddn_dy * ns))
    } else {
        let ddn_dx = dwodx.dot(ns) + wo.dot(dndx);
        let ddn_dy = dwody.dot(ns) + wo.dot(dndy);
        (wi - dwodx + 2.0 * (wo.dot(ns) * dndx + ddn_dx * ns), wi - dwody + 2.0 * (wo.dot(ns) * dndy + ddn_dy * ns))
    };
    let r = RayOffsets { rx_o: si.p + d.dpdx, rx_d, ry_o: si.p + d.dpdy, ry_d };
    [r.rx_o, r.rx_d, r.ry_o, r.ry_d].iter().all(|v| v.is_finite()).then_some(r)
}

/// A ray [`specular_ray`] sampled, and its weight `f · scale`.
pub struct SpecularRay {
    pub ray: RayDifferential,
    pub f: Rgb,
    pub scale: f32,
}

/// Whether `bsdf` has a perfectly specular lobe (one [`specular`] can follow).
pub fn has_specular(bsdf: &Bsdf) -> bool {
    bsdf.bxdfs().iter().any(|b| b.flags().is_specular())
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::interaction::Differentials;

    /// The interaction where a ray meets the sphere of radius `r` at the origin (parametrised
    /// p = r (cos u sin v, sin u sin v, cos v)), with its analytic ∂n/∂u, ∂n/∂v and the
    /// differentials of the offset rays `o`.
    fn sphere_hit(r: f32, ray: &RayDifferential) -> SurfaceInteraction {
        let t = {
            let (b, c) = (ray.o.dot(ray.d), ray.o.length_squared() - r * r);
            -b - (b * b - c).sqrt()
        };
        let p = ray.at(t);
        let (u, v) = (p.y.atan2(p.x), (p.z / r).acos());
        let dpdu = Vec3::new(-p.y, p.x, 0.0);
        let dpdv = r * Vec3::new(u.cos() * v.cos(), u.sin() * v.cos(), -v.sin());
        let n = p / r;
        let mut si = SurfaceInteraction {
            p,
            n,
            uv: Vec2::new(u, v),
            dpdu,
            dpdv,
            dndu: dpdu / r,
            dndv: dpdv / r,
            wo: -ray.d,
            ..Default::default()
        };
        si.compute_differentials(ray);
        si
    }

    fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
        -wo + 2.0 * wo.dot(n) * n
    }

    fn refract(wo: Vec3, n: Vec3, eta: f32) -> Vec3 {
        // eta: relative index (incident over transmitted); wo on n's side.
        let cos_i = wo.dot(n);
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
        let cos_t = (1.0 - sin2_t).sqrt();
        -eta * wo + (eta * cos_i - cos_t) * n
    }

    /// pbrt-v3's reflected and refracted differentials are first-order exact: the offset ray's
    /// own reflection (refraction) off the sphere where it really hits it differs from the
    /// predicted offset direction by second-order terms only.
    #[test]
    fn specular_differentials_follow_the_offset_rays_to_first_order() {
        let r = 1.0f32;
        let o = Vec3::new(0.3, -4.0, 0.5);
        let d = (Vec3::new(0.2, 0.0, 0.3) - o).normalize();
        let eps = 0.01f32;
        let (dx, dy) = (Vec3::new(eps, 0.0, 0.0), Vec3::new(0.0, 0.0, eps));
        let ray = RayDifferential {
            ray: Ray::new(o, d, f32::INFINITY),
            offsets: Some(RayOffsets { rx_o: o, rx_d: (d + dx).normalize(), ry_o: o, ry_d: (d + dy).normalize() }),
        };
        let si = sphere_hit(r, &ray);
        let offs = ray.offsets.unwrap();
        let eta_bsdf = 1.5f32;
        for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
            let scatter = |wo: Vec3, n: Vec3| {
                if kind == BxdfFlags::REFLECTION {
                    reflect(wo, n)
                } else {
                    refract(wo, n, 1.0 / eta_bsdf)
                }
            };
            let wi = scatter(si.wo, si.n);
            let pred = specular_offsets(&si, si.n, eta_bsdf, &offs, wi, kind).unwrap();
            for (od, pd) in [(offs.rx_d, pred.rx_d), (offs.ry_d, pred.ry_d)] {
                let h = sphere_hit(r, &RayDifferential::plain(Ray::new(o, od, f32::INFINITY)));
                let truth = scatter(h.wo, h.n);
                let first_order = (truth - wi).length();
                assert!(first_order > 1e-3, "{kind:?}: the offset must turn the ray");
                assert!((pd - truth).length() < 0.05 * first_order, "{kind:?}: {pd} vs {truth} (change {first_order})");
            }
            // The offset origins are on the tangent plane, one footprint away.
            assert_eq!(pred.rx_o, si.p + si.diff.dpdx);
        }
        // Without curvature (a flat mirror) the reflected offsets are the mirror images.
        let flat = SurfaceInteraction { dndu: Vec3::ZERO, dndv: Vec3::ZERO, diff: Differentials::default(), ..si };
        let wi = reflect(flat.wo, flat.n);
        let pred = specular_offsets(&flat, flat.n, 1.0, &offs, wi, BxdfFlags::REFLECTION).unwrap();
        assert!((pred.rx_d - reflect(-offs.rx_d, flat.n)).length() < 1e-5);
    }
}
