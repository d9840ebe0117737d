//! The variational sphere-set fit of Wang et al. 2006 as seed 003 §4.1 restates it: a closed
//! solid is discretised into inner points (a regular grid, inside by parity along grid lines)
//! and surface points (every vertex plus area-stratified samples); `k` spheres are iterated
//! through *assignment* (every point to the sphere whose outside volume grows least, estimated
//! as the point's distance beyond the sphere's clearance), *fit* (each centre moved by
//! Nelder–Mead — Powell's role in the thesis — to minimise its outside volume with the radius
//! bounding its points) and *teleportation* (the sphere overlapping others most is moved to
//! split the one sticking out most; kept only when the total outside volume drops).
//!
//! Outside volume `Vol(S \ O) = Vol(S) − Vol(S ∩ O)`, with `Vol(S ∩ O)` counted on the inner
//! grid (cell volume × inner points inside `S`, those within a quarter cell of its surface
//! counted in part). Deterministic: no random numbers, so the
//! same mesh always gives the same set (and the cache key is the mesh).

use super::canonical::{argmax_tol, argmin_tol, TIE};
use super::Sphere;
use glam::DVec3;
use penumbra_core::mesh::TriangleMesh;
use std::f64::consts::PI;

/// How finely a solid is discretised and how long it is optimised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FitParams {
    /// Leaf spheres per object.
    pub spheres: u32,
    /// Target number of inner (grid) points.
    pub inner_points: u32,
    /// Area-stratified surface samples (besides the vertices).
    pub surface_points: u32,
    /// Assignment/fit iterations per round.
    pub iterations: u32,
    /// Teleportation attempts.
    pub teleports: u32,
}

impl Default for FitParams {
    /// The digest's defaults for the tool (8000 inner, 4000 surface points), 32 leaves (seed
    /// 003 digest §12), 8 iterations, 8 teleportations.
    fn default() -> Self {
        FitParams { spheres: 32, inner_points: 8000, surface_points: 4000, iterations: 8, teleports: 8 }
    }
}

/// A fitted set and what it cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    pub spheres: Vec<Sphere>,
    /// `Σ_i Vol(S_i \ O)` (grid estimate).
    pub outside_volume: f64,
    /// `Vol(O)` (divergence theorem, exact for the mesh).
    pub volume: f64,
    pub inner_points: usize,
    pub surface_points: usize,
}

/// The volume enclosed by a closed mesh (absolute value of the signed divergence sum).
pub fn mesh_volume(mesh: &TriangleMesh) -> f64 {
    let mut v = 0.0;
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.vertices(t).map(|p| p.as_dvec3());
        v += a.dot(b.cross(c));
    }
    (v / 6.0).abs()
}

/// The R2 low-discrepancy sequence (Roberts 2018): deterministic, even 2-D samples.
fn r2(i: usize) -> (f64, f64) {
    const G: f64 = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / G, 1.0 / (G * G));
    ((0.5 + a1 * i as f64).fract(), (0.5 + a2 * i as f64).fract())
}

/// Every distinct vertex, then about `count` samples spread over the triangles by area. A
/// triangle gets `⌊count · area / total + d_t⌋` samples, `d_t` a fixed dither in [0, 1) per
/// triangle (golden-ratio sequence): unlike a carried remainder, equal triangles (tessellated
/// quadrics) do not sum to exact integers that rounding decides, and one triangle's count
/// does not depend on the others' rounding.
pub fn surface_samples(mesh: &TriangleMesh, count: usize) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for p in &mesh.positions {
        if seen.insert([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]) {
            out.push(p.as_dvec3());
        }
    }
    let area = |t: usize| {
        let [a, b, c] = mesh.vertices(t).map(|p| p.as_dvec3());
        0.5 * (b - a).cross(c - a).length()
    };
    let total: f64 = (0..mesh.triangle_count()).map(area).sum();
    if !(total > 0.0) || count == 0 {
        return out;
    }
    const PHI: f64 = 0.618_033_988_749_894_8;
    let mut seq = 0usize;
    for t in 0..mesh.triangle_count() {
        let n = (area(t) / total * count as f64 + (0.5 + PHI * t as f64).fract()).floor() as usize;
        let [a, b, c] = mesh.vertices(t).map(|p| p.as_dvec3());
        for _ in 0..n {
            let (u, v) = r2(seq);
            seq += 1;
            let su = u.sqrt();
            out.push(a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v));
        }
    }
    out
}

/// Inner points: centres of a regular grid of about `target` cells inside the closed mesh
/// (parity of crossings along x-lines through the cell centres, offset by irrational fractions
/// of a cell so that lines miss vertices and edges), and the cell volume.
pub fn inner_grid(mesh: &TriangleMesh, target: usize, volume: f64) -> (Vec<DVec3>, f64) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &mesh.positions {
        lo = lo.min(p.as_dvec3());
        hi = hi.max(p.as_dvec3());
    }
    if !(volume > 0.0) || target == 0 || !lo.is_finite() || !hi.is_finite() {
        return (Vec::new(), 0.0);
    }
    let ext = hi - lo;
    let mut h = (volume / target as f64).cbrt();
    // At most 256 cells per axis (a very thin or very elongated solid).
    h = h.max(ext.max_element() / 256.0);
    let dims = (ext / h).ceil().max(DVec3::ONE);
    let (ny, nz) = (dims.y as usize, dims.z as usize);
    let nx = dims.x as usize;
    // Cell centres, nudged off the symmetric positions that meshes like to have vertices on.
    let origin = lo + (ext - dims * h) * 0.5;
    let off = DVec3::new(0.5 + 0.013_7, 0.5 + 0.029_1, 0.5 - 0.041_9);
    let coord = |i: usize, axis: usize| origin[axis] + (i as f64 + off[axis]) * h;
    let mut crossings: Vec<Vec<f64>> = vec![Vec::new(); ny * nz];
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.vertices(t).map(|p| p.as_dvec3());
        let (ymin, ymax) = (a.y.min(b.y).min(c.y), a.y.max(b.y).max(c.y));
        let (zmin, zmax) = (a.z.min(b.z).min(c.z), a.z.max(b.z).max(c.z));
        let j0 = (((ymin - origin.y) / h - off.y).ceil().max(0.0)) as usize;
        let j1 = (((ymax - origin.y) / h - off.y).floor()).min(ny as f64 - 1.0);
        let k0 = (((zmin - origin.z) / h - off.z).ceil().max(0.0)) as usize;
        let k1 = (((zmax - origin.z) / h - off.z).floor()).min(nz as f64 - 1.0);
        if j1 < 0.0 || k1 < 0.0 {
            continue;
        }
        let area = (b.y - a.y) * (c.z - a.z) - (c.y - a.y) * (b.z - a.z);
        if area == 0.0 {
            continue;
        }
        for j in j0..=j1 as usize {
            let y = coord(j, 1);
            for k in k0..=k1 as usize {
                let z = coord(k, 2);
                // Barycentrics of (y, z) in the triangle's yz projection.
                let w0 = ((b.y - y) * (c.z - z) - (c.y - y) * (b.z - z)) / area;
                let w1 = ((c.y - y) * (a.z - z) - (a.y - y) * (c.z - z)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
                    crossings[j + ny * k].push(w0 * a.x + w1 * b.x + w2 * c.x);
                }
            }
        }
    }
    let mut pts = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            let xs = &mut crossings[j + ny * k];
            if xs.len() < 2 {
                continue;
            }
            xs.sort_by(f64::total_cmp);
            let (y, z) = (coord(j, 1), coord(k, 2));
            for i in 0..nx {
                let x = coord(i, 0);
                if xs.partition_point(|&v| v < x) % 2 == 1 {
                    pts.push(DVec3::new(x, y, z));
                }
            }
        }
    }
    (pts, h * h * h)
}

/// Nelder–Mead in 3-D from `x0` with initial step `step`, at most `evals` evaluations.
pub fn nelder_mead(f: &mut dyn FnMut(DVec3) -> f64, x0: DVec3, step: f64, evals: usize) -> (DVec3, f64) {
    let mut s = [x0, x0 + DVec3::X * step, x0 + DVec3::Y * step, x0 + DVec3::Z * step];
    let mut v = s.map(&mut *f);
    let mut used = 4;
    while used < evals {
        let mut idx = [0usize, 1, 2, 3];
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        s = idx.map(|i| s[i]);
        v = idx.map(|i| v[i]);
        let size = (1..4).map(|i| (s[i] - s[0]).length()).fold(0.0, f64::max);
        if size <= step * 1e-4 {
            break;
        }
        let c = (s[0] + s[1] + s[2]) / 3.0;
        let xr = c + (c - s[3]);
        let fr = f(xr);
        used += 1;
        if fr < v[0] {
            let xe = c + (c - s[3]) * 2.0;
            let fe = f(xe);
            used += 1;
            if fe < fr {
                (s[3], v[3]) = (xe, fe);
            } else {
                (s[3], v[3]) = (xr, fr);
            }
        } else if fr < v[2] {
            (s[3], v[3]) = (xr, fr);
        } else {
            let xc = c + (s[3] - c) * 0.5;
            let fc = f(xc);
            used += 1;
            if fc < v[3] {
                (s[3], v[3]) = (xc, fc);
            } else {
                for i in 1..4 {
                    s[i] = s[0] + (s[i] - s[0]) * 0.5;
                    v[i] = f(s[i]);
                }
                used += 3;
            }
        }
    }
    let best = (0..4).min_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap_or(0);
    (s[best], v[best])
}

struct Problem<'a> {
    /// Inner points then surface points.
    points: &'a [DVec3],
    inner: usize,
    surface: &'a [DVec3],
    /// `surface` sorted by x (for [`Problem::clearance`]).
    surface_by_x: Vec<DVec3>,
    cell: f64,
}

impl Problem<'_> {
    fn inner_points(&self) -> &[DVec3] {
        &self.points[..self.inner]
    }

    /// The inner points within `reach` of `x`, and perhaps a few more: they are sorted by x
    /// ([`fit`]), so this is one contiguous run of them in their order (a sum over it equals
    /// the sum over all, the others adding nothing).
    fn inner_near_x(&self, x: f64, reach: f64) -> &[DVec3] {
        let pts = self.inner_points();
        if !(reach.is_finite() && x.is_finite()) {
            return pts;
        }
        // A margin far above the rounding of the distance test.
        let reach = reach * (1.0 + 1e-9) + 1e-300;
        let lo = pts.partition_point(|p| p.x < x - reach);
        let hi = pts.partition_point(|p| p.x <= x + reach);
        &pts[lo..hi.max(lo)]
    }

    /// Distance from `c` to the nearest surface sample (the clearance of a centre): a scan
    /// outwards from `c.x` over the samples sorted by x, stopping where x alone is farther
    /// than the nearest found (the same minimum as over all of them).
    fn clearance(&self, c: DVec3) -> f64 {
        let s = &self.surface_by_x;
        let mid = s.partition_point(|p| p.x < c.x);
        let mut best = f64::INFINITY;
        for p in &s[mid..] {
            let dx = p.x - c.x;
            if dx * dx > best {
                break;
            }
            best = best.min(p.distance_squared(c));
        }
        for p in s[..mid].iter().rev() {
            let dx = c.x - p.x;
            if dx * dx > best {
                break;
            }
            best = best.min(p.distance_squared(c));
        }
        best.sqrt()
    }

    /// `Vol(S \ O)` for a sphere (grid estimate, never below 0). An inner point counts fully
    /// when at least a quarter cell inside the sphere, not at all a quarter cell outside, and
    /// linearly in between: the estimate is continuous in the centre and radius, so that
    /// rounding (a scaled or turned mesh) moves it by rounding instead of by a whole cell,
    /// which would send Nelder–Mead elsewhere.
    fn outside(&self, c: DVec3, r: f64) -> f64 {
        let band = 0.25 * self.cell.cbrt();
        let (lo2, hi2) = ((r - band).max(0.0).powi(2), (r + band).powi(2));
        let mut n = 0.0;
        for p in self.inner_near_x(c.x, r + band) {
            let d2 = p.distance_squared(c);
            if d2 <= lo2 {
                n += 1.0;
            } else if d2 < hi2 {
                n += (r + band - d2.sqrt()) / (2.0 * band);
            }
        }
        (4.0 / 3.0 * PI * r * r * r - n * self.cell).max(0.0)
    }

    /// Assigns every point to the sphere whose outside volume grows least (its distance
    /// beyond the centre's clearance), returning per-sphere point lists.
    fn assign(&self, centres: &[DVec3]) -> Vec<Vec<u32>> {
        let w: Vec<f64> = centres.iter().map(|c| self.clearance(*c)).collect();
        let mut sets = vec![Vec::new(); centres.len()];
        for (pi, p) in self.points.iter().enumerate() {
            let best = argmin_tol(centres.iter().zip(&w).map(|(c, w)| p.distance(*c) - w), TIE).unwrap_or(0);
            sets[best].push(pi as u32);
        }
        sets
    }

    fn radius(&self, c: DVec3, set: &[u32]) -> f64 {
        set.iter().map(|&i| self.points[i as usize].distance_squared(c)).fold(0.0, f64::max).sqrt()
    }

    /// One round: `iterations` of assignment and fit from `centres`; the best set seen.
    fn optimise(&self, mut centres: Vec<DVec3>, iterations: u32, scale: f64) -> (Vec<Sphere>, f64, Vec<Vec<u32>>) {
        let mut best: Option<(Vec<Sphere>, f64, Vec<Vec<u32>>)> = None;
        for _ in 0..iterations.max(1) {
            let sets = self.assign(&centres);
            let mut spheres = Vec::with_capacity(centres.len());
            let mut total = 0.0;
            for (c, set) in centres.iter_mut().zip(&sets) {
                if set.is_empty() {
                    spheres.push(Sphere { center: *c, radius: 0.0 });
                    continue;
                }
                let r0 = self.radius(*c, set);
                let mut f = |x: DVec3| self.outside(x, self.radius(x, set));
                let (x, _) = nelder_mead(&mut f, *c, (0.25 * r0).max(1e-6 * scale), 60);
                *c = x;
                let r = self.radius(x, set);
                total += self.outside(x, r);
                spheres.push(Sphere { center: x, radius: r });
            }
            let improved = best.as_ref().map(|b| total < b.1 * (1.0 - 1e-4)).unwrap_or(true);
            if improved {
                best = Some((spheres, total, sets));
            } else {
                break;
            }
        }
        best.unwrap_or_default()
    }
}

/// Greedy medial initialisation: the inner point farthest from the surface, then repeatedly
/// the one maximising its clearance times its distance to the chosen centres' balls.
fn initial_centres(problem: &Problem, k: usize) -> Vec<DVec3> {
    let cand: Vec<DVec3> = if problem.inner > 0 { problem.inner_points().to_vec() } else { problem.surface.to_vec() };
    let clear: Vec<f64> = cand.iter().map(|c| problem.clearance(*c)).collect();
    let mut chosen: Vec<usize> = Vec::new();
    let mut gap = vec![f64::INFINITY; cand.len()];
    while chosen.len() < k.min(cand.len()) {
        let score = |i: usize| if chosen.is_empty() { clear[i] } else { gap[i] * (clear[i] + 1e-12) };
        let top = (0..cand.len()).map(score).fold(0.0, f64::max);
        let Some(best) = argmax_tol((0..cand.len()).map(score), TIE * top) else { break };
        if !chosen.is_empty() && !(gap[best] > 0.0) {
            break;
        }
        chosen.push(best);
        let (c, r) = (cand[best], clear[best]);
        for (i, p) in cand.iter().enumerate() {
            gap[i] = gap[i].min((p.distance(c) - 0.5 * r).max(0.0));
        }
    }
    chosen.into_iter().map(|i| cand[i]).collect()
}

/// Volume shared with other spheres, counted on the inner grid.
fn overlaps(problem: &Problem, spheres: &[Sphere]) -> Vec<f64> {
    let mut out = vec![0.0; spheres.len()];
    let inside = |p: &DVec3, s: &Sphere| p.distance_squared(s.center) <= s.radius.powi(2);
    for p in problem.inner_points() {
        // Only points in two spheres or more count (no list built per point).
        if spheres.iter().filter(|s| inside(p, s)).nth(1).is_none() {
            continue;
        }
        for (o, s) in out.iter_mut().zip(spheres) {
            if inside(p, s) {
                *o += problem.cell;
            }
        }
    }
    out
}

/// Fits `params.spheres` spheres bounding a closed mesh. The caller checks closedness.
pub fn fit(mesh: &TriangleMesh, params: &FitParams) -> Fit {
    let volume = mesh_volume(mesh);
    let surface = surface_samples(mesh, params.surface_points as usize);
    let (mut inner, cell) = inner_grid(mesh, params.inner_points as usize, volume);
    // By x, the fitting frame's longest axis (a stable sort: each grid column keeps its order,
    // and columns lie a whole cell apart, so rounding cannot reorder them): a sphere's inner
    // points are then one contiguous run ([`Problem::inner_near_x`]).
    inner.sort_by(|a, b| a.x.total_cmp(&b.x));
    let mut points = inner.clone();
    points.extend_from_slice(&surface);
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &surface {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let scale = (hi - lo).length().max(f64::MIN_POSITIVE);
    let mut surface_by_x = surface.clone();
    surface_by_x.sort_by(|a, b| a.x.total_cmp(&b.x));
    let problem = Problem { points: &points, inner: inner.len(), surface: &surface, surface_by_x, cell };
    let k = (params.spheres.max(1) as usize).min(points.len().max(1));
    let init = initial_centres(&problem, k);
    let (mut spheres, mut total, mut sets) = problem.optimise(init, params.iterations, scale);
    let mut failures = 0;
    for _ in 0..params.teleports {
        if spheres.len() < 2 || failures >= 3 {
            break;
        }
        let ov = overlaps(&problem, &spheres);
        let out: Vec<f64> = spheres.iter().map(|s| problem.outside(s.center, s.radius)).collect();
        // Overlaps are whole cells; outside volumes tie within TIE of the largest.
        let Some(remove) = argmax_tol(ov.iter().copied(), 0.5 * cell) else { break };
        let top = out.iter().copied().fold(0.0, f64::max);
        let others = out.iter().enumerate().map(|(i, v)| if i == remove { f64::NEG_INFINITY } else { *v });
        let Some(split) = argmax_tol(others, TIE * top).filter(|&i| i != remove) else {
            break;
        };
        // The two farthest-apart points of the split sphere (two sweeps).
        let set = &sets[split];
        if set.len() < 2 {
            failures += 1;
            continue;
        }
        let far = |from: DVec3| {
            argmax_tol(set.iter().map(|&i| points[i as usize].distance(from)), TIE * scale)
                .map(|j| points[set[j] as usize])
        };
        let (Some(a), Some(b)) = (far(spheres[split].center), far(far(spheres[split].center).unwrap_or_default()))
        else {
            break;
        };
        let mut centres: Vec<DVec3> = spheres.iter().map(|s| s.center).collect();
        // Start the halves between the split centre and its extreme points.
        let c = centres[split];
        centres[split] = (a + c) * 0.5;
        centres[remove] = (b + c) * 0.5;
        let (s2, t2, sets2) = problem.optimise(centres, params.iterations, scale);
        if t2 < total * (1.0 - 1e-4) {
            (spheres, total, sets) = (s2, t2, sets2);
            failures = 0;
        } else {
            failures += 1;
        }
    }
    spheres.retain(|s| s.radius > 0.0);
    cover(&mut spheres, &surface);
    cover(&mut spheres, &surface_samples(mesh, 4 * params.surface_points as usize));
    let outside_volume = spheres.iter().map(|s| problem.outside(s.center, s.radius)).sum();
    Fit { spheres, outside_volume, volume, inner_points: inner.len(), surface_points: surface.len() }
}

/// Grows, for every point outside the union, the sphere needing the least growth so that it
/// contains the point (with a relative margin of 1e-6).
pub fn cover(spheres: &mut [Sphere], points: &[DVec3]) {
    const MARGIN: f64 = 1.0 + 1e-6;
    // Growths within TIE of the largest radius tie (lowest index wins).
    let tol = TIE * spheres.iter().map(|s| s.radius).fold(0.0, f64::max);
    for p in points {
        if spheres.iter().any(|s| p.distance(s.center) <= s.radius) {
            continue;
        }
        if let Some(i) = argmin_tol(spheres.iter().map(|s| p.distance(s.center) - s.radius), tol) {
            let s = &mut spheres[i];
            s.radius = p.distance(s.center) * MARGIN;
        }
    }
}
