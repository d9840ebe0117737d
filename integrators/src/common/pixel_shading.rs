//! Pixel shading ("multisample antialiasing"): the camera samples of a pixel only resolve
//! which surfaces the pixel sees and where their edges run; samples that see the same smooth
//! piece of surface form a cluster, shaded at ⌈√m⌉ of its m members spread over the film
//! ([`shading_points`]; the others take the nearest one's value). `ltc`, `ratio`,
//! `silhouette` and `shexp` use it through `PixelEstimator::begin_pixel`; the value shaded per
//! cluster is the integrator's (`T`, which [`Blend`]s: where the lighting varies across a
//! cluster its members take a blend of the shared value and their own, [`shade_clusters`]).

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
    "shade each surface a pixel sees at ⌈√m⌉ of its m camera samples (the others take the nearest one's value), or every camera sample",
);

/// Pixel shading's refinement band (`ltc`, `silhouette`, `shexp`): a cluster one of whose shaded
/// samples differs from the central one by `d` (the largest difference in any colour as a
/// fraction of the larger value, [`rgb_difference`]; the largest such `d`) gives each member
/// `(1 − w)` of its shaded neighbour's value plus `w` of its
/// own, `w` rising linearly from 0 at `d =` [`REFINE`] to 1 at `d =` [`REFINE_FULL`]
/// ([`refine_weight`]). A hard switch at 10 % let rounding decide between the shared value and
/// the member's own: `env/objects-sky-sun` scaled by 1e4 or turned changed single `shexp`
/// pixels by a few percent (`penumbra stability`: max |z| 9.9 and 10.4); the blend makes a
/// pixel a continuous function of the values.
///
/// The band ends where the switch was, so nothing is less exact than with it: from 10 % every
/// member takes its own value, as the switch had it (no bias against per-sample shading
/// there); below 5 % the shared value, as before; between, a member's error against its own
/// value is `(1 − w)` of the difference the switch left whole. The cost is the members of the
/// clusters in the band, shaded now and not before; at 24², 16 spp, one thread (callgrind,
/// instructions of the whole render; the switch shaded the same points as a band above it):
/// `ltc` on `ltc/two-lights-metal` 57.5 % → 67.6 % of the camera samples shaded, +16 %
/// instructions; `shexp` on `env/objects-sky-sun` 19.8 % → 24.4 %, +0.8 %; `silhouette`
/// there 20.3 % → 22.4 %, +2.3 %. A band above the switch (10 % to 20 %, the first version)
/// kept the cost but left up to all of a 20 % difference where the switch had left none.
pub const REFINE: f32 = 0.05;
/// The difference from which a member takes its own value alone (the hard switch's threshold).
pub const REFINE_FULL: f32 = 0.1;

/// The largest difference of two shaded values in any colour, as a fraction of the larger
/// (0 where both are 0).
pub fn rgb_difference(a: Rgb, b: Rgb) -> f32 {
    let (d, m) = ((a - b).abs(), a.abs().max(b.abs()));
    (0..3).map(|c| if m[c] > 0.0 { d[c] / m[c] } else { 0.0 }).fold(0.0, f32::max)
}

/// The weight of a member's own value for a cluster whose two shaded samples differ by `d`
/// ([`REFINE`]; 1 for a NaN).
pub fn refine_weight(d: f32) -> f32 {
    ramp(d, REFINE, REFINE_FULL)
}

/// 0 up to `lo`, 1 from `hi`, linear between; 1 for a NaN `x`.
fn ramp(x: f32, lo: f32, hi: f32) -> f32 {
    let w = (x - lo) / (hi - lo);
    if w.is_nan() {
        1.0
    } else {
        w.clamp(0.0, 1.0)
    }
}

/// A value pixel shading can blend between a cluster's shared value and a member's own.
pub trait Blend: Clone {
    /// `(1 − w)·self + w·other` (`w` in [0, 1]; `other` itself at `w = 1`).
    fn blend(&self, other: &Self, w: f32) -> Self;
}

impl Blend for Rgb {
    fn blend(&self, other: &Self, w: f32) -> Self {
        *self * (1.0 - w) + *other * w
    }
}

impl<A: Blend, B: Blend> Blend for (A, B) {
    fn blend(&self, other: &Self, w: f32) -> Self {
        (self.0.blend(&other.0, w), self.1.blend(&other.1, w))
    }
}

/// `None` (a shader that failed, such as `silhouette`'s traversal) has nothing to blend: the
/// member's own value stands.
impl<A: Blend> Blend for Option<A> {
    fn blend(&self, other: &Self, w: f32) -> Self {
        // The ends exactly (the shared value or the member's own, bit for bit).
        if w >= 1.0 {
            return other.clone();
        }
        if w <= 0.0 {
            return self.clone();
        }
        match (self, other) {
            (Some(a), Some(b)) => Some(a.blend(b, w)),
            _ => other.clone(),
        }
    }
}

/// Reads [`SHADING`]: `true` for pixel shading.
pub fn parse_shading(params: &Params) -> Result<bool, Diagnostic> {
    params.choice("shading", [true, false])
}

/// How finely a cluster is shaded (a shader's answer for its representative point and
/// extent), as two weights in [0, 1] that vary continuously with the scene: `every`, the
/// weight of each member's own value whatever the values (a light grazing the floor, a
/// sharp highlight); `compare`, how far the differences between its [`shading_points`]
/// refine it ([`shade_clusters`]). A shader that decided by thresholds let a pixel jump when
/// rounding put the scene scaled or turned on the other side; ramps over a band do not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refine {
    pub every: f32,
    pub compare: f32,
}

impl Refine {
    /// At the [`shading_points`] alone.
    pub const ONCE: Refine = Refine { every: 0.0, compare: 0.0 };
    /// At the [`shading_points`], and at every member as far as their values differ from the
    /// representative's ([`refine_weight`]).
    pub const COMPARE: Refine = Refine { every: 0.0, compare: 1.0 };
    /// At every member, each taking its own value.
    pub const EVERY: Refine = Refine { every: 1.0, compare: 0.0 };

    /// `every` and `compare` each rising linearly from 0 where `x_every` resp. `x_compare`
    /// reaches ½ to 1 where it reaches 1: a hard switch's threshold at 1 becomes the end of a
    /// band, so that from it the cluster is shaded as finely as the switch shaded it (as
    /// [`REFINE_FULL`]), and below half of it as coarsely.
    pub fn ramps(x_every: f64, x_compare: f64) -> Refine {
        Refine { every: ramp(x_every as f32, 0.5, 1.0), compare: ramp(x_compare as f32, 0.5, 1.0) }
    }
}

/// The size of a pixel cluster: the largest distance of a member's point from the
/// representative's (world units) and the largest angle between their camera rays (radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClusterExtent {
    pub world: f64,
    pub angle: f64,
}

/// A pixel cluster whose extent exceeds this fraction of its distance to the nearest light
/// takes the members' own values alone (the lighting varies across it); from half this
/// fraction it starts to take them ([`Refine::ramps`]).
pub const NEAR_FIELD: f64 = 0.05;

/// A camera ray's first surface (its BSDF not built), or the radiance it escaped with
/// ([`Scene::first_point`]).
pub type FirstSurface = Result<SurfacePoint, Rgb>;

/// The samples of one pixel: their first surfaces and the value of each one's cluster
/// (`None`: the ray escaped, or the shader gave none for that surface).
pub struct SharedPixel<T> {
    hits: Vec<FirstSurface>,
    shaded: Vec<Option<T>>,
}

impl<T: Blend> SharedPixel<T> {
    /// Traces the pixel's camera `rays` (one traversal for the bundle when it meets few
    /// triangles) and shades each cluster once with `shade` ([`shade_clusters`]), which is
    /// given `stats` to count its own rays; `samples` are the rays' camera samples; `refine`
    /// and `difference` as [`shade_clusters`]'.
    pub fn trace(
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
        refine: impl Fn(&SurfacePoint, ClusterExtent) -> Refine,
        difference: Option<fn(&T, &T) -> f32>,
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
        let shaded = shade_clusters(rays, samples, &hits, refine, difference, |p| shade(p, stats));
        SharedPixel { hits, shaded }
    }

    /// Sample `index` of the pixel: its first surface (or the radiance its ray escaped with) and
    /// its cluster's value. `index` is below the number of rays [`trace`](Self::trace) was
    /// given (the driver's contract for `li_shared`).
    pub fn sample(&self, index: usize) -> (&FirstSurface, Option<T>) {
        (&self.hits[index], self.shaded[index].clone())
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

/// The members of a cluster of `members` camera samples shaded on their own account (before
/// any refinement): ⌈√members⌉, so that a pixel's value converges to sample shading's as the
/// samples grow (issue 37). Shading a single central member left every variation under the
/// refinement's threshold unintegrated, at any spp: `silhouette mode=ao` on a 64² crop of
/// killeroos under a white sky at 256² kept an RMSE of 0.0201 against pbrt-v3 at 128 spp
/// where sample shading reaches 0.0091 (the reference's own noise: 0.0092 with ⌈√m⌉);
/// `silhouette` on `env/objects-sky-sun` 48², 64 spp differed from its sample-shaded image
/// by 2.93 % of the mean per pixel (0.22 % with ⌈√m⌉). See docs/integrators/silhouette.md.
pub fn shading_points(members: usize) -> usize {
    ((members as f64).sqrt().ceil() as usize).clamp(1, members.max(1))
}

/// Groups the pixel's hits into clusters and shades each at [`shading_points`] of its members:
/// first the member whose camera sample lies closest to the members' mean film position (the
/// first such member on a tie), then repeatedly the member farthest on the film from those
/// shaded (the first on a tie; the second is the member farthest from the first), each taking
/// its own value; every other member takes the value of the shaded member nearest it on the
/// film (the earliest shaded on a tie) — or more finely, as `refine` asks for the first
/// point and the cluster's extent. Choices are made on the film, not on the rays' world
/// directions, so that they are the same for the scene rotated, scaled or moved (`penumbra
/// stability`): near-ties between world-space dot products fell either way with rounding and
/// picked another shading point.
///
/// With `difference` and `refine`'s `compare > 0`, each further shaded member is compared
/// with the first: the largest `difference` (a fraction; infinite for values that cannot be
/// compared), through [`refine_weight`], times `compare` gives a weight `w` of each member's
/// own value: a shadow edge or a highlight crossing the pixel. `refine`'s `every` is another
/// such weight; the larger counts. With `w > 0` every member is shaded and takes `(1 − w)` of
/// its shaded neighbour's value plus `w` of its own ([`Blend`]), so that the pixel varies
/// continuously with the scene: a weight that jumped from 0 to 1 at a threshold let rounding
/// pick either value.
pub fn shade_clusters<T: Blend>(
    rays: &[RayDifferential],
    samples: &[CameraSample],
    hits: &[FirstSurface],
    refine: impl Fn(&SurfacePoint, ClusterExtent) -> Refine,
    difference: Option<fn(&T, &T) -> f32>,
    mut shade: impl FnMut(&SurfacePoint) -> Option<T>,
) -> Vec<Option<T>> {
    let (cluster, clusters) = clusters_of(rays, samples, hits);
    let mut shaded = vec![None; hits.len()];
    let mut shade_one = |i: usize| -> Option<T> { shade(hits[i].as_ref().ok()?) };
    let film = |i: usize| samples[i].p_film.as_dvec2();
    let pos = |i: usize| hits[i].as_ref().map(|h| h.si.p.as_dvec3()).unwrap_or(DVec3::ZERO);
    let dir = |i: usize| rays[i].d.as_dvec3().normalize_or_zero();
    for (k, c) in clusters.iter().enumerate() {
        let members: Vec<usize> = (0..hits.len()).filter(|&m| cluster[m] == k).collect();
        let mean = c.film_sum / members.len() as f64;
        let Some(&rep) = members
            .iter()
            .min_by(|a, b| (film(**a) - mean).length_squared().total_cmp(&(film(**b) - mean).length_squared()))
        else {
            continue;
        };
        let Ok(rep_point) = &hits[rep] else { continue };
        let extent = members.iter().map(|&m| (pos(m) - pos(rep)).length()).fold(0.0, f64::max);
        let angle = members.iter().map(|&m| dir(m).dot(dir(rep)).clamp(-1.0, 1.0).acos()).fold(0.0, f64::max);
        let how = refine(rep_point, ClusterExtent { world: extent, angle });
        let every = how.every.clamp(0.0, 1.0);
        // Every member takes its own value from `every` = 1: the first alone is shaded before.
        let target = if every >= 1.0 { 1 } else { shading_points(members.len()) };
        let mut points: Vec<(usize, Option<T>)> = Vec::with_capacity(target);
        points.push((rep, shade_one(rep)));
        // Each member's squared film distance to its nearest shaded member, and that member.
        let mut dist: Vec<f64> = members.iter().map(|&m| (film(m) - film(rep)).length_squared()).collect();
        let mut nearest = vec![0usize; members.len()];
        while points.len() < target {
            let (j, d) =
                dist.iter().enumerate().fold((0, 0.0), |(bj, bd), (j, &d)| if d > bd { (j, d) } else { (bj, bd) });
            if d <= 0.0 {
                break; // the rest lie on shaded members' film positions
            }
            let s = members[j];
            points.push((s, shade_one(s)));
            for (i, &m) in members.iter().enumerate() {
                let d = (film(m) - film(s)).length_squared();
                if d < dist[i] {
                    dist[i] = d;
                    nearest[i] = points.len() - 1;
                }
            }
        }
        let v = &points[0].1;
        let mut w = every;
        if let Some(difference) = difference.filter(|_| how.compare > 0.0 && w < 1.0) {
            let d = points[1..]
                .iter()
                .map(|(_, o)| match (v, o) {
                    (Some(a), Some(b)) => refine_weight(difference(a, b)),
                    (None, None) => 0.0,
                    _ => 1.0,
                })
                .fold(0.0, f32::max);
            w = w.max(how.compare.min(1.0) * d);
        }
        for (i, &m) in members.iter().enumerate() {
            let (s, base) = &points[nearest[i]];
            shaded[m] = if *s == m || w <= 0.0 { base.clone() } else { base.blend(&shade_one(m), w) };
        }
    }
    shaded
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weights are continuous in the differences and thresholds they replace: 1 from the
    /// old threshold (the switch's values there: each member its own), 0 below half of it, no
    /// step anywhere between. Fails for the hard switch (a step of 1 at 10 %).
    #[test]
    fn weights_are_continuous_ramps_up_to_the_old_thresholds() {
        assert_eq!(refine_weight(0.1), 1.0);
        assert_eq!(refine_weight(0.05), 0.0);
        assert_eq!(refine_weight(f32::NAN), 1.0);
        assert_eq!(Refine::ramps(0.5, 0.5), Refine::ONCE);
        assert_eq!(Refine::ramps(1.0, 1.0), Refine { every: 1.0, compare: 1.0 });
        let mut prev = 0.0f32;
        for i in 0..=4000 {
            let d = 0.3 * i as f32 / 4000.0;
            let w = refine_weight(d);
            assert!(w >= prev && w - prev <= 2e-3, "d {d}: {prev} -> {w}");
            prev = w;
        }
        // A pair of values just either side of the old 10 % threshold blends to nearly the
        // member's own value on both sides (the switch gave the shared value, then the own).
        let shared = Rgb::splat(1.0);
        let (below, above) = (Rgb::splat(0.9 + 1e-6), Rgb::splat(0.9 - 1e-6));
        let (a, b) = (
            shared.blend(&below, refine_weight(rgb_difference(shared, below))),
            shared.blend(&above, refine_weight(rgb_difference(shared, above))),
        );
        assert!((a - b).abs().max_element() < 1e-4, "{a} vs {b}");
        assert!((a - below).abs().max_element() < 1e-4, "{a} vs {below}");
    }

    /// The ends of a blend are the shared value and the member's own, bit for bit; `None` has
    /// nothing to blend.
    #[test]
    fn blends_end_exactly() {
        let (s, o) = (Some(Rgb::new(0.3, 0.1, 7.0)), Some(Rgb::new(0.2, 0.4, 1e-3)));
        assert_eq!(s.blend(&o, 0.0), s);
        assert_eq!(s.blend(&o, 1.0), o);
        assert_eq!(s.blend(&None, 0.5), None);
        assert_eq!(None.blend(&o, 0.5), o);
    }
}
