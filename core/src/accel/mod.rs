//! Ray/scene queries on an obvhs compressed wide BVH.
//!
//! Two things make queries behave the same at every scene scale:
//! - geometry is stored scaled by a power of two `s` chosen so the scene's
//!   extent is about 1; scaling by 2ᵏ is exact in floating point, so hits are
//!   the world-space hits, and obvhs's fixed node near-distance of 1e-4 is
//!   relative to the scene instead of absolute;
//! - that clamp would still cull nodes within 1e-4 (normalised) of the ray
//!   origin, so every query starts `BACKUP` behind its origin and triangles
//!   before the true origin are rejected in the intersection routine.
//!
//! Triangles are intersected with the watertight algorithm of Woop et al. and
//! pbrt-v3's conservative bound on `t`, so rays spawned with
//! [`crate::geometry::offset_ray_origin`] never re-hit their own surface.
//!
//! [`objects`]: a small hierarchy over object bounds queried with cones (occluder search).

#[cfg(feature = "embree")]
mod embree;
pub mod objects;

use crate::geometry::{gamma, next_float_down, Bounds3, Ray};
use crate::mesh::curve::Curves;
use crate::mesh::hash::WordHash;
use crate::mesh::TriangleMesh;
use crate::motion::MovingTransform;
use glam::{Vec2, Vec3, Vec3A};
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::{aabb::Aabb, Boundable, BvhBuildParams};
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Duration;

/// How far (normalised units) each query is started behind its origin; a power
/// of two so that backing up adds no rounding of its own beyond one subtraction.
const BACKUP: f32 = 1.0 / 1024.0;

/// A closest hit: the mesh, the triangle and the barycentrics of the hit point. On a curve
/// (a mesh with [`TriangleMesh::curves`]), `tri` is the curve's piece and `b` holds pbrt-v3's
/// `[u, v, hit width]` ([`crate::mesh::curve::CurveHit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub mesh: u32,
    pub tri: u32,
    /// Barycentric weights of vertices 0, 1, 2.
    pub b: [f32; 3],
}

#[derive(Clone, Copy)]
struct Tri([Vec3A; 3]);

impl Boundable for Tri {
    fn aabb(&self) -> Aabb {
        let mut a = Aabb::empty();
        for v in self.0 {
            a.extend(v);
        }
        a
    }
}

/// The alpha test of cut-out meshes (pbrt-v3's `alpha` and `shadowalpha` textures), asked by
/// every query about each candidate hit on a mesh the hierarchy was built with as cut-out
/// ([`Accel::set_filter`]).
pub trait HitFilter: Send + Sync {
    /// Whether the candidate `hit` (its `t` in world units) counts: pbrt-v3's
    /// `Triangle::Intersect` discards a hit where `alpha` evaluates to 0, and its
    /// `IntersectP` (`shadow`, occlusion queries) also where `shadowalpha` does.
    fn accept(&self, hit: &Hit, shadow: bool) -> bool;
}

/// A triangle of the scene: (mesh index, triangle index within the mesh).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriRef {
    pub mesh: u32,
    pub tri: u32,
}

/// Meshes that move as one (pbrt-v3's `TransformedPrimitive` over an animated shape's, or an
/// animated object instance's, primitives): queried through a hierarchy of their own in object
/// space, with each ray taken there by the inverse of the transform at the ray's time; the
/// scene's hierarchy holds them as one slot, a box bounding their whole motion.
#[derive(Clone, Debug)]
pub struct Mover {
    pub transform: MovingTransform,
    /// The scene's indices of its meshes (hits report these).
    pub meshes: Vec<u32>,
    /// The same meshes in object space, in the same order.
    pub object: Vec<TriangleMesh>,
}

/// A [`Mover`] as queried: its object-space hierarchy, whose mesh `i` is the scene's `ids[i]`.
struct MoverAccel {
    transform: MovingTransform,
    inner: Accel,
    ids: Vec<u32>,
}

/// The `TriRef::mesh` of a BVH slot holding a [`Mover`] (`tri` is the mover's index).
const MOVER: u32 = u32::MAX;

/// A hit filter for a mover's object-space hierarchy: its mesh indices mapped to the scene's.
struct MappedFilter {
    filter: Arc<dyn HitFilter>,
    ids: Vec<u32>,
}

impl HitFilter for MappedFilter {
    fn accept(&self, hit: &Hit, shadow: bool) -> bool {
        let mesh = self.ids.get(hit.mesh as usize).copied().unwrap_or(hit.mesh);
        self.filter.accept(&Hit { mesh, ..*hit }, shadow)
    }
}

/// Which library answers the ray queries (pbrt's `Accelerator` directive, `--accel`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelKind {
    /// obvhs's compressed wide BVH with the watertight triangle test (the default).
    #[default]
    Bvh,
    /// Embree 3 (cargo feature `embree`); without the feature, the same as `Bvh`.
    Embree,
}

impl AccelKind {
    /// Whether this build of penumbra has the Embree backend.
    pub const EMBREE_AVAILABLE: bool = cfg!(feature = "embree");
}

pub struct Accel {
    bvh: CwBvh,
    /// Embree's scene, which reads `tris` in place: declared before `tris` so it is dropped
    /// first.
    #[cfg(feature = "embree")]
    embree: Option<embree::EmbreeScene>,
    /// Triangles in BVH primitive order, scaled by `scale`.
    tris: Vec<[Vec3A; 3]>,
    refs: Vec<TriRef>,
    scale: f32,
    bounds: Bounds3,
    /// Per mesh: whether its hits go through `filter` (it has an `alpha` or `shadowalpha`).
    cutout: Vec<bool>,
    /// The alpha test of the `cutout` meshes (none: every hit counts).
    filter: Option<std::sync::Arc<dyn HitFilter>>,
    /// Per mesh, its curve (empty when no mesh has one): the BVH slots of a curve mesh hold its
    /// pieces (`tris` holds each piece's box as a degenerate triangle; `refs.tri` is the piece).
    curves: Vec<Option<Arc<Curves>>>,
    /// The moving groups (their slots' `TriRef` is `{ mesh: MOVER, tri: index here }`).
    movers: Vec<MoverAccel>,
    pub build_seconds: f64,
    /// Triangles left out as repeats of an earlier one of their mesh (see `build_with`), and
    /// the first mesh with one.
    pub duplicates: usize,
    pub duplicates_in: Option<usize>,
}

/// `v`'s corners as bits, starting from the least (so the three turns of a triangle agree).
fn turn_key(v: [Vec3; 3]) -> [u32; 9] {
    let b = v.map(|p| p.to_array().map(f32::to_bits));
    let first = (0..3).min_by_key(|&i| b[i]).unwrap_or(0);
    let mut k = [0u32; 9];
    for j in 0..3 {
        k[3 * j..3 * j + 3].copy_from_slice(&b[(first + j) % 3]);
    }
    k
}

/// A query: the triangle test's constants and the world-space ray (curves are intersected
/// against it, as pbrt-v3 does, in the curve's object space).
struct Query {
    pre: RayPrecomp,
    o: Vec3,
    d: Vec3,
    /// World ray parameter × `to_bvh` + [`BACKUP`] = BVH ray parameter.
    to_bvh: f32,
    time: f32,
}

/// Per-ray constants of the watertight test.
struct RayPrecomp {
    o: Vec3A,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl RayPrecomp {
    fn new(o: Vec3A, d: Vec3A) -> Self {
        let ad = d.abs();
        let kz = if ad.x > ad.y {
            if ad.x > ad.z {
                0
            } else {
                2
            }
        } else if ad.y > ad.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let dz = d[kz];
        RayPrecomp { o, kx, ky, kz, sx: -d[kx] / dz, sy: -d[ky] / dz, sz: 1.0 / dz }
    }

    /// `Some((t, b))` for a hit with `t_min < t < t_max`.
    #[inline(always)]
    fn intersect(&self, tri: &[Vec3A; 3], t_min: f32, t_max: f32) -> Option<(f32, [f32; 3])> {
        let p0 = tri[0] - self.o;
        let p1 = tri[1] - self.o;
        let p2 = tri[2] - self.o;
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let z = [p0[kz], p1[kz], p2[kz]];
        let x = [p0[kx] + self.sx * z[0], p1[kx] + self.sx * z[1], p2[kx] + self.sx * z[2]];
        let y = [p0[ky] + self.sy * z[0], p1[ky] + self.sy * z[1], p2[ky] + self.sy * z[2]];
        let mut e0 = x[1] * y[2] - y[1] * x[2];
        let mut e1 = x[2] * y[0] - y[2] * x[0];
        let mut e2 = x[0] * y[1] - y[0] * x[1];
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            // Exactly on an edge in single precision: decide in double so shared edges are watertight.
            let (x, y) = (x.map(|v| v as f64), y.map(|v| v as f64));
            e0 = (x[1] * y[2] - y[1] * x[2]) as f32;
            e1 = (x[2] * y[0] - y[2] * x[0]) as f32;
            e2 = (x[0] * y[1] - y[0] * x[1]) as f32;
        }
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        let zs = [z[0] * self.sz, z[1] * self.sz, z[2] * self.sz];
        let t_scaled = e0 * zs[0] + e1 * zs[1] + e2 * zs[2];
        if det < 0.0 && (t_scaled >= t_min * det || t_scaled <= t_max * det) {
            return None;
        }
        if det > 0.0 && (t_scaled <= t_min * det || t_scaled >= t_max * det) {
            return None;
        }
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        // pbrt-v3's conservative bound: reject t that is not certainly past t_min.
        let max_z = zs[0].abs().max(zs[1].abs()).max(zs[2].abs());
        let max_x = x[0].abs().max(x[1].abs()).max(x[2].abs());
        let max_y = y[0].abs().max(y[1].abs()).max(y[2].abs());
        let delta_z = gamma(3) * max_z;
        let delta_x = gamma(5) * (max_x + max_z);
        let delta_y = gamma(5) * (max_y + max_z);
        let delta_e = 2.0 * (gamma(2) * max_x * max_y + delta_y * max_x + delta_x * max_y);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = 3.0 * (gamma(3) * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv_det.abs();
        if t <= t_min + delta_t {
            return None;
        }
        Some((t, [e0 * inv_det, e1 * inv_det, e2 * inv_det]))
    }
}

impl Accel {
    /// Builds over every triangle of `meshes`, skipping degenerate or non-finite triangles.
    pub fn build(meshes: &[TriangleMesh]) -> Accel {
        Self::build_with(meshes, AccelKind::Bvh)
    }

    /// [`build`](Self::build) with the backend `kind`; Embree falls back to the BVH when this
    /// build lacks it or Embree cannot make a scene ([`kind`](Self::kind) tells which was built).
    /// Meshes with an `alpha` or `shadowalpha` cut-out are asked about through the filter
    /// given to [`set_filter`](Self::set_filter) (until then, every hit counts).
    pub fn build_with(meshes: &[TriangleMesh], kind: AccelKind) -> Accel {
        Self::build_moving(meshes, kind, &[])
    }

    /// [`build_with`](Self::build_with) where the meshes of `movers` move (their entries in
    /// `meshes` are not used): Embree is not given them (the caller asks for the BVH).
    pub fn build_moving(meshes: &[TriangleMesh], kind: AccelKind, movers: &[Mover]) -> Accel {
        let start = std::time::Instant::now();
        let mut moving = vec![false; meshes.len()];
        for &i in movers.iter().flat_map(|m| &m.meshes) {
            if let Some(b) = moving.get_mut(i as usize) {
                *b = true;
            }
        }
        let mut bounds = Bounds3::EMPTY;
        let mut mover_boxes = Vec::new();
        for m in movers {
            let inner = Accel::build(&m.object);
            let b = inner.bounds();
            let (lo, hi) = if b.is_empty() {
                (Vec3::NAN, Vec3::NAN)
            } else {
                let (lo, hi) = m.transform.motion_bounds(b.min.as_dvec3(), b.max.as_dvec3());
                (lo.as_vec3(), hi.as_vec3())
            };
            if lo.is_finite() && hi.is_finite() {
                bounds.extend(lo);
                bounds.extend(hi);
            }
            mover_boxes.push((lo, hi, MoverAccel { transform: m.transform.clone(), inner, ids: m.meshes.clone() }));
        }
        for m in meshes.iter().zip(&moving).filter(|(_, &mv)| !mv).map(|(m, _)| m) {
            for p in &m.positions {
                if p.is_finite() {
                    bounds.extend(*p);
                }
            }
            if let Some(c) = &m.curves {
                let b = c.world_bounds();
                if b.min.is_finite() && b.max.is_finite() {
                    bounds.extend(b.min);
                    bounds.extend(b.max);
                }
            }
        }
        let scale = power_of_two_scale(&bounds);
        let has_curves = meshes.iter().any(|m| m.curves.is_some());
        let curves: Vec<Option<Arc<Curves>>> =
            if has_curves { meshes.iter().map(|m| m.curves.clone()).collect() } else { Vec::new() };
        let cutout: Vec<bool> = meshes.iter().map(|m| m.alpha.is_some() || m.shadow_alpha.is_some()).collect();
        let mut tris = Vec::new();
        let mut refs = Vec::new();
        let (mut duplicates, mut duplicates_in) = (0, None);
        let mut seen: HashSet<[u32; 9], WordHash> = HashSet::default();
        for (mi, m) in meshes.iter().enumerate() {
            seen.clear();
            if moving[mi] {
                continue;
            }
            for (ti, idx) in m.indices.iter().enumerate() {
                let v = idx.map(|i| m.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
                if v.iter().any(|p| !p.is_finite()) || (v[1] - v[0]).cross(v[2] - v[0]) == Vec3::ZERO {
                    continue;
                }
                // A triangle that repeats one before it in its mesh (the same corners in the same
                // turn) answers every ray as that one does. Kept, thousands of copies of one box
                // made obvhs's PLOC merge one pair per pass: 46 080 copies of one face took 58 s
                // to build (the fuzz run's 877 KB input). Cut-out meshes keep theirs (a copy's
                // alpha test is its own).
                if !cutout[mi] && !seen.insert(turn_key(v)) {
                    duplicates += 1;
                    duplicates_in.get_or_insert(mi);
                    continue;
                }
                tris.push(Tri(v.map(|p| Vec3A::from(p * scale))));
                refs.push(TriRef { mesh: mi as u32, tri: ti as u32 });
            }
            if let Some(c) = &m.curves {
                for piece in 0..c.prim_count() {
                    let b = c.world_bound(piece);
                    if !(b.min.is_finite() && b.max.is_finite()) {
                        continue;
                    }
                    let (lo, hi) = (Vec3A::from(b.min * scale), Vec3A::from(b.max * scale));
                    tris.push(Tri([lo, hi, hi]));
                    refs.push(TriRef { mesh: mi as u32, tri: piece as u32 });
                }
            }
        }
        let mut mover_accels = Vec::with_capacity(mover_boxes.len());
        for (i, (lo, hi, ma)) in mover_boxes.into_iter().enumerate() {
            if lo.is_finite() && hi.is_finite() {
                tris.push(Tri([lo, hi, hi].map(|p| Vec3A::from(p * scale))));
                refs.push(TriRef { mesh: MOVER, tri: i as u32 });
            }
            mover_accels.push(ma);
        }
        // Embree gets static triangles only: a scene with curves or moving shapes is the
        // BVH's (the caller warns).
        #[cfg(feature = "embree")]
        if kind == AccelKind::Embree && !has_curves && mover_accels.is_empty() {
            // Opaque triangles first, then the cut-out ones: Embree gets them as two geometries,
            // the second with the alpha test as its filter.
            let mut order: Vec<usize> = (0..tris.len()).collect();
            order.sort_by_key(|&i| cutout[refs[i].mesh as usize]);
            let opaque = order.iter().filter(|&&i| !cutout[refs[i].mesh as usize]).count();
            let tris_ordered: Vec<[Vec3A; 3]> = order.iter().map(|&i| tris[i].0).collect();
            let refs_ordered: Vec<TriRef> = order.iter().map(|&i| refs[i]).collect();
            // SAFETY: `tris_ordered` moves into the returned `Accel` (its heap buffer stays
            // where it is) and is never changed; `embree` is declared before it, so dropped first.
            if let Some(scene) = unsafe { embree::EmbreeScene::build(&tris_ordered, opaque) } {
                return Accel {
                    bvh: CwBvh::default(),
                    embree: Some(scene),
                    tris: tris_ordered,
                    refs: refs_ordered,
                    scale,
                    bounds,
                    cutout,
                    filter: None,
                    curves,
                    movers: mover_accels,
                    build_seconds: start.elapsed().as_secs_f64(),
                    duplicates,
                    duplicates_in,
                };
            }
        }
        let _ = kind;
        let bvh = if tris.is_empty() {
            CwBvh::default()
        } else {
            build_cwbvh(&tris, BvhBuildParams::medium_build(), &mut Duration::default())
        };
        let order = &bvh.primitive_indices;
        let tris_ordered = order.iter().map(|&i| tris[i as usize].0).collect();
        let refs_ordered = order.iter().map(|&i| refs[i as usize]).collect();
        Accel {
            bvh,
            #[cfg(feature = "embree")]
            embree: None,
            tris: tris_ordered,
            refs: refs_ordered,
            scale,
            bounds,
            cutout,
            filter: None,
            curves,
            movers: mover_accels,
            build_seconds: start.elapsed().as_secs_f64(),
            duplicates,
            duplicates_in,
        }
    }

    /// [`hit_slot`](Self::hit_slot) with the mesh and triangle hit: for a mover's slot, its
    /// object-space hierarchy's answer to the ray at its time (with `shadow`, whether anything
    /// of it blocks the ray, at a `t` just short of `t_max`).
    #[inline(always)]
    fn hit_slot_ref(&self, slot: usize, q: &Query, t_max: f32, shadow: bool) -> Option<(f32, [f32; 3], TriRef)> {
        if !self.movers.is_empty() {
            let r = self.refs[slot];
            if r.mesh == MOVER {
                return self.hit_mover(r.tri as usize, q, t_max, shadow);
            }
        }
        let (t, b) = self.hit_slot(slot, q, t_max, shadow)?;
        Some((t, b, self.refs[slot]))
    }

    /// pbrt-v3's `TransformedPrimitive::Intersect`/`IntersectP`: the world ray taken into the
    /// mover's space by the inverse of its transform at the ray's time (the ray parameter
    /// is the same in both spaces).
    #[cold]
    fn hit_mover(&self, i: usize, q: &Query, t_max: f32, shadow: bool) -> Option<(f32, [f32; 3], TriRef)> {
        let m = self.movers.get(i)?;
        let object_from_world = m.transform.at(q.time).inverse();
        let o = object_from_world.transform_point3(q.o.as_dvec3()).as_vec3();
        let d = object_from_world.transform_vector3(q.d.as_dvec3()).as_vec3();
        let ray = Ray { o, d, t_max: (t_max - BACKUP) / q.to_bvh, time: q.time };
        if shadow {
            return m.inner.occluded(&ray).then(|| (next_float_down(t_max), [0.0; 3], TriRef { mesh: MOVER, tri: 0 }));
        }
        let h = m.inner.intersect(&ray)?;
        let t = h.t * q.to_bvh + BACKUP;
        let mesh = *m.ids.get(h.mesh as usize)?;
        (t < t_max).then_some((t, h.b, TriRef { mesh, tri: h.tri }))
    }

    /// The number of moving groups ([`Mover`]) in the hierarchy, each one slot of it.
    pub fn mover_count(&self) -> usize {
        if self.movers.is_empty() {
            return 0;
        }
        self.refs.iter().filter(|r| r.mesh == MOVER).count()
    }

    /// Whether candidate slot `slot` is hit before `t_max` (BVH parameter): the BVH parameter
    /// of the hit and its barycentrics (a curve's `[u, v, width]`), after the alpha test.
    #[inline(always)]
    fn hit_slot(&self, slot: usize, q: &Query, t_max: f32, shadow: bool) -> Option<(f32, [f32; 3])> {
        if !self.curves.is_empty() {
            let r = self.refs[slot];
            if let Some(Some(c)) = self.curves.get(r.mesh as usize) {
                let h = c.intersect(r.tri as usize, q.o, q.d, (t_max - BACKUP) / q.to_bvh, shadow)?;
                let t = h.t * q.to_bvh + BACKUP;
                return (t < t_max).then_some((t, [h.u, h.v, h.width]));
            }
        }
        let (t, b) = q.pre.intersect(&self.tris[slot], BACKUP, t_max)?;
        self.accepts(slot, (t - BACKUP) / q.to_bvh, b, shadow).then_some((t, b))
    }

    /// The number of curve pieces in the hierarchy (0 without curves).
    pub fn curve_piece_count(&self) -> usize {
        if self.curves.is_empty() {
            return 0;
        }
        self.refs.iter().filter(|r| matches!(self.curves.get(r.mesh as usize), Some(Some(_)))).count()
    }

    /// The alpha test of the cut-out meshes (see [`HitFilter`]).
    pub fn set_filter(&mut self, filter: std::sync::Arc<dyn HitFilter>) {
        for m in &mut self.movers {
            let mapped = MappedFilter { filter: filter.clone(), ids: m.ids.clone() };
            m.inner.cutout = m.ids.iter().map(|&i| self.cutout.get(i as usize).copied().unwrap_or(false)).collect();
            m.inner.set_filter(Arc::new(mapped));
        }
        self.filter = Some(filter);
    }

    /// Whether a candidate hit in BVH slot `slot` (barycentrics `b`, world `t`) counts.
    #[inline]
    fn accepts(&self, slot: usize, t: f32, b: [f32; 3], shadow: bool) -> bool {
        let Some(f) = &self.filter else { return true };
        let r = self.refs[slot];
        if !self.cutout.get(r.mesh as usize).copied().unwrap_or(false) {
            return true;
        }
        f.accept(&Hit { t, mesh: r.mesh, tri: r.tri, b }, shadow)
    }

    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }
    /// The backend that answers this hierarchy's queries.
    pub fn kind(&self) -> AccelKind {
        #[cfg(feature = "embree")]
        if self.embree.is_some() {
            return AccelKind::Embree;
        }
        AccelKind::Bvh
    }

    /// Embree's answer to a ray query, when Embree is the backend: the ray in BVH space with
    /// its direction scaled as its origin, so `t` stays the world ray's parameter.
    #[cfg(feature = "embree")]
    #[inline]
    fn embree_ray(&self, ray: &Ray) -> Option<(&embree::EmbreeScene, Vec3A, Vec3A, f32)> {
        let e = self.embree.as_ref()?;
        Some((e, Vec3A::from(ray.o * self.scale), Vec3A::from(ray.d * self.scale), ray.t_max))
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Whether a query can hit anything: triangles to hit, a finite origin and a finite,
    /// non-zero direction, a `t_max` that is not NaN.
    #[inline]
    fn valid_query(&self, ray: &Ray) -> bool {
        !(self.tris.is_empty() || !ray.o.is_finite() || !ray.d.is_finite() || ray.d == Vec3::ZERO || ray.t_max.is_nan())
    }

    fn prepare(&self, ray: &Ray) -> Option<(obvhs::ray::Ray, Query)> {
        if !self.valid_query(ray) {
            return None;
        }
        // Normalise the direction in BVH space so BACKUP is a distance.
        let (dn, len) = unit_direction(ray.d);
        let o = Vec3A::from(ray.o * self.scale) - dn * BACKUP;
        // A parameter along the world ray maps to (t * len * scale) + BACKUP along the BVH ray.
        let t_max = if ray.t_max.is_finite() { ray.t_max * len * self.scale + BACKUP } else { f32::INFINITY };
        let q = Query { pre: RayPrecomp::new(o, dn), o: ray.o, d: ray.d, to_bvh: len * self.scale, time: ray.time };
        Some((obvhs::ray::Ray::new(o, dn, 0.0, t_max), q))
    }

    /// The closest hit along `ray` with `0 < t < ray.t_max`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        #[cfg(feature = "embree")]
        if let Some((e, o, d, t_max)) = self.embree_ray(ray) {
            if !self.valid_query(ray) {
                return None;
            }
            let accept = |slot: u32, t: f32, b: [f32; 3]| self.accepts(slot as usize, t, b, false);
            let accept: Option<embree::Accept> = if self.filter.is_some() { Some(&accept) } else { None };
            let (slot, t, b) = e.intersect(o, d, t_max, accept)?;
            let r = self.refs[slot as usize];
            return Some(Hit { t, mesh: r.mesh, tri: r.tri, b });
        }
        let (bray, q) = self.prepare(ray)?;
        if !traversable(bray.direction) {
            let (r, t, b) = self.traverse_exact(&bray, &q, false)?;
            return Some(Hit { t: (t - BACKUP) / q.to_bvh, mesh: r.mesh, tri: r.tri, b });
        }
        let mut hit = RayHit::none();
        let mut best_b = [0.0f32; 3];
        let mut best_r = TriRef { mesh: 0, tri: 0 };
        let found = self.bvh.ray_traverse(bray, &mut hit, |r, id| match self.hit_slot_ref(id, &q, r.tmax, false) {
            Some((t, b, tr)) => {
                best_b = b;
                best_r = tr;
                t
            }
            None => f32::INFINITY,
        });
        if !found {
            return None;
        }
        Some(Hit { t: (hit.t - BACKUP) / q.to_bvh, mesh: best_r.mesh, tri: best_r.tri, b: best_b })
    }

    /// The triangles (BVH slots) that rays of a bundle sharing one origin — a pixel's camera
    /// rays — can hit: one traversal of the hierarchy against the bundle's bounding pyramid
    /// (apex at the origin, four planes bounding the directions, with a margin), instead of one
    /// traversal per ray. `None` when the rays do not share an origin, spread over more than
    /// ~75° from their mean, or more than `limit` triangles remain (the caller then traverses
    /// per ray). Use with [`intersect_among`](Self::intersect_among).
    pub fn bundle_candidates<R: AsRef<Ray>>(&self, rays: &[R], limit: usize) -> Option<Vec<u32>> {
        let first = rays.first()?.as_ref();
        if self.tris.is_empty() || !first.o.is_finite() || self.bvh.nodes.is_empty() {
            return None;
        }
        // The directions as `prepare` gives them to the triangle test, bounded by their slopes
        // against the first one's frame.
        let dir = |r: &Ray| unit_direction(r.d).0;
        let a = dir(first);
        let (u, v) = a.any_orthonormal_pair();
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for r in rays.iter().map(AsRef::as_ref) {
            if r.o != first.o || !r.d.is_finite() || r.d == Vec3::ZERO {
                return None;
            }
            let d = dir(r);
            let da = d.dot(a);
            if !(da >= 0.25) {
                return None;
            }
            let q = Vec2::new(d.dot(u), d.dot(v)) / da;
            lo = lo.min(q);
            hi = hi.max(q);
        }
        // Slopes widened by far more than their rounding; the apex's rounding (the query's
        // backed-up origin is a few ulps off it) and the boxes' (tested relative to the apex)
        // are covered by an absolute slack.
        let m = 1e-5 + 1e-3 * (hi - lo).max_element();
        let (lo, hi) = (lo - m, hi + m);
        let planes = [u - lo.x * a, hi.x * a - u, v - lo.y * a, hi.y * a - v, a].map(|n| n.normalize());
        let apex = Vec3A::from(first.o * self.scale);
        let slack = 1e-5 * (1.0 + apex.abs().max_element()) + 2.0 * BACKUP;
        // Each plane's farthest box corner along its normal, chosen by the normal's signs.
        let positive = planes.map(|n| n.cmpge(Vec3A::ZERO));
        let outside = |b: &Aabb| {
            let (bmin, bmax) = (b.min - apex, b.max - apex);
            planes.iter().zip(&positive).any(|(n, pos)| n.dot(Vec3A::select(*pos, bmax, bmin)) < -slack)
        };
        let mut out = Vec::new();
        let mut stack = vec![0u32];
        while let Some(ni) = stack.pop() {
            let node = self.bvh.nodes.get(ni as usize)?;
            for c in 0..8 {
                if node.is_child_empty(c) || outside(&node.child_aabb(c)) {
                    continue;
                }
                if node.is_leaf(c) {
                    let (start, count) = node.child_primitives(c);
                    out.extend(start..start + count);
                    if out.len() > limit {
                        return None;
                    }
                } else {
                    stack.push(node.child_node_index(c));
                }
            }
        }
        Some(out)
    }

    /// [`intersect`](Self::intersect) testing only the triangles `slots` (from
    /// [`bundle_candidates`](Self::bundle_candidates) for a bundle holding `ray`): the same hit.
    pub fn intersect_among(&self, ray: &Ray, slots: &[u32]) -> Option<Hit> {
        let (bray, q) = self.prepare(ray)?;
        let mut t_max = bray.tmax;
        let mut best = None;
        for &slot in slots {
            if slot as usize >= self.tris.len() {
                continue;
            }
            if let Some((t, b, r)) = self.hit_slot_ref(slot as usize, &q, t_max, false) {
                t_max = t;
                best = Some((r, b));
            }
        }
        let (r, b) = best?;
        Some(Hit { t: (t_max - BACKUP) / q.to_bvh, mesh: r.mesh, tri: r.tri, b })
    }

    /// The closest hit (or with `any`, the first found) of a BVH-space ray by a traversal of
    /// the hierarchy with an exact slab test: for the rays [`traversable`] refuses, whose
    /// direction has a component within f32's epsilon of 0. obvhs inverts such a component as
    /// ±1/ε, which bends the ray by ~1e-7 rad: a ray lying in a plane where geometry's bounds
    /// end (from a sphere's centre along its equator, along an axis-aligned box's face) left
    /// the box of the triangle it was to hit and missed. Here a zero component's slab is the
    /// whole line when the origin lies within the box's range (inclusive) and empty otherwise;
    /// the far slab distance is widened by pbrt-v3's 1 + 2γ(3). Returns the triangle hit, the
    /// BVH-space `t` and the barycentrics.
    fn traverse_exact(&self, bray: &obvhs::ray::Ray, q: &Query, any: bool) -> Option<(TriRef, f32, [f32; 3])> {
        let (o, d) = (bray.origin, bray.direction);
        let widen = 1.0 + 2.0 * gamma(3);
        let mut t_max = bray.tmax;
        let mut best = None;
        let mut stack = vec![0u32];
        while let Some(ni) = stack.pop() {
            let Some(node) = self.bvh.nodes.get(ni as usize) else { continue };
            for c in 0..8 {
                if node.is_child_empty(c) {
                    continue;
                }
                let b = node.child_aabb(c);
                let (mut t0, mut t1) = (0.0f32, t_max);
                for k in 0..3 {
                    if d[k] == 0.0 {
                        if o[k] < b.min[k] || o[k] > b.max[k] {
                            t0 = f32::INFINITY;
                        }
                        continue;
                    }
                    let (a, z) = ((b.min[k] - o[k]) / d[k], (b.max[k] - o[k]) / d[k]);
                    t0 = t0.max(a.min(z));
                    t1 = t1.min(a.max(z) * widen);
                }
                if !(t0 <= t1) {
                    continue;
                }
                if node.is_leaf(c) {
                    let (start, count) = node.child_primitives(c);
                    for slot in start..start + count {
                        if slot as usize >= self.tris.len() {
                            continue;
                        }
                        if let Some((t, bary, r)) = self.hit_slot_ref(slot as usize, q, t_max, any) {
                            t_max = t;
                            best = Some((r, t, bary));
                            if any {
                                return best;
                            }
                        }
                    }
                } else {
                    stack.push(node.child_node_index(c));
                }
            }
        }
        best
    }

    /// Whether anything blocks `ray` for `0 < t < ray.t_max` (early exit).
    pub fn occluded(&self, ray: &Ray) -> bool {
        #[cfg(feature = "embree")]
        if let Some((e, o, d, t_max)) = self.embree_ray(ray) {
            let accept = |slot: u32, t: f32, b: [f32; 3]| self.accepts(slot as usize, t, b, true);
            let accept: Option<embree::Accept> = if self.filter.is_some() { Some(&accept) } else { None };
            return self.valid_query(ray) && e.occluded(o, d, t_max, accept);
        }
        let Some((bray, q)) = self.prepare(ray) else { return false };
        if !traversable(bray.direction) {
            return self.traverse_exact(&bray, &q, true).is_some();
        }
        !self
            .bvh
            .ray_traverse_miss(bray, |r, id| self.hit_slot_ref(id, &q, r.tmax, true).map_or(f32::INFINITY, |h| h.0))
    }
}

/// `2^k` with `k` chosen so the scene's extent (and its distance from the origin) times it lies
/// in `[0.5, 1)`; 1 for an empty or non-finite box.
fn power_of_two_scale(bounds: &Bounds3) -> f32 {
    let extent =
        bounds.diagonal().abs().max_element().max(bounds.min.abs().max_element()).max(bounds.max.abs().max_element());
    if extent > 0.0 && extent.is_finite() {
        2f32.powi(-(extent.log2().floor() as i32 + 1))
    } else {
        1.0
    }
}

/// A query's unit direction (as the triangle test and the traversal see it) and the length of
/// `d`. `+ 0.0` turns -0.0 into +0.0: obvhs's octant logic misroutes signed zeros.
fn unit_direction(d: Vec3) -> (Vec3A, f32) {
    let d = Vec3A::from(d);
    let len = d.length();
    (d / len + Vec3A::ZERO, len)
}

/// Whether obvhs's traversal can take a BVH-space direction: it inverts a component within
/// f32's epsilon of 0 as ±1/ε ([`obvhs::ray::safe_inverse`]), which is only safe when no
/// component is that small.
fn traversable(d: Vec3A) -> bool {
    d.abs().min_element() > f32::EPSILON
}

/// pbrt-v3's default triangle uv when a mesh has none.
pub const DEFAULT_UV: [Vec2; 3] = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0)];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::AlphaSpec;

    /// Every backend this build has: each test below runs on each.
    fn kinds() -> Vec<AccelKind> {
        if AccelKind::EMBREE_AVAILABLE {
            vec![AccelKind::Bvh, AccelKind::Embree]
        } else {
            vec![AccelKind::Bvh]
        }
    }

    fn quad(y: f32, scale: f32) -> TriangleMesh {
        let s = scale;
        TriangleMesh {
            positions: vec![
                Vec3::new(-s, y * s, -s),
                Vec3::new(s, y * s, -s),
                Vec3::new(s, y * s, s),
                Vec3::new(-s, y * s, s),
            ],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn closest_hit_and_occlusion_at_every_scale() {
        for (scale, kind) in [1e-4f32, 1.0, 1e4].into_iter().flat_map(|s| kinds().into_iter().map(move |k| (s, k))) {
            let accel = Accel::build_with(&[quad(0.0, scale), quad(1.0, scale)], kind);
            assert_eq!(accel.kind(), kind);
            let ray = Ray::new(Vec3::new(0.1, -1.0, 0.2) * scale, Vec3::Y, f32::INFINITY);
            let h = accel.intersect(&ray).expect("hit");
            assert_eq!(h.mesh, 0);
            assert!((h.t - scale).abs() <= 1e-5 * scale, "t {} at scale {}", h.t, scale);
            assert!((h.b.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            // A ray starting just above the lower quad hits the upper one, even very close.
            let up = Ray::new(Vec3::new(0.1, 1e-6, 0.2) * scale, Vec3::Y, f32::INFINITY);
            assert_eq!(accel.intersect(&up).unwrap().mesh, 1);
            // Contact: an occluder 1e-5 (relative) above the origin is found despite obvhs's near clamp.
            let near = Ray::new(Vec3::new(0.1, 1.0 - 1e-5, 0.2) * scale, Vec3::Y, f32::INFINITY);
            let h = accel.intersect(&near).expect("near hit");
            assert!((h.t - 1e-5 * scale).abs() < 1e-6 * scale);
            assert!(accel.occluded(&Ray::new(Vec3::new(0.1, 0.5, 0.2) * scale, Vec3::Y, 1.0 * scale)));
            assert!(!accel.occluded(&Ray::new(Vec3::new(0.1, 0.5, 0.2) * scale, Vec3::Y, 0.4 * scale)));
            assert!(!accel.occluded(&Ray::new(Vec3::new(3.0, 0.5, 0.2) * scale, Vec3::Y, f32::INFINITY)));
        }
    }

    /// A UV sphere of radius 1 about the origin, its equator ring in the plane z = 0.
    fn uv_sphere(rings: usize, segments: usize) -> TriangleMesh {
        let mut positions = vec![Vec3::Z, -Vec3::Z];
        for i in 1..rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                let z = if 2 * i == rings { 0.0 } else { theta.cos() };
                positions.push(Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), z));
            }
        }
        let v = |i: usize, j: usize| (2 + (i - 1) * segments + j % segments) as u32;
        let mut indices = Vec::new();
        for j in 0..segments {
            indices.push([0, v(1, j), v(1, j + 1)]);
            indices.push([1, v(rings - 1, j + 1), v(rings - 1, j)]);
            for i in 1..rings - 1 {
                indices.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                indices.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        TriangleMesh { positions, indices, ..Default::default() }
    }

    /// Rays lying in a coordinate plane that is also a face plane of the hierarchy's boxes (the
    /// equator's vertices at z = 0, rays from z = 0 with d.z = 0): a slab test computing
    /// (bound − o) / d as 0 · ∞ gets NaN and loses the box. Every such ray from the centre
    /// must hit the sphere at distance ~1, and so must one from outside along an axis.
    #[test]
    fn rays_in_a_box_face_plane_still_hit() {
        for kind in kinds() {
            rays_in_a_box_face_plane_still_hit_with(kind);
        }
    }

    fn rays_in_a_box_face_plane_still_hit_with(kind: AccelKind) {
        let accel = Accel::build_with(&[uv_sphere(16, 32)], kind);
        let mut misses = 0;
        for k in 0..360 {
            let a = (k as f32).to_radians();
            for d in
                [Vec3::new(a.cos(), a.sin(), 0.0), Vec3::new(a.cos(), 0.0, a.sin()), Vec3::new(0.0, a.cos(), a.sin())]
            {
                let d = Vec3::new(d.x + 0.0, d.y + 0.0, d.z + 0.0);
                match accel.intersect(&Ray::new(Vec3::ZERO, d, f32::INFINITY)) {
                    Some(h) if (h.t - 1.0).abs() < 0.03 => {}
                    _ => misses += 1,
                }
            }
        }
        assert_eq!(misses, 0, "rays in coordinate planes that missed");
        for o in [Vec3::new(3.0, 0.0, 0.0), Vec3::new(3.0, 0.5, 0.0), Vec3::new(0.0, -3.0, 0.0)] {
            let h = accel.intersect(&Ray::new(o, -o.normalize(), f32::INFINITY));
            assert!(h.is_some(), "the ray from {o} towards the centre missed");
        }
    }

    #[test]
    fn shared_edges_are_watertight() {
        // Rays through the diagonal shared by the two triangles must hit exactly one of them, never miss.
        for kind in kinds() {
            let accel = Accel::build_with(&[quad(0.0, 1.0)], kind);
            let mut misses = 0;
            for i in 0..1000 {
                let x = -0.9 + 1.8 * (i as f32 / 999.0);
                let ray = Ray::new(Vec3::new(x, 1.0, x), -Vec3::Y, f32::INFINITY);
                if accel.intersect(&ray).is_none() {
                    misses += 1;
                }
            }
            assert_eq!(misses, 0, "misses ({kind:?})");
        }
    }

    #[test]
    fn bundle_candidates_give_the_same_hits() {
        // A soup of random triangles (some large, some tiny) and bundles of rays from one
        // origin through small random windows: every ray's hit among the bundle's candidates
        // is its hit by traversal, bit for bit.
        let mut rng = crate::rng::Rng::new(11);
        let mut u = || rng.uniform_f32();
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for k in 0..4000u32 {
            let c = Vec3::new(u(), u(), u()) * 20.0 - 10.0;
            let size = if k % 100 == 0 { 8.0 } else { 0.3 };
            for _ in 0..3 {
                positions.push(c + (Vec3::new(u(), u(), u()) - 0.5) * size);
            }
            indices.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let accel = Accel::build(&[TriangleMesh { positions, indices, ..Default::default() }]);
        let (mut bundles, mut hits) = (0, 0);
        for _ in 0..300 {
            let o = Vec3::new(u(), u(), u()) * 30.0 - 15.0;
            // Aimed into the soup half of the time.
            let target =
                if u() < 0.5 { Vec3::new(u(), u(), u()) * 16.0 - 8.0 } else { o + Vec3::new(u(), u(), u()) - 0.5 };
            let axis = (target - o).normalize();
            let (bu, bv) = axis.any_orthonormal_pair();
            let width = 0.002 + 0.1 * u();
            let rays: Vec<Ray> = (0..16)
                .map(|_| {
                    let d = axis + (bu * (u() - 0.5) + bv * (u() - 0.5)) * width;
                    Ray::new(o, d * (0.5 + u()), f32::INFINITY)
                })
                .collect();
            let Some(c) = accel.bundle_candidates(&rays, usize::MAX) else { continue };
            bundles += 1;
            assert!(c.len() < accel.triangle_count(), "the bundle should cull something");
            for r in &rays {
                let (a, b) = (accel.intersect(r), accel.intersect_among(r, &c));
                assert_eq!(a, b, "ray {r:?}");
                hits += a.is_some() as usize;
            }
        }
        assert!(bundles == 300 && hits > 1000, "{bundles} bundles, {hits} hits");
        // Rays from different origins, or spread too wide, are not bundled; a limit is kept.
        let o = Vec3::ZERO;
        let apart = [Ray::new(o, Vec3::X, f32::INFINITY), Ray::new(Vec3::Y, Vec3::X, f32::INFINITY)];
        assert!(accel.bundle_candidates(&apart, usize::MAX).is_none());
        let wide = [Ray::new(o, Vec3::X, f32::INFINITY), Ray::new(o, Vec3::Y, f32::INFINITY)];
        assert!(accel.bundle_candidates(&wide, usize::MAX).is_none());
        let all = [
            Ray::new(Vec3::new(-40.0, 0.0, 0.0), Vec3::X, f32::INFINITY),
            Ray::new(Vec3::new(-40.0, 0.0, 0.0), Vec3::new(1.0, 0.2, 0.2), f32::INFINITY),
        ];
        assert!(accel.bundle_candidates(&all, 3).is_none());
        assert!(accel.bundle_candidates(&all, usize::MAX).is_some_and(|c| c.len() > 3));
    }

    /// Embree answers as the BVH does: on a soup of random triangles, with rays in random and
    /// in axis-parallel directions, the same triangle (rays whose two nearest hits lie within
    /// 1e-5 of each other aside) at the same distance, and the same occlusion.
    #[test]
    fn embree_answers_as_the_bvh() {
        if !AccelKind::EMBREE_AVAILABLE {
            return;
        }
        let mut rng = crate::rng::Rng::new(5);
        let mut u = || rng.uniform_f32();
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        for k in 0..3000u32 {
            let c = Vec3::new(u(), u(), u()) * 20.0 - 10.0;
            for _ in 0..3 {
                positions.push(c + (Vec3::new(u(), u(), u()) - 0.5) * 1.5);
            }
            indices.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let mesh = TriangleMesh { positions, indices, ..Default::default() };
        let bvh = Accel::build_with(std::slice::from_ref(&mesh), AccelKind::Bvh);
        let embree = Accel::build_with(std::slice::from_ref(&mesh), AccelKind::Embree);
        assert_eq!(embree.kind(), AccelKind::Embree);
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let (mut hits, mut differ) = (0, 0);
        for i in 0..20_000 {
            let o = Vec3::new(u(), u(), u()) * 24.0 - 12.0;
            let d = if i % 4 == 0 { axes[i % 6] } else { Vec3::new(u(), u(), u()) * 2.0 - 1.0 };
            let t_max = if i % 3 == 0 { 5.0 } else { f32::INFINITY };
            let ray = Ray::new(o, d, t_max);
            let (a, b) = (bvh.intersect(&ray), embree.intersect(&ray));
            assert_eq!(bvh.occluded(&ray), embree.occluded(&ray), "ray {ray:?}");
            assert_eq!(a.is_some(), b.is_some(), "ray {ray:?}: {a:?} {b:?}");
            let (Some(a), Some(b)) = (a, b) else { continue };
            hits += 1;
            assert!((a.t - b.t).abs() <= 1e-4 * a.t.max(1.0), "ray {ray:?}: {a:?} {b:?}");
            if a.tri != b.tri {
                differ += 1;
            } else {
                assert!(a.b.iter().zip(b.b).all(|(x, y)| (x - y).abs() < 1e-3), "{a:?} {b:?}");
            }
        }
        assert!(hits > 5000, "{hits} hits");
        assert!(differ <= hits / 1000, "{differ} of {hits} hits on another triangle");
    }

    /// A stand-in alpha test: holes where a pattern in the barycentrics says so, more of them
    /// for shadow rays (as `shadowalpha`), and a count of the questions asked.
    struct Holes(std::sync::atomic::AtomicUsize);

    impl HitFilter for Holes {
        fn accept(&self, hit: &Hit, shadow: bool) -> bool {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let hole = |f: f32| (hit.b[1] * f).fract() < 0.3 && (hit.b[2] * f).fract() < 0.6;
            !(hole(4.0) || (shadow && hole(7.0)))
        }
    }

    /// A soup of random triangles, every other mesh cut out.
    fn soup(seed: u64, n: u32, cutouts: bool) -> Vec<TriangleMesh> {
        let mut rng = crate::rng::Rng::new(seed);
        let mut u = || rng.uniform_f32();
        (0..4)
            .map(|k| {
                let (mut positions, mut indices) = (Vec::new(), Vec::new());
                for i in 0..n {
                    let c = Vec3::new(u(), u(), u()) * 20.0 - 10.0;
                    for _ in 0..3 {
                        positions.push(c + (Vec3::new(u(), u(), u()) - 0.5) * 3.0);
                    }
                    indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
                }
                let alpha = (cutouts && k % 2 == 1).then_some(crate::mesh::AlphaSpec::Constant(0.0));
                TriangleMesh { positions, indices, alpha, ..Default::default() }
            })
            .collect()
    }

    /// Cut-outs: the closest hit is the closest hit the alpha test accepts (checked against a
    /// brute-force loop over every triangle), occlusion also asks `shadowalpha`, opaque meshes
    /// are never asked about; BVH and Embree answer alike, with the same questions asked.
    #[test]
    fn cutouts_in_bvh_and_embree() {
        let meshes = soup(3, 400, true);
        let brute = |ray: &Ray, shadow: bool, f: &Holes| {
            let mut best: Option<Hit> = None;
            for (mi, m) in meshes.iter().enumerate() {
                for ti in 0..m.indices.len() {
                    let one = Accel::build(&[TriangleMesh {
                        positions: m.vertices(ti).to_vec(),
                        indices: vec![[0, 1, 2]],
                        ..Default::default()
                    }]);
                    let Some(h) = one.intersect(ray) else { continue };
                    let h = Hit { mesh: mi as u32, tri: ti as u32, ..h };
                    if (m.alpha.is_none() || f.accept(&h, shadow)) && best.is_none_or(|b| h.t < b.t) {
                        best = Some(h);
                    }
                }
            }
            best
        };
        let mut rng = crate::rng::Rng::new(8);
        let mut u = || rng.uniform_f32();
        let rays: Vec<Ray> = (0..300)
            .map(|_| {
                Ray::new(Vec3::new(u(), u(), u()) * 24.0 - 12.0, Vec3::new(u(), u(), u()) * 2.0 - 1.0, f32::INFINITY)
            })
            .collect();
        let oracle = Holes(Default::default());
        let expected: Vec<(Option<Hit>, bool)> =
            rays.iter().map(|r| (brute(r, false, &oracle), brute(r, true, &oracle).is_some())).collect();
        let mut asked = Vec::new();
        for kind in kinds() {
            let mut accel = Accel::build_with(&meshes, kind);
            let holes = std::sync::Arc::new(Holes(Default::default()));
            accel.set_filter(holes.clone());
            let (mut hits, mut cut) = (0, 0);
            for (ray, (want, blocked)) in rays.iter().zip(&expected) {
                let got = accel.intersect(ray);
                assert_eq!(got.map(|h| (h.mesh, h.tri)), want.map(|h| (h.mesh, h.tri)), "{kind:?} ray {ray:?}");
                if let (Some(g), Some(w)) = (got, want) {
                    assert!((g.t - w.t).abs() <= 1e-5 * w.t, "{kind:?} {g:?} {w:?}");
                    hits += 1;
                }
                assert_eq!(accel.occluded(ray), *blocked, "{kind:?} shadow ray {ray:?}");
                cut += (accel.occluded(ray) != Accel::build_with(&meshes, kind).occluded(ray)) as usize;
            }
            assert!(hits > 100 && cut > 3, "{kind:?}: {hits} hits, {cut} rays through holes only");
            asked.push(holes.0.load(std::sync::atomic::Ordering::Relaxed));
        }
        // Both backends ask about the same candidates (in their own order; counts agree within
        // what traversal order changes).
        assert!(asked.iter().all(|&a| a > 100), "{asked:?}");
        // Without cut-out meshes the filter is never asked.
        let mut opaque = Accel::build(&soup(3, 400, false));
        let holes = std::sync::Arc::new(Holes(Default::default()));
        opaque.set_filter(holes.clone());
        for r in &rays {
            opaque.intersect(r);
            opaque.occluded(r);
        }
        assert_eq!(holes.0.load(std::sync::atomic::Ordering::Relaxed), 0);
    }

    #[test]
    fn degenerate_input_does_not_panic() {
        let mut m = quad(0.0, 1.0);
        m.positions[1] = Vec3::NAN;
        m.indices.push([0, 0, 0]);
        for kind in kinds() {
            let accel = Accel::build_with(&[m.clone(), TriangleMesh::default()], kind);
            assert_eq!(accel.triangle_count(), 1);
            assert!(accel.intersect(&Ray::new(Vec3::ZERO, Vec3::ZERO, 1.0)).is_none());
            assert!(accel.intersect(&Ray::new(Vec3::NAN, Vec3::Y, 1.0)).is_none());
            assert!(!accel.occluded(&Ray::new(Vec3::ZERO, Vec3::INFINITY, 1.0)));
            assert!(Accel::build_with(&[], kind).intersect(&Ray::new(Vec3::ZERO, Vec3::Y, 1.0)).is_none());
        }
    }

    /// Curves beside triangles in one hierarchy: over random rays through a soup of triangles
    /// and random flat curves, the closest hit and occlusion are a brute-force loop's over every
    /// triangle and every curve piece (the curve's own test), and a bundle's candidates give the
    /// same hits; Embree, asked for, still answers (its triangles only) — the scene build falls
    /// back to the BVH with a warning for scenes with curves.
    #[test]
    fn curves_beside_triangles() {
        use crate::mesh::curve::{CurveSegment, CurveType, Curves};
        use glam::Mat4;
        let mut meshes = soup(4, 200, false);
        let mut rng = crate::rng::Rng::new(21);
        let mut u = || rng.uniform_f32();
        let mut curves = Vec::new();
        for k in 0..6 {
            let c0 = Vec3::new(u(), u(), u()) * 16.0 - 8.0;
            let segments = (0..4)
                .map(|_| {
                    let cp = [0, 1, 2, 3].map(|i| c0 + Vec3::new(i as f32, u() * 2.0 - 1.0, u() * 2.0 - 1.0) * 1.5);
                    CurveSegment::new(cp, [0.3, 0.1], None)
                })
                .collect();
            let c = std::sync::Arc::new(Curves {
                kind: if k % 2 == 0 { CurveType::Flat } else { CurveType::Cylinder },
                segments,
                split_depth: 2,
                world_from_object: Mat4::IDENTITY,
                object_from_world: Mat4::IDENTITY,
                reverse_orientation: false,
                swaps_handedness: false,
            });
            curves.push(c.clone());
            meshes.push(TriangleMesh { curves: Some(c), ..Default::default() });
        }
        let accel = Accel::build(&meshes);
        assert_eq!(accel.curve_piece_count(), 6 * 4 * 4);
        let (mut curve_hits, mut tri_hits) = (0, 0);
        for _ in 0..3000 {
            let o = Vec3::new(u(), u(), u()) * 24.0 - 12.0;
            let target = Vec3::new(u(), u(), u()) * 16.0 - 8.0;
            let ray = Ray::new(o, target - o, if u() < 0.3 { 0.7 } else { f32::INFINITY });
            // Brute force: the nearest triangle (a one-mesh hierarchy per soup mesh) or curve piece.
            let mut best: Option<(f32, u32)> = None;
            for (mi, m) in meshes.iter().enumerate() {
                let t = match &m.curves {
                    Some(c) => (0..c.prim_count())
                        .filter_map(|p| c.intersect(p, ray.o, ray.d, ray.t_max, false))
                        .map(|h| h.t)
                        .reduce(f32::min),
                    None => Accel::build(std::slice::from_ref(m)).intersect(&ray).map(|h| h.t),
                };
                if let Some(t) = t {
                    if best.is_none_or(|b| t < b.0) {
                        best = Some((t, mi as u32));
                    }
                }
            }
            let got = accel.intersect(&ray);
            assert_eq!(got.map(|h| h.mesh), best.map(|b| b.1), "ray {ray:?}");
            if let (Some(g), Some(b)) = (got, best) {
                assert!((g.t - b.0).abs() <= 1e-4 * b.0.max(1.0), "{g:?} {b:?}");
                if meshes[g.mesh as usize].curves.is_some() {
                    curve_hits += 1;
                } else {
                    tri_hits += 1;
                }
            }
            assert_eq!(accel.occluded(&ray), best.is_some(), "ray {ray:?}");
            if let Some(c) = accel.bundle_candidates(std::slice::from_ref(&ray), usize::MAX) {
                assert_eq!(accel.intersect_among(&ray, &c), got, "ray {ray:?}");
            }
        }
        assert!(curve_hits > 30 && tri_hits > 300, "{curve_hits} curve hits, {tri_hits} triangle hits");
        let embree = Accel::build_with(&meshes, AccelKind::Embree);
        assert_eq!(embree.kind(), AccelKind::Bvh, "a hierarchy with curves is the BVH's");
    }

    /// A mesh that repeats one face 46 080 times (the fuzz run's 877 KB glass-dragon input; a
    /// mutated PLY face list): obvhs's PLOC merged one pair of the identical boxes per pass,
    /// 58 s of CPU for `penumbra render` before, 0.01 s now. Each copy past the first (in any of
    /// its three turns) is left out; the reversed face and a cut-out mesh's copies are kept.
    #[test]
    fn repeated_faces_are_traced_once() {
        let p = vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        let mut indices = vec![[0, 1, 2]; 46_078];
        indices.extend([[1, 2, 0], [2, 1, 0]]);
        let mesh = TriangleMesh { positions: p, indices, ..Default::default() };
        let t0 = std::time::Instant::now();
        let accel = Accel::build_with(std::slice::from_ref(&mesh), AccelKind::Bvh);
        let secs = t0.elapsed().as_secs_f64();
        assert_eq!((accel.duplicates, accel.duplicates_in), (46_078, Some(0)));
        assert_eq!(accel.triangle_count(), 2);
        // Generous for a loaded machine; the quadratic build took about a minute.
        assert!(secs < 10.0, "{secs} s");
        let down = Ray::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0), f32::INFINITY);
        let hit = accel.intersect(&down).expect("a hit");
        // The first copy or the reversed face, which coincides with it.
        assert!(hit.mesh == 0 && (hit.tri == 0 || hit.tri == 46_079), "{:?}", (hit.mesh, hit.tri));
        assert!((hit.t - 1.0).abs() < 1e-6);
        let cut = TriangleMesh { alpha: Some(AlphaSpec::Texture(0)), indices: vec![[0, 1, 2]; 3], ..mesh };
        assert_eq!(Accel::build_with(&[cut], AccelKind::Bvh).duplicates, 0);
    }
}
