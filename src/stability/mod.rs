//! `penumbra stability`: how each integrator's image changes where it must not.
//!
//! The scene is rendered as it is (the base) and as transformed variants of it (scaled,
//! rotated, moved far away, lights rescaled or shrunk, geometry duplicated, roughness at the
//! clamps: `variants`), each edited in the parsed description. Every render is measured
//! (`measure`): non-finite, negative and above-bound pixels, and the z-scores of its
//! difference from the base against both renders' per-pixel variance, so noise is not taken
//! for instability. The results go to `OUTDIR` (`output`): `stability.json`, `summary.md` and
//! `contact.png` (the worst pixel of each variant and integrator), and a table on stdout.
//!
//! Modules: `args` (the command line, tolerances, `setup`), `variants`, `measure`, `output`.

mod args;
mod measure;
mod report;
mod variants;

use crate::cli::cancel_on_interrupt;
use crate::cli::print_new_warnings;
use crate::diff::{EXIT_FAIL, EXIT_FILE, EXIT_OK, EXIT_WARN};
pub use args::StabilityArgs;
use args::{setup, Setup, Tolerances};
use measure::{measure, Bound, Channels, Measures};
use penumbra::pipeline::{self, RenderOptions};
use penumbra_core::integrator::{Integrator, RadianceBound};
use penumbra_core::scene::BuildOptions;
use penumbra_parser::{DiagSink, SceneDescription};
use report::{ContactCell, Row};
use std::collections::BTreeSet;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use variants::{Expect, Geometry, Kind, Variant};

/// Exit code: every gated measure within its tolerance.
pub const EXIT_STABLE: u8 = EXIT_OK;
/// Exit code: a tolerance of `--fail-on` exceeded.
pub const EXIT_TOLERANCE: u8 = EXIT_WARN;
/// Exit code: a render has non-finite values.
pub const EXIT_NONFINITE: u8 = EXIT_FAIL;
/// Exit code: an unreadable scene, a bad option value or a failed render.
pub const EXIT_ERROR: u8 = EXIT_FILE;

pub struct Failure {
    code: u8,
    message: String,
}

fn fail(message: impl std::fmt::Display) -> Failure {
    Failure { code: EXIT_ERROR, message: message.to_string() }
}

pub fn run(mut args: StabilityArgs) -> ExitCode {
    args.flags.threads = penumbra::cli_params::threads_or_warn(args.flags.threads);
    match run_inner(&args) {
        Ok(code) => ExitCode::from(code),
        Err(f) => penumbra::cli_params::exit_with_error(f.code, &f.message),
    }
}

/// Why a row fails, if it does: the gated measures over their tolerance.
fn verdict(v: Option<(&Variant, Expect)>, m: &Measures, t: &Tolerances) -> Vec<&'static str> {
    let mut why = Vec::new();
    if m.nonfinite > 0 {
        why.push("nonfinite");
    }
    if t.negative.is_some_and(|n| m.negative > n) {
        why.push("negative");
    }
    if t.bound.is_some_and(|n| m.above_bound.unwrap_or(0) > n) {
        why.push("bound");
    }
    let gated = v.is_some_and(|(v, expect)| {
        expect != Expect::Changed && !matches!(v.kind, Kind::Translate(k) if k.abs() > t.far)
    });
    if gated && t.z.is_some_and(|z| m.max_z.is_some_and(|mz| !(mz <= z))) {
        why.push("z");
    }
    why
}

/// Non-finite values anywhere (2) outrank a tolerance exceeded (1).
fn exit_code(rows: &[Row]) -> u8 {
    if rows.iter().any(|r| r.m.nonfinite > 0) {
        EXIT_NONFINITE
    } else if rows.iter().any(|r| !r.fails.is_empty()) {
        EXIT_TOLERANCE
    } else {
        EXIT_STABLE
    }
}

fn run_inner(args: &StabilityArgs) -> Result<u8, Failure> {
    let mut s = setup(args)?;
    std::fs::create_dir_all(&args.output).map_err(|e| fail(format!("cannot create {}: {e}", args.output.display())))?;
    let cancel = cancel_on_interrupt();
    let mut seen = std::mem::take(&mut s.seen);
    let say = |m: String| {
        if !args.quiet {
            eprintln!("{m}");
        }
    };
    let build = BuildOptions { spp: Some(args.spp), seed: args.flags.seed, crop: None, resolution: Some(s.resolution) };
    let geo = Geometry::of(&s.desc, &build).map_err(fail)?;
    let mut notes: Vec<String> = Vec::new();
    let mut scenes: Vec<(Variant, SceneDescription)> = Vec::new();
    for v in &s.variants {
        match v.apply(&s.desc, &geo) {
            Ok(d) => scenes.push((v.clone(), d)),
            Err(e) => notes.push(format!("{}: not run ({e})", v.name)),
        }
    }
    let filter = s.desc.filter.kind.as_str();
    let negative_lobes = matches!(filter, "mitchell" | "sinc" | "lanczos");
    if negative_lobes {
        notes.push(format!("bounds not checked: the \"{filter}\" pixel filter has negative lobes"));
    }
    let study = Study { args, s: &s, build, cancel: &cancel, check_bounds: !negative_lobes, say: &say };
    let mut rows: Vec<Row> = Vec::new();
    let mut cells: Vec<ContactCell> = Vec::new();
    for (name, integrator) in &s.integrators {
        let base = study.render(name, integrator.as_ref(), &s.desc, None, &mut seen)?;
        let (m, _) = measure(&base.channels, 1.0, None, base.bound.as_ref()).map_err(fail)?;
        let fails = verdict(None, &m, &s.tolerances);
        rows.push(Row::new(name, None, geo.extent, m, base.seconds, fails));
        for (v, d) in &scenes {
            let r = study.render(name, integrator.as_ref(), d, Some(v), &mut seen)?;
            let (bound, against) = (r.bound.as_ref(), Some(&base.channels));
            let mut expect = v.expect();
            let (mut m, mut zmap) = measure(&r.channels, expect.factor(), against, bound).map_err(fail)?;
            if let Expect::Scaled(_) = expect {
                // An image that does not depend on the lights (ambient occlusion, silhouette's AO
                // mode) must stay as it is instead.
                let (m1, z1) = measure(&r.channels, 1.0, against, bound).map_err(fail)?;
                if m1.max_z < m.max_z {
                    (m, zmap, expect) = (m1, z1, Expect::Same);
                }
            }
            let factor = expect.factor();
            cells.push(ContactCell::new(name, &v.name, &base.channels.rgb, &r.channels.rgb, factor, &zmap, &m));
            let fails = verdict(Some((v, expect)), &m, &s.tolerances);
            rows.push(Row::new(name, Some((v, expect)), geo.extent, m, r.seconds, fails));
        }
    }
    let code = exit_code(&rows);
    let out = report::Report { args, setup: &s, geo: &geo, rows: &rows, notes: &notes, exit_code: code };
    out.write(&cells).map_err(fail)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out.json()).unwrap_or_default());
    } else {
        print!("{}", out.table());
    }
    say(format!("wrote {}/{{stability.json,summary.md,contact.png}}", args.output.display()));
    Ok(code)
}

/// What every render of the study shares.
struct Study<'a> {
    args: &'a StabilityArgs,
    s: &'a Setup,
    build: BuildOptions,
    cancel: &'a AtomicBool,
    check_bounds: bool,
    say: &'a dyn Fn(String),
}

/// One render of the study: its channels, its bound and the seconds it took.
struct Render {
    channels: Channels,
    bound: Option<Bound>,
    seconds: f64,
}

impl Study<'_> {
    fn opts(&self) -> RenderOptions<'_> {
        RenderOptions {
            integrator: None,
            params: &self.s.params,
            build: self.build.clone(),
            threads: self.args.flags.threads,
            with_variance: true,
            cancel: self.cancel,
            progress: None,
        }
    }

    /// Renders `desc` with `integrator` (timed: build and render) and, when it declares an
    /// image bound, the bound (not timed).
    fn render(
        &self,
        name: &str,
        integrator: &dyn Integrator,
        desc: &SceneDescription,
        variant: Option<&Variant>,
        seen: &mut BTreeSet<String>,
    ) -> Result<Render, Failure> {
        let label = variant.map_or("base", |v| v.name.as_str());
        let warnings = DiagSink::new();
        let t0 = Instant::now();
        let result = pipeline::render_with(name, integrator, desc, &self.opts(), &warnings);
        let seconds = t0.elapsed().as_secs_f64();
        print_new_warnings(&warnings, seen);
        let rendered = result.map_err(|e| self.failed(name, label, e))?;
        let channels = Channels::of(&rendered.image).map_err(fail)?;
        if self.args.images {
            let dir = self.args.output.join("images");
            std::fs::create_dir_all(&dir).map_err(|e| fail(format!("cannot create {}: {e}", dir.display())))?;
            let path = dir.join(format!("{name}-{label}.exr"));
            penumbra_core::image::write(&rendered.image, &path)
                .map_err(|e| fail(format!("{}: {e}", path.display())))?;
        }
        let bound = match integrator.radiance_bound().filter(|_| self.check_bounds) {
            None => None,
            Some(RadianceBound::Constant(c)) => Some(Bound::Constant(c)),
            Some(RadianceBound::Image(b, tolerance)) => {
                let r =
                    pipeline::render_with(&format!("{name} (its bound)"), b.as_ref(), desc, &self.opts(), &warnings)
                        .map_err(|e| self.failed(name, &format!("{label} (its bound)"), e))?;
                print_new_warnings(&warnings, seen);
                Some(Bound::Image(Channels::of(&r.image).map_err(fail)?.rgb, tolerance))
            }
        };
        (self.say)(format!("{name:>16} {label:>14}: {seconds:.3} s"));
        Ok(Render { channels, bound, seconds })
    }

    fn failed(&self, name: &str, label: &str, e: pipeline::PipelineError) -> Failure {
        if self.cancel.load(Ordering::SeqCst) {
            Failure { code: penumbra::exit::INTERRUPTED, message: "interrupted".into() }
        } else {
            fail(format!("{name} on {label}: {e}"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What fails a row: non-finite always; negative and bound counts over their tolerance;
    /// |z| only where the image must not change, and translations only up to `far`.
    #[test]
    fn verdicts_and_exit_codes() {
        let t = Tolerances::parse("z=8,negative=0,bound=0,far=100").unwrap();
        let m = |z: f64| Measures { max_z: Some(z), above_bound: Some(0), ..Default::default() };
        let (rot, far, rough) =
            (Variant::new(Kind::Rotate), Variant::new(Kind::Translate(1e4)), Variant::new(Kind::Roughness(0.0)));
        fn v(v: &Variant) -> Option<(&Variant, Expect)> {
            Some((v, v.expect()))
        }
        assert!(verdict(v(&rot), &m(7.9), &t).is_empty());
        assert_eq!(verdict(v(&rot), &m(8.1), &t), ["z"]);
        assert_eq!(verdict(v(&rot), &m(f64::NAN), &t), ["z"], "a NaN |z| is not within tolerance");
        assert!(verdict(v(&far), &m(1e3), &t).is_empty(), "beyond far: reported, not gated");
        assert!(verdict(v(&rough), &m(1e3), &t).is_empty(), "roughness changes the image");
        let bad = Measures { negative: 2, above_bound: Some(1), ..m(1.0) };
        assert_eq!(verdict(v(&rough), &bad, &t), ["negative", "bound"]);
        let none = Tolerances::parse("none").unwrap();
        assert!(verdict(v(&rot), &Measures { negative: 5, ..m(1e9) }, &none).is_empty());
        let nan = Measures { nonfinite: 1, ..m(0.0) };
        assert_eq!(verdict(None, &nan, &none), ["nonfinite"]);

        let row = |m: Measures, fails| Row::new("x", None, 1.0, m, 0.0, fails);
        assert_eq!(exit_code(&[row(m(1.0), vec![])]), EXIT_STABLE);
        assert_eq!(exit_code(&[row(m(1.0), vec![]), row(m(9.0), vec!["z"])]), EXIT_TOLERANCE);
        assert_eq!(exit_code(&[row(m(9.0), vec!["z"]), row(nan, vec!["nonfinite"])]), EXIT_NONFINITE);
        assert_eq!((EXIT_STABLE, EXIT_TOLERANCE, EXIT_NONFINITE, EXIT_ERROR), (0, 1, 2, 4));
    }
}
