//! The `stability` command line ([`StabilityArgs`]), its tolerances ([`Tolerances`]) and
//! validation ([`setup`]): every integrator is created once before anything renders.

use super::variants::{self, Variant};
use super::{fail, Failure};
use crate::cli::print_new_warnings;
use crate::cli::{spp_parser, RenderFlags};
use penumbra::cli_params;
use penumbra::pipeline;
use penumbra_core::integrator::Integrator;
use penumbra_parser::{DiagSink, Param, SceneDescription};
use std::collections::BTreeSet;
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(after_help = "\
Variants (default: all that apply to the scene): scale-1e-4, scale-1e4 (and --scales): the whole
scene, camera included, scaled (point-like lights' intensity by s^2, so the image must not change);
rotate: everything turned 37 degrees about (1,2,3) around the scene's centre; translate-1e2,
translate-1e4 (--translations): moved by that many scene extents (the error is reported against the
distance); light-1e6, light-1e-6: every light's scale multiplied (the image scales exactly: compared
after dividing, or unchanged where the image does not depend on the lights, e.g. ambient occlusion,
whichever is nearer); tiny-light: area lights shrunk 1000x at constant power; grazing-light: area
lights turned 89 degrees about an axis in their plane; duplicate: one shape written twice
(coincident); offset-copy: and its copy moved by 1e-6 of its size; roughness-0, roughness-1: every
microfacet roughness at the clamps. Groups: all, scale, translate, light, roughness, geometry.

Per integrator and variant: non-finite and negative pixels, pixels above the bound the integrator
declares (ltc: its unshadowed render; ambientocclusion: pi, 2pi with uniform sampling), the largest
|z| of the difference from the base render against both renders' per-pixel variance (plus a floor
of 1e-4 of the value), the fraction of pixels with |z| > 3, the relative RMS difference and seconds.
tiny-light, grazing-light and roughness-* change the image: only their counts are gated.

--fail-on KEY=VALUE[,...] (default z=8,negative=0,bound=0,far=100; `none`: only non-finite values
fail): z: largest |z| allowed on the variants that must not change the image; negative, bound:
pixels allowed; far: translations beyond this many extents are reported, not gated.

Exit codes (as `diff`'s scheme): 0 stable, 1 a tolerance exceeded, 2 non-finite values,
4 an unreadable scene, bad option value or failed render; 64 command-line usage error.")]
pub struct StabilityArgs {
    /// The pbrt-v3 scene file.
    pub scene: PathBuf,
    /// Integrators to check, comma-separated.
    #[arg(short = 'i', long = "integrators", value_delimiter = ',', required = true, value_name = "NAME[,NAME...]", value_parser = penumbra::cli_params::integrator_arg)]
    pub integrators: Vec<String>,
    /// Samples per pixel of every render.
    #[arg(long, default_value_t = 4, value_parser = spp_parser())]
    pub spp: u32,
    /// Variants or groups to run, comma-separated (default: all).
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]")]
    pub variants: Option<Vec<String>>,
    /// Uniform scales to add to 1e-4 and 1e4, comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "S[,S...]")]
    pub scales: Vec<f64>,
    /// Translations in scene extents (default 1e2,1e4), comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "K[,K...]")]
    pub translations: Option<Vec<f64>>,
    #[command(flatten)]
    pub flags: RenderFlags,
    /// Output directory (stability.json, summary.md, contact.png).
    #[arg(short = 'o', long = "output", default_value = "stability-out")]
    pub output: PathBuf,
    /// Also write every render (R, G, B and variance channels) as OUTDIR/images/INTEGRATOR-VARIANT.exr.
    #[arg(long)]
    pub images: bool,
    /// Print stability.json on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Tolerances (see below).
    #[arg(long, value_name = "KEY=VALUE[,...]", default_value = "z=8,negative=0,bound=0,far=100")]
    pub fail_on: String,
    /// Only the table (or JSON) on stdout; no per-render lines.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// What fails the run (exit 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Largest |z| allowed on variants that must not change the image.
    pub z: Option<f64>,
    pub negative: Option<u64>,
    pub bound: Option<u64>,
    /// Translations farther than this many extents are not gated.
    pub far: f64,
}

impl Tolerances {
    pub fn parse(s: &str) -> Result<Tolerances, String> {
        let mut t = Tolerances { z: None, negative: None, bound: None, far: f64::INFINITY };
        if s.trim() == "none" {
            return Ok(t);
        }
        for item in s.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (k, v) =
                item.split_once('=').ok_or_else(|| format!("--fail-on: expected KEY=VALUE, got \"{item}\""))?;
            let num: f64 = v.trim().parse().map_err(|_| format!("--fail-on {k}: \"{v}\" is not a number"))?;
            if !(num >= 0.0) {
                return Err(format!("--fail-on {k}: must be a non-negative number"));
            }
            match k.trim() {
                "z" => t.z = Some(num),
                "negative" => t.negative = Some(num as u64),
                "bound" => t.bound = Some(num as u64),
                "far" => t.far = num,
                other => {
                    return Err(format!(
                        "--fail-on: unknown key \"{other}\" (expected z, negative, bound, far or none)"
                    ))
                }
            }
        }
        Ok(t)
    }
}

/// The validated command line, the parsed scene and the integrators.
pub struct Setup {
    pub desc: SceneDescription,
    pub params: Vec<Param>,
    pub resolution: (u32, u32),
    pub integrators: Vec<(String, Box<dyn Integrator>)>,
    pub variants: Vec<Variant>,
    pub tolerances: Tolerances,
    /// Warnings already printed.
    pub seen: BTreeSet<String>,
}

/// The default resolution: the scene's aspect ratio, its longer side 48 pixels.
fn default_resolution(desc: &SceneDescription) -> (u32, u32) {
    let (w, h) = crate::cli::full_resolution(desc, None);
    let (w, h) = (w.max(1) as f64, h.max(1) as f64);
    let s = 48.0 / w.max(h);
    (((w * s).round() as u32).max(1), ((h * s).round() as u32).max(1))
}

pub fn setup(args: &StabilityArgs) -> Result<Setup, Failure> {
    let tolerances = Tolerances::parse(&args.fail_on).map_err(fail)?;
    let names = cli_params::integrator_list(&args.integrators).map_err(fail)?;
    let scales: Vec<f64> = [1e-4, 1e4].into_iter().chain(args.scales.iter().copied()).collect();
    if scales.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(fail("--scales must be positive numbers"));
    }
    let translations = args.translations.clone().unwrap_or_else(|| vec![1e2, 1e4]);
    if translations.iter().any(|k| !k.is_finite()) {
        return Err(fail("--translations must be finite numbers"));
    }
    let all = variants::defaults(&scales, &translations);
    let variants = match &args.variants {
        Some(list) => variants::select(&all, list).map_err(fail)?,
        None => all,
    };
    let params = cli_params::parse_all(&args.flags.params).map_err(|e| fail(e.message))?;
    let parsed = pipeline::load_scene(Some(&args.scene)).map_err(|d| fail(d.to_string()))?;
    let resolution = args.flags.resolution.unwrap_or_else(|| default_resolution(&parsed.scene));
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    let mut integrators = Vec::new();
    for n in names {
        let i = pipeline::choose_integrator(&parsed.scene, Some(&n), &params, &warnings)
            .map_err(|d| fail(format!("integrator \"{n}\": {}", d.message)))?;
        integrators.push((n, i));
    }
    let mut seen = BTreeSet::new();
    print_new_warnings(&warnings, &mut seen);
    Ok(Setup { desc: parsed.scene, params, resolution, integrators, variants, tolerances, seen })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerances_parse() {
        let t = Tolerances::parse("z=8,negative=0,bound=3,far=100").unwrap();
        assert_eq!(t, Tolerances { z: Some(8.0), negative: Some(0), bound: Some(3), far: 100.0 });
        let none = Tolerances::parse("none").unwrap();
        assert_eq!((none.z, none.negative, none.bound), (None, None, None));
        assert!(Tolerances::parse("zz=1").unwrap_err().contains("unknown key"));
        assert!(Tolerances::parse("z=-1").is_err());
        assert!(Tolerances::parse("z").is_err());
    }
}
