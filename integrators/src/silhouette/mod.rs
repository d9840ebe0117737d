//! `silhouette`: semi-analytic spherical integration along visibility silhouettes (seed 000:
//! Nowrouzezahrai, Baran, Mitchell & Jarosz, "Visibility Silhouettes for Semi-Analytic
//! Spherical Integration", CGF 2014).
//!
//! At each shading point the contour edges come from the scene's 4D dual-edge hierarchy
//! (`core::silhouette::DualEdges`, built under `Requirements::dual_edges`), culled behind the
//! tangent plane; their arcs are bucketed on `"integer resolution"` meridians of the
//! `(φ, cos θ)` parameterisation about the coordinate axis closest to the normal, each
//! meridian is walked from the pole with the relative depth complexity `W`, and one shadow
//! ray through the longest interval of minimal `W` decides whether those intervals are the
//! visible ones (else the point sees nothing). The integrand is integrated exactly in `v`
//! over the visible intervals; only the azimuth is discretised (and, for environment maps,
//! the radiance, in prefix-sum tables along the meridians).
//!
//! Modes (`"string mode"`):
//! - `ao` (default without an infinite light): pbrt-v3's `ambientocclusion` value, the
//!   integral of `V·cos θ` over the hemisphere of the face-forwarded geometric normal
//!   (π for an open hemisphere), from the analytic moment `∫ ω dω` of the visible intervals.
//! - `shade` (default with an infinite light): Lambertian materials under infinite lights by
//!   the vector irradiance `v = ∫ L V H ω dω` (the band-1 formulation: 3 tables per colour),
//!   radiance `ρ/π · n_s·v`; the visible set is the hemisphere of the face-forwarded
//!   geometric normal (pbrt-v3's reflection test), the cosine that of the shading normal
//!   (signed: it differs from pbrt-v3's `|cos|` only where the two normals disagree).
//!   Materials with a glossy lobe or no Lambertian form take the infinite lights through
//!   `directlighting`'s estimator (counted as `"silhouette.estimator_fallbacks"`). Area,
//!   point, spot and distant lights are always added by that estimator, and perfectly
//!   specular materials recurse as in `directlighting` (up to `"integer maxdepth"`, 5).

use crate::common::direct::{estimate_direct, specular};
use crate::common::max_depth_param;
use penumbra_core::bxdf::BxdfFlags;
use penumbra_core::film::Film;
use penumbra_core::geometry::{face_forward, offset_ray_origin, Ray};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, ThreadStats,
};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::Light;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit};
use penumbra_core::silhouette::{param::moment, Contour, DualEdges, Meridians, MomentTable, PoleFrame, Traversal};
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Ao,
    Shade,
}

/// The tangent-plane cull's tolerance: edges below an elevation of ~1e-6 rad are dropped
/// (the normal is given in f32; coplanar neighbours of the shading point lie there).
const CULL_TOL: f64 = 1e-6;

pub struct Silhouette {
    /// `None`: `shade` when the scene has an infinite light, else `ao`.
    pub mode: Option<Mode>,
    /// `"integer resolution"` (√k): meridians, and table cells per meridian.
    pub resolution: usize,
    pub max_depth: u32,
}

impl Silhouette {
    pub fn create(params: &ParamSet, _warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let mode = match params.get_one_string("mode", "").as_str() {
            "" => None,
            "ao" => Some(Mode::Ao),
            "shade" => Some(Mode::Shade),
            other => {
                return Err(Diagnostic::error(
                    params.loc_of("mode").cloned(),
                    format!("silhouette: unknown \"mode\" \"{other}\" (expected \"ao\" or \"shade\")"),
                ))
            }
        };
        let resolution = params.get_one_int("resolution", 128);
        if !(4..=4096).contains(&resolution) {
            return Err(Diagnostic::error(
                params.loc_of("resolution").cloned(),
                format!("\"resolution\" must be in 4..=4096, got {resolution}"),
            ));
        }
        let max_depth = max_depth_param(params, 1024)?;
        Ok(Box::new(Silhouette { mode, resolution: resolution as usize, max_depth }))
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
    crossings: AtomicU64,
    occluded_points: AtomicU64,
    estimator_fallbacks: AtomicU64,
}

struct Estimator<'a> {
    mode: Mode,
    max_depth: u32,
    dual: &'a DualEdges,
    meridians: Meridians,
    /// The infinite lights' radiance moments (`shade`).
    table: Option<MomentTable>,
    counters: Counters,
}

/// What the visible part of a point's hemisphere integrates to.
enum Visible {
    /// `∫_{V·H} ω dω` (world axes).
    Moment(glam::DVec3),
    /// `∫_{V·H} L ω dω` per colour.
    Radiance([glam::DVec3; 3]),
}

impl Estimator<'_> {
    /// Integrates over the visible part of the hemisphere of `n` (unit, world) at `si`.
    fn visible(&self, scene: &Scene, si: &SurfaceInteraction, n: Vec3, stats: &mut ThreadStats) -> Visible {
        let dual = self.dual;
        // Offset off the surface by its error bound, as rays are: the surface itself and its
        // coplanar neighbours are then strictly behind the tangent plane, never contours.
        let p = dual.normalise(offset_ray_origin(si.p, si.p_error, n, n));
        let nd = n.as_dvec3().normalize();
        let frame = PoleFrame::for_normal(nd);
        let m = &self.meridians;
        SCRATCH.with_borrow_mut(|s| {
            s.contours.clear();
            dual.contours(p, nd, CULL_TOL, &mut s.contours);
            let vis = s.traversal.run(&s.contours, p, nd, &frame, m);
            self.counters.points.fetch_add(1, Ordering::Relaxed);
            self.counters.contours.fetch_add(s.contours.len() as u64, Ordering::Relaxed);
            self.counters.crossings.fetch_add(vis.crossings as u64, Ordering::Relaxed);
            // The intervals of minimal relative W are the visible ones iff one ray through the
            // longest of them escapes (inside a closed box no edge is a contour, W is 1
            // everywhere, and only the ray tells).
            stats.shadow_rays += 1;
            let occluded = scene.occluded(&si.spawn_ray(vis.probe.as_vec3()));
            if occluded {
                self.counters.occluded_points.fetch_add(1, Ordering::Relaxed);
            }
            let min_w = vis.min_w;
            match &self.table {
                Some(t) => {
                    let mut out = [glam::DVec3::ZERO; 3];
                    if !occluded {
                        for iv in s.traversal.with_w(min_w) {
                            t.add(&frame, m, iv.meridian as usize, iv.lo, iv.hi, &mut out);
                        }
                    }
                    Visible::Radiance(out.map(|v| v * m.dphi))
                }
                None => {
                    let mut out = glam::DVec3::ZERO;
                    if !occluded {
                        for iv in s.traversal.with_w(min_w) {
                            out += moment(&frame, m, iv.meridian as usize, iv.lo, iv.hi);
                        }
                    }
                    Visible::Moment(out * m.dphi)
                }
            }
        })
    }

    fn ao(&self, ray: &Ray, scene: &Scene, stats: &mut ThreadStats) -> Rgb {
        let mut ray = *ray;
        for _ in 0..64 {
            let Some(hit) = scene.intersect(&ray) else { return Rgb::ZERO };
            let si = scene.interaction(&ray, &hit);
            if scene.objects[hit.mesh as usize].material.is_none() {
                ray = si.spawn_ray(ray.d);
                stats.rays += 1;
                continue;
            }
            let n = face_forward(si.n, -ray.d);
            let Visible::Moment(v) = self.visible(scene, &si, n, stats) else { return Rgb::ZERO };
            return Rgb::splat(n.as_dvec3().dot(v).max(0.0) as f32);
        }
        Rgb::ZERO
    }

    fn shade(&self, ray: &Ray, scene: &Scene, sampler: &mut dyn Sampler, stats: &mut ThreadStats, depth: u32) -> Rgb {
        let (first, queries) = scene.first_surface(ray);
        stats.rays += queries - 1;
        let hit = match first {
            Ok(h) => h,
            Err(escaped) => return escaped,
        };
        let SurfaceHit { si, bsdf, le, .. } = &hit;
        let mut l = *le;
        let lambertian = self.table.as_ref().and_then(|_| {
            let (material, _, textures) = scene.material_of(si)?;
            let d = material.ltc_lobes(si, textures)?;
            d.specular.is_none().then_some(d)
        });
        for (k, light) in scene.light_list().iter().enumerate() {
            if light.is_infinite() && lambertian.is_some() {
                continue;
            }
            if light.is_infinite() {
                self.counters.estimator_fallbacks.fetch_add(1, Ordering::Relaxed);
            }
            let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
            l += estimate_direct(si, bsdf, u_scatter, k, light, u_light, scene, stats);
        }
        if let Some(d) = lambertian {
            let ng = face_forward(si.n, si.wo);
            if let Visible::Radiance(v) = self.visible(scene, si, ng, stats) {
                // pbrt-v3's |cos| with the shading normal: on the visible side.
                let ns = face_forward(d.n, ng).as_dvec3();
                let e = Rgb::new(ns.dot(v[0]) as f32, ns.dot(v[1]) as f32, ns.dot(v[2]) as f32);
                l += d.diffuse * e.max(Rgb::ZERO) * std::f32::consts::FRAC_1_PI;
            }
        }
        if depth + 1 < self.max_depth {
            for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
                l += specular(si, bsdf, sampler, stats, kind, |r, sampler, stats| {
                    self.shade(r, scene, sampler, stats, depth + 1)
                });
            }
        }
        l
    }
}

impl PixelEstimator for Estimator<'_> {
    fn li(
        &self,
        ray: &Ray,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        _aov: &mut [f32],
    ) -> Rgb {
        match self.mode {
            Mode::Ao => self.ao(ray, scene, stats),
            Mode::Shade => self.shade(ray, scene, sampler, stats, 0),
        }
    }
}

impl Integrator for Silhouette {
    fn name(&self) -> &str {
        "silhouette"
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, dual_edges: true, ..Default::default() }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        let dual = scene
            .dual_edges
            .as_ref()
            .ok_or_else(|| RenderError::Failed("silhouette: the scene was built without its dual edges".into()))?;
        let infinite: Vec<&Light> = scene.light_list().iter().filter(|l| l.is_infinite()).collect();
        let mode = self.mode.unwrap_or(if infinite.is_empty() { Mode::Ao } else { Mode::Shade });
        let meridians = Meridians::new(self.resolution);
        let table = (mode == Mode::Shade && !infinite.is_empty()).then(|| {
            MomentTable::build(&meridians, self.resolution, |w| {
                let ray = Ray::new(Vec3::ZERO, w.as_vec3(), f32::INFINITY);
                let l: Rgb = infinite.iter().map(|l| l.le(&ray)).sum();
                [l.x as f64, l.y as f64, l.z as f64]
            })
        });
        let est = Estimator { mode, max_depth: self.max_depth, dual, meridians, table, counters: Counters::default() };
        let mut stats = render_pixels(&est, scene, ctx, film)?;
        let c = &est.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64;
        let points = get(&c.points).max(1.0);
        stats.counters.insert("silhouette.points".into(), get(&c.points));
        stats.counters.insert("silhouette.contours_per_point".into(), get(&c.contours) / points);
        stats.counters.insert("silhouette.crossings_per_point".into(), get(&c.crossings) / points);
        stats.counters.insert("silhouette.occluded_points".into(), get(&c.occluded_points));
        stats.counters.insert("silhouette.estimator_fallbacks".into(), get(&c.estimator_fallbacks));
        Ok(stats)
    }
}
