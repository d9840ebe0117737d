//! Sphere-set approximations of the scene's occluders, for `shexp` (seed 003 §4.1): built once
//! per scene by `shexp`'s [`Integrator::prepare`](penumbra_core::integrator::Integrator::prepare).
//!
//! Every object that casts shadows gets one of:
//! - **exact**: a `sphere` shape (full, closed, uniformly scaled) is its own sphere;
//! - **fitted**: a closed mesh (after welding by position, every edge shared by exactly two
//!   triangles) gets `"integer spheres"` leaves by the variational fit of [`fit`] (or the
//!   single smallest sphere through its vertices when that sticks out less), then a
//!   [`hierarchy`] over them; fits are cached on disk by a hash of the mesh ([`cache`]);
//! - **ground plane**: the largest open planar mesh with other occluders on one side of it (the
//!   side with more of their vertices is its front) is not bounded by spheres; `shexp` cuts the
//!   environment at its horizon instead (receivers behind it take the environment through
//!   `directlighting`'s estimator);
//! - **traced** (`OpenMeshes::Trace`, the default): any other open mesh (a wall, a leaf, an open
//!   quadric or partial sphere, a disk) has no inside to bound; `shexp` traces its shadows
//!   ([`super::open`]);
//! - **shell** (`OpenMeshes::Shells`): such a mesh's surface samples bounded by spheres fitted
//!   without inner points (thick, conservative shells: they overshadow rather than vanish); a
//!   planar one does not shadow its own surface.
//!
//! Objects with `"bool occluder" false`, without a material, or without triangles get none.

pub mod cache;
pub mod canonical;
pub mod fit;
pub mod hierarchy;

use fit::{Fit, FitParams};
use glam::DVec3;
use hierarchy::Hierarchy;
use penumbra_core::interaction::SceneObject;
use penumbra_core::mesh::TriangleMesh;
use std::path::Path;
use std::time::Instant;

/// A sphere (world space, f64).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sphere {
    pub center: DVec3,
    pub radius: f64,
}

impl Sphere {
    pub fn volume(&self) -> f64 {
        4.0 / 3.0 * std::f64::consts::PI * self.radius.powi(3)
    }
    pub fn contains(&self, p: DVec3) -> bool {
        p.distance_squared(self.center) <= self.radius * self.radius
    }
}

/// Where a set came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    Exact,
    Fitted,
    /// Fitted earlier and read from the disk cache.
    Cached,
    /// An open mesh's conservative shell.
    Shell,
}

/// One object's spheres.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereSet {
    pub object: usize,
    pub leaves: Vec<Sphere>,
    pub hierarchy: Hierarchy,
    pub source: Source,
    /// `Σ_i Vol(S_i \ O)` (0 for exact spheres; the whole sphere volume for shells).
    pub outside_volume: f64,
    /// `Vol(O)` (0 for shells).
    pub volume: f64,
    pub seconds: f64,
    pub triangles: usize,
    /// A closed convex solid, or a planar open mesh, never shadows its own surface: `shexp`
    /// skips the set there. (A planar shell's centres lie in its surface's plane, where only
    /// rounding would decide whether a sphere shadows the surface.)
    pub convex: bool,
}

/// The plane `shexp` cuts the environment with: directions with `normal · ω < 0` are blocked
/// for every point above it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundPlane {
    pub object: usize,
    pub point: DVec3,
    pub normal: DVec3,
    /// Some other occluder's vertex lies behind the plane (its receivers there see the
    /// environment from the other side).
    pub behind: bool,
}

impl GroundPlane {
    /// Whether `p` lies behind the plane by more than `tol` (a length).
    pub fn is_behind(&self, p: DVec3, tol: f64) -> bool {
        (p - self.point).dot(self.normal) < -tol
    }
}

/// How open meshes other than the ground plane cast shadows (`"string openmeshes"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OpenMeshes {
    /// Exactly, by rays ([`super::open`]).
    #[default]
    Trace,
    /// Through conservative sphere shells.
    Shells,
}

/// Everything built for a scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereSets {
    /// The leaves asked for per fitted object (`"integer spheres"`).
    pub spheres: u32,
    pub sets: Vec<SphereSet>,
    pub ground: Option<GroundPlane>,
    /// How open meshes were taken.
    pub open: OpenMeshes,
    /// Open meshes whose shadows are traced (`OpenMeshes::Trace`), ascending.
    pub traced: Vec<usize>,
    /// Objects given nothing, with the reason (for `penumbra info`).
    pub skipped: Vec<(usize, &'static str)>,
    /// Open meshes approximated by shells (the integrator warns about them).
    pub cache_hits: usize,
    pub cache_misses: usize,
    /// The first cache write error, if any (the render goes on).
    pub cache_error: Option<String>,
}

impl SphereSets {
    /// One line per object for `penumbra info`: where its spheres came from, how many, how
    /// much they stick out, how long they took.
    pub fn describe(&self, objects: &[SceneObject]) -> Vec<String> {
        let mut o = Vec::new();
        for s in &self.sets {
            let Some(obj) = objects.get(s.object) else { continue };
            let rel = if s.volume > 0.0 {
                format!(" ({:.1} % of its volume)", 100.0 * s.outside_volume / s.volume)
            } else {
                String::new()
            };
            o.push(format!(
                "object {} ({} at {}:{}): {:?}, {} spheres, {} triangles, outside volume {:.4}{rel}, {:.3} s",
                s.object,
                obj.kind,
                obj.loc.file,
                obj.loc.line,
                s.source,
                s.leaves.len(),
                s.triangles,
                s.outside_volume,
                s.seconds
            ));
        }
        if let Some(g) = &self.ground {
            o.push(format!("object {} (ground plane): cuts the environment below normal {:.3}", g.object, g.normal));
        }
        for &i in &self.traced {
            let Some(obj) = objects.get(i) else { continue };
            o.push(format!("object {i} ({} at {}:{}): open, its shadows traced", obj.kind, obj.loc.file, obj.loc.line));
        }
        for (i, why) in &self.skipped {
            o.push(format!("object {i}: no spheres ({why})"));
        }
        o
    }

    pub fn leaf_count(&self) -> usize {
        self.sets.iter().map(|s| s.leaves.len()).sum()
    }

    /// One line for the build report.
    pub fn summary(&self) -> String {
        let count = |src: Source| self.sets.iter().filter(|s| s.source == src).count();
        let fitted: Vec<&SphereSet> =
            self.sets.iter().filter(|s| matches!(s.source, Source::Fitted | Source::Cached)).collect();
        let (out, vol): (f64, f64) = fitted.iter().fold((0.0, 0.0), |a, s| (a.0 + s.outside_volume, a.1 + s.volume));
        let mut s = format!(
            "{} leaf spheres: {} exact, {} fitted ({} from cache), {} shells; {} open meshes traced",
            self.leaf_count(),
            count(Source::Exact),
            count(Source::Fitted) + count(Source::Cached),
            count(Source::Cached),
            count(Source::Shell),
            self.traced.len()
        );
        if vol > 0.0 {
            s += &format!("; fitted outside volume {:.1} % of their volume", 100.0 * out / vol);
        }
        if self.ground.is_some() {
            s += "; ground plane cuts the environment";
        }
        if let Some(e) = &self.cache_error {
            s += &format!("; cache not written ({e})");
        }
        s
    }
}

/// `Some(sphere)` when every vertex of a closed mesh lies at the same distance (relative
/// `1e-5`) from its bounding-box centre: a tessellated `sphere`, whose exact sphere it is.
pub fn exact_sphere(mesh: &TriangleMesh) -> Option<Sphere> {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &mesh.positions {
        lo = lo.min(p.as_dvec3());
        hi = hi.max(p.as_dvec3());
    }
    let c = (lo + hi) * 0.5;
    let d: Vec<f64> = mesh.positions.iter().map(|p| p.as_dvec3().distance(c)).collect();
    let r = d.iter().sum::<f64>() / d.len().max(1) as f64;
    (r > 0.0 && r.is_finite() && d.iter().all(|x| (x - r).abs() <= 1e-5 * r)).then_some(Sphere { center: c, radius: r })
}

/// Whether `mesh`, welded by position, has every edge shared by exactly two triangles.
pub fn is_closed(mesh: &TriangleMesh) -> bool {
    let adj = mesh.build_adjacency();
    !adj.edges.is_empty() && adj.edges.iter().all(|e| e.count == 2)
}

/// `Some((point, unit normal))` when every vertex lies within `1e-5` of the extent from one plane.
fn plane_of(mesh: &TriangleMesh) -> Option<(DVec3, DVec3)> {
    let (mut best, mut n) = (0.0, DVec3::ZERO);
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.vertices(t).map(|p| p.as_dvec3());
        let x = (b - a).cross(c - a);
        if x.length() > best {
            (best, n) = (x.length(), x / x.length());
        }
    }
    let p0 = mesh.positions.first()?.as_dvec3();
    let ext = mesh.positions.iter().map(|p| p.as_dvec3().distance(p0)).fold(0.0, f64::max);
    (best > 0.0 && mesh.positions.iter().all(|p| (p.as_dvec3() - p0).dot(n).abs() <= 1e-5 * ext)).then_some((p0, n))
}

/// The smallest sphere through a mesh's vertices (Nelder–Mead on the centre from the
/// bounding-box centre), as a one-sphere fit.
fn single_sphere(mesh: &TriangleMesh, volume: f64, params: &FitParams) -> Fit {
    let pts: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
    let reach = |c: DVec3| pts.iter().map(|p| p.distance_squared(c)).fold(0.0, f64::max).sqrt();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &pts {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let c0 = (lo + hi) * 0.5;
    let (c, _) = fit::nelder_mead(&mut |c| reach(c), c0, 0.1 * reach(c0).max(f64::MIN_POSITIVE), 300);
    let c = if reach(c) <= reach(c0) { c } else { c0 };
    let mut spheres = vec![Sphere { center: c, radius: reach(c) * (1.0 + 1e-6) }];
    fit::cover(&mut spheres, &fit::surface_samples(mesh, params.surface_points as usize));
    let (inner, cell) = fit::inner_grid(mesh, params.inner_points as usize, volume);
    let s = spheres[0];
    let inside = inner.iter().filter(|p| s.contains(**p)).count();
    Fit {
        spheres,
        outside_volume: (s.volume() - inside as f64 * cell).max(0.0),
        volume,
        inner_points: inner.len(),
        surface_points: 0,
    }
}

/// A mesh in its [canonical frame](canonical), its coordinates snapped to a grid of
/// [`Canonical::step`]: what a closed mesh is fitted (and cached) as.
pub struct Canonical {
    pub frame: canonical::Frame,
    pub local: TriangleMesh,
    world: Vec<DVec3>,
}

/// The coarsest grid step (in units of the mesh's extent) canonical coordinates are snapped to.
const SNAP: f64 = 1.0 / 256.0;

impl Canonical {
    /// The canonical frame of `mesh` and its vertices in it, snapped to multiples of
    /// [`Self::step`]. A scaled or turned copy of a mesh has the same canonical coordinates up
    /// to rounding (about 1e-7 of its extent); the variational fit is an optimisation whose
    /// outcome such differences could change (Nelder–Mead steps, ties), so the coordinates are
    /// snapped first: only a coordinate within rounding of a grid line can then differ (about
    /// 2e-7 / step of them), and the copies get the same fit.
    pub fn of(mesh: &TriangleMesh) -> Canonical {
        let world: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let frame = canonical::Frame::of(&world);
        let raw: Vec<DVec3> = world.iter().map(|p| frame.to_local(*p)).collect();
        let step = Self::step(&raw, &mesh.indices);
        let local = TriangleMesh {
            positions: raw.iter().map(|p| ((*p / step).round() * step).as_vec3()).collect(),
            indices: mesh.indices.clone(),
            ..Default::default()
        };
        Canonical { frame, local, world }
    }

    /// [`SNAP`], or a power of two under an eighth of the shortest edge for a finer mesh (the
    /// snapped mesh keeps its shape).
    fn step(local: &[DVec3], indices: &[[u32; 3]]) -> f64 {
        let at = |i: u32| local.get(i as usize).copied().unwrap_or(DVec3::ZERO);
        let shortest = indices
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| at(a).distance(at(b)))
            .filter(|l| *l > 0.0)
            .fold(f64::INFINITY, f64::min);
        if shortest.is_finite() {
            SNAP.min(2f64.powi((shortest / 8.0).log2().floor().max(-40.0) as i32))
        } else {
            SNAP
        }
    }

    /// A fit of [`Self::local`] mapped to world space, its leaves grown to bound every
    /// world-space vertex.
    pub fn to_world(&self, mut f: Fit) -> Fit {
        f.spheres.iter_mut().for_each(|s| *s = self.frame.sphere_to_world(*s));
        fit::cover(&mut f.spheres, &self.world);
        let cube = self.frame.scale.powi(3);
        f.outside_volume *= cube;
        f.volume *= cube;
        f
    }
}

/// A closed mesh's leaves: the variational fit, or one sphere when that sticks out less.
/// Fitted in the mesh's [canonical frame](Canonical) and mapped back, so that a uniformly
/// scaled or turned mesh gets the same spheres, scaled and turned, up to rounding; the leaves
/// then bound every world-space vertex.
pub fn fit_closed(mesh: &TriangleMesh, params: &FitParams) -> Fit {
    let c = Canonical::of(mesh);
    let f = fit_closed_local(&c.local, params);
    c.to_world(f)
}

fn fit_closed_local(mesh: &TriangleMesh, params: &FitParams) -> Fit {
    let volume = fit::mesh_volume(mesh);
    let one = single_sphere(mesh, volume, params);
    if params.spheres <= 1 {
        return one;
    }
    let many = fit::fit(mesh, params);
    if one.outside_volume <= many.outside_volume {
        one
    } else {
        many
    }
}

/// Builds the sphere sets of a scene (see the module doc). `cache_dir` `None`: no cache.
pub fn build_for_scene(
    meshes: &[TriangleMesh],
    objects: &[SceneObject],
    params: &FitParams,
    open_meshes: OpenMeshes,
    cache_dir: Option<&Path>,
) -> SphereSets {
    let mut out = SphereSets { spheres: params.spheres, open: open_meshes, ..Default::default() };
    let mut open: Vec<(usize, Option<(DVec3, DVec3)>)> = Vec::new();
    for (i, (mesh, obj)) in meshes.iter().zip(objects).enumerate() {
        if !obj.occluder {
            out.skipped.push((i, "\"occluder\" false"));
            continue;
        }
        if obj.material.is_none() && obj.area_light.is_none() {
            out.skipped.push((i, "no material"));
            continue;
        }
        if mesh.triangle_count() == 0 {
            out.skipped.push((i, "no triangles"));
            continue;
        }
        let t0 = Instant::now();
        let closed = is_closed(mesh);
        if closed && obj.kind == "sphere" {
            if let Some(s) = exact_sphere(mesh) {
                out.sets.push(SphereSet {
                    object: i,
                    leaves: vec![s],
                    hierarchy: hierarchy::build(&[s]),
                    source: Source::Exact,
                    outside_volume: 0.0,
                    volume: s.volume(),
                    seconds: t0.elapsed().as_secs_f64(),
                    triangles: mesh.triangle_count(),
                    convex: true,
                });
                continue;
            }
        }
        if !closed {
            open.push((i, plane_of(mesh)));
            continue;
        }
        // Cached in the canonical frame: a moved, turned or scaled copy finds the same entry.
        let canonical = Canonical::of(mesh);
        let key = cache::key(&canonical.local, params);
        let (local_fit, source) = match cache_dir.and_then(|d| cache::load(d, key)) {
            Some(f) => {
                out.cache_hits += 1;
                (f, Source::Cached)
            }
            None => {
                out.cache_misses += 1;
                let f = fit_closed_local(&canonical.local, params);
                if let Some(d) = cache_dir {
                    if let Err(e) = cache::store(d, key, &f) {
                        out.cache_error.get_or_insert_with(|| format!("{}: {e}", d.display()));
                    }
                }
                (f, Source::Fitted)
            }
        };
        let fit = canonical.to_world(local_fit);
        out.sets.push(SphereSet {
            object: i,
            hierarchy: hierarchy::build(&fit.spheres),
            leaves: fit.spheres,
            source,
            outside_volume: fit.outside_volume,
            volume: fit.volume,
            seconds: t0.elapsed().as_secs_f64(),
            triangles: mesh.triangle_count(),
            convex: mesh.is_closed_convex(1e-5),
        });
    }
    // The ground plane: planar, with other occluders' vertices off its plane (its front is the
    // side with more of them); one with nothing behind it before one with something, then the
    // largest.
    let others = |skip: usize| {
        meshes
            .iter()
            .enumerate()
            .filter(move |(j, _)| *j != skip && objects[*j].occluder && meshes[*j].triangle_count() > 0)
    };
    let mut ground: Option<((bool, f64), GroundPlane)> = None;
    for &(i, plane) in &open {
        let Some((p0, n)) = plane else { continue };
        let ext = meshes[i].positions.iter().map(|p| p.as_dvec3().distance(p0)).fold(0.0, f64::max);
        let tol = 1e-5 * ext;
        let (mut front, mut back) = (0usize, 0usize);
        for (_, m) in others(i) {
            for p in &m.positions {
                let d = (p.as_dvec3() - p0).dot(n);
                if d > tol {
                    front += 1;
                } else if d < -tol {
                    back += 1;
                }
            }
        }
        if front == 0 && back == 0 {
            continue; // nothing to cut for
        }
        let (normal, behind) = if front >= back { (n, back > 0) } else { (-n, front > 0) };
        let key = (!behind, meshes[i].total_area());
        if ground.as_ref().map(|g| key > g.0).unwrap_or(true) {
            ground = Some((key, GroundPlane { object: i, point: p0, normal, behind }));
        }
    }
    out.ground = ground.map(|g| g.1);
    for (i, plane) in open {
        if out.ground.map(|g| g.object) == Some(i) {
            continue;
        }
        if plane.is_some() && others(i).next().is_none() {
            // A plane never shadows itself, and there is nothing else to shadow.
            out.skipped.push((i, "planar, nothing else to shadow"));
            continue;
        }
        if open_meshes == OpenMeshes::Trace {
            out.traced.push(i);
            continue;
        }
        let t0 = Instant::now();
        let mesh = &meshes[i];
        let surface = fit::surface_samples(mesh, params.surface_points as usize);
        // In the canonical frame, so that the ties below are scale-free.
        let frame = canonical::Frame::of(&surface);
        let local: Vec<DVec3> = surface.iter().map(|p| frame.to_local(*p)).collect();
        let spheres: Vec<Sphere> =
            shell(&local, params.spheres.max(1) as usize).into_iter().map(|s| frame.sphere_to_world(s)).collect();
        let outside_volume = spheres.iter().map(Sphere::volume).sum();
        out.sets.push(SphereSet {
            object: i,
            hierarchy: hierarchy::build(&spheres),
            leaves: spheres,
            source: Source::Shell,
            outside_volume,
            volume: 0.0,
            seconds: t0.elapsed().as_secs_f64(),
            triangles: mesh.triangle_count(),
            convex: plane.is_some(),
        });
    }
    out.sets.sort_by_key(|s| s.object);
    out
}

/// `k` spheres bounding surface samples (given in units of their extent): Lloyd (k-means)
/// clusters seeded by farthest points, each bounded by its smallest enclosing sphere about its
/// centroid. Distances within [`canonical::TIE`] tie, and ties go to the lowest index.
fn shell(points: &[DVec3], k: usize) -> Vec<Sphere> {
    use canonical::{argmax_tol, argmin_tol, TIE};
    if points.is_empty() {
        return Vec::new();
    }
    let k = k.min(points.len());
    let mut seeds = vec![points[0]];
    let mut gap: Vec<f64> = points.iter().map(|p| p.distance(points[0])).collect();
    while seeds.len() < k {
        let Some(i) = argmax_tol(gap.iter().copied(), TIE) else { break };
        seeds.push(points[i]);
        for (g, p) in gap.iter_mut().zip(points) {
            *g = g.min(p.distance(points[i]));
        }
    }
    let mut groups = vec![Vec::new(); k];
    for _ in 0..10 {
        groups = vec![Vec::new(); k];
        for p in points {
            let g = argmin_tol(seeds.iter().map(|s| s.distance(*p)), TIE);
            groups[g.unwrap_or(0)].push(*p);
        }
        for (s, g) in seeds.iter_mut().zip(&groups) {
            if !g.is_empty() {
                *s = g.iter().sum::<DVec3>() / g.len() as f64;
            }
        }
    }
    let mut spheres: Vec<Sphere> = seeds
        .iter()
        .zip(&groups)
        .filter(|(_, g)| !g.is_empty())
        .map(|(c, g)| Sphere {
            center: *c,
            radius: g.iter().map(|p| p.distance(*c)).fold(0.0, f64::max).max(f64::MIN_POSITIVE) * (1.0 + 1e-6),
        })
        .collect();
    fit::cover(&mut spheres, points);
    spheres
}

#[cfg(test)]
mod tests;
