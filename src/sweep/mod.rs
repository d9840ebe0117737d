//! `penumbra sweep`: error versus time for several integrators.
//!
//! Each integrator renders the scene at a series of budgets (samples per pixel,
//! or an integrator parameter given by `--budget-param`); every render is timed
//! and compared with a reference (R, G, B only). The results go to `OUTDIR`:
//! `sweep.csv`, `sweep.json`, a log-log plot (`sweep.png`, `sweep.svg`) and
//! `summary.md` (error at equal time, time to a target error).
//!
//! Modules: `args` (the command line and its validation), `cache` (the `--reference-spp`
//! reference, rendered once and cached), `schedule` (which budgets to render), `output`
//! (rows, CSV/JSON tables), `summary` (log-log curves, the Markdown summary), `plot`.

mod args;
mod cache;
mod fanout;
pub mod plot;
mod report;
mod row;
mod schedule;
mod summary;
#[cfg(test)]
mod tests;

use crate::cli::{cancel_on_interrupt, print_new_warnings};
use crate::pipeline::{self, RenderOptions};
pub use args::SweepArgs;
use args::{budget_param, setup, Setup};
use penumbra_core::image::{self, Image};
use penumbra_core::metrics;
use penumbra_core::scene::BuildOptions;
use penumbra_parser::DiagSink;
use report::Outputs;
pub use row::{Metric, Row};
use schedule::Schedule;
use std::collections::BTreeSet;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;
use summary::fmt_num;

/// Exit status when interrupted (as a shell reports SIGINT).
const EXIT_CANCELLED: u8 = crate::exit::INTERRUPTED;

/// Why a sweep stopped: the CLI's exit status for it and the message.
#[derive(Debug)]
pub struct Failure {
    pub code: u8,
    pub message: String,
}

impl Failure {
    /// Whether the sweep stopped because it was cancelled (Ctrl-C).
    pub fn cancelled(&self) -> bool {
        self.code == EXIT_CANCELLED
    }
}

fn fail(message: impl std::fmt::Display) -> Failure {
    Failure { code: 1, message: message.to_string() }
}

fn rgb_only(img: &Image, what: &str) -> Result<Image, Failure> {
    img.select_channels(&["R", "G", "B"]).map_err(|e| fail(format!("{what}: {e}")))
}

/// A reference of another size than the renders stops the sweep before any file is written.
fn check_reference_size(reference: &Image, s: &Setup) -> Result<(), Failure> {
    let opts = BuildOptions { crop: s.crop, resolution: s.resolution, ..Default::default() };
    // A film the build would refuse is its located error, reported by the first render.
    let Ok(film) = penumbra_core::scene::film_spec(&s.desc, &opts, &DiagSink::new()) else { return Ok(()) };
    size_matches(reference, (film.pixel_bounds.width() as u32, film.pixel_bounds.height() as u32))
}

fn size_matches(reference: &Image, (w, h): (u32, u32)) -> Result<(), Failure> {
    if (w, h) != (reference.width, reference.height) {
        return Err(fail(format!(
            "the reference is {}x{} but the render is {w}x{h} (render at the reference's size with --resolution/--crop)",
            reference.width, reference.height
        )));
    }
    Ok(())
}

/// One timed render of the sweep: its R, G, B and its clocks.
pub(crate) struct Timed {
    pub image: Image,
    pub spp: u32,
    pub build_s: f64,
    pub render_s: f64,
    pub total_s: f64,
}

impl Timed {
    fn of(rendered: &pipeline::Rendered, total_s: f64) -> Result<Timed, Failure> {
        Ok(Timed {
            image: rgb_only(&rendered.image, "render")?,
            spp: rendered.stats.spp,
            build_s: rendered.build.total_seconds(),
            render_s: rendered.stats.render_seconds,
            total_s,
        })
    }
}

fn compare_row(integrator: &str, budget: u32, t: &Timed, reference: &Image, with_flip: bool) -> Result<Row, Failure> {
    let test = &t.image;
    size_matches(reference, (test.width, test.height))?;
    let c = metrics::compare(test, reference, 1e-6, 1e-6).map_err(fail)?;
    let flip = if with_flip { flip_of(test, reference) } else { None };
    Ok(Row {
        integrator: integrator.to_string(),
        budget,
        spp: t.spp,
        build_s: t.build_s,
        render_s: t.render_s,
        total_s: t.total_s,
        mae: c.mean_error,
        rmse: c.rms_error,
        psnr: c.psnr,
        max_err: c.max_error,
        relmse: c.relmse,
        smape: c.smape,
        flip,
        nan_count: c.nan_a + c.inf_a,
    })
}

#[allow(unused_variables)]
fn flip_of(a: &Image, b: &Image) -> Option<f64> {
    #[cfg(feature = "flip")]
    {
        metrics::flip_mean(a, b, 67.0).ok()
    }
    #[cfg(not(feature = "flip"))]
    {
        None
    }
}

pub fn run(mut args: SweepArgs) -> ExitCode {
    args.flags.threads = crate::cli_params::threads_or_warn(args.flags.threads);
    match run_inner(&args) {
        Ok(code) => ExitCode::from(code),
        Err(f) => crate::cli_params::exit_with_error(f.code, &f.message),
    }
}

fn run_inner(args: &SweepArgs) -> Result<u8, Failure> {
    let mut s = setup(args)?;
    if args.plan {
        return fanout::plan(args, &s);
    }
    if let Some(k) = args.run_item {
        return fanout::run_item(args, &mut s, k);
    }
    // The reference file is read before anything renders.
    let file_reference = read_file_reference(args, &s)?;
    if args.collect {
        return fanout::collect(args, &mut s, file_reference);
    }
    std::fs::create_dir_all(&args.output).map_err(|e| fail(format!("cannot create {}: {e}", args.output.display())))?;
    let cancel = cancel_on_interrupt();
    let mut seen = std::mem::take(&mut s.seen);
    let say = |m: String| {
        if !args.quiet {
            eprintln!("{m}");
        }
    };
    let reference = cache::reference(args, &s, file_reference, &cancel, &mut seen, &say)?;
    let out = Outputs::new(args, &s.integrators, reference.json, reference.label);
    let sweep = Sweep { args, s: &s, reference: &reference.image, cancel: &cancel, out: Some(&out), say: &say };
    let mut rows: Vec<Row> = Vec::new();
    let mut error: Option<Failure> = None;
    for name in &s.integrators {
        if let Some(e) = sweep.integrator(name, &mut seen, &mut rows)? {
            error = Some(e);
            break;
        }
    }
    out.write_tables(&rows, error.is_none()).map_err(fail)?;
    let stopped = error.as_ref().map(|e| if e.code == EXIT_CANCELLED { "interrupted" } else { "error" });
    let (summary, plotted) = out.write_report(&rows, args.target_error, stopped).map_err(fail)?;
    print!("{summary}");
    say(format!(
        "wrote {}/{{sweep.csv,sweep.json,{}summary.md}}",
        args.output.display(),
        if plotted { "sweep.png,sweep.svg," } else { "" }
    ));
    match error {
        Some(e) => Err(e),
        None => Ok(0),
    }
}

/// The sweep as a library call (the Python API's `sweep`): the rows `penumbra sweep` would
/// tabulate, checked and rendered exactly as it does, without its tables, plot or summary (a
/// `--reference-spp` reference is still cached under `args.output`). `cancel` stops it at the
/// next tile (then `Err` with [`Failure::cancelled`]); `say` gets the progress lines.
pub fn rows(args: &SweepArgs, cancel: &Arc<AtomicBool>, say: &dyn Fn(String)) -> Result<Vec<Row>, Failure> {
    let mut s = setup(args)?;
    let file_reference = read_file_reference(args, &s)?;
    let mut seen = std::mem::take(&mut s.seen);
    let reference = cache::reference(args, &s, file_reference, cancel, &mut seen, say)?;
    let sweep = Sweep { args, s: &s, reference: &reference.image, cancel, out: None, say };
    let mut rows: Vec<Row> = Vec::new();
    for name in &s.integrators {
        if let Some(e) = sweep.integrator(name, &mut seen, &mut rows)? {
            return Err(e);
        }
    }
    Ok(rows)
}

/// The `--reference` image (R, G, B), checked against the renders' size.
fn read_file_reference(args: &SweepArgs, s: &Setup) -> Result<Option<Image>, Failure> {
    let Some(p) = &args.reference else { return Ok(None) };
    let r = rgb_only(&image::read(p).map_err(fail)?, &p.display().to_string())?;
    check_reference_size(&r, s)?;
    Ok(Some(r))
}

/// What every render of the sweep shares.
struct Sweep<'a> {
    args: &'a SweepArgs,
    s: &'a Setup,
    reference: &'a Image,
    cancel: &'a Arc<AtomicBool>,
    /// Where the tables are rewritten after each render (`None`: no files, as [`rows`]).
    out: Option<&'a Outputs<'a>>,
    say: &'a dyn Fn(String),
}

impl Sweep<'_> {
    /// Renders `name` at each budget of its schedule, appending a row per render (the tables
    /// are rewritten after each). `Ok(Some(e))`: the sweep stops here with `e` (what was
    /// rendered is reported); `Err`: it stops without a report.
    fn integrator(
        &self,
        name: &str,
        seen: &mut BTreeSet<String>,
        rows: &mut Vec<Row>,
    ) -> Result<Option<Failure>, Failure> {
        let (args, say) = (self.args, self.say);
        let mut schedule = match &args.budgets {
            Some(b) => Schedule::explicit(b.clone(), args.time_limit),
            None => Schedule::doubling(Some(args.time_limit.unwrap_or(60.0)), args.max_budget),
        };
        // Samples per pixel already rendered: an integrator may take more than the budget asks
        // (ltc's coverage floor), and a budget below that would render the same image again.
        let mut covered = 0u32;
        while let Some(budget) = schedule.next() {
            if args.budget_param.is_none() && budget <= covered {
                say(format!("{name:>16} {budget:>6}: skipped ({covered} spp already rendered)"));
                schedule.skip();
                continue;
            }
            let timed = match render_one(args, self.s, self.cancel, name, budget, seen)? {
                Ok((r, total_s)) => Timed::of(&r, total_s)?,
                Err(e) => return Ok(Some(e)),
            };
            let taken = taken_budget(args, budget, timed.spp);
            let row = match compare_row(name, taken, &timed, self.reference, !args.no_flip) {
                Ok(row) => row,
                Err(e) => return Ok(Some(e)),
            };
            covered = covered.max(taken);
            schedule.record(taken, row.render_s, row.total_s);
            say(format!(
                "{name:>16} {taken:>6}: build {:.3} s, render {:.3} s, total {:.3} s, {} {}",
                row.build_s,
                row.render_s,
                row.total_s,
                args.metric.column(),
                args.metric.of(&row).map(fmt_num).unwrap_or_else(|| "-".into())
            ));
            rows.push(row);
            if let Some(out) = self.out {
                out.write_tables(rows, false).map_err(fail)?;
            }
            if self.cancel.load(Ordering::SeqCst) {
                return Ok(Some(Failure {
                    code: EXIT_CANCELLED,
                    message: "render cancelled: the finished renders were written".into(),
                }));
            }
        }
        say(format!("{name:>16}: done, {:.2} s in all", schedule.spent()));
        Ok(None)
    }
}

/// The row's budget: what was rendered (more than asked when the integrator raises the spp).
fn taken_budget(args: &SweepArgs, budget: u32, spp: u32) -> u32 {
    if args.budget_param.is_none() {
        budget.max(spp)
    } else {
        budget
    }
}

/// One timed render of `name` at `budget` (spp, or the `--budget-param` value); the inner
/// `Err` is a failed or cancelled render, which stops the sweep.
fn render_one(
    args: &SweepArgs,
    s: &Setup,
    cancel: &AtomicBool,
    name: &str,
    budget: u32,
    seen: &mut BTreeSet<String>,
) -> Result<Result<(pipeline::Rendered, f64), Failure>, Failure> {
    let mut params = s.params.clone();
    let spp = match &args.budget_param {
        Some(p) => {
            params.push(budget_param(p, budget)?);
            args.spp
        }
        None => Some(budget),
    };
    let warnings = DiagSink::new();
    let opts = RenderOptions {
        integrator: Some(name),
        params: &params,
        build: BuildOptions { spp, seed: args.flags.seed, crop: s.crop, resolution: s.resolution },
        threads: args.flags.threads,
        with_variance: false,
        cancel,
        progress: None,
    };
    let t0 = Instant::now();
    let result = pipeline::render(&s.desc, &opts, &warnings);
    let total_s = t0.elapsed().as_secs_f64();
    print_new_warnings(&warnings, seen);
    Ok(match result {
        Ok(r) => Ok((r, total_s)),
        Err(e) => Err(if cancel.load(Ordering::SeqCst) {
            Failure { code: EXIT_CANCELLED, message: format!("{e}: the finished renders were written") }
        } else {
            fail(format!("{name} at budget {budget}: {e}"))
        }),
    })
}
