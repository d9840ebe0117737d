//! Sampling routines with pbrt-v3's conventions: warps from `[0,1)^2` to common
//! domains with their densities, MIS heuristics, stratification helpers, and
//! piecewise-constant 1D/2D distributions.

use crate::interpolation::find_interval;
use crate::rng::{Rng, ONE_MINUS_EPSILON_F32};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

const INV_2PI: f32 = 0.5 * FRAC_1_PI;
const INV_4PI: f32 = 0.25 * FRAC_1_PI;

/// A direction on the hemisphere z ≥ 0, uniform in solid angle.
pub fn uniform_sample_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

pub fn uniform_hemisphere_pdf() -> f32 {
    INV_2PI
}

/// A direction on the unit sphere, uniform in solid angle.
pub fn uniform_sample_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

pub fn uniform_sphere_pdf() -> f32 {
    INV_4PI
}

/// A direction uniform in the cone of half-angle acos(`cos_theta_max`) around +z.
pub fn uniform_sample_cone(u: Vec2, cos_theta_max: f32) -> Vec3 {
    let cos_theta = (1.0 - u.x) + u.x * cos_theta_max;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    Vec3::new(phi.cos() * sin_theta, phi.sin() * sin_theta, cos_theta)
}

/// 1 / (solid angle of the cone); infinite for a degenerate cone (`cos_theta_max` = 1).
pub fn uniform_cone_pdf(cos_theta_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_theta_max))
}

/// A point on the unit disk, uniform in area (polar mapping).
pub fn uniform_sample_disk(u: Vec2) -> Vec2 {
    let r = u.x.max(0.0).sqrt();
    let theta = 2.0 * PI * u.y;
    Vec2::new(r * theta.cos(), r * theta.sin())
}

/// A point on the unit disk, uniform in area, by Shirley–Chiu's concentric mapping.
pub fn concentric_sample_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, FRAC_PI_4 * (o.y / o.x)) } else { (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y)) };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// A direction on the hemisphere z ≥ 0 with density cos θ / π (Malley's method).
pub fn cosine_sample_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_sample_disk(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta * FRAC_1_PI
}

/// Barycentrics (b0, b1) uniform over a triangle (b2 = 1 − b0 − b1).
pub fn uniform_sample_triangle(u: Vec2) -> Vec2 {
    let su0 = u.x.max(0.0).sqrt();
    Vec2::new(1.0 - su0, u.y * su0)
}

/// Veach's balance heuristic; 0 when both densities vanish.
pub fn balance_heuristic(nf: u32, f_pdf: f32, ng: u32, g_pdf: f32) -> f32 {
    let (f, g) = (nf as f32 * f_pdf, ng as f32 * g_pdf);
    if f.is_infinite() {
        return if g.is_infinite() { 0.5 } else { 1.0 };
    }
    let s = f + g;
    if s > 0.0 {
        f / s
    } else {
        0.0
    }
}

/// Veach's power heuristic with β = 2; 0 when both densities vanish.
pub fn power_heuristic(nf: u32, f_pdf: f32, ng: u32, g_pdf: f32) -> f32 {
    let (f, g) = (nf as f32 * f_pdf, ng as f32 * g_pdf);
    if f.is_infinite() {
        return if g.is_infinite() { 0.5 } else { 1.0 };
    }
    if g.is_infinite() {
        return 0.0;
    }
    // Scale to avoid overflow of the squares.
    let m = f.max(g);
    if m.is_nan() || m <= 0.0 {
        return 0.0;
    }
    let (f, g) = (f / m, g / m);
    f * f / (f * f + g * g)
}

/// The direction with polar angle θ (given by its sine and cosine) and azimuth φ about +z.
pub fn spherical_direction(sin_theta: f32, cos_theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        sin_theta.clamp(-1.0, 1.0) * phi.cos(),
        sin_theta.clamp(-1.0, 1.0) * phi.sin(),
        cos_theta.clamp(-1.0, 1.0),
    )
}

/// [`spherical_direction`] expressed in the frame (`x`, `y`, `z`).
pub fn spherical_direction_in_frame(sin_theta: f32, cos_theta: f32, phi: f32, x: Vec3, y: Vec3, z: Vec3) -> Vec3 {
    sin_theta * phi.cos() * x + sin_theta * phi.sin() * y + cos_theta * z
}

/// Polar angle of a unit vector, in [0, π].
pub fn spherical_theta(v: Vec3) -> f32 {
    v.z.clamp(-1.0, 1.0).acos()
}

/// Azimuth of a vector about +z, in [0, 2π).
pub fn spherical_phi(v: Vec3) -> f32 {
    let p = v.y.atan2(v.x);
    if p < 0.0 {
        p + 2.0 * PI
    } else {
        p
    }
}

/// Fills `samples` with one (jittered or centred) sample per stratum of [0, 1).
pub fn stratified_sample_1d(samples: &mut [f32], rng: &mut Rng, jitter: bool) {
    let inv = 1.0 / samples.len() as f32;
    for (i, s) in samples.iter_mut().enumerate() {
        let delta = if jitter { rng.uniform_f32() } else { 0.5 };
        *s = ((i as f32 + delta) * inv).min(ONE_MINUS_EPSILON_F32);
    }
}

/// Fills `samples` (`nx * ny` long, row-major with x inner) with one sample per cell of an `nx × ny` grid.
pub fn stratified_sample_2d(samples: &mut [Vec2], nx: usize, ny: usize, rng: &mut Rng, jitter: bool) {
    let (dx, dy) = (1.0 / nx as f32, 1.0 / ny as f32);
    for (k, s) in samples.iter_mut().take(nx * ny).enumerate() {
        let (x, y) = (k % nx, k / nx);
        let jx = if jitter { rng.uniform_f32() } else { 0.5 };
        let jy = if jitter { rng.uniform_f32() } else { 0.5 };
        *s = Vec2::new(
            ((x as f32 + jx) * dx).min(ONE_MINUS_EPSILON_F32),
            ((y as f32 + jy) * dy).min(ONE_MINUS_EPSILON_F32),
        );
    }
}

/// Randomly permutes `samples`, seen as `samples.len() / n_dimensions` blocks of `n_dimensions` values.
pub fn shuffle<T>(samples: &mut [T], n_dimensions: usize, rng: &mut Rng) {
    let n_dimensions = n_dimensions.max(1);
    let count = samples.len() / n_dimensions;
    for i in 0..count {
        let other = i + rng.uniform_u32_below((count - i) as u32) as usize;
        for j in 0..n_dimensions {
            samples.swap(n_dimensions * i + j, n_dimensions * other + j);
        }
    }
}

/// Latin hypercube samples: `samples` holds `samples.len() / n_dim` points of `n_dim` coordinates,
/// each coordinate stratified into as many strata as there are points, independently permuted.
pub fn latin_hypercube(samples: &mut [f32], n_dim: usize, rng: &mut Rng) {
    let n_dim = n_dim.max(1);
    let n = samples.len() / n_dim;
    let inv = 1.0 / n as f32;
    for i in 0..n {
        for j in 0..n_dim {
            let sj = (i as f32 + rng.uniform_f32()) * inv;
            samples[n_dim * i + j] = sj.min(ONE_MINUS_EPSILON_F32);
        }
    }
    for j in 0..n_dim {
        for i in 0..n {
            let other = i + rng.uniform_u32_below((n - i) as u32) as usize;
            samples.swap(n_dim * i + j, n_dim * other + j);
        }
    }
}

/// [`latin_hypercube`] in 2D over a slice of points.
pub fn latin_hypercube_2d(samples: &mut [Vec2], rng: &mut Rng) {
    let mut flat: Vec<f32> = samples.iter().flat_map(|p| [p.x, p.y]).collect();
    latin_hypercube(&mut flat, 2, rng);
    for (p, c) in samples.iter_mut().zip(flat.chunks_exact(2)) {
        *p = Vec2::new(c[0], c[1]);
    }
}

fn sanitize(v: f32) -> f32 {
    if v.is_finite() && v > 0.0 {
        v
    } else {
        0.0
    }
}

/// A piecewise-constant density over [0, 1) proportional to `func` (pbrt-v3's `Distribution1D`).
///
/// Negative, NaN and infinite values count as 0. When the function integrates to 0 the
/// distribution falls back to uniform; unlike pbrt-v3 (which then reports pdf 0) its pdfs are
/// those of the uniform distribution, so pdfs always match what is sampled.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution1D {
    pub func: Vec<f32>,
    /// `func.len() + 1` entries from 0 to 1.
    pub cdf: Vec<f32>,
    /// ∫₀¹ of the piecewise-constant function (mean of `func`).
    pub func_int: f32,
    /// A guide table over `u`: entry `b` of `m + 1` (`m` a power of two) is the cell that
    /// `u = b / m` falls in, so that `u`'s cell lies between entries `⌊u m⌋` and `⌊u m⌋ + 1`
    /// and the search runs in that range only — the same cell as a search over all of `cdf`
    /// (the search is monotone in `u`, and `b / m` and `u m` are exact).
    guide: Vec<u32>,
}

/// The largest guide table: 2¹⁶ buckets.
const MAX_GUIDE_LOG2: u32 = 16;

impl Distribution1D {
    /// An empty `func` is treated as a single zero cell.
    pub fn new(func: &[f32]) -> Self {
        let mut func: Vec<f32> = func.iter().map(|&v| sanitize(v)).collect();
        if func.is_empty() {
            func.push(0.0);
        }
        let n = func.len();
        let mut acc = vec![0.0f64; n + 1];
        for i in 1..=n {
            acc[i] = acc[i - 1] + func[i - 1] as f64 / n as f64;
        }
        let total = acc[n];
        let cdf: Vec<f32> = if total > 0.0 {
            acc.iter().map(|&c| (c / total) as f32).collect()
        } else {
            (0..=n).map(|i| i as f32 / n as f32).collect()
        };
        let mut cdf = cdf;
        cdf[n] = 1.0;
        // About 8 cells per bucket: 3 search steps left, and an eighth of the entries to build
        // (an environment map has a distribution per row).
        let m = (n.next_power_of_two() / 8).clamp(1, 1 << MAX_GUIDE_LOG2);
        // One sweep: entry b is the largest i < n with cdf[i] <= b / m (cdf[0] = 0 always is).
        let mut i = 0;
        let guide = (0..=m)
            .map(|b| {
                let u = b as f32 / m as f32;
                while i + 1 < n && cdf[i + 1] <= u {
                    i += 1;
                }
                i as u32
            })
            .collect();
        Distribution1D { func, cdf, func_int: total.min(f32::MAX as f64) as f32, guide }
    }

    pub fn count(&self) -> usize {
        self.func.len()
    }

    fn is_uniform_fallback(&self) -> bool {
        self.func_int <= 0.0
    }

    fn offset_of(&self, u: f32) -> usize {
        let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, ONE_MINUS_EPSILON_F32) };
        let m = self.guide.len() - 1;
        let b = ((u * m as f32) as usize).min(m - 1);
        // cdf[lo] <= b / m <= u, and u's cell is at most hi: search lo + 1 ..= hi.
        let (lo, hi) = (self.guide[b] as usize, self.guide[b + 1] as usize);
        lo + find_interval(hi - lo + 2, |i| self.cdf[lo + i] <= u)
    }

    /// Density (w.r.t. [0,1)) of the cell at `offset`.
    fn cell_pdf(&self, offset: usize) -> f32 {
        if self.is_uniform_fallback() {
            1.0
        } else {
            self.func[offset] / self.func_int
        }
    }

    /// Samples x ∈ [0, 1): returns `(x, pdf(x), cell index)`.
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, ONE_MINUS_EPSILON_F32) };
        let offset = self.offset_of(u);
        let mut du = u - self.cdf[offset];
        let width = self.cdf[offset + 1] - self.cdf[offset];
        if width > 0.0 {
            du /= width;
        }
        let du = if du.is_finite() { du.clamp(0.0, 1.0) } else { 0.0 };
        let x = ((offset as f32 + du) / self.count() as f32).min(ONE_MINUS_EPSILON_F32);
        (x, self.cell_pdf(offset), offset)
    }

    /// Samples a cell index: returns `(index, probability, u remapped to [0,1) within the cell)`.
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, ONE_MINUS_EPSILON_F32) };
        let offset = self.offset_of(u);
        let width = self.cdf[offset + 1] - self.cdf[offset];
        let remapped =
            if width > 0.0 { ((u - self.cdf[offset]) / width).clamp(0.0, ONE_MINUS_EPSILON_F32) } else { 0.0 };
        (offset, self.discrete_pdf(offset), remapped)
    }

    /// Probability of choosing cell `index` (0 out of range).
    pub fn discrete_pdf(&self, index: usize) -> f32 {
        if index >= self.count() {
            return 0.0;
        }
        if self.is_uniform_fallback() {
            1.0 / self.count() as f32
        } else {
            (self.func[index] as f64 / (self.func_int as f64 * self.count() as f64)).min(1.0) as f32
        }
    }

    /// Density at x ∈ [0, 1] (0 outside).
    pub fn pdf(&self, x: f32) -> f32 {
        if !(0.0..=1.0).contains(&x) {
            return 0.0;
        }
        let i = ((x * self.count() as f32) as usize).min(self.count() - 1);
        self.cell_pdf(i)
    }
}

/// A piecewise-constant density over [0,1)² proportional to an `nu × nv` image
/// (`func[v * nu + u]`), sampled by its marginal in v and its conditionals in u
/// (pbrt-v3's `Distribution2D`), with [`Distribution1D`]'s robustness rules.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    pub conditional: Vec<Distribution1D>,
    pub marginal: Distribution1D,
}

impl Distribution2D {
    /// Missing values (when `func` is shorter than `nu * nv`) count as 0; `nu`, `nv` of 0 count as 1.
    pub fn new(func: &[f32], nu: usize, nv: usize) -> Self {
        let (nu, nv) = (nu.max(1), nv.max(1));
        let conditional: Vec<Distribution1D> = (0..nv)
            .map(|v| {
                let row: Vec<f32> = (0..nu).map(|u| func.get(v * nu + u).copied().unwrap_or(0.0)).collect();
                Distribution1D::new(&row)
            })
            .collect();
        let marginal_func: Vec<f32> = conditional.iter().map(|c| c.func_int).collect();
        Distribution2D { marginal: Distribution1D::new(&marginal_func), conditional }
    }

    /// Samples (u, v) ∈ [0,1)²: returns the point and its density.
    pub fn sample_continuous(&self, u: Vec2) -> (Vec2, f32) {
        let (d1, pdf1, v) = self.marginal.sample_continuous(u.y);
        let (d0, pdf0, _) = self.conditional[v].sample_continuous(u.x);
        (Vec2::new(d0, d1), pdf0 * pdf1)
    }

    /// Density at `p` ∈ [0,1]² (0 outside or for NaN).
    pub fn pdf(&self, p: Vec2) -> f32 {
        if !((0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y)) {
            return 0.0;
        }
        let nu = self.conditional[0].count();
        let nv = self.marginal.count();
        let iu = ((p.x * nu as f32) as usize).min(nu - 1);
        let iv = ((p.y * nv as f32) as usize).min(nv - 1);
        self.marginal.cell_pdf(iv) * self.conditional[iv].cell_pdf(iu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guide_table_finds_the_cell_a_full_search_finds() {
        // Skewed, zero-run, uniform-fallback and single-cell functions; u at random, at every
        // cdf value and its neighbours, at the guide's bucket bounds, and at the ends.
        let mut rng = crate::rng::Rng::new(5);
        let mut funcs: Vec<Vec<f32>> = vec![vec![0.0; 7], vec![2.0], vec![1.0, 0.0, 0.0, 5.0, 0.0]];
        for n in [3usize, 64, 1000, 70_000] {
            funcs.push((0..n).map(|i| if i % 7 == 3 { 0.0 } else { rng.uniform_f32().powi(8) * 1e3 }).collect());
        }
        let mut checked = 0;
        for f in &funcs {
            let d = Distribution1D::new(f);
            let m = d.guide.len() - 1;
            let mut us: Vec<f32> = (0..2000).map(|_| rng.uniform_f32()).collect();
            for &c in &d.cdf {
                us.extend([c, f32::from_bits(c.to_bits().saturating_sub(1)), f32::from_bits(c.to_bits() + 1)]);
            }
            us.extend((0..=m.min(5000)).map(|b| b as f32 / m as f32));
            us.extend([0.0, -0.0, ONE_MINUS_EPSILON_F32, 1.0, 2.0, -1.0, f32::NAN]);
            for u in us {
                let clamped = if u.is_nan() { 0.0 } else { u.clamp(0.0, ONE_MINUS_EPSILON_F32) };
                let full = find_interval(d.cdf.len(), |i| d.cdf[i] <= clamped);
                assert_eq!(d.offset_of(u), full, "u {u} of {} cells", f.len());
                checked += 1;
            }
        }
        assert!(checked > 20_000);
    }
    use crate::goodness_of_fit::chi2_test;

    const N: usize = 200_000;
    const ALPHA: f64 = 1e-4;

    fn rand2(rng: &mut Rng) -> Vec2 {
        Vec2::new(rng.uniform_f32(), rng.uniform_f32())
    }

    /// Bins directions by (t(z), φ) where t maps z to [0,1) uniformly under the tested density.
    fn direction_test(seed: u64, sample: impl Fn(Vec2) -> Vec3, t_of_z: impl Fn(f32) -> f64, check_unit: bool) {
        let (nt, nphi) = (20, 24);
        let mut rng = Rng::new(seed);
        let mut obs = vec![0.0; nt * nphi];
        for _ in 0..N {
            let w = sample(rand2(&mut rng));
            if check_unit {
                assert!((w.length() - 1.0).abs() < 1e-4, "{w:?}");
            }
            let t = t_of_z(w.z);
            let phi = spherical_phi(w) as f64 / (2.0 * std::f64::consts::PI);
            let it = ((t * nt as f64) as usize).min(nt - 1);
            let ip = ((phi * nphi as f64) as usize).min(nphi - 1);
            obs[it * nphi + ip] += 1.0;
        }
        let exp = vec![N as f64 / (nt * nphi) as f64; nt * nphi];
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > ALPHA, "chi2 {chi2} dof {dof} p {p}");
    }

    #[test]
    fn uniform_hemisphere_chi2() {
        direction_test(1, uniform_sample_hemisphere, |z| z as f64, true);
    }

    #[test]
    fn uniform_sphere_chi2() {
        direction_test(2, uniform_sample_sphere, |z| (1.0 - z as f64) / 2.0, true);
    }

    #[test]
    fn cosine_hemisphere_chi2() {
        direction_test(3, cosine_sample_hemisphere, |z| (z as f64) * (z as f64), true);
    }

    #[test]
    fn cone_chi2() {
        let cmax = 0.7f32;
        direction_test(4, |u| uniform_sample_cone(u, cmax), |z| (1.0 - z as f64) / (1.0 - cmax as f64), true);
    }

    #[test]
    fn concentric_and_polar_disk_chi2() {
        for (seed, f) in [(5u64, concentric_sample_disk as fn(Vec2) -> Vec2), (6, uniform_sample_disk)] {
            // (r², φ) is uniform for an area-uniform disk.
            direction_test(
                seed,
                |u| {
                    let d = f(u);
                    Vec3::new(d.x, d.y, d.length_squared())
                },
                |z| z as f64,
                false,
            );
        }
    }

    #[test]
    fn triangle_chi2() {
        let n = 16;
        let mut rng = Rng::new(7);
        let mut obs = vec![0.0; n * n];
        for _ in 0..N {
            let b = uniform_sample_triangle(rand2(&mut rng));
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            let i = ((b.x * n as f32) as usize).min(n - 1);
            let j = ((b.y * n as f32) as usize).min(n - 1);
            obs[j * n + i] += 1.0;
        }
        let mut exp = vec![0.0; n * n];
        for j in 0..n {
            for i in 0..n {
                let area = if i + j + 2 <= n {
                    1.0
                } else if i + j + 1 == n {
                    0.5
                } else {
                    0.0
                };
                exp[j * n + i] = N as f64 * 2.0 * area / (n * n) as f64;
            }
        }
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > ALPHA, "chi2 {chi2} dof {dof} p {p}");
    }

    #[test]
    fn pdfs_integrate_to_one() {
        // Monte Carlo over the sphere with uniform directions.
        let mut rng = Rng::new(8);
        let cmax = 0.5f32;
        let (mut hemi, mut cosine, mut cone) = (0.0f64, 0.0f64, 0.0f64);
        let n = 400_000;
        for _ in 0..n {
            let w = uniform_sample_sphere(rand2(&mut rng));
            if w.z >= 0.0 {
                hemi += uniform_hemisphere_pdf() as f64;
                cosine += cosine_hemisphere_pdf(w.z) as f64;
            }
            if w.z >= cmax {
                cone += uniform_cone_pdf(cmax) as f64;
            }
        }
        let s = 4.0 * std::f64::consts::PI / n as f64;
        for (name, v) in [("hemi", hemi * s), ("cos", cosine * s), ("cone", cone * s)] {
            assert!((v - 1.0).abs() < 0.01, "{name}: {v}");
        }
        assert!((uniform_sphere_pdf() * 4.0 * PI - 1.0).abs() < 1e-6);
    }

    #[test]
    fn warps_hit_known_points() {
        assert_eq!(concentric_sample_disk(Vec2::splat(0.5)), Vec2::ZERO);
        assert!((concentric_sample_disk(Vec2::new(1.0, 0.5)) - Vec2::new(1.0, 0.0)).length() < 1e-6);
        assert!((concentric_sample_disk(Vec2::new(0.5, 1.0)) - Vec2::new(0.0, 1.0)).length() < 1e-6);
        assert!((cosine_sample_hemisphere(Vec2::splat(0.5)) - Vec3::Z).length() < 1e-6);
        assert!((uniform_sample_cone(Vec2::ZERO, 0.3) - Vec3::Z).length() < 1e-6);
        assert!((uniform_sample_cone(Vec2::new(1.0, 0.0), 0.3).z - 0.3).abs() < 1e-6);
        assert_eq!(uniform_sample_triangle(Vec2::new(0.0, 0.7)), Vec2::new(1.0, 0.0));
        let w = spherical_direction(0.6, 0.8, 1.0);
        assert!((spherical_theta(w) - 0.8f32.acos()).abs() < 1e-5);
        assert!((spherical_phi(w) - 1.0).abs() < 1e-5);
        assert!((spherical_phi(Vec3::new(0.0, -1.0, 0.0)) - 1.5 * PI).abs() < 1e-5);
        let f = spherical_direction_in_frame(0.6, 0.8, 1.0, Vec3::Y, Vec3::Z, Vec3::X);
        assert!((f - Vec3::new(w.z, w.x, w.y)).length() < 1e-6);
    }

    #[test]
    fn heuristics() {
        assert!((power_heuristic(1, 1.0, 1, 3.0) - 0.1).abs() < 1e-6);
        assert!((balance_heuristic(1, 1.0, 1, 3.0) - 0.25).abs() < 1e-6);
        assert!((power_heuristic(2, 1.0, 1, 2.0) - 0.5).abs() < 1e-6);
        assert_eq!(power_heuristic(1, 0.0, 1, 0.0), 0.0);
        assert_eq!(balance_heuristic(1, 0.0, 1, 0.0), 0.0);
        assert_eq!(power_heuristic(1, f32::INFINITY, 1, 1.0), 1.0);
        assert_eq!(power_heuristic(1, 1.0, 1, f32::INFINITY), 0.0);
        assert!((power_heuristic(1, 1e30, 1, 1e30) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn stratification_helpers() {
        let mut rng = Rng::new(9);
        let mut s = vec![0.0f32; 16];
        stratified_sample_1d(&mut s, &mut rng, true);
        for (i, v) in s.iter().enumerate() {
            assert_eq!((v * 16.0) as usize, i);
        }
        shuffle(&mut s, 1, &mut rng);
        let mut strata: Vec<usize> = s.iter().map(|v| (v * 16.0) as usize).collect();
        strata.sort();
        assert_eq!(strata, (0..16).collect::<Vec<_>>());
        let mut p = vec![Vec2::ZERO; 12];
        stratified_sample_2d(&mut p, 4, 3, &mut rng, false);
        assert_eq!(p[5], Vec2::new(1.5 / 4.0, 1.5 / 3.0));
        let mut lh = vec![Vec2::ZERO; 10];
        latin_hypercube_2d(&mut lh, &mut rng);
        for axis in 0..2 {
            let mut st: Vec<usize> = lh.iter().map(|q| (q[axis] * 10.0) as usize).collect();
            st.sort();
            assert_eq!(st, (0..10).collect::<Vec<_>>());
        }
    }

    #[test]
    fn distribution1d_matches_pbrt_semantics() {
        let d = Distribution1D::new(&[1.0, 3.0, 0.0, 4.0]);
        assert_eq!(d.func_int, 2.0);
        assert_eq!(d.cdf, vec![0.0, 0.125, 0.5, 0.5, 1.0]);
        let (x, pdf, off) = d.sample_continuous(0.25);
        assert_eq!(off, 1);
        assert!((x - (1.0 + 1.0 / 3.0) / 4.0).abs() < 1e-6);
        assert!((pdf - 1.5).abs() < 1e-6);
        let (i, p, r) = d.sample_discrete(0.75);
        assert_eq!(i, 3);
        assert!((p - 0.5).abs() < 1e-6 && (r - 0.5).abs() < 1e-6);
        assert_eq!(d.discrete_pdf(2), 0.0);
        assert_eq!(d.discrete_pdf(9), 0.0);
        assert!((d.pdf(0.9) - 2.0).abs() < 1e-6);
        // Never lands in the zero cell, even at its cdf boundary.
        assert_eq!(d.sample_continuous(0.5).2, 3);
        assert!(d.sample_continuous(1.0).0 < 1.0);
    }

    #[test]
    fn distribution1d_chi2() {
        let f: Vec<f32> =
            (0..32).map(|i| ((i as f32 * 0.7).sin() + 1.1).powi(2) * if i % 7 == 3 { 0.0 } else { 1.0 }).collect();
        let d = Distribution1D::new(&f);
        let sub = 4; // check uniformity within cells, too
        let mut obs = vec![0.0; f.len() * sub];
        let mut rng = Rng::new(10);
        for _ in 0..N {
            let (x, pdf, off) = d.sample_continuous(rng.uniform_f32());
            assert_eq!(pdf, d.pdf(x));
            assert_eq!(off, (x * 32.0) as usize);
            obs[(x * (32 * sub) as f32) as usize] += 1.0;
        }
        let total: f32 = f.iter().sum();
        let exp: Vec<f64> = (0..32 * sub).map(|k| N as f64 * (f[k / sub] / total) as f64 / sub as f64).collect();
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > ALPHA, "chi2 {chi2} dof {dof} p {p}");
        let mut obs = vec![0.0; 32];
        for _ in 0..N {
            obs[d.sample_discrete(rng.uniform_f32()).0] += 1.0;
        }
        let exp: Vec<f64> = f.iter().map(|&v| N as f64 * (v / total) as f64).collect();
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > ALPHA, "discrete: chi2 {chi2} dof {dof} p {p}");
    }

    #[test]
    fn distributions_survive_degenerate_input() {
        for f in [vec![], vec![0.0; 5], vec![f32::NAN, -1.0, f32::INFINITY, f32::NEG_INFINITY]] {
            let d = Distribution1D::new(&f);
            for u in [0.0, 0.3, ONE_MINUS_EPSILON_F32, 1.0, f32::NAN, -2.0, 7.0] {
                let (x, pdf, off) = d.sample_continuous(u);
                assert!((0.0..1.0).contains(&x) && pdf == 1.0 && off < d.count(), "{f:?} {u}");
                let (i, p, r) = d.sample_discrete(u);
                assert!(i < d.count() && (p - 1.0 / d.count() as f32).abs() < 1e-6 && (0.0..1.0).contains(&r));
            }
        }
        let d = Distribution1D::new(&[f32::NAN, 2.0, -3.0]);
        assert_eq!(d.func, vec![0.0, 2.0, 0.0]);
        assert_eq!(d.sample_continuous(0.1).2, 1);
        let d2 = Distribution2D::new(&[0.0; 6], 3, 2);
        let (p, pdf) = d2.sample_continuous(Vec2::new(0.9, 0.2));
        assert!((p - Vec2::new(0.9, 0.2)).length() < 1e-6 && pdf == 1.0 && d2.pdf(p) == 1.0);
        let d2 = Distribution2D::new(&[1.0], 0, 3);
        assert_eq!(d2.conditional.len(), 3);
        assert_eq!(d2.pdf(Vec2::new(f32::NAN, 0.5)), 0.0);
        let (p, pdf) = d2.sample_continuous(Vec2::new(f32::NAN, f32::NAN));
        assert!(p.is_finite() && pdf.is_finite());
    }

    #[test]
    fn distribution2d_chi2_and_pdf() {
        let (nu, nv) = (12, 8);
        let f: Vec<f32> = (0..nu * nv)
            .map(|k| {
                let (u, v) = ((k % nu) as f32, (k / nu) as f32);
                if (u as usize + v as usize) % 5 < 1 {
                    0.0
                } else {
                    1.0 + u * 0.3 + (v * 0.9).cos() * 0.8
                }
            })
            .collect();
        let d = Distribution2D::new(&f, nu, nv);
        let mut rng = Rng::new(12);
        let mut obs = vec![0.0; nu * nv];
        for _ in 0..N {
            let (p, pdf) = d.sample_continuous(rand2(&mut rng));
            assert!((pdf - d.pdf(p)).abs() <= 1e-5 * pdf, "{pdf} {}", d.pdf(p));
            obs[(p.y * nv as f32) as usize * nu + (p.x * nu as f32) as usize] += 1.0;
        }
        let total: f64 = f.iter().map(|&v| v as f64).sum();
        let exp: Vec<f64> = f.iter().map(|&v| N as f64 * v as f64 / total).collect();
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > ALPHA, "chi2 {chi2} dof {dof} p {p}");
        // pdf integrates to 1 and equals the normalised function.
        let mean: f64 = total / (nu * nv) as f64;
        for (k, &fk) in f.iter().enumerate() {
            let c = Vec2::new(((k % nu) as f32 + 0.5) / nu as f32, ((k / nu) as f32 + 0.5) / nv as f32);
            assert!((d.pdf(c) as f64 - fk as f64 / mean).abs() < 1e-4);
        }
    }

    proptest::proptest! {
        #[test]
        fn distributions_never_panic(
            func in proptest::collection::vec(proptest::num::f32::ANY, 0..40),
            nu in 0usize..8,
            u in proptest::num::f32::ANY,
            v in proptest::num::f32::ANY,
        ) {
            let d = Distribution1D::new(&func);
            let (x, pdf, off) = d.sample_continuous(u);
            proptest::prop_assert!((0.0..1.0).contains(&x) && pdf.is_finite() && pdf >= 0.0 && off < d.count());
            let (i, p, r) = d.sample_discrete(u);
            proptest::prop_assert!(i < d.count() && (0.0..=1.0).contains(&p) && (0.0..1.0).contains(&r));
            let nv = func.len().checked_div(nu).unwrap_or(1);
            let d2 = Distribution2D::new(&func, nu, nv);
            let (q, pdf2) = d2.sample_continuous(Vec2::new(u, v));
            proptest::prop_assert!(q.cmpge(Vec2::ZERO).all() && q.cmplt(Vec2::ONE).all());
            proptest::prop_assert!(pdf2.is_finite() && pdf2 >= 0.0);
            let back = d2.pdf(q);
            proptest::prop_assert!(back.is_finite());
        }
    }
}
