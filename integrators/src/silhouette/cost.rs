//! The cost estimate `penumbra info -i silhouette` and the start of a render print (issue 37
//! item 3): a probe at a few dozen shading points, the first hits of a coarse grid of camera
//! rays, each run through the real contour query and traversal, and the same pixels' first
//! camera samples through `ambientocclusion` at its defaults (64 rays), both timed (the lower
//! of two runs); the estimate scales the measured times by the camera samples and the points
//! the render integrates. It counts the contour queries and the camera rays only, which
//! dominate on meshes of thousands of triangles (the case it warns about): elsewhere it is a
//! lower bound (the radiance tables' build, shading and the render driver are not counted;
//! measured figures in docs/integrators/silhouette.md). What the probe counts (points, hits, contour edges, edges
//! examined) is deterministic; only the times are measured.

use super::dual::DualEdges;
use super::param::Meridians;
use super::traverse::Traversal;
use super::{integration_axes, prepared_dual_edges, Estimator, Mode, Silhouette, CULL_TOL};
use crate::common::pixel_shading::shading_points;
use penumbra_core::camera::CameraSample;
use penumbra_core::geometry::{face_forward, offset_ray_origin};
use penumbra_core::integrator::{CostEstimate, ThreadStats};
use penumbra_core::light::Light;
use penumbra_core::scene::Scene;
use penumbra_core::{IVec2, Vec2};
use std::time::Instant;

/// Camera rays per side of the probe's grid at most (36 points).
const MAX_SIDE: usize = 6;
/// The probe takes at most this share of the points the render integrates (so that it costs
/// a few percent of the render), and never fewer than 2 × 2 rays.
const PROBE_SHARE: f64 = 0.02;
/// `ambientocclusion`'s default `"integer nsamples"`: the rays it traces per camera sample.
const AO_RAYS: usize = 64;
/// The warning's threshold: estimated time over `ambientocclusion`'s for the same image.
pub const WARN_RATIO: f64 = 10.0;
/// Pixel shading's integrations per pixel besides the [`shading_points`] of each surface, as
/// a share of the pixel's other samples (the samples where those differ by more than 5 %:
/// shadow edges and highlights). Measured with `tests/silhouette.rs`'s
/// `pixel_shading_matches_sample_shading` (its integration ratios, 48²): studio 0.27 / 0.30,
/// sky-sun 0.21 / 0.22, blinds 0.22 / 0.21 at 16 / 64 spp; see docs/integrators/silhouette.md.
pub const REFINED_SHARE: f64 = 0.25;

/// Shading points `silhouette` integrates per pixel at `spp` (before background pixels,
/// which integrate nothing): every sample with sample shading or `prt`; with pixel shading
/// ⌈√spp⌉ samples of each surface plus [`REFINED_SHARE`] of the others.
pub fn integrations_per_pixel(spp: u32, pixel_shading: bool) -> f64 {
    let k = shading_points(spp as usize) as f64;
    let spp = spp as f64;
    if !pixel_shading {
        spp
    } else {
        k + REFINED_SHARE * (spp - k)
    }
}

/// What the probe measured.
#[derive(Default)]
struct Probe {
    rays: usize,
    hits: usize,
    contours: usize,
    examined: usize,
    /// Seconds, summed over the probe's camera rays: the camera ray to its first surface; the
    /// contour query and traversal with its one shadow ray (0 where the ray missed); a camera
    /// sample of `ambientocclusion` at its defaults. The last two are each the lower of two
    /// runs, so that a thread switch does not count.
    camera: f64,
    silhouette: f64,
    ao: f64,
}

/// The probe's pixels: the centres of a `side` × `side` grid over the film's pixel bounds.
fn probe_pixels(scene: &Scene, side: usize) -> Vec<IVec2> {
    let pb = scene.film.pixel_bounds;
    let (w, h) = ((pb.max.x - pb.min.x) as f32, (pb.max.y - pb.min.y) as f32);
    let mut out = Vec::with_capacity(side * side);
    for j in 0..side {
        for i in 0..side {
            let x = pb.min.x + (w * (i as f32 + 0.5) / side as f32) as i32;
            let y = pb.min.y + (h * (j as f32 + 0.5) / side as f32) as i32;
            out.push(IVec2::new(x, y));
        }
    }
    out
}

fn probe(scene: &Scene, dual: &DualEdges, resolution: usize, side: usize) -> Probe {
    let infinite: Vec<&Light> = scene.light_list().iter().filter(|l| l.is_infinite()).collect();
    let axes = integration_axes(&infinite);
    let meridians = Meridians::new(resolution);
    let mut traversal = Traversal::default();
    let (mut contours, mut stats, mut out) = (Vec::new(), ThreadStats::default(), Probe::default());
    let pixels = probe_pixels(scene, side);
    out.ao = crate::ambientocclusion::time_first_samples(scene, &pixels).iter().sum();
    for p in pixels {
        let sample = CameraSample { p_film: p.as_vec2() + Vec2::splat(0.5), p_lens: Vec2::splat(0.5), time: 0.5 };
        let t = Instant::now();
        let ray = scene.camera.generate_ray_differential(&sample);
        let si = Estimator::first_surface(scene, &ray, &mut stats);
        out.camera += t.elapsed().as_secs_f64();
        out.rays += 1;
        let Some(si) = si else { continue };
        out.hits += 1;
        let n = face_forward(si.n, -ray.d);
        let (mut best, mut examined) = (f64::INFINITY, 0);
        for _ in 0..2 {
            let t = Instant::now();
            let p = dual.normalise(offset_ray_origin(si.p, si.p_error, n, n));
            let nd = n.as_dvec3().normalize();
            let frame = axes.frame_for_normal(nd);
            contours.clear();
            examined = dual.contours(p, nd, CULL_TOL, &mut contours).edges;
            let vis = traversal.run(&contours, p, nd, &frame, &meridians);
            std::hint::black_box(scene.occluded(&si.spawn_ray(vis.probe.as_vec3())));
            best = best.min(t.elapsed().as_secs_f64());
        }
        out.silhouette += best;
        out.contours += contours.len();
        out.examined += examined;
    }
    out
}

/// A duration for people, to about 3 significant digits.
fn human(seconds: f64) -> String {
    match seconds {
        s if s < 1e-3 => format!("{:.1} µs", s * 1e6),
        s if s < 1.0 => format!("{:.3} ms", s * 1e3),
        s if s < 100.0 => format!("{s:.2} s"),
        s if s < 7200.0 => format!("{s:.0} s ({:.0} min)", s / 60.0),
        s => format!("{s:.0} s ({:.1} h)", s / 3600.0),
    }
}

/// `silhouette`'s [`Integrator::estimate_cost`](penumbra_core::integrator::Integrator::estimate_cost).
pub fn estimate(s: &Silhouette, scene: &Scene, threads: usize) -> CostEstimate {
    let mut built = None;
    let dual = prepared_dual_edges(scene, &mut built);
    let mode = s.mode.unwrap_or(if scene.light_list().is_empty() { Mode::Ao } else { Mode::Shade });
    let pb = scene.film.pixel_bounds;
    let pixels = pb.area().max(0) as f64;
    let spp = scene.sampler.samples_per_pixel();
    let pixel_shading = s.pixel_shading && mode != Mode::Prt;
    let per_pixel = integrations_per_pixel(spp, pixel_shading);
    let points = pixels * per_pixel;
    let side = ((points * PROBE_SHARE).sqrt() as usize).clamp(2, MAX_SIDE);
    let t = Instant::now();
    let p = probe(scene, dual, s.resolution, side);
    let probe_seconds = t.elapsed().as_secs_f64();
    let (rays, hits) = (p.rays.max(1) as f64, p.hits.max(1) as f64);
    let hit_share = p.hits as f64 / rays;
    let threads = threads.max(1) as f64;
    let samples = pixels * spp as f64;
    // Per camera ray (a miss integrates nothing): the camera rays are traced for every
    // sample, the integrals at `per_pixel` of them.
    let sil = (samples * p.camera / rays + points * p.silhouette / rays) / threads;
    let ao = samples * p.ao / rays / threads;
    let sil_point = p.silhouette / hits;
    let contours = p.contours as f64 / hits;
    let how = if pixel_shading && spp > 2 {
        format!(
            "pixel shading: {} samples of each surface a pixel sees (⌈√spp⌉), and about {:.0} % of its other \
             samples",
            shading_points(spp as usize),
            100.0 * REFINED_SHARE
        )
    } else {
        "every camera sample".to_string()
    };
    let lines = vec![
        format!(
            "silhouette cost estimate: {contours:.0} contour edges per shading point ({:.0} edges examined), \
             {} per point (contour query and traversal, measured at {} of {} probe rays' first hits; the \
             probe took {})",
            p.examined as f64 / hits,
            human(sil_point),
            p.hits,
            p.rays,
            human(probe_seconds)
        ),
        format!(
            "  {points:.0} points to integrate ({pixels:.0} px × {per_pixel:.2}: {how}; {:.0} % hit geometry): \
             {} on {threads} thread(s) for their contour queries and the camera rays (a lower bound: the \
             radiance tables' build and the shading are not counted); ambientocclusion ({AO_RAYS} rays): {}",
            100.0 * hit_share,
            human(sil),
            human(ao)
        ),
    ];
    let warning = (p.hits > 0 && sil > WARN_RATIO * ao).then(|| {
        format!(
            "silhouette will be about {:.0}× slower than ambientocclusion here (estimated {} against {}): {contours:.0} \
             contour edges per shading point on this scene's meshes cost {} each. For a faster image use \
             -i ambientocclusion (or -i directlighting for the scene's lights), or fewer pixels (--resolution) and \
             samples (--spp)",
            sil / ao,
            human(sil),
            human(ao),
            human(sil_point)
        )
    });
    CostEstimate { seconds: sil, lines, warning }
}
