//! Lights with pbrt-v3's semantics: `point`, `spot`, `distant`, `goniometric`,
//! `projection`, `infinite` (alias `exinfinite`) light sources and `diffuse`
//! (alias `area`) area lights.
//!
//! Area lights over triangle meshes follow pbrt-v3's granularity: a
//! `trianglemesh`/`plymesh`/`loopsubdiv`/`heightfield`/`nurbs` area light is one light
//! per triangle (pbrt-v3 makes one `Triangle` shape, hence one light, per
//! triangle); a quadric (sphere, disk, …) is one light over all the triangles
//! of its tessellation, sampled by area (a triangle chosen in proportion to its
//! area, then a uniform point on it), so its surface density is 1 / total area.
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

use crate::accel::interpolate;
use crate::geometry::{face_forward, gamma, Bounds3, Ray};
use crate::image::Image;
use crate::mesh::TriangleMesh;
use crate::sampling::{spherical_phi, spherical_theta, uniform_sample_triangle, Distribution1D, Distribution2D};
use crate::scene::SceneObject;
use crate::spectrum::luminance;
use crate::Rgb;
use glam::{Mat3, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, FileLoc, ParamSet, SceneDescription, Transform};
use std::f32::consts::PI;
use std::path::Path;

// SHIM: remove at merge — replace with
// `use crate::image::read as read_image; use crate::spectrum::spectrum_to_rgb;`
use shim::{read_image, spectrum_to_rgb};

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

    fn texel(&self, s: i64, t: i64) -> Rgb {
        let s = s.rem_euclid(self.width as i64) as usize;
        let t = t.rem_euclid(self.height as i64) as usize;
        self.texels.get(t * self.width + s).copied().unwrap_or(Rgb::ZERO)
    }

    /// Bilinear lookup at `st` ∈ [0,1]² (zero for non-finite coordinates).
    pub fn lookup(&self, st: Vec2) -> Rgb {
        if !st.is_finite() || self.width == 0 || self.height == 0 {
            return Rgb::ZERO;
        }
        let s = st.x * self.width as f32 - 0.5;
        let t = st.y * self.height as f32 - 0.5;
        let (s0, t0) = (s.floor(), t.floor());
        let (ds, dt) = (s - s0, t - t0);
        let (s0, t0) = (s0 as i64, t0 as i64);
        (1.0 - ds) * (1.0 - dt) * self.texel(s0, t0)
            + (1.0 - ds) * dt * self.texel(s0, t0 + 1)
            + ds * (1.0 - dt) * self.texel(s0 + 1, t0)
            + ds * dt * self.texel(s0 + 1, t0 + 1)
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
    fn lookup_dir(&self, d: Vec3) -> Rgb {
        let w = (self.light_from_world * d).normalize_or_zero();
        if w == Vec3::ZERO || !w.is_finite() {
            return Rgb::ZERO;
        }
        let st = Vec2::new(spherical_phi(w) / (2.0 * PI), spherical_theta(w) / PI);
        self.map.lookup(st)
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
fn point_sample(ctx: &LightContext, p: Vec3, intensity: Rgb, modulation: impl Fn(Vec3) -> Rgb) -> Option<LightLiSample> {
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
    Some(LightLiSample {
        li,
        wi,
        pdf: 1.0,
        p_light: p,
        p_light_error: Vec3::ZERO,
        n_light: Vec3::ZERO,
        delta: true,
    })
}

fn tri_vertices(mesh: &TriangleMesh, tri: usize) -> Option<[Vec3; 3]> {
    let idx = mesh.indices.get(tri)?;
    Some([mesh.positions.get(idx[0] as usize)?, mesh.positions.get(idx[1] as usize)?, mesh.positions.get(idx[2] as usize)?]
        .map(|p| *p))
}

/// The normal pbrt-v3's `Triangle::Sample` gives the point with barycentrics `b`:
/// the winding normal, face-forwarded to the interpolated shading normal when the
/// mesh has normals, else flipped by `ReverseOrientation` xor handedness (as
/// [`crate::scene::Scene::interaction`] orients hits).
fn sampled_normal(mesh: &TriangleMesh, tri: usize, pv: [Vec3; 3], b: [f32; 3]) -> Vec3 {
    let mut n = (pv[1] - pv[0]).cross(pv[2] - pv[0]).normalize_or_zero();
    if mesh.flip_normals {
        n = -n;
    }
    if let (Some(ns), Some(idx)) = (&mesh.normals, mesh.indices.get(tri)) {
        let nv = idx.map(|i| ns.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        let s = interpolate(nv, b);
        if s != Vec3::ZERO && s.is_finite() {
            n = face_forward(n, s);
        }
    }
    n
}

impl Light {
    /// Samples an incident direction at `ctx` (pbrt-v3's `Sample_Li`). `None` if the
    /// pdf is 0 or the sample carries no radiance.
    pub fn sample_li(&self, ctx: &LightContext, u: Vec2, meshes: &[TriangleMesh]) -> Option<LightLiSample> {
        match self {
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
            Light::Area(a) => {
                let g = &a.geom;
                let mesh = meshes.get(g.mesh as usize)?;
                let (k, u0) = match &a.tri_dist {
                    Some(d) => {
                        let (i, _, r) = d.sample_discrete(u.x);
                        (i, r)
                    }
                    None => (0, u.x),
                };
                let tri = *g.tris.get(k)? as usize;
                let pv = tri_vertices(mesh, tri)?;
                let b = uniform_sample_triangle(Vec2::new(u0, u.y));
                let b = [b.x, b.y, 1.0 - b.x - b.y];
                let p = interpolate(pv, b);
                let n = sampled_normal(mesh, tri, pv, b);
                let p_err = gamma(6) * ((b[0] * pv[0]).abs() + (b[1] * pv[1]).abs() + (b[2] * pv[2]).abs());
                let d = p - ctx.p;
                let d2 = d.length_squared();
                if !(d2 > 0.0) || !d2.is_finite() {
                    return None;
                }
                let wi = d / d2.sqrt();
                let pdf = d2 / (n.dot(wi).abs() * g.area);
                if !(pdf.is_finite() && pdf > 0.0) {
                    return None;
                }
                let li = self.l(n, -wi);
                if li == Rgb::ZERO {
                    return None;
                }
                Some(LightLiSample { li, wi, pdf, p_light: p, p_light_error: p_err, n_light: n, delta: false })
            }
        }
    }

    /// Solid-angle pdf of sampling `wi` from `ctx`; for area lights the caller passes the point it found on the light (`light_hit`: point and geometric normal), since the caller already traced the ray.
    pub fn pdf_li(&self, ctx: &LightContext, wi: Vec3, light_hit: Option<(Vec3, Vec3)>) -> f32 {
        match self {
            Light::Infinite(l) => {
                let w = (l.light_from_world * wi).normalize_or_zero();
                if w == Vec3::ZERO || !w.is_finite() {
                    return 0.0;
                }
                let (theta, phi) = (spherical_theta(w), spherical_phi(w));
                let sin_t = theta.sin();
                if !(sin_t > 0.0) {
                    return 0.0;
                }
                let pdf = l.dist.pdf(Vec2::new(phi / (2.0 * PI), theta / PI)) / (2.0 * PI * PI * sin_t);
                if pdf.is_finite() {
                    pdf
                } else {
                    0.0
                }
            }
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
        }
    }

    /// Emitted radiance of an area light at a point with geometric normal `n` towards `w` (zero for other lights).
    pub fn l(&self, n: Vec3, w: Vec3) -> Rgb {
        match self {
            Light::Area(a) if a.geom.two_sided || n.dot(w) > 0.0 => a.geom.l,
            _ => Rgb::ZERO,
        }
    }

    /// Radiance of infinite lights along an escaping ray (zero for other lights).
    pub fn le(&self, ray: &Ray) -> Rgb {
        match self {
            Light::Infinite(l) => l.lookup_dir(ray.d),
            _ => Rgb::ZERO,
        }
    }

    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point(_) | Light::Spot(_) | Light::Distant(_) | Light::Goniometric(_) | Light::Projection(_)
        )
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
            Diagnostic::error(Some(p.loc_of(name).unwrap_or(loc).clone()), format!("{owner}: parameter \"{name}\": {e}"))
        }),
    }
}

/// pbrt-v3 reads `samples`, falling back to `nsamples` (both count as used).
fn n_samples_param(p: &ParamSet) -> u32 {
    let ns = p.get_one_int("nsamples", 1);
    p.get_one_int("samples", ns).max(1) as u32
}

/// pbrt-v3's `InverseGammaCorrect` (the sRGB decoding curve).
fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// An image as RGB texels: the R, G, B channels by name, else the first three, else grey from the first.
fn image_to_map(img: &Image, decode_srgb: bool) -> Option<RgbMap> {
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
            let c = if decode_srgb { Rgb::new(srgb_to_linear(c.x), srgb_to_linear(c.y), srgb_to_linear(c.z)) } else { c };
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

/// Reads `mapname` as pbrt-v3's `ReadImage` would (8-bit formats sRGB-decoded).
/// A missing name gives `None`; an unreadable file a warning and `None` (pbrt-v3 then falls back too).
fn load_map(desc: &SceneDescription, p: &ParamSet, owner: &str, warnings: &DiagSink) -> Option<RgbMap> {
    let name = p.get_one_string("mapname", "");
    if name.is_empty() {
        return None;
    }
    let loc = p.loc_of("mapname").cloned();
    let path = desc.resolve_path(&name);
    let decode = Path::new(&name)
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png") || e.eq_ignore_ascii_case("tga"));
    match read_image(&path) {
        Ok(img) => {
            let m = image_to_map(&img, decode);
            if m.is_none() {
                warnings.warn(loc, format!("{owner}: \"{}\" has no pixels: ignored", path.display()));
            }
            m
        }
        Err(e) => {
            warnings.warn(loc, format!("{owner}: cannot read \"{}\": {e}; ignoring the map as pbrt-v3 does", path.display()));
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
        let mut area_params: Vec<Option<Option<(Rgb, bool, u32)>>> = vec![None; desc.area_lights.len()];
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
                    let l = l * sc;
                    if !l.is_finite() {
                        warnings.warn(Some(ent.loc.clone()), format!("{owner}: non-finite radiance: ignored"));
                        None
                    } else {
                        Some((l, two_sided, ns))
                    }
                } else {
                    warnings.warn(Some(ent.loc.clone()), format!("area light \"{}\" unknown: its shapes do not emit", ent.kind));
                    ent.params.mark_all_used();
                    None
                };
                warnings.extend(ent.params.report_unused(&owner));
                area_params[ai] = Some(parsed);
            }
            let Some(Some((l, two_sided, n_samples))) = area_params[ai] else { continue };
            if l == Rgb::ZERO {
                continue;
            }
            let mesh = &meshes[oi];
            let areas: Vec<f32> = (0..mesh.triangle_count())
                .map(|t| match tri_vertices(mesh, t) {
                    Some([a, b, c]) => 0.5 * (b - a).cross(c - a).length(),
                    None => 0.0,
                })
                .collect();
            let ok = |a: f32| a > 0.0 && a.is_finite();
            let make = |tris: Vec<u32>, area: f32, tri_dist: Option<Distribution1D>| {
                Light::Area(DiffuseAreaLight {
                    geom: AreaLight { mesh: oi as u32, tris, l, two_sided, area },
                    tri_dist,
                    n_samples,
                })
            };
            if is_per_triangle_shape(&obj.kind) {
                let mut per = vec![u32::MAX; areas.len()];
                for (t, &a) in areas.iter().enumerate() {
                    if ok(a) {
                        per[t] = lights.len() as u32;
                        lights.push(make(vec![t as u32], a, None));
                    }
                }
                mesh_lights[oi] = MeshLights::PerTriangle(per);
            } else {
                let tris: Vec<u32> = (0..areas.len() as u32).filter(|&t| ok(areas[t as usize])).collect();
                let w: Vec<f32> = tris.iter().map(|&t| areas[t as usize]).collect();
                let total: f64 = w.iter().map(|&a| a as f64).sum();
                if tris.is_empty() || !(total > 0.0) || !(total as f32).is_finite() {
                    continue;
                }
                let dist = if tris.len() > 1 { Some(Distribution1D::new(&w)) } else { None };
                mesh_lights[oi] = MeshLights::Whole(lights.len() as u32);
                lights.push(make(tris, total as f32, dist));
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
        warnings.warn(Some(e.loc.clone()), format!("{owner}: animated light transforms are not supported: using the start transform"));
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
            let screen = if aspect > 1.0 { [-aspect, aspect, -1.0, 1.0] } else { [-1.0, 1.0, -1.0 / aspect, 1.0 / aspect] };
            let inv_tan = 1.0 / (fov.to_radians() / 2.0).tan();
            if !inv_tan.is_finite() || !(inv_tan > 0.0) {
                warnings.warn(p.loc_of("fov").cloned().or(Some(e.loc.clone())), format!("{owner}: invalid \"fov\": ignored"));
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

// SHIM: remove at merge — stand-ins for `crate::spectrum::spectrum_to_rgb` and
// `crate::image::read`, which are written on other branches.
mod shim {
    use crate::image::{Image, ImageError};
    use crate::Rgb;
    use penumbra_parser::SpectrumValue;
    use std::path::Path;

    #[derive(Debug, thiserror::Error)]
    #[error("{0}")]
    pub struct SpectrumError(String);

    /// SHIM: RGB values only.
    pub fn spectrum_to_rgb(v: &SpectrumValue) -> Result<Rgb, SpectrumError> {
        match v {
            SpectrumValue::Rgb(x) if x.len() >= 3 => Ok(Rgb::new(x[0], x[1], x[2])),
            _ => Err(SpectrumError("only rgb spectra are supported yet".into())),
        }
    }

    /// SHIM: PFM only (for the tests); other formats are an error.
    pub fn read_image(path: &Path) -> Result<Image, ImageError> {
        let bytes = std::fs::read(path).map_err(|e| ImageError(e.to_string()))?;
        let bad = || ImageError("not a PFM file".into());
        let mut fields = Vec::new();
        let mut pos = 0;
        while fields.len() < 4 {
            while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
                pos += 1;
            }
            let start = pos;
            while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
                pos += 1;
            }
            if start == pos {
                return Err(bad());
            }
            fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
        }
        pos += 1;
        let nc = match fields[0].as_str() {
            "PF" => 3,
            "Pf" => 1,
            _ => return Err(bad()),
        };
        let w: usize = fields[1].parse().map_err(|_| bad())?;
        let h: usize = fields[2].parse().map_err(|_| bad())?;
        let scale: f32 = fields[3].parse().map_err(|_| bad())?;
        let n = w.checked_mul(h).and_then(|v| v.checked_mul(nc)).ok_or_else(bad)?;
        let body = bytes.get(pos..pos + n * 4).ok_or_else(bad)?;
        let vals: Vec<f32> = body
            .chunks_exact(4)
            .map(|c| {
                let b = [c[0], c[1], c[2], c[3]];
                if scale < 0.0 {
                    f32::from_le_bytes(b)
                } else {
                    f32::from_be_bytes(b)
                }
            })
            .collect();
        let mut data = Vec::with_capacity(n);
        for y in (0..h).rev() {
            data.extend_from_slice(&vals[y * w * nc..(y + 1) * w * nc]);
        }
        let channels = if nc == 3 { vec!["R".into(), "G".into(), "B".into()] } else { vec!["Y".into()] };
        Ok(Image { width: w as u32, height: h as u32, channels, data })
    }
}
