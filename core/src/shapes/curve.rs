//! `Shape "curve"` as pbrt-v3's `CreateCurveShape` reads it: `P` in the `bezier` (degree + 1
//! points, then `degree` more per segment) or uniform `bspline` basis, degree 2 or 3, each
//! segment converted to a cubic Bézier as pbrt-v3 does (degree elevation, blossoming), the
//! width lerped from `width0` to `width1` over the segments, `type` `flat`, `ribbon` (with
//! normals `N` at the segments' ends) or `cylinder` (pbrt-v3's fallback for an unknown type),
//! each segment split into `2^splitdepth` pieces (`splitdepth` clamped to 0..=10).
//!
//! The result is a [`TriangleMesh`] without triangles whose [`Curves`] the hierarchy
//! intersects as pbrt-v3 does (`crate::mesh::curve`): nothing is tessellated.

use super::{loc_or_entity, ShapeContext};
use crate::mesh::curve::{CurveSegment, CurveType, Curves};
use crate::mesh::TriangleMesh;
use crate::parser::{Diagnostic, ShapeDesc};
use glam::{DVec3, Mat4, Vec3};
use std::sync::Arc;

/// The largest `splitdepth` penumbra takes (pbrt-v3 takes any: 2^depth pieces per segment).
const MAX_SPLIT_DEPTH: i32 = 10;

fn error(desc: &ShapeDesc, param: &str, msg: String) -> Diagnostic {
    Diagnostic::error(loc_or_entity(desc, param), format!("curve: {msg}"))
}

/// The cubic Bézier control points of every segment (pbrt-v3's conversions).
fn bezier_segments(cp: &[DVec3], degree: usize, bspline: bool) -> Vec<[DVec3; 4]> {
    let lerp = |t: f64, a: DVec3, b: DVec3| a + (b - a) * t;
    let n_seg = if bspline { cp.len() - degree } else { (cp.len() - 1) / degree };
    (0..n_seg)
        .map(|s| {
            if !bspline {
                let c = &cp[s * degree..];
                if degree == 2 {
                    [c[0], lerp(2.0 / 3.0, c[0], c[1]), lerp(1.0 / 3.0, c[1], c[2]), c[2]]
                } else {
                    [c[0], c[1], c[2], c[3]]
                }
            } else if degree == 2 {
                let (p01, p12, p23) = (cp[s], cp[s + 1], cp[s + 2]);
                let (p11, p22) = (lerp(0.5, p01, p12), lerp(0.5, p12, p23));
                [p11, lerp(2.0 / 3.0, p11, p12), lerp(1.0 / 3.0, p12, p22), p22]
            } else {
                let (p012, p123, p234, p345) = (cp[s], cp[s + 1], cp[s + 2], cp[s + 3]);
                let p122 = lerp(2.0 / 3.0, p012, p123);
                let p223 = lerp(1.0 / 3.0, p123, p234);
                let p233 = lerp(2.0 / 3.0, p123, p234);
                let p334 = lerp(1.0 / 3.0, p234, p345);
                [lerp(0.5, p122, p223), p223, p233, lerp(0.5, p233, p334)]
            }
        })
        .collect()
}

/// The curve's parameters, validated as pbrt-v3 validates them.
struct Params {
    segments: Vec<[DVec3; 4]>,
    width: [f64; 2],
    kind: CurveType,
    /// Ribbons: one per segment end.
    normals: Vec<DVec3>,
    split_depth: u32,
}

fn params(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Params, Diagnostic> {
    let ps = &desc.entity.params;
    let warn = |msg: String| ctx.warnings.warn(Some(desc.entity.loc.clone()), msg);
    let width = ps.get_one_float("width", 1.0);
    let width = [ps.get_one_float("width0", width) as f64, ps.get_one_float("width1", width) as f64];
    let degree = ps.get_one_int("degree", 3);
    if degree != 2 && degree != 3 {
        return Err(error(
            desc,
            "degree",
            format!("invalid degree {degree}: only degree 2 and 3 curves are supported"),
        ));
    }
    let degree = degree as usize;
    let basis = ps.get_one_string("basis", "bezier");
    if basis != "bezier" && basis != "bspline" {
        return Err(error(desc, "basis", format!("invalid basis \"{basis}\": only \"bezier\" and \"bspline\"")));
    }
    let Some(cp) = ps.get_point3s("P") else {
        return Err(error(desc, "P", "control points \"P\" not provided".into()));
    };
    let cp: Vec<DVec3> = cp.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
    if cp.iter().any(|p| !p.is_finite()) || !width.iter().all(|w| w.is_finite() && *w >= 0.0) {
        return Err(error(desc, "P", "control points and widths must be finite (widths non-negative)".into()));
    }
    let bspline = basis == "bspline";
    if !bspline && (cp.len() < degree + 1 || !(cp.len() - 1 - degree).is_multiple_of(degree)) {
        return Err(error(
            desc,
            "P",
            format!(
                "{} control points: the degree {degree} Bézier basis takes {} + n × {degree}, n >= 0",
                cp.len(),
                degree + 1
            ),
        ));
    }
    if bspline && cp.len() < degree + 1 {
        return Err(error(
            desc,
            "P",
            format!("{} control points: the degree {degree} b-spline basis takes at least {}", cp.len(), degree + 1),
        ));
    }
    let segments = bezier_segments(&cp, degree, bspline);
    let kind = match ps.get_one_string("type", "flat").as_str() {
        "flat" => CurveType::Flat,
        "ribbon" => CurveType::Ribbon,
        "cylinder" => CurveType::Cylinder,
        other => {
            warn(format!("curve: unknown curve type \"{other}\": using \"cylinder\" (as pbrt-v3)"));
            CurveType::Cylinder
        }
    };
    let depth = ps.get_one_int("splitdepth", ps.get_one_float("splitdepth", 3.0) as i32);
    if !(0..=MAX_SPLIT_DEPTH).contains(&depth) {
        warn(format!("curve: \"splitdepth\" {depth} clamped to {}", depth.clamp(0, MAX_SPLIT_DEPTH)));
    }
    let split_depth = depth.clamp(0, MAX_SPLIT_DEPTH) as u32;
    let normals: Vec<DVec3> =
        ps.get_normals("N").unwrap_or(&[]).iter().map(|n| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64)).collect();
    let normals = match kind {
        CurveType::Ribbon => {
            if normals.len() != segments.len() + 1 {
                let msg = if normals.is_empty() {
                    "ribbon curves need normals \"N\" at the segments' endpoints".to_string()
                } else {
                    format!(
                        "{} normals \"N\": a ribbon of {} segments takes {}",
                        normals.len(),
                        segments.len(),
                        segments.len() + 1
                    )
                };
                return Err(error(desc, "N", msg));
            }
            if normals.iter().any(|n| !n.is_finite() || n.length_squared() == 0.0) {
                return Err(error(desc, "N", "normals \"N\" must be finite and non-zero".into()));
            }
            normals
        }
        _ => {
            if !normals.is_empty() {
                warn("curve: normals \"N\" are only used with \"ribbon\" curves (as pbrt-v3): ignored".into());
            }
            Vec::new()
        }
    };
    Ok(Params { segments, width, kind, normals, split_depth })
}

fn mat4(m: &[[f64; 4]; 4]) -> Mat4 {
    Mat4::from_cols_array_2d(&m.map(|r| r.map(|x| x as f32))).transpose()
}

/// The curve shape `desc` as a triangle-less mesh carrying its [`Curves`].
pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<TriangleMesh>, Diagnostic> {
    let Params { segments, width, kind, normals, split_depth } = params(desc, ctx)?;
    let n_seg = segments.len() as f64;
    let v3 = |p: DVec3| Vec3::new(p.x as f32, p.y as f32, p.z as f32);
    let segments = segments
        .iter()
        .enumerate()
        .map(|(s, cp)| {
            let w = [s as f64 / n_seg, (s + 1) as f64 / n_seg].map(|t| (width[0] + (width[1] - width[0]) * t) as f32);
            let n = (kind == CurveType::Ribbon).then(|| [v3(normals[s]), v3(normals[s + 1])]);
            CurveSegment::new(cp.map(v3), w, n)
        })
        .collect();
    let t = &desc.render_from_object.start;
    let curves = Curves {
        kind,
        segments,
        split_depth,
        world_from_object: mat4(&t.m),
        object_from_world: mat4(&t.m_inv),
        reverse_orientation: desc.reverse_orientation,
        swaps_handedness: t.swaps_handedness(),
    };
    let b = curves.world_bounds();
    if !(b.min.is_finite() && b.max.is_finite()) {
        return Err(error(desc, "P", "the curve is not finite in world space".into()));
    }
    Ok(Some(TriangleMesh {
        reverse_orientation: desc.reverse_orientation,
        flip_normals: desc.reverse_orientation ^ t.swaps_handedness(),
        curves: Some(Arc::new(curves)),
        ..Default::default()
    }))
}
