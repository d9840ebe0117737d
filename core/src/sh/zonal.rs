//! Zonal harmonics: functions symmetric about +z, one coefficient `g_l` (of `Y_l^0`) per band.

use super::{basis, check_len, index, ShError, ShOrder, MAX_ORDER};
use glam::DVec3;
use std::f64::consts::PI;

/// `√((2l+1)/4π)`, the value of `Y_l^0` at +z.
#[inline]
fn y_l0_at_pole(l: usize) -> f64 {
    ((2 * l + 1) as f64 / (4.0 * PI)).sqrt()
}

/// Legendre polynomials `P_0(x) … P_{n−1}(x)` into `out[..n]`.
pub fn legendre(x: f64, out: &mut [f64]) {
    let n = out.len();
    if n == 0 {
        return;
    }
    out[0] = 1.0;
    if n > 1 {
        out[1] = x;
    }
    for l in 2..n {
        out[l] = ((2 * l - 1) as f64 * x * out[l - 1] - (l - 1) as f64 * out[l - 2]) / l as f64;
    }
}

/// The clamped cosine `max(0, cos θ)` as ZH: `g_l = 2π √((2l+1)/4π) ∫₀¹ x P_l(x) dx`, i.e.
/// `√π/2, √(π/3)`, then 0 for odd `l` and, for even `l ≥ 2`,
/// `2π √((2l+1)/4π) (−1)^{l/2−1} / ((l+2)(l−1)) · l! / (2^l ((l/2)!)²)` (Ramamoorthi–Hanrahan).
/// Its dot product with the constant function **1** is `π`.
pub fn clamped_cosine(order: ShOrder) -> Vec<f64> {
    (0..order.n())
        .map(|l| match l {
            0 => PI.sqrt() / 2.0,
            1 => (PI / 3.0).sqrt(),
            l if l % 2 == 1 => 0.0,
            l => {
                // l! / (2^l ((l/2)!)²) = Π_{k=1}^{l/2} (2k−1)/(2k), without overflow.
                let central: f64 = (1..=l / 2).map(|k| (2 * k - 1) as f64 / (2 * k) as f64).product();
                let sign = if (l / 2) % 2 == 1 { 1.0 } else { -1.0 };
                2.0 * PI * y_l0_at_pole(l) * sign / ((l + 2) as f64 * (l - 1) as f64) * central
            }
        })
        .collect()
}

/// The indicator of the cap `θ ≤ theta` about +z as ZH: `g_0 = √π (1 − cos θ)` and, for
/// `l ≥ 1`, `g_l = 2π √((2l+1)/4π) (P_{l−1}(cos θ) − P_{l+1}(cos θ))/(2l+1)`, evaluated as
/// `2π √((2l+1)/4π) sin²θ P_l′(cos θ) / (l(l+1))` (the same by Legendre's identities) so that
/// small caps keep their digits. `theta` is clamped to [0, π].
pub fn cap(order: ShOrder, theta: f64) -> Vec<f64> {
    let mut out = vec![0.0; order.n()];
    cap_into(theta, &mut out);
    out
}

/// [`cap`] into `out` (its length is the order).
pub fn cap_into(theta: f64, out: &mut [f64]) {
    let theta = if theta.is_nan() { 0.0 } else { theta.clamp(0.0, PI) };
    let x = theta.cos();
    let sin2 = theta.sin().powi(2);
    let half = (0.5 * theta).sin();
    let n = out.len();
    // P_l and P_l′ by P′_{l+1} = P′_{l−1} + (2l+1) P_l.
    let mut p = [0.0; MAX_ORDER + 2];
    legendre(x, &mut p[..(n + 1).min(MAX_ORDER + 2)]);
    let (mut dprev, mut dcur) = (0.0, 1.0); // P_0′, P_1′
    for (l, o) in out.iter_mut().enumerate() {
        *o = match l {
            0 => PI.sqrt() * 2.0 * half * half,
            _ => {
                if l >= 2 {
                    let d = dprev + (2 * l - 1) as f64 * p[l - 1];
                    dprev = dcur;
                    dcur = d;
                }
                2.0 * PI * y_l0_at_pole(l) * sin2 * dcur / (l * (l + 1)) as f64
            }
        };
    }
}

/// A zonal vector as a full SH vector about +z (`out[l(l+1)] = zh[l]`, the rest 0).
pub fn zh_to_sh(zh: &[f64], out: &mut [f64]) -> Result<(), ShError> {
    check_len("SH output", out.len(), zh.len() * zh.len())?;
    out.iter_mut().for_each(|v| *v = 0.0);
    for (l, g) in zh.iter().enumerate() {
        out[index(l, 0)] = *g;
    }
    Ok(())
}

/// The zonal vector `zh` (order = its length) turned from +z to `axis`:
/// `out_lm = √(4π/(2l+1)) zh_l Y_lm(axis)`. `axis` need not be unit length.
pub fn rotate_zh(zh: &[f64], axis: DVec3, out: &mut [f64]) -> Result<(), ShError> {
    let order = ShOrder::new(zh.len())?;
    check_len("SH output", out.len(), order.coeffs())?;
    basis::eval(order, axis, out);
    scale_by_bands(zh, out);
    Ok(())
}

/// `out += scale · rotate_zh(zh, axis)`, with `y` as scratch for the basis at `axis` (both at
/// least `n²` long): the inner loop of summing many turned blockers (`shexp`).
pub fn add_rotated_zh(zh: &[f64], axis: DVec3, scale: f64, y: &mut [f64], out: &mut [f64]) -> Result<(), ShError> {
    let order = ShOrder::new(zh.len())?;
    check_len("SH output", out.len(), order.coeffs())?;
    check_len("SH scratch", y.len(), order.coeffs())?;
    basis::eval(order, axis, y);
    for (l, g) in zh.iter().enumerate() {
        let k = scale * g * (4.0 * PI / (2 * l + 1) as f64).sqrt();
        for i in l * l..(l + 1) * (l + 1) {
            out[i] += k * y[i];
        }
    }
    Ok(())
}

fn scale_by_bands(zh: &[f64], out: &mut [f64]) {
    for (l, g) in zh.iter().enumerate() {
        let k = g * (4.0 * PI / (2 * l + 1) as f64).sqrt();
        out[l * l..(l + 1) * (l + 1)].iter_mut().for_each(|v| *v *= k);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::quadrature::{project, SphereQuadrature};
    use crate::sh::rotation::ShRotation;
    use crate::sh::SQRT_4PI;
    use glam::DMat3;

    fn o(n: usize) -> ShOrder {
        ShOrder::new(n).unwrap()
    }

    #[test]
    fn clamped_cosine_constants_and_dot_with_one_is_pi() {
        let h = clamped_cosine(o(8));
        let want =
            [0.886_226_925_452_758, 1.023_326_707_946_488_5, 0.495_415_912_200_751_6, 0.0, -0.110_778_365_681_594_8];
        for (a, b) in h.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        assert!((h[6] - 0.049_927).abs() < 1e-6);
        assert!((h[0] * SQRT_4PI - PI).abs() < 1e-14);
        // Against quadrature of max(0, z) itself (a kink at z = 0: a fine rule, loose bound).
        let q = SphereQuadrature::product(2000, 1);
        let p = project(o(8), |d| d.z.max(0.0), &q);
        for l in 0..8 {
            assert!((p[index(l, 0)] - h[l]).abs() < 1e-5, "l = {l}: {} vs {}", p[index(l, 0)], h[l]);
        }
    }

    /// Closed form vs the digest's reproduction (θ = 0.5 and 1.0) and vs brute-force quadrature.
    #[test]
    fn cap_matches_closed_form_and_quadrature() {
        let c = cap(o(4), 0.5);
        for (a, b) in c.iter().zip(&[0.2170, 0.3528, 0.3997, 0.3841]) {
            assert!((a - b).abs() < 6e-5, "{a} vs {b}");
        }
        let c = cap(o(4), 1.0);
        for (a, b) in c.iter().zip(&[0.8148, 1.0869, 0.7581, 0.1908]) {
            assert!((a - b).abs() < 6e-5, "{a} vs {b}");
        }
        for theta in [1e-3, 0.1, 0.5, 1.0, 2.0, 3.0] {
            let cf = cap(o(12), theta);
            // The (P_{l−1} − P_{l+1})/(2l+1) form, for l ≥ 1.
            let mut p13 = [0.0; 14];
            legendre(theta.cos(), &mut p13);
            for l in 1..12 {
                let direct = 2.0 * PI * y_l0_at_pole(l) * (p13[l - 1] - p13[l + 1]) / (2 * l + 1) as f64;
                assert!((cf[l] - direct).abs() < 1e-12 * (1.0 + theta.powi(-2)), "θ {theta} l {l}");
            }
            // Midpoint quadrature in z over the cap with 2M points.
            let (z0, nq) = (theta.cos(), 2_000_000);
            let dz = (1.0 - z0) / nq as f64;
            let mut q = [0.0; 12];
            let mut pl = [0.0; 12];
            for k in 0..nq {
                legendre(z0 + (k as f64 + 0.5) * dz, &mut pl);
                for l in 0..12 {
                    q[l] += 2.0 * PI * y_l0_at_pole(l) * pl[l] * dz;
                }
            }
            for l in 0..12 {
                assert!((cf[l] - q[l]).abs() < 1e-8, "θ {theta}, l {l}: {} vs {}", cf[l], q[l]);
            }
        }
        // A full cap is the constant 1, an empty one 0.
        let full = cap(o(6), PI);
        assert!((full[0] - SQRT_4PI).abs() < 1e-14 && full[1..].iter().all(|v| v.abs() < 1e-14));
        assert!(cap(o(6), 0.0).iter().all(|v| *v == 0.0));
    }

    /// ZH rotation against direct projection of the rotated function (a polynomial: exact
    /// Gauss quadrature), and against the general rotation.
    #[test]
    fn zh_rotation_matches_projection_and_general_rotation() {
        let n = 6;
        let zh: Vec<f64> = (0..n).map(|l| 1.0 / (1.0 + l as f64)).collect();
        let mut full = vec![0.0; n * n];
        zh_to_sh(&zh, &mut full).unwrap();
        let q = SphereQuadrature::exact_for_degree(2 * (n - 1));
        for axis in [DVec3::new(0.3, -0.5, 0.8), DVec3::X, -DVec3::Z, DVec3::new(-1.0, 2.0, -0.1)] {
            let a = axis.normalize();
            let mut rotated = vec![0.0; n * n];
            rotate_zh(&zh, axis, &mut rotated).unwrap();
            // The zonal function about `a`: Σ zh_l Y_l0(a·d measured from a).
            let f = |d: DVec3| {
                let mut p = vec![0.0; n];
                legendre(a.dot(d), &mut p);
                (0..n).map(|l| zh[l] * y_l0_at_pole(l) * p[l]).sum::<f64>()
            };
            let direct = project(o(n), f, &q);
            for i in 0..n * n {
                assert!((rotated[i] - direct[i]).abs() < 1e-12, "axis {axis}, i {i}");
            }
            // A rotation taking +z to `a`.
            let r = rotation_from_z(a);
            let mut general = vec![0.0; n * n];
            ShRotation::new(o(n), r).unwrap().apply(&full, &mut general).unwrap();
            for i in 0..n * n {
                assert!((rotated[i] - general[i]).abs() < 1e-12, "axis {axis}, i {i}");
            }
            let mut acc = vec![1.0; n * n];
            let mut y = vec![0.0; n * n];
            add_rotated_zh(&zh, axis, 2.0, &mut y, &mut acc).unwrap();
            for i in 0..n * n {
                assert!((acc[i] - 1.0 - 2.0 * rotated[i]).abs() < 1e-12);
            }
        }
        assert!(rotate_zh(&zh, DVec3::Z, &mut [0.0; 4]).is_err());
    }

    /// A rotation taking +z to the unit vector `a` (columns: the images of x, y, z).
    pub(crate) fn rotation_from_z(a: DVec3) -> DMat3 {
        let t = if a.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let x = (t - a * a.dot(t)).normalize();
        DMat3::from_cols(x, a.cross(x), a)
    }
}
