//! World-space SH of the scene's `infinite` lights.
//!
//! pbrt-v3's `InfiniteAreaLight::Le` looks a world direction `d` up as
//! `w = normalize(light_from_world · d)`, `(s, t) = (φ(w)/2π, θ(w)/π)` (θ from light-space
//! +z, φ from +x towards +y) in a MIPMap at level 0 — bilinear between texel centres at
//! half-integers, repeat wrapping in both `s` and `t` (so the half-texel rows at the poles
//! blend with the opposite edge row). That function is projected **exactly**: it is a sum
//! of texel values times separable hat functions `Λ_i(φ) Λ_j(θ)`, and so is the basis
//! (`Y_l^m ∝ Q_l^m(cos θ) sin^m θ · cos/sin(mφ)`), so
//! `∫ L Y_lm dω = Σ_j A_jlm Σ_i L_ij B_im` with `B_im = Δφ sinc²(mΔφ/2) cos/sin(mφ_i)` in closed
//! form and `A_jlm = ∫ Λ_j(θ) Q_l^m(cos θ) sin^{m+1} θ dθ` by Gauss–Legendre on the pieces
//! where `Λ_j` is linear (error far below f32). Light-space coefficients are then turned to
//! world space by the SH rotation of the light's world-from-light transform (orthogonal up to
//! a uniform scale, either handedness); any other linear transform is integrated over world
//! directions by [`project_lat_long_quadrature`].

use super::{basis, check_len, rotation::ShRotation, ShError, ShOrder, SQRT_4PI};
use crate::light::{InfiniteLight, RgbMap};
use glam::{DMat3, DVec3, Mat3, Vec2};
use std::f64::consts::PI;

/// SH coefficients of an RGB function, `[R, G, B]` per coefficient.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRgb {
    pub order: ShOrder,
    pub coeffs: Vec<[f64; 3]>,
}

impl ShRgb {
    pub fn zero(order: ShOrder) -> ShRgb {
        ShRgb { order, coeffs: vec![[0.0; 3]; order.coeffs()] }
    }

    /// Adds `other` (same order).
    pub fn add(&mut self, other: &ShRgb) -> Result<(), ShError> {
        check_len("SH sum", other.coeffs.len(), self.coeffs.len())?;
        for (a, b) in self.coeffs.iter_mut().zip(&other.coeffs) {
            for c in 0..3 {
                a[c] += b[c];
            }
        }
        Ok(())
    }

    /// One colour channel's coefficients.
    pub fn channel(&self, c: usize) -> Vec<f64> {
        self.coeffs.iter().map(|v| v[c.min(2)]).collect()
    }

    /// The reconstruction at direction `d`.
    pub fn eval(&self, d: DVec3) -> [f64; 3] {
        let y = basis::eval_vec(self.order, d);
        let mut out = [0.0; 3];
        for (yi, c) in y.iter().zip(&self.coeffs) {
            for ch in 0..3 {
                out[ch] += yi * c[ch];
            }
        }
        out
    }
}

/// World-space SH of `light` (its texels already carry `L × scale`).
pub fn project_infinite_light(light: &InfiniteLight, order: ShOrder) -> Result<ShRgb, ShError> {
    project_lat_long_world(&light.map, light.world_from_light, order)
}

/// The world-space SH of a lat-long map seen through `world_from_light`.
pub fn project_lat_long_world(map: &RgbMap, world_from_light: Mat3, order: ShOrder) -> Result<ShRgb, ShError> {
    let m = world_from_light.as_dmat3();
    if !m.is_finite() || m.determinant() == 0.0 {
        return Err(ShError::Invalid("infinite light: singular world-from-light transform".into()));
    }
    // A uniform scale does not change directions.
    let s = m.determinant().abs().cbrt();
    let r = m * (1.0 / s);
    let light_space = project_lat_long(map, order)?;
    match ShRotation::new(order, r) {
        Ok(rot) => {
            let mut out = ShRgb::zero(order);
            rot.apply_rgb(&light_space.coeffs, &mut out.coeffs)?;
            Ok(out)
        }
        Err(_) => Ok(project_lat_long_quadrature(map, world_from_light, order, 4)),
    }
}

/// Light-space SH of the bilinear lat-long function pbrt-v3 renders (see the module doc).
pub fn project_lat_long(map: &RgbMap, order: ShOrder) -> Result<ShRgb, ShError> {
    let (w, h) = (map.width, map.height);
    check_len("environment map texels", map.texels.len(), w * h)?;
    if w == 0 || h == 0 {
        return Err(ShError::Invalid("environment map has no texels".into()));
    }
    let mut out = ShRgb::zero(order);
    if w == 1 && h == 1 {
        // A constant: exact in one line.
        let c = map.texels[0];
        out.coeffs[0] = (c.as_dvec3() * SQRT_4PI).to_array();
        return Ok(out);
    }
    let n = order.n();
    let a = theta_integrals(h, n);
    let rows = row_fourier_sums(map, n);
    let dphi = 2.0 * PI / w as f64;
    let tri = n * (n + 1) / 2;
    for m in 0..n {
        // ∫ Λ(φ − φ_i) e^{imφ} dφ = Δφ sinc²(mΔφ/2) e^{imφ_i}.
        let x = 0.5 * m as f64 * dphi;
        let hat = if m == 0 { dphi } else { dphi * (x.sin() / x).powi(2) };
        for l in m..n {
            let mut cos_part = [0.0; 3];
            let mut sin_part = [0.0; 3];
            for j in 0..h {
                let aj = a[j * tri + l * (l + 1) / 2 + m];
                let (rc, rs) = (rows[(j * n + m) * 2], rows[(j * n + m) * 2 + 1]);
                for c in 0..3 {
                    cos_part[c] += aj * rc[c];
                    sin_part[c] += aj * rs[c];
                }
            }
            for c in 0..3 {
                out.coeffs[super::index(l, m as i32)][c] = hat * cos_part[c];
                if m > 0 {
                    out.coeffs[super::index(l, -(m as i32))][c] = hat * sin_part[c];
                }
            }
        }
    }
    Ok(out)
}

/// `Σ_i L_ij (cos mφ_i, sin mφ_i)` per row `j` and `m < n` (`(j n + m)·2` → cos, `+1` → sin).
fn row_fourier_sums(map: &RgbMap, n: usize) -> Vec<[f64; 3]> {
    let (w, h) = (map.width, map.height);
    let trig: Vec<(f64, f64)> = (0..w)
        .flat_map(|i| {
            let phi = 2.0 * PI * (i as f64 + 0.5) / w as f64;
            (0..n).map(move |m| {
                let (s, c) = (m as f64 * phi).sin_cos();
                (c, s)
            })
        })
        .collect();
    let mut rows = vec![[0.0; 3]; h * n * 2];
    for j in 0..h {
        let acc = &mut rows[j * n * 2..(j + 1) * n * 2];
        for i in 0..w {
            let t = map.texels[j * w + i];
            let t = t.as_dvec3().to_array();
            for m in 0..n {
                let (c, s) = trig[i * n + m];
                for ch in 0..3 {
                    acc[2 * m][ch] += c * t[ch];
                    acc[2 * m + 1][ch] += s * t[ch];
                }
            }
        }
    }
    rows
}

/// `A_jlm = ∫₀^π Λ_j(θ) Q_l^m(cos θ) sin^{m+1} θ dθ` (with `√2` for `m > 0`), at
/// `j·n(n+1)/2 + l(l+1)/2 + m`: Gauss–Legendre on each piece between texel-centre rows,
/// pieces cut to at most 0.05 rad.
fn theta_integrals(h: usize, n: usize) -> Vec<f64> {
    const NODES: usize = 8;
    let (gx, gw) = super::quadrature::gauss_legendre(NODES);
    let tri = n * (n + 1) / 2;
    let mut a = vec![0.0; h * tri];
    let dtheta = PI / h as f64;
    // Knots: 0, the row centres, π; between consecutive knots the weights are linear.
    let mut knots = vec![0.0];
    knots.extend((0..h).map(|j| (j as f64 + 0.5) * dtheta));
    knots.push(PI);
    let order = ShOrder::new(n).expect("order checked by the caller");
    let mut y = vec![0.0; n * n];
    for piece in knots.windows(2) {
        let (t0, t1) = (piece[0], piece[1]);
        let subs = ((t1 - t0) / 0.05).ceil().max(1.0) as usize;
        for s in 0..subs {
            let (u0, u1) = (t0 + (t1 - t0) * s as f64 / subs as f64, t0 + (t1 - t0) * (s + 1) as f64 / subs as f64);
            for (x, wq) in gx.iter().zip(&gw) {
                let theta = 0.5 * (u0 + u1) + 0.5 * (u1 - u0) * x;
                let wt = 0.5 * (u1 - u0) * wq * theta.sin();
                // pbrt's row weights at this θ: t = θ/π·H − 0.5, rows ⌊t⌋ and ⌊t⌋+1, repeat.
                let t = theta / PI * h as f64 - 0.5;
                let t0r = t.floor();
                let dt = t - t0r;
                let r0 = (t0r as i64).rem_euclid(h as i64) as usize;
                let r1 = (t0r as i64 + 1).rem_euclid(h as i64) as usize;
                // Y at φ = 0 gives Q_l^m sin^m θ (×√2 for m > 0) in the cos slots.
                basis::eval_unit(order, DVec3::new(theta.sin(), 0.0, theta.cos()), &mut y);
                for l in 0..n {
                    for m in 0..=l {
                        let v = wt * y[super::index(l, m as i32)];
                        let k = l * (l + 1) / 2 + m;
                        a[r0 * tri + k] += (1.0 - dt) * v;
                        a[r1 * tri + k] += dt * v;
                    }
                }
            }
        }
    }
    a
}

/// World-space SH of the map through any linear `world_from_light`, by a product quadrature
/// over world directions of pbrt-v3's own lookup (`samples_per_texel` nodes per texel side):
/// the fallback for transforms that are not rotations, and an independent check of the
/// exact path.
pub fn project_lat_long_quadrature(
    map: &RgbMap,
    world_from_light: Mat3,
    order: ShOrder,
    samples_per_texel: usize,
) -> ShRgb {
    let light_from_world = world_from_light.as_dmat3().inverse();
    let k = samples_per_texel.max(1);
    let q = super::quadrature::SphereQuadrature::product(map.height.max(8) * k, 2 * map.height.max(8) * k);
    let mut out = ShRgb::zero(order);
    let mut y = vec![0.0; order.coeffs()];
    for (d, wq) in q.dirs.iter().zip(&q.weights) {
        let l = lookup(map, &light_from_world, *d);
        if l == [0.0; 3] {
            continue;
        }
        basis::eval_unit(order, *d, &mut y);
        for (o, yi) in out.coeffs.iter_mut().zip(&y) {
            for c in 0..3 {
                o[c] += wq * yi * l[c];
            }
        }
    }
    out
}

/// pbrt-v3's `Le` for world direction `d`.
fn lookup(map: &RgbMap, light_from_world: &DMat3, d: DVec3) -> [f64; 3] {
    let w = (*light_from_world * d).normalize_or_zero();
    let theta = (w.x * w.x + w.y * w.y).sqrt().atan2(w.z);
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let c = map.lookup(Vec2::new((phi / (2.0 * PI)) as f32, (theta / PI) as f32));
    c.as_dvec3().to_array()
}

#[cfg(test)]
mod tests;
