//! Pixel shading ("multisample antialiasing"): the camera samples of a pixel only resolve
//! which surfaces the pixel sees and where their edges run; samples that see the same smooth
//! piece of surface form a cluster, shaded once at its most central member. `ltc` and `ratio`
//! use it through `PixelEstimator::begin_pixel`; the value shaded per cluster is the
//! integrator's (`T`).

use super::params::{ParamSpec, Params};
use glam::{DVec2, DVec3};
use penumbra_core::camera::CameraSample;
use penumbra_core::geometry::RayDifferential;
use penumbra_core::integrator::ThreadStats;
use penumbra_core::scene::{Scene, SurfaceHit, SurfacePoint};
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::Diagnostic;

/// `"string shading"`, read by `ltc` and `ratio`.
pub const SHADING: ParamSpec = ParamSpec::choice(
    "shading",
    &["pixel", "sample"],
    "shade each surface a pixel sees once (camera samples only anti-alias), or every camera sample",
);

/// Pixel shading's refinement threshold for noise-free shaders (`silhouette`, `shexp`): two
/// samples of one surface in a pixel whose values differ by more than this fraction of the
/// larger in any colour make every sample of it shaded ([`shade_clusters`]' `differs`).
pub const REFINE: f32 = 0.1;

/// Whether two shaded values differ by more than [`REFINE`] of the larger in any colour.
pub fn rgb_differs(a: Rgb, b: Rgb) -> bool {
    ((a - b).abs() - REFINE * a.abs().max(b.abs())).max_element() > 0.0
}

/// Reads [`SHADING`]: `true` for pixel shading.
pub fn parse_shading(params: &Params) -> Result<bool, Diagnostic> {
    params.choice("shading", [true, false])
}

/// A camera ray's first surface (its BSDF not built), or the radiance it escaped with
/// ([`Scene::first_point`]).
pub type FirstSurface = Result<SurfacePoint, Rgb>;

/// The samples of one pixel: their first surfaces and the value of each one's cluster
/// (`None`: the ray escaped, or the shader gave none for that surface).
pub struct SharedPixel<T> {
    hits: Vec<FirstSurface>,
    shaded: Vec<Option<T>>,
}

impl<T: Copy> SharedPixel<T> {
    /// Traces the pixel's camera `rays` (one traversal for the bundle when it meets few
    /// triangles) and shades each cluster once with `shade` ([`shade_clusters`]), which is
    /// given `stats` to count its own rays; `samples` are the rays' camera samples; `differs`
    /// as [`shade_clusters`]'.
    pub fn trace(
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
        light_distance: impl Fn(DVec3) -> f64,
        differs: Option<fn(&T, &T) -> bool>,
        mut shade: impl FnMut(&SurfacePoint, &mut ThreadStats) -> Option<T>,
    ) -> SharedPixel<T> {
        let candidates = scene.bundle_candidates(rays);
        let mut hits: Vec<FirstSurface> = Vec::with_capacity(rays.len());
        for r in rays {
            let prev = hits.last().and_then(|h| h.as_ref().ok()).map(|h| &h.si);
            let (first, queries) = scene.first_point_among(r, candidates.as_deref(), prev);
            // The driver counted the camera ray itself.
            stats.add_continued(queries);
            hits.push(first);
        }
        let shaded = shade_clusters(rays, samples, &hits, light_distance, differs, |p| shade(p, stats));
        SharedPixel { hits, shaded }
    }

    /// Sample `index` of the pixel: its first surface (or the radiance its ray escaped with) and
    /// its cluster's value. `index` is below the number of rays [`trace`](Self::trace) was
    /// given (the driver's contract for `li_shared`).
    pub fn sample(&self, index: usize) -> (&FirstSurface, Option<T>) {
        (&self.hits[index], self.shaded[index])
    }

    /// Sample `index` shaded by `shade` from its first surface (with its BSDF; black where it
    /// has none) and its cluster's value, or the radiance its ray escaped with.
    pub fn shade_sample(&self, index: usize, scene: &Scene, shade: impl FnOnce(&SurfaceHit, Option<T>) -> Rgb) -> Rgb {
        match self.sample(index) {
            (Ok(p), v) => p.with_bsdf(scene).map_or(Rgb::ZERO, |hit| shade(&hit, v)),
            (Err(escaped), _) => *escaped,
        }
    }
}

/// A pixel cluster whose extent exceeds this fraction of its distance to the nearest light is
/// shaded sample by sample.
const NEAR_FIELD: f64 = 0.05;

/// Samples of a pixel that see the same smooth piece of surface (its members are the samples
/// whose `cluster` entry is its index).
struct Cluster {
    mesh: u32,
    n: Vec3,
    depth: f32,
    /// The sum of the members' film positions.
    film_sum: DVec2,
}

/// Each hit's cluster (same mesh, shading normals within ~11°, depths within 5 %;
/// `usize::MAX`: none, the ray escaped) and the clusters.
fn clusters_of(
    rays: &[RayDifferential],
    samples: &[CameraSample],
    hits: &[FirstSurface],
) -> (Vec<usize>, Vec<Cluster>) {
    let mut clusters: Vec<Cluster> = Vec::new();
    let mut cluster = vec![usize::MAX; hits.len()];
    for (i, h) in hits.iter().enumerate() {
        let Ok(h) = h else { continue };
        let n = h.si.shading.z;
        let depth = (h.si.p - rays[i].o).length();
        let f = samples[i].p_film.as_dvec2();
        match clusters.iter().position(|c| {
            c.mesh == h.si.mesh && c.n.dot(n) > 0.98 && (c.depth - depth).abs() <= 0.05 * c.depth.max(depth)
        }) {
            Some(k) => {
                cluster[i] = k;
                clusters[k].film_sum += f;
            }
            None => {
                cluster[i] = clusters.len();
                clusters.push(Cluster { mesh: h.si.mesh, n, depth, film_sum: f });
            }
        }
    }
    (cluster, clusters)
}

/// Groups the pixel's hits into clusters and shades each cluster once, at the member whose
/// camera sample lies closest to the members' mean film position (the first such member on a
/// tie) — every member when the cluster's extent is not small against `light_distance` of that
/// point (the lighting varies across the pixel: a light grazing the floor). The choice is made
/// on the film, not on the rays' world directions, so that it is the same for the scene
/// rotated, scaled or moved (`penumbra stability`): near-ties between world-space dot products
/// fell either way with rounding and picked another shading point.
///
/// With `differs`, a cluster is also shaded at its member farthest from that one on the film
/// (the first on a tie), which keeps its own value; when `differs` finds the two values apart
/// (a shadow edge or a highlight crossing the pixel), every member is shaded.
pub fn shade_clusters<T: Copy>(
    rays: &[RayDifferential],
    samples: &[CameraSample],
    hits: &[FirstSurface],
    light_distance: impl Fn(DVec3) -> f64,
    differs: Option<fn(&T, &T) -> bool>,
    mut shade: impl FnMut(&SurfacePoint) -> Option<T>,
) -> Vec<Option<T>> {
    let (cluster, clusters) = clusters_of(rays, samples, hits);
    let mut shaded = vec![None; hits.len()];
    let mut shade_one = |i: usize| -> Option<T> { shade(hits[i].as_ref().ok()?) };
    let film = |i: usize| samples[i].p_film.as_dvec2();
    let pos = |i: usize| hits[i].as_ref().map(|h| h.si.p.as_dvec3()).unwrap_or(DVec3::ZERO);
    let cluster = &cluster[..];
    for (k, c) in clusters.iter().enumerate() {
        let members = || (0..hits.len()).filter(move |&m| cluster[m] == k);
        let count = members().count() as f64;
        let mean = c.film_sum / count;
        let Some(rep) =
            members().min_by(|a, b| (film(*a) - mean).length_squared().total_cmp(&(film(*b) - mean).length_squared()))
        else {
            continue;
        };
        let extent = members().map(|m| (pos(m) - pos(rep)).length()).fold(0.0, f64::max);
        let mut every = extent > NEAR_FIELD * light_distance(pos(rep));
        let v = shade_one(rep);
        let mut far = None;
        if let (Some(differs), false) = (differs, every) {
            let by_distance = |a: &usize, b: &usize| {
                let (da, db) = ((film(*a) - film(rep)).length_squared(), (film(*b) - film(rep)).length_squared());
                da.total_cmp(&db).then(b.cmp(a))
            };
            if let Some(f) = members().filter(|&m| m != rep).max_by(by_distance) {
                let w = shade_one(f);
                every = match (&v, &w) {
                    (Some(a), Some(b)) => differs(a, b),
                    (None, None) => false,
                    _ => true,
                };
                far = Some((f, w));
            }
        }
        for m in members() {
            shaded[m] = match far {
                Some((f, w)) if f == m => w,
                _ if m == rep || !every => v,
                _ => shade_one(m),
            };
        }
    }
    shaded
}
