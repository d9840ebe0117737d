//! One folder per integrator (`<name>/mod.rs` names the seed or paper it implements),
//! `common/` for what several share, plus the registry.

pub mod ambientocclusion;
pub mod common;
pub mod directlighting;
pub mod ltc;
pub mod path;
pub mod ratio;
pub mod sheared_ao;
pub mod shexp;
pub mod silhouette;
pub mod whitted;

use penumbra_core::integrator::Integrator;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub type Constructor = fn(&ParamSet, &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic>;

/// An integrator penumbra implements.
pub struct Entry {
    pub name: &'static str,
    pub method: &'static str,
    pub create: Constructor,
}

pub const REGISTRY: &[Entry] = &[
    Entry {
        name: "directlighting",
        method: "pbrt-v3 direct lighting: light + BSDF sampling with MIS, strategy all/one, specular recursion",
        create: directlighting::DirectLighting::create,
    },
    Entry {
        name: "path",
        method: "pbrt-v3 path tracing: one light per vertex (spatial/uniform/power) with MIS, Russian roulette",
        create: path::PathIntegrator::create,
    },
    Entry {
        name: "whitted",
        method: "pbrt-v3 Whitted ray tracing: every light one sample, perfect specular reflection and transmission",
        create: whitted::Whitted::create,
    },
    Entry {
        name: "ltc",
        method: "analytic area-light shading and soft shadows with Linearly Transformed Cosines (seed 004)",
        create: ltc::LtcIntegrator::create,
    },
    Entry {
        name: "ratio",
        method: "analytic LTC shading × denoised stochastic shadow ratio S_N/U_N (Heitz, Hill & McGuire 2018)",
        create: ratio::RatioIntegrator::create,
    },
    Entry {
        name: "silhouette",
        method: "semi-analytic integration along visibility silhouettes: 4D dual-edge contours, depth complexity along meridians (seed 000)",
        create: silhouette::Silhouette::create,
    },
    Entry {
        name: "shexp",
        method: "environment soft shadows from sphere-set occluders by SH exponentiation (seed 003)",
        create: shexp::Shexp::create,
    },
    Entry {
        name: "ambientocclusion",
        method: "ray-traced ambient occlusion (pbrt-v3 semantics: nsamples, cossample; pbrt-v4's maxdistance)",
        create: ambientocclusion::AmbientOcclusion::create,
    },
    Entry {
        name: "sheared-ao",
        method: "sparse ray-traced AO, neighbours' rays warped and weighted by a sheared filter (Egan et al. 2011, seed 002)",
        create: sheared_ao::ShearedAo::create,
    },
];

/// pbrt-v3 integrators penumbra does not implement; scenes naming them render with the fallback.
pub const PBRT_UNIMPLEMENTED: &[&str] = &["volpath", "bdpt", "mlt", "sppm"];

pub fn names() -> Vec<&'static str> {
    REGISTRY.iter().map(|e| e.name).collect()
}

pub fn find(name: &str) -> Option<&'static Entry> {
    REGISTRY.iter().find(|e| e.name == name)
}
