//! `silhouette`: semi-analytic spherical integration along visibility silhouettes (seed 000:
//! Nowrouzezahrai, Baran, Mitchell & Jarosz, "Visibility Silhouettes for Semi-Analytic
//! Spherical Integration", CGF 2014).
//!
//! At each shading point the contour edges come from the scene's 4D dual-edge hierarchy
//! ([`dual::DualEdges`], built by [`Integrator::prepare`]), culled behind the tangent plane; their arcs are bucketed on `"integer resolution"` meridians of the
//! `(φ, cos θ)` parameterisation about the axis closest to the normal (of the brightest
//! environment map's frame, so that a scene turned as a whole is integrated alike:
//! [`param::Axes`]), each
//! meridian is walked from the pole with the relative depth complexity `W`, and one shadow
//! ray through the longest interval of minimal `W` decides whether those intervals are the
//! visible ones (else the point sees nothing). The integrand is integrated exactly in `v`
//! over the visible intervals; only the azimuth is discretised (and, for environment maps,
//! the radiance, in prefix-sum tables along the meridians).
//!
//! Modes (`"string mode"`):
//! - `prt`: the `ao` image plus SH transfer channels (`core::sh`'s convention, order
//!   `"integer shorder"`, 3): `∫_{V·H} max(0, n_s·ω) Y_i(ω) dω` over the same visible
//!   intervals (Gauss–Legendre in θ along each), `n_s` the face-forwarded shading normal, and
//!   `albedo.*`; `penumbra relight` of them under the scene's sky reproduces `shade`. A scene's
//!   other lights (area, point, …) cannot be relit from them: `prt` warns, naming their kinds.
//! - `ao` (default only for a scene without lights, with a warning): pbrt-v3's `ambientocclusion` value, the
//!   integral of `V·cos θ` over the hemisphere of the face-forwarded geometric normal
//!   (π for an open hemisphere), from the analytic moment `∫ ω dω` of the visible intervals.
//! - `shade` (default when the scene has a light): Lambertian materials under infinite lights by
//!   the vector irradiance `v = ∫ L V H ω dω` (the band-1 formulation: 3 tables per colour),
//!   radiance `ρ/π · n_s·v`; the visible set is the hemisphere of the face-forwarded
//!   geometric normal (pbrt-v3's reflection test), the cosine that of the shading normal
//!   (signed: it differs from pbrt-v3's `|cos|` only where the two normals disagree).
//!   Materials with other non-specular reflection lobes (microfacet, Fresnel blend,
//!   Oren–Nayar) keep the vector irradiance for their Lambertian lobes and shade the rest by
//!   SH projection ([`glossy`]): the visible environment `L·V·H` projected onto `core::sh`
//!   from a second prefix-sum table ([`ShTable`], built on first use) and dotted with the
//!   projection of the material's own BRDF × |cos| over the same hemisphere, at an order
//!   chosen from the lobe's roughness (at most `"integer glossyorder"`, 12). Materials with a
//!   non-specular transmission lobe take the infinite lights through `directlighting`'s
//!   estimator (counted as `"silhouette.estimator_fallbacks"`). Area,
//!   point, spot and distant lights are always added by that estimator, and perfectly
//!   specular materials recurse as in `directlighting` (up to `"integer maxdepth"`, 5).
//!
//! `"string shading"` `pixel` (default; `ao` and `shade`): the integrals are noise-free, so a
//! pixel's camera samples only resolve which surfaces it sees and where their edges run; each
//! surface seen in a pixel (a cluster of [`crate::common::pixel_shading`]) is integrated at
//! ⌈√m⌉ of its m samples ([`shading_points`](crate::common::pixel_shading::shading_points):
//! the most central, then each the farthest on the film from those taken), the others taking
//! the nearest one's value, so that the pixel converges to sample shading's value as the
//! samples grow; and at every sample where those differ from the central one by more than
//! [`REFINE`](crate::common::pixel_shading::REFINE), 5 % (a shadow edge or highlight crossing
//! the pixel; each sample then takes a blend of its neighbour's value and its own, its own
//! alone from a difference of [`REFINE_FULL`](crate::common::pixel_shading::REFINE_FULL),
//! 10 %) (`shade`: the irradiance over π, multiplied by each sample's own albedo, and the
//! SH-shaded lobes' radiance; the estimator's
//! lights, emission and specular recursion stay per sample). `sample`: every camera sample is
//! integrated, as `prt` always is.

//!
//! Files: [`dual`] the 4D dual-edge hierarchy, whose hyperplane query gives a shading point's
//! contour edges (exactly the brute-force set), culled behind the tangent plane; [`param`] the
//! `(φ, cos θ)` sphere parameterisation (Jacobian 1, one shared start for every isoline) used
//! instead of the paper's octahedral map; [`table`] prefix sums of radiance-weighted moments
//! along meridians (environment lighting); [`shtable`] the same for radiance-weighted SH basis
//! functions (glossy lobes); [`traverse`] per-meridian crossing buckets, the depth-complexity
//! walk and the intervals of minimal depth complexity; [`orient`] the orientation predicate
//! everything is decided by; [`glossy`] the SH shading of glossy lobes; this file the
//! parameters and the estimator.

use crate::common::direct::{estimate_direct, specular};
use crate::common::other_lights::FallbackWarning;
use crate::common::params::{ParamSpec, Params};
use crate::common::pixel_shading::{parse_shading, rgb_difference, Refine, SharedPixel, SHADING};
use crate::common::{max_depth, max_depth_param, SH_ORDER};
use dual::{Contour, DualEdges};
use param::{moment, Axes, Meridians, PoleFrame};
use penumbra_core::bxdf::BxdfFlags;
use penumbra_core::camera::CameraSample;
use penumbra_core::film::Film;
use penumbra_core::geometry::{face_forward, offset_ray_origin, Frame, Ray, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, SampleContext, ThreadStats,
};
use penumbra_core::integrator::{CostEstimate, Preparation};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::Light;
use penumbra_core::sampler::Sampler;
use penumbra_core::sampling::uniform_sample_hemisphere;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit, SurfacePoint};
use penumbra_core::sh::{basis, quadrature::gauss_legendre, transfer::TransferChannels, ShOrder, MAX_ORDER};
use penumbra_core::{Rgb, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use shtable::ShTable;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use table::MomentTable;
use traverse::{Interval, Traversal};

pub mod cost;
pub mod dual;
pub mod glossy;
pub mod orient;
pub mod param;
pub mod shtable;
pub mod table;
pub mod traverse;

#[cfg(test)]
mod tests;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Ao,
    Shade,
    Prt,
}

/// The tangent-plane cull's tolerance: edges below an elevation of ~1e-6 rad are dropped
/// (the normal is given in f32; coplanar neighbours of the shading point lie there). An
/// angle, so scale-free, like every tolerance of the traversal (`v` merging) and of the
/// dual-edge filters (rounding bounds relative to their terms).
const CULL_TOL: f64 = 1e-6;

pub struct Silhouette {
    /// `None`: `shade` when the scene has a light, else `ao` ([`default_mode`]).
    pub mode: Option<Mode>,
    /// `"integer resolution"` (√k): meridians, and table cells per meridian.
    pub resolution: usize,
    pub max_depth: u32,
    /// `"integer shorder"` (3): the order of the `prt` transfer channels.
    pub sh_order: ShOrder,
    /// `"integer glossyorder"` (12): the highest SH order glossy lobes are shaded at (the order
    /// of the environment's SH table).
    pub glossy_order: ShOrder,
    /// `"string shading"` `pixel` (default): the integrals are computed once per surface a
    /// pixel sees ([`crate::common::pixel_shading`]); `sample`: at every camera sample.
    pub pixel_shading: bool,
}

/// The parameters `silhouette` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::choice(
        "mode",
        &["ao", "shade", "prt"],
        "ambient occlusion, shading under the scene's lights, or AO plus SH transfer channels for penumbra relight",
    )
    .unset("shade when the scene has lights, else ao")
    .strict(),
    ParamSpec::int("resolution", 128, "meridians of the (φ, cos θ) parameterisation").range(4, 4096),
    SH_ORDER,
    ParamSpec::int(
        "glossyorder",
        12,
        "the highest SH order glossy lobes are shaded at (the order of the environment's SH table)",
    )
    .range(1, 16),
    max_depth(1024),
    SHADING,
];

impl Silhouette {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("silhouette", PARAMS, params, warnings);
        let mode = p.choice_or_unset("mode", [Mode::Ao, Mode::Shade, Mode::Prt])?;
        let sh_order =
            ShOrder::new(p.count("shorder")? as usize).map_err(|e| Diagnostic::error(None, e.to_string()))?;
        let resolution = p.count("resolution")? as usize;
        let glossy_order =
            ShOrder::new(p.count("glossyorder")? as usize).map_err(|e| Diagnostic::error(None, e.to_string()))?;
        let max_depth = max_depth_param(&p)?;
        let pixel_shading = parse_shading(&p)?;
        Ok(Box::new(Silhouette { mode, resolution, max_depth, sh_order, glossy_order, pixel_shading }))
    }
}

/// The mode when `"string mode"` is not given: `shade` (the scene's own lighting) whenever the
/// scene has a light, `ao` only for a scene without lights (which pbrt-v3 renders black), with a
/// warning saying so. Never ambient occlusion in place of the scene's lights.
fn default_mode(scene: &Scene, warnings: &DiagSink) -> Mode {
    if scene.light_list().is_empty() {
        warnings.warn(
            None,
            "silhouette: the scene has no lights: rendering ambient occlusion (\"mode\" \"ao\"), not the black image \
             of its lighting",
        );
        Mode::Ao
    } else {
        Mode::Shade
    }
}

/// `prt` under lights its transfer channels cannot carry (only distant light relights them):
/// its image is ambient occlusion, so the scene's own lights are not in it. Says so, naming
/// the kinds of light (issue 37 item 4: never ambient occlusion in place of the scene's
/// lighting without a word).
fn warn_prt_lights(scene: &Scene, warnings: &DiagSink) {
    let mut kinds: Vec<&str> = scene
        .light_list()
        .iter()
        .filter_map(|l| match l {
            Light::Infinite(_) => None,
            Light::Point(_) => Some("point"),
            Light::Spot(_) => Some("spot"),
            Light::Distant(_) => Some("distant"),
            Light::Area(_) => Some("area"),
            Light::Goniometric(_) => Some("goniometric"),
            Light::Projection(_) => Some("projection"),
        })
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    if !kinds.is_empty() {
        warnings.warn(
            None,
            format!(
                "silhouette: \"mode\" \"prt\" renders ambient occlusion plus SH transfer channels for distant \
                 lighting: the scene's {} light(s) are not in its image (\"mode\" \"shade\" shades them)",
                kinds.join(", ")
            ),
        );
    }
}

/// `prt`'s transfer is a Lambertian cosine relit with the diffuse albedo: the scene's other
/// lobes (glossy, specular) are in `shade`'s image but not in the relit one. Says so, naming
/// the materials (issue 37 item 5: under the studio map a plastic sphere's highlight leaves
/// 7 % RMSE at any SH order).
fn warn_prt_materials(scene: &Scene, warnings: &DiagSink) {
    let Some(materials) = &scene.materials else { return };
    let mut names: Vec<&str> = scene
        .objects
        .iter()
        .filter_map(|o| materials.get(o.material?))
        .map(|m| m.type_name())
        .filter(|n| *n != "matte")
        .collect();
    names.sort_unstable();
    names.dedup();
    if !names.is_empty() {
        warnings.warn(
            None,
            format!(
                "silhouette: \"mode\" \"prt\"'s transfer channels relight the diffuse albedo only: the other lobes of \
                 the scene's {} material(s) are in \"mode\" \"shade\"'s image, not in the relit one",
                names.join(", ")
            ),
        );
    }
}

#[derive(Default)]
struct Scratch {
    contours: Vec<Contour>,
    traversal: Traversal,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

#[derive(Default)]
struct Counters {
    points: AtomicU64,
    contours: AtomicU64,
    examined: AtomicU64,
    nodes: AtomicU64,
    crossings: AtomicU64,
    occluded_points: AtomicU64,
    estimator_fallbacks: AtomicU64,
    fallbacks: AtomicU64,
    glossy_points: AtomicU64,
}

/// The finest texel among the infinite lights' maps, at most 1/2048 of π (a 4096 × 2048 map;
/// finer maps are sampled at that spacing, which bounds the tables' build cost), halved: the
/// spacing at which the radiance tables sample each cell, so every texel is sampled about four
/// times and a sun a few texels wide keeps its power in every axis frame ([`CellNodes`]).
/// A constant light (a 1 × 1 map) needs only the tables' fixed 3 × 3 nodes per cell.
///
/// [`CellNodes`]: param::CellNodes
fn table_spacing(infinite: &[&Light]) -> f64 {
    let texel = infinite
        .iter()
        .filter_map(|l| match l {
            Light::Infinite(l) if l.map.width * l.map.height > 1 => {
                Some((std::f64::consts::TAU / l.map.width as f64).min(std::f64::consts::PI / l.map.height as f64))
            }
            _ => None,
        })
        .fold(std::f64::consts::PI, f64::min);
    0.5 * texel.max(std::f64::consts::PI / 2048.0)
}

/// The axes the traversal and the tables are discretised about ([`Axes`]): the environment
/// map's of the brightest infinite light (its mean radiance summed over the colours; the first
/// of equals), so that the scene turned as a whole, lights included, is integrated alike;
/// the world's where there is no infinite light or its transform is degenerate.
fn integration_axes(infinite: &[&Light]) -> Axes {
    let mut best: Option<(f32, Axes)> = None;
    for l in infinite {
        let Light::Infinite(l) = l else { continue };
        let m = l.world_from_light.as_dmat3();
        let (Some(axes), power) = (Axes::of_map(m.x_axis, m.z_axis), l.map.mean().element_sum()) else { continue };
        if best.is_none_or(|(p, _)| power > p) {
            best = Some((power, axes));
        }
    }
    best.map_or(Axes::WORLD, |(_, a)| a)
}

/// Rays per side of the stratified grid of the AO modes' Monte Carlo fallback.
const FALLBACK_RAYS: usize = 16;

/// Samples per side of the stratified grid of `shade`'s estimator fallback.
const FALLBACK_SAMPLES: usize = 8;

struct Estimator<'a> {
    mode: Mode,
    max_depth: u32,
    dual: &'a DualEdges,
    meridians: Meridians,
    /// The axes the pole frames are taken about ([`integration_axes`]).
    axes: Axes,
    /// The infinite lights' radiance moments (`shade`).
    table: Option<MomentTable>,
    /// `prt`: the transfer order and Gauss–Legendre nodes in θ per interval.
    sh: Option<(ShOrder, Vec<f64>, Vec<f64>)>,
    /// `shade`: the infinite lights, the glossy order and the SH table of their radiance
    /// (built when a glossy lobe first needs it).
    infinite: Vec<&'a Light>,
    glossy_order: ShOrder,
    /// How far apart (radians) the tables sample the radiance: [`table_spacing`].
    table_spacing: f64,
    sh_table: OnceLock<ShTable>,
    counters: Counters,
    pixel_shading: bool,
    /// Names the materials whose lobes take the infinite lights through the estimator.
    fallback: FallbackWarning<'a>,
}

impl Estimator<'_> {
    /// Calls `f` with every visible interval of the hemisphere of `n` (unit, world) at `si`
    /// (none when the point sees nothing) and returns `true`; returns `false` without calling
    /// `f` when the traversal's horizon check finds a missed crossing (counted as
    /// `silhouette.fallbacks`): the caller then estimates the point another way
    /// ([`Self::fallback_rays`] for the bounded AO integrands, [`Self::fallback_estimator`]
    /// for the environment's radiance).
    fn visible(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        n: Vec3,
        stats: &mut ThreadStats,
        mut f: impl FnMut(&PoleFrame, &Interval),
    ) -> bool {
        let dual = self.dual;
        // Offset off the surface by its error bound, as rays are: the surface itself and its
        // coplanar neighbours are then strictly behind the tangent plane, never contours.
        let p = dual.normalise(offset_ray_origin(si.p, si.p_error, n, n));
        let nd = n.as_dvec3().normalize();
        let frame = self.axes.frame_for_normal(nd);
        SCRATCH.with_borrow_mut(|s| {
            s.contours.clear();
            let cost = dual.contours(p, nd, CULL_TOL, &mut s.contours);
            self.counters.examined.fetch_add(cost.edges as u64, Ordering::Relaxed);
            self.counters.nodes.fetch_add(cost.nodes as u64, Ordering::Relaxed);
            let vis = s.traversal.run(&s.contours, p, nd, &frame, &self.meridians);
            self.counters.points.fetch_add(1, Ordering::Relaxed);
            self.counters.contours.fetch_add(s.contours.len() as u64, Ordering::Relaxed);
            self.counters.crossings.fetch_add(vis.crossings as u64, Ordering::Relaxed);
            if vis.mismatches > 0 {
                self.counters.fallbacks.fetch_add(1, Ordering::Relaxed);
                return false;
            }
            // The intervals of minimal relative W are the visible ones iff one ray through the
            // longest of them escapes (inside a closed box no edge is a contour, W is 1
            // everywhere, and only the ray tells).
            stats.shadow_rays += 1;
            if scene.occluded(&si.spawn_ray(vis.probe.as_vec3())) {
                self.counters.occluded_points.fetch_add(1, Ordering::Relaxed);
                return true;
            }
            for iv in s.traversal.with_w(vis.min_w) {
                f(&frame, iv);
            }
            true
        })
    }

    /// The Monte Carlo fallback of the AO integrands (cosine, SH × cosine: bounded): calls `f`
    /// with the unoccluded directions of a stratified `FALLBACK_RAYS`² uniform sampling of
    /// the hemisphere of `n` and their solid angle.
    fn fallback_rays(
        scene: &Scene,
        si: &SurfaceInteraction,
        n: Vec3,
        stats: &mut ThreadStats,
        mut f: impl FnMut(glam::DVec3, f64),
    ) {
        let frame = Frame::from_z(n);
        let k = FALLBACK_RAYS;
        let w = std::f64::consts::TAU / (k * k) as f64;
        for a in 0..k {
            for b in 0..k {
                let u = Vec2::new((a as f32 + 0.5) / k as f32, (b as f32 + 0.5) / k as f32);
                let d = frame.from_local(uniform_sample_hemisphere(u));
                stats.shadow_rays += 1;
                if !scene.occluded(&si.spawn_ray(d)) {
                    f(d.as_dvec3(), w);
                }
            }
        }
    }

    /// The fallback of `shade`: the infinite lights' direct lighting at a point whose
    /// traversal failed, by `directlighting`'s estimator (light and BSDF sampling, power
    /// heuristic) averaged over a `FALLBACK_SAMPLES`² stratified grid shifted by one sampler
    /// value. Uniform directions would be unbounded here: a ray that happens to hit a small
    /// sun carries its radiance over `2π/256` sr, and such pixels came out ten times too bright.
    fn fallback_estimator(
        &self,
        si: &SurfaceInteraction,
        bsdf: &penumbra_core::bxdf::Bsdf,
        sampler: &mut dyn Sampler,
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let (shift_l, shift_s) = (sampler.get_2d(), sampler.get_2d());
        let k = FALLBACK_SAMPLES;
        let grid = |a: usize, b: usize, shift: Vec2| {
            let u = Vec2::new((a as f32 + shift.x) / k as f32, (b as f32 + shift.y) / k as f32);
            u.min(Vec2::splat(1.0 - f32::EPSILON / 2.0))
        };
        let mut l = Rgb::ZERO;
        for (index, light) in scene.light_list().iter().enumerate().filter(|(_, l)| l.is_infinite()) {
            for a in 0..k {
                for b in 0..k {
                    // The BSDF's grid transposed, so the two are not sampled in lockstep.
                    let (u_light, u_scatter) = (grid(a, b, shift_l), grid(b, a, shift_s));
                    l += estimate_direct(si, bsdf, u_scatter, index, light, u_light, scene, stats);
                }
            }
        }
        l / (k * k) as f32
    }

    /// The first surface with a material along `ray` (pbrt-v3's AO passes through the others),
    /// with the camera ray's differentials when it reached it directly (for the albedo's
    /// texture lookups).
    fn first_surface(
        scene: &Scene,
        camera_ray: &RayDifferential,
        stats: &mut ThreadStats,
    ) -> Option<SurfaceInteraction> {
        let mut ray = camera_ray.ray;
        for pass in 0..64 {
            let hit = scene.intersect(&ray)?;
            let mut si = scene.interaction(&ray, &hit);
            if scene.objects[hit.mesh as usize].material.is_some() {
                if pass == 0 {
                    si.compute_differentials(camera_ray);
                }
                return Some(si);
            }
            ray = si.spawn_ray(ray.d);
            stats.rays += 1;
        }
        None
    }

    fn ao(&self, ray: &RayDifferential, scene: &Scene, stats: &mut ThreadStats, aov: &mut [f32]) -> Rgb {
        match Self::first_surface(scene, ray, stats) {
            Some(si) => self.ao_at(&si, -ray.d, scene, stats, aov),
            None => Rgb::ZERO,
        }
    }

    /// The AO value (and, in `prt`, the transfer channels in `aov`) at `si` seen from `wo`.
    fn ao_at(&self, si: &SurfaceInteraction, wo: Vec3, scene: &Scene, stats: &mut ThreadStats, aov: &mut [f32]) -> Rgb {
        let si = *si;
        let n = face_forward(si.n, wo);
        let (nd, m) = (n.as_dvec3(), &self.meridians);
        let (mut sum, mut sum_mc) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        let k = self.sh.as_ref().map_or(0, |s| s.0.coeffs());
        // The transfer's cosine is the shading normal's (bumped; face-forwarded), as `shade`
        // and pbrt-v3's BSDFs use it, so that relighting reproduces `shade`.
        let ns = match (&self.sh, scene.material_of(&si)) {
            (Some(_), Some((material, materials, textures))) => {
                material.ltc_lobes(&si, materials, textures).map_or(si.shading.z, |d| d.n)
            }
            _ => si.shading.z,
        };
        let ns = face_forward(ns, n).as_dvec3();
        let (mut transfer, mut y) = ([0.0f64; MAX_ORDER * MAX_ORDER], [0.0f64; MAX_ORDER * MAX_ORDER]);
        let traversed = self.visible(scene, &si, n, stats, |frame, iv| {
            let i = iv.meridian as usize;
            sum += moment(frame, m, i, iv.lo, iv.hi);
            if let Some((order, x, w)) = &self.sh {
                // ∫ Y(ω) n·ω dv = ∫ Y n·ω sin θ dθ, Gauss–Legendre in θ.
                let (t0, t1) = (iv.hi.clamp(-1.0, 1.0).acos(), iv.lo.clamp(-1.0, 1.0).acos());
                let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
                for (xj, wj) in x.iter().zip(w) {
                    let t = mid + half * xj;
                    let d = frame.direction(m.cos[i], m.sin[i], t.cos());
                    basis::eval(*order, d, &mut y[..k]);
                    let weight = wj * half * t.sin() * ns.dot(d).max(0.0) * m.dphi;
                    transfer[..k].iter_mut().zip(&y[..k]).for_each(|(tr, yi)| *tr += weight * yi);
                }
            }
        });
        if !traversed {
            Self::fallback_rays(scene, &si, n, stats, |d, w| {
                sum_mc += d * w;
                if let Some((order, ..)) = &self.sh {
                    basis::eval(*order, d, &mut y[..k]);
                    let weight = w * ns.dot(d).max(0.0);
                    transfer[..k].iter_mut().zip(&y[..k]).for_each(|(tr, yi)| *tr += weight * yi);
                }
            });
        }
        if let Some((order, ..)) = &self.sh {
            TransferChannels::new(*order, 0).write(aov, &transfer[..k], crate::common::diffuse_albedo(scene, &si));
        }
        Rgb::splat((nd.dot(sum * m.dphi + sum_mc)).max(0.0) as f32)
    }

    fn shade(
        &self,
        ray: &RayDifferential,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let (first, queries) = scene.first_surface(ray);
        stats.add_continued(queries);
        match first {
            Ok(hit) => self.shade_hit(ray, &hit, None, scene, sampler, stats, depth),
            Err(escaped) => escaped,
        }
    }

    /// How `hit` takes the infinite lights in `shade` (`None`: by the estimator).
    fn env_kind(&self, scene: &Scene, hit: &SurfaceHit) -> Option<EnvKind> {
        self.table.as_ref()?;
        let lambertian = scene
            .material_of(&hit.si)
            .and_then(|(material, materials, textures)| material.ltc_lobes(&hit.si, materials, textures))
            .filter(|d| d.lobes.is_empty() && !d.transmits);
        match lambertian {
            Some(d) => Some(EnvKind::Lambertian { albedo: d.diffuse, n: d.n }),
            None => {
                let split = glossy::Split::of(&hit.bsdf, self.glossy_order).map(EnvKind::Split);
                if split.is_none() && hit.bsdf.num_components(BxdfFlags::NON_SPECULAR) > 0 {
                    let name = scene.material_of(&hit.si).map_or("none", |(m, _, _)| m.type_name());
                    self.fallback.material(name, "non-specular transmission", "the infinite lights");
                }
                split
            }
        }
    }

    /// The infinite lights' light reflected at `hit` by the surface's `kind` of lobes, as
    /// `(E, G)`: `E` the irradiance over π at the shading normal (the caller multiplies it by
    /// the Lambertian albedo) and `G` the SH-shaded lobes' radiance; `None` when the
    /// traversal failed (the caller takes the estimator fallback).
    fn env_terms(&self, kind: &EnvKind, hit: &SurfaceHit, scene: &Scene, stats: &mut ThreadStats) -> Option<EnvTerms> {
        let table = self.table.as_ref()?;
        let si = &hit.si;
        match kind {
            EnvKind::Lambertian { n, .. } => {
                let ng = face_forward(si.n, si.wo);
                let mut v = [glam::DVec3::ZERO; 3];
                let m = &self.meridians;
                let traversed = self.visible(scene, si, ng, stats, |frame, iv| {
                    table.add(frame, m, iv.meridian as usize, iv.lo, iv.hi, &mut v)
                });
                // pbrt-v3's |cos| with the shading normal: on the visible side.
                let ns = face_forward(*n, ng).as_dvec3();
                traversed.then(|| (irradiance_over_pi(ns, &v, m.dphi), Rgb::ZERO))
            }
            EnvKind::Split(split) => self.shade_split(split, si, &hit.bsdf, table, scene, stats),
        }
    }

    /// Radiance from `hit`, the `depth`-th surface of a camera ray's specular chain; `env` is
    /// its pixel cluster's [`Self::env_terms`] when pixel shading computed them already
    /// (`Some(None)`: the cluster's traversal failed).
    #[allow(clippy::too_many_arguments)]
    fn shade_hit(
        &self,
        ray: &RayDifferential,
        hit: &SurfaceHit,
        env: Option<Option<EnvTerms>>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let SurfaceHit { si, bsdf, le, .. } = hit;
        let mut l = *le;
        let kind = self.env_kind(scene, hit);
        for (k, light) in scene.light_list().iter().enumerate() {
            if light.is_infinite() && kind.is_some() {
                continue;
            }
            if light.is_infinite() {
                self.counters.estimator_fallbacks.fetch_add(1, Ordering::Relaxed);
            }
            let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
            l += estimate_direct(si, bsdf, u_scatter, k, light, u_light, scene, stats);
        }
        if let Some(kind) = &kind {
            let terms = match env {
                Some(shared) => shared,
                None => self.env_terms(kind, hit, scene, stats),
            };
            l += match terms {
                Some((e, g)) => kind.albedo() * e + g,
                None => self.fallback_estimator(si, bsdf, sampler, scene, stats),
            };
        }
        if depth + 1 < self.max_depth {
            for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                l += specular(si, bsdf, ray, sampler, stats, kind, |r, sampler, stats| {
                    self.shade(r, scene, sampler, stats, depth + 1)
                });
            }
        }
        l
    }
}

/// `(E, G)` of [`Estimator::env_terms`].
type EnvTerms = (Rgb, Rgb);

/// What pixel shading computes once per cluster: `ao`'s value (in the first slot) or
/// `shade`'s [`EnvTerms`] (`None`: the traversal failed).
type ClusterValue = Option<EnvTerms>;

/// How far apart a pixel cluster's two shaded samples are ([`rgb_difference`]: a shadow edge or
/// a highlight crossing the pixel makes every member take its own value, in part or whole);
/// infinite where the traversal failed at one of them.
fn difference(a: &ClusterValue, b: &ClusterValue) -> f32 {
    match (a, b) {
        (Some((e1, g1)), Some((e2, g2))) => rgb_difference(*e1 + *g1, *e2 + *g2),
        (None, None) => 0.0,
        _ => f32::INFINITY,
    }
}

/// How a surface takes the infinite lights in `shade`.
#[derive(Clone, Copy)]
enum EnvKind {
    /// Lambertian lobes only: albedo and shading normal (`ltc_lobes`).
    Lambertian { albedo: Rgb, n: Vec3 },
    /// Lambertian lobes by the vector irradiance, the others by SH ([`glossy`]).
    Split(glossy::Split),
}

impl EnvKind {
    fn albedo(&self) -> Rgb {
        match self {
            EnvKind::Lambertian { albedo, .. } => *albedo,
            EnvKind::Split(s) => s.diffuse,
        }
    }
}

/// `max(0, n_s·v)/π` per colour for the vector irradiance `v` summed over meridians of width
/// `dphi`.
fn irradiance_over_pi(ns: glam::DVec3, v: &[glam::DVec3; 3], dphi: f64) -> Rgb {
    let e = Rgb::new(ns.dot(v[0] * dphi) as f32, ns.dot(v[1] * dphi) as f32, ns.dot(v[2] * dphi) as f32);
    e.max(Rgb::ZERO) * std::f32::consts::FRAC_1_PI
}

impl Estimator<'_> {
    /// A surface with non-Lambertian lobes under the infinite lights: its Lambertian lobes by
    /// the vector irradiance, the others by SH projection of the visible environment and of
    /// the lobes ([`glossy`]), as [`EnvTerms`]; `None` when the traversal failed.
    fn shade_split(
        &self,
        split: &glossy::Split,
        si: &SurfaceInteraction,
        bsdf: &penumbra_core::bxdf::Bsdf,
        table: &MomentTable,
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Option<EnvTerms> {
        self.counters.glossy_points.fetch_add(1, Ordering::Relaxed);
        let sh_table = self.sh_table.get_or_init(|| {
            let cells = self.meridians.n.min(glossy::TABLE_CELLS);
            ShTable::build(&self.meridians, &self.axes, cells, self.glossy_order, self.table_spacing, |w| {
                let l = self.radiance(w);
                [l.x as f64, l.y as f64, l.z as f64]
            })
        });
        let order = split.order;
        let k = order.coeffs();
        let ng = face_forward(si.n, si.wo);
        let mut v = [glam::DVec3::ZERO; 3];
        let mut lsh = [0.0f64; 3 * glossy::MAX_COEFFS];
        let m = &self.meridians;
        let traversed = self.visible(scene, si, ng, stats, |frame, iv| {
            let i = iv.meridian as usize;
            table.add(frame, m, i, iv.lo, iv.hi, &mut v);
            sh_table.add(frame, i, iv.lo, iv.hi, order, &mut lsh[..3 * k]);
        });
        if !traversed {
            return None;
        }
        let e = if split.diffuse != Rgb::ZERO {
            irradiance_over_pi(face_forward(bsdf.shading_normal(), ng).as_dvec3(), &v, m.dphi)
        } else {
            Rgb::ZERO
        };
        lsh[..3 * k].iter_mut().for_each(|a| *a *= m.dphi);
        Some((e, glossy::shade(split, bsdf, si.wo, ng, &lsh[..3 * k])))
    }

    /// The infinite lights' radiance from direction `w` (world).
    fn radiance(&self, w: glam::DVec3) -> Rgb {
        let ray = Ray::new(Vec3::ZERO, w.as_vec3(), f32::INFINITY);
        self.infinite.iter().map(|l| l.le(&ray)).sum()
    }
}

impl PixelEstimator for Estimator<'_> {
    type Shared = SharedPixel<ClusterValue>;
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov } = cx;
        match self.mode {
            Mode::Ao | Mode::Prt => self.ao(ray, scene, stats, aov),
            Mode::Shade => self.shade(ray, scene, sampler, stats, 0),
        }
    }

    /// Pixel shading for `ao` and `shade` (`prt`'s transfer channels are per sample).
    fn shares_pixel_work(&self) -> bool {
        self.pixel_shading && self.mode != Mode::Prt
    }

    /// `prt`'s SH transfer is weighted as the AO value is (the albedo is not).
    fn weight_channels(&self, aov: &mut [f32], w: f32) {
        if let Some((order, ..)) = &self.sh {
            TransferChannels::new(*order, 0).weight(aov, w);
        }
    }

    fn begin_pixel(
        &self,
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Option<Self::Shared> {
        // Only the infinite lights are shared, so no cluster is near a light.
        Some(SharedPixel::trace(
            rays,
            samples,
            scene,
            stats,
            |_, _| Refine::COMPARE,
            Some(difference),
            |p: &SurfacePoint, stats: &mut ThreadStats| match self.mode {
                Mode::Shade => {
                    let hit = p.with_bsdf(scene)?;
                    let kind = self.env_kind(scene, &hit)?;
                    Some(self.env_terms(&kind, &hit, scene, stats))
                }
                _ => Some(Some((self.ao_at(&p.si, p.si.wo, scene, stats, &mut []), Rgb::ZERO))),
            },
        ))
    }

    fn li_shared(&self, ray: &RayDifferential, cx: SampleContext, shared: &Self::Shared, index: usize) -> Rgb {
        let SampleContext { scene, sampler, stats, aov } = cx;
        if self.mode == Mode::Shade {
            return shared
                .shade_sample(index, scene, |hit, env| self.shade_hit(ray, hit, env, scene, sampler, stats, 0));
        }
        match shared.sample(index) {
            (Ok(_), Some(Some((ao, _)))) => ao,
            (Ok(p), _) => self.ao_at(&p.si, -ray.d, scene, stats, aov),
            (Err(_), _) => Rgb::ZERO,
        }
    }
}

/// The dual-edge hierarchy over `scene`'s objects that occlude.
fn dual_edges(scene: &Scene) -> DualEdges {
    let occluders: Vec<bool> = scene.objects.iter().map(|o| o.occluder).collect();
    DualEdges::build(&scene.meshes, &occluders)
}

/// The hierarchy prepared with the scene (`build_scene`), or built into `slot` for a scene
/// built without it.
fn prepared_dual_edges<'a>(scene: &'a Scene, slot: &'a mut Option<DualEdges>) -> &'a DualEdges {
    match scene.prepared::<DualEdges>() {
        Some(d) => d,
        None => slot.insert(dual_edges(scene)),
    }
}

impl Integrator for Silhouette {
    /// Sample shading, or `prt` (whose samples never share).
    fn merges_sample_ranges(&self) -> bool {
        !self.pixel_shading || self.mode == Some(Mode::Prt)
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    /// The dual-edge hierarchy over the objects that occlude.
    fn prepare(&self, scene: &Scene) -> Option<Preparation> {
        let d = dual_edges(scene);
        Some(Preparation {
            stage: "dual edges".into(),
            summary: format!(
                "{} edges ({} boundary, {} non-manifold, {} tested at every point)",
                d.edge_count(),
                d.boundary_edges,
                d.non_manifold_edges,
                d.always_tested()
            ),
            details: Vec::new(),
            value: Arc::new(d),
        })
    }
    /// The probe of [`cost`]: contour edges per point and the render's time against
    /// `ambientocclusion`'s.
    fn estimates_cost(&self) -> bool {
        true
    }
    /// Nothing for a scene the render refuses (cut-outs, curves, moving occluders).
    fn estimate_cost(&self, scene: &Scene, threads: usize) -> Option<CostEstimate> {
        scene.non_polygonal_occluder().is_none().then(|| cost::estimate(self, scene, threads))
    }
    fn extra_channels(&self) -> Vec<String> {
        match self.mode {
            Some(Mode::Prt) => TransferChannels::new(self.sh_order, 0).names(),
            _ => Vec::new(),
        }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        crate::common::refuse_cutouts("silhouette", "visibility silhouettes (the meshes' dual edges)", scene)?;
        let mut built = None;
        let dual = prepared_dual_edges(scene, &mut built);
        let infinite: Vec<&Light> = scene.light_list().iter().filter(|l| l.is_infinite()).collect();
        let mode = self.mode.unwrap_or_else(|| default_mode(scene, ctx.warnings));
        if mode == Mode::Shade && infinite.len() < scene.light_list().len() {
            ctx.warnings.warn(
                None,
                if infinite.is_empty() {
                    "silhouette: the scene has no \"infinite\" light, the only kind silhouette integrates: its lights \
                     (area, point, spot, distant…) are all shaded with directlighting's estimator"
                } else {
                    "silhouette: lights other than \"infinite\" (area, point, spot, distant…) are shaded with \
                     directlighting's estimator"
                },
            );
        }
        if mode == Mode::Prt {
            warn_prt_lights(scene, ctx.warnings);
            warn_prt_materials(scene, ctx.warnings);
        }
        let meridians = Meridians::new(self.resolution);
        let table_spacing = table_spacing(&infinite);
        let axes = integration_axes(&infinite);
        let table = (mode == Mode::Shade && !infinite.is_empty()).then(|| {
            MomentTable::build(&meridians, &axes, self.resolution, table_spacing, |w| {
                let ray = Ray::new(Vec3::ZERO, w.as_vec3(), f32::INFINITY);
                let l: Rgb = infinite.iter().map(|l| l.le(&ray)).sum();
                [l.x as f64, l.y as f64, l.z as f64]
            })
        });
        let sh = (mode == Mode::Prt).then(|| {
            // Per interval the integrand is a trigonometric polynomial of degree ≤ order + 1 in
            // θ (the clamp is inactive in the visible hemisphere); 2n + 6 Gauss nodes leave
            // ~1e-12 over a quarter meridian at order 3.
            let (x, w) = gauss_legendre(2 * self.sh_order.n() + 6);
            (self.sh_order, x, w)
        });
        let est = Estimator {
            mode,
            max_depth: self.max_depth,
            dual,
            meridians,
            axes,
            table,
            sh,
            infinite,
            glossy_order: self.glossy_order,
            table_spacing,
            sh_table: OnceLock::new(),
            counters: Counters::default(),
            pixel_shading: self.pixel_shading,
            fallback: FallbackWarning::new("silhouette", ctx.warnings),
        };
        let mut stats = render_pixels(&est, scene, ctx, film)?;
        let c = &est.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64;
        let points = get(&c.points).max(1.0);
        stats.counters.insert("silhouette.points".into(), get(&c.points));
        stats.counters.insert("silhouette.contours_per_point".into(), get(&c.contours) / points);
        stats.counters.insert("silhouette.examined_per_point".into(), get(&c.examined) / points);
        stats.counters.insert("silhouette.nodes_per_point".into(), get(&c.nodes) / points);
        stats.counters.insert("silhouette.crossings_per_point".into(), get(&c.crossings) / points);
        stats.counters.insert("silhouette.occluded_points".into(), get(&c.occluded_points));
        stats.counters.insert("silhouette.estimator_fallbacks".into(), get(&c.estimator_fallbacks));
        stats.counters.insert("silhouette.fallbacks".into(), get(&c.fallbacks));
        stats.counters.insert("silhouette.glossy_points".into(), get(&c.glossy_points));
        Ok(stats)
    }
}
