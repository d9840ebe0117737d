//! `LH(N)`: the order-n SH projection of `L(ω) · max(0, N·ω)` (seed 003 eq. 3.61, Ren's
//! "LH cube map"), so that shading is one dot product with the visibility vector. Projected
//! exactly rather than as an SH product of L and H: `L̃·H̃` truncated would add a second
//! approximation, while `∫ Ṽ · proj(LH) = ∫ Ṽ · L · H` holds exactly.
//!
//! `LH(N) = L̄ · H(N) + R(N)`: `L̄` the mean radiance (DC term), `H(N)` the clamped cosine
//! turned to N (closed form), and the residual `R(N)` tabulated at the texel centres of a
//! normal cubemap (`res²` per face), interpolated bilinearly. A constant environment without
//! a ground cut has `R ≡ 0`: the white furnace is then exact. Each `R(N)` is a quadrature in
//! N's frame over the upper hemisphere only (no kink in the cosine): Gauss–Legendre in
//! `z = cos θ`, and in φ over exactly the arc of each ring that is above the ground plane's
//! horizon when there is one (so the cut is integrated without staircase error).

use super::bright::EnvSource;
use glam::DVec3;
use penumbra_core::light::Light;
use penumbra_core::sh::{self, quadrature::gauss_legendre, ShOrder, SQRT_4PI};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Quadrature nodes in z and in φ per normal (for the ground cut of the mean radiance).
const NZ: usize = 48;
const NPHI: usize = 64;
/// The environment's non-constant part is summed over blocks of texels, at most this many
/// blocks across the map's width (and half as many down its height).
const MAX_BLOCKS: usize = 256;

pub struct EnvLighting {
    order: ShOrder,
    res: usize,
    /// Mean radiance per channel (`L_00/√4π`).
    mean: [f64; 3],
    /// Clamped-cosine ZH.
    h: Vec<f64>,
    /// `6 · res² · n²` residual coefficients (empty: `R ≡ 0`).
    residual: Vec<[f64; 3]>,
}

/// A block of environment texels: the world direction of its centre, and its radiance minus
/// its light's mean, times its solid angle.
struct Block {
    d: DVec3,
    weight: [f64; 3],
}

/// The texel blocks of an environment (box-filtered with the solid angle of each row).
fn blocks(il: &EnvSource, mean: [f64; 3]) -> Vec<Block> {
    let map = &il.map;
    let (w, h) = (map.width, map.height);
    let f = w.div_ceil(MAX_BLOCKS).max(h.div_ceil(MAX_BLOCKS / 2)).max(1);
    let m = il.world_from_light.as_dmat3();
    let mut out = Vec::new();
    for bt in (0..h).step_by(f) {
        for bs in (0..w).step_by(f) {
            let (mut sum, mut area) = ([0.0f64; 3], 0.0);
            for t in bt..(bt + f).min(h) {
                let (t0, t1) = (PI * t as f64 / h as f64, PI * (t + 1) as f64 / h as f64);
                let dw = (t0.cos() - t1.cos()) * 2.0 * PI / w as f64;
                for s in bs..(bs + f).min(w) {
                    let c = map.texels[t * w + s];
                    for (o, v) in sum.iter_mut().zip(c.to_array()) {
                        *o += dw * v as f64;
                    }
                    area += dw;
                }
            }
            let te = (bt + f).min(h) as f64;
            let se = (bs + f).min(w) as f64;
            let theta = PI * 0.5 * (bt as f64 + te) / h as f64;
            let phi = PI * (bs as f64 + se) / w as f64;
            let local = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let d = (m * local).normalize_or_zero();
            if d == DVec3::ZERO {
                continue;
            }
            let weight = [sum[0] - mean[0] * area, sum[1] - mean[1] * area, sum[2] - mean[2] * area];
            out.push(Block { d, weight });
        }
    }
    out
}

/// The direction of texel `(face, i, j)`'s centre.
fn texel_dir(face: usize, i: usize, j: usize, res: usize) -> DVec3 {
    let u = 2.0 * (i as f64 + 0.5) / res as f64 - 1.0;
    let v = 2.0 * (j as f64 + 0.5) / res as f64 - 1.0;
    let d = match face {
        0 => DVec3::new(1.0, v, -u),
        1 => DVec3::new(-1.0, v, u),
        2 => DVec3::new(u, 1.0, -v),
        3 => DVec3::new(u, -1.0, v),
        4 => DVec3::new(u, v, 1.0),
        _ => DVec3::new(-u, v, -1.0),
    };
    d.normalize()
}

/// The face and continuous texel coordinates of direction `d` (inverse of [`texel_dir`]).
fn face_coords(d: DVec3, res: usize) -> (usize, f64, f64) {
    let a = d.abs();
    let (face, u, v) = if a.x >= a.y && a.x >= a.z {
        if d.x > 0.0 {
            (0, -d.z / a.x, d.y / a.x)
        } else {
            (1, d.z / a.x, d.y / a.x)
        }
    } else if a.y >= a.z {
        if d.y > 0.0 {
            (2, d.x / a.y, -d.z / a.y)
        } else {
            (3, d.x / a.y, d.z / a.y)
        }
    } else if d.z > 0.0 {
        (4, d.x / a.z, d.y / a.z)
    } else {
        (5, -d.x / a.z, d.y / a.z)
    };
    let r = res as f64;
    (face, (u + 1.0) * 0.5 * r - 0.5, (v + 1.0) * 0.5 * r - 0.5)
}

/// An orthonormal frame (t, b) around unit `n`.
fn frame(n: DVec3) -> (DVec3, DVec3) {
    let t = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = (t - n * n.dot(t)).normalize();
    (t, n.cross(t))
}

/// `∫_{n·ω>0, g·ω>0} (n·ω) y(ω) dω` in n's frame: Gauss–Legendre in `z = n·ω`, and in φ over
/// exactly the arc of each ring above the plane of `g`.
pub(crate) fn cut_hemisphere(
    order: ShOrder,
    n: DVec3,
    g: DVec3,
    (zs, zw): (&[f64], &[f64]),
    (ps, pw): (&[f64], &[f64]),
) -> Vec<f64> {
    let k = order.coeffs();
    let (t, b) = frame(n);
    let (gx, gy, gz) = (g.dot(t), g.dot(b), g.dot(n));
    let gxy = gx.hypot(gy);
    let mut out = vec![0.0; k];
    let mut y = vec![0.0; k];
    for (x, wz) in zs.iter().zip(zw) {
        let z = 0.5 * (x + 1.0);
        let wz = 0.5 * wz;
        let s = (1.0 - z * z).max(0.0).sqrt();
        // The arc [φ0 − α, φ0 + α] of this ring where g·ω = gz z + s gxy cos(φ − φ0) > 0.
        let (phi0, alpha) = if gxy * s > 1e-300 {
            let lim = -gz * z / (gxy * s);
            if lim <= -1.0 {
                (0.0, PI)
            } else if lim >= 1.0 {
                continue;
            } else {
                (gy.atan2(gx), lim.acos())
            }
        } else if gz * z > 0.0 {
            (0.0, PI)
        } else {
            continue;
        };
        for (u, wu) in ps.iter().zip(pw) {
            let phi = phi0 + alpha * u;
            let w = wz * wu * alpha * z;
            let d = t * (s * phi.cos()) + b * (s * phi.sin()) + n * z;
            sh::basis::eval_unit(order, d, &mut y);
            for (o, yi) in out.iter_mut().zip(&y) {
                *o += w * yi;
            }
        }
    }
    out
}

impl EnvLighting {
    /// [`build`](Self::build) from the scene's infinite lights as they are.
    pub fn from_lights(lights: &[&Light], ground: Option<DVec3>, order: ShOrder, res: usize) -> EnvLighting {
        let sources: Vec<EnvSource> = lights
            .iter()
            .filter_map(|l| match l {
                Light::Infinite(il) => Some(EnvSource { map: il.map.clone(), world_from_light: il.world_from_light }),
                _ => None,
            })
            .collect();
        EnvLighting::build(&sources, ground, order, res)
    }

    /// `sources`: the environments; `ground`: the unit normal of the plane whose lower side is
    /// cut off; `res`: normal cubemap texels per face edge.
    pub fn build(sources: &[EnvSource], ground: Option<DVec3>, order: ShOrder, res: usize) -> EnvLighting {
        let k = order.coeffs();
        let mut mean = [0.0; 3];
        let mut all_blocks = Vec::new();
        for il in sources {
            let mut m = [0.0; 3];
            if let Ok(c) =
                sh::env::project_lat_long_world(&il.map, il.world_from_light, ShOrder::new(1).expect("order 1"))
            {
                for (m, v) in m.iter_mut().zip(c.coeffs[0]) {
                    *m = v / SQRT_4PI;
                }
            }
            let t0 = il.map.texels.first().copied().unwrap_or_default();
            if !il.map.texels.iter().all(|t| *t == t0) {
                all_blocks.extend(blocks(il, m));
            }
            for c in 0..3 {
                mean[c] += m[c];
            }
        }
        let h = sh::zonal::clamped_cosine(order);
        let mut env = EnvLighting { order, res: res.max(1), mean, h, residual: Vec::new() };
        if all_blocks.is_empty() && ground.is_none() {
            return env;
        }
        let res = env.res;
        let ys: Vec<f64> = all_blocks.iter().flat_map(|b| sh::basis::eval_vec(order, b.d)).collect();
        let (zs, zw) = gauss_legendre(NZ);
        let (ps, pw) = gauss_legendre(NPHI);
        let rows: Vec<Vec<[f64; 3]>> = (0..6 * res * res)
            .into_par_iter()
            .map(|t| {
                let (face, j, i) = (t / (res * res), (t / res) % res, t % res);
                let n = texel_dir(face, i, j, res);
                let mut q = vec![[0.0; 3]; k];
                if let Some(g) = ground {
                    // The mean radiance over the cut hemisphere, minus the analytic uncut part.
                    let cut = cut_hemisphere(order, n, g, (&zs, &zw), (&ps, &pw));
                    let mut hn = vec![0.0; k];
                    let _ = sh::zonal::rotate_zh(&env.h, n, &mut hn);
                    for ((qi, c), hi) in q.iter_mut().zip(&cut).zip(&hn) {
                        for (o, m) in qi.iter_mut().zip(env.mean) {
                            *o = m * (c - hi);
                        }
                    }
                }
                for (b, y) in all_blocks.iter().zip(ys.chunks_exact(k)) {
                    let c = n.dot(b.d);
                    if c <= 0.0 || ground.is_some_and(|g| g.dot(b.d) <= 0.0) {
                        continue;
                    }
                    for (qi, yi) in q.iter_mut().zip(y) {
                        for (o, w) in qi.iter_mut().zip(b.weight) {
                            *o += c * w * yi;
                        }
                    }
                }
                q
            })
            .collect();
        env.residual = rows.into_iter().flatten().collect();
        env
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    /// `LH(n)` (unit `n`) into `out[..n²]`.
    pub fn lh(&self, n: DVec3, out: &mut [[f64; 3]], scratch: &mut [f64]) {
        let k = self.order.coeffs();
        let _ = sh::zonal::rotate_zh(&self.h, n, scratch);
        for (o, hi) in out.iter_mut().zip(&scratch[..k]) {
            *o = [self.mean[0] * hi, self.mean[1] * hi, self.mean[2] * hi];
        }
        if self.residual.is_empty() {
            return;
        }
        let res = self.res;
        let (face, u, v) = face_coords(n, res);
        let clamp = |x: f64| x.clamp(0.0, (res - 1) as f64);
        let (u, v) = (clamp(u), clamp(v));
        let (i0, j0) = (u.floor() as usize, v.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(res - 1), (j0 + 1).min(res - 1));
        let (fu, fv) = (u - i0 as f64, v - j0 as f64);
        let base = face * res * res;
        let texel = |i: usize, j: usize| &self.residual[(base + j * res + i) * k..(base + j * res + i + 1) * k];
        let corners = [
            (texel(i0, j0), (1.0 - fu) * (1.0 - fv)),
            (texel(i1, j0), fu * (1.0 - fv)),
            (texel(i0, j1), (1.0 - fu) * fv),
            (texel(i1, j1), fu * fv),
        ];
        for (c, w) in corners {
            for (o, r) in out.iter_mut().zip(c) {
                for ch in 0..3 {
                    o[ch] += w * r[ch];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubemap_coordinates_round_trip() {
        let res = 7;
        for face in 0..6 {
            for j in 0..res {
                for i in 0..res {
                    let d = texel_dir(face, i, j, res);
                    let (f, u, v) = face_coords(d, res);
                    assert_eq!(f, face);
                    assert!((u - i as f64).abs() < 1e-9 && (v - j as f64).abs() < 1e-9, "{face} {i} {j}: {u} {v}");
                }
            }
        }
    }
}
