//! The integrator interface and the generic parallel driver for per-pixel estimators.

use crate::camera::CameraSample;
use crate::film::Film;
use crate::geometry::Bounds2i;
use crate::geometry::RayDifferential;
use crate::sampler::Sampler;
use crate::scene::{BuildOptions, Requirements, Scene};
use crate::Rgb;
use glam::{IVec2, Vec2};
use penumbra_parser::{DiagSink, Diagnostic, SceneDescription};
use rayon::prelude::*;
use std::any::Any;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Tiles are laid on this fixed grid of absolute raster coordinates.
pub const TILE_SIZE: i32 = 16;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("render cancelled")]
    Cancelled,
    #[error("{0}")]
    Failed(String),
}

/// Everything a render needs besides the scene and the film.
pub struct RenderContext<'a> {
    /// Worker threads (0: one per core).
    pub threads: usize,
    /// Set (e.g. by Ctrl-C) to stop early; the render then returns `RenderError::Cancelled`.
    pub cancel: &'a AtomicBool,
    /// Called with (work done, work total) as tiles finish.
    pub progress: Option<&'a (dyn Fn(u64, u64) + Sync)>,
    pub warnings: &'a DiagSink,
}

/// Counters an estimator updates on its own thread; summed at the end.
///
/// The rule for `rays`: a ray is counted once, by whoever spawns it. The driver spawns the
/// camera rays and counts one per camera sample; an estimator counts the rays it spawns
/// (bounces, pass-throughs), and when it traces a ray someone else counted (the camera ray
/// it is given) it adds only the queries after the first, with [`ThreadStats::add_continued`].
/// Shadow (visibility) rays go to `shadow_rays`. `tests/conformance.rs` checks the counts of
/// every registered integrator on a scene where they are known.
#[derive(Clone, Debug, Default)]
pub struct ThreadStats {
    pub rays: u64,
    pub shadow_rays: u64,
    /// Non-finite or negative radiance values replaced by 0 (pbrt-v3 does the same, with an error).
    pub bad_samples: u64,
}

impl ThreadStats {
    /// Counts a ray already counted by its spawner (the camera ray, for an estimator) that
    /// took `queries` intersection queries (e.g. [`Scene::first_surface`]'s passes through
    /// surfaces without a material): the queries after the first.
    pub fn add_continued(&mut self, queries: u64) {
        self.rays += queries.saturating_sub(1);
    }
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    pub spp: u32,
    pub camera_samples: u64,
    pub rays: u64,
    pub shadow_rays: u64,
    pub bad_samples: u64,
    pub render_seconds: f64,
    pub threads: usize,
    /// Integrator-specific figures.
    pub counters: BTreeMap<String, f64>,
    /// Calls and estimated thread-seconds per phase ([`crate::profiling`]), filled in by whoever
    /// runs the integrator (`penumbra render`), from [`crate::profiling::take`].
    pub phases: crate::profiling::Phases,
}

/// An integrator: what it needs built, and its render. Its name, parameters and natural
/// reference are the registry's (`penumbra_integrators::REGISTRY`), not the integrator's.
pub trait Integrator: Send + Sync {
    /// What the scene build must provide.
    fn requirements(&self) -> Requirements;
    /// Builds what this integrator's own method needs over the built scene (a structure no
    /// other integrator uses, such as `silhouette`'s dual-edge hierarchy or `shexp`'s sphere
    /// sets): called once per scene by [`build_scene`], which keeps the result in
    /// [`Scene::prepared`] for every render of the scene and times it into the build report.
    /// The default prepares nothing. `render` should build the structure itself when it finds
    /// none (a scene built without [`build_scene`]).
    fn prepare(&self, _scene: &Scene) -> Option<Preparation> {
        None
    }
    /// Extra film channels this integrator writes (beyond R, G, B).
    fn extra_channels(&self) -> Vec<String> {
        Vec::new()
    }
    /// Render the whole image into `film`.
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError>;
    /// Whether renders of disjoint ranges of each pixel's samples (`render --spp-offset`, with
    /// a sampler whose samples do not depend on the count) add up, sum for sum, to the render
    /// of their union: true when each camera sample's estimate depends on its own sample values
    /// alone — no work shared between a pixel's samples ([`PixelEstimator::shares_pixel_work`]),
    /// no image-space pass over the finished film, no sample count raised by the integrator.
    fn merges_sample_ranges(&self) -> bool {
        false
    }
    /// An upper bound this integrator guarantees on every pixel's R, G, B (with a non-negative
    /// pixel filter), if it declares one; `penumbra stability` counts the pixels above it.
    fn radiance_bound(&self) -> Option<RadianceBound> {
        None
    }
    /// Whether [`estimate_cost`](Self::estimate_cost) has anything to say (`penumbra info`
    /// then builds the acceleration structure it otherwise skips, since the estimate traces
    /// camera rays).
    fn estimates_cost(&self) -> bool {
        false
    }
    /// For integrators whose cost per shading point varies by orders of magnitude with the
    /// scene (e.g. with its triangle count): a cheap probe over the built and prepared `scene`
    /// (its film, sampler and camera as the render will use them) estimating the render's
    /// time on `threads` threads, printed by `penumbra info` and at the start of `penumbra
    /// render`. The default estimates nothing.
    fn estimate_cost(&self, _scene: &Scene, _threads: usize) -> Option<CostEstimate> {
        None
    }
}

/// What [`Integrator::estimate_cost`] measured and predicts.
#[derive(Clone, Debug, Default)]
pub struct CostEstimate {
    /// The estimated render time in seconds (wall, on the threads given).
    pub seconds: f64,
    /// Lines stating the estimate, what was measured and what is assumed.
    pub lines: Vec<String>,
    /// Set when the render will be far slower than a ray-traced alternative: says so, with the
    /// numbers and what to do instead.
    pub warning: Option<String>,
}

/// What [`Integrator::prepare`] built.
pub struct Preparation {
    /// The build report's name for it ("dual edges").
    pub stage: String,
    /// One line saying what was built (the build report's detail).
    pub summary: String,
    /// Further lines for `penumbra info` (e.g. one per object).
    pub details: Vec<String>,
    /// The structure, read back with [`Scene::prepared`].
    pub value: Arc<dyn Any + Send + Sync>,
}

/// The scene `integrator` renders: built as its [`Integrator::requirements`] ask, with what
/// its [`Integrator::prepare`] builds.
pub fn build_scene(
    integrator: &dyn Integrator,
    desc: &SceneDescription,
    opts: &BuildOptions,
    warnings: &DiagSink,
) -> Result<Scene, Diagnostic> {
    let scene = Scene::build(desc, integrator.requirements(), opts, warnings)?;
    Ok(prepare_scene(integrator, scene))
}

/// [`build_scene`] without the acceleration structure ([`Scene::check`]: `penumbra info`).
pub fn check_scene(
    integrator: &dyn Integrator,
    desc: &SceneDescription,
    opts: &BuildOptions,
    warnings: &DiagSink,
) -> Result<Scene, Diagnostic> {
    let scene = Scene::check(desc, integrator.requirements(), opts, warnings)?;
    Ok(prepare_scene(integrator, scene))
}

/// `scene` with what `integrator` prepares over it (timed into its report).
pub fn prepare_scene(integrator: &dyn Integrator, mut scene: Scene) -> Scene {
    let t = Instant::now();
    if let Some(p) = integrator.prepare(&scene) {
        scene.report.stages.push((p.stage.clone(), t.elapsed().as_secs_f64(), p.summary));
        scene.report.prepared = Some(p.stage);
        scene.report.details.extend(p.details);
        scene.prepared = Some(p.value);
    }
    scene
}

/// What [`Integrator::radiance_bound`] declares.
pub enum RadianceBound {
    /// Every value is at most this (e.g. ambient occlusion's hemisphere integral).
    Constant(f32),
    /// Every pixel is at most the same pixel rendered by this integrator with the same scene
    /// and samples (e.g. `ltc` without shadows: the unshadowed value), up to the relative
    /// tolerance given (the two renders' numerical precision).
    Image(Box<dyn Integrator>, f32),
}

/// A per-pixel-sample estimator; [`render_pixels`] gives it a whole `render`.
pub trait PixelEstimator: Send + Sync {
    /// What [`begin_pixel`](Self::begin_pixel) computes once per pixel for all its samples
    /// (`()` for an estimator that shares nothing).
    type Shared: Send;
    /// Request sample arrays before rendering (pbrt-v3's `Request*Array`), on the prototype sampler.
    fn request_samples(&self, _sampler: &mut dyn Sampler) {}
    /// Radiance along a camera ray. The driver has counted the camera ray (see [`ThreadStats`]).
    /// The ray carries its offset rays, scaled by `1/√spp` as pbrt-v3 scales them
    /// ([`Scene::first_point`] turns them into the surface's differentials, for texture
    /// filtering and bump mapping).
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb;
    /// Work shared by all samples of one pixel (e.g. `ltc` shading each surface seen in the
    /// pixel once): called with the pixel's camera samples and their rays, in sample order,
    /// before any of its samples is estimated. `Some` makes the driver call [`li_shared`](Self::li_shared)
    /// instead of `li` for that pixel. Only called when [`shares_pixel_work`](Self::shares_pixel_work).
    fn begin_pixel(
        &self,
        _rays: &[RayDifferential],
        _samples: &[CameraSample],
        _scene: &Scene,
        _stats: &mut ThreadStats,
    ) -> Option<Self::Shared> {
        None
    }
    /// Whether [`begin_pixel`](Self::begin_pixel) should be called (the pixel's camera rays are
    /// then generated before its samples are estimated, and kept for them).
    fn shares_pixel_work(&self) -> bool {
        false
    }
    /// Pixels outside these bounds take no samples (pbrt-v3's integrator `"pixelbounds"`: the
    /// image keeps its size, with nothing in those pixels but their neighbours' filter tails).
    fn pixel_bounds(&self) -> Option<Bounds2i> {
        None
    }
    /// `li` for sample `index` (`< rays.len()` of `begin_pixel`) of a pixel whose shared work
    /// is `shared`.
    fn li_shared(&self, ray: &RayDifferential, cx: SampleContext, _shared: &Self::Shared, _index: usize) -> Rgb {
        self.li(ray, cx)
    }
    /// Scales one sample's extra channels (as `li` wrote them) by its camera ray's weight `w`
    /// (pbrt-v3's `GenerateRay` weight: the `realistic` camera's cos⁴θ and exit-pupil area;
    /// called only when `w` is neither 1 nor 0). The driver multiplies the radiance `li`
    /// returns by `w` itself, as pbrt-v3's film does; an estimator whose channels hold
    /// radiance estimates that a later pass turns into the image (`ratio`'s `U`, `S_N`, `U_N`,
    /// SH transfer) scales those here, and leaves guides (depth, normals) alone. The default
    /// scales nothing. A sample of weight 0 is not estimated: its radiance and channels are 0.
    fn weight_channels(&self, _aov: &mut [f32], _w: f32) {}
}

/// What a [`PixelEstimator`]'s per-sample call works with besides the ray.
pub struct SampleContext<'a> {
    pub scene: &'a Scene,
    /// The pixel's sampler, at this sample (the camera sample's dimensions drawn).
    pub sampler: &'a mut dyn Sampler,
    /// This thread's counters.
    pub stats: &'a mut ThreadStats,
    /// The integrator's extra channels for this sample (zero on entry).
    pub aov: &'a mut [f32],
}

/// The tiles covering `bounds`, on the fixed grid, in raster order.
pub fn tiles(bounds: Bounds2i) -> Vec<Bounds2i> {
    let mut out = Vec::new();
    if bounds.is_empty() {
        return out;
    }
    let t0 = IVec2::new(bounds.min.x.div_euclid(TILE_SIZE), bounds.min.y.div_euclid(TILE_SIZE));
    let t1 = IVec2::new((bounds.max.x - 1).div_euclid(TILE_SIZE), (bounds.max.y - 1).div_euclid(TILE_SIZE));
    for ty in t0.y..=t1.y {
        for tx in t0.x..=t1.x {
            let min = IVec2::new(tx, ty) * TILE_SIZE;
            let t = Bounds2i::new(min, min + IVec2::splat(TILE_SIZE)).intersect(&bounds);
            if !t.is_empty() {
                out.push(t);
            }
        }
    }
    out
}

/// The camera sample of pixel `p` as the driver draws it, in pbrt-v3's order: film 2D, time 1D,
/// lens 2D; the dimensions the camera ignores (`uses_time`, `uses_lens` false) are skipped
/// without being computed. For integrators with their own passes over the same samples.
pub fn draw_camera_sample(sampler: &mut dyn Sampler, p: IVec2, uses_time: bool, uses_lens: bool) -> CameraSample {
    CameraDims { uses_time, uses_lens }.sample(sampler, p, true)
}

/// Runs `f` on a pool of `threads` workers (0: all cores); each worker's [`crate::profiling`]
/// counters are flushed to the process-wide totals before the pool ends.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> Result<R, RenderError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RenderError::Failed(format!("cannot start worker threads: {e}")))?;
    let on = crate::profiling::enabled();
    pool.broadcast(|_| crate::profiling::enable_here(on));
    let r = pool.install(f);
    pool.broadcast(|_| crate::profiling::flush());
    Ok(r)
}

/// The generic driver: tiles in parallel, per-tile sampler clones, deterministic merge.
pub fn render_pixels<E: PixelEstimator + ?Sized>(
    est: &E,
    scene: &Scene,
    ctx: &RenderContext,
    film: &mut Film,
) -> Result<RenderStats, RenderError> {
    let start = Instant::now();
    let proto = prototype_sampler(est, scene, film);
    let spp = proto.samples_per_pixel();
    let tile_list = tiles(film.spec.sample_bounds(scene.filter.radius()));
    let total = tile_list.len() as u64;
    let done = AtomicU64::new(0);
    let pass = TilePass {
        est,
        scene,
        film: &*film,
        proto: proto.as_ref(),
        spp,
        camera: CameraDims { uses_time: scene.uses_time(), uses_lens: scene.camera.uses_lens() },
        cancel: ctx.cancel,
    };
    let results: Vec<Option<TileResult>> = with_threads(ctx.threads, || {
        tile_list
            .par_iter()
            .map(|tb| {
                if ctx.cancel.load(Ordering::Relaxed) {
                    return None;
                }
                let r = pass.render_tile(*tb)?;
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(pr) = ctx.progress {
                    pr(d, total);
                }
                Some(r)
            })
            .collect()
    })?;
    if results.iter().any(|r| r.is_none()) {
        return Err(RenderError::Cancelled);
    }
    let mut stats = merge_tiles(film, results.into_iter().flatten());
    stats.spp = spp;
    stats.threads = resolve_threads(ctx.threads);
    stats.render_seconds = start.elapsed().as_secs_f64();
    if stats.bad_samples > 0 {
        ctx.warnings.warn(
            None,
            format!("{} samples had NaN, infinite or negative radiance and were set to 0", stats.bad_samples),
        );
    }
    Ok(stats)
}

/// The sampler every tile clones: global samplers (halton, sobol) map pixels to sequence
/// indices over the *full* image's sample bounds, so that a crop renders exactly the samples
/// of the full image; the estimator's sample arrays are requested on it.
fn prototype_sampler<E: PixelEstimator + ?Sized>(est: &E, scene: &Scene, film: &Film) -> Box<dyn Sampler> {
    let mut proto = scene.sampler.clone_box();
    let full = crate::film::FilmSpec {
        pixel_bounds: Bounds2i::new(
            IVec2::ZERO,
            IVec2::new(film.spec.full_resolution.0 as i32, film.spec.full_resolution.1 as i32),
        ),
        ..film.spec.clone()
    }
    .sample_bounds(scene.filter.radius());
    proto.set_sample_bounds(full.min, full.max);
    est.request_samples(proto.as_mut());
    proto
}

/// The camera sample's dimensions, in pbrt-v3's order: film position (2D), time (1D), lens
/// (2D). [`sample`](Self::sample) both draws them and skips them, so the dimensions skipped
/// are by construction the ones drawn.
#[derive(Clone, Copy)]
struct CameraDims {
    uses_time: bool,
    uses_lens: bool,
}

impl CameraDims {
    /// The camera sample of pixel `p` when `draw`; otherwise its dimensions are only skipped
    /// (and the value returned is meaningless). Dimensions the camera ignores are always
    /// skipped, without being computed.
    fn sample(self, sampler: &mut dyn Sampler, p: IVec2, draw: bool) -> CameraSample {
        let dim_2d = |s: &mut dyn Sampler, used: bool, unused: Vec2| {
            if used {
                s.get_2d()
            } else {
                s.skip_2d();
                unused
            }
        };
        let film = dim_2d(sampler, draw, Vec2::ZERO);
        let time = if draw && self.uses_time {
            sampler.get_1d()
        } else {
            sampler.skip_1d();
            0.0
        };
        let p_lens = dim_2d(sampler, draw && self.uses_lens, Vec2::splat(0.5));
        CameraSample { p_film: p.as_vec2() + film, time, p_lens }
    }
}

/// A tile's film, the estimator's counters and the camera samples taken.
struct TileResult {
    tile: crate::film::FilmTile,
    stats: ThreadStats,
    camera_samples: u64,
}

/// What every tile of one [`render_pixels`] shares.
struct TilePass<'a, E: ?Sized> {
    est: &'a E,
    scene: &'a Scene,
    film: &'a Film,
    proto: &'a dyn Sampler,
    spp: u32,
    camera: CameraDims,
    /// Checked before every pixel, so that a slow pixel estimator stops within a pixel.
    cancel: &'a AtomicBool,
}

/// Per-tile scratch: the sampler, the extra channels of one sample, and a pixel's camera
/// samples and rays when the estimator shares pixel work.
struct TileScratch {
    sampler: Box<dyn Sampler>,
    aov: Vec<f32>,
    cams: Vec<CameraSample>,
    rays: Vec<RayDifferential>,
    weights: Vec<f32>,
}

impl<E: PixelEstimator + ?Sized> TilePass<'_, E> {
    /// `None` when the render was cancelled before the tile was done.
    fn render_tile(&self, tb: Bounds2i) -> Option<TileResult> {
        let mut out = TileResult { tile: self.film.make_tile(tb), stats: ThreadStats::default(), camera_samples: 0 };
        let mut scratch = TileScratch {
            sampler: self.proto.clone_box(),
            aov: vec![0.0f32; self.film.extra_channel_names.len()],
            cams: Vec::new(),
            rays: Vec::new(),
            weights: Vec::new(),
        };
        let pixel_bounds = self.est.pixel_bounds();
        for p in tb.iter() {
            if pixel_bounds.is_some_and(|b| !b.contains(p)) {
                continue;
            }
            if self.cancel.load(Ordering::Relaxed) {
                return None;
            }
            self.render_pixel(p, &mut scratch, &mut out);
        }
        Some(out)
    }

    /// The shared pass (when the estimator shares pixel work), then every sample of pixel `p`.
    fn render_pixel(&self, p: IVec2, scratch: &mut TileScratch, out: &mut TileResult) {
        let shared = if self.est.shares_pixel_work() { self.begin_pixel(p, scratch, &mut out.stats) } else { None };
        let TileScratch { sampler, aov, cams, rays, weights } = scratch;
        for s in 0..self.spp {
            sampler.start_pixel_sample(p, s);
            let i = s as usize;
            // The shared pass drew this sample's camera sample and ray already: its
            // dimensions are only skipped (the estimator's come after them).
            let (cs, (ray, w)) = match &shared {
                Some(_) => {
                    self.camera.sample(sampler.as_mut(), p, false);
                    (cams[i], (rays[i], weights[i]))
                }
                None => {
                    let cs = self.camera.sample(sampler.as_mut(), p, true);
                    (cs, self.generate_ray(&cs))
                }
            };
            aov.iter_mut().for_each(|v| *v = 0.0);
            let (est, scene, stats) = (self.est, self.scene, &mut out.stats);
            out.camera_samples += 1;
            // pbrt-v3 estimates only rays of positive weight; the others add 0 to the film.
            let l = if w > 0.0 {
                crate::profiling::camera_ray_given(true);
                let cx =
                    SampleContext { scene, sampler: sampler.as_mut(), stats: &mut *stats, aov: aov.as_mut_slice() };
                let l = match &shared {
                    Some(sh) => est.li_shared(&ray, cx, sh, i),
                    None => est.li(&ray, cx),
                };
                crate::profiling::camera_ray_given(false);
                if w != 1.0 {
                    est.weight_channels(aov, w);
                }
                guard_radiance(l, self.film.spec.max_sample_luminance, stats) * w
            } else {
                Rgb::ZERO
            };
            out.tile.add_sample(scene.filter.as_ref(), cs.p_film, l, aov);
        }
    }

    /// Generates the pixel's camera samples and rays, in sample order, into `scratch`, and
    /// hands the rays to the estimator's [`PixelEstimator::begin_pixel`].
    fn begin_pixel(&self, p: IVec2, scratch: &mut TileScratch, stats: &mut ThreadStats) -> Option<E::Shared> {
        scratch.cams.clear();
        scratch.rays.clear();
        scratch.weights.clear();
        for s in 0..self.spp {
            scratch.sampler.start_pixel_sample(p, s);
            let cs = self.camera.sample(scratch.sampler.as_mut(), p, true);
            let (ray, w) = self.generate_ray(&cs);
            scratch.rays.push(ray);
            scratch.weights.push(w);
            scratch.cams.push(cs);
        }
        crate::profiling::camera_ray_given(true);
        let shared = self.est.begin_pixel(&scratch.rays, &scratch.cams, self.scene, stats);
        crate::profiling::camera_ray_given(false);
        shared
    }

    /// The camera ray with its offset rays scaled to the sample spacing (pbrt-v3's
    /// `ScaleDifferentials(1 / √spp)`), and its weight.
    fn generate_ray(&self, cs: &CameraSample) -> (RayDifferential, f32) {
        crate::profiling::timed(crate::profiling::Phase::CameraRay, || {
            self.scene.camera.sample_ray_weighted(cs, self.spp)
        })
    }
}

/// pbrt-v3's guard: NaN, infinite or clearly negative luminance becomes black (counted in
/// `bad_samples`); luminance above `max_lum` is scaled down to it.
fn guard_radiance(mut l: Rgb, max_lum: f32, stats: &mut ThreadStats) -> Rgb {
    let y = crate::spectrum::luminance(l);
    if !l.is_finite() || y < -1e-5 {
        stats.bad_samples += 1;
        l = Rgb::ZERO;
    }
    if y > max_lum {
        l *= max_lum / y;
    }
    l
}

/// Merges the tiles into `film` in tile order (deterministic sums) and adds up their counters:
/// one camera ray per camera sample (the driver's count) plus the estimators' rays.
fn merge_tiles(film: &mut Film, results: impl Iterator<Item = TileResult>) -> RenderStats {
    let mut stats = RenderStats::default();
    for r in results {
        film.merge_tile(&r.tile);
        stats.camera_samples += r.camera_samples;
        stats.rays += r.camera_samples + r.stats.rays;
        stats.shadow_rays += r.stats.shadow_rays;
        stats.bad_samples += r.stats.bad_samples;
    }
    stats
}

/// [`render_pixels`] for image-space integrators whose output at a pixel reads the rendered
/// film up to `margin` pixels away (a denoiser's kernel, a sheared filter's footprint):
/// renders `film`'s pixels grown by `margin` (clipped to the full image) into a film of their
/// own, runs `pass` on it, then copies the film's own pixels back. A crop or a tile therefore
/// sees the neighbourhood the full image would and reproduces it bit for bit; with no crop
/// the grown film is the film itself. `pass` returns what the integrator wants to report.
pub fn render_pixels_with_margin<E: PixelEstimator + ?Sized, R>(
    est: &E,
    scene: &Scene,
    ctx: &RenderContext,
    film: &mut Film,
    margin: u32,
    pass: impl FnOnce(&mut Film) -> R,
) -> Result<(RenderStats, R), RenderError> {
    let mut grown = film.grown(margin);
    let stats = render_pixels(est, scene, ctx, &mut grown)?;
    let out = pass(&mut grown);
    film.copy_pixels_from(&grown);
    Ok((stats, out))
}

/// The number of worker threads a requested count means (0: one per core).
pub fn resolve_threads(requested: usize) -> usize {
    if requested > 0 {
        requested
    } else {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
    }
}
