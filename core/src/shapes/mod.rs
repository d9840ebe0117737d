//! Shapes to world-space [`TriangleMesh`]es: `trianglemesh`, `plymesh`, the six
//! pbrt-v3 quadrics (tessellated), `loopsubdiv`, `heightfield`, `nurbs`, and `curve` (a mesh
//! without triangles carrying the curve, which the hierarchy intersects as pbrt-v3 does).
//!
//! Every parameter is read through the [`ParamSet`](crate::parser::ParamSet)
//! getters so that unused ones can be reported by the caller.
//!
//! # Tessellation bound (quadrics)
//! With `ε = Tessellation::max_rel_error` and `R` the shape's largest radius
//! (sphere/cylinder/cone/paraboloid `radius`, disk outer `radius`, hyperboloid the
//! largest radius its fitted surface reaches, at most `max(|p1.xy|, |p2.xy|)`; hyperboloids
//! use `ε / 10`, see `quadrics::build`):
//! * every vertex lies exactly (to f64 rounding, then f32 storage) on the surface;
//! * around the axis, the chord sagitta of every circle is `≤ ε/2 · R`
//!   (`Δφ = 2 acos(1 - ε/2)`, at most [`MAX_SEGMENTS`] segments over 2π);
//! * along the axis, `[0, 1]` in `v` is bisected until the distance from the
//!   surface point at every triangle's centroid and edge midpoints (in (u, v)) to
//!   the triangle's plane is `≤ ε · R` (at most 12 bisections, [`MAX_SEGMENTS`] rows);
//!   planar and ruled pieces (disk, cylinder, cone) keep a single row of cells.
//! * Poles and apexes get one vertex per cell (u at the cell's centre, so uv stay
//!   pbrt-v3's) and one triangle per cell: no zero-area triangles; the seam of a
//!   full revolution is duplicated (u = 0 and u = 1) with bit-identical positions,
//!   so the mesh is closed after welding by position ([`TriangleMesh::build_adjacency`]).
//!
//! So the tessellation deviates from the analytic surface by about `ε · R` at most.

mod curve;
mod heightfield;
pub mod loopsubdiv;
mod nurbs;
pub mod ply;
mod quadrics;
mod trianglemesh;

use crate::mesh::{AlphaSpec, NormalRule, Quadric, QuadricShape, TriangleMesh};
use crate::parser::{DiagSink, Diagnostic, FileLoc, SceneDescription, ShapeDesc};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// At most this many segments around a quadric's axis and this many rows along it.
pub const MAX_SEGMENTS: usize = 4096;

/// How finely analytic shapes are tessellated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tessellation {
    /// Maximum distance between the tessellation and the analytic surface,
    /// relative to the shape's radius (see the module documentation).
    pub max_rel_error: f32,
}

impl Default for Tessellation {
    fn default() -> Self {
        Tessellation { max_rel_error: 1e-3 }
    }
}

/// The scene's triangle budget when [`MAX_TRIANGLES_ENV`] is not set: 2^26 (67 million).
pub const DEFAULT_MAX_TRIANGLES: usize = 1 << 26;
/// The environment variable that sets the scene's triangle budget.
pub const MAX_TRIANGLES_ENV: &str = "PENUMBRA_MAX_TRIANGLES";

/// How many triangles the scene's shapes may make together (every object instance counted,
/// as it is built): a small scene file can ask for minutes of tessellation and gigabytes (a
/// 260-byte `loopsubdiv` with `nlevels` 9), so shapes whose tessellation grows beyond their
/// input charge their count *before* making it, and the build stops at the first shape over
/// the budget with an error at its location.
///
/// Under the default budget a shape may also not *amplify* its input beyond
/// [`MAX_AMPLIFICATION`] triangles per input face once it makes more than [`AMPLIFIED_FLOOR`]:
/// 2^26 triangles is about 20 GB of scene, which a 260-byte `loopsubdiv` with `nlevels` 11
/// could ask for, and `nlevels` 9 of a tetrahedron (2^20 triangles from 4 faces) is already
/// seconds and hundreds of megabytes from a few bytes. Setting [`MAX_TRIANGLES_ENV`] lifts
/// that rule: the budget set is then the only bound.
#[derive(Debug)]
pub struct TriangleBudget {
    limit: usize,
    used: AtomicUsize,
    /// Whether [`MAX_TRIANGLES_ENV`] set the limit (then amplification is not bounded).
    explicit: bool,
}

/// Under the default budget, at most this many triangles per input face (`loopsubdiv`'s
/// `nlevels` 8: every level makes four of one)…
pub const MAX_AMPLIFICATION: usize = 1 << 16;
/// …once a shape makes more than this many triangles (2^18, a tetrahedron at `nlevels` 8).
pub const AMPLIFIED_FLOOR: usize = 1 << 18;

impl TriangleBudget {
    pub fn new(limit: usize) -> Self {
        TriangleBudget { limit, used: AtomicUsize::new(0), explicit: false }
    }

    /// A budget of `limit` set by the user: only `limit` bounds what shapes make.
    pub fn explicit(limit: usize) -> Self {
        TriangleBudget { explicit: true, ..TriangleBudget::new(limit) }
    }

    /// [`MAX_TRIANGLES_ENV`] if set (a positive integer), else [`DEFAULT_MAX_TRIANGLES`].
    pub fn from_env() -> Result<Self, String> {
        match std::env::var(MAX_TRIANGLES_ENV) {
            Err(std::env::VarError::NotPresent) => Ok(TriangleBudget::new(DEFAULT_MAX_TRIANGLES)),
            Ok(v) => match v.trim().parse::<usize>() {
                Ok(n) if n > 0 => Ok(TriangleBudget::explicit(n)),
                _ => Err(format!("{MAX_TRIANGLES_ENV}={v:?}: expected a positive number of triangles")),
            },
            Err(e) => Err(format!("{MAX_TRIANGLES_ENV}: {e}")),
        }
    }

    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Triangles charged so far.
    pub fn used(&self) -> usize {
        self.used.load(Ordering::Relaxed)
    }

    /// [`charge`](Self::charge)s `n` triangles that `what` is about to make from `input` faces,
    /// after refusing, under the default budget, more than [`MAX_AMPLIFICATION`] per face
    /// beyond [`AMPLIFIED_FLOOR`] (see the type's documentation).
    pub fn charge_amplified(&self, n: usize, input: usize, what: &str, loc: Option<FileLoc>) -> Result<(), Diagnostic> {
        if !self.explicit && n > AMPLIFIED_FLOOR && n / input.max(1) > MAX_AMPLIFICATION {
            return Err(Diagnostic::error(
                loc,
                format!(
                    "{what} makes {n} triangles, {} per input face: over the default triangle budget's \
                     {MAX_AMPLIFICATION} per face beyond {AMPLIFIED_FLOOR} in all (set {MAX_TRIANGLES_ENV} \
                     to a number of triangles to allow it)",
                    n / input.max(1)
                ),
            ));
        }
        self.charge(n, what, loc)
    }

    /// Charges `n` triangles that `what` makes (or is about to make), or refuses with an error
    /// at `loc` when the scene's total would exceed the budget.
    pub fn charge(&self, n: usize, what: &str, loc: Option<FileLoc>) -> Result<(), Diagnostic> {
        let before = self.used.fetch_add(n, Ordering::Relaxed);
        let total = before.saturating_add(n);
        if total > self.limit {
            return Err(Diagnostic::error(
                loc,
                format!(
                    "{what} makes {n} triangles, {before} already made: over the scene's triangle budget of {} \
                     (set {MAX_TRIANGLES_ENV} to allow more; default 2^26)",
                    self.limit
                ),
            ));
        }
        Ok(())
    }
}

/// What shape building needs besides the shape itself.
pub struct ShapeContext<'a> {
    /// Directory relative asset names (`"string filename"`) resolve against.
    pub base_dir: &'a Path,
    /// Where warnings go (skipped shapes, dropped attributes, skipped faces…).
    pub warnings: &'a DiagSink,
    pub tessellation: Tessellation,
    /// The scene's triangle budget, shared by every shape built with this context
    /// ([`DEFAULT_MAX_TRIANGLES`] unless set).
    pub budget: TriangleBudget,
}

impl<'a> ShapeContext<'a> {
    pub fn new(base_dir: &'a Path, warnings: &'a DiagSink) -> Self {
        let budget = TriangleBudget::new(DEFAULT_MAX_TRIANGLES);
        ShapeContext { base_dir, warnings, tessellation: Tessellation::default(), budget }
    }
    /// Resolves asset paths against the scene's `base_dir` (as `SceneDescription::resolve_path`).
    pub fn for_scene(scene: &'a SceneDescription, warnings: &'a DiagSink, tessellation: Tessellation) -> Self {
        let budget = TriangleBudget::new(DEFAULT_MAX_TRIANGLES);
        ShapeContext { base_dir: &scene.base_dir, warnings, tessellation, budget }
    }
    pub fn resolve_path(&self, name: &str) -> PathBuf {
        let p = PathBuf::from(name);
        if p.is_absolute() {
            p
        } else {
            self.base_dir.join(p)
        }
    }
}

/// Builds the world-space mesh of a shape.
///
/// `Ok(None)`: the shape was skipped and a warning explaining why was pushed to
/// `ctx.warnings`. `Err`: the shape's data is malformed (located at the offending
/// parameter when possible). Never panics. A shape under an animated transform is built at
/// its start transform (see [`build_shape_moving`] for its object-space geometry).
pub fn build_shape(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<TriangleMesh>, Diagnostic> {
    if desc.render_from_object.is_animated() && desc.entity.kind != "curve" {
        warn_animated(desc, ctx);
    }
    Ok(build_shape_moving(desc, ctx)?.map(|(m, _)| m))
}

/// A moving shape's vertices in its own space (pbrt-v3 builds an animated shape with the
/// identity transform and moves it as a whole): the mesh's vertex arrays, in the same order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjectSpace {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec3>>,
}

/// [`build_shape`], with the object-space vertices when the shape's transform is animated
/// (then the caller moves it, and no warning is given; a `curve` is not moved: it stays at
/// its start transform, with a warning).
pub fn build_shape_moving(
    desc: &ShapeDesc,
    ctx: &ShapeContext,
) -> Result<Option<(TriangleMesh, Option<ObjectSpace>)>, Diagnostic> {
    let kind = desc.entity.kind.as_str();
    let obj = match kind {
        "trianglemesh" => trianglemesh::build(desc, ctx)?,
        "plymesh" => ply::build(desc, ctx)?,
        "sphere" | "disk" | "cylinder" | "cone" | "paraboloid" | "hyperboloid" => quadrics::build(desc, ctx)?,
        "loopsubdiv" => loopsubdiv::build(desc, ctx)?,
        "heightfield" => heightfield::build(desc, ctx)?,
        "nurbs" => nurbs::build(desc, ctx)?,
        "curve" => {
            let mesh = curve::build(desc, ctx)?;
            if mesh.is_some() && desc.render_from_object.is_animated() {
                ctx.warnings.warn(
                    Some(desc.entity.loc.clone()),
                    "shape \"curve\" has an animated transform, which penumbra does not move curves by; using its \
                     start transform",
                );
            }
            return Ok(mesh.map(|m| (m, None)));
        }
        _ => {
            desc.entity.params.mark_all_used();
            ctx.warnings.warn(Some(desc.entity.loc.clone()), format!("shape \"{kind}\" unknown; skipped"));
            return Ok(None);
        }
    };
    let Some(obj) = obj else { return Ok(None) };
    if matches!(kind, "trianglemesh" | "plymesh") {
        // Their triangles are their input's; every other shape charged its count before making it.
        ctx.budget.charge(obj.tris.len(), &format!("shape \"{kind}\""), Some(desc.entity.loc.clone()))?;
    }
    if obj.tris.is_empty() {
        ctx.warnings.warn(Some(desc.entity.loc.clone()), format!("shape \"{kind}\" has no triangles; skipped"));
        return Ok(None);
    }
    let object = desc.render_from_object.is_animated().then(|| object_space(&obj));
    let mut mesh = finish(obj, desc)?;
    if matches!(kind, "sphere" | "disk" | "cylinder" | "cone" | "paraboloid" | "hyperboloid") {
        mesh.normal_rule = NormalRule::Quadric;
        mesh.analytic_ng = kind == "hyperboloid";
    }
    Ok(Some((mesh, object)))
}

/// The vertex arrays of `obj` as [`finish`] makes them, with the identity transform.
fn object_space(obj: &ObjMesh) -> ObjectSpace {
    let to_vec = |v: &[f64; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    let unit = |v: &[f64; 3]| {
        let w = to_vec(v).normalize_or_zero();
        if w.is_finite() {
            w
        } else {
            Vec3::ZERO
        }
    };
    ObjectSpace {
        positions: obj.p.iter().map(to_vec).collect(),
        normals: obj.n.as_ref().map(|ns| ns.iter().map(unit).collect()),
        tangents: obj
            .s
            .as_ref()
            .map(|ss| ss.iter().map(to_vec).map(|v| if v.is_finite() { v } else { Vec3::ZERO }).collect()),
    }
}

fn warn_animated(desc: &ShapeDesc, ctx: &ShapeContext) {
    ctx.warnings.warn(
        Some(desc.entity.loc.clone()),
        format!("shape \"{}\" has an animated transform; using its start transform", desc.entity.kind),
    );
}

/// Object-space mesh data before transformation.
#[derive(Clone, Debug, Default)]
pub(crate) struct ObjMesh {
    pub p: Vec<[f64; 3]>,
    pub n: Option<Vec<[f64; 3]>>,
    pub s: Option<Vec<[f64; 3]>>,
    pub uv: Option<Vec<[f32; 2]>>,
    /// In the shape's own vertex order.
    pub tris: Vec<[u32; 3]>,
    pub alpha: Option<AlphaSpec>,
    pub shadow_alpha: Option<AlphaSpec>,
    /// A sphere's, disk's or cylinder's parameters (object space) and the tessellation's
    /// largest distance from its surface.
    pub quadric: Option<(QuadricShape, f64)>,
    /// Where `n` (the analytic normal pbrt-v3 shades with) is not normal to the surface:
    /// the surface's own normals, per vertex (pbrt-v3's hyperboloid).
    pub surface_n: Option<Vec<[f64; 3]>>,
}

/// Reads pbrt-v3's `alpha`/`shadowalpha` parameters (meshes only, as pbrt-v3).
pub(crate) fn read_alpha(desc: &ShapeDesc, ctx: &ShapeContext, name: &str) -> Option<AlphaSpec> {
    let ps = &desc.entity.params;
    if let Some(t) = ps.get_texture(name) {
        return match t.float {
            Some(i) => Some(AlphaSpec::Texture(i)),
            None => {
                ctx.warnings.warn(
                    ps.loc_of(name).cloned(),
                    format!("couldn't find float texture \"{}\" for \"{name}\"; ignored", t.name),
                );
                None
            }
        };
    }
    (ps.get_one_float(name, 1.0) == 0.0).then_some(AlphaSpec::Constant(0.0))
}

pub(crate) fn loc_or_entity(desc: &ShapeDesc, name: &str) -> Option<FileLoc> {
    Some(desc.entity.params.loc_of(name).unwrap_or(&desc.entity.loc).clone())
}

fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Transforms to world space and orients the winding (see `crate::mesh`).
fn finish(obj: ObjMesh, desc: &ShapeDesc) -> Result<TriangleMesh, Diagnostic> {
    let t = &desc.render_from_object.start;
    let ro = desc.reverse_orientation;
    let flip = ro ^ t.swaps_handedness();
    let to_vec = |v: [f64; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    let mut positions = Vec::with_capacity(obj.p.len());
    for p in &obj.p {
        let w = t.apply_point(*p);
        let v = to_vec(w);
        if !v.is_finite() {
            return Err(Diagnostic::error(
                Some(desc.entity.loc.clone()),
                format!("shape \"{}\": a vertex is not finite in world space", desc.entity.kind),
            ));
        }
        positions.push(v);
    }
    let world_normals = |ns: &Vec<[f64; 3]>| {
        ns.iter()
            .map(|n| {
                let w = t.apply_normal(*n);
                let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
                if len > 0.0 && len.is_finite() && finite3(w) {
                    to_vec([w[0] / len, w[1] / len, w[2] / len])
                } else {
                    Vec3::ZERO
                }
            })
            .collect::<Vec<_>>()
    };
    let normals = obj.n.as_ref().map(world_normals);
    let surface_normals = obj.surface_n.as_ref().map(world_normals);
    let tangents = obj.s.as_ref().map(|ss| {
        ss.iter().map(|s| to_vec(t.apply_vector(*s))).map(|v| if v.is_finite() { v } else { Vec3::ZERO }).collect()
    });
    // Decide the winding.
    let reverse = match &normals {
        None => flip,
        Some(ns) => {
            // Area-weighted vote: does the given winding agree with the (flipped) shading normals?
            let mut agree = 0.0f64;
            for tri in &obj.tris {
                let [a, b, c] = tri.map(|i| positions[i as usize]);
                let ng = (b - a).cross(c - a);
                let mut nsum = ns[tri[0] as usize] + ns[tri[1] as usize] + ns[tri[2] as usize];
                if flip {
                    nsum = -nsum;
                }
                agree += (ng.dot(nsum.normalize_or_zero())) as f64;
            }
            if agree == 0.0 || !agree.is_finite() {
                flip
            } else {
                agree < 0.0
            }
        }
    };
    let indices = if reverse { obj.tris.iter().map(|t| [t[0], t[2], t[1]]).collect() } else { obj.tris };
    Ok(TriangleMesh {
        positions,
        indices,
        normals,
        uvs: obj.uv.map(|uv| uv.into_iter().map(|[u, v]| Vec2::new(u, v)).collect()),
        tangents,
        flip_normals: flip,
        reverse_orientation: ro,
        winding_reversed: reverse,
        alpha: obj.alpha,
        shadow_alpha: obj.shadow_alpha,
        normal_rule: NormalRule::Triangle,
        analytic_ng: false,
        surface_normals,
        quadric: obj.quadric.map(|(shape, deviation)| Quadric { shape, world_from_object: *t, deviation }),
        curves: None,
    })
}

#[cfg(test)]
pub(crate) mod test_util {
    use crate::parser::{AnimatedTransform, Entity, FileLoc, Param, ParamSet, ParamValue, ShapeDesc, Transform};
    use std::sync::Arc;

    pub fn loc(line: u32) -> FileLoc {
        FileLoc::new(Arc::from("test.pbrt"), line, 5)
    }

    pub fn shape(kind: &str, params: Vec<(&str, ParamValue)>) -> ShapeDesc {
        shape_with(kind, params, Transform::IDENTITY, false)
    }

    pub fn shape_with(kind: &str, params: Vec<(&str, ParamValue)>, t: Transform, ro: bool) -> ShapeDesc {
        let mut ps = ParamSet::new();
        for (i, (name, v)) in params.into_iter().enumerate() {
            ps.add(Param::new(name, v, loc(10 + i as u32)));
        }
        ShapeDesc {
            entity: Entity::new(kind, ps, loc(1)),
            render_from_object: AnimatedTransform::fixed(t),
            reverse_orientation: ro,
            material: None,
            area_light: None,
            inside_medium: None,
            outside_medium: None,
        }
    }

    /// A unique temporary directory for a test.
    pub fn temp_dir(tag: &str) -> std::path::PathBuf {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let d = std::env::temp_dir().join(format!(
            "penumbra-shapes-{}-{}-{}",
            std::process::id(),
            tag,
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::*;
    use super::*;
    use crate::parser::ParamValue;

    /// A flat curve builds to a triangle-less mesh carrying its one segment (split into pbrt-v3's
    /// default 2^3 pieces), with every parameter read and no warning; unknown shapes are skipped
    /// with a warning.
    #[test]
    fn curve_is_intersected_and_unknown_is_skipped_with_a_warning() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let d = shape(
            "curve",
            vec![("P", ParamValue::Point3(vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0, 0.0, 3.0, 0.0, 0.0]))],
        );
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert_eq!(m.triangle_count(), 0);
        let c = m.curves.as_ref().unwrap();
        assert_eq!((c.kind, c.segments.len(), c.prim_count()), (crate::mesh::curve::CurveType::Flat, 1, 8));
        assert!(d.entity.params.report_unused("x").is_empty());
        assert!(sink.take().is_empty());
        let d = shape("blob", vec![("P", ParamValue::Point3(vec![0.0; 12]))]);
        assert_eq!(build_shape(&d, &ctx).unwrap(), None);
        assert!(d.entity.params.report_unused("x").is_empty());
        let w = sink.take();
        assert_eq!(w.len(), 1);
        assert!(w[0].message.contains("\"blob\""));
    }

    /// A rational quadratic NURBS (a quarter of the unit circle in u, `Pw` with weight √½ on
    /// the middle point) extruded linearly in v: every vertex of the 30 × 30 tessellation
    /// lies on the unit cylinder with a radial normal and its (u, v); malformed knot vectors
    /// and counts are errors at the parameter.
    #[test]
    fn nurbs_tessellates_a_rational_cylinder_exactly() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let params = |uknots: Vec<f32>| {
            vec![
                ("nu", ParamValue::Int(vec![3])),
                ("uorder", ParamValue::Int(vec![3])),
                ("uknots", ParamValue::Float(uknots)),
                ("nv", ParamValue::Int(vec![2])),
                ("vorder", ParamValue::Int(vec![2])),
                ("vknots", ParamValue::Float(vec![0.0, 0.0, 2.0, 2.0])),
                (
                    "Pw",
                    ParamValue::Float(vec![
                        1.0, 0.0, 0.0, 1.0, h, h, 0.0, h, 0.0, 1.0, 0.0, 1.0, //
                        1.0, 0.0, 1.0, 1.0, h, h, h, h, 0.0, 1.0, 1.0, 1.0,
                    ]),
                ),
            ]
        };
        let m = build_shape(&shape("nurbs", params(vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0])), &ctx).unwrap().unwrap();
        assert_eq!((m.positions.len(), m.triangle_count()), (900, 2 * 29 * 29));
        let (normals, uvs) = (m.normals.as_ref().unwrap(), m.uvs.as_ref().unwrap());
        for (i, p) in m.positions.iter().enumerate() {
            assert!((p.x * p.x + p.y * p.y - 1.0).abs() < 1e-5 && (-1e-6..=1.0 + 1e-6).contains(&p.z), "{p}");
            let radial = Vec3::new(p.x, p.y, 0.0);
            assert!(normals[i].cross(radial).length() < 1e-4, "{} at {p}", normals[i]);
            assert_eq!(uvs[i], Vec2::new((i % 30) as f32 / 29.0, 2.0 * (i / 30) as f32 / 29.0));
        }
        assert!(sink.take().is_empty());
        let e = build_shape(&shape("nurbs", params(vec![0.0, 0.0, 1.0, 1.0, 1.0])), &ctx).unwrap_err();
        assert!(e.message.contains("5 knots in \"uknots\""), "{}", e.message);
        let e = build_shape(&shape("nurbs", params(vec![0.0, 0.0, 1.0, 0.5, 1.0, 1.0])), &ctx).unwrap_err();
        assert!(e.message.contains("non-decreasing"), "{}", e.message);
    }
}
