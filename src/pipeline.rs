//! Load → choose integrator → build → render.

use crate::cli_params;
use penumbra_core::film::{Film, FilmSpec};
use penumbra_core::image::Image;
use penumbra_core::integrator::{
    build_scene, resolve_threads, CostEstimate, Integrator, RenderContext, RenderError, RenderStats,
};
use penumbra_core::scene::{BuildOptions, BuildReport, Scene};
use penumbra_parser::{DiagSink, Diagnostic, Param, ParamSet, ParseOutput, SceneDescription};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// The scene rendered when no file is given.
pub const DEFAULT_SCENE: &str = include_str!("../scenes/default.pbrt");
pub const DEFAULT_SCENE_NAME: &str = "<embedded default scene>";

/// The integrator used for scenes that name one penumbra does not implement (pbrt-v3's
/// `volpath`, `bdpt`, `mlt` and `sppm` all estimate the light transport `path` does; their
/// `maxdepth` keeps its meaning).
pub const FALLBACK_INTEGRATOR: &str = "path";

/// Parses `path`, or the embedded default scene when `None`.
pub fn load_scene(path: Option<&Path>) -> Result<ParseOutput, Diagnostic> {
    match path {
        Some(p) => penumbra_parser::parse_file(p),
        None => penumbra_parser::parse_str(DEFAULT_SCENE, DEFAULT_SCENE_NAME, None),
    }
}

/// The integrator that will run: `-i`, else the scene's when penumbra implements it, else
/// [`FALLBACK_INTEGRATOR`] (`choose_integrator` says so).
pub fn integrator_name<'a>(desc: &'a SceneDescription, cli_name: Option<&'a str>) -> &'a str {
    match cli_name {
        Some(n) => n,
        None if penumbra_integrators::find(&desc.integrator.kind).is_some() => &desc.integrator.kind,
        None => FALLBACK_INTEGRATOR,
    }
}

/// The command-line parameters typed for the integrator that will run
/// ([`cli_params::conform`]): an unknown name or an ill-typed value is an error naming its
/// parameters (a usage error). An unknown integrator is left for [`choose_integrator`].
pub fn conform_params(
    desc: &SceneDescription,
    cli_name: Option<&str>,
    cli_params: &[Param],
) -> Result<Vec<Param>, Diagnostic> {
    match penumbra_integrators::find(integrator_name(desc, cli_name)) {
        Some(entry) => cli_params::conform(entry, cli_params),
        None => Ok(cli_params.to_vec()),
    }
}

/// The integrator to run and its parameters: `-i` wins; otherwise the scene's
/// own, falling back (with a warning) when penumbra does not implement it. The scene's
/// parameters keep pbrt-v3's semantics (unused ones warn); the command line's must be ones
/// the integrator declares ([`conform_params`]).
pub fn choose_integrator(
    desc: &SceneDescription,
    cli_name: Option<&str>,
    cli_params: &[Param],
    warnings: &DiagSink,
) -> Result<Box<dyn Integrator>, Diagnostic> {
    let scene_name = desc.integrator.kind.as_str();
    let name = integrator_name(desc, cli_name);
    let base = if name == scene_name {
        desc.integrator.params.clone()
    } else {
        desc.integrator.params.mark_all_used();
        if cli_name.is_none() {
            if !penumbra_integrators::PBRT_UNIMPLEMENTED.contains(&scene_name) {
                // pbrt-v3 renders nothing for an integrator it does not know (issue 41).
                let message = crate::cli_params::unknown_integrator(scene_name);
                return Err(Diagnostic::error(
                    Some(desc.integrator.loc.clone()),
                    format!("{message} (pbrt-v3 stops here too; -i chooses one)"),
                ));
            }
            warnings.warn(
                Some(desc.integrator.loc.clone()),
                format!(
                    "pbrt-v3 integrator \"{scene_name}\" is not implemented by penumbra: rendering with \"{FALLBACK_INTEGRATOR}\" instead (choose one with -i)"
                ),
            );
            // pbrt-v3's other integrators share `path`'s `maxdepth`.
            let base = desc.integrator.params.clone();
            base.mark_all_used();
            base
        } else {
            ParamSet::default()
        }
    };
    let entry = penumbra_integrators::find(name)
        .ok_or_else(|| Diagnostic::error(None, crate::cli_params::unknown_integrator(name)))?;
    let params = cli_params::merge(&base, &cli_params::conform(entry, cli_params)?);
    let integrator = (entry.create)(&params, warnings)?;
    warnings.extend(params.report_unused(&format!("integrator \"{name}\"")));
    Ok(integrator)
}

/// A finished render.
pub struct Rendered {
    pub integrator: String,
    pub image: Image,
    pub film: FilmSpec,
    pub stats: RenderStats,
    pub build: BuildReport,
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("{0}")]
    Scene(Diagnostic),
    #[error(transparent)]
    Render(#[from] RenderError),
    /// A request that cannot be rendered as asked (e.g. `--spp-offset` with a sampler that
    /// does not allow it).
    #[error("{0}")]
    Invalid(String),
}

impl From<Diagnostic> for PipelineError {
    fn from(d: Diagnostic) -> Self {
        PipelineError::Scene(d)
    }
}

pub struct RenderOptions<'a> {
    pub integrator: Option<&'a str>,
    pub params: &'a [Param],
    pub build: BuildOptions,
    pub threads: usize,
    pub with_variance: bool,
    pub cancel: &'a AtomicBool,
    pub progress: Option<&'a (dyn Fn(u64, u64) + Sync)>,
}

/// Chooses the integrator and builds what it needs.
pub fn prepare(
    desc: &SceneDescription,
    opts: &RenderOptions,
    warnings: &DiagSink,
) -> Result<(Box<dyn Integrator>, Scene), PipelineError> {
    let integrator = choose_integrator(desc, opts.integrator, opts.params, warnings)?;
    let scene = build_scene(integrator.as_ref(), desc, &opts.build, warnings)?;
    Ok((integrator, scene))
}

/// Renders the pixels of `spec` (the scene's film, or a part of it) into a new film.
pub fn render_film(
    integrator: &dyn Integrator,
    scene: &Scene,
    spec: FilmSpec,
    opts: &RenderOptions,
    warnings: &DiagSink,
) -> Result<(Film, RenderStats), PipelineError> {
    let mut film = Film::new(spec, scene.filter.radius(), integrator.extra_channels());
    let ctx = RenderContext { threads: opts.threads, cancel: opts.cancel, progress: opts.progress, warnings };
    penumbra_core::profiling::take();
    let mut stats = integrator.render(scene, &ctx, &mut film)?;
    stats.phases = penumbra_core::profiling::take();
    Ok((film, stats))
}

/// Chooses the integrator, builds what it needs and renders.
pub fn render(desc: &SceneDescription, opts: &RenderOptions, warnings: &DiagSink) -> Result<Rendered, PipelineError> {
    let integrator = choose_integrator(desc, opts.integrator, opts.params, warnings)?;
    render_with(integrator_name(desc, opts.integrator), integrator.as_ref(), desc, opts, warnings)
}

/// Builds what `integrator` (registered as `name`) needs and renders (`opts.integrator` and
/// `opts.params` are not read: the integrator is already made).
pub fn render_with(
    name: &str,
    integrator: &dyn Integrator,
    desc: &SceneDescription,
    opts: &RenderOptions,
    warnings: &DiagSink,
) -> Result<Rendered, PipelineError> {
    render_announced(name, integrator, desc, opts, warnings, None)
}

/// [`render`], calling `announce` with the integrator's [`Integrator::estimate_cost`] (if it
/// makes one) after the scene build and before rendering (`penumbra render` prints it).
pub fn render_estimated(
    desc: &SceneDescription,
    opts: &RenderOptions,
    warnings: &DiagSink,
    announce: &dyn Fn(&CostEstimate),
) -> Result<Rendered, PipelineError> {
    let integrator = choose_integrator(desc, opts.integrator, opts.params, warnings)?;
    let name = integrator_name(desc, opts.integrator);
    render_announced(name, integrator.as_ref(), desc, opts, warnings, Some(announce))
}

fn render_announced(
    name: &str,
    integrator: &dyn Integrator,
    desc: &SceneDescription,
    opts: &RenderOptions,
    warnings: &DiagSink,
    announce: Option<&dyn Fn(&CostEstimate)>,
) -> Result<Rendered, PipelineError> {
    let scene = build_scene(integrator, desc, &opts.build, warnings)?;
    let estimate = announce.and_then(|announce| {
        let e = integrator.estimate_cost(&scene, resolve_threads(opts.threads))?;
        announce(&e);
        Some(e.seconds)
    });
    let (film, mut stats) = render_film(integrator, &scene, scene.film.clone(), opts, warnings)?;
    // stats.json keeps the estimate beside the measured `render_seconds`.
    if let Some(seconds) = estimate {
        stats.counters.insert("estimate.render_seconds".into(), seconds);
    }
    Ok(Rendered {
        integrator: name.to_string(),
        image: film.to_image(opts.with_variance),
        film: scene.film.clone(),
        stats,
        build: scene.report.clone(),
    })
}

/// What a render's `stats.json` records besides the render itself.
pub struct StatsContext<'a> {
    /// The scene as the user named it.
    pub scene: &'a str,
    /// The `--param` arguments as given.
    pub parameters: &'a [String],
    /// The image written (`None`: none, as the Python API's renders).
    pub image: Option<&'a Path>,
    pub seed: u64,
    pub exposure: f32,
    pub parse_seconds: f64,
}

/// The `stats.json` of a render (`penumbra render` writes it beside the image; the Python
/// API's `Render.stats` is the same dictionary).
pub fn stats_json(r: &Rendered, c: &StatsContext) -> serde_json::Value {
    let pb = &r.film.pixel_bounds;
    serde_json::json!({
        "scene": c.scene,
        "integrator": r.integrator,
        "parameters": c.parameters,
        "image": c.image.map(|p| p.display().to_string()),
        "resolution": [r.film.full_resolution.0, r.film.full_resolution.1],
        "pixel_bounds": [pb.min.x, pb.max.x, pb.min.y, pb.max.y],
        "spp": r.stats.spp,
        "seed": c.seed,
        "exposure": c.exposure,
        "threads": r.stats.threads,
        "parse_seconds": c.parse_seconds,
        "build_seconds": r.build.total_seconds(),
        "build": r.build.stages.iter().map(|(s, t, d)| serde_json::json!({"stage": s, "seconds": t, "detail": d})).collect::<Vec<_>>(),
        "render_seconds": r.stats.render_seconds,
        "stats": r.stats,
    })
}
