//! `penumbra render`.

use crate::cli::{
    cancel_on_interrupt, check_crop, full_resolution, has_extension, spp_parser, write_outputs, RenderFlags,
};
use penumbra::cli_params;
use penumbra::output::{self, MissingDir};
use penumbra::pipeline::{self, RenderOptions};
use penumbra::shard::{self, ShardRequest};
use penumbra_core::integrator::CostEstimate;
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_core::shard_rects::TileLayout;
use penumbra_parser::{DiagSink, Param, SceneDescription};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

#[derive(clap::Args, Default)]
pub struct RenderArgs {
    /// The pbrt-v3 scene file (default: the embedded default scene).
    pub scene: Option<PathBuf>,
    /// Integrator to use (overrides the scene's `Integrator`).
    #[arg(short = 'i', long = "integrator", value_parser = penumbra::cli_params::integrator_arg)]
    pub integrator: Option<String>,
    #[command(flatten)]
    pub flags: RenderFlags,
    /// Samples per pixel (overrides the scene's sampler).
    #[arg(long, value_parser = spp_parser())]
    pub spp: Option<u32>,
    /// Output image (.exr, .png or .pfm; default: the scene's Film filename).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Crop `x0,x1,y0,y1`: pixel bounds (integers, half-open) or, if any value has a
    /// decimal point, fractions of the image as pbrt-v3's `cropwindow`.
    #[arg(long, value_name = "x0,x1,y0,y1", allow_hyphen_values = true, value_parser = crate::cli::parse_crop)]
    pub crop: Option<Crop>,
    /// PNG output: multiply by 2^S before the sRGB encoding (stops; EXR and PFM keep the
    /// rendered values).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// Also write per-pixel variance channels (EXR only).
    #[arg(long)]
    pub variance: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// Render shard I of N of the image's pixels (whole 16-pixel tiles, balanced by pixel
    /// count) into a shard file (`-o NAME.shard`) for `penumbra merge`.
    #[arg(long, value_name = "I/N", value_parser = parse_tile)]
    pub tile: Option<(u32, u32)>,
    /// How `--tile` deals out the tiles: `rows` (runs in raster order) or `grid` (blocks).
    #[arg(long, value_name = "rows|grid", default_value = "rows", value_parser = ["rows", "grid"])]
    pub tile_layout: String,
    /// Render samples K … K+spp−1 of each pixel's sample sequence into a shard file, to be
    /// merged with other ranges into one image at the summed spp (halton, sobol or random
    /// samplers; integrators whose samples are independent).
    #[arg(long, value_name = "K")]
    pub spp_offset: Option<u32>,
    /// Record where the render's time goes (`phases` in stats.json: calls and estimated
    /// thread-seconds of camera rays, closest-hit and shadow queries, shading, light sampling;
    /// costs a few percent).
    #[arg(long)]
    pub phases: bool,
    /// Ray-query backend, overriding the scene's `Accelerator`: `bvh` (obvhs, the default) or
    /// `embree` (Embree 3, in builds with the cargo feature `embree`).
    #[arg(long, value_name = "bvh|embree")]
    pub accel: Option<String>,
}

impl RenderArgs {
    /// Whether the render writes a shard file (`--tile` or `--spp-offset`).
    fn shard_mode(&self) -> bool {
        self.tile.is_some() || self.spp_offset.is_some()
    }
}

/// `--tile I/N` with 0 <= I < N (a clap value parser: a malformed value is a usage error).
pub fn parse_tile(t: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--tile expects I/N with 0 <= I < N (e.g. 2/7), got \"{t}\"");
    let (i, n) = t.split_once('/').ok_or_else(bad)?;
    let (i, n): (u32, u32) = (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The shard `--tile`, `--tile-layout` and `--spp-offset` ask for.
pub fn shard_request(tile: Option<(u32, u32)>, layout: &str, spp_offset: Option<u32>) -> Result<ShardRequest, String> {
    let layout = TileLayout::parse(layout)
        .ok_or_else(|| format!("--tile-layout must be \"rows\" or \"grid\", got \"{layout}\""))?;
    let (index, count) = tile.unwrap_or((0, 1));
    Ok(ShardRequest { index, count, layout, spp_offset })
}

fn print_warnings(w: &DiagSink) {
    for d in w.take() {
        eprint!("{d}");
    }
}

fn fail(msg: impl std::fmt::Display) -> ExitCode {
    eprintln!("error: {msg}");
    ExitCode::FAILURE
}

pub fn run(mut args: RenderArgs) -> ExitCode {
    let (threads, warning) = cli_params::thread_count(args.flags.threads);
    if let Some(w) = warning {
        eprintln!("{w}");
    }
    args.flags.threads = threads;
    let warnings = DiagSink::new();
    let t0 = Instant::now();
    let mut parsed = match pipeline::load_scene(args.scene.as_deref()) {
        Ok(p) => p,
        Err(e) => {
            eprint!("{e}");
            return ExitCode::FAILURE;
        }
    };
    let parse_seconds = t0.elapsed().as_secs_f64();
    warnings.extend(std::mem::take(&mut parsed.warnings));
    if let Some(a) = &args.accel {
        if !matches!(a.as_str(), "bvh" | "embree") {
            eprintln!("error: --accel must be \"bvh\" or \"embree\", got \"{a}\"");
            return ExitCode::from(penumbra::exit::USAGE);
        }
        parsed.scene.accelerator.kind = a.clone();
    }
    // A malformed `--param`, one the integrator does not declare, or one of the wrong type is
    // a usage error.
    let params = match cli_params::parse_all(&args.flags.params)
        .and_then(|p| pipeline::conform_params(&parsed.scene, args.integrator.as_deref(), &p))
    {
        Ok(p) => p,
        Err(d) => {
            eprint!("{d}");
            return ExitCode::from(penumbra::exit::USAGE);
        }
    };
    let inputs = match Inputs::of(&args, &parsed.scene, params) {
        Ok(i) => i,
        Err(e) => return fail(e),
    };
    // `-o` names a file the user typed: a missing directory is an error. The scene's own
    // `Film "filename"` gets its directories created (several public scenes point into one).
    let missing = if args.output.is_some() { MissingDir::Fail } else { MissingDir::Create };
    match output::prepare(&inputs.output, missing) {
        Ok(created) => {
            for d in created {
                eprintln!("created directory {} for the scene's Film \"filename\"", d.display());
            }
        }
        Err(e) => return fail(e),
    }
    warn_unused_output_options(&args, &inputs);
    let cancel = cancel_on_interrupt();
    let bar = (!args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr())).then(progress_bar);
    let progress = |done: u64, total: u64| {
        if let Some(b) = &bar {
            // The integrator's live status (ltc/ratio: shading points in the fallback path).
            if let Some(s) = warnings.status() {
                b.set_message(s);
            }
            b.set_length(total);
            b.set_position(done);
        }
    };
    let opts = RenderOptions {
        integrator: args.integrator.as_deref(),
        params: &inputs.params,
        build: BuildOptions { spp: args.spp, seed: args.flags.seed, crop: inputs.crop, resolution: inputs.resolution },
        threads: args.flags.threads,
        with_variance: args.variance,
        cancel: &cancel,
        progress: Some(&progress),
    };
    penumbra_core::profiling::set_enabled(args.phases);
    if let Some(req) = inputs.shard {
        let scene_name = scene_label(&args);
        let result = shard::render_shard(&parsed.scene, &scene_name, &opts, req, &warnings);
        if let Some(b) = &bar {
            b.finish_and_clear();
        }
        print_warnings(&warnings);
        let mut s = match result {
            Ok(s) => s,
            Err(e) => return render_failed(&e, &cancel),
        };
        s.header.stats.parse_seconds = parse_seconds;
        if let Err(e) = s.write(&inputs.output) {
            return fail(e);
        }
        if !args.quiet {
            let h = &s.header;
            eprintln!(
                "{}: {} tile {}/{} ({} px in {} rectangles), samples {}..{}, render {:.3} s",
                inputs.output.display(),
                h.identity.integrator,
                h.tile_index,
                h.identity.tile_count,
                s.pixels.len(),
                h.rects.len(),
                h.spp_offset,
                h.spp_offset as u64 + h.spp as u64,
                h.stats.render_seconds
            );
        }
        return ExitCode::SUCCESS;
    }
    let announce = |e: &CostEstimate| announce_estimate(e, args.quiet);
    let result = pipeline::render_estimated(&parsed.scene, &opts, &warnings, &announce);
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    print_warnings(&warnings);
    let r = match result {
        Ok(r) => r,
        Err(e) => return render_failed(&e, &cancel),
    };
    let output = &inputs.output;
    let stats = stats_json(&args, &r, output, parse_seconds);
    let image = match write_outputs(r.image, output, args.exposure, &stats) {
        Ok(i) => i,
        Err(e) => return fail(e),
    };
    if !args.quiet {
        eprintln!(
            "{}: {} at {} spp, {}x{} px, build {:.3} s, render {:.3} s, {:.2} M rays/s",
            output.display(),
            r.integrator,
            r.stats.spp,
            image.width,
            image.height,
            r.build.total_seconds(),
            r.stats.render_seconds,
            (r.stats.rays + r.stats.shadow_rays) as f64 / r.stats.render_seconds.max(1e-9) / 1e6
        );
        // What the integrator says of the render as a whole (ltc/ratio: the fallbacks' share).
        if let Some(s) = warnings.status() {
            eprintln!("{s}");
        }
    }
    ExitCode::SUCCESS
}

/// Prints the integrator's cost estimate (e.g. `silhouette` on a fine mesh) before it renders:
/// its lines unless `quiet`, its warning always.
fn announce_estimate(e: &CostEstimate, quiet: bool) {
    if !quiet {
        for line in &e.lines {
            eprintln!("{line}");
        }
    }
    if let Some(w) = &e.warning {
        eprintln!("warning: {w}");
    }
}

/// Says where `--variance` or `--exposure` will not apply to the file being written.
fn warn_unused_output_options(args: &RenderArgs, inputs: &Inputs) {
    if inputs.shard.is_some() && (args.variance || args.exposure != 0.0) {
        eprintln!("warning: --variance and --exposure apply to the merged image: give them to penumbra merge (the shard keeps every sum)");
    } else if args.variance && !has_extension(&inputs.output, "exr") {
        eprintln!(
            "warning: --variance: {} has no room for the variance channels (only .exr has): writing R, G, B only",
            inputs.output.display()
        );
    }
    if args.exposure != 0.0 && !has_extension(&inputs.output, "png") {
        eprintln!(
            "warning: --exposure applies to PNG output: {} keeps the rendered values (see penumbra convert)",
            inputs.output.display()
        );
    }
}

/// Reports a failed render (status 130 when it was interrupted).
fn render_failed(e: &pipeline::PipelineError, cancel: &AtomicBool) -> ExitCode {
    eprint!(
        "{}",
        match e {
            pipeline::PipelineError::Scene(d) => d.to_string(),
            other => format!("error: {other}\n"),
        }
    );
    if cancel.load(Ordering::SeqCst) {
        eprintln!("interrupted: nothing was written");
        return ExitCode::from(penumbra::exit::INTERRUPTED);
    }
    ExitCode::FAILURE
}

/// The scene as `stats.json` names it.
fn scene_label(args: &RenderArgs) -> String {
    args.scene.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| pipeline::DEFAULT_SCENE_NAME.to_string())
}

/// The command-line values `run` reads besides the scene: parsed and checked before rendering.
struct Inputs {
    params: Vec<Param>,
    crop: Option<Crop>,
    resolution: Option<(u32, u32)>,
    /// `-o`, else the scene's Film filename; .exr, .png or .pfm (.shard for a shard).
    output: PathBuf,
    /// `--tile` / `--spp-offset`: the shard to render.
    shard: Option<ShardRequest>,
}

impl Inputs {
    fn of(args: &RenderArgs, scene: &SceneDescription, params: Vec<Param>) -> Result<Inputs, String> {
        let (crop, resolution) = (args.crop, args.flags.resolution);
        if let Some(c) = crop {
            check_crop(c, full_resolution(scene, resolution))?;
        }
        let film_name = PathBuf::from(scene.film.params.get_one_string("filename", "pbrt.exr"));
        if args.shard_mode() {
            let req = shard_request(args.tile, &args.tile_layout, args.spp_offset)?;
            let output = args.output.clone().unwrap_or_else(|| {
                let stem = film_name.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                let range = args.spp_offset.map(|k| format!("-spp{k}")).unwrap_or_default();
                film_name.with_file_name(format!("{stem}-{}of{}{range}.shard", req.index, req.count))
            });
            if !has_extension(&output, "shard") {
                return Err(format!(
                    "{}: --tile and --spp-offset write a shard file: name it NAME.shard",
                    output.display()
                ));
            }
            return Ok(Inputs { params, crop, resolution, output, shard: Some(req) });
        }
        let output = args.output.clone().unwrap_or(film_name);
        if !matches!(
            output.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref(),
            Some("exr" | "png" | "pfm")
        ) {
            return Err(format!("{}: output must end in .exr, .png or .pfm", output.display()));
        }
        Ok(Inputs { params, crop, resolution, output, shard: None })
    }
}

/// The tile progress bar on stderr.
fn progress_bar() -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(1);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} tiles (eta {eta}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b
}

/// What `stats.json` records of a render.
fn stats_json(args: &RenderArgs, r: &pipeline::Rendered, output: &Path, parse_seconds: f64) -> serde_json::Value {
    let label = scene_label(args);
    let c = pipeline::StatsContext {
        scene: &label,
        parameters: &args.flags.params,
        image: Some(output),
        seed: args.flags.seed,
        exposure: args.exposure,
        parse_seconds,
    };
    pipeline::stats_json(r, &c)
}
