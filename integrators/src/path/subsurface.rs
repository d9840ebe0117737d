//! The BSSRDF step of pbrt-v3's `PathIntegrator::Li` (`integrators/path.cpp`, "Account for
//! subsurface scattering"): after a transmission lobe of a surface with a BSSRDF was sampled,
//! the path re-emerges at a point found by a probe segment ([`SeparableBssrdf::probe`]), is
//! weighted by `S_p / pdf`, lit there by one light sample through the exit lobe `S_w`, and
//! continues in a direction sampled from that lobe. Sampler dimensions as pbrt-v3: the probe
//! (1D, 2D), the light (1D, 2D, 2D), the continuation (2D).

use crate::common::direct::sample_one_light;
use crate::common::light_distribution::LightDistribution;
use penumbra_core::bssrdf::SeparableBssrdf;
use penumbra_core::bxdf::{Bsdf, Bxdf, BxdfFlags, TransportMode};
use penumbra_core::geometry::Ray;
use penumbra_core::integrator::ThreadStats;
use penumbra_core::interaction::{SurfaceInteraction, SHADOW_EPSILON};
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::Scene;
use penumbra_core::Rgb;

/// Most surfaces a probe segment collects (pbrt-v3 has no limit; a segment crossing more
/// surfaces of one material than this keeps the first ones).
const MAX_PROBE_HITS: usize = 64;

/// Where the path continues after the BSSRDF: the ray and whether its lobe was specular.
pub(super) struct Exit {
    pub ray: Ray,
    pub specular: bool,
}

/// The surfaces of the BSSRDF's material along the probe segment from `from` to `to`.
fn probe_hits(
    bssrdf: &SeparableBssrdf,
    from: glam::Vec3,
    to: glam::Vec3,
    scene: &Scene,
    stats: &mut ThreadStats,
) -> Vec<SurfaceInteraction> {
    let mut found = Vec::new();
    let mut ray = Ray::new(from, to - from, 1.0 - SHADOW_EPSILON);
    // Every surface on the segment is crossed (as pbrt-v3's chain, whose length is not bounded
    // either); the bound only guards against a degenerate segment that never advances.
    for _ in 0..4 * MAX_PROBE_HITS {
        if ray.d == glam::Vec3::ZERO {
            break;
        }
        stats.rays += 1;
        let Some(hit) = scene.intersect(&ray) else { break };
        let si = scene.interaction(&ray, &hit);
        if scene.objects.get(hit.mesh as usize).and_then(|o| o.material) == Some(bssrdf.material) {
            found.push(si);
            if found.len() == MAX_PROBE_HITS {
                break;
            }
        }
        ray = si.spawn_ray_to(to);
    }
    found
}

/// The step after the BSDF sampled a transmission at a surface with `bssrdf`: multiplies `beta`
/// by the probe's weight and the exit lobe's sample, adds the light at the exit point to `l`.
/// `None` ends the path (no surface found, or a zero weight), as pbrt-v3's `break`.
pub(super) fn exit(
    bssrdf: &SeparableBssrdf,
    scene: &Scene,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    lights: &LightDistribution,
    beta: &mut Rgb,
    l: &mut Rgb,
) -> Option<Exit> {
    let (u1, u2) = (sampler.get_1d(), sampler.get_2d());
    let probe = bssrdf.probe(u1, u2)?;
    let hits = probe_hits(bssrdf, probe.from, probe.to, scene, stats);
    if hits.is_empty() {
        return None;
    }
    let n = hits.len();
    let mut pi = hits[((probe.u * n as f32) as usize).min(n - 1)];
    let pdf = bssrdf.pdf_sp(pi.p, pi.n) / n as f32;
    let sp = bssrdf.sp(pi.p);
    if sp == Rgb::ZERO || !(pdf > 0.0) || !sp.is_finite() {
        return None;
    }
    *beta *= sp / pdf;
    // pbrt-v3's `SeparableBSSRDF::Sample_S`: the exit point's BSDF is the `S_w` lobe alone, in
    // its shading frame, seen from its shading normal.
    pi.wo = pi.shading.z;
    let mut bsdf = Bsdf::new(pi.shading.z, pi.shading.x, pi.n, 1.0);
    let _ = bsdf.add(Bxdf::SubsurfaceExit { eta: bssrdf.eta, mode: TransportMode::Radiance });
    let distribution = lights.lookup(pi.p, scene);
    *l += *beta * sample_one_light(&pi, &bsdf, scene, sampler, stats, Some(distribution));
    let s = bsdf.sample_f(pi.wo, sampler.get_2d(), BxdfFlags::ALL)?;
    if s.f == Rgb::ZERO || !(s.pdf > 0.0) {
        return None;
    }
    *beta *= s.f * (s.wi.dot(pi.shading.z).abs() / s.pdf);
    Some(Exit { ray: pi.spawn_ray(s.wi), specular: s.flags.contains(BxdfFlags::SPECULAR) })
}
