//! The lobes of pbrt-v3's Disney BSDF (`materials/disney.cpp`, after Burley 2012/2015) that
//! are not one of the generic lobes: the Fresnel-modified diffuse term, the Hanrahan–Krueger
//! "fake subsurface" of the thin variant, retro-reflection, sheen and the GTR1 clearcoat.
//! The specular lobe is [`Bxdf::MicrofacetReflection`](super::Bxdf) with
//! [`MicrofacetDistribution::DisneyTrowbridgeReitz`](crate::microfacet::MicrofacetDistribution)
//! and [`Fresnel::Disney`](super::Fresnel); the transmission lobes are the generic microfacet
//! and Lambertian ones. The diffuse family is sampled as pbrt-v3's `BxDF::Sample_f` does
//! (cosine-weighted on `wo`'s side), the clearcoat by its GTR1 distribution of half vectors.

use super::{cosine_sample_hemisphere, reflect, same_hemisphere, BxdfFlags};
use crate::spectrum::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// `(1 − cos θ)^5`, clamped (pbrt-v3's `SchlickWeight`).
#[inline]
pub fn schlick_weight(cos_theta: f32) -> f32 {
    let m = (1.0 - cos_theta).clamp(0.0, 1.0);
    (m * m) * (m * m) * m
}

/// Schlick's Fresnel approximation with normal-incidence reflectance `r0` (pbrt-v3's `FrSchlick`).
#[inline]
pub fn fr_schlick(r0: Rgb, cos_theta: f32) -> Rgb {
    let w = schlick_weight(cos_theta);
    r0 * (1.0 - w) + Rgb::splat(w)
}

/// Normal-incidence reflectance of a dielectric of index `eta` seen from air.
#[inline]
pub fn schlick_r0_from_eta(eta: f32) -> f32 {
    let s = (eta - 1.0) / (eta + 1.0);
    s * s
}

/// A Disney lobe (all but the clearcoat are diffuse reflection).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DisneyLobe {
    /// `R/π (1 − F_o/2)(1 − F_i/2)` (Burley 2015, eq. 4).
    Diffuse { r: Rgb },
    /// The thin surface's flattened diffuse (Hanrahan–Krueger), blended in by `flatness`.
    FakeSubsurface { r: Rgb, roughness: f32 },
    /// Retro-reflection, `R/π · R_R (F_o + F_i + F_o F_i (R_R − 1))`, `R_R = 2 roughness cos²θ_d`.
    Retro { r: Rgb, roughness: f32 },
    /// `R · SchlickWeight(cos θ_d)`.
    Sheen { r: Rgb },
    /// GTR1 clearcoat (index 1.5, masking with α = 0.25). `weight` is pbrt-v3's scalar
    /// `clearcoat`, an RGB here so that `mix` can scale the lobe exactly.
    Clearcoat { weight: Rgb, gloss: f32 },
}

/// The half vector of a pair of directions and `cos θ_d = wi·wh` (`None` when they cancel).
#[inline]
fn half(wo: Vec3, wi: Vec3) -> Option<(Vec3, f32)> {
    let wh = wi + wo;
    if wh == Vec3::ZERO {
        return None;
    }
    let wh = wh.normalize();
    Some((wh, wi.dot(wh)))
}

/// GTR1 (Berry) distribution of half vectors with parameter `alpha`.
#[inline]
fn gtr1(cos_theta: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos_theta * cos_theta))
}

/// Disney's Smith masking term for GGX as written in the BRDF explorer (it includes the
/// `1/(2 cos θ)` of the microfacet denominator).
#[inline]
fn smith_g_ggx(cos_theta: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_theta * cos_theta;
    1.0 / (cos_theta + (a2 + c2 - a2 * c2).sqrt())
}

impl DisneyLobe {
    pub fn flags(&self) -> BxdfFlags {
        match self {
            DisneyLobe::Clearcoat { .. } => BxdfFlags::REFLECTION | BxdfFlags::GLOSSY,
            _ => BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE,
        }
    }

    /// The lobe's value. Like pbrt-v3's Disney lobes it does not test the hemispheres itself:
    /// [`Bsdf`](super::Bsdf) counts reflection lobes only for directions on one side.
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let (ao, ai) = (wo.z.abs(), wi.z.abs());
        match *self {
            DisneyLobe::Diffuse { r } => {
                let (fo, fi) = (schlick_weight(ao), schlick_weight(ai));
                r * FRAC_1_PI * (1.0 - fo / 2.0) * (1.0 - fi / 2.0)
            }
            DisneyLobe::FakeSubsurface { r, roughness } => {
                let Some((_, cos_d)) = half(wo, wi) else { return Rgb::ZERO };
                let fss90 = cos_d * cos_d * roughness;
                let (fo, fi) = (schlick_weight(ao), schlick_weight(ai));
                let lerp = |t: f32| (1.0 - t) + t * fss90;
                let fss = lerp(fo) * lerp(fi);
                let ss = 1.25 * (fss * (1.0 / (ao + ai) - 0.5) + 0.5);
                r * FRAC_1_PI * ss
            }
            DisneyLobe::Retro { r, roughness } => {
                let Some((_, cos_d)) = half(wo, wi) else { return Rgb::ZERO };
                let (fo, fi) = (schlick_weight(ao), schlick_weight(ai));
                let rr = 2.0 * roughness * cos_d * cos_d;
                r * FRAC_1_PI * rr * (fo + fi + fo * fi * (rr - 1.0))
            }
            DisneyLobe::Sheen { r } => {
                let Some((_, cos_d)) = half(wo, wi) else { return Rgb::ZERO };
                r * schlick_weight(cos_d)
            }
            DisneyLobe::Clearcoat { weight, gloss } => {
                let Some((wh, _)) = half(wo, wi) else { return Rgb::ZERO };
                let dr = gtr1(wh.z.abs(), gloss);
                let fr = fr_schlick(Rgb::splat(0.04), wo.dot(wh)).x;
                let gr = smith_g_ggx(ao, 0.25) * smith_g_ggx(ai, 0.25);
                weight * (gr * fr * dr / 4.0)
            }
        }
    }

    /// Density of [`Self::sample_f`]'s direction.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !same_hemisphere(wo, wi) {
            return 0.0;
        }
        match *self {
            DisneyLobe::Clearcoat { gloss, .. } => {
                let Some((wh, _)) = half(wo, wi) else { return 0.0 };
                gtr1(wh.z.abs(), gloss) * wh.z.abs() / (4.0 * wo.dot(wh))
            }
            _ => wi.z.abs() * FRAC_1_PI,
        }
    }

    /// A direction for `wo` (its value and density are the caller's to evaluate): cosine-weighted
    /// on `wo`'s side, or the clearcoat's GTR1 half vector reflected.
    pub fn sample_wi(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        match *self {
            DisneyLobe::Clearcoat { gloss, .. } => {
                if wo.z == 0.0 {
                    return None;
                }
                // pbrt-v3's inversion of GTR1's CDF, written for sin²θ (pbrt-v3 takes
                // 1 − cos², which at gloss 1, α = 0.001, loses the angles near the peak).
                let a2 = gloss * gloss;
                let sin2 = ((a2.powf(1.0 - u.x) - a2) / (1.0 - a2)).clamp(0.0, 1.0);
                let sin2 = if sin2.is_finite() { sin2 } else { 1.0 };
                let (sin_theta, cos_theta) = (sin2.sqrt(), (1.0 - sin2).sqrt());
                let phi = 2.0 * PI * u.y;
                let mut wh = Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
                if !same_hemisphere(wo, wh) {
                    wh = -wh;
                }
                let wi = reflect(wo, wh);
                same_hemisphere(wo, wi).then_some(wi)
            }
            _ => {
                let mut wi = cosine_sample_hemisphere(u);
                if wo.z < 0.0 {
                    wi.z = -wi.z;
                }
                Some(wi)
            }
        }
    }

    /// The lobe with its colour (or the clearcoat's weight) multiplied by `s`.
    pub fn scaled(self, s: Rgb) -> Self {
        match self {
            DisneyLobe::Diffuse { r } => DisneyLobe::Diffuse { r: r * s },
            DisneyLobe::FakeSubsurface { r, roughness } => DisneyLobe::FakeSubsurface { r: r * s, roughness },
            DisneyLobe::Retro { r, roughness } => DisneyLobe::Retro { r: r * s, roughness },
            DisneyLobe::Sheen { r } => DisneyLobe::Sheen { r: r * s },
            DisneyLobe::Clearcoat { weight, gloss } => DisneyLobe::Clearcoat { weight: weight * s, gloss },
        }
    }
}
