//! The renderable scene, built from a `SceneDescription` according to what
//! the chosen integrator says it needs ([`Requirements`]).

use crate::accel::{Accel, Hit, Mover};
use crate::bxdf::Bsdf;
use crate::camera::Camera;
use crate::film::FilmSpec;
use crate::filter::Filter;
use crate::geometry::{face_forward, gamma, interpolate, Bounds3, Frame, Ray, RayDifferential};
use crate::interaction::{Differentials, SceneObject, SurfaceInteraction};
use crate::light::{Light, Lights};
use crate::material::{BsdfOptions, Material, Materials, ShadingGeometry};
use crate::mesh::{EdgeAdjacency, NormalRule, TriangleMesh};
use crate::profiling::Phase;
use crate::sampler::Sampler;
use crate::texture::{TextureEvalContext, Textures};
use glam::{Vec2, Vec3};
use penumbra_parser::Entity;
use std::any::Any;
use std::sync::Arc;

mod build;
pub mod cutout;
pub use build::film_spec;

/// What the scene build must provide for an integrator. Everything is off by
/// default: the builder computes only what is asked for and present.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Requirements {
    /// A BVH over all geometry for ray queries.
    pub accel: bool,
    /// Lights (with their sampling distributions).
    pub lights: bool,
    /// Materials and the textures they reference.
    pub materials: bool,
    /// Per-mesh edge adjacency ([`Scene::adjacency`]: silhouettes, closedness, outlines).
    pub adjacency: bool,
    /// At least this many camera samples per pixel, and the integrator's reason (said in the
    /// warning when the scene's or the command line's count is raised).
    pub min_pixel_samples: Option<(u32, &'static str)>,
    /// The integrator renders BSSRDFs ([`Scene::bssrdf`]; `path`). Otherwise the build warns
    /// once per material type that has one: only its interface is rendered.
    pub subsurface: bool,
}

/// A crop given on the command line: fractions (pbrt-v3's `cropwindow`) or pixel bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Crop {
    Fraction([f32; 4]),
    /// `[x0, x1, y0, y1]`, half-open.
    Pixels([i32; 4]),
}

/// Command-line overrides of what the scene file says.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildOptions {
    pub spp: Option<u32>,
    pub seed: u64,
    pub crop: Option<Crop>,
    /// Overrides of the film resolution (tests render scenes small).
    pub resolution: Option<(u32, u32)>,
}

/// The first surface with a material along a ray, before its BSDF is built
/// ([`Scene::first_point`]; [`SurfacePoint::with_bsdf`] builds it).
#[derive(Clone, Debug)]
pub struct SurfacePoint {
    pub hit: Hit,
    pub si: SurfaceInteraction,
    /// Radiance emitted towards the ray's origin when the surface is an area light.
    pub le: crate::Rgb,
}

impl SurfacePoint {
    /// With its BSDF (`None` only when `scene` has no material for it, which
    /// [`Scene::first_point`] never returns).
    pub fn with_bsdf(&self, scene: &Scene) -> Option<SurfaceHit> {
        let bsdf = scene.bsdf(&self.si)?;
        Some(SurfaceHit { hit: self.hit, si: self.si, bsdf, le: self.le })
    }
}

/// The first surface with a material along a ray ([`Scene::first_surface`]).
pub struct SurfaceHit {
    pub hit: Hit,
    pub si: SurfaceInteraction,
    pub bsdf: Bsdf,
    /// Radiance emitted towards the ray's origin when the surface is an area light.
    pub le: crate::Rgb,
}

/// Time spent and what was built, for `penumbra info` and `stats.json`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildReport {
    /// (stage, seconds, detail)
    pub stages: Vec<(String, f64, String)>,
    /// The stage name of what the integrator prepared for its own method, if anything.
    pub prepared: Option<String>,
    /// Further lines about what was built, for `penumbra info` (e.g. an integrator's prepared
    /// structure object by object).
    pub details: Vec<String>,
}

impl BuildReport {
    pub fn total_seconds(&self) -> f64 {
        self.stages.iter().map(|s| s.1).sum()
    }
}

pub struct Scene {
    pub camera: Camera,
    pub film: FilmSpec,
    pub filter: Box<dyn Filter>,
    pub sampler: Box<dyn Sampler>,
    /// World-space meshes, one per object.
    pub meshes: Vec<TriangleMesh>,
    pub objects: Vec<SceneObject>,
    pub accel: Option<Accel>,
    /// Edge adjacency of every mesh (built when `Requirements::adjacency`, else empty).
    pub adjacency: Vec<EdgeAdjacency>,
    /// Lights (built when `Requirements::lights`).
    pub lights: Option<Lights>,
    /// Built when `Requirements::materials`: only materials some object uses.
    pub materials: Option<Materials>,
    /// Built when `Requirements::materials` or a mesh has an alpha cut-out: only the textures a
    /// built material or a cut-out references.
    pub textures: Option<Arc<Textures>>,
    pub bounds: Bounds3,
    /// The scene's own `Integrator` directive.
    pub integrator: Entity,
    pub report: BuildReport,
    /// What the integrator built over the scene for its own method
    /// ([`Integrator::prepare`](crate::integrator::Integrator::prepare)), kept with the scene
    /// so that every render of it shares one build; read with [`Scene::prepared`].
    pub prepared: Option<Arc<dyn Any + Send + Sync>>,
    /// The shapes that move (their meshes in `meshes` are at their start transforms; ray
    /// queries and hits take them where they are at the ray's time).
    pub movers: Vec<Mover>,
    /// `(mesh, mover, place in the mover)` of every moving mesh, sorted by mesh.
    pub(crate) mover_lookup: Vec<(u32, u32, u32)>,
}

/// What [`Scene::non_polygonal_occluder`] says of a moving shape.
pub const MOVING: &str =
    "moves (animated transform: its ray queries follow it through the shutter; one outline cannot)";

/// A ray bundle with more candidate triangles than this is traversed ray by ray: testing each
/// candidate would cost more than a traversal.
const BUNDLE_LIMIT: usize = 12;

impl Scene {
    /// The integrator's prepared structure, when it is a `T`.
    pub fn prepared<T: Any>(&self) -> Option<&T> {
        self.prepared.as_deref()?.downcast_ref::<T>()
    }

    /// The edge adjacency of mesh `mesh` (`None` unless `Requirements::adjacency`).
    pub fn adjacency(&self, mesh: usize) -> Option<&EdgeAdjacency> {
        self.adjacency.get(mesh)
    }

    /// Closest hit (requires `Requirements::accel`).
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        crate::profiling::closest_hit(|| self.accel.as_ref().and_then(|a| a.intersect(ray)))
    }

    /// The scene's lights (empty when they were not built).
    pub fn light_list(&self) -> &[Light] {
        self.lights.as_ref().map(|l| l.lights.as_slice()).unwrap_or(&[])
    }

    /// Follows `ray` through surfaces without a material (pbrt-v3's `Material "none"`: passed
    /// through without counting depth, at most 64 of them) to the first surface with one.
    /// `Err` carries the radiance of the ray leaving the scene (the infinite lights'), or 0 after
    /// 64 pass-throughs. The second value is the number of intersection queries made.
    /// The interaction has the ray's differentials when it has offset rays and reached the
    /// surface directly (as in pbrt-v3, a ray passed through a surface loses them); pass a
    /// plain [`Ray`] as `&ray.into()`.
    pub fn first_surface(&self, ray: &RayDifferential) -> (Result<SurfaceHit, crate::Rgb>, u64) {
        let (first, queries) = self.first_point(ray);
        let first = first.and_then(|pt| pt.with_bsdf(self).ok_or(crate::Rgb::ZERO));
        (first, queries)
    }

    /// [`first_surface`](Self::first_surface) without building the BSDF (for a method that
    /// shades a pixel's surfaces once and may not need it for every sample).
    pub fn first_point(&self, ray: &RayDifferential) -> (Result<SurfacePoint, crate::Rgb>, u64) {
        self.first_point_among(ray, None, None)
    }

    /// The triangles that a bundle of rays from one origin (a pixel's camera rays) can hit,
    /// for [`first_point_among`](Self::first_point_among); `None` when a per-ray traversal is
    /// the better (or the only) way ([`Accel::bundle_candidates`](crate::accel::Accel::bundle_candidates)).
    pub fn bundle_candidates<R: AsRef<Ray>>(&self, rays: &[R]) -> Option<Vec<u32>> {
        self.accel.as_ref()?.bundle_candidates(rays, BUNDLE_LIMIT)
    }

    /// [`first_point`](Self::first_point) for a ray of a bundle whose
    /// [`bundle_candidates`](Self::bundle_candidates) are `candidates`: its first query tests
    /// only those (the same hit); pass-throughs of material-less surfaces traverse.
    /// `prev`, the bundle's previous first surface, may lend its per-triangle geometry
    /// ([`interaction_after`](Self::interaction_after)).
    pub fn first_point_among(
        &self,
        ray_differential: &RayDifferential,
        candidates: Option<&[u32]>,
        prev: Option<&SurfaceInteraction>,
    ) -> (Result<SurfacePoint, crate::Rgb>, u64) {
        let mut ray = ray_differential.ray;
        for queries in 1..=65u64 {
            let hit = match (candidates, &self.accel) {
                (Some(c), Some(a)) if queries == 1 => crate::profiling::closest_hit(|| a.intersect_among(&ray, c)),
                _ => self.intersect(&ray),
            };
            let Some(hit) = hit else {
                return (Err(self.light_list().iter().map(|l| l.le(&ray)).sum()), queries);
            };
            let mut si = self.interaction_after(&ray, &hit, prev);
            if queries == 1 {
                si.compute_differentials(ray_differential);
            }
            if self.material_of(&si).is_some() {
                let le = self.area_light_at(&hit).map_or(crate::Rgb::ZERO, |k| self.light_list()[k].l(si.n, si.wo));
                return (Ok(SurfacePoint { hit, si, le }), queries);
            }
            ray = si.spawn_ray(ray.d);
        }
        (Err(crate::Rgb::ZERO), 65)
    }

    /// The index (into `lights.lights`) of the area light that the hit triangle belongs to.
    pub fn area_light_at(&self, hit: &Hit) -> Option<usize> {
        self.lights.as_ref()?.light_of(hit.mesh, hit.tri)
    }

    /// Whether anything blocks `ray` before `ray.t_max`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        crate::profiling::timed(Phase::Shadow, || self.accel.as_ref().is_some_and(|a| a.occluded(ray)))
    }

    /// The BSDF at `si` (requires `Requirements::materials`); `None` when the object
    /// has no material (pbrt-v3's `Material "none"`) or materials were not built.
    pub fn bsdf(&self, si: &SurfaceInteraction) -> Option<Bsdf> {
        self.bsdf_with(si, BsdfOptions::default())
    }

    /// [`bsdf`](Self::bsdf) with explicit options (`path` asks for pbrt-v3's multiple-lobe glass).
    pub fn bsdf_with(&self, si: &SurfaceInteraction, opts: BsdfOptions) -> Option<Bsdf> {
        let (mat, materials, textures) = self.material_of(si)?;
        Some(crate::profiling::timed(Phase::Shading, || {
            mat.compute_bsdf_ext(
                si,
                &TextureEvalContext::from_si(si),
                &ShadingGeometry::of(si),
                opts,
                materials,
                textures,
            )
        }))
    }

    /// The first object with an `alpha` or `shadowalpha` cut-out that occludes (its
    /// `"bool occluder"` is not false): every ray query honours the cut-out, but visibility
    /// built from the meshes' outlines (`ltc`'s polygons, `silhouette`'s edges, `shexp`'s
    /// spheres) cannot represent one.
    pub fn cutout_occluder(&self) -> Option<&SceneObject> {
        self.meshes
            .iter()
            .zip(&self.objects)
            .find(|(m, o)| o.occluder && (m.alpha.is_some() || m.shadow_alpha.is_some()))
            .map(|(_, o)| o)
    }

    /// The first occluding object that visibility built from the meshes' outlines cannot
    /// represent, and why: an alpha cut-out ([`cutout_occluder`](Self::cutout_occluder)) or a
    /// `curve` (intersected analytically: it has no triangles to outline).
    pub fn non_polygonal_occluder(&self) -> Option<(&SceneObject, &'static str)> {
        self.cutout_occluder()
            .map(|o| (o, "has an \"alpha\"/\"shadowalpha\" cut-out"))
            .or_else(|| {
                self.meshes
                    .iter()
                    .zip(&self.objects)
                    .find(|(m, o)| o.occluder && m.curves.is_some())
                    .map(|(_, o)| (o, "is a curve (intersected as pbrt-v3 does, with no triangles to outline)"))
            })
            .or_else(|| self.moving_occluder().map(|o| (o, MOVING)))
    }

    /// The first occluding object that moves (an animated transform of its own or of its
    /// instance): ray queries find it where it is at each ray's time, but visibility built
    /// from the meshes' outlines has one position for every sample.
    pub fn moving_occluder(&self) -> Option<&SceneObject> {
        self.movers.iter().flat_map(|m| &m.meshes).filter_map(|&i| self.objects.get(i as usize)).find(|o| o.occluder)
    }

    /// The BSSRDF under `si`, whose BSDF (built with `opts`) is `bsdf`; `None` when its material
    /// has none (see [`Material::bssrdf`]).
    pub fn bssrdf(
        &self,
        si: &SurfaceInteraction,
        bsdf: &Bsdf,
        opts: BsdfOptions,
    ) -> Option<crate::bssrdf::SeparableBssrdf<'_>> {
        let mut index = self.objects.get(si.mesh as usize)?.material?;
        let (mut mat, materials, textures) = self.material_of(si)?;
        // pbrt-v3's `mix` keeps its first material's BSSRDF, whose probes then look for the
        // surfaces of that material (not the mix's: a mixed BSSRDF finds no exit and ends the path).
        for _ in 0..16 {
            let Material::Mix { m1, .. } = mat else { break };
            index = *m1;
            mat = materials.get(index)?;
        }
        if !mat.may_have_bssrdf() {
            return None;
        }
        mat.bssrdf(si, &TextureEvalContext::from_si(si), bsdf, opts, textures, index)
    }

    /// The material at `si`, with the material and texture tables (`None` as for [`bsdf`](Self::bsdf)).
    pub fn material_of(&self, si: &SurfaceInteraction) -> Option<(&Material, &Materials, &Textures)> {
        let (materials, textures) = (self.materials.as_ref()?, self.textures.as_deref()?);
        Some((materials.get(self.objects.get(si.mesh as usize)?.material?)?, materials, textures))
    }

    /// The surface geometry at a hit, as pbrt-v3's `Triangle::Intersect` computes it.
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        self.interaction_after(ray, hit, None)
    }

    /// [`interaction`](Self::interaction), taking the per-triangle part (normal, ∂p/∂u, ∂p/∂v,
    /// shading frame) from `prev` when it is on the same triangle of a mesh without per-vertex
    /// normals or tangents — where that part is the triangle's alone: the same result, for the
    /// samples of a pixel that mostly see one triangle. The differentials are left zero (see
    /// [`SurfaceInteraction::compute_differentials`]).
    pub fn interaction_after(&self, ray: &Ray, hit: &Hit, prev: Option<&SurfaceInteraction>) -> SurfaceInteraction {
        if !self.movers.is_empty() {
            if let Some(si) = self.moving_interaction(ray, hit) {
                return si;
            }
        }
        let mesh = &self.meshes[hit.mesh as usize];
        if let Some(c) = &mesh.curves {
            return curve_interaction(c, ray, hit);
        }
        mesh_interaction(mesh, ray, hit, prev)
    }

    /// Whether camera rays need a time: the camera or a shape moves.
    pub fn uses_time(&self) -> bool {
        self.camera.uses_time() || !self.movers.is_empty()
    }

    /// The moving shape (index into [`movers`](Self::movers)) and its mesh's place in it, of
    /// scene mesh `mesh`.
    pub fn mover_of(&self, mesh: u32) -> Option<(usize, usize)> {
        let i = self.mover_lookup.binary_search_by_key(&mesh, |e| e.0).ok()?;
        let (_, m, k) = self.mover_lookup[i];
        Some((m as usize, k as usize))
    }

    /// The interaction at a hit on a moving shape (pbrt-v3's `TransformedPrimitive`: the
    /// object-space hit moved by the transform at the ray's time): the triangle's vertices,
    /// normals and tangents at that time, with the error bound of the transform added.
    /// `None` when the mesh does not move.
    fn moving_interaction(&self, ray: &Ray, hit: &Hit) -> Option<SurfaceInteraction> {
        let (i, k) = self.mover_of(hit.mesh)?;
        let mover = &self.movers[i];
        let obj = mover.object.get(k)?;
        let tri = hit.tri as usize;
        let idx = *obj.indices.get(tri)?;
        let m = mover.transform.at(ray.time);
        let lin = glam::DMat3::from_mat4(m);
        let normal_m = lin.inverse().transpose();
        let pv = idx.map(|v| obj.positions[v as usize]);
        let at = |p: Vec3| m.transform_point3(p.as_dvec3()).as_vec3();
        let normals = obj
            .normals
            .as_ref()
            .map(|ns| idx.map(|v| (normal_m * ns[v as usize].as_dvec3()).normalize_or_zero().as_vec3()).to_vec());
        let tangents =
            obj.tangents.as_ref().map(|ts| idx.map(|v| (lin * ts[v as usize].as_dvec3()).as_vec3()).to_vec());
        let moved = TriangleMesh {
            positions: pv.map(at).to_vec(),
            indices: vec![[0, 1, 2]],
            normals,
            uvs: Some(obj.default_uvs(tri).to_vec()),
            tangents,
            flip_normals: obj.flip_normals,
            reverse_orientation: obj.reverse_orientation,
            winding_reversed: obj.winding_reversed,
            normal_rule: obj.normal_rule,
            analytic_ng: obj.analytic_ng,
            ..Default::default()
        };
        let mut si = mesh_interaction(&moved, ray, &Hit { tri: 0, ..*hit }, None);
        si.tri = hit.tri;
        // pbrt-v3's `Transform` of an interaction's error: the object-space point's bound
        // carried through the transform, plus the rounding of the transform itself.
        let b = hit.b;
        let p_obj = interpolate(pv, b).as_dvec3();
        let abs_obj = (pv[0].abs() * b[0].abs() + pv[1].abs() * b[1].abs() + pv[2].abs() * b[2].abs()).as_dvec3();
        let abs_lin = glam::DMat3::from_cols(lin.x_axis.abs(), lin.y_axis.abs(), lin.z_axis.abs());
        let err = abs_lin * (abs_obj * gamma(7) as f64)
            + (abs_lin * p_obj.abs() + m.w_axis.truncate().abs()) * gamma(3) as f64;
        si.p_error += err.as_vec3();
        Some(si)
    }
}

/// The surface geometry at a hit on a triangle of `mesh`, as pbrt-v3's `Triangle::Intersect`
/// computes it (see [`Scene::interaction_after`]).
fn mesh_interaction(
    mesh: &TriangleMesh,
    ray: &Ray,
    hit: &Hit,
    prev: Option<&SurfaceInteraction>,
) -> SurfaceInteraction {
    {
        let tri = hit.tri as usize;
        let pv = mesh.vertices(tri);
        let b = hit.b;
        let p = interpolate(pv, b);
        let p_abs = pv[0].abs() * b[0].abs() + pv[1].abs() * b[1].abs() + pv[2].abs() * b[2].abs();
        let p_error = gamma(7) * p_abs;
        let uvv = mesh.default_uvs(tri);
        let uv = interpolate(uvv, b);
        let wo = -ray.d.normalize_or_zero();
        let flat = mesh.normals.is_none() && mesh.tangents.is_none();
        if let Some(q) = prev.filter(|q| q.mesh == hit.mesh && q.tri == hit.tri && flat) {
            return SurfaceInteraction { p, p_error, uv, wo, diff: Differentials::default(), time: ray.time, ..*q };
        }
        let duv02 = uvv[0] - uvv[2];
        let duv12 = uvv[1] - uvv[2];
        let dp02 = pv[0] - pv[2];
        let dp12 = pv[1] - pv[2];
        let det = duv02.x * duv12.y - duv02.y * duv12.x;
        // The stored winding is pbrt-v3's geometric normal (see `crate::mesh`).
        let ng = dp02.cross(dp12).normalize_or_zero();
        let degenerate = det.abs() < 1e-8;
        let (dpdu, dpdv) = {
            let (u, v) = if degenerate {
                (Vec3::ZERO, Vec3::ZERO)
            } else {
                let inv = 1.0 / det;
                ((duv12.y * dp02 - duv02.y * dp12) * inv, (duv02.x * dp12 - duv12.x * dp02) * inv)
            };
            if degenerate || u.cross(v).length_squared() == 0.0 {
                let f = Frame::from_z(ng);
                (f.x, f.y)
            } else {
                (u, v)
            }
        };
        let base = SurfaceInteraction {
            p,
            p_error,
            n: ng,
            uv,
            dpdu,
            dpdv,
            shading: Frame::from_zx(ng, dpdu),
            shading_dpdu: dpdu,
            shading_dpdv: dpdv,
            dndu: Vec3::ZERO,
            dndv: Vec3::ZERO,
            diff: Differentials::default(),
            wo,
            mesh: hit.mesh,
            tri: hit.tri,
            wall: Vec3::ZERO,
            surface: Vec3::ZERO,
            time: ray.time,
        };
        if flat {
            return base;
        }
        let (dndu, dndv) = normal_derivatives(mesh, tri, uvv, degenerate);
        let ns0 = mesh.interpolated_normal(tri, b);
        let mut si = SurfaceInteraction { dndu, dndv, ..base };
        match (mesh.normal_rule, ns0) {
            (NormalRule::Quadric, Some(ns0)) => {
                // The analytic shape's frame: its normal (flipped as pbrt-v3 flips it) and its
                // own ∂p/∂u, ∂p/∂v, made tangent to that normal.
                let ns = ns0 * mesh.hit_normal_sign();
                si.n = if mesh.analytic_ng && ns != Vec3::ZERO { ns } else { face_forward(ng, ns) };
                if let Some(sn) = mesh.surface_normals.as_ref().filter(|_| mesh.analytic_ng && ns != Vec3::ZERO) {
                    let g = interpolate(mesh.indices[tri].map(|i| sn[i as usize]), b).normalize_or_zero();
                    if g != Vec3::ZERO && g.is_finite() {
                        si.wall = face_forward(ng, wo);
                        si.surface = face_forward(g, wo);
                    }
                }
                si.shading = Frame::from_zx(ns, dpdu);
                si.shading_dpdu = dpdu - ns * ns.dot(dpdu);
                si.shading_dpdv = dpdv - ns * ns.dot(dpdv);
            }
            (_, ns0) => {
                // pbrt-v3's `Triangle::Intersect` shading geometry: unit tangents around the
                // interpolated normal (or the geometric one), the bitangent negated by
                // `ReverseOrientation`, which flips the shading normal.
                let ns0 = ns0.unwrap_or(ng);
                let ss = mesh
                    .tangents
                    .as_ref()
                    .map(|s| interpolate(mesh.indices[tri].map(|i| s[i as usize]), b).normalize_or_zero())
                    .filter(|s| *s != Vec3::ZERO && s.is_finite())
                    .unwrap_or_else(|| dpdu.normalize_or_zero());
                let ts = ss.cross(ns0);
                let (ss, ts) = if ts.length_squared() > 0.0 {
                    let ts = ts.normalize();
                    (ts.cross(ns0), ts)
                } else {
                    let f = Frame::from_z(ns0);
                    (f.x, f.y)
                };
                let ts = if mesh.reverse_orientation { -ts } else { ts };
                let ns = ss.cross(ts).normalize_or_zero();
                si.n = face_forward(ng, ns);
                let x = mesh.tangents.as_ref().map_or(dpdu, |_| ss);
                si.shading = Frame::from_zx(ns, x);
                si.shading_dpdu = ss;
                si.shading_dpdv = ts;
            }
        }
        si
    }
}

/// pbrt-v3's `Curve::Intersect` surface interaction at a curve hit (`hit.b` = `[u, v, width]`):
/// one normal for geometry and shading, no normal derivatives.
fn curve_interaction(c: &crate::mesh::curve::Curves, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
    let h = crate::mesh::curve::CurveHit { t: hit.t, u: hit.b[0], v: hit.b[1], width: hit.b[2] };
    let g = c.geometry(hit.tri as usize, ray.o, ray.d, &h);
    SurfaceInteraction {
        p: g.p,
        p_error: g.p_error,
        n: g.n,
        uv: g.uv,
        dpdu: g.dpdu,
        dpdv: g.dpdv,
        shading: Frame::from_zx(g.n, g.dpdu),
        shading_dpdu: g.dpdu,
        shading_dpdv: g.dpdv,
        dndu: Vec3::ZERO,
        dndv: Vec3::ZERO,
        diff: Differentials::default(),
        wo: -ray.d.normalize_or_zero(),
        mesh: hit.mesh,
        tri: hit.tri,
        wall: Vec3::ZERO,
        surface: Vec3::ZERO,
        time: ray.time,
    }
}

/// pbrt-v3's `Triangle::Intersect` ∂n/∂u, ∂n/∂v: the (unflipped) per-vertex normals
/// differenced over the triangle's (u, v); for a degenerate (u, v), any two tangents of the
/// plane the normal differences span. Zero without normals.
fn normal_derivatives(mesh: &TriangleMesh, tri: usize, uvv: [Vec2; 3], degenerate_uv: bool) -> (Vec3, Vec3) {
    let Some(ns) = &mesh.normals else { return (Vec3::ZERO, Vec3::ZERO) };
    let [n0, n1, n2] = mesh.indices[tri].map(|i| ns[i as usize]);
    if degenerate_uv {
        let dn = (n2 - n0).cross(n1 - n0);
        if dn.length_squared() == 0.0 {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        let f = Frame::from_z(dn.normalize());
        return (f.x, f.y);
    }
    let (duv02, duv12) = (uvv[0] - uvv[2], uvv[1] - uvv[2]);
    let (dn1, dn2) = (n0 - n2, n1 - n2);
    let inv = 1.0 / (duv02.x * duv12.y - duv02.y * duv12.x);
    ((duv12.y * dn1 - duv02.y * dn2) * inv, (duv02.x * dn2 - duv12.x * dn1) * inv)
}
