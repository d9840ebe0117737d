//! The ground plane as a reflector (`"bool groundbounce"`, beyond the thesis, whose ground box
//! does not reflect): the plane `shexp` cuts the environment with is lit by the environment
//! and, as a Lambertian surface of albedo `ρ_g`, sends `L_g = ρ_g/π · E_g` back up. A receiver
//! above it sees that radiance wherever the cut removed the environment, through the same SH
//! visibility as the sky: `E = L_g · LH_below(N) · V`, with `LH_below(N)` the projection of
//! `max(0, N·ω)` over the directions below the plane's horizon ([`BelowTable`]), clamped to
//! `[0, L_g · LH_below(N) · 1]`.
//!
//! `E_g` is the plane's shadowed irradiance (the direct term, with shadow rays to the split-off
//! bright regions) averaged over the points the receiver mostly sees
//! ([`GroundBounce::seen_points`]); the unshadowed `E_g` where there are none. `ρ_g` is the
//! Lambertian albedo averaged over the plane's triangle centroids, weighted by area (at most
//! [`ALBEDO_POINTS`] of them). Only the direct light bounces: the plane's light is not fed
//! into the spheres' pass 1 (that would be a second bounce).

use super::super::bright::BrightLight;
use super::super::lighting::{cut_hemisphere, frame, EnvLighting, NZ};
use super::super::split_lambertian;
use crate::shexp::sphereset::GroundPlane;
use glam::{DMat3, DVec3, Vec3};
use penumbra_core::accel::Hit;
use penumbra_core::geometry::Ray;
use penumbra_core::scene::Scene;
use penumbra_core::sh::{quadrature::gauss_legendre, ShOrder, ShRotation, SQRT_4PI};
use penumbra_core::Rgb;

/// Triangles whose centroid albedo is averaged (evenly strided beyond this).
pub const ALBEDO_POINTS: usize = 4096;

/// How far (in receiver heights) the four outer seen points lie from the central one. One
/// point alone follows the hard shadows of the split-off lamps too closely: on
/// `env/objects-studio` (objects matte) and `env/objects-sky-sun` at 64², 4 spp, the RMS
/// difference of the objects' reflected light from `path`'s (maxdepth 2 − 1, 1024 spp) falls
/// from 94 % to 79 % and from 98 % to 85 % of its mean (spread 1: 86 % on studio).
pub const SPREAD: f64 = 2.0;

/// `LH_below(N) = ∫_{N·ω>0, g·ω<0} (N·ω) y(ω) dω`. In the plane's frame `G` (`e₃ = g`) it
/// depends on the angle `β` between `N` and `g` and on `N`'s azimuth `φ` about `g`: tabulated
/// over `β` for `φ = 0` (exact arcs of each ring, `lighting::cut_hemisphere`), turned about `e₃` by
/// `φ` (each `(m, −m)` pair by the angle `mφ`), then to world by the fixed rotation of `G`.
pub struct BelowTable {
    order: ShOrder,
    /// `BELOW_ENTRIES × n²`, `β_i = i π/(BELOW_ENTRIES − 1)`.
    table: Vec<f64>,
    frame: DMat3,
    to_world: ShRotation,
}

/// Entries of [`BelowTable`] over `β ∈ [0, π]`.
const BELOW_ENTRIES: usize = 257;

impl BelowTable {
    pub fn new(order: ShOrder, g: DVec3) -> Result<BelowTable, penumbra_core::sh::ShError> {
        let (zs, zw) = gauss_legendre(NZ);
        let mut table = Vec::with_capacity(BELOW_ENTRIES * order.coeffs());
        for i in 0..BELOW_ENTRIES {
            let beta = std::f64::consts::PI * i as f64 / (BELOW_ENTRIES - 1) as f64;
            let n = DVec3::new(beta.sin(), 0.0, beta.cos());
            table.extend(cut_hemisphere(order, n, -DVec3::Z, (&zs, &zw)));
        }
        let e3 = g.normalize();
        let (e1, e2) = frame(e3);
        let frame = DMat3::from_cols(e1, e2, e3);
        Ok(BelowTable { order, table, frame, to_world: ShRotation::new(order, frame)? })
    }

    /// `LH_below(n)` (unit `n`, world) into `out[..n²]`, with `tmp` (`n²`) as scratch.
    pub fn eval(&self, n: DVec3, tmp: &mut [f64], out: &mut [f64]) {
        let k = self.order.coeffs();
        let local = self.frame.transpose() * n;
        let beta = local.z.clamp(-1.0, 1.0).acos();
        let x = beta / std::f64::consts::PI * (BELOW_ENTRIES - 1) as f64;
        let i = (x.floor() as usize).min(BELOW_ENTRIES - 2);
        let f = x - i as f64;
        let (a, b) = (&self.table[i * k..(i + 1) * k], &self.table[(i + 1) * k..(i + 2) * k]);
        for ((t, a), b) in tmp[..k].iter_mut().zip(a).zip(b) {
            *t = a + f * (b - a);
        }
        // Turn about e₃ by φ: f(ψ − φ) has a′ = a cos mφ − b sin mφ, b′ = a sin mφ + b cos mφ
        // for the coefficients a of cos mψ (m > 0) and b of sin mψ (m < 0).
        let phi = local.y.atan2(local.x);
        for l in 1..self.order.n() {
            for m in 1..=l {
                let (sin, cos) = (m as f64 * phi).sin_cos();
                let (ip, im) = (l * (l + 1) + m, l * (l + 1) - m);
                let (a, b) = (tmp[ip], tmp[im]);
                tmp[ip] = a * cos - b * sin;
                tmp[im] = a * sin + b * cos;
            }
        }
        let _ = self.to_world.apply(&tmp[..k], &mut out[..k]);
    }
}

pub struct GroundBounce {
    /// `L_g` per channel (unshadowed).
    pub radiance: [f64; 3],
    /// `ρ_g` per channel.
    pub albedo: [f64; 3],
    below: BelowTable,
    pub plane: GroundPlane,
}

/// The area-weighted mean Lambertian albedo of `object`'s triangle centroids.
fn mean_albedo(scene: &Scene, object: usize) -> [f64; 3] {
    let Some(mesh) = scene.meshes.get(object) else { return [0.0; 3] };
    let count = mesh.triangle_count();
    let stride = count.div_ceil(ALBEDO_POINTS).max(1);
    let (mut sum, mut area) = ([0.0f64; 3], 0.0f64);
    for tri in (0..count).step_by(stride) {
        let a = mesh.area(tri) as f64;
        let [p0, p1, p2] = mesh.vertices(tri);
        let c = (p0 + p1 + p2) / 3.0;
        let n = mesh.winding_normal(tri);
        if !(a > 0.0) || n == Vec3::ZERO || !c.is_finite() {
            continue;
        }
        let ray = Ray::new(c + n, -n, 2.0);
        let hit = Hit { t: 1.0, mesh: object as u32, tri: tri as u32, b: [1.0 / 3.0; 3] };
        let si = scene.interaction(&ray, &hit);
        let Some(bsdf) = scene.bsdf(&si) else { continue };
        let (kd, _): (Rgb, _) = split_lambertian(&bsdf);
        for (s, k) in sum.iter_mut().zip(kd.to_array()) {
            *s += a * k as f64;
        }
        area += a;
    }
    if area > 0.0 {
        sum.map(|s| s / area)
    } else {
        [0.0; 3]
    }
}

impl GroundBounce {
    /// `None` when the plane reflects nothing (albedo 0, or an unlit plane).
    pub fn build(
        scene: &Scene,
        plane: GroundPlane,
        env: &EnvLighting,
        bright: &[BrightLight],
        order: ShOrder,
    ) -> Option<GroundBounce> {
        let albedo = mean_albedo(scene, plane.object);
        let g = plane.normal;
        let k = order.coeffs();
        let (mut lh, mut tmp) = (vec![[0.0; 3]; k], vec![0.0; k]);
        env.lh(g, &mut lh, &mut tmp);
        let mut e = lh[0].map(|v| v * SQRT_4PI);
        for b in bright {
            let c = g.dot(b.dir).max(0.0);
            for (ec, bc) in e.iter_mut().zip(b.irradiance) {
                *ec += bc * c;
            }
        }
        let radiance = [0, 1, 2].map(|c| (albedo[c] * e[c]).max(0.0) * std::f64::consts::FRAC_1_PI);
        if !radiance.iter().any(|v| *v > 0.0 && v.is_finite()) {
            return None;
        }
        let below = BelowTable::new(order, g).ok()?;
        Some(GroundBounce { radiance, albedo, below, plane })
    }

    /// The ground points whose shadowed irradiance stands for the plane's radiance as a
    /// receiver at `p` (unit normal `n`) sees it: the point it mostly sees, along the centroid
    /// direction of `max(0, n·ω)` over the directions below the horizon (band 1 of
    /// `LH_below(n)`), and four points [`SPREAD`]`·h` from it across the plane (`h` the
    /// receiver's height). `None`: the receiver is not above the plane or sees no ground.
    pub fn seen_points(&self, p: DVec3, n: DVec3, lh: &mut [f64], tmp: &mut [f64]) -> Option<[DVec3; 5]> {
        let g = self.plane.normal;
        let h = (p - self.plane.point).dot(g);
        if !(h > 0.0) || lh.len() < 4 {
            return None;
        }
        self.below.eval(n, tmp, lh);
        // Band 1 is (y, z, x) · √(3/4π).
        let d = DVec3::new(lh[3], lh[1], lh[2]);
        let down = -d.dot(g);
        if !(down > 1e-6 * d.length()) {
            return None;
        }
        let q = p + d * (h / down);
        let t = if g.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let u = (t - g * g.dot(t)).normalize() * (SPREAD * h);
        let v = g.cross(u);
        let points = [q, q + u, q - u, q + v, q - v];
        points.iter().all(|x| x.is_finite()).then_some(points)
    }

    /// The irradiance per channel at `p` (unit normal `n`) from the plane sending `radiance`,
    /// through the SH visibility `v`; `lh` and `tmp` are scratch of `n²` values.
    pub fn irradiance(
        &self,
        (p, n): (DVec3, DVec3),
        radiance: [f64; 3],
        v: &[f64],
        lh: &mut [f64],
        tmp: &mut [f64],
    ) -> [f64; 3] {
        if (p - self.plane.point).dot(self.plane.normal) <= 0.0 {
            return [0.0; 3];
        }
        self.below.eval(n, tmp, lh);
        let seen: f64 = lh.iter().zip(v).map(|(l, vi)| l * vi).sum();
        let open = lh[0] * SQRT_4PI;
        let f = if seen.is_finite() { seen.clamp(0.0, open.max(0.0)) } else { 0.0 };
        radiance.map(|l| l * f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn below_table_matches_the_direct_quadrature() {
        let order = ShOrder::new(4).unwrap();
        let g = DVec3::new(0.2, 0.9, -0.3).normalize();
        let table = BelowTable::new(order, g).unwrap();
        let fine = gauss_legendre(400);
        let coarse = gauss_legendre(NZ);
        let (mut tmp, mut out) = (vec![0.0; 16], vec![0.0; 16]);
        let (mut worst, mut worst_direct): (f64, f64) = (0.0, 0.0);
        for i in 0..40 {
            let t = i as f64 * 0.37;
            let n = DVec3::new(t.sin() * (2.1 * t).cos(), (1.3 * t).cos(), t.cos() * (0.7 * t).sin()).normalize();
            table.eval(n, &mut tmp, &mut out);
            let want = cut_hemisphere(order, n, -g, (&fine.0, &fine.1));
            let direct = cut_hemisphere(order, n, -g, (&coarse.0, &coarse.1));
            for ((a, b), c) in out.iter().zip(&want).zip(&direct) {
                worst = worst.max((a - b).abs());
                worst_direct = worst_direct.max((c - b).abs());
            }
        }
        eprintln!("table {worst:.2e}, direct quadrature {worst_direct:.2e} from a 400-node one");
        // The values are up to about 1 (π/2 for N = −g): the table's interpolation error.
        assert!(worst < 1e-4 && worst_direct < 5e-6, "{worst} {worst_direct}");
    }
}
