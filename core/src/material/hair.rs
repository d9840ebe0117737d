//! `hair`: pbrt-v3's `HairMaterial` (`materials/hair.cpp`) — the absorption from `sigma_a`,
//! else from the multiply-scattered `color`, else from `eumelanin`/`pheomelanin`
//! concentrations (default: eumelanin 1.3), and `eta`, `beta_m`, `beta_n`, `alpha` — building
//! one [`HairBxdf`] whose offset across the fibre is `h = −1 + 2v` of the surface's parametric
//! `(u, v)`, in a frame whose x axis is `∂p/∂u`, as pbrt-v3 does on every shape.
//!
//! On pbrt-v3's `curve` shapes `u` runs along the fibre and `v` across its width, so `h` is
//! where the ray met the fibre. On any other shape the same rule applies to that shape's own
//! parameterisation (pbrt-v3 renders it so): on a `cylinder`, `u` goes round the axis and `v`
//! along it, so the cylinder is a fibre bent into a ring round its axis whose width runs along
//! the axis — a short cylinder of height 2r is a ring-shaped fibre seen as a ribbon. The frame
//! is taken from the interaction's `∂p/∂u` (not the bump-mapped shading tangent; pbrt-v3's
//! hair has no bump map), oriented like pbrt-v3's analytic shapes and curves.

use super::{FloatParam, Lobes, SpectrumParam};
use crate::bxdf::hair::{sigma_a_from_concentration, sigma_a_from_reflectance};
use crate::bxdf::{Bsdf, Bxdf, HairBxdf};
use crate::interaction::SurfaceInteraction;
use crate::spectrum::Rgb;
use crate::texture::Textures;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

/// Where the fibre's absorption comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Absorption {
    SigmaA(SpectrumParam),
    /// The colour of the multiply-scattered fibre (Chiang et al.'s inversion).
    Color(SpectrumParam),
    Melanin {
        eumelanin: Option<FloatParam>,
        pheomelanin: Option<FloatParam>,
    },
}

/// The parameters of pbrt-v3's `hair`.
#[derive(Clone, Debug, PartialEq)]
pub struct Hair {
    pub absorption: Absorption,
    pub eta: FloatParam,
    pub beta_m: FloatParam,
    pub beta_n: FloatParam,
    pub alpha: FloatParam,
}

impl Hair {
    /// pbrt-v3's `CreateHairMaterial`, with its warnings for parameters that are ignored.
    pub fn create(
        tx: &mut Textures,
        p: &ParamSet,
        w: &DiagSink,
        loc: &penumbra_parser::FileLoc,
    ) -> Result<Hair, Diagnostic> {
        let sigma_a = tx.get_spectrum_param_opt(p, "sigma_a", w)?;
        let color = tx.get_spectrum_param_opt(p, "color", w)?;
        let eumelanin = tx.get_float_param_opt(p, "eumelanin", w)?;
        let pheomelanin = tx.get_float_param_opt(p, "pheomelanin", w)?;
        let ignored = |name: &str, since: &str| {
            let at = p.loc_of(name).cloned().unwrap_or_else(|| loc.clone());
            w.warn(Some(at), format!("hair: ignoring \"{name}\" since \"{since}\" was given"));
        };
        let absorption = if let Some(s) = sigma_a {
            for (name, given) in [("color", color.is_some()), ("eumelanin", eumelanin.is_some())] {
                if given {
                    ignored(name, "sigma_a");
                }
            }
            if pheomelanin.is_some() {
                ignored("pheomelanin", "sigma_a");
            }
            Absorption::SigmaA(s)
        } else if let Some(c) = color {
            if eumelanin.is_some() {
                ignored("eumelanin", "color");
            }
            if pheomelanin.is_some() {
                ignored("pheomelanin", "color");
            }
            Absorption::Color(c)
        } else if eumelanin.is_some() || pheomelanin.is_some() {
            Absorption::Melanin { eumelanin, pheomelanin }
        } else {
            Absorption::SigmaA(SpectrumParam::Const(sigma_a_from_concentration(1.3, 0.0)))
        };
        Ok(Hair {
            absorption,
            eta: tx.get_float_param(p, "eta", 1.55, w)?,
            beta_m: tx.get_float_param(p, "beta_m", 0.3, w)?,
            beta_n: tx.get_float_param(p, "beta_n", 0.3, w)?,
            alpha: tx.get_float_param(p, "alpha", 2.0, w)?,
        })
    }

    /// pbrt-v3's `HairMaterial::ComputeScatteringFunctions`.
    pub(super) fn scatter(&self, l: &Lobes, si: &SurfaceInteraction) -> Bsdf {
        let (bm, bn, alpha, e) = (l.f(self.beta_m), l.f(self.beta_n), l.f(self.alpha), l.f(self.eta));
        let sigma_a = match &self.absorption {
            Absorption::SigmaA(s) => l.s(*s),
            Absorption::Color(c) => sigma_a_from_reflectance(l.s(*c), bn),
            Absorption::Melanin { eumelanin, pheomelanin } => {
                let conc = |p: &Option<FloatParam>| p.map_or(0.0, |p| l.f(p).max(0.0));
                sigma_a_from_concentration(conc(eumelanin), conc(pheomelanin))
            }
        };
        let h = -1.0 + 2.0 * si.uv.y;
        let mut b = Bsdf::new(l.ns, si.dpdu, l.ng, e);
        let _ = b.add(Bxdf::Hair(HairBxdf::new(h, e, sigma_a.max(Rgb::ZERO), bm, bn, alpha)));
        b
    }
}
