//! Spherical polygons seen from a shading point (f64 throughout): projection,
//! horizon clipping, clamped-cosine edge integrals (Lambert / Baum et al. /
//! Arvo), solid angle, robust set difference, and silhouette loops of convex
//! meshes — the geometric half of the `ltc` integrator (seed 004).
//!
//! # Conventions
//!
//! * A *loop* is a closed sequence of direction vectors (unit or not, never
//!   zero) seen from the origin (the shading point); consecutive vertices are
//!   joined by the minor great-circle arc, the last one back to the first.
//! * Every loop must lie in an open hemisphere (some `m` with `v·m > 0` for all
//!   vertices). The projection of a planar polygon whose plane does not contain
//!   the shading point, and the silhouette of a convex object not containing
//!   it, always do. Its *region* is the one inside that hemisphere.
//! * **Orientation**: a loop is *positive* when it turns counter-clockwise about
//!   the outward direction (right-hand rule: `vᵢ × vᵢ₊₁` points into the region
//!   for a small convex loop). All integrals here are signed: a positive loop
//!   has positive solid angle and positive form factor (for a region above the
//!   horizon); reversing a loop negates them.
//! * A **set of loops** (the result of [`difference`]) represents the region
//!   whose winding number is the sum over loops: outer boundaries are positive,
//!   holes are negative, and any additive quantity (form factor, solid angle,
//!   LTC integral) of the region is the plain sum of the loops' signed values.
//!
//! # Set difference
//!
//! [`difference`] works in the six gnomonic charts of the cube map: every loop
//! is clipped (Sutherland–Hodgman against four planes through the origin, exact
//! on great circles) to each face's pyramid `{d : d·n ≥ |d·u|, d·n ≥ |d·v|}` and
//! projected onto that face's plane, where great arcs become segments and all
//! coordinates lie in `[-1, 1]²`. This is the paper's plane projection without
//! its limits: no vertex is ever projected from behind or near the projection
//! plane's horizon, whatever the occluders' position (partly behind the shading
//! point, spanning more than a hemisphere together, ...). The planar Boolean
//! (`light − ∪ occluders`, non-zero fill; [`intersection`] and [`union`] alike)
//! is done by the `i_overlay` crate, which
//! snaps to an integer grid and is robust to shared vertices, shared and
//! collinear edges, coincident polygons and zero-area input; each face's result
//! is lifted back to the sphere. The internal edges along face boundaries
//! appear twice with opposite directions and cancel in every edge-integral sum
//! (the edge integral is additive along a great circle).
//!
//! Snapping costs at most ~1e-9 rad per vertex (i32 grid over `[-1, 1]`).

use glam::DVec3;
use i_overlay::core::fill_rule::FillRule;
use i_overlay::core::overlay_rule::OverlayRule;
use i_overlay::float::overlay::FloatOverlay;

pub use penumbra_core::geometry::orthonormal_basis;
use penumbra_core::mesh::{EdgeAdjacency, TriangleMesh, BOUNDARY};

pub mod cone;

/// Unit directions from `p` to each of `points` (a point equal to `p` gives a
/// zero vector, which the other functions treat as degenerate).
pub fn project(p: DVec3, points: &[DVec3]) -> Vec<DVec3> {
    points.iter().map(|q| (*q - p).normalize_or_zero()).collect()
}

/// Clips a loop to the half-space `d·n ≥ 0` (`n` need not be unit).
///
/// Sutherland–Hodgman on the sphere: a vertex with `d·n ≥ 0` is kept, an edge
/// strictly crossing the plane gets its crossing point (on the great circle,
/// exactly on the plane), vertices lying on the plane are kept and create no
/// extra point. For a non-convex loop crossing the plane several times the
/// output may contain edges running back and forth along the clipping great
/// circle; they are exact in every additive integral. Returns an empty vector
/// when fewer than three vertices survive.
pub fn clip_to_halfspace(poly: &[DVec3], n: DVec3) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 4);
    clip_stream(poly.len(), |i| poly[i], n, |v| out.push(v));
    if out.len() < 3 {
        out.clear();
    }
    out
}

/// The Sutherland–Hodgman step of [`clip_to_halfspace`] without a buffer: calls `emit` with
/// each output vertex in order, for the loop of `len` vertices `vertex(0..len)` (each
/// evaluated once). The caller decides what fewer than three outputs mean.
fn clip_stream(len: usize, vertex: impl Fn(usize) -> DVec3, n: DVec3, mut emit: impl FnMut(DVec3)) {
    if len < 3 {
        return;
    }
    let nn = n.length_squared();
    let first = vertex(0);
    let mut a = first;
    for i in 0..len {
        let b = if i + 1 < len { vertex(i + 1) } else { first };
        let (da, db) = (a.dot(n), b.dot(n));
        if da >= 0.0 {
            emit(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let t = da / (da - db);
            let mut c = a + (b - a) * t;
            // Remove the residual component along n so that the point is exactly on the plane
            // (to rounding), which keeps a following clip against the same plane idempotent.
            if nn > 0.0 {
                c -= n * (c.dot(n) / nn);
            }
            emit(c);
        }
        a = b;
    }
}

/// The vector form factor (`(1/2π) Σ edge_vector`) of the loop `vertex(0..len)` clipped to
/// the horizon `z ≥ 0`: [`vector_form_factor`] of [`clip_to_horizon`], without building
/// either loop. Its `z` is [`form_factor`] (bit for bit: the same edges summed in the same
/// order). `vertex` maps each corner once (e.g. into a local or LTC frame).
pub fn horizon_vector_form_factor(len: usize, vertex: impl Fn(usize) -> DVec3) -> DVec3 {
    let (mut first, mut prev, mut count) = (DVec3::ZERO, DVec3::ZERO, 0usize);
    let mut sum = DVec3::ZERO;
    clip_stream(len, vertex, DVec3::Z, |mut v| {
        if v.z < 0.0 {
            v.z = 0.0;
        }
        if count == 0 {
            first = v;
        } else {
            sum += edge_vector(prev, v);
        }
        prev = v;
        count += 1;
    });
    if count < 3 {
        return DVec3::ZERO;
    }
    sum += edge_vector(prev, first);
    sum / std::f64::consts::TAU
}

/// Clips a loop to the intersection of the half-spaces `d·n ≥ 0` of `planes` (a convex region),
/// one [`clip_to_halfspace`] after another, skipping (without copying) the planes it lies wholly
/// inside. Returns the clipped loop (empty when nothing is left) and whether any plane cut it
/// (`false`: the loop, unchanged, is inside them all).
pub fn clip_to_halfspaces(poly: &[DVec3], planes: impl IntoIterator<Item = DVec3>) -> (Vec<DVec3>, bool) {
    let mut out = poly.to_vec();
    let mut clipped = false;
    for n in planes {
        if out.iter().all(|d| d.dot(n) >= 0.0) {
            continue;
        }
        out = clip_to_halfspace(&out, n);
        clipped = true;
        if out.is_empty() {
            break;
        }
    }
    (out, clipped)
}

/// Clips a loop to the upper hemisphere `z ≥ 0` of its local frame (keeps the
/// part above the horizon); see [`clip_to_halfspace`]. Vertices exactly on the
/// horizon are kept; crossing points get `z = 0` exactly.
pub fn clip_to_horizon(poly: &[DVec3]) -> Vec<DVec3> {
    let mut out = clip_to_halfspace(poly, DVec3::Z);
    for v in &mut out {
        if v.z < 0.0 {
            v.z = 0.0;
        }
    }
    out
}

/// The vector edge integral of the arc `v1 → v2`: `θ · normalize(v1 × v2)`
/// with `θ = ∠(v1, v2)` computed as `atan2(|v1×v2|, v1·v2)`. Zero for a
/// degenerate edge (coincident or zero vectors); for exactly antipodal
/// vertices (no defined arc) also zero.
pub fn edge_vector(v1: DVec3, v2: DVec3) -> DVec3 {
    let c = v1.cross(v2);
    let s = c.length();
    if s == 0.0 || !s.is_finite() {
        return DVec3::ZERO;
    }
    // θ / |c| is well conditioned even for a tiny |c|: atan2 gives θ ≈ |c| / (v1·v2) to full
    // relative precision, whatever error the cross product's cancellation put in |c|.
    c * (s.atan2(v1.dot(v2)) / s)
}

/// Lambert/Arvo edge integral of the arc `v1 → v2` against the `z` axis:
/// `acos(v̂1·v̂2) · normalize(v1 × v2).z` (robust, see [`edge_vector`]).
pub fn edge_integral(v1: DVec3, v2: DVec3) -> f64 {
    edge_vector(v1, v2).z
}

/// `(1/2π) Σ edge_vector` of a loop, *without* horizon clipping: the vector
/// form factor `F` of the region (`F·n` is the form factor for a receiver with
/// normal `n` when the region lies above its horizon). Used by LTC "sphere
/// proxy" horizon handling: `|F|` and `F/|F|` define the equivalent spherical cap.
pub fn vector_form_factor(poly: &[DVec3]) -> DVec3 {
    let n = poly.len();
    if n < 3 {
        return DVec3::ZERO;
    }
    let mut sum = DVec3::ZERO;
    for i in 0..n {
        sum += edge_vector(poly[i], poly[(i + 1) % n]);
    }
    sum / std::f64::consts::TAU
}

/// Signed clamped-cosine form factor `(1/π) ∫ max(0, z) dω` of a loop's
/// region (positive for a positive loop): the loop is clipped to the horizon,
/// then `(1/2π) Σ edge_integral`.
pub fn form_factor(poly: &[DVec3]) -> f64 {
    horizon_vector_form_factor(poly.len(), |i| poly[i]).z
}

/// Sum of the signed form factors of a set of loops (a region with holes).
pub fn form_factor_loops(loops: &[Vec<DVec3>]) -> f64 {
    loops.iter().map(|l| form_factor(l)).sum()
}

/// Signed solid angle of a loop: the sum over the fan triangles `(v0, vi, vi+1)`
/// of Van Oosterom–Strackee's `2 atan2(a·(b×c), 1 + a·b + b·c + c·a)` (unit
/// vectors). Exact for any loop inside an open hemisphere.
pub fn solid_angle(poly: &[DVec3]) -> f64 {
    let n = poly.len();
    if n < 3 {
        return 0.0;
    }
    let a = poly[0].normalize_or_zero();
    let mut sum = 0.0;
    for i in 1..n - 1 {
        let b = poly[i].normalize_or_zero();
        let c = poly[i + 1].normalize_or_zero();
        let num = a.dot(b.cross(c));
        let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
        if num != 0.0 || den > 0.0 {
            sum += 2.0 * num.atan2(den);
        }
    }
    sum
}

/// A direction `m` with `v̂·m > 0` for every vertex of the loop (the centre of
/// an open hemisphere containing it), or `None` if there is none (or it is too
/// thin to find in 10 000 steps: margins below ~1e-6).
///
/// Gilbert's algorithm for the point `p` of the vertices' convex hull nearest
/// to the origin, stopped as soon as every vertex is strictly in front of `p`:
/// starting from the mean direction, it steps towards the most violating
/// vertex with an exact line search, so `|p|` decreases monotonically and no
/// cycling is possible (the fixed half-step of a normalised perceptron can
/// bounce between the vertices of a wide triangle forever).
pub fn hemisphere_center(poly: &[DVec3]) -> Option<DVec3> {
    let unit: Vec<DVec3> = poly.iter().map(|v| v.normalize_or_zero()).collect();
    if unit.is_empty() || unit.iter().any(|v| *v == DVec3::ZERO || !v.is_finite()) {
        return None;
    }
    let mut p = unit.iter().sum::<DVec3>() / unit.len() as f64;
    for _ in 0..10_000 {
        let mn = p.normalize_or_zero();
        if mn == DVec3::ZERO {
            return None; // the origin is in the hull: no open hemisphere
        }
        let (i, d) = unit.iter().map(|v| v.dot(mn)).enumerate().min_by(|a, b| a.1.total_cmp(&b.1))?;
        if d > 1e-12 {
            return Some(mn);
        }
        let step = unit[i] - p;
        let len2 = step.length_squared();
        let t = if len2 > 0.0 { (-p.dot(step) / len2).clamp(0.0, 1.0) } else { 0.0 };
        if t == 0.0 {
            return None; // p is (to rounding) the nearest point and still violated
        }
        p += step * t;
    }
    None
}

/// Winding number of a loop around direction `d` (non-zero: inside). The loop
/// and `d` are projected gnomonically about [`hemisphere_center`] `m`; `d`
/// with `d·m ≤ 0` is outside. Returns 0 for loops in no open hemisphere.
pub fn winding_number(poly: &[DVec3], d: DVec3) -> i32 {
    if poly.len() < 3 {
        return 0;
    }
    let Some(m) = hemisphere_center(poly) else { return 0 };
    if d.dot(m) <= 0.0 {
        return 0;
    }
    let (u, v) = orthonormal_basis(m);
    let chart = |p: DVec3| {
        let w = p.dot(m);
        (p.dot(u) / w, p.dot(v) / w, w)
    };
    let (qx, qy, _) = chart(d);
    let mut wn = 0;
    let n = poly.len();
    for i in 0..n {
        let (ax, ay, aw) = chart(poly[i]);
        let (bx, by, bw) = chart(poly[(i + 1) % n]);
        if aw <= 0.0 || bw <= 0.0 {
            return 0;
        }
        let cross = (bx - ax) * (qy - ay) - (qx - ax) * (by - ay);
        if ay <= qy {
            if by > qy && cross > 0.0 {
                wn += 1;
            }
        } else if by <= qy && cross < 0.0 {
            wn -= 1;
        }
    }
    wn
}

/// Whether `d` lies inside the loop's region (non-zero winding number).
pub fn contains(poly: &[DVec3], d: DVec3) -> bool {
    winding_number(poly, d) != 0
}

/// Sum of winding numbers of a set of loops around `d` (the region
/// represented by [`difference`]'s output is where this is positive).
pub fn winding_number_loops(loops: &[Vec<DVec3>], d: DVec3) -> i32 {
    loops.iter().map(|l| winding_number(l, d)).sum()
}

// --- set difference -----------------------------------------------------------------------------

/// The six cube-map charts `(u, v, n)`, right-handed (`u × v = n`).
const FACES: [(DVec3, DVec3, DVec3); 6] = [
    (DVec3::X, DVec3::Y, DVec3::Z),
    (DVec3::Y, DVec3::X, DVec3::NEG_Z),
    (DVec3::Y, DVec3::Z, DVec3::X),
    (DVec3::Z, DVec3::Y, DVec3::NEG_X),
    (DVec3::Z, DVec3::X, DVec3::Y),
    (DVec3::X, DVec3::Z, DVec3::NEG_Y),
];

/// Clips a loop to face `f`'s pyramid and returns its chart coordinates
/// (empty when nothing or only a degenerate piece remains).
fn face_piece(poly: &[DVec3], f: usize) -> Vec<[f64; 2]> {
    let (u, v, n) = FACES[f];
    // Quick reject: every vertex strictly outside one of the four planes.
    for plane in [n - u, n + u, n - v, n + v] {
        if poly.iter().all(|p| p.dot(plane) < 0.0) {
            return Vec::new();
        }
    }
    let mut piece = clip_to_halfspace(poly, n - u);
    piece = clip_to_halfspace(&piece, n + u);
    piece = clip_to_halfspace(&piece, n - v);
    piece = clip_to_halfspace(&piece, n + v);
    let mut out = Vec::with_capacity(piece.len());
    for p in piece {
        let w = p.dot(n);
        if w <= 0.0 {
            continue; // only the zero vector (or rounding at it) can get here
        }
        let (x, y) = (p.dot(u) / w, p.dot(v) / w);
        if !(x.is_finite() && y.is_finite()) {
            return Vec::new();
        }
        out.push([x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0)]);
    }
    if out.len() < 3 {
        out.clear();
    }
    out
}

fn signed_area2(c: &[[f64; 2]]) -> f64 {
    let n = c.len();
    (0..n).map(|i| c[i][0] * c[(i + 1) % n][1] - c[(i + 1) % n][0] * c[i][1]).sum()
}

fn bbox(c: &[[f64; 2]]) -> [f64; 4] {
    c.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
        [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
    })
}

fn loop_is_usable(l: &[DVec3]) -> bool {
    l.len() >= 3 && l.iter().all(|v| v.is_finite() && *v != DVec3::ZERO)
}

/// The visible part of a light seen from the origin: the region of `light`
/// (a set of loops combined by winding number, non-zero = inside; a single
/// loop of either orientation is fine, a previous result can be fed back)
/// minus the union of the `occluders`' regions (each a loop of either
/// orientation; they may overlap, share vertices or edges, be degenerate,
/// lie partly behind the shading point or cover the light entirely).
///
/// Returns loops following the module convention: outer boundaries positive,
/// holes negative; the visible integral of any additive quantity is the sum
/// over the returned loops of its signed value. Loops with a zero or
/// non-finite vertex, or fewer than three vertices, are ignored.
///
/// Cost: linear in the input size plus `i_overlay`'s `O(n log n)` sweep per
/// cube face touched by the light; occluder pieces whose chart bounding box
/// misses the light's are dropped before the sweep.
pub fn difference(light: &[Vec<DVec3>], occluders: &[Vec<DVec3>]) -> Vec<Vec<DVec3>> {
    chart_overlay(light, occluders, &[], OverlayRule::Difference)
}

/// [`difference`] for one occluder whose loop is convex (the silhouette of a convex object
/// seen from outside, a triangle): the light minus its part inside the occluder, as the loops
/// `[light⁺, −(light⁺ ∩ occluder)]` — exact in every additive integral (the module's winding
/// convention), with `light⁺ ∩ occluder` clipped by Sutherland–Hodgman against the
/// occluder's edge planes instead of a planar Boolean over the cube-map charts. `light` is a
/// loop of either orientation; `occluder` a simple loop of either orientation.
///
/// Returns `[]` when the occluder covers the light, `[light⁺]` when it misses it, and `None`
/// (use [`difference`]) when it does not apply: a loop unusable, or the occluder's not convex
/// (turns of both signs) or not in an open hemisphere around its mean direction.
pub fn difference_convex(light: &[DVec3], occluder: &[DVec3]) -> Option<Vec<Vec<DVec3>>> {
    if !loop_is_usable(light) || !loop_is_usable(occluder) {
        return None;
    }
    let n = occluder.len();
    let unit: Vec<DVec3> = occluder.iter().map(|d| d.normalize()).collect();
    let mean: DVec3 = unit.iter().sum();
    if unit.iter().any(|d| d.dot(mean) <= 0.0) {
        return None;
    }
    // Turns det[v₋, v, v₊]: all ≥ 0 for a positive convex loop (zero where vertices are
    // collinear, to rounding), all ≤ 0 for a negative one.
    const COLLINEAR: f64 = 1e-12;
    let (mut left, mut right) = (false, false);
    for i in 0..n {
        let t = unit[(i + n - 1) % n].dot(unit[i].cross(unit[(i + 1) % n]));
        left |= t > COLLINEAR;
        right |= t < -COLLINEAR;
    }
    let mut light = light.to_vec();
    if solid_angle(&light) < 0.0 {
        light.reverse();
    }
    match (left, right) {
        (true, true) => return None,
        (false, false) => return Some(vec![light]), // zero area
        _ => {}
    }
    // Each edge's plane, turned towards the occluder's side of its great circle.
    let planes = (0..n).map(|i| {
        let (a, b) = (unit[i], unit[(i + 1) % n]);
        if left {
            a.cross(b)
        } else {
            b.cross(a)
        }
    });
    let (mut inside, clipped) = clip_to_halfspaces(&light, planes);
    if !clipped {
        return Some(Vec::new()); // the light lies within every edge's half-space
    }
    if inside.is_empty() {
        return Some(vec![light]);
    }
    inside.reverse();
    Some(vec![light, inside])
}

/// [`difference`] with two kinds of occluders: `loops`, each a region of its own (either
/// orientation, as in [`difference`]), and `chains`, loops taken together by winding
/// number — their sum must be non-negative everywhere, and the region is where it is
/// positive. [`triangle_chains`] makes such chains: the boundary of many adjacent
/// triangles, far fewer edges than the triangles one by one. Same cost model as
/// [`difference`], in the number of edges.
pub fn difference_chains(light: &[Vec<DVec3>], loops: &[Vec<DVec3>], chains: &[Vec<DVec3>]) -> Vec<Vec<DVec3>> {
    chart_overlay(light, loops, chains, OverlayRule::Difference)
}

/// The part of the region of `a` covered by the union of the `b` loops: the
/// complement of [`difference`]`(a, b)` within `a`, with the same input
/// conventions (`a` a set of loops combined by winding number, non-zero =
/// inside, e.g. a single loop of either orientation or a previous result;
/// each loop of `b` a region of its own of either orientation, overlapping,
/// degenerate or partly behind the shading point as you like).
///
/// Returns loops following the module convention (outer boundaries positive,
/// holes negative), so that for any additive quantity
/// `Σ difference(a, b) + Σ intersection(a, b) = Σ a` up to the ~1e-9 rad
/// snapping. Unusable loops are ignored as in [`difference`]; the result is
/// empty when `b` has no usable loop. Same cost as [`difference`].
pub fn intersection(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> Vec<Vec<DVec3>> {
    chart_overlay(a, b, &[], OverlayRule::Intersect)
}

/// The union of the region of `a` (loops combined by winding number, as the
/// light of [`difference`]) and of every loop of `b` (each a region of its
/// own, of either orientation), as positively oriented outer loops and
/// negative holes. Unusable loops are ignored as in [`difference`]. Every
/// cube face touched by either input gets an `i_overlay` sweep.
pub fn union(a: &[Vec<DVec3>], b: &[Vec<DVec3>]) -> Vec<Vec<DVec3>> {
    chart_overlay(a, b, &[], OverlayRule::Union)
}

/// The planar Boolean `rule` (`Difference`, `Intersect` or `Union`) of the
/// region of `subject` (non-zero winding) and the union of the `clip` loops (each
/// a region of its own) and of the region of the `chains` (by winding number),
/// face by face of the cube map (see the module docs).
fn chart_overlay(
    subject: &[Vec<DVec3>],
    clip_loops: &[Vec<DVec3>],
    chains: &[Vec<DVec3>],
    rule: OverlayRule,
) -> Vec<Vec<DVec3>> {
    let mut result = Vec::new();
    let subject: Vec<&Vec<DVec3>> = subject.iter().filter(|l| loop_is_usable(l)).collect();
    // A chain with an unusable loop would change the winding of the others: all or nothing.
    let chains: Vec<&Vec<DVec3>> =
        if chains.iter().all(|l| loop_is_usable(l)) { chains.iter().collect() } else { Vec::new() };
    let clip_loops: Vec<(&Vec<DVec3>, bool)> = clip_loops
        .iter()
        .filter(|l| loop_is_usable(l))
        .map(|l| (l, false))
        .chain(chains.into_iter().map(|l| (l, true)))
        .collect();
    let is_union = matches!(rule, OverlayRule::Union);
    for (f, &(u, v, n)) in FACES.iter().enumerate() {
        let subj: Vec<Vec<[f64; 2]>> = subject.iter().map(|l| face_piece(l, f)).filter(|c| !c.is_empty()).collect();
        if subj.is_empty() && !is_union {
            continue;
        }
        let lb = subj
            .iter()
            .map(|c| bbox(c))
            .fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, c| {
                [b[0].min(c[0]), b[1].min(c[1]), b[2].max(c[2]), b[3].max(c[3])]
            });
        let mut clip: Vec<Vec<[f64; 2]>> = Vec::new();
        for &(o, chained) in &clip_loops {
            let mut c = face_piece(o, f);
            if c.is_empty() {
                continue;
            }
            // Pieces away from the subject change neither its difference nor its intersection.
            let ob = bbox(&c);
            if !is_union && (ob[0] > lb[2] || ob[2] < lb[0] || ob[1] > lb[3] || ob[3] < lb[1]) {
                continue;
            }
            if chained {
                // Positive charts (u × v = n) keep the loops' orientation: holes stay holes.
                clip.push(c);
                continue;
            }
            let a = signed_area2(&c);
            if a == 0.0 {
                continue;
            }
            if a < 0.0 {
                c.reverse(); // union by non-zero winding needs a common orientation
            }
            clip.push(c);
        }
        let shapes = match (subj.is_empty(), clip.is_empty()) {
            (true, true) => continue,
            // Nothing to intersect with.
            (_, true) if matches!(rule, OverlayRule::Intersect) => continue,
            // Nothing to subtract or add: still normalise through the overlay (orientation, holes).
            (_, true) => FloatOverlay::with_subj(&subj).overlay(OverlayRule::Subject, FillRule::NonZero),
            (true, false) => FloatOverlay::with_subj(&clip).overlay(OverlayRule::Subject, FillRule::NonZero),
            (false, false) => FloatOverlay::with_subj_and_clip(&subj, &clip).overlay(rule, FillRule::NonZero),
        };
        for shape in shapes {
            for contour in shape {
                if contour.len() < 3 {
                    continue;
                }
                result.push(contour.iter().map(|p| (n + u * p[0] + v * p[1]).normalize()).collect());
            }
        }
    }
    result
}

// --- triangle chains ----------------------------------------------------------------------------

/// The boundary of the triangles `tris` of `mesh`, each taken positively oriented as seen
/// from `p`, as loops of world positions (project them with [`project`]; pass them as
/// `chains` to [`difference_chains`]). Seen from `p`, the winding number of the loops in any
/// direction is the number of those triangles covering it, so their non-zero region is the
/// union of the triangles' projections. Edges that two triangles share (same vertex ids
/// after `weld`, which maps mesh vertex indices to ids; empty: the indices themselves) in
/// opposite directions cancel: for a connected patch only its outline remains, for a closed
/// mesh the silhouette edges.
pub fn triangle_chains(mesh: &TriangleMesh, tris: &[usize], weld: &[u32], p: DVec3) -> Vec<Vec<DVec3>> {
    let id = |i: u32| -> u32 { weld.get(i as usize).copied().unwrap_or(i) };
    // Directed edges as (low id, high id, +1 low→high / −1 high→low, mesh index of low, of high).
    let mut edges: Vec<(u32, u32, i32, u32, u32)> = Vec::with_capacity(tris.len() * 3);
    for &t in tris {
        let Some(idx) = mesh.indices.get(t) else { continue };
        let pv = mesh.vertices(t).map(|q| q.as_dvec3());
        let det = (pv[0] - p).dot((pv[1] - p).cross(pv[2] - p));
        let idx = if det >= 0.0 { *idx } else { [idx[0], idx[2], idx[1]] };
        for k in 0..3 {
            let (a, b) = (idx[k], idx[(k + 1) % 3]);
            let (ia, ib) = (id(a), id(b));
            match ia.cmp(&ib) {
                std::cmp::Ordering::Less => edges.push((ia, ib, 1, a, b)),
                std::cmp::Ordering::Greater => edges.push((ib, ia, -1, b, a)),
                std::cmp::Ordering::Equal => {} // welded ends: no edge
            }
        }
    }
    edges.sort_unstable_by_key(|e| (e.0, e.1));
    // Net multiplicity per undirected edge, expanded back into directed edges
    // (start id, end id, start's mesh index).
    let mut directed: Vec<(u32, u32, u32)> = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let (a, b, ra, rb) = (edges[i].0, edges[i].1, edges[i].3, edges[i].4);
        let mut m = 0i32;
        while i < edges.len() && edges[i].0 == a && edges[i].1 == b {
            m += edges[i].2;
            i += 1;
        }
        for _ in 0..m.unsigned_abs() {
            directed.push(if m > 0 { (a, b, ra) } else { (b, a, rb) });
        }
    }
    // In-degree equals out-degree at every vertex: walking unused edges always closes a loop.
    directed.sort_unstable();
    let position = |raw: u32| mesh.positions.get(raw as usize).map(|q| q.as_dvec3()).unwrap_or(DVec3::ZERO);
    let mut used = vec![false; directed.len()];
    let first_unused = |v: u32, used: &[bool]| -> Option<usize> {
        let start = directed.partition_point(|e| e.0 < v);
        (start..directed.len()).take_while(|&k| directed[k].0 == v).find(|&k| !used[k])
    };
    let mut loops = Vec::new();
    for s in 0..directed.len() {
        if used[s] {
            continue;
        }
        used[s] = true;
        let start = directed[s].0;
        let mut chain = vec![position(directed[s].2)];
        let mut cur = directed[s].1;
        while cur != start {
            match first_unused(cur, &used) {
                Some(k) => {
                    used[k] = true;
                    chain.push(position(directed[k].2));
                    cur = directed[k].1;
                }
                None => break, // cannot happen for balanced degrees; the loop is closed anyway
            }
        }
        if chain.len() >= 3 {
            loops.push(chain);
        }
    }
    loops
}

// --- silhouettes --------------------------------------------------------------------------------

/// The silhouette loop(s) of a closed convex triangle mesh seen from `p`, as
/// world-space positions (project them with [`project`]).
///
/// A triangle is front-facing when `n̂·(p − a) > eps` (`n̂` its unit outward
/// winding normal, `a` a vertex); triangles within `eps` of edge-on (and
/// degenerate ones) count as back-facing, consistently for both sides of
/// every edge. Silhouette edges separate a front-facing from a back-facing
/// triangle; they are chained into closed loops along the boundary of the
/// front-facing patch and returned **positively oriented as seen from `p`**
/// (the reverse of the front faces' winding), so `form_factor(project(p, loop))`
/// is ≥ 0 when the silhouette is above the horizon.
///
/// For a convex mesh and `p` outside it this is one loop; an empty result
/// means no triangle faces `p` (p inside, or edge-on everywhere). A chain that
/// does not close (non-convex or open mesh) is dropped.
pub fn silhouette_loops(mesh: &TriangleMesh, adj: &EdgeAdjacency, p: DVec3, eps: f64) -> Vec<Vec<DVec3>> {
    SilhouetteMesh::new(mesh, adj).loops(p, eps)
}

/// What [`silhouette_loops`] needs of a mesh, computed once for the many points it is seen from:
/// welded positions, each triangle's vertices and unit winding normal, and the manifold edges.
#[derive(Clone, Debug, Default)]
pub struct SilhouetteMesh {
    positions: Vec<DVec3>,
    /// (vertices, unit normal; zero for a degenerate triangle).
    faces: Vec<([DVec3; 3], DVec3)>,
    /// Edges shared by two triangles: (welded ends in the first triangle's winding, triangles).
    edges: Vec<([u32; 2], [u32; 2])>,
    /// Edges of one triangle (an open mesh's boundary): (welded ends in its winding, triangle).
    boundary: Vec<([u32; 2], u32)>,
}

impl SilhouetteMesh {
    pub fn new(mesh: &TriangleMesh, adj: &EdgeAdjacency) -> SilhouetteMesh {
        let mut positions = vec![DVec3::ZERO; adj.welded_count];
        for (i, w) in adj.weld.iter().enumerate() {
            if let (Some(slot), Some(q)) = (positions.get_mut(*w as usize), mesh.positions.get(i)) {
                *slot = q.as_dvec3();
            }
        }
        let faces = (0..mesh.triangle_count())
            .map(|t| {
                let v = mesh.vertices(t).map(|q| q.as_dvec3());
                (v, (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero())
            })
            .collect();
        let edges = adj.edges.iter().filter(|e| e.count == 2 && e.tris[1] != BOUNDARY).map(|e| (e.v, e.tris)).collect();
        let boundary = adj.edges.iter().filter(|e| e.count == 1).map(|e| (e.v, e.tris[0])).collect();
        SilhouetteMesh { positions, faces, edges, boundary }
    }

    /// [`silhouette_loops`] from `p`. For an open mesh, the boundary edges of the faces turned
    /// towards `p` close the loops: the outline of what `p` sees of an open convex surface (a
    /// cylinder without caps: its two silhouette lines and the front arcs of its rims).
    pub fn loops(&self, p: DVec3, eps: f64) -> Vec<Vec<DVec3>> {
        let front: Vec<bool> = self
            .faces
            .iter()
            .map(|([a, b, c], n)| {
                *n != DVec3::ZERO && n.dot(p - *a) > eps && n.dot(p - *b) > eps && n.dot(p - *c) > eps
            })
            .collect();
        // Directed silhouette edges start -> end, following the front triangle's winding,
        // sorted by start (stably: of several edges leaving one vertex, the last found is
        // taken first).
        let mut next: Vec<(u32, u32)> = Vec::new();
        for (v, tris) in &self.edges {
            let f0 = front.get(tris[0] as usize).copied().unwrap_or(false);
            let f1 = front.get(tris[1] as usize).copied().unwrap_or(false);
            if f0 != f1 {
                next.push(if f0 { (v[0], v[1]) } else { (v[1], v[0]) });
            }
        }
        for (v, t) in &self.boundary {
            if front.get(*t as usize).copied().unwrap_or(false) {
                next.push((v[0], v[1]));
            }
        }
        next.sort_by_key(|e| e.0);
        let mut used = vec![false; next.len()];
        let mut left = next.len();
        // The unused edge leaving `v` found last, if any.
        let take = |v: u32, used: &mut [bool]| -> Option<u32> {
            let hi = next.partition_point(|e| e.0 <= v);
            let lo = next.partition_point(|e| e.0 < v);
            let k = (lo..hi).rev().find(|&k| !used[k])?;
            used[k] = true;
            Some(next[k].1)
        };
        let mut loops = Vec::new();
        while left > 0 {
            // The smallest vertex id with an unused edge: the same start on every run, so the
            // loop's vertex order, and its integrals to the last bit, are too.
            let Some(start) = next.iter().zip(&used).find(|(_, u)| !**u).map(|(e, _)| e.0) else { break };
            let mut chain = vec![start];
            let mut cur = start;
            let mut closed = false;
            while let Some(nx) = take(cur, &mut used) {
                left -= 1;
                if nx == start {
                    closed = true;
                    break;
                }
                chain.push(nx);
                cur = nx;
                if chain.len() > next.len() + 1 {
                    break;
                }
            }
            if closed && chain.len() >= 3 {
                let mut l: Vec<DVec3> =
                    chain.iter().map(|&i| self.positions.get(i as usize).copied().unwrap_or(DVec3::ZERO)).collect();
                l.reverse();
                loops.push(l);
            }
        }
        loops
    }
}

#[cfg(test)]
mod tests;
