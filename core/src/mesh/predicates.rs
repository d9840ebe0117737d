//! Shape predicates of a mesh: bounds, planarity, winding orientation, closed convexity,
//! and the outline of a planar mesh (one simple polygon).

use super::{EdgeAdjacency, TriangleMesh, BOUNDARY};
use crate::geometry::Bounds3;
use glam::{DVec3, Vec3};

/// A planar mesh as one simple polygon: see [`TriangleMesh::planar_outline`].
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarOutline {
    /// The boundary loop (world space), in the triangles' winding.
    pub outline: Vec<DVec3>,
    /// Unit normal of the plane, along the winding normals.
    pub normal: DVec3,
    /// A point of the plane: the first vertex of `largest`.
    pub origin: DVec3,
    /// The largest triangle (it defines the plane).
    pub largest: usize,
}

fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

impl TriangleMesh {
    /// The bounds of all of the mesh's vertices.
    pub fn bounds(&self) -> Bounds3 {
        let mut b = Bounds3::EMPTY;
        for q in &self.positions {
            b.extend(*q);
        }
        b
    }

    /// The length of the bounds' diagonal.
    pub fn extent(&self) -> f64 {
        let b = self.bounds();
        (b.max - b.min).length() as f64
    }

    /// The triangle of largest area (`None` without triangles; the last of equal ones).
    fn largest_triangle(&self) -> Option<usize> {
        (0..self.triangle_count()).max_by(|a, b| self.area(*a).total_cmp(&self.area(*b)))
    }

    /// Whether every vertex lies within 1e-6 of the mesh's extent from the plane of its
    /// largest triangle (true without triangles, false when that triangle is degenerate).
    pub fn is_planar(&self) -> bool {
        let Some(t) = self.largest_triangle() else {
            return true;
        };
        let [a, b, c] = self.vertices(t).map(d3);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if n == DVec3::ZERO {
            return false;
        }
        let bounds = self.bounds();
        let tol = 1e-6 * (bounds.max - bounds.min).length() as f64;
        self.positions.iter().all(|p| (d3(*p) - a).dot(n).abs() <= tol)
    }

    /// For a closed, consistently wound mesh: +1 when its winding normals point outwards
    /// (positive enclosed volume), −1 inwards, 0 when the volume is too small to tell.
    pub fn winding_sign(&self) -> f64 {
        let (mut vol, mut scale) = (0.0f64, 0.0f64);
        let c = self.positions.first().map(|q| d3(*q)).unwrap_or(DVec3::ZERO);
        for t in 0..self.triangle_count() {
            let [a, b, d] = self.vertices(t).map(|q| d3(q) - c);
            vol += a.dot(b.cross(d));
            scale += a.length() * b.length() * d.length();
        }
        if vol.abs() > 1e-9 * scale {
            vol.signum()
        } else {
            0.0
        }
    }

    /// The mesh as one simple planar polygon, when it is one: at least two triangles, planar
    /// ([`Self::is_planar`]), every non-degenerate triangle wound along the largest one's
    /// normal, manifold and consistently oriented ([`EdgeAdjacency`] `adj` of this mesh), a
    /// single boundary loop without pinches, enclosing exactly the triangles' area (no
    /// overlaps or folds, to 1e-6). The outline starts at the smallest welded id (the same on
    /// every run).
    pub fn planar_outline(&self, adj: &EdgeAdjacency) -> Option<PlanarOutline> {
        if self.triangle_count() < 2 || !self.is_planar() {
            return None;
        }
        let t0 = self.largest_triangle()?;
        let [a, b, c] = self.vertices(t0).map(d3);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        if normal == DVec3::ZERO {
            return None;
        }
        let tri_area = self.wound_area(normal)?;
        if adj.non_manifold_edges() > 0 || adj.edges.iter().any(|e| e.count == 2 && !e.consistent) {
            return None;
        }
        let outline = boundary_loop(self, adj)?;
        // No overlaps or folds: the outline encloses exactly the triangles' area.
        let mut vec_area = DVec3::ZERO;
        for i in 0..outline.len() {
            vec_area += outline[i].cross(outline[(i + 1) % outline.len()]);
        }
        let outline_area = 0.5 * vec_area.dot(normal);
        if !((outline_area - tri_area).abs() <= 1e-6 * tri_area) {
            return None;
        }
        Some(PlanarOutline { outline, normal, origin: a, largest: t0 })
    }

    /// The total area of the non-degenerate triangles when every one is wound along
    /// `normal`; `None` otherwise.
    fn wound_area(&self, normal: DVec3) -> Option<f64> {
        let mut area = 0.0;
        for t in 0..self.triangle_count() {
            let [p0, p1, p2] = self.vertices(t).map(d3);
            let w = (p1 - p0).cross(p2 - p0);
            if w.length() == 0.0 {
                continue;
            }
            if w.dot(normal) <= 0.0 {
                return None;
            }
            area += 0.5 * w.length();
        }
        Some(area)
    }

    /// Whether the mesh, after welding by position, is a closed, consistently
    /// oriented 2-manifold (every edge shared by exactly two triangles traversing
    /// it in opposite directions) and convex with outward winding: every vertex
    /// lies on or behind every triangle's plane, within `rel_tol` times the
    /// bounding-box diagonal.
    ///
    /// The test is exact (all vertex/plane pairs) up to 10⁸ pairs; beyond that it
    /// checks every edge's dihedral angle (local convexity) and connectivity, which
    /// for a closed connected embedded surface implies convexity (Tietze–Nakajima).
    pub fn is_closed_convex(&self, rel_tol: f32) -> bool {
        self.is_closed_convex_with(&self.build_adjacency(), rel_tol)
    }

    /// [`Self::is_closed_convex`] with the mesh's adjacency already built.
    pub fn is_closed_convex_with(&self, adj: &EdgeAdjacency, rel_tol: f32) -> bool {
        if !adj.is_closed_manifold() {
            return false;
        }
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let tol = (rel_tol.max(0.0) * (hi - lo).length()) as f64;
        if !tol.is_finite() {
            return false;
        }
        let p64 = |p: Vec3| [p.x as f64, p.y as f64, p.z as f64];
        let planes: Vec<([f64; 3], f64)> = (0..self.indices.len())
            .filter_map(|t| {
                let [a, b, c] = self.vertices(t).map(p64);
                let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if len <= 0.0 || !len.is_finite() {
                    return None; // degenerate triangles define no plane
                }
                let n = [n[0] / len, n[1] / len, n[2] / len];
                Some((n, n[0] * a[0] + n[1] * a[1] + n[2] * a[2]))
            })
            .collect();
        let behind = |(n, d): &([f64; 3], f64), p: [f64; 3]| n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - d <= tol;
        // Distinct welded positions.
        let mut verts = vec![[0.0f64; 3]; adj.welded_count];
        for (i, w) in adj.weld.iter().enumerate() {
            verts[*w as usize] = p64(self.positions[i]);
        }
        if (planes.len() as u64) * (verts.len() as u64) <= 100_000_000 {
            return planes.iter().all(|pl| verts.iter().all(|v| behind(pl, *v)));
        }
        // Local convexity at every edge plus connectivity.
        let plane_of = |t: u32| -> Option<([f64; 3], f64)> {
            let [a, b, c] = self.vertices(t as usize).map(p64);
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            (len > 0.0 && len.is_finite()).then(|| {
                let n = [n[0] / len, n[1] / len, n[2] / len];
                (n, n[0] * a[0] + n[1] * a[1] + n[2] * a[2])
            })
        };
        for e in &adj.edges {
            for (s, o) in [(0, 1), (1, 0)] {
                if let Some(pl) = plane_of(e.tris[s]) {
                    for &vi in &self.indices[e.tris[o] as usize] {
                        if !behind(&pl, p64(self.positions[vi as usize])) {
                            return false;
                        }
                    }
                }
            }
        }
        // Connectivity over triangles.
        let mut seen = vec![false; self.indices.len()];
        let mut stack = vec![0usize];
        seen[0] = true;
        let mut count = 1;
        while let Some(t) = stack.pop() {
            for &ei in &adj.tri_edges[t] {
                if ei == u32::MAX {
                    continue;
                }
                for &o in &adj.edges[ei as usize].tris {
                    if o != BOUNDARY && !seen[o as usize] {
                        seen[o as usize] = true;
                        count += 1;
                        stack.push(o as usize);
                    }
                }
            }
        }
        count == self.indices.len()
    }
}

/// The boundary edges of `adj` chained in their triangles' winding into one loop of
/// positions, from the smallest welded id (a HashMap's order is not the same on every run);
/// `None` for a vertex where the boundary pinches or for more than one loop.
fn boundary_loop(mesh: &TriangleMesh, adj: &EdgeAdjacency) -> Option<Vec<DVec3>> {
    let mut pos = vec![DVec3::ZERO; adj.welded_count];
    for (i, w) in adj.weld.iter().enumerate() {
        pos[*w as usize] = d3(mesh.positions[i]);
    }
    let mut next = std::collections::HashMap::new();
    for e in adj.edges.iter().filter(|e| e.count == 1) {
        if next.insert(e.v[0], e.v[1]).is_some() {
            return None; // a vertex where the boundary pinches
        }
    }
    let &start = next.keys().min()?;
    let mut outline = vec![pos[start as usize]];
    let mut cur = next[&start];
    while cur != start {
        outline.push(pos[cur as usize]);
        cur = *next.get(&cur)?;
        if outline.len() > next.len() {
            return None;
        }
    }
    if outline.len() != next.len() {
        return None; // more than one boundary loop (holes, several pieces)
    }
    Some(outline)
}
