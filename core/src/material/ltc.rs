//! How a material describes itself to analytic (LTC) integrators: a Lambertian albedo, up to
//! [`MAX_LOBES`] isotropic lobes each with the exact BRDF·cos pbrt-v3 evaluates
//! ([`LtcLobe::f_cos`]) and a GGX roughness an LTC can warp, and whether it also transmits.
//!
//! Materials: matte (σ = 0), plastic, metal, substrate (its `FresnelBlend` as two lobes: the
//! specular term, warped by the GGX LTC of its roughness, and the non-Lambertian diffuse
//! term, warped by the cosine), uber (its diffuse and glossy parts; its specular ones are
//! followed as specular chains), translucent (the reflection lobes; the transmission lobes
//! are left to the integrator: [`LtcDescription::transmits`]) and mix (the sub-materials'
//! lobes scaled as pbrt-v3's `ScaledBxDF` scales them, in the first one's shading frame).
//! Not described (`None`): Oren–Nayar matte, anisotropic roughness (`uroughness ≠
//! vroughness`), mirror, glass, fourier, hair, subsurface, disney (Burley's diffuse is not
//! Lambertian, its retro-reflection lobe is always present, its masking term is separable and
//! its Fresnel its own), a mix with such a sub-material or more than [`MAX_LOBES`] lobes.

use super::{eval_f, eval_s, is_black, Material, Materials, ShadingGeometry};
use crate::bxdf::{Bxdf, Fresnel};
use crate::interaction::SurfaceInteraction;
use crate::microfacet::{roughness_to_alpha, MicrofacetDistribution};
use crate::spectrum::Rgb;
use crate::texture::{TextureEvalContext, Textures};
use glam::{DVec3, Vec3};
use std::f32::consts::PI;

/// Lobes a description holds at most.
pub const MAX_LOBES: usize = 4;

/// How an LTC-based integrator can describe a material (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LtcDescription {
    /// Shading normal (after bump mapping).
    pub n: Vec3,
    /// Lambertian albedo.
    pub diffuse: Rgb,
    /// The other reflection lobes.
    pub lobes: LtcLobes,
    /// The material also has transmission lobes (translucent), which the description leaves
    /// out: an integrator must add the light they pass by other means.
    pub transmits: bool,
}

/// Up to [`MAX_LOBES`] lobes (a small inline list).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LtcLobes {
    len: usize,
    items: [LtcLobe; MAX_LOBES],
}

impl Default for LtcLobes {
    fn default() -> Self {
        const NONE: LtcLobe = LtcLobe { alpha: 1.0, kind: LtcLobeKind::Microfacet(LtcFresnel::NoOp), scale: Rgb::ZERO };
        LtcLobes { len: 0, items: [NONE; MAX_LOBES] }
    }
}

impl LtcLobes {
    /// The lobes in one list (`None` if there are too many).
    pub fn from_slice(lobes: &[LtcLobe]) -> Option<LtcLobes> {
        let mut out = LtcLobes::default();
        for l in lobes {
            out.push(*l)?;
        }
        Some(out)
    }
    /// Adds a lobe; `None` when full.
    pub fn push(&mut self, lobe: LtcLobe) -> Option<()> {
        let slot = self.items.get_mut(self.len)?;
        *slot = lobe;
        self.len += 1;
        Some(())
    }
    pub fn as_slice(&self) -> &[LtcLobe] {
        &self.items[..self.len]
    }
    pub fn iter(&self) -> std::slice::Iter<'_, LtcLobe> {
        self.as_slice().iter()
    }
    pub fn len(&self) -> usize {
        self.len
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// One isotropic lobe: `scale` times the lobe of `kind` with Trowbridge–Reitz roughness `alpha`
/// (already remapped and clamped as pbrt-v3's distribution clamps it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LtcLobe {
    pub alpha: f32,
    pub kind: LtcLobeKind,
    pub scale: Rgb,
}

/// The lobes pbrt-v3's LTC-describable materials are made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LtcLobeKind {
    /// `MicrofacetReflection` with this Fresnel (plastic, metal, uber, translucent).
    Microfacet(LtcFresnel),
    /// `FresnelBlend`'s specular term (substrate): `D / (4 |ωi·ωh| max(cos θi, cos θo))` times
    /// Schlick's Fresnel with `Rs`.
    BlendSpecular { rs: Rgb },
    /// `FresnelBlend`'s diffuse term: `28/(23π) Rd (1 − Rs) (1 − (1 − cos θi/2)⁵)(1 − (1 −
    /// cos θo/2)⁵)`; its warp is the cosine, not a GGX LTC.
    BlendDiffuse { rd: Rgb, rs: Rgb },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LtcFresnel {
    /// pbrt-v3's `FresnelDielectric(eta_i, eta_t)` (plastic uses 1.5, 1 — sic).
    Dielectric { eta_i: f32, eta_t: f32 },
    /// `FresnelConductor(1, eta, k)`.
    Conductor { eta: Rgb, k: Rgb },
    /// Schlick's approximation with normal-incidence reflectance `f0` (substrate's `Ks`).
    Schlick { f0: Rgb },
    /// No Fresnel factor (1).
    NoOp,
}

impl LtcFresnel {
    /// The reflectance at `cos_d` (pbrt-v3's definitions).
    pub fn evaluate(&self, cos_d: f32) -> Rgb {
        match *self {
            LtcFresnel::Dielectric { eta_i, eta_t } => Fresnel::Dielectric { eta_i, eta_t }.evaluate(cos_d),
            LtcFresnel::Conductor { eta, k } => Fresnel::Conductor { eta_i: Rgb::ONE, eta_t: eta, k }.evaluate(cos_d),
            LtcFresnel::Schlick { f0 } => f0 + (Rgb::ONE - f0) * (1.0 - cos_d).powi(5),
            LtcFresnel::NoOp => Rgb::ONE,
        }
    }
}

impl LtcLobe {
    /// The roughness of the GGX LTC that warps this lobe (`None`: the cosine).
    pub fn ggx_alpha(&self) -> Option<f32> {
        match self.kind {
            LtcLobeKind::BlendDiffuse { .. } => None,
            _ => Some(self.alpha),
        }
    }

    /// The lobe as pbrt-v3 evaluates it for `ωo` (and so `ωi`) on the far side of the shading
    /// normal, in the frame turned to `ωo`'s side: `MicrofacetReflection` takes its Fresnel at
    /// `ωi·Faceforward(ωh, n)`, negative there, and `FresnelDielectric` then swaps `ηi` and
    /// `ηt` (plastic's `(1.5, 1)`, with total internal reflection from the front, reflects as
    /// `(1, 1.5)` from behind). Conductors (`|cos θi|`), Schlick's term and `FresnelBlend`
    /// (`ωi·ωh ≥ 0`) are the same from either side.
    pub fn seen_from_behind(self) -> LtcLobe {
        match self.kind {
            LtcLobeKind::Microfacet(LtcFresnel::Dielectric { eta_i, eta_t }) => {
                LtcLobe { kind: LtcLobeKind::Microfacet(LtcFresnel::Dielectric { eta_i: eta_t, eta_t: eta_i }), ..self }
            }
            _ => self,
        }
    }

    /// The lobe's Fresnel, as the LTC's Fresnel treatment takes it (`BlendSpecular`: Schlick with
    /// `Rs`; `BlendDiffuse`: none).
    pub fn fresnel(&self) -> LtcFresnel {
        match self.kind {
            LtcLobeKind::Microfacet(f) => f,
            LtcLobeKind::BlendSpecular { rs } => LtcFresnel::Schlick { f0: rs },
            LtcLobeKind::BlendDiffuse { .. } => LtcFresnel::NoOp,
        }
    }

    /// The lobe's weight as the LTC alone (`"glossy" "ltc"`, Heitz et al.'s approximation)
    /// takes it: `scale`, times `Rd` for `FresnelBlend`'s diffuse term, which it shades as a
    /// Lambertian lobe of albedo `Rd`.
    pub fn ltc_scale(&self) -> Rgb {
        match self.kind {
            LtcLobeKind::BlendDiffuse { rd, .. } => self.scale * rd,
            _ => self.scale,
        }
    }

    /// [`Self::f_cos`] for `wo` (local, unit, above the surface) as a fast evaluator.
    pub fn evaluator(&self, wo: DVec3) -> LobeEval {
        let alpha2 = (self.alpha as f64) * (self.alpha as f64);
        let pow5 = |v: f64| (v * v) * (v * v) * v;
        LobeEval {
            kind: self.kind,
            scale: self.scale.as_dvec3(),
            wo,
            alpha2,
            one_plus_lambda_o: 1.0 + lambda(alpha2, wo.z),
            diffuse_o: 28.0 / (23.0 * std::f64::consts::PI) * (1.0 - pow5(1.0 - 0.5 * wo.z)),
        }
    }

    /// The exact `f(ωo, ωi) cos θi` of the lobe (local frame, both directions above the
    /// surface; zero otherwise), as pbrt-v3 evaluates it.
    pub fn f_cos(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !(wo.z > 0.0 && wi.z > 0.0) {
            return Rgb::ZERO;
        }
        let dist = || MicrofacetDistribution::trowbridge_reitz(self.alpha, self.alpha);
        let f = match self.kind {
            LtcLobeKind::Microfacet(fr) => {
                let fresnel = match fr {
                    LtcFresnel::Dielectric { eta_i, eta_t } => Fresnel::Dielectric { eta_i, eta_t },
                    LtcFresnel::Conductor { eta, k } => Fresnel::Conductor { eta_i: Rgb::ONE, eta_t: eta, k },
                    LtcFresnel::NoOp => Fresnel::NoOp,
                    LtcFresnel::Schlick { .. } => {
                        // Not a pbrt-v3 MicrofacetReflection Fresnel: evaluated here.
                        let b = Bxdf::microfacet_reflection(Rgb::ONE, dist(), Fresnel::NoOp).f(wo, wi);
                        let h = (wo + wi).normalize_or_zero();
                        return b * fr.evaluate(wi.dot(h)) * self.scale * wi.z;
                    }
                };
                Bxdf::microfacet_reflection(Rgb::ONE, dist(), fresnel).f(wo, wi)
            }
            LtcLobeKind::BlendSpecular { rs } => Bxdf::fresnel_blend(Rgb::ZERO, rs, dist()).f(wo, wi),
            LtcLobeKind::BlendDiffuse { rd, rs } => {
                let pow5 = |v: f32| (v * v) * (v * v) * v;
                (28.0 / (23.0 * PI))
                    * rd
                    * (Rgb::ONE - rs)
                    * (1.0 - pow5(1.0 - 0.5 * wi.z))
                    * (1.0 - pow5(1.0 - 0.5 * wo.z))
            }
        };
        f * self.scale * wi.z
    }
}

/// A lobe's [`LtcLobe::f_cos`] for one `ωo`, in f64 with what depends on `ωo` alone taken once
/// (the quadrature of an exact integration evaluates it hundreds of times per point): the same
/// formulas as pbrt-v3's (isotropic Trowbridge–Reitz `D = α² / (π (1 + (α² − 1) cos²θh)²)`,
/// height-correlated Smith `G = 1 / (1 + Λ(ωo) + Λ(ωi))`), to rounding.
#[derive(Clone, Copy, Debug)]
pub struct LobeEval {
    kind: LtcLobeKind,
    scale: DVec3,
    wo: DVec3,
    alpha2: f64,
    /// `1 + Λ(ωo)` (microfacet), `max(cos θo, ·)` operand (FresnelBlend).
    one_plus_lambda_o: f64,
    /// `28/(23π) (1 − (1 − cos θo/2)⁵)` (FresnelBlend's diffuse term).
    diffuse_o: f64,
}

fn lambda(alpha2: f64, cos: f64) -> f64 {
    let c2 = cos * cos;
    let tan2 = (1.0 - c2).max(0.0) / c2;
    if !tan2.is_finite() {
        return 0.0;
    }
    0.5 * ((1.0 + alpha2 * tan2).sqrt() - 1.0)
}

impl LobeEval {
    /// `f·cos θi` for the local unit direction `wi` (RGB as `DVec3`; zero below the horizon).
    pub fn f_cos(&self, wi: DVec3) -> DVec3 {
        let (wo, zi) = (self.wo, wi.z);
        if !(zi > 0.0) {
            return DVec3::ZERO;
        }
        if let LtcLobeKind::BlendDiffuse { rd, rs } = self.kind {
            let pow5 = |v: f64| (v * v) * (v * v) * v;
            let d = (rd * (Rgb::ONE - rs)).as_dvec3() * (self.diffuse_o * (1.0 - pow5(1.0 - 0.5 * zi)) * zi);
            return d * self.scale;
        }
        let h = wo + wi;
        let len = h.length();
        if !(len > 0.0) {
            return DVec3::ZERO;
        }
        let h = h / len;
        let c2 = h.z * h.z;
        let t = 1.0 + (self.alpha2 - 1.0) * c2;
        let d = self.alpha2 / (std::f64::consts::PI * t * t);
        let cos_d = wi.dot(h);
        let v = match self.kind {
            LtcLobeKind::Microfacet(fr) => {
                let g = 1.0 / (self.one_plus_lambda_o + lambda(self.alpha2, zi));
                let f = match fr {
                    LtcFresnel::NoOp => DVec3::ONE,
                    LtcFresnel::Dielectric { eta_i, eta_t } => {
                        Fresnel::Dielectric { eta_i, eta_t }.evaluate(cos_d as f32).as_dvec3()
                    }
                    LtcFresnel::Conductor { eta, k } => {
                        Fresnel::Conductor { eta_i: Rgb::ONE, eta_t: eta, k }.evaluate(cos_d as f32).as_dvec3()
                    }
                    LtcFresnel::Schlick { .. } => fr.evaluate(cos_d as f32).as_dvec3(),
                };
                f * (d * g / (4.0 * wo.z))
            }
            LtcLobeKind::BlendSpecular { rs } => {
                let schlick = LtcFresnel::Schlick { f0: rs }.evaluate(cos_d as f32).as_dvec3();
                schlick * (d * zi / (4.0 * cos_d.abs() * zi.max(wo.z)))
            }
            LtcLobeKind::BlendDiffuse { .. } => DVec3::ZERO,
        };
        let v = v * self.scale;
        if v.is_finite() {
            v
        } else {
            DVec3::ZERO
        }
    }
}

/// pbrt-v3's alpha for a roughness (remapped or not), clamped as its distributions clamp it.
fn alpha_of(r: f32, remap: bool) -> f32 {
    let a = if remap { roughness_to_alpha(r) } else { r };
    MicrofacetDistribution::trowbridge_reitz(a, a).alphas().0
}

/// `Some(alpha)` for equal u and v roughness.
fn isotropic(ur: f32, vr: f32, remap: bool) -> Option<f32> {
    let (a, b) = (alpha_of(ur, remap), alpha_of(vr, remap));
    (a == b).then_some(a)
}

/// What [`Material::ltc_parts`] returns: the Lambertian albedo, the lobes (when asked for) and
/// whether the material transmits.
pub(super) type LtcParts = (Rgb, LtcLobes, bool);

/// Where the parts are evaluated, and how deep in a `mix` (cut at 16 as the BSDF's).
pub(super) struct PartsAt<'a> {
    pub(super) ctx: &'a TextureEvalContext,
    pub(super) tx: &'a Textures,
    pub(super) materials: &'a Materials,
    /// Whether the lobes are wanted (else only the albedo and what decides the form).
    pub(super) lobes: bool,
    pub(super) depth: u32,
}

impl Material {
    /// The material in LTC terms (see [`LtcDescription`]); `None` when it has no such form.
    pub fn ltc_lobes(
        &self,
        si: &SurfaceInteraction,
        materials: &Materials,
        textures: &Textures,
    ) -> Option<LtcDescription> {
        let ctx = TextureEvalContext::from_si(si);
        let geom = ShadingGeometry::of(si);
        self.ltc_lobes_ext(si, &ctx, &geom, materials, textures)
    }

    /// [`Self::ltc_lobes`] with an explicit texture context and shading geometry.
    pub fn ltc_lobes_ext(
        &self,
        si: &SurfaceInteraction,
        ctx: &TextureEvalContext,
        geom: &ShadingGeometry,
        materials: &Materials,
        tx: &Textures,
    ) -> Option<LtcDescription> {
        let at = PartsAt { ctx, tx, materials, lobes: true, depth: 0 };
        let (diffuse, lobes, transmits) = self.ltc_parts(&at)?;
        // A mix's lobes live in its first material's frame, as its BSDF's.
        let mut framed = self;
        while let Material::Mix { m1, .. } = framed {
            framed = materials.get(*m1)?;
        }
        let (n, _) = framed.frame(si, ctx, geom, tx);
        Some(LtcDescription { n, diffuse, lobes, transmits })
    }

    /// The Lambertian albedo of [`Self::ltc_lobes`] alone (`None` exactly when it is `None`):
    /// neither the shading frame nor the other lobes are evaluated — what a pixel sample needs
    /// when its surface's lighting was integrated once for the pixel.
    pub fn ltc_diffuse(&self, si: &SurfaceInteraction, materials: &Materials, tx: &Textures) -> Option<Rgb> {
        let ctx = TextureEvalContext::from_si(si);
        self.ltc_parts(&PartsAt { ctx: &ctx, tx, materials, lobes: false, depth: 0 }).map(|(d, _, _)| d)
    }

    /// The parts of [`Self::ltc_lobes`] (without `at.lobes`, only what decides whether there is
    /// an LTC form is evaluated besides the albedo).
    pub(super) fn ltc_parts(&self, at: &PartsAt) -> Option<LtcParts> {
        let (ctx, tx) = (at.ctx, at.tx);
        let mut lobes = LtcLobes::default();
        let mut add = |lobe: LtcLobe| if at.lobes { lobes.push(lobe) } else { Some(()) };
        let diffuse = match *self {
            Material::Matte { kd, sigma, .. } => {
                if eval_f(tx, sigma, ctx).clamp(0.0, 90.0) != 0.0 {
                    return None;
                }
                eval_s(tx, kd, ctx)
            }
            Material::Plastic { kd, ks, roughness, remap, .. } => {
                let ks = eval_s(tx, ks, ctx);
                if at.lobes && !is_black(ks) {
                    let r = eval_f(tx, roughness, ctx);
                    let fresnel = LtcFresnel::Dielectric { eta_i: 1.5, eta_t: 1.0 };
                    add(LtcLobe { alpha: alpha_of(r, remap), kind: LtcLobeKind::Microfacet(fresnel), scale: ks })?;
                }
                eval_s(tx, kd, ctx)
            }
            Material::Metal { eta, k, roughness, uroughness, vroughness, remap, .. } => {
                let ur = eval_f(tx, uroughness.unwrap_or(roughness), ctx);
                let vr = eval_f(tx, vroughness.unwrap_or(roughness), ctx);
                let alpha = isotropic(ur, vr, remap)?;
                let fresnel = LtcFresnel::Conductor { eta: tx.eval_spectrum(eta, ctx), k: tx.eval_spectrum(k, ctx) };
                add(LtcLobe { alpha, kind: LtcLobeKind::Microfacet(fresnel), scale: Rgb::ONE })?;
                Rgb::ZERO
            }
            Material::Substrate { kd, ks, uroughness, vroughness, remap, .. } => {
                let alpha = isotropic(eval_f(tx, uroughness, ctx), eval_f(tx, vroughness, ctx), remap)?;
                let (rd, rs) = (eval_s(tx, kd, ctx), eval_s(tx, ks, ctx));
                if !is_black(rd) || !is_black(rs) {
                    add(LtcLobe { alpha, kind: LtcLobeKind::BlendSpecular { rs }, scale: Rgb::ONE })?;
                    if !is_black(rd) {
                        add(LtcLobe { alpha, kind: LtcLobeKind::BlendDiffuse { rd, rs }, scale: Rgb::ONE })?;
                    }
                }
                Rgb::ZERO
            }
            Material::Uber { kd, ks, roughness, uroughness, vroughness, eta, opacity, remap, .. } => {
                let op = eval_s(tx, opacity, ctx);
                let ks = op * eval_s(tx, ks, ctx);
                if !is_black(ks) {
                    let ur = eval_f(tx, uroughness.unwrap_or(roughness), ctx);
                    let vr = vroughness.map_or(ur, |v| eval_f(tx, v, ctx));
                    let alpha = isotropic(ur, vr, remap)?;
                    let fresnel = LtcFresnel::Dielectric { eta_i: 1.0, eta_t: eval_f(tx, eta, ctx) };
                    add(LtcLobe { alpha, kind: LtcLobeKind::Microfacet(fresnel), scale: ks })?;
                }
                op * eval_s(tx, kd, ctx)
            }
            Material::Translucent { kd, ks, reflect, transmit, roughness, remap, .. } => {
                let (r, t) = (eval_s(tx, reflect, ctx), eval_s(tx, transmit, ctx));
                if is_black(r) && is_black(t) {
                    return Some((Rgb::ZERO, lobes, false));
                }
                let ks = eval_s(tx, ks, ctx);
                if at.lobes && !is_black(ks) && !is_black(r) {
                    let alpha = alpha_of(eval_f(tx, roughness, ctx), remap);
                    let fresnel = LtcFresnel::Dielectric { eta_i: 1.0, eta_t: 1.5 };
                    add(LtcLobe { alpha, kind: LtcLobeKind::Microfacet(fresnel), scale: r * ks })?;
                }
                let transmits = !(is_black(t) || is_black(eval_s(tx, kd, ctx)) && is_black(ks));
                return Some((r * eval_s(tx, kd, ctx), lobes, transmits));
            }
            Material::Mix { amount, m1, m2 } => return self.mix_parts(at, amount, [m1, m2]),
            // No Lambertian-plus-GGX form (see `ltc_lobes`).
            Material::Mirror { .. }
            | Material::Glass { .. }
            | Material::Disney(_)
            | Material::Fourier(_)
            | Material::Hair(_)
            | Material::Subsurface(_) => return None,
        };
        Some((diffuse, lobes, false))
    }

    /// `mix`: both sub-materials' parts, scaled by `amount` and `1 − amount` (`None` if either
    /// has no LTC form, a sub-material is missing, the nesting passes 16 or the lobes pass
    /// [`MAX_LOBES`]).
    fn mix_parts(&self, at: &PartsAt, amount: crate::texture::SpectrumParam, m: [usize; 2]) -> Option<LtcParts> {
        if at.depth >= 16 {
            return None;
        }
        let s1 = eval_s(at.tx, amount, at.ctx);
        let s2 = (Rgb::ONE - s1).max(Rgb::ZERO);
        let sub = PartsAt { depth: at.depth + 1, ..*at };
        let (d1, l1, t1) = at.materials.get(m[0])?.ltc_parts(&sub)?;
        let (d2, l2, t2) = at.materials.get(m[1])?.ltc_parts(&sub)?;
        let mut lobes = LtcLobes::default();
        for (ls, s) in [(l1, s1), (l2, s2)] {
            for l in ls.iter() {
                lobes.push(LtcLobe { scale: l.scale * s, ..*l })?;
            }
        }
        Some((d1 * s1 + d2 * s2, lobes, t1 || t2))
    }
}
