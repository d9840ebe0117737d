//! The `sweep` command line ([`SweepArgs`], [`Metric`]) and its validation ([`setup`]):
//! every integrator is created once with its parameters before anything renders.

use super::row::Metric;
use super::{fail, Failure};
use crate::cli::print_new_warnings;
use crate::cli::{check_crop, full_resolution, spp_parser, RenderFlags};
use crate::cli_params;
use crate::pipeline;
use crate::scene_identity::scene_identity;
use penumbra_core::metrics;
use penumbra_core::scene::Crop;
use penumbra_integrators::common::params::Kind;
use penumbra_parser::{DiagSink, Param, SceneDescription};
use std::collections::BTreeSet;
use std::path::PathBuf;

impl SweepArgs {
    /// `--reference-integrator`, else the first `-i`'s natural reference (the registry's
    /// [`Entry::reference`](penumbra_integrators::Entry::reference)).
    pub fn reference_integrator(&self) -> &str {
        match &self.reference_integrator {
            Some(n) => n.trim(),
            None => penumbra_integrators::natural_reference(self.integrators.first().map_or("", |n| n.trim())),
        }
    }
}

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("ref").required(true).args(["reference", "reference_spp"])))]
pub struct SweepArgs {
    /// The pbrt-v3 scene file.
    pub scene: PathBuf,
    /// Reference image (.exr, .png or .pfm) of the same size as the renders.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Render the reference with --reference-integrator at N spp instead (cached under OUTDIR/cache/).
    #[arg(long, value_name = "N", value_parser = spp_parser())]
    pub reference_spp: Option<u32>,
    /// The integrator of the `--reference-spp` render: the estimator the others should converge
    /// to (default: the first -i's natural reference — ambientocclusion for ambientocclusion,
    /// path for path, whitted for whitted, directlighting for the others; `path` for scenes lit
    /// by more than direct light).
    #[arg(long, value_name = "NAME")]
    pub reference_integrator: Option<String>,
    /// Sampler seed of the `--reference-spp` render (default: --seed + 1, so that the
    /// reference's samples are not the renders' samples).
    #[arg(long, value_name = "S")]
    pub reference_seed: Option<u64>,
    /// Integrators to compare, comma-separated.
    #[arg(short = 'i', long = "integrators", value_delimiter = ',', required = true, value_name = "NAME[,NAME...]", value_parser = crate::cli_params::integrator_arg)]
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
    #[arg(long, requires = "budget_param", value_parser = spp_parser())]
    pub spp: Option<u32>,
    #[command(flatten)]
    pub flags: RenderFlags,
    /// Crop `x0,x1,y0,y1` (as `penumbra render --crop`).
    #[arg(long, value_name = "x0,x1,y0,y1", allow_hyphen_values = true, value_parser = crate::cli::parse_crop)]
    pub crop: Option<Crop>,
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
    /// Write the sweep's renders as independent items to OUTDIR/plan.json and exit (for a batch
    /// scheduler: needs --budgets, or the doubling schedule up to --max-budget; not --time-limit).
    #[arg(long, conflicts_with_all = ["run_item", "collect"])]
    pub plan: bool,
    /// Run item K of the plan (give the arguments --plan was given): one render (or the
    /// --reference-spp reference), written under OUTDIR/items/ (OUTDIR/cache/ for the reference).
    #[arg(long, value_name = "K", conflicts_with = "collect")]
    pub run_item: Option<usize>,
    /// Compare the items' renders with the reference and write sweep.csv, sweep.json, the plot
    /// and summary.md, as the sweep itself would (timings are each item's own).
    #[arg(long)]
    pub collect: bool,
}

/// The validated command line and the parsed scene.
pub struct Setup {
    pub desc: SceneDescription,
    /// [`scene_identity`]: what the reference cache is keyed by.
    pub scene_identity: String,
    pub params: Vec<Param>,
    pub crop: Option<Crop>,
    pub resolution: Option<(u32, u32)>,
    pub integrators: Vec<String>,
    /// Warnings already printed.
    pub seen: BTreeSet<String>,
}

/// Checks the arguments, reads and parses the scene, and creates each integrator once (so bad
/// parameter values fail before any render).
pub fn setup(args: &SweepArgs) -> Result<Setup, Failure> {
    let integrators = cli_params::integrator_list(&args.integrators).map_err(fail)?;
    if args.reference_spp.is_some() && penumbra_integrators::find(args.reference_integrator()).is_none() {
        return Err(fail(format!(
            "unknown reference integrator \"{}\"; valid names: {}",
            args.reference_integrator(),
            penumbra_integrators::names().join(", ")
        )));
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
    let usage = |d: penumbra_parser::Diagnostic| Failure { code: crate::exit::USAGE, message: d.to_string() };
    let params = cli_params::parse_all(&args.flags.params).map_err(usage)?;
    // Every `--param` applies to every integrator of the sweep: each must declare it, with its type.
    for n in &integrators {
        if let Some(entry) = penumbra_integrators::find(n) {
            cli_params::conform(entry, &params).map_err(usage)?;
        }
    }
    let (crop, resolution) = (args.crop, args.flags.resolution);
    let parsed = pipeline::load_scene(Some(&args.scene)).map_err(|d| Failure { code: 1, message: d.to_string() })?;
    let scene_identity = scene_identity(&parsed.scene).map_err(fail)?;
    if let Some(c) = crop {
        check_crop(c, full_resolution(&parsed.scene, resolution)).map_err(fail)?;
    }
    let warnings = DiagSink::new();
    warnings.extend(parsed.warnings);
    // Create each integrator once with its parameters, so that bad values fail before any render.
    for n in &integrators {
        // The budget parameter must be an integer parameter the integrator declares.
        if let (Some(name), Some(entry)) = (&args.budget_param, penumbra_integrators::find(n)) {
            if !entry.params.iter().any(|s| s.name == name.trim() && s.kind == Kind::Int) {
                return Err(fail(format!(
                    "--budget-param {}: integrator \"{n}\" has no such integer parameter",
                    name.trim()
                )));
            }
        }
        let mut p = params.clone();
        if let Some(name) = &args.budget_param {
            p.push(budget_param(name, 1)?);
        }
        pipeline::choose_integrator(&parsed.scene, Some(n), &p, &warnings)
            .map_err(|d| Failure { code: 1, message: format!("integrator \"{n}\": {}", d.message) })?;
    }
    let mut seen = BTreeSet::new();
    print_new_warnings(&warnings, &mut seen);
    Ok(Setup { desc: parsed.scene, scene_identity, params, crop, resolution, integrators, seen })
}

/// The `--budget-param NAME` parameter set to `budget`.
pub fn budget_param(name: &str, budget: u32) -> Result<Param, Failure> {
    cli_params::parse_param(&format!("{}={budget}", name.trim())).map_err(|e| fail(e.message))
}
