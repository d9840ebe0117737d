//! What the LTC shading is asked to do: how occluders are represented, whether there are
//! shadows at all, how the glossy lobes are integrated and (for the LTC alone) their Fresnel
//! applied, whether adjacent occluder triangles are merged into outlines.

use super::fresnel::FresnelMode;
use crate::common::params::{ParamSpec, Params};
use penumbra_parser::Diagnostic;

/// How the glossy lobes are integrated over the visible part of a light (`"string glossy"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Glossy {
    /// The material's own lobe: the LTC integral plus the residual by quadrature in the LTC's
    /// cosine space ([`crate::common::ltc::quadrature`]), to a relative tolerance of 1e-3.
    Exact,
    /// The LTC alone (Heitz et al. 2016, the paper's method), with `"fresnel"`'s treatment.
    Ltc,
}

impl Glossy {
    /// `"string glossy"`, read by `ltc` and `ratio`.
    pub const PARAM: ParamSpec = ParamSpec::choice(
        "glossy",
        &["exact", "ltc"],
        "glossy lobes: the material's own (LTC integral plus the residual by quadrature) or the LTC fit alone (the paper's)",
    );

    pub fn from_params(params: &Params) -> Result<Glossy, Diagnostic> {
        params.choice("glossy", [Glossy::Exact, Glossy::Ltc])
    }
}

/// How occluders (and light meshes) are turned into spherical polygons (`ltc`'s `"string mode"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One silhouette loop per closed mesh.
    Silhouette,
    /// Every light and every occluder as its triangles.
    PerTriangle,
    /// Silhouettes for objects proven closed and convex, triangles otherwise.
    Auto,
}

/// The settings of an [`LtcShader`](super::LtcShader).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderSettings {
    pub mode: Mode,
    /// Analytic visibility (false: the unshadowed term only).
    pub shadows: bool,
    pub glossy: Glossy,
    pub fresnel: FresnelMode,
    /// Occluder triangles of one object that lie wholly in front of the light are subtracted
    /// as their outline (false: triangle by triangle; the same image).
    pub merge_occluders: bool,
}
