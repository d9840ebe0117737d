//! pbrt-v3's `Curve` primitive, intersected as pbrt-v3 intersects it (`src/shapes/curve.cpp`).
//!
//! A `curve` shape is a list of cubic Bézier segments in object space ([`CurveSegment`]: control
//! points, the widths at its ends, for ribbons the normals at its ends), each split into
//! `2^splitdepth` pieces `[u_min, u_max]` of its parameter: the pieces are the hierarchy's
//! primitives ([`Curves::prim_count`], [`Curves::world_bound`]).
//!
//! A ray meets a piece ([`Curves::intersect`]) in pbrt-v3's ray-aligned space: the piece's
//! control points (blossomed from the segment's) are moved to a frame whose origin is the ray's
//! origin, whose z axis is the ray and whose y axis is `d × (p3 − p0)`; the piece is bisected
//! (`SubdivideBezier`) down to a depth fixed from its curvature and width (at most 10), pruning
//! halves whose control-point boxes, widened by half the width, miss the ray; on a leaf, taken
//! as a line segment, the closest point to the ray gives u (clamped to the leaf's range), and
//! the ray hits when it passes within half the width (for `ribbon`, the width times
//! `|n(u) · d̂|`, `n(u)` the end normals slerped: ribbons narrow edge-on) of the Bézier point at
//! that u, at a depth in `[0, t_max]`. `v` runs across the width, 0.5 on the curve.
//!
//! The hit's geometry ([`Curves::geometry`]) is pbrt-v3's: `∂p/∂u` the segment's derivative at
//! u, `∂p/∂v` across the width (ribbon: `n(u) × ∂p/∂u`; flat: perpendicular to `∂p/∂u`
//! projected on the plane facing the ray; cylinder: that vector turned about `∂p/∂u` by
//! `(v − ½)·180°`, so the normal bends over the width like a cylinder's), the normal
//! `∂p/∂u × ∂p/∂v` (negated by `ReverseOrientation` XOR a handedness swap), used as both
//! geometric and shading normal; the point is the ray's point at the hit's depth, with
//! pbrt-v3's error bound of twice the width (rays leaving it start clear of the curve).
//!
//! Two of pbrt-v3's quirks are kept: within one piece a ray meeting the curve twice keeps the
//! hit of larger u, not the nearer (pbrt-v3's recursion does not lower `t_max` between
//! halves); the width is in object space. One is not: where a ribbon's two normals are equal
//! pbrt-v3 slerps over a zero angle (0 · ∞ = NaN, and the NaN width accepts every ray inside
//! the piece's box); penumbra uses the common normal.

use crate::geometry::{gamma, Bounds3};
use glam::{Mat3, Mat4, Vec2, Vec3};

/// pbrt-v3's `CurveType`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveType {
    /// A ribbon always facing the ray.
    Flat,
    /// A ribbon with its own orientation (normals `N` at the segments' ends).
    Ribbon,
    /// Flat, with a normal that bends across the width like a cylinder's.
    Cylinder,
}

/// One cubic Bézier segment (pbrt-v3's `CurveCommon`), object space.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveSegment {
    pub cp: [Vec3; 4],
    /// The widths at u = 0 and u = 1.
    pub width: [f32; 2],
    /// Ribbons: the unit normals at u = 0 and u = 1 (zero otherwise).
    pub n: [Vec3; 2],
    /// `acos(clamp(n0 · n1, 0, 1))`.
    pub normal_angle: f32,
    /// `1 / sin(normal_angle)` (infinite when the normals are equal).
    pub inv_sin_normal_angle: f32,
}

impl CurveSegment {
    pub fn new(cp: [Vec3; 4], width: [f32; 2], n: Option<[Vec3; 2]>) -> CurveSegment {
        let n = n.map_or([Vec3::ZERO; 2], |n| n.map(Vec3::normalize_or_zero));
        let normal_angle = n[0].dot(n[1]).clamp(0.0, 1.0).acos();
        CurveSegment { cp, width, n, normal_angle, inv_sin_normal_angle: 1.0 / normal_angle.sin() }
    }

    fn width_at(&self, u: f32) -> f32 {
        lerp(u, self.width[0], self.width[1])
    }

    /// The ribbon normal at `u` (pbrt-v3's slerp; the common normal where the two are equal).
    fn ribbon_normal(&self, u: f32) -> Vec3 {
        if !self.inv_sin_normal_angle.is_finite() {
            return self.n[0] * (1.0 - u) + self.n[1] * u;
        }
        let s0 = ((1.0 - u) * self.normal_angle).sin() * self.inv_sin_normal_angle;
        let s1 = (u * self.normal_angle).sin() * self.inv_sin_normal_angle;
        self.n[0] * s0 + self.n[1] * s1
    }
}

/// One `curve` shape: its segments, type, split depth and transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Curves {
    pub kind: CurveType,
    pub segments: Vec<CurveSegment>,
    /// Each segment is `2^split_depth` primitives.
    pub split_depth: u32,
    pub world_from_object: Mat4,
    pub object_from_world: Mat4,
    /// pbrt-v3's `reverseOrientation` (the normal is negated by it XOR `swaps_handedness`).
    pub reverse_orientation: bool,
    pub swaps_handedness: bool,
}

/// A hit on a curve piece: the ray's parameter and pbrt-v3's (u, v) and hit width
/// ([`crate::accel::Hit::b`] carries `[u, v, width]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub width: f32,
}

/// The geometry of a hit, world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveGeometry {
    pub p: Vec3,
    pub p_error: Vec3,
    pub n: Vec3,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    pub uv: Vec2,
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

fn lerp3(t: f32, a: Vec3, b: Vec3) -> Vec3 {
    a * (1.0 - t) + b * t
}

fn blossom(p: &[Vec3; 4], u0: f32, u1: f32, u2: f32) -> Vec3 {
    let a = [lerp3(u0, p[0], p[1]), lerp3(u0, p[1], p[2]), lerp3(u0, p[2], p[3])];
    let b = [lerp3(u1, a[0], a[1]), lerp3(u1, a[1], a[2])];
    lerp3(u2, b[0], b[1])
}

fn subdivide(cp: &[Vec3; 4]) -> [Vec3; 7] {
    [
        cp[0],
        (cp[0] + cp[1]) / 2.0,
        (cp[0] + 2.0 * cp[1] + cp[2]) / 4.0,
        (cp[0] + 3.0 * cp[1] + 3.0 * cp[2] + cp[3]) / 8.0,
        (cp[1] + 2.0 * cp[2] + cp[3]) / 4.0,
        (cp[2] + cp[3]) / 2.0,
        cp[3],
    ]
}

/// pbrt-v3's `EvalBezier`: the point at `u` and the derivative (`cp[3] − cp[0]` where it vanishes).
fn eval_bezier(cp: &[Vec3; 4], u: f32) -> (Vec3, Vec3) {
    let c1 = [lerp3(u, cp[0], cp[1]), lerp3(u, cp[1], cp[2]), lerp3(u, cp[2], cp[3])];
    let c2 = [lerp3(u, c1[0], c1[1]), lerp3(u, c1[1], c1[2])];
    let d = c2[1] - c2[0];
    (lerp3(u, c2[0], c2[1]), if d.length_squared() > 0.0 { 3.0 * d } else { cp[3] - cp[0] })
}

/// pbrt-v3's `Log2Int`-like rounding in `Curve::Intersect` (exponent, rounded up past 1.5).
fn log2_bits(v: f32) -> i32 {
    if v < 1.0 {
        return 0;
    }
    let bits = v.to_bits();
    (bits >> 23) as i32 - 127 + if bits & (1 << 22) != 0 { 1 } else { 0 }
}

/// pbrt-v3's `LookAt(o, o + d, up)` as a rotation: rows (right, up, dir); `None` when the
/// frame degenerates.
fn ray_frame(d: Vec3, up: Vec3) -> Option<Mat3> {
    let dir = d.normalize();
    let right = up.normalize().cross(dir);
    if !(right.length_squared() > 0.0) || !dir.is_finite() {
        return None;
    }
    let right = right.normalize();
    let new_up = dir.cross(right);
    Some(Mat3::from_cols(right, new_up, dir).transpose())
}

/// pbrt-v3's `CoordinateSystem(v)`'s first vector.
fn perpendicular(v: Vec3) -> Vec3 {
    if v.x.abs() > v.y.abs() {
        Vec3::new(-v.z, 0.0, v.x) / (v.x * v.x + v.z * v.z).sqrt()
    } else {
        Vec3::new(0.0, v.z, -v.y) / (v.y * v.y + v.z * v.z).sqrt()
    }
}

/// Whether the control points' box, widened by `half`, misses the ray (x and y around 0, z in
/// `[0, z_max]`).
fn box_misses(cp: &[Vec3], half: f32, z_max: f32) -> bool {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in cp {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    hi.y + half < 0.0
        || lo.y - half > 0.0
        || hi.x + half < 0.0
        || lo.x - half > 0.0
        || hi.z + half < 0.0
        || lo.z - half > z_max
}

/// Per-query state of one piece's intersection.
struct Query<'a> {
    seg: &'a CurveSegment,
    kind: CurveType,
    /// The object-space ray direction (unnormalised) and its length.
    d: Vec3,
    ray_length: f32,
    z_max: f32,
    /// Stop at the first hit (occlusion).
    any: bool,
}

impl Query<'_> {
    fn recurse(&self, cp: &[Vec3; 4], u0: f32, u1: f32, depth: i32, out: &mut Option<CurveHit>) {
        if depth > 0 {
            let split = subdivide(cp);
            let u = [u0, (u0 + u1) / 2.0, u1];
            for seg in 0..2 {
                let cps: &[Vec3; 4] = split[3 * seg..3 * seg + 4].try_into().unwrap_or(cp);
                let max_width = self.seg.width_at(u[seg]).max(self.seg.width_at(u[seg + 1]));
                if box_misses(cps, 0.5 * max_width, self.z_max) {
                    continue;
                }
                self.recurse(cps, u[seg], u[seg + 1], depth - 1, out);
                if self.any && out.is_some() {
                    return;
                }
            }
            return;
        }
        // The leaf's ends: the ray must pass between the lines through them perpendicular to it.
        let edge = (cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x);
        if edge < 0.0 {
            return;
        }
        let edge = (cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x);
        if edge < 0.0 {
            return;
        }
        let dir = Vec2::new(cp[3].x - cp[0].x, cp[3].y - cp[0].y);
        let denom = dir.length_squared();
        if denom == 0.0 {
            return;
        }
        let w = (-Vec2::new(cp[0].x, cp[0].y)).dot(dir) / denom;
        let u = lerp(w, u0, u1).clamp(u0, u1);
        let mut width = self.seg.width_at(u);
        if self.kind == CurveType::Ribbon {
            width *= self.seg.ribbon_normal(u).dot(self.d).abs() / self.ray_length;
        }
        let (pc, dpcdw) = eval_bezier(cp, w.clamp(0.0, 1.0));
        let dist2 = pc.x * pc.x + pc.y * pc.y;
        if dist2 > width * width * 0.25 || !(width > 0.0) {
            return;
        }
        if pc.z < 0.0 || pc.z > self.z_max {
            return;
        }
        let dist = dist2.sqrt();
        let edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
        let v = if edge > 0.0 { 0.5 + dist / width } else { 0.5 - dist / width };
        // A later (larger u) hit replaces an earlier one, as in pbrt-v3.
        *out = Some(CurveHit { t: pc.z / self.ray_length, u, v, width });
    }
}

impl Curves {
    /// The number of primitives (pieces) the hierarchy holds for this shape.
    pub fn prim_count(&self) -> usize {
        self.segments.len() << self.split_depth
    }

    /// Piece `prim`: its segment, its u range, its control points (object space).
    fn piece(&self, prim: usize) -> Option<(&CurveSegment, f32, f32, [Vec3; 4])> {
        let seg = self.segments.get(prim >> self.split_depth)?;
        let n = (1u32 << self.split_depth) as f32;
        let i = (prim & ((1usize << self.split_depth) - 1)) as f32;
        let (u0, u1) = (i / n, (i + 1.0) / n);
        let c = &seg.cp;
        Some((
            seg,
            u0,
            u1,
            [blossom(c, u0, u0, u0), blossom(c, u0, u0, u1), blossom(c, u0, u1, u1), blossom(c, u1, u1, u1)],
        ))
    }

    /// pbrt-v3's `Curve::ObjectBound` carried to world space (the box of its eight corners).
    pub fn world_bound(&self, prim: usize) -> Bounds3 {
        let mut b = Bounds3::EMPTY;
        let Some((seg, u0, u1, cp)) = self.piece(prim) else { return b };
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in cp {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let half = Vec3::splat(seg.width_at(u0).max(seg.width_at(u1)) * 0.5);
        let (lo, hi) = (lo - half, hi + half);
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            b.extend(self.world_from_object.transform_point3(c));
        }
        b
    }

    /// The object-space ray and pbrt-v3's ray frame for piece `prim`.
    #[allow(clippy::type_complexity)]
    fn setup(&self, prim: usize, o: Vec3, d: Vec3) -> Option<(&CurveSegment, f32, f32, [Vec3; 4], Vec3, Vec3, Mat3)> {
        let (seg, u0, u1, cp) = self.piece(prim)?;
        let o = self.object_from_world.transform_point3(o);
        let d = self.object_from_world.transform_vector3(d);
        let mut dx = d.cross(cp[3] - cp[0]);
        if dx.length_squared() == 0.0 {
            dx = perpendicular(d);
        }
        let frame = ray_frame(d, dx)?;
        Some((seg, u0, u1, cp, o, d, frame))
    }

    /// pbrt-v3's `Curve::Intersect` of piece `prim` with the world-space ray `o + t d`,
    /// `0 <= t <= t_max`; with `any`, the first hit found (occlusion).
    pub fn intersect(&self, prim: usize, o: Vec3, d: Vec3, t_max: f32, any: bool) -> Option<CurveHit> {
        let (seg, u0, u1, cpo, o, d, frame) = self.setup(prim, o, d)?;
        let cp = cpo.map(|p| frame * (p - o));
        let max_width = seg.width_at(u0).max(seg.width_at(u1));
        let ray_length = d.length();
        let z_max = ray_length * t_max;
        if box_misses(&cp, 0.5 * max_width, z_max) {
            return None;
        }
        let mut l0 = 0.0f32;
        for i in 0..2 {
            let s = cp[i] - 2.0 * cp[i + 1] + cp[i + 2];
            l0 = l0.max(s.abs().max_element());
        }
        let eps = seg.width[0].max(seg.width[1]) * 0.05;
        let r0 = log2_bits(std::f32::consts::SQRT_2 * 6.0 * l0 / (8.0 * eps)) / 2;
        let depth = r0.clamp(0, 10);
        let q = Query { seg, kind: self.kind, d, ray_length, z_max, any };
        let mut out = None;
        q.recurse(&cp, u0, u1, depth, &mut out);
        out.filter(|h| h.t.is_finite() && h.u.is_finite() && h.v.is_finite())
    }

    /// pbrt-v3's surface interaction at `hit` of piece `prim` by the world-space ray `o + t d`.
    pub fn geometry(&self, prim: usize, o_world: Vec3, d_world: Vec3, hit: &CurveHit) -> CurveGeometry {
        let p = o_world + d_world * hit.t;
        let fallback_n = -d_world.normalize_or_zero();
        let Some((seg, _, _, _, _, d, frame)) = self.setup(prim, o_world, d_world) else {
            let f = crate::geometry::Frame::from_z(fallback_n);
            return CurveGeometry {
                p,
                p_error: Vec3::ZERO,
                n: fallback_n,
                dpdu: f.x,
                dpdv: f.y,
                uv: Vec2::new(hit.u, hit.v),
            };
        };
        let _ = d;
        let (u, v, width) = (hit.u, hit.v, hit.width);
        let dpdu = eval_bezier(&seg.cp, u).1;
        let dpdv = match self.kind {
            CurveType::Ribbon => seg.ribbon_normal(u).cross(dpdu).normalize_or_zero() * width,
            CurveType::Flat | CurveType::Cylinder => {
                let dpdu_plane = frame * dpdu;
                let mut dpdv_plane = Vec3::new(-dpdu_plane.y, dpdu_plane.x, 0.0).normalize_or_zero() * width;
                if self.kind == CurveType::Cylinder {
                    // pbrt-v3's Rotate(-θ, ∂p/∂u) with θ = lerp(v, −90°, 90°).
                    let theta = -lerp(v, -90.0, 90.0).to_radians();
                    let axis = dpdu_plane.normalize_or_zero();
                    let (s, c) = theta.sin_cos();
                    dpdv_plane = dpdv_plane * c + axis.cross(dpdv_plane) * s + axis * axis.dot(dpdv_plane) * (1.0 - c);
                }
                frame.transpose() * dpdv_plane
            }
        };
        let m = &self.world_from_object;
        let (dpdu_w, dpdv_w) = (m.transform_vector3(dpdu), m.transform_vector3(dpdv));
        // ∂p/∂u × ∂p/∂v carried to world space: the cross product of the world tangents, times
        // the determinant's sign; negated by ReverseOrientation XOR the handedness swap.
        let mut n = dpdu_w.cross(dpdv_w).normalize_or_zero();
        if self.reverse_orientation {
            n = -n;
        }
        if n == Vec3::ZERO || !n.is_finite() {
            n = fallback_n;
        }
        // pbrt-v3's bound: 2 × width in each object axis, carried through the transform.
        let a = Mat3::from_mat4(*m);
        let abs = Mat3::from_cols(a.x_axis.abs(), a.y_axis.abs(), a.z_axis.abs());
        let p_error = abs * Vec3::splat(2.0 * width) * (1.0 + gamma(3)) + p.abs() * gamma(3);
        CurveGeometry { p, p_error, n, dpdu: dpdu_w, dpdv: dpdv_w, uv: Vec2::new(u, v) }
    }

    /// The world-space box of the whole shape.
    pub fn world_bounds(&self) -> Bounds3 {
        let mut b = Bounds3::EMPTY;
        for i in 0..self.prim_count() {
            let w = self.world_bound(i);
            if w.min.is_finite() && w.max.is_finite() {
                b.extend(w.min);
                b.extend(w.max);
            }
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight curve along x from -1 to 1 (control points evenly spaced: u = (x + 1) / 2).
    fn straight(kind: CurveType, width: f32, n: Option<[Vec3; 2]>, world_from_object: Mat4) -> Curves {
        let cp = [-1.0, -1.0 / 3.0, 1.0 / 3.0, 1.0].map(|x| Vec3::new(x, 0.0, 0.0));
        Curves {
            kind,
            segments: vec![CurveSegment::new(cp, [width; 2], n)],
            split_depth: 0,
            world_from_object,
            object_from_world: world_from_object.inverse(),
            reverse_orientation: false,
            swaps_handedness: false,
        }
    }

    /// A flat curve seen from above: hit exactly within half its width of the axis, at the
    /// axis' depth, with u along it, v = 0.5 ± offset / width across it, and pbrt-v3's normal
    /// `∂p/∂u × ∂p/∂v` along the ray; missed beyond the ends and past `t_max`.
    #[test]
    fn flat_curve_is_its_width_wide_facing_the_ray() {
        let c = straight(CurveType::Flat, 0.2, None, Mat4::IDENTITY);
        let d = Vec3::new(0.0, 0.0, -2.0);
        for (x, y, hit) in
            [(0.3, 0.0, true), (-0.5, 0.099, true), (0.2, -0.099, true), (0.0, 0.101, false), (1.2, 0.0, false)]
        {
            let o = Vec3::new(x, y, 3.0);
            let h = c.intersect(0, o, d, f32::INFINITY, false);
            assert_eq!(h.is_some(), hit, "({x}, {y}): {h:?}");
            let Some(h) = h else { continue };
            assert!((h.t - 1.5).abs() < 1e-5 && (h.u - (x + 1.0) / 2.0).abs() < 1e-3, "{h:?}");
            assert!((h.width - 0.2).abs() < 1e-6 && ((h.v - 0.5).abs() - y.abs() / 0.2).abs() < 1e-3, "{h:?}");
            let g = c.geometry(0, o, d, &h);
            assert!((g.p - Vec3::new(x, y, 0.0)).length() < 1e-5 && g.n.z.abs() > 0.9999, "{g:?}");
            assert!(g.p_error.min_element() >= 0.4, "pbrt-v3's bound: twice the width");
        }
        assert!(c.intersect(0, Vec3::new(0.0, 0.0, 3.0), d, 1.4, false).is_none());
        assert!(c.intersect(0, Vec3::new(0.0, 0.0, 3.0), -d, f32::INFINITY, false).is_none());
    }

    /// A ribbon whose normal is z, seen by rays turned by θ about the curve's axis: its width
    /// is `w · |cos θ|` (pbrt-v3 narrows it edge-on); a flat curve keeps `w` at every θ.
    #[test]
    fn ribbon_narrows_edge_on() {
        let ribbon = straight(CurveType::Ribbon, 0.2, Some([Vec3::Z, Vec3::new(0.0, 1e-3, 1.0)]), Mat4::IDENTITY);
        let flat = straight(CurveType::Flat, 0.2, None, Mat4::IDENTITY);
        for deg in [0.0f32, 30.0, 60.0, 80.0] {
            let (s, cs) = deg.to_radians().sin_cos();
            let d = Vec3::new(0.0, s, -cs);
            // The half-width across the ray is the distance in the plane perpendicular to d.
            let across = Vec3::new(0.0, cs, s);
            let edge = |c: &Curves, half: f32| {
                let inside = c.intersect(0, -3.0 * d + across * half * 0.98, d, f32::INFINITY, false).is_some();
                let outside = c.intersect(0, -3.0 * d + across * half * 1.02, d, f32::INFINITY, false).is_some();
                inside && !outside
            };
            assert!(edge(&ribbon, 0.1 * cs), "ribbon at {deg}°");
            assert!(edge(&flat, 0.1), "flat at {deg}°");
        }
    }

    /// A cylinder curve's normal bends across its width as a cylinder's: facing the ray on the
    /// axis, turned by (v − ½)·180° about the axis off it.
    #[test]
    fn cylinder_normal_bends_across_the_width() {
        let c = straight(CurveType::Cylinder, 0.2, None, Mat4::IDENTITY);
        let d = Vec3::new(0.0, 0.0, -1.0);
        for y in [-0.09f32, -0.05, 0.0, 0.05, 0.09] {
            let o = Vec3::new(0.1, y, 2.0);
            let h = c.intersect(0, o, d, f32::INFINITY, false).unwrap();
            let g = c.geometry(0, o, d, &h);
            let angle = (h.v - 0.5) * std::f32::consts::PI;
            assert!((g.n.z.abs() - angle.cos()).abs() < 1e-3 && g.n.x.abs() < 1e-3, "y {y}: {g:?}");
            assert!(g.n.y.abs() > 0.0 || y == 0.0);
        }
    }

    /// The width is in object space: scaled by 3 (and moved), the curve is 3 × as wide in the
    /// world, at the moved place; reverse orientation negates the normal.
    #[test]
    fn width_and_normal_follow_the_transform() {
        let m = Mat4::from_translation(Vec3::new(0.0, 5.0, 0.0)) * Mat4::from_scale(Vec3::splat(3.0));
        let mut c = straight(CurveType::Flat, 0.2, None, m);
        let d = Vec3::new(0.0, 0.0, -1.0);
        assert!(c.intersect(0, Vec3::new(1.0, 5.29, 2.0), d, f32::INFINITY, false).is_some());
        assert!(c.intersect(0, Vec3::new(1.0, 5.31, 2.0), d, f32::INFINITY, false).is_none());
        let o = Vec3::new(1.0, 5.0, 2.0);
        let h = c.intersect(0, o, d, f32::INFINITY, false).unwrap();
        assert!((h.t - 2.0).abs() < 1e-5);
        let n = c.geometry(0, o, d, &h).n;
        c.reverse_orientation = true;
        assert_eq!(c.geometry(0, o, d, &h).n, -n);
        let b = c.world_bounds();
        assert!(
            (b.min - Vec3::new(-3.3, 4.7, -0.3)).length() < 1e-4 && (b.max - Vec3::new(3.3, 5.3, 0.3)).length() < 1e-4
        );
    }

    /// Split pieces cover the curve: every ray hitting the whole segment hits exactly the piece
    /// holding its u, with the same hit.
    #[test]
    fn pieces_partition_the_segment() {
        let whole = straight(CurveType::Flat, 0.1, None, Mat4::IDENTITY);
        let split = Curves { split_depth: 3, ..whole.clone() };
        assert_eq!(split.prim_count(), 8);
        let d = Vec3::new(0.0, 0.0, -1.0);
        for i in 0..50 {
            let o = Vec3::new(-0.98 + 1.96 * i as f32 / 49.0, 0.01, 1.0);
            let h = whole.intersect(0, o, d, f32::INFINITY, false).unwrap();
            let hits: Vec<CurveHit> = (0..8).filter_map(|p| split.intersect(p, o, d, f32::INFINITY, false)).collect();
            assert!(!hits.is_empty() && hits.len() <= 2, "{hits:?}");
            assert!(hits.iter().all(|s| (s.t - h.t).abs() < 1e-5 && (s.u - h.u).abs() < 2e-3), "{h:?} {hits:?}");
        }
    }
}
