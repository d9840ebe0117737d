//! pbrt-v3's alpha cut-outs: the `alpha` and `shadowalpha` float textures of `trianglemesh`
//! and `plymesh` shapes (the only shapes that read them in pbrt-v3; elsewhere they are unused
//! parameters), tested by every ray query of the hierarchy ([`HitFilter`]).
//!
//! pbrt-v3 (`Triangle::Intersect`, `Triangle::IntersectP`) evaluates the texture at a
//! candidate hit — its point, its interpolated (u, v) (the mesh's or pbrt-v3's default
//! per-triangle ones), no ray differentials — and discards the hit where the value is exactly
//! 0: closest-hit queries test `alpha`, occlusion queries `alpha` and then `shadowalpha`.
//! There is no partial transparency in pbrt-v3.

use crate::accel::{Hit, HitFilter};
use crate::geometry::interpolate;
use crate::mesh::{AlphaSpec, TriangleMesh};
use crate::texture::{FloatParam, TextureEvalContext, Textures};
use glam::{Vec2, Vec3};
use penumbra_parser::{DiagSink, Diagnostic};
use std::sync::Arc;

/// What the alpha test needs of one cut-out mesh: its geometry (copied: the test lives in
/// the hierarchy, which does not borrow the scene) and its textures.
struct CutoutMesh {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    /// Per triangle, its vertices' (u, v) (the mesh's, or pbrt-v3's defaults).
    uvs: Vec<[Vec2; 3]>,
    alpha: Option<FloatParam>,
    shadow_alpha: Option<FloatParam>,
}

/// The alpha test of a scene's cut-out meshes, by mesh index.
pub struct CutoutTest {
    meshes: Vec<Option<CutoutMesh>>,
    textures: Arc<Textures>,
}

/// Builds (in `textures`) the alpha textures `meshes` use; `true` when some mesh has one.
pub(super) fn build_textures(
    meshes: &[TriangleMesh],
    textures: &mut Textures,
    warnings: &DiagSink,
) -> Result<bool, Diagnostic> {
    let mut any = false;
    for m in meshes {
        for spec in [&m.alpha, &m.shadow_alpha].into_iter().flatten() {
            any = true;
            if let AlphaSpec::Texture(i) = spec {
                textures.ensure(*i, warnings)?;
            }
        }
    }
    Ok(any)
}

fn param(spec: &Option<AlphaSpec>) -> Option<FloatParam> {
    spec.as_ref().map(|s| match s {
        AlphaSpec::Constant(v) => FloatParam::Const(*v),
        AlphaSpec::Texture(i) => FloatParam::Tex(*i),
    })
}

impl CutoutTest {
    /// The test of `meshes`' cut-outs, their textures built by [`build_textures`]; `None`
    /// when no mesh has one.
    pub fn new(meshes: &[TriangleMesh], textures: Arc<Textures>) -> Option<CutoutTest> {
        let per_mesh: Vec<Option<CutoutMesh>> = meshes
            .iter()
            .map(|m| {
                (m.alpha.is_some() || m.shadow_alpha.is_some()).then(|| CutoutMesh {
                    positions: m.positions.clone(),
                    indices: m.indices.clone(),
                    uvs: (0..m.indices.len()).map(|t| m.default_uvs(t)).collect(),
                    alpha: param(&m.alpha),
                    shadow_alpha: param(&m.shadow_alpha),
                })
            })
            .collect();
        per_mesh.iter().any(Option::is_some).then_some(CutoutTest { meshes: per_mesh, textures })
    }

    /// The texture context pbrt-v3's alpha test evaluates at: the hit point, its (u, v) and
    /// the triangle's normal, without differentials.
    fn context(m: &CutoutMesh, tri: usize, b: [f32; 3]) -> Option<TextureEvalContext> {
        let idx = m.indices.get(tri)?;
        let pv = idx.map(|i| m.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        let n = (pv[1] - pv[0]).cross(pv[2] - pv[0]).normalize_or_zero();
        Some(TextureEvalContext { p: interpolate(pv, b), n, uv: interpolate(m.uvs[tri], b), ..Default::default() })
    }
}

impl HitFilter for CutoutTest {
    fn accept(&self, hit: &Hit, shadow: bool) -> bool {
        let Some(Some(m)) = self.meshes.get(hit.mesh as usize) else { return true };
        let masks = [m.alpha, if shadow { m.shadow_alpha } else { None }];
        if masks.iter().all(Option::is_none) {
            return true;
        }
        let Some(ctx) = Self::context(m, hit.tri as usize, hit.b) else { return true };
        masks.into_iter().flatten().all(|p| self.textures.eval_float(p, &ctx) != 0.0)
    }
}
