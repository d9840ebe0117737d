//! 4×4 transforms in f64 (the CTM is composed in double precision so that
//! scenes at extreme scales keep their digits), with pbrt-v3's conventions:
//! matrices act on column vectors, `a * b` applies `b` first.

pub type Matrix4 = [[f64; 4]; 4];

pub const IDENTITY: Matrix4 = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// A transform and its inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub m: Matrix4,
    pub m_inv: Matrix4,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

pub fn mul(a: &Matrix4, b: &Matrix4) -> Matrix4 {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    r
}

pub fn transpose(a: &Matrix4) -> Matrix4 {
    let mut r = [[0.0; 4]; 4];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[j][i];
        }
    }
    r
}

/// Inverse by Gauss–Jordan elimination with full pivoting; `None` if singular.
pub fn inverse(a: &Matrix4) -> Option<Matrix4> {
    let mut m = *a;
    let mut inv = IDENTITY;
    for c in 0..4 {
        let mut piv = c;
        for r in c + 1..4 {
            if m[r][c].abs() > m[piv][c].abs() {
                piv = r;
            }
        }
        if m[piv][c] == 0.0 || !m[piv][c].is_finite() {
            return None;
        }
        m.swap(c, piv);
        inv.swap(c, piv);
        let d = 1.0 / m[c][c];
        for j in 0..4 {
            m[c][j] *= d;
            inv[c][j] *= d;
        }
        for r in 0..4 {
            if r != c {
                let f = m[r][c];
                if f != 0.0 {
                    for j in 0..4 {
                        m[r][j] -= f * m[c][j];
                        inv[r][j] -= f * inv[c][j];
                    }
                }
            }
        }
    }
    Some(inv)
}

impl Transform {
    pub const IDENTITY: Transform = Transform { m: IDENTITY, m_inv: IDENTITY };

    /// From a matrix; `None` if it is singular or not finite.
    pub fn from_matrix(m: Matrix4) -> Option<Transform> {
        inverse(&m).map(|m_inv| Transform { m, m_inv })
    }
    pub fn inverse(&self) -> Transform {
        Transform { m: self.m_inv, m_inv: self.m }
    }
    /// `self ∘ other`: applies `other` first.
    pub fn compose(&self, other: &Transform) -> Transform {
        Transform { m: mul(&self.m, &other.m), m_inv: mul(&other.m_inv, &self.m_inv) }
    }
    pub fn translate(d: [f64; 3]) -> Transform {
        let mut m = IDENTITY;
        let mut mi = IDENTITY;
        for i in 0..3 {
            m[i][3] = d[i];
            mi[i][3] = -d[i];
        }
        Transform { m, m_inv: mi }
    }
    /// `None` if a factor is zero (the matrix would be singular).
    pub fn scale(s: [f64; 3]) -> Option<Transform> {
        if s.iter().any(|v| *v == 0.0 || !v.is_finite()) {
            return None;
        }
        let mut m = IDENTITY;
        let mut mi = IDENTITY;
        for i in 0..3 {
            m[i][i] = s[i];
            mi[i][i] = 1.0 / s[i];
        }
        Some(Transform { m, m_inv: mi })
    }
    /// Rotation by `degrees` about `axis` (normalised here), as pbrt-v3's `Rotate`.
    pub fn rotate(degrees: f64, axis: [f64; 3]) -> Option<Transform> {
        let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        if len == 0.0 || !len.is_finite() {
            return None;
        }
        let a = [axis[0] / len, axis[1] / len, axis[2] / len];
        let (s, c) = degrees.to_radians().sin_cos();
        let mut m = IDENTITY;
        m[0][0] = a[0] * a[0] + (1.0 - a[0] * a[0]) * c;
        m[0][1] = a[0] * a[1] * (1.0 - c) - a[2] * s;
        m[0][2] = a[0] * a[2] * (1.0 - c) + a[1] * s;
        m[1][0] = a[0] * a[1] * (1.0 - c) + a[2] * s;
        m[1][1] = a[1] * a[1] + (1.0 - a[1] * a[1]) * c;
        m[1][2] = a[1] * a[2] * (1.0 - c) - a[0] * s;
        m[2][0] = a[0] * a[2] * (1.0 - c) - a[1] * s;
        m[2][1] = a[1] * a[2] * (1.0 - c) + a[0] * s;
        m[2][2] = a[2] * a[2] + (1.0 - a[2] * a[2]) * c;
        Some(Transform { m, m_inv: transpose(&m) })
    }
    /// pbrt-v3's `LookAt`: the camera-from-world transform (left-handed, +z forward).
    /// `None` if `up` is parallel to the view direction or `eye == look`.
    pub fn look_at(eye: [f64; 3], look: [f64; 3], up: [f64; 3]) -> Option<Transform> {
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let norm = |a: [f64; 3]| {
            let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            if l == 0.0 || !l.is_finite() {
                None
            } else {
                Some([a[0] / l, a[1] / l, a[2] / l])
            }
        };
        let dir = norm(sub(look, eye))?;
        let right = norm(cross(norm(up)?, dir))?;
        let new_up = cross(dir, right);
        let mut world_from_camera = IDENTITY;
        for i in 0..3 {
            world_from_camera[i][0] = right[i];
            world_from_camera[i][1] = new_up[i];
            world_from_camera[i][2] = dir[i];
            world_from_camera[i][3] = eye[i];
        }
        Transform::from_matrix(world_from_camera).map(|t| t.inverse())
    }
    // (`#[inline]`, and no `array::map`, which is not inlined: these run per camera ray, from
    // other crates.)
    #[inline]
    pub fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        let mut r = [0.0; 4];
        for (i, v) in r.iter_mut().enumerate() {
            *v = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
        }
        if r[3] == 1.0 {
            [r[0], r[1], r[2]]
        } else {
            [r[0] / r[3], r[1] / r[3], r[2] / r[3]]
        }
    }
    #[inline]
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        let row = |i: usize| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
        [row(0), row(1), row(2)]
    }
    /// Normals transform by the inverse transpose.
    #[inline]
    pub fn apply_normal(&self, n: [f64; 3]) -> [f64; 3] {
        let mi = &self.m_inv;
        let col = |i: usize| mi[0][i] * n[0] + mi[1][i] * n[1] + mi[2][i] * n[2];
        [col(0), col(1), col(2)]
    }
    /// Whether this transform flips handedness (negative determinant of the 3×3 part).
    pub fn swaps_handedness(&self) -> bool {
        let m = &self.m;
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        det < 0.0
    }
}

/// A transform at the shutter's open and close times (`TransformTimes`, default 0 and 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnimatedTransform {
    pub start: Transform,
    pub end: Transform,
    pub start_time: f32,
    pub end_time: f32,
}

impl Default for AnimatedTransform {
    fn default() -> Self {
        AnimatedTransform::fixed(Transform::IDENTITY)
    }
}

impl AnimatedTransform {
    pub fn fixed(t: Transform) -> Self {
        AnimatedTransform { start: t, end: t, start_time: 0.0, end_time: 1.0 }
    }
    pub fn is_animated(&self) -> bool {
        self.start != self.end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Matrix4, b: &Matrix4) -> bool {
        a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn inverse_of_product_is_identity() {
        let t = Transform::translate([1.0, -2.0, 3.0])
            .compose(&Transform::rotate(33.0, [1.0, 2.0, 3.0]).unwrap())
            .compose(&Transform::scale([2.0, 0.5, -4.0]).unwrap());
        assert!(close(&mul(&t.m, &t.m_inv), &IDENTITY));
        assert!(close(&inverse(&t.m).unwrap(), &t.m_inv));
        assert!(t.swaps_handedness());
    }

    #[test]
    fn look_at_maps_eye_to_origin_and_look_to_plus_z() {
        let t = Transform::look_at([0.0, 4.5, -7.0], [0.0, 0.6, 0.0], [0.0, 1.0, 0.0]).unwrap();
        let o = t.apply_point([0.0, 4.5, -7.0]);
        assert!(o.iter().all(|v| v.abs() < 1e-12));
        let l = t.apply_point([0.0, 0.6, 0.0]);
        assert!(l[0].abs() < 1e-12 && l[1].abs() < 1e-12 && l[2] > 0.0);
        assert!(Transform::look_at([0.0; 3], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]).is_none());
    }
}
