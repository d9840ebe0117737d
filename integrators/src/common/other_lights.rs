//! The lights an analytic area-light integrator (`ltc`, `ratio`) does not shade itself:
//! delta lights with one shadow ray, infinite lights and the area lights of materials
//! without an LTC form with directlighting's estimator ([`crate::common::direct`]). A purely
//! specular surface (mirror, smooth glass) receives nothing from any light directly: what it
//! shows comes through its specular chain, which the integrators follow themselves.

use crate::common::direct::{estimate_direct, estimate_direct_with};
use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::integrator::ThreadStats;
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::{Light, LightContext};
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Scene, SurfaceHit};
use penumbra_core::{Rgb, Vec2};
use penumbra_parser::DiagSink;
use std::collections::HashSet;
use std::sync::Mutex;

/// The warnings an integrator gives when a material's lobes fall back to directlighting's
/// estimator: one per material type (`"disney"`, `"translucent"`…), naming it.
pub struct FallbackWarning<'a> {
    pub integrator: &'static str,
    warned: Mutex<HashSet<&'static str>>,
    pub warnings: &'a DiagSink,
    /// No per-material warning: the integrator has already said every light falls back.
    pub silent: bool,
}

impl<'a> FallbackWarning<'a> {
    pub fn new(integrator: &'static str, warnings: &'a DiagSink) -> FallbackWarning<'a> {
        FallbackWarning { integrator, warned: Mutex::new(HashSet::new()), warnings, silent: false }
    }

    /// Warns, once per material type, that `material`'s lobes described by `lobes` are lit by
    /// directlighting's estimator `under` the lights it names.
    pub fn material(&self, material: &'static str, lobes: &str, under: &str) {
        if self.silent {
            return;
        }
        let first = self.warned.lock().map(|mut w| w.insert(material)).unwrap_or(false);
        if first {
            self.warnings.warn(
                None,
                format!(
                    "{}: material \"{material}\" ({lobes}) is lit by directlighting's estimator under {under} \
                     (its perfectly specular lobes are followed up to maxdepth)",
                    self.integrator
                ),
            );
        }
    }

    fn no_ltc_form(&self, scene: &Scene, hit: &SurfaceHit) {
        let name = scene.material_of(&hit.si).map_or("none", |(m, _, _)| m.type_name());
        self.material(name, "no Lambertian-plus-GGX form", "area lights");
    }
}

/// What the analytic shading covered of a point's area lights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coverage {
    /// Nothing: the material has no LTC form.
    None,
    /// The reflection: the material also transmits (translucent), and the transmission lobes
    /// take the area lights by directlighting's estimator.
    Reflection,
    /// All of it.
    Area,
}

impl Coverage {
    /// From whether the material has an LTC form and whether that form leaves transmission out.
    pub fn of(ltc_form: bool, transmits: bool) -> Coverage {
        match (ltc_form, transmits) {
            (false, _) => Coverage::None,
            (true, true) => Coverage::Reflection,
            (true, false) => Coverage::Area,
        }
    }
}

/// Adds to `l` every light `ltc` and `ratio` do not shade analytically, at `hit`: delta lights
/// by [`delta_light`]; infinite lights, and area lights when the material has no LTC form
/// (`Coverage::None`, with one warning), by directlighting's estimator (two 2D samples each);
/// with `Coverage::Reflection`, the area lights through the transmission lobes only, by the
/// same estimator restricted to them. Nothing (no sample, no warning) when the BSDF has no
/// lobe but perfectly specular ones: no light sample could reach it.
pub fn add_other_lights(
    l: &mut Rgb,
    hit: &SurfaceHit,
    coverage: Coverage,
    scene: &Scene,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    warning: &FallbackWarning,
) {
    let SurfaceHit { si, bsdf, .. } = hit;
    if bsdf.num_components(BxdfFlags::NON_SPECULAR) == 0 {
        return;
    }
    let transmission = BxdfFlags::TRANSMISSION | BxdfFlags::DIFFUSE | BxdfFlags::GLOSSY;
    for (k, light) in scene.light_list().iter().enumerate() {
        match (light, coverage) {
            (Light::Area(_), Coverage::Area) => {} // shaded analytically
            (Light::Area(_), Coverage::Reflection) => {
                let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                *l += estimate_direct_with(si, bsdf, transmission, u_scatter, k, light, u_light, scene, stats);
            }
            (Light::Infinite(_) | Light::Area(_), _) => {
                if coverage == Coverage::None && matches!(light, Light::Area(_)) {
                    warning.no_ltc_form(scene, hit);
                }
                let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                *l += estimate_direct(si, bsdf, u_scatter, k, light, u_light, scene, stats);
            }
            _ => *l += delta_light(si, bsdf, light, scene, stats),
        }
    }
}

/// The one warning `integrator` gives when the scene has infinite lights (they have no polygon).
pub fn warn_infinite_lights(integrator: &str, scene: &Scene, warnings: &DiagSink) {
    if scene.light_list().iter().any(Light::is_infinite) {
        warnings.warn(
            None,
            format!("{integrator}: infinite lights have no polygon: they are rendered with directlighting's estimator"),
        );
    }
}

/// A delta light (point, spot, distant, goniometric, projection) at `si`: exact hard shadow by one
/// ray, the real BSDF.
fn delta_light(si: &SurfaceInteraction, bsdf: &Bsdf, light: &Light, scene: &Scene, stats: &mut ThreadStats) -> Rgb {
    let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
    let Some(ls) = light.sample_li(&ctx, Vec2::splat(0.5), &scene.meshes) else { return Rgb::ZERO };
    let f = bsdf.f(si.wo, ls.wi, BxdfFlags::NON_SPECULAR) * ls.wi.dot(si.shading.z).abs();
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    stats.shadow_rays += 1;
    if scene.occluded(&si.spawn_ray_to(ls.p_light)) {
        Rgb::ZERO
    } else {
        f * ls.li / ls.pdf
    }
}
