//! Rays, frames and pbrt-v3's conservative floating-point error bounds for
//! spawning rays off surfaces without self-intersection.

use glam::{DVec3, IVec2, Vec3};

/// A ray `o + t d` for `t` in `(0, t_max)`, at `time` (pbrt-v3's `Ray::time`: camera rays
/// take theirs in the shutter interval, rays spawned from a surface its hit's time; moving
/// shapes are intersected where they are at that time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub t_max: f32,
    pub time: f32,
}

impl Ray {
    /// A ray at time 0.
    pub fn new(o: Vec3, d: Vec3, t_max: f32) -> Self {
        Ray { o, d, t_max, time: 0.0 }
    }
    /// This ray at `time`.
    #[inline]
    pub fn at_time(self, time: f32) -> Self {
        Ray { time, ..self }
    }
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// The rays one pixel step away in x and in y that travel beside a [`RayDifferential`]'s
/// main ray (pbrt-v3's `rxOrigin`, `rxDirection`, `ryOrigin`, `ryDirection`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayOffsets {
    pub rx_o: Vec3,
    pub rx_d: Vec3,
    pub ry_o: Vec3,
    pub ry_d: Vec3,
}

/// A ray with, optionally, its offset rays (pbrt-v3's `RayDifferential`): camera rays have
/// them (scaled to the pixel's sample spacing), rays perfectly specular bounces spawn from a
/// ray with offsets carry them on, every other ray has none. Dereferences to the main ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayDifferential {
    pub ray: Ray,
    pub offsets: Option<RayOffsets>,
}

impl RayDifferential {
    /// A ray without offset rays.
    pub fn plain(ray: Ray) -> Self {
        RayDifferential { ray, offsets: None }
    }

    /// pbrt-v3's `ScaleDifferentials`: moves the offset rays' origins and directions towards
    /// the main ray's by the factor `s` (`1/√spp` for camera rays).
    pub fn scale_offsets(&mut self, s: f32) {
        let (o, d) = (self.ray.o, self.ray.d);
        if let Some(r) = &mut self.offsets {
            r.rx_o = o + (r.rx_o - o) * s;
            r.ry_o = o + (r.ry_o - o) * s;
            r.rx_d = d + (r.rx_d - d) * s;
            r.ry_d = d + (r.ry_d - d) * s;
        }
    }
}

impl From<Ray> for RayDifferential {
    fn from(ray: Ray) -> Self {
        RayDifferential::plain(ray)
    }
}

impl AsRef<Ray> for Ray {
    fn as_ref(&self) -> &Ray {
        self
    }
}

impl AsRef<Ray> for RayDifferential {
    fn as_ref(&self) -> &Ray {
        &self.ray
    }
}

impl std::ops::Deref for RayDifferential {
    type Target = Ray;
    fn deref(&self) -> &Ray {
        &self.ray
    }
}

/// pbrt-v3's γ(n) = nε / (1 − nε) with ε = 2⁻²⁴.
#[inline]
pub fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5 * n as f32;
    e / (1.0 - e)
}

#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// Moves `p` (with absolute error bound `p_error`) off the surface with normal `n`,
/// to the side `w` points to, far enough that the rounded origin is strictly on that side.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = d * n;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    Vec3::new(step_float(po.x, offset.x), step_float(po.y, offset.y), step_float(po.z, offset.z))
}

/// [`next_float_up`] of `v` where `toward > 0`, [`next_float_down`] where `toward < 0`, `v`
/// otherwise: the same bits, without branches on the signs (a ray's offset points either way,
/// so branches on it are mispredicted half the time). Floats are stepped as integers in
/// sign-magnitude order, clamped at the infinities.
#[inline]
pub fn step_float(v: f32, toward: f32) -> f32 {
    let dir = (toward > 0.0) as i32 - (toward < 0.0) as i32;
    let bits = v.to_bits() as i32;
    let magnitude = bits & 0x7fff_ffff;
    let key = if bits < 0 { -magnitude } else { magnitude };
    let k = (key + dir).clamp(-0x7f80_0000, 0x7f80_0000);
    // A step to zero from below is -0 (as next_float_up gives it).
    let negative = k < 0 || (k == 0 && key < 0);
    let stepped = f32::from_bits(k.unsigned_abs() | ((negative as u32) << 31));
    if dir == 0 || v.is_nan() {
        v
    } else {
        stepped
    }
}

/// An orthonormal frame; `to_local`/`from_local` map between world and frame coordinates (z = normal).
/// `Frame` (f32) is the shading frame of a surface interaction; `Frame<DVec3>` is the f64 frame
/// the analytic methods work in (LTC shading: x towards the outgoing direction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame<V = Vec3> {
    pub x: V,
    pub y: V,
    pub z: V,
}

impl Frame {
    /// A frame around unit vector `n` (Duff et al.'s branchless construction).
    pub fn from_z(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { x, y, z: n }
    }
    /// A frame with z = `n` and x along `s` projected onto the plane (falls back to `from_z`).
    pub fn from_zx(n: Vec3, s: Vec3) -> Frame {
        let y = n.cross(s);
        let l = y.length();
        if !(l > 1e-12) || !l.is_finite() {
            return Frame::from_z(n);
        }
        let y = y / l;
        Frame { x: y.cross(n), y, z: n }
    }
}

impl Frame<DVec3> {
    /// The frame for normal `n` and outgoing direction `wo`: z = `n` normalised (+z if it is
    /// zero), x = `wo`'s projection onto the tangent plane (any tangent if `wo ∥ n`), y = z × x.
    pub fn toward(n: DVec3, wo: DVec3) -> Self {
        let z = n.normalize_or_zero();
        let z = if z == DVec3::ZERO { DVec3::Z } else { z };
        let t = wo - z * z.dot(wo);
        let x = if t.length_squared() > 1e-24 * wo.length_squared().max(1e-300) {
            t.normalize()
        } else {
            orthonormal_basis(z).0
        };
        Frame { x, y: z.cross(x), z }
    }
}

macro_rules! frame_maps {
    ($v:ty) => {
        impl Frame<$v> {
            /// World direction to frame coordinates.
            #[inline]
            pub fn to_local(&self, v: $v) -> $v {
                <$v>::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
            }
            /// Frame coordinates to a world direction.
            #[inline]
            pub fn from_local(&self, v: $v) -> $v {
                self.x * v.x + self.y * v.y + self.z * v.z
            }
        }
    };
}
frame_maps!(Vec3);
frame_maps!(DVec3);

/// Two unit vectors completing `n` to a right-handed orthonormal frame (f64; Duff et al.).
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), DVec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// `n` flipped, if needed, to lie in the hemisphere of `v`.
#[inline]
pub fn face_forward(n: Vec3, v: Vec3) -> Vec3 {
    if n.dot(v) < 0.0 {
        -n
    } else {
        n
    }
}

/// Axis-aligned bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds3 {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Bounds3 {
    fn default() -> Self {
        Bounds3::EMPTY
    }
}

impl Bounds3 {
    pub const EMPTY: Bounds3 = Bounds3 { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    pub fn extend(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(&self, o: &Bounds3) -> Bounds3 {
        Bounds3 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    pub fn diagonal(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// Centre and radius of a sphere enclosing the bounds.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if self.is_empty() {
            return (Vec3::ZERO, 0.0);
        }
        let c = self.center();
        (c, (self.max - c).length())
    }
}

/// Half-open integer rectangle `[min, max)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bounds2i {
    pub min: IVec2,
    pub max: IVec2,
}

impl Bounds2i {
    pub fn new(min: IVec2, max: IVec2) -> Self {
        Bounds2i { min, max }
    }
    pub fn is_empty(&self) -> bool {
        self.max.x <= self.min.x || self.max.y <= self.min.y
    }
    pub fn width(&self) -> i32 {
        (self.max.x - self.min.x).max(0)
    }
    pub fn height(&self) -> i32 {
        (self.max.y - self.min.y).max(0)
    }
    pub fn area(&self) -> i64 {
        self.width() as i64 * self.height() as i64
    }
    pub fn intersect(&self, o: &Bounds2i) -> Bounds2i {
        Bounds2i { min: self.min.max(o.min), max: self.max.min(o.max) }
    }
    pub fn contains(&self, p: IVec2) -> bool {
        p.x >= self.min.x && p.x < self.max.x && p.y >= self.min.y && p.y < self.max.y
    }
    /// Pixels in raster order.
    pub fn iter(&self) -> impl Iterator<Item = IVec2> + '_ {
        (self.min.y..self.max.y).flat_map(move |y| (self.min.x..self.max.x).map(move |x| IVec2::new(x, y)))
    }
}

/// Interpolates a per-vertex attribute with barycentrics.
pub fn interpolate<T>(v: [T; 3], b: [f32; 3]) -> T
where
    T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let [a, c, d] = v;
    a * b[0] + c * b[1] + d * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `step_float` gives exactly the bits of the branching definition, for every kind of
    /// float (zeros of both signs, subnormals, the largest finite values, infinities, NaN)
    /// and random ones, in both directions and for a zero or NaN `toward`.
    #[test]
    fn step_float_is_next_float_up_and_down() {
        let reference = |v: f32, toward: f32| {
            if toward > 0.0 {
                next_float_up(v)
            } else if toward < 0.0 {
                next_float_down(v)
            } else {
                v
            }
        };
        let mut values = vec![
            0.0f32,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1.0,
            -1.0,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-30,
            -3.5e7,
        ];
        let mut rng = crate::rng::Rng::new(9);
        values.extend((0..20_000).map(|_| f32::from_bits(rng.uniform_u32())));
        for &v in &values {
            for toward in [1.0f32, -1.0, 0.0, -0.0, f32::NAN, 1e-40, -1e-40] {
                let (a, b) = (step_float(v, toward), reference(v, toward));
                assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "{v:e} ({:#x}) toward {toward}: {a:e} vs {b:e}",
                    v.to_bits()
                );
            }
        }
    }

    #[test]
    fn next_float_steps_one_ulp() {
        assert!(next_float_up(1.0) > 1.0 && next_float_up(1.0) - 1.0 == f32::EPSILON);
        assert!(next_float_down(0.0) < 0.0);
        assert!(next_float_up(-0.0) > 0.0);
    }

    #[test]
    fn frames_are_orthonormal() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.4, 0.5).normalize(), Vec3::new(0.0, -1.0, -1e-9).normalize()] {
            let f = Frame::from_z(n);
            assert!((f.x.length() - 1.0).abs() < 1e-5 && (f.y.length() - 1.0).abs() < 1e-5);
            assert!(f.x.dot(f.y).abs() < 1e-5 && f.x.dot(n).abs() < 1e-5 && f.y.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.2, 0.7, -0.1);
            assert!((f.from_local(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn offset_origin_lands_on_the_right_side() {
        let n = Vec3::new(0.0, 1.0, 0.0);
        let p = Vec3::new(1e4, 0.0, -3.0);
        let err = Vec3::splat(gamma(7) * 1e4);
        let up = offset_ray_origin(p, err, n, Vec3::Y);
        let down = offset_ray_origin(p, err, n, -Vec3::Y);
        assert!(up.y > 0.0 && down.y < 0.0);
    }
}
