//! `Shape "heightfield"`: `nu` × `nv` heights `Pz` over [0,1]², as pbrt-v3.

use super::{loc_or_entity, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let nu = ps.get_one_int("nu", -1);
    let nv = ps.get_one_int("nv", -1);
    let z = ps.get_floats("Pz");
    if nu < 2 || nv < 2 {
        return Err(Diagnostic::error(
            loc_or_entity(desc, if nu < 2 { "nu" } else { "nv" }),
            format!("heightfield: \"nu\" and \"nv\" must be at least 2 (got {nu} × {nv})"),
        ));
    }
    let Some(z) = z else {
        return Err(Diagnostic::error(Some(desc.entity.loc.clone()), "heightfield: \"Pz\" not provided"));
    };
    let (nu, nv) = (nu as usize, nv as usize);
    if nu.checked_mul(nv) != Some(z.len()) {
        return Err(Diagnostic::error(
            loc_or_entity(desc, "Pz"),
            format!("heightfield: {} \"Pz\" values given, {nu} × {nv} expected", z.len()),
        ));
    }
    if let Some(i) = z.iter().position(|v| !v.is_finite()) {
        return Err(Diagnostic::error(
            loc_or_entity(desc, "Pz"),
            format!("heightfield: \"Pz\" value {i} is not finite"),
        ));
    }
    if nu * nv > u32::MAX as usize / 2 {
        return Err(Diagnostic::error(loc_or_entity(desc, "Pz"), "heightfield: too many vertices"));
    }
    ctx.budget.charge(2 * (nu - 1) * (nv - 1), "shape \"heightfield\"", Some(desc.entity.loc.clone()))?;
    let mut p = Vec::with_capacity(nu * nv);
    let mut uv = Vec::with_capacity(nu * nv);
    for y in 0..nv {
        for x in 0..nu {
            let (fx, fy) = (x as f32 / (nu - 1) as f32, y as f32 / (nv - 1) as f32);
            p.push([fx as f64, fy as f64, z[x + y * nu] as f64]);
            uv.push([fx, fy]);
        }
    }
    let vert = |x: usize, y: usize| (x + y * nu) as u32;
    let mut tris = Vec::with_capacity(2 * (nu - 1) * (nv - 1));
    for y in 0..nv - 1 {
        for x in 0..nu - 1 {
            tris.push([vert(x, y), vert(x + 1, y), vert(x + 1, y + 1)]);
            tris.push([vert(x, y), vert(x + 1, y + 1), vert(x, y + 1)]);
        }
    }
    Ok(Some(ObjMesh { p, uv: Some(uv), tris, ..Default::default() }))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use crate::parser::ParamValue;

    #[test]
    fn heightfield_grid() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let d = shape(
            "heightfield",
            vec![
                ("nu", ParamValue::Int(vec![3])),
                ("nv", ParamValue::Int(vec![2])),
                ("Pz", ParamValue::Float(vec![0., 0., 0., 0., 0., 0.])),
            ],
        );
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangle_count(), 4);
        assert!((m.total_area() - 1.0).abs() < 1e-6);
        assert_eq!(m.positions[5], Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(m.uvs.as_ref().unwrap()[1], Vec2::new(0.5, 0.0));
        assert!(m.winding_normal(0).z > 0.0);
        // wrong count
        let d = shape(
            "heightfield",
            vec![
                ("nu", ParamValue::Int(vec![3])),
                ("nv", ParamValue::Int(vec![100000])),
                ("Pz", ParamValue::Float(vec![0.; 6])),
            ],
        );
        let e = build_shape(&d, &ctx).unwrap_err();
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("Pz"));
    }
}
