//! Edge adjacency of a position-welded mesh (silhouettes, closedness, outlines).

use super::hash::WordHash;
use super::TriangleMesh;
use glam::Vec3;
use std::collections::HashMap;

/// Marker for "no triangle on this side" in [`Edge::tris`].
pub const BOUNDARY: u32 = u32::MAX;

/// An undirected edge of the position-welded mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Edge {
    /// Welded vertex ids, in the direction `tris[0]` traverses the edge.
    pub v: [u32; 2],
    /// The first two incident triangles; `tris[1] == BOUNDARY` for a boundary edge.
    pub tris: [u32; 2],
    /// Number of incident triangles (1 boundary, 2 manifold, more: non-manifold).
    pub count: u32,
    /// Whether `tris[1]` traverses the edge in the opposite direction (consistent orientation).
    pub consistent: bool,
}

/// Edge adjacency after welding vertices with identical positions.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgeAdjacency {
    /// For each mesh vertex, its welded id.
    pub weld: Vec<u32>,
    /// Number of distinct positions.
    pub welded_count: usize,
    pub edges: Vec<Edge>,
    /// For each triangle, its edges (p0p1, p1p2, p2p0) as indices into `edges`;
    /// `u32::MAX` for an edge whose two ends weld together (degenerate triangle).
    pub tri_edges: Vec<[u32; 3]>,
}

impl EdgeAdjacency {
    pub fn boundary_edges(&self) -> usize {
        self.edges.iter().filter(|e| e.count == 1).count()
    }
    pub fn non_manifold_edges(&self) -> usize {
        self.edges.iter().filter(|e| e.count > 2).count()
    }
    /// Every edge has exactly two consistently oriented triangles.
    pub fn is_closed_manifold(&self) -> bool {
        !self.edges.is_empty() && self.edges.iter().all(|e| e.count == 2 && e.consistent)
    }
}

fn weld_key(p: Vec3) -> [u32; 3] {
    // +0.0 so that -0.0 and 0.0 weld together.
    [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()]
}

impl TriangleMesh {
    /// Edge adjacency after welding vertices with bit-identical positions
    /// (so seams duplicated for texture coordinates do not count as boundaries).
    pub fn build_adjacency(&self) -> EdgeAdjacency {
        let mut map: HashMap<[u32; 3], u32, WordHash> =
            HashMap::with_capacity_and_hasher(self.positions.len(), WordHash::default());
        let weld: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                let n = map.len() as u32;
                *map.entry(weld_key(*p)).or_insert(n)
            })
            .collect();
        let welded_count = map.len();
        let mut edges: Vec<Edge> = Vec::with_capacity(self.indices.len() * 3 / 2);
        let mut lookup: HashMap<(u32, u32), u32, WordHash> =
            HashMap::with_capacity_and_hasher(self.indices.len() * 3 / 2, WordHash::default());
        let mut tri_edges = Vec::with_capacity(self.indices.len());
        for (t, tri) in self.indices.iter().enumerate() {
            let w = tri.map(|i| weld.get(i as usize).copied().unwrap_or(u32::MAX));
            let mut te = [u32::MAX; 3];
            for k in 0..3 {
                let (a, b) = (w[k], w[(k + 1) % 3]);
                if a == b || a == u32::MAX || b == u32::MAX {
                    continue;
                }
                let key = (a.min(b), a.max(b));
                match lookup.get(&key) {
                    Some(&ei) => {
                        let e = &mut edges[ei as usize];
                        if e.count == 1 {
                            e.tris[1] = t as u32;
                            e.consistent = e.v == [b, a];
                        }
                        e.count += 1;
                        te[k] = ei;
                    }
                    None => {
                        let ei = edges.len() as u32;
                        edges.push(Edge { v: [a, b], tris: [t as u32, BOUNDARY], count: 1, consistent: false });
                        lookup.insert(key, ei);
                        te[k] = ei;
                    }
                }
            }
            tri_edges.push(te);
        }
        EdgeAdjacency { weld, welded_count, edges, tri_edges }
    }
}
