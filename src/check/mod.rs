//! `penumbra check TEST REF`: is the difference between a render and a reference noise? A
//! statistically sound image-regression gate ([`gate`]), its images ([`maps`]) and suites of
//! cases with JUnit XML and an HTML report ([`suite`]).

pub mod gate;
pub mod maps;
pub mod report;
pub mod suite;

use gate::{Correction, GateOptions, Outcome, RefMode, Side};
use penumbra_core::agreement::Tolerance;
use penumbra_core::image::{self, Image};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Exit code: the images agree (as `diff`).
pub const EXIT_OK: u8 = 0;
/// Exit code: they differ beyond their noise (as `diff`'s failure).
pub const EXIT_FAIL: u8 = 2;
/// Exit code: different sizes or channel sets (as `diff`).
pub const EXIT_DIFFERENT_SIZE: u8 = 3;
/// Exit code: a file could not be read or written, or an option does not fit the images.
pub const EXIT_FILE: u8 = 4;

#[derive(clap::Args, Debug, Clone)]
#[command(after_help = "\
Each image's noise is its variance channels (variance.R/G/B, written by `penumbra render --variance`:
the sample variance of the pixel's samples divided by their count, i.e. the variance of the pixel's
mean), with the samples per pixel from --test-spp/--reference-spp or the render's NAME.stats.json.

Tests, each family at alpha/3 so that a false alarm anywhere has probability <= alpha:
  values  per pixel and channel: Welch's t (both noisy), z (--converged-reference) or the pooled
          two-sample t (--same-estimator); Sidak (or Holm) over all values; fails when more than
          --fail-percent of the values are rejected;
  blocks  the mean of every BxB block of each channel (Sidak over blocks);
  whole   the mean of each channel and of all three (Sidak over 4).
A value whose samples were all equal (variance 0) borrows the other image's per-sample variance.
QMC samplers and filters wider than a pixel correlate pixels; per-value tests then misstate each
value's noise (usually conservatively), the block and whole-image means stay right.
--abs/--rel: an allowed difference |d| <= abs + rel*|ref| subtracted before the noise is weighed;
for noise-free images (no variance anywhere) it is the whole test, and one of them is required.
A cropped EXR (render --crop) keeps its place in the full frame as pbrt-v3 writes it (the crop is
the data window inside the full display window): images of one frame are judged on the pixels both
hold, so a cropped render is checked against the same pixels of a whole reference.

Exit codes (as diff): 0 pass, 2 failure, 3 different sizes or no R,G,B channels, 4 unreadable file,
unwritable output or an option that does not fit the images, 64 usage error, 130 interrupted (suite).
See docs/check.md.")]
pub struct CheckArgs {
    /// Test image (EXR with variance channels, PNG or PFM).
    pub test: Option<PathBuf>,
    /// Reference image.
    pub reference: Option<PathBuf>,
    /// Family-wise false-alarm probability of the whole gate.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Multiple-comparison correction of the per-value tests: sidak or holm.
    #[arg(long, default_value = "sidak", value_name = "sidak|holm")]
    pub correction: String,
    /// Percentage of values allowed to be rejected.
    #[arg(long, default_value_t = 0.25)]
    pub fail_percent: f64,
    /// Side of the pooled blocks, in pixels.
    #[arg(long, default_value_t = 8)]
    pub block: usize,
    /// The reference is converged: its noise is ignored (z-test on the test's variance).
    #[arg(long, conflicts_with = "same_estimator")]
    pub converged_reference: bool,
    /// Both images come from the same estimator (e.g. a pbrt-v3 reference, which has no
    /// variance channels, of the same integrator): their per-sample variance is pooled.
    #[arg(long)]
    pub same_estimator: bool,
    /// Allowed absolute difference per value (and per region mean).
    #[arg(long = "abs", value_name = "A")]
    pub abs_tol: Option<f64>,
    /// Allowed difference relative to the reference.
    #[arg(long = "rel", value_name = "R")]
    pub rel_tol: Option<f64>,
    /// Samples per pixel of the test (default: from TEST's .stats.json).
    #[arg(long, value_name = "N")]
    pub test_spp: Option<f64>,
    /// Samples per pixel of the reference (default: from REF's .stats.json).
    #[arg(long, value_name = "N")]
    pub reference_spp: Option<f64>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// On failure write the p-value map, the failing mask and the signed-error map into DIR
    /// (TEST's stem + .pvalue.png, .mask.png, .error.png).
    #[arg(long, value_name = "DIR")]
    pub maps: Option<PathBuf>,
    /// Write the maps also when the check passes.
    #[arg(long, requires = "maps")]
    pub maps_always: bool,
    /// Run a suite of cases (TOML; see docs/check.md) instead of comparing two images.
    #[arg(long, value_name = "SUITE.toml", conflicts_with_all = ["test", "reference"])]
    pub suite: Option<PathBuf>,
    /// Suite: render the references that are missing (penumbra or pbrt-v3, as the case says).
    #[arg(long, requires = "suite")]
    pub make_references: bool,
    /// Suite: the directory for test renders, maps, junit.xml and report.html
    /// (default: check-out beside the suite file).
    #[arg(long, value_name = "DIR", requires = "suite")]
    pub out: Option<PathBuf>,
    /// Suite: run only the cases whose name contains this.
    #[arg(long, value_name = "TEXT", requires = "suite")]
    pub only: Option<String>,
    /// Suite: pbrt-v3's binary, for the references a case has pbrt render
    /// (`reference_renderer = "pbrt"`).
    #[arg(long, value_name = "PATH", requires = "suite")]
    pub pbrt: Option<PathBuf>,
    /// Suite: worker threads per render (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
}

/// A check that could not be judged: its exit code and message.
#[derive(Debug)]
pub struct Failure {
    pub code: u8,
    pub message: String,
}

pub fn fail(code: u8, message: impl Into<String>) -> Failure {
    Failure { code, message: message.into() }
}

pub fn run(args: CheckArgs) -> ExitCode {
    if let Some(s) = &args.suite {
        return suite::run(&args, s);
    }
    match run_pair(&args) {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            eprintln!("penumbra check: {}", f.message);
            if args.json {
                println!(
                    "{}",
                    serde_json::json!({ "test": args.test, "reference": args.reference, "error": f.message, "exit_code": f.code })
                );
            }
            ExitCode::from(f.code)
        }
    }
}

/// The gate's options from the command line (or a suite case's overrides of them).
pub fn options(args: &CheckArgs) -> Result<GateOptions, Failure> {
    let correction = match args.correction.to_ascii_lowercase().as_str() {
        "sidak" | "šidák" => Correction::Sidak,
        "holm" => Correction::Holm,
        other => return Err(fail(EXIT_FILE, format!("--correction must be sidak or holm, got {other:?}"))),
    };
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(fail(EXIT_FILE, format!("--alpha must lie in (0, 1), got {}", args.alpha)));
    }
    if !(0.0..=100.0).contains(&args.fail_percent) {
        return Err(fail(EXIT_FILE, format!("--fail-percent must lie in [0, 100], got {}", args.fail_percent)));
    }
    if args.block == 0 {
        return Err(fail(EXIT_FILE, "--block must be at least 1"));
    }
    for (name, v) in [
        ("abs", args.abs_tol),
        ("rel", args.rel_tol),
        ("test-spp", args.test_spp),
        ("reference-spp", args.reference_spp),
    ] {
        if let Some(v) = v {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(fail(EXIT_FILE, format!("--{name} must be a non-negative number, got {v}")));
            }
        }
    }
    let mode = if args.converged_reference {
        RefMode::Converged
    } else if args.same_estimator {
        RefMode::SameEstimator
    } else {
        RefMode::Welch
    };
    Ok(GateOptions {
        alpha: args.alpha,
        correction,
        fail_fraction: args.fail_percent / 100.0,
        block: args.block,
        tolerance: Tolerance { abs: args.abs_tol.unwrap_or(0.0), rel: args.rel_tol.unwrap_or(0.0) },
        mode,
    })
}

/// `spp` from `NAME.stats.json` beside `image` (what `penumbra render` writes), if present.
pub fn spp_from_stats(image: &Path) -> Option<f64> {
    let stem = image.file_stem()?.to_string_lossy().into_owned();
    let text = std::fs::read_to_string(image.with_file_name(format!("{stem}.stats.json"))).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v.get("spp")?.as_f64()
}

/// Reads one side: the image and its samples per pixel.
pub fn read_side(path: &Path, spp: Option<f64>) -> Result<(Image, Side), Failure> {
    let img = image::read(path).map_err(|e| fail(EXIT_FILE, e.to_string()))?;
    let side = Side::from_image(&img, spp.or_else(|| spp_from_stats(path)))
        .map_err(|e| fail(EXIT_DIFFERENT_SIZE, format!("{}: {e}", path.display())))?;
    Ok((img, side))
}

/// The pixels a test and a reference image both hold ([`image::overlap`]): a cropped EXR (render
/// `--crop`) keeps its place in the full frame as pbrt-v3 writes it, so it is judged against the
/// same pixels of a whole reference (or of another crop); images of different frames, or crops
/// that share no pixel, are a size mismatch (exit 3).
pub fn common_window(test: Image, reference: Image) -> Result<(Image, Image), Failure> {
    image::overlap(test, reference, None)
        .map(|(t, r, _)| (t, r))
        .map_err(|e| fail(EXIT_DIFFERENT_SIZE, format!("test against reference: {e}")))
}

/// Reads a test and a reference image and cuts them to their [`common_window`].
pub fn read_pair(
    (tp, test_spp): (&Path, Option<f64>),
    (rp, reference_spp): (&Path, Option<f64>),
) -> Result<(Side, Side), Failure> {
    let read = |p: &Path| image::read(p).map_err(|e| fail(EXIT_FILE, e.to_string()));
    let (t, r) = common_window(read(tp)?, read(rp)?)?;
    let side = |img: &Image, p: &Path, spp: Option<f64>| {
        Side::from_image(img, spp.or_else(|| spp_from_stats(p)))
            .map_err(|e| fail(EXIT_DIFFERENT_SIZE, format!("{}: {e}", p.display())))
    };
    Ok((side(&t, tp, test_spp)?, side(&r, rp, reference_spp)?))
}

/// Runs the gate, turning its refusals into exit codes: a size mismatch is 3, anything the
/// images lack for the chosen test is 4. Noise-free comparisons need a tolerance.
pub fn judge(test: &Side, reference: &Side, o: &GateOptions, tolerance_given: bool) -> Result<Outcome, Failure> {
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(fail(
            EXIT_DIFFERENT_SIZE,
            format!(
                "the images differ in size: test {}x{}, reference {}x{}",
                test.width, test.height, reference.width, reference.height
            ),
        ));
    }
    if o.mode == RefMode::Welch && test.variance.is_some() && reference.variance.is_none() {
        return Err(fail(
            EXIT_FILE,
            "the reference has no variance channels: render it with `penumbra render --variance`, declare it \
             --converged-reference, or give --same-estimator when the same estimator rendered both",
        ));
    }
    let out = gate::run(test, reference, o).map_err(|e| fail(EXIT_FILE, e))?;
    if out.noise_free && !tolerance_given {
        return Err(fail(
            EXIT_FILE,
            "neither image has noise to weigh the difference against (no variance channels in the test, and the \
             reference converged or without them): give the allowed difference with --abs A and/or --rel R \
             (|d| <= A + R*|ref|)",
        ));
    }
    Ok(out)
}

/// The gate on two images in memory, each with its samples per pixel when known (the Python
/// API's `check`): `args` gives the options as the command line does (its paths are not read).
/// Returns the report `--json` prints, with its `exit_code`.
pub fn judge_images(
    (test, test_spp): (&Image, Option<f64>),
    (reference, reference_spp): (&Image, Option<f64>),
    args: &CheckArgs,
) -> Result<serde_json::Value, Failure> {
    let o = options(args)?;
    let side = |img: &Image, spp: Option<f64>, which: &str| {
        Side::from_image(img, spp).map_err(|e| fail(EXIT_DIFFERENT_SIZE, format!("{which}: {e}")))
    };
    let (test, reference) = common_window(test.clone(), reference.clone())?;
    let t = side(&test, test_spp.or(args.test_spp), "test")?;
    let r = side(&reference, reference_spp.or(args.reference_spp), "reference")?;
    let out = judge(&t, &r, &o, args.abs_tol.is_some() || args.rel_tol.is_some())?;
    let mut v = report::json(&out, &o);
    v["exit_code"] = serde_json::json!(if out.passed { EXIT_OK } else { EXIT_FAIL });
    Ok(v)
}

fn run_pair(args: &CheckArgs) -> Result<u8, Failure> {
    let (Some(tp), Some(rp)) = (&args.test, &args.reference) else {
        return Err(fail(crate::exit::USAGE, "give TEST and REF images, or --suite SUITE.toml"));
    };
    let o = options(args)?;
    if let Some(d) = &args.maps {
        if !d.is_dir() {
            return Err(fail(EXIT_FILE, format!("--maps {}: not a directory", d.display())));
        }
    }
    let (test, reference) = read_pair((tp, args.test_spp), (rp, args.reference_spp))?;
    let out = judge(&test, &reference, &o, args.abs_tol.is_some() || args.rel_tol.is_some())?;
    let maps = match &args.maps {
        Some(dir) if !out.passed || args.maps_always => {
            let stem = tp.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "check".into());
            maps::write_all(&out, dir, &stem).map_err(|e| fail(EXIT_FILE, e))?
        }
        _ => Vec::new(),
    };
    if args.json {
        let mut v = report::json(&out, &o);
        v["test"] = serde_json::json!(tp);
        v["reference"] = serde_json::json!(rp);
        v["maps"] = serde_json::json!(maps);
        v["exit_code"] = serde_json::json!(if out.passed { EXIT_OK } else { EXIT_FAIL });
        println!("{v}");
    } else {
        println!("Checking \"{}\" against \"{}\"", tp.display(), rp.display());
        print!("{}", report::text(&out, &o));
        for m in &maps {
            println!("  map: {}", m.display());
        }
        println!("{}", if out.passed { "PASS" } else { "FAILURE" });
    }
    Ok(if out.passed { EXIT_OK } else { EXIT_FAIL })
}
