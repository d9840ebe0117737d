//! Pass 2 of `sheared-ao` for one receiver, as plain functions over the sample cache: the
//! hemisphere cells (equal projected area), the per-cell occluder depth bounds, the sheared
//! filter's spatial radius (Eq. 8) and harmonic mid depth (Eq. 9), the warp of every
//! neighbour ray to an effective ray from the receiver, its weight and the per-cell
//! normalisation (Algorithm 1 of Egan, Durand & Ramamoorthi 2011). All in f64: points of a
//! neighbourhood are subtracted at any scene scale.

use glam::{DVec2, DVec3};
use penumbra_core::geometry::Frame;
use penumbra_core::sh::{basis, quadrature::gauss_legendre, ShOrder};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

/// One cached occlusion ray: unit direction and the distance from its shading point to the
/// first hit along it (`f64::INFINITY`: it escaped).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CachedRay {
    pub d: DVec3,
    pub t: f64,
    /// The geometric normal at the hit (any sign; unused for a miss).
    pub n_hit: DVec3,
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
    /// Weight occluded rays by the Jacobian of their warp ([`occluded_jacobian`], `"bool jacobian"`).
    pub jacobian: bool,
}

/// The largest importance weight [`filter_receiver`] gives a warped ray (grazing targets).
pub const JACOBIAN_CAP: f64 = 8.0;

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            cells: 8,
            omega_v: 2.0,
            min_weight: 2.0,
            max_distance: f64::INFINITY,
            warp: Warp::Sphere,
            jacobian: true,
        }
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
    concentric_hemisphere(DVec2::new(((c % n) as f64 + 0.5) / n as f64, ((c / n) as f64 + 0.5) / n as f64))
}

/// One wedge of the concentric map over one cell: the ranges of `ρ` and `t` and `o(ρ, t)`.
type Wedge = ([f64; 2], [f64; 2], fn(f64, f64) -> DVec2);

/// The SH transfer of each cell under full visibility, in the receiver's local frame (z = the
/// normal): `K_{c,i} = ∫_c max(0, z) Y_i(ω) dω`, row `c` of `cells² × order.coeffs()`. A
/// receiver's transfer is then `Σ_c V̄_c K_c` (rotated to world space), so `sh.0 = Y_0 · AO`
/// exactly and an unoccluded receiver gets the clamped cosine's `Â_l Y_lm(n)`.
///
/// The concentric map takes the square `o ∈ [−1, 1]²` to the disk with constant Jacobian π/4,
/// and projected solid angle is disk area, so `K_{c,i} = π/4 ∫_{square c} Y_i(lift(o)) do`. Each
/// square is split along the map's diagonals into its pieces in the four wedges; in a wedge the
/// radius is one coordinate `ρ` and the angle is linear in the other, so the integrand is smooth
/// but for `z = √(1 − ρ²)`, which the substitution `ρ = sin α` makes smooth too: Gauss–Legendre
/// in `(α, t)` is then exact to rounding (the midpoint rule in `u` converges like `q^−1.5`
/// at the rim: 5e-4 at 16² points per cell).
pub fn cell_transfer(cells: usize, order: ShOrder) -> Vec<f64> {
    let (nodes, weights) = gauss_legendre(12);
    let (nc, k) = (cells * cells, order.coeffs());
    let mut out = vec![0.0; nc * k];
    let mut y = vec![0.0; k];
    let grid = |i: usize| -1.0 + 2.0 * i as f64 / cells as f64;
    for (c, row) in out.chunks_exact_mut(k).enumerate() {
        let (x0, x1, y0, y1) = (grid(c % cells), grid(c % cells + 1), grid(c / cells), grid(c / cells + 1));
        // Wedges: right (o = (ρ, t)), left (−ρ, t), top (t, ρ), bottom (t, −ρ); ρ ≥ |t|.
        let wedges: [Wedge; 4] = [
            ([x0, x1], [y0, y1], |r, t| DVec2::new(r, t)),
            ([-x1, -x0], [y0, y1], |r, t| DVec2::new(-r, t)),
            ([y0, y1], [x0, x1], |r, t| DVec2::new(t, r)),
            ([-y1, -y0], [x0, x1], |r, t| DVec2::new(t, -r)),
        ];
        for (rho, t, to_o) in wedges {
            let (r0, r1) = (rho[0].max(0.0), rho[1]);
            if !(r1 > r0) {
                continue;
            }
            // The t range [max(t0, −ρ), min(t1, ρ)] bends where ρ = |t0| or |t1|.
            let mut cuts = vec![r0, r1];
            cuts.extend([t[0].abs(), t[1].abs()].into_iter().filter(|v| *v > r0 && *v < r1));
            cuts.sort_by(f64::total_cmp);
            for seg in cuts.windows(2) {
                let (a0, a1) = (seg[0].asin(), seg[1].asin());
                for (na, wa) in nodes.iter().zip(&weights) {
                    let alpha = 0.5 * (a0 + a1) + 0.5 * (a1 - a0) * na;
                    let r = alpha.sin();
                    let (ta, tb) = (t[0].max(-r), t[1].min(r));
                    if !(tb > ta) {
                        continue;
                    }
                    // π/4 · dρ dt, dρ = cos α dα.
                    let w_alpha = std::f64::consts::FRAC_PI_4 * 0.5 * (a1 - a0) * wa * alpha.cos() * 0.5 * (tb - ta);
                    for (nt, wt) in nodes.iter().zip(&weights) {
                        let o = to_o(r, 0.5 * (ta + tb) + 0.5 * (tb - ta) * nt);
                        basis::eval(order, concentric_hemisphere(0.5 * (o + DVec2::ONE)), &mut y);
                        row.iter_mut().zip(&y).for_each(|(dst, v)| *dst += w_alpha * wt * v);
                    }
                }
            }
        }
    }
    out
}

/// `cosine_sample_hemisphere` in f64: Shirley–Chiu's concentric map of `u ∈ [0, 1]²` lifted to
/// the hemisphere.
fn concentric_hemisphere(u: DVec2) -> DVec3 {
    let o = 2.0 * u - DVec2::ONE;
    if o == DVec2::ZERO {
        return DVec3::Z;
    }
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
    /// Some neighbour ray in this cell's direction escaped: the cell holds an occluder edge with
    /// open sky (depth ∞) beside it.
    miss: bool,
    /// Eq. 8 in closed form, `z_min z_max / (Ω_v (z_max − z_min))`, with `z_max = ∞` (so
    /// `z_min / Ω_v`) in a cell with a miss; ∞ with one depth and no miss, or no occluder.
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

/// The importance weight of an occluded neighbour ray warped to the receiver: the receiver's
/// cosine density at its effective direction `v` over the density the warp gives there. The
/// neighbour draws `d` with density `cos_q / π`; through the hit surface (normal `m`) a solid
/// angle dω_q from the neighbour is dω_p = dω_q · |m·v| |H−q|² / (|m·d| |H−p|²) from the receiver,
/// so the weight is `cos_p / cos_q · |m·v| |H−q|² / (|m·d| |H−p|²)` (1 for the receiver's own
/// rays), capped at [`JACOBIAN_CAP`] for grazing hits. Unoccluded rays keep weight 1: their
/// targets are not on a real surface, and directions to the sky at infinity have the same
/// density from every neighbour of a flat neighbourhood.
pub fn occluded_jacobian(r: &CachedRay, n_q: DVec3, n_p: DVec3, v: DVec3, dist_p: f64) -> f64 {
    let cos_q = r.d.dot(n_q);
    let m = r.n_hit;
    let j = v.dot(n_p) / cos_q * m.dot(v).abs() * r.t * r.t / (m.dot(r.d).abs() * dist_p * dist_p);
    if j.is_finite() && cos_q > 0.0 {
        j.clamp(0.0, JACOBIAN_CAP)
    } else {
        0.0
    }
}

/// The neighbour guard: cache point `q` may lend its rays to receiver `(p, n)` when its normal
/// is within ~26° of the receiver's and it lies near the receiver's tangent plane (slope ≤ 0.25
/// plus one footprint). Rejects other surfaces at silhouettes and points behind the receiver.
pub fn same_surface(recv: &Receiver, q: &CachePoint) -> bool {
    let n = recv.frame.z;
    let off = q.p - recv.p;
    q.n.dot(n) >= 0.9 && n.dot(off).abs() <= 0.25 * off.length() + recv.footprint
}

/// The point a cached ray hit, when it is an occluder within `max_distance` of `p`.
fn occluder_hit(r: &CachedRay, q: &CachePoint, p: DVec3, max_distance: f64) -> Option<DVec3> {
    if r.t.is_finite() {
        let hit = q.p + r.t * r.d;
        ((hit - p).length() <= max_distance).then_some(hit)
    } else {
        None
    }
}

/// Pass 2's first loop: each cell's occluder depth bounds (cells binned by the direction from
/// the receiver to the hit), whether a ray of the cell escaped, the contact test, the filter's
/// radius (Eq. 8) and the harmonic mid depth.
fn cell_depth_bounds<'a>(
    recv: &Receiver,
    neighbours: impl Iterator<Item = &'a CachePoint>,
    params: &FilterParams,
    bounds: &mut [Bounds],
) {
    let (n, p, inf) = (recv.frame.z, recv.p, f64::INFINITY);
    // Loop 1: occluder depth bounds per cell, cells binned by the effective direction.
    for q in neighbours {
        for r in &q.rays {
            let Some(hit) = occluder_hit(r, q, p, params.max_distance) else {
                bounds[cell_of(recv.frame.to_local(r.d), params.cells)].miss = true;
                continue;
            };
            let u = hit - p;
            let z = u.length();
            if !(u.dot(n) > 1e-9 * z) {
                continue;
            }
            let b = &mut bounds[cell_of(recv.frame.to_local(u / z), params.cells)];
            b.z_min = b.z_min.min(z);
            b.z_max = b.z_max.max(z);
        }
    }
    let contact = 2.0 * params.omega_v * recv.footprint;
    for b in bounds.iter_mut() {
        if b.z_max == 0.0 {
            continue; // no occluder: radius and mid depth stay infinite
        }
        b.mid = 2.0 / (1.0 / b.z_min + 1.0 / b.z_max);
        // Contact test Ω_v / z_min > Ω_pix = 0.5 / footprint.
        b.brute = b.z_min < contact;
        b.radius = if b.miss {
            b.z_min / params.omega_v
        } else if b.z_max > b.z_min {
            b.z_min * b.z_max / (params.omega_v * (b.z_max - b.z_min))
        } else {
            inf
        };
    }
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
    scratch.bounds.resize(nc, Bounds { z_min: inf, z_max: 0.0, brute: false, miss: false, radius: inf, mid: inf });
    if scratch.centers.len() != nc {
        scratch.centers = (0..nc).map(|c| recv.frame.from_local(cell_center(c, params.cells))).collect();
    } else {
        for (c, v) in scratch.centers.iter_mut().enumerate() {
            *v = recv.frame.from_local(cell_center(c, params.cells));
        }
    }
    let occluding = |r: &CachedRay, q: &CachePoint| occluder_hit(r, q, p, params.max_distance);
    let neighbours = neighbours.filter(|q| same_surface(recv, q));
    cell_depth_bounds(recv, neighbours.clone(), params, &mut scratch.bounds);
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
            let mut w = if b.radius.is_finite() { kernel(x.length() / b.radius) } else { 1.0 };
            // (The receiver's own rays weigh exactly 1: their Jacobian is 1 up to rounding, and a
            // weight sum a rounding below `minweight` would flip the cell to brute force.)
            if params.jacobian && visible == 0.0 && o != DVec3::ZERO {
                w *= occluded_jacobian(r, q.n, n, v, len);
            }
            scratch.w[c] += w;
            scratch.wv[c] += w * visible;
        }
    }
    out.clear();
    out.extend((0..nc).map(|c| {
        // A relative slack, so that weights summing to `minweight` up to rounding pass alike
        // at every scene scale.
        if scratch.bounds[c].brute || !(scratch.w[c] >= params.min_weight * (1.0 - 1e-9)) {
            CellValue::Brute
        } else {
            CellValue::Filtered((scratch.wv[c] / scratch.w[c]).clamp(0.0, 1.0))
        }
    }));
}

#[cfg(test)]
mod tests;
