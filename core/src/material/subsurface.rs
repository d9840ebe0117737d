//! `subsurface` and `kdsubsurface`: pbrt-v3's `SubsurfaceMaterial` and `KdSubsurfaceMaterial`
//! — a smooth or rough dielectric interface (`Kr`, `Kt`, `eta`, `uroughness`, `vroughness`,
//! exactly `glass`'s lobes, with a BSDF index `eta`) over a homogeneous medium whose light
//! leaves through the photon-beam-diffusion BSSRDF ([`crate::bssrdf`]).
//!
//! * `subsurface`: `sigma_a`, `sigma_s` (textures, in mm⁻¹ as pbrt-v3's defaults, those of
//!   whole milk) times `scale`; or the coefficients of a measured medium by `"string name"`
//!   (which also sets `g` to 0: the table's `σ'_s` are reduced coefficients); `g` (float).
//! * `kdsubsurface`: `Kd` (the effective albedo) and `mfp` (the mean free path) times
//!   `scale`, inverted into `σ_s`, `σ_a` through the table's effective albedos; `g`.
//!
//! `path` renders the BSSRDF as pbrt-v3's path tracer does. Every other integrator, as
//! pbrt-v3's `directlighting` and `whitted`, renders the interface alone (light refracted into
//! the object passes through it as through glass); penumbra warns once when such an
//! integrator meets one of these materials.

use super::{glass, FloatParam, Lobes, SpectrumParam};
use crate::bssrdf::{measured_medium, subsurface_from_diffuse, BssrdfTable, Profile, SeparableBssrdf};
use crate::bxdf::Bsdf;
use crate::spectrum::Rgb;
use crate::texture::Textures;
use penumbra_parser::{DiagSink, Diagnostic, FileLoc, ParamSet};
use std::sync::{Arc, OnceLock};

/// How the medium's coefficients are given.
#[derive(Clone, Debug, PartialEq)]
pub enum Medium {
    /// `subsurface`: absorption and scattering coefficients.
    Coefficients { sigma_a: SpectrumParam, sigma_s: SpectrumParam },
    /// `kdsubsurface`: effective albedo and mean free path.
    Albedo { kd: SpectrumParam, mfp: SpectrumParam },
}

/// `subsurface` or `kdsubsurface`.
#[derive(Clone, Debug)]
pub struct Subsurface {
    pub medium: Medium,
    pub scale: f32,
    pub g: f32,
    pub eta: f32,
    pub kr: SpectrumParam,
    pub kt: SpectrumParam,
    pub uroughness: FloatParam,
    pub vroughness: FloatParam,
    pub remap: bool,
    pub bump: Option<FloatParam>,
    /// The beam-diffusion table for `(g, eta)`, computed when `path` first asks for it.
    table: Arc<OnceLock<BssrdfTable>>,
}

impl PartialEq for Subsurface {
    fn eq(&self, o: &Self) -> bool {
        (&self.medium, self.scale, self.g, self.eta, self.kr, self.kt) == (&o.medium, o.scale, o.g, o.eta, o.kr, o.kt)
            && (self.uroughness, self.vroughness, self.remap, self.bump)
                == (o.uroughness, o.vroughness, o.remap, o.bump)
    }
}

impl Subsurface {
    /// pbrt-v3's `CreateSubsurfaceMaterial` (`kd` false) or `CreateKdSubsurfaceMaterial`.
    pub fn create(
        tx: &mut Textures,
        p: &ParamSet,
        w: &DiagSink,
        loc: &FileLoc,
        kd: bool,
    ) -> Result<Subsurface, Diagnostic> {
        let mut g = p.get_one_float("g", 0.0);
        let medium = if kd {
            Medium::Albedo {
                kd: tx.get_spectrum_param(p, "Kd", Rgb::splat(0.5), w)?,
                mfp: tx.get_spectrum_param(p, "mfp", Rgb::ONE, w)?,
            }
        } else {
            // Whole milk (Jensen et al. 2001), pbrt-v3's default.
            let (mut sig_a, mut sig_s) = (Rgb::new(0.0011, 0.0024, 0.014), Rgb::new(2.55, 3.21, 3.77));
            let name = p.get_one_string("name", "");
            if !name.is_empty() {
                match measured_medium(&name) {
                    Some((a, s)) => {
                        (sig_a, sig_s) = (a, s);
                        g = 0.0;
                    }
                    None => {
                        let at = p.loc_of("name").cloned().unwrap_or_else(|| loc.clone());
                        w.warn(Some(at), format!("subsurface: named medium \"{name}\" not found: using the defaults"));
                    }
                }
            }
            Medium::Coefficients {
                sigma_a: tx.get_spectrum_param(p, "sigma_a", sig_a, w)?,
                sigma_s: tx.get_spectrum_param(p, "sigma_s", sig_s, w)?,
            }
        };
        Ok(Subsurface {
            medium,
            scale: p.get_one_float("scale", 1.0),
            g,
            eta: p.get_one_float("eta", 1.33),
            kr: tx.get_spectrum_param(p, "Kr", Rgb::ONE, w)?,
            kt: tx.get_spectrum_param(p, "Kt", Rgb::ONE, w)?,
            uroughness: tx.get_float_param(p, "uroughness", 0.0, w)?,
            vroughness: tx.get_float_param(p, "vroughness", 0.0, w)?,
            remap: p.get_one_bool("remaproughness", true),
            bump: tx.get_float_param_opt(p, "bumpmap", w)?,
            table: Arc::new(OnceLock::new()),
        })
    }

    /// The interface: `glass`'s lobes with index `eta`.
    pub(super) fn scatter(&self, l: &Lobes) -> Bsdf {
        glass(l, self.kr, self.kt, FloatParam::Const(self.eta), [self.uroughness, self.vroughness], self.remap)
    }

    /// The BSSRDF at the point whose BSDF is `bsdf` (pbrt-v3's `TabulatedBSSRDF`).
    pub(super) fn bssrdf<'a>(
        &'a self,
        l: &Lobes,
        bsdf: &Bsdf,
        p: glam::Vec3,
        material: usize,
    ) -> Option<SeparableBssrdf<'a>> {
        let table = self.table.get_or_init(|| BssrdfTable::beam_diffusion(self.g, self.eta));
        let (sigma_a, sigma_s) = match self.medium {
            Medium::Coefficients { sigma_a, sigma_s } => (self.scale * l.s(sigma_a), self.scale * l.s(sigma_s)),
            Medium::Albedo { kd, mfp } => {
                let (s, a) = subsurface_from_diffuse(table, l.s(kd), self.scale * l.s(mfp));
                (a, s)
            }
        };
        Some(SeparableBssrdf {
            p,
            ns: bsdf.shading_normal(),
            ss: bsdf.local_to_world(glam::Vec3::X),
            ts: bsdf.local_to_world(glam::Vec3::Y),
            eta: self.eta,
            material,
            profile: Profile::tabulated(table, sigma_a, sigma_s),
        })
    }
}
