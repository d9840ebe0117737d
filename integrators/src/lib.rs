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

use common::params::ParamSpec;
use penumbra_core::integrator::Integrator;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub type Constructor = fn(&ParamSet, &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic>;

/// An integrator penumbra implements: everything known about it besides its code.
pub struct Entry {
    /// Its name (`-i NAME`, the scene's `Integrator "NAME"`).
    pub name: &'static str,
    /// One line: the method and its source.
    pub method: &'static str,
    pub create: Constructor,
    /// The parameters it reads ([`common::params`]): what `--param` accepts, `render --help`
    /// and the docs list.
    pub params: &'static [ParamSpec],
    /// The registered estimator its images converge to (`sweep --reference-spp` renders it
    /// unless told otherwise): AO images are not direct lighting, and `path` and `whitted` see
    /// more than it does. A reference is its own reference.
    pub reference: &'static str,
}

/// pbrt-v3's direct lighting: the estimator the direct-illumination methods converge to and
/// are compared with (a sweep's default target error is the one it reaches).
pub const DIRECT_LIGHTING: &str = "directlighting";

pub const REGISTRY: &[Entry] = &[
    Entry {
        name: DIRECT_LIGHTING,
        method: "pbrt-v3 direct lighting: light + BSDF sampling with MIS, strategy all/one, specular recursion",
        create: directlighting::DirectLighting::create,
        params: directlighting::PARAMS,
        reference: DIRECT_LIGHTING,
    },
    Entry {
        name: "path",
        method: "pbrt-v3 path tracing: one light per vertex (spatial/uniform/power) with MIS, Russian roulette",
        create: path::PathIntegrator::create,
        params: path::PARAMS,
        reference: "path",
    },
    Entry {
        name: "whitted",
        method: "pbrt-v3 Whitted ray tracing: every light one sample, perfect specular reflection and transmission",
        create: whitted::Whitted::create,
        params: whitted::PARAMS,
        reference: "whitted",
    },
    Entry {
        name: "ltc",
        method: "analytic area-light shading and soft shadows with Linearly Transformed Cosines (seed 004)",
        create: ltc::LtcIntegrator::create,
        params: ltc::PARAMS,
        reference: DIRECT_LIGHTING,
    },
    Entry {
        name: "ratio",
        method: "analytic LTC shading × denoised stochastic shadow ratio S_N/U_N (Heitz, Hill & McGuire 2018)",
        create: ratio::RatioIntegrator::create,
        params: ratio::PARAMS,
        reference: DIRECT_LIGHTING,
    },
    Entry {
        name: "silhouette",
        method: "semi-analytic integration along visibility silhouettes: 4D dual-edge contours, depth complexity along meridians (seed 000)",
        create: silhouette::Silhouette::create,
        params: silhouette::PARAMS,
        reference: DIRECT_LIGHTING,
    },
    Entry {
        name: "shexp",
        method: "environment soft shadows from sphere-set occluders by SH exponentiation (seed 003)",
        create: shexp::Shexp::create,
        params: shexp::PARAMS,
        reference: DIRECT_LIGHTING,
    },
    Entry {
        name: "ambientocclusion",
        method: "ray-traced ambient occlusion (pbrt-v3 semantics: nsamples, cossample; pbrt-v4's maxdistance)",
        create: ambientocclusion::AmbientOcclusion::create,
        params: ambientocclusion::PARAMS,
        reference: "ambientocclusion",
    },
    Entry {
        name: "sheared-ao",
        method: "sparse ray-traced AO, neighbours' rays warped and weighted by a sheared filter (Egan et al. 2011, seed 002)",
        create: sheared_ao::ShearedAo::create,
        params: sheared_ao::PARAMS,
        reference: "ambientocclusion",
    },
];

/// Integrators that [`find`] knows but [`names`] and [`REGISTRY`] do not list: test-only
/// estimators, deliberately wrong, that show a check catches what it claims to.
pub const HIDDEN: &[Entry] = &[Entry {
    name: ambientocclusion::FIXED_EPSILON_NAME,
    method:
        "ambientocclusion with a fixed absolute ray epsilon (deliberately unstable, for penumbra stability's tests)",
    create: ambientocclusion::AmbientOcclusion::create_fixed_epsilon,
    params: ambientocclusion::PARAMS,
    reference: "ambientocclusion",
}];

/// pbrt-v3 integrators penumbra does not implement; scenes naming them render with the fallback.
pub const PBRT_UNIMPLEMENTED: &[&str] = &["volpath", "bdpt", "mlt", "sppm"];

pub fn names() -> Vec<&'static str> {
    REGISTRY.iter().map(|e| e.name).collect()
}

pub fn find(name: &str) -> Option<&'static Entry> {
    REGISTRY.iter().chain(HIDDEN).find(|e| e.name == name)
}

/// The registered [`Entry::reference`] of `name` ([`DIRECT_LIGHTING`] for a name not registered).
pub fn natural_reference(name: &str) -> &'static str {
    find(name).map_or(DIRECT_LIGHTING, |e| e.reference)
}

/// `render --help`'s list of the registered integrators and their parameters.
pub fn help_text() -> String {
    let mut o =
        String::from("Integrators (-i NAME) and their parameters (--param NAME=VALUE; name: type = default):\n");
    for e in REGISTRY {
        o += &format!("  {}: {}\n", e.name, e.method);
        o += &common::params::help_text(e.params);
    }
    o
}

/// The page that documents integrator `name`, relative to the repository's root.
pub fn doc_page(name: &str) -> String {
    format!("docs/integrators/{name}.md")
}

/// Marks the generated parameter table in an integrator's page ([`with_generated_params`]).
pub const PARAMS_BEGIN: &str =
    "<!-- integrator-params:begin (generated from the registry: cargo run -p penumbra-integrators --example generate-docs) -->";
pub const PARAMS_END: &str = "<!-- integrator-params:end -->";
/// Marks the generated integrator table in the README ([`with_generated_table`]).
pub const TABLE_BEGIN: &str =
    "<!-- integrator-table:begin (generated from the registry: cargo run -p penumbra-integrators --example generate-docs) -->";
pub const TABLE_END: &str = "<!-- integrator-table:end -->";

/// `text` with what lies between the lines `begin` and `end` replaced by `generated`.
fn replace_between(text: &str, begin: &str, end: &str, generated: &str, what: &str) -> Result<String, String> {
    let b = text.find(begin).ok_or_else(|| format!("{what}: the marker `{begin}` is missing"))?;
    let e = text.find(end).ok_or_else(|| format!("{what}: the marker `{end}` is missing"))?;
    let from = b + begin.len();
    if e < from {
        return Err(format!("{what}: the end marker comes before the begin marker"));
    }
    Ok(format!("{}\n\n{}\n{}", &text[..from], generated.trim_end(), &text[e..]))
}

/// `page` (the text of `entry`'s [`doc_page`]) with its parameter table, between
/// [`PARAMS_BEGIN`] and [`PARAMS_END`], generated from `entry.params`.
pub fn with_generated_params(entry: &Entry, page: &str) -> Result<String, String> {
    replace_between(page, PARAMS_BEGIN, PARAMS_END, &common::params::markdown(entry.params), &doc_page(entry.name))
}

/// The README's integrator table: one line per registered integrator, linking its page.
pub fn integrator_table() -> String {
    let mut o = String::from("| integrator | method (its page: parameters, measurements, limits) |\n|---|---|\n");
    for e in REGISTRY {
        o += &format!("| [`{}`]({}) | {} |\n", e.name, doc_page(e.name), e.method.replace('|', "\\|"));
    }
    o
}

/// `readme` with its integrator table, between [`TABLE_BEGIN`] and [`TABLE_END`], generated.
pub fn with_generated_table(readme: &str) -> Result<String, String> {
    replace_between(readme, TABLE_BEGIN, TABLE_END, &integrator_table(), "README.md")
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::params::{DefaultValue, Kind};
    use penumbra_parser::{FileLoc, Param, ParamValue};
    use std::sync::Arc;

    /// A valid value of every declared parameter (bools true, so that parameters read only
    /// when a switch is on are read too).
    fn value_of(spec: &ParamSpec) -> ParamValue {
        match (spec.kind, spec.default) {
            (Kind::Int, DefaultValue::Int(v)) => ParamValue::Int(vec![v]),
            (Kind::Float, DefaultValue::Float(v)) => ParamValue::Float(vec![v]),
            (Kind::Bool, _) => ParamValue::Bool(vec![true]),
            (Kind::Enum(words), _) => ParamValue::String(vec![words[words.len() - 1].to_string()]),
            (Kind::Ints(n), _) => ParamValue::Int((0..n as i32).map(|i| i % 2).collect()),
            (kind, default) => panic!("{}: no test value for {kind:?} with default {default:?}", spec.name),
        }
    }

    /// Every natural reference is registered and is its own reference (a sweep's reference
    /// must not itself need another).
    #[test]
    fn references_are_registered_fixed_points() {
        for e in REGISTRY.iter().chain(HIDDEN) {
            let r =
                find(e.reference).unwrap_or_else(|| panic!("{}: reference {} is not registered", e.name, e.reference));
            assert_eq!(r.reference, r.name, "{}: its reference {} has another reference", e.name, r.name);
        }
        let mut names = names();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), REGISTRY.len(), "a name registered twice");
    }

    #[test]
    fn every_declared_parameter_is_read_and_defaults_are_quiet() {
        for e in REGISTRY {
            let warnings = DiagSink::new();
            assert!((e.create)(&ParamSet::new(), &warnings).is_ok(), "{}: defaults", e.name);
            assert!(warnings.take().is_empty(), "{}: defaults warn", e.name);
            let mut names: Vec<_> = e.params.iter().map(|s| s.name).collect();
            names.sort_unstable();
            names.dedup();
            assert_eq!(names.len(), e.params.len(), "{}: a parameter declared twice", e.name);
            let mut set = ParamSet::new();
            for s in e.params {
                set.add(Param::new(s.name, value_of(s), FileLoc::new(Arc::from("t.pbrt"), 1, 1)));
            }
            if let Err(d) = (e.create)(&set, &warnings) {
                panic!("{}: {}", e.name, d.message);
            }
            let unused = set.report_unused(e.name);
            assert!(unused.is_empty(), "{}: declared but not read: {:?}", e.name, unused);
        }
    }
}
