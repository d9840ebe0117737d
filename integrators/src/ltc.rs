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
//! the builder proves it convex) and by its triangles otherwise (`per-triangle`, which
//! also takes every light triangle on its own: the paper's Sect. 4.4).
//! Occluder geometry beyond the light triangle's plane cannot shadow it: triangles
//! are clipped to the half-space of the shading point first, and a convex object
//! straddling that plane is taken triangle by triangle. The triangles of one object
//! that need no clipping (and lie in the open hemisphere around the light) are
//! subtracted as the outline of their union ([`spherical::triangle_chains`]: each
//! taken positively oriented from the point, shared edges cancelled, the rest covers
//! by winding number), which is exact and has far fewer edges than the triangles —
//! for a closed mesh, its silhouette edges (`"bool mergeoccluders" "false"`: one by one).
//!
//! Point, spot, distant, goniometric and projection lights get exact hard shadows
//! (one shadow ray, the real BSDF). Infinite lights, and materials that do not reduce
//! to a Lambertian plus a GGX lobe, fall back to `directlighting`'s estimator for
//! that light or that point, with one warning each.

use crate::common::direct::estimate_direct;
use glam::DVec3;
use penumbra_core::bxdf::{Bsdf, BxdfFlags, Fresnel};
use penumbra_core::film::Film;
use penumbra_core::geometry::{Bounds3, Frame, Ray};
use penumbra_core::integrator::{
    render_pixels, Integrator, PixelEstimator, PixelShared, RenderContext, RenderError, RenderStats, ThreadStats,
};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::{emitting_normal, Light, LightContext};
use penumbra_core::ltc::{ltc_integrate_vector, Ltc, LtcCoeffs};
use penumbra_core::material::{LtcDescription, LtcFresnel, LtcSpecular};
use penumbra_core::mesh::TriangleMesh;
use penumbra_core::sampler::Sampler;
use penumbra_core::scene::{Requirements, Scene, SurfaceHit, SurfacePoint};
use penumbra_core::spectrum::luminance;
use penumbra_core::spherical::{self, SilhouetteMesh};
use penumbra_core::{Rgb, Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One silhouette loop per closed mesh.
    Silhouette,
    /// Every light and every occluder as its triangles.
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
    /// `"string shading" "pixel"` (default): the samples of a pixel only resolve visibility
    /// (edges, which surface is seen); each surface seen in the pixel is shaded once
    /// (multisample antialiasing). `"sample"`: every sample is shaded.
    pub pixel_shading: bool,
    /// Occluder triangles of one object that lie wholly in front of the light are subtracted as
    /// their outline (`"bool mergeoccluders"`, default true; false: triangle by triangle).
    pub merge_occluders: bool,
    /// With pixel shading, at least this many camera samples per pixel (`"integer
    /// coveragesamples"`, default 16; 1: the sampler's count as it is). They cost a camera ray
    /// each, not a shading: below ~16 the image's error is the aliasing of edges, not noise.
    pub coverage_samples: u32,
}

/// Why `ltc` raises the sampler's count (the scene build's warning says it).
const COVERAGE_REASON: &str = "ltc shades each surface a pixel sees once, and the camera samples only resolve which \
     surfaces those are and where their edges run (a camera ray each); \"integer coveragesamples\" sets this floor";

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
        let pixel_shading = parse_shading("ltc", params, warnings);
        let merge_occluders = params.get_one_bool("mergeoccluders", true);
        let coverage = params.get_one_int("coveragesamples", 16);
        if !(1..=1024).contains(&coverage) {
            return Err(Diagnostic::error(
                params.loc_of("coveragesamples").cloned(),
                format!("ltc: \"coveragesamples\" must be in 1..=1024, got {coverage}"),
            ));
        }
        Ok(Box::new(LtcIntegrator {
            mode,
            shadows,
            fresnel,
            pixel_shading,
            merge_occluders,
            coverage_samples: coverage as u32,
        }))
    }
}

/// `"string shading"`: `"pixel"` (default: each surface seen in a pixel shaded once) or
/// `"sample"` (every camera sample shaded); `true` for pixel.
pub(crate) fn parse_shading(integrator: &str, params: &ParamSet, warnings: &DiagSink) -> bool {
    match params.get_one_string("shading", "pixel").as_str() {
        "pixel" => true,
        "sample" => false,
        other => {
            warnings.warn(
                params.loc_of("shading").cloned(),
                format!("{integrator}: unknown shading \"{other}\" (expected pixel or sample): using \"pixel\""),
            );
            true
        }
    }
}

/// What the estimator knows about each object (mesh `i` = object `i`).
struct ObjectInfo {
    bounds: Bounds3,
    occluder: bool,
    /// Closed and convex (proven by the builder), with its adjacency for silhouettes.
    silhouette: Option<SilhouetteMesh>,
    /// A hierarchy over the object's triangles, for the per-triangle cone query.
    tris: ObjectBvh,
    /// All vertices in one plane: as a light, it cannot shadow itself.
    planar: bool,
    /// Mesh vertex index → id shared by vertices at the same position (for triangle outlines).
    weld: Vec<u32>,
    /// A closed, consistently wound mesh (after welding; known for silhouette meshes, and for
    /// others with `mergeoccluders`): +1 when its winding normals point out of the solid, −1
    /// when in, 0 otherwise or unknown. From outside or inside, the triangles facing away from a
    /// point cover exactly the directions in which a ray from it meets the solid (every such ray
    /// leaves it through one): the others need not be subtracted.
    closed: f64,
}

/// For a closed, consistently wound mesh: +1 when its winding normals point outwards (positive
/// enclosed volume), −1 inwards, 0 when the volume is too small to tell.
fn winding_sign(mesh: &TriangleMesh) -> f64 {
    let (mut vol, mut scale) = (0.0f64, 0.0f64);
    let c = mesh.positions.first().map(|q| d3(*q)).unwrap_or(DVec3::ZERO);
    for t in 0..mesh.triangle_count() {
        let [a, b, d] = mesh.vertices(t).map(|q| d3(q) - c);
        vol += a.dot(b.cross(d));
        scale += a.length() * b.length() * d.length();
    }
    if vol.abs() > 1e-9 * scale {
        vol.signum()
    } else {
        0.0
    }
}

/// Whether every vertex of `mesh` lies within 1e-6 of its extent from the plane of its
/// largest triangle.
fn is_planar(mesh: &TriangleMesh, bounds: &Bounds3) -> bool {
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

/// How an area light's emitting surface is turned into spherical polygons at a shading point.
enum LightShape {
    /// One triangle at a time (any mesh).
    Triangles,
    /// All triangles in one plane, emitting to the same side, forming one simple polygon:
    /// the `outline` (world space) is integrated once instead of triangle by triangle.
    Planar { outline: Vec<DVec3>, normal: DVec3, origin: DVec3 },
    /// A closed convex mesh emitting outwards: what a point outside sees of it is exactly
    /// its silhouette loop (the front faces tile it, none overlap), integrated once.
    Convex(ConvexShape),
}

/// What a convex light mesh needs at every shading point, computed once.
struct ConvexShape {
    sil: SilhouetteMesh,
    /// Edge-on tolerance of its faces: 1e-9 of the mesh's extent.
    eps: f64,
    /// (a point of the face, outward unit normal) of every non-degenerate face.
    faces: Vec<(DVec3, DVec3)>,
    vertices: Vec<DVec3>,
    center: DVec3,
}

impl ConvexShape {
    fn new(mesh: &TriangleMesh) -> ConvexShape {
        let faces = (0..mesh.triangle_count())
            .filter_map(|t| {
                let [a, b, c] = mesh.vertices(t).map(d3);
                let n = (b - a).cross(c - a).normalize_or_zero();
                (n != DVec3::ZERO).then_some((a, n))
            })
            .collect();
        let vertices: Vec<DVec3> = mesh.positions.iter().map(|q| d3(*q)).collect();
        let center = vertices.iter().copied().sum::<DVec3>() / vertices.len().max(1) as f64;
        let sil = SilhouetteMesh::new(mesh, &mesh.build_adjacency());
        ConvexShape { sil, eps: 1e-9 * mesh_extent(mesh), faces, vertices, center }
    }
}

impl LightShape {
    fn of(mesh: &TriangleMesh, tris: &[u32], two_sided: bool) -> LightShape {
        let n = mesh.triangle_count();
        let mut covered = vec![false; n];
        for t in tris {
            if let Some(c) = covered.get_mut(*t as usize) {
                *c = true;
            }
        }
        if n == 0 || tris.len() != n || !covered.iter().all(|c| *c) {
            return LightShape::Triangles;
        }
        if let Some(s) = Self::planar(mesh, two_sided) {
            return s;
        }
        if !two_sided && mesh.is_closed_convex(1e-5) {
            // Outward winding is proven; the emitting side must agree on every face.
            let outward = (0..n).all(|t| {
                let w = mesh.winding_normal(t);
                w == Vec3::ZERO || emitting_normal(mesh, t).dot(w) > 0.0
            });
            if outward {
                return LightShape::Convex(ConvexShape::new(mesh));
            }
        }
        LightShape::Triangles
    }

    fn planar(mesh: &TriangleMesh, two_sided: bool) -> Option<LightShape> {
        let b = mesh_bounds(mesh);
        if mesh.triangle_count() < 2 || !is_planar(mesh, &b) {
            return None;
        }
        let t0 = (0..mesh.triangle_count()).max_by(|a, c| mesh.area(*a).total_cmp(&mesh.area(*c)))?;
        let [a, bb, c] = mesh.vertices(t0).map(d3);
        let plane_n = (bb - a).cross(c - a).normalize_or_zero();
        if plane_n == DVec3::ZERO {
            return None;
        }
        // One emitting side for all (a one-sided light); winding consistent with it.
        let normal = if two_sided { plane_n } else { d3(emitting_normal(mesh, t0)).normalize_or_zero() };
        let mut tri_area = 0.0;
        for t in 0..mesh.triangle_count() {
            let [p0, p1, p2] = mesh.vertices(t).map(d3);
            let w = (p1 - p0).cross(p2 - p0);
            if w.length() == 0.0 {
                continue;
            }
            if w.dot(plane_n) <= 0.0 || (!two_sided && d3(emitting_normal(mesh, t)).dot(normal) <= 0.0) {
                return None;
            }
            tri_area += 0.5 * w.length();
        }
        let adj = mesh.build_adjacency();
        if adj.non_manifold_edges() > 0 || adj.edges.iter().any(|e| e.count == 2 && !e.consistent) {
            return None;
        }
        let mut pos = vec![DVec3::ZERO; adj.welded_count];
        for (i, w) in adj.weld.iter().enumerate() {
            pos[*w as usize] = d3(mesh.positions[i]);
        }
        // Boundary edges in their triangle's winding chain into the outline.
        let mut next = std::collections::HashMap::new();
        for e in adj.edges.iter().filter(|e| e.count == 1) {
            if next.insert(e.v[0], e.v[1]).is_some() {
                return None; // a vertex where the boundary pinches
            }
        }
        // The smallest id: the same outline start on every run (a HashMap's order is not).
        let &start = next.keys().min()?;
        let mut outline = vec![pos[start as usize]];
        let mut cur = next[&start];
        while cur != start {
            outline.push(pos[cur as usize]);
            cur = *next.get(&cur)?;
            if outline.len() > next.len() {
                return None;
            }
        }
        if outline.len() != next.len() {
            return None; // more than one boundary loop (holes, several pieces)
        }
        // No overlaps or folds: the outline encloses exactly the triangles' area.
        let mut vec_area = DVec3::ZERO;
        for i in 0..outline.len() {
            vec_area += outline[i].cross(outline[(i + 1) % outline.len()]);
        }
        let outline_area = 0.5 * vec_area.dot(plane_n);
        if !((outline_area - tri_area).abs() <= 1e-6 * tri_area) {
            return None;
        }
        Some(LightShape::Planar { outline, normal, origin: a })
    }
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
    /// The area lights, gathered per emitting mesh (pbrt-v3 makes one light per triangle).
    groups: Vec<LightGroup>,
}

struct Estimator<'a> {
    shader: LtcShader<'a>,
    warn_material: AtomicBool,
    warnings: &'a DiagSink,
    /// The scene has lights other than area lights.
    other_lights: bool,
}

/// A cone of directions containing a loop: unit `axis` and the half-angle's cosine.
#[derive(Clone, Copy)]
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
            let b = mesh_bounds(mesh);
            let occluder = scene.objects.get(i).is_none_or(|o| o.occluder);
            let silhouette = match settings.mode {
                Mode::PerTriangle => None,
                _ if !settings.shadows || !occluder => None,
                Mode::Auto => mesh.is_closed_convex(1e-4).then(|| mesh.build_adjacency()),
                Mode::Silhouette => {
                    let adj = mesh.build_adjacency();
                    adj.is_closed_manifold().then_some(adj)
                }
            }
            .map(|adj| {
                let sil = SilhouetteMesh::new(mesh, &adj);
                (adj, sil)
            });
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
            let (weld, closed) = if occluder && settings.shadows && settings.merge_occluders {
                let built;
                let adj = match &silhouette {
                    Some((adj, _)) => adj,
                    None => {
                        built = mesh.build_adjacency();
                        &built
                    }
                };
                (adj.weld.clone(), if adj.is_closed_manifold() { winding_sign(mesh) } else { 0.0 })
            } else {
                // (Silhouette meshes are closed: their orientation says which side is inside.)
                (Vec::new(), if silhouette.is_some() { winding_sign(mesh) } else { 0.0 })
            };
            let silhouette = silhouette.map(|(_, s)| s);
            objects.push(ObjectInfo { bounds: b, occluder, silhouette, tris, planar, weld, closed });
        }
        let mut groups: Vec<LightGroup> = Vec::new();
        for l in scene.light_list() {
            let Some(geom) = l.area() else { continue };
            if scene.meshes.get(geom.mesh as usize).is_none() {
                continue;
            }
            match groups
                .iter_mut()
                .find(|g| g.mesh == geom.mesh as usize && g.l == geom.l && g.two_sided == geom.two_sided)
            {
                Some(g) => g.tris.extend_from_slice(&geom.tris),
                None => groups.push(LightGroup {
                    mesh: geom.mesh as usize,
                    tris: geom.tris.clone(),
                    l: geom.l,
                    two_sided: geom.two_sided,
                    shape: LightShape::Triangles,
                    center: DVec3::ZERO,
                    radius: 0.0,
                }),
            }
        }
        for g in &mut groups {
            let mesh = &scene.meshes[g.mesh];
            // The paper's per-triangle method (its Sect. 4.4) takes every triangle of every
            // light, as of every occluder, on its own.
            g.shape = match settings.mode {
                Mode::PerTriangle => LightShape::Triangles,
                _ => LightShape::of(mesh, &g.tris, g.two_sided),
            };
            let mut b = Bounds3::EMPTY;
            for &t in &g.tris {
                if (t as usize) < mesh.triangle_count() {
                    for v in mesh.vertices(t as usize) {
                        b.extend(v);
                    }
                }
            }
            if b.min.x <= b.max.x {
                g.center = (d3(b.min) + d3(b.max)) * 0.5;
                g.radius = (d3(b.max) - d3(b.min)).length() * 0.5;
            }
        }
        LtcShader { ltc: settings, objects, bvh: ObjectBvh::build(&boxes), groups }
    }

    /// The area lights, one per emitting mesh and radiance.
    pub(crate) fn light_groups(&self) -> &[LightGroup] {
        &self.groups
    }

    /// Distance from `p` to the nearest area light's bounding sphere (0 inside one; infinite
    /// without area lights).
    fn nearest_light_distance(&self, p: DVec3) -> f64 {
        self.groups.iter().map(|g| ((p - g.center).length() - g.radius).max(0.0)).fold(f64::INFINITY, f64::min)
    }

    /// The LTC description of the material at `si` (`None`: no LTC form, or no material).
    pub fn lobes(scene: &Scene, si: &SurfaceInteraction) -> Option<LtcDescription> {
        let (m, _, tx) = scene.material_of(si)?;
        m.ltc_lobes(si, tx)
    }

    /// The diffuse albedo of [`Self::lobes`] alone (`None` exactly when it is `None`).
    fn diffuse_albedo(scene: &Scene, si: &SurfaceInteraction) -> Option<Rgb> {
        let (m, _, tx) = scene.material_of(si)?;
        m.ltc_diffuse(si, tx)
    }

    /// Occluder loops (world-space directions from `p`) for the light piece `piece` (world
    /// positions of a triangle, a planar outline or a convex light's silhouette).
    ///
    /// `plane` (a point and the normal towards `p`): occluder geometry beyond it is clipped
    /// away. `separate`: the light is convex (its front faces and vertices given) and every
    /// occluder must be separated from it by a plane with `p` on the occluder's side, so that
    /// it lies in front of the light along every ray; `None` is returned when one is not
    /// (the caller then takes the light triangle by triangle).
    #[allow(clippy::too_many_arguments)]
    fn occluders(
        &self,
        scene: &Scene,
        p: DVec3,
        skip: Skip,
        piece: &[DVec3],
        plane: Option<(DVec3, DVec3)>,
        separate: Option<&ConvexLight>,
        receiver: Receiver,
        scratch: &mut Vec<usize>,
    ) -> Option<Occluders> {
        let Receiver { mesh: receiver, tri: receiver_tri, facing } = receiver;
        let mut loops = Vec::new();
        let mut chains = Vec::new();
        let mut whole: Vec<usize> = Vec::new();
        let mut candidates: Vec<usize> = Vec::new();
        let c = piece.iter().copied().sum::<DVec3>() / piece.len().max(1) as f64;
        let r = piece.iter().map(|v| (*v - c).length()).fold(0.0, f64::max);
        let cone = Cone::towards(p.as_vec3(), c.as_vec3(), r as f32 * 1.001 + 1e-6);
        let axis = (c - p).normalize_or_zero();
        let (light_mesh, skip_tri) = match skip {
            Skip::Mesh(m) => (m, None),
            Skip::Triangle(m, t) => (m, Some(t)),
        };
        self.bvh.query(&cone, scratch);
        for &o in scratch.iter() {
            let info = &self.objects[o];
            if !info.occluder {
                continue;
            }
            if o == light_mesh && (skip_tri.is_none() || info.planar) {
                continue;
            }
            let inside = facing * info.closed < 0.0;
            if o == receiver && (info.planar || (info.silhouette.is_some() && !inside)) {
                // A plane through p subtends nothing; a convex object cannot shadow itself (seen
                // from outside; from inside, its other faces enclose p: taken by triangles below).
                continue;
            }
            if let Some(cl) = separate {
                if !cl.separated_from(&info.bounds, p) {
                    return None;
                }
            }
            let mesh = &scene.meshes[o];
            let straddles = plane.is_some_and(|(plane_o, ln)| {
                let corners = [info.bounds.min, info.bounds.max];
                (0..8).any(|k| {
                    let q = Vec3::new(corners[k & 1].x, corners[(k >> 1) & 1].y, corners[(k >> 2) & 1].z);
                    (d3(q) - plane_o).dot(ln) <= 0.0
                })
            });
            if let (Some(sil), false, false, false) = (&info.silhouette, straddles, o == light_mesh, o == receiver) {
                let eps = 1e-7 * (info.bounds.max - info.bounds.min).length() as f64;
                let sil_loops = sil.loops(p, eps);
                // No face turned towards p: p is inside the solid (or on it), which hides all
                // that lies outside it; its triangles below say exactly what (the light may be
                // inside too).
                if !sil_loops.is_empty() {
                    loops.extend(sil_loops.iter().map(|l| spherical::project(p, l)));
                    continue;
                }
            }
            info.tris.query(&cone, &mut candidates);
            whole.clear();
            let cull = self.ltc.merge_occluders && info.closed != 0.0 && !straddles && o != light_mesh;
            for &t in &candidates {
                // The light triangle itself, and the receiver's own triangle (flat: it cannot
                // shadow a point on it, and the point's rounding may put it a hair off its plane).
                if (o == light_mesh && Some(t) == skip_tri) || (o == receiver && t == receiver_tri) {
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
                let side = tn.dot(p - pv[0]);
                if !(tn_len > 0.0) || (side / tn_len).abs() <= 1e-6 * (tr + (p - tc).length()) {
                    continue;
                }
                // The light wholly on p's side of the triangle's plane (or on it): no segment from
                // p to the light crosses the plane, so none meets the triangle (e.g. a floor
                // below both the point and the light).
                if piece.iter().all(|q| tn.dot(*q - pv[0]) * side >= 0.0) {
                    continue;
                }
                // A closed solid wholly in front of the light: only the faces turned away from p
                // (where rays leave it) are needed; they cover what the others do.
                if cull && tn.dot(p - pv[0]) * info.closed > 0.0 {
                    continue;
                }
                // Chains are exact within an open hemisphere (the charts' clipping joins points
                // along minor arcs): only triangles wholly in the one around the light are merged.
                let in_hemisphere = pv.iter().all(|v| (*v - p).dot(axis) > 1e-3 * (*v - p).length());
                let Some((plane_o, ln)) = plane else {
                    if in_hemisphere {
                        whole.push(t);
                    } else {
                        loops.push(spherical::project(p, &pv));
                    }
                    continue;
                };
                // Nothing strictly in front of the light's plane (e.g. the other half of a quad
                // light, coplanar with it): it cannot occlude the light.
                let ln_len = ln.length();
                let dist = pv.map(|v| (v - plane_o).dot(ln) / ln_len);
                let front = dist.iter().copied().fold(f64::MIN, f64::max);
                if !(front > 1e-7 * (tr + (p - tc).length())) {
                    continue;
                }
                if in_hemisphere && dist.iter().all(|&d| d >= 0.0) {
                    whole.push(t);
                    continue;
                }
                let clipped = clip_to_plane(&pv, plane_o, ln);
                if clipped.is_empty() {
                    continue;
                }
                loops.push(spherical::project(p, &clipped));
            }
            // Adjacent triangles: their outline instead of each one (exact, far fewer edges).
            if whole.len() > 1 && self.ltc.merge_occluders {
                let outline = spherical::triangle_chains(mesh, &whole, &info.weld, p);
                let projected: Vec<Vec<DVec3>> = outline.iter().map(|l| spherical::project(p, l)).collect();
                if projected.iter().flatten().all(|d| *d != DVec3::ZERO) {
                    chains.extend(projected);
                    continue;
                }
            }
            loops.extend(whole.iter().map(|&t| spherical::project(p, &mesh.vertices(t).map(d3))));
        }
        Some(Occluders { loops, chains })
    }

    /// Analytic radiance reflected towards `si.wo` from all area lights, with analytic
    /// visibility when `shadows`, else unshadowed.
    pub fn area_lights(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        desc: &LtcDescription,
        shadows: bool,
        scratch: &mut Vec<usize>,
    ) -> Rgb {
        let (diffuse, specular) = self.area_lights_split(scene, si, desc, shadows, scratch);
        desc.diffuse * diffuse + specular
    }

    /// [`area_lights`](Self::area_lights) as the light reaching the Lambertian lobe (to be
    /// multiplied by the albedo: `Σ L · form factor`) and the glossy lobe's radiance.
    pub fn area_lights_split(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        desc: &LtcDescription,
        shadows: bool,
        scratch: &mut Vec<usize>,
    ) -> (Rgb, Rgb) {
        let (mut d, mut s) = (Rgb::ZERO, Rgb::ZERO);
        let facing = mesh_winding_normal(scene, si).dot(si.wo) as f64;
        let receiver = Receiver { mesh: si.mesh as usize, tri: si.tri as usize, facing };
        for g in &self.groups {
            let (gd, gs) = self.area_group(scene, si, receiver, desc, g, shadows, scratch);
            d += gd;
            s += gs;
        }
        (d, s)
    }

    /// The same for the lights of one mesh.
    #[allow(clippy::too_many_arguments)]
    fn area_group(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        receiver: Receiver,
        desc: &LtcDescription,
        geom: &LightGroup,
        shadows: bool,
        scratch: &mut Vec<usize>,
    ) -> (Rgb, Rgb) {
        let none = (Rgb::ZERO, Rgb::ZERO);
        let lm = geom.mesh;
        let Some(mesh) = scene.meshes.get(lm) else { return none };
        let p = d3(si.p);
        let n = desc.n.normalize_or_zero();
        if n == Vec3::ZERO {
            return none;
        }
        // pbrt-v3's BSDFs reflect on whichever side ωo is (a mesh wound inwards still lights
        // up): integrate over the hemisphere around the normal on ωo's side.
        let n = if n.dot(si.wo) < 0.0 { -n } else { n };
        let frame = Frame::toward(d3(n), d3(si.wo));
        let spec = desc.specular.map(|s| {
            let cos_o = frame.to_local(d3(si.wo)).z.clamp(0.0, 1.0);
            (s, Ltc::lookup(cos_o as f32, s.alpha))
        });
        let wo_local = frame.to_local(d3(si.wo));
        let mut acc = Accum { diffuse_ff: 0.0, spec_int: 0.0, spec_fresnel: Rgb::ZERO };
        let whole = match &geom.shape {
            LightShape::Triangles => false,
            LightShape::Planar { outline, normal, origin } => {
                let h = normal.dot(p - *origin);
                if h != 0.0 && (geom.two_sided || h > 0.0) {
                    let ln = if h > 0.0 { *normal } else { -*normal };
                    let occ = if shadows {
                        self.occluders(scene, p, Skip::Mesh(lm), outline, Some((*origin, ln)), None, receiver, scratch)
                    } else {
                        Some(Occluders::default())
                    };
                    self.integrate_piece(
                        p,
                        outline,
                        occ.unwrap_or_default(),
                        &frame,
                        wo_local,
                        spec.as_ref(),
                        &mut acc,
                    );
                }
                true
            }
            LightShape::Convex(shape) => {
                let sil = shape.sil.loops(p, shape.eps);
                match sil.as_slice() {
                    [] => true, // p inside (or edge-on everywhere): no face emits towards it
                    [outline] => {
                        let occ = if shadows {
                            let cl = ConvexLight::new(shape, p);
                            self.occluders(scene, p, Skip::Mesh(lm), outline, None, Some(&cl), receiver, scratch)
                        } else {
                            Some(Occluders::default())
                        };
                        match occ {
                            Some(occ) => {
                                self.integrate_piece(p, outline, occ, &frame, wo_local, spec.as_ref(), &mut acc);
                                true
                            }
                            None => false,
                        }
                    }
                    _ => false,
                }
            }
        };
        if !whole {
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
                let occ = if shadows {
                    // The light triangle's plane, oriented towards p: occluders beyond it cannot
                    // shadow it.
                    let mut ln = (pv[1] - pv[0]).cross(pv[2] - pv[0]);
                    if ln.dot(p - pv[0]) < 0.0 {
                        ln = -ln;
                    }
                    let plane = Some((pv[0], ln));
                    self.occluders(scene, p, Skip::Triangle(lm, tri), &pv, plane, None, receiver, scratch)
                        .unwrap_or_default()
                } else {
                    Occluders::default()
                };
                self.integrate_piece(p, &pv, occ, &frame, wo_local, spec.as_ref(), &mut acc);
            }
        }
        let le = geom.l;
        let diffuse = le * acc.diffuse_ff.max(0.0) as f32;
        let mut out = Rgb::ZERO;
        if let Some((s, coeffs)) = spec {
            let spec_term = match self.ltc.fresnel {
                FresnelMode::Schlick => {
                    fresnel_weight(&s.fresnel, coeffs.magnitude, coeffs.fresnel) * acc.spec_int.max(0.0) as f32
                }
                FresnelMode::Average => (acc.spec_fresnel * coeffs.magnitude).max(Rgb::ZERO),
            };
            out += s.scale * spec_term * le;
        }
        (diffuse, out)
    }

    /// Adds the diffuse form factor and the LTC integrals of the part of the light piece
    /// `piece` (world positions) not covered by the `occ` loops.
    #[allow(clippy::too_many_arguments)]
    fn integrate_piece(
        &self,
        p: DVec3,
        piece: &[DVec3],
        mut occ: Occluders,
        frame: &Frame<DVec3>,
        wo_local: DVec3,
        spec: Option<&(LtcSpecular, LtcCoeffs)>,
        acc: &mut Accum,
    ) {
        let light_loop = spherical::project(p, piece);
        // (Needed for occluders and for the Fresnel split: computed once, when first needed.)
        let light_cone_cell = std::cell::OnceCell::new();
        let light_cone = || *light_cone_cell.get_or_init(|| BoundingCone::of(&light_loop));
        // Keep only occluder loops whose bounding cone meets the light's: most shading
        // points see most lights unoccluded and then need no polygon clipping at all.
        // (A chain's covered region lies within its vertices' cone too: dropping one of its
        // loops changes the winding only outside the light.)
        if !occ.is_empty() {
            if let Some(lc) = light_cone() {
                occ.loops.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
                occ.chains.retain(|o| BoundingCone::of(o).is_none_or(|oc| oc.overlaps(&lc)));
            }
        }
        // Without occluders the piece's single loop may have either orientation: its
        // integrals are taken by magnitude. `difference` returns oriented loops.
        // `cut`: `visible` is `[light⁺, −(light⁺ ∩ occluder)]` (one convex occluder).
        let (visible, single, cut) = if occ.is_empty() {
            (vec![light_loop.clone()], true, false)
        } else {
            // One convex occluder loop (a convex object's silhouette, a triangle) — most occluded
            // points of most scenes — is clipped against directly; anything else goes through the
            // planar Boolean.
            match (&occ.loops[..], occ.chains.is_empty()) {
                ([o], true) => match spherical::difference_convex(&light_loop, o) {
                    // Missed after all (the cones overlapped): the light's own loop, as unoccluded.
                    Some(v) if v.len() == 1 => (vec![light_loop.clone()], true, false),
                    Some(v) => {
                        let cut = v.len() == 2;
                        (v, false, cut)
                    }
                    None => (spherical::difference(std::slice::from_ref(&light_loop), &occ.loops), false, false),
                },
                _ => {
                    let v = spherical::difference_chains(std::slice::from_ref(&light_loop), &occ.loops, &occ.chains);
                    (v, false, false)
                }
            }
        };
        // The diffuse form factor in the shading frame, then the LTC integral together with
        // its vector form factor (one pass over the edges for both).
        let ff: f64 =
            visible.iter().map(|l| spherical::horizon_vector_form_factor(l.len(), |i| frame.to_local(l[i])).z).sum();
        acc.diffuse_ff += if single { ff.abs() } else { ff };
        let Some((s, coeffs)) = spec else { return };
        let ltc_of = |loops: &[Vec<DVec3>]| ltc_integrate_vector(&coeffs.minv, frame, loops);
        let lv = ltc_of(&visible);
        let v = if single { lv.z.abs() } else { lv.z };
        acc.spec_int += v;
        if self.ltc.fresnel == FresnelMode::Average && v != 0.0 {
            // The region's LTC-space vector form factor (additive over regions), oriented as
            // its integral is taken.
            let vff = if single && lv.z < 0.0 { -lv } else { lv };
            // The material's exact Fresnel at the half-vector between ωo and the LTC-weighted
            // mean direction of a region (its vector form factor in the cosine space, mapped
            // back by M: Heitz et al.'s proxy direction).
            let fresnel_of = |vff: DVec3| {
                let dir = (coeffs.m() * vff).normalize_or_zero();
                let h = (wo_local + dir).normalize_or_zero();
                let cos_d = if h == DVec3::ZERO { 1.0 } else { wo_local.dot(h).clamp(0.0, 1.0) };
                fresnel_at(&s.fresnel, cos_d as f32)
            };
            // A dielectric seen from its dense side (pbrt-v3's plastic: FresnelDielectric(1.5,
            // 1)) reflects totally beyond the critical angle: F = 1 wherever ωo·ωi < t_c, a
            // kink no single mean direction captures. The region is split along that circle
            // (a 16-gon) when it straddles it: F = 1 outside, rings of mean-direction
            // Fresnel inside (below).
            let wo_world = frame.from_local(wo_local);
            // (Decided on the whole light, so that a shadowed point is split wherever the
            // unshadowed one is: the same Fresnel treatment, never brighter.)
            let split = tir_threshold(&s.fresnel).map(|tc| {
                let rho = tc.clamp(-1.0, 1.0).acos();
                match light_cone() {
                    Some(c) => {
                        let gamma = c.axis.dot(wo_world).clamp(-1.0, 1.0).acos();
                        let beta = c.cos.clamp(-1.0, 1.0).acos();
                        if gamma + beta < rho {
                            TirSplit::Inside
                        } else if gamma - beta > rho {
                            TirSplit::Outside
                        } else {
                            TirSplit::Straddles(tc)
                        }
                    }
                    None => TirSplit::Straddles(tc),
                }
            });
            match split {
                None | Some(TirSplit::Inside) => acc.spec_fresnel += fresnel_of(vff) * v as f32,
                Some(TirSplit::Outside) => acc.spec_fresnel += Rgb::splat(v as f32),
                Some(TirSplit::Straddles(tc)) => {
                    // Outside the critical circle F = 1. Inside, F climbs steeply towards it
                    // (from 0.04 to 1 within ~12° of θd for η = 1.5), and the Fresnel at one
                    // mean direction underestimates a region's average there (F is convex):
                    // nested circles where F = 1/2, 1/4 and 1/8 split the inside into rings,
                    // each with the Fresnel at its own LTC-weighted mean direction.
                    let ts = fresnel_circles(&s.fresnel, tc);
                    // (LTC integral, vector form factor) of `region` within each ring, from
                    // the outermost (beyond the critical circle) to the innermost cap.
                    let rings = |region: &[Vec<DVec3>], total: (f64, DVec3)| -> Vec<(f64, DVec3)> {
                        let all: Vec<DVec3> = region.iter().flatten().copied().collect();
                        let cone = BoundingCone::of(&all);
                        let mut out = Vec::with_capacity(ts.len() + 1);
                        let mut outer = total;
                        let mut region = region.to_vec();
                        for &t in &ts {
                            if region.is_empty() {
                                out.push((0.0, DVec3::ZERO));
                                continue;
                            }
                            let rho = t.clamp(-1.0, 1.0).acos();
                            let side = cone.as_ref().map(|c| {
                                let gamma = c.axis.dot(wo_world).clamp(-1.0, 1.0).acos();
                                let beta = c.cos.clamp(-1.0, 1.0).acos();
                                (gamma + beta < rho, gamma - beta > rho)
                            });
                            let inner = match side {
                                Some((true, _)) => {
                                    // Wholly inside this circle: nothing in the ring (and `region`
                                    // may still be the caller's loop of either orientation).
                                    out.push((0.0, DVec3::ZERO));
                                    continue;
                                }
                                Some((_, true)) => Vec::new(), // wholly outside
                                // F is continuous across every circle (it reaches 1 at the
                                // critical one): a 16-gon's error only moves area between rings
                                // of nearly the same F (images unchanged from 64-gons to 1e-4).
                                _ => clip_to_cap(&region, wo_world, t, 16),
                            };
                            let inner_total = if inner.is_empty() {
                                (0.0, DVec3::ZERO)
                            } else {
                                let w = ltc_of(&inner);
                                (w.z, w)
                            };
                            out.push(((outer.0 - inner_total.0).max(0.0), outer.1 - inner_total.1));
                            outer = inner_total;
                            region = inner;
                        }
                        out.push((outer.0.max(0.0), outer.1));
                        out
                    };
                    let ring_fresnel = |k: usize, vff: DVec3| if k == 0 { Rgb::ONE } else { fresnel_of(vff) };
                    // Sutherland–Hodgman keeps each loop's orientation: a single loop (either
                    // orientation) is turned positive first.
                    let positive = |l: &Vec<DVec3>| -> Vec<Vec<DVec3>> {
                        let mut l = l.clone();
                        if spherical::solid_angle(&l) < 0.0 {
                            l.reverse();
                        }
                        vec![l]
                    };
                    // With occluders, each ring's Fresnel is the whole light's in that ring, so that
                    // a shadowed value never exceeds the unshadowed one (the mean direction of a
                    // thin ring's visible part swings with the shadow).
                    let light_rings = if single {
                        None
                    } else {
                        let l = positive(&light_loop);
                        let w = ltc_of(&l);
                        Some(rings(&l, (w.z.abs(), if w.z < 0.0 { -w } else { w })))
                    };
                    let visible_rings = match &light_rings {
                        // The light minus its part behind the occluder: ring by ring, the light's
                        // rings (just taken) minus that part's, instead of the light's again.
                        Some(lr) if cut => {
                            let mut behind = visible[1].clone();
                            behind.reverse();
                            let behind = [behind];
                            let w = ltc_of(&behind);
                            let br = rings(&behind, (w.z, w));
                            lr.iter().zip(&br).map(|(l, b)| ((l.0 - b.0).max(0.0), l.1 - b.1)).collect()
                        }
                        _ => {
                            let visible = if single { positive(&visible[0]) } else { visible.clone() };
                            rings(&visible, (v, vff))
                        }
                    };
                    for (k, &(vk, vffk)) in visible_rings.iter().enumerate() {
                        if vk == 0.0 {
                            continue;
                        }
                        let f = match light_rings.as_ref().and_then(|lr| lr.get(k)) {
                            Some(&(lv, lvff)) if lv > 0.0 => ring_fresnel(k, lvff),
                            _ => ring_fresnel(k, vffk),
                        };
                        acc.spec_fresnel += f * vk as f32;
                    }
                }
            }
        }
    }
}

/// Where a region lies with respect to the total-internal-reflection circle.
enum TirSplit {
    Inside,
    Outside,
    /// Carries the threshold `t_c` on `ωo·ωi`.
    Straddles(f64),
}

/// For a dielectric Fresnel seen from the dense side (`eta_i > eta_t`), the value `t_c` of
/// `ωo·ωi` below which reflection is total: `cos θd = √((1 + ωo·ωi)/2)` reaches the critical
/// `√(1 − (η_t/η_i)²)` at `t_c = 1 − 2 (η_t/η_i)²`.
fn tir_threshold(f: &LtcFresnel) -> Option<f64> {
    match *f {
        LtcFresnel::Dielectric { eta_i, eta_t } if eta_i > eta_t && eta_t > 0.0 => {
            let r = (eta_t / eta_i) as f64;
            Some(1.0 - 2.0 * r * r)
        }
        _ => None,
    }
}

/// The critical circle `tc` and the circles where the dielectric's Fresnel is 1/2, 1/4 and 1/8,
/// increasing (memoised per thread: one material's values are needed at every shading point).
fn fresnel_circles(f: &LtcFresnel, tc: f64) -> Vec<f64> {
    thread_local! {
        static MEMO: std::cell::RefCell<Vec<(LtcFresnel, Vec<f64>)>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    MEMO.with(|m| {
        if let Some((_, ts)) = m.borrow().iter().find(|(g, _)| g == f) {
            return ts.clone();
        }
        let mut ts = vec![tc];
        for y in [0.5, 0.25, 0.125] {
            if let Some(t) = fresnel_circle(f, y) {
                if t > ts[ts.len() - 1] + 1e-4 && t < 1.0 {
                    ts.push(t);
                }
            }
        }
        let mut m = m.borrow_mut();
        if m.len() >= 16 {
            m.clear();
        }
        m.push((*f, ts.clone()));
        ts
    })
}

/// For a dielectric seen from its dense side, the value `t` of `ωo·ωi` at which the Fresnel
/// reflectance (at the half-vector) equals `y` (between its normal-incidence value and 1),
/// by bisection on `cos θd` (F decreases with it); `None` otherwise.
fn fresnel_circle(f: &LtcFresnel, y: f32) -> Option<f64> {
    let tc = tir_threshold(f)?;
    let f_of = |c: f64| luminance(fresnel_at(f, c as f32));
    let (mut lo, mut hi) = (((1.0 + tc) / 2.0).max(0.0).sqrt(), 1.0f64);
    if !(f_of(hi) < y && f_of(lo) >= y) {
        return None;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if f_of(mid) >= y {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(2.0 * hi * hi - 1.0)
}

/// The part of `region` (oriented loops, each within an open hemisphere) inside the cap
/// `{ω : ω·axis ≥ t}` approximated by its inscribed `n`-gon: Sutherland–Hodgman against the
/// polygon's `n` great-circle half-spaces, exact in every additive integral and far cheaper
/// than a general overlay. Caps of a hemisphere or more (t ≤ 0.02: not convex enough) go
/// through [`spherical::intersection`].
fn clip_to_cap(region: &[Vec<DVec3>], axis: DVec3, t: f64, n: usize) -> Vec<Vec<DVec3>> {
    let cap = cap_loop(axis, t, n);
    if t <= 0.02 {
        return spherical::intersection(region, &[cap]);
    }
    let sign = if cap[0].cross(cap[1]).dot(axis) >= 0.0 { 1.0 } else { -1.0 };
    let planes: Vec<DVec3> = (0..n).map(|i| cap[i].cross(cap[(i + 1) % n]) * sign).collect();
    region
        .iter()
        .filter_map(|l| {
            let (c, _) = spherical::clip_to_halfspaces(l, planes.iter().copied());
            (c.len() >= 3).then_some(c)
        })
        .collect()
}

/// The circle `{ω : ω·axis = t}` as an `n`-gon of unit directions (its arcs bow slightly
/// towards `axis`; a 16-gon covers 97.5 % of the cap's area).
fn cap_loop(axis: DVec3, t: f64, n: usize) -> Vec<DVec3> {
    thread_local! {
        /// (n, cos and sin of 2πk/n): the last polygon's angles.
        static ANGLES: std::cell::RefCell<(usize, Vec<(f64, f64)>)> = const { std::cell::RefCell::new((0, Vec::new())) };
    }
    let (u, v) = spherical::orthonormal_basis(axis);
    let r = (1.0 - t * t).max(0.0).sqrt();
    ANGLES.with(|a| {
        let mut a = a.borrow_mut();
        if a.0 != n {
            let angles = (0..n)
                .map(|k| {
                    let phi = std::f64::consts::TAU * k as f64 / n as f64;
                    (phi.cos(), phi.sin())
                })
                .collect();
            *a = (n, angles);
        }
        a.1.iter().map(|&(c, s)| axis * t + (u * c + v * s) * r).collect()
    })
}

/// The area lights of one emitting mesh with one radiance.
pub(crate) struct LightGroup {
    pub(crate) mesh: usize,
    pub(crate) tris: Vec<u32>,
    /// Bounding sphere of the emitting triangles.
    pub(crate) center: DVec3,
    pub(crate) radius: f64,
    pub(crate) l: Rgb,
    pub(crate) two_sided: bool,
    shape: LightShape,
}

/// What may hide a light piece from the shading point, projected: loops each covering a
/// region of its own, and chains covering by winding number (outlines of adjacent triangles).
#[derive(Default)]
struct Occluders {
    loops: Vec<Vec<DVec3>>,
    chains: Vec<Vec<DVec3>>,
}

impl Occluders {
    fn is_empty(&self) -> bool {
        self.loops.is_empty() && self.chains.is_empty()
    }
}

/// The surface being shaded: its mesh and triangle, and `ωo` · its winding normal (with the
/// orientation of a closed mesh: negative when seen from inside).
#[derive(Clone, Copy)]
struct Receiver {
    mesh: usize,
    tri: usize,
    facing: f64,
}

/// The winding normal of the triangle `si` lies on (zero if there is none).
fn mesh_winding_normal(scene: &Scene, si: &SurfaceInteraction) -> Vec3 {
    match scene.meshes.get(si.mesh as usize) {
        Some(m) if (si.tri as usize) < m.triangle_count() => m.winding_normal(si.tri as usize),
        _ => Vec3::ZERO,
    }
}

/// Which of the light's own triangles are not occluders of the piece being shaded.
#[derive(Clone, Copy)]
enum Skip {
    /// The whole light mesh (planar or convex lights cannot shadow themselves).
    Mesh(usize),
    /// One triangle of the light mesh (the others may shadow it).
    Triangle(usize, usize),
}

/// Sums over the pieces of one light.
struct Accum {
    diffuse_ff: f64,
    spec_int: f64,
    spec_fresnel: Rgb,
}

/// The bounds of all of `mesh`'s vertices.
fn mesh_bounds(mesh: &TriangleMesh) -> Bounds3 {
    let mut b = Bounds3::EMPTY;
    for q in &mesh.positions {
        b.extend(*q);
    }
    b
}

fn mesh_extent(mesh: &TriangleMesh) -> f64 {
    let b = mesh_bounds(mesh);
    (b.max - b.min).length() as f64
}

/// A convex light seen from a point: its front faces' planes and its vertices, to prove an
/// occluder lies in front of it.
struct ConvexLight<'a> {
    /// (a point of the face, outward unit normal) of every face turned towards the point.
    front: Vec<(DVec3, DVec3)>,
    vertices: &'a [DVec3],
    center: DVec3,
}

impl<'a> ConvexLight<'a> {
    fn new(shape: &'a ConvexShape, p: DVec3) -> ConvexLight<'a> {
        let front = shape.faces.iter().copied().filter(|(a, n)| n.dot(p - *a) > shape.eps).collect();
        ConvexLight { front, vertices: &shape.vertices, center: shape.center }
    }

    /// Whether a plane separates the box `b` (with the shading point `p` on its side) from the
    /// light: then along every ray from `p` the box's content comes before the light. Tried:
    /// the planes of the front faces, and the plane normal to the centres' offset.
    fn separated_from(&self, b: &Bounds3, p: DVec3) -> bool {
        let corners: [DVec3; 8] = std::array::from_fn(|k| {
            DVec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x } as f64,
                if k & 2 == 0 { b.min.y } else { b.max.y } as f64,
                if k & 4 == 0 { b.min.z } else { b.max.z } as f64,
            )
        });
        if self.front.iter().any(|(a, n)| corners.iter().all(|c| (*c - *a).dot(*n) > 0.0)) {
            return true;
        }
        let bc = (d3(b.min) + d3(b.max)) * 0.5;
        let axis = (bc - self.center).normalize_or_zero();
        if axis == DVec3::ZERO {
            return false;
        }
        let light_max = self.vertices.iter().map(|v| v.dot(axis)).fold(f64::MIN, f64::max);
        let box_min = corners.iter().map(|c| c.dot(axis)).fold(f64::MAX, f64::min);
        box_min > light_max && p.dot(axis) > light_max
    }
}

/// Adds to `l` every light `ltc` and `ratio` do not shade analytically, at `hit`: delta lights
/// by [`delta_light`]; infinite lights, and area lights when the material has no LTC form
/// (`ltc_form` false, with one warning), by directlighting's estimator (two 2D samples each).
#[allow(clippy::too_many_arguments)]
pub(crate) fn add_other_lights(
    l: &mut Rgb,
    integrator: &str,
    hit: &SurfaceHit,
    ltc_form: bool,
    scene: &Scene,
    sampler: &mut dyn Sampler,
    stats: &mut ThreadStats,
    warned: &AtomicBool,
    warnings: &DiagSink,
) {
    let SurfaceHit { si, bsdf, .. } = hit;
    for (k, light) in scene.light_list().iter().enumerate() {
        match light {
            Light::Area(_) if ltc_form => {} // shaded analytically
            Light::Infinite(_) | Light::Area(_) => {
                if !ltc_form {
                    warn_no_ltc_form(integrator, warned, warnings);
                }
                let (u_light, u_scatter) = (sampler.get_2d(), sampler.get_2d());
                *l += estimate_direct(si, bsdf, u_scatter, k, light, u_light, scene, stats);
            }
            _ => *l += delta_light(si, bsdf, light, scene, stats),
        }
    }
}

/// The one warning `integrator` gives when the scene has infinite lights (they have no polygon).
pub(crate) fn warn_infinite_lights(integrator: &str, scene: &Scene, warnings: &DiagSink) {
    if scene.light_list().iter().any(Light::is_infinite) {
        warnings.warn(
            None,
            format!("{integrator}: infinite lights have no polygon: they are rendered with directlighting's estimator"),
        );
    }
}

/// A delta light (point, spot, distant, goniometric, projection) at `si`: exact hard shadow by one
/// ray, the real BSDF.
fn delta_light(si: &SurfaceInteraction, bsdf: &Bsdf, light: &Light, scene: &Scene, stats: &mut ThreadStats) -> Rgb {
    let ctx = LightContext { p: si.p, p_error: si.p_error, n: si.n };
    let Some(ls) = light.sample_li(&ctx, Vec2::splat(0.5), &scene.meshes) else { return Rgb::ZERO };
    let f = bsdf.f(si.wo, ls.wi, BxdfFlags::NON_SPECULAR) * ls.wi.dot(si.shading.z).abs();
    if f == Rgb::ZERO {
        return Rgb::ZERO;
    }
    stats.shadow_rays += 1;
    if scene.occluded(&si.spawn_ray_to(ls.p_light)) {
        Rgb::ZERO
    } else {
        f * ls.li / ls.pdf
    }
}

/// The one warning `integrator` gives when a material without an LTC form is rendered with
/// directlighting's estimator.
fn warn_no_ltc_form(integrator: &str, warned: &AtomicBool, warnings: &DiagSink) {
    if !warned.swap(true, Ordering::Relaxed) {
        warnings.warn(
            None,
            format!(
                "{integrator}: a material that does not reduce to a Lambertian plus a GGX lobe (mirror, glass, \
                 translucent, mix, Oren–Nayar, anisotropic…) is rendered with directlighting's estimator"
            ),
        );
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

/// A camera ray's first surface (its BSDF not built), or the radiance it escaped with
/// ([`Scene::first_point`]).
type FirstSurface = Result<SurfacePoint, Rgb>;

/// The samples of one pixel (shading `pixel`): their first surfaces and, for those with an
/// LTC material, the analytic area lighting of their cluster (`(Σ L·form factor, glossy)`).
pub(crate) struct SharedPixel {
    hits: Vec<FirstSurface>,
    area: Vec<Option<(Rgb, Rgb)>>,
}

impl SharedPixel {
    /// Traces the pixel's camera `rays` and shades each surface they see once
    /// ([`LtcShader::shade_pixel`], with or without `shadows`): `begin_pixel` of `ltc` and `ratio`.
    pub(crate) fn trace(
        shader: &LtcShader,
        rays: &[Ray],
        scene: &Scene,
        shadows: bool,
        stats: &mut ThreadStats,
    ) -> SharedPixel {
        // One traversal for the pixel's bundle of rays when it meets few triangles.
        let candidates = scene.bundle_candidates(rays);
        let mut hits: Vec<FirstSurface> = Vec::with_capacity(rays.len());
        for r in rays {
            let prev = hits.last().and_then(|h| h.as_ref().ok()).map(|h| &h.si);
            let (first, queries) = scene.first_point_among(r, candidates.as_deref(), prev);
            stats.rays += queries;
            hits.push(first);
        }
        let area = shader.shade_pixel(rays, &hits, scene, shadows);
        SharedPixel { hits, area }
    }

    /// Sample `index` of the pixel: its first surface (or the radiance its ray escaped with) and
    /// its cluster's analytic area lighting; `None` when `shared` is not a `SharedPixel` or has
    /// no such sample.
    pub(crate) fn sample(shared: &PixelShared, index: usize) -> Option<(&FirstSurface, Option<(Rgb, Rgb)>)> {
        let sh = shared.downcast_ref::<SharedPixel>()?;
        Some((sh.hits.get(index)?, sh.area.get(index).copied().flatten()))
    }
}

/// A pixel cluster whose extent exceeds this fraction of its distance to the nearest light is
/// shaded sample by sample.
const NEAR_FIELD: f64 = 0.05;

/// Samples of a pixel that see the same smooth piece of surface (its members are the samples
/// whose `cluster` entry is its index).
struct Cluster {
    mesh: u32,
    n: Vec3,
    depth: f32,
    dir_sum: Vec3,
}

impl LtcShader<'_> {
    /// Groups the pixel's hits on LTC-shaded surfaces into clusters (same mesh, shading
    /// normals within ~11°, depths within 5 %) and shades each cluster once, at the member
    /// whose ray is closest to the cluster's mean direction.
    pub(crate) fn shade_pixel(
        &self,
        rays: &[Ray],
        hits: &[FirstSurface],
        scene: &Scene,
        shadows: bool,
    ) -> Vec<Option<(Rgb, Rgb)>> {
        let mut clusters: Vec<Cluster> = Vec::new();
        // Each sample's cluster (`usize::MAX`: none, the ray escaped).
        let mut cluster = vec![usize::MAX; hits.len()];
        let dirs: Vec<Vec3> = rays.iter().map(|r| r.d.normalize_or_zero()).collect();
        for (i, h) in hits.iter().enumerate() {
            let Ok(h) = h else { continue };
            let n = h.si.shading.z;
            let depth = (h.si.p - rays[i].o).length();
            let d = dirs[i];
            match clusters.iter().position(|c| {
                c.mesh == h.si.mesh && c.n.dot(n) > 0.98 && (c.depth - depth).abs() <= 0.05 * c.depth.max(depth)
            }) {
                Some(k) => {
                    cluster[i] = k;
                    clusters[k].dir_sum += d;
                }
                None => {
                    cluster[i] = clusters.len();
                    clusters.push(Cluster { mesh: h.si.mesh, n, depth, dir_sum: d });
                }
            }
        }
        let mut area = vec![None; hits.len()];
        let mut scratch = Vec::new();
        let mut shade_one = |i: usize| -> Option<(Rgb, Rgb)> {
            let Ok(h) = &hits[i] else { return None };
            let desc = LtcShader::lobes(scene, &h.si)?;
            Some(self.area_lights_split(scene, &h.si, &desc, shadows, &mut scratch))
        };
        let dir = |i: usize| dirs[i];
        let pos = |i: usize| hits[i].as_ref().map(|h| d3(h.si.p)).unwrap_or(DVec3::ZERO);
        let cluster = &cluster[..];
        for (k, c) in clusters.iter().enumerate() {
            let members = || (0..hits.len()).filter(move |&m| cluster[m] == k);
            let mean = c.dir_sum.normalize_or_zero();
            let Some(rep) = members().max_by(|a, b| dir(*a).dot(mean).total_cmp(&dir(*b).dot(mean))) else {
                continue;
            };
            // Near field: when the cluster's extent is not small against the distance to the
            // nearest light, the lighting varies across the pixel (a light grazing the floor):
            // every member is shaded.
            let extent = members().map(|m| (pos(m) - pos(rep)).length()).fold(0.0, f64::max);
            let near = extent > NEAR_FIELD * self.nearest_light_distance(pos(rep));
            let v = shade_one(rep);
            for m in members() {
                area[m] = if m == rep || !near { v } else { shade_one(m) };
            }
        }
        area
    }
}

impl Estimator<'_> {
    /// Radiance from the first surface `hit`; `area` is its analytic area lighting when already
    /// computed for the pixel.
    fn shade(
        &self,
        hit: &SurfacePoint,
        area: Option<(Rgb, Rgb)>,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
    ) -> Rgb {
        let SurfacePoint { si, le, .. } = hit;
        let mut l = *le;
        // With the pixel's lighting integrated already, only the sample's albedo is needed.
        let lit = match area {
            Some((diffuse, specular)) => LtcShader::diffuse_albedo(scene, si).map(|kd| kd * diffuse + specular),
            None => LtcShader::lobes(scene, si)
                .map(|d| self.shader.area_lights(scene, si, &d, self.shader.ltc.shadows, &mut Vec::new())),
        };
        let ltc_form = lit.is_some();
        if let Some(v) = lit {
            l += v;
        }
        // The BSDF only for what the LTC does not shade (delta and infinite lights, materials
        // without an LTC form).
        if !ltc_form || self.other_lights {
            if let Some(hit) = hit.with_bsdf(scene) {
                add_other_lights(
                    &mut l,
                    "ltc",
                    &hit,
                    ltc_form,
                    scene,
                    sampler,
                    stats,
                    &self.warn_material,
                    self.warnings,
                );
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
        let (first, queries) = scene.first_point(ray);
        stats.rays += queries;
        match first {
            Ok(h) => self.shade(&h, None, scene, sampler, stats),
            Err(escaped) => escaped,
        }
    }

    fn shares_pixel_work(&self) -> bool {
        self.shader.ltc.pixel_shading
    }

    fn begin_pixel(&self, rays: &[Ray], scene: &Scene, stats: &mut ThreadStats) -> Option<PixelShared> {
        Some(Box::new(SharedPixel::trace(&self.shader, rays, scene, self.shader.ltc.shadows, stats)))
    }

    fn li_shared(
        &self,
        ray: &Ray,
        scene: &Scene,
        sampler: &mut dyn Sampler,
        stats: &mut ThreadStats,
        aov: &mut [f32],
        shared: &PixelShared,
        index: usize,
    ) -> Rgb {
        match SharedPixel::sample(shared, index) {
            Some((Ok(h), area)) => self.shade(h, area, scene, sampler, stats),
            Some((Err(escaped), _)) => *escaped,
            None => self.li(ray, scene, sampler, stats, aov),
        }
    }
}

impl Integrator for LtcIntegrator {
    fn name(&self) -> &str {
        "ltc"
    }
    fn requirements(&self) -> Requirements {
        Requirements {
            accel: true,
            lights: true,
            materials: true,
            min_pixel_samples: (self.pixel_shading && self.coverage_samples > 1)
                .then_some((self.coverage_samples, COVERAGE_REASON)),
            ..Default::default()
        }
    }
    fn render(&self, scene: &Scene, ctx: &RenderContext, film: &mut Film) -> Result<RenderStats, RenderError> {
        warn_infinite_lights("ltc", scene, ctx.warnings);
        let est = Estimator {
            shader: LtcShader::new(self, scene),
            warn_material: AtomicBool::new(false),
            warnings: ctx.warnings,
            other_lights: scene.light_list().iter().any(|l| !matches!(l, Light::Area(_))),
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
