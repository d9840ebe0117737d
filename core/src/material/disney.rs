//! `disney`: pbrt-v3's `DisneyMaterial` (`materials/disney.cpp`; Burley 2012, 2015) — its
//! parameters and defaults, and the lobes it builds: Fresnel-modified diffuse (or, `thin`, a
//! `flatness` blend of it with the fake-subsurface lobe, weighted by `1 − difftrans/2`),
//! retro-reflection, sheen, the anisotropic Trowbridge–Reitz specular with the separable
//! masking term and Disney's Fresnel, the GTR1 clearcoat, rough specular transmission (the
//! thin variant's roughness scaled by the index) and, `thin`, diffuse transmission. With a
//! non-black `scatterdistance` (and not `thin`) the diffuse lobe becomes a smooth dielectric
//! interface and the light under it a BSSRDF (Burley's profile), which `path` renders
//! ([`crate::bssrdf`]); every other integrator renders the interface alone, as pbrt-v3's do.

use super::{FloatParam, Lobes, SpectrumParam};
use crate::bssrdf::{Profile, SeparableBssrdf};
use crate::bxdf::{disney::schlick_r0_from_eta, Bsdf, Bxdf, DisneyLobe, Fresnel};
use crate::microfacet::MicrofacetDistribution;
use crate::spectrum::{Rgb, LUMINANCE_WEIGHTS};
use crate::texture::Textures;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

/// The parameters of pbrt-v3's `disney` (defaults in [`Disney::create`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Disney {
    pub color: SpectrumParam,
    pub metallic: FloatParam,
    pub eta: FloatParam,
    pub roughness: FloatParam,
    pub specular_tint: FloatParam,
    pub anisotropic: FloatParam,
    pub sheen: FloatParam,
    pub sheen_tint: FloatParam,
    pub clearcoat: FloatParam,
    pub clearcoat_gloss: FloatParam,
    pub spec_trans: FloatParam,
    pub scatter_distance: SpectrumParam,
    pub thin: bool,
    pub flatness: FloatParam,
    pub diff_trans: FloatParam,
    pub bump: Option<FloatParam>,
}

fn lerp(t: f32, a: Rgb, b: Rgb) -> Rgb {
    a * (1.0 - t) + b * t
}

impl Disney {
    /// pbrt-v3's `CreateDisneyMaterial`.
    pub fn create(tx: &mut Textures, p: &ParamSet, w: &DiagSink) -> Result<Disney, Diagnostic> {
        let mut f = |name: &str, default: f32| tx.get_float_param(p, name, default, w);
        Ok(Disney {
            metallic: f("metallic", 0.0)?,
            eta: f("eta", 1.5)?,
            roughness: f("roughness", 0.5)?,
            specular_tint: f("speculartint", 0.0)?,
            anisotropic: f("anisotropic", 0.0)?,
            sheen: f("sheen", 0.0)?,
            sheen_tint: f("sheentint", 0.5)?,
            clearcoat: f("clearcoat", 0.0)?,
            clearcoat_gloss: f("clearcoatgloss", 1.0)?,
            spec_trans: f("spectrans", 0.0)?,
            flatness: f("flatness", 0.0)?,
            diff_trans: f("difftrans", 1.0)?,
            color: tx.get_spectrum_param(p, "color", Rgb::splat(0.5), w)?,
            scatter_distance: tx.get_spectrum_param(p, "scatterdistance", Rgb::ZERO, w)?,
            thin: p.get_one_bool("thin", false),
            bump: tx.get_float_param_opt(p, "bumpmap", w)?,
        })
    }

    /// What the diffuse lobes and the BSSRDF share: the colour, the diffuse weight, the index.
    fn base(&self, l: &Lobes) -> (Rgb, f32, f32) {
        let c = l.s(self.color);
        let diffuse_weight = (1.0 - l.f(self.metallic)) * (1.0 - l.f(self.spec_trans));
        (c, diffuse_weight, l.f(self.eta))
    }

    /// pbrt-v3's `DisneyMaterial::ComputeScatteringFunctions` (the BSDF's own index is 1, as
    /// pbrt-v3's `BSDF(*si)`).
    pub(super) fn scatter(&self, l: &Lobes) -> Bsdf {
        let mut b = l.bsdf(1.0);
        let (c, diffuse_weight, e) = self.base(l);
        let metallic = l.f(self.metallic);
        let strans = l.f(self.spec_trans);
        let dt = l.f(self.diff_trans) / 2.0;
        let rough = l.f(self.roughness);
        let lum = c.dot(LUMINANCE_WEIGHTS);
        let c_tint = if lum > 0.0 { c / lum } else { Rgb::ONE };
        let sheen = l.f(self.sheen);
        let c_sheen = if sheen > 0.0 { lerp(l.f(self.sheen_tint), Rgb::ONE, c_tint) } else { Rgb::ZERO };
        let mut add = |x: Bxdf| {
            let _ = b.add(x);
        };
        if diffuse_weight > 0.0 {
            if self.thin {
                let flat = l.f(self.flatness);
                add(Bxdf::Disney(DisneyLobe::Diffuse { r: diffuse_weight * (1.0 - flat) * (1.0 - dt) * c }));
                add(Bxdf::Disney(DisneyLobe::FakeSubsurface {
                    r: diffuse_weight * flat * (1.0 - dt) * c,
                    roughness: rough,
                }));
            } else if l.s(self.scatter_distance) == Rgb::ZERO {
                add(Bxdf::Disney(DisneyLobe::Diffuse { r: diffuse_weight * c }));
            } else {
                // The light under the surface is the BSSRDF's (`Material::bssrdf`).
                add(Bxdf::specular_transmission(Rgb::ONE, 1.0, e, l.opts.mode));
            }
            add(Bxdf::Disney(DisneyLobe::Retro { r: diffuse_weight * c, roughness: rough }));
            if sheen > 0.0 {
                add(Bxdf::Disney(DisneyLobe::Sheen { r: diffuse_weight * sheen * c_sheen }));
            }
        }
        let aspect = (1.0 - l.f(self.anisotropic) * 0.9).sqrt();
        let alphas = |r: f32| ((r * r / aspect).max(0.001), (r * r * aspect).max(0.001));
        let (ax, ay) = alphas(rough);
        let distrib = MicrofacetDistribution::disney(ax, ay);
        let spec_tint = l.f(self.specular_tint);
        let c_spec0 = lerp(metallic, schlick_r0_from_eta(e) * lerp(spec_tint, Rgb::ONE, c_tint), c);
        let fresnel = Fresnel::Disney { r0: c_spec0, metallic, eta: e };
        add(Bxdf::microfacet_reflection(Rgb::ONE, distrib, fresnel));
        let cc = l.f(self.clearcoat);
        if cc > 0.0 {
            let g = l.f(self.clearcoat_gloss);
            add(Bxdf::Disney(DisneyLobe::Clearcoat { weight: Rgb::splat(cc), gloss: (1.0 - g) * 0.1 + g * 0.001 }));
        }
        if strans > 0.0 {
            let t = strans * c.max(Rgb::ZERO).powf(0.5);
            if self.thin {
                let (ax, ay) = alphas((0.65 * e - 0.35) * rough);
                let scaled = MicrofacetDistribution::trowbridge_reitz(ax, ay);
                add(Bxdf::microfacet_transmission(t, scaled, 1.0, e, l.opts.mode));
            } else {
                add(Bxdf::microfacet_transmission(t, distrib, 1.0, e, l.opts.mode));
            }
        }
        if self.thin {
            add(Bxdf::lambertian_transmission(dt * c));
        }
        b
    }

    /// The BSSRDF under a non-thin surface with a non-black `scatterdistance` (pbrt-v3's
    /// `DisneyBSSRDF`, whose scatter distance is scaled by 0.2).
    pub(super) fn bssrdf(
        &self,
        l: &Lobes,
        bsdf: &Bsdf,
        p: glam::Vec3,
        material: usize,
    ) -> Option<SeparableBssrdf<'static>> {
        if self.thin {
            return None;
        }
        let (c, diffuse_weight, e) = self.base(l);
        let sd = l.s(self.scatter_distance);
        if diffuse_weight <= 0.0 || sd == Rgb::ZERO {
            return None;
        }
        Some(SeparableBssrdf {
            p,
            ns: bsdf.shading_normal(),
            ss: bsdf.local_to_world(glam::Vec3::X),
            ts: bsdf.local_to_world(glam::Vec3::Y),
            eta: e,
            material,
            profile: Profile::Disney { r: c * diffuse_weight, d: 0.2 * sd },
        })
    }
}
