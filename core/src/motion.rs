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

/// One factor of a [`MovingTransform`].
#[derive(Clone, Debug, PartialEq)]
enum Factor {
    Fixed(DMat4),
    Moving(Box<Motion>),
}

impl Factor {
    fn at(&self, time: f32) -> DMat4 {
        match self {
            Factor::Fixed(m) => *m,
            Factor::Moving(m) => m.at(time),
        }
    }
}

/// A world-from-object transform that moves: the product of an object instance's transform
/// and its shape's, either or both animated (pbrt-v3's `TransformedPrimitive` of an animated
/// shape inside a — possibly animated — instance: each interpolated at the ray's time).
#[derive(Clone, Debug, PartialEq)]
pub struct MovingTransform {
    /// Outermost first: world-from-object = `factors[0] · factors[1] · …`.
    factors: Vec<Factor>,
}

/// How many times [`MovingTransform::motion_bounds`] samples the motion.
const BOUND_SAMPLES: usize = 128;

impl MovingTransform {
    /// `outer · inner`, `None` when neither moves (or a moving one cannot be interpolated:
    /// [`Motion::new`]; the caller then keeps the start transforms).
    pub fn new(outer: &AnimatedTransform, inner: &AnimatedTransform) -> Option<MovingTransform> {
        let factor = |a: &AnimatedTransform| match Motion::new(a) {
            Some(m) => Some(Factor::Moving(Box::new(m))),
            None if a.is_animated() => None,
            None => Some(Factor::Fixed(to_dmat4(&a.start.m))),
        };
        let factors = vec![factor(outer)?, factor(inner)?];
        factors.iter().any(|f| matches!(f, Factor::Moving(_))).then_some(MovingTransform { factors })
    }

    /// World from object at `time`.
    pub fn at(&self, time: f32) -> DMat4 {
        self.factors.iter().fold(DMat4::IDENTITY, |m, f| m * f.at(time))
    }

    /// The times over which it moves (before and after, it stands at its ends).
    fn time_range(&self) -> (f32, f32) {
        self.factors.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), f| match f {
            Factor::Moving(m) => (a.min(m.start_time), b.max(m.end_time)),
            Factor::Fixed(_) => (a, b),
        })
    }

    /// A box holding the object box `[lo, hi]` at every time (pbrt-v3's
    /// `AnimatedTransform::MotionBounds`, conservatively instead of by the derivative's roots):
    /// the union of its transforms' boxes at evenly spaced times, each grown by how far a point
    /// of the box can travel in half a spacing. That distance comes from a bound on the
    /// speed of every point, composed factor by factor: a moving factor turns at the constant
    /// rate of its slerp (×1.01 for the normalised lerp glam uses below acos 0.9995) and
    /// translates and scales linearly.
    pub fn motion_bounds(&self, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
        let (t0, t1) = self.time_range();
        let (mut bmin, mut bmax) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let corners: Vec<DVec3> =
            (0..8).map(|i| DVec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][(i >> 1) & 1], [lo.z, hi.z][i >> 2])).collect();
        for k in 0..=BOUND_SAMPLES {
            let t = t0 + (t1 - t0) * k as f32 / BOUND_SAMPLES as f32;
            let m = self.at(t);
            for c in &corners {
                let p = m.transform_point3(*c);
                bmin = bmin.min(p);
                bmax = bmax.max(p);
            }
        }
        // Innermost first: the radius of the points (about the factor's origin) and their speed.
        let mut radius = corners.iter().map(|c| c.length()).fold(0.0, f64::max);
        let mut speed = 0.0f64;
        for f in self.factors.iter().rev() {
            let (lin, trans, v) = match f {
                Factor::Fixed(m) => (frobenius(&DMat3::from_mat4(*m)), m.w_axis.truncate().length(), 0.0),
                Factor::Moving(m) => {
                    let [a, b] = &m.parts;
                    let dt = (m.end_time - m.start_time) as f64;
                    let s_max = frobenius(&a.s).max(frobenius(&b.s));
                    let angle = a.r.angle_between(b.r).min(std::f64::consts::PI) * 1.01;
                    let v = ((b.t - a.t).length() + (angle * s_max + frobenius(&(b.s - a.s))) * radius) / dt;
                    (s_max, a.t.length().max(b.t.length()), v)
                }
            };
            speed = lin * speed + v;
            radius = lin * radius + trans;
        }
        let grow = speed * (t1 - t0) as f64 / BOUND_SAMPLES as f64 * 0.5;
        // And f32's rounding of the boxes and of the points transformed.
        let slack = grow + 1e-5 * (bmax - bmin).max_element() + 1e-6 * bmin.abs().max(bmax.abs()).max_element();
        (bmin - DVec3::splat(slack), bmax + DVec3::splat(slack))
    }
}

/// The Frobenius norm, a bound on the operator norm.
fn frobenius(m: &DMat3) -> f64 {
    (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt()
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

    /// The motion bounds hold the box at every time — checked densely (4001 times, the box's
    /// corners and a grid over its faces) on a chain of a turning, sliding, growing instance and
    /// a shape spinning the long way round inside it — and are tight: within 6 % of the dense
    /// box's extent on each side (the sampled union plus the travel bound over 1/256 of the motion).
    #[test]
    fn motion_bounds_hold_every_time() {
        let outer = AnimatedTransform {
            start: Transform::translate([1.0, 0.0, 0.0]),
            end: Transform::translate([3.0, 1.0, -1.0])
                .compose(&Transform::rotate(170.0, [0.3, 0.2, 1.0]).unwrap())
                .compose(&Transform::scale([2.0, 1.0, 0.5]).unwrap()),
            start_time: 0.0,
            end_time: 2.0,
        };
        let inner = AnimatedTransform {
            start: Transform::translate([0.0, 0.5, 0.0]),
            end: Transform::translate([0.0, 0.5, 0.0]).compose(&Transform::rotate(150.0, [1.0, 0.0, 0.0]).unwrap()),
            start_time: 0.0,
            end_time: 2.0,
        };
        let m = MovingTransform::new(&outer, &inner).unwrap();
        let (lo, hi) = (DVec3::new(-0.5, -0.2, 0.0), DVec3::new(0.5, 0.3, 1.5));
        let (blo, bhi) = m.motion_bounds(lo, hi);
        let (mut dlo, mut dhi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for k in 0..=4000 {
            let w = m.at(-0.5 + 3.0 * k as f32 / 4000.0);
            for i in 0..=4 {
                for j in 0..=4 {
                    for face in 0..6 {
                        let (a, b) = (i as f64 / 4.0, j as f64 / 4.0);
                        let f = [a, b, (face % 2) as f64];
                        let u = DVec3::new(f[face / 2 % 3], f[(face / 2 + 1) % 3], f[(face / 2 + 2) % 3]);
                        let p = w.transform_point3(lo + (hi - lo) * u);
                        dlo = dlo.min(p);
                        dhi = dhi.max(p);
                    }
                }
            }
        }
        assert!(blo.cmple(dlo).all() && bhi.cmpge(dhi).all(), "{blo} {bhi} vs {dlo} {dhi}");
        let extent = (dhi - dlo).max_element();
        let slack = (dlo - blo).max_element().max((bhi - dhi).max_element()) / extent;
        eprintln!("motion bounds: widest margin beyond the dense sweep {:.2} % of its extent", slack * 100.0);
        assert!(slack < 0.06, "{slack}"); // measured 4.89 %
                                          // Neither moving: no moving transform.
        assert!(MovingTransform::new(&AnimatedTransform::default(), &AnimatedTransform::default()).is_none());
    }
}
