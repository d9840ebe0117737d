//! pbrt-v3's materials: parameters and defaults, bump mapping, and the BSDF
//! each one builds at a surface point (`ComputeScatteringFunctions`).
//!
//! Deviations from pbrt-v3:
//! - `mix` scales each lobe's reflectance/transmittance colours by the mix weight
//!   (pbrt-v3 wraps lobes in `ScaledBxDF`). This is exact for every lobe except
//!   `FresnelBlend` (substrate), whose value is affine, not linear, in its colours:
//!   a mixed substrate is approximate.
//! - Bump mapping ignores ∂n/∂u, ∂n/∂v of the shading normal (pbrt-v3 adds
//!   `displacement · ∂n/∂u`; penumbra's interactions do not carry normal derivatives).
//! - Unknown material types render as `matte` with their `Kd` (default 0.5), with one warning
//!   per type.
//!
//! `disney`, `fourier`, `hair`, `subsurface` and `kdsubsurface` live in their own modules
//! ([`disney`], [`fourier`], [`hair`], [`subsurface`]); see `docs/materials.md`.

use crate::bxdf::{Bsdf, Bxdf, Fresnel, TransportMode};
use crate::geometry::face_forward;
use crate::interaction::SurfaceInteraction;
use crate::microfacet::{roughness_to_alpha, MicrofacetDistribution};
use crate::spectrum::{copper_eta, copper_k, Rgb};
use crate::texture::{FloatParam, SpectrumParam, TextureEvalContext, Textures};
use glam::{Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, SceneDescription};
use std::collections::HashSet;

pub mod disney;
pub mod fourier;
pub mod hair;
pub mod subsurface;

/// A material as pbrt-v3 defines it; texture-valued parameters refer to [`Textures`].
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    Matte {
        kd: SpectrumParam,
        sigma: FloatParam,
        bump: Option<FloatParam>,
    },
    Plastic {
        kd: SpectrumParam,
        ks: SpectrumParam,
        roughness: FloatParam,
        remap: bool,
        bump: Option<FloatParam>,
    },
    Metal {
        eta: SpectrumParam,
        k: SpectrumParam,
        roughness: FloatParam,
        uroughness: Option<FloatParam>,
        vroughness: Option<FloatParam>,
        remap: bool,
        bump: Option<FloatParam>,
    },
    Mirror {
        kr: SpectrumParam,
        bump: Option<FloatParam>,
    },
    Glass {
        kr: SpectrumParam,
        kt: SpectrumParam,
        eta: FloatParam,
        uroughness: FloatParam,
        vroughness: FloatParam,
        remap: bool,
        bump: Option<FloatParam>,
    },
    Substrate {
        kd: SpectrumParam,
        ks: SpectrumParam,
        uroughness: FloatParam,
        vroughness: FloatParam,
        remap: bool,
        bump: Option<FloatParam>,
    },
    Uber {
        kd: SpectrumParam,
        ks: SpectrumParam,
        kr: SpectrumParam,
        kt: SpectrumParam,
        roughness: FloatParam,
        uroughness: Option<FloatParam>,
        vroughness: Option<FloatParam>,
        eta: FloatParam,
        opacity: SpectrumParam,
        remap: bool,
        bump: Option<FloatParam>,
    },
    /// Lobes of `m1` scaled by `amount`, plus lobes of `m2` scaled by `1 - amount`
    /// (pbrt-v3's weighting, in `m1`'s shading frame). Indices into `SceneDescription::materials`.
    Mix {
        amount: SpectrumParam,
        m1: usize,
        m2: usize,
    },
    Translucent {
        kd: SpectrumParam,
        ks: SpectrumParam,
        reflect: SpectrumParam,
        transmit: SpectrumParam,
        roughness: FloatParam,
        remap: bool,
        bump: Option<FloatParam>,
    },
    /// pbrt-v3's Disney BSDF ([`disney`]).
    Disney(Box<disney::Disney>),
    /// A tabulated BSDF read from a `.bsdf` file ([`fourier`]).
    Fourier(fourier::Fourier),
    /// Chiang et al.'s hair fibre ([`hair`]).
    Hair(Box<hair::Hair>),
    /// `subsurface` and `kdsubsurface` ([`subsurface`]).
    Subsurface(Box<subsurface::Subsurface>),
}

/// The shading-geometry derivatives pbrt-v3 bump-maps with (`si.shading.{n, dpdu, dpdv,
/// dndu, dndv}`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingGeometry {
    pub n: Vec3,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    pub dndu: Vec3,
    pub dndv: Vec3,
}

impl ShadingGeometry {
    /// The interaction's shading geometry, as the scene set it up for its shape (see
    /// `SurfaceInteraction::shading_dpdu`).
    pub fn of(si: &SurfaceInteraction) -> Self {
        ShadingGeometry { n: si.shading.z, dpdu: si.shading_dpdu, dpdv: si.shading_dpdv, dndu: si.dndu, dndv: si.dndv }
    }
}

/// Options of [`Material::compute_bsdf_ext`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfOptions {
    pub mode: TransportMode,
    /// pbrt-v3's `allowMultipleLobes` (false in `directlighting`, true in `path`):
    /// smooth glass then becomes one `FresnelSpecular` lobe.
    pub allow_multiple_lobes: bool,
}

impl Default for BsdfOptions {
    fn default() -> Self {
        BsdfOptions { mode: TransportMode::Radiance, allow_multiple_lobes: false }
    }
}

/// The scene's materials, by index in `SceneDescription::materials`; only those some
/// object uses (and the materials a used `mix` refers to) are built.
#[derive(Clone, Debug, Default)]
pub struct Materials {
    slots: Vec<Option<Material>>,
}

fn clamp0(c: Rgb) -> Rgb {
    c.max(Rgb::ZERO)
}

fn is_black(c: Rgb) -> bool {
    c == Rgb::ZERO
}

enum BuildState {
    Unbuilt,
    Building,
    Built(Material),
}

struct Builder<'a> {
    desc: &'a SceneDescription,
    textures: &'a mut Textures,
    warnings: &'a DiagSink,
    states: Vec<BuildState>,
    warned_types: HashSet<String>,
}

impl Builder<'_> {
    fn build(&mut self, i: usize) -> Result<(), Diagnostic> {
        match self.states.get(i) {
            None => return Err(Diagnostic::error(None, format!("material index {i} out of range"))),
            Some(BuildState::Built(_)) => return Ok(()),
            Some(BuildState::Building) => {
                let e = &self.desc.materials[i].entity;
                return Err(Diagnostic::error(Some(e.loc.clone()), "mix material refers to itself"));
            }
            Some(BuildState::Unbuilt) => {}
        }
        self.states[i] = BuildState::Building;
        let m = self.create(i)?;
        let e = &self.desc.materials[i].entity;
        self.warnings.extend(e.params.report_unused(&format!("material \"{}\"", e.kind)));
        self.states[i] = BuildState::Built(m);
        Ok(())
    }

    /// The named material `name` as seen from material `from`: the latest definition before it, else any.
    fn find_named(&self, name: &str, from: usize) -> Option<usize> {
        let mats = &self.desc.materials;
        let is = |j: &usize| mats[*j].name.as_deref() == Some(name);
        (0..from).rev().find(is).or_else(|| (0..mats.len()).rev().find(is))
    }

    fn create(&mut self, i: usize) -> Result<Material, Diagnostic> {
        let e = &self.desc.materials[i].entity;
        let p = &e.params;
        let w = self.warnings;
        p.get_strings("type");
        let tx = &mut *self.textures;
        let one = |v: f32| Rgb::splat(v);
        let bump = |tx: &mut Textures| tx.get_float_param_opt(p, "bumpmap", w);
        let remap = || p.get_one_bool("remaproughness", true);
        Ok(match e.kind.as_str() {
            "matte" => Material::Matte {
                kd: tx.get_spectrum_param(p, "Kd", one(0.5), w)?,
                sigma: tx.get_float_param(p, "sigma", 0.0, w)?,
                bump: bump(tx)?,
            },
            "plastic" => Material::Plastic {
                kd: tx.get_spectrum_param(p, "Kd", one(0.25), w)?,
                ks: tx.get_spectrum_param(p, "Ks", one(0.25), w)?,
                roughness: tx.get_float_param(p, "roughness", 0.1, w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "metal" => Material::Metal {
                eta: tx.get_spectrum_param(p, "eta", copper_eta(), w)?,
                k: tx.get_spectrum_param(p, "k", copper_k(), w)?,
                roughness: tx.get_float_param(p, "roughness", 0.01, w)?,
                uroughness: tx.get_float_param_opt(p, "uroughness", w)?,
                vroughness: tx.get_float_param_opt(p, "vroughness", w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "mirror" => Material::Mirror { kr: tx.get_spectrum_param(p, "Kr", one(0.9), w)?, bump: bump(tx)? },
            "glass" => Material::Glass {
                kr: tx.get_spectrum_param(p, "Kr", one(1.0), w)?,
                kt: tx.get_spectrum_param(p, "Kt", one(1.0), w)?,
                eta: match tx.get_float_param_opt(p, "eta", w)? {
                    Some(e) => e,
                    None => tx.get_float_param(p, "index", 1.5, w)?,
                },
                uroughness: tx.get_float_param(p, "uroughness", 0.0, w)?,
                vroughness: tx.get_float_param(p, "vroughness", 0.0, w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "substrate" => Material::Substrate {
                kd: tx.get_spectrum_param(p, "Kd", one(0.5), w)?,
                ks: tx.get_spectrum_param(p, "Ks", one(0.5), w)?,
                uroughness: tx.get_float_param(p, "uroughness", 0.1, w)?,
                vroughness: tx.get_float_param(p, "vroughness", 0.1, w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "uber" => Material::Uber {
                kd: tx.get_spectrum_param(p, "Kd", one(0.25), w)?,
                ks: tx.get_spectrum_param(p, "Ks", one(0.25), w)?,
                kr: tx.get_spectrum_param(p, "Kr", one(0.0), w)?,
                kt: tx.get_spectrum_param(p, "Kt", one(0.0), w)?,
                roughness: tx.get_float_param(p, "roughness", 0.1, w)?,
                uroughness: tx.get_float_param_opt(p, "uroughness", w)?,
                vroughness: tx.get_float_param_opt(p, "vroughness", w)?,
                eta: match tx.get_float_param_opt(p, "eta", w)? {
                    Some(e) => e,
                    None => tx.get_float_param(p, "index", 1.5, w)?,
                },
                opacity: tx.get_spectrum_param(p, "opacity", one(1.0), w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "translucent" => Material::Translucent {
                kd: tx.get_spectrum_param(p, "Kd", one(0.25), w)?,
                ks: tx.get_spectrum_param(p, "Ks", one(0.25), w)?,
                reflect: tx.get_spectrum_param(p, "reflect", one(0.5), w)?,
                transmit: tx.get_spectrum_param(p, "transmit", one(0.5), w)?,
                roughness: tx.get_float_param(p, "roughness", 0.1, w)?,
                bump: bump(tx)?,
                remap: remap(),
            },
            "disney" => Material::Disney(Box::new(disney::Disney::create(tx, p, w)?)),
            "fourier" => Material::Fourier(fourier::Fourier::create(tx, p, w, &e.loc, &self.desc.base_dir)?),
            "hair" => Material::Hair(Box::new(hair::Hair::create(tx, p, w, &e.loc)?)),
            "subsurface" | "kdsubsurface" => Material::Subsurface(Box::new(subsurface::Subsurface::create(
                tx,
                p,
                w,
                &e.loc,
                e.kind == "kdsubsurface",
            )?)),
            "mix" => {
                let amount = tx.get_spectrum_param(p, "amount", one(0.5), w)?;
                let mut refs = [0usize; 2];
                for (k, key) in ["namedmaterial1", "namedmaterial2"].iter().enumerate() {
                    let name = p.get_one_string(key, "");
                    let loc = p.loc_of(key).cloned().unwrap_or_else(|| e.loc.clone());
                    if name.is_empty() {
                        return Err(Diagnostic::error(Some(loc), format!("mix material needs \"string {key}\"")));
                    }
                    let Some(j) = self.find_named(&name, i) else {
                        return Err(Diagnostic::error(Some(loc), format!("named material \"{name}\" undefined")));
                    };
                    self.build(j)?;
                    refs[k] = j;
                }
                Material::Mix { amount, m1: refs[0], m2: refs[1] }
            }
            other => {
                if self.warned_types.insert(other.to_string()) {
                    let msg = format!("material \"{other}\" unknown: rendering it as \"matte\" with its Kd");
                    w.warn(Some(e.loc.clone()), msg);
                }
                let kd = tx.get_spectrum_param(p, "Kd", one(0.5), w).unwrap_or(SpectrumParam::Const(one(0.5)));
                p.mark_all_used();
                Material::Matte { kd, sigma: FloatParam::Const(0.0), bump: None }
            }
        })
    }
}

impl Materials {
    /// Builds the materials `used` marks (indices into `desc.materials`) and the
    /// named materials used `mix`es refer to, building the textures they reference.
    pub fn build(
        desc: &SceneDescription,
        used: &[bool],
        textures: &mut Textures,
        warnings: &DiagSink,
    ) -> Result<Materials, Diagnostic> {
        let n = desc.materials.len();
        let mut b = Builder {
            desc,
            textures,
            warnings,
            states: (0..n).map(|_| BuildState::Unbuilt).collect(),
            warned_types: HashSet::new(),
        };
        for (i, &u) in used.iter().enumerate().take(n) {
            if u {
                b.build(i)?;
            }
        }
        let slots = b
            .states
            .into_iter()
            .map(|s| match s {
                BuildState::Built(m) => Some(m),
                _ => None,
            })
            .collect();
        Ok(Materials { slots })
    }

    /// Material `i`, if it was built.
    pub fn get(&self, i: usize) -> Option<&Material> {
        self.slots.get(i).and_then(|m| m.as_ref())
    }

    pub fn built_count(&self) -> usize {
        self.slots.iter().filter(|m| m.is_some()).count()
    }
}

fn eval_f(tx: &Textures, p: FloatParam, ctx: &TextureEvalContext) -> f32 {
    tx.eval_float(p, ctx)
}

fn eval_s(tx: &Textures, p: SpectrumParam, ctx: &TextureEvalContext) -> Rgb {
    clamp0(tx.eval_spectrum(p, ctx))
}

/// pbrt-v3's `Material::Bump`: the bumped shading normal and ∂p/∂u. The displacement is
/// differenced over half the pixel footprint in (u, v) (`du = ½(|∂u/∂x| + |∂u/∂y|)`), or over
/// 0.0005 where the ray had no differentials, as pbrt-v3.
pub fn bump(
    d: FloatParam,
    si: &SurfaceInteraction,
    geom: &ShadingGeometry,
    ctx: &TextureEvalContext,
    textures: &Textures,
) -> (Vec3, Vec3) {
    let step = |a: f32, b: f32| {
        let s = 0.5 * (a.abs() + b.abs());
        if s == 0.0 || !s.is_finite() {
            0.0005
        } else {
            s
        }
    };
    let du = step(ctx.dudx, ctx.dudy);
    let dv = step(ctx.dvdx, ctx.dvdy);
    let base = geom.dpdu.cross(geom.dpdv);
    let shifted_u = TextureEvalContext {
        p: ctx.p + du * geom.dpdu,
        uv: ctx.uv + Vec2::new(du, 0.0),
        n: (base + du * geom.dndu).normalize_or_zero(),
        ..*ctx
    };
    let shifted_v = TextureEvalContext {
        p: ctx.p + dv * geom.dpdv,
        uv: ctx.uv + Vec2::new(0.0, dv),
        n: (base + dv * geom.dndv).normalize_or_zero(),
        ..*ctx
    };
    let u_disp = textures.eval_float(d, &shifted_u);
    let v_disp = textures.eval_float(d, &shifted_v);
    let disp = textures.eval_float(d, ctx);
    let dpdu = geom.dpdu + (u_disp - disp) / du * geom.n + disp * geom.dndu;
    let dpdv = geom.dpdv + (v_disp - disp) / dv * geom.n + disp * geom.dndv;
    let ns = dpdu.cross(dpdv).normalize_or_zero();
    if ns == Vec3::ZERO || !ns.is_finite() {
        return (geom.n, geom.dpdu);
    }
    (face_forward(ns, si.n), dpdu)
}

/// What a material's BSDF is built from, shared with the sub-materials of `mix`.
struct ScatterInputs<'a> {
    si: &'a SurfaceInteraction,
    ctx: &'a TextureEvalContext,
    geom: &'a ShadingGeometry,
    opts: BsdfOptions,
    materials: &'a Materials,
    tx: &'a Textures,
}

/// The lobe builders' view of a point: textures evaluated there, and the (bumped) shading frame.
struct Lobes<'a> {
    tx: &'a Textures,
    ctx: &'a TextureEvalContext,
    opts: BsdfOptions,
    ns: Vec3,
    ss: Vec3,
    ng: Vec3,
}

impl Lobes<'_> {
    /// An empty BSDF in the shading frame with relative index of refraction `eta`.
    fn bsdf(&self, eta: f32) -> Bsdf {
        Bsdf::new(self.ns, self.ss, self.ng, eta)
    }
    /// A spectrum parameter at the point, clamped to ≥ 0.
    fn s(&self, p: SpectrumParam) -> Rgb {
        eval_s(self.tx, p, self.ctx)
    }
    fn f(&self, p: FloatParam) -> f32 {
        eval_f(self.tx, p, self.ctx)
    }
}

/// `glass`: specular or microfacet reflection and transmission (one `FresnelSpecular` lobe
/// for smooth glass when the integrator allows multiple-lobe BxDFs). `rough` = [u, v].
fn glass(
    l: &Lobes,
    kr: SpectrumParam,
    kt: SpectrumParam,
    eta: FloatParam,
    rough: [FloatParam; 2],
    remap: bool,
) -> Bsdf {
    let eta = l.f(eta);
    let ur = l.f(rough[0]);
    let vr = l.f(rough[1]);
    let r = l.s(kr);
    let t = l.s(kt);
    let mut b = l.bsdf(eta);
    if is_black(r) && is_black(t) {
        return b;
    }
    let specular = ur == 0.0 && vr == 0.0;
    if specular && l.opts.allow_multiple_lobes {
        let _ = b.add(Bxdf::fresnel_specular(r, t, 1.0, eta, l.opts.mode));
        return b;
    }
    let distrib = trowbridge(ur, vr, remap);
    if !is_black(r) {
        let fresnel = Fresnel::Dielectric { eta_i: 1.0, eta_t: eta };
        let _ = b.add(if specular {
            Bxdf::specular_reflection(r, fresnel)
        } else {
            Bxdf::microfacet_reflection(r, distrib, fresnel)
        });
    }
    if !is_black(t) {
        let _ = b.add(if specular {
            Bxdf::specular_transmission(t, 1.0, eta, l.opts.mode)
        } else {
            Bxdf::microfacet_transmission(t, distrib, 1.0, eta, l.opts.mode)
        });
    }
    b
}

/// `translucent`: diffuse and glossy reflection and transmission; `k` = [Kd, Ks],
/// `rt` = [reflect, transmit].
fn translucent(l: &Lobes, k: [SpectrumParam; 2], rt: [SpectrumParam; 2], roughness: FloatParam, remap: bool) -> Bsdf {
    let eta = 1.5;
    let mut b = l.bsdf(eta);
    let r = l.s(rt[0]);
    let t = l.s(rt[1]);
    if is_black(r) && is_black(t) {
        return b;
    }
    let kd = l.s(k[0]);
    if !is_black(kd) {
        if !is_black(r) {
            let _ = b.add(Bxdf::lambertian_reflection(r * kd));
        }
        if !is_black(t) {
            let _ = b.add(Bxdf::lambertian_transmission(t * kd));
        }
    }
    let ks = l.s(k[1]);
    if !is_black(ks) && (!is_black(r) || !is_black(t)) {
        let rough = l.f(roughness);
        let distrib = trowbridge(rough, rough, remap);
        if !is_black(r) {
            let fresnel = Fresnel::Dielectric { eta_i: 1.0, eta_t: eta };
            let _ = b.add(Bxdf::microfacet_reflection(r * ks, distrib, fresnel));
        }
        if !is_black(t) {
            let _ = b.add(Bxdf::microfacet_transmission(t * ks, distrib, 1.0, eta, l.opts.mode));
        }
    }
    b
}

fn trowbridge(urough: f32, vrough: f32, remap: bool) -> MicrofacetDistribution {
    if remap {
        MicrofacetDistribution::trowbridge_reitz(roughness_to_alpha(urough), roughness_to_alpha(vrough))
    } else {
        MicrofacetDistribution::trowbridge_reitz(urough, vrough)
    }
}

impl Material {
    fn bump_map(&self) -> Option<FloatParam> {
        match self {
            Material::Matte { bump, .. }
            | Material::Plastic { bump, .. }
            | Material::Metal { bump, .. }
            | Material::Mirror { bump, .. }
            | Material::Glass { bump, .. }
            | Material::Substrate { bump, .. }
            | Material::Uber { bump, .. }
            | Material::Translucent { bump, .. } => *bump,
            Material::Disney(d) => d.bump,
            Material::Fourier(f) => f.bump,
            Material::Subsurface(s) => s.bump,
            Material::Mix { .. } | Material::Hair(_) => None,
        }
    }

    /// The BSDF at `si` as pbrt-v3's `directlighting` builds it (radiance transport,
    /// no multiple-lobe glass), with `si`'s differentials and shading geometry.
    pub fn compute_bsdf(&self, si: &SurfaceInteraction, materials: &Materials, textures: &Textures) -> Bsdf {
        self.compute_bsdf_ext(
            si,
            &TextureEvalContext::from_si(si),
            &ShadingGeometry::of(si),
            BsdfOptions::default(),
            materials,
            textures,
        )
    }

    /// The BSDF with an explicit texture context (e.g. with differentials), shading geometry and options.
    pub fn compute_bsdf_ext(
        &self,
        si: &SurfaceInteraction,
        ctx: &TextureEvalContext,
        geom: &ShadingGeometry,
        opts: BsdfOptions,
        materials: &Materials,
        textures: &Textures,
    ) -> Bsdf {
        self.scatter(&ScatterInputs { si, ctx, geom, opts, materials, tx: textures }, 0)
    }

    fn frame(
        &self,
        si: &SurfaceInteraction,
        ctx: &TextureEvalContext,
        geom: &ShadingGeometry,
        tx: &Textures,
    ) -> (Vec3, Vec3) {
        match self.bump_map() {
            Some(d) => bump(d, si, geom, ctx, tx),
            None => (geom.n, geom.dpdu),
        }
    }

    /// pbrt-v3's `ComputeScatteringFunctions`: the lobes of each material (`depth` counts the
    /// `mix` nesting, cut at 16).
    fn scatter(&self, inp: &ScatterInputs, depth: u32) -> Bsdf {
        let (ns, ss) = self.frame(inp.si, inp.ctx, inp.geom, inp.tx);
        let l = Lobes { tx: inp.tx, ctx: inp.ctx, opts: inp.opts, ns, ss, ng: inp.si.n };
        match *self {
            Material::Matte { kd, sigma, .. } => {
                let mut b = l.bsdf(1.0);
                let r = l.s(kd);
                let sig = l.f(sigma).clamp(0.0, 90.0);
                if !is_black(r) {
                    let lobe = if sig == 0.0 { Bxdf::lambertian_reflection(r) } else { Bxdf::oren_nayar(r, sig) };
                    let _ = b.add(lobe);
                }
                b
            }
            Material::Plastic { kd, ks, roughness, remap, .. } => {
                let mut b = l.bsdf(1.0);
                let kd = l.s(kd);
                if !is_black(kd) {
                    let _ = b.add(Bxdf::lambertian_reflection(kd));
                }
                let ks = l.s(ks);
                if !is_black(ks) {
                    let r = l.f(roughness);
                    let fresnel = Fresnel::Dielectric { eta_i: 1.5, eta_t: 1.0 };
                    let _ = b.add(Bxdf::microfacet_reflection(ks, trowbridge(r, r, remap), fresnel));
                }
                b
            }
            Material::Metal { eta, k, roughness, uroughness, vroughness, remap, .. } => {
                let mut b = l.bsdf(1.0);
                let ur = l.f(uroughness.unwrap_or(roughness));
                let vr = l.f(vroughness.unwrap_or(roughness));
                let fresnel = Fresnel::Conductor {
                    eta_i: Rgb::ONE,
                    eta_t: l.tx.eval_spectrum(eta, l.ctx),
                    k: l.tx.eval_spectrum(k, l.ctx),
                };
                let _ = b.add(Bxdf::microfacet_reflection(Rgb::ONE, trowbridge(ur, vr, remap), fresnel));
                b
            }
            Material::Mirror { kr, .. } => {
                let mut b = l.bsdf(1.0);
                let r = l.s(kr);
                if !is_black(r) {
                    let _ = b.add(Bxdf::specular_reflection(r, Fresnel::NoOp));
                }
                b
            }
            Material::Glass { kr, kt, eta, uroughness, vroughness, remap, .. } => {
                glass(&l, kr, kt, eta, [uroughness, vroughness], remap)
            }
            Material::Substrate { kd, ks, uroughness, vroughness, remap, .. } => {
                let mut b = l.bsdf(1.0);
                let d = l.s(kd);
                let s = l.s(ks);
                let ur = l.f(uroughness);
                let vr = l.f(vroughness);
                if !is_black(d) || !is_black(s) {
                    let _ = b.add(Bxdf::fresnel_blend(d, s, trowbridge(ur, vr, remap)));
                }
                b
            }
            Material::Uber { .. } => self.uber(&l),
            Material::Translucent { kd, ks, reflect, transmit, roughness, remap, .. } => {
                translucent(&l, [kd, ks], [reflect, transmit], roughness, remap)
            }
            Material::Mix { amount, m1, m2 } => self.mix(inp, &l, amount, [m1, m2], depth),
            Material::Disney(ref d) => d.scatter(&l),
            Material::Fourier(ref f) => f.scatter(&l),
            Material::Hair(ref h) => h.scatter(&l, inp.si),
            Material::Subsurface(ref s) => s.scatter(&l),
        }
    }

    /// `uber`: a specular transmission for `1 − opacity`, then diffuse, glossy, specular
    /// reflection and specular transmission lobes scaled by `opacity`.
    fn uber(&self, l: &Lobes) -> Bsdf {
        let Material::Uber { kd, ks, kr, kt, roughness, uroughness, vroughness, eta, opacity, remap, .. } = *self
        else {
            unreachable!("Material::uber on another material")
        };
        let e = l.f(eta);
        let op = l.s(opacity);
        let t = clamp0(Rgb::ONE - op);
        let mut b;
        if !is_black(t) {
            b = l.bsdf(1.0);
            let _ = b.add(Bxdf::specular_transmission(t, 1.0, 1.0, l.opts.mode));
        } else {
            b = l.bsdf(e);
        }
        let kd = op * l.s(kd);
        if !is_black(kd) {
            let _ = b.add(Bxdf::lambertian_reflection(kd));
        }
        let ks = op * l.s(ks);
        if !is_black(ks) {
            let ur = l.f(uroughness.unwrap_or(roughness));
            let vr = match vroughness {
                Some(v) => l.f(v),
                None => ur,
            };
            let fresnel = Fresnel::Dielectric { eta_i: 1.0, eta_t: e };
            let _ = b.add(Bxdf::microfacet_reflection(ks, trowbridge(ur, vr, remap), fresnel));
        }
        let kr = op * l.s(kr);
        if !is_black(kr) {
            let _ = b.add(Bxdf::specular_reflection(kr, Fresnel::Dielectric { eta_i: 1.0, eta_t: e }));
        }
        let kt = op * l.s(kt);
        if !is_black(kt) {
            let _ = b.add(Bxdf::specular_transmission(kt, 1.0, e, l.opts.mode));
        }
        b
    }

    /// `mix`: the lobes of `m[0]` scaled by `amount` and of `m[1]` by `1 − amount`, in `m[0]`'s
    /// shading frame (a missing sub-material, or nesting past 16, is an empty BSDF).
    fn mix(&self, inp: &ScatterInputs, l: &Lobes, amount: SpectrumParam, m: [usize; 2], depth: u32) -> Bsdf {
        let s1 = l.s(amount);
        let s2 = clamp0(Rgb::ONE - s1);
        let sub = |m: usize| -> Bsdf {
            match inp.materials.get(m) {
                Some(mat) if depth < 16 => mat.scatter(inp, depth + 1),
                _ => l.bsdf(1.0),
            }
        };
        let b1 = sub(m[0]);
        let b2 = sub(m[1]);
        let mut b = Bsdf::new(b1.shading_normal(), b1.local_to_world(Vec3::X), b1.geometric_normal(), b1.eta);
        for l in b1.bxdfs() {
            let _ = b.add(l.scaled(s1));
        }
        for l in b2.bxdfs() {
            let _ = b.add(l.scaled(s2));
        }
        b
    }

    /// Whether a BSDF of this material may have a perfectly specular lobe: `false` is a
    /// guarantee (matte, plastic, metal, substrate, translucent, fourier, hair; uber with
    /// constant black `Kr` and `Kt` and constant opacity 1; disney without a scatter distance),
    /// `true` a maybe (mirror, glass, mix, subsurface, other uber and disney). For
    /// an integrator that builds the BSDF only to follow specular lobes.
    pub fn may_be_specular(&self) -> bool {
        match *self {
            Material::Mirror { .. } | Material::Glass { .. } | Material::Mix { .. } => true,
            // A smooth interface; `disney`'s only over a BSSRDF.
            Material::Subsurface(_) => true,
            Material::Disney(_) => self.may_have_bssrdf(),
            Material::Uber { kr, kt, opacity, .. } => {
                kr != SpectrumParam::Const(Rgb::ZERO)
                    || kt != SpectrumParam::Const(Rgb::ZERO)
                    || opacity != SpectrumParam::Const(Rgb::ONE)
            }
            _ => false,
        }
    }

    /// The material's type as a scene names it (`"matte"`, `"disney"`…; both subsurface kinds
    /// are `"subsurface"`), for warnings.
    pub fn type_name(&self) -> &'static str {
        match self {
            Material::Matte { .. } => "matte",
            Material::Plastic { .. } => "plastic",
            Material::Metal { .. } => "metal",
            Material::Mirror { .. } => "mirror",
            Material::Glass { .. } => "glass",
            Material::Substrate { .. } => "substrate",
            Material::Uber { .. } => "uber",
            Material::Mix { .. } => "mix",
            Material::Translucent { .. } => "translucent",
            Material::Disney(_) => "disney",
            Material::Fourier(_) => "fourier",
            Material::Hair(_) => "hair",
            Material::Subsurface(s) => match s.medium {
                subsurface::Medium::Coefficients { .. } => "subsurface",
                subsurface::Medium::Albedo { .. } => "kdsubsurface",
            },
        }
    }

    /// Whether the material may have a BSSRDF (`subsurface`, `kdsubsurface`, `disney` with a
    /// `scatterdistance` that is not constant black and not `thin`).
    pub fn may_have_bssrdf(&self) -> bool {
        match self {
            Material::Subsurface(_) => true,
            Material::Disney(d) => !d.thin && d.scatter_distance != SpectrumParam::Const(Rgb::ZERO),
            _ => false,
        }
    }

    /// The BSSRDF under the surface at `si` whose BSDF (built with `opts`) is `bsdf`, for the
    /// material at index `index` of `SceneDescription::materials`; `None` for materials without one.
    #[allow(clippy::too_many_arguments)]
    pub fn bssrdf<'a>(
        &'a self,
        si: &SurfaceInteraction,
        ctx: &TextureEvalContext,
        bsdf: &Bsdf,
        opts: BsdfOptions,
        textures: &'a Textures,
        index: usize,
    ) -> Option<crate::bssrdf::SeparableBssrdf<'a>> {
        let l =
            Lobes { tx: textures, ctx, opts, ns: bsdf.shading_normal(), ss: bsdf.local_to_world(Vec3::X), ng: si.n };
        match self {
            Material::Subsurface(s) => s.bssrdf(&l, bsdf, si.p, index),
            Material::Disney(d) => d.bssrdf(&l, bsdf, si.p, index),
            _ => None,
        }
    }
}

mod ltc;
pub use ltc::{LobeEval, LtcDescription, LtcFresnel, LtcLobe, LtcLobeKind, LtcLobes, MAX_LOBES};

#[cfg(test)]
mod tests;
