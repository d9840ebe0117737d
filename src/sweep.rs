//! `penumbra sweep`: error versus time for several integrators.
//!
//! Each integrator renders the scene at a series of budgets (samples per pixel,
//! or an integrator parameter given by `--budget-param`); every render is timed
//! and compared with a reference (R, G, B only). The results go to `OUTDIR`:
//! `sweep.csv`, `sweep.json`, a log-log plot (`sweep.png`, `sweep.svg`) and
//! `summary.md` (error at equal time, time to a target error).

use crate::render::{parse_crop, parse_resolution};
use penumbra::cli_params;
use penumbra::pipeline::{self, RenderOptions};
use penumbra_core::image::{self, Image};
use penumbra_core::metrics;
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_parser::{DiagSink, Param, SceneDescription};
use serde_json::{json, Value};
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The integrator that renders `--reference-spp` references unless `--reference-integrator` names one.
const REFERENCE_INTEGRATOR: &str = "directlighting";
/// Exit status when interrupted (as a shell reports SIGINT).
const EXIT_CANCELLED: u8 = 130;

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("ref").required(true).args(["reference", "reference_spp"])))]
pub struct SweepArgs {
    /// The pbrt-v3 scene file.
    pub scene: PathBuf,
    /// Reference image (.exr, .png or .pfm) of the same size as the renders.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Render the reference with --reference-integrator at N spp instead (cached under OUTDIR/cache/).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub reference_spp: Option<u32>,
    /// The integrator of the `--reference-spp` render: the estimator the others should converge
    /// to (`path` for scenes lit by more than direct light).
    #[arg(long, value_name = "NAME", default_value = REFERENCE_INTEGRATOR)]
    pub reference_integrator: String,
    /// Sampler seed of the `--reference-spp` render (default: --seed + 1, so that the
    /// reference's samples are not the renders' samples).
    #[arg(long, value_name = "S")]
    pub reference_seed: Option<u64>,
    /// Integrators to compare, comma-separated.
    #[arg(short = 'i', long = "integrators", value_delimiter = ',', required = true, value_name = "NAME[,NAME...]")]
    pub integrators: Vec<String>,
    /// Explicit budgets, comma-separated (default: 1, 2, 4, ... until --time-limit).
    #[arg(long, value_delimiter = ',', value_name = "B[,B...]", value_parser = clap::value_parser!(u32).range(1..))]
    pub budgets: Option<Vec<u32>>,
    /// Seconds of build + render per integrator: the next budget is skipped when the time
    /// predicted from the previous render would exceed it (default 60; with --budgets,
    /// no limit unless given).
    #[arg(long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// Largest budget of the doubling schedule.
    #[arg(long, default_value_t = 65536, value_name = "B", value_parser = clap::value_parser!(u32).range(1..))]
    pub max_budget: u32,
    /// The budget sets this integrator parameter (`--param NAME=budget`) instead of the spp.
    #[arg(long, value_name = "NAME")]
    pub budget_param: Option<String>,
    /// Samples per pixel when the budget is a parameter (default: the scene's sampler).
    #[arg(long, requires = "budget_param", value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: Option<u32>,
    /// Integrator parameter `key=value` for every integrator (repeatable; type inferred).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Sampler seed of the renders.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Override the film resolution `WxH`.
    #[arg(long)]
    pub resolution: Option<String>,
    /// Crop `x0,x1,y0,y1` (as `penumbra render --crop`).
    #[arg(long)]
    pub crop: Option<String>,
    /// Output directory.
    #[arg(short = 'o', long = "output", default_value = "sweep-out")]
    pub output: PathBuf,
    /// Error to reach for the "time to error" column (default: the error directlighting
    /// reaches at its largest budget, else the smallest error of the first integrator).
    #[arg(long, value_name = "E")]
    pub target_error: Option<f64>,
    /// The error plotted and summarised.
    #[arg(long, value_enum, default_value_t = Metric::Rmse)]
    pub metric: Metric,
    /// Do not compute FLIP (it is computed outside the timed region anyway).
    #[arg(long)]
    pub no_flip: bool,
    /// Only the summary on stdout; no per-render lines.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// An error metric, lower is better (PSNR is recorded but cannot be plotted on a log axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Metric {
    Mae,
    Rmse,
    #[value(name = "max_err", alias = "max-err")]
    MaxErr,
    Relmse,
    Smape,
    Flip,
}

impl Metric {
    fn column(self) -> &'static str {
        match self {
            Metric::Mae => "mae",
            Metric::Rmse => "rmse",
            Metric::MaxErr => "max_err",
            Metric::Relmse => "relmse",
            Metric::Smape => "smape",
            Metric::Flip => "flip",
        }
    }
    fn label(self) -> &'static str {
        match self {
            Metric::Mae => "MAE",
            Metric::Rmse => "RMSE",
            Metric::MaxErr => "max error",
            Metric::Relmse => "relMSE",
            Metric::Smape => "SMAPE",
            Metric::Flip => "FLIP",
        }
    }
    fn of(self, r: &Row) -> Option<f64> {
        Some(match self {
            Metric::Mae => r.mae,
            Metric::Rmse => r.rmse,
            Metric::MaxErr => r.max_err,
            Metric::Relmse => r.relmse,
            Metric::Smape => r.smape,
            Metric::Flip => r.flip?,
        })
    }
}

/// One render of the sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub integrator: String,
    pub budget: u32,
    /// Samples per pixel actually rendered.
    pub spp: u32,
    /// Scene build (the pipeline's build report).
    pub build_s: f64,
    /// The integrator's render (its own clock).
    pub render_s: f64,
    /// Wall time around choose-integrator + build + render + film readout.
    pub total_s: f64,
    pub mae: f64,
    pub rmse: f64,
    pub psnr: f64,
    pub max_err: f64,
    pub relmse: f64,
    pub smape: f64,
    pub flip: Option<f64>,
    /// Non-finite (NaN or infinite) R, G, B values in the render.
    pub nan_count: u64,
}

pub const CSV_HEADER: &str =
    "integrator,budget,build_s,render_s,total_s,mae,rmse,psnr,max_err,relmse,smape,flip,nan_count";

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn csv_text(rows: &[Row]) -> String {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.integrator),
            r.budget,
            r.build_s,
            r.render_s,
            r.total_s,
            r.mae,
            r.rmse,
            r.psnr,
            r.max_err,
            r.relmse,
            r.smape,
            r.flip.map(|v| v.to_string()).unwrap_or_default(),
            r.nan_count
        );
    }
    s
}

/// A JSON number, or "inf" / "-inf" / "nan" for non-finite values.
fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else if v.is_nan() {
        json!("nan")
    } else if v > 0.0 {
        json!("inf")
    } else {
        json!("-inf")
    }
}

fn row_json(r: &Row) -> Value {
    json!({
        "integrator": r.integrator,
        "budget": r.budget,
        "spp": r.spp,
        "build_s": num(r.build_s),
        "render_s": num(r.render_s),
        "total_s": num(r.total_s),
        "mae": num(r.mae),
        "rmse": num(r.rmse),
        "psnr": num(r.psnr),
        "max_err": num(r.max_err),
        "relmse": num(r.relmse),
        "smape": num(r.smape),
        "flip": r.flip.map(num).unwrap_or(Value::Null),
        "nan_count": r.nan_count,
    })
}

// ---------------------------------------------------------------------------
// Budget schedule

/// Which budgets to render for one integrator: an explicit list, or 1, 2, 4, …
/// (up to `max_budget`); either way, with a time limit, a budget is skipped (and
/// the schedule ends) when the previous render predicts that it would take the
/// integrator's total over the limit. The prediction keeps the previous render's
/// fixed cost (total − render time) and scales its render time by the budget ratio.
#[derive(Clone, Debug)]
pub struct Schedule {
    explicit: Option<Vec<u32>>,
    index: usize,
    time_limit: Option<f64>,
    max_budget: u32,
    spent: f64,
    /// (budget, render seconds, total seconds) of the previous render.
    last: Option<(u32, f64, f64)>,
}

impl Schedule {
    pub fn doubling(time_limit: Option<f64>, max_budget: u32) -> Schedule {
        Schedule { explicit: None, index: 0, time_limit, max_budget: max_budget.max(1), spent: 0.0, last: None }
    }

    pub fn explicit(budgets: Vec<u32>, time_limit: Option<f64>) -> Schedule {
        Schedule { explicit: Some(budgets), index: 0, time_limit, max_budget: u32::MAX, spent: 0.0, last: None }
    }

    /// Predicted total seconds of a render at `budget` after one at `last_budget`
    /// that took `last_render_s` rendering and `last_total_s` in all.
    pub fn predict(last_budget: u32, last_render_s: f64, last_total_s: f64, budget: u32) -> f64 {
        let fixed = (last_total_s - last_render_s).max(0.0);
        fixed + last_render_s.max(0.0) * budget as f64 / last_budget.max(1) as f64
    }

    /// The next budget to render, or `None` when the schedule is over.
    pub fn next(&self) -> Option<u32> {
        let candidate = match &self.explicit {
            Some(list) => *list.get(self.index)?,
            None => match self.last {
                None => 1,
                Some((b, _, _)) => b.checked_mul(2)?,
            },
        };
        if candidate > self.max_budget {
            return None;
        }
        if let (Some(limit), Some((b, render, total))) = (self.time_limit, self.last) {
            if self.spent + Schedule::predict(b, render, total, candidate) > limit {
                return None;
            }
        }
        Some(candidate)
    }

    /// Passes over the next budget of an explicit list without rendering it.
    pub fn skip(&mut self) {
        self.index += 1;
    }

    /// Records a finished render (`budget`: what it rendered, which may exceed what was asked).
    pub fn record(&mut self, budget: u32, render_s: f64, total_s: f64) {
        self.index += 1;
        self.spent += total_s;
        self.last = Some((budget, render_s, total_s));
    }

    pub fn spent(&self) -> f64 {
        self.spent
    }
}

// ---------------------------------------------------------------------------
// Log-log curves

/// Points `(x, y)` with positive, finite coordinates, sorted by `x`.
pub fn positive_sorted(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> =
        points.iter().copied().filter(|&(x, y)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite()).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    p
}

/// `y` at `x` on the piecewise-linear curve through `points` in log-log space
/// (`points` as [`positive_sorted`] returns them); `None` outside their `x` range.
pub fn interp_loglog(points: &[(f64, f64)], x: f64) -> Option<f64> {
    if !(x > 0.0) || !x.is_finite() {
        return None;
    }
    let first = points.first()?;
    let last = points.last()?;
    if x < first.0 || x > last.0 {
        return None;
    }
    if let Some(p) = points.iter().find(|p| p.0 == x) {
        return Some(p.1);
    }
    let i = points.windows(2).position(|w| w[0].0 <= x && x <= w[1].0)?;
    let (a, b) = (points[i], points[i + 1]);
    let u = (x.ln() - a.0.ln()) / (b.0.ln() - a.0.ln());
    Some((a.1.ln() + u * (b.1.ln() - a.1.ln())).exp())
}

/// When a run reaches an error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reach {
    /// Already the first render (at this time) is at or below the error.
    AtFirst(f64),
    /// Log-log interpolation between the renders that bracket the error.
    At(f64),
    NotReached,
}

/// The time at which the run `points` (`(time, error)` in budget order) first
/// gets to `target`: log-time interpolated linearly in log-error between the
/// last render above the target and the first at or below it.
pub fn time_to_reach(points: &[(f64, f64)], target: f64) -> Reach {
    let ok = |&(t, e): &(f64, f64)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite();
    let pts: Vec<(f64, f64)> = points.iter().copied().filter(ok).collect();
    if !(target > 0.0) || !target.is_finite() {
        return Reach::NotReached;
    }
    let Some(i) = pts.iter().position(|p| p.1 <= target) else {
        return Reach::NotReached;
    };
    if i == 0 {
        return Reach::AtFirst(pts[0].0);
    }
    let (a, b) = (pts[i - 1], pts[i]);
    let u = (target.ln() - a.1.ln()) / (b.1.ln() - a.1.ln());
    Reach::At((a.0.ln() + u * (b.0.ln() - a.0.ln())).exp())
}

/// Least-squares slope of log(y) against log(x) (≈ −0.5 for Monte Carlo noise); `None`
/// with fewer than two distinct `x`.
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let p = positive_sorted(points);
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let mx = p.iter().map(|q| q.0.ln()).sum::<f64>() / n;
    let my = p.iter().map(|q| q.1.ln()).sum::<f64>() / n;
    let sxx: f64 = p.iter().map(|q| (q.0.ln() - mx).powi(2)).sum();
    let sxy: f64 = p.iter().map(|q| (q.0.ln() - mx) * (q.1.ln() - my)).sum();
    (sxx > 1e-12).then(|| sxy / sxx)
}

// ---------------------------------------------------------------------------
// Reference cache key

/// 64-bit FNV-1a.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The cache key of a `--reference-spp` render.
pub fn reference_key(
    scene_bytes: &[u8],
    integrator: &str,
    resolution: Option<(u32, u32)>,
    crop: Option<Crop>,
    spp: u32,
    seed: u64,
) -> String {
    let mut key = b"penumbra-sweep-reference-v1\0".to_vec();
    key.extend_from_slice(scene_bytes);
    key.extend_from_slice(
        format!("\0integrator={integrator}\0resolution={resolution:?}\0crop={crop:?}\0spp={spp}\0seed={seed}")
            .as_bytes(),
    );
    format!("{:016x}", fnv1a64(&key))
}

// ---------------------------------------------------------------------------
// Output

fn write_text(path: &Path, text: &str) -> Result<(), String> {
    image::write_atomic(path, |w| w.write_all(text.as_bytes())).map_err(|e| e.to_string())
}

fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    }
}

/// Everything the summary needs besides the rows.
pub struct SummaryInput<'a> {
    pub scene: &'a str,
    pub reference: &'a str,
    pub metric: Metric,
    pub budget_name: &'a str,
    pub target: Option<(f64, String)>,
    pub threads: usize,
    pub integrators: &'a [String],
    /// Why the sweep stopped early, if it did.
    pub stopped: Option<&'a str>,
}

/// An integrator's `(time, error)` points and budgets, in budget order.
type Curve = (String, Vec<(f64, f64)>, Vec<u32>);

fn curves(rows: &[Row], names: &[String], metric: Metric) -> Vec<Curve> {
    names
        .iter()
        .map(|n| {
            let mine: Vec<&Row> = rows.iter().filter(|r| &r.integrator == n).collect();
            let pts = mine.iter().filter_map(|r| Some((r.total_s, metric.of(r)?))).collect();
            (n.clone(), pts, mine.iter().map(|r| r.budget).collect())
        })
        .collect()
}

/// The default target error: directlighting's error at its largest budget, else the
/// smallest error of the first integrator.
pub fn default_target(rows: &[Row], names: &[String], metric: Metric) -> Option<(f64, String)> {
    let valid = |e: &f64| *e > 0.0 && e.is_finite();
    if names.iter().any(|n| n == REFERENCE_INTEGRATOR) {
        if let Some(r) = rows.iter().filter(|r| r.integrator == REFERENCE_INTEGRATOR).max_by_key(|r| r.budget) {
            if let Some(e) = metric.of(r).filter(valid) {
                return Some((
                    e,
                    format!("the {} directlighting reaches at its largest budget, {}", metric.label(), r.budget),
                ));
            }
        }
    }
    let first = names.first()?;
    let e =
        rows.iter().filter(|r| &r.integrator == first).filter_map(|r| metric.of(r)).filter(valid).reduce(f64::min)?;
    Some((e, format!("the smallest {} {first} reached", metric.label())))
}

pub fn summary_markdown(rows: &[Row], s: &SummaryInput) -> String {
    let m = s.metric.label();
    let cs = curves(rows, s.integrators, s.metric);
    let sorted: Vec<Vec<(f64, f64)>> = cs.iter().map(|c| positive_sorted(&c.1)).collect();
    let equal_time = sorted
        .iter()
        .map(|p| p.last().map(|q| q.0))
        .collect::<Option<Vec<f64>>>()
        .and_then(|v| v.into_iter().reduce(f64::min));
    let mut out = String::new();
    let _ = writeln!(out, "# penumbra sweep: {}\n", s.scene);
    let _ = writeln!(out, "Reference: {}. Error: {m} of R, G, B against it. Budget: {}.\n", s.reference, s.budget_name);
    if let Some(why) = s.stopped {
        let _ = writeln!(out, "**The sweep stopped early ({why}): only the renders that finished are included.**\n");
    }
    let eq_head = match equal_time {
        Some(t) => format!("{m} at {} s", fmt_num(t)),
        None => format!("{m} at equal time"),
    };
    let target_head = match &s.target {
        Some((e, _)) => format!("time to {m} {}", fmt_num(*e)),
        None => "time to target".into(),
    };
    let _ = writeln!(
        out,
        "| integrator | renders | budgets | time range (s) | final {m} | {eq_head} | {target_head} | log-log slope |"
    );
    let _ = writeln!(out, "|---|---:|---|---|---:|---:|---:|---:|");
    for ((name, pts, budgets), sp) in cs.iter().zip(&sorted) {
        let budgets_txt = match (budgets.first(), budgets.last()) {
            (Some(a), Some(b)) if a != b => format!("{a}-{b}"),
            (Some(a), _) => a.to_string(),
            _ => "-".into(),
        };
        let range = match (sp.first(), sp.last()) {
            (Some(a), Some(b)) => format!("{}-{}", fmt_num(a.0), fmt_num(b.0)),
            _ => "-".into(),
        };
        let last = pts.last().map(|p| fmt_num(p.1)).unwrap_or_else(|| "-".into());
        let at_eq = match equal_time {
            Some(t) => match interp_loglog(sp, t) {
                Some(e) => fmt_num(e),
                None => format!("n/a (first render took {} s)", sp.first().map(|p| fmt_num(p.0)).unwrap_or_default()),
            },
            None => "-".into(),
        };
        let reach = match &s.target {
            Some(_) if pts.is_empty() => "-".into(),
            Some((e, _)) => match time_to_reach(pts, *e) {
                Reach::AtFirst(t) => format!("<= {} s (first render)", fmt_num(t)),
                Reach::At(t) => format!("{} s", fmt_num(t)),
                Reach::NotReached => "not reached".into(),
            },
            None => "-".into(),
        };
        let slope = loglog_slope(pts).map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
        let _ = writeln!(
            out,
            "| {name} | {} | {budgets_txt} | {range} | {last} | {at_eq} | {reach} | {slope} |",
            budgets.len()
        );
    }
    let _ = writeln!(out, "\nNotes:");
    if let Some(t) = equal_time {
        let _ = writeln!(
            out,
            "- Equal time: each integrator's log({m})-log(time) curve is interpolated linearly at {} s, the largest total time every integrator reached.",
            fmt_num(t)
        );
    }
    if let Some((e, why)) = &s.target {
        let _ = writeln!(
            out,
            "- Target {m} {} ({why}): the time is interpolated in log-log between the last render above it and the first at or below it; \"not reached\" if no render got there.",
            fmt_num(*e)
        );
    }
    let _ = writeln!(
        out,
        "- Times are wall-clock seconds of scene build + render per budget on {} threads (parsing excluded); the slope is the least-squares fit of log({m}) against log(time) (-0.5 for plain Monte Carlo noise).",
        s.threads
    );
    out
}

// ---------------------------------------------------------------------------
// Plot

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans-ascii.ttf");

const COLOURS: [(u8, u8, u8); 8] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
];

/// One plotted line: the integrator and its renders' (time, error, budget).
pub type Series = (String, Vec<(f64, f64, u32)>);

pub const PLOT_SIZE: (u32, u32) = (800, 560);

fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&a) {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    }
}

fn draw_chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    metric: Metric,
    series: &[Series],
) -> Result<(), String> {
    use plotters::prelude::*;
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let all = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y, _) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !(x0 <= x1 && y0 <= y1) {
        return Err("nothing to plot".into());
    }
    let pad = |lo: f64, hi: f64| {
        let r = (hi / lo).max(1.0).ln();
        let m = (0.08 * r).max(0.15);
        (lo * (-m).exp(), hi * m.exp())
    };
    let (x0, x1) = pad(x0, x1);
    let (y0, y1) = pad(y0, y1);
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("total time: build + render (s)")
        .y_desc(format!("{} vs reference", metric.label()))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(e)?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let (r, g, b) = COLOURS[i % COLOURS.len()];
        let colour = RGBColor(r, g, b);
        chart
            .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.1)), colour.stroke_width(2)))
            .map_err(e)?
            .label(name.as_str())
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (22, 0)], colour.stroke_width(2))
                    + Circle::new((11, 0), 4, colour.filled())
            });
        chart.draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 4, colour.filled()))).map_err(e)?;
        chart
            .draw_series(pts.iter().map(|p| {
                EmptyElement::at((p.0, p.1))
                    + Text::new(p.2.to_string(), (5, -16), ("sans-serif", 11).into_font().color(&RGBColor(90, 90, 90)))
            }))
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// Draws the plot as SVG text and as PNG bytes.
pub fn render_plots(title: &str, metric: Metric, series: &[Series]) -> Result<(String, Vec<u8>), String> {
    use plotters::prelude::*;
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "the embedded plot font is invalid".to_string())?;
    let mut svg = String::new();
    draw_chart(SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    draw_chart(BitMapBackend::with_buffer(&mut rgb, PLOT_SIZE).into_drawing_area(), title, metric, series)?;
    let png = image::encode_png_rgb8(w, h, &rgb, Path::new("sweep.png")).map_err(|e| e.to_string())?;
    Ok((svg, png))
}

// ---------------------------------------------------------------------------
// The command

struct Failure {
    code: u8,
    message: String,
}

fn fail(message: impl std::fmt::Display) -> Failure {
    Failure { code: 1, message: message.to_string() }
}

/// What the sweep writes, kept up to date as rows arrive.
struct Outputs<'a> {
    dir: &'a Path,
    scene: String,
    reference: Value,
    reference_label: String,
    integrators: Vec<String>,
    metric: Metric,
    budget_name: String,
    threads: usize,
    args_json: Value,
}

impl Outputs<'_> {
    fn write_tables(&self, rows: &[Row], complete: bool) -> Result<(), String> {
        write_text(&self.dir.join("sweep.csv"), &csv_text(rows))?;
        let machine_threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        let doc = json!({
            "scene": self.scene,
            "reference": self.reference,
            "integrators": self.integrators,
            "metric": self.metric.column(),
            "budget": self.budget_name,
            "machine": { "threads": machine_threads },
            "threads": self.threads,
            "arguments": self.args_json,
            "complete": complete,
            "rows": rows.iter().map(row_json).collect::<Vec<_>>(),
        });
        write_text(&self.dir.join("sweep.json"), &(serde_json::to_string_pretty(&doc).unwrap_or_default() + "\n"))
    }

    /// The plot (if there is anything to plot) and the summary; returns the summary text and
    /// whether the plot was written.
    fn write_report(&self, rows: &[Row], target: Option<f64>, stopped: Option<&str>) -> Result<(String, bool), String> {
        let target = match target {
            Some(e) => Some((e, "given with --target-error".to_string())),
            None => default_target(rows, &self.integrators, self.metric),
        };
        let summary = summary_markdown(
            rows,
            &SummaryInput {
                scene: &self.scene,
                reference: &self.reference_label,
                metric: self.metric,
                budget_name: &self.budget_name,
                target,
                threads: self.threads,
                integrators: &self.integrators,
                stopped,
            },
        );
        write_text(&self.dir.join("summary.md"), &summary)?;
        let series: Vec<Series> = self
            .integrators
            .iter()
            .map(|n| {
                let pts = rows
                    .iter()
                    .filter(|r| &r.integrator == n)
                    .filter_map(|r| Some((r.total_s, self.metric.of(r)?, r.budget)))
                    .filter(|&(t, e, _)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite())
                    .collect();
                (n.clone(), pts)
            })
            .filter(|s: &Series| !s.1.is_empty())
            .collect();
        let (png, svg) = (self.dir.join("sweep.png"), self.dir.join("sweep.svg"));
        if series.is_empty() {
            let _ = std::fs::remove_file(&png);
            let _ = std::fs::remove_file(&svg);
            Ok((summary, false))
        } else {
            let name = Path::new(&self.scene).file_name().map(|s| s.to_string_lossy().into_owned());
            let title = format!("{}: {} vs time", name.unwrap_or_else(|| self.scene.clone()), self.metric.label());
            let (svg_text, png_bytes) = render_plots(&title, self.metric, &series)?;
            write_text(&svg, &svg_text)?;
            image::write_atomic(&png, |w| w.write_all(&png_bytes)).map_err(|e| e.to_string())?;
            Ok((summary, true))
        }
    }
}

fn rgb_only(img: &Image, what: &str) -> Result<Image, Failure> {
    img.select_channels(&["R", "G", "B"]).map_err(|e| fail(format!("{what}: {e}")))
}

fn print_new_warnings(w: &DiagSink, seen: &mut BTreeSet<String>) {
    for d in w.take() {
        let text = d.to_string();
        if seen.insert(text.clone()) {
            eprint!("{text}");
        }
    }
}

fn compare_row(
    integrator: &str,
    budget: u32,
    rendered: &pipeline::Rendered,
    total_s: f64,
    reference: &Image,
    with_flip: bool,
) -> Result<Row, Failure> {
    let test = rgb_only(&rendered.image, "render")?;
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(fail(format!(
            "the reference is {}x{} but the render is {}x{} (render at the reference's size with --resolution/--crop)",
            reference.width, reference.height, test.width, test.height
        )));
    }
    let c = metrics::compare(&test, reference, 1e-6, 1e-6).map_err(fail)?;
    let flip = if with_flip { flip_of(&test, reference) } else { None };
    Ok(Row {
        integrator: integrator.to_string(),
        budget,
        spp: rendered.stats.spp,
        build_s: rendered.build.total_seconds(),
        render_s: rendered.stats.render_seconds,
        total_s,
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

struct Setup {
    desc: SceneDescription,
    scene_bytes: Vec<u8>,
    params: Vec<Param>,
    crop: Option<Crop>,
    resolution: Option<(u32, u32)>,
    integrators: Vec<String>,
    /// Warnings already printed.
    seen: BTreeSet<String>,
}

fn setup(args: &SweepArgs) -> Result<Setup, Failure> {
    let mut integrators: Vec<String> = Vec::new();
    for n in args.integrators.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        if penumbra_integrators::find(n).is_none() {
            return Err(fail(format!(
                "unknown integrator \"{n}\"; valid names: {}",
                penumbra_integrators::names().join(", ")
            )));
        }
        if !integrators.iter().any(|m| m == n) {
            integrators.push(n.to_string());
        }
    }
    if args.reference_spp.is_some() && penumbra_integrators::find(&args.reference_integrator).is_none() {
        return Err(fail(format!(
            "unknown reference integrator \"{}\"; valid names: {}",
            args.reference_integrator,
            penumbra_integrators::names().join(", ")
        )));
    }
    if integrators.is_empty() {
        return Err(fail("-i: no integrator given"));
    }
    if let Some(t) = args.time_limit {
        if !(t > 0.0) || !t.is_finite() {
            return Err(fail("--time-limit must be a positive number of seconds"));
        }
    }
    if let Some(e) = args.target_error {
        if !(e > 0.0) || !e.is_finite() {
            return Err(fail("--target-error must be a positive number"));
        }
    }
    if matches!(&args.budgets, Some(b) if b.is_empty()) {
        return Err(fail("--budgets: empty list"));
    }
    if args.metric == Metric::Flip && (args.no_flip || !metrics::FLIP_AVAILABLE) {
        return Err(fail(if args.no_flip {
            "--metric flip contradicts --no-flip"
        } else {
            "--metric flip: FLIP is not available in this build"
        }));
    }
    if let Some(p) = &args.budget_param {
        if p.trim().is_empty() || p.contains('=') {
            return Err(fail("--budget-param expects a parameter name"));
        }
    }
    let params = args
        .params
        .iter()
        .map(|p| cli_params::parse_param(p))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| fail(e.message))?;
    let crop = args.crop.as_deref().map(parse_crop).transpose().map_err(fail)?;
    let resolution = args.resolution.as_deref().map(parse_resolution).transpose().map_err(fail)?;
    let scene_bytes =
        std::fs::read(&args.scene).map_err(|e| fail(format!("cannot read scene {}: {e}", args.scene.display())))?;
    let parsed = pipeline::load_scene(Some(&args.scene)).map_err(|d| Failure { code: 1, message: d.to_string() })?;
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    // Create each integrator once with its parameters, so that bad values fail before any render.
    for n in &integrators {
        let mut p = params.clone();
        if let Some(name) = &args.budget_param {
            p.push(budget_param(name, 1)?);
        }
        pipeline::choose_integrator(&parsed.scene, Some(n), &p, &warnings)
            .map_err(|d| Failure { code: 1, message: format!("integrator \"{n}\": {}", d.message) })?;
        // The budget parameter must be one the integrator reads.
        if let (Some(name), Some(entry)) = (&args.budget_param, penumbra_integrators::find(n)) {
            let ps = cli_params::merge(&Default::default(), &[budget_param(name, 1)?]);
            let _ = (entry.create)(&ps, &DiagSink::new());
            if !ps.find(name.trim()).is_some_and(|p| p.was_used()) {
                return Err(fail(format!("--budget-param {}: integrator \"{n}\" has no such parameter", name.trim())));
            }
        }
    }
    let mut seen = BTreeSet::new();
    print_new_warnings(&warnings, &mut seen);
    Ok(Setup { desc: parsed.scene, scene_bytes, params, crop, resolution, integrators, seen })
}

fn budget_param(name: &str, budget: u32) -> Result<Param, Failure> {
    cli_params::parse_param(&format!("{}={budget}", name.trim())).map_err(|e| fail(e.message))
}

pub fn run(args: SweepArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            let m = f.message.trim_end();
            if m.starts_with("error") || m.contains(": error") {
                eprintln!("{m}");
            } else {
                eprintln!("error: {m}");
            }
            ExitCode::from(f.code)
        }
    }
}

fn run_inner(args: &SweepArgs) -> Result<u8, Failure> {
    let mut s = setup(args)?;
    // The reference file is read before anything renders.
    let mut reference = match &args.reference {
        Some(p) => Some(rgb_only(&image::read(p).map_err(fail)?, &p.display().to_string())?),
        None => None,
    };
    std::fs::create_dir_all(&args.output).map_err(|e| fail(format!("cannot create {}: {e}", args.output.display())))?;

    let cancel = Arc::new(AtomicBool::new(false));
    {
        let c = cancel.clone();
        let _ = ctrlc::set_handler(move || {
            if c.swap(true, Ordering::SeqCst) {
                std::process::exit(EXIT_CANCELLED as i32);
            }
        });
    }
    let mut seen = std::mem::take(&mut s.seen);
    let say = |m: String| {
        if !args.quiet {
            eprintln!("{m}");
        }
    };

    let reference_json;
    let reference_label;
    match (&args.reference, args.reference_spp) {
        (Some(p), _) => {
            reference_json = json!({ "kind": "file", "path": p.display().to_string() });
            reference_label = format!("`{}`", p.display());
        }
        (None, Some(n)) => {
            let rseed = args.reference_seed.unwrap_or(args.seed.wrapping_add(1));
            let ri = args.reference_integrator.as_str();
            let key = reference_key(&s.scene_bytes, ri, s.resolution, s.crop, n, rseed);
            let cache_dir = args.output.join("cache");
            let path = cache_dir.join(format!("{key}.exr"));
            let cached = match image::read(&path) {
                Ok(img) => match rgb_only(&img, &path.display().to_string()) {
                    Ok(i) => Some(i),
                    Err(e) => {
                        eprintln!("warning: ignoring cached reference: {}", e.message);
                        None
                    }
                },
                Err(e) if path.exists() => {
                    eprintln!("warning: ignoring unreadable cached reference: {e}");
                    None
                }
                Err(_) => None,
            };
            let was_cached = cached.is_some();
            if let Some(img) = cached {
                say(format!("using cached reference {} ({ri}, {n} spp)", path.display()));
                reference = Some(img);
            } else {
                say(format!("rendering reference: {ri} at {n} spp, seed {rseed}"));
                std::fs::create_dir_all(&cache_dir)
                    .map_err(|e| fail(format!("cannot create {}: {e}", cache_dir.display())))?;
                let warnings = DiagSink::new();
                let t0 = Instant::now();
                let opts = RenderOptions {
                    integrator: Some(ri),
                    params: &[],
                    build: BuildOptions { spp: Some(n), seed: rseed, crop: s.crop, resolution: s.resolution },
                    threads: args.threads,
                    with_variance: false,
                    cancel: &cancel,
                    progress: None,
                };
                let result = pipeline::render(&s.desc, &opts, &warnings);
                print_new_warnings(&warnings, &mut seen);
                let r = match result {
                    Ok(r) => r,
                    Err(e) if cancel.load(Ordering::SeqCst) => {
                        return Err(Failure { code: EXIT_CANCELLED, message: format!("{e}: nothing was written") })
                    }
                    Err(e) => return Err(fail(format!("reference render: {e}"))),
                };
                let img = rgb_only(&r.image, "reference render")?;
                image::write(&img, &path).map_err(fail)?;
                say(format!("reference written to {} in {:.2} s", path.display(), t0.elapsed().as_secs_f64()));
                reference = Some(img);
            }
            reference_json = json!({
                "kind": "rendered",
                "integrator": ri,
                "spp": n,
                "seed": rseed,
                "path": path.display().to_string(),
                "cached": was_cached,
            });
            reference_label = format!("{ri} at {n} spp (seed {rseed}), `{}`", path.display());
        }
        (None, None) => return Err(fail("give --reference or --reference-spp")),
    }
    let Some(reference) = reference else {
        return Err(fail("no reference"));
    };

    let threads = if args.threads == 0 {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
    } else {
        args.threads
    };
    let out = Outputs {
        dir: &args.output,
        scene: args.scene.display().to_string(),
        reference: reference_json,
        reference_label,
        integrators: s.integrators.clone(),
        metric: args.metric,
        budget_name: match &args.budget_param {
            Some(p) => format!("parameter \"{}\"", p.trim()),
            None => "samples per pixel".into(),
        },
        threads,
        args_json: json!({
            "budgets": args.budgets,
            "time_limit": args.time_limit,
            "max_budget": args.max_budget,
            "budget_param": args.budget_param,
            "spp": args.spp,
            "params": args.params,
            "seed": args.seed,
            "resolution": args.resolution,
            "crop": args.crop,
        }),
    };

    let mut rows: Vec<Row> = Vec::new();
    let mut error: Option<Failure> = None;
    'outer: for name in &s.integrators {
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
                build: BuildOptions { spp, seed: args.seed, crop: s.crop, resolution: s.resolution },
                threads: args.threads,
                with_variance: false,
                cancel: &cancel,
                progress: None,
            };
            let t0 = Instant::now();
            let result = pipeline::render(&s.desc, &opts, &warnings);
            let total_s = t0.elapsed().as_secs_f64();
            print_new_warnings(&warnings, &mut seen);
            let r = match result {
                Ok(r) => r,
                Err(e) => {
                    error = Some(if cancel.load(Ordering::SeqCst) {
                        Failure { code: EXIT_CANCELLED, message: format!("{e}: the finished renders were written") }
                    } else {
                        fail(format!("{name} at budget {budget}: {e}"))
                    });
                    break 'outer;
                }
            };
            // The row's budget is what was rendered (more than asked when the integrator raises it).
            let taken = if args.budget_param.is_none() { budget.max(r.stats.spp) } else { budget };
            let row = match compare_row(name, taken, &r, total_s, &reference, !args.no_flip) {
                Ok(row) => row,
                Err(e) => {
                    error = Some(e);
                    break 'outer;
                }
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
            out.write_tables(&rows, false).map_err(fail)?;
            if cancel.load(Ordering::SeqCst) {
                error = Some(Failure {
                    code: EXIT_CANCELLED,
                    message: "render cancelled: the finished renders were written".into(),
                });
                break 'outer;
            }
        }
        say(format!("{name:>16}: done, {:.2} s in all", schedule.spent()));
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

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn loglog_interpolation_hand_computed() {
        let p = positive_sorted(&[(16.0, 0.25), (1.0, 1.0), (4.0, 0.5)]);
        assert_eq!(p, vec![(1.0, 1.0), (4.0, 0.5), (16.0, 0.25)]);
        // Halfway between 1 and 4 in log x: sqrt(1 * 0.5).
        assert!(close(interp_loglog(&p, 2.0).unwrap(), 0.5f64.sqrt()));
        // Between 4 and 16 at 8: sqrt(0.5 * 0.25).
        assert!(close(interp_loglog(&p, 8.0).unwrap(), (0.125f64).sqrt()));
        // A quarter of the way from 4 to 16 in log x: 0.5 * (0.5)^(1/4).
        assert!(close(interp_loglog(&p, 4.0 * 4f64.powf(0.25)).unwrap(), 0.5 * 0.5f64.powf(0.25)));
        assert_eq!(interp_loglog(&p, 4.0), Some(0.5));
        assert_eq!(interp_loglog(&p, 16.0), Some(0.25));
        assert_eq!(interp_loglog(&p, 0.5), None);
        assert_eq!(interp_loglog(&p, 17.0), None);
        assert_eq!(interp_loglog(&[], 1.0), None);
        // Zero / NaN errors are dropped, not interpolated through.
        assert_eq!(positive_sorted(&[(1.0, 0.0), (2.0, f64::NAN), (3.0, 1.0)]), vec![(3.0, 1.0)]);
    }

    #[test]
    fn time_to_reach_hand_computed() {
        let run = [(1.0, 1.0), (4.0, 0.5), (16.0, 0.25)];
        // 0.25·√2 is halfway (in log) between 0.5 and 0.25: time √(4·16) = 8.
        match time_to_reach(&run, 0.25 * 2f64.sqrt()) {
            Reach::At(t) => assert!(close(t, 8.0), "{t}"),
            other => panic!("{other:?}"),
        }
        // Exactly an error reached: that render's time.
        match time_to_reach(&run, 0.5) {
            Reach::At(t) => assert!(close(t, 4.0), "{t}"),
            other => panic!("{other:?}"),
        }
        assert_eq!(time_to_reach(&run, 2.0), Reach::AtFirst(1.0));
        assert_eq!(time_to_reach(&run, 0.1), Reach::NotReached);
        assert_eq!(time_to_reach(&run, 0.0), Reach::NotReached);
        // Non-monotone error: the first crossing counts. 0.6 between (1, 1) and (2, 0.5):
        // log t = log 2 · ln(0.6)/ln(0.5).
        let bumpy = [(1.0, 1.0), (2.0, 0.5), (4.0, 0.7), (8.0, 0.3)];
        match time_to_reach(&bumpy, 0.6) {
            Reach::At(t) => assert!(close(t, 2f64.powf(0.6f64.ln() / 0.5f64.ln())), "{t}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn slope_of_power_law() {
        let p: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 8.0].iter().map(|&t: &f64| (t, 3.0 * t.powf(-0.5))).collect();
        assert!((loglog_slope(&p).unwrap() + 0.5).abs() < 1e-12);
        assert_eq!(loglog_slope(&p[..1]), None);
    }

    #[test]
    fn doubling_schedule_stops_before_the_limit() {
        let mut s = Schedule::doubling(Some(10.0), 1 << 20);
        assert_eq!(s.next(), Some(1));
        // 0.5 s fixed + 1 s rendering.
        s.record(1, 1.0, 1.5);
        // Next: 0.5 + 2 = 2.5 s predicted; 1.5 + 2.5 = 4 <= 10.
        assert!(close(Schedule::predict(1, 1.0, 1.5, 2), 2.5));
        assert_eq!(s.next(), Some(2));
        s.record(2, 2.0, 2.5);
        // Spent 4; predicted 0.5 + 4 = 4.5; 8.5 <= 10.
        assert_eq!(s.next(), Some(4));
        s.record(4, 4.0, 4.5);
        // Spent 8.5; predicted 0.5 + 8 = 8.5; 17 > 10: stop.
        assert!(close(s.spent(), 8.5));
        assert_eq!(s.next(), None);
    }

    #[test]
    fn doubling_schedule_caps_and_explicit_lists() {
        let mut s = Schedule::doubling(None, 5);
        let mut got = vec![];
        while let Some(b) = s.next() {
            got.push(b);
            s.record(b, 0.0, 0.0);
        }
        assert_eq!(got, vec![1, 2, 4]);
        // Explicit list without a limit: all of it.
        let mut s = Schedule::explicit(vec![1, 4, 16], None);
        let mut got = vec![];
        while let Some(b) = s.next() {
            got.push(b);
            s.record(b, 100.0, 100.0);
        }
        assert_eq!(got, vec![1, 4, 16]);
        // With a limit: stops when 16 spp would not fit (1 s at 4 spp -> 4 s predicted).
        let mut s = Schedule::explicit(vec![1, 4, 16], Some(5.0));
        s.record(1, 0.25, 0.25);
        assert_eq!(s.next(), Some(4));
        s.record(4, 1.0, 1.0);
        assert_eq!(s.next(), None);
        // A render that took more than asked (ltc's coverage floor: 1 asked, 16 taken): doubling
        // goes on from what was taken, an explicit list's next budget can be skipped.
        let mut s = Schedule::doubling(None, 64);
        assert_eq!(s.next(), Some(1));
        s.record(16, 1.0, 1.0);
        assert_eq!(s.next(), Some(32));
        let mut s = Schedule::explicit(vec![1, 4, 32], None);
        s.record(16, 1.0, 1.0);
        assert_eq!(s.next(), Some(4));
        s.skip();
        assert_eq!(s.next(), Some(32));
    }

    #[test]
    fn fnv_and_key() {
        // FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
        let k = reference_key(b"scene", "directlighting", Some((32, 32)), None, 256, 1);
        assert_eq!(k, reference_key(b"scene", "directlighting", Some((32, 32)), None, 256, 1));
        assert_ne!(k, reference_key(b"scene", "directlighting", Some((32, 32)), None, 256, 2));
        assert_ne!(k, reference_key(b"scene", "directlighting", Some((32, 32)), None, 512, 1));
        assert_ne!(k, reference_key(b"scene", "directlighting", Some((64, 32)), None, 256, 1));
        assert_ne!(
            k,
            reference_key(b"scene", "directlighting", Some((32, 32)), Some(Crop::Pixels([0, 8, 0, 8])), 256, 1)
        );
        assert_ne!(k, reference_key(b"scene2", "directlighting", Some((32, 32)), None, 256, 1));
        assert_ne!(k, reference_key(b"scene", "path", Some((32, 32)), None, 256, 1));
        assert_eq!(k.len(), 16);
    }

    fn row(name: &str, budget: u32, t: f64, e: f64) -> Row {
        Row {
            integrator: name.into(),
            budget,
            spp: budget,
            build_s: 0.0,
            render_s: t,
            total_s: t,
            mae: e,
            rmse: e,
            psnr: 0.0,
            max_err: e,
            relmse: e,
            smape: e,
            flip: None,
            nan_count: 0,
        }
    }

    #[test]
    fn summary_equal_time_and_target() {
        let rows = vec![
            row("directlighting", 1, 1.0, 1.0),
            row("directlighting", 4, 4.0, 0.5),
            row("directlighting", 16, 16.0, 0.25),
            row("ambientocclusion", 1, 0.5, 2.0),
            row("ambientocclusion", 2, 2.0, 1.0),
        ];
        let names = vec!["directlighting".to_string(), "ambientocclusion".to_string()];
        let target = default_target(&rows, &names, Metric::Rmse);
        assert_eq!(target.as_ref().map(|t| t.0), Some(0.25));
        let md = summary_markdown(
            &rows,
            &SummaryInput {
                scene: "s.pbrt",
                reference: "ref.exr",
                metric: Metric::Rmse,
                budget_name: "samples per pixel",
                target,
                threads: 2,
                integrators: &names,
                stopped: None,
            },
        );
        // Equal time = 2 s (ambientocclusion's largest); directlighting there: sqrt(0.5) = 0.7071.
        assert!(md.contains("RMSE at 2.000 s"), "{md}");
        assert!(md.contains("| directlighting | 3 | 1-16 |"), "{md}");
        assert!(md.contains("| 0.7071 |"), "{md}");
        assert!(md.contains("not reached"), "{md}");
        // CSV: a header and one line per row, flip empty.
        let csv = csv_text(&rows);
        assert_eq!(csv.lines().count(), 6);
        assert!(csv.lines().nth(1).unwrap().starts_with("directlighting,1,0,1,1,1,1,0,1,1,1,,0"));
    }

    #[test]
    fn plots_render() {
        let series = vec![
            ("directlighting".to_string(), vec![(0.01, 0.1, 1), (0.02, 0.07, 2), (0.04, 0.05, 4)]),
            ("ambientocclusion".to_string(), vec![(0.005, 0.3, 1)]),
        ];
        let (svg, png) = render_plots("test", Metric::Rmse, &series).unwrap();
        assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
        assert!(svg.contains("directlighting"));
        let img = image::decode_png(&png, Path::new("p.png")).unwrap();
        assert_eq!((img.width, img.height), PLOT_SIZE);
        // Something other than the white background was drawn.
        assert!(img.data.iter().any(|&v| v < 0.5));
    }
}
