//! `Shape "curve"` as pbrt-v3's `CreateCurveShape` reads it: `P` in the `bezier` (degree + 1
//! points, then `degree` more per segment) or uniform `bspline` basis, degree 2 or 3, each
//! segment converted to a cubic Bézier as pbrt-v3 does (degree elevation, blossoming), the
//! width lerped from `width0` to `width1` over the segments.
//!
//! `ribbon` curves: at each u pbrt-v3's `Curve::Intersect` takes the normal `nHit` slerped
//! between the segment's two `N` (over the angle `acos(clamp(n0·n1, 0, 1))`) and accepts a ray
//! within `width · |nHit · d̂| / 2` of the curve *projected along the ray*. A strip of width
//! `width · |nHit|` across `normalize(nHit × ∂p/∂u)` projects to exactly that where the ray is
//! perpendicular to the curve; where it is not, pbrt-v3's is narrower (by
//! `sqrt(1 − (t̂ · d̂)²)`, t̂ the tangent), so pbrt-v3's ribbon depends on the ray too. penumbra
//! tessellates the strip ([`STEPS`] quads per Bézier segment, `nHit` as the vertex normals, u
//! along the segment, v across: 0 on the `nHit × ∂p/∂u` side, as pbrt-v3 from the side `nHit`
//! faces) and says so in a warning. Where two neighbouring normals are equal pbrt-v3 divides by
//! sin 0; penumbra uses the common normal.
//!
//! `flat` and `cylinder` curves are strips facing each ray in pbrt-v3 (with, for `cylinder`, a
//! normal turned across the width): skipped with a warning.

use super::{loc_or_entity, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};
use glam::DVec3;

/// Quads per cubic Bézier segment along u.
pub(crate) const STEPS: usize = 64;

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

/// The Bézier point at `u` and its derivative (pbrt-v3's `EvalBezier`, with its fallback
/// `cp[3] − cp[0]` where the derivative vanishes).
fn eval_bezier(cp: &[DVec3; 4], u: f64) -> (DVec3, DVec3) {
    let lerp = |a: DVec3, b: DVec3| a + (b - a) * u;
    let c1 = [lerp(cp[0], cp[1]), lerp(cp[1], cp[2]), lerp(cp[2], cp[3])];
    let c2 = [lerp(c1[0], c1[1]), lerp(c1[1], c1[2])];
    let d = 3.0 * (c2[1] - c2[0]);
    (lerp(c2[0], c2[1]), if d.length_squared() > 0.0 { d } else { cp[3] - cp[0] })
}

/// The curve's parameters, validated as pbrt-v3 validates them.
struct Params {
    segments: Vec<[DVec3; 4]>,
    width: [f64; 2],
    normals: Vec<DVec3>,
}

fn params(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<Params>, Diagnostic> {
    let ps = &desc.entity.params;
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
    let kind = ps.get_one_string("type", "flat");
    ps.get_one_int("splitdepth", ps.get_one_float("splitdepth", 3.0) as i32);
    let normals: Vec<DVec3> =
        ps.get_normals("N").unwrap_or(&[]).iter().map(|n| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64)).collect();
    if kind != "ribbon" {
        let what = match kind.as_str() {
            "flat" | "cylinder" => format!(
                "curve type \"{kind}\" is a strip facing each ray in pbrt-v3, not a surface: not supported; skipped"
            ),
            _ => format!("unknown curve type \"{kind}\" (pbrt-v3 uses \"cylinder\", which is not supported); skipped"),
        };
        ps.mark_all_used();
        ctx.warnings.warn(Some(desc.entity.loc.clone()), what);
        return Ok(None);
    }
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
    ctx.warnings.warn(
        Some(desc.entity.loc.clone()),
        "curve type \"ribbon\": rendered as the strip it approximates; pbrt-v3 narrows its width where a ray \
         runs along the curve, so shadows and silhouettes of ribbons seen or lit along their length differ"
            .to_string(),
    );
    Ok(Some(Params { segments, width, normals: normals.iter().map(|n| n.normalize()).collect() }))
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let Some(Params { segments, width, normals }) = params(desc, ctx)? else { return Ok(None) };
    let n_seg = segments.len() as f64;
    let mut m = ObjMesh { n: Some(Vec::new()), uv: Some(Vec::new()), ..Default::default() };
    let (mut ns, mut uvs) = (Vec::new(), Vec::new());
    for (s, cp) in segments.iter().enumerate() {
        let w = [s as f64 / n_seg, (s + 1) as f64 / n_seg].map(|t| width[0] + (width[1] - width[0]) * t);
        let (n0, n1) = (normals[s], normals[s + 1]);
        let angle = n0.dot(n1).clamp(0.0, 1.0).acos();
        let base = m.p.len() as u32;
        for i in 0..=STEPS {
            let u = i as f64 / STEPS as f64;
            // pbrt-v3's slerp; equal normals (angle 0, where pbrt-v3 divides by zero) give n0.
            let n_hit = if angle > 0.0 {
                n0 * (((1.0 - u) * angle).sin() / angle.sin()) + n1 * ((u * angle).sin() / angle.sin())
            } else {
                n0
            };
            let (p, dpdu) = eval_bezier(cp, u);
            let half = 0.5 * (w[0] + (w[1] - w[0]) * u) * n_hit.length();
            let side = n_hit.cross(dpdu).normalize_or_zero() * half;
            let n = n_hit.normalize_or_zero().to_array();
            for (q, v) in [(p + side, 0.0), (p - side, 1.0)] {
                m.p.push(q.to_array());
                ns.push(n);
                uvs.push([u as f32, v]);
            }
            if i > 0 {
                let (a, b) = (base + 2 * (i as u32 - 1), base + 2 * i as u32);
                m.tris.push([a, b, b + 1]);
                m.tris.push([a, b + 1, a + 1]);
            }
        }
    }
    m.n = Some(ns);
    m.uv = Some(uvs);
    Ok(Some(m))
}
