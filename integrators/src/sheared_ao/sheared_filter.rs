//! Pass 2 of `sheared-ao` for one receiver, as plain functions over the sample cache: the
//! hemisphere cells (equal projected area), the per-cell occluder depth bounds, the sheared
//! filter's spatial radius (Eq. 8) and harmonic mid depth (Eq. 9), the warp of every
//! neighbour ray to an effective ray from the receiver, its weight and the per-cell
//! normalisation (Algorithm 1 of Egan, Durand & Ramamoorthi 2011). Points of a neighbourhood
//! are subtracted in f64 (at any scene scale); the rays' terms, relative to their point, are
//! turned and filtered in f32, as arrays over a receiver's neighbour rays (loops the compiler
//! vectorises, four rays per instruction with SSE2).

use glam::{DVec2, DVec3, Vec3};
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
/// receiver it lends them to would otherwise recompute ([`CachePoint::new`]; in f32, relative to
/// the point: 48 bytes per occluded ray, 12 per escaped one).
#[derive(Clone, Debug, PartialEq)]
pub struct CachePoint {
    pub p: DVec3,
    /// Face-forwarded geometric normal (towards the camera).
    pub n: DVec3,
    /// World size of one pixel at `p` (the paper's shading diameter).
    pub footprint: f64,
    /// The rays that hit something, with their receiver-independent terms.
    hits: Vec<HitTerms>,
    /// The directions of the rays that escaped (world).
    misses: Vec<Vec3>,
}

/// What a receiver needs of an occluded cached ray, computed once per cache point, in f32 and
/// relative to the point (a receiver adds the point's offset, subtracted in f64): the hit `r = t d`
/// and the direction `d` (world orientation), the hit's normal `m`, `t`, `m·r`, and the
/// receiver-independent factor of the warp's Jacobian ([`occluded_jacobian`]),
/// `k = t² / (cos_q |m·d|)` (0 when `cos_q ≤ 0`: the weight is 0).
#[derive(Clone, Copy, Debug, PartialEq)]
struct HitTerms {
    r: Vec3,
    d: Vec3,
    m: Vec3,
    t: f32,
    mr: f32,
    k: f32,
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
                HitTerms {
                    r: (r.t * r.d).as_vec3(),
                    d: r.d.as_vec3(),
                    m: r.n_hit.as_vec3(),
                    t: r.t as f32,
                    mr: (r.t * r.n_hit.dot(r.d)) as f32,
                    // Capped so that an edge-on hit stays finite in f32 (and is capped as in f64).
                    k: k.min(f32::MAX as f64) as f32,
                }
            })
            .collect();
        let misses = rays.iter().filter(|r| !r.t.is_finite()).map(|r| r.d.as_vec3()).collect();
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

/// [`Grid`] in f32 and branch-free, for the filter's loops over neighbour rays (which the
/// compiler vectorises): the cell of the local direction `(x, y, ·) / len` given `1 / len`.
/// Both wedges of the concentric map are computed from `min(|x|, |y|) / max(|x|, |y|)` and the
/// signs, so it chooses [`Grid::cell_of`]'s cell but within f32 rounding of a cell boundary.
#[derive(Clone, Copy, Debug)]
struct Grid32 {
    n: u32,
    half_n: f32,
    last: f32,
}

impl Grid32 {
    fn new(n: usize) -> Self {
        Grid32 { n: n as u32, half_n: 0.5 * n as f32, last: n as f32 - 1.0 }
    }

    #[inline(always)]
    fn cell(&self, x: f32, y: f32, inv_len: f32) -> u32 {
        let (ax, ay) = (x.abs(), y.abs());
        let big = ax >= ay;
        // Selects rather than `f32::min`/`max`, whose NaN rules cost three more instructions.
        let (lo, hi) = if big { (ay, ax) } else { (ax, ay) };
        let hi = if hi > f32::MIN_POSITIVE { hi } else { f32::MIN_POSITIVE };
        let t = atan_unit32(lo / hi) * (4.0 / std::f32::consts::PI);
        let rho = (x * x + y * y).sqrt() * inv_len;
        let ox = (rho * if big { 1.0 } else { t }).copysign(x);
        let oy = (rho * if big { t } else { 1.0 }).copysign(y);
        self.index(oy) * self.n + self.index(ox)
    }

    #[inline(always)]
    fn index(&self, o: f32) -> u32 {
        // Compared so that NaN gives 0: an in-range value.
        let v = (o + 1.0) * self.half_n;
        let v = if v > 0.0 { v } else { 0.0 };
        let v = if v < self.last { v } else { self.last };
        // SAFETY: `v` is finite and in [0, n − 1] with n ≤ 32: its integer part fits an i32.
        (unsafe { v.to_int_unchecked::<i32>() }) as u32
    }
}

/// [`atan_unit`] in f32 (the same polynomial).
#[inline(always)]
fn atan_unit32(x: f32) -> f32 {
    let x2 = x * x;
    x * (0.99997726 + x2 * (-0.33262347 + x2 * (0.19354346 + x2 * (-0.11643287 + x2 * (0.05265332 - x2 * 0.0117212)))))
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
/// root nor an exponential. Written as a select, not a branch, for the filter's weight loops
/// (the same bits as the branch form: test `select_kernel_is_the_kernel_bit_for_bit`).
#[inline(always)]
pub fn kernel(t2: f64) -> f64 {
    const T2: f64 = 1.5 * 1.5;
    let a = if t2 < T2 { 1.0 - t2 * (1.0 / T2) } else { 0.0 };
    let a2 = a * a;
    a2 * a2
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
    x2: f32,
    j: f32,
}

/// The occluded neighbour rays of a receiver as arrays (one per coordinate), local to the
/// receiver: the inputs of [`hit_terms`] (`u`: the vector from the receiver to the hit, `mu =
/// m·u`, `ud = u·d`, `k` of [`HitTerms`], negative for the receiver's own rays, which weigh 1;
/// `point`: the index of the ray's point in [`Scratch::offsets`]) and its outputs.
#[derive(Default)]
struct HitSoa {
    ux: Vec<f32>,
    uy: Vec<f32>,
    uz: Vec<f32>,
    mu: Vec<f32>,
    ud: Vec<f32>,
    k: Vec<f32>,
    point: Vec<u32>,
    cell: Vec<u32>,
    z: Vec<f32>,
    vd: Vec<f32>,
    x2: Vec<f32>,
    j: Vec<f32>,
}

/// The unoccluded neighbour rays of a receiver (and those whose hit lies beyond `maxdistance`)
/// as arrays: direction `d` and its point's offset `o` (local) with `|o|²` ([`miss_terms`]'s
/// inputs); the cell of `d`, the cell of the warped direction and the squared tangent offset
/// (negative: the ray lends nothing), its outputs.
#[derive(Default)]
struct MissSoa {
    dx: Vec<f32>,
    dy: Vec<f32>,
    dz: Vec<f32>,
    ox: Vec<f32>,
    oy: Vec<f32>,
    oz: Vec<f32>,
    oo: Vec<f32>,
    cd: Vec<u32>,
    cv: Vec<u32>,
    x2: Vec<f32>,
}

impl MissSoa {
    fn push(&mut self, d: Vec3, o: Vec3) {
        self.dx.push(d.x);
        self.dy.push(d.y);
        self.dz.push(d.z);
        self.ox.push(o.x);
        self.oy.push(o.y);
        self.oz.push(o.z);
        self.oo.push(o.length_squared());
    }
}

/// Scratch space for [`filter_receiver`] (one per thread).
#[derive(Default)]
pub struct Scratch {
    bounds: Vec<Bounds>,
    w: Vec<f64>,
    wv: Vec<f64>,
    /// Per cell: `radius²` (∞ at an infinite radius).
    r2: Vec<f64>,
    /// The cells' central directions (local).
    centers: Vec<DVec3>,
    /// What loop 1 found about the occluded neighbour rays that lend something.
    hits: Vec<HitVisit>,
    h: HitSoa,
    m: MissSoa,
    /// Per neighbour point: its offset from the receiver (local).
    offsets: Vec<Vec3>,
    /// Per cell: the occluder depth bounds as [`cell_depth_bounds`] scatters them.
    z_lo: Vec<f32>,
    z_hi: Vec<f32>,
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

/// [`occluded_jacobian`] as [`filter_receiver`] computes it (f32), from the ray's
/// receiver-independent factor `k = t² / (cos_q |m·d|)` ([`HitTerms`]) and, with `u` the
/// vector from the receiver to the hit and `z² = |u|²`: `cos_p = u_z / z`, `|m·v| = |m·u| / z`,
/// so the weight is `(u_z / z²) (|m·u| / z²) k` (no square root; each factor about `1 / z`, so
/// that `z⁴` does not overflow f32 at large scene scales).
#[inline(always)]
fn hit_jacobian(u_z: f32, m_u: f32, k: f32, z2: f32) -> f32 {
    let j = (u_z / z2) * (m_u.abs() / z2) * k;
    if j.is_finite() {
        j.clamp(0.0, JACOBIAN_CAP as f32)
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

/// Gathers the rays of `neighbours` into the receiver's arrays ([`HitSoa`], [`MissSoa`]),
/// local to the receiver: each point's offset is subtracted in f64 world coordinates and turned
/// once (then kept in f32), each ray's terms are turned in f32. The arrays are sized once and
/// filled point by point through slices of the point's length (no capacity or bounds test per
/// ray: pushing seven values per ray cost more than the arithmetic).
fn gather(recv: &Receiver, neighbours: &[&CachePoint], params: &FilterParams, s: &mut Scratch) {
    let f = &recv.frame;
    let (fx, fy, fz) = (f.x.as_vec3(), f.y.as_vec3(), f.z.as_vec3());
    let Scratch { h, m, offsets, .. } = s;
    let (nh, nm) = neighbours.iter().fold((0, 0), |(a, b), q| (a + q.hits.len(), b + q.misses.len()));
    for v in [&mut h.ux, &mut h.uy, &mut h.uz, &mut h.mu, &mut h.ud, &mut h.k] {
        v.resize(nh, 0.0);
    }
    h.point.resize(nh, 0);
    for v in [&mut m.dx, &mut m.dy, &mut m.dz, &mut m.ox, &mut m.oy, &mut m.oz, &mut m.oo] {
        v.resize(nm, 0.0);
    }
    offsets.clear();
    let (mut ih, mut im) = (0, 0);
    for (point, q) in neighbours.iter().enumerate() {
        let ow64 = q.p - recv.p;
        let (ow, o) = (ow64.as_vec3(), f.to_local(ow64).as_vec3());
        offsets.push(o);
        // (The receiver's own rays weigh exactly 1: their Jacobian is 1 up to rounding, and a
        // weight sum a rounding below `minweight` would flip the cell to brute force.)
        let weigh = params.jacobian && ow64 != DVec3::ZERO;
        let l = q.hits.len();
        let (hits, r) = (&q.hits[..l], ih..ih + l);
        let (ux, uy, uz) = (&mut h.ux[r.clone()], &mut h.uy[r.clone()], &mut h.uz[r.clone()]);
        let (mu, ud, k, pt) = (&mut h.mu[r.clone()], &mut h.ud[r.clone()], &mut h.k[r.clone()], &mut h.point[r]);
        for j in 0..l {
            let t = &hits[j];
            ux[j] = o.x + fx.dot(t.r);
            uy[j] = o.y + fy.dot(t.r);
            uz[j] = o.z + fz.dot(t.r);
            mu[j] = t.m.dot(ow) + t.mr;
            ud[j] = ow.dot(t.d) + t.t;
            k[j] = if weigh { t.k } else { -1.0 };
            pt[j] = point as u32;
        }
        ih += l;
        let l = q.misses.len();
        let (ds, r) = (&q.misses[..l], im..im + l);
        let (dx, dy, dz) = (&mut m.dx[r.clone()], &mut m.dy[r.clone()], &mut m.dz[r.clone()]);
        let (ox, oy, oz, oo) = (&mut m.ox[r.clone()], &mut m.oy[r.clone()], &mut m.oz[r.clone()], &mut m.oo[r]);
        let o2 = o.length_squared();
        for j in 0..l {
            // World directions: [`miss_terms`] turns them, four at a time.
            let d = ds[j];
            dx[j] = d.x;
            dy[j] = d.y;
            dz[j] = d.z;
            ox[j] = o.x;
            oy[j] = o.y;
            oz[j] = o.z;
            oo[j] = o2;
        }
        im += l;
    }
}

/// Loop 1's arithmetic over the occluded rays, branch-free over arrays so that the compiler
/// vectorises it: each hit's distance `z`, cell, cosine `vd` with its ray, tangent offset `|x|²`
/// and Jacobian weight (whatever the ray's fate, decided in [`cell_depth_bounds`]).
fn hit_terms(h: &mut HitSoa, g: &Grid32) {
    let n = h.ux.len();
    for v in [&mut h.z, &mut h.vd, &mut h.x2, &mut h.j] {
        v.resize(n, 0.0);
    }
    h.cell.resize(n, 0);
    let (ux, uy, uz, mu, ud, k) = (&h.ux[..n], &h.uy[..n], &h.uz[..n], &h.mu[..n], &h.ud[..n], &h.k[..n]);
    let (cell, zo, vdo, x2o, jo) = (&mut h.cell[..n], &mut h.z[..n], &mut h.vd[..n], &mut h.x2[..n], &mut h.j[..n]);
    for i in 0..n {
        let (x, y, zz) = (ux[i], uy[i], uz[i]);
        let z2 = x * x + y * y + zz * zz;
        let z = z2.sqrt();
        let inv = 1.0 / z;
        cell[i] = g.cell(x, y, inv);
        let vd = ud[i] * inv;
        zo[i] = z;
        vdo[i] = vd;
        x2o[i] = (z2 * (1.0 / (vd * vd) - 1.0)).max(0.0);
        jo[i] = hit_jacobian(zz, mu[i], k[i], z2);
    }
}

/// Pass 2's first loop, in the receiver's frame (z = its normal): each cell's occluder depth
/// bounds (cells binned by the direction from the receiver to the hit) and what loop 2 needs of
/// every occluded ray that lends something ([`HitVisit`]); hits beyond `maxdistance` join the
/// escaped rays.
fn cell_depth_bounds(recv: &Receiver, params: &FilterParams, s: &mut Scratch) {
    let Scratch { bounds, hits, h, m, offsets, z_lo, z_hi, .. } = s;
    let n = h.ux.len();
    // The bounds scattered in f32 (each `z` is an f32: its min and max are those of the f64s),
    // the lending rays written into a vector sized once (no capacity test per ray).
    z_lo.clear();
    z_lo.resize(bounds.len(), f32::INFINITY);
    z_hi.clear();
    z_hi.resize(bounds.len(), 0.0);
    hits.resize(n, HitVisit { cell: 0, x2: 0.0, j: 0.0 });
    let mut lent = 0;
    let max_distance = params.max_distance as f32;
    let (zs, uz, cells, vd, k, j, x2) =
        (&h.z[..n], &h.uz[..n], &h.cell[..n], &h.vd[..n], &h.k[..n], &h.j[..n], &h.x2[..n]);
    for i in 0..n {
        let z = zs[i];
        if !(z <= max_distance) {
            // An occluder beyond `maxdistance`: a miss.
            // Its direction, back to world (the escaped rays' arrays hold world directions).
            let o = offsets[h.point[i] as usize];
            let d = (Vec3::new(h.ux[i], h.uy[i], uz[i]) - o).normalize_or_zero();
            m.push((recv.frame.x * d.x as f64 + recv.frame.y * d.y as f64 + recv.frame.z * d.z as f64).as_vec3(), o);
            continue;
        }
        if !(uz[i] > 1e-9 * z) {
            continue; // on or behind the receiver's tangent plane: it lends nothing
        }
        let cell = cells[i];
        let c = cell as usize;
        // (`z` is not NaN here: selects are `min` and `max`.)
        z_lo[c] = if z < z_lo[c] { z } else { z_lo[c] };
        z_hi[c] = if z > z_hi[c] { z } else { z_hi[c] };
        if !(vd[i] > GRAZING as f32) {
            continue;
        }
        let j = if k[i] < 0.0 { 1.0 } else { j[i] };
        hits[lent] = HitVisit { cell, x2: x2[i], j };
        lent += 1;
    }
    hits.truncate(lent);
    for (b, (&lo, &hi)) in bounds.iter_mut().zip(z_lo.iter().zip(z_hi.iter())) {
        b.z_min = lo as f64;
        b.z_max = hi as f64;
    }
}

/// The escaped rays' arithmetic (branch-free over arrays, vectorised): each direction turned to
/// the receiver's frame (in place), its cell and, with [`Warp::Sphere`], the warp to an
/// effective direction from the receiver through the sphere of radius `gmid` (none when it is
/// infinite), its cell and tangent offset.
fn miss_terms(m: &mut MissSoa, frame: &Frame<DVec3>, g: &Grid32, gmid: f64) {
    let n = m.dx.len();
    let (fx, fy, fz) = (frame.x.as_vec3(), frame.y.as_vec3(), frame.z.as_vec3());
    let (dx, dy, dz) = (&mut m.dx[..n], &mut m.dy[..n], &mut m.dz[..n]);
    for i in 0..n {
        let (x, y, z) = (dx[i], dy[i], dz[i]);
        dx[i] = fx.x * x + fx.y * y + fx.z * z;
        dy[i] = fy.x * x + fy.y * y + fy.z * z;
        dz[i] = fz.x * x + fz.y * y + fz.z * z;
    }
    for v in [&mut m.cd, &mut m.cv] {
        v.resize(n, 0);
    }
    m.x2.resize(n, 0.0);
    let (dx, dy, dz, ox, oy, oz, oo) =
        (&m.dx[..n], &m.dy[..n], &m.dz[..n], &m.ox[..n], &m.oy[..n], &m.oz[..n], &m.oo[..n]);
    let (cd, cv, x2o) = (&mut m.cd[..n], &mut m.cv[..n], &mut m.x2[..n]);
    let grazing = GRAZING as f32;
    if !gmid.is_finite() {
        // No occluder: no warp, every cell's radius infinite (weight 1).
        for i in 0..n {
            cd[i] = g.cell(dx[i], dy[i], 1.0);
            cv[i] = cd[i];
            x2o[i] = if dz[i] > 1e-9 { 0.0 } else { -1.0 };
        }
        return;
    }
    let gmid2 = (gmid * gmid) as f32;
    for i in 0..n {
        let (x, y, z) = (dx[i], dy[i], dz[i]);
        cd[i] = g.cell(x, y, 1.0);
        let od = ox[i] * x + oy[i] * y + oz[i] * z;
        let tau = -od + (od * od - oo[i] + gmid2).max(0.0).sqrt();
        let (tx, ty, tz) = (ox[i] + tau * x, oy[i] + tau * y, oz[i] + tau * z);
        let len2 = tx * tx + ty * ty + tz * tz;
        let len = len2.sqrt();
        let inv = 1.0 / len;
        let vd = (tx * x + ty * y + tz * z) * inv;
        cv[i] = g.cell(tx, ty, inv);
        let ok = tz > 1e-9 * len && vd > grazing;
        x2o[i] = if ok { (len2 * (1.0 / (vd * vd) - 1.0)).max(0.0) } else { -1.0 };
    }
}

/// [`Warp::Cell`] (the paper's per-cell plane) for the escaped rays, scalar: the warped cell and
/// tangent offset into `m.cv`, `m.x2` ([`miss_terms`] computed `m.cd`).
fn warp_cell(m: &mut MissSoa, g: &Grid32, bounds: &[Bounds], centers: &[DVec3]) {
    let grazing = GRAZING as f32;
    for i in 0..m.dx.len() {
        let (d, o) = (Vec3::new(m.dx[i], m.dy[i], m.dz[i]), Vec3::new(m.ox[i], m.oy[i], m.oz[i]));
        let c0 = m.cd[i];
        let mid = bounds[c0 as usize].mid;
        m.cv[i] = c0;
        m.x2[i] = -1.0;
        if !mid.is_finite() {
            // No occluder in the ray's cell: no warp (target at infinity, v = d), infinite
            // radius: weight 1 in that cell.
            m.x2[i] = if d.z > grazing { 0.0 } else { -1.0 };
            continue;
        }
        let a = centers[c0 as usize].as_vec3();
        let den = a.dot(d);
        if !(den > grazing) {
            continue;
        }
        let tau = (mid as f32 - a.dot(o)) / den;
        if !(tau > 0.0) {
            continue;
        }
        let target = o + tau * d;
        let len2 = target.length_squared();
        let len = len2.sqrt();
        if !(target.z > 1e-9 * len) {
            continue;
        }
        let v = target / len;
        let vd = v.dot(d);
        m.cv[i] = g.cell(target.x, target.y, 1.0 / len);
        if vd > grazing {
            m.x2[i] = (len2 * (1.0 / (vd * vd) - 1.0)).max(0.0);
        }
    }
}

/// Per cell: the escaped rays' flag (where the cell has occluders), the contact test, the
/// filter's radius (Eq. 8) and the harmonic mid depth.
fn finish_bounds(params: &FilterParams, footprint: f64, bounds: &mut [Bounds], cd: &[u32]) {
    // A cell's escaped rays matter only where it also has occluders (its radius).
    if bounds.iter().any(|b| b.z_max > 0.0) {
        for &c in cd {
            bounds[c as usize].miss = true;
        }
    }
    let contact = 2.0 * params.omega_v * footprint;
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
            f64::INFINITY
        };
        b.radius2 = b.radius * b.radius;
    }
}

/// Warped rays closer to grazing than this (cosine with the sample ray) are rejected.
const GRAZING: f64 = 1e-3;

/// Per-cell filtered visibility at `recv` from the rays of `neighbours` (the receiver's own
/// point included; [`same_surface`] is applied here). `out` gets `cells²` values. Computed in
/// the receiver's frame: each neighbour's offset is subtracted in f64 world coordinates and
/// turned once; the rays' terms are turned and filtered in f32, as arrays
/// ([`gather`], [`hit_terms`], [`miss_terms`]: loops the compiler vectorises).
pub fn filter_receiver<'a>(
    recv: &Receiver,
    neighbours: impl Iterator<Item = &'a CachePoint> + Clone,
    params: &FilterParams,
    scratch: &mut Scratch,
    out: &mut Vec<CellValue>,
) {
    let nc = params.cells * params.cells;
    let grid = Grid32::new(params.cells);
    let inf = f64::INFINITY;
    scratch.bounds.clear();
    scratch
        .bounds
        .resize(nc, Bounds { z_min: inf, z_max: 0.0, brute: false, miss: false, radius: inf, radius2: inf, mid: inf });
    if scratch.centers.len() != nc {
        scratch.centers = (0..nc).map(|c| cell_center(c, params.cells)).collect();
    }
    // The guard once per point (the gather sizes its arrays in a first pass over the points).
    let accepted: Vec<&CachePoint> = neighbours.filter(|q| same_surface(recv, q)).collect();
    gather(recv, &accepted, params, scratch);
    hit_terms(&mut scratch.h, &grid);
    cell_depth_bounds(recv, params, scratch);
    // The receiver's mid depth over all cells, for `Warp::Sphere`.
    let (gmin, gmax) = scratch
        .bounds
        .iter()
        .filter(|b| b.z_max > 0.0)
        .fold((inf, 0.0f64), |(a, b), c| (a.min(c.z_min), b.max(c.z_max)));
    let gmid = if gmax > 0.0 && params.warp == Warp::Sphere { 2.0 / (1.0 / gmin + 1.0 / gmax) } else { inf };
    miss_terms(&mut scratch.m, &recv.frame, &grid, gmid);
    let Scratch { bounds, w: sw, wv: swv, r2: sr2, centers, hits, m, .. } = scratch;
    finish_bounds(params, recv.footprint, bounds, &m.cd);
    if params.warp == Warp::Cell {
        warp_cell(m, &grid, bounds, centers);
    }
    // Loop 2: weight every ray in its cell (occluded rays) or in the cell of its effective ray
    // from p (unoccluded ones), accumulate per cell.
    sw.clear();
    sw.resize(nc, 0.0);
    swv.clear();
    swv.resize(nc, 0.0);
    // Per cell, the kernel's scale: `radius²`, infinite at an infinite radius, where a finite
    // `x2 / radius²` is 0 and the weight `kernel(0)` is 1. Brute-forced cells are weighed too
    // (their sums are not read): the loops have no branch on the cell.
    sr2.clear();
    sr2.extend(bounds.iter().map(|b| b.radius2));
    for h in hits.iter() {
        let c = h.cell as usize;
        sw[c] += kernel(h.x2 as f64 / sr2[c]) * h.j as f64;
    }
    for (&c, &x2) in m.cv.iter().zip(&m.x2) {
        // A negative offset: the ray lends nothing (weight 0; `s + 0.0` is `s` for `s ≥ 0`).
        let c = c as usize;
        let w = if x2 >= 0.0 { kernel(x2 as f64 / sr2[c]) } else { 0.0 };
        sw[c] += w;
        swv[c] += w;
    }
    out.clear();
    out.extend((0..nc).map(|c| {
        // A relative slack, so that weights summing to `minweight` up to rounding pass alike
        // at every scene scale.
        if bounds[c].brute || !(sw[c] >= params.min_weight * (1.0 - 1e-9)) {
            CellValue::Brute
        } else {
            CellValue::Filtered((swv[c] / sw[c]).clamp(0.0, 1.0))
        }
    }));
}

#[cfg(test)]
mod tests;
