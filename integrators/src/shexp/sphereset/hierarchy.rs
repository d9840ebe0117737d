//! The sphere hierarchy over a set of leaves (seed 003 §4.1, "parent sphere construction"):
//! Lloyd clustering of the children's centres with a branching factor, each parent the
//! smallest sphere (Nelder–Mead on its centre) bounding its children, level by level up to one
//! root. Every level bounds what the leaves bound.

use super::fit::nelder_mead;
use super::Sphere;
use glam::DVec3;

/// Children per parent.
pub const BRANCHING: usize = 4;

/// One node: a sphere and its children (indices into [`Hierarchy::nodes`]); leaves have none
/// and are `nodes[..leaves]`, in the order of the leaf set.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub sphere: Sphere,
    pub children: Vec<u32>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hierarchy {
    pub nodes: Vec<Node>,
    pub leaves: usize,
}

impl Hierarchy {
    /// The root (the last node), if any.
    pub fn root(&self) -> Option<u32> {
        self.nodes.len().checked_sub(1).map(|r| r as u32)
    }

    /// Calls `visit` with every leaf index whose ancestors all pass `keep` (and which passes it).
    pub fn for_each_leaf(&self, keep: &mut dyn FnMut(&Sphere) -> bool, visit: &mut dyn FnMut(usize)) {
        let Some(root) = self.root() else { return };
        let mut stack = vec![root];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            if !keep(&node.sphere) {
                continue;
            }
            if node.children.is_empty() {
                visit(n as usize);
            } else {
                stack.extend(node.children.iter().rev());
            }
        }
    }

    /// Levels above the leaves.
    pub fn depth(&self) -> usize {
        let mut d = 0;
        let mut n = self.root();
        while let Some(i) = n {
            let node = &self.nodes[i as usize];
            match node.children.first() {
                Some(&c) => {
                    d += 1;
                    n = Some(c);
                }
                None => break,
            }
        }
        d
    }
}

/// The smallest sphere (centre by Nelder–Mead from the centroid) containing `spheres`.
pub fn bounding_sphere_of(spheres: &[Sphere]) -> Sphere {
    if spheres.len() == 1 {
        return spheres[0];
    }
    let reach = |c: DVec3| spheres.iter().map(|s| c.distance(s.center) + s.radius).fold(0.0, f64::max);
    let c0 = spheres.iter().map(|s| s.center).sum::<DVec3>() / spheres.len() as f64;
    let r0 = reach(c0);
    let (c, _) = nelder_mead(&mut |c| reach(c), c0, 0.25 * r0.max(f64::MIN_POSITIVE), 200);
    let c = if reach(c) <= r0 { c } else { c0 };
    // A relative margin so that rounding never lets a child poke out.
    Sphere { center: c, radius: reach(c) * (1.0 + 1e-9) }
}

/// Builds the hierarchy over `leaves`.
pub fn build(leaves: &[Sphere]) -> Hierarchy {
    let mut nodes: Vec<Node> = leaves.iter().map(|s| Node { sphere: *s, children: Vec::new() }).collect();
    let mut level: Vec<u32> = (0..nodes.len() as u32).collect();
    while level.len() > 1 {
        let k = level.len().div_ceil(BRANCHING);
        let centres: Vec<DVec3> = level.iter().map(|&i| nodes[i as usize].sphere.center).collect();
        // Farthest-point initialisation (deterministic), then Lloyd iterations.
        let mut seeds = vec![centres[0]];
        while seeds.len() < k {
            let next = centres
                .iter()
                .max_by(|a, b| {
                    let da = seeds.iter().map(|s| s.distance_squared(**a)).fold(f64::INFINITY, f64::min);
                    let db = seeds.iter().map(|s| s.distance_squared(**b)).fold(f64::INFINITY, f64::min);
                    da.total_cmp(&db)
                })
                .copied()
                .unwrap_or(centres[0]);
            seeds.push(next);
        }
        let mut groups: Vec<Vec<u32>> = Vec::new();
        for _ in 0..10 {
            groups = vec![Vec::new(); k];
            for (j, c) in centres.iter().enumerate() {
                let g = (0..k).min_by(|&a, &b| seeds[a].distance_squared(*c).total_cmp(&seeds[b].distance_squared(*c)));
                groups[g.unwrap_or(0)].push(level[j]);
            }
            for (s, g) in seeds.iter_mut().zip(&groups) {
                if !g.is_empty() {
                    *s = g.iter().map(|&i| nodes[i as usize].sphere.center).sum::<DVec3>() / g.len() as f64;
                }
            }
        }
        groups.retain(|g| !g.is_empty());
        if groups.len() == level.len() {
            // No merging happened (coincident centres): put everything under one parent.
            groups = vec![level.clone()];
        }
        let mut next = Vec::with_capacity(groups.len());
        for g in groups {
            let children: Vec<Sphere> = g.iter().map(|&i| nodes[i as usize].sphere).collect();
            let sphere = bounding_sphere_of(&children);
            next.push(nodes.len() as u32);
            nodes.push(Node { sphere, children: g });
        }
        level = next;
    }
    Hierarchy { nodes, leaves: leaves.len() }
}
