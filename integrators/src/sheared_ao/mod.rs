//! `sheared-ao`: sparse ray-traced ambient occlusion with the sheared, rotationally-invariant
//! filter of seed 002 (`../shared/seeds/002_*`: Egan, Durand & Ramamoorthi 2011, "Practical
//! Filtering for Efficient Ray-Traced Directional Occlusion"; digest
//! `../shared/notes/002-sheared-ao.md`).
//!
//! Output convention: `ambientocclusion`'s (pbrt-v3's): ∫ V cosθ dω over the hemisphere of the
//! face-forwarded geometric normal, in [0, π], 0 where the camera ray escapes; surfaces
//! without a material are passed through.
//!
//! * **Pass 1** ([`sample_pass`]): every camera sample of every pixel in the film's sample
//!   bounds *plus a margin of `screenradius` pixels* (clamped to the full image) is a shading
//!   point; it shoots `nsamples` cosine-distributed occlusion rays (no distance cap) and keeps
//!   them in an image-space cache (point, normal, pixel footprint, ray directions, hit
//!   distances and hit normals). The margin makes a crop or a tile see exactly the neighbours of the full image.
//! * **Pass 2** ([`filter::filter_receiver`]): the cached rays of every point within
//!   `screenradius` pixels (a disk) on the same surface are warped to effective rays from the
//!   receiver, binned into `cells × cells` hemisphere cells of equal projected area, weighted by
//!   the sheared filter and normalised per cell; cells with too little weight or too close
//!   occluders take `brutesamples` fresh rays each, stratified in the cell (2D samples hashed
//!   from a per-sample seed, [`brute_sample`], so only the cells brute-forced cost anything).
//!   AO = (π / cells²) Σ_c V̄_c. With `"string shading" "pixel"` (default) the receiver is
//!   one camera sample per surface a pixel sees ([`pixel_clusters`]: the member nearest the
//!   cluster's mean film position), whose filtered cells every member shares; each member still
//!   brute-forces its own contact cells from its own point. With `"sample"` every camera sample
//!   is a receiver (the paper's per-shading-point filter).
//! * **SH** (`"bool sh" "true"`, order `"integer shorder"`, 5): the transfer
//!   `Σ_c V̄_c K_c`, `K_c = ∫_c max(0, n·ω) Y(ω) dω` per cell ([`filter::cell_transfer`], exact
//!   to rounding), turned from the receiver's frame to world space, in channels `sh.*` with the
//!   diffuse albedo in `albedo.*` (`core::sh::transfer`'s convention, as `ambientocclusion`'s):
//!   `sh.0 = Y_0 · AO` sample by sample, the clamped cosine's `Â_l Y_lm(n)` where unoccluded.
//! * **Rays** (`stats.json`): the integrator is its own driver and counts every ray once:
//!   per pass-1 camera sample (crop *and* margin) its camera ray, pass-throughs and `nsamples`
//!   cached rays; per pass-2 camera sample (crop only) `brutesamples` rays per brute-forced
//!   cell and no camera ray. So with `P` pass-1 and `C` pass-2 camera samples and a brute-forced
//!   fraction `f`: rays (camera rays) = `P` (+ pass-throughs), shadow rays
//!   `P nsamples + C f cells² brutesamples` (`tests/conformance.rs`,
//!   `tests/sheared_ao.rs::a_crop_counts_its_margin_rays_once`). (The occlusion rays were
//!   counted in both before, and the margin's camera rays in neither.)
//!
//! Parameters: [`PARAMS`], beside [`ShearedAo::create`] (`maxpoints` caps the cache points
//! per receiver, nearest pixels first; `warp`: see [`filter::Warp`]).
//!
//! Choices the paper leaves open (see also [`filter`]):
//! * kernel: `(1 − t²/1.5²)⁴` of t = |x| / r, within 0.044 of the Gaussian exp(−2t²) truncated
//!   at 1.5 used before (same bias and RMSE to the table's precision) without a square root or
//!   an exponential;
//! * pixel shading (measured below and in the README): the filter, not the rays, is the cost
//!   (80 % of the instructions), and a pixel's camera samples see nearly the same neighbourhood,
//!   so sharing one filtered result per surface and pixel cuts pass 2 by the spp; contact cells
//!   stay per sample, where sub-pixel changes of the visibility are largest;
//! * Ω_pix^max = 0.5 / footprint, footprint = the larger side of the pixel's footprint on the
//!   receiver's tangent plane (camera rays one pixel over); with Eq. 8 the spatial radius is
//!   `z_min z_max / (Ω_v (z_max − z_min))` and the contact test `z_min < 2 Ω_v · footprint`;
//! * `nsamples` 8 by measurement (README table, `tools/sheared_ao_table.py`): per ray within
//!   10–20 % of the most efficient of 4/8/16/32 and the smallest bias of the four; the error
//!   floor is the brute-forced cells' single rays, which more pass-1 rays do not cut;
//! * `maxpoints` 64 by measurement (64², 4 spp, against `ambientocclusion` at 1024 rays on the
//!   same camera samples; callgrind instructions of the render): RMSE² × instructions, lower is
//!   better, spheres-on-plane / blinds: 256 points 7.3e-4 / 3.9e-3, 128 points 5.2e-4 / 1.8e-3,
//!   64 points 4.4e-4 / 1.15e-3, 32 points 5.0e-4 / 1.2e-3 (more cells brute-forced) — a wider
//!   neighbourhood lowers the noise less than it costs, and adds reprojection bias (blinds
//!   +0.27 % at 64 points);
//! * the depth bounds count open sky: a cell where some neighbour ray (unwarped direction)
//!   escaped has `z_max = ∞`, so radius `z_min / Ω_v` — its visibility has an edge between an
//!   occluder and infinity, and the occluders alone (one depth: an infinite radius)
//!   understate its bandwidth. Bias against `ambientocclusion` at 1024 rays on the same camera
//!   samples (64², 4 spp, `nsamples` 8): blinds −0.30 % → −0.21 %, spheres-on-plane −0.064 % →
//!   −0.044 %, same rays; RMSE 0.0449 → 0.0406, 0.0115 → 0.0113;
//! * occluded neighbour rays are weighted by the Jacobian of their warp through the hit
//!   surface ([`filter::occluded_jacobian`]), so that they arrive with the receiver's cosine
//!   density: without it they are over-represented where the warp compresses directions, and
//!   the image darkens. Same measurement, on top of the line above: blinds −0.21 % → −0.02 %,
//!   RMSE 0.0406 → 0.0371; spheres-on-plane −0.044 % → +0.041 %, 0.0113 → 0.0115. Weighting
//!   unoccluded rays through the sphere too overcorrects (blinds +0.44 %): their targets lie on
//!   no real surface;
//! * the bias floor that remains is a few tenths of a percent of either sign (README: +0.32 %
//!   at 32², −0.07 % at 1 spp on blinds); it comes from the reprojection (it grows with the
//!   neighbourhood, `maxpoints` 1024: −0.30 %) and does not fall with `nsamples`;
//! * a cell with no occluded neighbour ray is not brute-forced: its depth is taken as
//!   infinite (no warp, infinite radius: every ray weighs 1); only a cell whose weight stays
//!   below `minweight` is;
//! * cells combine as equal projected solid angles π / cells²: the mean visibility of each
//!   cell (filtered or brute-forced) times π / cells²;
//! * unoccluded rays are warped through the sphere of the receiver's harmonic mid depth
//!   ([`filter::Warp::Sphere`]) rather than the paper's per-cell plane, whose discontinuity at
//!   cell edges darkens: image means −0.65 % / −1.36 % (`cell`) against −0.07 % / −0.38 %
//!   (`sphere`) of pbrt-v3's references on `suite/ao/spheres-on-plane` / `blinds` (64², 4 spp,
//!   `nsamples` 8, `tests/sheared_ao.rs`; before the two changes above; with them blinds is
//!   −0.91 % (`cell`) against −0.02 % against same-sample MC);
//! * `maxdistance`: a hit farther than it from the *receiver* counts as a miss;
//! * neighbours: normal within ~26° and within a slope of 0.25 (+ one footprint) of the
//!   receiver's tangent plane; grazing warps (cos < 1e-3) are rejected.

pub mod sheared_filter;

use crate::common::image_pass::ImageBuffer;
use crate::common::params::{ParamSpec, Params, Range};
use crate::common::pixel_shading::parse_shading;
use crate::common::SH_TRANSFER;
use glam::{IVec2, Vec2};
use penumbra_core::camera::CameraSample;
use penumbra_core::film::Film;
use penumbra_core::geometry::{face_forward, offset_ray_origin, Bounds2i, Frame, Ray, RayDifferential};
use penumbra_core::integrator::{
    draw_camera_sample, tiles, with_threads, Integrator, RenderContext, RenderError, RenderStats,
};
use penumbra_core::rng::hash_words;
use penumbra_core::sampler::Sampler;
use penumbra_core::sampling::cosine_sample_hemisphere;
use penumbra_core::scene::{Requirements, Scene};
use penumbra_core::sh::{rotation::ShRotation, transfer::TransferChannels, ShOrder};
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use rayon::prelude::*;
use sheared_filter::{CachePoint, CachedRay, CellValue, FilterParams, Receiver, Scratch, Warp};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

pub struct ShearedAo {
    pub nsamples: u32,
    /// Neighbour window radius in pixels; also pass 1's margin around the sampled pixels.
    pub screen_radius: u32,
    pub brute_samples: u32,
    /// At most this many cache points (nearest pixels first) lend their rays to a receiver.
    pub max_points: u32,
    pub filter: FilterParams,
    /// The order of the SH transfer channels, when they are written (`"bool sh"`).
    pub sh: Option<ShOrder>,
    /// `"string shading" "pixel"`: one receiver per surface seen in a pixel.
    pub pixel_shading: bool,
}

/// `"string shading"`: `sheared-ao`'s own sense of pixel shading (the filter once per surface,
/// not [`crate::common::pixel_shading::shade_clusters`]'s shading points).
const SHADING: ParamSpec = ParamSpec::choice(
    "shading",
    &["pixel", "sample"],
    "filter once per surface a pixel sees (each camera sample keeps its own brute-forced cells), or at every camera sample",
);

/// The parameters `sheared-ao` reads.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec::int("nsamples", 8, "occlusion rays per camera sample, cached in image space (rounded by the sampler)")
        .range(1, 1024),
    ParamSpec::int("screenradius", 8, "receivers borrow the cached rays of points within this many pixels")
        .range(0, 64),
    ParamSpec::int("cells", 8, "cells × cells hemisphere cells of equal projected area").range(1, 32),
    ParamSpec::float("omegav", 2.0, "the filter's Ω_v (Eq. 8): larger gives smaller spatial radii")
        .within(Range::Positive),
    ParamSpec::float("minweight", 2.0, "a cell whose filter weight stays below this takes fresh rays")
        .within(Range::Positive),
    ParamSpec::int("brutesamples", 1, "fresh rays per brute-forced cell, stratified in the cell").range(1, 64),
    ParamSpec::int("maxpoints", 64, "at most this many cache points (nearest pixels first) per receiver")
        .range(1, 1 << 20),
    ParamSpec::float("maxdistance", f32::INFINITY, "occluders farther than this are ignored (as ambientocclusion)")
        .within(Range::Positive),
    ParamSpec::choice(
        "warp",
        &["sphere", "cell"],
        "unoccluded rays warped through the sphere of the harmonic mid depth, or the paper's per-cell plane",
    ),
    ParamSpec::bool(
        "jacobian",
        true,
        "occluded neighbour rays weighted by the Jacobian of their warp through the hit surface",
    ),
    SH_TRANSFER,
    SH_ORDER_DEFAULT_5,
    SHADING,
];

/// `"integer shorder"` with default 5 (the other integrators' is 3): relit under the studio map
/// (`scenes/relight/spheres-on-plane-studio.pbrt`, killeroo-simple's geometry all matte) order
/// 3 is 2.9–4.0 % below `directlighting`'s mean, order 4 −0.9 / −3.2 %, order 5 −1.3 / −0.6 %:
/// the truncation of the map (an unoccluded plane under it: −3.5 % at order 3, −1.0 % at 5, with
/// an exact transfer), not of the visibility (docs/integrators/sheared-ao.md).
const SH_ORDER_DEFAULT_5: ParamSpec = ParamSpec::int(
    "shorder",
    5,
    "order of the sh.* transfer channels (n² coefficients; 5: relit within 2 % of directlighting's mean)",
)
.range(1, penumbra_core::sh::MAX_ORDER as i32);

impl ShearedAo {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let p = Params::new("sheared-ao", PARAMS, params, warnings);
        let sh = if p.bool("sh")? {
            Some(ShOrder::new(p.count("shorder")? as usize).map_err(|e| Diagnostic::error(None, e.to_string()))?)
        } else {
            None
        };
        Ok(Box::new(ShearedAo {
            sh,
            pixel_shading: parse_shading(&p)?,
            nsamples: p.count("nsamples")?,
            screen_radius: p.count("screenradius")?,
            brute_samples: p.count("brutesamples")?,
            max_points: p.count("maxpoints")?,
            filter: FilterParams {
                cells: p.count("cells")? as usize,
                omega_v: p.float("omegav")? as f64,
                min_weight: p.float("minweight")? as f64,
                max_distance: p.float("maxdistance")? as f64,
                warp: p.choice("warp", [Warp::Sphere, Warp::Cell])?,
                jacobian: p.bool("jacobian")?,
            },
        }))
    }
}

/// A pass-1 shading point: the cache entry and what brute-force rays need to leave it.
#[derive(Clone, Debug)]
pub struct Shading {
    pub point: CachePoint,
    p: Vec3,
    p_error: Vec3,
    n: Vec3,
    frame: Frame,
    /// The diffuse albedo (only with `"bool sh"`).
    albedo: Rgb,
    /// The camera ray's time (brute-force rays see moving shapes where it saw them).
    time: f32,
}

/// One camera sample of pass 1: where it lands on the film, the seed of its brute-force rays,
/// and its shading point (`None`: the camera ray escaped).
#[derive(Clone, Debug)]
pub struct CacheSample {
    p_film: Vec2,
    brute_seed: u64,
    shading: Option<Shading>,
    /// The camera ray's weight (pbrt-v3's `GenerateRay`: 1 except for the `realistic`
    /// camera); the sample's AO and SH transfer are multiplied by it. A ray of weight 0 is not
    /// traced: no shading point, black.
    weight: f32,
}

/// The 2D sample of brute-force ray `k` of cell `cell` of a receiver whose seed is `seed`: a
/// hash, so that only the cells pass 2 brute-forces cost anything (from the sampler, all
/// `cells² × brutesamples` of them were drawn for every camera sample, twice: 14 % of the
/// instructions of a render). With `m` rays per cell they are stratified in `x`.
fn brute_sample(seed: u64, cell: usize, k: usize, m: usize) -> Vec2 {
    let h = hash_words(&[seed, cell as u64, k as u64]);
    let unit = |bits: u64| (bits >> 40) as f32 * (1.0 / (1u64 << 24) as f32);
    Vec2::new((k as f32 + unit(h)) / m as f32, unit(h << 24)).min(Vec2::splat(1.0 - f32::EPSILON / 2.0))
}

/// Rays traced: camera rays with their pass-throughs (queries of the closest hit along the camera
/// ray) and occlusion rays (pass 1's cached rays, pass 2's brute-force rays).
#[derive(Clone, Copy, Debug, Default)]
struct RayCount {
    camera: u64,
    occlusion: u64,
}

impl RayCount {
    fn add_to(self, total: &Mutex<RayCount>) {
        let mut t = total.lock().unwrap_or_else(|e| e.into_inner());
        t.camera += self.camera;
        t.occlusion += self.occlusion;
    }
}

/// Keeps a 2D sample off the border of the unit square, where the concentric map puts the
/// direction on the horizon (z = 0; QMC samplers produce exact 0s): the cosine-distributed
/// direction always has z ≥ 2e-3, so every sample becomes a ray and the counts are closed forms.
fn open_square(u: Vec2) -> Vec2 {
    const E: f32 = 1e-6;
    u.clamp(Vec2::splat(E), Vec2::splat(1.0 - E))
}

/// The camera sample of pixel `p` as `render_pixels` draws it.
fn camera_sample(scene: &Scene, sampler: &mut dyn Sampler, p: IVec2) -> CameraSample {
    draw_camera_sample(sampler, p, scene.uses_time(), scene.camera.uses_lens())
}

impl ShearedAo {
    /// Pass 1 for one camera sample: the first surface with a material and its cached rays
    /// (`None`: the ray escaped). `us` are the occlusion rays' 2D samples.
    fn shade(
        &self,
        scene: &Scene,
        cs: &CameraSample,
        camera_ray: &RayDifferential,
        us: &[Vec2],
        rays: &mut RayCount,
    ) -> Option<Shading> {
        let mut ray = camera_ray.ray;
        for pass in 0..64 {
            rays.camera += 1;
            let hit = scene.intersect(&ray)?;
            let mut si = scene.interaction(&ray, &hit);
            if scene.objects[hit.mesh as usize].material.is_none() {
                ray = si.spawn_ray(ray.d);
                continue;
            }
            // The camera ray's differentials, for the albedo's texture lookups.
            if pass == 0 {
                si.compute_differentials(camera_ray);
            }
            let n = face_forward(si.n, -ray.d);
            let frame = Frame::from_zx(n, si.dpdu);
            let pd = si.p.as_dvec3();
            let footprint = footprint(scene, cs, pd, n.as_dvec3());
            let mut cached = Vec::with_capacity(us.len());
            for &u in us {
                let wi = frame.from_local(cosine_sample_hemisphere(open_square(u)));
                let r = si.spawn_ray(wi);
                rays.occlusion += 1;
                let d = wi.as_dvec3().normalize();
                let (t, n_hit) = match scene.intersect(&r) {
                    Some(h) => (
                        (r.o.as_dvec3() + h.t as f64 * r.d.as_dvec3() - pd).dot(d).max(0.0),
                        scene.interaction(&r, &h).n.as_dvec3(),
                    ),
                    None => (f64::INFINITY, glam::DVec3::ZERO),
                };
                cached.push(CachedRay { d, t, n_hit });
            }
            return Some(Shading {
                point: CachePoint::new(pd, n.as_dvec3(), footprint, &cached),
                p: si.p,
                p_error: si.p_error,
                n,
                frame,
                albedo: if self.sh.is_some() { crate::common::diffuse_albedo(scene, &si) } else { Rgb::ZERO },
                time: si.time,
            });
        }
        None
    }

    /// Pass 2's filter for one receiver: every cell's filtered visibility, or
    /// [`CellValue::Brute`], into `scratch.cells`.
    fn filter(&self, recv: &Shading, neighbours: &[&CachePoint], scratch: &mut PassScratch) {
        let f = &recv.point;
        let frame = Frame { x: recv.frame.x.as_dvec3(), y: recv.frame.y.as_dvec3(), z: f.n };
        let receiver = Receiver { p: f.p, frame, footprint: f.footprint };
        let PassScratch { filter: fs, cells, .. } = scratch;
        sheared_filter::filter_receiver(&receiver, neighbours.iter().copied(), &self.filter, fs, cells);
    }

    /// The mean visibility of every cell at shading point `at` into `scratch.vbar`: the
    /// filtered value of `scratch.cells`, or for a cell the filter left to brute force the
    /// fraction of `brutesamples` fresh rays from `at` (stratified in the cell, seeded by
    /// `brute_seed`, [`brute_sample`]) that escape. Returns the number of brute-forced cells.
    #[allow(clippy::too_many_arguments)]
    fn resolve(
        &self,
        scene: &Scene,
        at: &Shading,
        frame: &Frame,
        brute_seed: u64,
        scratch: &mut PassScratch,
        rays: &mut RayCount,
    ) -> usize {
        let nside = self.filter.cells;
        let m = self.brute_samples as usize;
        let mut brute = 0usize;
        let PassScratch { cells, vbar, .. } = scratch;
        vbar.clear();
        for (c, v) in cells.iter().enumerate() {
            vbar.push(match *v {
                CellValue::Filtered(v) => v,
                CellValue::Brute => {
                    brute += 1;
                    let mut unoccluded = 0usize;
                    for k in 0..m {
                        let xi = brute_sample(brute_seed, c, k, m);
                        let u = Vec2::new(
                            ((c % nside) as f32 + xi.x) / nside as f32,
                            ((c / nside) as f32 + xi.y) / nside as f32,
                        );
                        let wi = frame.from_local(cosine_sample_hemisphere(open_square(u)));
                        let r = Ray::new(
                            offset_ray_origin(at.p, at.p_error, at.n, wi),
                            wi,
                            self.filter.max_distance as f32,
                        )
                        .at_time(at.time);
                        rays.occlusion += 1;
                        if !scene.occluded(&r) {
                            unoccluded += 1;
                        }
                    }
                    unoccluded as f64 / m as f64
                }
            });
        }
        brute
    }

    /// The sample's extra channels from the receiver's cell visibilities: the brute-forced
    /// fraction, then (with `"bool sh"`) the world-space transfer `Σ_c V̄_c K_c` and the albedo.
    #[allow(clippy::too_many_arguments)]
    fn write_channels(
        &self,
        recv: &Shading,
        frame: &Frame,
        brute: usize,
        table: &[f64],
        scratch: &mut PassScratch,
        aov: &mut [f32],
    ) {
        let nc = scratch.vbar.len().max(1);
        aov[0] = (brute as f64 / nc as f64) as f32;
        let Some(order) = self.sh else { return };
        let k = order.coeffs();
        let PassScratch { vbar, local, world, rot, .. } = scratch;
        local.clear();
        local.resize(k, 0.0);
        for (v, row) in vbar.iter().zip(table.chunks_exact(k)) {
            local.iter_mut().zip(row).for_each(|(t, kc)| *t += v * kc);
        }
        world.clear();
        world.resize(k, 0.0);
        // The local frame in f64, orthonormalised (the f32 frame is orthonormal to ~1e-7 only),
        // right-handed like `Frame::from_zx`; its columns take local directions to world ones.
        let z = recv.point.n.normalize();
        let x = (frame.x.as_dvec3() - z * z.dot(frame.x.as_dvec3())).normalize();
        let world_from_local = glam::DMat3::from_cols(x, z.cross(x), z);
        // The rotation depends on the frame only: members of a cluster on one flat face (and
        // the pixels of a plane) share the receiver's frame bit for bit, so the last one built
        // is kept and reused when the matrix is the same (its construction was a quarter of
        // the instructions of an order-5 render).
        if !matches!(rot, Some((m, r)) if *m == world_from_local && r.order() == order) {
            *rot = ShRotation::new(order, world_from_local).ok().map(|r| (world_from_local, r));
        }
        match rot {
            Some((_, r)) => {
                let _ = r.apply(local, world);
            }
            None => world.iter_mut().for_each(|w| *w = 0.0),
        }
        TransferChannels::new(order, 1).write(aov, world, recv.albedo);
    }
}

impl ShearedAo {
    /// Pass 2 for the camera samples `own` of one pixel, each added to the film with `add`
    /// (film position, AO, extra channels). With pixel shading the samples that see the same
    /// piece of surface ([`pixel_clusters`]) are filtered once, at the member closest to their
    /// mean film position, and share its filtered cells; else every sample is a receiver.
    /// Returns the receivers filtered, the samples resolved and their brute-forced cells.
    #[allow(clippy::too_many_arguments)]
    fn pass2_pixel(
        &self,
        scene: &Scene,
        own: &[CacheSample],
        neigh: &[&CachePoint],
        table: &[f64],
        scratch: &mut PassScratch,
        aov: &mut [f32],
        count: &mut RayCount,
        add: &mut impl FnMut(Vec2, f32, &[f32]),
    ) -> [u64; 3] {
        let (mut receivers, mut points, mut brute_cells) = (0u64, 0u64, 0u64);
        let clusters =
            if self.pixel_shading { pixel_clusters(own) } else { (0..own.len()).map(|i| (i, vec![i])).collect() };
        let mut done = vec![false; own.len()];
        for (rep, members) in clusters {
            let Some(recv) = &own[rep].shading else { continue };
            receivers += 1;
            self.filter(recv, neigh, scratch);
            // The filtered cells are shared; brute-forced cells (contact occluders, where the
            // visibility changes fastest) are estimated at every member's own point.
            // Every member lays its cells in the receiver's frame (its tangent turned onto the
            // member's normal), so that cell `c` means the same directions for the shared
            // filtered cells, the member's brute-forced ones and its SH rotation: the members'
            // own tangents (`dpdu`) can point anywhere (a mesh's triangles each have theirs).
            for m in members {
                let Some(at) = &own[m].shading else { continue };
                let frame = aligned_frame(&recv.frame, at.n);
                aov.iter_mut().for_each(|v| *v = 0.0);
                let brute = self.resolve(scene, at, &frame, own[m].brute_seed, scratch, count);
                brute_cells += brute as u64;
                points += 1;
                self.write_channels(at, &frame, brute, table, scratch, aov);
                // Cells of equal projected solid angle π / cells², weighted by the camera ray.
                let sum: f64 = scratch.vbar.iter().sum();
                let w = own[m].weight;
                let ao = (std::f64::consts::PI * sum / scratch.vbar.len().max(1) as f64) as f32 * w;
                if let (Some(order), true) = (self.sh, w != 1.0) {
                    TransferChannels::new(order, 1).weight(aov, w);
                }
                done[m] = true;
                add(own[m].p_film, ao, aov);
            }
        }
        // Samples whose camera ray escaped: black.
        aov.iter_mut().for_each(|v| *v = 0.0);
        for (sample, _) in own.iter().zip(&done).filter(|(_, d)| !**d) {
            add(sample.p_film, 0.0, aov);
        }
        [receivers, points, brute_cells]
    }
}

/// `frame` turned onto the normal `n` (unit): z = `n`, x = `frame.x` projected onto the plane
/// of `n`, right-handed; `frame` itself when `n` is its z (the receiver), and `from_z(n)` when
/// `frame.x` is (nearly) along `n`, which the clusters' normals (within ~11°) rule out.
fn aligned_frame(frame: &Frame, n: Vec3) -> Frame {
    if n == frame.z {
        return *frame;
    }
    Frame::from_zx(n, frame.x)
}

/// The camera samples of a pixel that see the same piece of surface (shading normals within
/// ~11°, each within two pixel footprints of the first member's tangent plane), as
/// `(representative, members)`: the representative is the member whose film position lies
/// closest to the members' mean (the first on a tie), chosen on the film so that it is the same
/// for the scene turned or moved. Samples whose camera ray escaped are in no cluster.
fn pixel_clusters(own: &[CacheSample]) -> Vec<(usize, Vec<usize>)> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, s) in own.iter().enumerate() {
        let Some(q) = &s.shading else { continue };
        let q = &q.point;
        let same = |g: &Vec<usize>| {
            own[g[0]].shading.as_ref().is_some_and(|a| {
                let a = &a.point;
                a.n.dot(q.n) > 0.98 && a.n.dot(q.p - a.p).abs() <= 2.0 * a.footprint.max(q.footprint)
            })
        };
        match groups.iter_mut().find(|g| same(g)) {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
        .into_iter()
        .map(|g| {
            let mean = g.iter().map(|&i| own[i].p_film.as_dvec2()).sum::<glam::DVec2>() / g.len() as f64;
            let d = |i: usize| (own[i].p_film.as_dvec2() - mean).length_squared();
            let rep = g.iter().copied().fold(g[0], |best, i| if d(i) < d(best) { i } else { best });
            (rep, g)
        })
        .collect()
}

/// Pass 2's per-thread buffers.
#[derive(Default)]
struct PassScratch {
    filter: Scratch,
    cells: Vec<CellValue>,
    vbar: Vec<f64>,
    local: Vec<f64>,
    world: Vec<f64>,
    /// The last SH rotation built, with its matrix (world from local).
    rot: Option<(glam::DMat3, ShRotation)>,
}

/// The larger side of the pixel's footprint at `p` on the plane of normal `n`: where the camera
/// rays one pixel over in x and in y meet that plane (0 when they do not, or when a lens
/// system blocks them).
fn footprint(scene: &Scene, cs: &CameraSample, p: glam::DVec3, n: glam::DVec3) -> f64 {
    let side = |dp: Vec2| -> f64 {
        let (r, w) = scene.camera.generate_ray_weighted(&CameraSample { p_film: cs.p_film + dp, ..*cs });
        if w == 0.0 {
            return 0.0;
        }
        let (o, d) = (r.o.as_dvec3(), r.d.as_dvec3());
        let t = n.dot(p - o) / n.dot(d);
        let q = o + t * d;
        let l = (q - p).length();
        if t.is_finite() && t > 0.0 && l.is_finite() {
            l
        } else {
            0.0
        }
    };
    side(Vec2::X).max(side(Vec2::Y))
}

/// Pass 1 over `region` (absolute pixels): per pixel its `spp` camera samples and shading points.
fn sample_pass(
    ao: &ShearedAo,
    scene: &Scene,
    proto: &dyn Sampler,
    region: Bounds2i,
    spp: u32,
    n: u32,
    rays: &Mutex<RayCount>,
) -> ImageBuffer<Vec<CacheSample>> {
    let (w, h) = (region.width().max(0) as usize, region.height().max(0) as usize);
    ImageBuffer::from_rows_par(w, h, |y| {
        let mut sampler = proto.clone_box();
        let mut count = RayCount::default();
        let row = (0..w)
            .map(|x| {
                let p = region.min + IVec2::new(x as i32, y as i32);
                (0..spp)
                    .map(|s| {
                        sampler.start_pixel_sample(p, s);
                        let cs = camera_sample(scene, sampler.as_mut(), p);
                        let us: Vec<Vec2> = sampler.get_2d_array(n).map(|a| a.to_vec()).unwrap_or_default();
                        // One more dimension, a function of (pixel, sample, seed) like every
                        // other, seeds the brute-force rays.
                        let u = sampler.get_1d();
                        let brute_seed = hash_words(&[
                            u.to_bits() as u64,
                            p.x as u32 as u64 | ((p.y as u32 as u64) << 32),
                            s as u64,
                        ]);
                        let (camera_ray, weight) = scene.camera.sample_ray_weighted(&cs, spp);
                        let shading =
                            if weight > 0.0 { ao.shade(scene, &cs, &camera_ray, &us, &mut count) } else { None };
                        CacheSample { p_film: cs.p_film, brute_seed, shading, weight }
                    })
                    .collect()
            })
            .collect();
        count.add_to(rays);
        row
    })
}

impl Integrator for ShearedAo {
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, materials: self.sh.is_some(), ..Default::default() }
    }
    fn extra_channels(&self) -> Vec<String> {
        let sh = self.sh.map(|o| TransferChannels::new(o, 1).names()).unwrap_or_default();
        std::iter::once("shearedao.brute".to_string()).chain(sh).collect()
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        let start = Instant::now();
        let n = scene.sampler.round_count(self.nsamples);
        if n != self.nsamples {
            ctx.warnings.warn(None, format!("sheared-ao: taking {n} samples, not {} as specified", self.nsamples));
        }
        let nc = (self.filter.cells * self.filter.cells) as u32;
        let full_res = IVec2::new(film.spec.full_resolution.0 as i32, film.spec.full_resolution.1 as i32);
        let full =
            penumbra_core::film::FilmSpec { pixel_bounds: Bounds2i::new(IVec2::ZERO, full_res), ..film.spec.clone() }
                .sample_bounds(scene.filter.radius());
        let mut proto = scene.sampler.clone_box();
        proto.set_sample_bounds(full.min, full.max);
        proto.request_2d_array(n);
        let spp = proto.samples_per_pixel();
        let sample_bounds = film.spec.sample_bounds(scene.filter.radius());
        // Pass 1 covers the sampled pixels plus the filter's screen radius (the margin), within
        // the full image: a crop sees the neighbours the full render sees.
        let margin = IVec2::splat(self.screen_radius as i32);
        let region = Bounds2i::new(sample_bounds.min - margin, sample_bounds.max + margin).intersect(&full);
        let pass1_rays = Mutex::new(RayCount::default());
        let pass2_rays = Mutex::new(RayCount::default());
        let table = self.sh.map(|o| sheared_filter::cell_transfer(self.filter.cells, o)).unwrap_or_default();
        let n_aov = self.extra_channels().len();
        let proto_ref = &*proto;
        let cache = with_threads(ctx.threads, || sample_pass(self, scene, proto_ref, region, spp, n, &pass1_rays))?;
        if ctx.cancel.load(Ordering::Relaxed) {
            return Err(RenderError::Cancelled);
        }
        let pass1_seconds = start.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let tile_list = tiles(sample_bounds);
        let total = tile_list.len() as u64;
        let done = AtomicU64::new(0);
        let film_ref = &*film;
        let r = self.screen_radius as i32;
        // The window, nearest pixels first (ties in raster order), so that the cap on points
        // keeps the nearest ones.
        let mut offsets: Vec<IVec2> = (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| IVec2::new(dx, dy)))
            .filter(|d| d.length_squared() <= r * r)
            .collect();
        offsets.sort_by_key(|d| (d.length_squared(), d.y, d.x));
        let max_points = self.max_points as usize;
        let (receivers, points, brute_cells) = (AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0));
        let results = with_threads(ctx.threads, || {
            tile_list
                .par_iter()
                .map(|tb| {
                    if ctx.cancel.load(Ordering::Relaxed) {
                        return None;
                    }
                    let mut tile = film_ref.make_tile(*tb);
                    let (mut scratch, mut neigh) = (PassScratch::default(), Vec::new());
                    let mut aov = vec![0.0f32; n_aov];
                    let (mut count, mut counts) = (RayCount::default(), [0u64; 3]);
                    for p in tb.iter() {
                        neigh.clear();
                        for d in &offsets {
                            let q = p + *d;
                            if neigh.len() >= max_points {
                                break;
                            }
                            if region.contains(q) {
                                let l = q - region.min;
                                let pts = cache
                                    .at(l.x as usize, l.y as usize)
                                    .iter()
                                    .filter_map(|s| Some(&s.shading.as_ref()?.point));
                                neigh.extend(pts.take(max_points - neigh.len()));
                            }
                        }
                        let l = p - region.min;
                        let own = cache.at(l.x as usize, l.y as usize);
                        let mut add = |p_film: Vec2, ao: f32, aov: &[f32]| {
                            let ao = if ao.is_finite() { ao.max(0.0) } else { 0.0 };
                            tile.add_sample(scene.filter.as_ref(), p_film, Rgb::splat(ao), aov);
                        };
                        let c =
                            self.pass2_pixel(scene, own, &neigh, &table, &mut scratch, &mut aov, &mut count, &mut add);
                        counts.iter_mut().zip(c).for_each(|(a, b)| *a += b);
                    }
                    count.add_to(&pass2_rays);
                    receivers.fetch_add(counts[0], Ordering::Relaxed);
                    points.fetch_add(counts[1], Ordering::Relaxed);
                    brute_cells.fetch_add(counts[2], Ordering::Relaxed);
                    let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if let Some(pr) = ctx.progress {
                        pr(d, total);
                    }
                    Some(tile)
                })
                .collect::<Vec<_>>()
        })?;
        if results.iter().any(|t| t.is_none()) {
            return Err(RenderError::Cancelled);
        }
        for tile in results.into_iter().flatten() {
            film.merge_tile(&tile);
        }
        let filter_seconds = t2.elapsed().as_secs_f64();
        let points = points.load(Ordering::Relaxed).max(1) as f64;
        let lock = |m: Mutex<RayCount>| m.into_inner().unwrap_or_else(|e| e.into_inner());
        let (c1, c2) = (lock(pass1_rays), lock(pass2_rays));
        let (r1, r2) = (c1.occlusion, c2.occlusion);
        // Every ray once, by this integrator (it is its own driver): `rays` are pass 1's camera
        // rays over the whole region (the margin too) with their pass-throughs (pass 2 traces
        // none), `shadow_rays` the occlusion rays of both passes.
        let mut stats = RenderStats {
            spp,
            camera_samples: sample_bounds.area() as u64 * spp as u64,
            rays: c1.camera + c2.camera,
            shadow_rays: r1 + r2,
            threads: if ctx.threads > 0 { ctx.threads } else { rayon::current_num_threads() },
            render_seconds: start.elapsed().as_secs_f64(),
            ..Default::default()
        };
        let c = &mut stats.counters;
        c.insert("pass1_points".into(), (region.area() as u64 * spp as u64) as f64);
        c.insert("pass1_rays_per_point".into(), r1 as f64 / (region.area().max(1) as f64 * spp as f64));
        c.insert("pass2_rays_per_point".into(), r2 as f64 / points);
        c.insert("pass2_receivers_per_point".into(), receivers.load(Ordering::Relaxed) as f64 / points);
        c.insert("brute_cell_fraction".into(), brute_cells.load(Ordering::Relaxed) as f64 / (points * nc as f64));
        c.insert("pass1_seconds".into(), pass1_seconds);
        c.insert("pass2_seconds".into(), filter_seconds);
        Ok(stats)
    }
}
