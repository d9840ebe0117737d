//! The real SH basis by recurrence (see the module conventions in [`crate::sh`]).
//!
//! `Y_l^m = √2 Q_l^|m|(z) · Re/Im (x + iy)^|m|` (`m ≠ 0`) and `Q_l^0(z)` (`m = 0`), where
//! `Q_l^m(z) = N_l^m P_l^m(z) / sin^m θ` is a polynomial in `z`. The normalised recurrences
//! `Q_m^m = √((2m+1)/2m) Q_{m−1}^{m−1}`, `Q_{m+1}^m = √(2m+3) z Q_m^m`,
//! `Q_l^m = a_lm (z Q_{l−1}^m − b_lm Q_{l−2}^m)` with `a_lm = √((4l²−1)/(l²−m²))`,
//! `b_lm = √(((l−1)²−m²)/(4(l−1)²−1))` never form the factorials of `N_l^m`, so they stay
//! accurate at high order; `(x + iy)^m` is one complex multiplication per `m`.

use super::{index, ShOrder, MAX_ORDER};
use glam::DVec3;
use std::sync::OnceLock;

/// Recurrence coefficients up to `MAX_ORDER`, built once.
struct Tables {
    /// `Q_m^m` (the constant polynomial), for `m < MAX_ORDER`, `√2` included for `m > 0`.
    diag: Vec<f64>,
    /// `(a_lm, b_lm)` at `l(l+1)/2 + m`, for `l ≥ m + 2`.
    ab: Vec<(f64, f64)>,
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        let mut diag = Vec::with_capacity(MAX_ORDER);
        let mut q = 1.0 / (4.0 * std::f64::consts::PI).sqrt();
        diag.push(q);
        for m in 1..MAX_ORDER {
            q *= ((2 * m + 1) as f64 / (2 * m) as f64).sqrt();
            diag.push(q * std::f64::consts::SQRT_2);
        }
        let mut ab = vec![(0.0, 0.0); MAX_ORDER * (MAX_ORDER + 1) / 2];
        for l in 2..MAX_ORDER {
            for m in 0..l - 1 {
                let (lf, mf) = (l as f64, m as f64);
                let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                let l1 = lf - 1.0;
                let b = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
                ab[l * (l + 1) / 2 + m] = (a, b);
            }
        }
        Tables { diag, ab }
    })
}

/// Writes `Y_0 … Y_{n²−1}` at direction `d` into `out[..n²]` (`out` shorter than `n²`: only
/// its length is written). `d` need not be unit length; a zero or non-finite `d` gives zeros.
pub fn eval(order: ShOrder, d: DVec3, out: &mut [f64]) {
    let len = d.length();
    if !(len > 0.0) || !len.is_finite() {
        out.iter_mut().take(order.coeffs()).for_each(|v| *v = 0.0);
        return;
    }
    eval_unit(order, d / len, out);
}

/// [`eval`] into a new vector.
pub fn eval_vec(order: ShOrder, d: DVec3) -> Vec<f64> {
    let mut v = vec![0.0; order.coeffs()];
    eval(order, d, &mut v);
    v
}

/// [`eval`] for a direction already of unit length (not checked).
pub fn eval_unit(order: ShOrder, d: DVec3, out: &mut [f64]) {
    let n = order.n();
    if out.len() < order.coeffs() {
        let mut full = [0.0; MAX_ORDER * MAX_ORDER];
        eval_unit(order, d, &mut full);
        let k = out.len();
        out.copy_from_slice(&full[..k]);
        return;
    }
    let t = tables();
    let z = d.z;
    // (c, s) = Re, Im of (x + iy)^m.
    let (mut c, mut s) = (1.0, 0.0);
    for m in 0..n {
        let qmm = t.diag[m];
        let (cm, sm) = (c, s);
        let put = |out: &mut [f64], l: usize, q: f64| {
            if m == 0 {
                out[index(l, 0)] = q;
            } else {
                out[index(l, m as i32)] = q * cm;
                out[index(l, -(m as i32))] = q * sm;
            }
        };
        put(out, m, qmm);
        if m + 1 < n {
            let mut q1 = ((2 * m + 3) as f64).sqrt() * z * qmm;
            put(out, m + 1, q1);
            let mut q0 = qmm;
            for l in m + 2..n {
                let (a, b) = t.ab[l * (l + 1) / 2 + m];
                let q = a * (z * q1 - b * q0);
                put(out, l, q);
                q0 = q1;
                q1 = q;
            }
        }
        let cn = c * d.x - s * d.y;
        s = c * d.y + s * d.x;
        c = cn;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::quadrature::SphereQuadrature;
    use crate::sh::SQRT_4PI;

    fn order(n: usize) -> ShOrder {
        ShOrder::new(n).unwrap()
    }

    /// The graphics table of bands 0–3 (graphics sign convention: Y₁,₋₁ ∝ y, Y₁₀ ∝ z, Y₁₁ ∝ x).
    fn table(d: DVec3) -> [f64; 16] {
        let (x, y, z) = (d.x, d.y, d.z);
        [
            0.282_094_791_773_878_1,
            0.488_602_511_902_919_9 * y,
            0.488_602_511_902_919_9 * z,
            0.488_602_511_902_919_9 * x,
            1.092_548_430_592_079_2 * x * y,
            1.092_548_430_592_079_2 * y * z,
            0.315_391_565_252_520_05 * (3.0 * z * z - 1.0),
            1.092_548_430_592_079_2 * x * z,
            0.546_274_215_296_039_6 * (x * x - y * y),
            0.590_043_589_926_643_5 * y * (3.0 * x * x - y * y),
            2.890_611_442_640_554 * x * y * z,
            0.457_045_799_464_465_8 * y * (5.0 * z * z - 1.0),
            0.373_176_332_590_115_4 * z * (5.0 * z * z - 3.0),
            0.457_045_799_464_465_8 * x * (5.0 * z * z - 1.0),
            1.445_305_721_320_277 * z * (x * x - y * y),
            0.590_043_589_926_643_5 * x * (x * x - 3.0 * y * y),
        ]
    }

    #[test]
    fn matches_the_graphics_table_to_order_4() {
        let mut rng = crate::rng::Rng::new(3);
        for _ in 0..500 {
            let d = DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5);
            let y = eval_vec(order(4), d * 3.0);
            let t = table(d.normalize());
            for i in 0..16 {
                assert!((y[i] - t[i]).abs() < 1e-14, "Y_{i}({d}) = {} not {}", y[i], t[i]);
            }
        }
    }

    /// Orthonormal to 1e-10 at order 8 (exact Gauss quadrature of degree 14), and order 10
    /// and 20 too; the quadrature is exact for products of degree ≤ 2(n−1).
    #[test]
    fn orthonormal_by_quadrature() {
        for n in [1usize, 2, 3, 8, 10, 20] {
            let o = order(n);
            let q = SphereQuadrature::exact_for_degree(2 * (n - 1));
            let k = o.coeffs();
            let mut gram = vec![0.0; k * k];
            let mut y = vec![0.0; k];
            for (d, w) in q.dirs.iter().zip(&q.weights) {
                eval(o, *d, &mut y);
                for i in 0..k {
                    for j in 0..k {
                        gram[i * k + j] += w * y[i] * y[j];
                    }
                }
            }
            let worst =
                (0..k * k).map(|ij| (gram[ij] - if ij / k == ij % k { 1.0 } else { 0.0 }).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-10, "order {n}: |YᵀWY − I| = {worst:e}");
        }
    }

    /// A Monte Carlo Gram matrix is orthonormal within its noise too: the quadrature above is
    /// not what makes the basis orthonormal.
    #[test]
    fn orthonormal_under_random_directions() {
        let o = order(4);
        let mut rng = crate::rng::Rng::new(11);
        let n = 200_000;
        let mut gram = [[0.0f64; 16]; 16];
        let mut y = [0.0; 16];
        for _ in 0..n {
            let u = crate::sampling::uniform_sample_sphere(glam::Vec2::new(rng.uniform_f32(), rng.uniform_f32()));
            eval(o, u.as_dvec3(), &mut y);
            for i in 0..16 {
                for j in 0..16 {
                    gram[i][j] += y[i] * y[j] * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (i, row) in gram.iter().enumerate() {
            for (j, g) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 0.03, "({i},{j}): {g}");
            }
        }
    }

    #[test]
    fn degenerate_directions_give_zeros_and_short_outputs_are_filled() {
        let o = order(3);
        for d in [DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 1.0), DVec3::splat(f64::INFINITY)] {
            assert!(eval_vec(o, d).iter().all(|v| *v == 0.0));
        }
        let mut short = [0.0; 4];
        eval(o, DVec3::Z, &mut short);
        assert_eq!(short[0], 1.0 / SQRT_4PI);
        assert!((short[2] - 0.488_602_511_902_919_9).abs() < 1e-15);
        // At the poles the recurrence in (x + iy)^m leaves every m ≠ 0 at exactly 0.
        let y = eval_vec(order(10), -DVec3::Z);
        for l in 0..10 {
            for m in -(l as i32)..=l as i32 {
                if m != 0 {
                    assert_eq!(y[index(l, m)], 0.0);
                }
            }
            let want = (-1f64).powi(l as i32) * ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt();
            assert!((y[index(l, 0)] - want).abs() < 1e-13, "l = {l}");
        }
    }
}
