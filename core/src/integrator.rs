//! The integrator interface and the generic parallel driver for per-pixel estimators.

use crate::camera::CameraSample;
use crate::film::Film;
use crate::geometry::Bounds2i;
use crate::geometry::Ray;
use crate::sampler::Sampler;
use crate::scene::{Requirements, Scene};
use crate::Rgb;
use glam::{IVec2, Vec2};
use penumbra_parser::DiagSink;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
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
#[derive(Clone, Debug, Default)]
pub struct ThreadStats {
    pub rays: u64,
    pub shadow_rays: u64,
    /// Non-finite or negative radiance values replaced by 0 (pbrt-v3 does the same, with an error).
    pub bad_samples: u64,
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
}

pub trait Integrator: Send + Sync {
    fn name(&self) -> &str;
    /// What the scene build must provide.
    fn requirements(&self) -> Requirements;
    /// Extra film channels this integrator writes (beyond R, G, B).
    fn extra_channels(&self) -> Vec<String> {
        Vec::new()
    }
    /// Render the whole image into `film`.
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError>;
}

/// A per-pixel-sample estimator; [`render_pixels`] gives it a whole `render`.
pub trait PixelEstimator: Send + Sync {
    /// Request sample arrays before rendering (pbrt-v3's `Request*Array`), on the prototype sampler.
    fn request_samples(&self, _sampler: &mut dyn Sampler) {}
    /// Radiance along a camera ray; `aov` holds the integrator's extra channels for this sample.
    fn li(&self, ray: &Ray, scene: &Scene, sampler: &mut dyn Sampler, stats: &mut ThreadStats, aov: &mut [f32]) -> Rgb;
    /// Work shared by all samples of one pixel (e.g. `ltc` shading each surface seen in the
    /// pixel once): called with the pixel's camera rays, in sample order, before any of its
    /// samples is estimated. `Some` makes the driver call [`li_shared`](Self::li_shared)
    /// instead of `li` for that pixel. Only called when [`shares_pixel_work`](Self::shares_pixel_work).
    fn begin_pixel(&self, _rays: &[Ray], _scene: &Scene, _stats: &mut ThreadStats) -> Option<PixelShared> {
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
    /// `li` for sample `index` of a pixel whose shared work is `shared`.
    #[allow(clippy::too_many_arguments)]
    fn li_shared(
        &self,
        ray: &Ray,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        aov: &mut [f32],
        _shared: &PixelShared,
        _index: usize,
    ) -> Rgb {
        self.li(ray, scene, sampler, stats, aov)
    }
}

/// What an estimator's [`PixelEstimator::begin_pixel`] computed for one pixel.
pub type PixelShared = Box<dyn std::any::Any + Send>;

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
    let p_film = p.as_vec2() + sampler.get_2d();
    let time = if uses_time {
        sampler.get_1d()
    } else {
        sampler.skip_1d();
        0.0
    };
    let p_lens = if uses_lens {
        sampler.get_2d()
    } else {
        sampler.skip_2d();
        Vec2::splat(0.5)
    };
    CameraSample { p_film, time, p_lens }
}

/// Runs `f` on a pool of `threads` workers (0: all cores).
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> Result<R, RenderError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RenderError::Failed(format!("cannot start worker threads: {e}")))?;
    Ok(pool.install(f))
}

/// The generic driver: tiles in parallel, per-tile sampler clones, deterministic merge.
pub fn render_pixels(
    est: &dyn PixelEstimator,
    scene: &Scene,
    ctx: &RenderContext,
    film: &mut Film,
) -> Result<RenderStats, RenderError> {
    let start = Instant::now();
    let mut proto = scene.sampler.clone_box();
    // Global samplers (halton, sobol) map pixels to sequence indices over the *full* image's
    // sample bounds, so that a crop renders exactly the samples of the full image.
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
    let spp = proto.samples_per_pixel();
    let sample_bounds = film.spec.sample_bounds(scene.filter.radius());
    let tile_list = tiles(sample_bounds);
    let total = tile_list.len() as u64;
    let done = AtomicU64::new(0);
    let naov = film.extra_channel_names.len();
    let max_lum = film.spec.max_sample_luminance;
    let film_ref = &*film;
    let (uses_time, uses_lens) = (scene.camera.uses_time(), scene.camera.uses_lens());
    let results: Vec<Option<(crate::film::FilmTile, ThreadStats)>> = with_threads(ctx.threads, || {
        tile_list
            .par_iter()
            .map(|tb| {
                if ctx.cancel.load(Ordering::Relaxed) {
                    return None;
                }
                let mut sampler = proto.clone_box();
                let mut tile = film_ref.make_tile(*tb);
                let mut stats = ThreadStats::default();
                let mut aov = vec![0.0f32; naov];
                // The film, time and lens dimensions are drawn in pbrt-v3's order; the ones the
                // camera ignores are skipped without being computed.
                let camera_sample =
                    |sampler: &mut dyn Sampler, p: IVec2| draw_camera_sample(sampler, p, uses_time, uses_lens);
                let shares = est.shares_pixel_work();
                let (mut cams, mut rays) = (Vec::new(), Vec::new());
                let pixel_bounds = est.pixel_bounds();
                for p in tb.iter() {
                    if pixel_bounds.is_some_and(|b| !b.contains(p)) {
                        continue;
                    }
                    let shared = if shares {
                        cams.clear();
                        rays.clear();
                        for s in 0..spp {
                            sampler.start_pixel_sample(p, s);
                            let cs = camera_sample(sampler.as_mut(), p);
                            rays.push(scene.camera.generate_ray(&cs));
                            cams.push(cs);
                        }
                        est.begin_pixel(&rays, scene, &mut stats)
                    } else {
                        None
                    };
                    for s in 0..spp {
                        sampler.start_pixel_sample(p, s);
                        // The shared pass drew this sample's camera sample and ray already: its
                        // dimensions are only skipped (the estimator's come after them).
                        let (cs, ray) = match (cams.get(s as usize), rays.get(s as usize)) {
                            (Some(cs), Some(r)) if shared.is_some() => {
                                sampler.skip_2d();
                                sampler.skip_1d();
                                sampler.skip_2d();
                                (*cs, *r)
                            }
                            _ => {
                                let cs = camera_sample(sampler.as_mut(), p);
                                (cs, scene.camera.generate_ray(&cs))
                            }
                        };
                        aov.iter_mut().for_each(|v| *v = 0.0);
                        let mut l = match &shared {
                            Some(sh) => {
                                est.li_shared(&ray, scene, sampler.as_mut(), &mut stats, &mut aov, sh, s as usize)
                            }
                            None => est.li(&ray, scene, sampler.as_mut(), &mut stats, &mut aov),
                        };
                        stats.rays += 1;
                        // pbrt-v3's guard: NaN, infinite or clearly negative luminance becomes black.
                        let y = crate::spectrum::luminance(l);
                        if !l.is_finite() || y < -1e-5 {
                            stats.bad_samples += 1;
                            l = Rgb::ZERO;
                        }
                        if y > max_lum {
                            l *= max_lum / y;
                        }
                        tile.add_sample(scene.filter.as_ref(), cs.p_film, l, &aov);
                    }
                }
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(pr) = ctx.progress {
                    pr(d, total);
                }
                Some((tile, stats))
            })
            .collect()
    })?;
    if results.iter().any(|r| r.is_none()) {
        return Err(RenderError::Cancelled);
    }
    let mut stats = RenderStats { spp, threads: rayon_threads(ctx.threads), ..Default::default() };
    for (tile, ts) in results.into_iter().flatten() {
        film.merge_tile(&tile);
        stats.rays += ts.rays;
        stats.shadow_rays += ts.shadow_rays;
        stats.bad_samples += ts.bad_samples;
    }
    stats.camera_samples = sample_bounds.area() as u64 * spp as u64;
    stats.render_seconds = start.elapsed().as_secs_f64();
    if stats.bad_samples > 0 {
        ctx.warnings.warn(
            None,
            format!("{} samples had NaN, infinite or negative radiance and were set to 0", stats.bad_samples),
        );
    }
    Ok(stats)
}

/// [`render_pixels`] for image-space integrators whose output at a pixel reads the rendered
/// film up to `margin` pixels away (a denoiser's kernel, a sheared filter's footprint):
/// renders `film`'s pixels grown by `margin` (clipped to the full image) into a film of their
/// own, runs `pass` on it, then copies the film's own pixels back. A crop or a tile therefore
/// sees the neighbourhood the full image would and reproduces it bit for bit; with no crop
/// the grown film is the film itself. `pass` returns what the integrator wants to report.
pub fn render_pixels_with_margin<R>(
    est: &dyn PixelEstimator,
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

fn rayon_threads(requested: usize) -> usize {
    if requested > 0 {
        requested
    } else {
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
    }
}
