//! `"integer brightlights"`: the brightest compact regions of an environment map, which order-n
//! SH would smear and ring (seed 003 digest §8.1), are split off and shaded with shadow rays
//! in directions drawn over each region ([`BrightLight::sample`]), so that their shadows are
//! as soft as the region is wide (the bounce's precomputations use one ray towards the
//! region's power centroid). A region grows from the brightest remaining texel over its
//! 4-neighbours (φ wraps) while they stay above a tenth of that peak and within
//! [`MAX_RADIUS`] of it; its texels are lowered to the mean of the texels bordering it, and the
//! light carries exactly what was removed (`Σ (L − L_border) dω`). Regions are split while
//! their peak exceeds [`PEAK_RATIO`] times the map's mean luminance.

use glam::DVec3;
use glam::Mat3;
use penumbra_core::light::{InfiniteLight, RgbMap};
use penumbra_core::Rgb;
use std::f64::consts::PI;

/// A region is split only if its peak luminance is at least this many times the map's mean
/// (the default of `"float brightratio"`), and it grows to at most [`MAX_RADIUS`] (the default
/// of `"float brightradius"`). Since the regions are sampled over their extent (soft shadows,
/// [`BrightLight::sample`]) rather than shaded from one direction, splitting more of the map
/// only moves light from the order-n SH to shadow rays: 2 and 75° (were 4 and 45°) take
/// `env/objects-studio`'s three soft boxes whole, and its RMSE against pbrt-v3 at 256², 64 spp
/// falls from 0.0216 to 0.0084 (`env/objects-sky-sun`'s compact sun: 0.0104 either way).
pub const PEAK_RATIO: f64 = 2.0;
/// The largest angular radius of a split region.
pub const MAX_RADIUS: f64 = 75.0 * PI / 180.0;

/// What is split off: at most `max_lights` regions of peak ≥ `peak_ratio` × the map's mean
/// luminance and angular radius ≤ `max_radius`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitRule {
    pub max_lights: usize,
    pub peak_ratio: f64,
    pub max_radius: f64,
}

impl SplitRule {
    pub fn new(max_lights: usize) -> SplitRule {
        SplitRule { max_lights, peak_ratio: PEAK_RATIO, max_radius: MAX_RADIUS }
    }
}

/// An environment as `shexp` projects it.
#[derive(Clone, Debug)]
pub struct EnvSource {
    pub map: RgbMap,
    pub world_from_light: Mat3,
}

/// A split-off region: unit world direction of its removed power's centroid, and that power
/// per channel (its irradiance at normal incidence were it a directional light), with the
/// texels it was taken from to sample directions over it ([`BrightLight::sample`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BrightLight {
    pub dir: DVec3,
    pub irradiance: [f64; 3],
    /// The region's texels with removed power: `(s, t)` and the removed power per channel.
    texels: Vec<RegionTexel>,
    /// The map's size, and the light's frame.
    size: (usize, usize),
    world_from_light: glam::DMat3,
    /// The region's (luminance) power up to and including each texel, and its guide table:
    /// `guide[j]` is the first texel whose `cdf` exceeds `j/len` of the total.
    cdf: Vec<f64>,
    guide: Vec<u32>,
    /// A cone around `dir` holding every direction of the region: the cosine and sine of its
    /// half-angle.
    cone: (f64, f64),
    /// The region's unshadowed irradiance `Σ ΔL max(0, n·ω) dω` per channel on a normal
    /// cubemap ([`IRR_RES`]² texels per face, bilinear; [`BrightLight::irradiance_at`]).
    irr: Vec<[f64; 3]>,
}

/// Normal-cubemap texels per face edge of a region's unshadowed irradiance. Where a region is
/// wholly seen the ratio estimate is this value alone, so its interpolation error is what a
/// turned scene changes: `penumbra stability scenes/suite/env/objects-studio.pbrt -i shexp
/// --variants rotate --resolution 32x32` gives max |z| 8.5 (over the gate of 8) at 32, 5.0 at 64.
pub const IRR_RES: usize = 64;
/// Map texels merged (per side) into one block when tabulating a region's irradiance.
const IRR_BLOCK: u32 = 4;
/// Draws of [`BrightLight::estimate`] before it falls back to a power-drawn direction (the
/// region is then almost all behind the receiver's tangent plane).
const MAX_DRAWS: usize = 32;

/// SplitMix64: the retries and acceptance tests of [`BrightLight::estimate`], seeded by the
/// sample.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The region's irradiance table: its texels merged into blocks (power summed, direction the
/// power-weighted mean), summed at every normal texel.
fn irradiance_table(texels: &[RegionTexel], (w, h): (usize, usize), m: glam::DMat3) -> Vec<[f64; 3]> {
    let mut blocks: std::collections::BTreeMap<(u32, u32), ([f64; 3], DVec3)> = Default::default();
    for tx in texels {
        let e = blocks.entry((tx.t / IRR_BLOCK, tx.s / IRR_BLOCK)).or_insert(([0.0; 3], DVec3::ZERO));
        for (o, p) in e.0.iter_mut().zip(tx.power) {
            *o += p;
        }
        let l = (tx.power[0] + tx.power[1] + tx.power[2]) / 3.0;
        e.1 += m * texel_dir(tx.s as usize, tx.t as usize, w, h) * l;
    }
    let blocks: Vec<([f64; 3], DVec3)> = blocks.into_values().map(|(p, d)| (p, d.normalize_or_zero())).collect();
    let res = IRR_RES;
    (0..6 * res * res)
        .map(|t| {
            let (face, j, i) = (t / (res * res), (t / res) % res, t % res);
            let n = super::cubemap::texel_dir(face, i, j, res);
            let mut e = [0.0; 3];
            for (p, d) in &blocks {
                let c = n.dot(*d);
                if c > 0.0 {
                    for (o, v) in e.iter_mut().zip(p) {
                        *o += c * v;
                    }
                }
            }
            e
        })
        .collect()
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct RegionTexel {
    s: u32,
    t: u32,
    power: [f64; 3],
    /// `cos θ` at the texel's upper and lower edges.
    z: (f64, f64),
}

impl BrightLight {
    /// The region's unshadowed irradiance per channel at unit normal `n` (interpolated).
    pub fn irradiance_at(&self, n: DVec3) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (t, w) in super::cubemap::cubemap_bilinear(n, IRR_RES) {
            for (o, x) in out.iter_mut().zip(self.irr[t]) {
                *o += w * x;
            }
        }
        out
    }

    /// [`Self::estimate`]'s plain counterpart (`"brightestimator" "plain"`): a direction drawn
    /// by power ([`Self::sample`]), its weight times its cosine if `visible`.
    pub fn estimate_plain(&self, n: DVec3, u: [f32; 2], visible: &mut dyn FnMut(DVec3) -> bool) -> [f64; 3] {
        let (d, w) = self.sample(u);
        let c = n.dot(d);
        if c > 0.0 && visible(d) {
            w.map(|v| v * c)
        } else {
            [0.0; 3]
        }
    }

    /// One sample of the region's shadowed irradiance at unit normal `n`, `∫ ΔL V max(0, n·ω) dω`
    /// per channel, with `visible(ω)` the shadow test. A direction is drawn with density
    /// proportional to the removed luminance times `max(0, n·ω)` (by [`Self::sample`] and
    /// kept with probability `n·ω` over its bound on the region; the first draw uses `u`, the
    /// retries and acceptance tests a generator seeded by `u`), and the estimate is
    /// `irradiance_at(n) · V(ω)`: exact wherever the region is wholly seen or hidden. If
    /// [`MAX_DRAWS`] draws are all rejected (the region is almost all behind the tangent plane), a
    /// fresh power-drawn direction weighted by its cosine stands in, so the estimate stays
    /// unbiased.
    pub fn estimate(&self, n: DVec3, u: [f32; 2], visible: &mut dyn FnMut(DVec3) -> bool) -> [f64; 3] {
        // The largest n·ω over the region's cone: the acceptance is n·ω over it, and nothing
        // is drawn for a region wholly behind the tangent plane.
        let (ca, sa) = self.cone;
        let cn = n.dot(self.dir).clamp(-1.0, 1.0);
        let sn = (1.0 - cn * cn).max(0.0).sqrt();
        // cos(max(0, angle(n, dir) − half-angle)).
        let c_max = if cn >= ca { 1.0 } else { cn * ca + sn * sa };
        if c_max <= 0.0 {
            return [0.0; 3];
        }
        let mut state = ((u[0].to_bits() as u64) << 32) | u[1].to_bits() as u64;
        let mut next = || {
            state = mix(state);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut uu = u;
        for _ in 0..MAX_DRAWS {
            let (d, _) = self.sample(uu);
            let c = n.dot(d);
            if c > 0.0 && next() * c_max < c {
                return if visible(d) { self.irradiance_at(n) } else { [0.0; 3] };
            }
            uu = [next() as f32, next() as f32].map(|x| x.min(1.0 - f32::EPSILON));
        }
        self.estimate_plain(n, uu, visible)
    }

    /// A direction over the region, drawn in proportion to its removed power (a texel by its
    /// luminance power, then uniformly in solid angle inside it), with the estimator's weight
    /// per channel: `∫ ΔL(ω) f(ω) dω ≈ weight · f(ω)`. `u` ∈ [0, 1)².
    pub fn sample(&self, u: [f32; 2]) -> (DVec3, [f64; 3]) {
        let Some(&total) = self.cdf.last() else { return (self.dir, self.irradiance) };
        let x = u[0] as f64 * total;
        // A guide table (the cutpoint method) starts a short linear search near the answer.
        let m = self.guide.len();
        let g = ((u[0] as f64 * m as f64) as usize).min(m.saturating_sub(1));
        let mut i = self.guide.get(g).map_or(0, |&i| i as usize);
        while i + 1 < self.cdf.len() && self.cdf[i] <= x {
            i += 1;
        }
        let (tx, cdf) = (self.texels[i], self.cdf[i]);
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let p = (cdf - prev) / total;
        // Reuse the first dimension inside the chosen texel (stratification carries over).
        let u0 = if cdf > prev { ((x - prev) / (cdf - prev)).clamp(0.0, 1.0) } else { 0.5 };
        let (w, _) = self.size;
        let phi = 2.0 * PI * (tx.s as f64 + u0) / w as f64;
        let (c0, c1) = tx.z;
        let z = c0 + (c1 - c0) * u[1] as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sp, cp) = phi.sin_cos();
        let d = (self.world_from_light * DVec3::new(r * cp, r * sp, z)).normalize_or_zero();
        let weight = if p > 0.0 { tx.power.map(|v| v / p) } else { [0.0; 3] };
        (d, weight)
    }
}

fn lum(c: Rgb) -> f64 {
    (c.x as f64 + c.y as f64 + c.z as f64) / 3.0
}

/// Light-space direction of texel `(s, t)`'s centre.
fn texel_dir(s: usize, t: usize, w: usize, h: usize) -> DVec3 {
    let theta = PI * (t as f64 + 0.5) / h as f64;
    let phi = 2.0 * PI * (s as f64 + 0.5) / w as f64;
    DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// Splits the bright regions `rule` allows off `il`'s map.
pub fn split(il: &InfiniteLight, rule: SplitRule) -> (EnvSource, Vec<BrightLight>) {
    split_map(&il.map, il.world_from_light, rule)
}

/// [`split`] for a lat-long map seen through `world_from_light`.
pub fn split_map(map: &RgbMap, world_from_light: Mat3, rule: SplitRule) -> (EnvSource, Vec<BrightLight>) {
    let mut map = map.clone();
    let (w, h) = (map.width, map.height);
    let mut lights = Vec::new();
    if w * h < 2 || map.texels.len() < w * h {
        return (EnvSource { map, world_from_light }, lights);
    }
    let dw: Vec<f64> = (0..h)
        .map(|t| {
            let (t0, t1) = (PI * t as f64 / h as f64, PI * (t + 1) as f64 / h as f64);
            (t0.cos() - t1.cos()) * 2.0 * PI / w as f64
        })
        .collect();
    let total: f64 = (0..w * h).map(|i| lum(map.texels[i]) * dw[i / w]).sum();
    let mean = total / (4.0 * PI);
    let m = world_from_light.as_dmat3();
    let mut taken = vec![false; w * h];
    for _ in 0..rule.max_lights {
        let Some(peak) =
            (0..w * h).filter(|&i| !taken[i]).max_by(|&a, &b| lum(map.texels[a]).total_cmp(&lum(map.texels[b])))
        else {
            break;
        };
        let lp = lum(map.texels[peak]);
        if !(lp >= rule.peak_ratio * mean) || !(mean > 0.0) {
            break;
        }
        let centre = texel_dir(peak % w, peak / w, w, h);
        let cos_max = rule.max_radius.cos();
        let mut region = vec![peak];
        let mut in_region = vec![false; w * h];
        in_region[peak] = true;
        let mut k = 0;
        let mut border: Vec<usize> = Vec::new();
        while k < region.len() {
            let i = region[k];
            k += 1;
            let (s, t) = (i % w, i / w);
            let mut nb = vec![t * w + (s + 1) % w, t * w + (s + w - 1) % w];
            if t > 0 {
                nb.push((t - 1) * w + s);
            }
            if t + 1 < h {
                nb.push((t + 1) * w + s);
            }
            for j in nb {
                if in_region[j] {
                    continue;
                }
                let inside =
                    !taken[j] && lum(map.texels[j]) >= 0.1 * lp && texel_dir(j % w, j / w, w, h).dot(centre) >= cos_max;
                if inside {
                    in_region[j] = true;
                    region.push(j);
                } else if !border.contains(&j) {
                    border.push(j);
                }
            }
        }
        let mut bg = [0.0f64; 3];
        for &j in &border {
            for (b, v) in bg.iter_mut().zip(map.texels[j].to_array()) {
                *b += v as f64 / border.len().max(1) as f64;
            }
        }
        let (mut e, mut d) = ([0.0f64; 3], DVec3::ZERO);
        let (mut texels, mut cdf) = (Vec::new(), Vec::new());
        region.sort_unstable();
        for &i in &region {
            let c = map.texels[i].to_array();
            let mut removed = 0.0;
            let mut power = [0.0; 3];
            for ch in 0..3 {
                let x = (c[ch] as f64 - bg[ch]).max(0.0) * dw[i / w];
                e[ch] += x;
                power[ch] = x;
                removed += x / 3.0;
            }
            if removed > 0.0 {
                cdf.push(cdf.last().copied().unwrap_or(0.0) + removed);
                let t = i / w;
                let z = ((PI * t as f64 / h as f64).cos(), (PI * (t + 1) as f64 / h as f64).cos());
                texels.push(RegionTexel { s: (i % w) as u32, t: t as u32, power, z });
            }
            d += texel_dir(i % w, i / w, w, h) * removed;
            map.texels[i] = Rgb::new(
                (c[0] as f64).min(bg[0]) as f32,
                (c[1] as f64).min(bg[1]) as f32,
                (c[2] as f64).min(bg[2]) as f32,
            );
            taken[i] = true;
        }
        let dir = (m * d).normalize_or_zero();
        if dir != DVec3::ZERO && e.iter().any(|v| *v > 0.0) {
            let irr = irradiance_table(&texels, (w, h), m);
            // The cone: the farthest texel centre from `dir`, plus half a texel's diagonal.
            let pad = 0.5 * ((PI / h as f64).powi(2) + (2.0 * PI / w as f64).powi(2)).sqrt();
            let far = texels
                .iter()
                .map(|tx| {
                    // The light's transform may scale (a scaled scene): directions are normalised.
                    let d = (m * texel_dir(tx.s as usize, tx.t as usize, w, h)).normalize_or_zero();
                    d.dot(dir).clamp(-1.0, 1.0).acos()
                })
                .fold(0.0, f64::max);
            let half = (far + pad).min(PI);
            let cone = (half.cos(), half.sin());
            let total = cdf.last().copied().unwrap_or(0.0);
            let guide = (0..cdf.len())
                .map(|j| cdf.partition_point(|&c| c <= total * j as f64 / cdf.len() as f64).min(cdf.len() - 1) as u32)
                .collect();
            lights.push(BrightLight {
                dir,
                irradiance: e,
                texels,
                cdf,
                guide,
                size: (w, h),
                world_from_light: m,
                cone,
                irr,
            });
        }
    }
    (EnvSource { map, world_from_light }, lights)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn power(map: &RgbMap) -> f64 {
        let (w, h) = (map.width, map.height);
        (0..w * h)
            .map(|i| {
                let t = i / w;
                let (t0, t1) = (PI * t as f64 / h as f64, PI * (t + 1) as f64 / h as f64);
                lum(map.texels[i]) * (t0.cos() - t1.cos()) * 2.0 * PI / w as f64
            })
            .sum()
    }

    /// A `w × h` map of radiance `bg` with the texels `(s, t)` in `ss × ts` set by `f(s, t)`.
    fn patch_map(
        (w, h): (usize, usize),
        bg: f32,
        (ss, ts): (std::ops::Range<usize>, std::ops::Range<usize>),
        f: impl Fn(usize, usize) -> Rgb,
    ) -> RgbMap {
        let mut map = RgbMap { width: w, height: h, texels: vec![Rgb::splat(bg); w * h] };
        for t in ts {
            for s in ss.clone() {
                map.texels[t * w + s] = f(s, t);
            }
        }
        map
    }

    #[test]
    fn split_conserves_power_and_finds_the_spot() {
        let (w, h) = (64, 32);
        // A 3×3 spot of radiance 100 around texel (10, 8).
        let map = patch_map((w, h), 0.5, (9..12, 7..10), |_, _| Rgb::new(100.0, 80.0, 60.0));
        let (src, lights) = split_map(&map, Mat3::IDENTITY, SplitRule::new(4));
        assert_eq!(lights.len(), 1, "{lights:?}");
        let e: f64 = lights[0].irradiance.iter().sum::<f64>() / 3.0;
        assert!((power(&src.map) + e - power(&map)).abs() < 1e-9 * power(&map));
        assert!(src.map.texels.iter().all(|c| *c == Rgb::splat(0.5)));
        // The power centroid of the spot: within a fraction of a texel (0.1 rad) of its centre.
        assert!(lights[0].dir.dot(texel_dir(10, 8, w, h)) > 0.03f64.cos(), "{}", lights[0].dir);
        // A constant map has nothing to split.
        let flat = RgbMap { width: w, height: h, texels: vec![Rgb::splat(2.0); w * h] };
        assert!(split_map(&flat, Mat3::IDENTITY, SplitRule::new(4)).1.is_empty());
    }

    #[test]
    fn sampled_directions_integrate_the_removed_light() {
        // A wide, uneven bright patch: the sampled estimate of ∫ ΔL max(0, n·ω) dω matches
        // the sum over its texels (each integrated finely), for normals facing it and grazing.
        let (w, h) = (64, 32);
        let map = patch_map((w, h), 0.2, (20..36, 4..14), |s, t| {
            let v = 5.0 + (s as f32 - 20.0) * 1.5 + (t as f32 - 4.0);
            Rgb::new(v, 0.5 * v, 0.1 * v + 0.3)
        });
        let rot = Mat3::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        let (_, lights) = split_map(&map, rot, SplitRule { max_lights: 1, peak_ratio: 2.0, max_radius: 1.5 });
        assert_eq!(lights.len(), 1);
        let b = &lights[0];
        let m = rot.as_dmat3();
        for n in [b.dir, (b.dir + DVec3::new(0.7, 0.3, -0.2)).normalize(), DVec3::new(0.0, 1.0, 0.0)] {
            // Reference: every region texel at 16×16 sub-points, uniformly in solid angle.
            let mut want = [0.0; 3];
            for tx in &b.texels {
                for a in 0..16 {
                    for c in 0..16 {
                        let phi = 2.0 * PI * (tx.s as f64 + (a as f64 + 0.5) / 16.0) / w as f64;
                        let (c0, c1) = ((PI * tx.t as f64 / h as f64).cos(), (PI * (tx.t + 1) as f64 / h as f64).cos());
                        let z = c0 + (c1 - c0) * (c as f64 + 0.5) / 16.0;
                        let r = (1.0 - z * z).sqrt();
                        let d = m * DVec3::new(r * phi.cos(), r * phi.sin(), z);
                        for (o, p) in want.iter_mut().zip(tx.power) {
                            *o += p * n.dot(d).max(0.0) / 256.0;
                        }
                    }
                }
            }
            // Estimate: a stratified grid of samples, fine in the first dimension (which picks
            // the texel, then the azimuth inside it).
            let mut got = [0.0; 3];
            let (ki, kj) = (8192, 8);
            for i in 0..ki {
                for j in 0..kj {
                    let u = [(i as f32 + 0.5) / ki as f32, (j as f32 + 0.5) / kj as f32];
                    let (d, wt) = b.sample(u);
                    assert!((d.length() - 1.0).abs() < 1e-9);
                    for ch in 0..3 {
                        got[ch] += wt[ch] * n.dot(d).max(0.0) / (ki * kj) as f64;
                    }
                }
            }
            for ch in 0..3 {
                assert!(
                    (got[ch] - want[ch]).abs() <= 2e-3 * want[ch].max(1e-3),
                    "{n} ch {ch}: {} vs {}",
                    got[ch],
                    want[ch]
                );
            }
        }
        // Every sampled direction lies inside the region's texels: the power-weighted mean
        // weight is the removed power.
        let mut mean = [0.0; 3];
        for i in 0..64 {
            let (_, wt) = b.sample([(i as f32 + 0.5) / 64.0, 0.5]);
            for ch in 0..3 {
                mean[ch] += wt[ch] / 64.0;
            }
        }
        for ch in 0..3 {
            assert!((mean[ch] - b.irradiance[ch]).abs() < 0.05 * b.irradiance[ch], "{mean:?} vs {:?}", b.irradiance);
        }
    }

    #[test]
    fn cosine_sampling_and_the_irradiance_table_agree_with_quadrature() {
        let (w, h) = (128, 64);
        let map = patch_map((w, h), 0.1, (30..70, 8..30), |s, t| {
            let v = 4.0 + ((s as f32 - 30.0) * 0.2).sin() * 2.0 + (t as f32 - 8.0) * 0.3;
            Rgb::new(v, 0.7 * v, 0.4 * v)
        });
        let rot = Mat3::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        let (_, lights) = split_map(&map, rot, SplitRule { max_lights: 1, peak_ratio: 2.0, max_radius: 1.5 });
        let b = &lights[0];
        let m = rot.as_dmat3();
        // Fine quadrature of the region: ∫ ΔL max(0, n·ω) g(ω) dω, 8×8 points per texel.
        let quad = |n: DVec3, g: &dyn Fn(DVec3) -> f64| {
            let mut out = [0.0; 3];
            for tx in &b.texels {
                for a in 0..8 {
                    for c in 0..8 {
                        let phi = 2.0 * PI * (tx.s as f64 + (a as f64 + 0.5) / 8.0) / w as f64;
                        let z = tx.z.0 + (tx.z.1 - tx.z.0) * (c as f64 + 0.5) / 8.0;
                        let r = (1.0 - z * z).sqrt();
                        let d = m * DVec3::new(r * phi.cos(), r * phi.sin(), z);
                        for (o, p) in out.iter_mut().zip(tx.power) {
                            *o += p * n.dot(d).max(0.0) * g(d) / 64.0;
                        }
                    }
                }
            }
            out
        };
        let axis = DVec3::new(0.3, 0.8, -0.5).normalize();
        for n in [b.dir, (b.dir + DVec3::new(0.8, -0.5, 0.1)).normalize(), DVec3::new(0.0, 1.0, 0.0), DVec3::X] {
            // Within 1 % of the expected value plus a fraction of the region's power.
            let close = |got: [f64; 3], want: [f64; 3], of_power: f64| {
                for c in 0..3 {
                    let tol = 0.01 * want[c] + of_power * b.irradiance[c];
                    assert!((got[c] - want[c]).abs() <= tol, "{n} ch {c}: {} vs {}", got[c], want[c]);
                }
            };
            close(b.irradiance_at(n), quad(n, &|_| 1.0), 1e-3);
            // The estimate under a half-space visibility V(ω) = [ω·axis > 0], averaged over a
            // stratified grid, matches the quadrature of ∫ ΔL V max(0, n·ω) dω.
            let v = |d: DVec3| (d.dot(axis) > 0.0) as u32 as f64;
            let expect = quad(n, &v);
            let mut mean = [0.0; 3];
            let k = 256;
            for i in 0..k {
                for j in 0..k {
                    let u = [(i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32];
                    let e = b.estimate(n, u, &mut |d| {
                        assert!(n.dot(d) > 0.0);
                        d.dot(axis) > 0.0
                    });
                    for (o, x) in mean.iter_mut().zip(e) {
                        *o += x / (k * k) as f64;
                    }
                }
            }
            close(mean, expect, 2e-3);
        }
        // A normal facing away from the whole region draws nothing.
        assert_eq!(b.estimate(-b.dir, [0.5, 0.5], &mut |_| panic!("nothing to test")), [0.0; 3]);
    }

    #[test]
    fn a_scaled_light_transform_samples_the_same_directions() {
        // A scene scaled by 1e4 scales the infinite light's transform too: directions must be
        // normalised everywhere (the cone once was not, which bounded n·ω wrongly).
        let (w, h) = (64, 32);
        let map = patch_map((w, h), 0.2, (10..30, 6..16), |s, _| Rgb::new(6.0 + s as f32 * 0.1, 5.0, 4.0));
        let rot = Mat3::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        let rule = SplitRule { max_lights: 1, peak_ratio: 2.0, max_radius: 1.3 };
        let (_, a) = split_map(&map, rot, rule);
        let (_, b) = split_map(&map, rot * Mat3::from_diagonal(Vec3::splat(1e4)), rule);
        let (a, b) = (&a[0], &b[0]);
        assert!((a.cone.0 - b.cone.0).abs() < 1e-9, "{:?} vs {:?}", a.cone, b.cone);
        let n = DVec3::new(0.2, 0.9, -0.3).normalize();
        let (mut sa, mut sb) = (0.0, 0.0);
        for i in 0..64 {
            for j in 0..8 {
                let u = [(i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 8.0];
                let half = |d: DVec3| d.x > 0.0;
                sa += a.estimate(n, u, &mut |d| half(d))[0];
                sb += b.estimate(n, u, &mut |d| half(d))[0];
            }
        }
        assert!((sa - sb).abs() <= 1e-6 * sa.abs(), "{sa} vs {sb}");
    }
}
