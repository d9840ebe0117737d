//! Float and spectrum textures with pbrt-v3's semantics: texture-coordinate
//! mappings, the MIP-mapped image texture (trilinear and EWA filtering), the
//! procedural textures, and the `TextureParams`-style lookups materials use.
//!
//! Textures are built lazily: [`Textures::new`] only records the scene's texture
//! definitions; a texture is built when a material parameter refers to it (and
//! then, transitively, the textures *it* refers to). A broken texture nobody
//! uses therefore never causes an error.
//!
//! Deviations from pbrt-v3 (see also the individual items):
//! - A missing or unreadable image file is an error (pbrt-v3 warns and uses a grey texture).
//! - Image `scale`/`invert` are applied at lookup time so that one pyramid per
//!   (file, gamma, wrap) is shared; identical to pbrt-v3 for `scale >= 0`.
//! - `invert` is pbrt-v4's parameter (pbrt-v3 has none): `max(0, 1 - v)` after scaling.
//! - Parameters on the `Shape` that override material parameters (pbrt-v3's
//!   `geomParams`) are not supported: only the material's own parameters are used.

use crate::interaction::SurfaceInteraction;
use crate::spectrum::{srgb_decode, Rgb};
use glam::{Mat4, Vec2, Vec3};
use penumbra_parser::{
    DiagSink, Diagnostic, FileLoc, ParamSet, SceneDescription, SpectrumValue, TextureDesc, TextureKind, Transform,
};
use std::collections::HashMap;
use std::f32::consts::PI;
use std::ops::{Add, Mul};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

// ---------------------------------------------------------------------------
// Evaluation context and mappings
// ---------------------------------------------------------------------------

/// The geometry a texture is evaluated at. Screen-space differentials are zero where the
/// ray had no offset rays: image textures then use a bilinear lookup of the finest MIP level
/// and the antialiased procedural textures take every octave, as pbrt-v3 does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TextureEvalContext {
    pub p: Vec3,
    pub dpdx: Vec3,
    pub dpdy: Vec3,
    pub n: Vec3,
    pub uv: Vec2,
    pub dudx: f32,
    pub dudy: f32,
    pub dvdx: f32,
    pub dvdy: f32,
}

impl TextureEvalContext {
    /// The context at a surface point, with its differentials (pbrt-v3's `SurfaceInteraction`
    /// as textures see it).
    pub fn from_si(si: &SurfaceInteraction) -> Self {
        let d = &si.diff;
        TextureEvalContext {
            p: si.p,
            n: si.n,
            uv: si.uv,
            dpdx: d.dpdx,
            dpdy: d.dpdy,
            dudx: d.dudx,
            dudy: d.dudy,
            dvdx: d.dvdx,
            dvdy: d.dvdy,
        }
    }
}

impl From<&SurfaceInteraction> for TextureEvalContext {
    fn from(si: &SurfaceInteraction) -> Self {
        TextureEvalContext::from_si(si)
    }
}

fn mat4_of(t: &Transform) -> Mat4 {
    let m = t.m;
    Mat4::from_cols_array_2d(&[0, 1, 2, 3].map(|c| [0, 1, 2, 3].map(|r| m[r][c] as f32)))
}

/// A 2D texture-coordinate mapping (pbrt-v3's `TextureMapping2D`).
#[derive(Clone, Debug, PartialEq)]
pub enum Mapping2D {
    /// `st = (su·u + du, sv·v + dv)`.
    Uv { su: f32, sv: f32, du: f32, dv: f32 },
    /// Spherical coordinates of the point in texture space: `(θ/π, φ/2π)`.
    Spherical { texture_from_render: Mat4 },
    /// `((π + atan2(y, x))/2π, z)` of the normalised texture-space point.
    Cylindrical { texture_from_render: Mat4 },
    /// `(ds + p·vs, dt + p·vt)` with `p` in render space (pbrt-v3 ignores the texture transform here).
    Planar { vs: Vec3, vt: Vec3, ds: f32, dt: f32 },
}

impl Mapping2D {
    /// pbrt-v3's mapping selection from a texture's parameters (`mapping`, `uscale`…).
    pub fn from_params(params: &ParamSet, render_from_texture: &Transform, loc: &FileLoc, warnings: &DiagSink) -> Self {
        let kind = params.get_one_string("mapping", "uv");
        let texture_from_render = mat4_of(&render_from_texture.inverse());
        match kind.as_str() {
            "uv" => Mapping2D::Uv {
                su: params.get_one_float("uscale", 1.0),
                sv: params.get_one_float("vscale", 1.0),
                du: params.get_one_float("udelta", 0.0),
                dv: params.get_one_float("vdelta", 0.0),
            },
            "spherical" => Mapping2D::Spherical { texture_from_render },
            "cylindrical" => Mapping2D::Cylindrical { texture_from_render },
            "planar" => Mapping2D::Planar {
                vs: Vec3::from(params.get_one_vector3("v1", [1.0, 0.0, 0.0])),
                vt: Vec3::from(params.get_one_vector3("v2", [0.0, 1.0, 0.0])),
                ds: params.get_one_float("udelta", 0.0),
                dt: params.get_one_float("vdelta", 0.0),
            },
            other => {
                warnings.warn(
                    Some(params.loc_of("mapping").cloned().unwrap_or_else(|| loc.clone())),
                    format!("2D texture mapping \"{other}\" unknown: using \"uv\""),
                );
                Mapping2D::Uv { su: 1.0, sv: 1.0, du: 0.0, dv: 0.0 }
            }
        }
    }

    /// `(st, dst/dx, dst/dy)`.
    pub fn map(&self, ctx: &TextureEvalContext) -> (Vec2, Vec2, Vec2) {
        match self {
            Mapping2D::Uv { su, sv, du, dv } => (
                Vec2::new(su * ctx.uv.x + du, sv * ctx.uv.y + dv),
                Vec2::new(su * ctx.dudx, sv * ctx.dvdx),
                Vec2::new(su * ctx.dudy, sv * ctx.dvdy),
            ),
            Mapping2D::Spherical { texture_from_render: m } => {
                let f = |p: Vec3| {
                    let v = m.project_point3(p).normalize_or_zero();
                    Vec2::new(spherical_theta(v) / PI, spherical_phi(v) / (2.0 * PI))
                };
                finite_difference_map(f, ctx, 0.1)
            }
            Mapping2D::Cylindrical { texture_from_render: m } => {
                let f = |p: Vec3| {
                    let v = m.project_point3(p).normalize_or_zero();
                    Vec2::new((PI + v.y.atan2(v.x)) / (2.0 * PI), v.z)
                };
                finite_difference_map(f, ctx, 0.01)
            }
            Mapping2D::Planar { vs, vt, ds, dt } => (
                Vec2::new(ds + ctx.p.dot(*vs), dt + ctx.p.dot(*vt)),
                Vec2::new(ctx.dpdx.dot(*vs), ctx.dpdx.dot(*vt)),
                Vec2::new(ctx.dpdy.dot(*vs), ctx.dpdy.dot(*vt)),
            ),
        }
    }
}

/// Forward differences over `delta` along the screen-space position differentials,
/// with pbrt-v3's fix-up of the wrap-around in the second coordinate.
fn finite_difference_map(f: impl Fn(Vec3) -> Vec2, ctx: &TextureEvalContext, delta: f32) -> (Vec2, Vec2, Vec2) {
    let st = f(ctx.p);
    let fix = |mut d: Vec2| {
        if d.y > 0.5 {
            d.y = 1.0 - d.y;
        } else if d.y < -0.5 {
            d.y = -(d.y + 1.0);
        }
        d
    };
    let dx = fix((f(ctx.p + delta * ctx.dpdx) - st) / delta);
    let dy = fix((f(ctx.p + delta * ctx.dpdy) - st) / delta);
    (st, dx, dy)
}

fn spherical_theta(v: Vec3) -> f32 {
    v.z.clamp(-1.0, 1.0).acos()
}

fn spherical_phi(v: Vec3) -> f32 {
    let p = v.y.atan2(v.x);
    if p < 0.0 {
        p + 2.0 * PI
    } else {
        p
    }
}

/// pbrt-v3's `IdentityMapping3D`. Note that pbrt-v3 hands it the *world-from-texture*
/// transform (the CTM at `Texture`), so points are mapped by the CTM itself, not its
/// inverse; penumbra matches that.
#[derive(Clone, Debug, PartialEq)]
pub struct Mapping3D {
    pub m: Mat4,
}

impl Mapping3D {
    pub fn new(render_from_texture: &Transform) -> Self {
        Mapping3D { m: mat4_of(render_from_texture) }
    }
    /// `(p, dp/dx, dp/dy)` in texture space.
    pub fn map(&self, ctx: &TextureEvalContext) -> (Vec3, Vec3, Vec3) {
        (self.m.project_point3(ctx.p), self.m.transform_vector3(ctx.dpdx), self.m.transform_vector3(ctx.dpdy))
    }
}

// ---------------------------------------------------------------------------
// MIP maps
// ---------------------------------------------------------------------------

/// Out-of-range texel handling (pbrt-v3's `ImageWrap`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WrapMode {
    Repeat,
    Black,
    Clamp,
}

/// Values a MIP map can hold.
pub trait Texel: Copy + Add<Output = Self> + Mul<f32, Output = Self> + Send + Sync + 'static {
    const ZERO: Self;
    fn clamp_nonnegative(self) -> Self;
    /// Component-wise product.
    fn mul_elem(self, o: Self) -> Self;
}

impl Texel for f32 {
    const ZERO: Self = 0.0;
    fn clamp_nonnegative(self) -> Self {
        self.max(0.0)
    }
    fn mul_elem(self, o: Self) -> Self {
        self * o
    }
}

impl Texel for Vec3 {
    const ZERO: Self = Vec3::ZERO;
    fn clamp_nonnegative(self) -> Self {
        self.max(Vec3::ZERO)
    }
    fn mul_elem(self, o: Self) -> Self {
        self * o
    }
}

#[derive(Clone, Debug)]
struct Level<T> {
    w: usize,
    h: usize,
    data: Vec<T>,
}

/// An image pyramid with pbrt-v3's construction (Lanczos resampling of
/// non-power-of-two images up to a power of two, then 2×2 box reduction) and
/// lookups (bilinear `triangle`, trilinear, EWA).
///
/// Texel `(s, t)` has `t = 0` at the *bottom* row of the image (pbrt-v3 flips
/// images on load so that `(0, 0)` is the lower-left corner).
#[derive(Clone, Debug)]
pub struct MipMap<T> {
    levels: Vec<Level<T>>,
    wrap: WrapMode,
}

fn is_pow2(v: usize) -> bool {
    v != 0 && v & (v - 1) == 0
}

fn lanczos(x: f32, tau: f32) -> f32 {
    let x = x.abs();
    if x < 1e-5 {
        return 1.0;
    }
    if x > 1.0 {
        return 0.0;
    }
    let x = x * PI;
    let s = (x * tau).sin() / (x * tau);
    s * x.sin() / x
}

/// For each new texel: the first of 4 source texels and their normalised weights.
fn resample_weights(old: usize, new: usize) -> Vec<(i64, [f32; 4])> {
    let width = 2.0f32;
    (0..new)
        .map(|i| {
            let center = (i as f32 + 0.5) * old as f32 / new as f32;
            let first = ((center - width) + 0.5).floor() as i64;
            let mut w = [0.0f32; 4];
            for (j, wj) in w.iter_mut().enumerate() {
                let pos = first as f32 + j as f32 + 0.5;
                *wj = lanczos((pos - center) / width, 2.0);
            }
            let inv = 1.0 / (w[0] + w[1] + w[2] + w[3]);
            (first, w.map(|x| x * inv))
        })
        .collect()
}

fn ewa_weight_lut() -> &'static [f32; 128] {
    static LUT: OnceLock<[f32; 128]> = OnceLock::new();
    LUT.get_or_init(|| {
        let mut l = [0.0f32; 128];
        for (i, v) in l.iter_mut().enumerate() {
            let r2 = i as f32 / 127.0;
            *v = (-2.0 * r2).exp() - (-2.0f32).exp();
        }
        l
    })
}

impl<T: Texel> MipMap<T> {
    /// `data` is row-major with row 0 = texture-space `t = 0`. `w·h` must equal `data.len()`, both nonzero.
    pub fn new(w: usize, h: usize, data: Vec<T>, wrap: WrapMode) -> Option<Self> {
        if w == 0 || h == 0 || data.len() != w * h {
            return None;
        }
        let (mut w, mut h, mut data) = (w, h, data);
        if !is_pow2(w) || !is_pow2(h) {
            let (nw, nh) = (w.next_power_of_two(), h.next_power_of_two());
            let map_index = |i: i64, n: usize| -> Option<usize> {
                let n = n as i64;
                let j = match wrap {
                    WrapMode::Repeat => i.rem_euclid(n),
                    WrapMode::Clamp => i.clamp(0, n - 1),
                    WrapMode::Black => i,
                };
                (0..n).contains(&j).then_some(j as usize)
            };
            let sw = resample_weights(w, nw);
            let mut tmp = vec![T::ZERO; nw * h];
            for t in 0..h {
                for (s, (first, wt)) in sw.iter().enumerate() {
                    let mut acc = T::ZERO;
                    for (j, wj) in wt.iter().enumerate() {
                        if let Some(os) = map_index(first + j as i64, w) {
                            acc = acc + data[t * w + os] * *wj;
                        }
                    }
                    tmp[t * nw + s] = acc;
                }
            }
            let tw = resample_weights(h, nh);
            let mut out = vec![T::ZERO; nw * nh];
            for s in 0..nw {
                for (t, (first, wt)) in tw.iter().enumerate() {
                    let mut acc = T::ZERO;
                    for (j, wj) in wt.iter().enumerate() {
                        if let Some(ot) = map_index(first + j as i64, h) {
                            acc = acc + tmp[ot * nw + s] * *wj;
                        }
                    }
                    out[t * nw + s] = acc.clamp_nonnegative();
                }
            }
            (w, h, data) = (nw, nh, out);
        }
        let n_levels = 1 + w.max(h).ilog2() as usize;
        let mut levels = vec![Level { w, h, data }];
        for _ in 1..n_levels {
            let prev = levels.last().expect("nonempty");
            let (pw, ph) = (prev.w, prev.h);
            let (nw, nh) = ((pw / 2).max(1), (ph / 2).max(1));
            let mut data = Vec::with_capacity(nw * nh);
            let mm = MipMap { levels: Vec::new(), wrap };
            for t in 0..nh as i64 {
                for s in 0..nw as i64 {
                    let v = mm.texel_in(prev, 2 * s, 2 * t)
                        + mm.texel_in(prev, 2 * s + 1, 2 * t)
                        + mm.texel_in(prev, 2 * s, 2 * t + 1)
                        + mm.texel_in(prev, 2 * s + 1, 2 * t + 1);
                    data.push(v * 0.25);
                }
            }
            levels.push(Level { w: nw, h: nh, data });
        }
        Some(MipMap { levels, wrap })
    }

    pub fn levels(&self) -> usize {
        self.levels.len()
    }
    /// Resolution of level 0 (after power-of-two resampling).
    pub fn resolution(&self) -> (usize, usize) {
        (self.levels[0].w, self.levels[0].h)
    }

    fn texel_in(&self, l: &Level<T>, s: i64, t: i64) -> T {
        let (w, h) = (l.w as i64, l.h as i64);
        let (s, t) = match self.wrap {
            WrapMode::Repeat => (s.rem_euclid(w), t.rem_euclid(h)),
            WrapMode::Clamp => (s.clamp(0, w - 1), t.clamp(0, h - 1)),
            WrapMode::Black => {
                if s < 0 || s >= w || t < 0 || t >= h {
                    return T::ZERO;
                }
                (s, t)
            }
        };
        l.data[(t * w + s) as usize]
    }

    /// Texel `(s, t)` of `level`, with the wrap mode applied.
    pub fn texel(&self, level: usize, s: i64, t: i64) -> T {
        let l = &self.levels[level.min(self.levels.len() - 1)];
        self.texel_in(l, s, t)
    }

    /// Bilinear interpolation of one level (pbrt-v3's `triangle`).
    pub fn bilerp(&self, level: usize, st: Vec2) -> T {
        let level = level.min(self.levels.len() - 1);
        let l = &self.levels[level];
        let s = st.x * l.w as f32 - 0.5;
        let t = st.y * l.h as f32 - 0.5;
        if !s.is_finite() || !t.is_finite() {
            return T::ZERO;
        }
        let (s0, t0) = (s.floor(), t.floor());
        let (ds, dt) = (s - s0, t - t0);
        let (s0, t0) = (s0 as i64, t0 as i64);
        self.texel_in(l, s0, t0) * ((1.0 - ds) * (1.0 - dt))
            + self.texel_in(l, s0, t0 + 1) * ((1.0 - ds) * dt)
            + self.texel_in(l, s0 + 1, t0) * (ds * (1.0 - dt))
            + self.texel_in(l, s0 + 1, t0 + 1) * (ds * dt)
    }

    /// Trilinear lookup for a square filter of the given width in `st` space.
    pub fn lookup_width(&self, st: Vec2, width: f32) -> T {
        let n = self.levels.len();
        let level = (n - 1) as f32 + width.max(1e-8).log2();
        if !(level >= 0.0) {
            self.bilerp(0, st)
        } else if level >= (n - 1) as f32 {
            self.texel(n - 1, 0, 0)
        } else {
            let il = level.floor() as usize;
            let d = level - il as f32;
            self.bilerp(il, st) * (1.0 - d) + self.bilerp(il + 1, st) * d
        }
    }

    /// Filtered lookup: trilinear when `trilinear`, else EWA with eccentricity clamped to `max_aniso`.
    /// The trilinear filter width is the largest footprint component, not twice it: pbrt-v3's
    /// commit aaa552a ("Fix trilinear filtering", in the 13d871f the references were made with)
    /// dropped the factor 2, since each level's bilinear lookup already widens the filter.
    pub fn lookup(&self, st: Vec2, mut d0: Vec2, mut d1: Vec2, trilinear: bool, max_aniso: f32) -> T {
        if trilinear {
            let w = d0.x.abs().max(d0.y.abs()).max(d1.x.abs().max(d1.y.abs()));
            return self.lookup_width(st, w);
        }
        if d0.length_squared() < d1.length_squared() {
            std::mem::swap(&mut d0, &mut d1);
        }
        let major = d0.length();
        let mut minor = d1.length();
        if minor * max_aniso < major && minor > 0.0 {
            let scale = major / (minor * max_aniso);
            d1 *= scale;
            minor *= scale;
        }
        if !(minor > 0.0) || !minor.is_finite() {
            return self.bilerp(0, st);
        }
        let lod = ((self.levels.len() - 1) as f32 + minor.log2()).max(0.0);
        let il = lod.floor() as usize;
        let d = lod - il as f32;
        self.ewa(il, st, d0, d1) * (1.0 - d) + self.ewa(il + 1, st, d0, d1) * d
    }

    fn ewa(&self, level: usize, st: Vec2, d0: Vec2, d1: Vec2) -> T {
        if level >= self.levels.len() {
            return self.texel(self.levels.len() - 1, 0, 0);
        }
        let l = &self.levels[level];
        let res = Vec2::new(l.w as f32, l.h as f32);
        let st = st * res - Vec2::splat(0.5);
        let (d0, d1) = (d0 * res, d1 * res);
        let mut a = d0.y * d0.y + d1.y * d1.y + 1.0;
        let mut b = -2.0 * (d0.x * d0.y + d1.x * d1.y);
        let mut c = d0.x * d0.x + d1.x * d1.x + 1.0;
        let inv_f = 1.0 / (a * c - b * b * 0.25);
        a *= inv_f;
        b *= inv_f;
        c *= inv_f;
        let det = -b * b + 4.0 * a * c;
        let inv_det = 1.0 / det;
        let (us, vs) = ((det * c).sqrt(), (a * det).sqrt());
        let s0 = (st.x - 2.0 * inv_det * us).ceil();
        let s1 = (st.x + 2.0 * inv_det * us).floor();
        let t0 = (st.y - 2.0 * inv_det * vs).ceil();
        let t1 = (st.y + 2.0 * inv_det * vs).floor();
        if !(s0.is_finite() && s1.is_finite() && t0.is_finite() && t1.is_finite())
            || (s1 - s0 + 1.0) * (t1 - t0 + 1.0) > 1.0e7
        {
            return self.bilerp(level, (st + Vec2::splat(0.5)) / res);
        }
        let lut = ewa_weight_lut();
        let mut sum = T::ZERO;
        let mut sum_w = 0.0f32;
        for it in t0 as i64..=t1 as i64 {
            let tt = it as f32 - st.y;
            for is in s0 as i64..=s1 as i64 {
                let ss = is as f32 - st.x;
                let r2 = a * ss * ss + b * ss * tt + c * tt * tt;
                if r2 < 1.0 {
                    let w = lut[((r2 * 128.0) as usize).min(127)];
                    sum = sum + self.texel_in(l, is, it) * w;
                    sum_w += w;
                }
            }
        }
        if sum_w > 0.0 {
            sum * (1.0 / sum_w)
        } else {
            self.bilerp(level, (st + Vec2::splat(0.5)) / res)
        }
    }
}

// ---------------------------------------------------------------------------
// Perlin noise
// ---------------------------------------------------------------------------

/// Ken Perlin's permutation ("Improving Noise", SIGGRAPH 2002, and his reference
/// implementation), the table pbrt-v3's noise uses, so noise textures reproduce pbrt-v3's
/// patterns exactly.
#[rustfmt::skip]
const PERLIN_PERMUTATION: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225,
    140, 36, 103, 30, 69, 142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148,
    247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32,
    57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122,
    60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54,
    65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169,
    200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64,
    52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212,
    207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213,
    119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9,
    129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104,
    218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241,
    81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157,
    184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93,
    222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
];

fn noise_perm() -> &'static [u8; 512] {
    static PERM: OnceLock<[u8; 512]> = OnceLock::new();
    PERM.get_or_init(|| std::array::from_fn(|i| PERLIN_PERMUTATION[i & 255]))
}

fn grad(x: usize, y: usize, z: usize, dx: f32, dy: f32, dz: f32) -> f32 {
    let perm = noise_perm();
    let h = perm[perm[perm[x] as usize + y] as usize + z] & 15;
    let u = if h < 8 || h == 12 || h == 13 { dx } else { dy };
    let v = if h < 4 || h == 12 || h == 13 { dy } else { dz };
    (if h & 1 != 0 { -u } else { u }) + (if h & 2 != 0 { -v } else { v })
}

fn noise_weight(t: f32) -> f32 {
    let t3 = t * t * t;
    let t4 = t3 * t;
    6.0 * t4 * t - 15.0 * t4 + 10.0 * t3
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

/// Gradient noise in [-1, 1] with pbrt-v3's construction and Perlin's permutation.
pub fn noise(p: Vec3) -> f32 {
    if !p.is_finite() {
        return 0.0;
    }
    let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
    let (dx, dy, dz) = (p.x - fx, p.y - fy, p.z - fz);
    let ix = (fx as i64 & 255) as usize;
    let iy = (fy as i64 & 255) as usize;
    let iz = (fz as i64 & 255) as usize;
    let w000 = grad(ix, iy, iz, dx, dy, dz);
    let w100 = grad(ix + 1, iy, iz, dx - 1.0, dy, dz);
    let w010 = grad(ix, iy + 1, iz, dx, dy - 1.0, dz);
    let w110 = grad(ix + 1, iy + 1, iz, dx - 1.0, dy - 1.0, dz);
    let w001 = grad(ix, iy, iz + 1, dx, dy, dz - 1.0);
    let w101 = grad(ix + 1, iy, iz + 1, dx - 1.0, dy, dz - 1.0);
    let w011 = grad(ix, iy + 1, iz + 1, dx, dy - 1.0, dz - 1.0);
    let w111 = grad(ix + 1, iy + 1, iz + 1, dx - 1.0, dy - 1.0, dz - 1.0);
    let (wx, wy, wz) = (noise_weight(dx), noise_weight(dy), noise_weight(dz));
    let x00 = lerp(wx, w000, w100);
    let x10 = lerp(wx, w010, w110);
    let x01 = lerp(wx, w001, w101);
    let x11 = lerp(wx, w011, w111);
    lerp(wz, lerp(wy, x00, x10), lerp(wy, x01, x11))
}

fn smooth_step(min: f32, max: f32, v: f32) -> f32 {
    let v = ((v - min) / (max - min)).clamp(0.0, 1.0);
    v * v * (-2.0 * v + 3.0)
}

fn octave_count(dpdx: Vec3, dpdy: Vec3, max_octaves: i32) -> f32 {
    let len2 = dpdx.length_squared().max(dpdy.length_squared());
    let n = -1.0 - 0.5 * len2.log2();
    if n.is_nan() {
        0.0
    } else {
        n.clamp(0.0, max_octaves.max(0) as f32)
    }
}

/// Fractional Brownian motion, antialiased by the differentials (pbrt-v3's `FBm`).
pub fn fbm(p: Vec3, dpdx: Vec3, dpdy: Vec3, omega: f32, max_octaves: i32) -> f32 {
    let n = octave_count(dpdx, dpdy, max_octaves);
    let ni = n.floor() as i32;
    let (mut sum, mut lambda, mut o) = (0.0f32, 1.0f32, 1.0f32);
    for _ in 0..ni {
        sum += o * noise(lambda * p);
        lambda *= 1.99;
        o *= omega;
    }
    sum + o * smooth_step(0.3, 0.7, n - ni as f32) * noise(lambda * p)
}

/// Turbulence (sum of |noise|), antialiased as pbrt-v3's `Turbulence`.
pub fn turbulence(p: Vec3, dpdx: Vec3, dpdy: Vec3, omega: f32, max_octaves: i32) -> f32 {
    let n = octave_count(dpdx, dpdy, max_octaves);
    let ni = n.floor() as i32;
    let (mut sum, mut lambda, mut o) = (0.0f32, 1.0f32, 1.0f32);
    for _ in 0..ni {
        sum += o * noise(lambda * p).abs();
        lambda *= 1.99;
        o *= omega;
    }
    sum += o * lerp(smooth_step(0.3, 0.7, n - ni as f32), 0.2, noise(lambda * p).abs());
    for _ in ni..max_octaves {
        sum += o * 0.2;
        o *= omega;
    }
    sum
}

// ---------------------------------------------------------------------------
// Textures
// ---------------------------------------------------------------------------

/// A float material/texture parameter: a constant or a float texture (index into
/// `SceneDescription::textures`, built in [`Textures`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FloatParam {
    Const(f32),
    Tex(usize),
}

/// A spectrum material/texture parameter: a constant or a spectrum texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpectrumParam {
    Const(Rgb),
    Tex(usize),
}

/// Closed-form box-filtered or point-sampled 2D checkerboard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckerAa {
    None,
    ClosedForm,
}

/// An image texture's shared pyramid and per-texture lookup settings.
#[derive(Clone, Debug)]
pub struct ImageLookup<T> {
    pub mapping: Mapping2D,
    pub mip: Arc<MipMap<T>>,
    pub trilinear: bool,
    pub max_aniso: f32,
    pub scale: f32,
    pub invert: bool,
}

impl<T: Texel> ImageLookup<T> {
    fn eval(&self, ctx: &TextureEvalContext) -> T {
        let (st, dx, dy) = self.mapping.map(ctx);
        self.mip.lookup(st, dx, dy, self.trilinear, self.max_aniso) * self.scale
    }
}

/// The texture classes shared by float and spectrum textures, generic over the
/// parameter type `P` (FloatParam/SpectrumParam) and value type `V`.
#[derive(Clone, Debug)]
pub enum TextureNode<P, V: Texel> {
    Constant(V),
    Scale {
        tex1: P,
        tex2: P,
    },
    Mix {
        tex1: P,
        tex2: P,
        amount: FloatParam,
    },
    Bilerp {
        mapping: Mapping2D,
        v: [V; 4],
    },
    Image(ImageLookup<V>),
    Checkerboard2D {
        mapping: Mapping2D,
        tex1: P,
        tex2: P,
        aa: CheckerAa,
    },
    Checkerboard3D {
        mapping: Mapping3D,
        tex1: P,
        tex2: P,
    },
    /// pbrt-v3's `dots`, whose constructor takes `(outside, inside)` but is called with the
    /// `"inside"` and `"outside"` parameters in that order: the dots show `"outside"` and the
    /// space between them `"inside"`. penumbra renders what pbrt-v3 renders.
    Dots {
        mapping: Mapping2D,
        /// The `"outside"` parameter (default 0).
        in_dots: P,
        /// The `"inside"` parameter (default 1).
        between_dots: P,
    },
    Fbm {
        mapping: Mapping3D,
        octaves: i32,
        omega: f32,
    },
    Wrinkled {
        mapping: Mapping3D,
        octaves: i32,
        omega: f32,
    },
    Windy {
        mapping: Mapping3D,
    },
    /// `uv` (spectrum only): `(s - ⌊s⌋, t - ⌊t⌋, 0)`.
    Uv {
        mapping: Mapping2D,
    },
    /// `marble` (spectrum only).
    Marble {
        mapping: Mapping3D,
        octaves: i32,
        omega: f32,
        scale: f32,
        variation: f32,
    },
}

pub type FloatTexture = TextureNode<FloatParam, f32>;
pub type SpectrumTexture = TextureNode<SpectrumParam, Rgb>;

#[derive(Clone, Debug)]
enum Slot {
    Unbuilt,
    Building,
    Float(FloatTexture),
    Spectrum(SpectrumTexture),
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct MipKey {
    path: PathBuf,
    gamma: bool,
    wrap: WrapMode,
    float: bool,
}

#[derive(Clone, Debug)]
enum CachedMip {
    Float(Arc<MipMap<f32>>),
    Rgb(Arc<MipMap<Rgb>>),
}

/// The scene's textures, keyed by their index in `SceneDescription::textures`,
/// built on demand.
#[derive(Clone, Debug)]
pub struct Textures {
    descs: Vec<TextureDesc>,
    base_dir: PathBuf,
    slots: Vec<Slot>,
    mips: HashMap<MipKey, CachedMip>,
}

fn luminance(c: Rgb) -> f32 {
    crate::spectrum::luminance(c)
}

fn spectrum_value_to_rgb(v: &SpectrumValue) -> Result<Rgb, String> {
    crate::spectrum::spectrum_to_rgb(v).map_err(|e| e.to_string())
}

fn read_image(path: &Path) -> Result<crate::image::Image, String> {
    crate::image::read_scene_input(path).map_err(|e| e.to_string())
}

/// RGB per pixel, top row first.
fn image_rgb(img: &crate::image::Image) -> Result<Vec<Rgb>, String> {
    let nc = img.channels.len();
    let npix = img.width as usize * img.height as usize;
    if nc == 0 || img.data.len() < npix * nc {
        return Err("image has no pixel data".into());
    }
    let find = |n: &str| img.channels.iter().position(|c| c == n);
    let idx = match (find("R"), find("G"), find("B")) {
        (Some(r), Some(g), Some(b)) => [r, g, b],
        _ if nc >= 3 => [0, 1, 2],
        _ => [0, 0, 0],
    };
    Ok((0..npix)
        .map(|i| Vec3::new(img.data[i * nc + idx[0]], img.data[i * nc + idx[1]], img.data[i * nc + idx[2]]))
        .collect())
}

fn has_ext(name: &str, ext: &str) -> bool {
    // On bytes: a name ending in a multi-byte character must not be sliced inside it (found by the fuzz smoke).
    let (name, ext) = (name.as_bytes(), ext.as_bytes());
    name.len() >= ext.len() && name[name.len() - ext.len()..].eq_ignore_ascii_case(ext)
}

fn err_at(params: &ParamSet, name: &str, fallback: &FileLoc, msg: impl Into<String>) -> Diagnostic {
    Diagnostic::error(Some(params.loc_of(name).cloned().unwrap_or_else(|| fallback.clone())), msg)
}

impl Textures {
    /// Records the scene's texture definitions; nothing is built yet.
    pub fn new(desc: &SceneDescription) -> Self {
        Textures {
            descs: desc.textures.clone(),
            base_dir: desc.base_dir.clone(),
            slots: vec![Slot::Unbuilt; desc.textures.len()],
            mips: HashMap::new(),
        }
    }

    /// How many textures have been built.
    pub fn built_count(&self) -> usize {
        self.slots.iter().filter(|s| matches!(s, Slot::Float(_) | Slot::Spectrum(_))).count()
    }
    /// Whether texture `index` has been built.
    pub fn is_built(&self, index: usize) -> bool {
        matches!(self.slots.get(index), Some(Slot::Float(_) | Slot::Spectrum(_)))
    }
    /// How many distinct image pyramids were loaded.
    pub fn image_count(&self) -> usize {
        self.mips.len()
    }

    /// Builds texture `index` (and what it references) if not yet built.
    pub fn ensure(&mut self, index: usize, warnings: &DiagSink) -> Result<(), Diagnostic> {
        match self.slots.get(index) {
            None => return Err(Diagnostic::error(None, format!("texture index {index} out of range"))),
            Some(Slot::Float(_) | Slot::Spectrum(_)) => return Ok(()),
            Some(Slot::Building) => {
                let d = &self.descs[index];
                return Err(Diagnostic::error(
                    Some(d.entity.loc.clone()),
                    format!("texture \"{}\" refers to itself", d.name),
                ));
            }
            Some(Slot::Unbuilt) => {}
        }
        self.slots[index] = Slot::Building;
        let desc = self.descs[index].clone();
        let built = match desc.kind {
            TextureKind::Float => self.build_float(&desc, warnings).map(Slot::Float),
            TextureKind::Spectrum => self.build_spectrum(&desc, warnings).map(Slot::Spectrum),
        };
        match built {
            Ok(s) => {
                self.slots[index] = s;
                warnings.extend(desc.entity.params.report_unused(&format!("texture \"{}\"", desc.name)));
                Ok(())
            }
            Err(e) => {
                self.slots[index] = Slot::Unbuilt;
                Err(e)
            }
        }
    }

    /// pbrt-v3's `GetFloatTexture(name, default)`: a `texture` parameter naming a float
    /// texture, else a `float` value, else `default`.
    pub fn get_float_param(
        &mut self,
        params: &ParamSet,
        name: &str,
        default: f32,
        warnings: &DiagSink,
    ) -> Result<FloatParam, Diagnostic> {
        Ok(self.get_float_param_opt(params, name, warnings)?.unwrap_or(FloatParam::Const(default)))
    }

    /// pbrt-v3's `GetFloatTextureOrNull`: like [`Self::get_float_param`] but `None` when neither is given.
    pub fn get_float_param_opt(
        &mut self,
        params: &ParamSet,
        name: &str,
        warnings: &DiagSink,
    ) -> Result<Option<FloatParam>, Diagnostic> {
        if let Some(r) = params.get_texture(name) {
            let loc = params.loc_of(name).cloned();
            return match r.float {
                Some(i) => {
                    self.ensure(i, warnings)?;
                    Ok(Some(FloatParam::Tex(i)))
                }
                None => Err(Diagnostic::error(
                    loc,
                    format!("couldn't find float texture named \"{}\" for parameter \"{name}\"", r.name),
                )),
            };
        }
        Ok(params.get_floats(name).and_then(|v| v.first().copied()).map(FloatParam::Const))
    }

    /// pbrt-v3's `GetSpectrumTexture(name, default)`.
    pub fn get_spectrum_param(
        &mut self,
        params: &ParamSet,
        name: &str,
        default: Rgb,
        warnings: &DiagSink,
    ) -> Result<SpectrumParam, Diagnostic> {
        Ok(self.get_spectrum_param_opt(params, name, warnings)?.unwrap_or(SpectrumParam::Const(default)))
    }

    /// pbrt-v3's `GetSpectrumTextureOrNull`, also accepting a spectrum value.
    pub fn get_spectrum_param_opt(
        &mut self,
        params: &ParamSet,
        name: &str,
        warnings: &DiagSink,
    ) -> Result<Option<SpectrumParam>, Diagnostic> {
        if let Some(r) = params.get_texture(name) {
            let loc = params.loc_of(name).cloned();
            return match r.spectrum {
                Some(i) => {
                    self.ensure(i, warnings)?;
                    Ok(Some(SpectrumParam::Tex(i)))
                }
                None => Err(Diagnostic::error(
                    loc,
                    format!("couldn't find spectrum texture named \"{}\" for parameter \"{name}\"", r.name),
                )),
            };
        }
        match params.get_spectrum(name) {
            Some(v) => {
                let c = spectrum_value_to_rgb(v)
                    .map_err(|e| Diagnostic::error(params.loc_of(name).cloned(), format!("\"{name}\": {e}")))?;
                Ok(Some(SpectrumParam::Const(c)))
            }
            None => Ok(None),
        }
    }

    fn load_mip(
        &mut self,
        params: &ParamSet,
        loc: &FileLoc,
        float: bool,
        wrap: WrapMode,
        gamma: Option<bool>,
    ) -> Result<CachedMip, Diagnostic> {
        let filename = params.get_one_string("filename", "");
        if filename.is_empty() {
            return Err(Diagnostic::error(Some(loc.clone()), "imagemap texture needs a \"string filename\""));
        }
        let gamma = gamma.unwrap_or(has_ext(&filename, ".png") || has_ext(&filename, ".tga"));
        let p = PathBuf::from(&filename);
        let path = if p.is_absolute() { p } else { self.base_dir.join(p) };
        let key = MipKey { path: path.clone(), gamma, wrap, float };
        if let Some(m) = self.mips.get(&key) {
            return Ok(m.clone());
        }
        let fail =
            |e: String| err_at(params, "filename", loc, format!("cannot read image \"{}\": {e}", path.display()));
        let img = read_image(&path).map_err(fail)?;
        let rgb = image_rgb(&img).map_err(fail)?;
        let (w, h) = (img.width as usize, img.height as usize);
        // Flip: texture-space t = 0 is the bottom row.
        let rows = |f: &dyn Fn(Rgb) -> Rgb| -> Vec<Rgb> {
            (0..h).rev().flat_map(|y| rgb[y * w..(y + 1) * w].iter().map(|c| f(*c))).collect()
        };
        let m = if float {
            let data: Vec<f32> = rows(&|c| c)
                .into_iter()
                .map(|c| {
                    let y = luminance(c);
                    if gamma {
                        srgb_decode(y)
                    } else {
                        y
                    }
                })
                .collect();
            CachedMip::Float(Arc::new(MipMap::new(w, h, data, wrap).ok_or_else(|| fail("empty image".into()))?))
        } else {
            let data = rows(&|c| {
                if gamma {
                    Vec3::new(srgb_decode(c.x), srgb_decode(c.y), srgb_decode(c.z))
                } else {
                    c
                }
            });
            CachedMip::Rgb(Arc::new(MipMap::new(w, h, data, wrap).ok_or_else(|| fail("empty image".into()))?))
        };
        self.mips.insert(key, m.clone());
        Ok(m)
    }

    fn image_settings(params: &ParamSet) -> (bool, f32, WrapMode, f32, bool, Option<bool>) {
        let max_aniso = params.get_one_float("maxanisotropy", 8.0);
        let trilinear = params.get_one_bool("trilinear", false);
        // pbrt-v4 spells the choice as "filter"; accept it too.
        let trilinear = match params.get_strings("filter").and_then(|v| v.first().cloned()).as_deref() {
            Some("ewa") | Some("EWA") => false,
            Some(_) => true,
            None => trilinear,
        };
        let wrap = match params.get_one_string("wrap", "repeat").as_str() {
            "black" => WrapMode::Black,
            "clamp" => WrapMode::Clamp,
            _ => WrapMode::Repeat,
        };
        let scale = params.get_one_float("scale", 1.0);
        let invert = params.get_one_bool("invert", false);
        let gamma = params.get_bools("gamma").and_then(|v| v.first().copied());
        (trilinear, max_aniso, wrap, scale, invert, gamma)
    }

    fn checker_aa(params: &ParamSet, loc: &FileLoc, warnings: &DiagSink) -> CheckerAa {
        match params.get_one_string("aamode", "closedform").as_str() {
            "none" => CheckerAa::None,
            "closedform" => CheckerAa::ClosedForm,
            other => {
                warnings.warn(
                    Some(params.loc_of("aamode").cloned().unwrap_or_else(|| loc.clone())),
                    format!("antialiasing mode \"{other}\" not understood by checkerboard: using \"closedform\""),
                );
                CheckerAa::ClosedForm
            }
        }
    }

    fn build_float(&mut self, d: &TextureDesc, warnings: &DiagSink) -> Result<FloatTexture, Diagnostic> {
        let p = &d.entity.params;
        let loc = &d.entity.loc;
        let xf = &d.render_from_texture.start;
        let m2 = |w: &DiagSink| Mapping2D::from_params(p, xf, loc, w);
        Ok(match d.entity.kind.as_str() {
            "constant" => TextureNode::Constant(p.get_one_float("value", 1.0)),
            "scale" => TextureNode::Scale {
                tex1: self.get_float_param(p, "tex1", 1.0, warnings)?,
                tex2: self.get_float_param(p, "tex2", 1.0, warnings)?,
            },
            "mix" => TextureNode::Mix {
                tex1: self.get_float_param(p, "tex1", 0.0, warnings)?,
                tex2: self.get_float_param(p, "tex2", 1.0, warnings)?,
                amount: self.get_float_param(p, "amount", 0.5, warnings)?,
            },
            "bilerp" => TextureNode::Bilerp {
                mapping: m2(warnings),
                v: [
                    p.get_one_float("v00", 0.0),
                    p.get_one_float("v01", 1.0),
                    p.get_one_float("v10", 0.0),
                    p.get_one_float("v11", 1.0),
                ],
            },
            "imagemap" => {
                let mapping = m2(warnings);
                let (trilinear, max_aniso, wrap, scale, invert, gamma) = Self::image_settings(p);
                let CachedMip::Float(mip) = self.load_mip(p, loc, true, wrap, gamma)? else {
                    return Err(Diagnostic::error(Some(loc.clone()), "internal: image cache kind mismatch"));
                };
                TextureNode::Image(ImageLookup { mapping, mip, trilinear, max_aniso, scale, invert })
            }
            "checkerboard" => self.checkerboard(
                d,
                warnings,
                |s, w| s.get_float_param(p, "tex1", 1.0, w),
                |s, w| s.get_float_param(p, "tex2", 0.0, w),
            )?,
            "dots" => TextureNode::Dots {
                mapping: m2(warnings),
                between_dots: self.get_float_param(p, "inside", 1.0, warnings)?,
                in_dots: self.get_float_param(p, "outside", 0.0, warnings)?,
            },
            "fbm" => TextureNode::Fbm {
                mapping: Mapping3D::new(xf),
                octaves: p.get_one_int("octaves", 8),
                omega: p.get_one_float("roughness", 0.5),
            },
            "wrinkled" => TextureNode::Wrinkled {
                mapping: Mapping3D::new(xf),
                octaves: p.get_one_int("octaves", 8),
                omega: p.get_one_float("roughness", 0.5),
            },
            "windy" => TextureNode::Windy { mapping: Mapping3D::new(xf) },
            "uv" | "marble" => {
                return Err(Diagnostic::error(
                    Some(loc.clone()),
                    format!(
                        "\"{}\" is a spectrum texture only: float texture \"{}\" cannot be created",
                        d.entity.kind, d.name
                    ),
                ))
            }
            other => {
                return Err(Diagnostic::error(Some(loc.clone()), format!("float texture type \"{other}\" unknown")))
            }
        })
    }

    fn build_spectrum(&mut self, d: &TextureDesc, warnings: &DiagSink) -> Result<SpectrumTexture, Diagnostic> {
        let p = &d.entity.params;
        let loc = &d.entity.loc;
        let xf = &d.render_from_texture.start;
        let m2 = |w: &DiagSink| Mapping2D::from_params(p, xf, loc, w);
        let one = Vec3::ONE;
        Ok(match d.entity.kind.as_str() {
            "constant" => match self.get_spectrum_param(p, "value", one, warnings)? {
                SpectrumParam::Const(c) => TextureNode::Constant(c),
                SpectrumParam::Tex(_) => {
                    return Err(err_at(p, "value", loc, "constant texture \"value\" must be a value, not a texture"))
                }
            },
            "scale" => TextureNode::Scale {
                tex1: self.get_spectrum_param(p, "tex1", one, warnings)?,
                tex2: self.get_spectrum_param(p, "tex2", one, warnings)?,
            },
            "mix" => TextureNode::Mix {
                tex1: self.get_spectrum_param(p, "tex1", Vec3::ZERO, warnings)?,
                tex2: self.get_spectrum_param(p, "tex2", one, warnings)?,
                amount: self.get_float_param(p, "amount", 0.5, warnings)?,
            },
            "bilerp" => {
                let mut v = [Vec3::ZERO, one, Vec3::ZERO, one];
                for (i, n) in ["v00", "v01", "v10", "v11"].iter().enumerate() {
                    if let Some(s) = p.get_spectrum(n) {
                        v[i] = spectrum_value_to_rgb(s).map_err(|e| err_at(p, n, loc, format!("\"{n}\": {e}")))?;
                    }
                }
                TextureNode::Bilerp { mapping: m2(warnings), v }
            }
            "imagemap" => {
                let mapping = m2(warnings);
                let (trilinear, max_aniso, wrap, scale, invert, gamma) = Self::image_settings(p);
                let CachedMip::Rgb(mip) = self.load_mip(p, loc, false, wrap, gamma)? else {
                    return Err(Diagnostic::error(Some(loc.clone()), "internal: image cache kind mismatch"));
                };
                TextureNode::Image(ImageLookup { mapping, mip, trilinear, max_aniso, scale, invert })
            }
            "checkerboard" => self.checkerboard(
                d,
                warnings,
                |s, w| s.get_spectrum_param(p, "tex1", one, w),
                |s, w| s.get_spectrum_param(p, "tex2", Vec3::ZERO, w),
            )?,
            "dots" => TextureNode::Dots {
                mapping: m2(warnings),
                between_dots: self.get_spectrum_param(p, "inside", one, warnings)?,
                in_dots: self.get_spectrum_param(p, "outside", Vec3::ZERO, warnings)?,
            },
            "fbm" => TextureNode::Fbm {
                mapping: Mapping3D::new(xf),
                octaves: p.get_one_int("octaves", 8),
                omega: p.get_one_float("roughness", 0.5),
            },
            "wrinkled" => TextureNode::Wrinkled {
                mapping: Mapping3D::new(xf),
                octaves: p.get_one_int("octaves", 8),
                omega: p.get_one_float("roughness", 0.5),
            },
            "windy" => TextureNode::Windy { mapping: Mapping3D::new(xf) },
            "uv" => TextureNode::Uv { mapping: m2(warnings) },
            "marble" => TextureNode::Marble {
                mapping: Mapping3D::new(xf),
                octaves: p.get_one_int("octaves", 8),
                omega: p.get_one_float("roughness", 0.5),
                scale: p.get_one_float("scale", 1.0),
                variation: p.get_one_float("variation", 0.2),
            },
            other => {
                return Err(Diagnostic::error(Some(loc.clone()), format!("spectrum texture type \"{other}\" unknown")))
            }
        })
    }

    fn checkerboard<P, V: Texel>(
        &mut self,
        d: &TextureDesc,
        warnings: &DiagSink,
        tex1: impl FnOnce(&mut Self, &DiagSink) -> Result<P, Diagnostic>,
        tex2: impl FnOnce(&mut Self, &DiagSink) -> Result<P, Diagnostic>,
    ) -> Result<TextureNode<P, V>, Diagnostic> {
        let p = &d.entity.params;
        let loc = &d.entity.loc;
        let dim = p.get_one_int("dimension", 2);
        let t1 = tex1(self, warnings)?;
        let t2 = tex2(self, warnings)?;
        match dim {
            2 => Ok(TextureNode::Checkerboard2D {
                mapping: Mapping2D::from_params(p, &d.render_from_texture.start, loc, warnings),
                tex1: t1,
                tex2: t2,
                aa: Self::checker_aa(p, loc, warnings),
            }),
            3 => Ok(TextureNode::Checkerboard3D {
                mapping: Mapping3D::new(&d.render_from_texture.start),
                tex1: t1,
                tex2: t2,
            }),
            _ => Err(err_at(p, "dimension", loc, format!("{dim} dimensional checkerboard texture not supported"))),
        }
    }

    /// Value of a float parameter at `ctx`.
    pub fn eval_float(&self, p: FloatParam, ctx: &TextureEvalContext) -> f32 {
        match p {
            FloatParam::Const(v) => v,
            FloatParam::Tex(i) => match self.slots.get(i) {
                Some(Slot::Float(t)) => t.eval(self, ctx),
                _ => 0.0,
            },
        }
    }

    /// Value of a spectrum parameter at `ctx`.
    pub fn eval_spectrum(&self, p: SpectrumParam, ctx: &TextureEvalContext) -> Rgb {
        match p {
            SpectrumParam::Const(v) => v,
            SpectrumParam::Tex(i) => match self.slots.get(i) {
                Some(Slot::Spectrum(t)) => t.eval(self, ctx),
                _ => Vec3::ZERO,
            },
        }
    }
}

/// Evaluating a child parameter of the right kind.
pub trait TextureParam: Copy {
    type Value: Texel;
    fn eval(self, textures: &Textures, ctx: &TextureEvalContext) -> Self::Value;
}

impl TextureParam for FloatParam {
    type Value = f32;
    fn eval(self, textures: &Textures, ctx: &TextureEvalContext) -> f32 {
        textures.eval_float(self, ctx)
    }
}

impl TextureParam for SpectrumParam {
    type Value = Rgb;
    fn eval(self, textures: &Textures, ctx: &TextureEvalContext) -> Rgb {
        textures.eval_spectrum(self, ctx)
    }
}

/// Converting a scalar to a texture value (noise textures return `v` in every channel).
pub trait FromScalar {
    fn from_scalar(v: f32) -> Self;
    fn from_rgb(c: Rgb) -> Self;
    fn invert(self) -> Self;
}

impl FromScalar for f32 {
    fn from_scalar(v: f32) -> Self {
        v
    }
    fn from_rgb(c: Rgb) -> Self {
        luminance(c)
    }
    fn invert(self) -> Self {
        (1.0 - self).max(0.0)
    }
}

impl FromScalar for Vec3 {
    fn from_scalar(v: f32) -> Self {
        Vec3::splat(v)
    }
    fn from_rgb(c: Rgb) -> Self {
        c
    }
    fn invert(self) -> Self {
        (Vec3::ONE - self).max(Vec3::ZERO)
    }
}

/// The closed-form box-filtered fraction of a 2D checkerboard's filter footprint that
/// lies in "odd" checks (where tex2 applies), as pbrt-v3; `None` when the footprint
/// lies within one check (then point-sample).
pub fn checkerboard_closed_form(st: Vec2, dstdx: Vec2, dstdy: Vec2) -> Option<f32> {
    let ds = dstdx.x.abs().max(dstdy.x.abs());
    let dt = dstdx.y.abs().max(dstdy.y.abs());
    let (s0, s1) = (st.x - ds, st.x + ds);
    let (t0, t1) = (st.y - dt, st.y + dt);
    if s0.floor() == s1.floor() && t0.floor() == t1.floor() {
        return None;
    }
    // Integral of the indicator "floor(x) is odd" from 0 to x.
    let bump_int = |x: f32| (x / 2.0).floor() + 2.0 * (x / 2.0 - (x / 2.0).floor() - 0.5).max(0.0);
    // With a zero-width filter along one axis, the average is the point value there.
    let odd = |x: f32| if (x.floor() as i64).rem_euclid(2) == 1 { 1.0 } else { 0.0 };
    let sint = if ds > 0.0 { (bump_int(s1) - bump_int(s0)) / (2.0 * ds) } else { odd(st.x) };
    let tint = if dt > 0.0 { (bump_int(t1) - bump_int(t0)) / (2.0 * dt) } else { odd(st.y) };
    let mut area2 = sint + tint - 2.0 * sint * tint;
    if ds > 1.0 || dt > 1.0 {
        area2 = 0.5;
    }
    Some(area2)
}

fn checker_even(a: f32, b: f32, c: f32) -> bool {
    // pbrt-v3 sums the integer cells and tests `% 2 == 0` with C's truncating remainder.
    let sum = a.floor() as i64 + b.floor() as i64 + c.floor() as i64;
    sum % 2 == 0
}

fn marble_color(t: f32) -> Rgb {
    const C: [[f32; 3]; 9] = [
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.5, 0.5, 0.5],
        [0.6, 0.59, 0.58],
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.2, 0.2, 0.33],
        [0.58, 0.58, 0.6],
    ];
    let nseg = (C.len() - 3) as f32;
    // pbrt-v3 takes min(1, ⌊t·nseg⌋) as the first control point.
    let first = ((t * nseg).floor() as i64).clamp(0, 1) as usize;
    let t = t * nseg - first as f32;
    let c = |i: usize| Vec3::from(C[(first + i).min(C.len() - 1)]);
    let (c0, c1, c2, c3) = (c(0), c(1), c(2), c(3));
    let s0 = c0.lerp(c1, t);
    let s1 = c1.lerp(c2, t);
    let s2 = c2.lerp(c3, t);
    let s0 = s0.lerp(s1, t);
    let s1 = s1.lerp(s2, t);
    1.5 * s0.lerp(s1, t)
}

impl<P: TextureParam<Value = V>, V: Texel + FromScalar> TextureNode<P, V> {
    /// The texture's value at `ctx`.
    pub fn eval(&self, tx: &Textures, ctx: &TextureEvalContext) -> V {
        match self {
            TextureNode::Constant(v) => *v,
            TextureNode::Scale { tex1, tex2 } => tex1.eval(tx, ctx).mul_elem(tex2.eval(tx, ctx)),
            TextureNode::Mix { tex1, tex2, amount } => {
                let a = tx.eval_float(*amount, ctx);
                let (t1, t2) = (
                    if a != 1.0 { tex1.eval(tx, ctx) } else { V::ZERO },
                    if a != 0.0 { tex2.eval(tx, ctx) } else { V::ZERO },
                );
                t1 * (1.0 - a) + t2 * a
            }
            TextureNode::Bilerp { mapping, v } => {
                let (st, _, _) = mapping.map(ctx);
                let (s, t) = (st.x, st.y);
                v[0] * ((1.0 - s) * (1.0 - t)) + v[1] * ((1.0 - s) * t) + v[2] * (s * (1.0 - t)) + v[3] * (s * t)
            }
            TextureNode::Image(im) => {
                let v = im.eval(ctx);
                if im.invert {
                    v.invert()
                } else {
                    v
                }
            }
            TextureNode::Checkerboard2D { mapping, tex1, tex2, aa } => {
                let (st, dx, dy) = mapping.map(ctx);
                let area2 = match aa {
                    CheckerAa::None => None,
                    CheckerAa::ClosedForm => checkerboard_closed_form(st, dx, dy),
                };
                match area2 {
                    None => {
                        if checker_even(st.x, st.y, 0.0) {
                            tex1.eval(tx, ctx)
                        } else {
                            tex2.eval(tx, ctx)
                        }
                    }
                    Some(a) => tex1.eval(tx, ctx) * (1.0 - a) + tex2.eval(tx, ctx) * a,
                }
            }
            TextureNode::Checkerboard3D { mapping, tex1, tex2 } => {
                let (p, _, _) = mapping.map(ctx);
                if checker_even(p.x, p.y, p.z) {
                    tex1.eval(tx, ctx)
                } else {
                    tex2.eval(tx, ctx)
                }
            }
            TextureNode::Dots { mapping, in_dots, between_dots } => {
                let (st, _, _) = mapping.map(ctx);
                let s_cell = (st.x + 0.5).floor();
                let t_cell = (st.y + 0.5).floor();
                let n2 = |x: f32, y: f32| noise(Vec3::new(x, y, 0.5));
                if n2(s_cell + 0.5, t_cell + 0.5) > 0.0 {
                    let radius = 0.35f32;
                    let max_shift = 0.5 - radius;
                    let sc = s_cell + max_shift * n2(s_cell + 1.5, t_cell + 2.8);
                    let tc = t_cell + max_shift * n2(s_cell + 4.5, t_cell + 9.8);
                    if (st - Vec2::new(sc, tc)).length_squared() < radius * radius {
                        return in_dots.eval(tx, ctx);
                    }
                }
                between_dots.eval(tx, ctx)
            }
            TextureNode::Fbm { mapping, octaves, omega } => {
                let (p, dx, dy) = mapping.map(ctx);
                V::from_scalar(fbm(p, dx, dy, *omega, *octaves))
            }
            TextureNode::Wrinkled { mapping, octaves, omega } => {
                let (p, dx, dy) = mapping.map(ctx);
                V::from_scalar(turbulence(p, dx, dy, *omega, *octaves))
            }
            TextureNode::Windy { mapping } => {
                let (p, dx, dy) = mapping.map(ctx);
                let wind = fbm(0.1 * p, 0.1 * dx, 0.1 * dy, 0.5, 3);
                let wave = fbm(p, dx, dy, 0.5, 6);
                V::from_scalar(wind.abs() * wave)
            }
            TextureNode::Uv { mapping } => {
                let (st, _, _) = mapping.map(ctx);
                V::from_rgb(Vec3::new(st.x - st.x.floor(), st.y - st.y.floor(), 0.0))
            }
            TextureNode::Marble { mapping, octaves, omega, scale, variation } => {
                let (p, dx, dy) = mapping.map(ctx);
                let p = p * *scale;
                let m = p.y + variation * fbm(p, *scale * dx, *scale * dy, *omega, *octaves);
                let t = 0.5 + 0.5 * m.sin();
                V::from_rgb(marble_color(t))
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
