//! Quadrature on the sphere and projection of functions onto SH.
//!
//! [`SphereQuadrature::product`] is Gauss–Legendre in `z = cos θ` times the uniform rule in `φ`:
//! with `N_θ` nodes and `N_φ` angles it integrates every spherical polynomial of degree
//! `≤ min(2N_θ − 1, N_φ − 1)` exactly (the φ-average of a polynomial in x, y, z is a polynomial
//! in z of the same degree), so products of SH, rotated zonal functions and the triple
//! products are integrated to rounding.

use super::{basis, ShOrder};
use glam::DVec3;

/// Gauss–Legendre nodes and weights on [−1, 1] (`n ≥ 1`), by Newton's method on `P_n`.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let n = n.max(1);
    let (mut x, mut w) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..n.div_ceil(2) {
        // Tricomi's initial guess, then Newton to full precision.
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, z);
            dp = d;
            let dz = p / d;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        let (_, d) = legendre_and_derivative(n, z);
        dp = if d.is_finite() { d } else { dp };
        x[i] = -z;
        x[n - 1 - i] = z;
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        w[i] = wi;
        w[n - 1 - i] = wi;
    }
    (x, w)
}

/// `(P_n(z), P_n′(z))` by the three-term recurrence.
fn legendre_and_derivative(n: usize, z: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, z);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
        p0 = p1;
        p1 = p2;
    }
    (p1, n as f64 * (z * p1 - p0) / (z * z - 1.0))
}

/// Directions on the unit sphere with weights summing to 4π.
#[derive(Clone, Debug)]
pub struct SphereQuadrature {
    pub dirs: Vec<DVec3>,
    pub weights: Vec<f64>,
}

impl SphereQuadrature {
    /// `n_theta` Gauss–Legendre nodes in `z` × `n_phi` equally spaced angles in `φ` (offset by
    /// half a step, so no node lies on the `φ = 0` seam).
    pub fn product(n_theta: usize, n_phi: usize) -> SphereQuadrature {
        let (z, wz) = gauss_legendre(n_theta);
        let n_phi = n_phi.max(1);
        let dphi = 2.0 * std::f64::consts::PI / n_phi as f64;
        let mut dirs = Vec::with_capacity(z.len() * n_phi);
        let mut weights = Vec::with_capacity(z.len() * n_phi);
        for (zi, wi) in z.iter().zip(&wz) {
            let r = (1.0 - zi * zi).max(0.0).sqrt();
            for j in 0..n_phi {
                let (s, c) = ((j as f64 + 0.5) * dphi).sin_cos();
                dirs.push(DVec3::new(r * c, r * s, *zi));
                weights.push(wi * dphi);
            }
        }
        SphereQuadrature { dirs, weights }
    }

    /// The smallest product rule exact for spherical polynomials of degree `≤ degree`.
    pub fn exact_for_degree(degree: usize) -> SphereQuadrature {
        SphereQuadrature::product(degree / 2 + 1, degree + 1)
    }

    pub fn len(&self) -> usize {
        self.dirs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.dirs.is_empty()
    }
}

/// `∫ f(ω) Y_i(ω) dω` for `i < n²` by the quadrature `q` (exact when `f` is a spherical
/// polynomial of degree `d` and `q` is exact for degree `d + n − 1`).
pub fn project(order: ShOrder, f: impl Fn(DVec3) -> f64, q: &SphereQuadrature) -> Vec<f64> {
    let mut out = vec![0.0; order.coeffs()];
    let mut y = vec![0.0; order.coeffs()];
    for (d, w) in q.dirs.iter().zip(&q.weights) {
        let v = f(*d) * w;
        if v == 0.0 {
            continue;
        }
        basis::eval_unit(order, *d, &mut y);
        out.iter_mut().zip(&y).for_each(|(o, yi)| *o += v * yi);
    }
    out
}

/// The reconstruction `Σ_i c_i Y_i(d)` (`c.len()` must be `n²` for some order).
pub fn reconstruct(c: &[f64], d: DVec3) -> f64 {
    let Ok(order) = ShOrder::from_coeffs(c.len()) else { return 0.0 };
    let y = basis::eval_vec(order, d);
    c.iter().zip(&y).map(|(a, b)| a * b).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in [1usize, 2, 5, 16, 40] {
            let (x, w) = gauss_legendre(n);
            assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-13, "n = {n}");
            for k in 0..2 * n {
                let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let want = if k % 2 == 1 { 0.0 } else { 2.0 / (k + 1) as f64 };
                assert!((got - want).abs() < 1e-13, "n = {n}, x^{k}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn product_rule_weights_sum_to_4pi_and_integrate_monomials() {
        let q = SphereQuadrature::exact_for_degree(6);
        assert!((q.weights.iter().sum::<f64>() - 4.0 * std::f64::consts::PI).abs() < 1e-12);
        // ∫ x² dω = 4π/3, ∫ x²y²z² dω = 4π/105, ∫ x⁴ dω = 4π/5.
        let int = |f: &dyn Fn(DVec3) -> f64| q.dirs.iter().zip(&q.weights).map(|(d, w)| w * f(*d)).sum::<f64>();
        let pi4 = 4.0 * std::f64::consts::PI;
        assert!((int(&|d| d.x * d.x) - pi4 / 3.0).abs() < 1e-12);
        assert!((int(&|d| d.x * d.x * d.y * d.y * d.z * d.z) - pi4 / 105.0).abs() < 1e-12);
        assert!((int(&|d| d.x.powi(4)) - pi4 / 5.0).abs() < 1e-12);
    }

    #[test]
    fn projection_reproduces_a_band_limited_function() {
        let o = ShOrder::new(4).unwrap();
        let c: Vec<f64> = (0..16).map(|i| (i as f64 * 0.37).sin()).collect();
        let q = SphereQuadrature::exact_for_degree(6);
        let p = project(o, |d| reconstruct(&c, d), &q);
        for (a, b) in p.iter().zip(&c) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
