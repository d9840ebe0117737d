//! Area lights on spheres, disks and cylinders sampled as pbrt-v3's shapes sample themselves
//! (`Sphere::Sample(ref, u)`, `Disk::Sample(u)`, `Cylinder::Sample(u)`, `Shape::Pdf`), rather
//! than by area over their tessellation.
//!
//! pbrt-v3 works in a mix of spaces here, and penumbra reproduces it (mode
//! [`ShapeSampling::Pbrt`], the default, so that scenes tuned against pbrt-v3 render as they
//! were tuned):
//! - a sphere seen from outside its *object-space* radius `r` is sampled uniformly in the cone
//!   of half-angle `asin(r / d)` about its world-space centre at distance `d`, the point placed
//!   at distance `r` from that centre; from inside (`d ≤ r`) uniformly over its surface, with
//!   the area density `1 / Area()`;
//! - disks and cylinders are sampled uniformly over their object-space parameter domain, the
//!   area density `1 / Area()`;
//! - `Area()` is the object-space area, whatever the transform;
//! - a partial sphere or disk (`zmin`, `zmax`, `phimax`, `innerradius`) is sampled whole.
//!
//! Under a rigid transform and for whole shapes these are exact; under a scale `s` the light
//! is about `1/s²` as bright as its geometry where light sampling dominates (a sphere with
//! `s > 1` samples points inside itself, which its own surface shadows). Mode
//! [`ShapeSampling::Physical`] samples a whole sphere under a uniform scale by the cone of its
//! world-space radius, and every other case by area over the tessellation.

use crate::geometry::{gamma, offset_ray_origin};
use crate::light::LightContext;
use crate::mesh::{Quadric, QuadricShape};
use crate::sampling::{concentric_sample_disk, uniform_cone_pdf, uniform_sample_sphere};
use glam::{Vec2, Vec3};
use penumbra_parser::Transform;
use std::f32::consts::PI;

/// How an area light on a sphere, disk or cylinder picks its points (`"string shapesampling"`
/// on the `AreaLightSource`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeSampling {
    /// As pbrt-v3 does (the default; see the module documentation).
    Pbrt,
    /// As the geometry says: the light emits what its shape's world-space surface does.
    Physical,
}

/// The scale factors of a transform's linear part (the lengths of its columns: how much it
/// stretches object-space x, y and z).
pub fn axis_scales(t: &Transform) -> [f64; 3] {
    [0, 1, 2].map(|c| (0..3).map(|r| t.m[r][c] * t.m[r][c]).sum::<f64>().sqrt())
}

/// Whether the three axis scales are equal to rounding (a similarity transform, if the
/// columns are also orthogonal).
fn is_similarity(t: &Transform) -> Option<f64> {
    let s = axis_scales(t);
    let col = |c: usize| [t.m[0][c], t.m[1][c], t.m[2][c]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let tol = 1e-6 * s[0];
    let equal = (s[1] - s[0]).abs() <= tol && (s[2] - s[0]).abs() <= tol;
    let orthogonal = dot(col(0), col(1)).abs() <= tol * s[0]
        && dot(col(0), col(2)).abs() <= tol * s[0]
        && dot(col(1), col(2)).abs() <= tol * s[0];
    (equal && orthogonal && s[0] > 0.0).then_some(s[0])
}

/// A point a [`QuadricSampler`] chose, with its normal, error bound and solid-angle pdf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadricSample {
    pub p: Vec3,
    pub p_error: Vec3,
    pub n: Vec3,
    pub pdf: f32,
}

/// pbrt-v3's `Shape::Sample(ref, u)` and `Shape::Pdf(ref, wi)` for one quadric.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadricSampler {
    shape: QuadricShape,
    world_from_object: Transform,
    /// The world-space centre (the object-space origin).
    center: Vec3,
    /// The sphere's radius for its cone and its inside test: object space in pbrt-v3's mode.
    radius: f32,
    /// The area of the pdfs' `1 / Area()`.
    area: f32,
    /// `ReverseOrientation`: the sampled normal is negated.
    reverse_orientation: bool,
    /// Added to a sampled point's error bound: twice the tessellation's largest distance from
    /// the analytic surface (world space), so that the shadow ray to a point on the analytic
    /// surface stops short of the tessellated one. Seen from its concave side (the inside of
    /// a cylinder or sphere) the tessellation lies in front of the analytic surface, and would
    /// shadow every sample.
    surface_error: f32,
}

impl QuadricSampler {
    /// The sampler for `quadric` in `mode` (`None`: sample by area over the tessellation,
    /// [`ShapeSampling::Physical`] where the shape is not a whole sphere under a uniform scale).
    pub fn new(quadric: &Quadric, reverse_orientation: bool, mode: ShapeSampling) -> Option<QuadricSampler> {
        let t = quadric.world_from_object;
        let c = t.apply_point([0.0; 3]);
        let mut s = QuadricSampler {
            shape: quadric.shape,
            world_from_object: t,
            center: Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32),
            radius: match quadric.shape {
                QuadricShape::Sphere { radius, .. } => radius.abs() as f32,
                _ => 0.0,
            },
            area: quadric.shape.area() as f32,
            reverse_orientation,
            surface_error: (2.0 * quadric.deviation * axis_scales(&t).into_iter().fold(0.0, f64::max)) as f32,
        };
        match mode {
            ShapeSampling::Pbrt => {}
            ShapeSampling::Physical => {
                let scale = is_similarity(&t)?;
                if !matches!(quadric.shape, QuadricShape::Sphere { .. }) || !quadric.shape.sampled_whole() {
                    return None;
                }
                s.radius *= scale as f32;
                s.area *= (scale * scale) as f32;
            }
        }
        (s.area > 0.0 && s.area.is_finite() && s.center.is_finite()).then_some(s)
    }

    /// The area `1 / pdf` is taken over (pbrt-v3's object-space `Area()` in its mode): the
    /// light's power is `L · area · π` (twice for two-sided), as pbrt-v3 computes it.
    pub fn area(&self) -> f32 {
        self.area
    }

    fn to_world_point(&self, p: Vec3) -> Vec3 {
        let w = self.world_from_object.apply_point([p.x as f64, p.y as f64, p.z as f64]);
        Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32)
    }

    fn to_world_normal(&self, n: Vec3) -> Vec3 {
        let w = self.world_from_object.apply_normal([n.x as f64, n.y as f64, n.z as f64]);
        let n = Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32).normalize_or_zero();
        if self.reverse_orientation {
            -n
        } else {
            n
        }
    }

    /// Whether `ctx` is inside the sphere as pbrt-v3 decides it (its spawned origin towards
    /// the centre within `radius` of the centre): then the sphere is sampled by area.
    fn inside(&self, ctx: &LightContext) -> bool {
        let o = offset_ray_origin(ctx.p, ctx.p_error, ctx.n, self.center - ctx.p);
        o.distance_squared(self.center) <= self.radius * self.radius
    }

    /// pbrt-v3's `Shape::Sample(ref, u)` for the light at `ctx` (`None` when its pdf is 0).
    pub fn sample(&self, ctx: &LightContext, u: Vec2) -> Option<QuadricSample> {
        match self.shape {
            QuadricShape::Sphere { .. } if !self.inside(ctx) => self.sample_cone(ctx, u),
            _ => {
                let (p, p_error, n) = self.sample_area(u);
                let d = p - ctx.p;
                let d2 = d.length_squared();
                if !(d2 > 0.0) {
                    return None;
                }
                let pdf = d2 / (n.dot(-d / d2.sqrt()).abs() * self.area);
                let p_error = p_error + Vec3::splat(self.surface_error);
                (pdf.is_finite() && pdf > 0.0).then_some(QuadricSample { p, p_error, n, pdf })
            }
        }
    }

    /// pbrt-v3's `Shape::Sample(u)`: a point by the parameter domain (area density 1/area).
    fn sample_area(&self, u: Vec2) -> (Vec3, Vec3, Vec3) {
        match self.shape {
            QuadricShape::Sphere { radius, .. } => {
                let r = radius as f32;
                let p_obj = r * uniform_sample_sphere(u);
                let n = self.to_world_normal(p_obj);
                let p_obj = p_obj * (r / p_obj.length());
                let p = self.to_world_point(p_obj);
                (p, gamma(5) * p.abs(), n)
            }
            QuadricShape::Disk { height, radius, .. } => {
                let d = concentric_sample_disk(u) * radius as f32;
                let n = self.to_world_normal(Vec3::Z);
                (self.to_world_point(Vec3::new(d.x, d.y, height as f32)), Vec3::ZERO, n)
            }
            QuadricShape::Cylinder { radius, z_min, z_max, phi_max } => {
                let z = (1.0 - u.x) * z_min as f32 + u.x * z_max as f32;
                let phi = u.y * phi_max as f32;
                let r = radius as f32;
                let p_obj = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let n = self.to_world_normal(Vec3::new(p_obj.x, p_obj.y, 0.0));
                let p = self.to_world_point(p_obj);
                (p, gamma(3) * p.abs(), n)
            }
        }
    }

    /// pbrt-v3's sphere cone sampling, for a point outside the sphere.
    fn sample_cone(&self, ctx: &LightContext, u: Vec2) -> Option<QuadricSample> {
        let dc = ctx.p.distance(self.center);
        if !(dc > 0.0) || !dc.is_finite() {
            return None;
        }
        let inv_dc = 1.0 / dc;
        let wc = (self.center - ctx.p) * inv_dc;
        let (wc_x, wc_y) = coordinate_system(wc);
        let sin_theta_max = self.radius * inv_dc;
        let sin_theta_max2 = sin_theta_max * sin_theta_max;
        let inv_sin_theta_max = 1.0 / sin_theta_max;
        let cos_theta_max = (1.0 - sin_theta_max2).max(0.0).sqrt();
        let mut cos_theta = (cos_theta_max - 1.0) * u.x + 1.0;
        let mut sin_theta2 = 1.0 - cos_theta * cos_theta;
        // sin²(1.5°): below it pbrt-v3 takes a Taylor expansion against cancellation.
        if sin_theta_max2 < 0.000_685_23 {
            sin_theta2 = sin_theta_max2 * u.x;
            cos_theta = (1.0 - sin_theta2).sqrt();
        }
        let cos_alpha = sin_theta2 * inv_sin_theta_max
            + cos_theta * (1.0 - sin_theta2 * inv_sin_theta_max * inv_sin_theta_max).max(0.0).sqrt();
        let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
        let phi = u.y * 2.0 * PI;
        let n = sin_alpha * phi.cos() * -wc_x + sin_alpha * phi.sin() * -wc_y + cos_alpha * -wc;
        let p = self.center + self.radius * n;
        let pdf = uniform_cone_pdf(cos_theta_max);
        let n = if self.reverse_orientation { -n } else { n };
        let p_error = gamma(5) * p.abs() + Vec3::splat(self.surface_error);
        (pdf.is_finite() && pdf > 0.0).then_some(QuadricSample { p, p_error, n, pdf })
    }

    /// pbrt-v3's `Shape::Pdf(ref, wi)` for a direction whose ray meets the light at
    /// `light_hit` (point, normal): the sphere's cone density from outside, else the area
    /// density `1/area` in solid angle.
    pub fn pdf(&self, ctx: &LightContext, light_hit: Option<(Vec3, Vec3)>) -> f32 {
        if matches!(self.shape, QuadricShape::Sphere { .. }) && !self.inside(ctx) {
            let sin2 = self.radius * self.radius / ctx.p.distance_squared(self.center);
            let pdf = uniform_cone_pdf((1.0 - sin2).max(0.0).sqrt());
            return if pdf.is_finite() { pdf } else { 0.0 };
        }
        let Some((p, n)) = light_hit else { return 0.0 };
        let d = p - ctx.p;
        let d2 = d.length_squared();
        let pdf = d2 / (n.normalize_or_zero().dot(d / d2.sqrt()).abs() * self.area);
        if pdf.is_finite() && pdf > 0.0 {
            pdf
        } else {
            0.0
        }
    }
}

/// pbrt-v3's `CoordinateSystem`: two unit vectors completing `v` (unit) to an orthonormal basis.
fn coordinate_system(v: Vec3) -> (Vec3, Vec3) {
    let v2 = if v.x.abs() > v.y.abs() {
        Vec3::new(-v.z, 0.0, v.x) / (v.x * v.x + v.z * v.z).sqrt()
    } else {
        Vec3::new(0.0, v.z, -v.y) / (v.y * v.y + v.z * v.z).sqrt()
    };
    (v2, v.cross(v2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::goodness_of_fit::chi2_test;
    use crate::rng::Rng;

    fn quadric(shape: QuadricShape, t: Transform) -> Quadric {
        Quadric { shape, world_from_object: t, deviation: 0.0 }
    }

    fn sphere(r: f64) -> QuadricShape {
        QuadricShape::Sphere { radius: r, z_min: -r, z_max: r, phi_max: std::f64::consts::TAU }
    }

    fn at(p: Vec3, n: Vec3) -> LightContext {
        LightContext { p, p_error: Vec3::ZERO, n }
    }

    /// The irradiance at `ctx` (radiance 1, one-sided) estimated from `n` samples, counting,
    /// as a one-sided light does, only samples whose normal faces the receiver; no shadows.
    fn irradiance(s: &QuadricSampler, ctx: &LightContext, n: usize, seed: u64) -> f64 {
        let mut rng = Rng::new(seed);
        let mut e = 0.0f64;
        for _ in 0..n {
            let u = Vec2::new(rng.uniform_f32(), rng.uniform_f32());
            if let Some(q) = s.sample(ctx, u) {
                let wi = (q.p - ctx.p).normalize();
                if q.n.dot(-wi) > 0.0 {
                    e += (ctx.n.dot(wi).max(0.0) / q.pdf) as f64;
                }
            }
        }
        e / n as f64
    }

    /// A sphere of world radius 1 at distance 3 (facing the receiver): irradiance π/9 whatever
    /// the transform in the physical mode. pbrt-v3's mode takes the object-space radius for the
    /// cone (scale 2, object radius ½: a quarter of it) and for its inside test, then the
    /// object-space area for the density (scale ¼, object radius 4 > 3: sampled by area,
    /// 16 times too bright).
    #[test]
    fn sphere_irradiance_matches_closed_forms_and_pbrt_v3s_scaling() {
        let e_true = std::f64::consts::PI / 9.0;
        let ctx = at(Vec3::new(0.0, 0.0, -3.0), Vec3::Z);
        let cases = [(1.0f64, 1.0f64, 1.0f64), (2.0, 0.5, 0.25), (0.25, 4.0, 16.0)];
        for (scale, r, pbrt_factor) in cases {
            let t = Transform::scale([scale; 3]).unwrap();
            let q = quadric(sphere(r), t);
            for (mode, factor) in [(ShapeSampling::Pbrt, pbrt_factor), (ShapeSampling::Physical, 1.0)] {
                let s = QuadricSampler::new(&q, false, mode).unwrap();
                let e = irradiance(&s, &ctx, 400_000, 3);
                assert!(
                    (e / (e_true * factor) - 1.0).abs() < 0.01,
                    "scale {scale} {mode:?}: {e} vs {}",
                    e_true * factor
                );
            }
        }
        // Reverse orientation: the sampled normals face inward, nothing reaches an outside point.
        let s = QuadricSampler::new(&quadric(sphere(1.0), Transform::IDENTITY), true, ShapeSampling::Pbrt).unwrap();
        assert_eq!(irradiance(&s, &ctx, 1000, 4), 0.0);
    }

    /// A disk of world radius 1 seen on its axis from height 2: π/5 physically; pbrt-v3's
    /// object-space area makes a disk scaled by ½ four times as bright. The physical mode of a
    /// disk samples its tessellation (no quadric sampler).
    #[test]
    fn disk_irradiance_and_object_space_area() {
        let ctx = at(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z);
        let e_true = std::f64::consts::PI / 5.0;
        for (scale, factor) in [(1.0f64, 1.0f64), (0.5, 4.0)] {
            let shape = QuadricShape::Disk {
                height: 0.0,
                radius: 1.0 / scale,
                inner_radius: 0.0,
                phi_max: std::f64::consts::TAU,
            };
            let q = quadric(shape, Transform::scale([scale; 3]).unwrap());
            let s = QuadricSampler::new(&q, false, ShapeSampling::Pbrt).unwrap();
            let e = irradiance(&s, &ctx, 400_000, 5);
            assert!((e / (e_true * factor) - 1.0).abs() < 0.01, "scale {scale}: {e}");
            assert!(QuadricSampler::new(&q, false, ShapeSampling::Physical).is_none());
        }
    }

    /// The directions to cone samples are uniform in the cone the sphere subtends (χ² over
    /// equal-solid-angle bins in cos θ and φ), and `pdf` gives their density.
    #[test]
    fn cone_samples_are_uniform_in_the_subtended_cone() {
        let center = Vec3::new(0.3, -0.2, 0.5);
        let q = quadric(sphere(0.6), Transform::translate([0.3, -0.2, 0.5]));
        let s = QuadricSampler::new(&q, false, ShapeSampling::Pbrt).unwrap();
        let ctx = at(Vec3::new(2.0, 1.0, -0.5), Vec3::ZERO);
        let d = center.distance(ctx.p);
        let cos_max = (1.0 - (0.6 / d) * (0.6 / d)).sqrt();
        let axis = (center - ctx.p) / d;
        let (x, y) = coordinate_system(axis);
        let (nt, np, n) = (8, 8, 200_000);
        let mut obs = vec![0.0f64; nt * np];
        let mut rng = Rng::new(11);
        for _ in 0..n {
            let q = s.sample(&ctx, Vec2::new(rng.uniform_f32(), rng.uniform_f32())).unwrap();
            assert!((q.pdf - s.pdf(&ctx, None)).abs() <= 1e-6 * q.pdf);
            assert!((q.p.distance(center) - 0.6).abs() < 1e-5, "on the sphere");
            let w = (q.p - ctx.p).normalize();
            let c = w.dot(axis).clamp(-1.0, 1.0);
            let it = (((1.0 - c) / (1.0 - cos_max) * nt as f32) as usize).min(nt - 1);
            let phi = w.dot(y).atan2(w.dot(x)).rem_euclid(std::f32::consts::TAU);
            let ip = ((phi / std::f32::consts::TAU * np as f32) as usize).min(np - 1);
            obs[it * np + ip] += 1.0;
        }
        let exp = vec![n as f64 / (nt * np) as f64; nt * np];
        let (_, _, p) = chi2_test(&obs, &exp, 5.0);
        assert!(p > 1e-4, "p = {p}");
        // ∫ pdf over the cone is 1: the pdf times the cone's solid angle.
        let pdf = s.pdf(&ctx, None) as f64;
        assert!((pdf * 2.0 * std::f64::consts::PI * (1.0 - cos_max as f64) - 1.0).abs() < 1e-4);
    }
}
