//! What the shading prepares per scene (the objects, see [`super::objects`]; the area lights
//! gathered per emitting mesh with their shapes) and the analytic shading of the area lights
//! at a point, light by light.

use super::fresnel::{fresnel_weight, FresnelMode};
use super::integrate::{integrate_piece, Accum, LobeLtc, PieceFrame};
use super::objects::{object_info, ConvexShape, Objects, Receiver, Skip};
use super::occluders::{closest_on_triangle, ConvexLight, PieceQuery};
use super::region::Occluders;
use super::settings::{Glossy, Mode, ShaderSettings};
use crate::common::ltc::{Ltc, LtcCoeffs};
use crate::common::pixel_shading::{rgb_difference, Blend, ClusterExtent, Refine, SharedPixel, NEAR_FIELD};
use glam::DVec3;
use penumbra_core::accel::objects::ObjectBvh;
use penumbra_core::camera::CameraSample;
use penumbra_core::geometry::{Frame, RayDifferential};
use penumbra_core::integrator::{RenderContext, RenderStats, ThreadStats};
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::light::emitting_normal;
use penumbra_core::material::LtcDescription;
use penumbra_core::mesh::{EdgeAdjacency, TriangleMesh};
use penumbra_core::scene::{Scene, SurfacePoint};
use penumbra_core::{Rgb, Vec3};
use penumbra_parser::DiagSink;
use std::cell::OnceCell;
use std::sync::atomic::{AtomicU64, Ordering};

/// What pixel shading computes once per surface a pixel sees: the analytic area lighting
/// `(Σ L·form factor, glossy)` ([`LtcShader::area_lights_split`]).
pub type AreaLighting = (Rgb, Rgb);

/// The lights a shading point leaves to `directlighting`'s estimator because taking them
/// analytically would exceed the cost budget ([`LIGHT_TRIANGLE_BUDGET`]): bit `g` for the
/// shader's light group `g` ([`LtcShader::light_groups`]), for any number of groups (the first
/// 64 inline; the others in words allocated only when one of them is over budget).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OverBudget {
    low: u64,
    /// Groups 64.. (word `k` holds groups `64 (k + 1)…`); its last word is never 0, so that
    /// equal sets compare equal.
    more: Vec<u64>,
}

impl OverBudget {
    pub fn is_empty(&self) -> bool {
        self.low == 0 && self.more.is_empty()
    }
    /// Whether group `g` is left to the estimator.
    pub fn has(&self, g: usize) -> bool {
        match g.checked_sub(64) {
            None => self.low >> g & 1 == 1,
            Some(h) => self.more.get(h / 64).is_some_and(|w| w >> (h % 64) & 1 == 1),
        }
    }
    /// Leaves group `g` to the estimator.
    pub fn insert(&mut self, g: usize) {
        match g.checked_sub(64) {
            None => self.low |= 1 << g,
            Some(h) => {
                if self.more.len() <= h / 64 {
                    self.more.resize(h / 64 + 1, 0);
                }
                self.more[h / 64] |= 1 << (h % 64);
            }
        }
    }
}

/// [`AreaLighting`] of the lights taken analytically, and those left to the estimator.
#[derive(Clone, Debug, PartialEq)]
pub struct BudgetedLighting {
    pub lighting: AreaLighting,
    pub over: OverBudget,
}

/// Pixel shading blends a member's lighting with its cluster's only when both leave the same
/// lights to the estimator; otherwise the member takes its own (a blend would count a light
/// both analytically, in part, and by the estimator).
impl Blend for BudgetedLighting {
    fn blend(&self, other: &Self, w: f32) -> Self {
        if self.over == other.over {
            BudgetedLighting { lighting: self.lighting.blend(&other.lighting, w), over: self.over.clone() }
        } else if w <= 0.0 {
            self.clone()
        } else {
            other.clone()
        }
    }
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
    /// A `sphere` shape (its tessellation's vertices on one sphere): the true sphere pbrt-v3
    /// renders, whose silhouette from a point outside is a circle — taken as the regular polygon
    /// of the same solid angle ([`sphere_sides`]), whatever the tessellation (12 600 triangles
    /// for a default sphere, whose silhouette loop would have hundreds of edges).
    Sphere(SphereShape),
}

/// A sphere light: the sphere its mesh's vertices lie on.
struct SphereShape {
    center: DVec3,
    radius: f64,
}

/// Sides of the polygon that stands for a sphere light's silhouette circle (a regular polygon
/// of the circle's solid angle; with 32 sides its corners lie 0.32 % of the circle's radius
/// outside it, its edges' middles 0.16 % inside): 32 when the point's sharpest lobe is
/// narrower than the circle (it resolves the outline), 16 when narrower than 4 times it, 8
/// otherwise (a smooth integrand over an equal-area polygon: the difference is of fourth
/// order in the circle's radius).
fn sphere_sides(angular_radius: f64, lobe_width: f64) -> usize {
    if lobe_width < angular_radius {
        32
    } else if lobe_width < 4.0 * angular_radius {
        16
    } else {
        8
    }
}

/// The silhouette circle of the sphere (`center`, `radius`) seen from `p` as the regular
/// [`sphere_sides`]-gon of the same solid angle for a lobe `lobe_width` wide (radians), as
/// world points at the tangent distance (so that their bounding sphere bounds the circle);
/// `None` when `p` is inside the sphere.
fn sphere_outline(p: DVec3, center: DVec3, radius: f64, lobe_width: f64) -> Option<Vec<DVec3>> {
    let axis = center - p;
    let d = axis.length();
    if !(d > radius * (1.0 + 1e-9)) {
        return None;
    }
    let axis = axis / d;
    let sin_rho = radius / d;
    let cos_rho = (1.0 - sin_rho * sin_rho).max(0.0).sqrt();
    let sides = sphere_sides(sin_rho.asin(), lobe_width);
    // A regular spherical n-gon of circumradius ρ' has solid angle 2π + 2nB − nπ with
    // cot B = cos ρ' tan(π/n): ρ' for the cap's 2π(1 − cos ρ).
    let n = sides as f64;
    let omega = std::f64::consts::TAU * (1.0 - cos_rho);
    let b = (omega - std::f64::consts::TAU + n * std::f64::consts::PI) / (2.0 * n);
    let cos_r = (1.0 / b.tan() / (std::f64::consts::PI / n).tan()).clamp(-1.0, 1.0);
    let sin_r = (1.0 - cos_r * cos_r).max(0.0).sqrt();
    let (u, v) = crate::common::spherical_polygon::orthonormal_basis(axis);
    let tangent = (d * d - radius * radius).max(0.0).sqrt();
    Some(
        (0..sides)
            .map(|k| {
                let phi = std::f64::consts::TAU * k as f64 / n;
                p + (axis * cos_r + (u * phi.cos() + v * phi.sin()) * sin_r) * tangent
            })
            .collect(),
    )
}

/// The sphere through all of `vertices` (the centre of their bounding box and the largest
/// distance from it, all distances within 1e-5 of it plus the `f32` positions' rounding at their
/// distance from the origin), if there is one. (Without the rounding term a small sphere away
/// from the origin failed the test — r 0.033 at (−3, 1.2, −2.2): its vertices' f32 rounding,
/// 2.4e-7, is 7e-6 of its radius — and was taken as a convex mesh of 12 600 triangles, whose
/// silhouette sent points of issue 42's MIS plates to the cost budget's fallback.)
fn on_one_sphere(vertices: &[DVec3]) -> Option<(DVec3, f64)> {
    let (lo, hi) = vertices
        .iter()
        .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let center = (lo + hi) * 0.5;
    let (near, far) =
        vertices.iter().map(|v| (*v - center).length()).fold((f64::INFINITY, 0.0f64), |(a, b), r| (a.min(r), b.max(r)));
    let rounding = 4.0 * f64::from(f32::EPSILON) * (center.abs().max_element() + far);
    (far > 0.0 && near >= far * (1.0 - 1e-5) - rounding).then_some((center, far))
}

/// Whether `mesh` is part of the surface of a convex body, wound outwards, with a boundary (a
/// cylinder without caps, a partial sphere or cylinder): every edge of one or two consistently
/// wound triangles, some of one, and every vertex behind (within `rel_tol` of the mesh's extent)
/// the winding plane of every face. Seen from a point, its faces turned towards the point are
/// then what the point sees of it, none hiding another (a ray enters the convex body once, through
/// a face turned towards its origin), so their outline — silhouette edges plus the boundary edges
/// of those faces ([`SilhouetteMesh::loops`](crate::common::spherical_polygon::SilhouetteMesh::loops))
/// — bounds exactly the directions in which the light is seen, as a closed convex light's
/// silhouette does. Refused (false) above 10⁸ plane–vertex tests.
fn is_open_convex(mesh: &TriangleMesh, adj: &EdgeAdjacency, rel_tol: f64) -> bool {
    let manifold = adj.edges.iter().all(|e| e.count == 1 || (e.count == 2 && e.consistent));
    if adj.edges.is_empty() || !manifold || !adj.edges.iter().any(|e| e.count == 1) {
        return false;
    }
    let mut verts = vec![DVec3::ZERO; adj.welded_count];
    for (i, w) in adj.weld.iter().enumerate() {
        if let (Some(slot), Some(q)) = (verts.get_mut(*w as usize), mesh.positions.get(i)) {
            *slot = d3(*q);
        }
    }
    let planes: Vec<(DVec3, DVec3)> = (0..mesh.triangle_count())
        .filter_map(|t| {
            let [a, b, c] = mesh.vertices(t).map(d3);
            let n = (b - a).cross(c - a).normalize_or_zero();
            (n != DVec3::ZERO).then_some((a, n))
        })
        .collect();
    if planes.is_empty() || (planes.len() as u64) * (verts.len() as u64) > 100_000_000 {
        return false;
    }
    let tol = rel_tol * mesh.extent();
    tol.is_finite() && planes.iter().all(|(a, n)| verts.iter().all(|v| n.dot(*v - *a) <= tol))
}

impl LightShape {
    /// `sphere`: the mesh is a `sphere` shape's tessellation.
    fn of(mesh: &TriangleMesh, adj: &EdgeAdjacency, tris: &[u32], two_sided: bool, sphere: bool) -> LightShape {
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
        if let Some(s) = Self::planar(mesh, adj, two_sided) {
            return s;
        }
        if two_sided {
            return LightShape::Triangles;
        }
        let closed = mesh.is_closed_convex_with(adj, 1e-5);
        if closed || is_open_convex(mesh, adj, 1e-5) {
            // Outward winding is proven; the emitting side must agree on every face.
            let outward = (0..n).all(|t| {
                let w = mesh.winding_normal(t);
                w == Vec3::ZERO || emitting_normal(mesh, t).dot(w) > 0.0
            });
            if outward {
                let vertices: Vec<DVec3> = mesh.positions.iter().map(|v| d3(*v)).collect();
                return match (sphere && closed).then(|| on_one_sphere(&vertices)).flatten() {
                    Some((center, radius)) => LightShape::Sphere(SphereShape { center, radius }),
                    None => LightShape::Convex(ConvexShape::new(mesh, adj)),
                };
            }
        }
        LightShape::Triangles
    }

    /// A planar mesh's outline ([`TriangleMesh::planar_outline`]) when, one-sided, every
    /// triangle emits to the side of the largest one.
    fn planar(mesh: &TriangleMesh, adj: &EdgeAdjacency, two_sided: bool) -> Option<LightShape> {
        let po = mesh.planar_outline(adj)?;
        // One emitting side for all (a one-sided light); winding consistent with it.
        let normal = if two_sided { po.normal } else { d3(emitting_normal(mesh, po.largest)).normalize_or_zero() };
        if !two_sided {
            for t in 0..mesh.triangle_count() {
                let [p0, p1, p2] = mesh.vertices(t).map(d3);
                if (p1 - p0).cross(p2 - p0).length() != 0.0 && d3(emitting_normal(mesh, t)).dot(normal) <= 0.0 {
                    return None;
                }
            }
        }
        Some(LightShape::Planar { outline: po.outline, normal, origin: po.origin })
    }
}

/// The area lights of one emitting mesh with one radiance.
pub struct LightGroup {
    pub mesh: usize,
    /// How warnings name it: its shape and where it was declared.
    pub label: String,
    pub tris: Vec<u32>,
    /// Bounding sphere of the emitting triangles (centred on their vertices' mean).
    pub center: DVec3,
    pub radius: f64,
    pub l: Rgb,
    pub two_sided: bool,
    shape: LightShape,
}

/// The winding normal of the triangle `si` lies on (zero if there is none).
fn mesh_winding_normal(scene: &Scene, si: &SurfaceInteraction) -> Vec3 {
    match scene.meshes.get(si.mesh as usize) {
        Some(m) if (si.tri as usize) < m.triangle_count() => m.winding_normal(si.tri as usize),
        _ => Vec3::ZERO,
    }
}

fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

/// The analytic area-light shading of `ltc` and `ratio` (see the module doc).
pub struct LtcShader {
    pub settings: ShaderSettings,
    objects: Objects,
    /// The area lights, gathered per emitting mesh (pbrt-v3 makes one light per triangle).
    groups: Vec<LightGroup>,
    counters: ShaderCounters,
    /// The integrator's name, for warnings (`ltc` or `ratio`).
    name: &'static str,
    /// For each of the scene's lights ([`Scene::light_list`]), its group (area lights).
    light_group: Vec<Option<usize>>,
    /// The cost bound applies without shadows too ([`Self::with_unshadowed_budget`]: `ratio`,
    /// whose unshadowed `U` of a light of no simple shape is otherwise integrated triangle by
    /// triangle, however many triangles face the point).
    budget_unshadowed: bool,
}

/// What the shader counts over a render (for `stats.json`).
#[derive(Default)]
struct ShaderCounters {
    /// Shading points integrated analytically.
    points: AtomicU64,
    /// Evaluations of a glossy lobe by the exact integration's quadrature.
    quadrature_evals: AtomicU64,
    /// Quadrature triangles split for accuracy.
    quadrature_splits: AtomicU64,
    /// Points whose material's lobes the table does not reach (`"glossy" "ltc"`): shaded by
    /// `directlighting`'s estimator.
    beyond_table: AtomicU64,
    /// (point, light) pairs taken whole: a planar outline, a convex silhouette, a sphere's cap.
    whole_lights: AtomicU64,
    /// (point, light) pairs taken triangle by triangle, by why: the light's shape has no
    /// outline, a convex light's silhouette is not one loop, an occluder is not separated from
    /// a convex or sphere light.
    by_triangles_shape: AtomicU64,
    by_triangles_loops: AtomicU64,
    by_triangles_occluder: AtomicU64,
    /// Light triangles integrated one by one.
    light_triangles: AtomicU64,
    /// (point, light) pairs over the cost budget ([`LIGHT_TRIANGLE_BUDGET`]), the light left to
    /// `directlighting`'s estimator, by the light's shape: convex, sphere, no simple shape.
    over_budget_convex: AtomicU64,
    over_budget_sphere: AtomicU64,
    over_budget_triangles: AtomicU64,
    /// The same per light group (for the warning that names them).
    over_budget_groups: Vec<AtomicU64>,
}

/// The cost bound of a shading point: a light whose whole outline cannot be used (an occluder
/// reaches into a sphere light, a convex light's silhouette is not one loop, a light mesh of no
/// simple shape) is integrated triangle by triangle, each with its own occluder search and
/// clipping; when more than this many of its triangles face the point with shadows on, the
/// point is shaded by `directlighting`'s estimator instead (issue 42: a tessellated sphere
/// light, 12 600 triangles, took each point hundreds of occluder searches — hours for an image
/// `directlighting` renders in a minute). 256 triangles, each an occluder search plus a
/// clipped integration, cost about as much as directlighting's estimator at a few hundred
/// samples; a quad, a box or a low-poly light stays analytic.
pub const LIGHT_TRIANGLE_BUDGET: usize = 256;

/// A glossy lobe narrower than this many times a pixel cluster's angular extent (its camera
/// rays' spread) is shaded at every member (partly from twice as wide, [`Refine::ramps`]): the
/// highlight (a sharp reflection of the light's outline) moves across the pixel by about that
/// angle, while the lobe is `~2α` wide.
const SHARP_EVERY: f32 = 0.5;
/// … and narrower than this many times (partly from twice as wide), at every member as far as
/// the cluster's shading points differ ([`crate::common::pixel_shading::REFINE`]).
const SHARP_COMPARE: f32 = 8.0;

/// A shading point's query: where it is and whether occluders are searched.
struct PointQuery<'s> {
    at: PieceFrame,
    receiver: Receiver,
    shadows: bool,
    scratch: &'s mut Vec<usize>,
    /// The lights that would exceed [`LIGHT_TRIANGLE_BUDGET`]: left to the estimator.
    over: OverBudget,
}

impl LtcShader {
    /// Prepares the per-object data `settings` needs on `scene` (silhouette adjacency only for
    /// the objects its mode takes as silhouettes).
    pub fn new(settings: ShaderSettings, scene: &Scene, name: &'static str) -> LtcShader {
        let cells: Vec<OnceCell<EdgeAdjacency>> = scene.meshes.iter().map(|_| OnceCell::new()).collect();
        // The scene's (built once when the integrator asks: `ltc` does); `ratio` asks for none
        // and builds only its light meshes' here.
        let adjacency = |i: usize| match scene.adjacency(i) {
            Some(a) => a,
            None => cells[i].get_or_init(|| scene.meshes[i].build_adjacency()),
        };
        let mut objects = Vec::with_capacity(scene.meshes.len());
        let mut boxes = Vec::new();
        for (i, mesh) in scene.meshes.iter().enumerate() {
            let occluder = scene.objects.get(i).is_none_or(|o| o.occluder);
            let info = object_info(&settings, mesh, occluder, || adjacency(i));
            if occluder && mesh.triangle_count() > 0 {
                boxes.push((i, info.bounds));
            }
            objects.push(info);
        }
        let mut groups = gather_lights(scene);
        for g in &mut groups {
            let mesh = &scene.meshes[g.mesh];
            // The paper's per-triangle method (its Sect. 4.4) takes every triangle of every
            // light, as of every occluder, on its own.
            g.shape = match settings.mode {
                Mode::PerTriangle => LightShape::Triangles,
                _ => {
                    let sphere = scene.objects.get(g.mesh).is_some_and(|o| o.kind == "sphere");
                    LightShape::of(mesh, adjacency(g.mesh), &g.tris, g.two_sided, sphere)
                }
            };
        }
        let objects =
            Objects { info: objects, bvh: ObjectBvh::build(&boxes), merge_occluders: settings.merge_occluders };
        let counters = ShaderCounters {
            over_budget_groups: groups.iter().map(|_| AtomicU64::new(0)).collect(),
            ..ShaderCounters::default()
        };
        let light_group = scene
            .light_list()
            .iter()
            .map(|l| {
                l.area().and_then(|a| {
                    groups.iter().position(|g| g.mesh == a.mesh as usize && g.l == a.l && g.two_sided == a.two_sided)
                })
            })
            .collect();
        LtcShader { settings, objects, groups, counters, name, light_group, budget_unshadowed: false }
    }

    /// The cost bound ([`LIGHT_TRIANGLE_BUDGET`]) also without shadows: a light that would be
    /// integrated triangle by triangle with more than the budget's triangles facing the point is
    /// left to the caller's estimator there (`ratio`: its stochastic shadowed estimate of that
    /// light, added as is).
    pub fn with_unshadowed_budget(mut self) -> LtcShader {
        self.budget_unshadowed = true;
        self
    }

    /// Traces a pixel's camera `rays` and shades each surface they see once (with or without
    /// `shadows`): its analytic lighting and the lights it leaves to the estimator (the
    /// `begin_pixel` of `ltc` and `ratio`).
    pub fn trace_pixel_budgeted(
        &self,
        rays: &[RayDifferential],
        samples: &[CameraSample],
        scene: &Scene,
        shadows: bool,
        stats: &mut ThreadStats,
    ) -> SharedPixel<BudgetedLighting> {
        let mut scratch = Vec::new();
        SharedPixel::trace(
            rays,
            samples,
            scene,
            stats,
            |p, extent| self.refine(scene, p, extent),
            Some(|a: &BudgetedLighting, b: &BudgetedLighting| {
                if a.over != b.over {
                    return f32::INFINITY; // different lights left to the estimator
                }
                let (a, b) = (a.lighting, b.lighting);
                rgb_difference(a.0, b.0).max(rgb_difference(a.1, b.1))
            }),
            |h, _| {
                let desc = self.lobes(scene, &h.si)?;
                Some(self.area_lights_budgeted(scene, &h.si, &desc, shadows, &mut scratch))
            },
        )
    }

    /// How finely pixel shading shades a cluster at `p` ([`Refine::ramps`]): every member near
    /// a light (the cluster's extent at [`NEAR_FIELD`] of its distance) or for a lobe far
    /// sharper than the cluster's angle ([`SHARP_EVERY`]); its shading points compared for
    /// a sharp one ([`SHARP_COMPARE`]); at its shading points alone otherwise.
    fn refine(&self, scene: &Scene, p: &SurfacePoint, extent: ClusterExtent) -> Refine {
        let near = if extent.world > 0.0 {
            extent.world / (NEAR_FIELD * self.nearest_light_distance(p.si.p.as_dvec3()))
        } else {
            0.0
        };
        let alpha = scene
            .material_of(&p.si)
            .and_then(|(m, materials, tx)| m.ltc_lobes(&p.si, materials, tx))
            .and_then(|d| d.lobes.iter().filter_map(|l| l.ggx_alpha()).reduce(f32::min));
        // How many times sharper than the thresholds the lobe is (0 without a glossy lobe).
        let sharp = |k: f32| match alpha {
            Some(a) if extent.angle > 0.0 => f64::from(k * extent.angle as f32 / a),
            _ => 0.0,
        };
        let r = Refine::ramps(sharp(SHARP_EVERY), sharp(SHARP_COMPARE));
        Refine { every: r.every.max(Refine::ramps(near, 0.0).every), compare: r.compare }
    }

    /// After the render: the counters into `stats`, and the warnings they call for.
    pub fn finish(&self, stats: &mut RenderStats, warnings: &DiagSink) {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let c = &self.counters;
        for (k, v) in [
            ("ltc_points", get(&c.points)),
            ("ltc_quadrature_evals", get(&c.quadrature_evals)),
            ("ltc_quadrature_splits", get(&c.quadrature_splits)),
            ("ltc_beyond_table_points", get(&c.beyond_table)),
            ("ltc_whole_lights", get(&c.whole_lights)),
            ("ltc_by_triangles_shape", get(&c.by_triangles_shape)),
            ("ltc_by_triangles_loops", get(&c.by_triangles_loops)),
            ("ltc_by_triangles_occluder", get(&c.by_triangles_occluder)),
            ("ltc_light_triangles", get(&c.light_triangles)),
            ("ltc_over_budget_lights_convex", get(&c.over_budget_convex)),
            ("ltc_over_budget_lights_sphere", get(&c.over_budget_sphere)),
            ("ltc_over_budget_lights_triangles", get(&c.over_budget_triangles)),
        ] {
            stats.counters.insert(k.into(), v as f64);
        }
        let lights: Vec<String> = self
            .groups
            .iter()
            .zip(&c.over_budget_groups)
            .filter(|(_, n)| get(n) > 0)
            .map(|(g, n)| format!("{} ({} points)", g.label, get(n)))
            .collect();
        if !lights.is_empty() {
            warnings.warn(
                None,
                format!(
                    "{}: {} (shading point, light) pairs would have taken the light triangle by triangle with \
                     more than {LIGHT_TRIANGLE_BUDGET} of its triangles facing the point (an occluder inside a \
                     sphere light or a convex light's box, a light mesh of no simple shape): directlighting's \
                     estimator shaded those lights there, to bound the cost; lights: {}",
                    self.name,
                    c.over_budget_groups.iter().map(get).sum::<u64>(),
                    lights.join(", ")
                ),
            );
        }
        if let Some(s) = self.live_status() {
            warnings.set_status(s);
        }
        let beyond = get(&c.beyond_table);
        if beyond > 0 {
            let alpha_max = Ltc::ggx().map_or(0.0, |t| t.alpha_max);
            warnings.warn(
                None,
                format!(
                    "{}: \"glossy\" \"ltc\": {beyond} shading points have a lobe rougher than the LTC table \
                     reaches (alpha > {alpha_max}): directlighting's estimator shaded them (\"glossy\" \"exact\" \
                     is exact there)",
                    self.name
                ),
            );
        }
    }

    /// The render's status line so far ([`DiagSink::set_status`]: the progress bar's message and
    /// the summary's last line): how many (point, light) pairs the cost bound left to the
    /// estimator, against the points shaded; `None` while there are none, so that a user can
    /// tell a render in the fallback path from one that is not (issue 42).
    pub fn live_status(&self) -> Option<String> {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let c = &self.counters;
        let pairs: u64 = c.over_budget_groups.iter().map(get).sum();
        if pairs == 0 {
            return None;
        }
        let points = get(&c.points).max(1);
        Some(format!(
            "{}: cost bound: {pairs} (point, light) pairs ({:.1} % of {points} points) by the estimator",
            self.name,
            100.0 * pairs as f64 / points as f64
        ))
    }

    /// Runs `render` with `ctx`'s progress reports preceded by [`Self::live_status`] into
    /// `ctx.warnings` (the command line's progress bar shows it beside the tiles done).
    pub fn with_live_status<R>(&self, ctx: &RenderContext, render: impl FnOnce(&RenderContext) -> R) -> R {
        let report = |done: u64, total: u64| {
            if let Some(s) = self.live_status() {
                ctx.warnings.set_status(s);
            }
            if let Some(p) = ctx.progress {
                p(done, total);
            }
        };
        let inner =
            RenderContext { threads: ctx.threads, cancel: ctx.cancel, progress: Some(&report), warnings: ctx.warnings };
        render(&inner)
    }

    /// Zeroes the counters (a shader prepared with the scene is reused by each of its renders,
    /// one after another: each reports its own counts).
    pub fn reset_counters(&self) {
        let c = &self.counters;
        for a in [
            &c.points,
            &c.quadrature_evals,
            &c.quadrature_splits,
            &c.beyond_table,
            &c.whole_lights,
            &c.by_triangles_shape,
            &c.by_triangles_loops,
            &c.by_triangles_occluder,
            &c.light_triangles,
            &c.over_budget_convex,
            &c.over_budget_sphere,
            &c.over_budget_triangles,
        ]
        .into_iter()
        .chain(&c.over_budget_groups)
        {
            a.store(0, Ordering::Relaxed);
        }
    }

    /// How group `g` is taken at a shading point, and why points may take its slow path
    /// (triangle by triangle, or `directlighting`'s estimator over [`LIGHT_TRIANGLE_BUDGET`]
    /// facing triangles), if they may: predicted from the light's shape and the occluders' boxes.
    pub fn light_plan(&self, scene: &Scene, g: &LightGroup) -> (String, Option<String>) {
        let n = g.tris.len();
        let shadows = self.settings.shadows;
        // Whether the cost bound applies to a light taken triangle by triangle.
        let budgeted = shadows || self.budget_unshadowed;
        // An occluder with a triangle inside the light's bounding sphere: it may reach into a
        // sphere light or fail a convex light's separation tests.
        let (c, r) = match &g.shape {
            LightShape::Sphere(sp) => (sp.center, sp.radius),
            _ => (g.center, g.radius),
        };
        let reaching = || {
            self.objects.info.iter().enumerate().find(|(o, info)| {
                let near = c.clamp(info.bounds.min.as_dvec3(), info.bounds.max.as_dvec3());
                *o != g.mesh
                    && info.occluder
                    && (near - c).length_squared() < r * r
                    && scene.meshes.get(*o).is_some_and(|m| {
                        (0..m.triangle_count())
                            .any(|t| (closest_on_triangle(c, m.vertices(t).map(d3)) - c).length_squared() < r * r)
                    })
            })
        };
        let beyond = if n > LIGHT_TRIANGLE_BUDGET {
            format!("by directlighting's estimator where more than {LIGHT_TRIANGLE_BUDGET} of its {n} triangles face the point")
        } else {
            format!("triangle by triangle ({n} triangles)")
        };
        let whole = |what: &str| -> (String, Option<String>) {
            let why = shadows.then(reaching).flatten().map(|(o, _)| {
                let o = match scene.objects.get(o) {
                    Some(o) => format!("shape \"{}\" at {}", o.kind, o.loc),
                    None => format!("mesh {o}"),
                };
                format!(
                    "where {o}, which reaches into the light's bounding sphere, is not proven in front of it: {beyond}"
                )
            });
            (what.to_string(), why)
        };
        match &g.shape {
            LightShape::Planar { outline, .. } => (format!("planar outline ({} corners)", outline.len()), None),
            LightShape::Sphere(_) => whole("sphere: its silhouette circle as one polygon"),
            LightShape::Convex(_) => whole("convex: its outline (silhouette and boundary) as one polygon"),
            LightShape::Triangles if self.settings.mode == Mode::PerTriangle => (
                "triangle by triangle (mode per-triangle)".into(),
                (budgeted && n > LIGHT_TRIANGLE_BUDGET).then_some(beyond),
            ),
            LightShape::Triangles => (
                "no simple shape: triangle by triangle".into(),
                (budgeted && n > LIGHT_TRIANGLE_BUDGET).then_some(beyond),
            ),
        }
    }

    /// One line per area light for `penumbra info` and the render's start: how it is taken, and
    /// when it takes the slow path.
    pub fn light_report(&self, scene: &Scene) -> Vec<String> {
        self.groups
            .iter()
            .map(|g| {
                let (how, slow) = self.light_plan(scene, g);
                match slow {
                    Some(why) => format!("light {}: {how}; slow path {why}", g.label),
                    None => format!("light {}: {how}", g.label),
                }
            })
            .collect()
    }

    /// Warns, once per light, about the lights whose slow path [`Self::light_plan`] predicts.
    pub fn warn_slow_lights(&self, scene: &Scene, warnings: &DiagSink) {
        for g in &self.groups {
            if let (how, Some(why)) = self.light_plan(scene, g) {
                warnings.warn(None, format!("{}: light {} ({how}) may take the slow path {why}", self.name, g.label));
            }
        }
    }

    /// The area lights, one per emitting mesh and radiance.
    pub fn light_groups(&self) -> &[LightGroup] {
        &self.groups
    }

    /// Distance from `p` to the nearest area light's bounding sphere (0 inside one; infinite
    /// without area lights).
    pub fn nearest_light_distance(&self, p: DVec3) -> f64 {
        self.groups.iter().map(|g| ((p - g.center).length() - g.radius).max(0.0)).fold(f64::INFINITY, f64::min)
    }

    /// The LTC description of the material at `si` (`None`: no LTC form, or no material, or —
    /// with `"glossy" "ltc"`, which has no exact fallback of its own — a lobe rougher than the
    /// table reaches: then `directlighting`'s estimator shades the point, counted).
    pub fn lobes(&self, scene: &Scene, si: &SurfaceInteraction) -> Option<LtcDescription> {
        let (m, materials, tx) = scene.material_of(si)?;
        let d = m.ltc_lobes(si, materials, tx)?;
        if self.settings.glossy == Glossy::Ltc && d.lobes.iter().any(|l| l.ggx_alpha().is_some_and(|a| !Ltc::covers(a)))
        {
            self.counters.beyond_table.fetch_add(1, Ordering::Relaxed);
            return None;
        }
        Some(d)
    }

    /// The diffuse albedo of [`Self::lobes`] (`None` when the material has no LTC form).
    pub fn diffuse_albedo(scene: &Scene, si: &SurfaceInteraction) -> Option<Rgb> {
        let (m, materials, tx) = scene.material_of(si)?;
        m.ltc_diffuse(si, materials, tx)
    }

    /// Analytic radiance reflected towards `si.wo` from the area lights within the cost budget
    /// ([`LIGHT_TRIANGLE_BUDGET`]; with shadows, or without after
    /// [`Self::with_unshadowed_budget`]), with analytic visibility when `shadows`, as the light
    /// reaching the Lambertian lobe (to be multiplied by the albedo: `Σ L · form factor`) and the
    /// glossy lobe's radiance; and the lights over the budget, which the caller shades with its
    /// estimator ([`Self::light_group_of`]).
    pub fn area_lights_budgeted(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        desc: &LtcDescription,
        shadows: bool,
        scratch: &mut Vec<usize>,
    ) -> BudgetedLighting {
        let (mut d, mut s) = (Rgb::ZERO, Rgb::ZERO);
        let facing = mesh_winding_normal(scene, si).dot(si.wo) as f64;
        let receiver = Receiver { mesh: si.mesh as usize, tri: si.tri as usize, facing };
        let Some(at) = piece_frame(si, desc) else {
            return BudgetedLighting { lighting: (d, s), over: OverBudget::default() };
        };
        let mut q = PointQuery { at, receiver, shadows, scratch, over: OverBudget::default() };
        self.counters.points.fetch_add(1, Ordering::Relaxed);
        for (gi, g) in self.groups.iter().enumerate() {
            if scene.meshes.get(g.mesh).is_none() {
                continue;
            }
            let (gd, gs) = self.area_group(scene, &mut q, gi, g);
            d += gd;
            s += gs;
        }
        BudgetedLighting { lighting: (d, s), over: q.over }
    }

    /// The counter of (point, light) pairs over budget for `g`'s shape.
    fn over_budget_counter(&self, g: &LightGroup) -> &AtomicU64 {
        let c = &self.counters;
        match g.shape {
            LightShape::Sphere(_) => &c.over_budget_sphere,
            LightShape::Convex(_) | LightShape::Planar { .. } => &c.over_budget_convex,
            LightShape::Triangles => &c.over_budget_triangles,
        }
    }

    /// The light group of the scene's light `k` ([`Scene::light_list`]), if it is an area light
    /// the shader takes: bit `g` of [`OverBudget`] says whether a point left it to the estimator.
    pub fn light_group_of(&self, k: usize) -> Option<usize> {
        self.light_group.get(k).copied().flatten()
    }

    /// The same for the lights of one mesh (group `gi`).
    fn area_group(&self, scene: &Scene, q: &mut PointQuery, gi: usize, geom: &LightGroup) -> (Rgb, Rgb) {
        let mut acc = Accum::default();
        let c = &self.counters;
        let by_triangles = match &geom.shape {
            LightShape::Triangles => Some(&c.by_triangles_shape),
            LightShape::Planar { outline, normal, origin } => {
                self.planar_light(scene, q, geom, (outline.as_slice(), *normal, *origin), &mut acc);
                None
            }
            LightShape::Convex(shape) => {
                let sil = shape.sil.loops(q.at.p, shape.eps);
                match sil.as_slice() {
                    [] => None, // p inside (or edge-on everywhere): no face emits towards it
                    [outline] => {
                        let p = q.at.p;
                        let cl = || ConvexLight::new(shape, p);
                        (!self.convex_light(scene, q, geom, cl, outline, &mut acc)).then_some(&c.by_triangles_occluder)
                    }
                    _ => Some(&c.by_triangles_loops),
                }
            }
            LightShape::Sphere(s) => match sphere_outline(q.at.p, s.center, s.radius, q.at.lobe_width()) {
                None => None, // inside the sphere
                Some(outline) => {
                    (!self.sphere_light(scene, q, geom, s, &outline, &mut acc)).then_some(&c.by_triangles_occluder)
                }
            },
        };
        match by_triangles {
            Some(_)
                if (q.shadows || self.budget_unshadowed)
                    && facing_triangles(scene, q.at.p, geom) > LIGHT_TRIANGLE_BUDGET =>
            {
                q.over.insert(gi);
                self.counters.over_budget_groups[gi].fetch_add(1, Ordering::Relaxed);
                self.over_budget_counter(geom).fetch_add(1, Ordering::Relaxed);
                return (Rgb::ZERO, Rgb::ZERO);
            }
            Some(counter) => {
                counter.fetch_add(1, Ordering::Relaxed);
                self.light_triangles(scene, q, geom, &mut acc);
            }
            None => {
                c.whole_lights.fetch_add(1, Ordering::Relaxed);
            }
        }
        let le = geom.l;
        let diffuse = le * acc.diffuse_ff.max(0.0) as f32;
        let mut out = Rgb::ZERO;
        for (k, lc) in q.at.lobes.iter().enumerate() {
            let term = match (self.settings.glossy, self.settings.fresnel) {
                (Glossy::Exact, _) => acc.exact[k].as_vec3().max(Rgb::ZERO),
                (Glossy::Ltc, FresnelMode::Schlick) => {
                    let c = &lc.coeffs;
                    lc.lobe.ltc_scale()
                        * fresnel_weight(&lc.lobe.fresnel(), c.magnitude, c.fresnel)
                        * acc.spec_int[k].max(0.0) as f32
                }
                (Glossy::Ltc, FresnelMode::Average) => {
                    lc.lobe.ltc_scale() * (acc.spec_fresnel[k] * lc.coeffs.magnitude).max(Rgb::ZERO)
                }
            };
            out += term * le;
        }
        let st = &acc.quadrature;
        if st.evals > 0 {
            self.counters.quadrature_evals.fetch_add(st.evals, Ordering::Relaxed);
            self.counters.quadrature_splits.fetch_add(st.splits, Ordering::Relaxed);
        }
        (diffuse, out)
    }

    /// A planar light's outline as one piece (nothing when the point is in its plane or
    /// behind a one-sided light).
    fn planar_light(
        &self,
        scene: &Scene,
        q: &mut PointQuery,
        geom: &LightGroup,
        (outline, normal, origin): (&[DVec3], DVec3, DVec3),
        acc: &mut Accum,
    ) {
        let p = q.at.p;
        let h = normal.dot(p - origin);
        // A planar light does not light its own surface, nor a point in its plane (which
        // rounding puts on either side: the light's own top face read as lit by it, 56 where
        // directlighting has 0, and differently for the scene scaled or turned). The
        // tolerance is relative, as the occluders' coplanarity test.
        let extent = outline.iter().map(|v| (*v - origin).length()).fold(0.0, f64::max);
        let in_plane = q.receiver.mesh == geom.mesh || h.abs() <= 1e-6 * (extent + (p - origin).length());
        if !in_plane && (geom.two_sided || h > 0.0) {
            let ln = if h > 0.0 { normal } else { -normal };
            let occ = if q.shadows {
                let pq = PieceQuery {
                    p,
                    skip: Skip::Mesh(geom.mesh),
                    piece: outline,
                    plane: Some((origin, ln)),
                    separate: None,
                    ball: None,
                    receiver: q.receiver,
                };
                self.objects.occluders(scene, &pq, q.scratch)
            } else {
                Some(Occluders::default())
            };
            integrate_piece(&self.settings, &q.at, outline, occ.unwrap_or_default(), acc);
        }
    }

    /// A convex light's silhouette `outline` (world points) as one piece; false when an
    /// occluder is not wholly in front of it (then it is taken triangle by triangle). `light`
    /// makes what the occluders' separation tests need of it.
    fn convex_light<'s>(
        &self,
        scene: &Scene,
        q: &mut PointQuery,
        geom: &LightGroup,
        light: impl FnOnce() -> ConvexLight<'s>,
        outline: &[DVec3],
        acc: &mut Accum,
    ) -> bool {
        let p = q.at.p;
        let occ = if q.shadows {
            let cl = light();
            let pq = PieceQuery {
                p,
                skip: Skip::Mesh(geom.mesh),
                piece: outline,
                plane: None,
                separate: Some(&cl),
                ball: None,
                receiver: q.receiver,
            };
            self.objects.occluders(scene, &pq, q.scratch)
        } else {
            Some(Occluders::default())
        };
        self.integrate_if_found(q, outline, occ, acc)
    }

    /// Integrates `outline` against its occluders when they were found (`false` otherwise: the
    /// caller takes the light triangle by triangle).
    fn integrate_if_found(&self, q: &PointQuery, outline: &[DVec3], occ: Option<Occluders>, acc: &mut Accum) -> bool {
        match occ {
            Some(occ) => {
                integrate_piece(&self.settings, &q.at, outline, occ, acc);
                true
            }
            None => false,
        }
    }

    /// A sphere light's cap `outline` as one piece, its occluders clipped to the silhouette
    /// circle's plane (exact: see [`Objects::enters_ball`]); false when an occluder reaches into
    /// the sphere (then it is taken triangle by triangle).
    fn sphere_light(
        &self,
        scene: &Scene,
        q: &mut PointQuery,
        geom: &LightGroup,
        s: &SphereShape,
        outline: &[DVec3],
        acc: &mut Accum,
    ) -> bool {
        let p = q.at.p;
        let occ = if q.shadows {
            let axis = s.center - p;
            let d = axis.length();
            let axis = axis / d;
            // The silhouette circle's plane: at d − r²/d from p along the axis; normal towards p.
            let plane = (p + axis * (d - s.radius * s.radius / d), -axis);
            let pq = PieceQuery {
                p,
                skip: Skip::Mesh(geom.mesh),
                piece: outline,
                plane: Some(plane),
                separate: None,
                ball: Some((s.center, s.radius)),
                receiver: q.receiver,
            };
            self.objects.occluders(scene, &pq, q.scratch)
        } else {
            Some(Occluders::default())
        };
        self.integrate_if_found(q, outline, occ, acc)
    }

    /// The light's triangles one by one (those of a one-sided light facing the point).
    fn light_triangles(&self, scene: &Scene, q: &mut PointQuery, geom: &LightGroup, acc: &mut Accum) {
        let mesh = &scene.meshes[geom.mesh];
        let p = q.at.p;
        for &tri in &geom.tris {
            let tri = tri as usize;
            if tri >= mesh.triangle_count() {
                continue;
            }
            let pv = mesh.vertices(tri).map(d3);
            // A triangle does not light itself nor a point in its plane (see `planar_light`).
            let tn = (pv[1] - pv[0]).cross(pv[2] - pv[0]);
            let tn_len = tn.length();
            let extent = pv.iter().map(|v| (*v - pv[0]).length()).fold(0.0, f64::max);
            let h = tn.dot(p - pv[0]);
            if (q.receiver.mesh == geom.mesh && q.receiver.tri == tri)
                || !(h.abs() > 1e-6 * tn_len * (extent + (p - pv[0]).length()))
            {
                continue;
            }
            if !geom.two_sided {
                let ne = d3(emitting_normal(mesh, tri));
                if ne.dot(p - pv[0]) <= 0.0 {
                    continue;
                }
            }
            let occ = if q.shadows {
                // The light triangle's plane, oriented towards p: occluders beyond it cannot
                // shadow it.
                let ln = if h < 0.0 { -tn } else { tn };
                let pq = PieceQuery {
                    p,
                    skip: Skip::Triangle(geom.mesh, tri),
                    piece: &pv,
                    plane: Some((pv[0], ln)),
                    separate: None,
                    ball: None,
                    receiver: q.receiver,
                };
                self.objects.occluders(scene, &pq, q.scratch).unwrap_or_default()
            } else {
                Occluders::default()
            };
            self.counters.light_triangles.fetch_add(1, Ordering::Relaxed);
            integrate_piece(&self.settings, &q.at, &pv, occ, acc);
        }
    }
}

/// How many of the light's triangles [`LtcShader::light_triangles`] would integrate at `p`
/// (all of a two-sided light's; those of a one-sided light whose emitting side faces `p`).
fn facing_triangles(scene: &Scene, p: DVec3, geom: &LightGroup) -> usize {
    let Some(mesh) = scene.meshes.get(geom.mesh) else { return 0 };
    if geom.two_sided {
        return geom.tris.len();
    }
    geom.tris
        .iter()
        .filter(|&&t| {
            let t = t as usize;
            t < mesh.triangle_count() && d3(emitting_normal(mesh, t)).dot(p - d3(mesh.vertices(t)[0])) > 0.0
        })
        .count()
}

/// The shading frame at `si` for `desc` (its normal turned to ωo's side: pbrt-v3's BSDFs
/// reflect on whichever side ωo is, so a mesh wound inwards still lights up), ωo in it and
/// the glossy lobes' LTCs; `None` without a normal.
fn piece_frame(si: &SurfaceInteraction, desc: &LtcDescription) -> Option<PieceFrame> {
    let n = desc.n.normalize_or_zero();
    if n == Vec3::ZERO {
        return None;
    }
    let behind = n.dot(si.wo) < 0.0;
    let n = if behind { -n } else { n };
    let frame = Frame::toward(d3(n), d3(si.wo));
    let wo_local = frame.to_local(d3(si.wo));
    let cos_o = wo_local.z.clamp(0.0, 1.0) as f32;
    let lobes = desc
        .lobes
        .iter()
        .map(|lobe| {
            // Seen from behind its shading normal, a dielectric's Fresnel has its η swapped.
            let lobe = if behind { lobe.seen_from_behind() } else { *lobe };
            let coeffs = match lobe.ggx_alpha() {
                Some(a) => Ltc::lookup(cos_o, a),
                // The cosine (FresnelBlend's diffuse term).
                None => LtcCoeffs { minv: glam::DMat3::IDENTITY, magnitude: 1.0, fresnel: 0.0 },
            };
            LobeLtc { lobe, coeffs }
        })
        .collect();
    Some(PieceFrame { p: d3(si.p), frame, wo_local, lobes })
}

/// The scene's area lights gathered per emitting mesh, radiance and sidedness, with the
/// bounding spheres of their triangles (shapes still [`LightShape::Triangles`]).
fn gather_lights(scene: &Scene) -> Vec<LightGroup> {
    let mut groups: Vec<LightGroup> = Vec::new();
    for l in scene.light_list() {
        let Some(geom) = l.area() else { continue };
        if scene.meshes.get(geom.mesh as usize).is_none() {
            continue;
        }
        match groups.iter_mut().find(|g| g.mesh == geom.mesh as usize && g.l == geom.l && g.two_sided == geom.two_sided)
        {
            Some(g) => g.tris.extend_from_slice(&geom.tris),
            None => groups.push(LightGroup {
                mesh: geom.mesh as usize,
                tris: geom.tris.clone(),
                l: geom.l,
                two_sided: geom.two_sided,
                label: match scene.objects.get(geom.mesh as usize) {
                    Some(o) => format!("\"{}\" at {}", o.kind, o.loc),
                    None => format!("mesh {}", geom.mesh),
                },
                shape: LightShape::Triangles,
                center: DVec3::ZERO,
                radius: 0.0,
            }),
        }
    }
    for g in &mut groups {
        // Centred on the vertices' mean, through the farthest vertex: a sphere that turns with
        // the scene (an axis-aligned box's would grow when the scene is rotated, and move the
        // pixel-shading near-field decision with it).
        let mesh = &scene.meshes[g.mesh];
        let vertices = || {
            g.tris.iter().filter(|&&t| (t as usize) < mesh.triangle_count()).flat_map(|&t| mesh.vertices(t as usize))
        };
        let (sum, count) = vertices().fold((DVec3::ZERO, 0usize), |(s, n), v| (s + d3(v), n + 1));
        if count > 0 {
            g.center = sum / count as f64;
            g.radius = vertices().map(|v| (d3(v) - g.center).length()).fold(0.0, f64::max);
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The f32 vertices of a UV sphere (`n` rings) of radius `r` around `c`, as a scene holds them.
    fn sphere_vertices(c: Vec3, r: f32, n: usize) -> Vec<DVec3> {
        let mut v = Vec::new();
        for i in 0..=n {
            let theta = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..2 * n {
                let phi = std::f32::consts::PI * j as f32 / n as f32;
                let d = Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                v.push(d3(c + d * r));
            }
        }
        v
    }

    /// Issue 42's smallest sphere light (r 0.033) away from the origin is one sphere: the f32
    /// rounding of its vertices (7e-6 of its radius) is not a departure from it; a vertex moved
    /// by 1e-4 of the radius is.
    #[test]
    fn on_one_sphere_allows_f32_rounding_only() {
        for (c, r) in [(Vec3::new(-3.0, 1.2, -2.2), 0.033), (Vec3::new(-3.75, 0.0, 0.0), 0.0333), (Vec3::ZERO, 1.0)] {
            let mut v = sphere_vertices(c, r, 60);
            let (center, radius) = on_one_sphere(&v).unwrap_or_else(|| panic!("{c} {r}"));
            assert!((center - d3(c)).length() < 1e-6 && (radius / r as f64 - 1.0).abs() < 1e-5);
            let k = v.len() / 3;
            v[k] = d3(c) + (v[k] - d3(c)) * (1.0 - 1e-4);
            assert!(on_one_sphere(&v).is_none(), "{c} {r}");
        }
    }
}
