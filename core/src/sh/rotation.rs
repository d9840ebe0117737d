//! Rotation of SH coefficient vectors by a 3×3 rotation (Ivanic & Ruedenberg 1996, with their
//! 1998 corrections): band `l`'s `(2l+1)²` block is built from band `l−1`'s and band 1's,
//! which in the `(y, z, x)` order of `(Y_1^−1, Y_1^0, Y_1^1)` is the rotation matrix itself.

use super::{check_len, ShError, ShOrder};
use glam::DMat3;

/// The block-diagonal matrix taking the coefficients of `f` to those of `f ∘ R⁻¹`.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    order: ShOrder,
    /// Band `l`'s block, row-major `(2l+1)²`, entry `(m, m′)` at `(m+l)(2l+1) + m′+l`.
    blocks: Vec<Vec<f64>>,
}

/// The determinant of `r`, which must be orthogonal (`RᵀR = I` within `1e-6`, either handedness).
fn check_orthogonal(r: DMat3) -> Result<f64, ShError> {
    if !r.is_finite() {
        return Err(ShError::Invalid("SH rotation: non-finite matrix".into()));
    }
    let rtr = r.transpose() * r;
    let err = (rtr - DMat3::IDENTITY).to_cols_array().iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(err <= 1e-6) {
        return Err(ShError::Invalid(format!("SH rotation: the matrix is not orthogonal (|RᵀR − I| = {err:.3e})")));
    }
    Ok(r.determinant())
}

impl ShRotation {
    /// The SH rotation by `r` (columns: images of x, y, z). An improper `r` (a reflection,
    /// determinant −1) is `−r` followed by the inversion `ω → −ω`, which multiplies band `l`
    /// by `(−1)^l`. Matrices that are not orthogonal are refused.
    pub fn new(order: ShOrder, r: DMat3) -> Result<ShRotation, ShError> {
        let det = check_orthogonal(r)?;
        let (r, parity) = if det < 0.0 { (-r, true) } else { (r, false) };
        let n = order.n();
        let mut blocks = Vec::with_capacity(n);
        blocks.push(vec![1.0]);
        if n > 1 {
            // (y, z, x) order: row/column m ∈ {−1, 0, 1} ↔ axis 1, 2, 0; R[row][col] = col(c)[row].
            let axis = [1usize, 2, 0];
            let mut b1 = vec![0.0; 9];
            for (i, &ai) in axis.iter().enumerate() {
                for (j, &aj) in axis.iter().enumerate() {
                    b1[i * 3 + j] = r.col(aj)[ai];
                }
            }
            blocks.push(b1);
        }
        for l in 2..n {
            let next = band_block(l, &blocks[1], &blocks[l - 1]);
            blocks.push(next);
        }
        if parity {
            for (l, b) in blocks.iter_mut().enumerate() {
                if l % 2 == 1 {
                    b.iter_mut().for_each(|v| *v = -*v);
                }
            }
        }
        Ok(ShRotation { order, blocks })
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    /// Band `l`'s block (row-major, `(2l+1)²`).
    pub fn band(&self, l: usize) -> &[f64] {
        &self.blocks[l]
    }

    /// `out = D(R) f` for the first `n²` coefficients (`f` and `out` at least that long).
    pub fn apply(&self, f: &[f64], out: &mut [f64]) -> Result<(), ShError> {
        self.apply_with(f, out, |acc, a, x| *acc += a * x)
    }

    /// [`apply`](Self::apply) to each of three colour channels stored per coefficient.
    pub fn apply_rgb(&self, f: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), ShError> {
        self.apply_with(f, out, |acc, a, x| {
            for ch in 0..3 {
                acc[ch] += a * x[ch];
            }
        })
    }

    /// `out_r = Σ_c D_rc f_c` band by band, with `mac(acc, D_rc, f_c)` accumulating.
    fn apply_with<T: Copy + Default>(
        &self,
        f: &[T],
        out: &mut [T],
        mac: impl Fn(&mut T, f64, T),
    ) -> Result<(), ShError> {
        let k = self.order.coeffs();
        check_len("SH input", f.len(), k)?;
        check_len("SH output", out.len(), k)?;
        for (l, b) in self.blocks.iter().enumerate() {
            let (w, base) = (2 * l + 1, l * l);
            for r in 0..w {
                let mut acc = T::default();
                for (a, x) in b[r * w..(r + 1) * w].iter().zip(&f[base..base + w]) {
                    mac(&mut acc, *a, *x);
                }
                out[base + r] = acc;
            }
        }
        Ok(())
    }
}

/// Band `l`'s block from band 1's (`r1`) and band `l−1`'s (`prev`).
fn band_block(l: usize, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as i32;
    let w = 2 * l + 1;
    let wp = 2 * l - 1;
    let r1_at = |i: i32, j: i32| r1[((i + 1) * 3 + (j + 1)) as usize];
    let prev_at = |a: i32, b: i32| prev[((a + li - 1) * wp as i32 + (b + li - 1)) as usize];
    // Ivanic–Ruedenberg's P: band 1's row i against band l−1's row a, at column b of band l.
    let p = |i: i32, a: i32, b: i32| {
        if b == li {
            r1_at(i, 1) * prev_at(a, li - 1) - r1_at(i, -1) * prev_at(a, -li + 1)
        } else if b == -li {
            r1_at(i, 1) * prev_at(a, -li + 1) + r1_at(i, -1) * prev_at(a, li - 1)
        } else {
            r1_at(i, 0) * prev_at(a, b)
        }
    };
    let mut out = vec![0.0; w * w];
    for m in -li..=li {
        for n in -li..=li {
            let d = (m == 0) as i32 as f64;
            let am = m.abs() as f64;
            let lf = l as f64;
            let denom = if n.abs() == li { (2.0 * lf) * (2.0 * lf - 1.0) } else { ((li + n) * (li - n)) as f64 };
            let u = (((li + m) * (li - m)) as f64 / denom).sqrt();
            let v = 0.5 * ((1.0 + d) * (lf + am - 1.0) * (lf + am) / denom).sqrt() * (1.0 - 2.0 * d);
            let wc = -0.5 * ((lf - am - 1.0) * (lf - am) / denom).max(0.0).sqrt() * (1.0 - d);
            let mut val = 0.0;
            if u != 0.0 {
                val += u * p(0, m, n);
            }
            if v != 0.0 {
                let vv = if m == 0 {
                    p(1, 1, n) + p(-1, -1, n)
                } else if m > 0 {
                    let d1 = (m == 1) as i32 as f64;
                    p(1, m - 1, n) * (1.0 + d1).sqrt() - if m == 1 { 0.0 } else { p(-1, -m + 1, n) }
                } else {
                    let d1 = (m == -1) as i32 as f64;
                    (if m == -1 { 0.0 } else { p(1, m + 1, n) }) + p(-1, -m - 1, n) * (1.0 + d1).sqrt()
                };
                val += v * vv;
            }
            if wc != 0.0 {
                let ww = if m > 0 { p(1, m + 1, n) + p(-1, -m - 1, n) } else { p(1, m - 1, n) - p(-1, -m + 1, n) };
                val += wc * ww;
            }
            out[((m + li) as usize) * w + (n + li) as usize] = val;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::quadrature::{project, reconstruct, SphereQuadrature};
    use glam::DVec3;

    fn random_rotation(rng: &mut crate::rng::Rng) -> DMat3 {
        let axis = DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5).normalize();
        DMat3::from_axis_angle(axis, 6.0 * rng.uniform_f64())
    }

    /// The SH of a rotated function equals the rotated SH (projection by exact quadrature of
    /// the band-limited function turned by R), for proper and improper rotations.
    #[test]
    fn rotated_projection_equals_rotated_coefficients() {
        let mut rng = crate::rng::Rng::new(5);
        for n in [2usize, 4, 7, 10] {
            let o = ShOrder::new(n).unwrap();
            let c: Vec<f64> = (0..n * n).map(|_| rng.uniform_f64() - 0.5).collect();
            let q = SphereQuadrature::exact_for_degree(2 * (n - 1));
            for k in 0..4 {
                let mut r = random_rotation(&mut rng);
                if k == 3 {
                    r *= DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0));
                }
                let inv = r.transpose();
                let direct = project(o, |d| reconstruct(&c, inv * d), &q);
                let mut rot = vec![0.0; n * n];
                ShRotation::new(o, r).unwrap().apply(&c, &mut rot).unwrap();
                for i in 0..n * n {
                    assert!((rot[i] - direct[i]).abs() < 1e-11, "n {n}, k {k}, i {i}: {} vs {}", rot[i], direct[i]);
                }
            }
        }
    }

    #[test]
    fn rotations_compose_and_preserve_norm() {
        let mut rng = crate::rng::Rng::new(9);
        let o = ShOrder::new(8).unwrap();
        let (a, b) = (random_rotation(&mut rng), random_rotation(&mut rng));
        let c: Vec<f64> = (0..64).map(|_| rng.uniform_f64() - 0.5).collect();
        let (mut t1, mut t2, mut t3) = (vec![0.0; 64], vec![0.0; 64], vec![0.0; 64]);
        ShRotation::new(o, b).unwrap().apply(&c, &mut t1).unwrap();
        ShRotation::new(o, a).unwrap().apply(&t1, &mut t2).unwrap();
        ShRotation::new(o, a * b).unwrap().apply(&c, &mut t3).unwrap();
        for i in 0..64 {
            assert!((t2[i] - t3[i]).abs() < 1e-12);
        }
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
        assert!((norm(&c) - norm(&t3)).abs() < 1e-12);
        let mut id = vec![0.0; 64];
        ShRotation::new(o, DMat3::IDENTITY).unwrap().apply(&c, &mut id).unwrap();
        assert_eq!(id, c);
    }

    #[test]
    fn refuses_non_orthogonal_matrices() {
        let o = ShOrder::new(3).unwrap();
        assert!(ShRotation::new(o, DMat3::from_diagonal(DVec3::new(2.0, 1.0, 1.0))).is_err());
        assert!(ShRotation::new(o, DMat3::from_cols_array(&[f64::NAN; 9])).is_err());
        assert!(ShRotation::new(o, DMat3::IDENTITY).unwrap().apply(&[0.0; 4], &mut [0.0; 9]).is_err());
    }
}
