//! World-space triangle meshes: every shape becomes one of these.

use glam::{Vec2, Vec3};

/// A triangle mesh in world (render) space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    /// Triangle vertex indices, counter-clockwise seen from the side the
    /// geometric normal `(p1 - p0) × (p2 - p0)` points to (after `ReverseOrientation`
    /// and handedness have been applied, the normal points "outside").
    pub indices: Vec<[u32; 3]>,
    /// Per-vertex shading normals, if the shape has them.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates, if the shape has them (else pbrt-v3's defaults apply).
    pub uvs: Option<Vec<Vec2>>,
    /// Per-vertex tangents (`S` in pbrt-v3), if given.
    pub tangents: Option<Vec<Vec3>>,
    /// pbrt-v3's `ReverseOrientation` XOR `transformSwapsHandedness`: flips the
    /// geometric normal relative to the winding when interpreting shading normals.
    pub flip_normals: bool,
}

impl TriangleMesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
    pub fn vertices(&self, tri: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[tri];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }
    pub fn area(&self, tri: usize) -> f32 {
        let [a, b, c] = self.vertices(tri);
        0.5 * (b - a).cross(c - a).length()
    }
}
