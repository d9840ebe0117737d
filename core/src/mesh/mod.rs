//! World-space triangle meshes: every shape becomes one of these.
//!
//! # Orientation: how to get pbrt-v3's normals
//!
//! pbrt-v3 computes, for a ray hit, a geometric normal `n` and a shading normal `ns`
//! (`SurfaceInteraction::n` / `shading.n`), and for a point an area light samples
//! (`Shape::Sample`) a normal whose side is the one that emits. Its rules differ between
//! shapes, and between hits and samples; a [`TriangleMesh`] reproduces them with its
//! [`NormalRule`] (see [`TriangleMesh::hit_normals`] and [`TriangleMesh::sample_normal`],
//! which implement exactly this; `flip` is `ReverseOrientation` XOR the transform's
//! handedness swap, `ro` is `ReverseOrientation` alone, `N` the interpolated per-vertex
//! normal, world space, as stored):
//!
//! | mesh | hit `ns` | hit `n` | sample normal |
//! |---|---|---|---|
//! | triangles, no `N` | `ng` | `ng` | `ng` |
//! | triangles with `N` | `N`, negated if `ro` | `faceforward(ng, ns)` | `faceforward(ng, N)` (`ro` ignored) |
//! | quadrics | `N`, negated if `flip` | `faceforward(ng, ns)` | `N`, negated if `ro` |
//!
//! where `ng = normalize((p1 - p0) × (p2 - p0))` with the *stored* winding. (A triangle mesh
//! with tangents `S` but no `N` has `n = ns = ng`, negated if `ro`.) The builders
//! (`crate::shapes`) choose the stored winding so that:
//! * for meshes without per-vertex normals, `ng` *is* pbrt-v3's `n` (the winding is
//!   reversed exactly when `flip`);
//! * for meshes with normals, the winding agrees with `N` negated if `flip` on the
//!   (area-weighted) majority of triangles — for tessellated quadrics all of them.
//!
//! So a consumer that only needs the "outside" of a surface (silhouettes, convexity) may use
//! the winding directly. pbrt-v3 is not consistent: a quadric under a mirroring transform is
//! hit on its inside but emits (is sampled) on its outside, and a triangle mesh with normals
//! and `ReverseOrientation` is hit on one side and sampled on the other. penumbra reproduces
//! both, so that its images are pbrt-v3's (`docs/real-scenes.md`).

use glam::{Vec2, Vec3};

mod adjacency;
pub mod curve;
pub mod hash;
mod predicates;

pub use adjacency::{Edge, EdgeAdjacency, BOUNDARY};
pub use predicates::PlanarOutline;

/// pbrt-v3's `"texture alpha"` / `"float alpha"` (and `shadowalpha`) cut-outs.
///
/// pbrt-v3 discards a hit where the alpha texture evaluates to exactly `0`
/// (no stochastic transparency). A constant `"float alpha"` only creates a mask
/// when it is `0` (the shape is then invisible); any other constant means "no mask"
/// and is represented by `None`.
#[derive(Clone, Debug, PartialEq)]
pub enum AlphaSpec {
    /// A constant alpha; the builders only produce `Constant(0.0)` (invisible).
    Constant(f32),
    /// Index into `SceneDescription::textures` of the float texture to evaluate
    /// at the hit's (u, v) (the triangle's interpolated `uvs`, or pbrt-v3's default ones).
    Texture(usize),
}

/// Which of pbrt-v3's normal rules a mesh follows (module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NormalRule {
    /// pbrt-v3's `Triangle` (`trianglemesh`, `plymesh`, `loopsubdiv`, `heightfield`, `nurbs`).
    #[default]
    Triangle,
    /// pbrt-v3's analytic quadrics (`sphere`, `disk`, `cylinder`, `cone`, `paraboloid`,
    /// `hyperboloid`), tessellated, with their analytic normals as `normals`.
    Quadric,
}

/// The parameters of a pbrt-v3 quadric that area lights sample analytically, as pbrt-v3's
/// shape classes hold them (object space, after pbrt-v3's clamping; angles in radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum QuadricShape {
    Sphere { radius: f64, z_min: f64, z_max: f64, phi_max: f64 },
    Disk { height: f64, radius: f64, inner_radius: f64, phi_max: f64 },
    Cylinder { radius: f64, z_min: f64, z_max: f64, phi_max: f64 },
}

impl QuadricShape {
    /// pbrt-v3's `Shape::Area()`: in object space, whatever the transform.
    pub fn area(&self) -> f64 {
        match *self {
            QuadricShape::Sphere { radius, z_min, z_max, phi_max } => phi_max * radius * (z_max - z_min),
            QuadricShape::Disk { radius, inner_radius, phi_max, .. } => {
                phi_max * 0.5 * (radius * radius - inner_radius * inner_radius)
            }
            QuadricShape::Cylinder { radius, z_min, z_max, phi_max } => (z_max - z_min) * radius * phi_max,
        }
    }

    /// Whether pbrt-v3's `Shape::Sample(u)` covers exactly this surface (it samples a whole
    /// sphere or a whole disk whatever `zmin`, `zmax`, `phimax` or `innerradius` cut away).
    pub fn sampled_whole(&self) -> bool {
        let full = |phi_max: f64| phi_max >= std::f64::consts::TAU;
        match *self {
            QuadricShape::Sphere { radius, z_min, z_max, phi_max } => {
                full(phi_max) && z_min <= -radius && z_max >= radius
            }
            QuadricShape::Disk { inner_radius, phi_max, .. } => full(phi_max) && inner_radius <= 0.0,
            QuadricShape::Cylinder { .. } => true,
        }
    }
}

/// A quadric's own description beside its tessellation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric {
    pub shape: QuadricShape,
    /// The shape's object-to-world transform.
    pub world_from_object: penumbra_parser::Transform,
    /// How far (object space) the tessellation may lie from the analytic surface (see
    /// `crate::shapes`): a point sampled on the analytic surface is this close to the mesh.
    pub deviation: f64,
}

/// A triangle mesh in world (render) space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    /// Triangle vertex indices. The geometric normal `(p1 - p0) × (p2 - p0)` points
    /// to pbrt-v3's "outside" (after `ReverseOrientation` and handedness have been
    /// applied); see the module documentation for the exact rule.
    pub indices: Vec<[u32; 3]>,
    /// Per-vertex shading normals in world space (unit length, transformed by the
    /// inverse transpose), *before* the `flip_normals` negation — as pbrt-v3 stores them.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates, if the shape has them (else pbrt-v3's defaults
    /// apply: see [`TriangleMesh::default_uvs`]).
    pub uvs: Option<Vec<Vec2>>,
    /// Per-vertex tangents (`S` in pbrt-v3), transformed as vectors, not normalised.
    pub tangents: Option<Vec<Vec3>>,
    /// pbrt-v3's `ReverseOrientation` XOR `transformSwapsHandedness`: the shading
    /// normals must be negated (step 3 of the module documentation).
    pub flip_normals: bool,
    /// The shape's `ReverseOrientation` (needed for pbrt-v3's `Sample` normals).
    pub reverse_orientation: bool,
    /// Whether the stored winding is the reverse of the shape's own vertex order
    /// (stored `[a, c, b]` for a given `[a, b, c]`); matters only for pbrt-v3's
    /// default per-triangle (u, v) and for [`TriangleMesh::sample_normal`].
    pub winding_reversed: bool,
    /// `"alpha"` cut-out: applies to every ray (camera, indirect and shadow rays).
    pub alpha: Option<AlphaSpec>,
    /// `"shadowalpha"` cut-out: applies to shadow rays only.
    pub shadow_alpha: Option<AlphaSpec>,
    /// Which pbrt-v3 shape the mesh stands for, as far as its normals go.
    pub normal_rule: NormalRule,
    /// The hit's geometric normal is the analytic normal (the per-vertex `normals`), not the
    /// triangle's: pbrt-v3's hyperboloid, whose `∂p/∂u × ∂p/∂v` uses the segment `p1 → p2`
    /// and so is not normal to the surface it intersects (up to 160° off on public scenes);
    /// BSDFs decide reflection against it, as pbrt-v3's do.
    pub analytic_ng: bool,
    /// With `analytic_ng`: the surface's own normals per vertex (unoriented), which decide
    /// whether a ray leaving a hit passes through the surface (see
    /// [`crate::interaction::SurfaceInteraction::wall`]).
    pub surface_normals: Option<Vec<Vec3>>,
    /// For a sphere, disk or cylinder: its parameters, for what pbrt-v3 computes on the
    /// analytic shape (area-light sampling).
    pub quadric: Option<Quadric>,
    /// For a `curve` shape: the curve, intersected as pbrt-v3 intersects it (the mesh then has
    /// no triangles; see [`curve`]).
    pub curves: Option<std::sync::Arc<curve::Curves>>,
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
    /// Total surface area (accumulated in f64).
    pub fn total_area(&self) -> f64 {
        (0..self.indices.len()).map(|t| self.area(t) as f64).sum()
    }
    /// `ReverseOrientation XOR flip_normals`.
    pub fn swaps_handedness(&self) -> bool {
        self.flip_normals ^ self.reverse_orientation
    }

    /// Normalised `(p1 - p0) × (p2 - p0)` with the stored winding (zero for a degenerate triangle).
    pub fn winding_normal(&self, tri: usize) -> Vec3 {
        let [a, b, c] = self.vertices(tri);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// The interpolated per-vertex normal at barycentrics `b` (unit; `None` without normals
    /// or where it vanishes).
    pub fn interpolated_normal(&self, tri: usize, b: [f32; 3]) -> Option<Vec3> {
        let ns = self.normals.as_ref()?;
        let [i0, i1, i2] = self.indices[tri].map(|i| i as usize);
        let n = (b[0] * ns[i0] + b[1] * ns[i1] + b[2] * ns[i2]).normalize_or_zero();
        (n != Vec3::ZERO && n.is_finite()).then_some(n)
    }

    /// The sign pbrt-v3 gives the per-vertex normals of a hit's shading normal: `-1` when
    /// they are negated (`ReverseOrientation` for triangles, `ReverseOrientation` XOR the
    /// handedness swap for quadrics).
    pub fn hit_normal_sign(&self) -> f32 {
        let negate = match self.normal_rule {
            NormalRule::Triangle => self.reverse_orientation,
            NormalRule::Quadric => self.flip_normals,
        };
        if negate {
            -1.0
        } else {
            1.0
        }
    }

    /// The sign pbrt-v3 gives the per-vertex normals of a sampled point's normal (`-1` for a
    /// quadric with `ReverseOrientation`; triangles ignore it).
    pub fn sample_normal_sign(&self) -> f32 {
        if self.normal_rule == NormalRule::Quadric && self.reverse_orientation {
            -1.0
        } else {
            1.0
        }
    }

    /// pbrt-v3's geometric and shading normals `(n, ns)` of a hit at barycentrics `b`
    /// (weights of the stored vertices 0, 1, 2); see the module documentation.
    pub fn hit_normals(&self, tri: usize, b: [f32; 3]) -> (Vec3, Vec3) {
        let ng = self.winding_normal(tri);
        match self.interpolated_normal(tri, b) {
            Some(ns) => {
                let ns = ns * self.hit_normal_sign();
                (if ng.dot(ns) < 0.0 { -ng } else { ng }, ns)
            }
            None if self.normals.is_none() && self.tangents.is_some() && self.reverse_orientation => (-ng, -ng),
            None => (ng, ng),
        }
    }

    /// pbrt-v3's `Shape::Sample` normal at barycentrics `b`, flat (the triangle's own plane)
    /// and on the side that emits; see the module documentation.
    pub fn sample_normal(&self, tri: usize, b: [f32; 3]) -> Vec3 {
        let ng = self.winding_normal(tri);
        match self.interpolated_normal(tri, b) {
            Some(ns) if ng.dot(ns * self.sample_normal_sign()) < 0.0 => -ng,
            _ => ng,
        }
    }

    /// The (u, v) of the three stored vertices of `tri`: the mesh's `uvs`, or
    /// pbrt-v3's defaults (0,0), (1,0), (1,1) in the shape's own vertex order.
    pub fn default_uvs(&self, tri: usize) -> [Vec2; 3] {
        if let Some(uv) = &self.uvs {
            return self.indices[tri].map(|i| uv[i as usize]);
        }
        if self.winding_reversed {
            [Vec2::new(0.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0)]
        } else {
            [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0)]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> TriangleMesh {
        let positions: Vec<Vec3> =
            (0..8).map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32)).collect();
        // Quads with outward counter-clockwise winding.
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let mut indices = vec![];
        for q in quads {
            indices.push([q[0], q[1], q[2]]);
            indices.push([q[0], q[2], q[3]]);
        }
        TriangleMesh { positions, indices, ..Default::default() }
    }

    fn torus(n: usize, m: usize) -> TriangleMesh {
        let (big, small) = (1.0f32, 0.3f32);
        let mut positions = vec![];
        for i in 0..n {
            for j in 0..m {
                let (su, cu) = (std::f32::consts::TAU * i as f32 / n as f32).sin_cos();
                let (sv, cv) = (std::f32::consts::TAU * j as f32 / m as f32).sin_cos();
                positions.push(Vec3::new((big + small * cv) * cu, (big + small * cv) * su, small * sv));
            }
        }
        let id = |i: usize, j: usize| ((i % n) * m + (j % m)) as u32;
        let mut indices = vec![];
        for i in 0..n {
            for j in 0..m {
                indices.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                indices.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriangleMesh { positions, indices, ..Default::default() }
    }

    #[test]
    fn cube_is_closed_convex() {
        let c = cube();
        for t in 0..12 {
            // outward: normal points away from the centre
            let [a, b, cc] = c.vertices(t);
            let centroid = (a + b + cc) / 3.0;
            assert!(c.winding_normal(t).dot(centroid - Vec3::splat(0.5)) > 0.0);
        }
        let adj = c.build_adjacency();
        assert_eq!(adj.edges.len(), 18);
        assert_eq!(adj.boundary_edges(), 0);
        assert!(c.is_closed_convex(1e-5));
        // Inward winding is closed but not convex "with outward normals".
        let mut inv = c.clone();
        for t in &mut inv.indices {
            t.swap(1, 2);
        }
        assert!(!inv.is_closed_convex(1e-5));
    }

    #[test]
    fn open_cube_is_not_closed() {
        let mut c = cube();
        c.indices.truncate(10);
        let adj = c.build_adjacency();
        assert_eq!(adj.boundary_edges(), 4);
        assert!(!adj.is_closed_manifold());
        assert!(!c.is_closed_convex(1e-5));
    }

    #[test]
    fn welding_joins_duplicated_seam_vertices() {
        // Split the cube into per-face vertices: still closed after welding.
        let c = cube();
        let mut s = TriangleMesh::default();
        for t in 0..c.triangle_count() {
            let base = s.positions.len() as u32;
            s.positions.extend(c.vertices(t));
            s.indices.push([base, base + 1, base + 2]);
        }
        assert_eq!(s.build_adjacency().welded_count, 8);
        assert!(s.is_closed_convex(1e-5));
    }

    #[test]
    fn torus_is_closed_not_convex() {
        let t = torus(24, 12);
        let adj = t.build_adjacency();
        assert!(adj.is_closed_manifold());
        assert_eq!(adj.edges.len(), 3 * 24 * 12);
        assert!(!t.is_closed_convex(1e-3));
    }

    /// The table of the module documentation, for a triangle whose stored winding gives +z
    /// and whose vertex normals are +z, under every flag: pbrt-v3's `Triangle::Intersect` /
    /// `Triangle::Sample` and the quadrics' `Intersect` / `Sample` (checked against renders
    /// of the real pbrt-v3 in `tests/real_scenes.rs`).
    #[test]
    fn hit_and_sample_normals_follow_pbrt_rules() {
        let b = [1.0 / 3.0; 3];
        for rule in [NormalRule::Triangle, NormalRule::Quadric] {
            for (ro, swaps) in [(false, false), (true, false), (false, true), (true, true)] {
                let mut m = TriangleMesh {
                    positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
                    indices: vec![[0, 1, 2]],
                    flip_normals: ro ^ swaps,
                    reverse_orientation: ro,
                    normal_rule: rule,
                    ..Default::default()
                };
                assert!(m.swaps_handedness() == swaps);
                if rule == NormalRule::Triangle {
                    assert_eq!(m.hit_normals(0, b), (Vec3::Z, Vec3::Z));
                    assert_eq!(m.sample_normal(0, b), Vec3::Z);
                    m.tangents = Some(vec![Vec3::X; 3]);
                    let n = if ro { -Vec3::Z } else { Vec3::Z };
                    assert_eq!(m.hit_normals(0, b), (n, n));
                    m.tangents = None;
                }
                m.normals = Some(vec![Vec3::Z; 3]);
                let hit_flip = match rule {
                    NormalRule::Triangle => ro,
                    NormalRule::Quadric => ro ^ swaps,
                };
                let hit = if hit_flip { -Vec3::Z } else { Vec3::Z };
                assert_eq!(m.hit_normals(0, b), (hit, hit), "{rule:?} ro {ro} swaps {swaps}");
                let sample_flip = rule == NormalRule::Quadric && ro;
                assert_eq!(m.sample_normal(0, b), if sample_flip { -Vec3::Z } else { Vec3::Z });
            }
        }
    }
}
