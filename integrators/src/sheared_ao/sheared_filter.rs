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

/// A shading point of pass 1 with its occlusion rays, kept as the terms of its rays that every
/// receiver it lends them to would otherwise recompute ([`CachePoint::new`]; no more memory than
/// the rays themselves, 56 bytes each, when half of them escape).
#[derive(Clone, Debug, PartialEq)]
pub struct CachePoint {
    pub p: DVec3,
    /// Face-forwarded geometric normal (towards the camera).
    pub n: DVec3,
    /// World size of one pixel at `p` (the paper's shading diameter).
    pub footprint: f64,
    /// The rays that hit something, with their receiver-independent terms.
    hits: Vec<HitTerms>,
    /// The directions of the rays that escaped.
    misses: Vec<DVec3>,
}

/// What a receiver needs of an occluded cached ray, computed once per cache point: its hit
/// point and direction (world), the hit's normal `m` and the receiver-independent factor of the
/// warp's Jacobian ([`occluded_jacobian`]), `k = t² / (cos_q |m·d|)` (0 when `cos_q ≤ 0`: the
/// weight is 0).
#[derive(Clone, Copy, Debug, PartialEq)]
struct HitTerms {
    h: DVec3,
    d: DVec3,
    m: DVec3,
    k: f64,
}

impl CachePoint {
    /// The cache point of `rays` from `p` (normal `n`), with the rays' receiver-independent
    /// terms.
    pub fn new(p: DVec3, n: DVec3, footprint: f64, rays: &[CachedRay]) -> Self {
        let hits = rays
            .iter()
            .filter(|r| r.t.is_finite())
            .map(|r| {
                let cos_q = r.d.dot(n);
                let k = if cos_q > 0.0 { r.t * r.t / (cos_q * r.n_hit.dot(r.d).abs()) } else { 0.0 };
                HitTerms { h: p + r.t * r.d, d: r.d, m: r.n_hit, k }
            })
            .collect();
        let misses = rays.iter().filter(|r| !r.t.is_finite()).map(|r| r.d).collect();
        CachePoint { p, n, footprint, hits, misses }
    }
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
    Grid::new(n).cell_of(w)
}

/// The cell grid of [`cell_of`] with `n` as a float computed once: a `usize` to `f64`
/// conversion takes several instructions on x86-64, and the lookup runs twice per neighbour ray.
#[derive(Clone, Copy, Debug)]
struct Grid {
    n: usize,
    nf: f64,
    last: f64,
}

impl Grid {
    fn new(n: usize) -> Self {
        let nf = n as f64;
        Grid { n, nf, last: nf - 1.0 }
    }

    #[inline]
    fn cell_of(&self, w: DVec3) -> usize {
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
        let (nf, last) = (self.nf, self.last);
        // Clamped as floats (`max` and `min` return the number when one operand is NaN), so the
        // value is an in-range integer part and the unchecked conversion is exact; the saturating
        // `as` conversions were a fifth of the filter's instructions. (To i32, one instruction
        // on x86-64; to usize, a branch and several.)
        let index = |x: f64| -> usize {
            let x = ((x + 1.0) * 0.5 * nf).max(0.0).min(last);
            // SAFETY: `x` is finite and in [0, n − 1] with n ≤ 32 (`"integer cells"`), so its
            // integer part fits an i32 and is not negative.
            (unsafe { x.to_int_unchecked::<i32>() }) as usize
        };
        index(o.y) * self.n + index(o.x)
    }
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

/// The filter kernel of `t² = |x|² / r²` (the paper leaves it open): `(1 − t²/T²)⁴`, zero from
/// `t = T = 1.5`. It follows the Gaussian exp(−2t²) (σ = r/2, truncated at 1.5) this filter
/// used before to within 0.044 at every t, reaches 0 continuously, and needs neither a square
/// root nor an exponential.
#[inline]
pub fn kernel(t2: f64) -> f64 {
    const T2: f64 = 1.5 * 1.5;
    if t2 < T2 {
        let a = 1.0 - t2 * (1.0 / T2);
        let a2 = a * a;
        a2 * a2
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
    /// `radius²`.
    radius2: f64,
    /// Harmonic mean of the bounds (∞ without occluder: unoccluded rays are not warped).
    mid: f64,
}

/// An occluded neighbour ray whose hit lies in front of the receiver and within `maxdistance`,
/// as loop 2 needs it (loop 1 computed it once): the cell of the direction from the receiver to
/// the hit, the squared tangent offset `|x|²` of the sheared filter (the sample ray meets the
/// plane through the receiver perpendicular to that direction `v` at distance
/// `|x| = z √(1/(v·d)² − 1)`, `z` the hit's distance) and the ray's Jacobian weight.
#[derive(Clone, Copy, Debug)]
struct HitVisit {
    cell: u32,
    x2: f64,
    j: f64,
}

/// A neighbour ray that escaped, or whose hit lies beyond `maxdistance`: its direction in the
/// receiver's frame and the index of its point in [`Scratch::offsets`].
#[derive(Clone, Copy, Debug)]
struct MissVisit {
    d: DVec3,
    point: u32,
}

/// A neighbour point's offset from the receiver (local) and its squared length.
#[derive(Clone, Copy, Debug)]
struct Offset {
    o: DVec3,
    oo: f64,
}

/// Scratch space for [`filter_receiver`] (one per thread).
#[derive(Default)]
pub struct Scratch {
    bounds: Vec<Bounds>,
    w: Vec<f64>,
    wv: Vec<f64>,
    /// The cells' central directions (local).
    centers: Vec<DVec3>,
    /// What loop 1 found about the occluded neighbour rays that lend something.
    hits: Vec<HitVisit>,
    /// The unoccluded neighbour rays, warped in loop 2.
    misses: Vec<MissVisit>,
    /// Per neighbour point.
    offsets: Vec<Offset>,
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
    let (cos_p, cos_q, m_v, m_d) = (v.dot(n_p), r.d.dot(n_q), r.n_hit.dot(v), r.n_hit.dot(r.d));
    let j = cos_p / cos_q * m_v.abs() * r.t * r.t / (m_d.abs() * dist_p * dist_p);
    if j.is_finite() && cos_q > 0.0 {
        j.clamp(0.0, JACOBIAN_CAP)
    } else {
        0.0
    }
}

/// [`occluded_jacobian`] as [`filter_receiver`] computes it, from the ray's
/// receiver-independent factor `k = t² / (cos_q |m·d|)` ([`HitTerms`]) and, with `u` the
/// vector from the receiver to the hit and `z² = |u|²`: `cos_p = u_z / z`, `|m·v| = |m·u| / z`,
/// so the weight is `u_z |m·u| k / z⁴` (no square root, one division).
#[inline]
fn hit_jacobian(u_z: f64, m_u: f64, k: f64, z2: f64) -> f64 {
    let j = u_z * m_u.abs() * k / (z2 * z2);
    if j.is_finite() {
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

/// Pass 2's first loop, in the receiver's frame (z = its normal): each cell's occluder depth
/// bounds (cells binned by the direction from the receiver to the hit), whether a ray of the
/// cell escaped, the contact test, the filter's radius (Eq. 8) and the harmonic mid depth.
/// Everything about an occluded ray but its kernel weight (which needs its cell's radius, known
/// only after this loop) is computed here, once: its cell, tangent offset and Jacobian
/// ([`HitVisit`]); escaped rays are kept with their local direction for the warp of loop 2.
fn cell_depth_bounds<'a>(
    recv: &Receiver,
    neighbours: impl Iterator<Item = &'a CachePoint>,
    params: &FilterParams,
    grid: &Grid,
    scratch: &mut Scratch,
) {
    let (frame, inf) = (&recv.frame, f64::INFINITY);
    let Scratch { bounds, hits, misses, offsets, .. } = scratch;
    hits.clear();
    misses.clear();
    offsets.clear();
    for q in neighbours {
        // Points of a neighbourhood are subtracted in f64 world coordinates, then turned.
        let o = frame.to_local(q.p - recv.p);
        let point = offsets.len() as u32;
        offsets.push(Offset { o, oo: o.length_squared() });
        // (The receiver's own rays weigh exactly 1: their Jacobian is 1 up to rounding, and a
        // weight sum a rounding below `minweight` would flip the cell to brute force.)
        let weigh = params.jacobian && o != DVec3::ZERO;
        for r in &q.hits {
            let uw = r.h - recv.p;
            let u = frame.to_local(uw);
            let z2 = u.length_squared();
            let z = z2.sqrt();
            if !(z <= params.max_distance) {
                // An occluder beyond `maxdistance`: a miss.
                misses.push(MissVisit { d: frame.to_local(r.d), point });
                continue;
            }
            if !(u.z > 1e-9 * z) {
                continue; // on or behind the receiver's tangent plane: it lends nothing
            }
            let cell = grid.cell_of(u / z);
            let b = &mut bounds[cell];
            b.z_min = b.z_min.min(z);
            b.z_max = b.z_max.max(z);
            let vd = uw.dot(r.d) / z;
            if !(vd > GRAZING) {
                continue;
            }
            let j = if weigh { hit_jacobian(u.z, r.m.dot(uw), r.k, z2) } else { 1.0 };
            hits.push(HitVisit { cell: cell as u32, x2: (z2 * (1.0 / (vd * vd) - 1.0)).max(0.0), j });
        }
        misses.extend(q.misses.iter().map(|d| MissVisit { d: frame.to_local(*d), point }));
    }
    // A cell's escaped rays matter only where it also has occluders (its radius): the
    // directions of the misses are binned only when some cell has.
    if bounds.iter().any(|b| b.z_max > 0.0) {
        for m in misses.iter() {
            bounds[grid.cell_of(m.d)].miss = true;
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
        b.radius2 = b.radius * b.radius;
    }
}

/// The receiver-wide terms of [`warp_unoccluded`].
struct WarpCtx<'a> {
    params: &'a FilterParams,
    grid: Grid,
    /// The receiver's harmonic mid depth over all cells ([`Warp::Sphere`]) and its square.
    gmid: f64,
    gmid2: f64,
    bounds: &'a [Bounds],
    centers: &'a [DVec3],
}

/// Where [`warp_unoccluded`] puts an unoccluded neighbour ray.
enum Warped {
    /// [`Warp::Cell`] in a cell without occluders: its own direction, unwarped, weight 1 in
    /// this cell.
    Unwarped(usize),
    /// Its effective direction from the receiver `v` (local), the squared distance to its
    /// target and the cell of `v`.
    To(DVec3, f64, usize),
}

/// The effective direction from the receiver (local) of an unoccluded neighbour ray of local
/// direction `d` from offset `o` ([`Warped`]; `None`: it lends nothing).
#[inline]
fn warp_unoccluded(d: DVec3, off: &Offset, cx: &WarpCtx) -> Option<Warped> {
    let o = off.o;
    let target = if cx.params.warp == Warp::Sphere {
        if !cx.gmid.is_finite() {
            d
        } else {
            let od = o.dot(d);
            let tau = -od + (od * od - off.oo + cx.gmid2).max(0.0).sqrt();
            o + tau * d
        }
    } else {
        let c0 = cx.grid.cell_of(d);
        let mid = cx.bounds[c0].mid;
        if !mid.is_finite() {
            // No occluder in the ray's cell: no warp (target at infinity, v = d), infinite
            // radius: weight 1 in that cell.
            return (d.z > GRAZING).then_some(Warped::Unwarped(c0));
        }
        let a = cx.centers[c0];
        let den = a.dot(d);
        if !(den > GRAZING) {
            return None;
        }
        let tau = (mid - a.dot(o)) / den;
        if !(tau > 0.0) {
            return None;
        }
        o + tau * d
    };
    let len2 = target.length_squared();
    let len = len2.sqrt();
    if !(target.z > 1e-9 * len) {
        return None;
    }
    let v = target / len;
    Some(Warped::To(v, len2, cx.grid.cell_of(v)))
}

/// Warped rays closer to grazing than this (cosine with the sample ray) are rejected.
const GRAZING: f64 = 1e-3;

/// Per-cell filtered visibility at `recv` from the rays of `neighbours` (the receiver's own
/// point included; [`same_surface`] is applied here). `out` gets `cells²` values. Computed in
/// the receiver's frame: each neighbour's offset and each occluded ray's hit point are
/// subtracted in f64 world coordinates and turned once, each escaped ray's direction turned
/// once.
pub fn filter_receiver<'a>(
    recv: &Receiver,
    neighbours: impl Iterator<Item = &'a CachePoint> + Clone,
    params: &FilterParams,
    scratch: &mut Scratch,
    out: &mut Vec<CellValue>,
) {
    let nc = params.cells * params.cells;
    let grid = Grid::new(params.cells);
    let inf = f64::INFINITY;
    scratch.bounds.clear();
    scratch
        .bounds
        .resize(nc, Bounds { z_min: inf, z_max: 0.0, brute: false, miss: false, radius: inf, radius2: inf, mid: inf });
    if scratch.centers.len() != nc {
        scratch.centers = (0..nc).map(|c| cell_center(c, params.cells)).collect();
    }
    cell_depth_bounds(recv, neighbours.filter(|q| same_surface(recv, q)), params, &grid, scratch);
    // The receiver's mid depth over all cells, for `Warp::Sphere`.
    let (gmin, gmax) = scratch
        .bounds
        .iter()
        .filter(|b| b.z_max > 0.0)
        .fold((inf, 0.0f64), |(a, b), c| (a.min(c.z_min), b.max(c.z_max)));
    let gmid = if gmax > 0.0 { 2.0 / (1.0 / gmin + 1.0 / gmax) } else { inf };
    // Loop 2: weight every ray in its cell (occluded rays) or warp it to an effective ray from
    // p and weight it (unoccluded ones), accumulate per cell.
    scratch.w.clear();
    scratch.w.resize(nc, 0.0);
    scratch.wv.clear();
    scratch.wv.resize(nc, 0.0);
    let Scratch { bounds, w: sw, wv: swv, centers, hits, misses, offsets } = scratch;
    // The kernel's weight of a squared tangent offset in cell `b` (1 at an infinite radius).
    let weight = |b: &Bounds, x2: f64| if b.radius.is_finite() { kernel(x2 / b.radius2) } else { 1.0 };
    for h in hits.iter() {
        let c = h.cell as usize;
        let b = &bounds[c];
        if !b.brute {
            sw[c] += weight(b, h.x2) * h.j;
        }
    }
    let cx = WarpCtx { params, grid, gmid, gmid2: gmid * gmid, bounds, centers };
    for m in misses.iter() {
        match warp_unoccluded(m.d, &offsets[m.point as usize], &cx) {
            Some(Warped::Unwarped(c)) => {
                sw[c] += 1.0;
                swv[c] += 1.0;
            }
            Some(Warped::To(v, len2, c)) if !bounds[c].brute => {
                let vd = v.dot(m.d);
                if !(vd > GRAZING) {
                    continue;
                }
                let w = weight(&bounds[c], (len2 * (1.0 / (vd * vd) - 1.0)).max(0.0));
                sw[c] += w;
                swv[c] += w;
            }
            _ => {}
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
