//! The 4D dual-edge hierarchy: every edge between two triangles is a segment between the
//! triangles' (signed) plane equations, in a bounding-volume hierarchy over 4D; a shading
//! point `p` is the hyperplane `{x : x·(p, 1) = 0}`, and an edge is a contour edge of `p`
//! exactly where its segment crosses that hyperplane (Nowrouzezahrai et al. 2014, §3.1,
//! Eq. 6; Hertzmann & Zorin 2000).
//!
//! Orientation does not matter: for an edge `(a, b)` and an incident triangle with opposite
//! vertex `c`, `side = orient3d(a, b, c, p)` says on which side of the plane through `p, a,
//! b` the triangle lies, and `w = Σ side` over the incident triangles is the edge's weight:
//! 0 (not a contour), ±1 (boundary, or `p` on a plane), ±2 (one triangle front-facing, one
//! back-facing). Crossing the edge's arc away from the side `m = (a−p)×(b−p)` points to
//! changes the depth complexity by `−w` ([`Contour::delta_w`]). For two triangles the
//! signed planes `g_t` with `g_t·(p, 1) ∝ side_t` make the dual segment `[g₁, −g₂]`, which
//! crosses the hyperplane iff `side₁ = side₂`; boundary edges, edges of three or more
//! triangles and edges of degenerate triangles are tested at every point instead.
//!
//! The hierarchy only filters: its boxes are padded by a bound on the rounding of the plane
//! equations, a node survives when the hyperplane can touch its padded box, and every
//! surviving edge is decided by the exact predicate of [`super::orient`], so
//! [`DualEdges::contours`] returns exactly [`DualEdges::contours_brute_force`]'s set
//! (property-tested). A node's offsets are taken from the centre of its primal box, and the
//! tree is split where the expected work of a query below is least ([`sah`]: each part's
//! leaves times a measure of its dual box; the median split it replaced, which split space
//! first and normals only where the node is small against its mesh, [`NORMAL_WEIGHT`], is
//! kept as the fallback). Nodes also
//! keep the primal box of their edges: a node wholly behind the shading point's tangent plane
//! is skipped, and so is every edge with both ends behind it. The binary tree is stored 4-wide
//! ([`Node4`]: four grandchildren tested side by side in f32, with slacks for its rounding).
//!
//! Geometry is translated to its centre and scaled by a power of two to an extent of about 1
//! (exact for the f32 input in all but pathological cases), so every tolerance is relative
//! to the scene and scaled scenes give the same contours.

use super::orient::orient3d;
use glam::{DVec3, Vec3, Vec4};
use penumbra_core::mesh::TriangleMesh;

/// Edges per leaf (a multiple of 4 below 32: the lane masks are `u32`). On killeroo-simple
/// (mode=ao, 16², callgrind) with the 4-wide nodes and the median split: 4 tests 15.3k boxes
/// and 16.5k edges per point (contour search 2.43 M Ir), 8 tests 9.2k and 23.1k (2.08 M), 16
/// tests 6.3k and 31.3k (2.33 M). With the cost split ([`sah`]) and the f32 leaf filter,
/// contour search per point: 8 1.192 M, 12 1.139 M, 16 1.125 M, 20 1.122 M, 24 1.139 M.
const LEAF: usize = 16;
const _: () = assert!(LEAF.is_multiple_of(4) && LEAF < 32);
/// The split's weight of the normals' extents, times the extent of the mesh the node's edges
/// come from (a length: a node's dual test spans about `Δn·|p − c|` plus its offsets, and
/// shading points see contours at distances of about the mesh's size). Measured on
/// killeroo-simple (two 66k-triangle killeroos, floor, wall) and on the killeroos alone: 0.1
/// gives 17.7k nodes / 16.5k edges examined per point (was 37.5k / 48.1k with the unweighted
/// dual split) and 9.8k / 7.7k (was 37.1k / 29.4k); 0.2–0.3 are within 5 % on the first
/// and 13–25 % worse on the second, 0 (a purely primal split) 40 % worse on the first.
const NORMAL_WEIGHT: f64 = 0.1;
/// The split cost's weight of the normals' extents (the distance `|p − c|` per axis at which
/// a node's normals' range widens its dual test, [`Bounds::measure`]), times the mesh's
/// extent. Contour search per point (`mode=ao`, 16², 1 spp, callgrind), 8-edge leaves on
/// killeroo-simple: 0.2 gives 1.204 M Ir, 0.4 1.193 M, 0.8 1.200 M; 16-edge leaves on
/// killeroo-simple / scenes/meshes/killeroos-sky: 0.25 1.130 / 1.081 M, 0.4 1.125 / 1.075 M,
/// 0.6 1.123 / 1.074 M, 1.0 1.142 / 1.091 M.
const SPLIT_NORMAL_WEIGHT: f64 = 0.6;
/// The split cost's weight of the primal extents (a child's centre moves its offsets).
/// Contour search per point on killeroo-simple / killeroos-sky (16-edge leaves, normals'
/// weight 0.6, as [`SPLIT_NORMAL_WEIGHT`]): 0.1 1.139 / 1.087 M Ir, 0.25 1.123 / 1.074 M,
/// 0.5 1.126 / 1.077 M.
const PRIMAL_WEIGHT: f64 = 0.25;
/// Rounding bound, relative to the sum of the magnitudes of its terms, of a dot product of up
/// to 4 terms (γ₄ ≈ 4ε, doubled): every slack of the hierarchy's filters is this times the
/// magnitudes involved, so none is an absolute length and the filters are scale-free.
const DOT_ROUNDING: f64 = 8.0 * f64::EPSILON;

/// An edge of the hierarchy while it is built: its dual segment and rounding pad, and the
/// bounds the split measures (0–2: the primal x, y, z of its ends; 3–5: the normals'
/// components of both signed planes, the split's axes; 6: both planes' offsets about the
/// centre of the node being split, [`set_offsets`]).
#[derive(Clone, Copy, Debug)]
struct Item {
    id: u32,
    d: [[f64; 4]; 2],
    pad: f64,
    lo: [f64; 7],
    hi: [f64; 7],
}

impl Item {
    fn new(id: u32, d: [[f64; 4]; 2], pad: f64, a: DVec3, b: DVec3) -> Item {
        let (mut lo, mut hi) = ([0.0; 7], [0.0; 7]);
        for k in 0..3 {
            (lo[k], hi[k]) = (a[k].min(b[k]), a[k].max(b[k]));
            (lo[k + 3], hi[k + 3]) = (d[0][k].min(d[1][k]), d[0][k].max(d[1][k]));
        }
        Item { id, d, pad, lo, hi }
    }

    /// Twice the centre of its bounds on `axis` (the split's sort key).
    fn key(&self, axis: usize) -> f64 {
        self.lo[axis] + self.hi[axis]
    }
}

/// `min` and `max` without the NaN cases (the build's bounds are finite).
fn fmin(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
}
fn fmax(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// The union of items' bounds, and their count.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: [f64; 7],
    hi: [f64; 7],
    n: usize,
}

impl Bounds {
    const EMPTY: Bounds = Bounds { lo: [f64::INFINITY; 7], hi: [f64::NEG_INFINITY; 7], n: 0 };

    fn add(&mut self, it: &Item) {
        for k in 0..7 {
            self.lo[k] = fmin(self.lo[k], it.lo[k]);
            self.hi[k] = fmax(self.hi[k], it.hi[k]);
        }
        self.n += 1;
    }

    fn merge(&mut self, o: &Bounds) {
        for k in 0..7 {
            self.lo[k] = fmin(self.lo[k], o.lo[k]);
            self.hi[k] = fmax(self.hi[k], o.hi[k]);
        }
        self.n += o.n;
    }

    /// How often a query tests a node of these edges, up to a factor common to all nodes:
    /// the range of `n·(p − c) + o` over the node's dual box, which the hyperplane of a point
    /// `p` crosses, is its offsets' range plus `Σ_k Δn_k |p_k − c_k|`; the offsets' range is
    /// measured about the centre of the node being split (a child's own centre moves it by
    /// about `PRIMAL_WEIGHT` × its primal extents) and `|p − c|` is taken as `wn`.
    fn measure(&self, wn: f64) -> f64 {
        let e = |k: usize| self.hi[k] - self.lo[k];
        e(6) + PRIMAL_WEIGHT * (e(0) + e(1) + e(2)) + wn * (e(3) + e(4) + e(5))
    }

    /// The expected work below a node of these edges: its leaves ([`LEAF`] edges each; a
    /// leaf's test costs the same for 1 or 8) times [`Self::measure`].
    fn cost(&self, wn: f64) -> f64 {
        self.n.div_ceil(LEAF) as f64 * self.measure(wn)
    }
}

/// Bins per axis of the split's cost. On killeroo-simple (16², 1 spp, callgrind) 32 bins
/// took 0.6 % off the contour search and added 0.36 G Ir to the build.
const BINS: usize = 16;
/// Below this depth of the binary tree the split is the median one (a 4-wide node descends
/// at least one binary level and pushes at most 3 more nodes than it pops, so the traversal's
/// stack of 256 holds binary depths up to 85: 48 plus a median split of < 2^37 edges).
const MAX_SAH_DEPTH: usize = 48;

/// Items a split's cost is estimated from: a node of more takes every `n / SAMPLE`-th.
const SAMPLE: usize = 1024;

/// The bin of a key at `(key − kmin)·scale`, clamped to the bins.
fn bin(key: f64, kmin: f64, scale: f64) -> usize {
    let x = (key - kmin) * scale;
    if !(x > 0.0) {
        0
    } else if x < (BINS - 1) as f64 {
        x as i32 as usize
    } else {
        BINS - 1
    }
}

/// Sets the items' offset bounds (axis 6): both planes' `g₃ + n·c`.
fn set_offsets(items: &mut [Item], c: DVec3) {
    for it in items {
        let [v1, v2] = it.d.map(|g| g[3] + g[0] * c.x + g[1] * c.y + g[2] * c.z);
        (it.lo[6], it.hi[6]) = (fmin(v1, v2), fmax(v1, v2));
    }
}

/// The cheapest binned split of `items` (axis, its key's minimum and bin scale, the last bin
/// of the left part) by [`Bounds::cost`] of the two parts, over the six axes (primal and
/// normals; a key is the centre of an item's bounds), binned in one pass.
fn sah(items: &[Item], wn: f64) -> Option<(usize, f64, f64, usize)> {
    let stride = (items.len() / SAMPLE).max(1);
    let (mut kmin, mut kmax) = ([f64::INFINITY; 6], [f64::NEG_INFINITY; 6]);
    for it in items.iter().step_by(stride) {
        for a in 0..6 {
            kmin[a] = fmin(kmin[a], it.key(a));
            kmax[a] = fmax(kmax[a], it.key(a));
        }
    }
    let scale: [f64; 6] =
        std::array::from_fn(|a| if kmax[a] > kmin[a] { BINS as f64 / (kmax[a] - kmin[a]) } else { 0.0 });
    let mut bins = [[Bounds::EMPTY; BINS]; 6];
    for it in items.iter().step_by(stride) {
        for a in 0..6 {
            bins[a][bin(it.key(a), kmin[a], scale[a])].add(it);
        }
    }
    let mut best = (f64::INFINITY, None);
    for (a, bins) in bins.iter().enumerate().filter(|(a, _)| scale[*a] > 0.0) {
        let mut right = [Bounds::EMPTY; BINS];
        let mut acc = Bounds::EMPTY;
        for i in (1..BINS).rev() {
            acc.merge(&bins[i]);
            right[i] = acc;
        }
        let mut left = Bounds::EMPTY;
        for cut in 0..BINS - 1 {
            left.merge(&bins[cut]);
            let r = &right[cut + 1];
            if left.n == 0 || r.n == 0 {
                continue;
            }
            let cost = left.cost(wn) + r.cost(wn);
            if cost < best.0 {
                best = (cost, Some((a, kmin[a], scale[a], cut)));
            }
        }
    }
    best.1
}

/// Splits `items` (of a node centred at `c` whose items' bounds are `b`, at `depth` in the
/// binary tree) in two non-empty parts (left first) and returns the left one's length: the
/// binned cost split ([`sah`]), or the median of the widest axis (normals weighted by
/// [`NORMAL_WEIGHT`]) where that finds none.
fn split(items: &mut [Item], b: &Bounds, c: DVec3, mext: f64, depth: usize) -> usize {
    let n = items.len();
    if depth < MAX_SAH_DEPTH {
        set_offsets(items, c);
        if let Some((axis, kmin, scale, cut)) = sah(items, SPLIT_NORMAL_WEIGHT * mext) {
            let mut l = 0;
            for i in 0..n {
                if bin(items[i].key(axis), kmin, scale) <= cut {
                    items.swap(i, l);
                    l += 1;
                }
            }
            if l > 0 && l < n {
                return l;
            }
        }
    }
    let wn = NORMAL_WEIGHT * mext;
    let ext: [f64; 6] = std::array::from_fn(|k| (b.hi[k] - b.lo[k]) * if k < 3 { 1.0 } else { wn });
    let axis = (0..6).fold(0, |a, k| if ext[k] > ext[a] { k } else { a });
    let mid = n / 2;
    items.select_nth_unstable_by(mid, |x, y| x.key(axis).total_cmp(&y.key(axis)).then(x.id.cmp(&y.id)));
    mid
}

/// A contour edge of a shading point, in normalised scene coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contour {
    /// The edge's index in [`DualEdges`] (stable: the order of meshes, then of their edges).
    pub edge: u32,
    /// The indices of `a` and `b` among the hierarchy's welded vertices (a contour chain's
    /// edges share them: the traversal transforms each vertex once per point).
    pub va: u32,
    pub vb: u32,
    pub a: DVec3,
    pub b: DVec3,
    /// `Σ orient3d(a, b, c_t, p)` over the incident triangles (never 0).
    pub w: i32,
}

impl Contour {
    /// The change of the depth complexity when a direction from `p` crosses the edge's arc
    /// from the side of the great circle containing `from` to the other side (`from` not on
    /// that great circle): `−w · sign(m·from)`, `m = (a−p)×(b−p)`.
    pub fn delta_w(&self, p: DVec3, from: DVec3) -> i32 {
        let m = (self.a - p).cross(self.b - p);
        let s = m.dot(from);
        if s > 0.0 {
            -self.w
        } else if s < 0.0 {
            self.w
        } else {
            0
        }
    }
}

/// A hierarchy edge's index and ends, stored in leaf order so that a leaf's survivors read
/// neighbouring records, which the query asks the cache for as soon as a node's test lets the
/// leaf through ([`Node4::order`]), rather than an [`EdgeRec`] and two vertices each from
/// anywhere in the scene: those three cache misses per surviving edge took about 30 % of the
/// contour search's cycles on the killeroos (`perf annotate`, 64², 1 spp). The records
/// alone saved 2 % of the render; with the leaves and records fetched ahead, 10 %
/// (docs/integrators/silhouette.md).
#[derive(Clone, Copy, Debug)]
struct OrderEdge {
    a: DVec3,
    b: DVec3,
    va: u32,
    vb: u32,
    id: u32,
}

#[derive(Clone, Copy, Debug)]
struct EdgeRec {
    a: u32,
    b: u32,
    /// Range into `opposite`.
    start: u32,
    count: u32,
}

/// What one [`DualEdges::contours`] query cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryCost {
    /// Edges the hierarchy did not reject (each then tested by the f64 filter or exactly).
    pub edges: usize,
    /// Nodes whose boxes were tested.
    pub nodes: usize,
}

/// A node while the hierarchy is built (f64 bounds; `c` and `r` exact in f32).
#[derive(Clone, Copy, Debug)]
struct BuildNode {
    lo: [f64; 4],
    hi: [f64; 4],
    /// The centre of the primal box (the node's offsets are taken about it) and its half
    /// extents, rounded up: `[c − r, c + r]` contains the node's edges.
    c: DVec3,
    r: DVec3,
    /// Leaf: `count > 0`, its index in `leaves` (items `order..order + count` of `order`);
    /// inner: children `first`, `first+1`.
    first: u32,
    count: u32,
    /// Leaf: its first edge in `DualEdges::order`; inner: 0.
    order: u32,
    /// The number of edges below.
    size: u32,
}

/// A node of the 4-wide hierarchy: up to four boxes tested together (the grandchildren of a
/// node of the binary tree the build splits, or a child where that is a leaf), structure of
/// arrays. Per slot the dual box (components 0–2 the planes' normals, 3 their offsets from
/// the centre `c` of the slot's primal box, `g₃ + n·c`, padded by the rounding bound) and the
/// primal box as centre and half extent, in f32 rounded outwards (the bounds only filter, so
/// a looser box is safe; the centre is exact, the offsets are taken about it). Measured
/// against the binary tree with one 64-byte node per box: see docs/integrators/silhouette.md.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Node4 {
    /// `[component][slot]`, so the four slots' tests run side by side.
    lo: [[f32; 4]; 4],
    hi: [[f32; 4]; 4],
    c: [[f32; 4]; 3],
    r: [[f32; 4]; 3],
    /// Leaf slot: its index in `DualEdges::leaves`; inner slot: the index of its `Node4`.
    first: [u32; 4],
    /// Leaf slot: its edge count; inner slot: 0.
    count: [u32; 4],
    /// Leaf slot: its first edge in `DualEdges::order` (here, not in the leaf, so the records
    /// can be fetched before the leaf is read); inner slot: 0.
    order: [u32; 4],
    /// Slots in use (1..=4).
    len: u32,
}

/// `x` rounded down / up to f32.
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

impl Node4 {
    fn set(&mut self, j: usize, b: &BuildNode, first: u32) {
        self.order[j] = b.order;
        for k in 0..4 {
            self.lo[k][j] = down(b.lo[k]);
            self.hi[k][j] = up(b.hi[k]);
        }
        for k in 0..3 {
            self.c[k][j] = b.c[k] as f32;
            self.r[k][j] = up(b.r[k]);
        }
        self.first[j] = first;
        self.count[j] = b.count;
    }
}

/// Plane components per edge in a [`LeafPlanes`]: both triangles' normals and offsets.
const PLANE_COMPONENTS: usize = 8;

/// A leaf's edges for the f32 pre-filter, structure of arrays (lane `j`: the leaf's `j`-th
/// edge): both signed planes' normals `g_t` rounded to nearest and their offsets about the
/// leaf's centre `c`, `g_t3 + g_t·c` (from f64), and the edge's rounding pad rounded up.
/// Unused lanes have infinite offsets (always rejected). The f32 test rejects an edge only
/// where the f64 test would ([`NodeQuery::leaf_slack`]), so the survivors are a superset of
/// the f64 filter's and each still takes it: the contour set (and its order) is unchanged.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct LeafPlanes {
    /// `[half][component][lane]` (lane `4·half + j`): `g₁x g₁y g₁z o₁ g₂x g₂y g₂z o₂`, in
    /// halves of four lanes (one SIMD register each).
    g: [[Vec4; PLANE_COMPONENTS]; LEAF / 4],
    pad: [Vec4; LEAF / 4],
    c: [f32; 3],
}

impl LeafPlanes {
    fn new(c: DVec3, items: &[Item]) -> LeafPlanes {
        let mut g = [[Vec4::ZERO; PLANE_COMPONENTS]; LEAF / 4];
        for h in &mut g {
            h[3] = Vec4::INFINITY;
            h[7] = Vec4::INFINITY;
        }
        let mut pad = [Vec4::ZERO; LEAF / 4];
        for (lane, Item { d, pad: pd, .. }) in items.iter().enumerate() {
            let (h, j) = (lane / 4, lane % 4);
            for (t, plane) in d.iter().enumerate() {
                for k in 0..3 {
                    g[h][4 * t + k][j] = plane[k] as f32;
                }
                g[h][4 * t + 3][j] = (plane[3] + plane[0] * c.x + plane[1] * c.y + plane[2] * c.z) as f32;
            }
            pad[h][j] = up(*pd);
        }
        LeafPlanes { g, pad, c: [c.x as f32, c.y as f32, c.z as f32] }
    }
}

/// The 4-wide hierarchy of a binary one: each 4-wide node holds the grandchildren of an inner
/// binary node (a leaf child stands for itself); the root's is node 0, and a tree of one leaf
/// is one node of one slot.
fn collapse(b: &[BuildNode]) -> Vec<Node4> {
    let mut out = vec![Node4::default()];
    if b[0].count > 0 {
        out[0].set(0, &b[0], b[0].first);
        out[0].len = 1;
        return out;
    }
    let mut work = vec![(0usize, 0usize)];
    while let Some((bi, oi)) = work.pop() {
        let x = b[bi];
        // x's children, then, while there are fewer than four, the inner slot with the most
        // edges replaced by its two children.
        let (mut slots, mut len) = ([x.first as usize, x.first as usize + 1, 0, 0], 2);
        while len < 4 {
            let inner = (0..len).filter(|&i| b[slots[i]].count == 0);
            let Some(i) = inner.fold(None, |m: Option<usize>, i| match m {
                Some(m) if b[slots[m]].size >= b[slots[i]].size => Some(m),
                _ => Some(i),
            }) else {
                break;
            };
            let s = slots[i];
            (slots[i], slots[len]) = (b[s].first as usize, b[s].first as usize + 1);
            len += 1;
        }
        let mut node = Node4::default();
        let mut j = 0;
        for &s in &slots[..len] {
            let first = if b[s].count > 0 {
                b[s].first
            } else {
                out.push(Node4::default());
                work.push((s, out.len() - 1));
                (out.len() - 1) as u32
            };
            node.set(j, &b[s], first);
            j += 1;
        }
        node.len = j as u32;
        out[oi] = node;
    }
    out
}

/// Asks the cache for the `lines` 64-byte lines from `x` on (a hint: no effect on results;
/// nothing on targets without it).
#[inline(always)]
fn prefetch<T>(x: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    for k in 0..lines {
        let p = (x as *const T as *const i8).wrapping_add(64 * k);
        // SAFETY: a prefetch reads nothing and cannot fault, whatever the address.
        unsafe { std::arch::x86_64::_mm_prefetch(p, std::arch::x86_64::_MM_HINT_T0) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (x, lines);
}

/// Unit roundoff of f32.
const U32: f64 = f32::EPSILON as f64 / 2.0;

/// A query's constants for the node tests, in f32 (the four slots of a node are tested in one
/// SIMD lane each), with slacks bounding the rounding of both tests for every node (from
/// bounds over all nodes: conservative for each).
struct NodeQuery {
    p: [f32; 3],
    n: [f32; 3],
    abs_n: [f32; 3],
    /// Rounding slack of the dual test.
    slack: f32,
    /// Rounding margin of the tangent-plane test; infinite: no tangent-plane cull (`tol < 0`).
    margin: f32,
    /// Rounding slack of the leaves' f32 plane test ([`LeafPlanes`]).
    leaf_slack: f32,
}

impl NodeQuery {
    fn new(p: DVec3, n: DVec3, tol: f64, root: (DVec3, DVec3), dmax: f64, cmax: f64) -> NodeQuery {
        let (plo, phi) = root;
        // The dual test computes lo₃ + Σ_k (lo_k or hi_k)·q_k, q_k = p_k − c_k, in f32 with p
        // rounded to f32: |q_k − q̃_k| ≤ 2.01u(|p_k| + |c_k|); the products and the 4-term sum
        // add at most 4u times the terms' magnitudes (the offset ≤ dmax, normals ≤ 1.001 in
        // f32, times |q_k|), and where q̃_k's sign differs from q_k's the wrong bound costs at
        // most (hi_k − lo_k)|q_k| ≤ 2.002 · 2.01u(|p_k| + |c_k|): with S = Σ|p_k| + cmax, at
        // most 11u(dmax + 1.01 S). Doubled, and an absolute floor for underflow.
        let s = p.x.abs() + p.y.abs() + p.z.abs() + cmax;
        let slack = 32.0 * U32 * (dmax + 1.01 * s) + 1e-30;
        // The tangent-plane test sums 6 terms |n_k| r_k and −n_k q_k, each at most |n_k| times
        // the root's reach from p (up to the f32 rounding): with n and q rounded to f32 and a
        // 6-term sum, at most 10u of twice that plus the q error 2.01u·S.
        let reach = (plo - p).abs().max((phi - p).abs()) * 1.001;
        let margin = if tol >= 0.0 { 32.0 * U32 * (n.abs().dot(reach) + s) + 1e-30 } else { f64::INFINITY };
        // The leaf test computes o + Σ_k g_k·q_k in f32 with g_k (|g_k| ≤ 1) and o (|o| ≤ dmax)
        // rounded to nearest and q̃_k as above: at most u|o| + Σ_k (u|q_k| + 2.01u(|p_k| + |c_k|))
        // + 4.1u(|o| + Σ_k |q_k|) ≤ 5.1u dmax + 7.3u S, within the dual test's slack; the f64
        // value it stands for, g·p + g₃ (|g₃| ≤ 1 for normalised geometry), is within
        // DOT_ROUNDING (1 + |p|₁) of the exact one. Rejecting beyond pad + this slack rejects
        // only what the f64 test rejects.
        let leaf_slack = slack + DOT_ROUNDING * (1.0 + p.abs().element_sum()) * 2.0;
        let f = |v: DVec3| v.to_array().map(|x| x as f32);
        NodeQuery {
            p: f(p),
            n: f(n),
            abs_n: f(n.abs()),
            slack: slack as f32,
            margin: margin as f32,
            leaf_slack: up(leaf_slack),
        }
    }

    /// The slots of `node` (a bit each) where the hyperplane `x·(p, 1) = 0` can touch the
    /// dual box and some of the edges can be in front of the tangent plane ([`Cull::behind`]
    /// with one margin: the farthest corner along `n`, `n·(c − p) + |n|·r`).
    fn visits(&self, node: &Node4) -> u32 {
        let (mut mn, mut mx) = (node.lo[3], node.hi[3]);
        let mut e = [0.0f32; 4];
        for k in 0..3 {
            let (lo, hi, c, r) = (&node.lo[k], &node.hi[k], &node.c[k], &node.r[k]);
            for j in 0..4 {
                let q = self.p[k] - c[j];
                // lo ≤ hi, and rounding is monotonic: the order of the products is q's sign
                // (cheaper than f32::min/max, which handle NaN).
                let (l, h) = (lo[j] * q, hi[j] * q);
                let pos = q >= 0.0;
                mn[j] += if pos { l } else { h };
                mx[j] += if pos { h } else { l };
                e[j] += self.abs_n[k] * r[j] - self.n[k] * q;
            }
        }
        let mut mask = 0;
        for j in 0..4 {
            let hit = !(mn[j] > self.slack) & !(mx[j] < -self.slack) & (e[j] > -self.margin);
            mask |= (hit as u32) << j;
        }
        mask & ((1u32 << node.len) - 1)
    }

    /// The lanes of `leaf` (a bit each) the f32 plane test cannot reject: not both planes
    /// certainly on one side of `p` beyond the edge's pad.
    ///
    /// Also the lanes certainly on opposite sides (each plane beyond the edge's pad, with
    /// opposite signs: the f64 filter's certain contour of weight ±2) and, of those, the
    /// ones with `g₁·(p, 1) > 0` (weight +2): `(survivors, opposite, positive)`.
    fn leaf_edges(&self, leaf: &LeafPlanes) -> (u32, u32, u32) {
        let q = [self.p[0] - leaf.c[0], self.p[1] - leaf.c[1], self.p[2] - leaf.c[2]];
        let (mut keep, mut opposite, mut positive) = (0, 0, 0);
        for (h, (g, pad)) in leaf.g.iter().zip(&leaf.pad).enumerate() {
            let (k, o, s) = self.leaf_half(g, *pad, q);
            keep |= k << (4 * h);
            opposite |= o << (4 * h);
            positive |= s << (4 * h);
        }
        (keep, opposite, positive)
    }

    /// [`Self::leaf_edges`] of four lanes, in `Vec4` (SIMD) arithmetic.
    #[inline(always)]
    fn leaf_half(&self, g: &[Vec4; PLANE_COMPONENTS], pad: Vec4, q: [f32; 3]) -> (u32, u32, u32) {
        let (q0, q1, q2) = (Vec4::splat(q[0]), Vec4::splat(q[1]), Vec4::splat(q[2]));
        let v1 = g[3] + g[0] * q0 + g[1] * q1 + g[2] * q2;
        let v2 = g[7] + g[4] * q0 + g[5] * q1 + g[6] * q2;
        let t = pad + Vec4::splat(self.leaf_slack);
        let (above1, below1) = (v1.cmpgt(t), v1.cmplt(-t));
        let (above2, below2) = (v2.cmpgt(t), v2.cmplt(-t));
        let reject = (above1 & above2) | (below1 & below2);
        let opposite = (above1 & below2) | (below1 & above2);
        (reject.bitmask() ^ 0xf, opposite.bitmask(), above1.bitmask())
    }
}

/// The dual-edge hierarchy of a scene (built once, when the `silhouette` integrator asks).
#[derive(Clone, Debug, Default)]
pub struct DualEdges {
    center: DVec3,
    inv_scale: f64,
    /// Welded vertices of all meshes, normalised.
    verts: Vec<DVec3>,
    edges: Vec<EdgeRec>,
    /// Opposite vertex of each incident triangle, per edge.
    opposite: Vec<u32>,
    /// Edges tested at every point: boundary, non-manifold, degenerate incident triangle.
    always: Vec<u32>,
    /// Per `always` edge: a boundary edge's signed plane and its rounding pad (its weight is
    /// the sign of `g·(p, 1)` wherever that exceeds the pad); the pad is infinite for the
    /// others (decided exactly).
    always_plane: Vec<([f64; 4], f64)>,
    nodes: Vec<Node4>,
    leaves: Vec<LeafPlanes>,
    /// The primal box of all hierarchy edges (the query's rounding margins).
    root_box: (DVec3, DVec3),
    /// Edges of the hierarchy in leaf order: their ends ([`OrderEdge`]), dual endpoints and
    /// rounding pad.
    order: Vec<OrderEdge>,
    dual: Vec<[[f64; 4]; 2]>,
    pad: Vec<f64>,
    pub boundary_edges: usize,
    pub non_manifold_edges: usize,
    pub build_seconds: f64,
    dmax: f64,
    cmax: f64,
    mesh_extent: Vec<f64>,
}

/// The signed plane `g` of triangle `(a, b, c)` seen from edge `(a, b)`, with `g·(p, 1)`
/// of the sign of `orient3d(a, b, c, p)` (up to rounding), and a bound on that rounding for
/// `|p| ≤ 4`; `None` for a degenerate triangle.
fn signed_plane(a: DVec3, b: DVec3, c: DVec3) -> Option<([f64; 4], f64)> {
    let (e1, e2) = (b - a, c - a);
    let n = e1.cross(e2);
    let len = n.length();
    // orient3d(a,b,c,p) = −(p−a)·n.
    let scale = e1.length() * e2.length();
    if !(len > 1e-12 * scale) || !len.is_finite() {
        return None;
    }
    let u = -n / len;
    let g = [u.x, u.y, u.z, -u.dot(a)];
    // Direction error of a normalised cross product ~ ε |e1||e2| / |n|; times |p − a| ≤ ~6.
    let pad = 64.0 * f64::EPSILON * (scale / len + 1.0);
    Some((g, pad))
}

fn dot4(g: &[f64; 4], p: DVec3) -> f64 {
    g[0] * p.x + g[1] * p.y + g[2] * p.z + g[3]
}

impl DualEdges {
    /// Builds the hierarchy over the meshes whose `include` flag is set (welding each mesh's
    /// bit-identical positions, as [`TriangleMesh::build_adjacency`] does).
    pub fn build(meshes: &[TriangleMesh], include: &[bool]) -> DualEdges {
        let t0 = std::time::Instant::now();
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (m, _) in meshes.iter().zip(include).filter(|(_, &i)| i) {
            for p in &m.positions {
                lo = lo.min(p.as_dvec3());
                hi = hi.max(p.as_dvec3());
            }
        }
        let mut out = DualEdges::default();
        if !(lo.x <= hi.x) {
            out.inv_scale = 1.0;
            return out;
        }
        // An f32 centre and a power-of-two scale keep the normalisation exact.
        let center = ((lo + hi) * 0.5).as_vec3().as_dvec3();
        let extent = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let inv_scale = 2f64.powi(-(extent.log2().ceil() as i32));
        out.center = center;
        out.inv_scale = inv_scale;
        for (m, _) in meshes.iter().zip(include).filter(|(_, &i)| i) {
            out.add_mesh(m);
        }
        out.build_hierarchy();
        out.build_seconds = t0.elapsed().as_secs_f64();
        out
    }

    fn add_mesh(&mut self, mesh: &TriangleMesh) {
        let adj = mesh.build_adjacency();
        let base = self.verts.len() as u32;
        let mut pos = vec![DVec3::ZERO; adj.welded_count];
        for (i, &w) in adj.weld.iter().enumerate() {
            pos[w as usize] = self.normalise(mesh.positions[i]);
        }
        let ext = pos.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), p| (l.min(*p), h.max(*p)));
        let ext = (ext.1 - ext.0).max_element().max(0.0);
        self.verts.extend_from_slice(&pos);
        // Incident triangles of every edge, as opposite welded vertices (tri_edges lists every
        // incident triangle, also past the two `Edge::tris` keeps).
        let mut incident: Vec<Vec<u32>> = vec![Vec::new(); adj.edges.len()];
        for (t, te) in adj.tri_edges.iter().enumerate() {
            let w = mesh.indices[t].map(|i| adj.weld[i as usize]);
            for k in 0..3 {
                if let Some(e) = incident.get_mut(te[k] as usize) {
                    e.push(w[(k + 2) % 3]);
                }
            }
        }
        for (e, opp) in adj.edges.iter().zip(incident) {
            let id = self.edges.len() as u32;
            self.edges.push(EdgeRec {
                a: base + e.v[0],
                b: base + e.v[1],
                start: self.opposite.len() as u32,
                count: opp.len() as u32,
            });
            self.opposite.extend(opp.iter().map(|o| base + o));
            self.mesh_extent.push(ext);
            match e.count {
                1 => self.boundary_edges += 1,
                2 => {}
                _ => self.non_manifold_edges += 1,
            }
            if e.count != 2 {
                self.always.push(id);
            }
        }
    }

    fn build_hierarchy(&mut self) {
        let mut items: Vec<Item> = Vec::new();
        for (id, e) in self.edges.iter().enumerate() {
            if e.count != 2 {
                continue;
            }
            let (a, b) = (self.verts[e.a as usize], self.verts[e.b as usize]);
            let c1 = self.verts[self.opposite[e.start as usize] as usize];
            let c2 = self.verts[self.opposite[e.start as usize + 1] as usize];
            match (signed_plane(a, b, c1), signed_plane(a, b, c2)) {
                (Some((g1, p1)), Some((g2, p2))) => {
                    let neg = [-g2[0], -g2[1], -g2[2], -g2[3]];
                    items.push(Item::new(id as u32, [g1, neg], p1.max(p2), a, b));
                }
                _ => self.always.push(id as u32),
            }
        }
        self.always.sort_unstable();
        self.always_plane = self.always.iter().map(|&id| self.boundary_plane(id)).collect();
        self.nodes.clear();
        if items.is_empty() {
            return;
        }
        let mut nodes = vec![BuildNode {
            lo: [0.0; 4],
            hi: [0.0; 4],
            c: DVec3::ZERO,
            r: DVec3::ZERO,
            first: 0,
            count: 0,
            order: 0,
            size: 0,
        }];
        let mut stack = vec![(0usize, 0usize, items.len(), 0usize)];
        while let Some((node, begin, end, depth)) = stack.pop() {
            // The node's primal box and normals' ranges are the union of its items' (the
            // offsets' range, lo[3] and hi[3], is taken about the node's centre below).
            let mut b = Bounds::EMPTY;
            let mut mext = 0.0f64;
            for it in &items[begin..end] {
                b.add(it);
                mext = mext.max(self.mesh_extent[it.id as usize]);
            }
            let (plo, phi) = (DVec3::from_slice(&b.lo[..3]), DVec3::from_slice(&b.hi[..3]));
            let mut lo = [b.lo[3], b.lo[4], b.lo[5], 0.0];
            let mut hi = [b.hi[3], b.hi[4], b.hi[5], 0.0];
            // The offsets relative to the node's centre `c` (in f32, as the query reads it):
            // g·(p, 1) = n·(p − c) + (g₃ + n·c), and the second term ranges over about the
            // node's size, where g₃ ranged over |n|·|c| more.
            let c = (0.5 * (plo + phi)).as_vec3().as_dvec3();
            // Half extents about c, rounded up (Node4::set rounds them up to f32 again).
            let r = (phi - c).max(c - plo) * (1.0 + 4.0 * f64::EPSILON);
            {
                let (mut dlo, mut dhi) = (f64::INFINITY, f64::NEG_INFINITY);
                for Item { d, pad, .. } in &items[begin..end] {
                    for g in d {
                        let v = g[3] + g[0] * c.x + g[1] * c.y + g[2] * c.z;
                        let err = DOT_ROUNDING * (g[3].abs() + c.abs().element_sum()) + pad;
                        dlo = dlo.min(v - err);
                        dhi = dhi.max(v + err);
                    }
                }
                self.dmax = self.dmax.max(dlo.abs()).max(dhi.abs());
                self.cmax = self.cmax.max(c.abs().element_sum());
                lo[3] = dlo;
                hi[3] = dhi;
            }
            if node == 0 {
                self.root_box = (plo, phi);
            }
            let n = end - begin;
            if n <= LEAF {
                self.leaves.push(LeafPlanes::new(c, &items[begin..end]));
                let (first, order) = (self.leaves.len() as u32 - 1, self.order.len() as u32);
                nodes[node] = BuildNode { lo, hi, c, r, first, count: n as u32, order, size: n as u32 };
                for Item { id, d, pad, .. } in &items[begin..end] {
                    self.order.push(self.order_edge(*id));
                    self.dual.push(*d);
                    self.pad.push(*pad);
                }
                continue;
            }
            let mid = split(&mut items[begin..end], &b, c, mext, depth);
            let first = nodes.len();
            let empty = BuildNode { lo, hi, c, r, first: 0, count: 0, order: 0, size: 0 };
            nodes.push(empty);
            nodes.push(empty);
            nodes[node] = BuildNode { lo, hi, c, r, first: first as u32, count: 0, order: 0, size: n as u32 };
            stack.push((first + 1, begin + mid, end, depth + 1));
            stack.push((first, begin, begin + mid, depth + 1));
        }
        self.nodes = collapse(&nodes);
    }

    /// The signed plane of a boundary edge's one triangle and its pad ([`signed_plane`]);
    /// an infinite pad (never certain) for other edges and degenerate triangles.
    fn boundary_plane(&self, id: u32) -> ([f64; 4], f64) {
        let e = self.edges[id as usize];
        let never = ([0.0; 4], f64::INFINITY);
        if e.count != 1 {
            return never;
        }
        let (a, b) = (self.verts[e.a as usize], self.verts[e.b as usize]);
        let c = self.verts[self.opposite[e.start as usize] as usize];
        signed_plane(a, b, c).unwrap_or(never)
    }

    /// A world point in the hierarchy's normalised coordinates.
    pub fn normalise(&self, p: Vec3) -> DVec3 {
        (p.as_dvec3() - self.center) * self.inv_scale
    }

    /// World length to normalised length.
    pub fn inv_scale(&self) -> f64 {
        self.inv_scale
    }

    pub fn edge_count(&self) -> usize {
        self.edges.len()
    }

    /// Edges tested at every point (boundary, non-manifold, degenerate).
    pub fn always_tested(&self) -> usize {
        self.always.len()
    }

    /// The exact weight of edge `id` at `p` (normalised).
    fn weight(&self, id: u32, p: DVec3) -> i32 {
        let e = self.edges[id as usize];
        let (a, b) = (self.verts[e.a as usize], self.verts[e.b as usize]);
        self.opposite[e.start as usize..(e.start + e.count) as usize]
            .iter()
            .map(|&c| orient3d(a, b, self.verts[c as usize], p) as i32)
            .sum()
    }

    /// Appends edge `id` if it is a contour of `p` not culled; `w`: its weight when the f64
    /// filter already decided it (else the exact predicate does).
    #[inline(always)]
    fn emit(&self, id: u32, p: DVec3, cull: &Cull, w: Option<i32>, out: &mut Vec<Contour>) {
        self.emit_ordered(&self.order_edge(id), p, cull, w, out);
    }

    /// Edge `id`'s record: its index, vertex indices and ends.
    fn order_edge(&self, id: u32) -> OrderEdge {
        let e = self.edges[id as usize];
        OrderEdge { a: self.verts[e.a as usize], b: self.verts[e.b as usize], va: e.a, vb: e.b, id }
    }

    /// [`Self::emit`] from the edge's record (a hierarchy edge's, in leaf order).
    #[inline(always)]
    fn emit_ordered(&self, e: &OrderEdge, p: DVec3, cull: &Cull, w: Option<i32>, out: &mut Vec<Contour>) {
        if cull.behind(e.a) && cull.behind(e.b) {
            return;
        }
        let w = w.unwrap_or_else(|| self.weight(e.id, p));
        if w != 0 {
            out.push(Contour { edge: e.id, va: e.va, vb: e.vb, a: e.a, b: e.b, w });
        }
    }

    /// The contour edges of `p` (normalised coordinates) not wholly behind the plane through
    /// `p` with normal `n` (within `tol`, see [`Cull`]), appended to `out` in the hierarchy's
    /// order (the traversal's result does not depend on the order; sorting them by edge cost a
    /// third of a shading point's time on a 79k-triangle scene). Returns the number of edges
    /// the hierarchy did not reject (each tested exactly, or by a certain f64 filter) and the
    /// nodes it visited.
    pub fn contours(&self, p: DVec3, n: DVec3, tol: f64, out: &mut Vec<Contour>) -> QueryCost {
        let mut examined = self.always.len();
        let mut visited = 0;
        let cull = Cull { p, n, tol };
        // The rounding pads hold for |p| ≤ 4 (signed_plane).
        let near = p.abs().max_element() <= 4.0;
        for (&id, (g, pad)) in self.always.iter().zip(&self.always_plane) {
            // A boundary edge's weight is its one triangle's side, ±1 (never 0 off its
            // plane): the f64 filter decides it where it is certain.
            let v = dot4(g, p);
            let certain = (near && v.abs() > *pad).then_some(if v > 0.0 { 1 } else { -1 });
            self.emit(id, p, &cull, certain, out);
        }
        if self.nodes.is_empty() {
            return QueryCost { edges: examined, nodes: 0 };
        }
        let query = NodeQuery::new(p, n, tol, self.root_box, self.dmax, self.cmax);
        let mut stack = [0u32; 256];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            visited += node.len as usize;
            let mut mask = query.visits(node);
            // Ask for every surviving slot's data before the first is read, so the fetches
            // overlap (the hierarchy is larger than the core's cache: each is a miss).
            let mut ahead = mask;
            while ahead != 0 {
                let j = ahead.trailing_zeros() as usize;
                ahead &= ahead - 1;
                if node.count[j] == 0 {
                    prefetch(&self.nodes[node.first[j] as usize], 5);
                } else {
                    prefetch(&self.leaves[node.first[j] as usize], 10);
                    prefetch(&self.order[node.order[j] as usize], node.count[j] as usize);
                }
            }
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let (first, count, records) = (node.first[j], node.count[j], node.order[j] as usize);
                if count == 0 {
                    // Deeper than the stack is impossible: see MAX_SAH_DEPTH.
                    assert!(sp < stack.len(), "dual-edge hierarchy deeper than its traversal stack");
                    stack[sp] = first;
                    sp += 1;
                    continue;
                }
                examined += count as usize;
                let leaf = &self.leaves[first as usize];
                let (lanes, opposite, positive) = query.leaf_edges(leaf);
                let mut lanes = lanes & ((1u32 << count) - 1);
                while lanes != 0 {
                    let j = lanes.trailing_zeros();
                    let i = records + j as usize;
                    lanes &= lanes - 1;
                    if (opposite >> j) & 1 != 0 {
                        // What the f64 test below decides for it (the f32 test's slack covers
                        // both roundings): a contour, of weight ±2 where the pads hold.
                        let w = if (positive >> j) & 1 != 0 { 2 } else { -2 };
                        self.emit_ordered(&self.order[i], p, &cull, near.then_some(w), out);
                        continue;
                    }
                    let [g1, g2] = &self.dual[i];
                    let (v1, v2) = (dot4(g1, p), dot4(g2, p));
                    let pad = self.pad[i];
                    // Both ends certainly on one side: not a contour. Certainly on opposite
                    // sides: both triangles on one side of the plane through p and the edge
                    // (side₁ = side₂ = sign v₁), a contour of weight ±2 without the exact
                    // predicate (inside the pad's range |p| ≤ 4).
                    if (v1 > pad && v2 > pad) || (v1 < -pad && v2 < -pad) {
                        continue;
                    }
                    let certain = (near && v1.abs() > pad && v2.abs() > pad).then_some(if v1 > 0.0 { 2 } else { -2 });
                    self.emit_ordered(&self.order[i], p, &cull, certain, out);
                }
            }
        }
        QueryCost { edges: examined, nodes: visited }
    }

    /// [`contours`](Self::contours) by testing every edge (the oracle).
    pub fn contours_brute_force(&self, p: DVec3, n: DVec3, tol: f64, out: &mut Vec<Contour>) {
        let cull = Cull { p, n, tol };
        for id in 0..self.edges.len() as u32 {
            self.emit(id, p, &cull, None, out);
        }
    }
}

/// The tangent-plane cull: a point `x` is behind when `n·(x−p) ≤ tol·|x−p|₁` (an elevation
/// below ~`tol` radians; `tol` absorbs the rounding of a normal given in f32).
#[derive(Clone, Copy, Debug)]
pub struct Cull {
    pub p: DVec3,
    pub n: DVec3,
    pub tol: f64,
}

impl Cull {
    pub fn behind(&self, x: DVec3) -> bool {
        let d = x - self.p;
        self.n.dot(d) <= self.tol * (d.x.abs() + d.y.abs() + d.z.abs())
    }
}
