//! `ltc`: analytic shading and soft shadows from polygonal area lights (seed 004).
//!
//! At each shading point and for each emitting triangle of each area light, the
//! triangle is projected onto the sphere of directions, the occluders between the
//! point and the triangle are projected too, and the visible part (light minus the
//! union of occluders, [`spherical::difference`]) is integrated in closed form:
//! the clamped cosine for the Lambertian lobe (exact), and a Linearly Transformed
//! Cosine fitted to the Trowbridge–Reitz lobe for the glossy part.
//!
//! Occluders come from a bounding-volume hierarchy over the scene's objects,
//! queried with the cone from the shading point around the light triangle's
//! bounding sphere (the paper's `GetBetween`). An occluder is represented by its
//! silhouette loop when it is closed and convex (mode `silhouette`, or `auto` when
//! the builder proves it convex) and by its triangles otherwise (`per-triangle`).
//! Occluder geometry beyond the light triangle's plane cannot shadow it: triangles
//! are clipped to the half-space of the shading point first, and a convex object
//! straddling that plane is taken triangle by triangle.
//!
//! Point, spot, distant, goniometric and projection lights get exact hard shadows
//! (one shadow ray, the real BSDF). Infinite lights, and materials that do not reduce
//! to a Lambertian plus a GGX lobe, fall back to `directlighting`'s estimator for
//! that light or that point, with one warning each.

use crate::directlighting::estimate_direct;
use glam::DVec3;
use penumbra_core::bxdf::{BxdfFlags, Fresnel};
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds3, Ray};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, RenderContext, RenderError, RenderStats, ThreadStats,
};
use penumbra_core::light::{emitting_normal, Light, LightContext};
use penumbra_core::ltc::{ltc_integrate, Ltc, ShadingFrame};
use penumbra_core::material::{LtcDescription, LtcFresnel};
use penumbra_core::mesh::EdgeAdjacency;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit, SurfaceInteraction};
use penumbra_core::spherical;
use penumbra_core::{Rgb, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One silhouette loop per closed mesh.
    Silhouette,
    /// Every occluder as its triangles.
    PerTriangle,
    /// Silhouettes for objects proven closed and convex, triangles otherwise.
    Auto,
}

/// How the glossy lobe's Fresnel factor is applied to the LTC integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FresnelMode {
    /// Heitz et al.'s split: `magnitude · (F0 + (1 − F0) · fresnel)` with the material's
    /// normal-incidence reflectance `F0` (exact for Schlick's Fresnel).
    Schlick,
    /// The material's exact Fresnel at the half-vector between ωo and the visible region's
    /// LTC-weighted mean direction, per light triangle (handles pbrt-v3's plastic, whose
    /// dielectric Fresnel is not Schlick-like).
    Average,
}

pub struct LtcIntegrator {
    pub mode: Mode,
    pub shadows: bool,
    pub fresnel: FresnelMode,
}

impl LtcIntegrator {
    pub fn create(params: &ParamSet, warnings: &DiagSink) -> Result<Box<dyn Integrator>, Diagnostic> {
        let m = params.get_one_string("mode", "auto");
        let mode = match m.as_str() {
            "auto" => Mode::Auto,
            "silhouette" => Mode::Silhouette,
            "per-triangle" | "pertriangle" => Mode::PerTriangle,
            other => {
                warnings.warn(
                    params.loc_of("mode").cloned(),
                    format!(
                        "ltc: unknown mode \"{other}\" (expected auto, silhouette or per-triangle): using \"auto\""
                    ),
                );
                Mode::Auto
            }
        };
        let shadows = params.get_one_bool("shadows", true);
        let fresnel = match params.get_one_string("fresnel", "average").as_str() {
            "schlick" => FresnelMode::Schlick,
            "average" => FresnelMode::Average,
            other => {
                warnings.warn(
                    params.loc_of("fresnel").cloned(),
                    format!("ltc: unknown fresnel \"{other}\" (expected average or schlick): using \"average\""),
                );
                FresnelMode::Average
            }
        };
        Ok(Box::new(LtcIntegrator { mode, shadows, fresnel }))
    }
}

/// What the estimator knows about each object (mesh `i` = object `i`).
struct ObjectInfo {
    bounds: Bounds3,
    occluder: bool,
    /// Closed and convex (proven by the builder), with its adjacency for silhouettes.
    silhouette: Option<EdgeAdjacency>,
    /// A hierarchy over the object's triangles, for the per-triangle cone query.
    tris: ObjectBvh,
    /// All vertices in one plane: as a light, it cannot shadow itself.
    planar: bool,
}

/// Whether every vertex of `mesh` lies within 1e-6 of its extent from the plane of its
/// largest triangle.
fn is_planar(mesh: &penumbra_core::mesh::TriangleMesh, bounds: &Bounds3) -> bool {
    let Some(t) = (0..mesh.triangle_count()).max_by(|a, b| mesh.area(*a).total_cmp(&mesh.area(*b))) else {
        return true;
    };
    let [a, b, c] = mesh.vertices(t).map(d3);
    let n = (b - a).cross(c - a).normalize_or_zero();
    if n == DVec3::ZERO {
        return false;
    }
    let tol = 1e-6 * (bounds.max - bounds.min).length() as f64;
    mesh.positions.iter().all(|p| (d3(*p) - a).dot(n).abs() <= tol)
}

/// A binary hierarchy over object bounds, for the cone query.
struct ObjectBvh {
    nodes: Vec<Node>,
}

struct Node {
    bounds: Bounds3,
    /// Leaf: object index; inner: `usize::MAX`.
    object: usize,
    children: [usize; 2],
}

/// A cone from `apex` along unit `axis` with half-angle `sin`/`cos`, up to distance `far`.
#[derive(Clone, Copy)]
struct Cone {
    apex: Vec3,
    axis: Vec3,
    cos: f32,

    far: f32,
}

impl Cone {
    /// Around the bounding sphere (`c`, `r`) seen from `apex`; `None` if `apex` is inside it
    /// (then everything in front may occlude: a full-sphere query).
    fn towards(apex: Vec3, c: Vec3, r: f32) -> Cone {
        let d = c - apex;
        let dist = d.length();
        if !(dist > r * 1.0001) {
            return Cone { apex, axis: Vec3::Z, cos: -1.0, far: dist + r };
        }
        let sin = r / dist;
        Cone { apex, axis: d / dist, cos: (1.0 - sin * sin).max(0.0).sqrt(), far: dist + r }
    }

    /// Whether the sphere (`c`, `r`) may intersect the cone (conservative).
    fn hits_sphere(&self, c: Vec3, r: f32) -> bool {
        let v = c - self.apex;
        let dist = v.length();
        if dist <= r {
            return true;
        }
        if dist - r > self.far {
            return false;
        }
        if self.cos <= -1.0 {
            return true;
        }
        // Angle between v and the axis minus the sphere's angular radius ≤ the cone's half-angle.
        let cos_v = v.dot(self.axis) / dist;
        let sin_v = (1.0 - cos_v * cos_v).max(0.0).sqrt();
        let sin_s = (r / dist).min(1.0);
        let cos_s = (1.0 - sin_s * sin_s).max(0.0).sqrt();
        // cos(θv − θs) ≥ cos(θc)  ⇔  the sphere reaches into the cone.
        let cos_diff = cos_v * cos_s + sin_v * sin_s;
        cos_diff >= self.cos - 1e-6 || cos_v >= cos_s.min(self.cos)
    }

    fn hits_box(&self, b: &Bounds3) -> bool {
        let c = (b.min + b.max) * 0.5;
        let r = (b.max - b.min).length() * 0.5;
        self.hits_sphere(c, r)
    }
}

impl ObjectBvh {
    fn build(bounds: &[(usize, Bounds3)]) -> ObjectBvh {
        let mut bvh = ObjectBvh { nodes: Vec::new() };
        if !bounds.is_empty() {
            let mut items = bounds.to_vec();
            bvh.build_rec(&mut items);
        }
        bvh
    }

    fn build_rec(&mut self, items: &mut [(usize, Bounds3)]) -> usize {
        let mut b = Bounds3::EMPTY;
        for (_, ib) in items.iter() {
            b = b.union(ib);
        }
        let idx = self.nodes.len();
        if items.len() == 1 {
            self.nodes.push(Node { bounds: b, object: items[0].0, children: [0, 0] });
            return idx;
        }
        self.nodes.push(Node { bounds: b, object: usize::MAX, children: [0, 0] });
        let ext = b.max - b.min;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        items.sort_by(|a, c| {
            let ca = (a.1.min[axis] + a.1.max[axis]) * 0.5;
            let cc = (c.1.min[axis] + c.1.max[axis]) * 0.5;
            ca.total_cmp(&cc)
        });
        let mid = items.len() / 2;
        let (l, r) = items.split_at_mut(mid);
        let left = self.build_rec(l);
        let right = self.build_rec(r);
        self.nodes[idx].children = [left, right];
        idx
    }

    /// Objects whose bounds may meet `cone`.
    fn query(&self, cone: &Cone, out: &mut Vec<usize>) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            if !cone.hits_box(&n.bounds) {
                continue;
            }
            if n.object != usize::MAX {
                out.push(n.object);
            } else {
                stack.extend_from_slice(&n.children);
            }
        }
        out.sort_unstable();
    }
}

/// What `ltc` prepares per scene (object bounds, convexity, the object hierarchy) and the
/// analytic shading of one area light at a point: shared with the `ratio` estimator, which
/// needs the unshadowed term.
pub struct LtcShader<'a> {
    ltc: &'a LtcIntegrator,
    objects: Vec<ObjectInfo>,
    bvh: ObjectBvh,
}

struct Estimator<'a> {
    shader: LtcShader<'a>,
    warn_material: AtomicBool,
    warnings: &'a DiagSink,
}

/// A cone of directions containing a loop: unit `axis` and the half-angle's cosine.
struct BoundingCone {
    axis: DVec3,
    cos: f64,
}

impl BoundingCone {
    /// `None` when the loop is too wide for a useful cone (then it is kept).
    fn of(l: &[DVec3]) -> Option<BoundingCone> {
        let sum: DVec3 = l.iter().map(|d| d.normalize_or_zero()).sum();
        let axis = sum.normalize_or_zero();
        if axis == DVec3::ZERO {
            return None;
        }
        // The loop's arcs bulge at most to their endpoints' great circles; for loops within a
        // hemisphere around `axis` the vertex bound holds for the arcs when every vertex is
        // within 90° of the axis (minor arcs between two points of a cap stay in the cap).
        let cos = l.iter().map(|d| d.normalize_or_zero().dot(axis)).fold(1.0, f64::min);
        (cos > 1e-3).then_some(BoundingCone { axis, cos })
    }

    fn overlaps(&self, o: &BoundingCone) -> bool {
        // Angle between axes < sum of half-angles (with a small margin).
        let (a, b) = (self.cos.clamp(-1.0, 1.0).acos(), o.cos.clamp(-1.0, 1.0).acos());
        self.axis.dot(o.axis).clamp(-1.0, 1.0).acos() < a + b + 1e-6
    }
}

/// Sutherland–Hodgman in 3D: the part of polygon `poly` with `(x − o)·n ≥ 0`.
fn clip_to_plane(poly: &[DVec3], o: DVec3, n: DVec3) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = ((a - o).dot(n), (b - o).dot(n));
        if da >= 0.0 {
            out.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let t = da / (da - db);
            out.push(a + (b - a) * t);
        }
    }
    if out.len() < 3 {
        out.clear();
    }
    out
}

fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

impl<'a> LtcShader<'a> {
    /// Prepares the per-object data `settings` needs on `scene` (silhouette adjacency only for
    /// the objects its mode takes as silhouettes).
    pub fn new(settings: &'a LtcIntegrator, scene: &Scene) -> LtcShader<'a> {
        let mut objects = Vec::with_capacity(scene.meshes.len());
        let mut boxes = Vec::new();
        for (i, mesh) in scene.meshes.iter().enumerate() {
            let mut b = Bounds3::EMPTY;
            for p in &mesh.positions {
                b.extend(*p);
            }
            let occluder = scene.objects.get(i).is_none_or(|o| o.occluder);
            let silhouette = match settings.mode {
                Mode::PerTriangle => None,
                _ if !settings.shadows || !occluder => None,
                Mode::Auto => mesh.is_closed_convex(1e-4).then(|| mesh.build_adjacency()),
                Mode::Silhouette => {
                    let adj = mesh.build_adjacency();
                    adj.is_closed_manifold().then_some(adj)
                }
            };
            let tris = if occluder && settings.shadows {
                let tb: Vec<(usize, Bounds3)> = (0..mesh.triangle_count())
                    .map(|t| {
                        let mut tb = Bounds3::EMPTY;
                        for v in mesh.vertices(t) {
                            tb.extend(v);
                        }
                        (t, tb)
                    })
                    .collect();
                ObjectBvh::build(&tb)
            } else {
                ObjectBvh::build(&[])
            };
            if occluder && mesh.triangle_count() > 0 {
                boxes.push((i, b));
            }
            let planar = is_planar(mesh, &b);
            objects.push(ObjectInfo { bounds: b, occluder, silhouette, tris, planar });
        }
        LtcShader { ltc: settings, objects, bvh: ObjectBvh::build(&boxes) }
    }

    /// The LTC description of the material at `si` (`None`: no LTC form, or no material).
    pub fn lobes(scene: &Scene, si: &SurfaceInteraction) -> Option<LtcDescription> {
        scene
            .objects
            .get(si.mesh as usize)
            .and_then(|o| o.material)
            .and_then(|m| scene.materials.as_ref()?.get(m))
            .and_then(|m| m.ltc_lobes(si, scene.textures.as_ref()?))
    }

    /// Occluder loops (world-space directions from `p`) for light triangle `tri` of `light_mesh`.
    #[allow(clippy::too_many_arguments)]
    fn occluders(
        &self,
        scene: &Scene,
        p: DVec3,
        light_mesh: usize,
        tri: usize,
        light_pv: [DVec3; 3],
        receiver: usize,
        scratch: &mut Vec<usize>,
    ) -> Vec<Vec<DVec3>> {
        let mut loops = Vec::new();
        let c = (light_pv[0] + light_pv[1] + light_pv[2]) / 3.0;
        let r = light_pv.iter().map(|v| (*v - c).length()).fold(0.0, f64::max);
        let cone = Cone::towards(p.as_vec3(), c.as_vec3(), r as f32 * 1.001 + 1e-6);
        // The light triangle's plane, oriented towards p: occluders beyond it cannot shadow it.
        let mut ln = (light_pv[1] - light_pv[0]).cross(light_pv[2] - light_pv[0]);
        if ln.dot(p - light_pv[0]) < 0.0 {
            ln = -ln;
        }
        let plane_o = light_pv[0];
        self.bvh.query(&cone, scratch);
        for &o in scratch.iter() {
            let info = &self.objects[o];
            if !info.occluder || (o == light_mesh && info.planar) {
                continue;
            }
            let mesh = &scene.meshes[o];
            let side = |q: Vec3| (d3(q) - plane_o).dot(ln);
            let corners = [info.bounds.min, info.bounds.max];
            let straddles = (0..8).any(|k| {
                let q = Vec3::new(corners[k & 1].x, corners[(k >> 1) & 1].y, corners[(k >> 2) & 1].z);
                side(q) <= 0.0
            });
            if info.silhouette.is_some() && o == receiver {
                // A convex object cannot shadow its own surface.
                continue;
            }
            if let (Some(adj), false, false) = (&info.silhouette, straddles, o == light_mesh) {
                let eps = 1e-7 * (info.bounds.max - info.bounds.min).length() as f64;
                for l in spherical::silhouette_loops(mesh, adj, p, eps) {
                    loops.push(spherical::project(p, &l));
                }
                continue;
            }
            let mut candidates = Vec::new();
            info.tris.query(&cone, &mut candidates);
            for t in candidates {
                if o == light_mesh && t == tri {
                    continue;
                }
                let pv = mesh.vertices(t).map(d3);
                let tc = (pv[0] + pv[1] + pv[2]) / 3.0;
                let tr = pv.iter().map(|v| (*v - tc).length()).fold(0.0, f64::max);
                if !cone.hits_sphere(tc.as_vec3(), tr as f32 * 1.001 + 1e-6) {
                    continue;
                }
                // A triangle whose plane passes through p (the receiver's own, or coplanar
                // with it) subtends no solid angle, but its projection winds around p along a
                // great circle, which would read as a whole hemisphere: skip it.
                let tn = (pv[1] - pv[0]).cross(pv[2] - pv[0]);
                let tn_len = tn.length();
                if !(tn_len > 0.0) || (tn.dot(p - pv[0]) / tn_len).abs() <= 1e-6 * (tr + (p - tc).length()) {
                    continue;
                }
                // Nothing strictly in front of the light's plane (e.g. the other half of a quad
                // light, coplanar with it): it cannot occlude the light.
                let ln_len = ln.length();
                let front = pv.iter().map(|v| (*v - plane_o).dot(ln) / ln_len).fold(f64::MIN, f64::max);
                if !(front > 1e-7 * (tr + (p - tc).length())) {
                    continue;
                }
                let clipped = clip_to_plane(&pv, plane_o, ln);
                if clipped.is_empty() {
                    continue;
                }
                loops.push(spherical::project(p, &clipped));
            }
        }
        loops
    }

    /// Analytic radiance reflected towards `si.wo` from area light `light` (zero for other
    /// lights), with analytic visibility when `shadows`, else unshadowed.
    pub fn area_light(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        desc: &LtcDescription,
        light: &Light,
        shadows: bool,
        scratch: &mut Vec<usize>,
    ) -> Rgb {
        let Some(geom) = light.area() else { return Rgb::ZERO };
        let Some(mesh) = scene.meshes.get(geom.mesh as usize) else { return Rgb::ZERO };
        let p = d3(si.p);
        let n = desc.n.normalize_or_zero();
        if n == Vec3::ZERO {
            return Rgb::ZERO;
        }
        // pbrt-v3's BSDFs reflect on whichever side ωo is (a mesh wound inwards still lights
        // up): integrate over the hemisphere around the normal on ωo's side.
        let n = if n.dot(si.wo) < 0.0 { -n } else { n };
        let frame = ShadingFrame::new(d3(n), d3(si.wo));
        let spec = desc.specular.map(|s| {
            let cos_o = frame.to_local(d3(si.wo)).z.clamp(0.0, 1.0);
            (s, Ltc::lookup(cos_o as f32, s.alpha))
        });
        let mut diffuse_ff = 0.0f64;
        let mut spec_int = 0.0f64;
        // Σ over triangles of F(θd)·∫LTC, for the "average" Fresnel mode.
        let mut spec_fresnel = Rgb::ZERO;
        let wo_local = frame.to_local(d3(si.wo));
        for &tri in &geom.tris {
            let tri = tri as usize;
            if tri >= mesh.triangle_count() {
                continue;
            }
            let pv = mesh.vertices(tri).map(d3);
            if !geom.two_sided {
                let ne = d3(emitting_normal(mesh, tri));
                if ne.dot(p - pv[0]) <= 0.0 {
                    continue;
                }
            }
            let light_loop = spherical::project(p, &pv);
            let mut occ = if shadows {
                self.occluders(scene, p, geom.mesh as usize, tri, pv, si.mesh as usize, scratch)
            } else {
                Vec::new()
            };
            // Keep only occluder loops whose bounding cone meets the light's: most shading
            // points see most lights unoccluded and then need no polygon clipping at all.
            if !occ.is_empty() {
                if let Some(lc) = BoundingCone::of(&light_loop) {
                    occ.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
                }
            }
            // Without occluders the triangle's single loop may have either orientation: its
            // integrals are taken by magnitude. `difference` returns oriented loops.
            let (visible, single) = if occ.is_empty() {
                (vec![light_loop], true)
            } else {
                (spherical::difference(&[light_loop], &occ), false)
            };
            let local: Vec<Vec<DVec3>> =
                visible.iter().map(|l| l.iter().map(|d| frame.to_local(*d)).collect()).collect();
            let ff = spherical::form_factor_loops(&local);
            diffuse_ff += if single { ff.abs() } else { ff };
            if let Some((s, coeffs)) = &spec {
                let v = ltc_integrate(&coeffs.minv, &frame, &visible);
                let v = if single { v.abs() } else { v };
                spec_int += v;
                if self.ltc.fresnel == FresnelMode::Average && v != 0.0 {
                    // The LTC-weighted mean direction of the visible region: the vector form factor
                    // in the cosine space, mapped back by M (Heitz et al.'s proxy direction); the
                    // material's exact Fresnel is taken at the half-vector with ωo.
                    let mut vff = DVec3::ZERO;
                    for l in &local {
                        let t: Vec<DVec3> = l.iter().map(|d| coeffs.minv * *d).collect();
                        let c = spherical::clip_to_horizon(&t);
                        if c.len() >= 3 {
                            vff += spherical::vector_form_factor(&c);
                        }
                    }
                    if single && vff.z < 0.0 {
                        vff = -vff;
                    }
                    let dir = (coeffs.m() * vff).normalize_or_zero();
                    let h = (wo_local + dir).normalize_or_zero();
                    let cos_d = if h == DVec3::ZERO { 1.0 } else { wo_local.dot(h).clamp(0.0, 1.0) };
                    spec_fresnel += fresnel_at(&s.fresnel, cos_d as f32) * v as f32;
                }
            }
        }
        let le = geom.l;
        let mut out = desc.diffuse * le * diffuse_ff.max(0.0) as f32;
        if let Some((s, coeffs)) = spec {
            let spec_term = match self.ltc.fresnel {
                FresnelMode::Schlick => {
                    fresnel_weight(&s.fresnel, coeffs.magnitude, coeffs.fresnel) * spec_int.max(0.0) as f32
                }
                FresnelMode::Average => (spec_fresnel * coeffs.magnitude).max(Rgb::ZERO),
            };
            out += s.scale * spec_term * le;
        }
        out
    }
}

/// The material's own Fresnel reflectance at `cos_d` (pbrt-v3's definitions).
pub(crate) fn fresnel_at(f: &LtcFresnel, cos_d: f32) -> Rgb {
    match *f {
        LtcFresnel::Dielectric { eta_i, eta_t } => Fresnel::Dielectric { eta_i, eta_t }.evaluate(cos_d),
        LtcFresnel::Conductor { eta, k } => Fresnel::Conductor { eta_i: Rgb::ONE, eta_t: eta, k }.evaluate(cos_d),
        LtcFresnel::Schlick { f0 } => f0 + (Rgb::ONE - f0) * (1.0 - cos_d).powi(5),
    }
}

/// The BRDF's integral over the visible region is `magnitude · (F0 + (1 − F0) · fresnel)` times
/// the normalised LTC integral (Heitz et al.'s Schlick split); the material's own Fresnel is
/// reduced to its normal-incidence reflectance `F0` (per channel).
fn fresnel_weight(f: &LtcFresnel, magnitude: f32, fresnel: f32) -> Rgb {
    let f0 = match *f {
        LtcFresnel::Dielectric { eta_i, eta_t } => {
            let r = (eta_t - eta_i) / (eta_t + eta_i);
            Rgb::splat(r * r)
        }
        LtcFresnel::Conductor { eta, k } => {
            // Normal incidence from vacuum: ((η−1)² + k²) / ((η+1)² + k²).
            let one = Rgb::ONE;
            ((eta - one) * (eta - one) + k * k) / ((eta + one) * (eta + one) + k * k)
        }
        LtcFresnel::Schlick { f0 } => f0,
    };
    magnitude * (f0 + (Rgb::ONE - f0) * fresnel)
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
        let lights = scene.light_list();
        let (first, queries) = scene.first_surface(ray);
        stats.rays += queries;
        let SurfaceHit { si, bsdf, le, .. } = match first {
            Ok(h) => h,
            Err(escaped) => return escaped,
        };
        let mut l = le;
        let desc = LtcShader::lobes(scene, &si);
        let mut scratch = Vec::new();
        for (k, light) in lights.iter().enumerate() {
            match (light, &desc) {
                (Light::Area(_), Some(d)) => {
                    l += self.shader.area_light(scene, &si, d, light, self.shader.ltc.shadows, &mut scratch)
                }
                (Light::Infinite(_), _) | (Light::Area(_), None) => {
                    if desc.is_none() && !self.warn_material.swap(true, Ordering::Relaxed) {
                        self.warnings.warn(
                            None,
                            "ltc: a material that does not reduce to a Lambertian plus a GGX lobe \
                             (mirror, glass, translucent, mix, Oren–Nayar, anisotropic…) is rendered \
                             with directlighting's estimator",
                        );
                    }
                    let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                    l += estimate_direct(&si, &bsdf, u_scatter, k, light, u_light, scene, stats);
                }
                _ => {
                    // Delta lights: exact hard shadows with one ray and the real BSDF.
                    let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
                    if let Some(ls) = light.sample_li(&ctx, Vec2::splat(0.5), &scene.meshes) {
                        let f = bsdf.f(si.wo, ls.wi, BxdfFlags::NON_SPECULAR) * ls.wi.dot(si.shading.z).abs();
                        if f != Rgb::ZERO {
                            stats.shadow_rays += 1;
                            if !scene.occluded(&si.spawn_ray_to(ls.p_light)) {
                                l += f * ls.li / ls.pdf;
                            }
                        }
                    }
                }
            }
        }
        l
    }
}

impl Integrator for LtcIntegrator {
    fn name(&self) -> &str {
        "ltc"
    }
    fn requirements(&self) -> Requirements {
        Requirements { accel: true, lights: true, materials: true, ..Default::default() }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        if scene.lights.as_ref().is_some_and(|l| l.lights.iter().any(|x| matches!(x, Light::Infinite(_)))) {
            ctx.warnings
                .warn(None, "ltc: infinite lights have no polygon: they are rendered with directlighting's estimator");
        }
        let est = Estimator {
            shader: LtcShader::new(self, scene),
            warn_material: AtomicBool::new(false),
            warnings: ctx.warnings,
        };
        render_pixels(&est, scene, ctx, film)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    /// A coplanar light triangle sharing an edge (the other half of a quad light) does not
    /// occlude its neighbour from any point.
    fn coplanar_neighbour_does_not_occlude() {
        let a = [DVec3::new(-0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, 0.8)];
        let b = [DVec3::new(-0.8, 3.0, -0.8), DVec3::new(0.8, 3.0, 0.8), DVec3::new(-0.8, 3.0, 0.8)];
        let mut bad = 0;
        for i in 0..200 {
            let p = DVec3::new(-2.0 + 0.02 * i as f64, 0.0, 0.3 - 0.01 * i as f64);
            let la = spherical::project(p, &a);
            let lb = spherical::project(p, &b);
            let ff_a = spherical::form_factor(&la).abs();
            let d = spherical::difference(std::slice::from_ref(&la), &[lb]);
            let ff_d = spherical::form_factor_loops(&d);
            if (ff_a - ff_d).abs() > 1e-6 * ff_a.max(1e-3) {
                bad += 1;
                eprintln!("p {p}: A {ff_a} diff {ff_d} loops {}", d.len());
            }
        }
        assert_eq!(bad, 0);
    }
}
