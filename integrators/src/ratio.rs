//! `ratio`: analytic direct illumination × denoised stochastic shadows (Heitz, Hill &
//! McGuire 2018, "Combining Analytic Direct Illumination and Stochastic Shadows"), the ratio
//! estimator of seed 004 (`../shared/seeds/004_*`), built on `ltc`'s analytic shading.
//!
//! For every area light and every point whose material has an LTC form, three terms:
//!
//! * `U`: the analytic unshadowed radiance, from `ltc` with `shadows = false`;
//! * `S_N`, `U_N`: Monte Carlo estimates of the shadowed and the unshadowed radiance from
//!   the *same* samples (same directions, same points on the light, same weights; `S_N`
//!   multiplies each by its visibility), with the real BSDF and the light's radiance.
//!
//! Per camera sample and area light, `nsamples` samples are drawn: `⌈n/2⌉` from the light
//! (a triangle of the emitting mesh in proportion to its area, then a point uniformly on it:
//! pbrt-v3's per-triangle lights of one mesh are sampled as one light, so that a sample costs
//! one shadow ray whatever the number of triangles) and `⌊n/2⌋` from the point's BRDF as LTCs
//! (the clamped cosine for the diffuse part, the GGX LTC for the glossy part, chosen in
//! proportion to their luminance weights `Kd` and `scale · F(θo) · magnitude`), combined
//! with the balance heuristic (every sample is weighted by `1 / (n_l p_light + n_b p_brdf)`,
//! densities at the sample's point on the light). A BRDF-sampled direction counts every
//! light triangle it crosses (ignoring occluders), as `U` integrates every triangle, so
//! that `E[U_N]` is the unshadowed integral whatever the light's shape.
//!
//! `U` is `ltc`'s: with `"string shading" "pixel"` (default) once per surface seen in a pixel
//! (see `ltc`), with `"sample"` per camera sample. The film's extra channels hold, per pixel,
//! `U`, `S_N`, `U_N` (RGB), the luminance moments `⟨S²⟩`, `⟨U²⟩`, `⟨S·U⟩` of the
//! single-sample estimates `n · (contribution of stochastic sample k)` (summed over the
//! lights; the noise estimate, over camera × stochastic samples, so that one camera sample
//! per pixel still has one), the depth, the normal facing the viewer and the plane offset
//! `n·p`. After the pass the
//! image is `rest + U · D(S_N) / D(U_N)` per channel, where `rest` is everything else
//! (emission seen directly, delta lights with one shadow ray, infinite lights and
//! materials without LTC form through `directlighting`'s estimator, as in `ltc`) and `D`
//! is [`cross_bilateral`] with the same weights for both. The kernel radius per pixel
//! comes from the delta-method standard deviation `σ_r` of the pixel's ratio estimate:
//! the smallest `R ≤ maxradius` with `σ_r / (2R + 1) ≤ noisetarget`, dilated by one pixel.
//!
//! Guard: `S_N ≤ U_N` sample by sample, so with non-negative weights the ratio is in
//! `[0, 1]`; it is clamped there. Where `D(U_N)` is zero or not positive-finite, the raw
//! `S_N / U_N` is used if `U_N > 0`, and otherwise the shadowing is unknown (no sample
//! reached the light) and the ratio is taken as 1 (the analytic `U` unchanged). The
//! output is never NaN or infinite.

use crate::common::other_lights::{add_other_lights, warn_infinite_lights, FallbackWarning};
use crate::common::pixel_shading::{parse_shading, SharedPixel};
use crate::ltc::{fresnel_at, AreaLighting, FresnelMode, LtcIntegrator, LtcShader, Mode};
use glam::{DVec2, DVec3};
use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::film::Film;
use penumbra_core::geometry::{gamma, Frame, Ray};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, PixelShared, RenderContext, RenderError, RenderStats, ThreadStats,
};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::{emitting_normal, DiffuseAreaLight, Light, LightContext};
use penumbra_core::ltc::Ltc;
use penumbra_core::material::LtcDescription;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit};
use penumbra_core::spectrum::luminance;
use penumbra_core::{Rgb, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use rayon::prelude::*;

/// Weights of the cross-bilateral filter (all relative, see [`cross_bilateral`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterParams {
    /// Relative depth tolerance: weight `exp(−½ ((z_q − z_p) / (σ z_p))²)`.
    pub sigma_depth: f32,
    /// Normal weight `max(0, n_p·n_q)^e`.
    pub normal_exponent: f32,
    /// Plane-offset tolerance relative to depth: `exp(−½ ((d_q − d_p) / (σ z_p))²)`, `d = n·p`.
    pub sigma_plane: f32,
    /// Relative tolerance on the analytic `U` (luminance): `exp(−½ ((U_q − U_p) / (σ max(U_p, U_q)))²)`.
    pub sigma_u: f32,
    /// Edge stop on the raw ratio itself: `exp(−½ (|r_q − r_p| / (k √(σ_p² + σ_q²) + floor))²)`
    /// with `k` = `ratio_k` (0 disables it) and `floor` = `ratio_floor`: differences the
    /// pixels' own noise explains do not stop the filter, a contact shadow next to lit floor does.
    pub ratio_k: f32,
    pub ratio_floor: f32,
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            sigma_depth: 0.1,
            normal_exponent: 32.0,
            sigma_plane: 0.02,
            sigma_u: 0.5,
            ratio_k: 2.0,
            ratio_floor: 0.02,
        }
    }
}

/// The guide of one pixel. `depth ≤ 0` (or not finite) marks a pixel without geometry: it is
/// neither filtered nor used as a neighbour.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guide {
    pub depth: f32,
    pub normal: Vec3,
    pub plane: f32,
    pub u: f32,
    /// The raw ratio `S_N / U_N` (luminance) and the standard deviation of its estimate.
    pub ratio: f32,
    pub ratio_sigma: f32,
}

/// Cross-bilateral filter of `values` (`channels` interleaved values per pixel, row-major
/// `width × height`) with per-pixel kernel radius `radius` (0: the pixel is copied). The
/// weight of neighbour `q` for pixel `p` is the product of a spatial Gaussian (σ = R/2) and
/// the guide terms of [`FilterParams`]; all channels share the weights. Returns the
/// filtered values and, per pixel, `Σw² / (Σw)²` (the variance reduction of independent
/// noise). Inputs whose lengths do not match give the input back unchanged.
pub fn cross_bilateral(
    width: usize,
    height: usize,
    guides: &[Guide],
    radius: &[u32],
    values: &[f32],
    channels: usize,
    params: &FilterParams,
) -> (Vec<f32>, Vec<f32>) {
    let n = width * height;
    if guides.len() != n || radius.len() != n || values.len() != n * channels {
        return (values.to_vec(), vec![1.0; n]);
    }
    let valid = |g: &Guide| g.depth > 0.0 && g.depth.is_finite();
    let unit = |v: Vec3| v.normalize_or_zero();
    let rows: Vec<(Vec<f32>, Vec<f32>)> = (0..height)
        .into_par_iter()
        .map(|y| {
            let mut out = vec![0.0f32; width * channels];
            let mut red = vec![1.0f32; width];
            let mut acc = vec![0.0f64; channels];
            for x in 0..width {
                let i = y * width + x;
                let gp = &guides[i];
                let r = radius[i] as i64;
                if r == 0 || !valid(gp) {
                    out[x * channels..(x + 1) * channels].copy_from_slice(&values[i * channels..(i + 1) * channels]);
                    continue;
                }
                let np = unit(gp.normal);
                let sig_s = (r as f32 * 0.5).max(0.5);
                acc.iter_mut().for_each(|a| *a = 0.0);
                let (mut sw, mut sw2) = (0.0f64, 0.0f64);
                for qy in (y as i64 - r).max(0)..=(y as i64 + r).min(height as i64 - 1) {
                    for qx in (x as i64 - r).max(0)..=(x as i64 + r).min(width as i64 - 1) {
                        let j = qy as usize * width + qx as usize;
                        let gq = &guides[j];
                        if !valid(gq) {
                            continue;
                        }
                        let (dx, dy) = ((qx - x as i64) as f32, (qy - y as i64) as f32);
                        let mut e = (dx * dx + dy * dy) / (2.0 * sig_s * sig_s);
                        let dz = (gq.depth - gp.depth) / (params.sigma_depth * gp.depth);
                        let dd = (gq.plane - gp.plane) / (params.sigma_plane * gp.depth);
                        let umax = gp.u.max(gq.u);
                        let du = if umax > 0.0 { (gq.u - gp.u) / (params.sigma_u * umax) } else { 0.0 };
                        let dr = if params.ratio_k > 0.0 {
                            let sr = params.ratio_k * (gp.ratio_sigma.powi(2) + gq.ratio_sigma.powi(2)).sqrt()
                                + params.ratio_floor;
                            (gq.ratio - gp.ratio) / sr
                        } else {
                            0.0
                        };
                        e += 0.5 * (dz * dz + dd * dd + du * du + dr * dr);
                        let c = np.dot(unit(gq.normal));
                        let wn = if j == i {
                            1.0
                        } else if c > 0.0 {
                            c.powf(params.normal_exponent)
                        } else {
                            0.0
                        };
                        let w = (-e).exp() * wn;
                        if !(w > 0.0 && w.is_finite()) {
                            continue;
                        }
                        let w = w as f64;
                        sw += w;
                        sw2 += w * w;
                        for (c, a) in acc.iter_mut().enumerate() {
                            *a += w * values[j * channels + c] as f64;
                        }
                    }
                }
                if sw > 0.0 {
                    for c in 0..channels {
                        out[x * channels + c] = (acc[c] / sw) as f32;
                    }
                    red[x] = (sw2 / (sw * sw)) as f32;
                } else {
                    out[x * channels..(x + 1) * channels].copy_from_slice(&values[i * channels..(i + 1) * channels]);
                }
            }
            (out, red)
        })
        .collect();
    let mut out = Vec::with_capacity(n * channels);
    let mut red = Vec::with_capacity(n);
    for (o, r) in rows {
        out.extend(o);
        red.extend(r);
    }
    (out, red)
}

/// Kernel radii from per-pixel noise: the smallest `R ≤ max_radius` with
/// `sigma / (2R + 1) ≤ target`, then the maximum over each pixel's 3×3 neighbourhood (a
/// pixel whose few samples happened to agree still gets its noisy neighbours' radius).
pub fn noise_radius(width: usize, height: usize, sigma: &[f32], target: f32, max_radius: u32) -> Vec<u32> {
    let base: Vec<u32> = sigma
        .iter()
        .map(|&s| {
            if !(s > 0.0) || !(target > 0.0) {
                return 0;
            }
            let r = ((s / target - 1.0) * 0.5).ceil();
            if r.is_finite() {
                (r.max(0.0) as u32).min(max_radius)
            } else {
                max_radius
            }
        })
        .collect();
    if base.len() != width * height {
        return base;
    }
    let mut out = base.clone();
    for y in 0..height {
        for x in 0..width {
            let mut m = 0;
            for qy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for qx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    m = m.max(base[qy * width + qx]);
                }
            }
            out[y * width + x] = m;
        }
    }
    out
}

/// The shadow ratio `s / u` of one channel with the module's guard (see the module docs):
/// `d_s / d_u` (denoised) if `d_u` is positive and finite, else the raw ratio if `u > 0`,
/// else 1; clamped to `[0, 1]`.
pub fn guarded_ratio(d_s: f32, d_u: f32, s: f32, u: f32) -> f32 {
    let r = if d_u > 0.0 && d_u.is_finite() && d_s.is_finite() {
        d_s / d_u
    } else if u > 0.0 && u.is_finite() && s.is_finite() {
        s / u
    } else {
        1.0
    };
    if r.is_nan() {
        1.0
    } else {
        r.clamp(0.0, 1.0)
    }
}

pub struct RatioIntegrator {
    /// The analytic part (`shadows` is false).
    pub ltc: LtcIntegrator,
    pub nsamples: u32,
    pub denoise: bool,
    pub max_radius: u32,
    pub noise_target: f32,
    pub filter: FilterParams,
}

impl RatioIntegrator {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let nsamples = params.get_one_int("nsamples", 4);
        if !(1..=1024).contains(&nsamples) {
            return Err(Diagnostic::error(
                params.loc_of("nsamples").cloned(),
                format!("ratio: \"nsamples\" must be in 1..=1024, got {nsamples}"),
            ));
        }
        let max_radius = params.get_one_int("maxradius", 8);
        if !(0..=64).contains(&max_radius) {
            return Err(Diagnostic::error(
                params.loc_of("maxradius").cloned(),
                format!("ratio: \"maxradius\" must be in 0..=64, got {max_radius}"),
            ));
        }
        let d = FilterParams::default();
        let positive = |name: &str, default: f32| -> Result<f32, Diagnostic> {
            let v = params.get_one_float(name, default);
            if v > 0.0 && v.is_finite() {
                Ok(v)
            } else {
                Err(Diagnostic::error(
                    params.loc_of(name).cloned(),
                    format!("ratio: \"{name}\" must be positive and finite, got {v}"),
                ))
            }
        };
        let noise_target = positive("noisetarget", 0.05)?;
        let filter = FilterParams {
            sigma_depth: positive("sigmadepth", d.sigma_depth)?,
            normal_exponent: positive("normalexponent", d.normal_exponent)?,
            sigma_plane: positive("sigmaplane", d.sigma_plane)?,
            sigma_u: positive("sigmau", d.sigma_u)?,
            ratio_k: {
                let v = params.get_one_float("ratiok", d.ratio_k);
                if v >= 0.0 && v.is_finite() {
                    v
                } else {
                    return Err(Diagnostic::error(
                        params.loc_of("ratiok").cloned(),
                        format!("ratio: \"ratiok\" must be non-negative and finite, got {v}"),
                    ));
                }
            },
            ratio_floor: positive("ratiofloor", d.ratio_floor)?,
        };
        let fresnel = match params.get_one_string("fresnel", "average").as_str() {
            "schlick" => FresnelMode::Schlick,
            "average" => FresnelMode::Average,
            other => {
                warnings.warn(
                    params.loc_of("fresnel").cloned(),
                    format!("ratio: unknown fresnel \"{other}\" (expected average or schlick): using \"average\""),
                );
                FresnelMode::Average
            }
        };
        Ok(Box::new(RatioIntegrator {
            ltc: LtcIntegrator {
                mode: Mode::Auto, // shadows off: only the lights' shapes (one polygon where possible)
                shadows: false,
                fresnel,
                pixel_shading: parse_shading("ratio", params, warnings),
                merge_occluders: true,
                coverage_samples: 1, // ratio's camera samples are its stochastic budget
            },
            nsamples: nsamples as u32,
            denoise: params.get_one_bool("denoise", true),
            max_radius: max_radius as u32,
            noise_target,
            filter,
        }))
    }
}

/// Extra film channels, in this order.
pub const CHANNELS: [&str; 17] = [
    "U.R",
    "U.G",
    "U.B",
    "S.R",
    "S.G",
    "S.B",
    "UN.R",
    "UN.G",
    "UN.B",
    "moment.SS",
    "moment.UU",
    "moment.SU",
    "depth",
    "N.X",
    "N.Y",
    "N.Z",
    "plane",
];
const C_U: usize = 0;
const C_S: usize = 3;
const C_UN: usize = 6;
const C_SS: usize = 9;
const C_UU: usize = 10;
const C_SU: usize = 11;
const C_DEPTH: usize = 12;
const C_N: usize = 13;
const C_PLANE: usize = 16;

/// A bounding sphere of an area light's triangles, for quick rejection of BRDF samples.
struct LightBound {
    c: DVec3,
    r: f64,
}

/// One area light as `ratio` samples it: an emitting mesh's triangles gathered (pbrt-v3 makes
/// one light per triangle of a `trianglemesh`), a triangle chosen in proportion to its area
/// and a point uniformly on it, so that each sample costs one shadow ray whatever the
/// number of triangles.
struct SampleGroup {
    /// A `Light::Area` over all the group's triangles (with their area distribution).
    light: Light,
    bound: LightBound,
}

impl SampleGroup {
    /// The groups of `shader`'s area lights (those with a positive area), bounded by the
    /// groups' spheres.
    fn of(shader: &LtcShader, scene: &Scene) -> Vec<SampleGroup> {
        shader
            .light_groups()
            .iter()
            .filter_map(|g| {
                let mesh = scene.meshes.get(g.mesh)?;
                let light = DiffuseAreaLight::over_triangles(
                    g.mesh as u32,
                    mesh,
                    &mut g.tris.iter().copied(),
                    g.l,
                    g.two_sided,
                    1,
                )?;
                Some(SampleGroup {
                    light: Light::Area(light),
                    bound: LightBound { c: g.center, r: g.radius * (1.0 + 1e-6) + 1e-9 },
                })
            })
            .collect()
    }
}

struct Estimator<'a> {
    shader: LtcShader<'a>,
    n: u32,
    groups: Vec<SampleGroup>,
    pixel_shading: bool,
    fallback: FallbackWarning<'a>,
}

fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

/// Ray–triangle intersection (Möller–Trumbore, both sides): the distance along unit `d`.
fn hit_triangle(o: DVec3, d: DVec3, pv: [DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (pv[1] - pv[0], pv[2] - pv[0]);
    let pvec = d.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - pv[0];
    let u = s.dot(pvec) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv;
    let scale = pv.iter().map(|p| p.abs().max_element()).fold(o.abs().max_element(), f64::max);
    (t > 1e-7 * scale.max(1e-30) && t.is_finite()).then_some(t)
}

/// One Monte Carlo sample's point on the light, with what the two estimates need.
struct LightPoint {
    p: Vec3,
    p_error: Vec3,
    n: Vec3,
}

impl Estimator<'_> {
    /// `(S_N, U_N)` for the area light `group` at `si`, from the 2D samples `us`.
    #[allow(clippy::too_many_arguments)]
    fn stochastic(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        desc: &LtcDescription,
        group: &SampleGroup,
        us: &[Vec2],
        per_sample: &mut [(f32, f32)],
        stats: &mut ThreadStats,
    ) -> (Rgb, Rgb) {
        let light = &group.light;
        let (mut s, mut u) = (Rgb::ZERO, Rgb::ZERO);
        let Some(geom) = light.area() else { return (s, u) };
        let Some(mesh) = scene.meshes.get(geom.mesh as usize) else { return (s, u) };
        let n0 = desc.n.normalize_or_zero();
        let n = if n0.dot(si.wo) < 0.0 { -n0 } else { n0 };
        let frame = Frame::toward(d3(n), d3(si.wo));
        let cos_o = frame.to_local(d3(si.wo)).z.clamp(0.0, 1.0) as f32;
        let spec = desc.specular.map(|sp| (sp, Ltc::lookup(cos_o, sp.alpha)));
        let w_d = luminance(desc.diffuse).max(0.0) as f64;
        let w_s = spec
            .map(|(sp, c)| luminance(sp.scale * fresnel_at(&sp.fresnel, cos_o) * c.magnitude).max(0.0) as f64)
            .unwrap_or(0.0);
        let w_sum = w_d + w_s;
        let (w_d, w_s) =
            if w_sum > 0.0 && w_sum.is_finite() && n != Vec3::ZERO { (w_d / w_sum, w_s / w_sum) } else { (0.0, 0.0) };
        let total = us.len();
        let n_b = if w_d + w_s > 0.0 { total / 2 } else { 0 };
        let n_l = total - n_b;
        let pdf_brdf = |w: Vec3| -> f64 {
            if n_b == 0 {
                return 0.0;
            }
            let l = frame.to_local(d3(w));
            let mut p = w_d * l.z.max(0.0) * std::f64::consts::FRAC_1_PI;
            if let Some((_, c)) = &spec {
                p += w_s * c.pdf(l);
            }
            if p.is_finite() {
                p
            } else {
                0.0
            }
        };
        let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
        let mut add = |k: usize, c: Rgb, lp: &LightPoint, stats: &mut ThreadStats| {
            if !(c.is_finite() && c.min_element() >= 0.0) || c == Rgb::ZERO {
                return;
            }
            u += c;
            let y = luminance(c);
            stats.shadow_rays += 1;
            let visible = !scene.occluded(&si.spawn_ray_to_surface(lp.p, lp.p_error, lp.n));
            if visible {
                s += c;
            }
            if let Some(ps) = per_sample.get_mut(k) {
                ps.0 += if visible { y } else { 0.0 };
                ps.1 += y;
            }
        };
        for (k, uv) in us[..n_l].iter().enumerate() {
            let Some(ls) = light.sample_li(&ctx, *uv, &scene.meshes) else { continue };
            if !(ls.pdf > 0.0) || ls.li == Rgb::ZERO {
                continue;
            }
            let f = bsdf.f(si.wo, ls.wi, BxdfFlags::NON_SPECULAR) * ls.wi.dot(si.shading.z).abs();
            if f == Rgb::ZERO {
                continue;
            }
            let denom = n_l as f64 * ls.pdf as f64 + n_b as f64 * pdf_brdf(ls.wi);
            let c = f * ls.li * (1.0 / denom) as f32;
            add(k, c, &LightPoint { p: ls.p_light, p_error: ls.p_light_error, n: ls.n_light }, stats);
        }
        if n_b == 0 {
            return (s, u);
        }
        let o = d3(si.p);
        for (j, uv) in us[n_l..].iter().enumerate() {
            let k = n_l + j;
            let (x, y) = (uv.x as f64, uv.y as f64);
            let local = if x < w_d || spec.is_none() {
                let x = (x / w_d.max(1e-300)).min(1.0 - f64::EPSILON / 2.0);
                penumbra_core::ltc::cosine_sample(DVec2::new(x, y))
            } else {
                let x = ((x - w_d) / w_s.max(1e-300)).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
                spec.as_ref().map(|(_, c)| c.sample(DVec2::new(x, y))).unwrap_or(DVec3::ZERO)
            };
            let wd = frame.from_local(local).normalize_or_zero();
            if wd == DVec3::ZERO {
                continue;
            }
            let w = wd.as_vec3();
            let p_b = pdf_brdf(w);
            if !(p_b > 0.0) {
                continue;
            }
            let f = bsdf.f(si.wo, w, BxdfFlags::NON_SPECULAR) * w.dot(si.shading.z).abs();
            if f == Rgb::ZERO {
                continue;
            }
            // Distance from the bounding sphere's centre to the ray (half-line from o along wd).
            let b = &group.bound;
            let oc = b.c - o;
            let t = oc.dot(wd);
            let dist2 = (oc - wd * t).length_squared();
            if dist2 > b.r * b.r || (t < 0.0 && oc.length_squared() > b.r * b.r) {
                continue;
            }
            for &tri in &geom.tris {
                let tri = tri as usize;
                if tri >= mesh.triangle_count() {
                    continue;
                }
                let pv = mesh.vertices(tri).map(d3);
                let Some(t) = hit_triangle(o, wd, pv) else { continue };
                let ne = emitting_normal(mesh, tri);
                let le = light.l(ne, -w);
                if le == Rgb::ZERO {
                    continue;
                }
                let xp = o + wd * t;
                let cos_l = d3(ne).dot(wd).abs();
                let p_l = t * t / (cos_l * geom.area as f64);
                if !(p_l.is_finite() && p_l > 0.0) {
                    continue;
                }
                let denom = n_l as f64 * p_l + n_b as f64 * p_b;
                let c = f * le * (1.0 / denom) as f32;
                let err = Vec3::splat(gamma(6)) * (pv[0].abs() + pv[1].abs() + pv[2].abs()).as_vec3();
                add(k, c, &LightPoint { p: xp.as_vec3(), p_error: err, n: ne }, stats);
            }
        }
        (s, u)
    }
}

impl Estimator<'_> {
    /// Radiance (everything but the area lights' shaded part) from the first surface `hit`
    /// of `ray`, writing `U`, `S_N`, `U_N` and the guides to `aov`; `area` is the analytic
    /// unshadowed area lighting (form factor, glossy) when already computed for the pixel.
    #[allow(clippy::too_many_arguments)]
    fn shade(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        area: Option<(Rgb, Rgb)>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        aov: &mut [f32],
    ) -> Rgb {
        let SurfaceHit { si, bsdf, le, .. } = hit;
        let mut rest = *le;
        let desc = LtcShader::lobes(scene, si);
        let nf = if si.n.dot(si.wo) < 0.0 { -si.n } else { si.n };
        let (mut u, mut s, mut un) = (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO);
        let mut us = Vec::new();
        // Per stochastic sample index, its luminance contributions (shadowed, unshadowed) summed
        // over the lights: the noise estimate.
        let mut per_sample = vec![(0.0f32, 0.0f32); self.n as usize];
        if let Some(d) = &desc {
            u = match area {
                Some((diffuse, specular)) => d.diffuse * diffuse + specular,
                None => self.shader.area_lights(scene, si, d, false, &mut Vec::new()),
            };
        }
        for g in &self.groups {
            // Always drawn, so that every light gets its own array whatever the material.
            us.clear();
            match sampler.get_2d_array(self.n) {
                Some(a) => us.extend_from_slice(a),
                None => us.extend((0..self.n).map(|_| sampler.get_2d())),
            }
            if let Some(d) = &desc {
                let (sk, uk) = self.stochastic(scene, si, bsdf, d, g, &us, &mut per_sample, stats);
                s += sk;
                un += uk;
            }
        }
        add_other_lights(&mut rest, hit, desc.is_some(), scene, sampler, stats, &self.fallback);
        if aov.len() == CHANNELS.len() {
            let finite = |c: Rgb| if c.is_finite() { c.max(Rgb::ZERO) } else { Rgb::ZERO };
            let (u, s, un) = (finite(u), finite(s), finite(un));
            aov[C_U..C_U + 3].copy_from_slice(&u.to_array());
            aov[C_S..C_S + 3].copy_from_slice(&s.to_array());
            aov[C_UN..C_UN + 3].copy_from_slice(&un.to_array());
            // Moments of the single-sample estimates n·(contribution of sample k).
            let n = per_sample.len().max(1) as f32;
            let (mut ss, mut uu, mut su) = (0.0f32, 0.0f32, 0.0f32);
            for &(ys, yu) in &per_sample {
                let (ys, yu) = (n * ys, n * yu);
                ss += ys * ys;
                uu += yu * yu;
                su += ys * yu;
            }
            let finite1 = |v: f32| if v.is_finite() { v } else { 0.0 };
            aov[C_SS] = finite1(ss / n);
            aov[C_UU] = finite1(uu / n);
            aov[C_SU] = finite1(su / n);
            aov[C_DEPTH] = (si.p - ray.o).length();
            aov[C_N..C_N + 3].copy_from_slice(&nf.to_array());
            aov[C_PLANE] = nf.dot(si.p);
        }
        rest
    }
}

impl PixelEstimator for Estimator<'_> {
    fn request_samples(&self, sampler: &mut dyn Sampler) {
        for _ in &self.groups {
            sampler.request_2d_array(self.n);
        }
    }

    fn li(&self, ray: &Ray, scene: &Scene, sampler: &mut dyn Sampler, stats: &mut ThreadStats, aov: &mut [f32]) -> Rgb {
        let (first, queries) = scene.first_surface(ray);
        stats.rays += queries;
        match first {
            Ok(h) => self.shade(ray, &h, None, scene, sampler, stats, aov),
            Err(escaped) => escaped,
        }
    }

    fn shares_pixel_work(&self) -> bool {
        self.pixel_shading
    }

    /// `U` once per surface seen in the pixel (as `ltc`'s pixel shading, unshadowed); the
    /// stochastic `S_N`, `U_N` stay per camera sample.
    fn begin_pixel(&self, rays: &[Ray], scene: &Scene, stats: &mut ThreadStats) -> Option<PixelShared> {
        Some(Box::new(self.shader.trace_pixel(rays, scene, false, stats)))
    }

    fn li_shared(
        &self,
        ray: &Ray,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        aov: &mut [f32],
        shared: &PixelShared,
        index: usize,
    ) -> Rgb {
        match SharedPixel::<AreaLighting>::sample(shared, index) {
            Some((Ok(pt), area)) => match pt.with_bsdf(scene) {
                Some(h) => self.shade(ray, &h, area, scene, sampler, stats, aov),
                None => Rgb::ZERO, // (first_point returns only surfaces with a material)
            },
            Some((Err(escaped), _)) => *escaped,
            None => self.li(ray, scene, sampler, stats, aov),
        }
    }
}

impl Integrator for RatioIntegrator {
    fn name(&self) -> &str {
        "ratio"
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    fn extra_channels(&self) -> Vec<String> {
        CHANNELS.iter().map(|c| format!("ratio.{c}")).collect()
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        warn_infinite_lights("ratio", scene, ctx.warnings);
        let shader = LtcShader::new(&self.ltc, scene);
        let groups = SampleGroup::of(&shader, scene);
        let est = Estimator {
            shader,
            n: scene.sampler.round_count(self.nsamples).max(1),
            groups,
            pixel_shading: self.ltc.pixel_shading,
            fallback: FallbackWarning::new("ratio", ctx.warnings),
        };
        let mut stats = render_pixels(&est, scene, ctx, film)?;
        let t = std::time::Instant::now();
        let filtered = self.resolve(film, est.n);
        stats.counters.insert("denoise_seconds".into(), t.elapsed().as_secs_f64());
        stats.counters.insert("mean_radius".into(), filtered);
        stats.render_seconds += t.elapsed().as_secs_f64();
        Ok(stats)
    }
}

impl RatioIntegrator {
    /// The whole-image pass: reads the channels back, denoises, writes `rest + U·ratio`.
    /// Returns the mean kernel radius over pixels with area-light shading.
    fn resolve(&self, film: &mut Film, n_stochastic: u32) -> f64 {
        let pb = film.pixel_bounds();
        let (w, h) = (pb.width().max(0) as usize, pb.height().max(0) as usize);
        let n = w * h;
        let nc = CHANNELS.len();
        if film.extra_channel_names.len() != nc {
            return 0.0;
        }
        let mut rest = vec![Rgb::ZERO; n];
        let mut rest_var = vec![[0.0f64; 3]; n];
        let mut ch = vec![0.0f32; n * nc];
        let mut count = vec![0.0f64; n];
        for (i, p) in pb.iter().enumerate() {
            let (Some(ps), Some(ex)) = (film.pixel_sums(p), film.pixel_extra(p)) else { continue };
            if !(ps.weight != 0.0) {
                continue;
            }
            let inv = 1.0 / ps.weight;
            rest[i] = Rgb::new((ps.rgb[0] * inv) as f32, (ps.rgb[1] * inv) as f32, (ps.rgb[2] * inv) as f32);
            let m = ps.own_count as f64;
            count[i] = m;
            if m > 1.0 {
                for (c, v) in rest_var[i].iter_mut().enumerate() {
                    let mean = ps.own_sum[c] / m;
                    *v = ((ps.own_sum_sq[c] / m - mean * mean).max(0.0) * m / (m - 1.0)) / m;
                }
            }
            for (e, v) in ex.iter().enumerate() {
                ch[i * nc + e] = (v * inv) as f32;
            }
        }
        let at = |i: usize, c: usize| ch[i * nc + c];
        let rgb_at = |i: usize, c: usize| Rgb::new(at(i, c), at(i, c + 1), at(i, c + 2));
        // Delta-method standard deviation of each pixel's ratio estimate (luminance).
        let sigma: Vec<f32> = (0..n)
            .map(|i| {
                let s = luminance(rgb_at(i, C_S)) as f64;
                let u = luminance(rgb_at(i, C_UN)) as f64;
                if !(u > 0.0) || count[i] < 1.0 {
                    return 0.0;
                }
                let r = s / u;
                let var_s = at(i, C_SS) as f64 - s * s;
                let var_u = at(i, C_UU) as f64 - u * u;
                let cov = at(i, C_SU) as f64 - s * u;
                // Over the pixel's camera samples × stochastic samples.
                let count = count[i] * n_stochastic as f64;
                let v = (var_s - 2.0 * r * cov + r * r * var_u).max(0.0) / (count.max(2.0) - 1.0) / (u * u);
                let sd = v.sqrt() as f32;
                if sd.is_finite() {
                    sd
                } else {
                    0.0
                }
            })
            .collect();
        let guides: Vec<Guide> = (0..n)
            .map(|i| Guide {
                depth: at(i, C_DEPTH),
                normal: Vec3::new(at(i, C_N), at(i, C_N + 1), at(i, C_N + 2)),
                plane: at(i, C_PLANE),
                u: luminance(rgb_at(i, C_U)),
                ratio: {
                    let s = luminance(rgb_at(i, C_S));
                    let u = luminance(rgb_at(i, C_UN));
                    guarded_ratio(f32::NAN, 0.0, s, u)
                },
                ratio_sigma: sigma[i],
            })
            .collect();
        let mut su = vec![0.0f32; n * 6];
        for i in 0..n {
            su[i * 6..i * 6 + 3].copy_from_slice(&ch[i * nc + C_S..i * nc + C_S + 3]);
            su[i * 6 + 3..i * 6 + 6].copy_from_slice(&ch[i * nc + C_UN..i * nc + C_UN + 3]);
        }
        let radius =
            if self.denoise { noise_radius(w, h, &sigma, self.noise_target, self.max_radius) } else { vec![0; n] };
        let (d, reduction) = cross_bilateral(w, h, &guides, &radius, &su, 6, &self.filter);
        let (mut rsum, mut rcount) = (0.0f64, 0usize);
        for (i, p) in pb.iter().enumerate() {
            let u = rgb_at(i, C_U);
            let mut out = rest[i];
            let mut var = rest_var[i];
            if u != Rgb::ZERO {
                rsum += radius[i] as f64;
                rcount += 1;
                for c in 0..3 {
                    let ratio = guarded_ratio(d[i * 6 + c], d[i * 6 + 3 + c], at(i, C_S + c), at(i, C_UN + c));
                    out[c] += u[c] * ratio;
                    let sr = sigma[i] as f64 * u[c] as f64;
                    var[c] += sr * sr * reduction[i] as f64;
                }
            }
            if !out.is_finite() {
                out = if rest[i].is_finite() { rest[i] } else { Rgb::ZERO };
            }
            film.set_pixel_rgb(p, out.max(Rgb::ZERO), var);
        }
        if rcount > 0 {
            rsum / rcount as f64
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::rng::Rng;

    fn plane_guides(w: usize, h: usize) -> Vec<Guide> {
        vec![Guide { depth: 5.0, normal: Vec3::Z, plane: 1.0, u: 1.0, ..Default::default() }; w * h]
    }

    #[test]
    fn constant_noisy_input_is_smoothed() {
        let (w, h) = (128, 128);
        let g = plane_guides(w, h);
        let mut rng = Rng::new(7);
        let vals: Vec<f32> = (0..w * h).map(|_| 0.5 + (rng.uniform_f32() - 0.5)).collect();
        let var = |v: &[f32]| {
            let m = v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64;
            v.iter().map(|x| (*x as f64 - m).powi(2)).sum::<f64>() / v.len() as f64
        };
        for r in [1u32, 2, 4] {
            let (out, red) = cross_bilateral(w, h, &g, &vec![r; w * h], &vals, 1, &FilterParams::default());
            // Interior pixels only (the borders see fewer neighbours).
            let b = r as usize;
            let inner = |v: &[f32]| -> Vec<f32> {
                (b..h - b).flat_map(|y| (b..w - b).map(move |x| y * w + x)).map(|i| v[i]).collect()
            };
            let (vi, vo) = (var(&inner(&vals)), var(&inner(&out)));
            let factor = vi / vo;
            let predicted = 1.0 / red[h / 2 * w + w / 2] as f64;
            eprintln!("radius {r}: variance reduction ×{factor:.2} (Σw²/(Σw)² predicts ×{predicted:.2})");
            // Independent noise: the measured reduction follows Σw²/(Σw)² within sampling error.
            assert!(factor > 0.7 * predicted && factor < 1.3 * predicted, "radius {r}: ×{factor} vs ×{predicted}");
            assert!(factor > 2.0, "radius {r}: too little smoothing (×{factor})");
            let m = inner(&out).iter().map(|x| *x as f64).sum::<f64>() / ((w - 2 * b) * (h - 2 * b)) as f64;
            assert!((m - 0.5).abs() < 0.01, "mean moved to {m}");
        }
    }

    #[test]
    fn depth_step_edge_is_preserved() {
        let (w, h) = (32, 16);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if x >= w / 2 {
                    g[i].depth = 10.0;
                    g[i].plane = 6.0;
                    vals[i] = 1.0;
                }
            }
        }
        let (out, _) = cross_bilateral(w, h, &g, &vec![6; w * h], &vals, 1, &FilterParams::default());
        for (i, (o, v)) in out.iter().zip(&vals).enumerate() {
            assert!((o - v).abs() < 1e-4, "pixel {i}: {o} vs {v} across the depth edge");
        }
        // Without the depth/plane guides the edge would blur: check the test can fail.
        let flat = plane_guides(w, h);
        let (blur, _) = cross_bilateral(w, h, &flat, &vec![6; w * h], &vals, 1, &FilterParams::default());
        assert!(blur[w / 2 - 1] > 0.1 && blur[w / 2] < 0.9);
    }

    #[test]
    fn normal_edge_is_preserved_and_shared_weights() {
        let (w, h) = (16, 16);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h * 2];
        for y in 0..h {
            for x in w / 2..w {
                g[y * w + x].normal = Vec3::X;
                vals[(y * w + x) * 2] = 1.0;
                vals[(y * w + x) * 2 + 1] = 2.0;
            }
        }
        let (out, _) = cross_bilateral(w, h, &g, &vec![4; w * h], &vals, 2, &FilterParams::default());
        for i in 0..w * h {
            assert!((out[i * 2] - vals[i * 2]).abs() < 1e-4);
            // Same weights for every channel: the second channel stays twice the first.
            assert!((out[i * 2 + 1] - 2.0 * out[i * 2]).abs() < 1e-5);
        }
    }

    /// The raw-ratio edge stop keeps a step the pixels' noise cannot explain (a contact shadow
    /// on one plane) and smooths one it can.
    #[test]
    fn ratio_edge_stop_follows_noise() {
        let (w, h) = (16, 8);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h];
        for y in 0..h {
            for x in w / 2..w {
                vals[y * w + x] = 1.0;
                g[y * w + x].ratio = 1.0;
            }
        }
        let p = FilterParams::default();
        let (sharp, _) = cross_bilateral(w, h, &g, &vec![4; w * h], &vals, 1, &p);
        assert!(sharp.iter().zip(&vals).all(|(a, b)| (a - b).abs() < 1e-4), "confident step blurred");
        g.iter_mut().for_each(|q| q.ratio_sigma = 1.0);
        let (soft, _) = cross_bilateral(w, h, &g, &vec![4; w * h], &vals, 1, &p);
        assert!(soft[w / 2 - 1] > 0.2 && soft[w / 2] < 0.8, "noisy step kept: {} {}", soft[w / 2 - 1], soft[w / 2]);
        let off = FilterParams { ratio_k: 0.0, ..p };
        g.iter_mut().for_each(|q| q.ratio_sigma = 0.0);
        let (blur, _) = cross_bilateral(w, h, &g, &vec![4; w * h], &vals, 1, &off);
        assert!(blur[w / 2 - 1] > 0.2, "ratio_k = 0 must disable the edge stop");
    }

    #[test]
    fn zero_un_never_gives_nan() {
        let (w, h) = (8, 8);
        let mut g = plane_guides(w, h);
        g[3].depth = 0.0;
        g[5].depth = f32::NAN;
        g[9].normal = Vec3::ZERO;
        g[10].u = 0.0;
        let vals = vec![0.0f32; w * h * 2];
        let (out, red) = cross_bilateral(w, h, &g, &vec![3; w * h], &vals, 2, &FilterParams::default());
        assert!(out.iter().chain(&red).all(|v| v.is_finite()));
        for i in 0..w * h {
            let r = guarded_ratio(out[2 * i], out[2 * i + 1], 0.0, 0.0);
            assert_eq!(r, 1.0, "unknown shadowing is taken as lit");
        }
        assert_eq!(guarded_ratio(0.0, 0.0, 0.0, 2.0), 0.0);
        assert_eq!(guarded_ratio(f32::NAN, 0.0, 1.0, 4.0), 0.25);
        assert_eq!(guarded_ratio(1.0, f32::INFINITY, f32::NAN, f32::NAN), 1.0);
        assert_eq!(guarded_ratio(3.0, 2.0, 0.0, 0.0), 1.0);
        assert_eq!(guarded_ratio(1.0, 4.0, 0.0, 0.0), 0.25);
    }

    #[test]
    fn noise_radius_follows_sigma() {
        let (w, h) = (5, 5);
        let mut s = vec![0.0f32; 25];
        s[12] = 0.1;
        // 0.1 / (2R + 1) ≤ 0.02 ⇒ R = 2; dilated over 3×3.
        let r = noise_radius(w, h, &s, 0.02, 8);
        for y in 0..5 {
            for x in 0..5 {
                let inside = (1..=3).contains(&x) && (1..=3).contains(&y);
                assert_eq!(r[y * 5 + x], if inside { 2 } else { 0 }, "({x}, {y})");
            }
        }
        assert_eq!(noise_radius(1, 1, &[f32::INFINITY], 0.02, 8), vec![8]);
        assert_eq!(noise_radius(1, 1, &[f32::NAN], 0.02, 8), vec![0]);
        assert_eq!(noise_radius(1, 1, &[10.0], 0.02, 3), vec![3]);
    }
}
