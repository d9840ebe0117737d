//! `Shape "trianglemesh"`.

use super::{loc_or_entity, read_alpha, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};

/// Validated `indices` (a multiple of 3, each in `0..n_p`) as triangles.
pub(crate) fn checked_triangles(desc: &ShapeDesc, idx: &[i32], n_p: usize) -> Result<Vec<[u32; 3]>, Diagnostic> {
    let kind = &desc.entity.kind;
    if !idx.chunks_exact(3).remainder().is_empty() {
        return Err(Diagnostic::error(
            loc_or_entity(desc, "indices"),
            format!("{kind}: \"indices\" has {} values, not a multiple of 3", idx.len()),
        ));
    }
    if let Some((i, v)) = idx.iter().enumerate().find(|(_, v)| **v < 0 || **v as usize >= n_p) {
        return Err(Diagnostic::error(
            loc_or_entity(desc, "indices"),
            format!(
                "{kind}: vertex index {v} (entry {i} of \"indices\") is out of range: {n_p} \"P\" values were given"
            ),
        ));
    }
    Ok(idx.chunks_exact(3).map(|c| [c[0] as u32, c[1] as u32, c[2] as u32]).collect())
}

/// Validated `P` (required, finite).
pub(crate) fn checked_points(desc: &ShapeDesc) -> Result<Vec<[f64; 3]>, Diagnostic> {
    let kind = &desc.entity.kind;
    let Some(p) = desc.entity.params.get_point3s("P") else {
        return Err(Diagnostic::error(
            Some(desc.entity.loc.clone()),
            format!("{kind}: vertex positions \"P\" not provided"),
        ));
    };
    if let Some(i) = p.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
        return Err(Diagnostic::error(
            loc_or_entity(desc, "P"),
            format!("{kind}: \"P\" value {i} is not finite ({:?})", p[i]),
        ));
    }
    Ok(p.iter().map(|v| v.map(|x| x as f64)).collect())
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let warn = |name: &str, msg: String| ctx.warnings.warn(loc_or_entity(desc, name), msg);
    let p = checked_points(desc)?;
    let n_p = p.len();
    let tris = match ps.get_ints("indices") {
        Some(idx) => checked_triangles(desc, idx, n_p)?,
        None if n_p == 3 => vec![[0, 1, 2]],
        None => {
            return Err(Diagnostic::error(
                Some(desc.entity.loc.clone()),
                "trianglemesh: vertex indices \"indices\" not provided",
            ))
        }
    };

    // uv: point2 "uv"/"st", else float "uv"/"st" pairs.
    let mut uv_name = "uv";
    let mut uv: Option<Vec<[f32; 2]>> = ps.get_point2s("uv").map(|v| v.to_vec());
    if uv.is_none() {
        uv_name = "st";
        uv = ps.get_point2s("st").map(|v| v.to_vec());
    }
    if uv.is_none() {
        for name in ["uv", "st"] {
            if let Some(f) = ps.get_floats(name) {
                uv_name = name;
                if f.len() % 2 != 0 {
                    warn(name, format!("trianglemesh: odd number of \"{name}\" values; the last one is ignored"));
                }
                uv = Some(f.chunks_exact(2).map(|c| [c[0], c[1]]).collect());
                break;
            }
        }
    }
    if let Some(u) = &uv {
        if u.len() < n_p {
            warn(
                uv_name,
                format!("trianglemesh: not enough \"{uv_name}\"s: expected {n_p}, found {}; discarding them", u.len()),
            );
            uv = None;
        } else if u.len() > n_p {
            warn(
                uv_name,
                format!("trianglemesh: more \"{uv_name}\"s ({}) than \"P\"s ({n_p}); extra ignored", u.len()),
            );
            if let Some(u) = uv.as_mut() {
                u.truncate(n_p);
            }
        }
    }
    if uv.as_ref().is_some_and(|u| u.iter().flatten().any(|x| !x.is_finite())) {
        warn(uv_name, format!("trianglemesh: non-finite \"{uv_name}\" values; discarding them"));
        uv = None;
    }

    let mut s = ps.get_vector3s("S").map(|v| v.iter().map(|x| x.map(|c| c as f64)).collect::<Vec<_>>());
    if s.as_ref().is_some_and(|v| v.len() != n_p) {
        warn("S", "trianglemesh: number of \"S\"s must match \"P\"s; discarding them".into());
        s = None;
    } else if s.as_ref().is_some_and(|v| v.iter().flatten().any(|x| !x.is_finite())) {
        warn("S", "trianglemesh: non-finite \"S\" values; discarding them".into());
        s = None;
    }
    let mut n = ps.get_normals("N").map(|v| v.iter().map(|x| x.map(|c| c as f64)).collect::<Vec<_>>());
    if n.as_ref().is_some_and(|v| v.len() != n_p) {
        warn("N", "trianglemesh: number of \"N\"s must match \"P\"s; discarding them".into());
        n = None;
    } else if n.as_ref().is_some_and(|v| v.iter().flatten().any(|x| !x.is_finite())) {
        warn("N", "trianglemesh: non-finite \"N\" values; discarding them".into());
        n = None;
    }
    let alpha = read_alpha(desc, ctx, "alpha");
    let shadow_alpha = read_alpha(desc, ctx, "shadowalpha");
    Ok(Some(ObjMesh { p, n, s, uv, tris, alpha, shadow_alpha, quadric: None, surface_n: None }))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use crate::parser::{ParamValue, TextureRef, Transform};

    fn quad_params() -> Vec<(&'static str, ParamValue)> {
        vec![
            ("indices", ParamValue::Int(vec![0, 1, 2, 0, 2, 3])),
            ("P", ParamValue::Point3(vec![0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.])),
        ]
    }

    #[test]
    fn builds_a_quad_and_tracks_params() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let mut p = quad_params();
        p.push(("uv", ParamValue::Float(vec![0., 0., 1., 0., 1., 1., 0., 1.])));
        p.push(("N", ParamValue::Normal([0., 0., 1.].repeat(4))));
        p.push(("radius", ParamValue::Float(vec![1.0])));
        let d = shape("trianglemesh", p);
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert_eq!(m.triangle_count(), 2);
        assert!((m.total_area() - 1.0).abs() < 1e-6);
        assert_eq!(m.uvs.as_ref().unwrap()[2], Vec2::new(1.0, 1.0));
        assert!(!m.winding_reversed);
        let unused = d.entity.params.report_unused("shape");
        assert_eq!(unused.len(), 1);
        assert!(unused[0].message.contains("radius"));
        assert!(sink.is_empty());
    }

    #[test]
    fn out_of_range_index_is_located_error() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let mut p = quad_params();
        p[0] = ("indices", ParamValue::Int(vec![0, 1, 2, 0, 2, 4]));
        let d = shape("trianglemesh", p);
        let e = build_shape(&d, &ctx).unwrap_err();
        assert!(e.is_error());
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("indices"));
        assert!(e.message.contains("out of range"), "{}", e.message);
        // negative
        let mut p = quad_params();
        p[0] = ("indices", ParamValue::Int(vec![0, 1, -2]));
        assert!(build_shape(&shape("trianglemesh", p), &ctx).is_err());
        // not a multiple of 3
        let mut p = quad_params();
        p[0] = ("indices", ParamValue::Int(vec![0, 1, 2, 3]));
        let d = shape("trianglemesh", p);
        let e = build_shape(&d, &ctx).unwrap_err();
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("indices"));
        // NaN position
        let mut p = quad_params();
        p[1] = ("P", ParamValue::Point3(vec![0., 0., 0., 1., f32::NAN, 0., 1., 1., 0., 0., 1., 0.]));
        let d = shape("trianglemesh", p);
        let e = build_shape(&d, &ctx).unwrap_err();
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("P"));
        // missing indices with more than 3 points
        let p = vec![quad_params().remove(1)];
        assert!(build_shape(&shape("trianglemesh", p), &ctx).is_err());
    }

    #[test]
    fn three_points_need_no_indices_and_bad_attributes_are_dropped() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let d = shape(
            "trianglemesh",
            vec![
                ("P", ParamValue::Point3(vec![0., 0., 0., 1., 0., 0., 0., 1., 0.])),
                ("N", ParamValue::Normal(vec![0., 0., 1.])),
                ("st", ParamValue::Point2(vec![0., 0., 1., 0., 0., 1., 5., 5.])),
            ],
        );
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert_eq!(m.indices, vec![[0, 1, 2]]);
        assert!(m.normals.is_none());
        assert_eq!(m.uvs.as_ref().unwrap().len(), 3);
        assert_eq!(sink.len(), 2); // N dropped, extra st
    }

    #[test]
    fn orientation_matches_pbrt_for_all_flag_combinations() {
        // A triangle with normal +z in object space.
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let p = ParamValue::Point3(vec![0., 0., 0., 1., 0., 0., 0., 1., 0.]);
        let mirror = Transform::scale([-1.0, 1.0, 1.0]).unwrap();
        for (t, swaps) in [(Transform::IDENTITY, false), (mirror, true)] {
            for ro in [false, true] {
                let d = shape_with("trianglemesh", vec![("P", p.clone())], t, ro);
                let m = build_shape(&d, &ctx).unwrap().unwrap();
                // pbrt-v3: n = cross(world p1 - p0, p2 - p0), flipped if ro ^ swaps.
                let [a, b, c] = [0, 1, 2].map(|i| m.positions[i]);
                let raw = (b - a).cross(c - a).normalize();
                let expect = if ro ^ swaps { -raw } else { raw };
                let (n, ns) = m.hit_normals(0, [1.0 / 3.0; 3]);
                assert_eq!((n, ns), (expect, expect));
                assert_eq!(m.flip_normals, ro ^ swaps);
                // Object-space +z is preserved unless ReverseOrientation.
                assert_eq!(n.z, if ro { -1.0 } else { 1.0 });
                // pbrt-v3's `Triangle::Sample` without normals: the cross product of the shape's
                // own vertex order, negated if `reverseOrientation ^ transformSwapsHandedness`.
                assert_eq!(m.sample_normal(0, [1.0 / 3.0; 3]), expect);
                // Default uvs stay attached to the original vertices.
                let uv = m.default_uvs(0);
                for (slot, orig) in uv.iter().zip(m.indices[0]) {
                    assert_eq!(*slot, [Vec2::ZERO, Vec2::X, Vec2::ONE][orig as usize]);
                }
            }
        }
    }

    #[test]
    fn alpha_parameters() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let mut p = quad_params();
        p.push(("alpha", ParamValue::Float(vec![0.0])));
        p.push((
            "shadowalpha",
            ParamValue::Texture(TextureRef { name: "leaf".into(), float: Some(3), spectrum: None }),
        ));
        let m = build_shape(&shape("trianglemesh", p), &ctx).unwrap().unwrap();
        assert_eq!(m.alpha, Some(AlphaSpec::Constant(0.0)));
        assert_eq!(m.shadow_alpha, Some(AlphaSpec::Texture(3)));
        let mut p = quad_params();
        p.push(("alpha", ParamValue::Float(vec![0.5])));
        let m = build_shape(&shape("trianglemesh", p), &ctx).unwrap().unwrap();
        assert_eq!(m.alpha, None);
        let mut p = quad_params();
        p.push(("alpha", ParamValue::Texture(TextureRef { name: "nope".into(), float: None, spectrum: Some(0) })));
        let m = build_shape(&shape("trianglemesh", p), &ctx).unwrap().unwrap();
        assert_eq!(m.alpha, None);
        assert_eq!(sink.len(), 1);
    }
}
