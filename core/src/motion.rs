//! pbrt-v3's `AnimatedTransform`: a transform moving between two keyframes (`ActiveTransform`
//! `StartTime`/`EndTime`, at the `TransformTimes`), interpolated at a ray's time by
//! decomposing each keyframe into translation, rotation and scale (`Decompose`: the polar
//! decomposition `M = R S` by iterating `R ← (R + R⁻ᵀ)/2`), then lerping the translations,
//! slerping the rotations along the shorter arc and lerping the scale matrices.

use glam::{DMat3, DMat4, DQuat, DVec3, DVec4};
use penumbra_parser::{AnimatedTransform, Matrix4};

/// One keyframe's decomposition.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Parts {
    t: DVec3,
    r: DQuat,
    s: DMat3,
}

/// A transform that moves between two times; `None` from [`Motion::new`] when it does not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    start: DMat4,
    end: DMat4,
    start_time: f32,
    end_time: f32,
    parts: [Parts; 2],
}

/// `m` (row-major, pbrt-v3's layout) as a glam matrix.
pub fn to_dmat4(m: &Matrix4) -> DMat4 {
    DMat4::from_cols_array_2d(m).transpose()
}

/// pbrt-v3's `AnimatedTransform::Decompose` (perspective parts ignored, as there).
fn decompose(m: &DMat4) -> Parts {
    let t = m.w_axis.truncate();
    let m3 = DMat3::from_mat4(*m);
    let mut r = m3;
    for _ in 0..100 {
        let next = (r + r.transpose().inverse()) * 0.5;
        let norm =
            (0..3).map(|i| (0..3).map(|j| (r.col(j)[i] - next.col(j)[i]).abs()).sum::<f64>()).fold(0.0, f64::max);
        r = next;
        if norm <= 1e-4 || !norm.is_finite() {
            break;
        }
    }
    // A mirroring keyframe gives an improper R; -R is a rotation and M = (-R)(-S).
    if r.determinant() < 0.0 {
        r = -r;
    }
    let s = r.inverse() * m3;
    Parts { t, r: DQuat::from_mat3(&r).normalize(), s }
}

impl Motion {
    /// The motion of `a`; `None` when its keyframes are equal (or a keyframe is singular, as
    /// pbrt-v3 then has no decomposition either: the caller keeps the start transform).
    pub fn new(a: &AnimatedTransform) -> Option<Motion> {
        if !a.is_animated() {
            return None;
        }
        let (start, end) = (to_dmat4(&a.start.m), to_dmat4(&a.end.m));
        let parts = [decompose(&start), decompose(&end)];
        let finite = |p: &Parts| p.t.is_finite() && p.r.is_finite() && p.s.is_finite();
        if !parts.iter().all(finite) || !(a.end_time > a.start_time) {
            return None;
        }
        Some(Motion { start, end, start_time: a.start_time, end_time: a.end_time, parts })
    }

    /// The transform at `time` (pbrt-v3's `AnimatedTransform::Interpolate`): the keyframes at
    /// and beyond their times, the interpolation between.
    pub fn at(&self, time: f32) -> DMat4 {
        if time <= self.start_time {
            return self.start;
        }
        if time >= self.end_time {
            return self.end;
        }
        let dt = ((time - self.start_time) / (self.end_time - self.start_time)) as f64;
        let [a, b] = &self.parts;
        let t = a.t.lerp(b.t, dt);
        // glam's slerp takes the shorter arc, as pbrt-v3 does by flipping the second
        // quaternion; both lerp (normalised) when the rotations are within acos(0.9995).
        let r = a.r.slerp(b.r, dt);
        let s = a.s * (1.0 - dt) + b.s * dt;
        let lin = DMat3::from_quat(r) * s;
        DMat4::from_cols(lin.x_axis.extend(0.0), lin.y_axis.extend(0.0), lin.z_axis.extend(0.0), DVec4::from((t, 1.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_parser::Transform;

    fn close(a: DMat4, b: DMat4, tol: f64) -> bool {
        a.to_cols_array().iter().zip(b.to_cols_array().iter()).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// The keyframes come back at and beyond their times; in between, a rotation about one
    /// axis turns at a constant rate (half the angle at the half time) while translation and
    /// scale move linearly — what pbrt-v3's decomposition gives in closed form.
    #[test]
    fn interpolates_translation_rotation_and_scale() {
        let start = Transform::translate([1.0, 2.0, 3.0]).compose(&Transform::scale([2.0, 1.0, 1.0]).unwrap());
        let end = Transform::translate([3.0, 2.0, -1.0])
            .compose(&Transform::rotate(120.0, [0.0, 0.0, 1.0]).unwrap())
            .compose(&Transform::scale([4.0, 1.0, 1.0]).unwrap());
        let a = AnimatedTransform { start, end, start_time: 1.0, end_time: 3.0 };
        let m = Motion::new(&a).unwrap();
        assert!(close(m.at(0.5), to_dmat4(&start.m), 0.0));
        assert!(close(m.at(1.0), to_dmat4(&start.m), 0.0));
        assert!(close(m.at(3.5), to_dmat4(&end.m), 0.0));
        let half = Transform::translate([2.0, 2.0, 1.0])
            .compose(&Transform::rotate(60.0, [0.0, 0.0, 1.0]).unwrap())
            .compose(&Transform::scale([3.0, 1.0, 1.0]).unwrap());
        assert!(close(m.at(2.0), to_dmat4(&half.m), 1e-6), "{:?}", m.at(2.0));
        // A rotation beyond 180° takes the shorter way round (-100° about z, not +260°).
        let b = AnimatedTransform {
            start: Transform::IDENTITY,
            end: Transform::rotate(260.0, [0.0, 0.0, 1.0]).unwrap(),
            start_time: 0.0,
            end_time: 1.0,
        };
        let quarter = Motion::new(&b).unwrap().at(0.25);
        assert!(close(quarter, to_dmat4(&Transform::rotate(-25.0, [0.0, 0.0, 1.0]).unwrap().m), 1e-6));
        assert!(Motion::new(&AnimatedTransform::fixed(start)).is_none());
    }
}
