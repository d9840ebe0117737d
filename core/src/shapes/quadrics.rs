//! pbrt-v3's quadrics (sphere, disk, cylinder, cone, paraboloid, hyperboloid),
//! tessellated on pbrt-v3's own (u, v) parameterisation, so that the stored
//! texture coordinates are those pbrt-v3's analytic shapes report, with
//! analytic per-vertex normals `∂p/∂u × ∂p/∂v` (pbrt-v3's unflipped normal).
//!
//! Every quadric is a surface of revolution `p(u, v) = Rz(u φmax) m(v)` for a
//! "meridian" `m(v)` (for the hyperboloid, the segment `p1 → p2`). See the parent
//! module for the error bound.

use super::{loc_or_entity, ObjMesh, ShapeContext, MAX_SEGMENTS};
use crate::mesh::QuadricShape;
use crate::parser::{Diagnostic, ShapeDesc};

type V3 = [f64; 3];

#[derive(Clone, Copy, Debug)]
enum Meridian {
    /// θ(v) = th0 + v (th1 - th0); m = r (sin θ, 0, cos θ).
    Sphere {
        r: f64,
        th0: f64,
        th1: f64,
    },
    Cylinder {
        r: f64,
        z0: f64,
        z1: f64,
    },
    /// ρ(v) = r - v (r - ri) at height h.
    Disk {
        h: f64,
        r: f64,
        ri: f64,
    },
    /// ρ = r (1 - v), z = v h.
    Cone {
        h: f64,
        r: f64,
    },
    /// z = z0 + v (z1 - z0), ρ = r sqrt(z / z1).
    Paraboloid {
        r: f64,
        z0: f64,
        z1: f64,
    },
    /// m = (1 - v) p1 + v p2.
    Hyperboloid {
        p1: V3,
        p2: V3,
    },
}

impl Meridian {
    /// The meridian point and its derivative in v.
    fn eval(&self, v: f64) -> (V3, V3) {
        match *self {
            Meridian::Sphere { r, th0, th1 } => {
                let th = th0 + v * (th1 - th0);
                let (s, c) = th.sin_cos();
                ([r * s, 0.0, r * c], [(th1 - th0) * r * c, 0.0, -(th1 - th0) * r * s])
            }
            Meridian::Cylinder { r, z0, z1 } => ([r, 0.0, z0 + v * (z1 - z0)], [0.0, 0.0, z1 - z0]),
            Meridian::Disk { h, r, ri } => ([r - v * (r - ri), 0.0, h], [ri - r, 0.0, 0.0]),
            Meridian::Cone { h, r } => ([r * (1.0 - v), 0.0, v * h], [-r, 0.0, h]),
            Meridian::Paraboloid { r, z0, z1 } => {
                let z = (z0 + v * (z1 - z0)).max(0.0);
                let rho = r * (z / z1).sqrt();
                // dρ/dv = r (z1 - z0) / (2 sqrt(z z1)); infinite at the apex (handled by the caller).
                ([rho, 0.0, z], [r * (z1 - z0) / (2.0 * (z * z1).sqrt()), 0.0, z1 - z0])
            }
            Meridian::Hyperboloid { p1, p2 } => {
                let m = [0, 1, 2].map(|i| (1.0 - v) * p1[i] + v * p2[i]);
                (m, [0, 1, 2].map(|i| p2[i] - p1[i]))
            }
        }
    }
}

fn rot(m: V3, (s, c): (f64, f64)) -> V3 {
    [m[0] * c - m[1] * s, m[0] * s + m[1] * c, m[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn len(a: V3) -> f64 {
    dot(a, a).sqrt()
}

struct Surface {
    m: Meridian,
    phi_max: f64,
    v_lo: f64,
    v_hi: f64,
    r_ref: f64,
}

impl Surface {
    fn point(&self, u: f64, v: f64) -> V3 {
        rot(self.m.eval(v).0, (u * self.phi_max).sin_cos())
    }
    fn is_pole(&self, v: f64) -> bool {
        let m = self.m.eval(v).0;
        m[0].hypot(m[1]) <= 1e-12 * self.r_ref
    }
    /// Unit `∂p/∂u × ∂p/∂v`, nudged into the domain where it vanishes (poles, apexes).
    fn normal(&self, u: f64, v: f64) -> V3 {
        let span = self.v_hi - self.v_lo;
        for k in 0..8 {
            let dv = if k == 0 { 0.0 } else { span * 1e-9 * 10f64.powi(k) };
            let vv = if v - self.v_lo < self.v_hi - v { v + dv } else { v - dv };
            let (m, dm) = self.m.eval(vv);
            let sc = (u * self.phi_max).sin_cos();
            let p = rot(m, sc);
            let dpdu = [-self.phi_max * p[1], self.phi_max * p[0], 0.0];
            let n = cross(dpdu, rot(dm, sc));
            let l = len(n);
            if l.is_finite() && l > 1e-300 && n.iter().all(|x| x.is_finite()) {
                return [n[0] / l, n[1] / l, n[2] / l];
            }
        }
        [0.0, 0.0, 0.0]
    }

    /// The triangles (as (u, v) corners) of the cell [0, du] × [va, vb].
    fn cell_tris(&self, du: f64, va: f64, vb: f64) -> Vec<[(f64, f64); 3]> {
        match (self.is_pole(va), self.is_pole(vb)) {
            (false, false) => vec![[(0.0, va), (du, va), (du, vb)], [(0.0, va), (du, vb), (0.0, vb)]],
            (true, false) => vec![[(du / 2.0, va), (du, vb), (0.0, vb)]],
            (false, true) => vec![[(0.0, va), (du, va), (du / 2.0, vb)]],
            (true, true) => vec![],
        }
    }

    /// Largest distance from the surface at the triangles' centroids and edge
    /// midpoints (in (u, v)) to the triangles' planes.
    fn cell_error(&self, du: f64, va: f64, vb: f64) -> f64 {
        let mut err: f64 = 0.0;
        for t in self.cell_tris(du, va, vb) {
            let p = t.map(|(u, v)| self.point(u, v));
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let l = len(n);
            if !(l > 1e-300 && l.is_finite()) {
                continue;
            }
            let mid = |a: (f64, f64), b: (f64, f64)| ((a.0 + b.0) / 2.0, (a.1 + b.1) / 2.0);
            let c = ((t[0].0 + t[1].0 + t[2].0) / 3.0, (t[0].1 + t[1].1 + t[2].1) / 3.0);
            for (u, v) in [c, mid(t[0], t[1]), mid(t[1], t[2]), mid(t[2], t[0])] {
                err = err.max((dot(sub(self.point(u, v), p[0]), n) / l).abs());
            }
        }
        err
    }

    fn refine(&self, du: f64, va: f64, vb: f64, tol: f64, depth: u32, out: &mut Vec<f64>) {
        // A cell between two poles has no triangles: always split it.
        let split = (self.is_pole(va) && self.is_pole(vb)) || self.cell_error(du, va, vb) > tol;
        if depth < 12 && split {
            let vm = 0.5 * (va + vb);
            self.refine(du, va, vm, tol, depth + 1, out);
            self.refine(du, vm, vb, tol, depth + 1, out);
        } else {
            out.push(vb);
        }
    }

    fn tessellate(&self, eps: f64) -> ObjMesh {
        let eps = if eps.is_finite() { eps.clamp(1e-9, 1.0) } else { 1e-4 };
        let full = self.phi_max >= std::f64::consts::TAU * (1.0 - 1e-12);
        let dphi = 2.0 * (1.0 - eps / 2.0).acos();
        let min_u = if full { 3.0 } else { 1.0 };
        let nu = (self.phi_max / dphi).ceil().clamp(min_u, MAX_SEGMENTS as f64) as usize;
        let du = 1.0 / nu as f64;
        // Rows in v: [v_lo, v_hi] bisected (depth ≤ 12) until within tolerance.
        let mut rows = vec![self.v_lo];
        self.refine(du, self.v_lo, self.v_hi, eps * self.r_ref, 0, &mut rows);
        // Angles; the last column of a full revolution repeats the first bit for bit.
        let angles: Vec<(f64, f64)> = (0..=nu)
            .map(|i| if full && i == nu { (0.0f64, 1.0f64) } else { (i as f64 * du * self.phi_max).sin_cos() })
            .collect();
        let mut mesh = ObjMesh::default();
        let (mut p, mut n, mut uv) = (vec![], vec![], vec![]);
        // First vertex index of each row and whether the row is a pole.
        let mut row_start = Vec::with_capacity(rows.len());
        for &v in &rows {
            row_start.push((p.len() as u32, self.is_pole(v)));
            let m = self.m.eval(v).0;
            if self.is_pole(v) {
                for i in 0..nu {
                    let u = (i as f64 + 0.5) * du;
                    p.push([0.0, 0.0, m[2]]);
                    n.push(self.normal(u, v));
                    uv.push([u as f32, v as f32]);
                }
            } else {
                for (i, sc) in angles.iter().enumerate() {
                    let u = i as f64 * du;
                    p.push(rot(m, *sc));
                    n.push(self.normal(u, v));
                    uv.push([u as f32, v as f32]);
                }
            }
        }
        for w in row_start.windows(2) {
            let ((a, pa), (b, pb)) = (w[0], w[1]);
            for i in 0..nu as u32 {
                match (pa, pb) {
                    (false, false) => {
                        mesh.tris.push([a + i, a + i + 1, b + i + 1]);
                        mesh.tris.push([a + i, b + i + 1, b + i]);
                    }
                    (true, false) => mesh.tris.push([a + i, b + i + 1, b + i]),
                    (false, true) => mesh.tris.push([a + i, a + i + 1, b + i]),
                    (true, true) => {}
                }
            }
        }
        mesh.p = p;
        mesh.n = Some(n);
        mesh.uv = Some(uv);
        mesh
    }
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let kind = desc.entity.kind.as_str();
    let mut bad: Option<&str> = None;
    let mut f = |name: &'static str, default: f32| -> f64 {
        let v = ps.get_one_float(name, default);
        if !v.is_finite() && bad.is_none() {
            bad = Some(name);
        }
        v as f64
    };
    let phi_max_of = |deg: f64| deg.clamp(0.0, 360.0).to_radians();
    let mut quadric = None;
    let (m, phi_max, v_lo, r_ref) = match kind {
        "sphere" => {
            let r = f("radius", 1.0);
            let zmin = f("zmin", -r as f32);
            let zmax = f("zmax", r as f32);
            let phi = phi_max_of(f("phimax", 360.0));
            let (lo, hi) = (zmin.min(zmax), zmin.max(zmax));
            let th0 = (lo / r).clamp(-1.0, 1.0).acos();
            let th1 = (hi / r).clamp(-1.0, 1.0).acos();
            let (z_min, z_max) = (lo.clamp(-r.abs(), r.abs()), hi.clamp(-r.abs(), r.abs()));
            quadric = Some(QuadricShape::Sphere { radius: r, z_min, z_max, phi_max: phi });
            (Meridian::Sphere { r, th0, th1 }, phi, 0.0, r)
        }
        "cylinder" => {
            let r = f("radius", 1.0);
            let (a, b) = (f("zmin", -1.0), f("zmax", 1.0));
            let phi = phi_max_of(f("phimax", 360.0));
            quadric = Some(QuadricShape::Cylinder { radius: r, z_min: a.min(b), z_max: a.max(b), phi_max: phi });
            (Meridian::Cylinder { r, z0: a.min(b), z1: a.max(b) }, phi, 0.0, r)
        }
        "disk" => {
            let h = f("height", 0.0);
            let r = f("radius", 1.0);
            let ri = f("innerradius", 0.0);
            let phi = phi_max_of(f("phimax", 360.0));
            quadric = Some(QuadricShape::Disk { height: h, radius: r, inner_radius: ri, phi_max: phi });
            (Meridian::Disk { h, r, ri }, phi, 0.0, r)
        }
        "cone" => {
            let h = f("height", 1.0);
            let r = f("radius", 1.0);
            let phi = phi_max_of(f("phimax", 360.0));
            (Meridian::Cone { h, r }, phi, 0.0, r)
        }
        "paraboloid" => {
            let r = f("radius", 1.0);
            let (a, b) = (f("zmin", 0.0), f("zmax", 1.0));
            let phi = phi_max_of(f("phimax", 360.0));
            let (z0, z1) = (a.min(b), a.max(b));
            // The surface only exists for z ≥ 0: start v where z = 0.
            let v_lo = if z0 < 0.0 && z1 > 0.0 { -z0 / (z1 - z0) } else { 0.0 };
            (Meridian::Paraboloid { r, z0, z1 }, phi, v_lo, r)
        }
        "hyperboloid" => {
            let mut p1 = ps.get_one_point3("p1", [0.0, 0.0, 0.0]).map(|x| x as f64);
            let mut p2 = ps.get_one_point3("p2", [1.0, 1.0, 1.0]).map(|x| x as f64);
            let phi = phi_max_of(f("phimax", 360.0));
            if !p1.iter().chain(&p2).all(|x| x.is_finite()) {
                bad = Some(if p1.iter().all(|x| x.is_finite()) { "p2" } else { "p1" });
            }
            if p2[2] == 0.0 {
                std::mem::swap(&mut p1, &mut p2); // as pbrt-v3 does
            }
            let r_ref = p1[0].hypot(p1[1]).max(p2[0].hypot(p2[1]));
            (Meridian::Hyperboloid { p1, p2 }, phi, 0.0, r_ref)
        }
        _ => return Ok(None),
    };
    if let Some(name) = bad {
        return Err(Diagnostic::error(loc_or_entity(desc, name), format!("{kind}: \"{name}\" is not finite")));
    }
    let surf = Surface { m, phi_max, v_lo, v_hi: 1.0, r_ref };
    // Degenerate parameters: pbrt-v3 would render nothing (or NaNs); skip with a warning.
    let degenerate = match m {
        _ if r_ref.is_nan() || r_ref <= 0.0 || phi_max.is_nan() || phi_max <= 0.0 => true,
        Meridian::Sphere { th0, th1, .. } => th0 == th1,
        Meridian::Cylinder { z0, z1, .. } => z0 == z1,
        Meridian::Disk { r, ri, .. } => !(ri >= 0.0 && ri < r),
        Meridian::Cone { h, .. } => h == 0.0,
        Meridian::Paraboloid { z1, .. } => z1.is_nan() || z1 <= 0.0 || v_lo >= 1.0,
        Meridian::Hyperboloid { p1, p2 } => p1[2] == p2[2],
    };
    if degenerate {
        ctx.warnings.warn(Some(desc.entity.loc.clone()), format!("{kind}: degenerate parameters (zero area); skipped"));
        return Ok(None);
    }
    let eps = ctx.tessellation.max_rel_error as f64;
    let quadric = quadric.map(|q| (q, eps * r_ref));
    Ok(Some(ObjMesh { quadric, ..surf.tessellate(eps) }))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use crate::parser::{ParamValue, Transform};
    use std::f64::consts::PI;

    const EPS: f32 = 1e-4;

    fn build(kind: &str, params: Vec<(&str, ParamValue)>) -> TriangleMesh {
        let sink = DiagSink::new();
        // The tests check the bound at 1e-4, tighter than the 1e-3 default.
        let mut ctx = ShapeContext::new(Path::new("."), &sink);
        ctx.tessellation.max_rel_error = EPS;
        let d = shape(kind, params);
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert!(sink.is_empty(), "{:?}", sink.take());
        assert!(d.entity.params.report_unused("x").is_empty());
        m
    }
    fn fl(v: f32) -> ParamValue {
        ParamValue::Float(vec![v])
    }
    fn check_area(m: &TriangleMesh, expect: f64) {
        let a = m.total_area();
        let rel = (a - expect).abs() / expect;
        assert!(rel <= EPS as f64, "area {a} vs {expect}: rel {rel}");
        // inscribed: the tessellation is (slightly) smaller for convex pieces, never wildly off
        assert!(m.triangle_count() < 2_000_000);
    }

    #[test]
    fn sphere_full_closed_area_normals_and_bound() {
        let m = build("sphere", vec![("radius", fl(2.0))]);
        check_area(&m, 4.0 * PI * 4.0);
        assert!(m.build_adjacency().is_closed_manifold());
        assert!(m.is_closed_convex(1e-5));
        for t in 0..m.triangle_count() {
            assert!(m.area(t) > 0.0, "degenerate triangle {t}");
            let [a, b, c] = m.vertices(t);
            let cen = (a + b + c) / 3.0;
            // outward, and within the tessellation bound of the sphere
            assert!(m.winding_normal(t).dot(cen) > 0.0);
            assert!((cen.length() - 2.0).abs() <= 2.0 * EPS * 1.01, "{}", cen.length());
        }
        for (p, n) in m.positions.iter().zip(m.normals.as_ref().unwrap()) {
            assert!((p.length() - 2.0).abs() < 1e-5);
            assert!((*n - *p / 2.0).length() < 1e-4, "{n} {p}");
        }
        // uv as pbrt-v3 computes them from the hit point (away from the seam and poles).
        for (p, uv) in m.positions.iter().zip(m.uvs.as_ref().unwrap()) {
            let (x, y, z) = (p.x as f64, p.y as f64, p.z as f64);
            if x.hypot(y) < 1e-3 || (y.abs() < 1e-6 && x > 0.0) {
                continue;
            }
            let mut phi = y.atan2(x);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            let v = ((z / 2.0).clamp(-1.0, 1.0).acos() - PI) / (0.0 - PI);
            assert!((uv.x as f64 - phi / (2.0 * PI)).abs() < 1e-5);
            assert!((uv.y as f64 - v).abs() < 1e-5);
        }
    }

    #[test]
    fn partial_sphere_area() {
        let m =
            build("sphere", vec![("radius", fl(1.5)), ("zmin", fl(-0.5)), ("zmax", fl(1.0)), ("phimax", fl(250.0))]);
        check_area(&m, 250f64.to_radians() * 1.5 * 1.5);
        assert!(!m.build_adjacency().is_closed_manifold());
    }

    #[test]
    fn disk_cylinder_cone_paraboloid_areas() {
        let m = build("disk", vec![("radius", fl(2.0)), ("innerradius", fl(0.5)), ("height", fl(0.3))]);
        check_area(&m, PI * (4.0 - 0.25));
        assert!(m.positions.iter().all(|p| (p.z - 0.3).abs() < 1e-6));
        assert!((0..m.triangle_count()).all(|t| m.winding_normal(t).z > 0.99));
        let m = build("disk", vec![("phimax", fl(90.0))]);
        check_area(&m, PI / 4.0);
        let m = build("cylinder", vec![("radius", fl(0.5)), ("zmin", fl(1.0)), ("zmax", fl(-2.0))]);
        check_area(&m, 2.0 * PI * 0.5 * 3.0);
        let m = build("cone", vec![("radius", fl(1.0)), ("height", fl(2.0)), ("phimax", fl(300.0))]);
        check_area(&m, 300f64.to_radians() * 5f64.sqrt() / 2.0);
        let (r, z0, z1) = (1.5f64, 0.0f64, 2.0f64);
        let c = r * r / z1;
        let area = |zl: f64, zh: f64| {
            2.0 * PI * 2.0 / (3.0 * c) * ((c * zh + c * c / 4.0).powf(1.5) - (c * zl + c * c / 4.0).powf(1.5))
        };
        let m = build("paraboloid", vec![("radius", fl(r as f32)), ("zmin", fl(z0 as f32)), ("zmax", fl(z1 as f32))]);
        check_area(&m, area(z0, z1));
        for (p, n) in m.positions.iter().zip(m.normals.as_ref().unwrap()) {
            // on the surface x² + y² = r² z / zmax, normal outward (away from the axis, down)
            let (x, y, z) = (p.x as f64, p.y as f64, p.z as f64);
            assert!((x * x + y * y - r * r * z / z1).abs() < 1e-5);
            assert!(n.z < 0.0);
        }
        let m = build("paraboloid", vec![("radius", fl(1.5)), ("zmin", fl(0.5)), ("zmax", fl(2.0))]);
        check_area(&m, area(0.5, 2.0));
    }

    #[test]
    fn hyperboloid_area_by_numeric_integration() {
        for (p1, p2, phimax) in [
            ([1.0f64, 0.0, -1.0], [0.0, 1.0, 1.0], 360.0f64),
            ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 360.0),
            ([0.5, 0.3, 0.2], [-1.0, 0.8, 1.5], 200.0),
        ] {
            let pf = |p: [f64; 3]| ParamValue::Point3(p.iter().map(|x| *x as f32).collect());
            let m = build("hyperboloid", vec![("p1", pf(p1)), ("p2", pf(p2)), ("phimax", fl(phimax as f32))]);
            // Surface of revolution of the meridian (ρ(v), z(v)): A = φmax ∫ ρ sqrt(ρ'² + z'²) dv (Simpson).
            let rho = |v: f64| {
                let x = p1[0] + v * (p2[0] - p1[0]);
                let y = p1[1] + v * (p2[1] - p1[1]);
                x.hypot(y)
            };
            let n = 20000;
            let h = 1.0 / n as f64;
            let g = |v: f64| {
                let d =
                    (rho((v + 1e-7).min(1.0)) - rho((v - 1e-7).max(0.0))) / ((v + 1e-7).min(1.0) - (v - 1e-7).max(0.0));
                rho(v) * (d * d + (p2[2] - p1[2]).powi(2)).sqrt()
            };
            let mut s = g(0.0) + g(1.0);
            for i in 1..n {
                s += g(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            check_area(&m, phimax.to_radians() * s * h / 3.0);
        }
    }

    #[test]
    fn sphere_orientation_under_mirror_and_reverse_orientation() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        let mirror = Transform::scale([-1.0, 1.0, 1.0]).unwrap();
        let shift = Transform::translate([3.0, 0.0, 0.0]);
        for (t, swaps) in [(shift, false), (shift.compose(&mirror), true)] {
            for ro in [false, true] {
                let d = shape_with("sphere", vec![], t, ro);
                let m = build_shape(&d, &ctx).unwrap().unwrap();
                assert_eq!(m.flip_normals, ro ^ swaps);
                // pbrt-v3's Intersect: n = ±(M^-T ∂p/∂u×∂p/∂v), negated iff ro ^ swaps.
                let outward = !(ro ^ swaps);
                let centre = glam::Vec3::new(3.0, 0.0, 0.0);
                for tri in (0..m.triangle_count()).step_by(97) {
                    let [a, b, c] = m.vertices(tri);
                    let p = (a + b + c) / 3.0 - centre;
                    let (n, ns) = m.hit_normals(tri, [1.0 / 3.0; 3]);
                    assert_eq!(n.dot(p) > 0.0, outward, "ro {ro} swaps {swaps}");
                    assert_eq!(m.winding_normal(tri).dot(p) > 0.0, outward);
                    assert!(ns.dot(n) > 0.99);
                    // pbrt-v3's Sample: outward unless ReverseOrientation.
                    assert_eq!(m.sample_normal(tri, [1.0 / 3.0; 3]).dot(p) > 0.0, !ro);
                }
                assert_eq!(m.is_closed_convex(1e-5), outward);
            }
        }
    }

    #[test]
    fn tessellation_follows_the_requested_error() {
        let sink = DiagSink::new();
        let mut ctx = ShapeContext::new(Path::new("."), &sink);
        let d = shape("sphere", vec![]);
        let mut prev = 0;
        for eps in [1e-2f32, 1e-3, 1e-4] {
            ctx.tessellation.max_rel_error = eps;
            let m = build_shape(&d, &ctx).unwrap().unwrap();
            for t in 0..m.triangle_count() {
                let [a, b, c] = m.vertices(t);
                assert!(1.0 - ((a + b + c) / 3.0).length() <= eps * 1.01);
            }
            assert!(m.triangle_count() > prev);
            prev = m.triangle_count();
        }
        // Planar/ruled pieces need a single row of cells.
        let m = build_shape(&shape("cylinder", vec![]), &ctx).unwrap().unwrap();
        assert_eq!(m.positions.len(), 2 * (m.triangle_count() / 2 + 1));
        let m = build_shape(&shape("disk", vec![]), &ctx).unwrap().unwrap();
        assert_eq!(m.positions.len(), 2 * m.triangle_count() + 1);
    }

    #[test]
    fn degenerate_quadrics_are_skipped_and_nan_is_an_error() {
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(Path::new("."), &sink);
        for (k, p) in [
            ("sphere", vec![("radius", fl(0.0))]),
            ("disk", vec![("innerradius", fl(2.0))]),
            ("cylinder", vec![("zmin", fl(1.0))]),
            ("sphere", vec![("phimax", fl(-5.0))]),
            ("hyperboloid", vec![("p1", ParamValue::Point3(vec![1., 0., 1.]))]),
        ] {
            assert_eq!(build_shape(&shape(k, p), &ctx).unwrap(), None, "{k}");
            assert_eq!(sink.take().len(), 1);
        }
        let d = shape("cone", vec![("height", fl(f32::NAN))]);
        let e = build_shape(&d, &ctx).unwrap_err();
        assert_eq!(e.loc.as_ref(), d.entity.params.loc_of("height"));
    }
}
