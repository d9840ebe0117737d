//! Pass 2 of `sheared-ao` for one receiver, as plain functions over the sample cache: the
//! hemisphere cells (equal projected area), the per-cell occluder depth bounds, the sheared
//! filter's spatial radius (Eq. 8) and harmonic mid depth (Eq. 9), the warp of every
//! neighbour ray to an effective ray from the receiver, its weight and the per-cell
//! normalisation (Algorithm 1 of Egan, Durand & Ramamoorthi 2011). All in f64: points of a
//! neighbourhood are subtracted at any scene scale.

use glam::{DVec2, DVec3};
use penumbra_core::geometry::Frame;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

/// One cached occlusion ray: unit direction and the distance from its shading point to the
/// first hit along it (`f64::INFINITY`: it escaped).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CachedRay {
    pub d: DVec3,
    pub t: f64,
}

/// A shading point of pass 1 with its occlusion rays.
#[derive(Clone, Debug, PartialEq)]
pub struct CachePoint {
    pub p: DVec3,
    /// Face-forwarded geometric normal (towards the camera).
    pub n: DVec3,
    /// World size of one pixel at `p` (the paper's shading diameter).
    pub footprint: f64,
    pub rays: Vec<CachedRay>,
}

/// The receiver: a cache point with its tangent frame (z = `n`), in which cells are laid.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    pub p: DVec3,
    pub frame: Frame<DVec3>,
    pub footprint: f64,
}

/// Where an unoccluded neighbour ray's target (the point its effective ray from the receiver
/// aims at) is put.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Warp {
    /// On the sphere around the receiver whose radius is the harmonic mean of the receiver's
    /// occluder depth bounds over all cells (no warp without occluders): the warp is continuous
    /// across cells. Measured bias on a plane under a disk at the centre: −0.1 % (`Cell`: −2.7 %).
    Sphere,
    /// The paper's: on the plane perpendicular to the central direction of the ray's own cell at
    /// that cell's mid depth, no warp in cells without occluders. The warp jumps at cell
    /// boundaries, which depletes unoccluded samples next to unwarped cells: too dark.
    Cell,
}

/// The filter's parameters (see the module doc of `sheared_ao` for their defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterParams {
    /// Cells per side of the projected disk (`"integer cells"`): `cells²` cells.
    pub cells: usize,
    /// Ω_v^max, the angular bandlimit of BRDF × lighting (`"float omegav"`).
    pub omega_v: f64,
    /// A cell with less total weight falls back to brute force (`"float minweight"`; W(0) = 1).
    pub min_weight: f64,
    /// Occluders farther than this do not occlude (`"float maxdistance"`).
    pub max_distance: f64,
    /// `"string warp"`: `"sphere"` (default) or `"cell"` (the paper's).
    pub warp: Warp,
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams { cells: 8, omega_v: 2.0, min_weight: 2.0, max_distance: f64::INFINITY, warp: Warp::Sphere }
    }
}

/// The cell of a local direction `w` (z ≥ 0; only x, y are read) on an `n × n` grid: the
/// inverse of Shirley–Chiu's concentric map (`penumbra_core::sampling::concentric_sample_disk`),
/// so that `cosine_sample_hemisphere` of a point in cell square `(i, j)` lands in cell `(i, j)`
/// (up to [`atan_unit`]'s 1e-5 rad), and every cell subtends projected solid angle π / n².
#[inline]
pub fn cell_of(w: DVec3, n: usize) -> usize {
    let rho = (w.x * w.x + w.y * w.y).sqrt();
    let o = if rho == 0.0 {
        DVec2::ZERO
    } else if w.x.abs() >= w.y.abs() {
        let s = if w.x < 0.0 { -1.0 } else { 1.0 };
        DVec2::new(s * rho, s * rho * atan_unit(w.y / w.x) * (1.0 / FRAC_PI_4))
    } else {
        let s = if w.y < 0.0 { -1.0 } else { 1.0 };
        DVec2::new(s * rho * atan_unit(w.x / w.y) * (1.0 / FRAC_PI_4), s * rho)
    };
    let nf = n as f64;
    let ix = (((o.x + 1.0) * 0.5 * nf) as usize).min(n - 1);
    let iy = (((o.y + 1.0) * 0.5 * nf) as usize).min(n - 1);
    iy * n + ix
}

/// atan(x) for |x| ≤ 1 (a minimax polynomial, |error| < 1e-5 rad): the cell lookup runs for
/// every neighbour ray, twice, and `f64::atan` dominated it.
#[inline]
pub fn atan_unit(x: f64) -> f64 {
    let x2 = x * x;
    x * (0.99997726 + x2 * (-0.33262347 + x2 * (0.19354346 + x2 * (-0.11643287 + x2 * (0.05265332 - x2 * 0.01172120)))))
}

/// The central direction of cell `c` in local coordinates (the concentric map of the centre
/// of its square).
pub fn cell_center(c: usize, n: usize) -> DVec3 {
    let u = DVec2::new(((c % n) as f64 + 0.5) / n as f64, ((c / n) as f64 + 0.5) / n as f64);
    let o = 2.0 * u - DVec2::ONE;
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, FRAC_PI_4 * (o.y / o.x)) } else { (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y)) };
    let d = r * DVec2::new(theta.cos(), theta.sin());
    DVec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

/// The filter kernel of `t = |x| / r` (the paper leaves it open): a Gaussian exp(−2t²)
/// (σ = r/2) truncated at t = 1.5, where it is 1.1 %.
pub fn kernel(t: f64) -> f64 {
    if t < 1.5 {
        (-2.0 * t * t).exp()
    } else {
        0.0
    }
}

/// What pass 2 decided for one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CellValue {
    /// The filtered mean visibility of the cell, in [0, 1].
    Filtered(f64),
    /// Too little weight or too close occluders: to be estimated with brute-force rays.
    Brute,
}

/// Depth bounds of one cell (loop 1 of Algorithm 1).
#[derive(Clone, Copy, Debug)]
struct Bounds {
    z_min: f64,
    z_max: f64,
    brute: bool,
    /// Eq. 8 × footprint in closed form, `z_min z_max / (Ω_v (z_max − z_min))` (∞ with one depth or
    /// no occluder).
    radius: f64,
    /// Harmonic mean of the bounds (∞ without occluder: unoccluded rays are not warped).
    mid: f64,
}

/// Scratch space for [`filter_receiver`] (one per thread).
#[derive(Default)]
pub struct Scratch {
    bounds: Vec<Bounds>,
    w: Vec<f64>,
    wv: Vec<f64>,
    centers: Vec<DVec3>,
}

/// The neighbour guard: cache point `q` may lend its rays to receiver `(p, n)` when its normal
/// is within ~26° of the receiver's and it lies near the receiver's tangent plane (slope ≤ 0.25
/// plus one footprint). Rejects other surfaces at silhouettes and points behind the receiver.
pub fn same_surface(recv: &Receiver, q: &CachePoint) -> bool {
    let n = recv.frame.z;
    let off = q.p - recv.p;
    q.n.dot(n) >= 0.9 && n.dot(off).abs() <= 0.25 * off.length() + recv.footprint
}

/// Per-cell filtered visibility at `recv` from the rays of `neighbours` (the receiver's own
/// point included; [`same_surface`] is applied here). `out` gets `cells²` values.
pub fn filter_receiver<'a>(
    recv: &Receiver,
    neighbours: impl Iterator<Item = &'a CachePoint> + Clone,
    params: &FilterParams,
    scratch: &mut Scratch,
    out: &mut Vec<CellValue>,
) {
    let nc = params.cells * params.cells;
    let n = recv.frame.z;
    let p = recv.p;
    let inf = f64::INFINITY;
    scratch.bounds.clear();
    scratch.bounds.resize(nc, Bounds { z_min: inf, z_max: 0.0, brute: false, radius: inf, mid: inf });
    if scratch.centers.len() != nc {
        scratch.centers = (0..nc).map(|c| recv.frame.from_local(cell_center(c, params.cells))).collect();
    } else {
        for (c, v) in scratch.centers.iter_mut().enumerate() {
            *v = recv.frame.from_local(cell_center(c, params.cells));
        }
    }
    let occluding = |r: &CachedRay, q: &CachePoint| -> Option<DVec3> {
        if r.t.is_finite() {
            let hit = q.p + r.t * r.d;
            ((hit - p).length() <= params.max_distance).then_some(hit)
        } else {
            None
        }
    };
    let neighbours = neighbours.filter(|q| same_surface(recv, q));
    // Loop 1: occluder depth bounds per cell, cells binned by the effective direction.
    for q in neighbours.clone() {
        for r in &q.rays {
            let Some(hit) = occluding(r, q) else { continue };
            let u = hit - p;
            let z = u.length();
            if !(u.dot(n) > 1e-9 * z) {
                continue;
            }
            let b = &mut scratch.bounds[cell_of(recv.frame.to_local(u / z), params.cells)];
            b.z_min = b.z_min.min(z);
            b.z_max = b.z_max.max(z);
        }
    }
    let contact = 2.0 * params.omega_v * recv.footprint;
    for b in scratch.bounds.iter_mut() {
        if b.z_max == 0.0 {
            continue; // no occluder: radius and mid depth stay infinite
        }
        b.mid = 2.0 / (1.0 / b.z_min + 1.0 / b.z_max);
        // Contact test Ω_v / z_min > Ω_pix = 0.5 / footprint.
        b.brute = b.z_min < contact;
        b.radius = if b.z_max > b.z_min { b.z_min * b.z_max / (params.omega_v * (b.z_max - b.z_min)) } else { inf };
    }
    // The receiver's mid depth over all cells, for `Warp::Sphere`.
    let (gmin, gmax) = scratch
        .bounds
        .iter()
        .filter(|b| b.z_max > 0.0)
        .fold((inf, 0.0f64), |(a, b), c| (a.min(c.z_min), b.max(c.z_max)));
    let gmid = if gmax > 0.0 { 2.0 / (1.0 / gmin + 1.0 / gmax) } else { inf };
    // Loop 2: warp every ray to an effective ray from p, weight it, accumulate per cell.
    scratch.w.clear();
    scratch.w.resize(nc, 0.0);
    scratch.wv.clear();
    scratch.wv.resize(nc, 0.0);
    const GRAZING: f64 = 1e-3;
    for q in neighbours {
        let o = q.p - p;
        for r in &q.rays {
            let (target, visible) = match occluding(r, q) {
                Some(hit) => (hit - p, 0.0),
                None => {
                    if params.warp == Warp::Sphere {
                        if !gmid.is_finite() {
                            (r.d, 1.0)
                        } else {
                            let od = o.dot(r.d);
                            let tau = -od + (od * od - o.length_squared() + gmid * gmid).max(0.0).sqrt();
                            (o + tau * r.d, 1.0)
                        }
                    } else {
                        let c0 = cell_of(recv.frame.to_local(r.d), params.cells);
                        let mid = scratch.bounds[c0].mid;
                        if !mid.is_finite() {
                            // No occluder in the ray's cell: no warp (target at infinity, v = d),
                            // infinite radius: weight 1 in that cell.
                            if r.d.dot(n) > GRAZING {
                                scratch.w[c0] += 1.0;
                                scratch.wv[c0] += 1.0;
                            }
                            continue;
                        }
                        {
                            let a = scratch.centers[c0];
                            let den = a.dot(r.d);
                            if !(den > GRAZING) {
                                continue;
                            }
                            let tau = (mid - a.dot(o)) / den;
                            if !(tau > 0.0) {
                                continue;
                            }
                            (o + tau * r.d, 1.0)
                        }
                    }
                }
            };
            let len = target.length();
            if !(target.dot(n) > 1e-9 * len) {
                continue;
            }
            let v = target / len;
            let vd = v.dot(r.d);
            if !(vd > GRAZING) {
                continue;
            }
            let c = cell_of(recv.frame.to_local(v), params.cells);
            let b = &scratch.bounds[c];
            if b.brute {
                continue;
            }
            // Tangent offset: the sample ray meets the plane through p perpendicular to v at p + x.
            let x = o + (-v.dot(o) / vd) * r.d;
            let w = if b.radius.is_finite() { kernel(x.length() / b.radius) } else { 1.0 };
            scratch.w[c] += w;
            scratch.wv[c] += w * visible;
        }
    }
    out.clear();
    out.extend((0..nc).map(|c| {
        if scratch.bounds[c].brute || !(scratch.w[c] >= params.min_weight) {
            CellValue::Brute
        } else {
            CellValue::Filtered((scratch.wv[c] / scratch.w[c]).clamp(0.0, 1.0))
        }
    }));
}

#[cfg(test)]
mod tests;
