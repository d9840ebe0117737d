//! Open meshes as exact occluders outside the SH product.
//!
//! Sphere sets bound solids. An open surface (an open cylinder, cone, paraboloid or
//! hyperboloid, a partial sphere, a disk, an open triangle mesh) has no inside to bound:
//! spheres thick enough not to leak through it shadow its own inside and everything near it
//! (the conservative shells `"string openmeshes" "shells"` builds: on hackmad's
//! `shapes/all-shapes` the image mean was 10 % under `directlighting`'s, the insides of the open
//! cylinder and cone black), and many small spheres leak, because `exp*` of their summed logs at
//! order 4 behaves like an absorbing medium (a layer that covers each direction once lets
//! `e^{-1}` of the light through). So `shexp` keeps its sphere-set visibility `V` for the solids
//! and the ground plane, and takes the open meshes (the "traced" objects) exactly, by rays:
//!
//! `E = ∫ L(ω) max(0, n·ω) V(ω) V_o(ω) dω`,
//!
//! `V_o(ω)` = no traced object along the ray. With `S` the noise-free term without them
//! (`⟨LH(n), V⟩` plus the light under the horizon past the ground plane's edge, [`super::horizon`]),
//! one sample is `S · V_o(ω)` for a direction `ω` drawn with density proportional to
//! `L(ω) max(0, n·ω) w(ω)`, where `w` is `V` clamped to [0, 1] above the ground's horizon and
//! the edge test below it ([`EnvProposal::factor`]): unbiased for that integral, noise-free where
//! no traced object blocks, and never negative. Each colour channel draws by its own radiance
//! (channels whose maps are proportional share one draw and one ray). A draw is by rejection:
//! a direction by the map's power ([`EnvProposal`]), kept with probability `max(0, n·ω) w(ω)`;
//! after [`MAX_DRAWS`] rejections (a receiver that sees almost nothing) one more power-drawn
//! direction weighted by `max(0, n·ω) w(ω) Λ / S` stands in (`Λ` the map's power), so the
//! estimate stays unbiased.
//!
//! Rays are cast only when `ω` may meet a traced object (inside the cap of its bounding sphere
//! seen from the receiver); [`TracedObjects::blocked`] follows the ray through the other
//! objects (whose shadow is already in `V`) to the first traced one.

use super::bright::EnvSource;
use super::horizon::HorizonGap;
use super::sphereset::Sphere;
use glam::{DMat3, DVec3};
use penumbra_core::geometry::Ray;
use penumbra_core::mesh::TriangleMesh;
use penumbra_core::scene::Scene;
use penumbra_core::sh::{basis, ShOrder};
use std::f64::consts::PI;

/// Rejected draws before the weighted fallback (a receiver whose visible light is under
/// about 5 % of what the map sends over the whole sphere).
pub const MAX_DRAWS: usize = 64;
/// The environment is drawn over blocks of texels, at most this many across a map's width
/// (and half as many down its height), as [`super::lighting`] sums it.
const MAX_BLOCKS: usize = 256;
/// Pass-throughs of other objects a traced-visibility ray follows before it gives up (and
/// counts as unblocked: the sphere sets hold those objects' shadows).
const MAX_STEPS: usize = 64;

/// The open meshes whose shadows are traced: their objects and bounding spheres.
pub struct TracedObjects {
    traced: Vec<bool>,
    bounds: Vec<Sphere>,
}

impl TracedObjects {
    /// `objects`: indices into `meshes` (= the scene's objects).
    pub fn new(meshes: &[TriangleMesh], objects: &[usize]) -> TracedObjects {
        let mut traced = vec![false; meshes.len()];
        let mut bounds = Vec::new();
        for &i in objects {
            let Some(m) = meshes.get(i) else { continue };
            traced[i] = true;
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for p in &m.positions {
                lo = lo.min(p.as_dvec3());
                hi = hi.max(p.as_dvec3());
            }
            let c = (lo + hi) * 0.5;
            let r = m.positions.iter().map(|p| p.as_dvec3().distance(c)).fold(0.0, f64::max);
            if r.is_finite() {
                bounds.push(Sphere { center: c, radius: r * (1.0 + 1e-6) });
            }
        }
        TracedObjects { traced, bounds }
    }

    pub fn is_empty(&self) -> bool {
        self.bounds.is_empty()
    }

    /// Whether a traced object may lie in the hemisphere of unit `n` at `p`.
    pub fn may_block(&self, p: DVec3, n: DVec3) -> bool {
        self.bounds.iter().any(|s| (s.center - p).dot(n) > -s.radius)
    }

    /// Whether unit direction `d` from `p` may meet a traced object (it lies in the cap of one's
    /// bounding sphere, or `p` is inside one).
    pub fn may_meet(&self, p: DVec3, d: DVec3) -> bool {
        self.bounds.iter().any(|s| {
            let v = s.center - p;
            let (l2, r2) = (v.length_squared(), s.radius * s.radius);
            if l2 <= r2 {
                return true;
            }
            let c = v.dot(d);
            // cos(angle to the centre) ≥ cos(cap half-angle) = √(1 − r²/l²), squared.
            c > 0.0 && c * c >= l2 - r2
        })
    }

    /// Whether `ray` meets a traced object: the closest hit, and past every other object it
    /// meets first, with the number of intersection queries made.
    pub fn blocked(&self, scene: &Scene, ray: Ray) -> (bool, u64) {
        let mut ray = ray;
        for step in 1..=MAX_STEPS as u64 {
            let Some(hit) = scene.intersect(&ray) else { return (false, step) };
            if self.traced.get(hit.mesh as usize).copied().unwrap_or(false) {
                return (true, step);
            }
            let si = scene.interaction(&ray, &hit);
            ray = si.spawn_ray(ray.d);
        }
        (false, MAX_STEPS as u64)
    }
}

/// A block of one map's texels: its source and its light-space ranges of `φ` and `cos θ`.
#[derive(Clone, Copy, Debug)]
struct Block {
    source: usize,
    phi: (f64, f64),
    z: (f64, f64),
}

/// Directions drawn by the environment's power, per colour channel: a block of texels by its
/// power `Σ L_c dω`, then uniformly in solid angle inside it.
pub struct EnvProposal {
    blocks: Vec<Block>,
    /// Each source's world-from-light rotation (a scaled scene's scale divided out).
    frames: Vec<DMat3>,
    /// Per channel, the cumulative power of the blocks.
    cdf: [Vec<f64>; 3],
    /// Per channel, the first channel whose normalised `cdf` is the same (itself if none):
    /// its draws are this channel's.
    same: [usize; 3],
}

impl EnvProposal {
    pub fn build(sources: &[EnvSource]) -> EnvProposal {
        let mut blocks = Vec::new();
        let mut frames = Vec::new();
        let mut power: Vec<[f64; 3]> = Vec::new();
        for (k, src) in sources.iter().enumerate() {
            let m = src.world_from_light.as_dmat3();
            let s = m.determinant().abs().cbrt();
            frames.push(if s > 0.0 && s.is_finite() { m * (1.0 / s) } else { m });
            let map = &src.map;
            let (w, h) = (map.width, map.height);
            if w == 0 || h == 0 || map.texels.len() < w * h {
                continue;
            }
            let f = w.div_ceil(MAX_BLOCKS).max(h.div_ceil(MAX_BLOCKS / 2)).max(1);
            for bt in (0..h).step_by(f) {
                let te = (bt + f).min(h);
                for bs in (0..w).step_by(f) {
                    let se = (bs + f).min(w);
                    let mut p = [0.0f64; 3];
                    for t in bt..te {
                        let (t0, t1) = (PI * t as f64 / h as f64, PI * (t + 1) as f64 / h as f64);
                        let dw = (t0.cos() - t1.cos()) * 2.0 * PI / w as f64;
                        for s in bs..se {
                            for (o, v) in p.iter_mut().zip(map.texels[t * w + s].to_array()) {
                                *o += dw * (v.max(0.0) as f64);
                            }
                        }
                    }
                    let phi = (2.0 * PI * bs as f64 / w as f64, 2.0 * PI * se as f64 / w as f64);
                    let z = ((PI * bt as f64 / h as f64).cos(), (PI * te as f64 / h as f64).cos());
                    blocks.push(Block { source: k, phi, z });
                    power.push(p);
                }
            }
        }
        let cdf: [Vec<f64>; 3] = [0, 1, 2].map(|c| {
            let mut acc = 0.0;
            power
                .iter()
                .map(|p| {
                    acc += p[c];
                    acc
                })
                .collect()
        });
        let normalised = |c: usize, i: usize| cdf[c][i] / cdf[c].last().copied().unwrap_or(1.0);
        let same = [0, 1, 2].map(|c| {
            (0..c)
                .find(|&o| {
                    cdf[o].last().is_some_and(|t| *t > 0.0)
                        && cdf[c].last().is_some_and(|t| *t > 0.0)
                        && (0..cdf[c].len()).all(|i| (normalised(c, i) - normalised(o, i)).abs() <= 1e-12)
                })
                .unwrap_or(c)
        });
        EnvProposal { blocks, frames, cdf, same }
    }

    /// `Λ_c`: the map's power `∫ L_c dω` over the sphere (as drawn: blocks of texels).
    pub fn total(&self, c: usize) -> f64 {
        self.cdf[c].last().copied().unwrap_or(0.0)
    }

    /// A world direction drawn for channel `c` from `u` ∈ [0, 1)² (the first coordinate picks
    /// the block and is reused inside it); `None` for a channel without light.
    pub fn sample(&self, c: usize, u: [f64; 2]) -> Option<DVec3> {
        let cdf = &self.cdf[c];
        let total = *cdf.last()?;
        if !(total > 0.0) {
            return None;
        }
        let x = u[0] * total;
        let i = cdf.partition_point(|&v| v <= x).min(cdf.len() - 1);
        let prev = if i == 0 { 0.0 } else { cdf[i - 1] };
        let u0 = if cdf[i] > prev { ((x - prev) / (cdf[i] - prev)).clamp(0.0, 1.0) } else { 0.5 };
        let b = self.blocks[i];
        let phi = b.phi.0 + (b.phi.1 - b.phi.0) * u0;
        let z = b.z.0 + (b.z.1 - b.z.0) * u[1];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sp, cp) = phi.sin_cos();
        let d = (self.frames[b.source] * DVec3::new(r * cp, r * sp, z)).normalize_or_zero();
        (d != DVec3::ZERO).then_some(d)
    }
}

/// SplitMix64 (the retries of a draw, seeded by its sample).
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// What one channel's draw found.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Draw {
    /// Kept by rejection: whether it was blocked.
    Kept { blocked: bool },
    /// The fallback: its weight `max(0, n·ω) w(ω)` (0: nothing to trace) and whether it was
    /// blocked.
    Fallback { weight: f64, blocked: bool },
    /// The channel has no light.
    Dark,
}

/// A receiver's traced visibility: the receiver, its sphere-set visibility and the model the
/// noise-free term integrates.
pub struct Receiver<'a> {
    pub p: DVec3,
    /// Unit normal of the Lambertian lobe (the shading normal, on the viewer's side).
    pub n: DVec3,
    /// The sphere-set visibility `V` (SH coefficients of `order`).
    pub v: &'a [f32],
    pub order: ShOrder,
    /// The ground plane's unit normal, with its horizon gap.
    pub ground: Option<(DVec3, Option<&'a HorizonGap>)>,
}

impl Receiver<'_> {
    /// `w(ω)·max(0, n·ω)`: the density (up to a constant) of the directions the estimate draws.
    fn weight(&self, d: DVec3, y: &mut [f64]) -> f64 {
        let c = self.n.dot(d);
        if !(c > 0.0) {
            return 0.0;
        }
        if let Some((g, gap)) = self.ground {
            if g.dot(d) <= 0.0 {
                return if gap.is_some_and(|gap| gap.passes(self.p, d)) { c } else { 0.0 };
            }
        }
        let k = self.order.coeffs();
        basis::eval_unit(self.order, d, &mut y[..k]);
        let v: f64 = y[..k].iter().zip(self.v).map(|(a, b)| a * *b as f64).sum();
        c * v.clamp(0.0, 1.0)
    }
}

impl EnvProposal {
    /// Per channel, one sample of the factor that takes the noise-free term `model` (`S`, per
    /// channel) to the light the traced objects leave: 0 or 1 for a kept draw,
    /// `weight · Λ_c / S_c` for the fallback. `u` seeds the draws; `blocked(ω)` traces.
    pub fn factor(
        &self,
        r: &Receiver,
        model: [f64; 3],
        u: [f32; 2],
        blocked: &mut dyn FnMut(DVec3) -> bool,
    ) -> [f64; 3] {
        let mut y = [0.0f64; 64];
        let mut draws = [Draw::Dark; 3];
        for c in 0..3 {
            let o = self.same[c];
            draws[c] = if o < c { draws[o] } else { self.draw(c, r, u, &mut y, blocked) };
        }
        [0, 1, 2].map(|c| match draws[c] {
            Draw::Kept { blocked } => f64::from(u8::from(!blocked)),
            Draw::Fallback { weight, blocked } if !blocked && model[c] > 0.0 => weight * self.total(c) / model[c],
            Draw::Fallback { .. } => 0.0,
            Draw::Dark => 1.0,
        })
    }

    fn draw(&self, c: usize, r: &Receiver, u: [f32; 2], y: &mut [f64], blocked: &mut dyn FnMut(DVec3) -> bool) -> Draw {
        let mut state = ((u[0].to_bits() as u64) << 32) | u[1].to_bits() as u64;
        let mut next = || {
            state = mix(state);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut uu = [u[0] as f64, u[1] as f64];
        for _ in 0..MAX_DRAWS {
            let Some(d) = self.sample(c, uu) else { return Draw::Dark };
            let a = r.weight(d, y);
            if a > 0.0 && next() < a {
                return Draw::Kept { blocked: blocked(d) };
            }
            uu = [next(), next()];
        }
        let Some(d) = self.sample(c, uu) else { return Draw::Dark };
        let weight = r.weight(d, y);
        Draw::Fallback { weight, blocked: weight > 0.0 && blocked(d) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;
    use penumbra_core::light::RgbMap;
    use penumbra_core::sh::SQRT_4PI;
    use penumbra_core::Rgb;

    /// A lat-long map (light space = world) of radiance `f(direction)` per channel.
    fn map(w: usize, h: usize, f: impl Fn(DVec3) -> [f32; 3]) -> EnvSource {
        let mut texels = Vec::new();
        for t in 0..h {
            for s in 0..w {
                let (theta, phi) = (PI * (t as f64 + 0.5) / h as f64, 2.0 * PI * (s as f64 + 0.5) / w as f64);
                let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let [r, g, b] = f(d);
                texels.push(Rgb::new(r, g, b));
            }
        }
        EnvSource { map: RgbMap { width: w, height: h, texels }, world_from_light: Mat3::IDENTITY }
    }

    /// A low-discrepancy point set in [0, 1)² (R2 sequence).
    fn r2(i: usize) -> [f32; 2] {
        let (a1, a2) = (0.754_877_666_246_692_8, 0.569_840_290_998_053_3);
        let f = |x: f64| (x - x.floor()) as f32;
        [f(0.5 + a1 * i as f64).min(0.999_999_9), f(0.5 + a2 * i as f64).min(0.999_999_9)]
    }

    /// `∫ L_c(ω) g(ω) dω` over the sphere by a fine midpoint grid, with `L` the map's texel value
    /// at `ω` (piecewise constant, as drawn).
    fn quadrature(src: &EnvSource, g: impl Fn(DVec3) -> f64) -> [f64; 3] {
        let (nt, np) = (400, 800);
        let (w, h) = (src.map.width, src.map.height);
        let mut out = [0.0; 3];
        for i in 0..nt {
            let (t0, t1) = (PI * i as f64 / nt as f64, PI * (i + 1) as f64 / nt as f64);
            let theta = 0.5 * (t0 + t1);
            for j in 0..np {
                let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let dw = (t0.cos() - t1.cos()) * 2.0 * PI / np as f64;
                let (s, t) = (((phi / (2.0 * PI)) * w as f64) as usize, ((theta / PI) * h as f64) as usize);
                let l = src.map.texels[t.min(h - 1) * w + s.min(w - 1)].to_array();
                let gv = g(d) * dw;
                for c in 0..3 {
                    out[c] += l[c] as f64 * gv;
                }
            }
        }
        out
    }

    /// The visibility `0.5 + 0.4 z` as order-2 SH coefficients (exact), padded to order 4.
    fn linear_v() -> Vec<f32> {
        let mut v = vec![0.0f32; 16];
        v[0] = (0.5 * SQRT_4PI) as f32;
        v[2] = (0.4 / (3.0 / (4.0 * PI)).sqrt()) as f32;
        v
    }

    #[test]
    fn directions_are_drawn_by_power() {
        // Twice as bright in the upper half, red only in the lower: channel shares, and the
        // fraction of draws above the equator.
        let src = map(32, 16, |d| if d.z > 0.0 { [2.0, 2.0, 2.0] } else { [1.0, 0.0, 0.0] });
        let p = EnvProposal::build(std::slice::from_ref(&src));
        assert_eq!(p.same, [0, 1, 1]);
        assert!((p.total(0) - 6.0 * PI).abs() < 1e-9 && (p.total(1) - 4.0 * PI).abs() < 1e-9);
        let n = 20_000;
        let up = (0..n).filter(|&i| p.sample(0, r2(i).map(|x| x as f64)).unwrap().z > 0.0).count() as f64 / n as f64;
        assert!((up - 2.0 / 3.0).abs() < 5e-3, "{up}");
        assert!((0..1000).all(|i| p.sample(1, r2(i).map(|x| x as f64)).unwrap().z > 0.0));
        // A constant map is one block: uniform over the sphere; proportional channels share.
        let flat = EnvProposal::build(&[EnvSource {
            map: RgbMap::constant(Rgb::new(0.8, 0.9, 1.0)),
            world_from_light: Mat3::IDENTITY,
        }]);
        assert_eq!(flat.same, [0, 0, 0]);
        let mean_z = (0..n).map(|i| flat.sample(0, r2(i).map(|x| x as f64)).unwrap().z).sum::<f64>() / n as f64;
        assert!(mean_z.abs() < 5e-3, "{mean_z}");
    }

    /// The factor's mean is the share of the model's light the blocker leaves,
    /// `∫ L max(0, n·ω) V [unblocked] / ∫ L max(0, n·ω) V`, for a gradient map, a linear
    /// visibility and a half-space blocker; also where almost all of the map is behind the
    /// receiver, so that most draws fall back.
    #[test]
    fn the_factor_is_the_unblocked_share() {
        type Map = fn(DVec3) -> [f32; 3];
        let cases: [(DVec3, f64, Map); 2] = [
            (DVec3::new(0.3, -0.2, 0.9).normalize(), 0.3, |d: DVec3| {
                [1.0 + 0.8 * d.x as f32, 0.5, 0.2 + d.z.max(0.0) as f32]
            }),
            (DVec3::Z, -0.5, |d: DVec3| if d.z < -0.2 { [50.0, 50.0, 50.0] } else { [0.02, 0.02, 0.02] }),
        ];
        for (n, cut, f) in cases {
            let src = map(64, 32, f);
            let prop = EnvProposal::build(std::slice::from_ref(&src));
            let v = linear_v();
            let r = Receiver { p: DVec3::ZERO, n, v: &v, order: ShOrder::new(4).unwrap(), ground: None };
            let vis = |d: DVec3| (0.5 + 0.4 * d.z) * n.dot(d).max(0.0);
            let model = quadrature(&src, vis);
            let want = quadrature(&src, |d| if d.x > cut { 0.0 } else { vis(d) });
            let count = 40_000;
            let mut sum = [0.0; 3];
            let mut sq = [0.0; 3];
            for i in 0..count {
                let x = prop.factor(&r, model, r2(i), &mut |d| d.x > cut);
                for c in 0..3 {
                    sum[c] += x[c];
                    sq[c] += x[c] * x[c];
                }
            }
            for c in 0..3 {
                let mean = sum[c] / count as f64;
                let sd = ((sq[c] / count as f64 - mean * mean).max(0.0) / count as f64).sqrt();
                let expect = want[c] / model[c];
                assert!((mean - expect).abs() < 5.0 * sd + 2e-3, "n {n} ch {c}: {mean} vs {expect} (sd {sd})");
            }
        }
    }

    #[test]
    fn caps_hold_every_direction_that_meets_the_mesh() {
        // An open cylinder about z (radius 1, height 2) at (3, 0, 0).
        let (seg, rings) = (24u32, 3u32);
        let mut positions = Vec::new();
        for j in 0..=rings {
            for i in 0..seg {
                let a = 2.0 * std::f32::consts::PI * i as f32 / seg as f32;
                positions.push(glam::Vec3::new(3.0 + a.cos(), a.sin(), 2.0 * j as f32 / rings as f32 - 1.0));
            }
        }
        let mut indices = Vec::new();
        for j in 0..rings {
            for i in 0..seg {
                let (a, b) = (j * seg + i, j * seg + (i + 1) % seg);
                indices.extend([[a, b, b + seg], [a, b + seg, a + seg]]);
            }
        }
        let mesh = TriangleMesh { positions, indices, ..Default::default() };
        let traced = TracedObjects::new(std::slice::from_ref(&mesh), &[0]);
        let hits = |p: DVec3, d: DVec3| {
            mesh.indices.iter().any(|t| {
                let [a, b, c] = t.map(|k| mesh.positions[k as usize].as_dvec3());
                let (e1, e2) = (b - a, c - a);
                let pv = d.cross(e2);
                let det = e1.dot(pv);
                if det.abs() < 1e-12 {
                    return false;
                }
                let tv = p - a;
                let u = tv.dot(pv) / det;
                let qv = tv.cross(e1);
                let v = d.dot(qv) / det;
                u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(qv) / det > 0.0
            })
        };
        let mut met = 0;
        for p in [DVec3::new(0.0, 0.0, 0.0), DVec3::new(3.0, 0.0, 0.5), DVec3::new(6.0, 4.0, -3.0)] {
            for i in 0..4000 {
                let u = r2(i);
                let z = 1.0 - 2.0 * u[0] as f64;
                let (s, c) = (2.0 * PI * u[1] as f64).sin_cos();
                let d = DVec3::new((1.0 - z * z).sqrt() * c, (1.0 - z * z).sqrt() * s, z);
                if hits(p, d) {
                    met += 1;
                    assert!(traced.may_meet(p, d), "{p} {d}");
                }
            }
        }
        assert!(met > 1000, "{met}");
        assert!(!traced.may_meet(DVec3::ZERO, -DVec3::X));
        assert!(traced.may_block(DVec3::ZERO, DVec3::X) && !traced.may_block(DVec3::ZERO, -DVec3::X));
    }
}
