//! The fixed tables of the diffuse-reflection extension (seed 003 §4.3): the form-factor ZH
//! `f_θ` by angular radius, the geodesic sample directions of a sphere, and the basis sums
//! over their Voronoi cells (eq. 4.19).

use glam::DVec3;
use penumbra_core::sh::{self, quadrature::gauss_legendre, ShOrder, SphereQuadrature};
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

/// How a reflecting sphere's radiance reaches a receiver (`"string formfactor"`). `α` is the
/// angle on the sphere from the direction towards the receiver, `θ` the sphere's angular
/// radius there, `s = sin θ`, `t = cos α`, `q = 1 − 2st + s²` (the squared distance to the
/// receiver over the centre's), and `cos γ = (t − s)/√q` the cosine at the sphere's surface
/// towards the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormFactor {
    /// The thesis: `L̃` averages `r_S` with `f_θ(α) = max(0, cos γ)` (eq. 4.24), and `Ṽ` is the
    /// SH value of eq. 4.33 as it comes.
    Thesis,
    /// Exact for a lone sphere in front of the receiver, up to the SH truncation of `r_S`:
    /// - `L̃` weighs each surface element by the solid angle it subtends at the receiver
    ///   (`cos γ/q`) times the receiver's own cosine `N·ω`. That cosine is linear in the
    ///   sphere's normal `m`: with `a` the unit direction from the centre to the receiver,
    ///   `N·ω ∝ −(N·a)(1 − st) + s N⊥·m` (`N⊥` the part of `N` across `a`), so the weight is
    ///   the zonal `K₀ = (t − s)(1 − st)/q²` plus `s/(−N·a)` times `K₁(t) (N⊥·m)` with
    ///   `K₁ = (t − s)/q²`, whose SH coefficients are the derivative along `N⊥` of the turned
    ///   zonal `Z(t) = ∫₋₁ᵗ K₁`;
    /// - `Ṽ` is scaled by the exact unoccluded form factor of the sphere's cap over its SH
    ///   value, `π sin²θ (N·axis) / Σ_l cap_l(θ) h_l P_l(N·axis)`: order-4 ringing otherwise
    ///   makes a small cap near the horizon up to 11 times too bright, a hemisphere-sized one
    ///   up to 8 % too dark.
    Exact,
}

/// The weight at `t = cos α` on a sphere with `s = sin θ` (unnormalised): `f_θ`, or `K₀`.
fn weight_at(model: FormFactor, s: f64, t: f64) -> f64 {
    let q = (1.0 - 2.0 * s * t + s * s).max(0.0);
    if t <= s || !(q > 0.0) {
        return 0.0;
    }
    match model {
        FormFactor::Thesis => (t - s) / q.sqrt(),
        FormFactor::Exact => (t - s) * (1.0 - s * t) / (q * q),
    }
}

/// The thesis's form factor (eq. 4.24) at angle `alpha` for angular radius `theta`.
pub fn form_factor(theta: f64, alpha: f64) -> f64 {
    weight_at(FormFactor::Thesis, theta.sin(), alpha.cos())
}

/// `∫_s^1 f(t) dt` for a weight peaked at `t = 1` with width about `(1 − s)/2s`: Gauss–Legendre
/// in `v = ln(1 + u/δ)`, `u = (1 − t)/(1 − s)`, so the peak is resolved as `s → 1`.
fn integrate_band(s: f64, nodes: (&[f64], &[f64]), mut f: impl FnMut(f64, f64)) {
    let delta = ((1.0 - s) / (2.0 * s.max(1e-300))).clamp(1e-15, 1.0);
    let vmax = (1.0 / delta).ln_1p();
    for (x, w) in nodes.0.iter().zip(nodes.1) {
        let v = 0.5 * (x + 1.0) * vmax;
        let u = delta * v.exp_m1();
        let t = 1.0 - (1.0 - s) * u;
        // dt = (1 − s) du, du = (u + δ) dv, dv = vmax/2 dx.
        f(t, 0.5 * w * vmax * (u + delta) * (1.0 - s));
    }
}

/// The normalised form factor (unit integral over the sphere of directions) as ZH, tabulated
/// over `θ ∈ [0, π/2]` and interpolated linearly; for [`FormFactor::Exact`] `K₀`, and the ZH
/// of `Z` over the same normaliser (the integral of `K₀`).
#[derive(Clone, Debug)]
pub struct FormFactorTable {
    model: FormFactor,
    n: usize,
    entries: usize,
    zh: Vec<f64>,
    z: Vec<f64>,
}

/// Quadrature nodes over the visible band `cos α ∈ [sin θ, 1]`.
const FF_NODES: usize = 128;

/// `√((2l+1)/4π)`.
fn pole(l: usize) -> f64 {
    ((2 * l + 1) as f64 / (4.0 * PI)).sqrt()
}

impl FormFactorTable {
    pub fn new(order: ShOrder, entries: usize, model: FormFactor) -> FormFactorTable {
        let (n, entries) = (order.n(), entries.max(2));
        let (x, w) = gauss_legendre(FF_NODES);
        let mut p = vec![0.0; n + 1];
        let mut zh = Vec::with_capacity(entries * n);
        let mut zs = Vec::new();
        for i in 0..entries {
            let s = (FRAC_PI_2 * i as f64 / (entries - 1) as f64).sin();
            let (mut g, mut z) = (vec![0.0; n], vec![0.0; n]);
            let mut total = 0.0;
            if i + 1 < entries {
                integrate_band(s, (&x, &w), |t, dt| {
                    let f = weight_at(model, s, t) * dt;
                    let k1 = if t > s { (t - s) / (1.0 - 2.0 * s * t + s * s).powi(2) * dt } else { 0.0 };
                    sh::zonal::legendre(t, &mut p);
                    total += f;
                    for l in 0..n {
                        g[l] += f * p[l] * pole(l);
                        // Z_l = −2π √((2l+1)/4π) ∫ K₁ (P_{l+1} − P_{l−1})/(2l+1) (by parts; l ≥ 1).
                        if l > 0 {
                            z[l] -= k1 * (p[l + 1] - p[l - 1]) / (2 * l + 1) as f64 * pole(l);
                        }
                    }
                });
            }
            if total > 0.0 {
                // ∫ f dω = 2π ∫ f dt: the 2π cancels.
                g.iter_mut().chain(z.iter_mut()).for_each(|v| *v /= total);
            } else {
                // θ = π/2 (the receiver on the sphere): a delta at the point facing it.
                g.iter_mut().enumerate().for_each(|(l, v)| *v = pole(l));
                z.iter_mut().for_each(|v| *v = 0.0);
            }
            zh.extend_from_slice(&g);
            if model == FormFactor::Exact {
                zs.extend_from_slice(&z);
            }
        }
        FormFactorTable { model, n, entries, zh, z: zs }
    }

    pub fn model(&self) -> FormFactor {
        self.model
    }

    fn lerp(&self, table: &[f64], theta: f64, out: &mut [f64]) {
        let x = if theta.is_nan() { 0.0 } else { (theta / FRAC_PI_2).clamp(0.0, 1.0) * (self.entries - 1) as f64 };
        let i = (x.floor() as usize).min(self.entries - 2);
        let t = x - i as f64;
        let (a, b) = (&table[i * self.n..(i + 1) * self.n], &table[(i + 1) * self.n..(i + 2) * self.n]);
        for (l, o) in out.iter_mut().enumerate().take(self.n) {
            *o = a[l] + t * (b[l] - a[l]);
        }
    }

    /// The normalised form factor `f_θ` (ZH, `n` values; `K₀` for [`FormFactor::Exact`]).
    pub fn lookup(&self, theta: f64, out: &mut [f64]) {
        self.lerp(&self.zh, theta, out);
    }

    /// The ZH of `Z` over `∫K₀` ([`FormFactor::Exact`] only; zeros otherwise).
    pub fn lookup_z(&self, theta: f64, out: &mut [f64]) {
        if self.z.is_empty() {
            out.iter_mut().take(self.n).for_each(|v| *v = 0.0);
        } else {
            self.lerp(&self.z, theta, out);
        }
    }
}

/// The vertices of an icosahedron subdivided `level` times, on the unit sphere (12, 42, 162,
/// 642, … directions), in a fixed order.
pub fn geodesic_directions(level: u32) -> Vec<DVec3> {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let mut m = [0usize; 3];
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *mid.entry(key).or_insert_with(|| {
                    v.push(((v[a] + v[b]) * 0.5).normalize());
                    v.len() - 1
                });
            }
            next.extend([[f[0], m[0], m[2]], [f[1], m[1], m[0]], [f[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        faces = next;
    }
    v
}

/// The geodesic sample directions `ω_j` of a sphere and, per direction, `Σ_k w_k y(ω̂_k)` over
/// the fine quadrature directions `ω̂_k` of its Voronoi cell (eq. 4.19): the projection of the
/// piecewise-constant function that takes value `M_j` on cell `j` is `Σ_j M_j · sums_j`.
#[derive(Clone, Debug)]
pub struct VoronoiCells {
    pub dirs: Vec<DVec3>,
    /// `dirs.len() × n²`.
    pub sums: Vec<f64>,
    pub coeffs: usize,
}

impl VoronoiCells {
    /// `level`: icosphere subdivisions of the sample directions; the cells are integrated with
    /// a `fine × 2·fine` Gauss–Legendre × uniform-φ rule (weights exact, no randomness).
    /// The directions are turned by a fixed rotation out of the coordinate planes: a ray from a
    /// centre on such a plane running exactly within it (a zero direction component) can miss
    /// the BVH's boxes that lie in it (an equator ray through the centre of an exact sphere
    /// misses the sphere).
    pub fn new(order: ShOrder, level: u32, fine: usize) -> VoronoiCells {
        let turn = glam::DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.5);
        let dirs: Vec<DVec3> = geodesic_directions(level).into_iter().map(|d| (turn * d).normalize()).collect();
        let k = order.coeffs();
        let q = SphereQuadrature::product(fine.max(1), 2 * fine.max(1));
        let mut sums = vec![0.0; dirs.len() * k];
        let mut y = vec![0.0; k];
        for (d, w) in q.dirs.iter().zip(&q.weights) {
            let mut best = 0;
            let mut best_dot = f64::NEG_INFINITY;
            for (j, s) in dirs.iter().enumerate() {
                let c = s.dot(*d);
                if c > best_dot {
                    (best, best_dot) = (j, c);
                }
            }
            sh::basis::eval_unit(order, *d, &mut y);
            for (o, yi) in sums[best * k..(best + 1) * k].iter_mut().zip(&y) {
                *o += w * yi;
            }
        }
        VoronoiCells { dirs, sums, coeffs: k }
    }

    pub fn cell(&self, j: usize) -> &[f64] {
        &self.sums[j * self.coeffs..(j + 1) * self.coeffs]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geodesic_counts_and_unit_length() {
        for (level, count) in [(0, 12), (1, 42), (2, 162), (3, 642)] {
            let d = geodesic_directions(level);
            assert_eq!(d.len(), count);
            assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-12));
            // No two directions coincide.
            let min = d
                .iter()
                .enumerate()
                .flat_map(|(i, a)| d[i + 1..].iter().map(move |b| a.distance(*b)))
                .fold(f64::INFINITY, f64::min);
            assert!(min > 0.5 / (1 << level) as f64, "level {level}: {min}");
        }
    }

    #[test]
    fn voronoi_cells_project_a_constant_exactly_and_sum_to_the_sphere() {
        let order = ShOrder::new(4).unwrap();
        let cells = VoronoiCells::new(order, 2, 128);
        let mut total = vec![0.0; 16];
        for j in 0..cells.dirs.len() {
            for (t, v) in total.iter_mut().zip(cells.cell(j)) {
                *t += v;
            }
        }
        // Σ_j sums_j = ∫ y = (√4π, 0, …).
        assert!((total[0] - sh::SQRT_4PI).abs() < 1e-12);
        assert!(total[1..].iter().all(|v| v.abs() < 1e-12), "{total:?}");
        // Each cell holds about 4π/162 of the sphere.
        for j in 0..cells.dirs.len() {
            let area = cells.cell(j)[0] * sh::SQRT_4PI;
            assert!((area / (4.0 * PI / 162.0) - 1.0).abs() < 0.2, "cell {j}: {area}");
        }
    }

    #[test]
    fn form_factor_formula_matches_the_thesis_arctangent_form() {
        // eq. 4.24: max(0, sin(atan((1 − sin θ cos α)/(sin θ sin α)) − α)).
        for theta in [0.1f64, 0.4, 0.9, 1.3] {
            for alpha in [0.05f64, 0.3, 0.7, 1.0, 1.4] {
                let s = theta.sin();
                let thesis = ((1.0 - s * alpha.cos()) / (s * alpha.sin())).atan() - alpha;
                let thesis = thesis.sin().max(0.0);
                let ours = form_factor(theta, alpha);
                assert!((thesis - ours).abs() < 1e-12, "θ {theta} α {alpha}: {thesis} vs {ours}");
            }
        }
    }

    #[test]
    fn form_factor_zh_is_normalised_and_matches_direct_projection() {
        let order = ShOrder::new(4).unwrap();
        let q = SphereQuadrature::product(400, 8);
        for weighting in [FormFactor::Thesis, FormFactor::Exact] {
            let table = FormFactorTable::new(order, 4097, weighting);
            for theta in [0.0f64, 0.2, 0.6, 1.0, 1.4] {
                let mut g = vec![0.0; 4];
                table.lookup(theta, &mut g);
                // A unit-integral function has DC 1/√4π.
                assert!((g[0] * sh::SQRT_4PI - 1.0).abs() < 1e-6, "{weighting:?} θ {theta}: {}", g[0]);
                let f = |d: DVec3| weight_at(weighting, theta.sin(), d.z.clamp(-1.0, 1.0));
                let raw = sh::project(order, f, &q);
                let norm = raw[0] * sh::SQRT_4PI;
                for l in 0..4 {
                    let want = raw[l * (l + 1)] / norm;
                    assert!(
                        (g[l] - want).abs() < 2e-3 * g[0].abs(),
                        "{weighting:?} θ {theta} l {l}: {} vs {want}",
                        g[l]
                    );
                }
            }
            // θ → 90°: a delta at the pole, continuously.
            let (mut a, mut b) = (vec![0.0; 4], vec![0.0; 4]);
            table.lookup(FRAC_PI_2, &mut a);
            table.lookup(FRAC_PI_2 - 1e-3, &mut b);
            for l in 0..4 {
                assert!((a[l] - b[l]).abs() < 0.02 * a[l], "{weighting:?} l {l}: {} vs {}", a[l], b[l]);
            }
        }
    }
}
