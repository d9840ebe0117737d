//! The renderable scene, built from a `SceneDescription` according to what
//! the chosen integrator says it needs ([`Requirements`]).

use crate::accel::{Accel, Hit, DEFAULT_UV};
use crate::bxdf::Bsdf;
use crate::camera::Camera;
use crate::film::FilmSpec;
use crate::filter::Filter;
use crate::geometry::{face_forward, gamma, interpolate, Bounds3, Frame, Ray};
use crate::interaction::{SceneObject, SurfaceInteraction};
use crate::light::{Light, Lights};
use crate::material::{BsdfOptions, Material, Materials, ShadingGeometry};
use crate::mesh::{EdgeAdjacency, TriangleMesh};
use crate::phase::Phase;
use crate::sampler::Sampler;
use crate::texture::{TextureEvalContext, Textures};
use glam::Vec3;
use penumbra_parser::Entity;
use std::any::Any;
use std::sync::Arc;

mod build;
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
    /// Built when `Requirements::materials`: only textures a built material references.
    pub textures: Option<Textures>,
    pub bounds: Bounds3,
    /// The scene's own `Integrator` directive.
    pub integrator: Entity,
    pub report: BuildReport,
    /// What the integrator built over the scene for its own method
    /// ([`Integrator::prepare`](crate::integrator::Integrator::prepare)), kept with the scene
    /// so that every render of it shares one build; read with [`Scene::prepared`].
    pub prepared: Option<Arc<dyn Any + Send + Sync>>,
}

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
        crate::phase::closest_hit(|| self.accel.as_ref().and_then(|a| a.intersect(ray)))
    }

    /// The scene's lights (empty when they were not built).
    pub fn light_list(&self) -> &[Light] {
        self.lights.as_ref().map(|l| l.lights.as_slice()).unwrap_or(&[])
    }

    /// Follows `ray` through surfaces without a material (pbrt-v3's `Material "none"`: passed
    /// through without counting depth, at most 64 of them) to the first surface with one.
    /// `Err` carries the radiance of the ray leaving the scene (the infinite lights'), or 0 after
    /// 64 pass-throughs. The second value is the number of intersection queries made.
    pub fn first_surface(&self, ray: &Ray) -> (Result<SurfaceHit, crate::Rgb>, u64) {
        let (first, queries) = self.first_point(ray);
        let first = first.and_then(|pt| pt.with_bsdf(self).ok_or(crate::Rgb::ZERO));
        (first, queries)
    }

    /// [`first_surface`](Self::first_surface) without building the BSDF (for a method that
    /// shades a pixel's surfaces once and may not need it for every sample).
    pub fn first_point(&self, ray: &Ray) -> (Result<SurfacePoint, crate::Rgb>, u64) {
        self.first_point_among(ray, None, None)
    }

    /// The triangles that a bundle of rays from one origin (a pixel's camera rays) can hit,
    /// for [`first_point_among`](Self::first_point_among); `None` when a per-ray traversal is
    /// the better (or the only) way ([`Accel::bundle_candidates`](crate::accel::Accel::bundle_candidates)).
    pub fn bundle_candidates(&self, rays: &[Ray]) -> Option<Vec<u32>> {
        self.accel.as_ref()?.bundle_candidates(rays, BUNDLE_LIMIT)
    }

    /// [`first_point`](Self::first_point) for a ray of a bundle whose
    /// [`bundle_candidates`](Self::bundle_candidates) are `candidates`: its first query tests
    /// only those (the same hit); pass-throughs of material-less surfaces traverse.
    /// `prev`, the bundle's previous first surface, may lend its per-triangle geometry
    /// ([`interaction_after`](Self::interaction_after)).
    pub fn first_point_among(
        &self,
        ray: &Ray,
        candidates: Option<&[u32]>,
        prev: Option<&SurfaceInteraction>,
    ) -> (Result<SurfacePoint, crate::Rgb>, u64) {
        let mut ray = *ray;
        for queries in 1..=65u64 {
            let hit = match (candidates, &self.accel) {
                (Some(c), Some(a)) if queries == 1 => crate::phase::closest_hit(|| a.intersect_among(&ray, c)),
                _ => self.intersect(&ray),
            };
            let Some(hit) = hit else {
                return (Err(self.light_list().iter().map(|l| l.le(&ray)).sum()), queries);
            };
            let si = self.interaction_after(&ray, &hit, prev);
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
        crate::phase::timed(Phase::Shadow, || self.accel.as_ref().is_some_and(|a| a.occluded(ray)))
    }

    /// The BSDF at `si` (requires `Requirements::materials`); `None` when the object
    /// has no material (pbrt-v3's `Material "none"`) or materials were not built.
    pub fn bsdf(&self, si: &SurfaceInteraction) -> Option<Bsdf> {
        self.bsdf_with(si, BsdfOptions::default())
    }

    /// [`bsdf`](Self::bsdf) with explicit options (`path` asks for pbrt-v3's multiple-lobe glass).
    pub fn bsdf_with(&self, si: &SurfaceInteraction, opts: BsdfOptions) -> Option<Bsdf> {
        let (mat, materials, textures) = self.material_of(si)?;
        let normals = self.meshes.get(si.mesh as usize).is_some_and(|m| m.normals.is_some());
        Some(crate::phase::timed(Phase::Shading, || {
            mat.compute_bsdf_ext(
                si,
                &TextureEvalContext::from_si(si),
                &ShadingGeometry::of(si, normals),
                opts,
                materials,
                textures,
            )
        }))
    }

    /// The material at `si`, with the material and texture tables (`None` as for [`bsdf`](Self::bsdf)).
    pub fn material_of(&self, si: &SurfaceInteraction) -> Option<(&Material, &Materials, &Textures)> {
        let (materials, textures) = (self.materials.as_ref()?, self.textures.as_ref()?);
        Some((materials.get(self.objects.get(si.mesh as usize)?.material?)?, materials, textures))
    }

    /// The surface geometry at a hit, as pbrt-v3's `Triangle::Intersect` computes it.
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        self.interaction_after(ray, hit, None)
    }

    /// [`interaction`](Self::interaction), taking the per-triangle part (normal, ∂p/∂u, ∂p/∂v,
    /// shading frame) from `prev` when it is on the same triangle of a mesh without per-vertex
    /// normals — where that part is the triangle's alone: the same result, for the samples of a
    /// pixel that mostly see one triangle.
    pub fn interaction_after(&self, ray: &Ray, hit: &Hit, prev: Option<&SurfaceInteraction>) -> SurfaceInteraction {
        let mesh = &self.meshes[hit.mesh as usize];
        let tri = hit.tri as usize;
        let idx = mesh.indices[tri];
        let pv = mesh.vertices(tri);
        let b = hit.b;
        let p = interpolate(pv, b);
        let p_abs = pv[0].abs() * b[0].abs() + pv[1].abs() * b[1].abs() + pv[2].abs() * b[2].abs();
        let p_error = gamma(7) * p_abs;
        let uvv = match &mesh.uvs {
            Some(uv) => idx.map(|i| uv[i as usize]),
            None => DEFAULT_UV,
        };
        let uv = interpolate(uvv, b);
        let wo = -ray.d.normalize_or_zero();
        if let Some(q) = prev.filter(|q| q.mesh == hit.mesh && q.tri == hit.tri && mesh.normals.is_none()) {
            return SurfaceInteraction { p, p_error, uv, wo, ..*q };
        }
        let duv02 = uvv[0] - uvv[2];
        let duv12 = uvv[1] - uvv[2];
        let dp02 = pv[0] - pv[2];
        let dp12 = pv[1] - pv[2];
        let det = duv02.x * duv12.y - duv02.y * duv12.x;
        let mut ng = dp02.cross(dp12).normalize_or_zero();
        if mesh.flip_normals {
            ng = -ng;
        }
        let (dpdu, dpdv) = {
            let degenerate = det.abs() < 1e-8;
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
        let mut n = ng;
        let ns = mesh.normals.as_ref().map(|ns| interpolate(idx.map(|i| ns[i as usize]), b).normalize_or_zero());
        let shading = match ns {
            Some(ns) if ns != Vec3::ZERO && ns.is_finite() => {
                n = face_forward(n, ns);
                let ss = match &mesh.tangents {
                    Some(s) => interpolate(idx.map(|i| s[i as usize]), b),
                    None => dpdu,
                };
                Frame::from_zx(ns, ss)
            }
            _ => Frame::from_zx(n, dpdu),
        };
        SurfaceInteraction { p, p_error, n, uv, dpdu, dpdv, shading, wo, mesh: hit.mesh, tri: hit.tri }
    }
}
