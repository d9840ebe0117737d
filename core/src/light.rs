//! Lights with pbrt-v3's semantics: `point`, `spot`, `distant`, `goniometric`,
//! `projection`, `infinite` (alias `exinfinite`) light sources and `diffuse`
//! (alias `area`) area lights.
//!
//! Area lights over triangle meshes follow pbrt-v3's granularity: a
//! `trianglemesh`/`plymesh`/`loopsubdiv`/`heightfield`/`nurbs` area light is one light
//! per triangle (pbrt-v3 makes one `Triangle` shape, hence one light, per
//! triangle); a quadric (sphere, disk, …) is one light over all the triangles
//! of its tessellation. Spheres, disks and cylinders are sampled as pbrt-v3's shapes
//! sample themselves (the sphere by the cone it subtends; see [`quadric`], which also
//! says how pbrt-v3 mixes object and world space under a scale and how
//! `"string shapesampling" "physical"` avoids it); other quadrics by area (a triangle
//! chosen in proportion to its area, then a uniform point on it), so their surface
//! density is 1 / total area.
//!
//! Mesh `i` of the scene is the geometry of `SceneObject` `i` (the scene builder
//! pushes them together); an emissive triangle maps to its light through
//! [`Lights::light_of`].
//!
//! Lights that cannot contribute are not built: an `L`/`I` of zero, an area
//! light of zero area (and zero-area triangles of a per-triangle mesh light).
//! pbrt-v3 keeps them, but they add nothing to any image: the only visible
//! difference is in the light count (which changes which light pbrt's `one`
//! strategy picks for a given sample, not the converged image).

use crate::geometry::{face_forward, gamma, interpolate, Bounds3, Ray};
use crate::image::Image;
use crate::interaction::SceneObject;
use crate::mesh::TriangleMesh;
use crate::profiling::Phase;
use crate::sampling::{spherical_phi, spherical_theta, uniform_sample_triangle, Distribution1D, Distribution2D};
use crate::spectrum::luminance;
use crate::Rgb;
use glam::{Mat3, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, FileLoc, ParamSet, SceneDescription, Transform};
use std::f32::consts::PI;

use crate::image::read_scene_input as read_image;
use crate::spectrum::spectrum_to_rgb;

pub mod quadric;
use quadric::{QuadricSampler, ShapeSampling};

/// The receiving point of a light query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightContext {
    pub p: Vec3,
    pub p_error: Vec3,
    /// Geometric normal at `p` (zero if `p` is not on a surface).
    pub n: Vec3,
}

/// A sampled incident direction from a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightLiSample {
    /// Incident radiance (delta lights: intensity / distance², as pbrt-v3).
    pub li: Rgb,
    /// Unit direction from the receiving point towards the light.
    pub wi: Vec3,
    /// Solid-angle density (1 for delta lights).
    pub pdf: f32,
    /// The sampled point on the light, its error bound and normal (zero normal for
    /// point-like and infinitely distant lights), for the shadow ray.
    pub p_light: Vec3,
    pub p_light_error: Vec3,
    pub n_light: Vec3,
    pub delta: bool,
}

/// An emitting surface: which mesh and triangles, with what radiance.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    pub mesh: u32,
    pub tris: Vec<u32>,
    /// Emitted radiance `L × scale`.
    pub l: Rgb,
    pub two_sided: bool,
    pub area: f32,
}

/// An RGB texture with pbrt-v3's `MIPMap` level-0 lookup: bilinear, texel centres
/// at half-integers, repeat wrapping, `(0, 0)` at the top-left corner.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbMap {
    pub width: usize,
    pub height: usize,
    /// Row-major from the top row.
    pub texels: Vec<Rgb>,
}

impl RgbMap {
    pub fn constant(c: Rgb) -> RgbMap {
        RgbMap { width: 1, height: 1, texels: vec![c] }
    }

    /// The texel at wrapped coordinates (`s < width`, `t < height`).
    #[inline]
    fn texel(&self, s: usize, t: usize) -> Rgb {
        self.texels.get(t * self.width + s).copied().unwrap_or(Rgb::ZERO)
    }

    /// The mean texel.
    pub fn mean(&self) -> Rgb {
        let n = self.texels.len().max(1) as f64;
        let sum = self.texels.iter().fold(glam::DVec3::ZERO, |acc, t| acc + t.as_dvec3());
        (sum / n).as_vec3()
    }

    /// Bilinear lookup at `st` ∈ [0,1]² (zero for non-finite coordinates). Always inlined: the
    /// sampling distribution's build looks up a whole row at one `t`, whose part is then hoisted.
    #[inline(always)]
    pub fn lookup(&self, st: Vec2) -> Rgb {
        if !st.is_finite() || self.width == 0 || self.height == 0 {
            return Rgb::ZERO;
        }
        let s = st.x * self.width as f32 - 0.5;
        let t = st.y * self.height as f32 - 0.5;
        let ((s0, si), (t0, ti)) = (floor_parts(s), floor_parts(t));
        let (ds, dt) = (s - s0, t - t0);
        let (s0, t0) = (si, ti);
        let (s0, s1) = (wrap(s0, self.width), wrap(s0.wrapping_add(1), self.width));
        let (t0, t1) = (wrap(t0, self.height), wrap(t0.wrapping_add(1), self.height));
        (1.0 - ds) * (1.0 - dt) * self.texel(s0, t0)
            + (1.0 - ds) * dt * self.texel(s0, t1)
            + ds * (1.0 - dt) * self.texel(s1, t0)
            + ds * dt * self.texel(s1, t1)
    }
}

/// `(x.floor(), x.floor() as i64)` for finite `x` that is not `-0.0` (a lookup's `s · w − 0.5`
/// never is): below 2²³ in magnitude from the truncation, without the library call the baseline
/// x86-64 target makes for `floor`; larger values are integers already.
#[inline]
fn floor_parts(x: f32) -> (f32, i64) {
    if x.abs() < 8_388_608.0 {
        let i = x as i32;
        let i = if i as f32 > x { i - 1 } else { i };
        (i as f32, i as i64)
    } else {
        let f = x.floor();
        (f, f as i64)
    }
}

/// `i.rem_euclid(n)`, without the division when `i` is already in `[0, n)` (a bilinear lookup's
/// four texels nearly always are; two divisions per texel were 4 % of an environment-lit render).
#[inline]
fn wrap(i: i64, n: usize) -> usize {
    if i >= 0 && (i as u64) < n as u64 {
        i as usize
    } else {
        i.rem_euclid(n as i64) as usize
    }
}

/// `point`: position `CTM(0) + from` (pbrt-v3 translates by `from` after the CTM).
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    pub p: Vec3,
    pub i: Rgb,
}

/// `spot`: cone around `from → to` (in light space), pbrt-v3's quartic falloff.
#[derive(Clone, Debug, PartialEq)]
pub struct SpotLight {
    pub p: Vec3,
    pub i: Rgb,
    /// The linear part of light-from-world, without the direction rotation.
    pub light_from_world: Mat3,
    /// The spot axis in (CTM) light space, unit.
    pub axis: Vec3,
    pub cos_total_width: f32,
    pub cos_falloff_start: f32,
}

impl SpotLight {
    /// pbrt-v3's `SpotLight::Falloff` for the world direction `w` leaving the light.
    pub fn falloff(&self, w: Vec3) -> f32 {
        let wl = (self.light_from_world * w).normalize_or_zero();
        let cos_theta = wl.dot(self.axis);
        if !(cos_theta >= self.cos_total_width) {
            return 0.0;
        }
        if cos_theta > self.cos_falloff_start {
            return 1.0;
        }
        let delta = (cos_theta - self.cos_total_width) / (self.cos_falloff_start - self.cos_total_width);
        if !delta.is_finite() {
            return 0.0;
        }
        (delta * delta) * (delta * delta)
    }
}

/// `distant`: radiance `l` arriving from direction `w` (unit, pointing towards the light).
#[derive(Clone, Debug, PartialEq)]
pub struct DistantLight {
    pub l: Rgb,
    pub w: Vec3,
    pub scene_radius: f32,
}

/// A diffuse area light over one triangle or over all triangles of one shape.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffuseAreaLight {
    pub geom: AreaLight,
    /// Triangle choice in proportion to area (only when `geom.tris` has several).
    pub tri_dist: Option<Distribution1D>,
    pub n_samples: u32,
    /// `geom.tris`' geometry as a sample needs it (the meshes do not change after the build).
    triangles: Vec<LightTriangle>,
    /// pbrt-v3's own sampling of the sphere, disk or cylinder the light is on (`None`: by area
    /// over `triangles`).
    quadric: Option<Box<QuadricSampler>>,
}

/// An emitting triangle as [`DiffuseAreaLight::sample_point`] reads it: its vertices, its
/// winding normal (normalised) and its vertex normals (missing ones zero; negated where pbrt-v3
/// negates them for a sample), the values [`TriangleMesh::sample_normal`] computes from the
/// mesh at every sample.
#[derive(Clone, Debug, PartialEq)]
struct LightTriangle {
    pv: [Vec3; 3],
    n: Vec3,
    shading: Option<[Vec3; 3]>,
}

impl LightTriangle {
    fn new(mesh: &TriangleMesh, tri: usize, pv: [Vec3; 3]) -> Self {
        let n = (pv[1] - pv[0]).cross(pv[2] - pv[0]).normalize_or_zero();
        let sign = mesh.sample_normal_sign();
        let shading = match (&mesh.normals, mesh.indices.get(tri)) {
            (Some(ns), Some(idx)) => Some(idx.map(|i| sign * ns.get(i as usize).copied().unwrap_or(Vec3::ZERO))),
            _ => None,
        };
        LightTriangle { pv, n, shading }
    }

    /// The normal pbrt-v3's `Shape::Sample` gives the point with barycentrics `b` (flat, on
    /// the emitting side; [`TriangleMesh::sample_normal`]).
    #[inline]
    fn normal_at(&self, b: [f32; 3]) -> Vec3 {
        if let Some(nv) = self.shading {
            let s = interpolate(nv, b);
            if s != Vec3::ZERO && s.is_finite() {
                return face_forward(self.n, s);
            }
        }
        self.n
    }
}

/// A point an area light's sample chose, with its normal and error bound: the part of
/// [`Light::sample_li`] that does not depend on the receiving point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaLightPoint {
    pub p: Vec3,
    pub p_error: Vec3,
    pub n: Vec3,
}

impl DiffuseAreaLight {
    /// One light over the triangles `tris` of mesh `mesh_index` (`mesh`) that have a positive,
    /// finite area, a triangle chosen for sampling in proportion to its area; `None` when no
    /// triangle qualifies or the total area is not finite.
    pub fn over_triangles(
        mesh_index: u32,
        mesh: &TriangleMesh,
        tris: &mut dyn Iterator<Item = u32>,
        l: Rgb,
        two_sided: bool,
        n_samples: u32,
    ) -> Option<DiffuseAreaLight> {
        let area = |t: u32| match tri_vertices(mesh, t as usize) {
            Some([a, b, c]) => 0.5 * (b - a).cross(c - a).length(),
            None => 0.0,
        };
        let (tris, w): (Vec<u32>, Vec<f32>) =
            tris.map(|t| (t, area(t))).filter(|&(_, a)| a > 0.0 && a.is_finite()).unzip();
        let total: f64 = w.iter().map(|&a| a as f64).sum();
        if tris.is_empty() || !(total > 0.0) || !(total as f32).is_finite() {
            return None;
        }
        let tri_dist = (tris.len() > 1).then(|| Distribution1D::new(&w));
        let triangles = tris
            .iter()
            .map(|&t| LightTriangle::new(mesh, t as usize, tri_vertices(mesh, t as usize).unwrap_or_default()))
            .collect();
        Some(DiffuseAreaLight {
            geom: AreaLight { mesh: mesh_index, tris, l, two_sided, area: total as f32 },
            tri_dist,
            n_samples,
            triangles,
            quadric: None,
        })
    }

    /// Whether the light's points are chosen by area over its triangles
    /// ([`Self::sample_point`], independent of the receiver) rather than by its quadric's own
    /// pbrt-v3 sampling (which depends on the receiver).
    pub fn samples_by_area(&self) -> bool {
        self.quadric.is_none()
    }

    /// The quadric's sample at `ctx` ([`quadric::QuadricSampler::sample`]).
    fn sample_quadric(&self, q: &QuadricSampler, ctx: &LightContext, u: Vec2) -> Option<LightLiSample> {
        let s = q.sample(ctx, u)?;
        let d = s.p - ctx.p;
        if !(d.length_squared() > 0.0) {
            return None;
        }
        let wi = d.normalize();
        let g = &self.geom;
        if !(g.two_sided || s.n.dot(-wi) > 0.0) {
            return None;
        }
        Some(LightLiSample {
            li: g.l,
            wi,
            pdf: s.pdf,
            p_light: s.p,
            p_light_error: s.p_error,
            n_light: s.n,
            delta: false,
        })
    }

    /// The point `u` chooses (pbrt-v3's `Shape::Sample(u)`: a triangle in proportion to area,
    /// then uniformly on it).
    #[inline]
    pub fn sample_point(&self, u: Vec2) -> Option<AreaLightPoint> {
        let (k, u0) = match &self.tri_dist {
            Some(d) => {
                let (i, _, r) = d.sample_discrete(u.x);
                (i, r)
            }
            None => (0, u.x),
        };
        let tri = self.triangles.get(k)?;
        let pv = tri.pv;
        let b = uniform_sample_triangle(Vec2::new(u0, u.y));
        let b = [b.x, b.y, 1.0 - b.x - b.y];
        let p = interpolate(pv, b);
        let n = tri.normal_at(b);
        let p_error = gamma(6) * ((b[0] * pv[0]).abs() + (b[1] * pv[1]).abs() + (b[2] * pv[2]).abs());
        Some(AreaLightPoint { p, p_error, n })
    }

    /// The incident radiance sample at `ctx` from the light's `point` (pbrt-v3's `Sample_Li`
    /// after `Shape::Sample`): direction, solid-angle pdf, emitted radiance toward `ctx`.
    #[inline]
    fn sample_li_from(&self, ctx: &LightContext, point: &AreaLightPoint) -> Option<LightLiSample> {
        let (wi, pdf, li) = self.li_from(ctx.p, point)?;
        let &AreaLightPoint { p, p_error, n } = point;
        Some(LightLiSample { li, wi, pdf, p_light: p, p_light_error: p_error, n_light: n, delta: false })
    }

    /// The direction, solid-angle pdf and radiance of [`Light::sample_li_from`]'s sample at
    /// the point `at` (`None` where that gives none).
    #[inline(always)]
    pub fn li_from(&self, at: Vec3, point: &AreaLightPoint) -> Option<(Vec3, f32, Rgb)> {
        let &AreaLightPoint { p, n, .. } = point;
        let g = &self.geom;
        let d = p - at;
        let d2 = d.length_squared();
        if !(d2 > 0.0) || !d2.is_finite() {
            return None;
        }
        let wi = d / d2.sqrt();
        let pdf = d2 / (n.dot(wi).abs() * g.area);
        if !(pdf.is_finite() && pdf > 0.0) {
            return None;
        }
        let li = if g.two_sided || n.dot(-wi) > 0.0 { g.l } else { Rgb::ZERO };
        if li == Rgb::ZERO {
            return None;
        }
        Some((wi, pdf, li))
    }
}

/// `infinite`: an environment map in pbrt-v3's lat-long parameterisation
/// (u = φ/2π, v = θ/π about light-space +z), importance-sampled by a
/// piecewise-constant distribution of luminance × sin θ.
#[derive(Clone, Debug, PartialEq)]
pub struct InfiniteLight {
    /// Texels already multiplied by `L × scale`.
    pub map: RgbMap,
    pub dist: Distribution2D,
    pub light_from_world: Mat3,
    pub world_from_light: Mat3,
    pub scene_radius: f32,
    pub n_samples: u32,
}

impl InfiniteLight {
    /// Light-space (θ, sin θ, φ) of the world direction `d`; θ by `atan2`, which
    /// (unlike pbrt-v3's `acos`, equal up to rounding) stays accurate near the poles.
    fn angles(&self, d: Vec3) -> Option<(f32, f32, f32)> {
        let w = (self.light_from_world * d).normalize_or_zero();
        if w == Vec3::ZERO || !w.is_finite() {
            return None;
        }
        let r = (w.x * w.x + w.y * w.y).sqrt();
        Some((r.atan2(w.z), r, spherical_phi(w)))
    }

    fn lookup_dir(&self, d: Vec3) -> Rgb {
        self.angles(d).map_or(Rgb::ZERO, |a| self.lookup_at(a))
    }

    /// The map's radiance at the [`InfiniteLight::angles`] `(θ, sin θ, φ)`.
    #[inline]
    fn lookup_at(&self, (theta, _, phi): (f32, f32, f32)) -> Rgb {
        self.map.lookup(Vec2::new(phi / (2.0 * PI), theta / PI))
    }

    /// The solid-angle density of sampling the direction at `(θ, sin θ, φ)` (0 at the poles).
    #[inline]
    fn pdf_at(&self, (theta, sin_t, phi): (f32, f32, f32)) -> f32 {
        if !(sin_t > 0.0) {
            return 0.0;
        }
        let pdf = self.dist.pdf(Vec2::new(phi / (2.0 * PI), theta / PI)) / (2.0 * PI * PI * sin_t);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }
}

/// `goniometric`: a point light whose intensity is modulated by a lat-long map
/// about light-space +y (pbrt-v3 swaps y and z before the lookup).
#[derive(Clone, Debug, PartialEq)]
pub struct GoniometricLight {
    pub p: Vec3,
    pub i: Rgb,
    pub light_from_world: Mat3,
    pub map: Option<RgbMap>,
}

impl GoniometricLight {
    /// pbrt-v3's `GonioPhotometricLight::Scale` for the world direction `w` leaving the light.
    pub fn scale(&self, w: Vec3) -> Rgb {
        let Some(map) = &self.map else { return Rgb::ONE };
        let wp = (self.light_from_world * w).normalize_or_zero();
        if wp == Vec3::ZERO || !wp.is_finite() {
            return Rgb::ZERO;
        }
        let wp = Vec3::new(wp.x, wp.z, wp.y);
        map.lookup(Vec2::new(spherical_phi(wp) / (2.0 * PI), spherical_theta(wp) / PI))
    }
}

/// `projection`: a point light projecting an image through a perspective frustum along light-space +z.
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectionLight {
    pub p: Vec3,
    pub i: Rgb,
    pub light_from_world: Mat3,
    pub map: Option<RgbMap>,
    /// Screen window `[x0, x1, y0, y1]` (the longer image side spans [-aspect, aspect]).
    pub screen: [f32; 4],
    /// 1 / tan(fov / 2).
    pub inv_tan_half_fov: f32,
}

impl ProjectionLight {
    const HITHER: f32 = 1e-3;

    /// pbrt-v3's `ProjectionLight::Projection` for the world direction `w` leaving the light.
    pub fn projection(&self, w: Vec3) -> Rgb {
        let wl = self.light_from_world * w;
        if !(wl.z >= Self::HITHER) {
            return Rgb::ZERO;
        }
        let x = wl.x / wl.z * self.inv_tan_half_fov;
        let y = wl.y / wl.z * self.inv_tan_half_fov;
        let [x0, x1, y0, y1] = self.screen;
        if !(x >= x0 && x <= x1 && y >= y0 && y <= y1) {
            return Rgb::ZERO;
        }
        match &self.map {
            None => Rgb::ONE,
            Some(m) => m.lookup(Vec2::new((x - x0) / (x1 - x0), (y - y0) / (y1 - y0))),
        }
    }
}

/// One light (enum dispatch).
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    Point(PointLight),
    Spot(SpotLight),
    Distant(DistantLight),
    Area(DiffuseAreaLight),
    Infinite(InfiniteLight),
    Goniometric(GoniometricLight),
    Projection(ProjectionLight),
}

/// A delta-position light sample: intensity × `modulation` / d² from `p`.
fn point_sample(
    ctx: &LightContext,
    p: Vec3,
    intensity: Rgb,
    modulation: impl Fn(Vec3) -> Rgb,
) -> Option<LightLiSample> {
    let d = p - ctx.p;
    let d2 = d.length_squared();
    if !(d2 > 0.0) || !d2.is_finite() {
        return None;
    }
    let wi = d / d2.sqrt();
    let li = intensity * modulation(-wi) / d2;
    if li == Rgb::ZERO || !li.is_finite() {
        return None;
    }
    Some(LightLiSample { li, wi, pdf: 1.0, p_light: p, p_light_error: Vec3::ZERO, n_light: Vec3::ZERO, delta: true })
}

fn tri_vertices(mesh: &TriangleMesh, tri: usize) -> Option<[Vec3; 3]> {
    let idx = mesh.indices.get(tri)?;
    Some(
        [
            mesh.positions.get(idx[0] as usize)?,
            mesh.positions.get(idx[1] as usize)?,
            mesh.positions.get(idx[2] as usize)?,
        ]
        .map(|p| *p),
    )
}

/// The normal pbrt-v3's `Shape::Sample` gives the point with barycentrics `b`
/// ([`TriangleMesh::sample_normal`], through the light's cached triangle).
fn sampled_normal(mesh: &TriangleMesh, tri: usize, pv: [Vec3; 3], b: [f32; 3]) -> Vec3 {
    LightTriangle::new(mesh, tri, pv).normal_at(b)
}

/// The emitting side of triangle `tri` of `mesh`, as area lights define it (the normal
/// [`Light::sample_li`] gives a point at the triangle's centroid). Zero for a degenerate triangle.
pub fn emitting_normal(mesh: &TriangleMesh, tri: usize) -> Vec3 {
    match tri_vertices(mesh, tri) {
        Some(pv) => sampled_normal(mesh, tri, pv, [1.0 / 3.0; 3]),
        None => Vec3::ZERO,
    }
}

impl Light {
    /// Samples an incident direction at `ctx` (pbrt-v3's `Sample_Li`). `None` if the
    /// pdf is 0 or the sample carries no radiance.
    /// (`_meshes`: area lights keep what they sample of their triangles; the argument stays so
    /// that callers need not change.)
    pub fn sample_li(&self, ctx: &LightContext, u: Vec2, _meshes: &[TriangleMesh]) -> Option<LightLiSample> {
        crate::profiling::timed(Phase::LightSampling, || match self {
            Light::Point(l) => point_sample(ctx, l.p, l.i, |_| Rgb::ONE),
            Light::Spot(l) => point_sample(ctx, l.p, l.i, |w| Rgb::splat(l.falloff(w))),
            Light::Goniometric(l) => point_sample(ctx, l.p, l.i, |w| l.scale(w)),
            Light::Projection(l) => point_sample(ctx, l.p, l.i, |w| l.projection(w)),
            Light::Distant(l) => {
                if !ctx.p.is_finite() {
                    return None;
                }
                Some(LightLiSample {
                    li: l.l,
                    wi: l.w,
                    pdf: 1.0,
                    p_light: ctx.p + l.w * (2.0 * l.scene_radius),
                    p_light_error: Vec3::ZERO,
                    n_light: Vec3::ZERO,
                    delta: true,
                })
            }
            Light::Infinite(l) => {
                let (uv, map_pdf) = l.dist.sample_continuous(u);
                if !(map_pdf > 0.0) {
                    return None;
                }
                let (theta, phi) = (uv.y * PI, uv.x * 2.0 * PI);
                let (sin_t, cos_t) = theta.sin_cos();
                let (sin_p, cos_p) = phi.sin_cos();
                if !(sin_t > 0.0) {
                    return None;
                }
                let wi = (l.world_from_light * Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t)).normalize_or_zero();
                let pdf = map_pdf / (2.0 * PI * PI * sin_t);
                let li = l.map.lookup(uv);
                if wi == Vec3::ZERO || !(pdf.is_finite() && pdf > 0.0) || li == Rgb::ZERO || !ctx.p.is_finite() {
                    return None;
                }
                Some(LightLiSample {
                    li,
                    wi,
                    pdf,
                    p_light: ctx.p + wi * (2.0 * l.scene_radius),
                    p_light_error: Vec3::ZERO,
                    n_light: Vec3::ZERO,
                    delta: false,
                })
            }
            Light::Area(a) => match &a.quadric {
                Some(q) => a.sample_quadric(q, ctx, u),
                None => a.sample_li_from(ctx, &a.sample_point(u)?),
            },
        })
    }

    /// [`Light::sample_li`] for an area light whose point [`DiffuseAreaLight::sample_point`]
    /// already chose (it does not depend on `ctx`): the same sample, for lights that
    /// [`DiffuseAreaLight::samples_by_area`]. `None` for other lights.
    pub fn sample_li_from(&self, ctx: &LightContext, point: &AreaLightPoint) -> Option<LightLiSample> {
        crate::profiling::timed(Phase::LightSampling, || match self {
            Light::Area(a) => a.sample_li_from(ctx, point),
            _ => None,
        })
    }

    /// Solid-angle pdf of sampling `wi` from `ctx`; for area lights the caller passes the point it found on the light (`light_hit`: point and geometric normal), since the caller already traced the ray.
    pub fn pdf_li(&self, ctx: &LightContext, wi: Vec3, light_hit: Option<(Vec3, Vec3)>) -> f32 {
        crate::profiling::timed(Phase::LightSampling, || match self {
            Light::Infinite(l) => l.angles(wi).map_or(0.0, |a| l.pdf_at(a)),
            Light::Area(a) if a.quadric.is_some() => a.quadric.as_ref().map_or(0.0, |q| q.pdf(ctx, light_hit)),
            Light::Area(a) => {
                let Some((p, n)) = light_hit else { return 0.0 };
                let d2 = (p - ctx.p).length_squared();
                let cos = n.normalize_or_zero().dot(wi.normalize_or_zero()).abs();
                let pdf = d2 / (cos * a.geom.area);
                if pdf.is_finite() && pdf > 0.0 {
                    pdf
                } else {
                    0.0
                }
            }
            _ => 0.0,
        })
    }

    /// Emitted radiance of an area light at a point with geometric normal `n` towards `w` (zero for other lights).
    /// Pass `SurfaceInteraction::n` (pbrt-v3's oriented normal) and `wo` for a ray hit.
    pub fn l(&self, n: Vec3, w: Vec3) -> Rgb {
        match self {
            Light::Area(a) if a.geom.two_sided || n.dot(w) > 0.0 => a.geom.l,
            _ => Rgb::ZERO,
        }
    }

    /// Radiance of infinite lights along an escaping ray (zero for other lights).
    pub fn le(&self, ray: &Ray) -> Rgb {
        crate::profiling::timed(Phase::LightSampling, || match self {
            Light::Infinite(l) => l.lookup_dir(ray.d),
            _ => Rgb::ZERO,
        })
    }

    /// [`Light::le`] of an escaping ray and [`Light::pdf_li`] of its direction (which for the
    /// lights with radiance there, infinite lights, does not depend on the receiving point):
    /// the same values, with the direction's angles found once.
    pub fn le_and_pdf(&self, ray: &Ray) -> (Rgb, f32) {
        crate::profiling::timed(Phase::LightSampling, || match self {
            Light::Infinite(l) => match l.angles(ray.d) {
                Some(a) => (l.lookup_at(a), l.pdf_at(a)),
                None => (Rgb::ZERO, 0.0),
            },
            _ => (Rgb::ZERO, 0.0),
        })
    }

    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point(_) | Light::Spot(_) | Light::Distant(_) | Light::Goniometric(_) | Light::Projection(_)
        )
    }

    /// Emitted power (pbrt-v3's `Light::Power`), for choosing lights in proportion to it. Maps
    /// enter by their mean texel, where pbrt-v3 takes a coarse MIP-map level's lookup at the
    /// centre (an approximation of the same mean).
    pub fn power(&self) -> Rgb {
        let mean = |m: &Option<RgbMap>| m.as_ref().map_or(Rgb::ONE, RgbMap::mean);
        match self {
            Light::Point(l) => 4.0 * PI * l.i,
            Light::Spot(l) => l.i * 2.0 * PI * (1.0 - 0.5 * (l.cos_falloff_start + l.cos_total_width)),
            Light::Distant(l) => l.l * PI * l.scene_radius * l.scene_radius,
            Light::Area(a) => {
                let area = a.quadric.as_ref().map_or(a.geom.area, |q| q.area());
                (if a.geom.two_sided { 2.0 } else { 1.0 }) * a.geom.l * area * PI
            }
            Light::Infinite(l) => PI * l.scene_radius * l.scene_radius * l.map.mean(),
            Light::Goniometric(l) => 4.0 * PI * l.i * mean(&l.map),
            Light::Projection(l) => {
                let [x0, x1, y0, y1] = l.screen;
                let aspect = (x1 - x0) / (y1 - y0);
                let tan_diag = (1.0 + 1.0 / (aspect * aspect)).sqrt() / l.inv_tan_half_fov;
                let cos_total_width = 1.0 / (1.0 + tan_diag * tan_diag).sqrt();
                mean(&l.map) * l.i * 2.0 * PI * (1.0 - cos_total_width)
            }
        }
    }

    pub fn is_infinite(&self) -> bool {
        matches!(self, Light::Infinite(_))
    }

    /// pbrt-v3's `nSamples` (`samples`, falling back to `nsamples`, for area and infinite lights; 1 otherwise).
    pub fn n_samples(&self) -> u32 {
        match self {
            Light::Area(a) => a.n_samples,
            Light::Infinite(l) => l.n_samples,
            _ => 1,
        }
    }

    /// Whether this is an area light whose points do not depend on the receiver
    /// ([`DiffuseAreaLight::samples_by_area`]).
    pub fn area_samples_by_area(&self) -> bool {
        matches!(self, Light::Area(a) if a.samples_by_area())
    }

    /// The light geometry, for analytic integrators.
    pub fn area(&self) -> Option<&AreaLight> {
        match self {
            Light::Area(a) => Some(&a.geom),
            _ => None,
        }
    }
}

/// Which lights the triangles of one mesh belong to.
#[derive(Clone, Debug, PartialEq)]
enum MeshLights {
    None,
    Whole(u32),
    /// Light index per triangle, `u32::MAX` for none.
    PerTriangle(Vec<u32>),
}

/// All lights of a scene and the map from emissive triangles to their lights.
#[derive(Clone, Debug, PartialEq)]
pub struct Lights {
    pub lights: Vec<Light>,
    mesh_lights: Vec<MeshLights>,
}

/// A `diffuse` `AreaLightSource`'s parameters.
#[derive(Clone, Debug)]
struct AreaParams {
    l: Rgb,
    two_sided: bool,
    n_samples: u32,
    sampling: ShapeSampling,
    loc: FileLoc,
}

/// `"string shapesampling"`: `"pbrt-v3"` (default) or `"physical"` ([`quadric`]).
fn shape_sampling_param(p: &ParamSet, owner: &str, loc: &FileLoc, warnings: &DiagSink) -> ShapeSampling {
    match p.get_one_string("shapesampling", "pbrt-v3").as_str() {
        "pbrt-v3" => ShapeSampling::Pbrt,
        "physical" => ShapeSampling::Physical,
        other => {
            warnings.warn(
                Some(p.loc_of("shapesampling").unwrap_or(loc).clone()),
                format!(
                    "{owner}: \"shapesampling\" \"{other}\" unknown (\"pbrt-v3\" or \"physical\"): using \"pbrt-v3\""
                ),
            );
            ShapeSampling::Pbrt
        }
    }
}

/// Warns where pbrt-v3's sampling of a quadric light (reproduced by default) makes it emit
/// other than its geometry does: a scaling transform, a partial sphere or disk.
fn warn_quadric_sampling(
    q: &crate::mesh::Quadric,
    kind: &str,
    sampling: ShapeSampling,
    light_loc: &FileLoc,
    shape_loc: &FileLoc,
    warnings: &DiagSink,
) {
    if sampling == ShapeSampling::Physical {
        return;
    }
    let s = quadric::axis_scales(&q.world_from_object);
    let scaled = s.iter().any(|v| (v - 1.0).abs() > 1e-4);
    let hint = "\"string shapesampling\" \"physical\" on the AreaLightSource gives the light its geometry emits";
    if scaled {
        let scale = if (s[0] - s[1]).abs() <= 1e-4 * s[0] && (s[0] - s[2]).abs() <= 1e-4 * s[0] {
            format!("{:.4}", s[0])
        } else {
            format!("({:.4}, {:.4}, {:.4}) along object x, y, z", s[0], s[1], s[2])
        };
        let factor = 1.0 / (s[0] * s[1].max(s[2]).max(1e-30));
        warnings.warn(
            Some(shape_loc.clone()),
            format!(
                "area light (at {light_loc}) on a {kind} scaled by {scale}: sampled as pbrt-v3 samples it, with its \
                 object-space radius and area against world-space distances, so it is not the light its geometry \
                 emits (about {factor:.3}x as bright where light sampling dominates{}); {hint}",
                if kind == "sphere" && s[0] > 1.0 { ", and darker where its samples fall inside itself" } else { "" }
            ),
        );
    }
    if !q.shape.sampled_whole() {
        warnings.warn(
            Some(shape_loc.clone()),
            format!(
                "area light (at {light_loc}) on a partial {kind} (zmin/zmax/phimax/innerradius): pbrt-v3 samples the \
                 whole {kind}, so points the shape cuts away emit too; reproduced; {hint}"
            ),
        );
    }
}

/// Shape types pbrt-v3 turns into one `Triangle` shape per triangle (so one area light per triangle).
pub fn is_per_triangle_shape(kind: &str) -> bool {
    matches!(kind, "trianglemesh" | "plymesh" | "loopsubdiv" | "heightfield" | "nurbs")
}

fn linear_part(m: &[[f64; 4]; 4]) -> Mat3 {
    Mat3::from_cols(
        Vec3::new(m[0][0] as f32, m[1][0] as f32, m[2][0] as f32),
        Vec3::new(m[0][1] as f32, m[1][1] as f32, m[2][1] as f32),
        Vec3::new(m[0][2] as f32, m[1][2] as f32, m[2][2] as f32),
    )
}

fn point_f32(t: &Transform, p: [f32; 3]) -> Vec3 {
    Vec3::from(t.apply_point([p[0] as f64, p[1] as f64, p[2] as f64]).map(|v| v as f32))
}

fn spectrum_param(p: &ParamSet, name: &str, default: Rgb, owner: &str, loc: &FileLoc) -> Result<Rgb, Diagnostic> {
    match p.get_spectrum(name) {
        None => Ok(default),
        Some(v) => spectrum_to_rgb(v).map_err(|e| {
            Diagnostic::error(
                Some(p.loc_of(name).unwrap_or(loc).clone()),
                format!("{owner}: parameter \"{name}\": {e}"),
            )
        }),
    }
}

/// pbrt-v3 reads `samples`, falling back to `nsamples` (both count as used).
fn n_samples_param(p: &ParamSet) -> u32 {
    let ns = p.get_one_int("nsamples", 1);
    p.get_one_int("samples", ns).max(1) as u32
}

/// An image as RGB texels: the R, G, B channels by name, else the first three, else grey from the first.
fn image_to_map(img: &Image) -> Option<RgbMap> {
    let (w, h) = (img.width as usize, img.height as usize);
    let nc = img.channels.len();
    if w == 0 || h == 0 || nc == 0 || img.data.len() < w * h * nc {
        return None;
    }
    let find = |name: &str| {
        img.channels.iter().position(|c| {
            c.eq_ignore_ascii_case(name) || c.rsplit('.').next().is_some_and(|s| s.eq_ignore_ascii_case(name))
        })
    };
    let idx = match (find("R"), find("G"), find("B")) {
        (Some(r), Some(g), Some(b)) => [r, g, b],
        _ if nc >= 3 => [0, 1, 2],
        _ => [0, 0, 0],
    };
    let texels = img
        .data
        .chunks_exact(nc)
        .take(w * h)
        .map(|px| {
            let c = Rgb::from(idx.map(|i| px[i]));
            // Non-finite texels would poison every estimate: count them as black.
            if c.is_finite() {
                c
            } else {
                Rgb::ZERO
            }
        })
        .collect();
    Some(RgbMap { width: w, height: h, texels })
}

/// Reads `mapname` as pbrt-v3's `ReadImage` does: EXR/PFM values as stored,
/// PNG code values / 255 with no sRGB decoding and alpha ignored.
/// A missing name gives `None`; an unreadable file a warning and `None` (pbrt-v3 then falls back too).
fn load_map(desc: &SceneDescription, p: &ParamSet, owner: &str, warnings: &DiagSink) -> Option<RgbMap> {
    let name = p.get_one_string("mapname", "");
    if name.is_empty() {
        return None;
    }
    let loc = p.loc_of("mapname").cloned();
    let path = desc.resolve_path(&name);
    match read_image(&path) {
        Ok(img) => {
            let m = image_to_map(&img);
            if m.is_none() {
                warnings.warn(loc, format!("{owner}: \"{}\" has no pixels: ignored", path.display()));
            }
            m
        }
        Err(e) => {
            warnings.warn(
                loc,
                format!("{owner}: cannot read \"{}\": {e}; ignoring the map as pbrt-v3 does", path.display()),
            );
            None
        }
    }
}

/// Largest map (in texels) whose sampling distribution is built at twice its
/// resolution, as pbrt-v3 does; larger maps use their own resolution to bound memory.
const MAX_TEXELS_FOR_2X_DISTRIBUTION: usize = 1 << 22;

fn infinite_distribution(map: &RgbMap) -> Distribution2D {
    let scale = if map.width * map.height <= MAX_TEXELS_FOR_2X_DISTRIBUTION { 2 } else { 1 };
    let (nu, nv) = (scale * map.width, scale * map.height);
    let mut img = vec![0.0f32; nu * nv];
    for v in 0..nv {
        let vp = (v as f32 + 0.5) / nv as f32;
        let sin_theta = (PI * vp).sin();
        for u in 0..nu {
            let up = (u as f32 + 0.5) / nu as f32;
            img[v * nu + u] = luminance(map.lookup(Vec2::new(up, vp))) * sin_theta;
        }
    }
    Distribution2D::new(&img, nu, nv)
}

fn usable(c: Rgb) -> bool {
    c != Rgb::ZERO && c.is_finite()
}

impl Lights {
    /// Builds the lights of `desc`. `meshes[i]` is the geometry of `objects[i]`;
    /// `scene_bounds` gives the scene radius for distant and infinite lights.
    /// Unused parameters of light entities are reported to `warnings`.
    pub fn build(
        desc: &SceneDescription,
        meshes: &[TriangleMesh],
        objects: &[SceneObject],
        scene_bounds: Bounds3,
        warnings: &DiagSink,
    ) -> Result<Lights, Diagnostic> {
        let (_, r) = scene_bounds.bounding_sphere();
        let scene_radius = if r.is_finite() { r } else { 0.0 };
        let mut lights = Vec::new();
        for ld in &desc.lights {
            let e = &ld.entity;
            let owner = format!("light \"{}\"", e.kind);
            if let Some(l) = make_light(desc, ld, &owner, scene_radius, warnings)? {
                lights.push(l);
            }
            warnings.extend(e.params.report_unused(&owner));
        }

        // Area lights: parse each AreaLightSource once.
        let mut area_params: Vec<Option<Option<AreaParams>>> = vec![None; desc.area_lights.len()];
        let mut mesh_lights = vec![MeshLights::None; meshes.len()];
        let mut warned_instance = false;
        for (oi, obj) in objects.iter().enumerate().take(meshes.len()) {
            let Some(ai) = obj.area_light else { continue };
            if obj.instance.is_some() {
                if !warned_instance {
                    warnings.warn(
                        Some(obj.loc.clone()),
                        "area lights are not supported with object instancing (as in pbrt-v3): the instanced shapes do not emit",
                    );
                    warned_instance = true;
                }
                continue;
            }
            let Some(ent) = desc.area_lights.get(ai) else { continue };
            if area_params[ai].is_none() {
                let owner = format!("area light \"{}\"", ent.kind);
                let parsed = if ent.kind == "diffuse" || ent.kind == "area" {
                    let p = &ent.params;
                    let l = spectrum_param(p, "L", Rgb::ONE, &owner, &ent.loc)?;
                    let sc = spectrum_param(p, "scale", Rgb::ONE, &owner, &ent.loc)?;
                    let two_sided = p.get_one_bool("twosided", false);
                    let ns = n_samples_param(p);
                    let sampling = shape_sampling_param(p, &owner, &ent.loc, warnings);
                    let l = l * sc;
                    if !l.is_finite() {
                        warnings.warn(Some(ent.loc.clone()), format!("{owner}: non-finite radiance: ignored"));
                        None
                    } else {
                        Some(AreaParams { l, two_sided, n_samples: ns, sampling, loc: ent.loc.clone() })
                    }
                } else {
                    warnings.warn(
                        Some(ent.loc.clone()),
                        format!("area light \"{}\" unknown: its shapes do not emit", ent.kind),
                    );
                    ent.params.mark_all_used();
                    None
                };
                warnings.extend(ent.params.report_unused(&owner));
                area_params[ai] = Some(parsed);
            }
            let Some(Some(AreaParams { l, two_sided, n_samples, sampling, ref loc })) = area_params[ai] else {
                continue;
            };
            if l == Rgb::ZERO {
                continue;
            }
            let mesh = &meshes[oi];
            if mesh.curves.is_some() {
                // pbrt-v3's `Curve::Sample` is unimplemented (it aborts the render).
                warnings.warn(
                    Some(obj.loc.clone()),
                    "area light on a \"curve\": pbrt-v3 cannot sample curves (it aborts); the curve does not emit",
                );
                continue;
            }
            let over = |tris: &mut dyn Iterator<Item = u32>| {
                DiffuseAreaLight::over_triangles(oi as u32, mesh, tris, l, two_sided, n_samples)
            };
            if is_per_triangle_shape(&obj.kind) {
                let mut per = vec![u32::MAX; mesh.triangle_count()];
                for (t, slot) in per.iter_mut().enumerate() {
                    if let Some(a) = over(&mut std::iter::once(t as u32)) {
                        *slot = lights.len() as u32;
                        lights.push(Light::Area(a));
                    }
                }
                mesh_lights[oi] = MeshLights::PerTriangle(per);
            } else if let Some(mut a) = over(&mut (0..mesh.triangle_count() as u32)) {
                if let Some(q) = &mesh.quadric {
                    warn_quadric_sampling(q, &obj.kind, sampling, loc, &obj.loc, warnings);
                    a.quadric = QuadricSampler::new(q, mesh.reverse_orientation, sampling).map(Box::new);
                }
                mesh_lights[oi] = MeshLights::Whole(lights.len() as u32);
                lights.push(Light::Area(a));
            }
        }
        Ok(Lights { lights, mesh_lights })
    }

    /// The light that triangle `tri` of mesh `mesh` belongs to, if it emits.
    pub fn light_of(&self, mesh: u32, tri: u32) -> Option<usize> {
        match self.mesh_lights.get(mesh as usize)? {
            MeshLights::None => None,
            MeshLights::Whole(i) => Some(*i as usize),
            MeshLights::PerTriangle(v) => v.get(tri as usize).filter(|&&i| i != u32::MAX).map(|&i| i as usize),
        }
    }

    pub fn infinite(&self) -> impl Iterator<Item = &Light> {
        self.lights.iter().filter(|l| l.is_infinite())
    }

    pub fn len(&self) -> usize {
        self.lights.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }
}

/// One `LightSource`; `None` (after a warning where pbrt-v3 warns) when it is skipped.
fn make_light(
    desc: &SceneDescription,
    ld: &penumbra_parser::LightDesc,
    owner: &str,
    scene_radius: f32,
    warnings: &DiagSink,
) -> Result<Option<Light>, Diagnostic> {
    let e = &ld.entity;
    let p = &e.params;
    let ctm = ld.render_from_light.start;
    if ld.render_from_light.is_animated() {
        warnings.warn(
            Some(e.loc.clone()),
            format!("{owner}: animated light transforms are not supported: using the start transform"),
        );
    }
    let kind = e.kind.as_str();
    let known = matches!(kind, "point" | "spot" | "goniometric" | "projection" | "distant" | "infinite" | "exinfinite");
    if !known {
        warnings.warn(Some(e.loc.clone()), format!("light \"{kind}\" unknown: ignored"));
        p.mark_all_used();
        return Ok(None);
    }
    let intensity_name = if matches!(kind, "distant" | "infinite" | "exinfinite") { "L" } else { "I" };
    let base = spectrum_param(p, intensity_name, Rgb::ONE, owner, &e.loc)?;
    let sc = spectrum_param(p, "scale", Rgb::ONE, owner, &e.loc)?;
    let c = base * sc;
    let ctm_lin = linear_part(&ctm.m);
    let ctm_inv_lin = linear_part(&ctm.m_inv);
    let light = match kind {
        "point" => {
            let from = p.get_one_point3("from", [0.0; 3]);
            Light::Point(PointLight { p: point_f32(&ctm, [0.0; 3]) + Vec3::from(from), i: c })
        }
        "spot" => {
            let cone = p.get_one_float("coneangle", 30.0);
            let delta = p.get_one_float("conedeltaangle", 5.0);
            let from = Vec3::from(p.get_one_point3("from", [0.0; 3]));
            let to = Vec3::from(p.get_one_point3("to", [0.0, 0.0, 1.0]));
            let axis = (to - from).normalize_or_zero();
            if axis == Vec3::ZERO || !axis.is_finite() {
                warnings.warn(Some(e.loc.clone()), format!("{owner}: \"from\" and \"to\" coincide: ignored"));
                return Ok(None);
            }
            Light::Spot(SpotLight {
                p: point_f32(&ctm, from.to_array()),
                i: c,
                light_from_world: ctm_inv_lin,
                axis,
                cos_total_width: cone.to_radians().cos(),
                cos_falloff_start: (cone - delta).to_radians().cos(),
            })
        }
        "goniometric" => Light::Goniometric(GoniometricLight {
            p: point_f32(&ctm, [0.0; 3]),
            i: c,
            light_from_world: ctm_inv_lin,
            map: load_map(desc, p, owner, warnings),
        }),
        "projection" => {
            let fov = p.get_one_float("fov", 45.0);
            let map = load_map(desc, p, owner, warnings);
            let aspect = map.as_ref().map_or(1.0, |m| m.width as f32 / m.height as f32);
            let screen =
                if aspect > 1.0 { [-aspect, aspect, -1.0, 1.0] } else { [-1.0, 1.0, -1.0 / aspect, 1.0 / aspect] };
            let inv_tan = 1.0 / (fov.to_radians() / 2.0).tan();
            if !inv_tan.is_finite() || !(inv_tan > 0.0) {
                warnings.warn(
                    p.loc_of("fov").cloned().or(Some(e.loc.clone())),
                    format!("{owner}: invalid \"fov\": ignored"),
                );
                return Ok(None);
            }
            Light::Projection(ProjectionLight {
                p: point_f32(&ctm, [0.0; 3]),
                i: c,
                light_from_world: ctm_inv_lin,
                map,
                screen,
                inv_tan_half_fov: inv_tan,
            })
        }
        "distant" => {
            let from = Vec3::from(p.get_one_point3("from", [0.0; 3]));
            let to = Vec3::from(p.get_one_point3("to", [0.0, 0.0, 1.0]));
            let w = (ctm_lin * (from - to)).normalize_or_zero();
            if w == Vec3::ZERO || !w.is_finite() {
                warnings.warn(Some(e.loc.clone()), format!("{owner}: \"from\" and \"to\" coincide: ignored"));
                return Ok(None);
            }
            Light::Distant(DistantLight { l: c, w, scene_radius })
        }
        _ => {
            // infinite / exinfinite
            let n_samples = n_samples_param(p);
            let map = match load_map(desc, p, owner, warnings) {
                Some(mut m) => {
                    for t in &mut m.texels {
                        *t *= c;
                    }
                    m
                }
                None => RgbMap::constant(c),
            };
            if !map.texels.iter().any(|t| usable(*t)) {
                return Ok(None);
            }
            let dist = infinite_distribution(&map);
            Light::Infinite(InfiniteLight {
                map,
                dist,
                light_from_world: ctm_inv_lin,
                world_from_light: ctm_lin,
                scene_radius,
                n_samples,
            })
        }
    };
    if !usable(c) {
        if !c.is_finite() {
            warnings.warn(Some(e.loc.clone()), format!("{owner}: non-finite intensity: ignored"));
        }
        return Ok(None);
    }
    Ok(Some(light))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_parts_is_floor() {
        let mut rng = Rng::new(9);
        let special = [0.0f32, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5, 8_388_607.5, -8_388_607.5, 8_388_608.0, -8_388_609.0];
        let special = special.into_iter().chain([1e30, -1e30, f32::MAX, f32::MIN, f32::MIN_POSITIVE, -1e-45, 1e-45]);
        let random: Vec<f32> = (0..200_000).map(|_| f32::from_bits(rng.uniform_u32())).collect();
        let near: Vec<f32> = (0..200_000).map(|_| (rng.uniform_f32() - 0.5) * 4096.0).collect();
        for x in special.chain(random).chain(near).filter(|x| x.is_finite() && x.to_bits() != (-0.0f32).to_bits()) {
            let (f, i) = floor_parts(x);
            assert_eq!(f.to_bits(), x.floor().to_bits(), "{x}");
            assert_eq!(i, x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn wrap_is_rem_euclid() {
        for n in [1usize, 2, 3, 7, 512] {
            for i in -1100i64..1100 {
                assert_eq!(wrap(i, n), i.rem_euclid(n as i64) as usize, "{i} mod {n}");
            }
            for i in [i64::MIN, i64::MIN + 1, i64::MAX, -(n as i64), n as i64] {
                assert_eq!(wrap(i, n), i.rem_euclid(n as i64) as usize, "{i} mod {n}");
            }
        }
    }
    use crate::geometry::Frame;
    use crate::goodness_of_fit::chi2_test;
    use crate::rng::Rng;
    use penumbra_parser::{AnimatedTransform, CameraDesc, Entity, LightDesc, Param, ParamValue, SpectrumValue};
    use std::f64::consts::PI as PI64;
    use std::path::PathBuf;

    const ALPHA: f64 = 1e-4;

    fn loc() -> FileLoc {
        FileLoc::new("test.pbrt".into(), 3, 1)
    }

    fn desc() -> SceneDescription {
        SceneDescription {
            camera: CameraDesc {
                entity: Entity::default_of("perspective"),
                camera_from_world: AnimatedTransform::default(),
                world_from_camera: AnimatedTransform::default(),
                medium: None,
            },
            film: Entity::default_of("image"),
            sampler: Entity::default_of("halton"),
            filter: Entity::default_of("box"),
            integrator: Entity::default_of("directlighting"),
            accelerator: Entity::default_of("bvh"),
            transform_times: (0.0, 1.0),
            shapes: vec![],
            lights: vec![],
            area_lights: vec![],
            materials: vec![],
            textures: vec![],
            media: vec![],
            instance_definitions: vec![],
            instances: vec![],
            main_file: None,
            base_dir: PathBuf::new(),
            files_read: vec![],
        }
    }

    fn param(name: &str, v: ParamValue) -> Param {
        Param::new(name, v, FileLoc::new("test.pbrt".into(), 4, 7))
    }
    fn rgb(name: &str, c: [f32; 3]) -> Param {
        param(name, ParamValue::Spectrum(SpectrumValue::Rgb(c.to_vec())))
    }
    fn float(name: &str, v: f32) -> Param {
        param(name, ParamValue::Float(vec![v]))
    }
    fn point3(name: &str, v: [f32; 3]) -> Param {
        param(name, ParamValue::Point3(v.to_vec()))
    }
    fn string(name: &str, v: &str) -> Param {
        param(name, ParamValue::String(vec![v.to_string()]))
    }
    fn int(name: &str, v: i32) -> Param {
        param(name, ParamValue::Int(vec![v]))
    }
    fn entity(kind: &str, params: Vec<Param>) -> Entity {
        let mut ps = ParamSet::new();
        for p in params {
            ps.add(p);
        }
        Entity::new(kind, ps, loc())
    }
    fn light_desc(kind: &str, params: Vec<Param>, ctm: Transform) -> LightDesc {
        LightDesc { entity: entity(kind, params), render_from_light: AnimatedTransform::fixed(ctm), medium: None }
    }
    fn unit_bounds() -> Bounds3 {
        Bounds3 { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) }
    }

    /// Builds the lights of `lights` (no geometry); returns them and the warnings.
    fn build(lights: Vec<LightDesc>) -> (Vec<Light>, Vec<Diagnostic>) {
        let mut d = desc();
        d.lights = lights;
        let sink = DiagSink::new();
        let l = Lights::build(&d, &[], &[], unit_bounds(), &sink).expect("build");
        (l.lights, sink.take())
    }
    fn build_one(kind: &str, params: Vec<Param>, ctm: Transform) -> Light {
        let (mut l, w) = build(vec![light_desc(kind, params, ctm)]);
        assert_eq!(l.len(), 1, "warnings: {w:?}");
        l.remove(0)
    }

    fn object(kind: &str, area_light: Option<usize>, instance: Option<usize>) -> SceneObject {
        SceneObject { kind: kind.into(), loc: loc(), material: None, area_light, instance, occluder: true }
    }

    /// Area lights of `meshes`, all emitting through AreaLightSource 0 = `area`.
    fn build_area(meshes: &[TriangleMesh], kinds: &[&str], area: Entity) -> (Lights, Vec<Diagnostic>) {
        let mut d = desc();
        d.area_lights = vec![area];
        let objects: Vec<SceneObject> = kinds.iter().map(|k| object(k, Some(0), None)).collect();
        let sink = DiagSink::new();
        let l = Lights::build(&d, meshes, &objects, unit_bounds(), &sink).expect("build");
        (l, sink.take())
    }

    fn ctx(p: Vec3) -> LightContext {
        LightContext { p, p_error: Vec3::ZERO, n: Vec3::ZERO }
    }
    fn rand2(rng: &mut Rng) -> Vec2 {
        Vec2::new(rng.uniform_f32(), rng.uniform_f32())
    }

    /// Two-sided Möller–Trumbore in f64: the distance along unit `d`.
    fn ray_tri(o: Vec3, d: Vec3, t: [Vec3; 3]) -> Option<f64> {
        let (o, d) = (o.as_dvec3(), d.as_dvec3());
        let [a, b, c] = t.map(|v| v.as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-14 {
            return None;
        }
        let tv = o - a;
        let u = tv.dot(pv) / det;
        let qv = tv.cross(e1);
        let v = d.dot(qv) / det;
        let t = e2.dot(qv) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
    }

    /// The closest triangle of `mesh` along the ray: (distance, point, pbrt-v3 normal).
    fn first_hit(mesh: &TriangleMesh, o: Vec3, d: Vec3) -> Option<(f64, Vec3, Vec3)> {
        let mut best: Option<(f64, usize)> = None;
        for t in 0..mesh.triangle_count() {
            if let Some(h) = ray_tri(o, d, mesh.vertices(t)) {
                if best.is_none_or(|b| h < b.0) {
                    best = Some((h, t));
                }
            }
        }
        let (t, tri) = best?;
        let (n, _) = mesh.hit_normals(tri, [1.0 / 3.0; 3]);
        Some((t, o + d * t as f32, n))
    }

    /// Chi-square test that the directions `sample` returns (`None`: no sample) follow
    /// the solid-angle density `pdf`, binned in θ ≤ `theta_max` × φ about `frame.z`;
    /// expected counts integrate `pdf` with k×k midpoint sub-cells per bin.
    #[allow(clippy::too_many_arguments)]
    fn chi2_dirs(
        seed: u64,
        n: usize,
        frame: Frame,
        theta_max: f64,
        (nt, np, k): (usize, usize, usize),
        mut sample: impl FnMut(Vec2) -> Option<Vec3>,
        pdf: impl Fn(Vec3) -> f64,
    ) -> f64 {
        let mut rng = Rng::new(seed);
        let mut obs = vec![0.0f64; nt * np];
        for _ in 0..n {
            let Some(w) = sample(rand2(&mut rng)) else { continue };
            let l = frame.to_local(w).as_dvec3();
            let theta = l.z.clamp(-1.0, 1.0).acos();
            assert!(theta <= theta_max * (1.0 + 1e-6), "sample outside the light's cone: θ = {theta}");
            let phi = l.y.atan2(l.x).rem_euclid(2.0 * PI64);
            let it = ((theta / theta_max * nt as f64) as usize).min(nt - 1);
            let ip = ((phi / (2.0 * PI64) * np as f64) as usize).min(np - 1);
            obs[it * np + ip] += 1.0;
        }
        let (dt, dp) = (theta_max / (nt * k) as f64, 2.0 * PI64 / (np * k) as f64);
        let mut exp = vec![0.0f64; nt * np];
        for it in 0..nt * k {
            let theta = (it as f64 + 0.5) * dt;
            for ip in 0..np * k {
                let phi = (ip as f64 + 0.5) * dp;
                let l =
                    Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32);
                exp[(it / k) * np + ip / k] += pdf(frame.from_local(l)) * theta.sin() * dt * dp;
            }
        }
        let exp: Vec<f64> = exp.iter().map(|e| (e * n as f64).max(1e-9)).collect();
        let (chi2, dof, p) = chi2_test(&obs, &exp, 5.0);
        eprintln!("chi2 {chi2:.1} dof {dof} p {p:.3}");
        p
    }

    /// Smallest cone about the direction from `p` to the centre of `pts` that holds them, widened by 2 %.
    fn cone_over(p: Vec3, pts: &[Vec3]) -> (Frame, f64) {
        let c = pts.iter().copied().sum::<Vec3>() / pts.len() as f32;
        let z = (c - p).normalize();
        let tmax = pts.iter().map(|q| ((*q - p).normalize().dot(z).clamp(-1.0, 1.0) as f64).acos()).fold(0.0, f64::max);
        (Frame::from_z(z), tmax * 1.02)
    }

    /// ∫ pdf dω over the cone by a jittered grid uniform in (cos θ, φ).
    fn integrate_cone(frame: Frame, theta_max: f64, pdf: impl Fn(Vec3) -> f64) -> f64 {
        let (nz, np) = (512, 512);
        let mut rng = Rng::new(99);
        let zmin = theta_max.cos();
        let mut s = 0.0;
        for i in 0..nz {
            for j in 0..np {
                let z = 1.0 - (1.0 - zmin) * (i as f64 + rng.uniform_f64()) / nz as f64;
                let phi = 2.0 * PI64 * (j as f64 + rng.uniform_f64()) / np as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                s += pdf(frame.from_local(Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)));
            }
        }
        s / (nz * np) as f64 * 2.0 * PI64 * (1.0 - zmin)
    }

    /// A triangle facing `p` (winding normal towards it) as a one-triangle mesh.
    fn facing_triangle(p: Vec3, mut v: [Vec3; 3]) -> TriangleMesh {
        if (v[1] - v[0]).cross(v[2] - v[0]).dot(p - v[0]) < 0.0 {
            v.swap(1, 2);
        }
        TriangleMesh { positions: v.to_vec(), indices: vec![[0, 1, 2]], ..Default::default() }
    }

    /// Lambert's closed form of the irradiance at `p` (normal `n`) from a unit-radiance polygon above its horizon.
    fn polygon_irradiance(p: Vec3, n: Vec3, v: &[Vec3]) -> f64 {
        let u: Vec<_> = v.iter().map(|q| (*q - p).as_dvec3().normalize()).collect();
        let n = n.as_dvec3();
        let mut s = 0.0;
        for i in 0..u.len() {
            let (a, b) = (u[i], u[(i + 1) % u.len()]);
            s += a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(a.cross(b).normalize());
        }
        0.5 * s.abs()
    }

    #[test]
    fn triangle_light_samples_follow_pdf_li() {
        let p = Vec3::new(0.1, -0.2, 0.0);
        let v = [Vec3::new(-0.5, -0.3, 2.0), Vec3::new(0.9, -0.2, 2.6), Vec3::new(0.1, 0.8, 1.5)];
        let mesh = facing_triangle(p, v);
        let meshes = [mesh.clone()];
        let (lights, w) = build_area(&meshes, &["trianglemesh"], entity("diffuse", vec![rgb("L", [1.0, 2.0, 3.0])]));
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(lights.len(), 1);
        let light = &lights.lights[0];
        assert!(!light.is_delta() && !light.is_infinite());
        let c = ctx(p);
        let (frame, tmax) = cone_over(p, &v);
        let sample = |u: Vec2| {
            let s = light.sample_li(&c, u, &meshes)?;
            // The sampled direction hits the triangle at the sampled point, and the pdfs agree.
            let (t, hp, hn) = first_hit(&mesh, p, s.wi).expect("sampled direction misses the light");
            assert!((t as f32 - (s.p_light - p).length()).abs() < 1e-4 * t as f32);
            assert!(s.n_light.dot(hn) > 0.999, "normal {:?} vs {hn:?}", s.n_light);
            let q = light.pdf_li(&c, s.wi, Some((hp, hn)));
            assert!((q - s.pdf).abs() <= 1e-3 * s.pdf, "{q} vs {}", s.pdf);
            assert_eq!(s.li, Rgb::new(1.0, 2.0, 3.0));
            assert!(!s.delta);
            Some(s.wi)
        };
        let pdf =
            |w: Vec3| first_hit(&mesh, p, w).map_or(0.0, |(_, hp, hn)| light.pdf_li(&c, w, Some((hp, hn))) as f64);
        assert!(chi2_dirs(1, 100_000, frame, tmax, (8, 16, 40), sample, pdf) > ALPHA);
        let total = integrate_cone(frame, tmax, pdf);
        assert!((total - 1.0).abs() < 0.01, "∫ pdf_li dω = {total}");
    }

    #[test]
    fn quadric_light_over_several_triangles_samples_by_area() {
        // A lopsided octahedron (faces of different areas; "sphere" shape: one light over all triangles).
        let centre = Vec3::new(0.3, -0.2, 3.0);
        let axes = [(Vec3::X, 1.0, 0.4), (Vec3::Y, 0.6, 1.1), (Vec3::Z, 1.4, 0.7)];
        let mut positions = Vec::new();
        for (a, plus, minus) in axes {
            positions.push(centre + a * plus);
            positions.push(centre - a * minus);
        }
        let mut indices = Vec::new();
        for sx in 0..2u32 {
            for sy in 0..2u32 {
                for sz in 0..2u32 {
                    let mut t = [sx, 2 + sy, 4 + sz];
                    let [a, b, c] = t.map(|i| positions[i as usize]);
                    if (b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) < 0.0 {
                        t.swap(1, 2);
                    }
                    indices.push(t);
                }
            }
        }
        let mesh = TriangleMesh { positions: positions.clone(), indices, ..Default::default() };
        let meshes = [mesh.clone()];
        let (lights, _) = build_area(&meshes, &["sphere"], entity("area", vec![rgb("L", [2.0, 2.0, 2.0])]));
        assert_eq!(lights.len(), 1);
        let light = &lights.lights[0];
        let g = light.area().unwrap();
        assert_eq!(g.tris.len(), 8);
        let total_area: f32 = (0..8).map(|t| mesh.area(t)).sum();
        assert!((g.area - total_area).abs() < 1e-5 * total_area);
        let areas: Vec<f32> = (0..8).map(|t| mesh.area(t)).collect();
        assert!(areas.iter().cloned().fold(0.0, f32::max) > 2.0 * areas.iter().cloned().fold(f32::MAX, f32::min));
        for t in 0..8 {
            assert_eq!(lights.light_of(0, t), Some(0));
        }
        let p = Vec3::new(-0.4, 0.5, 0.2);
        let c = ctx(p);
        let (frame, tmax) = cone_over(p, &positions);
        let mut hidden = 0;
        let sample = |u: Vec2| {
            let s = light.sample_li(&c, u, &meshes)?;
            assert!(s.n_light.dot(s.p_light - centre) > 0.0, "normal points inwards");
            let (t, hp, hn) = first_hit(&mesh, p, s.wi).expect("sampled direction misses the light");
            if (t as f32 - (s.p_light - p).length()).abs() > 1e-4 * t as f32 {
                hidden += 1;
                return None;
            }
            let q = light.pdf_li(&c, s.wi, Some((hp, hn)));
            assert!((q - s.pdf).abs() <= 1e-3 * s.pdf, "{q} vs {}", s.pdf);
            Some(s.wi)
        };
        let pdf =
            |w: Vec3| first_hit(&mesh, p, w).map_or(0.0, |(_, hp, hn)| light.pdf_li(&c, w, Some((hp, hn))) as f64);
        assert!(chi2_dirs(2, 100_000, frame, tmax, (8, 16, 40), sample, pdf) > ALPHA);
        assert_eq!(hidden, 0, "a convex one-sided light only returns its visible side");
        let total = integrate_cone(frame, tmax, pdf);
        let visible_area: f32 = (0..8)
            .filter(|&t| {
                let v = mesh.vertices(t);
                (v[1] - v[0]).cross(v[2] - v[0]).dot(p - v[0]) > 0.0
            })
            .map(|t| mesh.area(t))
            .sum();
        // ∫ pdf_li dω over the visible side is the visible fraction of the area.
        let frac = (visible_area / total_area) as f64;
        assert!(frac > 0.2 && frac < 0.8);
        assert!((total / frac - 1.0).abs() < 0.01, "∫ pdf_li dω = {total}, visible fraction {frac}");
    }

    #[test]
    fn triangle_irradiance_matches_lamberts_formula() {
        let cases = [
            (Vec3::ZERO, Vec3::Z, [Vec3::new(-0.4, -0.3, 1.0), Vec3::new(0.8, -0.1, 1.3), Vec3::new(0.0, 0.7, 0.9)]),
            (
                Vec3::new(1.0, 2.0, -1.0),
                Vec3::new(0.3, 0.2, 1.0).normalize(),
                [Vec3::new(1.5, 2.0, 0.0), Vec3::new(0.0, 2.5, -0.5), Vec3::new(1.0, 1.0, 0.5)],
            ),
        ];
        for (case, (p, n, v)) in cases.into_iter().enumerate() {
            let exact = polygon_irradiance(p, n, &v);
            for two_sided in [false, true] {
                // Facing the receiver, and (two-sided only) facing away from it.
                for facing in [true, false] {
                    let mut mesh = facing_triangle(p, v);
                    if !facing {
                        // The winding is the emitting side of a mesh without normals.
                        mesh.indices[0].swap(1, 2);
                    }
                    let meshes = [mesh];
                    let area = entity("diffuse", vec![param("twosided", ParamValue::Bool(vec![two_sided]))]);
                    let (lights, _) = build_area(&meshes, &["trianglemesh"], area);
                    let light = &lights.lights[0];
                    let mut rng = Rng::new(7 + case as u64);
                    let n_samples = 200_000;
                    let mut e = 0.0f64;
                    for _ in 0..n_samples {
                        if let Some(s) = light.sample_li(&ctx(p), rand2(&mut rng), &meshes) {
                            e += (s.li.x * n.dot(s.wi).max(0.0) / s.pdf) as f64;
                        }
                    }
                    e /= n_samples as f64;
                    if facing || two_sided {
                        assert!((e / exact - 1.0).abs() < 0.01, "case {case}: {e} vs {exact}");
                    } else {
                        assert_eq!(e, 0.0, "a one-sided light emits only on its normal's side");
                    }
                }
            }
        }
    }

    #[test]
    fn spot_falloff_is_pbrt_v3s() {
        // The spot points along light-space +x; the CTM rotates that to world +y and moves it.
        let ctm = Transform::translate([1.0, 2.0, 3.0]).compose(&Transform::rotate(90.0, [0.0, 0.0, 1.0]).unwrap());
        let light = build_one(
            "spot",
            vec![rgb("I", [3.0, 3.0, 3.0]), point3("from", [0.0, 0.0, 0.0]), point3("to", [5.0, 0.0, 0.0])],
            ctm,
        );
        assert!(light.is_delta());
        let pl = Vec3::new(1.0, 2.0, 3.0);
        let (ct, cf) = (30f64.to_radians().cos(), 25f64.to_radians().cos());
        for deg in [0.0f64, 10.0, 24.0, 26.0, 27.5, 29.0, 29.9, 30.5, 45.0, 120.0] {
            let a = deg.to_radians();
            let q = pl + 2.0 * Vec3::new(0.0, a.cos() as f32, a.sin() as f32);
            let cos = a.cos();
            let expect = if cos < ct {
                0.0
            } else if cos > cf {
                1.0
            } else {
                ((cos - ct) / (cf - ct)).powi(4)
            };
            match light.sample_li(&ctx(q), Vec2::splat(0.5), &[]) {
                Some(s) => {
                    let f = s.li.x as f64 * 4.0 / 3.0;
                    assert!((f - expect).abs() < 2e-4, "{deg}°: {f} vs {expect}");
                    assert!((s.wi - (pl - q).normalize()).length() < 1e-5 && s.p_light == pl && s.pdf == 1.0);
                }
                None => assert_eq!(expect, 0.0, "{deg}°"),
            }
        }
    }

    #[test]
    fn point_light_is_intensity_over_distance_squared() {
        // pbrt-v3 places the light at CTM(0) + from, not CTM(from).
        let ctm = Transform::scale([2.0, 2.0, 2.0]).unwrap();
        let light = build_one(
            "point",
            vec![rgb("I", [1.0, 2.0, 4.0]), rgb("scale", [2.0, 2.0, 2.0]), point3("from", [0.0, 2.0, 0.0])],
            ctm,
        );
        for q in [Vec3::new(0.0, 2.0, 3.0), Vec3::new(1.0, -1.0, 0.5), Vec3::new(-7.0, 2.0, 0.0)] {
            let s = light.sample_li(&ctx(q), Vec2::ZERO, &[]).unwrap();
            let d2 = (Vec3::new(0.0, 2.0, 0.0) - q).length_squared();
            assert!((s.li - Rgb::new(2.0, 4.0, 8.0) / d2).length() < 1e-5 * s.li.length());
            assert!(s.delta && s.pdf == 1.0 && s.p_light == Vec3::new(0.0, 2.0, 0.0));
            assert_eq!(light.pdf_li(&ctx(q), s.wi, None), 0.0);
        }
        assert!(light.sample_li(&ctx(Vec3::new(0.0, 2.0, 0.0)), Vec2::ZERO, &[]).is_none());
    }

    #[test]
    fn distant_light_shadow_end_is_two_scene_radii_away() {
        let light = build_one(
            "distant",
            vec![rgb("L", [0.5, 1.0, 1.5]), point3("from", [0.0, 0.0, 0.0]), point3("to", [0.0, 0.0, 1.0])],
            Transform::IDENTITY,
        );
        let q = Vec3::new(0.2, 0.3, 0.4);
        let s = light.sample_li(&ctx(q), Vec2::ZERO, &[]).unwrap();
        assert_eq!(s.wi, Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(s.li, Rgb::new(0.5, 1.0, 1.5));
        let r = 3f32.sqrt();
        assert!((s.p_light - (q + s.wi * 2.0 * r)).length() < 1e-5);
    }

    #[test]
    fn constant_infinite_light() {
        let ctm = Transform::rotate(40.0, [1.0, 2.0, 0.5]).unwrap();
        let light = build_one("infinite", vec![rgb("L", [1.0, 2.0, 3.0]), rgb("scale", [0.5, 0.5, 0.5])], ctm);
        assert!(light.is_infinite() && !light.is_delta() && light.n_samples() == 1);
        let c = ctx(Vec3::new(0.1, 0.2, 0.3));
        let mut rng = Rng::new(5);
        let lin = linear_part(&ctm.m);
        for _ in 0..1000 {
            let w = crate::sampling::uniform_sample_sphere(rand2(&mut rng));
            let le = light.le(&Ray::new(Vec3::ZERO, w * 3.0, f32::INFINITY));
            assert!((le - Rgb::new(0.5, 1.0, 1.5)).abs().max_element() < 1e-6, "{le:?}");
            // pbrt-v3: a 1×1 map is uniform in (u, v), so pdf = 1 / (2π² sin θ) (θ in light space).
            let sin_t = (lin.transpose() * w).z.clamp(-1.0, 1.0).acos().sin();
            let pdf = light.pdf_li(&c, w, None);
            assert!((pdf * sin_t * 2.0 * PI * PI - 1.0).abs() < 1e-4, "{pdf} at sin θ {sin_t}");
        }
        let frame = Frame { x: lin * Vec3::X, y: lin * Vec3::Y, z: lin * Vec3::Z };
        let mut mismatched = 0;
        let sample = |u: Vec2| {
            let s = light.sample_li(&c, u, &[])?;
            // f32 round trips through the rotation move θ slightly: near the poles the pdfs differ a little.
            mismatched += ((s.pdf - light.pdf_li(&c, s.wi, None)).abs() > 1e-3 * s.pdf) as usize;
            assert!((s.li - Rgb::new(0.5, 1.0, 1.5)).abs().max_element() < 1e-6);
            Some(s.wi)
        };
        assert!(chi2_dirs(3, 100_000, frame, PI64, (16, 16, 4), sample, |w| light.pdf_li(&c, w, None) as f64) > ALPHA);
        assert!(mismatched < 100, "sample_li and pdf_li disagree on {mismatched} samples");
    }

    /// Writes a little-endian 3-channel PFM (`rows[0]` is the top row).
    fn write_pfm(name: &str, w: usize, h: usize, texel: impl Fn(usize, usize) -> [f32; 3]) -> PathBuf {
        let path = std::env::temp_dir().join(format!("penumbra-light-{}-{name}.pfm", std::process::id()));
        let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
        for y in (0..h).rev() {
            for x in 0..w {
                for c in texel(x, y) {
                    bytes.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        std::fs::write(&path, bytes).unwrap();
        path
    }

    fn map_texel(x: usize, y: usize) -> [f32; 3] {
        if (x, y) == (5, 1) {
            return [40.0, 30.0, 20.0];
        }
        let v = 0.1 + ((x * 3 + y * 5) % 7) as f32;
        [v, 0.5 * v + 0.2, 1.0 + (x % 2) as f32]
    }

    #[test]
    fn infinite_map_light_samples_follow_pdf_li() {
        let (w, h) = (8, 4);
        let path = write_pfm("envmap", w, h, map_texel);
        let ctm = Transform::rotate(30.0, [1.0, 1.0, 0.0]).unwrap();
        let params = vec![string("mapname", path.to_str().unwrap()), rgb("scale", [2.0, 2.0, 2.0]), int("nsamples", 4)];
        let light = build_one("infinite", params, ctm);
        let _ = std::fs::remove_file(&path);
        assert_eq!(light.n_samples(), 4);
        let lin = linear_part(&ctm.m);
        let frame = Frame { x: lin * Vec3::X, y: lin * Vec3::Y, z: lin * Vec3::Z };
        let c = ctx(Vec3::new(-1.0, 0.0, 2.0));
        // The lat-long mapping: texel (x, y) is seen along light-space (φ, θ) = (2π (x+½)/w, π (y+½)/h).
        for y in 0..h {
            for x in 0..w {
                let (phi, theta) = (2.0 * PI * (x as f32 + 0.5) / w as f32, PI * (y as f32 + 0.5) / h as f32);
                let d = frame.from_local(Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
                let le = light.le(&Ray::new(c.p, d, f32::INFINITY));
                let expect = Rgb::from(map_texel(x, y)) * 2.0;
                assert!(
                    (le - expect).abs().max_element() < 1e-3 * expect.max_element(),
                    "({x},{y}): {le:?} vs {expect:?}"
                );
            }
        }
        let mut mismatched = 0;
        let sample = |u: Vec2| {
            let s = light.sample_li(&c, u, &[])?;
            // Rounding can move a direction across a cell boundary or (near the poles) change θ slightly.
            mismatched += ((s.pdf - light.pdf_li(&c, s.wi, None)).abs() > 1e-3 * s.pdf) as usize;
            let le = light.le(&Ray::new(c.p, s.wi, f32::INFINITY));
            // (φ is ill-conditioned at the poles, where the lookup blends the first and last rows.)
            mismatched += ((s.li - le).abs().max_element() > 1e-3 * le.max_element().max(1.0)) as usize;
            assert!((s.p_light - (c.p + s.wi * 2.0 * 3f32.sqrt())).length() < 1e-4);
            Some(s.wi)
        };
        // Bins aligned with the 16×8 distribution cells.
        let p = chi2_dirs(4, 200_000, frame, PI64, (16, 32, 4), sample, |w| light.pdf_li(&c, w, None) as f64);
        assert!(p > ALPHA);
        assert!(mismatched < 200, "sample_li and pdf_li disagree on {mismatched} samples");
        // ∫ pdf_li dω = 1 on a jittered (θ, φ) grid.
        let mut rng = Rng::new(8);
        let (nt, np) = (256, 512);
        let mut total = 0.0f64;
        for i in 0..nt {
            for j in 0..np {
                let theta = PI64 * (i as f64 + rng.uniform_f64()) / nt as f64;
                let phi = 2.0 * PI64 * (j as f64 + rng.uniform_f64()) / np as f64;
                let l =
                    Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32);
                total += light.pdf_li(&c, frame.from_local(l), None) as f64 * theta.sin();
            }
        }
        total *= PI64 * 2.0 * PI64 / (nt * np) as f64;
        assert!((total - 1.0).abs() < 0.01, "∫ pdf_li dω = {total}");
    }

    #[test]
    fn goniometric_and_projection_maps() {
        let (w, h) = (8, 4);
        let path = write_pfm("gonio", w, h, map_texel);
        let pl = Vec3::new(0.0, 1.0, 0.0);
        let ctm = Transform::translate([0.0, 1.0, 0.0]);
        let gonio =
            build_one("goniometric", vec![string("mapname", path.to_str().unwrap()), rgb("I", [2.0, 2.0, 2.0])], ctm);
        let plain = build_one("goniometric", vec![], ctm);
        // Texel (x, y) lies along the direction whose y/z-swapped spherical angles are its centre.
        for (x, y) in [(5, 1), (2, 2), (7, 0)] {
            let (phi, theta) = (2.0 * PI * (x as f32 + 0.5) / w as f32, PI * (y as f32 + 0.5) / h as f32);
            let wp = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let dir = Vec3::new(wp.x, wp.z, wp.y);
            let q = pl + 2.0 * dir;
            let s = gonio.sample_li(&ctx(q), Vec2::ZERO, &[]).unwrap();
            let expect = Rgb::from(map_texel(x, y)) * 2.0 / 4.0;
            assert!(
                (s.li - expect).abs().max_element() < 1e-4 * expect.max_element(),
                "({x},{y}): {:?} vs {expect:?}",
                s.li
            );
            assert!((plain.sample_li(&ctx(q), Vec2::ZERO, &[]).unwrap().li - Rgb::splat(0.25)).length() < 1e-6);
        }

        // Projection of a 4×2 map (aspect 2: screen [-2,2]×[-1,1]), fov 45°.
        let ppath = write_pfm("proj", 4, 2, map_texel);
        let proj = build_one("projection", vec![string("mapname", ppath.to_str().unwrap())], ctm);
        let bare = build_one("projection", vec![float("fov", 45.0)], ctm);
        let _ = std::fs::remove_file(&path);
        let _ = std::fs::remove_file(&ppath);
        let tan = 22.5f32.to_radians().tan();
        for (x, y) in [(1usize, 0usize), (3, 1), (0, 1)] {
            let (sx, sy) = (-2.0 + 4.0 * (x as f32 + 0.5) / 4.0, -1.0 + 2.0 * (y as f32 + 0.5) / 2.0);
            let dir = Vec3::new(sx * tan, sy * tan, 1.0).normalize();
            let s = proj.sample_li(&ctx(pl + 3.0 * dir), Vec2::ZERO, &[]).unwrap();
            let expect = Rgb::from(map_texel(x, y)) / 9.0;
            assert!(
                (s.li - expect).abs().max_element() < 1e-4 * expect.max_element(),
                "({x},{y}): {:?} vs {expect:?}",
                s.li
            );
        }
        // Without a map: 1 inside the square frustum, 0 outside and behind.
        assert!(
            (bare.sample_li(&ctx(pl + Vec3::Z * 2.0), Vec2::ZERO, &[]).unwrap().li - Rgb::splat(0.25)).length() < 1e-6
        );
        let off = Vec3::new(30f32.to_radians().sin(), 0.0, 30f32.to_radians().cos());
        assert!(bare.sample_li(&ctx(pl + off), Vec2::ZERO, &[]).is_none());
        assert!(bare.sample_li(&ctx(pl - Vec3::Z), Vec2::ZERO, &[]).is_none());
    }

    #[test]
    fn build_maps_triangles_to_lights_and_warns() {
        // Three triangles, the middle one degenerate; a one-light "disk" next to it.
        let tri_mesh = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0)],
            indices: vec![[0, 1, 2], [0, 1, 3], [0, 2, 4]],
            ..Default::default()
        };
        let disk = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(-1.0, 0.0, 0.0)],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        let plain = tri_mesh.clone();
        let mut d = desc();
        d.area_lights = vec![
            entity("diffuse", vec![rgb("L", [1.0, 1.0, 1.0]), int("samples", 3), int("nsamples", 8)]),
            entity("blinking", vec![]),
            entity("area", vec![rgb("L", [0.0, 0.0, 0.0])]),
        ];
        d.lights = vec![
            light_desc("laser", vec![float("power", 1.0)], Transform::IDENTITY),
            light_desc("point", vec![float("radius", 1.0)], Transform::IDENTITY),
            light_desc("point", vec![rgb("I", [0.0, 0.0, 0.0])], Transform::IDENTITY),
        ];
        let meshes = vec![tri_mesh.clone(), disk, plain.clone(), plain.clone(), plain.clone(), plain];
        let objects = vec![
            object("trianglemesh", Some(0), None),
            object("disk", Some(0), None),
            object("trianglemesh", None, None),
            object("trianglemesh", Some(1), None),
            object("trianglemesh", Some(0), Some(0)),
            object("trianglemesh", Some(2), Some(1)),
        ];
        let sink = DiagSink::new();
        let lights = Lights::build(&d, &meshes, &objects, unit_bounds(), &sink).unwrap();
        let w: Vec<String> = sink.take().into_iter().map(|d| d.message).collect();
        // The point light with I = 0 is skipped; the unknown "laser" too.
        assert_eq!(lights.len(), 1 + 2 + 1, "{w:?}");
        assert!(matches!(lights.lights[0], Light::Point(_)));
        assert_eq!(lights.light_of(0, 0), Some(1));
        assert_eq!(lights.light_of(0, 1), None);
        assert_eq!(lights.light_of(0, 2), Some(2));
        assert_eq!(lights.light_of(1, 0), Some(3));
        assert_eq!(lights.light_of(1, 1), Some(3));
        assert_eq!(lights.light_of(2, 0), None);
        assert_eq!(lights.light_of(3, 0), None);
        assert_eq!(lights.light_of(4, 0), None);
        assert_eq!(lights.light_of(99, 0), None);
        let area = lights.lights[3].area().unwrap();
        assert_eq!((area.mesh, area.tris.clone(), area.area), (1, vec![0, 1], 1.0));
        assert_eq!(lights.lights[1].n_samples(), 3, "\"samples\" wins over \"nsamples\"");
        assert_eq!(lights.infinite().count(), 0);
        let count = |s: &str| w.iter().filter(|m| m.contains(s)).count();
        assert_eq!(count("\"laser\" unknown"), 1, "{w:?}");
        assert_eq!(count("\"blinking\" unknown"), 1, "{w:?}");
        assert_eq!(count("object instancing"), 1, "{w:?}");
        assert_eq!(count("radius"), 1, "{w:?}");
        assert_eq!(count("power"), 0, "{w:?}");
        assert_eq!(count("samples"), 0, "{w:?}");
    }

    #[test]
    fn bad_spectrum_is_a_located_error() {
        let mut d = desc();
        d.lights = vec![light_desc(
            "point",
            vec![param("I", ParamValue::Spectrum(SpectrumValue::Rgb(vec![1.0, 2.0])))],
            Transform::IDENTITY,
        )];
        let err = Lights::build(&d, &[], &[], unit_bounds(), &DiagSink::new()).unwrap_err();
        assert!(err.is_error() && err.loc.as_ref().is_some_and(|l| l.line == 4), "{err:?}");
        assert!(err.message.contains("\"I\""), "{}", err.message);
    }

    #[test]
    fn degenerate_input_never_panics_or_gives_nan() {
        let mesh =
            facing_triangle(Vec3::ZERO, [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]);
        let meshes = [mesh];
        let (area, _) = build_area(&meshes, &["trianglemesh"], entity("diffuse", vec![]));
        let path = write_pfm("nan", 2, 1, |x, _| if x == 0 { [f32::NAN, 1.0, f32::INFINITY] } else { [1.0; 3] });
        let mut all = vec![
            build_one("point", vec![], Transform::IDENTITY),
            build_one("spot", vec![], Transform::IDENTITY),
            build_one("distant", vec![], Transform::IDENTITY),
            build_one("infinite", vec![string("mapname", path.to_str().unwrap())], Transform::IDENTITY),
            build_one("goniometric", vec![], Transform::IDENTITY),
            build_one("projection", vec![], Transform::IDENTITY),
        ];
        let _ = std::fs::remove_file(&path);
        all.extend(area.lights);
        let bad = [f32::NAN, f32::INFINITY, -f32::INFINITY, 0.0, 1e30];
        for l in &all {
            for &a in &bad {
                for p in [Vec3::splat(a), Vec3::new(0.0, 0.0, a), Vec3::new(0.2, 0.2, 1.0)] {
                    for u in [Vec2::splat(a), Vec2::ZERO, Vec2::ONE, Vec2::new(a, 0.5)] {
                        if let Some(s) = l.sample_li(&ctx(p), u, &meshes) {
                            assert!(
                                s.li.is_finite() && s.wi.is_finite() && s.pdf.is_finite() && s.pdf > 0.0,
                                "{l:?} {s:?}"
                            );
                        }
                    }
                    for wi in [Vec3::splat(a), Vec3::Z, -Vec3::Z, Vec3::ZERO] {
                        for hit in [None, Some((Vec3::splat(a), Vec3::Z)), Some((Vec3::Z, Vec3::ZERO))] {
                            let pdf = l.pdf_li(&ctx(p), wi, hit);
                            assert!(pdf.is_finite() && pdf >= 0.0, "{pdf}");
                        }
                        assert!(l.le(&Ray::new(p, wi, 1.0)).is_finite());
                        assert!(l.l(wi, Vec3::Z).is_finite());
                    }
                }
            }
        }
        // An area light keeps what it samples of its triangles: no mesh lookup at sampling time
        // (so no out-of-range reference), the same sample without the meshes.
        let light = all.last().unwrap();
        let at = ctx(Vec3::new(0.2, 0.2, 1.0));
        assert_eq!(light.sample_li(&at, Vec2::splat(0.3), &[]), light.sample_li(&at, Vec2::splat(0.3), &meshes));
    }
}
