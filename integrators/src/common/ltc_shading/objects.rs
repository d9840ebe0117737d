//! What the shading knows about the scene's objects, prepared once per scene: each object's
//! bounds, convexity and silhouette, triangle hierarchy and welding, and the hierarchy over
//! the occluders that the occluder search queries (see [`super::occluders`]).

use super::settings::{Mode, ShaderSettings};
use crate::common::spherical_polygon::SilhouetteMesh;
use glam::DVec3;
use penumbra_core::accel::objects::ObjectBvh;
use penumbra_core::geometry::Bounds3;
use penumbra_core::mesh::{EdgeAdjacency, TriangleMesh};

/// The scene's objects as the occluder search sees them.
pub(super) struct Objects {
    /// Mesh `i` = object `i`.
    pub(super) info: Vec<ObjectInfo>,
    /// A hierarchy over the bounds of the objects that occlude.
    pub(super) bvh: ObjectBvh,
    /// Subtract an object's triangles in front of the light as their outline.
    pub(super) merge_occluders: bool,
}

/// What the estimator knows about each object (mesh `i` = object `i`).
pub(super) struct ObjectInfo {
    pub(super) bounds: Bounds3,
    pub(super) occluder: bool,
    /// Closed and convex (proven by the builder), with its adjacency for silhouettes.
    pub(super) silhouette: Option<SilhouetteMesh>,
    /// A hierarchy over the object's triangles, for the per-triangle cone query.
    pub(super) tris: ObjectBvh,
    /// All vertices in one plane: as a light, it cannot shadow itself.
    pub(super) planar: bool,
    /// Mesh vertex index → id shared by vertices at the same position (for triangle outlines).
    pub(super) weld: Vec<u32>,
    /// A closed, consistently wound mesh (after welding; known for silhouette meshes, and for
    /// others with `mergeoccluders`): +1 when its winding normals point out of the solid, −1
    /// when in, 0 otherwise or unknown. From outside or inside, the triangles facing away from a
    /// point cover exactly the directions in which a ray from it meets the solid (every such ray
    /// leaves it through one): the others need not be subtracted.
    pub(super) closed: f64,
}

/// What a convex light mesh needs at every shading point, computed once.
pub(super) struct ConvexShape {
    pub(super) sil: SilhouetteMesh,
    /// Edge-on tolerance of its faces: 1e-9 of the mesh's extent.
    pub(super) eps: f64,
    /// (a point of the face, outward unit normal) of every non-degenerate face.
    pub(super) faces: Vec<(DVec3, DVec3)>,
    pub(super) vertices: Vec<DVec3>,
    pub(super) center: DVec3,
    /// The largest distance of a vertex from `center`.
    pub(super) radius: f64,
}

impl ConvexShape {
    pub(super) fn new(mesh: &TriangleMesh, adj: &EdgeAdjacency) -> ConvexShape {
        let faces = (0..mesh.triangle_count())
            .filter_map(|t| {
                let [a, b, c] = mesh.vertices(t).map(|v| v.as_dvec3());
                let n = (b - a).cross(c - a).normalize_or_zero();
                (n != DVec3::ZERO).then_some((a, n))
            })
            .collect();
        let vertices: Vec<DVec3> = mesh.positions.iter().map(|q| q.as_dvec3()).collect();
        let center = vertices.iter().copied().sum::<DVec3>() / vertices.len().max(1) as f64;
        let sil = SilhouetteMesh::new(mesh, adj);
        let radius = vertices.iter().map(|v| (*v - center).length()).fold(0.0, f64::max);
        ConvexShape { sil, eps: 1e-9 * mesh.extent(), faces, vertices, center, radius }
    }
}

/// The surface being shaded: its mesh and triangle, and `ωo` · its winding normal (with the
/// orientation of a closed mesh: negative when seen from inside).
#[derive(Clone, Copy)]
pub(super) struct Receiver {
    pub(super) mesh: usize,
    pub(super) tri: usize,
    pub(super) facing: f64,
}

/// Which of the light's own triangles are not occluders of the piece being shaded.
#[derive(Clone, Copy)]
pub(super) enum Skip {
    /// The whole light mesh (planar or convex lights cannot shadow themselves).
    Mesh(usize),
    /// One triangle of the light mesh (the others may shadow it).
    Triangle(usize, usize),
}

/// What `settings` needs of object `mesh` (`adjacency`: its edge adjacency, asked for only
/// when needed).
pub(super) fn object_info<'m>(
    settings: &ShaderSettings,
    mesh: &TriangleMesh,
    occluder: bool,
    adjacency: impl Fn() -> &'m EdgeAdjacency,
) -> ObjectInfo {
    let bounds = mesh.bounds();
    let shadowing = settings.shadows && occluder;
    let silhouette = match settings.mode {
        Mode::PerTriangle => None,
        _ if !shadowing => None,
        Mode::Auto => mesh.is_closed_convex_with(adjacency(), 1e-4).then(|| SilhouetteMesh::new(mesh, adjacency())),
        Mode::Silhouette => adjacency().is_closed_manifold().then(|| SilhouetteMesh::new(mesh, adjacency())),
    };
    let tris = if shadowing { ObjectBvh::over_triangles(mesh) } else { ObjectBvh::build(&[]) };
    let (weld, closed) = if shadowing && settings.merge_occluders {
        let adj = adjacency();
        (adj.weld.clone(), if adj.is_closed_manifold() { mesh.winding_sign() } else { 0.0 })
    } else {
        // (Silhouette meshes are closed: their orientation says which side is inside.)
        (Vec::new(), if silhouette.is_some() { mesh.winding_sign() } else { 0.0 })
    };
    ObjectInfo { bounds, occluder, silhouette, tris, planar: mesh.is_planar(), weld, closed }
}
