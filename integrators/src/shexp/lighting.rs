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
use super::cubemap::{cubemap_bilinear, texel_dir};
use glam::DVec3;
use penumbra_core::light::Light;
use penumbra_core::sh::{self, quadrature::gauss_legendre, ShOrder, SQRT_4PI};
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Gauss–Legendre nodes in z per normal and part of the hemisphere (for the ground cut of the
/// mean radiance; φ is exact).
pub(crate) const NZ: usize = 24;
/// The environment's non-constant part is summed over blocks of texels, at most this many
/// blocks across the map's width (and half as many down its height).
const MAX_BLOCKS: usize = 256;
/// Normal-cubemap texels integrated together (and computed on first use together).
const TILE: usize = 32;

pub struct EnvLighting {
    order: ShOrder,
    res: usize,
    /// Mean radiance per channel (`L_00/√4π`).
    mean: [f64; 3],
    /// Clamped-cosine ZH.
    h: Vec<f64>,
    /// The residual's texels, computed on first use (`None`: `R ≡ 0`).
    residual: Option<Residual>,
}

/// `R(N)` on the normal cubemap, [`TILE`] texels at a time as receivers first need them: only
/// the normals a scene shows are integrated (flat-shaded meshes show a few hundred), and the
/// values do not depend on which thread asks first.
struct Residual {
    ground: Option<DVec3>,
    /// Block directions and, per block, its weight times its basis values, channel-major.
    dirs: Vec<DVec3>,
    wys: Vec<f64>,
    zq: (Vec<f64>, Vec<f64>),
    /// Per tile, `TILE · n²` coefficients.
    tiles: Vec<OnceLock<Vec<[f64; 3]>>>,
}

impl Residual {
    /// The coefficients of texel `t` (`n²`) of `env`'s residual (`self`).
    fn texel(&self, env: &EnvLighting, t: usize) -> &[[f64; 3]] {
        let k = env.order.coeffs();
        let tile = self.tiles[t / TILE].get_or_init(|| self.tile(env, t / TILE));
        &tile[(t % TILE) * k..(t % TILE + 1) * k]
    }

    /// Integrates one tile: each block once over the tile's normals (it streams from memory
    /// once per tile), each texel summing its blocks in order.
    fn tile(&self, env: &EnvLighting, tile: usize) -> Vec<[f64; 3]> {
        let (k, res) = (env.order.coeffs(), env.res);
        let ts = tile * TILE..((tile + 1) * TILE).min(6 * res * res);
        let normals: Vec<DVec3> = ts
            .map(|t| {
                let (face, j, i) = (t / (res * res), (t / res) % res, t % res);
                texel_dir(face, i, j, res)
            })
            .collect();
        let mut acc = vec![0.0; normals.len() * 3 * k];
        for (d, wy) in self.dirs.iter().zip(self.wys.chunks_exact(3 * k)) {
            for (n, a) in normals.iter().zip(acc.chunks_exact_mut(3 * k)) {
                let c = n.dot(*d);
                if c <= 0.0 {
                    continue;
                }
                for (o, v) in a.iter_mut().zip(wy) {
                    *o += c * v;
                }
            }
        }
        let mut out = Vec::with_capacity(normals.len() * k);
        for (&n, a) in normals.iter().zip(acc.chunks_exact(3 * k)) {
            let mut q = vec![[0.0; 3]; k];
            if let Some(g) = self.ground {
                // The mean radiance over the cut hemisphere, minus the analytic uncut part.
                let cut = cut_hemisphere(env.order, n, g, (&self.zq.0, &self.zq.1));
                let mut hn = vec![0.0; k];
                let _ = sh::zonal::rotate_zh(&env.h, n, &mut hn);
                for ((qi, c), hi) in q.iter_mut().zip(&cut).zip(&hn) {
                    for (o, m) in qi.iter_mut().zip(env.mean) {
                        *o = m * (c - hi);
                    }
                }
            }
            for (i, qi) in q.iter_mut().enumerate() {
                for (c, o) in qi.iter_mut().enumerate() {
                    *o += a[c * k + i];
                }
            }
            out.extend(q);
        }
        out
    }
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

/// An orthonormal frame (t, b) around unit `n`.
pub(crate) fn frame(n: DVec3) -> (DVec3, DVec3) {
    let t = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = (t - n * n.dot(t)).normalize();
    (t, n.cross(t))
}

/// `∫_{n·ω>0, g·ω>0} (n·ω) y(ω) dω` in n's frame: Gauss–Legendre in `z = n·ω` (`zq`, nodes
/// and weights on [−1, 1], used once on the rings the horizon cuts and once on the others, so
/// `2 zq.len()` rings), and in φ exactly over the arc of each ring above the plane of `g`.
///
/// On a ring of fixed `z` an SH basis function of band `l < n` is a trigonometric polynomial
/// of degree at most `L = n − 1` in φ, so its values at `M = 2L + 1` equally spaced φ fix it;
/// integrating each Fourier mode over the arc `[φ0 − α, φ0 + α]` in closed form turns that
/// into weights `w_m = (2α + Σ_{j=1..L} 4 sin(jα) cos(j(φ0 − φ_m)) / j) / M` on those nodes,
/// exact for every arc (the full ring gets `2π/M`). No trigonometric calls: `cos α`, `φ0` and
/// the multiple angles come from the ring's geometry and Chebyshev recurrences.
pub(crate) fn cut_hemisphere(order: ShOrder, n: DVec3, g: DVec3, (zs, zw): (&[f64], &[f64])) -> Vec<f64> {
    let k = order.coeffs();
    let l_max = order.n() - 1;
    let m_nodes = 2 * l_max + 1;
    let (t, b) = frame(n);
    let (gx, gy, gz) = (g.dot(t), g.dot(b), g.dot(n));
    let gxy = gx.hypot(gy);
    // The arc's centre φ0 (only its cosine and sine are needed).
    let (c0, s0) = if gxy > 0.0 { (gx / gxy, gy / gxy) } else { (1.0, 0.0) };
    let nodes: Vec<(f64, f64)> = (0..m_nodes)
        .map(|m| {
            let p = 2.0 * PI * m as f64 / m_nodes as f64;
            (p.cos(), p.sin())
        })
        .collect();
    // Rings below zc are cut (the horizon crosses them), rings above it are whole or gone.
    // The arc's half-width grows as √(zc − z) from zc, so the cut part is integrated in u with
    // z = zc (1 − u²), which makes the integrand smooth; the rest is a polynomial in z.
    let zc = gxy / gxy.hypot(gz).max(1e-300);
    let rings = zs.iter().zip(zw).flat_map(|(x, w)| {
        let u = 0.5 * (x + 1.0);
        [(zc * (1.0 - u * u), w * zc * u), (zc + (1.0 - zc) * u, 0.5 * w * (1.0 - zc))]
    });
    let mut out = vec![0.0; k];
    let mut y = vec![0.0; k];
    let mut sin_j = vec![0.0; l_max + 1];
    let mut weights = vec![0.0; m_nodes];
    for (z, wz) in rings {
        if wz == 0.0 {
            continue;
        }
        let s = (1.0 - z * z).max(0.0).sqrt();
        // The arc [φ0 − α, φ0 + α] of this ring where g·ω = gz z + s gxy cos(φ − φ0) > 0.
        let (cos_a, sin_a, alpha) = if gxy * s > 1e-300 {
            let lim = -gz * z / (gxy * s);
            if lim <= -1.0 {
                (-1.0, 0.0, PI)
            } else if lim >= 1.0 {
                continue;
            } else {
                (lim, (1.0 - lim * lim).sqrt(), lim.acos())
            }
        } else if gz * z > 0.0 {
            (-1.0, 0.0, PI)
        } else {
            continue;
        };
        // sin(jα) by sin(jα) = 2 cos α sin((j−1)α) − sin((j−2)α); sin_j[0] stays 0.
        if l_max >= 1 {
            sin_j[1] = sin_a;
        }
        for j in 2..=l_max {
            sin_j[j] = 2.0 * cos_a * sin_j[j - 1] - sin_j[j - 2];
        }
        for (w, (cm, sm)) in weights.iter_mut().zip(&nodes) {
            // cos(j δ) for δ = φ0 − φ_m, by the same recurrence.
            let cd = c0 * cm + s0 * sm;
            let (mut prev, mut cur) = (1.0, cd);
            let mut acc = 2.0 * alpha;
            for (j, sj) in sin_j.iter().enumerate().skip(1) {
                acc += 4.0 * sj * cur / j as f64;
                let next = 2.0 * cd * cur - prev;
                prev = cur;
                cur = next;
            }
            *w = acc / m_nodes as f64;
        }
        for (w, (cm, sm)) in weights.iter().zip(&nodes) {
            // φ_m measured from t towards b.
            let d = t * (s * cm) + b * (s * sm) + n * z;
            sh::basis::eval_unit(order, d, &mut y);
            let w = wz * w * z;
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
        let mut env = EnvLighting { order, res: res.max(1), mean, h, residual: None };
        if all_blocks.is_empty() && ground.is_none() {
            return env;
        }
        let res = env.res;
        // Blocks under the ground's horizon never reach a receiver.
        all_blocks.retain(|b| !ground.is_some_and(|g| g.dot(b.d) <= 0.0));
        // Per block, its weight times its basis values, channel-major.
        let mut wys = Vec::with_capacity(all_blocks.len() * 3 * order.coeffs());
        for b in &all_blocks {
            let y = sh::basis::eval_vec(order, b.d);
            for w in b.weight {
                wys.extend(y.iter().map(|yi| w * yi));
            }
        }
        env.residual = Some(Residual {
            ground,
            dirs: all_blocks.iter().map(|b| b.d).collect(),
            wys,
            zq: gauss_legendre(NZ),
            tiles: (0..(6 * res * res).div_ceil(TILE)).map(|_| OnceLock::new()).collect(),
        });
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
        let Some(residual) = &self.residual else { return };
        for (t, w) in cubemap_bilinear(n, self.res) {
            for (o, r) in out.iter_mut().zip(residual.texel(self, t)) {
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

    /// The arc integral by brute force: Gauss–Legendre in φ over each ring's arc, plain
    /// Gauss–Legendre in z over [0, 1] (no substitution at the horizon).
    fn cut_by_arc_quadrature(order: ShOrder, n: DVec3, g: DVec3, nz: usize, nphi: usize) -> Vec<f64> {
        let (zs, zw) = gauss_legendre(nz);
        let (ps, pw) = gauss_legendre(nphi);
        let (t, b) = frame(n);
        let (gx, gy, gz) = (g.dot(t), g.dot(b), g.dot(n));
        let gxy = gx.hypot(gy);
        let mut out = vec![0.0; order.coeffs()];
        let mut y = vec![0.0; order.coeffs()];
        for (x, wz) in zs.iter().zip(&zw) {
            let z = 0.5 * (x + 1.0);
            let s = (1.0 - z * z).sqrt();
            let lim = if gxy * s > 0.0 {
                -gz * z / (gxy * s)
            } else if gz * z > 0.0 {
                -2.0
            } else {
                2.0
            };
            if lim >= 1.0 {
                continue;
            }
            let alpha = if lim <= -1.0 { PI } else { lim.acos() };
            let phi0 = gy.atan2(gx);
            for (u, wu) in ps.iter().zip(&pw) {
                let phi = phi0 + alpha * u;
                let d = t * (s * phi.cos()) + b * (s * phi.sin()) + n * z;
                sh::basis::eval_unit(order, d, &mut y);
                for (o, yi) in out.iter_mut().zip(&y) {
                    *o += 0.5 * wz * wu * alpha * z * yi;
                }
            }
        }
        out
    }

    #[test]
    fn cut_hemispheres_match_a_fine_quadrature() {
        let mut worst: f64 = 0.0;
        for o in [1, 2, 4, 8] {
            let order = ShOrder::new(o).unwrap();
            let (zs, zw) = gauss_legendre(NZ);
            for i in 0..6 {
                let t = i as f64 * 1.23;
                let n = DVec3::new(t.sin() * (2.1 * t).cos(), (1.3 * t).cos(), t.cos() * (0.7 * t).sin()).normalize();
                let g = DVec3::new((0.9 * t).cos(), 0.4 + (1.7 * t).sin(), (0.3 * t).sin()).normalize();
                let got = cut_hemisphere(order, n, g, (&zs, &zw));
                let want = cut_by_arc_quadrature(order, n, g, 3000, 32);
                for (a, b) in got.iter().zip(&want) {
                    worst = worst.max((a - b).abs());
                }
            }
            // No ground below the hemisphere: the clamped cosine's own projection.
            let n = DVec3::new(0.3, -0.5, 0.8).normalize();
            let got = cut_hemisphere(order, n, n, (&zs, &zw));
            let mut want = vec![0.0; order.coeffs()];
            let _ = sh::zonal::rotate_zh(&sh::zonal::clamped_cosine(order), n, &mut want);
            for (a, b) in got.iter().zip(&want) {
                assert!((a - b).abs() < 1e-12, "order {o}: {a} vs {b}");
            }
        }
        eprintln!("worst difference from 3000 × 32 nodes: {worst:.2e}");
        // The values are up to about 1; plain Gauss–Legendre with 48 nodes in z is off by 2e-3.
        assert!(worst < 1e-5, "{worst}");
    }
}
