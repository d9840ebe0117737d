//! Shapes to world-space triangle meshes (stub: trianglemesh only; replaced by the full set).

use crate::mesh::TriangleMesh;
use glam::Vec3;
use penumbra_parser::{DiagSink, Diagnostic, ShapeDesc};

pub struct ShapeContext<'a> {
    pub warnings: &'a DiagSink,
}

pub fn build_shape(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<TriangleMesh>, Diagnostic> {
    let p = &desc.entity.params;
    if desc.entity.kind != "trianglemesh" {
        ctx.warnings.warn(Some(desc.entity.loc.clone()), format!("shape \"{}\" not supported yet", desc.entity.kind));
        p.mark_all_used();
        return Ok(None);
    }
    let pts = p.get_point3s("P").unwrap_or(&[]);
    let idx = p.get_ints("indices").unwrap_or(&[]);
    let t = desc.render_from_object.start;
    let positions: Vec<Vec3> = pts
        .iter()
        .map(|q| Vec3::from(t.apply_point([q[0] as f64, q[1] as f64, q[2] as f64]).map(|v| v as f32)))
        .collect();
    let mut indices = Vec::new();
    for c in idx.chunks_exact(3) {
        if c.iter().any(|&i| i < 0 || i as usize >= positions.len()) {
            return Err(Diagnostic::error(p.loc_of("indices").cloned(), "index out of range"));
        }
        indices.push([c[0] as u32, c[1] as u32, c[2] as u32]);
    }
    let normals = p.get_normals("N").map(|ns| {
        ns.iter()
            .map(|n| {
                Vec3::from(t.apply_normal([n[0] as f64, n[1] as f64, n[2] as f64]).map(|v| v as f32))
                    .normalize_or_zero()
            })
            .collect()
    });
    Ok(Some(TriangleMesh {
        positions,
        indices,
        normals,
        flip_normals: desc.reverse_orientation ^ t.swaps_handedness(),
        ..Default::default()
    }))
}
