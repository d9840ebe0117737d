//! `shexp`: environment soft shadows from sphere-set occluders by SH exponentiation — seed 003
//! (Guerrero's thesis restating Ren et al. 2006, "Real-time soft shadows in dynamic scenes using
//! spherical harmonic exponentiation"), as an offline, noise-free CPU integrator.
//!
//! At the first non-specular surface, the Lambertian part of the BSDF (albedo `ρ`) under the
//! scene's `infinite` lights is `ρ/π · LH(N) · V` ([`lighting`], [`visibility`]):
//! - `V = exp*(Σ_i G_{θ_i} turned to ω_i) ∗ Π_big B_θ` over the leaf spheres of every
//!   occluder ([`sphereset`], built by [`Integrator::prepare`]), each adjusted by
//!   the receiver-inside rules; caps wider than `"float bigblocker"` are multiplied explicitly;
//! - `LH(N)`: the exact order-n projection of `L · max(0, N·ω)`, with the environment cut at
//!   the ground plane's horizon when the scene has one (an open planar mesh under everything);
//! - the result is clamped to `[0, LH(N)·1]` (between black and unshadowed);
//! - plus, when the ground plane is finite, the environment below the horizon that passes
//!   its edge ([`horizon`], in closed form along each azimuth; not shadowed by the spheres).
//!
//! Open meshes other than the ground plane (open quadrics, partial spheres, disks, open
//! triangle meshes) have no inside for spheres to bound: their shadows are traced ([`open`]:
//! per camera sample, a direction drawn by the term above and one ray against them, so that
//! the estimate is `S · V_o(ω)`, noise-free where they block nothing; one warning names each),
//! or with `"string openmeshes" "shells"` bounded by conservative sphere shells. Receivers
//! behind the ground plane (an object through the floor) take the environment through
//! `directlighting`'s estimator (one warning). What SH at low order cannot carry, and what is not Lambertian, goes
//! through `directlighting`'s estimator (`common::direct::estimate_direct`, one warning): the
//! non-Lambertian lobes under the infinite lights, every other light (area, point, spot,
//! distant) with the full BSDF, and perfectly specular lobes recursively up to `maxdepth`.
//!
//! Parameters (also `--param`):
//! - `"integer order"` 4: SH order `n` (1–8).
//! - `"string exp"` `"ss"`: `exp*` by scaling and squaring; `"ol"` optimal linear, `"hyb"`
//!   hybrid (for comparison).
//! - `"integer spheres"` 32: leaf spheres per fitted closed mesh.
//! - `"float bigblocker"` 45: caps wider than this (degrees) are multiplied explicitly.
//! - `"integer lhresolution"` 32: normal cubemap texels per face edge for `LH(N)`.
//! - `"integer maxdepth"` 5: specular recursion depth, as `directlighting`.
//! - `"integer brightlights"` 4: at most this many bright compact regions of each map are
//!   shaded with shadow rays instead of SH ([`bright`]; 0: the whole map is projected to SH).
//! - `"float brightratio"` 2, `"float brightradius"` 75: a region is split off while its peak
//!   is at least this many times the map's mean luminance; its largest radius (degrees).
//! - `"integer brightsamples"` 1: shadow rays per split region and camera sample.
//! - `"string brightestimator"` `"ratio"`: a split region's light is its unshadowed irradiance
//!   (tabulated over the normal) times the visible share of directions drawn by power × cosine
//!   (unbiased, and exact wherever the region is wholly seen or hidden); `"plain"`: directions
//!   drawn by power, each weighted by its cosine.
//! - `"bool interreflect"` false: the thesis's one-bounce diffuse reflection off the closed
//!   objects' sphere sets ([`reflect`]): `ρ/π · E^R` is added to the Lambertian part.
//! - `"string formfactor"` `"exact"`: how a reflecting sphere's radiance reaches a receiver
//!   ([`reflect::tables::FormFactor`]); `"thesis"`: eqs. 4.24 and 4.32 as written.
//! - `"bool groundbounce"` true: with `interreflect`, the ground plane reflects its shadowed
//!   light onto what stands on it ([`reflect::ground`]; not in the thesis).
//! - `"string openmeshes"` `"trace"`: open meshes' shadows traced ([`open`]); `"shells"`:
//!   through conservative sphere shells (noise-free, too dark near and inside them).
//! - `"integer opensamples"` 1: traced-visibility directions per camera sample.

pub mod bright;
pub mod cubemap;
pub mod horizon;
pub mod lighting;
pub mod open;
pub mod reflect;
pub mod sphereset;
pub mod visibility;

use crate::common::direct::{estimate_direct, specular};
use crate::common::other_lights::FallbackWarning;
use crate::common::params::{ParamSpec, Params, Range};
use crate::common::pixel_shading::{parse_shading, rgb_difference, Blend, Refine, SharedPixel, SHADING};
use crate::common::{max_depth, max_depth_param, pixel_bounds_param, PIXEL_BOUNDS};
use glam::DVec3;
use lighting::EnvLighting;
use penumbra_core::bxdf::{Bsdf, Bxdf, BxdfFlags};
use penumbra_core::camera::CameraSample;
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds2i, Ray, RayDifferential};
use penumbra_core::integrator::{
    render_pixels, with_threads, Integrator, PixelEstimator, Preparation, RenderContext, RenderError, RenderStats,
    SampleContext, ThreadStats,
};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::Light;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit, SurfacePoint};
use penumbra_core::sh::ShOrder;
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use sphereset::{OpenMeshes, Source, SphereSets};
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use visibility::{ExpChoice, Visibility};

pub struct Shexp {
    pub order: ShOrder,
    pub exp: ExpChoice,
    pub spheres: u32,
    /// Radians.
    pub big_theta: f64,
    pub lh_resolution: usize,
    /// Bright regions split off each environment map and shaded with shadow rays.
    pub bright: bright::SplitRule,
    /// Shadow rays per split region per camera sample.
    pub bright_samples: u32,
    /// `"string brightestimator"` `ratio` (default): the region's unshadowed irradiance times
    /// the visible share of directions drawn by power × cosine; `plain`: power-sampled
    /// directions weighted by their cosine.
    pub bright_ratio: bool,
    pub max_depth: u32,
    pub pixel_bounds: Option<Bounds2i>,
    /// One bounce of diffuse reflection off the sphere-set objects ([`reflect`]).
    pub interreflect: bool,
    /// How a reflecting sphere's radiance reaches a receiver.
    pub form_factor: reflect::tables::FormFactor,
    /// With `interreflect`, the ground plane reflects too ([`reflect::ground`]).
    pub ground_bounce: bool,
    /// `"string shading"` `pixel` (default): the environment's Lambertian term once per
    /// surface a pixel sees ([`crate::common::pixel_shading`]); `sample`: every camera sample.
    pub pixel_shading: bool,
    /// `"string openmeshes"`: open meshes' shadows traced ([`open`]) or through shells.
    pub open_meshes: OpenMeshes,
    /// `"integer opensamples"`: traced-visibility draws per camera sample.
    pub open_samples: u32,
}

/// The parameters `shexp` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::int("order", 4, "SH order of visibility and lighting (n² coefficients)").range(1, 8),
    ParamSpec::choice(
        "exp",
        &["ss", "ol", "hyb"],
        "SH exponential: scaling and squaring, optimal linear, or the hybrid",
    )
    .strict(),
    ParamSpec::int("spheres", 32, "leaves of a closed mesh's sphere-set fit").range(1, 4096),
    ParamSpec::float("bigblocker", 45.0, "caps wider than this (degrees) are multiplied in as SH products")
        .within(Range::LeftOpen(0.0, 90.0)),
    ParamSpec::int("lhresolution", 32, "normal-cubemap texels per face for the projection of L·max(0, N·ω)")
        .range(1, 256),
    ParamSpec::int("brightlights", 4, "bright compact regions of each environment map split off and shaded with shadow rays")
        .range(0, 64),
    ParamSpec::float(
        "brightratio",
        bright::PEAK_RATIO as f32,
        "a bright region is split off only if its peak is this many times the map's mean luminance",
    )
    .within(Range::PositiveFinite),
    ParamSpec::float("brightradius", 75.0, "largest angular radius (degrees) of a split bright region")
        .within(Range::LeftOpen(0.0, 90.0)),
    ParamSpec::int(
        "brightsamples",
        1,
        "shadow rays per split bright region and camera sample, in directions drawn over the region",
    )
    .range(1, 1024),
    ParamSpec::choice(
        "brightestimator",
        &["ratio", "plain"],
        "split regions: unshadowed irradiance × visible share of power·cosine-drawn directions (exact where all or none is seen), or power-drawn directions × cosine",
    )
    .strict(),
    ParamSpec::bool(
        "interreflect",
        false,
        "one bounce of diffuse light off the closed objects' sphere sets (seed 003 §4.3) onto the Lambertian part",
    ),
    ParamSpec::choice(
        "formfactor",
        &["exact", "thesis"],
        "interreflect: how a sphere's radiance reaches a receiver: exact for a lone sphere, or the thesis's eqs. 4.24 and 4.32",
    )
    .strict(),
    ParamSpec::bool(
        "groundbounce",
        true,
        "interreflect: the ground plane reflects its shadowed direct light onto what stands on it (not in the thesis)",
    ),
    ParamSpec::choice(
        "openmeshes",
        &["trace", "shells"],
        "open meshes other than the ground plane (open quadrics, disks, open triangle meshes): their shadows traced exactly by rays, or through conservative sphere shells (noise-free, overshadowing)",
    )
    .strict(),
    ParamSpec::int("opensamples", 1, "traced open-mesh visibility: directions drawn per camera sample").range(1, 1024),
    max_depth(1024),
    PIXEL_BOUNDS,
    SHADING,
];

impl Shexp {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("shexp", PARAMS, params, warnings);
        let order = ShOrder::new(p.count("order")? as usize).map_err(|e| Diagnostic::error(None, e.to_string()))?;
        let exp = p.choice("exp", [ExpChoice::ScalingSquaring, ExpChoice::OptimalLinear, ExpChoice::Hybrid])?;
        let spheres = p.count("spheres")?;
        let big = p.float("bigblocker")?;
        let lh_resolution = p.count("lhresolution")? as usize;
        let bright = bright::SplitRule {
            max_lights: p.count("brightlights")? as usize,
            peak_ratio: p.float("brightratio")? as f64,
            max_radius: (p.float("brightradius")? as f64).to_radians(),
        };
        let bright_samples = p.count("brightsamples")?;
        let bright_ratio = p.choice("brightestimator", [true, false])?;
        let interreflect = p.bool("interreflect")?;
        let form_factor =
            p.choice("formfactor", [reflect::tables::FormFactor::Exact, reflect::tables::FormFactor::Thesis])?;
        let ground_bounce = p.bool("groundbounce")?;
        let max_depth = max_depth_param(&p)?;
        let pixel_bounds = pixel_bounds_param(&p)?;
        let pixel_shading = parse_shading(&p)?;
        let open_meshes = p.choice("openmeshes", [OpenMeshes::Trace, OpenMeshes::Shells])?;
        let open_samples = p.count("opensamples")?;
        Ok(Box::new(Shexp {
            pixel_shading,
            open_meshes,
            open_samples,
            order,
            exp,
            spheres,
            big_theta: (big as f64).to_radians(),
            lh_resolution,
            bright,
            bright_samples,
            bright_ratio,
            max_depth,
            pixel_bounds,
            interreflect,
            form_factor,
            ground_bounce,
        }))
    }
}

/// Splits a BSDF into its Lambertian reflection albedo and the rest (same frame).
fn split_lambertian(bsdf: &Bsdf) -> (Rgb, Option<Bsdf>) {
    let mut kd = Rgb::ZERO;
    let ss = bsdf.local_to_world(Vec3::X);
    let mut rest = Bsdf::new(bsdf.shading_normal(), ss, bsdf.geometric_normal(), bsdf.eta);
    let mut any = false;
    for b in bsdf.bxdfs() {
        match b {
            Bxdf::LambertianReflection { r } => kd += *r,
            other => {
                any |= rest.add(*other).is_ok();
            }
        }
    }
    (kd, any.then_some(rest))
}

struct Estimator<'a> {
    shexp: &'a Shexp,
    vis: Visibility,
    env: Option<EnvLighting>,
    /// The environment under the horizon beyond the ground plane's edge ([`horizon`]).
    gap: Option<horizon::HorizonGap>,
    sets: &'a SphereSets,
    infinite: Vec<usize>,
    others: Vec<usize>,
    bright: Vec<bright::BrightLight>,
    reflect: Option<reflect::Reflectors>,
    ground: Option<reflect::ground::GroundBounce>,
    /// The open meshes whose shadows are traced, and the directions drawn for them ([`open`]).
    traced: Option<open::TracedObjects>,
    proposal: Option<open::EnvProposal>,
    warn_behind: AtomicBool,
    warnings: &'a DiagSink,
    /// Names the materials whose non-Lambertian lobes take the environment through the estimator.
    fallback: FallbackWarning<'a>,
    /// Evaluations of the smooth environment term ([`Estimator::lambertian_irradiance`]).
    receivers: AtomicU64,
}

/// The largest `n²` (order 8).
const MAX_COEFFS: usize = 64;

/// The environment's smooth light on a receiver's Lambertian lobes, over π, as pixel shading
/// shares it: the part open meshes can block (the SH term, the light under the horizon past the
/// ground plane's edge), the rest (the ground's and the spheres' reflected light), and the
/// sphere-set visibility `V` the traced open meshes' estimate draws by (zero without them).
#[derive(Clone, Copy, Debug)]
struct EnvValue {
    open: Rgb,
    rest: Rgb,
    v: [f32; MAX_COEFFS],
}

impl Blend for EnvValue {
    fn blend(&self, other: &Self, w: f32) -> Self {
        let mut v = self.v;
        for (a, b) in v.iter_mut().zip(other.v) {
            *a = *a * (1.0 - w) + b * w;
        }
        EnvValue { open: self.open.blend(&other.open, w), rest: self.rest.blend(&other.rest, w), v }
    }
}

/// Per-thread buffers: visibility scratch, `V`, `LH(N)`, a basis scratch and `LH_below(N)`.
type ShadeScratch = (visibility::Scratch, Vec<f64>, Vec<[f64; 3]>, Vec<f64>, Vec<f64>);

thread_local! {
    static SCRATCH: RefCell<Option<ShadeScratch>> = const { RefCell::new(None) };
    static REFLECT_SCRATCH: RefCell<Option<reflect::Scratch>> = const { RefCell::new(None) };
}

impl Estimator<'_> {
    /// `∫ L V max(0, n·ω) dω` per channel at `p` (shexp's approximation, clamped); with
    /// `ground`, plus the ground plane's light of that radiance through the same `V`
    /// ([`reflect::ground`]).
    fn shadowed(&self, p: DVec3, n: DVec3, object: usize, ground: Option<[f64; 3]>) -> [f64; 3] {
        let (open, rest) = self.shadowed_parts(p, n, object, ground, None);
        [0, 1, 2].map(|c| open[c] + rest[c])
    }

    /// [`Self::shadowed`] in two parts: what open meshes can block (the SH term and the light
    /// under the horizon past the ground plane's edge), and the ground plane's light; the
    /// visibility vector `V` into `v_out` (its first `n²` entries) when given.
    fn shadowed_parts(
        &self,
        p: DVec3,
        n: DVec3,
        object: usize,
        ground: Option<[f64; 3]>,
        v_out: Option<&mut [f32]>,
    ) -> ([f64; 3], [f64; 3]) {
        let Some(env) = &self.env else { return ([0.0; 3], [0.0; 3]) };
        let k = self.vis.order().coeffs();
        SCRATCH.with(|cell| {
            let mut cell = cell.borrow_mut();
            let (s, v, lh, tmp, below) = cell.get_or_insert_with(|| {
                (self.vis.scratch(), vec![0.0; k], vec![[0.0; 3]; k], vec![0.0; k], vec![0.0; k])
            });
            if v.len() != k {
                *s = self.vis.scratch();
                *v = vec![0.0; k];
                *lh = vec![[0.0; 3]; k];
                *tmp = vec![0.0; k];
                *below = vec![0.0; k];
            }
            env.lh(n, lh, tmp);
            self.vis.vector_for_scene(p, n, object, self.sets, s, v);
            let mut out = [0.0; 3];
            for c in 0..3 {
                let shadowed: f64 = lh.iter().zip(v.iter()).map(|(l, vi)| l[c] * vi).sum();
                let unshadowed = lh[0][c] * penumbra_core::sh::SQRT_4PI;
                out[c] = if shadowed.is_finite() { shadowed.clamp(0.0, unshadowed.max(0.0)) } else { 0.0 };
            }
            if let Some(gap) = &self.gap {
                for (o, e) in out.iter_mut().zip(gap.irradiance(p, n)) {
                    *o += e;
                }
            }
            if let Some(v_out) = v_out {
                for (o, x) in v_out.iter_mut().zip(v.iter()) {
                    *o = *x as f32;
                }
            }
            let mut rest = [0.0; 3];
            if let (Some(g), Some(radiance)) = (&self.ground, ground) {
                rest = g.irradiance((p, n), radiance, v, below, tmp);
            }
            (out, rest)
        })
    }

    /// The radiance of the ground plane as a receiver at `p` (unit normal `n`) sees it: the
    /// plane's albedo/π times its shadowed irradiance (the direct term, the bright regions
    /// with shadow rays) averaged over [`reflect::ground::GroundBounce::seen_points`].
    fn ground_radiance(&self, p: DVec3, n: DVec3, scene: &Scene, shadow_rays: &mut u64) -> Option<[f64; 3]> {
        let g = self.ground.as_ref()?;
        let k = self.vis.order().coeffs();
        let (mut lh, mut tmp) = (vec![0.0; k], vec![0.0; k]);
        let Some(points) = g.seen_points(p, n, &mut lh, &mut tmp) else { return Some(g.radiance) };
        let up = g.plane.normal;
        let mut sum = [0.0; 3];
        for q in points {
            let mut e = self.shadowed(q, up, g.plane.object, None);
            // Off the plane by a distance relative to the receiver's.
            let origin = (q + up * (1e-5 * (p - q).length())).as_vec3();
            for b in &self.bright {
                let c = up.dot(b.dir);
                if c <= 0.0 {
                    continue;
                }
                *shadow_rays += 1;
                if !scene.occluded(&Ray::new(origin, b.dir.as_vec3(), f32::INFINITY)) {
                    for (ec, bc) in e.iter_mut().zip(b.irradiance) {
                        *ec += bc * c;
                    }
                }
            }
            for (sc, ec) in sum.iter_mut().zip(e) {
                *sc += ec.max(0.0) / points.len() as f64;
            }
        }
        Some([0, 1, 2].map(|c| g.albedo[c] * sum[c] * std::f64::consts::FRAC_1_PI))
    }

    /// Adds to `e` the irradiance per channel from the split-off bright regions at `si` (unit
    /// shading normal `n`, on the side of `side` by the geometric normal). With `sampler`:
    /// `"brightsamples"` shadow rays per region in directions drawn over it
    /// ([`bright::BrightLight::sample`]), so a wide region casts soft shadows; without (the
    /// bounce's precomputations): one ray towards its power's centroid.
    fn add_bright(
        &self,
        e: &mut [f64; 3],
        si: &SurfaceInteraction,
        (n, side): (Vec3, Vec3),
        scene: &Scene,
        shadow_rays: &mut u64,
        mut sampler: Option<&mut dyn Sampler>,
    ) {
        // Whether direction `d` reaches the region (above both normals' sides, unoccluded).
        let visible = |d: Vec3, shadow_rays: &mut u64| {
            if n.dot(d) <= 0.0 || si.n.dot(d) * si.n.dot(side) <= 0.0 {
                return false;
            }
            *shadow_rays += 1;
            !scene.occluded(&si.spawn_ray(d))
        };
        let nd = n.as_dvec3().normalize();
        for b in &self.bright {
            match sampler.as_deref_mut() {
                Some(sampler) => {
                    let k = self.shexp.bright_samples.max(1);
                    for _ in 0..k {
                        let u = sampler.get_2d();
                        let mut vis = |d: DVec3| visible(d.as_vec3(), shadow_rays);
                        let x = if self.shexp.bright_ratio {
                            b.estimate(nd, [u.x, u.y], &mut vis)
                        } else {
                            b.estimate_plain(nd, [u.x, u.y], &mut vis)
                        };
                        for (v, x) in e.iter_mut().zip(x) {
                            *v += x / k as f64;
                        }
                    }
                }
                None => {
                    let d = b.dir.as_vec3();
                    if visible(d, shadow_rays) {
                        let c = n.dot(d) as f64;
                        for (v, x) in e.iter_mut().zip(b.irradiance) {
                            *v += x * c;
                        }
                    }
                }
            }
        }
    }

    /// The reflected irradiance `E^R` at `p` (zero without `"interreflect"`).
    fn reflected(&self, p: DVec3, n: DVec3, object: usize) -> [f64; 3] {
        let Some(r) = &self.reflect else { return [0.0; 3] };
        REFLECT_SCRATCH.with(|cell| {
            let mut cell = cell.borrow_mut();
            if !cell.as_ref().is_some_and(|s| r.fits(s)) {
                *cell = Some(r.scratch(&self.vis));
            }
            match cell.as_mut() {
                Some(s) => r.irradiance(&self.vis, self.sets, p, n, object, s),
                None => [0.0; 3],
            }
        })
    }

    /// The white-albedo outgoing radiance of a sphere's surface sample point (pass 1 of the
    /// bounce): the same direct term as a receiver's Lambertian part, over π.
    fn sample_radiance(
        &self,
        sample: &reflect::surface::SurfaceSample,
        scene: &Scene,
        shadow_rays: &mut u64,
    ) -> [f64; 3] {
        let si = &sample.si;
        let mut e = self.shadowed(si.p.as_dvec3(), sample.n, si.mesh as usize, None);
        let n = sample.n.as_vec3();
        self.add_bright(&mut e, si, (n, n), scene, shadow_rays, None);
        e.map(|v| v * std::f64::consts::FRAC_1_PI)
    }

    fn li(
        &self,
        ray: &RayDifferential,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let (first, queries) = scene.first_surface(ray);
        stats.rays += queries.saturating_sub(1);
        match first {
            Ok(hit) => self.shade_hit(ray, &hit, None, scene, sampler, stats, depth),
            Err(escaped) => escaped,
        }
    }

    /// The environment's smooth light on the Lambertian lobes at `hit`, over π (the caller
    /// multiplies it by the albedo): shadowed by the sphere sets, with the ground's and, with
    /// `interreflect`, the spheres' reflected light. `None` without an environment, or behind
    /// the ground plane ([`Self::behind_ground`]). The split bright regions are not in it
    /// ([`Self::bright_irradiance`]), nor the traced objects' shadows ([`Self::traced_share`]).
    fn lambertian_irradiance(&self, hit: &SurfaceHit, scene: &Scene, stats: &mut ThreadStats) -> Option<EnvValue> {
        self.env.as_ref()?;
        if self.behind_ground(&hit.si) {
            return None;
        }
        self.receivers.fetch_add(1, Ordering::Relaxed);
        let (n, p) = (Self::facing_normal(hit), hit.si.p.as_dvec3());
        let nd = n.as_dvec3().normalize();
        let ground = self.ground_radiance(p, nd, scene, &mut stats.shadow_rays);
        let mut value = EnvValue { open: Rgb::ZERO, rest: Rgb::ZERO, v: [0.0; MAX_COEFFS] };
        let v_out = self.traced.is_some().then_some(&mut value.v[..]);
        let (open, mut rest) = self.shadowed_parts(p, nd, hit.si.mesh as usize, ground, v_out);
        if self.reflect.is_some() {
            for (v, rv) in rest.iter_mut().zip(self.reflected(p, nd, hit.si.mesh as usize)) {
                *v += rv;
            }
        }
        let rgb = |e: [f64; 3]| Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32) * std::f32::consts::FRAC_1_PI;
        value.open = rgb(open);
        value.rest = rgb(rest);
        Some(value)
    }

    /// Whether the receiver at `si` lies behind the ground plane (an object through the floor):
    /// the environment cut at the plane's horizon is not what it sees, so `shade_hit` takes the
    /// infinite lights through `directlighting`'s estimator there.
    fn behind_ground(&self, si: &SurfaceInteraction) -> bool {
        let Some(g) = self.sets.ground.filter(|g| g.behind) else { return false };
        let p = si.p.as_dvec3();
        si.mesh as usize != g.object && g.is_behind(p, 1e-5 * (p - g.point).length())
    }

    /// Per channel, the share of `value.open` that the traced objects leave at `hit`:
    /// `"opensamples"` draws of [`open::EnvProposal::factor`], averaged (1 without traced
    /// objects; the sampler's dimensions are taken whenever the scene has some).
    fn traced_share(
        &self,
        hit: &SurfaceHit,
        value: &EnvValue,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let (Some(traced), Some(proposal)) = (&self.traced, &self.proposal) else { return Rgb::ONE };
        let k = self.shexp.open_samples.max(1);
        let us: Vec<[f32; 2]> = (0..k)
            .map(|_| {
                let u = sampler.get_2d();
                [u.x, u.y]
            })
            .collect();
        let si = &hit.si;
        let (n, p) = (Self::facing_normal(hit).as_dvec3().normalize(), si.p.as_dvec3());
        if !traced.may_block(p, n) {
            return Rgb::ONE;
        }
        let order = self.vis.order();
        let receiver = open::Receiver {
            p,
            n,
            v: &value.v[..order.coeffs()],
            order,
            ground: self.sets.ground.map(|g| (g.normal, self.gap.as_ref())),
        };
        let model = [value.open.x, value.open.y, value.open.z].map(|v| v as f64 * std::f64::consts::PI);
        let wo_side = si.n.dot(si.wo);
        let mut blocked = |d: DVec3| {
            let d32 = d.as_vec3();
            // Below the geometric surface the Lambertian lobe gets nothing from any ray; not a
            // traced object's shadow.
            if si.n.dot(d32) * wo_side <= 0.0 || !traced.may_meet(p, d) {
                return false;
            }
            let (b, queries) = traced.blocked(scene, si.spawn_ray(d32));
            stats.shadow_rays += queries;
            b
        };
        let mut sum = [0.0; 3];
        for u in us {
            for (s, f) in sum.iter_mut().zip(proposal.factor(&receiver, model, u, &mut blocked)) {
                *s += f / k as f64;
            }
        }
        Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32)
    }

    /// The split-off bright regions' light on the Lambertian lobes at `hit`, over π: one
    /// shadow ray each, per sample (their shadows are hard; the other lobes see the whole map
    /// through directlighting's estimator).
    fn bright_irradiance(
        &self,
        hit: &SurfaceHit,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let mut e = [0.0; 3];
        let side = (Self::facing_normal(hit), hit.si.wo);
        self.add_bright(&mut e, &hit.si, side, scene, &mut stats.shadow_rays, Some(sampler));
        Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32) * std::f32::consts::FRAC_1_PI
    }

    /// The shading normal turned to the side `wo` is on.
    fn facing_normal(hit: &SurfaceHit) -> Vec3 {
        let ns = hit.bsdf.shading_normal();
        if ns.dot(hit.si.wo) < 0.0 {
            -ns
        } else {
            ns
        }
    }

    /// Radiance from `hit`, the `depth`-th surface of a camera ray's specular chain;
    /// `irradiance` is its pixel cluster's [`Self::lambertian_irradiance`] when pixel shading
    /// computed it already.
    #[allow(clippy::too_many_arguments)]
    fn shade_hit(
        &self,
        ray: &RayDifferential,
        hit: &SurfaceHit,
        irradiance: Option<EnvValue>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let SurfaceHit { si, bsdf, le, .. } = hit;
        let mut l = *le;
        let lights = scene.light_list();
        if self.env.is_some() && self.behind_ground(si) {
            if !self.warn_behind.swap(true, Ordering::Relaxed) {
                self.warnings.warn(
                    None,
                    "shexp: surfaces behind the ground plane (objects through the floor) take the environment through \
                     directlighting's estimator",
                );
            }
            for &i in &self.infinite {
                let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                l += estimate_direct(si, bsdf, u_scatter, i, &lights[i], u_light, scene, stats);
            }
            return l + self.others_and_specular(ray, hit, scene, sampler, stats, depth);
        }
        let (kd, rest) = split_lambertian(bsdf);
        if kd != Rgb::ZERO && self.env.is_some() {
            let smooth = match irradiance.or_else(|| self.lambertian_irradiance(hit, scene, stats)) {
                Some(e) => e.open * self.traced_share(hit, &e, scene, sampler, stats) + e.rest,
                None => Rgb::ZERO,
            };
            l += kd * (smooth + self.bright_irradiance(hit, scene, sampler, stats));
        }
        if let Some(rest) = &rest {
            if rest.num_components(BxdfFlags::NON_SPECULAR) > 0 && !self.infinite.is_empty() {
                let name = scene.material_of(si).map_or("none", |(m, _, _)| m.type_name());
                self.fallback.material(name, "non-Lambertian lobes", "the environment");
                for &i in &self.infinite {
                    let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                    l += estimate_direct(si, rest, u_scatter, i, &lights[i], u_light, scene, stats);
                }
            }
        }
        l + self.others_and_specular(ray, hit, scene, sampler, stats, depth)
    }

    /// The lights other than the infinite ones (`directlighting`'s estimator) and the perfectly
    /// specular lobes, recursively.
    #[allow(clippy::too_many_arguments)]
    fn others_and_specular(
        &self,
        ray: &RayDifferential,
        hit: &SurfaceHit,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        depth: u32,
    ) -> Rgb {
        let SurfaceHit { si, bsdf, .. } = hit;
        let lights = scene.light_list();
        let mut l = Rgb::ZERO;
        for &i in &self.others {
            let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
            l += estimate_direct(si, bsdf, u_scatter, i, &lights[i], u_light, scene, stats);
        }
        if depth + 1 < self.shexp.max_depth {
            for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                l += specular(si, bsdf, ray, sampler, stats, kind, |r, sampler, stats| {
                    self.li(r, scene, sampler, stats, depth + 1)
                });
            }
        }
        l
    }
}

impl Estimator<'_> {
    /// The bounce's precomputation and pass 1, with the rays and shadow rays they cast.
    fn build_reflectors(
        &self,
        scene: &Scene,
        cancel: &AtomicBool,
    ) -> (Result<reflect::Reflectors, penumbra_core::sh::ShError>, (u64, u64)) {
        let surfaces = reflect::Surfaces::build(scene, self.sets, self.vis.order(), cancel);
        let shadow_rays = std::sync::atomic::AtomicU64::new(0);
        let shade = |sample: &reflect::surface::SurfaceSample| {
            let mut n = 0;
            let v = self.sample_radiance(sample, scene, &mut n);
            shadow_rays.fetch_add(n, Ordering::Relaxed);
            v
        };
        let r = reflect::Reflectors::build(self.sets, &surfaces, self.shexp.form_factor, &shade);
        (r, (surfaces.rays, shadow_rays.into_inner()))
    }
}

impl PixelEstimator for Estimator<'_> {
    type Shared = SharedPixel<EnvValue>;
    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        self.li(ray, scene, sampler, stats, 0)
    }

    /// Pixel shading where there is an environment to share.
    fn shares_pixel_work(&self) -> bool {
        self.shexp.pixel_shading && self.env.is_some()
    }

    fn begin_pixel(
        &self,
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Option<Self::Shared> {
        // Only the environment's term is shared, so no cluster is near a light.
        let shade = |p: &SurfacePoint, stats: &mut ThreadStats| {
            let hit = p.with_bsdf(scene)?;
            (split_lambertian(&hit.bsdf).0 != Rgb::ZERO).then(|| self.lambertian_irradiance(&hit, scene, stats))?
        };
        let difference = |a: &EnvValue, b: &EnvValue| rgb_difference(a.open + a.rest, b.open + b.rest);
        Some(SharedPixel::trace(rays, samples, scene, stats, |_, _| Refine::COMPARE, Some(difference), shade))
    }

    fn li_shared(&self, ray: &RayDifferential, cx: SampleContext, shared: &Self::Shared, index: usize) -> Rgb {
        let SampleContext { scene, sampler, stats, aov: _ } = cx;
        shared.shade_sample(index, scene, |hit, e| self.shade_hit(ray, hit, e, scene, sampler, stats, 0))
    }
    fn pixel_bounds(&self) -> Option<Bounds2i> {
        self.shexp.pixel_bounds
    }
}

impl Shexp {
    /// The sphere sets of `scene`'s occluders with this integrator's `"integer spheres"`
    /// (fits read from and written to the disk cache).
    fn sphere_sets(&self, scene: &Scene) -> SphereSets {
        let params = sphereset::fit::FitParams { spheres: self.spheres, ..Default::default() };
        let dir = sphereset::cache::default_dir();
        sphereset::build_for_scene(&scene.meshes, &scene.objects, &params, self.open_meshes, dir.as_deref())
    }
}

impl Integrator for Shexp {
    /// Sample shading (pixel shading shares the environment's term between a pixel's samples;
    /// without an environment it shares nothing, but that is known only at render time).
    fn merges_sample_ranges(&self) -> bool {
        !self.pixel_shading
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    /// The sphere sets of the occluders.
    fn prepare(&self, scene: &Scene) -> Option<Preparation> {
        let sets = self.sphere_sets(scene);
        Some(Preparation {
            stage: "sphere sets".into(),
            summary: sets.summary(),
            details: sets.describe(&scene.objects),
            value: Arc::new(sets),
        })
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        crate::common::refuse_cutouts("shexp", "visibility (sphere sets fitted to the meshes)", scene)?;
        // Prepared with the scene (`build_scene`), or built here for a scene built without it.
        let built;
        let sets =
            match scene.prepared::<SphereSets>().filter(|s| s.spheres == self.spheres && s.open == self.open_meshes) {
                Some(s) => s,
                None => {
                    built = self.sphere_sets(scene);
                    &built
                }
            };
        for s in sets.sets.iter().filter(|s| s.source == Source::Shell) {
            ctx.warnings.warn(
                scene.objects.get(s.object).map(|o| o.loc.clone()),
                format!(
                    "shexp: open mesh \"{}\" cannot be bounded as a solid: it casts shadows through {} conservative \
                     sphere shells",
                    scene.objects.get(s.object).map(|o| o.kind.as_str()).unwrap_or("?"),
                    s.leaves.len()
                ),
            );
        }
        for &i in &sets.traced {
            ctx.warnings.warn(
                scene.objects.get(i).map(|o| o.loc.clone()),
                format!(
                    "shexp: open mesh \"{}\" has no inside for sphere sets to bound: its shadows are traced (\"integer \
                     opensamples\" rays per camera sample and receiver that may see it)",
                    scene.objects.get(i).map(|o| o.kind.as_str()).unwrap_or("?"),
                ),
            );
        }
        let lights = scene.light_list();
        let infinite: Vec<usize> = (0..lights.len()).filter(|&i| lights[i].is_infinite()).collect();
        let others: Vec<usize> = (0..lights.len()).filter(|&i| !lights[i].is_infinite()).collect();
        if !others.is_empty() {
            ctx.warnings.warn(
                None,
                "shexp: lights other than \"infinite\" (area, point, spot, distant…) are shaded with directlighting's \
                 estimator",
            );
        }
        if self.interreflect && (infinite.is_empty() || !others.is_empty()) {
            ctx.warnings.warn(
                None,
                "shexp: \"interreflect\" bounces the \"infinite\" lights only: other lights are not reflected",
            );
        }
        let vis = Visibility::new(self.order, self.exp, self.big_theta)
            .map_err(|e| RenderError::Failed(format!("shexp: {e}")))?;
        let mut bright_lights = Vec::new();
        let mut gap = None;
        let (mut traced, mut proposal) = (None, None);
        let env = if infinite.is_empty() {
            None
        } else {
            let mut sources = Vec::new();
            for &i in &infinite {
                if let Light::Infinite(il) = &lights[i] {
                    let (src, b) = bright::split(il, self.bright);
                    sources.push(src);
                    bright_lights.extend(b);
                }
            }
            let ground = sets.ground.map(|g| g.normal);
            gap = sets
                .ground
                .and_then(|g| scene.meshes.get(g.object).and_then(|m| horizon::HorizonGap::build(&sources, g, m)));
            if !sets.traced.is_empty() {
                traced = Some(open::TracedObjects::new(&scene.meshes, &sets.traced));
                proposal = Some(open::EnvProposal::build(&sources));
            }
            Some(with_threads(ctx.threads, || EnvLighting::build(&sources, ground, self.order, self.lh_resolution))?)
        };
        let mut est = Estimator {
            shexp: self,
            vis,
            env,
            gap,
            sets,
            infinite,
            others,
            bright: bright_lights,
            reflect: None,
            ground: None,
            traced,
            proposal,
            warn_behind: AtomicBool::new(false),
            warnings: ctx.warnings,
            fallback: FallbackWarning::new("shexp", ctx.warnings),
            receivers: AtomicU64::new(0),
        };
        let mut pass = (0, 0);
        if let (true, true, Some(env), Some(plane)) = (self.interreflect, self.ground_bounce, &est.env, sets.ground) {
            est.ground = with_threads(ctx.threads, || {
                reflect::ground::GroundBounce::build(scene, plane, env, &est.bright, self.order)
            })?;
        }
        if self.interreflect && est.env.is_some() {
            let (r, rays) = with_threads(ctx.threads, || est.build_reflectors(scene, ctx.cancel))?;
            if ctx.cancel.load(Ordering::Relaxed) {
                return Err(RenderError::Cancelled);
            }
            let r = r.map_err(|e| RenderError::Failed(format!("shexp: {e}")))?;
            // Nothing reflects (albedo 0, or no closed object): the image is the direct one.
            est.reflect = (r.reflecting() > 0).then_some(r);
            pass = rays;
        }
        let mut stats = render_pixels(&est, scene, ctx, film)?;
        stats.rays += pass.0;
        stats.shadow_rays += pass.1;
        stats.counters.insert("leaf spheres".into(), sets.leaf_count() as f64);
        stats.counters.insert("bright lights".into(), est.bright.len() as f64);
        stats.counters.insert("shexp.receivers".into(), est.receivers.load(Ordering::Relaxed) as f64);
        stats.counters.insert("shexp.traced_objects".into(), sets.traced.len() as f64);
        if let Some(r) = &est.reflect {
            stats.counters.insert("reflecting spheres".into(), r.reflecting() as f64);
        }
        Ok(stats)
    }
}
