//! `penumbra render`.

use penumbra::cli_params;
use penumbra::output::{self, MissingDir};
use penumbra::pipeline::{self, RenderOptions};
use penumbra::shard::{self, ShardRequest};
use penumbra_core::image::Image;
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_core::shard_rects::TileLayout;
use penumbra_parser::{DiagSink, Param, SceneDescription};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(clap::Args, Default)]
pub struct RenderArgs {
    /// The pbrt-v3 scene file (default: the embedded default scene).
    pub scene: Option<PathBuf>,
    /// Integrator to use (overrides the scene's `Integrator`).
    #[arg(short = 'i', long = "integrator")]
    pub integrator: Option<String>,
    /// Integrator parameter `key=value` (repeatable): one the integrator declares (listed
    /// below), its value of the declared type.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Samples per pixel (overrides the scene's sampler).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=penumbra_core::sampler::MAX_SAMPLES))]
    pub spp: Option<u32>,
    /// Output image (.exr, .png or .pfm; default: the scene's Film filename).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Crop `x0,x1,y0,y1`: pixel bounds (integers, half-open) or, if any value has a
    /// decimal point, fractions of the image as pbrt-v3's `cropwindow`.
    #[arg(long, allow_hyphen_values = true)]
    pub crop: Option<String>,
    /// Override the film resolution `WxH` (e.g. for quick previews).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Sampler seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
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
    #[arg(long, value_name = "I/N")]
    pub tile: Option<String>,
    /// How `--tile` deals out the tiles: `rows` (runs in raster order) or `grid` (blocks).
    #[arg(long, value_name = "rows|grid", default_value = "rows")]
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

/// `--tile I/N` and `--tile-layout`, checked.
pub fn parse_tile(tile: Option<&str>, layout: &str, spp_offset: Option<u32>) -> Result<ShardRequest, String> {
    let layout = TileLayout::parse(layout)
        .ok_or_else(|| format!("--tile-layout must be \"rows\" or \"grid\", got \"{layout}\""))?;
    let (index, count) = match tile {
        None => (0, 1),
        Some(t) => {
            let bad = || format!("--tile expects I/N with 0 <= I < N (e.g. 2/7), got \"{t}\"");
            let (i, n) = t.split_once('/').ok_or_else(bad)?;
            let (i, n): (u32, u32) = (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
            if n == 0 || i >= n {
                return Err(bad());
            }
            (i, n)
        }
    };
    Ok(ShardRequest { index, count, layout, spp_offset })
}

pub fn parse_crop(s: &str) -> Result<Crop, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err(format!("--crop needs 4 comma-separated values x0,x1,y0,y1, got \"{s}\""));
    }
    if parts.iter().any(|p| p.contains('.')) {
        let v: Result<Vec<f32>, _> = parts.iter().map(|p| p.parse::<f32>()).collect();
        let v = v.map_err(|_| format!("--crop: \"{s}\" is not four numbers"))?;
        Ok(Crop::Fraction([v[0], v[1], v[2], v[3]]))
    } else {
        let v: Result<Vec<i32>, _> = parts.iter().map(|p| p.parse::<i32>()).collect();
        let v = v.map_err(|_| format!("--crop: \"{s}\" is not four integers"))?;
        Ok(Crop::Pixels([v[0], v[1], v[2], v[3]]))
    }
}

/// The film's full resolution: `--resolution`, else the scene's (pbrt-v3's default 1280×720).
pub fn full_resolution(scene: &SceneDescription, resolution: Option<(u32, u32)>) -> (i32, i32) {
    match resolution {
        Some((w, h)) => (w as i32, h as i32),
        None => {
            let p = &scene.film.params;
            (p.get_one_int("xresolution", 1280), p.get_one_int("yresolution", 720))
        }
    }
}

/// A `--crop` must lie inside the image and contain a pixel (as `diff --crop`): not clamped.
pub fn check_crop(crop: Crop, (w, h): (i32, i32)) -> Result<(), String> {
    let bad = match crop {
        Crop::Pixels([x0, x1, y0, y1]) => !(0 <= x0 && x0 < x1 && x1 <= w && 0 <= y0 && y0 < y1 && y1 <= h),
        Crop::Fraction([x0, x1, y0, y1]) => !(0.0 <= x0 && x0 < x1 && x1 <= 1.0 && 0.0 <= y0 && y0 < y1 && y1 <= 1.0),
    };
    if !bad || w <= 0 || h <= 0 {
        // (An out-of-range film resolution is the scene build's located error.)
        return Ok(());
    }
    Err(match crop {
        Crop::Pixels([x0, x1, y0, y1]) => format!(
            "--crop {x0},{x1},{y0},{y1} is outside the {w}x{h} image: pixel bounds need 0 <= x0 < x1 <= {w} and 0 <= y0 < y1 <= {h}"
        ),
        Crop::Fraction([x0, x1, y0, y1]) => format!(
            "--crop {x0},{x1},{y0},{y1}: fractions need 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1"
        ),
    })
}

pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("--resolution expects WxH, got \"{s}\""))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("--resolution: bad width in \"{s}\""))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("--resolution: bad height in \"{s}\""))?;
    if w == 0 || h == 0 || w > 1 << 16 || h > 1 << 16 {
        return Err(format!("--resolution {w}x{h} is out of range"));
    }
    Ok((w, h))
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

pub fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// `out.exr` → `out.stats.json`.
pub fn stats_path(image: &Path) -> PathBuf {
    let stem = image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "penumbra".into());
    image.with_file_name(format!("{stem}.stats.json"))
}

pub fn run(mut args: RenderArgs) -> ExitCode {
    let (threads, warning) = cli_params::thread_count(args.threads);
    if let Some(w) = warning {
        eprintln!("{w}");
    }
    args.threads = threads;
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
    let params = match cli_params::parse_all(&args.params)
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
    let cancel = cancel_on_interrupt();
    let bar = (!args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr())).then(progress_bar);
    let progress = |done: u64, total: u64| {
        if let Some(b) = &bar {
            b.set_length(total);
            b.set_position(done);
        }
    };
    let opts = RenderOptions {
        integrator: args.integrator.as_deref(),
        params: &inputs.params,
        build: BuildOptions { spp: args.spp, seed: args.seed, crop: inputs.crop, resolution: inputs.resolution },
        threads: args.threads,
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
    let result = pipeline::render(&parsed.scene, &opts, &warnings);
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
    }
    ExitCode::SUCCESS
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
        let crop = args.crop.as_deref().map(parse_crop).transpose()?;
        let resolution = args.resolution.as_deref().map(parse_resolution).transpose()?;
        if let Some(c) = crop {
            check_crop(c, full_resolution(scene, resolution))?;
        }
        let film_name = PathBuf::from(scene.film.params.get_one_string("filename", "pbrt.exr"));
        if args.shard_mode() {
            let req = parse_tile(args.tile.as_deref(), &args.tile_layout, args.spp_offset)?;
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

/// A flag set by the first Ctrl-C (renders stop at the next tile, then exit with status 130,
/// as a shell reports SIGINT); a second one exits with 130 at once.
pub fn cancel_on_interrupt() -> Arc<AtomicBool> {
    let cancel = Arc::new(AtomicBool::new(false));
    let c = cancel.clone();
    let _ = ctrlc::set_handler(move || {
        if c.swap(true, Ordering::SeqCst) {
            std::process::exit(penumbra::exit::INTERRUPTED.into());
        }
    });
    cancel
}

/// The tile progress bar on stderr.
fn progress_bar() -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(1);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} tiles (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b
}

/// What `stats.json` records of a render.
fn stats_json(args: &RenderArgs, r: &pipeline::Rendered, output: &Path, parse_seconds: f64) -> serde_json::Value {
    serde_json::json!({
        "scene": scene_label(args),
        "integrator": r.integrator,
        "parameters": args.params,
        "image": output.display().to_string(),
        "resolution": [r.film.full_resolution.0, r.film.full_resolution.1],
        "pixel_bounds": [r.film.pixel_bounds.min.x, r.film.pixel_bounds.max.x, r.film.pixel_bounds.min.y, r.film.pixel_bounds.max.y],
        "spp": r.stats.spp,
        "seed": args.seed,
        "exposure": args.exposure,
        "threads": r.stats.threads,
        "parse_seconds": parse_seconds,
        "build_seconds": r.build.total_seconds(),
        "build": r.build.stages.iter().map(|(s, t, d)| serde_json::json!({"stage": s, "seconds": t, "detail": d})).collect::<Vec<_>>(),
        "render_seconds": r.stats.render_seconds,
        "stats": r.stats,
    })
}

/// Writes the image (R, G, B only unless it is an EXR; a PNG with `exposure` stops), then `stats`
/// beside it; returns the image written.
pub fn write_outputs(
    mut image: Image,
    output: &Path,
    exposure: f32,
    stats: &serde_json::Value,
) -> Result<Image, String> {
    if !has_extension(output, "exr") && image.channels.len() > 3 {
        image = image.select_channels(&["R", "G", "B"]).map_err(|e| e.to_string())?;
    }
    if has_extension(output, "png") {
        penumbra_core::image::write_png(&image, output, exposure)
    } else {
        penumbra_core::image::write(&image, output)
    }
    .map_err(|e| e.to_string())?;
    let sp = stats_path(output);
    let text = serde_json::to_string_pretty(stats).unwrap_or_default();
    penumbra_core::image::write_atomic(&sp, |w| w.write_all(text.as_bytes())).map_err(|e| e.to_string())?;
    Ok(image)
}
