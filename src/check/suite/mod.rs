//! `penumbra check --suite SUITE.toml`: renders every case ([`spec`]), checks it against its
//! reference with the gate, prints one line per case and keeps `junit.xml` ([`junit`]) and a
//! self-contained `report.html` ([`html`]) current after every case, so an interrupted run
//! keeps the cases it finished.

pub mod html;
pub mod junit;
pub mod render;
pub mod spec;

use super::gate::{GateOptions, RefMode, Side};
use super::{fail, maps, options, read_side, report, CheckArgs, Failure, EXIT_FAIL, EXIT_FILE, EXIT_OK};
use penumbra_core::agreement::Tolerance;
use penumbra_core::image::{self, Image};
use render::Request;
use spec::{Case, Kind, Renderer};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Pass,
    Fail,
    /// The case could not be run (a scene, a reference or an option is unusable).
    Error,
}

/// The images of a checked case, as PNG bytes.
#[derive(Default)]
pub struct Images {
    pub test: Vec<u8>,
    pub reference: Vec<u8>,
    pub difference: Vec<u8>,
    pub pvalue: Vec<u8>,
    pub mask: Vec<u8>,
    pub error: Vec<u8>,
}

/// One case's verdict.
pub struct CaseResult {
    pub name: String,
    pub status: Status,
    /// One line: why it failed, or the headline numbers.
    pub summary: String,
    /// The gate's text report, or the error.
    pub detail: String,
    pub seconds: f64,
    pub images: Option<Images>,
}

/// The first Ctrl-C stops the render at its next tile; the finished cases are reported and the
/// run exits with 130. A second one exits at once.
fn cancel_on_interrupt() -> Arc<AtomicBool> {
    let cancel = Arc::new(AtomicBool::new(false));
    let c = cancel.clone();
    let _ = ctrlc::set_handler(move || {
        if c.swap(true, Ordering::SeqCst) {
            std::process::exit(crate::exit::INTERRUPTED.into());
        }
    });
    cancel
}

pub fn run(args: &CheckArgs, suite: &Path) -> ExitCode {
    match run_suite(args, suite) {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            eprintln!("penumbra check: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

fn run_suite(args: &CheckArgs, suite: &Path) -> Result<u8, Failure> {
    let _ = options(args)?;
    let mut cases = spec::read(suite).map_err(|e| fail(EXIT_FILE, e))?;
    if let Some(only) = &args.only {
        cases.retain(|c| c.name.contains(only.as_str()));
        if cases.is_empty() {
            return Err(fail(EXIT_FILE, format!("--only {only:?}: no case's name contains it")));
        }
    }
    let out = args.out.clone().unwrap_or_else(|| suite.parent().unwrap_or(Path::new(".")).join("check-out"));
    std::fs::create_dir_all(&out).map_err(|e| fail(EXIT_FILE, format!("{}: {e}", out.display())))?;
    let threads = crate::cli_params::threads_or_warn(args.threads);
    let cancel = cancel_on_interrupt();
    let suite_name = suite.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "suite".into());
    let mut results: Vec<CaseResult> = Vec::new();
    let n = cases.len();
    for (i, case) in cases.iter().enumerate() {
        eprintln!("[{}/{n}] {} ...", i + 1, case.name);
        let t0 = Instant::now();
        let r = run_case(args, case, &out, threads, &cancel);
        if cancel.load(Ordering::SeqCst) {
            eprintln!("interrupted: {} finished case(s) kept in {}", results.len(), out.display());
            break;
        }
        let r = finish(case, r, t0.elapsed().as_secs_f64());
        println!("{:5} {} ({:.1} s): {}", status_word(r.status), r.name, r.seconds, r.summary);
        results.push(r);
        write_reports(&out, &suite_name, &results)?;
    }
    write_reports(&out, &suite_name, &results)?;
    let count = |s: Status| results.iter().filter(|r| r.status == s).count();
    let (pass, failed, errors) = (count(Status::Pass), count(Status::Fail), count(Status::Error));
    println!(
        "{pass} passed, {failed} failed, {errors} could not run, of {n}; reports: {}, {}",
        out.join("junit.xml").display(),
        out.join("report.html").display()
    );
    Ok(if cancel.load(Ordering::SeqCst) {
        crate::exit::INTERRUPTED
    } else if errors > 0 {
        EXIT_FILE
    } else if failed > 0 {
        EXIT_FAIL
    } else {
        EXIT_OK
    })
}

pub fn status_word(s: Status) -> &'static str {
    match s {
        Status::Pass => "PASS",
        Status::Fail => "FAIL",
        Status::Error => "ERROR",
    }
}

fn write_reports(out: &Path, suite_name: &str, results: &[CaseResult]) -> Result<(), Failure> {
    let write = |name: &str, text: String| {
        let p = out.join(name);
        image::write_atomic(&p, |w| w.write_all(text.as_bytes()))
            .map_err(|e| fail(EXIT_FILE, format!("{}: {e}", p.display())))
    };
    write("junit.xml", junit::xml(suite_name, results))?;
    write("report.html", html::report(suite_name, results))
}

/// What a run of one case produced: the gate's outcome and the images.
struct Checked {
    outcome: super::gate::Outcome,
    opts: GateOptions,
    test: Image,
    reference: Image,
}

fn finish(case: &Case, r: Result<Checked, String>, seconds: f64) -> CaseResult {
    match r {
        Err(e) => CaseResult {
            name: case.name.clone(),
            status: Status::Error,
            summary: e.lines().next().unwrap_or("").to_string(),
            detail: e,
            seconds,
            images: None,
        },
        Ok(c) => {
            let o = &c.outcome;
            let all = o.bias.iter().find(|b| b.channel == "all");
            let bias = all
                .map(|b| {
                    format!(
                        "mean bias {:+.3} % (95 % CI {:+.3} .. {:+.3} %)",
                        100.0 * b.rel,
                        100.0 * b.rel_lo,
                        100.0 * b.rel_hi
                    )
                })
                .unwrap_or_default();
            let summary = if o.passed {
                format!("{} of {} values rejected; {bias}", o.values.rejected, o.values.count)
            } else {
                format!("{}; {bias}", o.reasons.join("; "))
            };
            let images = case_images(&c).unwrap_or_default();
            CaseResult {
                name: case.name.clone(),
                status: if o.passed { Status::Pass } else { Status::Fail },
                summary,
                detail: report::text(o, &c.opts),
                seconds,
                images: Some(images),
            }
        }
    }
}

fn case_images(c: &Checked) -> Result<Images, String> {
    let o = &c.outcome;
    let e = |x: image::ImageError| x.to_string();
    let p = Path::new("map.png");
    Ok(Images {
        test: maps::image_png(&c.test, 0.0).map_err(e)?,
        reference: maps::image_png(&c.reference, 0.0).map_err(e)?,
        difference: maps::png(o, &difference_rgb(&c.test, &c.reference)?, p).map_err(e)?,
        pvalue: maps::png(o, &maps::pvalue_rgb(o), p).map_err(e)?,
        mask: maps::png(o, &maps::mask_rgb(o), p).map_err(e)?,
        error: maps::png(o, &maps::signed_rgb(o), p).map_err(e)?,
    })
}

/// |test − reference| per channel, scaled so that the largest difference is white.
pub fn difference_rgb(test: &Image, reference: &Image) -> Result<Vec<u8>, String> {
    let t = test.select_channels(&["R", "G", "B"]).map_err(|e| e.to_string())?;
    let r = reference.select_channels(&["R", "G", "B"]).map_err(|e| e.to_string())?;
    let d: Vec<f32> = t.data.iter().zip(&r.data).map(|(a, b)| (a - b).abs()).collect();
    let max = d.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    Ok(d.iter().map(|v| if max > 0.0 { (v / max * 255.0).round().clamp(0.0, 255.0) as u8 } else { 0 }).collect())
}

/// The gate's options for a case: the command line's, overridden by the case's keys.
fn case_options(args: &CheckArgs, case: &Case) -> Result<GateOptions, String> {
    let mut a = args.clone();
    a.alpha = case.alpha.unwrap_or(a.alpha);
    a.fail_percent = case.fail_percent.unwrap_or(a.fail_percent);
    a.block = case.block.unwrap_or(a.block);
    a.abs_tol = case.abs.or(a.abs_tol);
    a.rel_tol = case.rel.or(a.rel_tol);
    let mut o = options(&a).map_err(|f| format!("{}: case {:?}: {}", case.at, case.name, f.message))?;
    o.mode = match case.kind {
        Kind::Welch => RefMode::Welch,
        Kind::SameEstimator => RefMode::SameEstimator,
        Kind::Converged | Kind::Tolerance => RefMode::Converged,
    };
    o.tolerance = Tolerance { abs: case.abs.unwrap_or(0.0), rel: case.rel.unwrap_or(0.0) };
    Ok(o)
}

/// The reference's path: the case's file (rendered first under `--make-references` when
/// missing), or a fresh penumbra render into the output directory when the case names none.
fn reference(
    args: &CheckArgs,
    case: &Case,
    out: &Path,
    threads: usize,
    cancel: &AtomicBool,
) -> Result<PathBuf, String> {
    let Some(p) = &case.reference else {
        let p = out.join(format!("{}.reference.exr", case.name));
        render::penumbra(&Request::reference(case), &p, threads, cancel)?;
        return Ok(p);
    };
    if p.exists() {
        return Ok(p.clone());
    }
    if !args.make_references {
        return Err(format!(
            "{}: case {:?}: reference {} does not exist (render it with --make-references)",
            case.at,
            case.name,
            p.display()
        ));
    }
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    eprintln!("      making reference {}", p.display());
    match case.reference_renderer {
        Renderer::Penumbra => render::penumbra(&Request::reference(case), p, threads, cancel).map(|_| ()),
        Renderer::Pbrt => {
            let pbrt = case.pbrt.clone().or_else(|| args.pbrt.clone()).ok_or_else(|| {
                format!("{}: case {:?}: a pbrt-v3 reference needs --pbrt PATH or `pbrt = \"PATH\"`", case.at, case.name)
            })?;
            render::pbrt(case, &pbrt, p, threads)
        }
    }?;
    Ok(p.clone())
}

fn run_case(args: &CheckArgs, case: &Case, out: &Path, threads: usize, cancel: &AtomicBool) -> Result<Checked, String> {
    let opts = case_options(args, case)?;
    let rp = reference(args, case, out, threads, cancel)?;
    let tp = out.join(format!("{}.exr", case.name));
    for w in render::penumbra(&Request::test(case), &tp, threads, cancel)? {
        eprintln!("      warning: {w}");
    }
    let m = |f: Failure| f.message;
    let (test_img, mut test) = read_side(&tp, None).map_err(m)?;
    let (ref_img, mut refs) = read_side(&rp, case.reference_spp.map(f64::from)).map_err(m)?;
    let tolerance_given = case.abs.is_some() || case.rel.is_some();
    if case.kind == Kind::Tolerance {
        noise_free(&mut test);
        noise_free(&mut refs);
    }
    let outcome = super::judge(&test, &refs, &opts, tolerance_given).map_err(m)?;
    if !outcome.passed || args.maps_always {
        maps::write_all(&outcome, out, &case.name)?;
    }
    Ok(Checked { outcome, opts, test: test_img, reference: ref_img })
}

/// A tolerance-only case: the noise is set aside (|d| <= abs + rel·|ref| is the whole test).
fn noise_free(s: &mut Side) {
    s.variance = Some(vec![0.0; s.mean.len()]);
    s.spp = s.spp.or(Some(1.0));
}
