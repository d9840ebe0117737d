//! A binary hierarchy over object (or triangle) bounds queried with a cone from a point: the
//! seed 004 paper's `GetBetween`, "what may lie between this point and that light". `ltc`
//! finds its occluders with it; any integrator that needs the objects between a point and a
//! bounded target can.

use crate::geometry::Bounds3;
use glam::Vec3;

/// A cone from `apex` along unit `axis` with half-angle cosine `cos`, up to distance `far`
/// (a region of space, in f32 like the bounds it is tested against; for a cone of
/// directions bounding a spherical loop see `BoundingCone` in the integrators' `common::spherical_polygon`).
#[derive(Clone, Copy, Debug)]
pub struct Cone {
    pub apex: Vec3,
    pub axis: Vec3,
    pub cos: f32,
    pub far: f32,
}

impl Cone {
    /// Around the bounding sphere (`c`, `r`) seen from `apex`; when `apex` is inside it,
    /// everything within `far` may be in between: a full-sphere cone (`cos` = −1).
    pub fn towards(apex: Vec3, c: Vec3, r: f32) -> Cone {
        let d = c - apex;
        let dist = d.length();
        if !(dist > r * 1.0001) {
            return Cone { apex, axis: Vec3::Z, cos: -1.0, far: dist + r };
        }
        let sin = r / dist;
        Cone { apex, axis: d / dist, cos: (1.0 - sin * sin).max(0.0).sqrt(), far: dist + r }
    }

    /// Whether the sphere (`c`, `r`) may intersect the cone (conservative).
    pub fn hits_sphere(&self, c: Vec3, r: f32) -> bool {
        let v = c - self.apex;
        let dist = v.length();
        if dist <= r {
            return true;
        }
        if dist - r > self.far {
            return false;
        }
        if self.cos <= -1.0 {
            return true;
        }
        // Angle between v and the axis minus the sphere's angular radius ≤ the cone's half-angle.
        let cos_v = v.dot(self.axis) / dist;
        let sin_v = (1.0 - cos_v * cos_v).max(0.0).sqrt();
        let sin_s = (r / dist).min(1.0);
        let cos_s = (1.0 - sin_s * sin_s).max(0.0).sqrt();
        // cos(θv − θs) ≥ cos(θc)  ⇔  the sphere reaches into the cone.
        let cos_diff = cos_v * cos_s + sin_v * sin_s;
        cos_diff >= self.cos - 1e-6 || cos_v >= cos_s.min(self.cos)
    }

    /// Whether the box `b` may intersect the cone (through its bounding sphere).
    pub fn hits_box(&self, b: &Bounds3) -> bool {
        let c = (b.min + b.max) * 0.5;
        let r = (b.max - b.min).length() * 0.5;
        self.hits_sphere(c, r)
    }
}

/// A binary hierarchy over `(id, bounds)` items (objects of a scene, triangles of a mesh),
/// split at the median of the longest axis, for [`ObjectBvh::query`].
#[derive(Clone, Debug, Default)]
pub struct ObjectBvh {
    nodes: Vec<Node>,
}

#[derive(Clone, Debug)]
struct Node {
    bounds: Bounds3,
    /// Leaf: item id; inner: `usize::MAX`.
    object: usize,
    children: [usize; 2],
}

impl ObjectBvh {
    pub fn build(bounds: &[(usize, Bounds3)]) -> ObjectBvh {
        let mut bvh = ObjectBvh { nodes: Vec::new() };
        if !bounds.is_empty() {
            let mut items = bounds.to_vec();
            bvh.build_rec(&mut items);
        }
        bvh
    }

    /// One per triangle of `mesh` (ids = triangle indices).
    pub fn over_triangles(mesh: &crate::mesh::TriangleMesh) -> ObjectBvh {
        let tb: Vec<(usize, Bounds3)> = (0..mesh.triangle_count())
            .map(|t| {
                let mut tb = Bounds3::EMPTY;
                for v in mesh.vertices(t) {
                    tb.extend(v);
                }
                (t, tb)
            })
            .collect();
        ObjectBvh::build(&tb)
    }

    fn build_rec(&mut self, items: &mut [(usize, Bounds3)]) -> usize {
        let mut b = Bounds3::EMPTY;
        for (_, ib) in items.iter() {
            b = b.union(ib);
        }
        let idx = self.nodes.len();
        if items.len() == 1 {
            self.nodes.push(Node { bounds: b, object: items[0].0, children: [0, 0] });
            return idx;
        }
        self.nodes.push(Node { bounds: b, object: usize::MAX, children: [0, 0] });
        let ext = b.max - b.min;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        items.sort_by(|a, c| {
            let ca = (a.1.min[axis] + a.1.max[axis]) * 0.5;
            let cc = (c.1.min[axis] + c.1.max[axis]) * 0.5;
            ca.total_cmp(&cc)
        });
        let mid = items.len() / 2;
        let (l, r) = items.split_at_mut(mid);
        let left = self.build_rec(l);
        let right = self.build_rec(r);
        self.nodes[idx].children = [left, right];
        idx
    }

    /// The ids whose bounds may meet `cone`, in increasing order (into `out`, cleared first).
    pub fn query(&self, cone: &Cone, out: &mut Vec<usize>) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            if !cone.hits_box(&n.bounds) {
                continue;
            }
            if n.object != usize::MAX {
                out.push(n.object);
            } else {
                stack.extend_from_slice(&n.children);
            }
        }
        out.sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_at(c: Vec3, h: f32) -> Bounds3 {
        let mut b = Bounds3::EMPTY;
        b.extend(c - Vec3::splat(h));
        b.extend(c + Vec3::splat(h));
        b
    }

    /// The query returns exactly the boxes a brute-force test over all of them accepts, and
    /// a narrow cone towards one box finds it and not the boxes behind the apex or far off axis.
    #[test]
    fn query_matches_brute_force() {
        let items: Vec<(usize, Bounds3)> = (0..64)
            .map(|i| {
                let (x, y, z) = ((i % 4) as f32, ((i / 4) % 4) as f32, (i / 16) as f32);
                (i, cube_at(Vec3::new(x * 3.0 - 4.5, y * 3.0 - 4.5, z * 3.0 - 4.5), 0.4))
            })
            .collect();
        let bvh = ObjectBvh::build(&items);
        let apex = Vec3::new(-4.5, -4.5, -4.5);
        let mut out = Vec::new();
        for target in [Vec3::new(4.5, 4.5, 4.5), Vec3::new(-4.5, 4.5, -4.5), Vec3::new(1.5, -1.5, 4.5)] {
            let cone = Cone::towards(apex, target, 0.5);
            bvh.query(&cone, &mut out);
            let brute: Vec<usize> = items.iter().filter(|(_, b)| cone.hits_box(b)).map(|(i, _)| *i).collect();
            assert_eq!(out, brute);
            let hit_target = items.iter().find(|(_, b)| (b.center() - target).length() < 1e-3).unwrap().0;
            assert!(out.contains(&hit_target));
            assert!(out.len() < 16, "a narrow cone accepted {} of 64 boxes", out.len());
        }
        // From inside the target sphere: everything within reach.
        let cone = Cone::towards(Vec3::ZERO, Vec3::ZERO, 1.0);
        assert_eq!(cone.cos, -1.0);
        assert!(cone.hits_sphere(Vec3::new(0.0, 0.0, -0.5), 0.1));
        assert!(!cone.hits_sphere(Vec3::new(0.0, 0.0, -5.0), 0.1));
    }
}
