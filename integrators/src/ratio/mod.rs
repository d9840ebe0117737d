//! `ratio`: analytic direct illumination × denoised stochastic shadows (Heitz, Hill &
//! McGuire 2018, "Combining Analytic Direct Illumination and Stochastic Shadows"), the ratio
//! estimator of seed 004 (`../shared/seeds/004_*`), built on the analytic shading `ltc` uses ([`crate::common::ltc_shading`]).
//!
//! For every area light and every point whose material has an LTC form, three terms:
//!
//! * `U`: the analytic unshadowed radiance, the LTC shading with `shadows = false`;
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
//! `n·p`, and the camera samples' spread (`spread.UU`: `U²`, `spread.RU`: `rest·U`, RGB), from
//! which the variance written for a pixel gets what its camera samples' different `U` add (a
//! pixel over a silhouette, a texture or an opacity edge). After the pass the
//! image is `rest + U · D(S_N) / D(U_N)` per channel, where `rest` is everything else
//! (emission seen directly, delta lights with one shadow ray, infinite lights and
//! materials without LTC form through `directlighting`'s estimator, as in `ltc`) and `D`
//! is [`denoise::cross_bilateral`] with the same weights for both. The kernel radius per pixel
//! comes from the delta-method standard deviation `σ_r` of the pixel's ratio estimate:
//! the smallest `R ≤ maxradius` with `σ_r / (2R + 1) ≤ noisetarget`, dilated by one pixel.
//!
//! Guard: `S_N ≤ U_N` sample by sample, so with non-negative weights the ratio is in
//! `[0, 1]`; it is clamped there. Where `D(U_N)` is zero or not positive-finite, the raw
//! `S_N / U_N` is used if `U_N > 0`, and otherwise the shadowing is unknown (no sample
//! reached the light) and the ratio is taken as 1 (the analytic `U` unchanged). The
//! output is never NaN or infinite.
//!
//! Specular chains: perfectly specular lobes (mirror, smooth glass, uber's `Kr`/`Kt`/opacity)
//! are followed as `directlighting` follows them, up to `"integer maxdepth"` (5), and every
//! surface a chain reaches gets the same three terms, weighted by the chain's throughput β
//! (the product of `f·|cos θ|/pdf` along it). Their sums per camera sample go to channels of
//! their own (`chain.U`, `chain.S`, `chain.UN`), and everything else the reached surfaces
//! receive (emission, delta and infinite lights, materials without an LTC form) to `rest`.
//! Only the first surfaces' ratio is denoised: the guides (depth, normal, plane) describe the
//! first surface, and across a mirror they would blur what it reflects. The chains' term is
//! `chain.U · chain.S / chain.UN` from the pixel's own means (the ratio estimator over the
//! pixel's camera × stochastic samples, guarded as above, not filtered), so a pixel is
//! `rest + U · D(S_N)/D(U_N) + chain.U · chain.S/chain.UN`; where the chains' surfaces are
//! fully lit the term is the analytic `chain.U` exactly. The variance written for a pixel does
//! not include the chains' term.
//!
//! Files: `estimator.rs` (the per-pixel estimator writing [`RatioSample`]s), `denoise.rs` (the
//! denoiser: a plain function over [`ImageBuffer`]s), this file (parameters, channels and the
//! whole-image pass).

pub mod denoise;
mod estimator;

pub use denoise::{cross_bilateral, guarded_ratio, noise_radius, FilterParams, Guide};

use crate::common::image_pass::ImageBuffer;
use crate::common::ltc_shading::{FresnelMode, Glossy, LtcShader, Mode, ShaderSettings};
use crate::common::other_lights::{warn_infinite_lights, FallbackWarning};
use crate::common::params::{ParamSpec, Params, Range};
use crate::common::pixel_shading::{parse_shading, SHADING};
use crate::common::{max_depth, max_depth_param};
use estimator::{Estimator, SampleGroup};
use penumbra_core::film::Film;
use penumbra_core::integrator::{render_pixels_with_margin, Integrator, RenderContext, RenderError, RenderStats};
use penumbra_core::scene::{Requirements, Scene};
use penumbra_core::spectrum::luminance;
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

pub struct RatioIntegrator {
    /// The analytic part's settings (`shadows` is false).
    pub shading: ShaderSettings,
    /// `"string shading" "pixel"`: `U` once per surface a pixel sees (as `ltc`'s).
    pub pixel_shading: bool,
    /// pbrt-v3's `"integer maxdepth"`: the surfaces a camera ray's specular chain may meet.
    pub max_depth: u32,
    pub nsamples: u32,
    pub denoise: bool,
    pub max_radius: u32,
    pub noise_target: f32,
    pub filter: FilterParams,
}

const D: FilterParams = FilterParams::DEFAULT;

/// The parameters `ratio` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::int(
        "nsamples",
        4,
        "stochastic samples per camera sample and light mesh (half light, half BRDF sampling)",
    )
    .range(1, 1024),
    ParamSpec::bool("denoise", true, "false: the raw ratio S_N/U_N, not filtered"),
    ParamSpec::int("maxradius", 8, "largest cross-bilateral kernel radius, pixels").range(0, 64),
    ParamSpec::float("noisetarget", 0.05, "the kernel grows until the ratio's estimated noise is below this")
        .within(Range::PositiveFinite),
    ParamSpec::float("sigmadepth", D.sigma_depth, "depth guide: depth tolerance relative to the pixel's depth")
        .within(Range::PositiveFinite),
    ParamSpec::float("normalexponent", D.normal_exponent, "normal guide: weight max(0, n_p·n_q)^e")
        .within(Range::PositiveFinite),
    ParamSpec::float("sigmaplane", D.sigma_plane, "plane guide: plane-offset tolerance relative to depth")
        .within(Range::PositiveFinite),
    ParamSpec::float("sigmau", D.sigma_u, "guide on the analytic U (luminance): relative tolerance")
        .within(Range::PositiveFinite),
    ParamSpec::float("ratiok", D.ratio_k, "edge stop on the raw ratio, in units of the pixels' own noise (0: off)")
        .within(Range::NonNegativeFinite),
    ParamSpec::float("ratiofloor", D.ratio_floor, "added to the ratio edge stop's noise scale")
        .within(Range::PositiveFinite),
    Glossy::PARAM,
    FresnelMode::PARAM,
    SHADING,
    max_depth(1024),
];

impl RatioIntegrator {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("ratio", PARAMS, params, warnings);
        let nsamples = p.count("nsamples")?;
        let max_radius = p.count("maxradius")?;
        let noise_target = p.float("noisetarget")?;
        let filter = FilterParams {
            sigma_depth: p.float("sigmadepth")?,
            normal_exponent: p.float("normalexponent")?,
            sigma_plane: p.float("sigmaplane")?,
            sigma_u: p.float("sigmau")?,
            ratio_k: p.float("ratiok")?,
            ratio_floor: p.float("ratiofloor")?,
        };
        Ok(Box::new(RatioIntegrator {
            shading: ShaderSettings {
                mode: Mode::Auto, // shadows off: only the lights' shapes (one polygon where possible)
                shadows: false,
                glossy: Glossy::from_params(&p)?,
                fresnel: FresnelMode::from_params(&p)?,
                merge_occluders: true,
            },
            pixel_shading: parse_shading(&p)?,
            max_depth: max_depth_param(&p)?,
            nsamples,
            denoise: p.bool("denoise")?,
            max_radius,
            noise_target,
            filter,
        }))
    }
}

/// Extra film channels, in this order.
pub const CHANNELS: [&str; 32] = [
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
    "chain.U.R",
    "chain.U.G",
    "chain.U.B",
    "chain.S.R",
    "chain.S.G",
    "chain.S.B",
    "chain.UN.R",
    "chain.UN.G",
    "chain.UN.B",
    "spread.UU.R",
    "spread.UU.G",
    "spread.UU.B",
    "spread.RU.R",
    "spread.RU.G",
    "spread.RU.B",
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
const C_CHAIN_U: usize = 17;
const C_CHAIN_S: usize = 20;
const C_CHAIN_UN: usize = 23;
const C_SPREAD_UU: usize = 26;
const C_SPREAD_RU: usize = 29;

/// What one camera sample writes to the extra channels (the film averages them per pixel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct RatioSample {
    /// The analytic unshadowed radiance.
    pub(crate) u: Rgb,
    /// The stochastic shadowed and unshadowed estimates.
    pub(crate) s: Rgb,
    pub(crate) un: Rgb,
    /// Luminance moments `⟨S²⟩`, `⟨U²⟩`, `⟨S·U⟩` of the single-sample estimates.
    pub(crate) ss: f32,
    pub(crate) uu: f32,
    pub(crate) su: f32,
    /// Guides: depth along the ray, normal facing the viewer, plane offset `n·p`.
    pub(crate) depth: f32,
    pub(crate) n: Vec3,
    pub(crate) plane: f32,
    /// The specular chains' `U`, `S_N`, `U_N`, weighted by their throughput.
    pub(crate) chain: ChainTerms,
    /// The camera-sample spread of the pixel: `U²` and `rest · U` per channel (their pixel
    /// means with `U`'s and `rest`'s give the variance of `rest + U·ratio` over the pixel's
    /// camera samples).
    pub(crate) spread_uu: Rgb,
    pub(crate) spread_ru: Rgb,
}

/// `U`, `S_N` and `U_N` of the surfaces a camera sample's specular chains reach, each weighted
/// by its chain's throughput, summed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ChainTerms {
    pub(crate) u: Rgb,
    pub(crate) s: Rgb,
    pub(crate) un: Rgb,
}

impl RatioSample {
    /// Into `aov` in [`CHANNELS`] order (nothing when it has another length).
    pub(crate) fn write(&self, aov: &mut [f32]) {
        if aov.len() != CHANNELS.len() {
            return;
        }
        aov[C_U..C_U + 3].copy_from_slice(&self.u.to_array());
        aov[C_S..C_S + 3].copy_from_slice(&self.s.to_array());
        aov[C_UN..C_UN + 3].copy_from_slice(&self.un.to_array());
        aov[C_SS] = self.ss;
        aov[C_UU] = self.uu;
        aov[C_SU] = self.su;
        aov[C_DEPTH] = self.depth;
        aov[C_N..C_N + 3].copy_from_slice(&self.n.to_array());
        aov[C_PLANE] = self.plane;
        aov[C_CHAIN_U..C_CHAIN_U + 3].copy_from_slice(&self.chain.u.to_array());
        aov[C_CHAIN_S..C_CHAIN_S + 3].copy_from_slice(&self.chain.s.to_array());
        aov[C_CHAIN_UN..C_CHAIN_UN + 3].copy_from_slice(&self.chain.un.to_array());
        aov[C_SPREAD_UU..C_SPREAD_UU + 3].copy_from_slice(&self.spread_uu.to_array());
        aov[C_SPREAD_RU..C_SPREAD_RU + 3].copy_from_slice(&self.spread_ru.to_array());
    }

    /// Sets the spread terms for this camera sample's `rest`.
    pub(crate) fn with_spread(self, rest: Rgb) -> RatioSample {
        let finite = |c: Rgb| if c.is_finite() { c } else { Rgb::ZERO };
        RatioSample { spread_uu: finite(self.u * self.u), spread_ru: finite(rest * self.u), ..self }
    }

    /// Scales a sample's channels (as [`write`](Self::write) left them) by its camera ray's
    /// weight `w`: the estimates `U`, `S_N`, `U_N` and the chains' by `w`, their second
    /// moments and the camera-sample spread by `w²` (so that they stay the moments of the
    /// weighted estimates); the guides (depth, normal, plane) unchanged. The film's RGB (`rest`) is weighted by the driver, so
    /// the resolved `rest + U·ratio` is the weighted radiance pbrt-v3's film accumulates.
    pub(crate) fn weight(aov: &mut [f32], w: f32) {
        if aov.len() != CHANNELS.len() {
            return;
        }
        for c in [C_U, C_S, C_UN, C_CHAIN_U, C_CHAIN_S, C_CHAIN_UN] {
            aov[c..c + 3].iter_mut().for_each(|v| *v *= w);
        }
        for c in [C_SS, C_UU, C_SU] {
            aov[c] *= w * w;
        }
        // The camera-sample spread: `U²` and `rest · U`, each a product of two weighted terms.
        for c in [C_SPREAD_UU, C_SPREAD_RU] {
            aov[c..c + 3].iter_mut().for_each(|v| *v *= w * w);
        }
    }

    /// From [`CHANNELS`]-ordered values.
    fn read(ch: &[f32]) -> RatioSample {
        let rgb = |c: usize| Rgb::new(ch[c], ch[c + 1], ch[c + 2]);
        RatioSample {
            u: rgb(C_U),
            s: rgb(C_S),
            un: rgb(C_UN),
            ss: ch[C_SS],
            uu: ch[C_UU],
            su: ch[C_SU],
            depth: ch[C_DEPTH],
            n: Vec3::new(ch[C_N], ch[C_N + 1], ch[C_N + 2]),
            plane: ch[C_PLANE],
            chain: ChainTerms { u: rgb(C_CHAIN_U), s: rgb(C_CHAIN_S), un: rgb(C_CHAIN_UN) },
            spread_uu: rgb(C_SPREAD_UU),
            spread_ru: rgb(C_SPREAD_RU),
        }
    }
}

/// One pixel of the film after the render pass: the mean of everything but the area lights'
/// shaded part (`rest`) with the variance of that mean, its own sample count, and the mean of
/// its [`RatioSample`]s.
#[derive(Clone, Copy, Debug, Default)]
struct FilmPixel {
    rest: Rgb,
    rest_var: [f64; 3],
    count: f64,
    mean: RatioSample,
}

impl Integrator for RatioIntegrator {
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    fn extra_channels(&self) -> Vec<String> {
        CHANNELS.iter().map(|c| format!("ratio.{c}")).collect()
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        warn_infinite_lights("ratio", scene, ctx.warnings);
        let shader = LtcShader::new(self.shading, scene, "ratio").with_unshadowed_budget();
        shader.warn_slow_lights(scene, ctx.warnings);
        let groups = SampleGroup::of(&shader, scene);
        let est = Estimator {
            shader,
            n: scene.sampler.round_count(self.nsamples).max(1),
            max_depth: self.max_depth,
            groups,
            pixel_shading: self.pixel_shading,
            fallback: FallbackWarning::new("ratio", ctx.warnings),
        };
        let (mut stats, (filtered, seconds)) = est.shader.with_live_status(ctx, |ctx| {
            render_pixels_with_margin(&est, scene, ctx, film, self.margin(), |grown| {
                let t = std::time::Instant::now();
                let filtered = self.resolve(grown, est.n);
                (filtered, t.elapsed().as_secs_f64())
            })
        })?;
        stats.counters.insert("denoise_seconds".into(), seconds);
        stats.counters.insert("mean_radius".into(), filtered);
        est.shader.finish(&mut stats, ctx.warnings);
        stats.render_seconds += seconds;
        Ok(stats)
    }
}

impl RatioIntegrator {
    /// How far the denoiser reads: a pixel's kernel radius is the maximum over its 3×3
    /// neighbourhood (one pixel), and its kernel reaches `maxradius` pixels.
    fn margin(&self) -> u32 {
        self.max_radius.max(1)
    }

    /// The whole-image pass: reads the channels back, denoises, writes `rest + U·ratio`.
    /// Returns the mean kernel radius over pixels with area-light shading.
    fn resolve(&self, film: &mut Film, n_stochastic: u32) -> f64 {
        if film.extra_channel_names.len() != CHANNELS.len() {
            return 0.0;
        }
        let px = read_film(film);
        let (w, h) = (px.width(), px.height());
        let sigma = px.map(|p| ratio_sigma(p, n_stochastic));
        let guides = ImageBuffer::from_fn(w, h, |i| guide(&px[i].mean, sigma[i]));
        let su = px.map(|p| {
            let (s, un) = (p.mean.s, p.mean.un);
            [s[0], s[1], s[2], un[0], un[1], un[2]]
        });
        let radius = if self.denoise {
            noise_radius(&sigma, self.noise_target, self.max_radius)
        } else {
            ImageBuffer::filled(w, h, 0)
        };
        let (d, reduction) = cross_bilateral(&guides, &radius, &su, &self.filter);
        let (mut rsum, mut rcount) = (0.0f64, 0usize);
        for (i, p) in film.pixel_bounds().iter().enumerate() {
            let FilmPixel { rest, rest_var: mut var, mean, count } = px[i];
            let mut out = rest;
            if mean.u != Rgb::ZERO {
                rsum += radius[i] as f64;
                rcount += 1;
                for c in 0..3 {
                    let ratio = guarded_ratio(d[i][c], d[i][3 + c], mean.s[c], mean.un[c]);
                    out[c] += mean.u[c] * ratio;
                    let sr = sigma[i] as f64 * mean.u[c] as f64;
                    let spread = camera_spread(rest[c], mean.u[c], mean.spread_uu[c], mean.spread_ru[c], ratio, count);
                    var[c] = (var[c] + spread).max(0.0) + sr * sr * reduction[i] as f64;
                }
            }
            let chain = mean.chain;
            if chain.u != Rgb::ZERO {
                for c in 0..3 {
                    out[c] += chain.u[c] * guarded_ratio(chain.s[c], chain.un[c], chain.s[c], chain.un[c]);
                }
            }
            if !out.is_finite() {
                out = if rest.is_finite() { rest } else { Rgb::ZERO };
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

/// The film's pixels (within its pixel bounds) as [`FilmPixel`]s; pixels without weight stay
/// zero.
fn read_film(film: &Film) -> ImageBuffer<FilmPixel> {
    let pb = film.pixel_bounds();
    let (w, h) = (pb.width().max(0) as usize, pb.height().max(0) as usize);
    let mut px = ImageBuffer::filled(w, h, FilmPixel::default());
    for (i, p) in pb.iter().enumerate() {
        let (Some(ps), Some(ex)) = (film.pixel_sums(p), film.pixel_extra(p)) else { continue };
        if !(ps.weight != 0.0) {
            continue;
        }
        let inv = 1.0 / ps.weight;
        let q = &mut px[i];
        q.rest = Rgb::new((ps.rgb[0] * inv) as f32, (ps.rgb[1] * inv) as f32, (ps.rgb[2] * inv) as f32);
        let m = ps.own_count as f64;
        q.count = m;
        if m > 1.0 {
            for (c, v) in q.rest_var.iter_mut().enumerate() {
                let mean = ps.own_sum[c] / m;
                *v = ((ps.own_sum_sq[c] / m - mean * mean).max(0.0) * m / (m - 1.0)) / m;
            }
        }
        let ch: Vec<f32> = ex.iter().map(|v| (v * inv) as f32).collect();
        q.mean = RatioSample::read(&ch);
    }
    px
}

/// What `U · ratio` adds to the variance of a pixel's mean over its `count` camera samples (the
/// variance of `rest` is the film's): `(r² var(U) + 2r cov(rest, U)) / count` from the pixel
/// means of `U`, `U²` and `rest·U`, Bessel-corrected (0 for a single sample). Without it the
/// variance written for `ratio` missed the camera samples' spread of `U` — a pixel over a
/// silhouette, a texture or an opacity edge — which `ltc`'s and `directlighting`'s carry.
fn camera_spread(rest: f32, u: f32, uu: f32, ru: f32, ratio: f32, count: f64) -> f64 {
    if !(count > 1.0) {
        return 0.0;
    }
    let (rest, u, r) = (rest as f64, u as f64, ratio as f64);
    let var_u = (uu as f64 - u * u).max(0.0);
    let cov = ru as f64 - rest * u;
    let v = (r * r * var_u + 2.0 * r * cov) / (count - 1.0);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Delta-method standard deviation of a pixel's ratio estimate (luminance), over its camera
/// samples × `n_stochastic` stochastic samples.
fn ratio_sigma(p: &FilmPixel, n_stochastic: u32) -> f32 {
    let s = luminance(p.mean.s) as f64;
    let u = luminance(p.mean.un) as f64;
    if !(u > 0.0) || p.count < 1.0 {
        return 0.0;
    }
    let r = s / u;
    let var_s = p.mean.ss as f64 - s * s;
    let var_u = p.mean.uu as f64 - u * u;
    let cov = p.mean.su as f64 - s * u;
    let count = p.count * n_stochastic as f64;
    let v = (var_s - 2.0 * r * cov + r * r * var_u).max(0.0) / (count.max(2.0) - 1.0) / (u * u);
    let sd = v.sqrt() as f32;
    if sd.is_finite() {
        sd
    } else {
        0.0
    }
}

/// The filter's guide of a pixel with mean channels `m` and ratio deviation `sigma`.
fn guide(m: &RatioSample, sigma: f32) -> Guide {
    Guide {
        depth: m.depth,
        normal: m.n,
        plane: m.plane,
        u: luminance(m.u),
        ratio: guarded_ratio(f32::NAN, 0.0, luminance(m.s), luminance(m.un)),
        ratio_sigma: sigma,
    }
}

#[cfg(test)]
mod tests {
    use super::camera_spread;

    /// The variance of the mean of `rest_k + r·U_k` over the camera samples, by its definition
    /// (Bessel-corrected sample variance over `m`), minus `rest`'s alone: what
    /// [`camera_spread`] adds from the pixel means of `U`, `U²` and `rest·U`.
    #[test]
    fn camera_spread_is_the_variance_u_adds_to_the_pixel_mean() {
        let rest = [0.3f64, 0.0, 0.1, 0.7, 0.2];
        let u = [2.0f64, 0.5, 1.5, 0.0, 3.0];
        let m = rest.len() as f64;
        let mean = |v: &dyn Fn(usize) -> f64| (0..rest.len()).map(v).sum::<f64>() / m;
        let var_of_mean = |v: &dyn Fn(usize) -> f64| {
            let mu = mean(v);
            (0..rest.len()).map(|k| (v(k) - mu).powi(2)).sum::<f64>() / (m - 1.0) / m
        };
        for r in [0.0f64, 0.25, 0.6, 1.0] {
            let want = var_of_mean(&|k| rest[k] + r * u[k]) - var_of_mean(&|k| rest[k]);
            let got = camera_spread(
                mean(&|k| rest[k]) as f32,
                mean(&|k| u[k]) as f32,
                mean(&|k| u[k] * u[k]) as f32,
                mean(&|k| rest[k] * u[k]) as f32,
                r as f32,
                m,
            );
            assert!((got - want).abs() <= 1e-6 * (1.0 + want.abs()), "r = {r}: {got} vs {want}");
        }
        // Every camera sample on one surface with one U: nothing added.
        assert!(camera_spread(0.2, 1.5, 2.25, 0.3, 0.5, 16.0).abs() < 1e-8);
        // One camera sample: no spread to estimate.
        assert_eq!(camera_spread(0.2, 1.5, 9.0, 0.3, 0.5, 1.0), 0.0);
        // Not finite in, not finite out.
        assert!(camera_spread(0.2, f32::NAN, 9.0, 0.3, 0.5, 4.0).is_finite());
    }
}
