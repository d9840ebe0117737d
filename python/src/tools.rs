//! `integrators`, `diff`, `check`, `sweep`, `relight`: the library functions behind the CLI's
//! commands, with options checked by the CLI's own parsers.

use crate::convert::{image_of, rgb_array};
use crate::errors::ParamError;
use crate::run::cancellable;
use crate::scene::param_args;
use clap::Parser;
use penumbra_cli::check::CheckArgs;
use penumbra_cli::relight::{env_lighting, relight as shade, scene_lighting};
use penumbra_cli::sweep::SweepArgs;
use penumbra_core::metrics::{self, Thresholds};
use penumbra_core::sh::transfer::TransferLayout;
use penumbra_parser::DiagSink;
use pyo3::exceptions::{PyIOError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Every integrator in the registry: name, method, the estimator it converges to, and its
/// parameters (name, type, default, range, doc) — what `--param`/`params=` accept.
#[pyfunction]
pub fn integrators<'py>(py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    penumbra_integrators::REGISTRY
        .iter()
        .map(|e| {
            let d = PyDict::new(py);
            d.set_item("name", e.name)?;
            d.set_item("method", e.method)?;
            d.set_item("reference", e.reference)?;
            let params = e
                .params
                .iter()
                .map(|p| {
                    let s = PyDict::new(py);
                    s.set_item("name", p.name)?;
                    s.set_item("type", p.kind.describe())?;
                    s.set_item("pbrt_type", p.kind.pbrt_type())?;
                    s.set_item("default", p.default.to_string())?;
                    s.set_item("range", p.range.describe())?;
                    s.set_item("doc", p.doc)?;
                    Ok(s)
                })
                .collect::<PyResult<Vec<_>>>()?;
            d.set_item("params", params)?;
            Ok(d)
        })
        .collect()
}

/// Compares two images with `penumbra diff`'s metrics (OpenImageIO idiff's mean, RMS, PSNR,
/// max error and counts, plus relative MSE, SMAPE and FLIP) and verdict.
///
/// `a` (test) and `b` (reference): paths, Renders (their R, G, B) or arrays of one shape.
/// Returns a dict; `status` is "pass", "warn" or "fail" for the thresholds (idiff's).
#[pyfunction]
#[pyo3(signature = (a, b, warn=1e-6, fail=1e-6, warnpercent=0.0, failpercent=0.0, hardwarn=f32::INFINITY, hardfail=f32::INFINITY, flip=true))]
#[allow(clippy::too_many_arguments)]
pub fn diff<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
    warn: f32,
    fail: f32,
    warnpercent: f32,
    failpercent: f32,
    hardwarn: f32,
    hardfail: f32,
    flip: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (ia, _) = image_of(a)?;
    let (ib, _) = image_of(b)?;
    let t = Thresholds { warn, fail, warnpercent, failpercent, hardwarn, hardfail };
    let (r, flip_value) = py.detach(|| {
        let r = metrics::compare(&ia, &ib, t.warn, t.fail);
        let f = if flip { flip_of(&ia, &ib) } else { None };
        (r, f)
    });
    let r = r.map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("width", r.width)?;
    d.set_item("height", r.height)?;
    d.set_item("channels", r.channels.clone())?;
    d.set_item("mean_error", r.mean_error)?;
    d.set_item("rms_error", r.rms_error)?;
    d.set_item("psnr", r.psnr)?;
    d.set_item("max_error", r.max_error)?;
    d.set_item("max_at", (r.max_x, r.max_y, r.max_channel_name().to_string()))?;
    d.set_item("mse", r.mse)?;
    d.set_item("relmse", r.relmse)?;
    d.set_item("smape", r.smape)?;
    d.set_item("flip", flip_value)?;
    d.set_item("npixels", r.npixels)?;
    d.set_item("nwarn", r.nwarn)?;
    d.set_item("nfail", r.nfail)?;
    d.set_item("nonfinite_a", r.nan_a + r.inf_a)?;
    d.set_item("nonfinite_b", r.nan_b + r.inf_b)?;
    let status = match r.status(&t) {
        metrics::Status::Pass => "pass",
        metrics::Status::Warn => "warn",
        metrics::Status::Fail => "fail",
    };
    d.set_item("status", status)?;
    Ok(d)
}

#[allow(unused_variables)]
fn flip_of(a: &penumbra_core::image::Image, b: &penumbra_core::image::Image) -> Option<f64> {
    #[cfg(feature = "flip")]
    {
        let (a, b) = (a.select_channels(&["R", "G", "B"]).ok()?, b.select_channels(&["R", "G", "B"]).ok()?);
        metrics::flip_mean(&a, &b, 67.0).ok()
    }
    #[cfg(not(feature = "flip"))]
    {
        None
    }
}

/// Options given as keyword arguments, as command-line flags: `fail_percent=1` →
/// `--fail-percent 1`, `True` → the bare flag, `False`/`None` → nothing.
fn flags(options: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    let Some(o) = options else { return Ok(out) };
    for (k, v) in o.iter() {
        let flag = format!("--{}", k.extract::<String>()?.replace('_', "-"));
        if v.is_none() {
            continue;
        }
        if let Ok(b) = v.extract::<bool>() {
            if b {
                out.push(flag);
            }
            continue;
        }
        // Sequences are comma-separated, except `resolution=(W, H)`, which is `WxH`.
        let sep = if flag == "--resolution" { "x" } else { "," };
        let value = match v.extract::<Vec<Bound<'_, PyAny>>>() {
            Ok(items) if !v.is_instance_of::<pyo3::types::PyString>() => {
                items.iter().map(|i| i.str().map(|s| s.to_string())).collect::<PyResult<Vec<_>>>()?.join(sep)
            }
            _ => v.str()?.to_string(),
        };
        out.push(format!("{flag}={value}"));
    }
    Ok(out)
}

/// A clap error as ParamError (its message names the valid options).
fn usage(e: clap::Error) -> PyErr {
    ParamError::new_err(e.render().to_string().trim().to_string())
}

#[derive(Parser)]
#[command(name = "check", no_binary_name = true)]
struct CheckCli {
    #[command(flatten)]
    args: CheckArgs,
}

#[derive(Parser)]
#[command(name = "sweep", no_binary_name = true)]
struct SweepCli {
    #[command(flatten)]
    args: SweepArgs,
}

/// The statistical image-regression gate of `penumbra check`: is the difference between
/// `test` and `reference` more than their noise explains?
///
/// Each is a path (its variance channels and the spp of its stats.json, as the CLI reads
/// them), a Render (rendered with `variance=True` for its noise) or an array. Options are
/// `penumbra check`'s, as keywords: alpha, correction, fail_percent, block,
/// converged_reference, same_estimator, abs, rel, test_spp, reference_spp. Returns the report
/// `penumbra check --json` prints (`status` "pass" or "fail", `exit_code` 0 or 2); an image
/// pair the gate cannot judge raises ValueError with the CLI's message.
#[pyfunction]
#[pyo3(signature = (test, reference, **options))]
pub fn check<'py>(
    py: Python<'py>,
    test: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let args = CheckCli::try_parse_from(flags(options)?).map_err(usage)?.args;
    let t = image_of(test)?;
    let r = image_of(reference)?;
    let v = py
        .detach(|| penumbra_cli::check::judge_images((&t.0, t.1), (&r.0, r.1), &args))
        .map_err(|f| PyValueError::new_err(f.message))?;
    py.import("json")?.call_method1("loads", (v.to_string(),))
}

/// Error against time, as `penumbra sweep`: each integrator renders `scene` at each budget,
/// timed and compared with a reference; returns one dict per render (integrator, budget,
/// spp, build_s, render_s, total_s, mae, rmse, psnr, max_err, relmse, smape, flip,
/// nan_count) — `pandas.DataFrame(rows)` takes it as it is.
///
/// reference: a path or an array (H, W, 3) of the renders' size; or reference_spp=N renders
/// one (with reference_integrator, default the first integrator's natural reference).
/// budgets: a list (default 1, 2, 4, ... within time_limit seconds). Other keywords are
/// `penumbra sweep`'s options (params, spp, seed, threads, resolution, crop, time_limit,
/// max_budget, budget_param, reference_seed, no_flip, ...). `output`: a directory for the
/// cached reference render (default: a temporary one, removed). Ctrl-C cancels
/// (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (scene, integrators, reference=None, budgets=None, params=None, output=None, verbose=false, **options))]
#[allow(clippy::too_many_arguments)]
pub fn sweep<'py>(
    py: Python<'py>,
    scene: PathBuf,
    integrators: Vec<String>,
    reference: Option<&Bound<'py, PyAny>>,
    budgets: Option<Vec<i64>>,
    params: Option<&Bound<'py, PyDict>>,
    output: Option<PathBuf>,
    verbose: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let temp = TempDir::new()?;
    let outdir = output.unwrap_or_else(|| temp.0.clone());
    let mut argv = vec![scene.display().to_string(), format!("--integrators={}", integrators.join(","))];
    argv.push(format!("--output={}", outdir.display()));
    if let Some(b) = budgets {
        argv.push(format!("--budgets={}", b.iter().map(i64::to_string).collect::<Vec<_>>().join(",")));
    }
    for p in param_args(params)? {
        argv.push(format!("--param={p}"));
    }
    if let Some(r) = reference {
        let path = match r.extract::<PathBuf>() {
            Ok(p) => p,
            Err(_) => {
                let p = temp.0.join("reference.exr");
                crate::convert::write_image(p.clone(), r, None, 0.0)?;
                p
            }
        };
        argv.push(format!("--reference={}", path.display()));
    }
    argv.extend(flags(options)?);
    let mut args = SweepCli::try_parse_from(argv).map_err(usage)?.args;
    args.flags.threads = penumbra_cli::cli_params::thread_count(args.flags.threads).0;
    let rows = cancellable(py, None, |cancel, _| {
        // The sweep's cancel flag is shared with its reference render: an Arc of our own,
        // mirrored from the runner's.
        let flag = Arc::new(AtomicBool::new(false));
        std::thread::scope(|s| {
            let watcher = s.spawn(|| {
                while Arc::strong_count(&flag) > 1 {
                    if cancel.load(std::sync::atomic::Ordering::SeqCst) {
                        flag.store(true, std::sync::atomic::Ordering::SeqCst);
                    }
                    std::thread::sleep(std::time::Duration::from_millis(10));
                }
            });
            let say = |m: String| {
                if verbose {
                    eprintln!("{m}");
                }
            };
            let flag2 = flag.clone();
            let rows = penumbra_cli::sweep::rows(&args, &flag2, &say);
            drop(flag2);
            let _ = watcher.join();
            rows
        })
    })?;
    let rows = rows.map_err(|f| {
        if f.cancelled() {
            pyo3::exceptions::PyKeyboardInterrupt::new_err(f.message)
        } else {
            PyRuntimeError::new_err(f.message)
        }
    })?;
    rows.iter()
        .map(|r| {
            let d = PyDict::new(py);
            d.set_item("integrator", &r.integrator)?;
            d.set_item("budget", r.budget)?;
            d.set_item("spp", r.spp)?;
            d.set_item("build_s", r.build_s)?;
            d.set_item("render_s", r.render_s)?;
            d.set_item("total_s", r.total_s)?;
            d.set_item("mae", r.mae)?;
            d.set_item("rmse", r.rmse)?;
            d.set_item("psnr", r.psnr)?;
            d.set_item("max_err", r.max_err)?;
            d.set_item("relmse", r.relmse)?;
            d.set_item("smape", r.smape)?;
            d.set_item("flip", r.flip)?;
            d.set_item("nan_count", r.nan_count)?;
            Ok(d)
        })
        .collect()
}

/// A temporary directory, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> PyResult<TempDir> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static N: AtomicU64 = AtomicU64::new(0);
        let nanos =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_nanos()).unwrap_or(0);
        let p = std::env::temp_dir().join(format!(
            "penumbra-py-{}-{nanos}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&p).map_err(|e| PyIOError::new_err(format!("{}: {e}", p.display())))?;
        Ok(TempDir(p))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Re-shades an image's SH transfer channels (`sh.*`, `albedo.*`, written by `shexp`'s
/// transfer output) under new distant lighting, as `penumbra relight`: the lighting of
/// `scene` (a pbrt-v3 file's lights) or of `env` (an environment map), scaled by 2^exposure.
/// `image`: a Render or a path. Returns the (H, W, 3) float32 image.
#[pyfunction]
#[pyo3(signature = (image, scene=None, env=None, exposure=0.0))]
pub fn relight<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    scene: Option<PathBuf>,
    env: Option<PathBuf>,
    exposure: f32,
) -> PyResult<Bound<'py, PyAny>> {
    let (img, _) = image_of(image)?;
    let layout = TransferLayout::find(&img.channels).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let warnings = DiagSink::new();
    let light = match (&scene, &env) {
        (Some(s), None) => scene_lighting(s, layout.order, &warnings),
        (None, Some(e)) => env_lighting(e, layout.order, &warnings),
        _ => return Err(ParamError::new_err("give the lighting: scene=SCENE.pbrt or env=MAP.exr (one of them)")),
    }
    .map_err(PyValueError::new_err)?;
    crate::errors::emit_warnings(py, &warnings)?;
    let out = py.detach(|| shade(&img, &light, exposure.exp2())).map_err(PyValueError::new_err)?;
    let (a, _) = rgb_array(py, out.width, out.height, out.data)?;
    Ok(a.into_any())
}
