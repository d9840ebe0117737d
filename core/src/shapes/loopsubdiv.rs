//! `Shape "loopsubdiv"`: pbrt-v3's Loop subdivision — `nlevels` (default 3;
//! `levels` is accepted too) rounds of 1→4 splitting with Loop's even/odd
//! rules and pbrt-v3's boundary rules, then every vertex is pushed to its limit
//! position and given its limit normal `S × T` from pbrt-v3's tangent masks.
//!
//! As in pbrt-v3, the limit normals point opposite to the counter-clockwise
//! winding normal of the control mesh; the result is a mesh with normals, so
//! pbrt-v3's `n = faceforward(ng, ns)` rule makes the shading normals
//! authoritative (see `crate::mesh`).
//!
//! The input must be a consistently oriented 2-manifold (with or without
//! boundary); anything else is an error. Vertices used by no face are dropped.

use super::trianglemesh::{checked_points, checked_triangles};
use super::{loc_or_entity, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

const NONE: u32 = u32::MAX;
/// The subdivided mesh may have at most this many triangles.
pub const MAX_TRIANGLES: usize = 1 << 26;

type V3 = [f64; 3];
/// Limit positions, limit normals, triangles.
type Subdivided = (Vec<V3>, Vec<V3>, Vec<[u32; 3]>);

/// Connectivity of a manifold triangle mesh in pbrt-v3's terms.
struct Topology {
    /// Undirected edge id of edge k = (v[k], v[k+1]) of each face.
    edge_of: Vec<[u32; 3]>,
    /// Neighbour face across edge k (NONE on a boundary).
    nbr: Vec<[u32; 3]>,
    /// Per vertex: its one-ring in pbrt-v3's order (CSR) and whether it is on the boundary.
    ring_start: Vec<u32>,
    ring: Vec<u32>,
    boundary: Vec<bool>,
    /// Endpoints of each undirected edge.
    edges: Vec<[u32; 2]>,
}

/// The hash of a directed edge's key `a << 32 | b`: one `mix_bits` instead of SipHash (the map
/// is only queried, never iterated, so the hasher cannot change the result).
#[derive(Default)]
struct EdgeHasher(u64);

impl Hasher for EdgeHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = crate::rng::mix_bits(self.0 ^ b as u64);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = crate::rng::mix_bits(self.0 ^ v);
    }
}

fn edge_key(a: u32, b: u32) -> u64 {
    (a as u64) << 32 | b as u64
}

fn topology(nv: usize, faces: &[[u32; 3]]) -> Result<Topology, String> {
    let mut directed: HashMap<u64, (u32, u8), BuildHasherDefault<EdgeHasher>> =
        HashMap::with_capacity_and_hasher(faces.len() * 3, Default::default());
    for (f, t) in faces.iter().enumerate() {
        if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
            return Err(format!("face {f} uses a vertex twice"));
        }
        for k in 0..3 {
            if directed.insert(edge_key(t[k], t[(k + 1) % 3]), (f as u32, k as u8)).is_some() {
                return Err(format!(
                    "edge ({}, {}) is used twice in the same direction (non-manifold or inconsistently oriented)",
                    t[k],
                    t[(k + 1) % 3]
                ));
            }
        }
    }
    let mut nbr = vec![[NONE; 3]; faces.len()];
    let mut edge_of = vec![[NONE; 3]; faces.len()];
    let mut edges = Vec::with_capacity(faces.len() * 3 / 2 + 3);
    for (f, t) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if let Some(&(g, kk)) = directed.get(&edge_key(b, a)) {
                nbr[f][k] = g;
                if (g as usize) < f {
                    edge_of[f][k] = edge_of[g as usize][kk as usize];
                    continue;
                }
            }
            edge_of[f][k] = edges.len() as u32;
            edges.push([a, b]);
        }
    }
    drop(directed);
    // Incident faces per vertex (CSR).
    let mut count = vec![0u32; nv + 1];
    for t in faces {
        for &v in t {
            count[v as usize + 1] += 1;
        }
    }
    for i in 0..nv {
        count[i + 1] += count[i];
    }
    let mut fill = count.clone();
    let mut inc = vec![0u32; faces.len() * 3];
    for (f, t) in faces.iter().enumerate() {
        for &v in t {
            inc[fill[v as usize] as usize] = f as u32;
            fill[v as usize] += 1;
        }
    }
    let vnum = |f: u32, v: u32| faces[f as usize].iter().position(|&x| x == v).unwrap_or(0);
    let next_face = |f: u32, v: u32| nbr[f as usize][vnum(f, v)];
    let prev_face = |f: u32, v: u32| nbr[f as usize][(vnum(f, v) + 2) % 3];
    let next_vert = |f: u32, v: u32| faces[f as usize][(vnum(f, v) + 1) % 3];
    let prev_vert = |f: u32, v: u32| faces[f as usize][(vnum(f, v) + 2) % 3];
    let mut ring_start = Vec::with_capacity(nv + 1);
    let mut ring = Vec::with_capacity(faces.len() * 3 + nv);
    let mut boundary = vec![false; nv];
    for v in 0..nv as u32 {
        ring_start.push(ring.len() as u32);
        let incident = (count[v as usize + 1] - count[v as usize]) as usize;
        if incident == 0 {
            return Err(format!("vertex {v} is used by no face"));
        }
        let start = inc[count[v as usize] as usize];
        // Walk forward around v.
        let (mut f, mut steps) = (start, 1usize);
        let closed = loop {
            let g = next_face(f, v);
            if g == NONE {
                break false;
            }
            if g == start {
                break true;
            }
            f = g;
            steps += 1;
            if steps > incident {
                return Err(format!("vertex {v} has an inconsistent fan of faces"));
            }
        };
        if closed {
            if steps != incident {
                return Err(format!("vertex {v} is non-manifold (its faces form several fans)"));
            }
            let mut f = start;
            loop {
                ring.push(next_vert(f, v));
                f = next_face(f, v);
                if f == start {
                    break;
                }
            }
        } else {
            boundary[v as usize] = true;
            // f is the last face forward; walk backwards from it over the whole fan.
            ring.push(next_vert(f, v));
            let mut n = 0;
            let mut g = f;
            while g != NONE {
                ring.push(prev_vert(g, v));
                n += 1;
                if n > incident {
                    return Err(format!("vertex {v} has an inconsistent fan of faces"));
                }
                g = prev_face(g, v);
            }
            if n != incident {
                return Err(format!("vertex {v} is non-manifold (its faces form several fans)"));
            }
        }
    }
    ring_start.push(ring.len() as u32);
    Ok(Topology { edge_of, nbr, ring_start, ring, boundary, edges })
}

impl Topology {
    fn ring(&self, v: usize) -> &[u32] {
        &self.ring[self.ring_start[v] as usize..self.ring_start[v + 1] as usize]
    }
}

fn beta(valence: usize) -> f64 {
    if valence == 3 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * valence as f64)
    }
}

fn loop_gamma(valence: usize) -> f64 {
    1.0 / (valence as f64 + 3.0 / (8.0 * beta(valence)))
}

fn add(a: V3, b: V3, w: f64) -> V3 {
    [a[0] + w * b[0], a[1] + w * b[1], a[2] + w * b[2]]
}

fn scale(a: V3, w: f64) -> V3 {
    [a[0] * w, a[1] * w, a[2] * w]
}

fn weight_one_ring(p: &[V3], topo: &Topology, v: usize, b: f64) -> V3 {
    let r = topo.ring(v);
    let mut q = scale(p[v], 1.0 - r.len() as f64 * b);
    for &w in r {
        q = add(q, p[w as usize], b);
    }
    q
}

fn weight_boundary(p: &[V3], topo: &Topology, v: usize, b: f64) -> V3 {
    let r = topo.ring(v);
    let q = scale(p[v], 1.0 - 2.0 * b);
    add(add(q, p[r[0] as usize], b), p[r[r.len() - 1] as usize], b)
}

/// One round of Loop subdivision.
fn subdivide(p: &[V3], faces: &[[u32; 3]], topo: &Topology) -> (Vec<V3>, Vec<[u32; 3]>) {
    let nv = p.len();
    let mut np = Vec::with_capacity(nv + topo.edges.len());
    for v in 0..nv {
        np.push(if topo.boundary[v] {
            weight_boundary(p, topo, v, 1.0 / 8.0)
        } else {
            weight_one_ring(p, topo, v, beta(topo.ring(v).len()))
        });
    }
    // Odd vertices, one per edge, in edge-id order.
    let mut odd = vec![[0.0; 3]; topo.edges.len()];
    let mut done = vec![false; topo.edges.len()];
    for (f, t) in faces.iter().enumerate() {
        for k in 0..3 {
            let e = topo.edge_of[f][k] as usize;
            if done[e] {
                continue;
            }
            done[e] = true;
            let (a, b) = (p[t[k] as usize], p[t[(k + 1) % 3] as usize]);
            let g = topo.nbr[f][k];
            odd[e] = if g == NONE {
                scale(add(a, b, 1.0), 0.5)
            } else {
                let c = p[t[(k + 2) % 3] as usize];
                let gt = faces[g as usize];
                let d = gt.iter().find(|&&x| x != t[k] && x != t[(k + 1) % 3]).map_or(c, |&x| p[x as usize]);
                add(add(scale(add(a, b, 1.0), 3.0 / 8.0), c, 1.0 / 8.0), d, 1.0 / 8.0)
            };
        }
    }
    np.extend(odd);
    let mut nf = Vec::with_capacity(faces.len() * 4);
    for (f, t) in faces.iter().enumerate() {
        let e = topo.edge_of[f].map(|e| nv as u32 + e);
        let [v0, v1, v2] = *t;
        nf.push([v0, e[0], e[2]]);
        nf.push([e[0], v1, e[1]]);
        nf.push([e[2], e[1], v2]);
        nf.push([e[0], e[1], e[2]]);
    }
    (np, nf)
}

/// Subdivides `levels` times and returns limit positions, limit normals and triangles.
pub(crate) fn loop_subdivide(p: &[V3], faces: &[[u32; 3]], levels: u32) -> Result<Subdivided, String> {
    // Drop vertices no face uses.
    let mut remap = vec![NONE; p.len()];
    let mut pts = vec![];
    for t in faces {
        for &v in t {
            if remap[v as usize] == NONE {
                remap[v as usize] = pts.len() as u32;
                pts.push(p[v as usize]);
            }
        }
    }
    let mut faces: Vec<[u32; 3]> = faces.iter().map(|t| t.map(|v| remap[v as usize])).collect();
    if faces.len().saturating_mul(1usize.checked_shl(2 * levels).unwrap_or(usize::MAX)) > MAX_TRIANGLES {
        return Err(format!("{levels} levels of subdivision of {} triangles is too many triangles", faces.len()));
    }
    let mut topo = topology(pts.len(), &faces)?;
    for _ in 0..levels {
        let (np, nf) = subdivide(&pts, &faces, &topo);
        pts = np;
        faces = nf;
        topo = topology(pts.len(), &faces)?;
    }
    // Limit positions.
    let limit: Vec<V3> = (0..pts.len())
        .map(|v| {
            if topo.boundary[v] {
                weight_boundary(&pts, &topo, v, 1.0 / 5.0)
            } else {
                weight_one_ring(&pts, &topo, v, loop_gamma(topo.ring(v).len()))
            }
        })
        .collect();
    // Limit normals from the tangent masks, evaluated on the limit positions.
    let normals = (0..limit.len())
        .map(|v| {
            let ring: Vec<V3> = topo.ring(v).iter().map(|&w| limit[w as usize]).collect();
            let n = ring.len();
            let pv = limit[v];
            let (mut s, mut t) = ([0.0; 3], [0.0; 3]);
            if !topo.boundary[v] {
                for (j, r) in ring.iter().enumerate() {
                    let a = std::f64::consts::TAU * j as f64 / n as f64;
                    s = add(s, *r, a.cos());
                    t = add(t, *r, a.sin());
                }
            } else {
                s = add(ring[n - 1], ring[0], -1.0);
                t = match n {
                    2 => add(add(ring[0], ring[1], 1.0), pv, -2.0),
                    3 => add(ring[1], pv, -1.0),
                    4 => {
                        let q = add(add(scale(ring[0], -1.0), ring[1], 2.0), ring[2], 2.0);
                        add(add(q, ring[3], -1.0), pv, -2.0)
                    }
                    _ => {
                        let th = std::f64::consts::PI / (n - 1) as f64;
                        let mut q = scale(add(ring[0], ring[n - 1], 1.0), th.sin());
                        for (k, r) in ring.iter().enumerate().take(n - 1).skip(1) {
                            q = add(q, *r, (2.0 * th.cos() - 2.0) * (k as f64 * th).sin());
                        }
                        scale(q, -1.0)
                    }
                };
            }
            [s[1] * t[2] - s[2] * t[1], s[2] * t[0] - s[0] * t[2], s[0] * t[1] - s[1] * t[0]]
        })
        .collect();
    Ok((limit, normals, faces))
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let levels_v4 = ps.get_one_int("levels", 3);
    let levels = ps.get_one_int("nlevels", levels_v4).max(0) as u32;
    let _scheme = ps.get_one_string("scheme", "loop"); // read (and ignored) as pbrt-v3 does
    let p = checked_points(desc)?;
    let Some(idx) = ps.get_ints("indices") else {
        return Err(Diagnostic::error(
            Some(desc.entity.loc.clone()),
            "loopsubdiv: vertex indices \"indices\" not provided",
        ));
    };
    let tris = checked_triangles(desc, idx, p.len())?;
    if tris.is_empty() {
        return Ok(Some(ObjMesh::default()));
    }
    // Every level splits each triangle in four: the count is known before any work is done.
    let made = tris.len().saturating_mul(1usize.checked_shl(2 * levels).unwrap_or(usize::MAX));
    let at = if ps.get_ints("nlevels").is_some() { "nlevels" } else { "levels" };
    ctx.budget.charge_amplified(
        made,
        tris.len(),
        &format!("loopsubdiv: {levels} levels of subdivision of {} triangles", tris.len()),
        loc_or_entity(desc, at),
    )?;
    let (p, n, tris) = loop_subdivide(&p, &tris, levels)
        .map_err(|e| Diagnostic::error(loc_or_entity(desc, "indices"), format!("loopsubdiv: {e}")))?;
    Ok(Some(ObjMesh { p, n: Some(n), tris, ..Default::default() }))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::parser::ParamValue;
    use glam::Vec3;

    const TET_P: [f32; 12] = [1., 1., 1., 1., -1., -1., -1., 1., -1., -1., -1., 1.];
    /// Counter-clockwise seen from outside.
    const TET_I: [i32; 12] = [0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2];

    fn tet(levels: i32) -> ShapeDesc {
        shape(
            "loopsubdiv",
            vec![
                ("nlevels", ParamValue::Int(vec![levels])),
                ("indices", ParamValue::Int(TET_I.to_vec())),
                ("P", ParamValue::Point3(TET_P.to_vec())),
            ],
        )
    }

    #[test]
    fn tetrahedron_levels() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let p: Vec<Vec3> = TET_P.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let centre = Vec3::ZERO;
        // outward planes of the control tetrahedron
        let planes: Vec<(Vec3, f32)> = TET_I
            .chunks(3)
            .map(|t| {
                let [a, b, c] = [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]];
                let n = (b - a).cross(c - a).normalize();
                assert!(n.dot(a - centre) > 0.0);
                (n, n.dot(a))
            })
            .collect();
        let (mut v, mut e, mut f) = (4usize, 6usize, 4usize);
        for levels in 0..5 {
            let d = tet(levels);
            let m = build_shape(&d, &ctx).unwrap().unwrap();
            assert_eq!(m.positions.len(), v, "level {levels}");
            assert_eq!(m.triangle_count(), f);
            let adj = m.build_adjacency();
            assert!(adj.is_closed_manifold());
            assert_eq!(adj.welded_count, v);
            for q in &m.positions {
                for (n, dd) in &planes {
                    assert!(n.dot(*q) <= dd + 1e-5, "outside the control hull");
                }
            }
            // Limit normals point inward (pbrt-v3's convention) and the winding follows them.
            for (q, n) in m.positions.iter().zip(m.normals.as_ref().unwrap()) {
                assert!(n.dot(*q - centre) < 0.0);
            }
            for t in 0..m.triangle_count() {
                let [a, b, c] = m.vertices(t);
                assert!(m.winding_normal(t).dot((a + b + c) / 3.0 - centre) < 0.0);
            }
            // The limit surface of a tetrahedron is convex (seen from inside here).
            assert!(d.entity.params.report_unused("x").is_empty());
            (v, e, f) = (v + e, 2 * e + 3 * f, 4 * f);
        }
        assert!(sink.is_empty());
    }

    #[test]
    fn limit_points_are_fixed_points_of_a_regular_plane() {
        // A flat regular grid: subdivision keeps it planar, normals ±z.
        let n = 6;
        let mut p = vec![];
        for j in 0..n {
            for i in 0..n {
                p.push([i as f64 + 0.5 * j as f64, j as f64 * 0.75f64.sqrt(), 0.0]);
            }
        }
        let mut t = vec![];
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                t.push([a, a + 1, a + n as u32]);
                t.push([a + 1, a + n as u32 + 1, a + n as u32]);
            }
        }
        let (lp, ln, lt) = loop_subdivide(&p, &t, 2).unwrap();
        assert_eq!(lt.len(), t.len() * 16);
        for (q, nn) in lp.iter().zip(&ln) {
            assert_eq!(q[2], 0.0);
            let l = (nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]).sqrt();
            assert!(l > 0.0 && (nn[2].abs() / l - 1.0).abs() < 1e-9, "{nn:?}");
            assert!(nn[2] < 0.0);
        }
    }

    #[test]
    fn non_manifold_input_is_an_error() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        // three triangles on one edge
        let d = shape(
            "loopsubdiv",
            vec![
                ("indices", ParamValue::Int(vec![0, 1, 2, 1, 0, 3, 0, 1, 4])),
                ("P", ParamValue::Point3(vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 0., -1., 0., 0., 0., 1.])),
            ],
        );
        let e = build_shape(&d, &ctx).unwrap_err();
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("indices"));
        // bow-tie: two triangles sharing only a vertex
        let d = shape(
            "loopsubdiv",
            vec![
                ("levels", ParamValue::Int(vec![1])),
                ("indices", ParamValue::Int(vec![0, 1, 2, 0, 3, 4])),
                ("P", ParamValue::Point3(vec![0., 0., 0., 1., 0., 0., 0., 1., 0., -1., 0., 0., 0., -1., 0.])),
            ],
        );
        assert!(build_shape(&d, &ctx).unwrap_err().message.contains("non-manifold"));
        // inconsistent orientation
        let mut idx = TET_I.to_vec();
        idx.swap(0, 1);
        let d = shape("loopsubdiv", vec![("indices", ParamValue::Int(idx)), ("P", ParamValue::Point3(TET_P.to_vec()))]);
        assert!(build_shape(&d, &ctx).is_err());
        // too many levels
        assert!(build_shape(&tet(20), &ctx).is_err());
    }

    #[test]
    fn open_mesh_uses_boundary_rules() {
        // A single triangle: boundary rules keep points on the triangle's plane and edges.
        let (lp, ln, lt) =
            loop_subdivide(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]], 3).unwrap();
        assert_eq!(lt.len(), 64);
        assert_eq!(lp.len(), 45);
        for (q, n) in lp.iter().zip(&ln) {
            assert!(q[2] == 0.0 && q[0] >= -1e-12 && q[1] >= -1e-12 && q[0] + q[1] <= 1.0 + 1e-12);
            assert!(n[0].abs() < 1e-9 && n[1].abs() < 1e-9);
        }
    }

    /// The scene's triangle budget is charged with 4^nlevels × faces before any subdivision:
    /// nlevels 12 of a tetrahedron (4 × 4^12 = 2^26 triangles, minutes and gigabytes to make) is
    /// refused at once, at the `nlevels` parameter, and what fits is charged exactly.
    #[test]
    fn the_triangle_budget_is_charged_before_subdividing() {
        let sink = DiagSink::new();
        let mut ctx = ShapeContext::new(Path::new("."), &sink);
        ctx.budget = TriangleBudget::explicit(1000);
        let t0 = std::time::Instant::now();
        let e = build_shape(&tet(12), &ctx).unwrap_err();
        // Nothing was subdivided (a 12-level build takes minutes; the refusal is immediate).
        assert!(t0.elapsed().as_secs_f64() < 5.0);
        assert!(e.message.contains("triangle budget of 1000") && e.message.contains("67108864"), "{}", e.message);
        assert!(e.message.contains("PENUMBRA_MAX_TRIANGLES"), "{}", e.message);
        // Located at the nlevels parameter (line 10 of the test shape's parameters).
        assert_eq!(e.loc.as_ref().map(|l| l.line), Some(10));
        // A fresh budget: 3 levels (256 triangles) twice fit, a third copy does not (768 + 256).
        let mut ctx = ShapeContext::new(Path::new("."), &sink);
        ctx.budget = TriangleBudget::new(1000);
        for _ in 0..3 {
            build_shape(&tet(3), &ctx).unwrap().unwrap();
        }
        assert_eq!(ctx.budget.used(), 768);
        assert!(build_shape(&tet(3), &ctx).is_err());
    }

    /// Under the default budget, `nlevels` 9 of a tetrahedron (2^20 triangles from 4 faces, the
    /// 219-byte scene of tests/cli_new_user.rs) is refused before subdividing, naming the knob;
    /// 8 levels (2^18) are made. A budget the user sets is the only bound.
    #[test]
    fn the_default_budget_refuses_amplifying_a_few_faces_past_eight_levels() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let t0 = std::time::Instant::now();
        let e = build_shape(&tet(9), &ctx).unwrap_err();
        assert!(t0.elapsed().as_secs_f64() < 1.0);
        assert!(
            e.message.contains("1048576 triangles, 262144 per input face")
                && e.message.contains("PENUMBRA_MAX_TRIANGLES"),
            "{}",
            e.message
        );
        assert_eq!(e.loc.as_ref().map(|l| l.line), Some(10));
        assert_eq!(ctx.budget.used(), 0);
        assert_eq!(build_shape(&tet(8), &ctx).unwrap().unwrap().triangle_count(), 1 << 18);
        // Set explicitly, the budget alone decides (charged, not made, here).
        let set = TriangleBudget::explicit(1 << 20);
        assert!(set.charge_amplified(1 << 20, 4, "t", None).is_ok());
        assert!(TriangleBudget::new(1 << 26).charge_amplified(1 << 20, 4, "t", None).is_err());
        // Many faces amplified 4^8 each stay within the rule (the total budget still applies).
        assert!(TriangleBudget::new(1 << 26).charge_amplified(1 << 22, 64, "t", None).is_ok());
    }
}
