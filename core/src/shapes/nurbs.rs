//! `Shape "nurbs"`: a non-uniform rational B-spline surface, tessellated as pbrt-v3's
//! `CreateNURBS` does: the surface evaluated (de Boor's algorithm on homogeneous control
//! points) on a 30 × 30 grid of parameter values spanning [u0, u1] × [v0, v1], each grid
//! point carrying its (u, v) and the normal `normalize(∂p/∂u × ∂p/∂v)`, two triangles per
//! grid cell. `P` gives non-rational control points (w = 1); `Pw` gives (x, y, z, w) taken as
//! pbrt-v3 takes them (already multiplied by w).

use super::{loc_or_entity, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};
use glam::{DVec3, DVec4};

/// pbrt-v3's dicing rate in u and v.
const DICE: usize = 30;

/// One direction of the spline: its order and knots.
struct Basis<'a> {
    order: usize,
    knots: &'a [f64],
    /// Control points in this direction.
    n: usize,
}

impl Basis<'_> {
    /// The knot span of `t` (pbrt-v3's `KnotOffset`): the last `k >= order - 1` with
    /// `knots[k] < t`, at most `n - 1`.
    fn span(&self, t: f64) -> usize {
        let mut k = self.order - 1;
        while k + 1 < self.n && t > self.knots[k + 1] {
            k += 1;
        }
        k
    }

    /// The curve through the homogeneous points `cp(0..n)` at `t` and, with `deriv`, its
    /// (projected) derivative (pbrt-v3's `NURBSEvaluate`).
    fn eval(&self, cp: impl Fn(usize) -> DVec4, t: f64) -> (DVec4, DVec3) {
        let order = self.order;
        let span = self.span(t);
        let knot = |i: isize| self.knots[(span as isize + i) as usize];
        let first = span + 1 - order;
        let mut w: Vec<DVec4> = (0..order).map(|i| cp(first + i)).collect();
        for i in 0..order.saturating_sub(2) {
            for j in 0..order - 1 - i {
                let den = knot(1 + j as isize) - knot(j as isize + 2 - order as isize + i as isize);
                let a = if den != 0.0 { (knot(1 + j as isize) - t) / den } else { 0.0 };
                w[j] = w[j] * a + w[j + 1] * (1.0 - a);
            }
        }
        let den = knot(1) - knot(0);
        let a = if den != 0.0 { (knot(1) - t) / den } else { 0.0 };
        let val = w[0] * a + w[1] * (1.0 - a);
        let factor = if den != 0.0 { (order - 1) as f64 / den } else { 0.0 };
        let delta = (w[1] - w[0]) * factor;
        let deriv = delta.truncate() / val.w - val.truncate() * (delta.w / (val.w * val.w));
        (val, deriv)
    }
}

/// The surface point at (u, v) and its partial derivatives (pbrt-v3's
/// `NURBSEvaluateSurface`).
fn eval_surface(bu: &Basis, bv: &Basis, cp: &[DVec4], u: f64, v: f64) -> (DVec3, DVec3, DVec3) {
    let u_first = bu.span(u) + 1 - bu.order;
    let iso: Vec<DVec4> = (0..bu.order).map(|i| bv.eval(|k| cp[k * bu.n + u_first + i], v).0).collect();
    let (p, dpdu) = bu.eval(|k| iso[k - u_first], u);
    let v_first = bv.span(v) + 1 - bv.order;
    let iso: Vec<DVec4> = (0..bv.order).map(|i| bu.eval(|k| cp[(v_first + i) * bu.n + k], u).0).collect();
    let (_, dpdv) = bv.eval(|k| iso[k - v_first], v);
    (p.truncate() / p.w, dpdu, dpdv)
}

fn error(desc: &ShapeDesc, param: &str, msg: String) -> Diagnostic {
    Diagnostic::error(loc_or_entity(desc, param), format!("nurbs: {msg}"))
}

/// One direction's order, knots and parameter range, validated.
fn basis(desc: &ShapeDesc, d: &str) -> Result<(usize, usize, Vec<f64>, f64, f64), Diagnostic> {
    let ps = &desc.entity.params;
    let (n_name, order_name, knots_name) = (format!("n{d}"), format!("{d}order"), format!("{d}knots"));
    let n = ps.get_one_int(&n_name, -1);
    let order = ps.get_one_int(&order_name, -1);
    if n < 2 {
        return Err(error(desc, &n_name, format!("\"{n_name}\" (control points in {d}) must be at least 2, got {n}")));
    }
    if order < 2 || order > n {
        return Err(error(
            desc,
            &order_name,
            format!("\"{order_name}\" must be in 2..={n} (\"{n_name}\"), got {order}"),
        ));
    }
    let (n, order) = (n as usize, order as usize);
    let Some(knots) = ps.get_floats(&knots_name) else {
        return Err(error(desc, &knots_name, format!("knot vector \"{knots_name}\" not provided")));
    };
    if knots.len() != n + order {
        return Err(error(
            desc,
            &knots_name,
            format!(
                "{} knots in \"{knots_name}\", {n} control points + order {order} = {} expected",
                knots.len(),
                n + order
            ),
        ));
    }
    if knots.windows(2).any(|w| !(w[1] >= w[0])) || knots.iter().any(|k| !k.is_finite()) {
        return Err(error(desc, &knots_name, format!("\"{knots_name}\" must be finite and non-decreasing")));
    }
    let knots: Vec<f64> = knots.iter().map(|&k| k as f64).collect();
    let t0 = ps.get_one_float(&format!("{d}0"), knots[order - 1] as f32) as f64;
    let t1 = ps.get_one_float(&format!("{d}1"), knots[n] as f32) as f64;
    if !(t0 >= knots[order - 1] && t1 <= knots[n] && t0 <= t1) {
        return Err(error(
            desc,
            &format!("{d}0"),
            format!("parameter range [{t0}, {t1}] outside the knots' [{}, {}]", knots[order - 1], knots[n]),
        ));
    }
    Ok((n, order, knots, t0, t1))
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let (nu, uorder, uknots, u0, u1) = basis(desc, "u")?;
    let (nv, vorder, vknots, v0, v1) = basis(desc, "v")?;
    let cp: Vec<DVec4> = if let Some(p) = ps.get_point3s("P") {
        p.iter().map(|v| DVec4::new(v[0] as f64, v[1] as f64, v[2] as f64, 1.0)).collect()
    } else if let Some(pw) = ps.get_floats("Pw") {
        if pw.len() % 4 != 0 {
            return Err(error(desc, "Pw", format!("{} \"Pw\" values: not a multiple of four", pw.len())));
        }
        pw.chunks(4).map(|c| DVec4::new(c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64)).collect()
    } else {
        return Err(error(desc, "P", "control points \"P\" or \"Pw\" not provided".into()));
    };
    let cp_name = if ps.get_point3s("P").is_some() { "P" } else { "Pw" };
    if nu.checked_mul(nv) != Some(cp.len()) {
        return Err(error(desc, cp_name, format!("{nu} × {nv} control points expected, {} given", cp.len())));
    }
    if cp.iter().any(|c| !c.is_finite() || c.w == 0.0) {
        return Err(error(desc, cp_name, "control points must be finite with a non-zero weight".into()));
    }
    ctx.budget.charge(2 * (DICE - 1) * (DICE - 1), "shape \"nurbs\"", Some(desc.entity.loc.clone()))?;
    let bu = Basis { order: uorder, knots: &uknots, n: nu };
    let bv = Basis { order: vorder, knots: &vknots, n: nv };
    // pbrt-v3 lerps in single precision.
    let lerp = |i: usize, a: f64, b: f64| {
        let t = i as f32 / (DICE - 1) as f32;
        ((1.0 - t) * a as f32 + t * b as f32) as f64
    };
    let (mut p, mut n, mut uv) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..DICE {
        for i in 0..DICE {
            let (u, v) = (lerp(i, u0, u1), lerp(j, v0, v1));
            let (pt, dpdu, dpdv) = eval_surface(&bu, &bv, &cp, u, v);
            if !pt.is_finite() {
                return Err(error(desc, cp_name, format!("the surface is not finite at (u, v) = ({u}, {v})")));
            }
            p.push(pt.to_array());
            // A degenerate point (a pole) gets no normal (zero: the triangle's own is used).
            n.push(dpdu.cross(dpdv).normalize_or_zero().to_array());
            uv.push([u as f32, v as f32]);
        }
    }
    let vert = |i: usize, j: usize| (j * DICE + i) as u32;
    let mut tris = Vec::with_capacity(2 * (DICE - 1) * (DICE - 1));
    for j in 0..DICE - 1 {
        for i in 0..DICE - 1 {
            tris.push([vert(i, j), vert(i + 1, j), vert(i + 1, j + 1)]);
            tris.push([vert(i, j), vert(i + 1, j + 1), vert(i, j + 1)]);
        }
    }
    Ok(Some(ObjMesh { p, n: Some(n), uv: Some(uv), tris, ..Default::default() }))
}
