//! `ratio`'s per-pixel estimator: the analytic unshadowed `U` (from `ltc`), the stochastic
//! `S_N` and `U_N` from the same light and BRDF samples, and the guides, written per camera
//! sample into the film's extra channels ([`RatioSample`]); the same terms of the surfaces its
//! specular chains reach ([`ChainTerms`]).

use super::{ChainTerms, RatioSample};
use crate::common::direct::{has_specular, specular_ray};
use crate::common::ltc::{Ltc, LtcCoeffs};
use crate::common::ltc_shading::{fresnel_at, BudgetedLighting, LtcShader, OverBudget};
use crate::common::other_lights::{add_other_lights, Coverage, FallbackWarning};
use crate::common::pixel_shading::SharedPixel;
use glam::{DVec2, DVec3};
use penumbra_core::bxdf::{Bsdf, BxdfFlags};
use penumbra_core::camera::CameraSample;
use penumbra_core::geometry::{gamma, Frame, Ray, RayDifferential};
use penumbra_core::integrator::{PixelEstimator, SampleContext, ThreadStats};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::{emitting_normal, DiffuseAreaLight, Light, LightContext};
use penumbra_core::material::{LtcDescription, LtcLobe};
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Scene, SurfaceHit};
use penumbra_core::spectrum::luminance;
use penumbra_core::{Rgb, Vec2, Vec3};

/// A bounding sphere of an area light's triangles, for quick rejection of BRDF samples.
struct LightBound {
    c: DVec3,
    r: f64,
}

/// One area light as `ratio` samples it: an emitting mesh's triangles gathered (pbrt-v3 makes
/// one light per triangle of a `trianglemesh`), a triangle chosen in proportion to its area
/// and a point uniformly on it, so that each sample costs one shadow ray whatever the
/// number of triangles.
pub(super) struct SampleGroup {
    /// A `Light::Area` over all the group's triangles (with their area distribution).
    light: Light,
    bound: LightBound,
    /// The shader's light group ([`LtcShader::light_groups`]; its bit in [`OverBudget`]).
    group: usize,
}

impl SampleGroup {
    /// The groups of `shader`'s area lights (those with a positive area), bounded by the
    /// groups' spheres.
    pub(super) fn of(shader: &LtcShader, scene: &Scene) -> Vec<SampleGroup> {
        shader
            .light_groups()
            .iter()
            .enumerate()
            .filter_map(|(group, g)| {
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
                    group,
                })
            })
            .collect()
    }
}

pub(super) struct Estimator<'a> {
    pub(super) shader: LtcShader,
    pub(super) n: u32,
    /// pbrt-v3's `"integer maxdepth"`: surfaces a specular chain may meet, the first included.
    pub(super) max_depth: u32,
    pub(super) groups: Vec<SampleGroup>,
    pub(super) pixel_shading: bool,
    pub(super) fallback: FallbackWarning<'a>,
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

/// The point's BRDF as `ratio` samples it: the shading frame (normal on ωo's side), each
/// glossy lobe's LTC (the cosine for one without a GGX warp) and the normalised luminance
/// weights of the Lambertian lobe and of the glossy ones (all 0: no BRDF sampling). `flags`:
/// the BSDF lobes the stochastic estimates take (the reflection ones only when the LTC form
/// leaves the transmission out, which `directlighting`'s estimator then shades).
struct Lobes {
    frame: Frame<DVec3>,
    glossy: Vec<(LtcLobe, LtcCoeffs, f64)>,
    w_d: f64,
    flags: BxdfFlags,
}

impl Lobes {
    fn of(si: &SurfaceInteraction, desc: &LtcDescription) -> Lobes {
        let n0 = desc.n.normalize_or_zero();
        let n = if n0.dot(si.wo) < 0.0 { -n0 } else { n0 };
        let frame = Frame::toward(d3(n), d3(si.wo));
        let cos_o = frame.to_local(d3(si.wo)).z.clamp(0.0, 1.0) as f32;
        let mut w_d = luminance(desc.diffuse).max(0.0) as f64;
        let mut glossy: Vec<(LtcLobe, LtcCoeffs, f64)> = desc
            .lobes
            .iter()
            .map(|l| {
                let c = match l.ggx_alpha() {
                    Some(a) => Ltc::lookup(cos_o, a),
                    None => LtcCoeffs { minv: glam::DMat3::IDENTITY, magnitude: 1.0, fresnel: 0.0 },
                };
                let w = luminance(l.ltc_scale() * fresnel_at(&l.fresnel(), cos_o) * c.magnitude).max(0.0) as f64;
                (*l, c, w)
            })
            .collect();
        let w_sum = w_d + glossy.iter().map(|g| g.2).sum::<f64>();
        if w_sum > 0.0 && w_sum.is_finite() && n != Vec3::ZERO {
            w_d /= w_sum;
            for g in &mut glossy {
                g.2 /= w_sum;
            }
        } else {
            w_d = 0.0;
            for g in &mut glossy {
                g.2 = 0.0;
            }
        }
        let flags = if desc.transmits {
            BxdfFlags::REFLECTION | BxdfFlags::DIFFUSE | BxdfFlags::GLOSSY
        } else {
            BxdfFlags::NON_SPECULAR
        };
        Lobes { frame, glossy, w_d, flags }
    }

    /// Whether there is anything to sample.
    fn samples_brdf(&self) -> bool {
        self.w_d + self.glossy.iter().map(|g| g.2).sum::<f64>() > 0.0
    }

    /// The density of direction `w` under the lobe mixture (0 without BRDF samples).
    fn pdf(&self, w: Vec3, n_b: usize) -> f64 {
        if n_b == 0 {
            return 0.0;
        }
        let l = self.frame.to_local(d3(w));
        let mut p = self.w_d * l.z.max(0.0) * std::f64::consts::FRAC_1_PI;
        for (_, c, wk) in &self.glossy {
            if *wk > 0.0 {
                p += wk * c.pdf(l);
            }
        }
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }

    /// A direction (world space, unit or zero) from the lobe mixture for the 2D sample `uv`.
    fn sample(&self, uv: Vec2) -> DVec3 {
        let (x, y) = (uv.x as f64, uv.y as f64);
        let remap = |x: f64, lo: f64, w: f64| ((x - lo) / w.max(1e-300)).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        let mut lo = self.w_d;
        let local = if x < self.w_d || self.glossy.is_empty() {
            crate::common::ltc::cosine_sample(DVec2::new(remap(x, 0.0, self.w_d), y))
        } else {
            let last = self.glossy.len() - 1;
            let mut out = DVec3::ZERO;
            for (k, (_, c, wk)) in self.glossy.iter().enumerate() {
                if x < lo + wk || k == last {
                    out = c.sample(DVec2::new(remap(x, lo, *wk), y));
                    break;
                }
                lo += wk;
            }
            out
        };
        self.frame.from_local(local).normalize_or_zero()
    }
}

/// The sums `(S_N, U_N)` of one light and each stochastic sample's luminance contributions
/// (shadowed, unshadowed).
struct Tally<'a> {
    s: Rgb,
    u: Rgb,
    per_sample: &'a mut [(f32, f32)],
}

impl Tally<'_> {
    /// Adds sample `k`'s contribution `c` towards `lp` (one shadow ray decides `S_N`'s part).
    fn add(
        &mut self,
        scene: &Scene,
        si: &SurfaceInteraction,
        k: usize,
        c: Rgb,
        lp: &LightPoint,
        stats: &mut ThreadStats,
    ) {
        if !(c.is_finite() && c.min_element() >= 0.0) || c == Rgb::ZERO {
            return;
        }
        self.u += c;
        let y = luminance(c);
        stats.shadow_rays += 1;
        let visible = !scene.occluded(&si.spawn_ray_to_surface(lp.p, lp.p_error, lp.n));
        if visible {
            self.s += c;
        }
        if let Some(ps) = self.per_sample.get_mut(k) {
            ps.0 += if visible { y } else { 0.0 };
            ps.1 += y;
        }
    }
}

/// One stochastic estimate's inputs at a point: the scene, the surface and its BSDF, the
/// light, the lobes and the split of the samples (`n_l` from the light, `n_b` from the BRDF).
struct Sampling<'a> {
    scene: &'a Scene,
    si: &'a SurfaceInteraction,
    bsdf: &'a Bsdf,
    group: &'a SampleGroup,
    lobes: &'a Lobes,
    n_l: usize,
    n_b: usize,
}

impl Sampling<'_> {
    /// The light-sampled half: a point on the light per sample, weighted by the balance heuristic.
    fn light_samples(&self, us: &[Vec2], tally: &mut Tally, stats: &mut ThreadStats) {
        let si = self.si;
        let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
        for (k, uv) in us.iter().enumerate() {
            let Some(ls) = self.group.light.sample_li(&ctx, *uv, &self.scene.meshes) else { continue };
            if !(ls.pdf > 0.0) || ls.li == Rgb::ZERO {
                continue;
            }
            let f = self.bsdf.f(si.wo, ls.wi, self.lobes.flags) * ls.wi.dot(si.shading.z).abs();
            if f == Rgb::ZERO {
                continue;
            }
            let denom = self.n_l as f64 * ls.pdf as f64 + self.n_b as f64 * self.lobes.pdf(ls.wi, self.n_b);
            let c = f * ls.li * (1.0 / denom) as f32;
            tally.add(
                self.scene,
                si,
                k,
                c,
                &LightPoint { p: ls.p_light, p_error: ls.p_light_error, n: ls.n_light },
                stats,
            );
        }
    }

    /// The BRDF-sampled half (samples `n_l..`): every light triangle a direction crosses counts
    /// (ignoring occluders), as `U` integrates every triangle.
    fn brdf_samples(&self, us: &[Vec2], tally: &mut Tally, stats: &mut ThreadStats) {
        let (si, light) = (self.si, &self.group.light);
        let Some(geom) = light.area() else { return };
        let Some(mesh) = self.scene.meshes.get(geom.mesh as usize) else { return };
        let o = d3(si.p);
        for (j, uv) in us.iter().enumerate() {
            let k = self.n_l + j;
            let wd = self.lobes.sample(*uv);
            if wd == DVec3::ZERO {
                continue;
            }
            let w = wd.as_vec3();
            let p_b = self.lobes.pdf(w, self.n_b);
            if !(p_b > 0.0) {
                continue;
            }
            let f = self.bsdf.f(si.wo, w, self.lobes.flags) * w.dot(si.shading.z).abs();
            if f == Rgb::ZERO || !self.group.bound.may_hit(o, wd) {
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
                let denom = self.n_l as f64 * p_l + self.n_b as f64 * p_b;
                let c = f * le * (1.0 / denom) as f32;
                let err = Vec3::splat(gamma(6)) * (pv[0].abs() + pv[1].abs() + pv[2].abs()).as_vec3();
                tally.add(self.scene, si, k, c, &LightPoint { p: xp.as_vec3(), p_error: err, n: ne }, stats);
            }
        }
    }
}

impl LightBound {
    /// Whether the half-line from `o` along unit `wd` may meet the sphere.
    fn may_hit(&self, o: DVec3, wd: DVec3) -> bool {
        // Distance from the bounding sphere's centre to the ray.
        let oc = self.c - o;
        let t = oc.dot(wd);
        let dist2 = (oc - wd * t).length_squared();
        !(dist2 > self.r * self.r || (t < 0.0 && oc.length_squared() > self.r * self.r))
    }
}

/// `(S_N, U_N)` for the area light `group` at `hit` (BRDF `lobes`), from the 2D samples `us`.
fn stochastic(
    scene: &Scene,
    hit: &SurfaceHit,
    lobes: &Lobes,
    group: &SampleGroup,
    us: &[Vec2],
    per_sample: &mut [(f32, f32)],
    stats: &mut ThreadStats,
) -> (Rgb, Rgb) {
    let mut tally = Tally { s: Rgb::ZERO, u: Rgb::ZERO, per_sample };
    if group.light.area().is_none_or(|g| scene.meshes.get(g.mesh as usize).is_none()) {
        return (tally.s, tally.u);
    }
    let total = us.len();
    let n_b = if lobes.samples_brdf() { total / 2 } else { 0 };
    let n_l = total - n_b;
    let sampling = Sampling { scene, si: &hit.si, bsdf: &hit.bsdf, group, lobes, n_l, n_b };
    sampling.light_samples(&us[..n_l], &mut tally, stats);
    if n_b > 0 {
        sampling.brdf_samples(&us[n_l..], &mut tally, stats);
    }
    (tally.s, tally.u)
}

impl Estimator<'_> {
    /// [`shade_surface`](Self::shade_surface) of the first surface `hit` of `ray`, with what
    /// its specular chains reach ([`follow_specular`](Self::follow_specular)).
    fn shade(
        &self,
        ray: &RayDifferential,
        hit: &SurfaceHit,
        area: Option<BudgetedLighting>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> (Rgb, RatioSample) {
        let (mut rest, mut sample) = self.shade_surface(ray, hit, area, scene, sampler, stats);
        if has_specular(&hit.bsdf) {
            let mut chain = Chain::default();
            self.follow_specular(ray, hit, Rgb::ONE, 0, scene, sampler, stats, &mut chain);
            rest += chain.rest;
            sample.chain = chain.terms;
        }
        (rest, sample)
    }

    /// Follows the perfectly specular lobes of `hit` (the `depth`-th surface of its chain,
    /// reached with throughput `beta`) as `directlighting` does, while the chain may have more
    /// surfaces, and adds to `chain` what every surface reached gives ([`shade_surface`]
    /// (Self::shade_surface)), weighted by the throughput.
    #[allow(clippy::too_many_arguments)]
    fn follow_specular(
        &self,
        ray: &RayDifferential,
        hit: &SurfaceHit,
        beta: Rgb,
        depth: u32,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        chain: &mut Chain,
    ) {
        if depth + 1 >= self.max_depth || !has_specular(&hit.bsdf) {
            return;
        }
        for kind in [BxdfFlags::REFLECTION, BxdfFlags::TRANSMISSION] {
            let Some(sr) = specular_ray(&hit.si, &hit.bsdf, ray, sampler, stats, kind) else { continue };
            let beta = beta * sr.f * sr.scale;
            let (next, queries) = scene.first_surface(&sr.ray);
            stats.add_continued(queries);
            match next {
                Ok(h) => {
                    let (rest, t) = self.shade_surface(&sr.ray, &h, None, scene, sampler, stats);
                    chain.add(beta, rest, &t);
                    self.follow_specular(&sr.ray, &h, beta, depth + 1, scene, sampler, stats, chain);
                }
                Err(escaped) => chain.rest += beta * escaped,
            }
        }
    }

    /// Radiance (everything but the area lights' shaded part) from the surface `hit` of `ray`,
    /// and what it writes to the film's channels (`U`, `S_N`, `U_N`, the guides; no chain
    /// terms); `area` is the analytic unshadowed area lighting (form factor, glossy) when
    /// already computed for the pixel.
    fn shade_surface(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        area: Option<BudgetedLighting>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> (Rgb, RatioSample) {
        let SurfaceHit { si, le, .. } = hit;
        let mut rest = *le;
        let desc = self.shader.lobes(scene, si);
        let nf = if si.n.dot(si.wo) < 0.0 { -si.n } else { si.n };
        let (mut u, mut s, mut un) = (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO);
        let mut us = Vec::new();
        // Per stochastic sample index, its luminance contributions (shadowed, unshadowed) summed
        // over the lights: the noise estimate.
        let mut per_sample = vec![(0.0f32, 0.0f32); self.n as usize];
        // The lights over the cost budget (`U` of a light of no simple shape, triangle by
        // triangle, over `LIGHT_TRIANGLE_BUDGET` facing triangles): their stochastic shadowed
        // estimate goes into `rest` as is (`directlighting`'s estimator with N samples), out of
        // the ratio.
        let mut over = OverBudget::default();
        if let Some(d) = &desc {
            let BudgetedLighting { lighting: (diffuse, specular), over: o } = match area {
                Some(b) => b,
                None => self.shader.area_lights_budgeted(scene, si, d, false, &mut Vec::new()),
            };
            u = d.diffuse * diffuse + specular;
            over = o;
        }
        let lobes = desc.as_ref().map(|d| Lobes::of(si, d));
        let mut own = vec![(0.0f32, 0.0f32); self.n as usize];
        for g in &self.groups {
            // Always drawn, so that every light gets its own array whatever the material.
            us.clear();
            match sampler.get_2d_array(self.n) {
                Some(a) => us.extend_from_slice(a),
                None => us.extend((0..self.n).map(|_| sampler.get_2d())),
            }
            if let Some(lobes) = &lobes {
                if over.has(g.group) {
                    let (sk, _) = stochastic(scene, hit, lobes, g, &us, &mut own, stats);
                    rest += sk;
                } else {
                    let (sk, uk) = stochastic(scene, hit, lobes, g, &us, &mut per_sample, stats);
                    s += sk;
                    un += uk;
                }
            }
        }
        let coverage = Coverage::of(desc.is_some(), desc.as_ref().is_some_and(|d| d.transmits));
        add_other_lights(&mut rest, hit, coverage, scene, sampler, stats, &self.fallback);
        let finite = |c: Rgb| if c.is_finite() { c.max(Rgb::ZERO) } else { Rgb::ZERO };
        let (ss, uu, su) = moments(&per_sample);
        let sample = RatioSample {
            u: finite(u),
            s: finite(s),
            un: finite(un),
            ss,
            uu,
            su,
            depth: (si.p - ray.o).length(),
            n: nf,
            plane: nf.dot(si.p),
            chain: ChainTerms::default(),
            spread_uu: Rgb::ZERO,
            spread_ru: Rgb::ZERO,
        };
        (rest, sample)
    }
}

/// What a camera sample's specular chains add: radiance into `rest`, and the area lights'
/// terms.
#[derive(Default)]
struct Chain {
    rest: Rgb,
    terms: ChainTerms,
}

impl Chain {
    /// A reached surface's `rest` and terms `t`, through throughput `beta`.
    fn add(&mut self, beta: Rgb, rest: Rgb, t: &RatioSample) {
        let finite = |c: Rgb| if c.is_finite() { c.max(Rgb::ZERO) } else { Rgb::ZERO };
        self.rest += beta * rest;
        self.terms.u += finite(beta * t.u);
        self.terms.s += finite(beta * t.s);
        self.terms.un += finite(beta * t.un);
    }
}

/// Moments `(⟨S²⟩, ⟨U²⟩, ⟨S·U⟩)` of the single-sample estimates `n·(contribution of sample
/// k)` (0 where not finite).
fn moments(per_sample: &[(f32, f32)]) -> (f32, f32, f32) {
    let n = per_sample.len().max(1) as f32;
    let (mut ss, mut uu, mut su) = (0.0f32, 0.0f32, 0.0f32);
    for &(ys, yu) in per_sample {
        let (ys, yu) = (n * ys, n * yu);
        ss += ys * ys;
        uu += yu * yu;
        su += ys * yu;
    }
    let finite1 = |v: f32| if v.is_finite() { v } else { 0.0 };
    (finite1(ss / n), finite1(uu / n), finite1(su / n))
}

impl PixelEstimator for Estimator<'_> {
    type Shared = SharedPixel<BudgetedLighting>;

    fn request_samples(&self, sampler: &mut dyn Sampler) {
        for _ in &self.groups {
            sampler.request_2d_array(self.n);
        }
    }

    fn li(&self, ray: &RayDifferential, cx: SampleContext) -> Rgb {
        let SampleContext { scene, sampler, stats, aov } = cx;
        let (first, queries) = scene.first_surface(ray);
        stats.add_continued(queries);
        match first {
            Ok(h) => {
                let (rest, sample) = self.shade(ray, &h, None, scene, sampler, stats);
                sample.with_spread(rest).write(aov);
                rest
            }
            Err(escaped) => escaped,
        }
    }

    fn shares_pixel_work(&self) -> bool {
        self.pixel_shading
    }

    fn weight_channels(&self, aov: &mut [f32], w: f32) {
        super::RatioSample::weight(aov, w);
    }

    /// `U` once per surface seen in the pixel (as `ltc`'s pixel shading, unshadowed); the
    /// stochastic `S_N`, `U_N` stay per camera sample.
    fn begin_pixel(
        &self,
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        stats: &mut ThreadStats,
    ) -> Option<Self::Shared> {
        Some(self.shader.trace_pixel_budgeted(rays, samples, scene, false, stats))
    }

    fn li_shared(&self, ray: &RayDifferential, cx: SampleContext, shared: &Self::Shared, index: usize) -> Rgb {
        let SampleContext { scene, sampler, stats, aov } = cx;
        match shared.sample(index) {
            (Ok(pt), area) => match pt.with_bsdf(scene) {
                Some(h) => {
                    let (rest, sample) = self.shade(ray, &h, area, scene, sampler, stats);
                    sample.with_spread(rest).write(aov);
                    rest
                }
                None => Rgb::ZERO, // (first_point returns only surfaces with a material)
            },
            (Err(escaped), _) => *escaped,
        }
    }
}
