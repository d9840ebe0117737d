//! Reflection models with pbrt-v3's semantics: Fresnel terms, the BxDF lobes
//! (in the local shading frame, z = shading normal) and the [`Bsdf`] that holds
//! up to [`MAX_BXDFS`] lobes and works in world space.
//!
//! Lobes are an enum ([`Bxdf`]), not trait objects. Every evaluation is guarded
//! so that degenerate directions (grazing, zero cosines, tiny alphas) give 0
//! instead of NaN or infinity; elsewhere the values are pbrt-v3's.

use crate::microfacet::{cos_phi, sin_phi, sin_theta, MicrofacetDistribution};
use crate::profiling::Phase;
use crate::spectrum::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};
use std::ops::BitOr;

pub mod disney;
pub mod fourier;
pub mod hair;

pub use disney::DisneyLobe;
pub use fourier::{FourierBxdf, FourierTable};
pub use hair::HairBxdf;

/// The largest f32 below 1 (pbrt-v3's `OneMinusEpsilon`).
pub const ONE_MINUS_EPSILON: f32 = 0.999_999_94;

/// Most lobes a [`Bsdf`] holds (pbrt-v3's `MaxBxDFs`).
pub const MAX_BXDFS: usize = 8;

/// pbrt-v3's `BxDFType` bit set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BxdfFlags(pub u8);

impl BxdfFlags {
    pub const NONE: BxdfFlags = BxdfFlags(0);
    pub const REFLECTION: BxdfFlags = BxdfFlags(1);
    pub const TRANSMISSION: BxdfFlags = BxdfFlags(2);
    pub const DIFFUSE: BxdfFlags = BxdfFlags(4);
    pub const GLOSSY: BxdfFlags = BxdfFlags(8);
    pub const SPECULAR: BxdfFlags = BxdfFlags(16);
    pub const ALL: BxdfFlags = BxdfFlags(31);
    /// pbrt-v3's `BSDF_ALL & ~BSDF_SPECULAR`.
    pub const NON_SPECULAR: BxdfFlags = BxdfFlags(15);

    /// All bits of `other` are set in `self`.
    pub const fn contains(self, other: BxdfFlags) -> bool {
        self.0 & other.0 == other.0
    }
    /// Some bit of `other` is set in `self`.
    pub const fn intersects(self, other: BxdfFlags) -> bool {
        self.0 & other.0 != 0
    }
    pub const fn is_specular(self) -> bool {
        self.intersects(BxdfFlags::SPECULAR)
    }
}

impl BitOr for BxdfFlags {
    type Output = BxdfFlags;
    fn bitor(self, rhs: BxdfFlags) -> BxdfFlags {
        BxdfFlags(self.0 | rhs.0)
    }
}

/// Whether radiance or importance is transported (affects the η² scaling of transmission).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TransportMode {
    #[default]
    Radiance,
    Importance,
}

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Incident direction (local frame for a [`Bxdf`], world space for a [`Bsdf`]).
    pub wi: Vec3,
    /// BSDF value for (wo, wi); for specular lobes, the Dirac lobe's weight over |cos θi|.
    pub f: Rgb,
    /// Density of `wi` (solid angle); for specular lobes, the discrete probability.
    pub pdf: f32,
    /// Flags of the lobe that was sampled.
    pub flags: BxdfFlags,
}

/// A [`Bsdf`] is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BsdfError {
    #[error("a BSDF holds at most {MAX_BXDFS} lobes")]
    TooManyLobes,
}

// --- helpers ----------------------------------------------------------------------------------

#[inline]
fn finite_or_zero(v: Rgb) -> Rgb {
    if v.is_finite() {
        v
    } else {
        Rgb::ZERO
    }
}

#[inline]
fn finite_pdf(p: f32) -> f32 {
    if p.is_finite() && p > 0.0 {
        p
    } else {
        0.0
    }
}

#[inline]
fn sqrt3(v: Rgb) -> Rgb {
    Rgb::new(v.x.max(0.0).sqrt(), v.y.max(0.0).sqrt(), v.z.max(0.0).sqrt())
}

/// Both directions on the same side of the z = 0 plane (strictly).
#[inline]
pub fn same_hemisphere(w: Vec3, wp: Vec3) -> bool {
    w.z * wp.z > 0.0
}

/// Mirror `wo` about `n`.
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + 2.0 * wo.dot(n) * n
}

/// Refract `wi` through a surface with normal `n` (on `wi`'s side) and relative
/// index `eta = eta_i / eta_t`; `None` on total internal reflection.
#[inline]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = n.dot(wi);
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = eta * eta * sin2_i;
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(eta * -wi + (eta * cos_i - cos_t) * n)
}

pub use crate::sampling::{concentric_sample_disk, cosine_sample_hemisphere};

/// Unpolarised Fresnel reflectance of a dielectric interface (pbrt-v3's `FrDielectric`):
/// `cos_i` is signed; a negative value means the ray arrives from the `eta_t` side.
pub fn fr_dielectric(cos_i: f32, eta_i: f32, eta_t: f32) -> f32 {
    let mut cos_i = cos_i.clamp(-1.0, 1.0);
    let (mut ei, mut et) = (eta_i, eta_t);
    if cos_i <= 0.0 {
        std::mem::swap(&mut ei, &mut et);
        cos_i = cos_i.abs();
    }
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    let sin_t = ei / et * sin_i;
    if sin_t >= 1.0 || sin_t.is_nan() {
        // Total internal reflection (or a degenerate index).
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
    let r_parl = (et * cos_i - ei * cos_t) / (et * cos_i + ei * cos_t);
    let r_perp = (ei * cos_i - et * cos_t) / (ei * cos_i + et * cos_t);
    let r = (r_parl * r_parl + r_perp * r_perp) / 2.0;
    if r.is_finite() {
        r
    } else {
        1.0
    }
}

/// Fresnel reflectance of a conductor with complex index `eta_t + i k` under a
/// dielectric with index `eta_i` (pbrt-v3's `FrConductor`).
pub fn fr_conductor(cos_i: f32, eta_i: Rgb, eta_t: Rgb, k: Rgb) -> Rgb {
    let cos_i = cos_i.clamp(-1.0, 1.0);
    let eta = eta_t / eta_i;
    let etak = k / eta_i;
    let cos2 = cos_i * cos_i;
    let sin2 = 1.0 - cos2;
    let eta2 = eta * eta;
    let etak2 = etak * etak;
    let t0 = eta2 - etak2 - Rgb::splat(sin2);
    let a2b2 = sqrt3(t0 * t0 + 4.0 * eta2 * etak2);
    let t1 = a2b2 + Rgb::splat(cos2);
    let a = sqrt3(0.5 * (a2b2 + t0));
    let t2 = 2.0 * cos_i * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = cos2 * a2b2 + Rgb::splat(sin2 * sin2);
    let t4 = t2 * sin2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    let r = 0.5 * (rp + rs);
    if r.is_finite() {
        r
    } else {
        Rgb::ONE
    }
}

/// A Fresnel term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fresnel {
    /// Always 1 (pbrt-v3's `FresnelNoOp`, used by `mirror`).
    NoOp,
    Dielectric {
        eta_i: f32,
        eta_t: f32,
    },
    Conductor {
        eta_i: Rgb,
        eta_t: Rgb,
        k: Rgb,
    },
    /// `disney`'s specular Fresnel (pbrt-v3's `DisneyFresnel`): the dielectric term of index
    /// `eta` blended by `metallic` into Schlick's with normal-incidence reflectance `r0`.
    Disney {
        r0: Rgb,
        metallic: f32,
        eta: f32,
    },
}

impl Fresnel {
    /// Fraction of light reflected for the (signed) cosine of the incident angle.
    pub fn evaluate(&self, cos_i: f32) -> Rgb {
        match *self {
            Fresnel::NoOp => Rgb::ONE,
            Fresnel::Dielectric { eta_i, eta_t } => Rgb::splat(fr_dielectric(cos_i, eta_i, eta_t)),
            Fresnel::Conductor { eta_i, eta_t, k } => fr_conductor(cos_i.abs(), eta_i, eta_t, k),
            Fresnel::Disney { r0, metallic, eta } => {
                Rgb::splat(fr_dielectric(cos_i, 1.0, eta)) * (1.0 - metallic) + disney::fr_schlick(r0, cos_i) * metallic
            }
        }
    }
}

/// One scattering lobe, in the local shading frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bxdf {
    LambertianReflection {
        r: Rgb,
    },
    LambertianTransmission {
        t: Rgb,
    },
    /// Oren–Nayar with precomputed `a`, `b` (see [`Bxdf::oren_nayar`]).
    OrenNayar {
        r: Rgb,
        a: f32,
        b: f32,
    },
    SpecularReflection {
        r: Rgb,
        fresnel: Fresnel,
    },
    SpecularTransmission {
        t: Rgb,
        eta_a: f32,
        eta_b: f32,
        mode: TransportMode,
    },
    /// Specular reflection and transmission chosen by the dielectric Fresnel term.
    FresnelSpecular {
        r: Rgb,
        t: Rgb,
        eta_a: f32,
        eta_b: f32,
        mode: TransportMode,
    },
    MicrofacetReflection {
        r: Rgb,
        distribution: MicrofacetDistribution,
        fresnel: Fresnel,
    },
    MicrofacetTransmission {
        t: Rgb,
        distribution: MicrofacetDistribution,
        eta_a: f32,
        eta_b: f32,
        mode: TransportMode,
    },
    /// Ashikhmin–Shirley diffuse + glossy coating (pbrt-v3's `FresnelBlend`, used by `substrate`).
    FresnelBlend {
        rd: Rgb,
        rs: Rgb,
        distribution: MicrofacetDistribution,
    },
    /// The diffuse, retro-reflection, sheen and clearcoat lobes of `disney` ([`disney`]).
    Disney(DisneyLobe),
    /// `hair`'s fibre scattering ([`hair`]).
    Hair(HairBxdf),
    /// `fourier`'s tabulated BSDF ([`fourier`]).
    Fourier(FourierBxdf),
    /// Where a BSSRDF's light leaves the surface (pbrt-v3's `SeparableBSSRDFAdapter`): the
    /// directional term `Sw` of a separable BSSRDF of relative index `eta` ([`crate::bssrdf`]).
    SubsurfaceExit {
        eta: f32,
        mode: TransportMode,
    },
}

impl Bxdf {
    pub fn lambertian_reflection(r: Rgb) -> Self {
        Bxdf::LambertianReflection { r }
    }
    pub fn lambertian_transmission(t: Rgb) -> Self {
        Bxdf::LambertianTransmission { t }
    }
    /// Oren–Nayar with surface roughness `sigma_degrees` (standard deviation of facet angles, degrees).
    pub fn oren_nayar(r: Rgb, sigma_degrees: f32) -> Self {
        let s = sigma_degrees.to_radians();
        let s2 = if s.is_finite() { s * s } else { 0.0 };
        Bxdf::OrenNayar { r, a: 1.0 - s2 / (2.0 * (s2 + 0.33)), b: 0.45 * s2 / (s2 + 0.09) }
    }
    pub fn specular_reflection(r: Rgb, fresnel: Fresnel) -> Self {
        Bxdf::SpecularReflection { r, fresnel }
    }
    /// `eta_a` is the index above the surface (z > 0), `eta_b` below.
    pub fn specular_transmission(t: Rgb, eta_a: f32, eta_b: f32, mode: TransportMode) -> Self {
        Bxdf::SpecularTransmission { t, eta_a, eta_b, mode }
    }
    pub fn fresnel_specular(r: Rgb, t: Rgb, eta_a: f32, eta_b: f32, mode: TransportMode) -> Self {
        Bxdf::FresnelSpecular { r, t, eta_a, eta_b, mode }
    }
    pub fn microfacet_reflection(r: Rgb, distribution: MicrofacetDistribution, fresnel: Fresnel) -> Self {
        Bxdf::MicrofacetReflection { r, distribution, fresnel }
    }
    pub fn microfacet_transmission(
        t: Rgb,
        distribution: MicrofacetDistribution,
        eta_a: f32,
        eta_b: f32,
        mode: TransportMode,
    ) -> Self {
        Bxdf::MicrofacetTransmission { t, distribution, eta_a, eta_b, mode }
    }
    pub fn fresnel_blend(rd: Rgb, rs: Rgb, distribution: MicrofacetDistribution) -> Self {
        Bxdf::FresnelBlend { rd, rs, distribution }
    }

    /// The lobe's type.
    pub fn flags(&self) -> BxdfFlags {
        use BxdfFlags as F;
        match self {
            Bxdf::LambertianReflection { .. } | Bxdf::OrenNayar { .. } => F::REFLECTION | F::DIFFUSE,
            Bxdf::LambertianTransmission { .. } => F::TRANSMISSION | F::DIFFUSE,
            Bxdf::SpecularReflection { .. } => F::REFLECTION | F::SPECULAR,
            Bxdf::SpecularTransmission { .. } => F::TRANSMISSION | F::SPECULAR,
            Bxdf::FresnelSpecular { .. } => F::REFLECTION | F::TRANSMISSION | F::SPECULAR,
            Bxdf::MicrofacetReflection { .. } | Bxdf::FresnelBlend { .. } => F::REFLECTION | F::GLOSSY,
            Bxdf::MicrofacetTransmission { .. } => F::TRANSMISSION | F::GLOSSY,
            Bxdf::Disney(l) => l.flags(),
            Bxdf::Hair(h) => h.flags(),
            Bxdf::Fourier(b) => b.flags(),
            Bxdf::SubsurfaceExit { .. } => F::REFLECTION | F::DIFFUSE,
        }
    }

    /// pbrt-v3's `MatchesFlags`: every bit of the lobe's type is in `flags`.
    pub fn matches(&self, flags: BxdfFlags) -> bool {
        flags.contains(self.flags())
    }

    /// BSDF value for the pair of directions (0 for specular lobes).
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        finite_or_zero(self.f_raw(wo, wi))
    }

    fn f_raw(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match *self {
            Bxdf::LambertianReflection { r } => r * FRAC_1_PI,
            Bxdf::LambertianTransmission { t } => t * FRAC_1_PI,
            Bxdf::OrenNayar { r, a, b } => {
                let sin_i = sin_theta(wi);
                let sin_o = sin_theta(wo);
                let mut max_cos = 0.0f32;
                if sin_i > 1e-4 && sin_o > 1e-4 {
                    let d_cos = cos_phi(wi) * cos_phi(wo) + sin_phi(wi) * sin_phi(wo);
                    max_cos = d_cos.max(0.0);
                }
                let (sin_alpha, tan_beta) =
                    if wi.z.abs() > wo.z.abs() { (sin_o, sin_i / wi.z.abs()) } else { (sin_i, sin_o / wo.z.abs()) };
                let term = if max_cos > 0.0 { b * max_cos * sin_alpha * tan_beta } else { 0.0 };
                r * FRAC_1_PI * (a + term)
            }
            Bxdf::SpecularReflection { .. } | Bxdf::SpecularTransmission { .. } | Bxdf::FresnelSpecular { .. } => {
                Rgb::ZERO
            }
            Bxdf::MicrofacetReflection { r, distribution, fresnel } => {
                let (cos_o, cos_i) = (wo.z.abs(), wi.z.abs());
                let wh = wi + wo;
                if cos_i == 0.0 || cos_o == 0.0 || wh == Vec3::ZERO {
                    return Rgb::ZERO;
                }
                let wh = wh.normalize();
                let f = fresnel.evaluate(wi.dot(toward_normal(wh)));
                r * distribution.d(wh) * distribution.g(wo, wi) * f / (4.0 * cos_i * cos_o)
            }
            Bxdf::MicrofacetTransmission { t, distribution, eta_a, eta_b, mode } => {
                if same_hemisphere(wo, wi) {
                    return Rgb::ZERO;
                }
                let (cos_o, cos_i) = (wo.z, wi.z);
                if cos_i == 0.0 || cos_o == 0.0 {
                    return Rgb::ZERO;
                }
                let eta = if cos_o > 0.0 { eta_b / eta_a } else { eta_a / eta_b };
                let mut wh = (wo + wi * eta).normalize();
                if !wh.is_finite() {
                    return Rgb::ZERO;
                }
                if wh.z < 0.0 {
                    wh = -wh;
                }
                // Both directions on the same side of the microfacet: no refraction.
                if wo.dot(wh) * wi.dot(wh) > 0.0 {
                    return Rgb::ZERO;
                }
                let f = Fresnel::Dielectric { eta_i: eta_a, eta_t: eta_b }.evaluate(wo.dot(wh));
                let sqrt_denom = wo.dot(wh) + eta * wi.dot(wh);
                let factor = if mode == TransportMode::Radiance { 1.0 / eta } else { 1.0 };
                let v = distribution.d(wh)
                    * distribution.g(wo, wi)
                    * eta
                    * eta
                    * wi.dot(wh).abs()
                    * wo.dot(wh).abs()
                    * factor
                    * factor
                    / (cos_i * cos_o * sqrt_denom * sqrt_denom);
                (Rgb::ONE - f) * t * v.abs()
            }
            Bxdf::FresnelBlend { rd, rs, distribution } => {
                let pow5 = |v: f32| (v * v) * (v * v) * v;
                let diffuse = (28.0 / (23.0 * PI))
                    * rd
                    * (Rgb::ONE - rs)
                    * (1.0 - pow5(1.0 - 0.5 * wi.z.abs()))
                    * (1.0 - pow5(1.0 - 0.5 * wo.z.abs()));
                let wh = wi + wo;
                if wh == Vec3::ZERO {
                    return Rgb::ZERO;
                }
                let wh = wh.normalize();
                let schlick = rs + pow5(1.0 - wi.dot(wh)) * (Rgb::ONE - rs);
                let specular = distribution.d(wh) / (4.0 * wi.dot(wh).abs() * wi.z.abs().max(wo.z.abs())) * schlick;
                diffuse + finite_or_zero(specular)
            }
            Bxdf::Disney(l) => l.f(wo, wi),
            Bxdf::Hair(h) => h.f(wo, wi),
            Bxdf::Fourier(b) => b.f(wo, wi),
            Bxdf::SubsurfaceExit { eta, mode } => {
                let f = crate::bssrdf::sw(wi.z, eta);
                Rgb::splat(if mode == TransportMode::Radiance { f * eta * eta } else { f })
            }
        }
    }

    /// `(self.f(wo, wi), self.pdf(wo, wi))`, bit for bit, sharing the work the two have in
    /// common (half vector, distribution and masking terms).
    pub fn f_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        match *self {
            Bxdf::MicrofacetReflection { r, distribution, fresnel } => {
                let (cos_o, cos_i) = (wo.z.abs(), wi.z.abs());
                let sum = wi + wo;
                let has_f = !(cos_i == 0.0 || cos_o == 0.0 || sum == Vec3::ZERO);
                let has_pdf = same_hemisphere(wo, wi);
                if !has_f && !has_pdf {
                    return (Rgb::ZERO, 0.0);
                }
                // `(wo + wi).normalize()` in `pdf` is the same vector (addition commutes exactly).
                let wh = sum.normalize();
                let d = distribution.d(wh);
                let lambda_o = distribution.lambda(wo);
                let f = if has_f {
                    let g = distribution.g_of_lambdas(lambda_o, distribution.lambda(wi));
                    let fr = fresnel.evaluate(wi.dot(toward_normal(wh)));
                    finite_or_zero(r * d * g * fr / (4.0 * cos_i * cos_o))
                } else {
                    Rgb::ZERO
                };
                let pdf = if has_pdf {
                    let pdf_wh = if wo.z == 0.0 {
                        0.0
                    } else {
                        let g1 = 1.0 / (1.0 + lambda_o);
                        let p = d * g1 * wo.dot(wh).abs() / wo.z.abs();
                        if p.is_finite() {
                            p
                        } else {
                            0.0
                        }
                    };
                    finite_pdf(pdf_wh / (4.0 * wo.dot(wh)))
                } else {
                    0.0
                };
                (f, pdf)
            }
            _ => (self.f(wo, wi), self.pdf(wo, wi)),
        }
    }

    /// Density with which [`sample_f`](Self::sample_f) returns `wi` (0 for specular lobes).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        finite_pdf(self.pdf_raw(wo, wi))
    }

    fn pdf_raw(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Bxdf::LambertianReflection { .. } | Bxdf::OrenNayar { .. } | Bxdf::SubsurfaceExit { .. } => {
                if same_hemisphere(wo, wi) {
                    wi.z.abs() * FRAC_1_PI
                } else {
                    0.0
                }
            }
            Bxdf::LambertianTransmission { .. } => {
                if !same_hemisphere(wo, wi) {
                    wi.z.abs() * FRAC_1_PI
                } else {
                    0.0
                }
            }
            Bxdf::SpecularReflection { .. } | Bxdf::SpecularTransmission { .. } | Bxdf::FresnelSpecular { .. } => 0.0,
            Bxdf::MicrofacetReflection { distribution, .. } => {
                if !same_hemisphere(wo, wi) {
                    return 0.0;
                }
                let wh = (wo + wi).normalize();
                distribution.pdf(wo, wh) / (4.0 * wo.dot(wh))
            }
            Bxdf::MicrofacetTransmission { distribution, eta_a, eta_b, .. } => {
                if same_hemisphere(wo, wi) || wo.z == 0.0 {
                    return 0.0;
                }
                let eta = if wo.z > 0.0 { eta_b / eta_a } else { eta_a / eta_b };
                let mut wh = (wo + wi * eta).normalize();
                if !wh.is_finite() {
                    return 0.0;
                }
                // Orient the microfacet normal to wo's side, as `sample_wh` produces it, and
                // give back-facing microfacets zero density: they are never sampled. (pbrt-v3
                // only rejects `(wo·wh)(wi·wh) > 0` here and so counts them; its pdf then
                // integrates to more than 1. `f` keeps pbrt-v3's definition.)
                if wh.z * wo.z < 0.0 {
                    wh = -wh;
                }
                if wo.dot(wh) <= 0.0 || wi.dot(wh) >= 0.0 {
                    return 0.0;
                }
                let sqrt_denom = wo.dot(wh) + eta * wi.dot(wh);
                let dwh_dwi = ((eta * eta * wi.dot(wh)) / (sqrt_denom * sqrt_denom)).abs();
                distribution.pdf(wo, wh) * dwh_dwi
            }
            Bxdf::FresnelBlend { distribution, .. } => {
                if !same_hemisphere(wo, wi) {
                    return 0.0;
                }
                let wh = (wo + wi).normalize();
                let pdf_wh = distribution.pdf(wo, wh);
                0.5 * (wi.z.abs() * FRAC_1_PI + finite_pdf(pdf_wh / (4.0 * wo.dot(wh))))
            }
            Bxdf::Disney(l) => l.pdf(wo, wi),
            Bxdf::Hair(h) => h.pdf(wo, wi),
            Bxdf::Fourier(b) => b.pdf(wo, wi),
        }
    }

    /// Sample an incident direction for `wo` with the 2D sample `u` ∈ [0,1)².
    /// `None` when no direction results (pbrt-v3 returns a zero pdf then).
    pub fn sample_f(&self, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
        if !wo.is_finite() {
            return None;
        }
        let u = Vec2::new(clamp_u(u.x), clamp_u(u.y));
        let flags = self.flags();
        let lobe = |wi: Vec3| -> Option<BsdfSample> {
            let (f, pdf) = self.f_pdf(wo, wi);
            if pdf > 0.0 && wi.is_finite() {
                Some(BsdfSample { wi, f, pdf, flags })
            } else {
                None
            }
        };
        let specular = |wi: Vec3, f: Rgb, pdf: f32, flags: BxdfFlags| -> Option<BsdfSample> {
            let f = finite_or_zero(f);
            if pdf > 0.0 && wi.is_finite() && wi.z != 0.0 {
                Some(BsdfSample { wi, f, pdf, flags })
            } else {
                None
            }
        };
        match *self {
            Bxdf::LambertianReflection { .. } | Bxdf::OrenNayar { .. } | Bxdf::SubsurfaceExit { .. } => {
                let mut wi = cosine_sample_hemisphere(u);
                if wo.z < 0.0 {
                    wi.z = -wi.z;
                }
                lobe(wi)
            }
            Bxdf::LambertianTransmission { .. } => {
                let mut wi = cosine_sample_hemisphere(u);
                if wo.z > 0.0 {
                    wi.z = -wi.z;
                }
                lobe(wi)
            }
            Bxdf::SpecularReflection { r, fresnel } => {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                specular(wi, fresnel.evaluate(wi.z) * r / wi.z.abs(), 1.0, flags)
            }
            Bxdf::SpecularTransmission { t, eta_a, eta_b, mode } => {
                let entering = wo.z > 0.0;
                let (eta_i, eta_t) = if entering { (eta_a, eta_b) } else { (eta_b, eta_a) };
                let n = if wo.z < 0.0 { -Vec3::Z } else { Vec3::Z };
                let wi = refract(wo, n, eta_i / eta_t)?;
                let mut ft = t * (Rgb::ONE - Fresnel::Dielectric { eta_i: eta_a, eta_t: eta_b }.evaluate(wi.z));
                if mode == TransportMode::Radiance {
                    ft *= (eta_i * eta_i) / (eta_t * eta_t);
                }
                specular(wi, ft / wi.z.abs(), 1.0, flags)
            }
            Bxdf::FresnelSpecular { r, t, eta_a, eta_b, mode } => {
                let f = fr_dielectric(wo.z, eta_a, eta_b);
                if u.x < f {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    specular(wi, f * r / wi.z.abs(), f, BxdfFlags::SPECULAR | BxdfFlags::REFLECTION)
                } else {
                    let entering = wo.z > 0.0;
                    let (eta_i, eta_t) = if entering { (eta_a, eta_b) } else { (eta_b, eta_a) };
                    let n = if wo.z < 0.0 { -Vec3::Z } else { Vec3::Z };
                    let wi = refract(wo, n, eta_i / eta_t)?;
                    let mut ft = t * (1.0 - f);
                    if mode == TransportMode::Radiance {
                        ft *= (eta_i * eta_i) / (eta_t * eta_t);
                    }
                    specular(wi, ft / wi.z.abs(), 1.0 - f, BxdfFlags::SPECULAR | BxdfFlags::TRANSMISSION)
                }
            }
            Bxdf::MicrofacetReflection { distribution, .. } => {
                if wo.z == 0.0 {
                    return None;
                }
                let wh = distribution.sample_wh(wo, u)?;
                if wo.dot(wh) < 0.0 {
                    return None;
                }
                let wi = reflect(wo, wh);
                if !same_hemisphere(wo, wi) {
                    return None;
                }
                lobe(wi)
            }
            Bxdf::MicrofacetTransmission { distribution, eta_a, eta_b, .. } => {
                if wo.z == 0.0 {
                    return None;
                }
                let wh = distribution.sample_wh(wo, u)?;
                if wo.dot(wh) < 0.0 {
                    return None;
                }
                let eta = if wo.z > 0.0 { eta_a / eta_b } else { eta_b / eta_a };
                let wi = refract(wo, wh, eta)?;
                lobe(wi)
            }
            Bxdf::FresnelBlend { distribution, .. } => {
                let wi = if u.x < 0.5 {
                    let u = Vec2::new((2.0 * u.x).min(ONE_MINUS_EPSILON), u.y);
                    let mut wi = cosine_sample_hemisphere(u);
                    if wo.z < 0.0 {
                        wi.z = -wi.z;
                    }
                    wi
                } else {
                    let u = Vec2::new((2.0 * (u.x - 0.5)).min(ONE_MINUS_EPSILON), u.y);
                    let wh = distribution.sample_wh(wo, u)?;
                    let wi = reflect(wo, wh);
                    if !same_hemisphere(wo, wi) {
                        return None;
                    }
                    wi
                };
                lobe(wi)
            }
            Bxdf::Disney(l) => lobe(l.sample_wi(wo, u)?),
            Bxdf::Hair(h) => lobe(h.sample_wi(wo, u)?),
            Bxdf::Fourier(b) => lobe(b.sample_wi(wo, u)?),
        }
    }

    /// The lobe with its value multiplied by `s` (pbrt-v3's `ScaledBxDF`, for `mix`): exact for
    /// every lobe but `FresnelBlend`, whose value is affine, not linear, in its colours (see
    /// the `material` module notes).
    pub fn scaled(self, s: Rgb) -> Bxdf {
        match self {
            Bxdf::LambertianReflection { r } => Bxdf::LambertianReflection { r: r * s },
            Bxdf::LambertianTransmission { t } => Bxdf::LambertianTransmission { t: t * s },
            Bxdf::OrenNayar { r, a, b } => Bxdf::OrenNayar { r: r * s, a, b },
            Bxdf::SpecularReflection { r, fresnel } => Bxdf::SpecularReflection { r: r * s, fresnel },
            Bxdf::SpecularTransmission { t, eta_a, eta_b, mode } => {
                Bxdf::SpecularTransmission { t: t * s, eta_a, eta_b, mode }
            }
            Bxdf::FresnelSpecular { r, t, eta_a, eta_b, mode } => {
                Bxdf::FresnelSpecular { r: r * s, t: t * s, eta_a, eta_b, mode }
            }
            Bxdf::MicrofacetReflection { r, distribution, fresnel } => {
                Bxdf::MicrofacetReflection { r: r * s, distribution, fresnel }
            }
            Bxdf::MicrofacetTransmission { t, distribution, eta_a, eta_b, mode } => {
                Bxdf::MicrofacetTransmission { t: t * s, distribution, eta_a, eta_b, mode }
            }
            Bxdf::FresnelBlend { rd, rs, distribution } => Bxdf::FresnelBlend { rd: rd * s, rs: rs * s, distribution },
            Bxdf::Disney(l) => Bxdf::Disney(l.scaled(s)),
            Bxdf::Hair(h) => Bxdf::Hair(h.scaled(s)),
            Bxdf::Fourier(b) => Bxdf::Fourier(b.scaled(s)),
            // Only `path` builds it, at a BSSRDF's exit point, never inside a `mix`.
            Bxdf::SubsurfaceExit { .. } => self,
        }
    }
}

/// `w` turned into the shading normal's hemisphere (pbrt-v3's `Faceforward(w, (0, 0, 1))`):
/// the microfacet Fresnel term sees the half vector on the normal's side, so that a dielectric's
/// total internal reflection depends on the side the light is on, not on the sign of `wh`.
#[inline]
fn toward_normal(w: Vec3) -> Vec3 {
    if w.z < 0.0 {
        -w
    } else {
        w
    }
}

#[inline]
fn clamp_u(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, ONE_MINUS_EPSILON)
    }
}

/// A surface's scattering function in world space: a shading frame, the
/// geometric normal, and up to [`MAX_BXDFS`] lobes (pbrt-v3's `BSDF`).
#[derive(Clone, Debug, PartialEq)]
pub struct Bsdf {
    /// Relative index of refraction over the boundary (1 for opaque surfaces).
    pub eta: f32,
    ns: Vec3,
    ng: Vec3,
    ss: Vec3,
    ts: Vec3,
    n: usize,
    bxdfs: [Bxdf; MAX_BXDFS],
}

/// Whether a lobe of type `t` contributes to `f` for a pair of directions on the same side
/// (`reflect`) or on opposite sides of the geometric normal.
#[inline]
fn lobe_counts(t: BxdfFlags, reflect: bool) -> bool {
    (reflect && t.contains(BxdfFlags::REFLECTION)) || (!reflect && t.contains(BxdfFlags::TRANSMISSION))
}

fn any_perpendicular(n: Vec3) -> Vec3 {
    // Duff et al.'s branchless orthonormal basis.
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x)
}

impl Bsdf {
    /// A BSDF with shading normal `ns`, tangent `ss` (pbrt-v3: the normalised
    /// shading ∂p/∂u), geometric normal `ng` and relative index `eta`. `ns` and
    /// `ng` are normalised and `ss` is made orthogonal to `ns` (an arbitrary
    /// tangent is chosen when it is degenerate), so the frame is always orthonormal.
    pub fn new(ns: Vec3, ss: Vec3, ng: Vec3, eta: f32) -> Self {
        let ng_n = ng.try_normalize();
        let ns = ns.try_normalize().or(ng_n).unwrap_or(Vec3::Z);
        let ng = ng_n.unwrap_or(ns);
        let ss = (ss - ns * ns.dot(ss)).try_normalize().unwrap_or_else(|| any_perpendicular(ns));
        let ts = ns.cross(ss);
        Bsdf { eta, ns, ng, ss, ts, n: 0, bxdfs: [Bxdf::LambertianReflection { r: Rgb::ZERO }; MAX_BXDFS] }
    }

    /// Add a lobe.
    pub fn add(&mut self, b: Bxdf) -> Result<(), BsdfError> {
        if self.n >= MAX_BXDFS {
            return Err(BsdfError::TooManyLobes);
        }
        self.bxdfs[self.n] = b;
        self.n += 1;
        Ok(())
    }

    /// The lobes.
    pub fn bxdfs(&self) -> &[Bxdf] {
        &self.bxdfs[..self.n]
    }

    pub fn shading_normal(&self) -> Vec3 {
        self.ns
    }

    pub fn geometric_normal(&self) -> Vec3 {
        self.ng
    }

    /// Number of lobes matching `flags`.
    pub fn num_components(&self, flags: BxdfFlags) -> usize {
        self.bxdfs().iter().filter(|b| b.matches(flags)).count()
    }

    pub fn world_to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.ss), v.dot(self.ts), v.dot(self.ns))
    }

    pub fn local_to_world(&self, v: Vec3) -> Vec3 {
        self.ss * v.x + self.ts * v.y + self.ns * v.z
    }

    fn reflects(&self, wo_w: Vec3, wi_w: Vec3) -> bool {
        wi_w.dot(self.ng) * wo_w.dot(self.ng) > 0.0
    }

    fn f_local(&self, wo_w: Vec3, wi_w: Vec3, wo: Vec3, wi: Vec3, flags: BxdfFlags) -> Rgb {
        let reflect = self.reflects(wo_w, wi_w);
        let mut f = Rgb::ZERO;
        for b in self.bxdfs() {
            if b.matches(flags) && lobe_counts(b.flags(), reflect) {
                f += b.f(wo, wi);
            }
        }
        f
    }

    /// BSDF value for world-space directions (both pointing away from the
    /// surface). Reflection lobes count when `wo` and `wi` are on the same side of
    /// the *geometric* normal, transmission lobes otherwise (pbrt-v3).
    pub fn f(&self, wo_w: Vec3, wi_w: Vec3, flags: BxdfFlags) -> Rgb {
        crate::profiling::timed(Phase::Shading, || {
            let (wo, wi) = (self.world_to_local(wo_w), self.world_to_local(wi_w));
            if wo.z == 0.0 || !wo.is_finite() || !wi.is_finite() {
                return Rgb::ZERO;
            }
            self.f_local(wo_w, wi_w, wo, wi, flags)
        })
    }

    /// `(self.f(wo_w, wi_w, flags), self.pdf(wo_w, wi_w, flags))`, bit for bit, in one pass.
    pub fn f_pdf(&self, wo_w: Vec3, wi_w: Vec3, flags: BxdfFlags) -> (Rgb, f32) {
        crate::profiling::timed(Phase::Shading, || {
            let (wo, wi) = (self.world_to_local(wo_w), self.world_to_local(wi_w));
            if wo.z == 0.0 || !wo.is_finite() || !wi.is_finite() {
                return (Rgb::ZERO, 0.0);
            }
            let reflect = self.reflects(wo_w, wi_w);
            let mut f = Rgb::ZERO;
            let mut pdf = 0.0;
            let mut matching = 0;
            for b in self.bxdfs().iter().filter(|b| b.matches(flags)) {
                matching += 1;
                if lobe_counts(b.flags(), reflect) {
                    let (fb, pb) = b.f_pdf(wo, wi);
                    f += fb;
                    pdf += pb;
                } else {
                    pdf += b.pdf(wo, wi);
                }
            }
            (f, if matching > 0 { pdf / matching as f32 } else { 0.0 })
        })
    }

    /// Average of the matching lobes' densities (pbrt-v3's `BSDF::Pdf`).
    pub fn pdf(&self, wo_w: Vec3, wi_w: Vec3, flags: BxdfFlags) -> f32 {
        crate::profiling::timed(Phase::Shading, || {
            if self.n == 0 {
                return 0.0;
            }
            let (wo, wi) = (self.world_to_local(wo_w), self.world_to_local(wi_w));
            if wo.z == 0.0 || !wo.is_finite() || !wi.is_finite() {
                return 0.0;
            }
            let mut pdf = 0.0;
            let mut matching = 0;
            for b in self.bxdfs().iter().filter(|b| b.matches(flags)) {
                matching += 1;
                pdf += b.pdf(wo, wi);
            }
            if matching > 0 {
                pdf / matching as f32
            } else {
                0.0
            }
        })
    }

    /// Sample a world-space incident direction (pbrt-v3's `BSDF::Sample_f`): `u.x`
    /// picks one of the lobes matching `flags` uniformly and is then remapped to
    /// [0,1) for that lobe's own sampling. For a non-specular choice the returned
    /// pdf is the average over all matching lobes and `f` the sum of the matching
    /// lobes selected by the geometric normal, as [`Bsdf::pdf`] and [`Bsdf::f`].
    pub fn sample_f(&self, wo_w: Vec3, u: Vec2, flags: BxdfFlags) -> Option<BsdfSample> {
        crate::profiling::timed(Phase::Shading, || {
            let matching = self.num_components(flags);
            if matching == 0 {
                return None;
            }
            let ux = clamp_u(u.x);
            // (`as usize` truncates and saturates negatives and NaN to 0: `floor` without its
            // library call, the same index for every value.)
            let comp = ((ux * matching as f32) as usize).min(matching - 1);
            let bxdf = self.bxdfs().iter().filter(|b| b.matches(flags)).nth(comp)?;
            let u_remapped = Vec2::new((ux * matching as f32 - comp as f32).min(ONE_MINUS_EPSILON), u.y);

            let wo = self.world_to_local(wo_w);
            if wo.z == 0.0 || !wo.is_finite() {
                return None;
            }
            let s = bxdf.sample_f(wo, u_remapped)?;
            if s.pdf.is_nan() || s.pdf <= 0.0 {
                return None;
            }
            let wi_w = self.local_to_world(s.wi);
            let mut pdf = s.pdf;
            let mut f = s.f;
            let specular = bxdf.flags().is_specular();
            if !specular && matching == 1 && !lobe_counts(bxdf.flags(), self.reflects(wo_w, wi_w)) {
                // As pbrt-v3, `f` counts a lobe only on its side of the *geometric* normal: a
                // direction sampled about a tilted shading normal may cross the surface.
                f = Rgb::ZERO;
            }
            if !specular && matching > 1 {
                // pdf: the sampled lobe's, then the others' in order; f: every matching lobe that
                // the geometric normal selects, in order (the sampled lobe's value is `s.f`).
                let reflect = self.reflects(wo_w, wi_w);
                f = Rgb::ZERO;
                for (i, b) in self.bxdfs().iter().filter(|b| b.matches(flags)).enumerate() {
                    let counts = lobe_counts(b.flags(), reflect);
                    if i == comp {
                        if counts {
                            f += s.f;
                        }
                    } else if counts {
                        let (fb, pb) = b.f_pdf(wo, s.wi);
                        f += fb;
                        pdf += pb;
                    } else {
                        pdf += b.pdf(wo, s.wi);
                    }
                }
            }
            if matching > 1 {
                pdf /= matching as f32;
            }
            Some(BsdfSample { wi: wi_w, f, pdf, flags: s.flags })
        })
    }
}

#[cfg(test)]
mod tests;
