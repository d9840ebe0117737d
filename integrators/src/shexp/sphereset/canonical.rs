//! The canonical frame a mesh is fitted in, and tie-robust choices, so that a uniformly scaled
//! or turned mesh gets the same spheres (scaled and turned) up to rounding.
//!
//! The frame: origin at the vertices' mean, unit length their largest distance from it, axes
//! the principal axes of the vertices (eigenvectors of their covariance, largest variance
//! first). Everything the frame picks from the data is picked by a rule that turns and scales
//! with the mesh: each axis's sign points at the vertex farthest along it; where eigenvalues
//! coincide (relative gap below [`DEGENERATE`]: a surface of revolution, a cube, a regular
//! tetrahedron) the axes inside the degenerate plane or space point at the farthest vertex
//! (then the one farthest from that axis). Ties (symmetric shapes have many) go to the lowest
//! vertex index, which the transform does not change ([`argmax_tol`]).

use super::Sphere;
use glam::{DMat3, DVec3};

/// Eigenvalues closer than this fraction of the largest count as equal.
pub const DEGENERATE: f64 = 1e-3;
/// Distances (in units of the frame, i.e. of the mesh's extent) closer than this tie.
pub const TIE: f64 = 1e-5;

/// The lowest index whose value is within `tol` of the largest (non-finite values other than
/// `+∞` are never chosen). Unlike a plain arg-max, the choice among values that differ only by
/// rounding does not depend on the rounding.
pub fn argmax_tol(values: impl IntoIterator<Item = f64> + Clone, tol: f64) -> Option<usize> {
    let max = values.clone().into_iter().filter(|v| !v.is_nan()).fold(f64::NEG_INFINITY, f64::max);
    if max == f64::NEG_INFINITY {
        return None;
    }
    values.into_iter().position(|v| v >= max - tol)
}

/// The lowest index whose value is within `tol` of the smallest (see [`argmax_tol`]).
pub fn argmin_tol(values: impl IntoIterator<Item = f64> + Clone, tol: f64) -> Option<usize> {
    let min = values.clone().into_iter().filter(|v| !v.is_nan()).fold(f64::INFINITY, f64::min);
    if min == f64::INFINITY {
        return None;
    }
    values.into_iter().position(|v| v <= min + tol)
}

/// A similarity transform `world = origin + scale · axes · local`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub origin: DVec3,
    /// Orthonormal columns (possibly a reflection).
    pub axes: DMat3,
    pub scale: f64,
}

impl Frame {
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.axes.transpose() * (p - self.origin) / self.scale
    }

    pub fn to_world(&self, p: DVec3) -> DVec3 {
        self.origin + self.axes * (p * self.scale)
    }

    pub fn sphere_to_world(&self, s: Sphere) -> Sphere {
        Sphere { center: self.to_world(s.center), radius: s.radius * self.scale }
    }

    /// The canonical frame of `points` (see the module doc). Degenerate input (no points, all
    /// at one place, non-finite) gives a translation-only frame of unit scale.
    pub fn of(points: &[DVec3]) -> Frame {
        let n = points.len().max(1) as f64;
        let origin = points.iter().sum::<DVec3>() / n;
        let scale = points.iter().map(|p| p.distance(origin)).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite() && origin.is_finite()) {
            return Frame {
                origin: if origin.is_finite() { origin } else { DVec3::ZERO },
                axes: DMat3::IDENTITY,
                scale: 1.0,
            };
        }
        let local: Vec<DVec3> = points.iter().map(|p| (*p - origin) / scale).collect();
        let mut cov = [[0.0f64; 3]; 3];
        for q in &local {
            for (i, row) in cov.iter_mut().enumerate() {
                for (j, c) in row.iter_mut().enumerate() {
                    *c += q[i] * q[j];
                }
            }
        }
        cov.iter_mut().flatten().for_each(|c| *c /= n);
        let (values, vectors) = jacobi3(cov);
        let gap = DEGENERATE * values[0].abs().max(f64::MIN_POSITIVE);
        let mut axes: Vec<DVec3> = Vec::with_capacity(3);
        let mut i = 0;
        while i < 3 {
            let mut j = i + 1;
            while j < 3 && values[j - 1] - values[j] <= gap {
                j += 1;
            }
            match j - i {
                1 => axes.push(signed(vectors[i], &local)),
                2 => {
                    let (u, w) = (vectors[i], vectors[i + 1]);
                    let a = farthest_direction(&local, |q| q.dot(u) * u + q.dot(w) * w).unwrap_or(u);
                    let b = signed((u * a.dot(w) - w * a.dot(u)).normalize_or(w), &local);
                    axes.extend([a, b]);
                }
                _ => {
                    let a = farthest_direction(&local, |q| q).unwrap_or(DVec3::X);
                    let b =
                        farthest_direction(&local, |q| q - a * q.dot(a)).unwrap_or_else(|| a.any_orthonormal_vector());
                    let c = signed(a.cross(b).normalize(), &local);
                    axes.extend([a, b, c]);
                }
            }
            i = j;
        }
        Frame { origin, axes: DMat3::from_cols(axes[0], axes[1], axes[2]), scale }
    }
}

/// `v` or `−v`, whichever points at the vertex farthest along the line (ties: lowest index).
fn signed(v: DVec3, local: &[DVec3]) -> DVec3 {
    match argmax_tol(local.iter().map(|q| q.dot(v).abs()), TIE) {
        Some(i) if local[i].dot(v) < 0.0 => -v,
        _ => v,
    }
}

/// The unit direction of the longest `part(q)` (ties: lowest index); `None` if all vanish.
fn farthest_direction(local: &[DVec3], part: impl Fn(DVec3) -> DVec3) -> Option<DVec3> {
    let i = argmax_tol(local.iter().map(|q| part(*q).length()), TIE)?;
    let d = part(local[i]);
    (d.length() > TIE).then(|| d.normalize())
}

/// Eigenvalues (descending) and unit eigenvectors of a symmetric 3×3 matrix (cyclic Jacobi).
fn jacobi3(m: [[f64; 3]; 3]) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..64 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let diag = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if !(off > 1e-300 && off > 1e-17 * diag) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J with J the rotation in the (p, q) plane.
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * rp[k] - s * rq[k];
                a[q][k] = s * rp[k] + c * rq[k];
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&x, &y| a[y][y].total_cmp(&a[x][x]));
    let values = order.map(|i| a[i][i]);
    let vectors = order.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize());
    (values, vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobi_diagonalises() {
        let m = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 1.0]];
        let (vals, vecs) = jacobi3(m);
        for (l, v) in vals.iter().zip(vecs) {
            let mv = DVec3::new(
                m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
            );
            assert!((mv - v * *l).length() < 1e-12, "{mv} {v} {l}");
        }
        assert!(vals[0] >= vals[1] && vals[1] >= vals[2]);
    }

    #[test]
    fn ties_go_to_the_lowest_index() {
        assert_eq!(argmax_tol([1.0, 3.0, 3.0 + 1e-9, 2.0], 1e-6), Some(1));
        assert_eq!(argmax_tol([1.0, 3.0 - 1e-9, 3.0, 2.0], 1e-6), Some(1));
        assert_eq!(argmin_tol([f64::NAN, 2.0, 1.0, 1.0 - 1e-9], 1e-6), Some(2));
        assert_eq!(argmax_tol(std::iter::empty::<f64>(), 1e-6), None);
    }
}
