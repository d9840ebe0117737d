//! The exact integral of a lobe over a spherical region, with an LTC as control variate and
//! as the warp of an adaptive quadrature.
//!
//! An LTC `D` with matrix `M` maps its cosine space (directions `u`) to directions
//! `ω = Mu/|Mu|`; for any integrand `f` (a BRDF·cos·Fresnel in the local shading frame),
//!
//! `∫_P f(ω) dω = ∫_{M⁻¹P} g(u) du`, with `g(u) = f(Mu/|Mu|) · |det M| / |Mu|³` (`u` unit).
//!
//! Where the LTC fits `f`, `g ≈ b·max(0, u_z)/π` for the lobe's integral `b` (magnitude ×
//! Fresnel), a smooth function even where `f` is a narrow peak. So the integral is split into
//! the analytic `b · ∫_P D` (the LTC integral, [`super::ltc_integrate`]) and the residual
//! `∫_{M⁻¹P} (g(u) − b·max(0, u_z)/π) du`, which is integrated numerically: the region is cut
//! at the cosine space's horizon (where the control variate has its kink), every loop is fanned
//! into spherical triangles from its first vertex, and each triangle is integrated by a
//! collapsed Gauss–Legendre rule on the flat triangle through its corners, radially projected
//! (`dω = det[a, b, c] / |x|³ ds dt`, signed, so a fan covers any loop in an open hemisphere
//! with its winding number). The error of a triangle's 4×4 rule is taken as its difference from
//! the 3×3 rule's, and the whole region's triangles are refined globally: the one with the
//! largest error is split in four until the errors sum to the tolerance (each at most
//! [`MAX_DEPTH`] times).
//!
//! The result is the exact integral up to the tolerance asked for, whatever the LTC's fit error
//! (it only decides how much work the quadrature does): the LTC's tails, its error at high
//! roughness, the table's interpolation and a Fresnel factor that varies over the region all go
//! into the residual.

use glam::{DMat3, DVec3};

use crate::common::spherical_polygon as spherical;
use penumbra_core::geometry::Frame;

/// Subdivision levels of a fan triangle at most (4⁵ = 1024 pieces).
pub const MAX_DEPTH: u32 = 5;

/// Gauss–Legendre nodes and weights on `[0, 1]`, 3 and 4 points.
const GL3: [(f64, f64); 3] = [
    (0.112_701_665_379_258_3, 0.277_777_777_777_777_8),
    (0.5, 0.444_444_444_444_444_4),
    (0.887_298_334_620_741_7, 0.277_777_777_777_777_8),
];
const GL4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_9),
    (0.330_009_478_207_571_9, 0.326_072_577_431_273_1),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_1),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_9),
];

/// An integrand over unit directions with RGB values (`DVec3`: R, G, B).
pub trait Integrand {
    fn eval(&self, u: DVec3) -> DVec3;
}

impl<F: Fn(DVec3) -> DVec3> Integrand for F {
    fn eval(&self, u: DVec3) -> DVec3 {
        self(u)
    }
}

/// Work counters of [`integrate_residual`] (integrand evaluations, triangles split).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QuadratureStats {
    pub evals: u64,
    pub splits: u64,
}

/// The collapsed product rule on the flat triangle `(a, b, c)` projected onto the sphere.
fn triangle_rule<const N: usize>(rule: &[(f64, f64); N], a: DVec3, b: DVec3, c: DVec3, h: &impl Integrand) -> DVec3 {
    let det = a.dot(b.cross(c));
    let (e1, e2) = (b - a, c - a);
    let mut sum = DVec3::ZERO;
    for &(xi, wx) in rule {
        for &(eta, we) in rule {
            let x = a + e1 * (xi * (1.0 - eta)) + e2 * (xi * eta);
            let r = x.length();
            if !(r > 0.0) {
                continue;
            }
            sum += h.eval(x / r) * (wx * we * xi / (r * r * r));
        }
    }
    sum * det
}

/// A spherical triangle of the adaptive quadrature with its 4×4 estimate and that estimate's
/// error (the largest channel's difference from the 3×3 rule's).
struct Piece {
    corners: [DVec3; 3],
    q: DVec3,
    err: f64,
    depth: u32,
}

impl PartialEq for Piece {
    fn eq(&self, o: &Self) -> bool {
        self.err.total_cmp(&o.err).is_eq()
    }
}
impl Eq for Piece {}
impl PartialOrd for Piece {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Piece {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.err.total_cmp(&o.err)
    }
}

/// The two rules on the spherical triangle `(a, b, c)` (unit corners); `None` for a degenerate
/// one. A non-finite error is taken as settled (error 0), a non-finite estimate as 0.
fn piece(corners: [DVec3; 3], depth: u32, h: &impl Integrand, st: &mut QuadratureStats) -> Option<Piece> {
    let [a, b, c] = corners;
    let det = a.dot(b.cross(c));
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let q4 = triangle_rule(&GL4, a, b, c, h);
    let q3 = triangle_rule(&GL3, a, b, c, h);
    st.evals += 25;
    let err = (q4 - q3).abs().max_element();
    let q = if q4.is_finite() { q4 } else { DVec3::ZERO };
    Some(Piece { corners, q, err: if err.is_finite() { err } else { 0.0 }, depth })
}

/// Globally adaptive integral of `h` over the spherical triangles `tris` (unit corners; signed
/// by orientation) to the absolute tolerance `tol` on the sum of their error estimates (the
/// largest channel's): the piece with the largest error is split in four (at its edges'
/// midpoints) until the errors sum to `tol` or less; a piece [`MAX_DEPTH`] splits deep is
/// settled as it is. Refining where the error is, rather than giving every triangle of a fan an
/// equal share of the tolerance, leaves the many thin triangles of a complex visible region
/// (an occluder's silhouette) at one rule each.
fn integrate_triangles(tris: &[[DVec3; 3]], h: &impl Integrand, tol: f64, st: &mut QuadratureStats) -> DVec3 {
    let mut heap = std::collections::BinaryHeap::with_capacity(tris.len() * 2);
    let mut err_sum = 0.0;
    for &t in tris {
        if let Some(p) = piece(t, 0, h, st) {
            err_sum += p.err;
            heap.push(p);
        }
    }
    let mut settled = DVec3::ZERO;
    while err_sum > tol {
        let Some(p) = heap.pop() else { break };
        err_sum -= p.err;
        if p.depth >= MAX_DEPTH || !(p.err > 0.0) {
            settled += p.q;
            continue;
        }
        st.splits += 1;
        let [a, b, c] = p.corners;
        let (ab, bc, ca) = ((a + b).normalize(), (b + c).normalize(), (c + a).normalize());
        for t in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
            if let Some(q) = piece(t, p.depth + 1, h, st) {
                err_sum += q.err;
                heap.push(q);
            }
        }
    }
    heap.into_iter().fold(settled, |s, p| s + p.q)
}

/// The fan of the loop `l` from its first vertex, as triangles.
fn fan(l: &[DVec3], out: &mut Vec<[DVec3; 3]>) {
    if l.len() >= 3 {
        out.extend((1..l.len() - 1).map(|i| [l[0], l[i], l[i + 1]]));
    }
}

/// The lobe being integrated: the LTC's inverse matrix (local frame), the control variate's
/// weight `base` (the LTC integral is multiplied by it; any value gives the same result up to
/// the tolerance, the closer to the lobe's integral the less work) and `f`, the exact
/// BRDF·cos·Fresnel of local unit directions (zero below the horizon).
pub struct Lobe<'a, F: Fn(DVec3) -> DVec3> {
    pub minv: &'a DMat3,
    pub base: DVec3,
    pub f: F,
}

/// `∫_P f − base·∫_P D` over the region of `loops` (world-space directions, oriented as in
/// [`crate::common::spherical_polygon`]; positive loops give positive values), by adaptive quadrature in the
/// LTC's cosine space to the absolute tolerance `tol` (over all loops together). Add `base ·`
/// [`super::ltc_integrate`] of the same loops for `∫_P f`.
pub fn integrate_residual<F: Fn(DVec3) -> DVec3>(
    lobe: &Lobe<F>,
    frame: &Frame<DVec3>,
    loops: &[Vec<DVec3>],
    tol: f64,
    st: &mut QuadratureStats,
) -> DVec3 {
    let minv = *lobe.minv;
    let det_minv = minv.determinant();
    if det_minv == 0.0 || !det_minv.is_finite() {
        return DVec3::ZERO;
    }
    let m = minv.inverse();
    let det_m = det_minv.recip().abs();
    let base_over_pi = lobe.base * std::f64::consts::FRAC_1_PI;
    // g(u) = f(Mu/|Mu|) |det M| / |Mu|³, above the cosine horizon minus the control variate.
    let g = |u: DVec3| {
        let w = m * u;
        let l = w.length();
        if !(l > 0.0) {
            return DVec3::ZERO;
        }
        let v = (lobe.f)(w / l) * (det_m / (l * l * l));
        if v.is_finite() {
            v
        } else {
            DVec3::ZERO
        }
    };
    // Below the cosine horizon the control variate is 0, so `above` is `g` there: one
    // integrand for both halves, which are still cut apart so that no triangle straddles the
    // control variate's kink.
    let above = |u: DVec3| g(u) - base_over_pi * u.z.max(0.0);
    let sign = det_minv.signum();
    let mut tris = Vec::new();
    for l in loops {
        // The region above the surface's horizon, in the cosine space (orientation kept up to
        // det M⁻¹'s sign), then cut at the cosine space's horizon.
        let local: Vec<DVec3> = l.iter().map(|v| frame.to_local(*v)).collect();
        let local = spherical::clip_to_halfspace(&local, DVec3::Z);
        if local.len() < 3 {
            continue;
        }
        let u: Vec<DVec3> = local.iter().map(|v| (minv * *v).normalize_or_zero()).collect();
        if u.contains(&DVec3::ZERO) {
            continue;
        }
        let norm = |l: Vec<DVec3>| -> Vec<DVec3> { l.into_iter().map(|v| v.normalize_or_zero()).collect() };
        fan(&norm(spherical::clip_to_halfspace(&u, DVec3::Z)), &mut tris);
        fan(&norm(spherical::clip_to_halfspace(&u, -DVec3::Z)), &mut tris);
    }
    // One tolerance for the whole region, spent where the error is.
    integrate_triangles(&tris, &above, tol, st) * sign
}
