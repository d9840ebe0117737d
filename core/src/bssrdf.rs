//! pbrt-v3's separable BSSRDFs (`core/bssrdf.cpp`, `materials/disney.cpp`), used by `path`
//! for `subsurface`, `kdsubsurface` and `disney` with a `scatterdistance`:
//!
//! * the photon-beam-diffusion profile table (Habel, Christensen & Jarosz 2013: the multiple
//!   scattering of a classical dipole integrated along the refracted beam, plus single
//!   scattering, 100 albedos × 64 optical radii, spline-interpolated; [`BssrdfTable`]) behind
//!   `subsurface`/`kdsubsurface` ([`Profile::Tabulated`]), with `kdsubsurface`'s inversion of
//!   the effective albedo ([`subsurface_from_diffuse`]);
//! * Burley's normalised diffusion profile ([`Profile::Disney`], Christensen & Burley 2015);
//! * the separable form `S = (1 − F_r(cos θ_o)) S_p(|p_o − p_i|) S_w(ω_i)` with pbrt-v3's
//!   sampling of the incident point: a radius from the profile of a random colour channel,
//!   projected along one of the three frame axes (½ normal, ¼ each tangent), and a probe
//!   segment through the sphere of radius `r_max` ([`SeparableBssrdf::probe`]; the integrator
//!   intersects it with the scene and keeps the hits on the same material), and its
//!   multiple-importance density over the three axes and channels ([`SeparableBssrdf::pdf_sp`]).
//!
//! As in pbrt-v3, `path` never evaluates the full `S`: the entry term `1 − F_r` is the
//! transmission lobe it sampled into the surface, `S_p / pdf` is the probe's weight, and the
//! exit term `S_w` is the diffuse lobe [`Bxdf::SubsurfaceExit`](crate::bxdf::Bxdf) at the
//! incident point.

use crate::bxdf::fr_dielectric;
use crate::interpolation::{catmull_rom_weights, integrate_catmull_rom, invert_catmull_rom, sample_catmull_rom_2d};
use crate::spectrum::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// First moment of the dielectric Fresnel reflectance (pbrt-v3's polynomial fits).
pub fn fresnel_moment1(eta: f32) -> f32 {
    let (e2, e3, e4, e5) = (eta * eta, eta.powi(3), eta.powi(4), eta.powi(5));
    if eta < 1.0 {
        0.45966 - 1.73965 * eta + 3.37668 * e2 - 3.904945 * e3 + 2.49277 * e4 - 0.68441 * e5
    } else {
        -4.61686 + 11.1136 * eta - 10.4646 * e2 + 5.11455 * e3 - 1.27198 * e4 + 0.12746 * e5
    }
}

/// Second moment of the dielectric Fresnel reflectance (pbrt-v3's polynomial fits).
pub fn fresnel_moment2(eta: f32) -> f32 {
    let (e2, e3, e4, e5) = (eta * eta, eta.powi(3), eta.powi(4), eta.powi(5));
    if eta < 1.0 {
        0.27614 - 0.87350 * eta + 1.12077 * e2 - 0.65095 * e3 + 0.07883 * e4 + 0.04860 * e5
    } else {
        let (r, r2, r3) = (1.0 / eta, 1.0 / e2, 1.0 / e3);
        -547.033 + 45.3087 * r3 - 218.725 * r2 + 458.843 * r + 404.557 * eta - 189.519 * e2 + 54.9327 * e3
            - 9.00603 * e4
            + 0.63942 * e5
    }
}

/// The directional exit term `S_w(cos θ)` of a separable BSSRDF of relative index `eta`:
/// `(1 − F_r) / (c π)`, normalised by `c = 1 − 2 · FresnelMoment1(1/η)`.
pub fn sw(cos_theta: f32, eta: f32) -> f32 {
    let c = 1.0 - 2.0 * fresnel_moment1(1.0 / eta);
    (1.0 - fr_dielectric(cos_theta, 1.0, eta)) / (c * PI)
}

/// Henyey–Greenstein phase function (pbrt-v3's `PhaseHG`).
fn phase_hg(cos_theta: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g + 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * denom * denom.sqrt())
}

/// Multiple scattering of photon beam diffusion at radius `r` (pbrt-v3's `BeamDiffusionMS`),
/// 100 real-source depths by stratified exponential sampling.
pub fn beam_diffusion_ms(sigma_s: f64, sigma_a: f64, g: f64, eta: f64, r: f64) -> f64 {
    const N: usize = 100;
    let sigmap_s = sigma_s * (1.0 - g);
    let sigmap_t = sigma_a + sigmap_s;
    let rhop = sigmap_s / sigmap_t;
    let d_g = (2.0 * sigma_a + sigmap_s) / (3.0 * sigmap_t * sigmap_t);
    let sigma_tr = (sigma_a / d_g).sqrt();
    let (fm1, fm2) = (fresnel_moment1(eta as f32) as f64, fresnel_moment2(eta as f32) as f64);
    let ze = -2.0 * d_g * (1.0 + 3.0 * fm2) / (1.0 - 2.0 * fm1);
    let (c_phi, c_e) = (0.25 * (1.0 - 2.0 * fm1), 0.5 * (1.0 - 3.0 * fm2));
    let inv4pi = 1.0 / (4.0 * std::f64::consts::PI);
    let mut ed = 0.0;
    for i in 0..N {
        let zr = -(1.0 - (i as f64 + 0.5) / N as f64).ln() / sigmap_t;
        let zv = -zr + 2.0 * ze;
        let (dr, dv) = ((r * r + zr * zr).sqrt(), (r * r + zv * zv).sqrt());
        let phi_d = inv4pi / d_g * ((-sigma_tr * dr).exp() / dr - (-sigma_tr * dv).exp() / dv);
        let ed_n = inv4pi
            * (zr * (1.0 + sigma_tr * dr) * (-sigma_tr * dr).exp() / (dr * dr * dr)
                - zv * (1.0 + sigma_tr * dv) * (-sigma_tr * dv).exp() / (dv * dv * dv));
        let e = phi_d * c_phi + ed_n * c_e;
        let kappa = 1.0 - (-2.0 * sigmap_t * (dr + zr)).exp();
        ed += kappa * rhop * rhop * e;
    }
    ed / N as f64
}

/// Single scattering of photon beam diffusion at radius `r` (pbrt-v3's `BeamDiffusionSS`).
pub fn beam_diffusion_ss(sigma_s: f64, sigma_a: f64, g: f64, eta: f64, r: f64) -> f64 {
    const N: usize = 100;
    let sigma_t = sigma_a + sigma_s;
    let rho = sigma_s / sigma_t;
    let t_crit = r * (eta * eta - 1.0).max(0.0).sqrt();
    let mut ess = 0.0;
    for i in 0..N {
        let ti = t_crit - (1.0 - (i as f64 + 0.5) / N as f64).ln() / sigma_t;
        let d = (r * r + ti * ti).sqrt();
        let cos_o = ti / d;
        ess += rho * (-sigma_t * (d + t_crit)).exp() / (d * d)
            * phase_hg(cos_o, g)
            * (1.0 - fr_dielectric(-cos_o as f32, 1.0, eta as f32) as f64)
            * cos_o.abs();
    }
    ess / N as f64
}

/// pbrt-v3's `BSSRDFTable`: the radial profile `2π r S_r(r)` of a unit-extinction medium for
/// 100 single-scattering albedos × 64 optical radii, the effective albedo of each and the
/// running integrals for sampling. Built by [`BssrdfTable::beam_diffusion`].
#[derive(Clone, Debug, PartialEq)]
pub struct BssrdfTable {
    pub rho_samples: Vec<f32>,
    pub radius_samples: Vec<f32>,
    pub profile: Vec<f32>,
    pub rho_eff: Vec<f32>,
    pub profile_cdf: Vec<f32>,
}

impl BssrdfTable {
    /// pbrt-v3's `ComputeBeamDiffusionBSSRDF(g, eta)` on its 100 × 64 grid (radii 0, 2.5e-3,
    /// then ×1.2; albedos `(1 − e^{−8i/99}) / (1 − e^{−8})`).
    pub fn beam_diffusion(g: f32, eta: f32) -> BssrdfTable {
        let (n_rho, n_r) = (100usize, 64usize);
        let mut radius_samples = vec![0.0f32; n_r];
        radius_samples[1] = 2.5e-3;
        for i in 2..n_r {
            radius_samples[i] = radius_samples[i - 1] * 1.2;
        }
        let rho_samples: Vec<f32> = (0..n_rho)
            .map(|i| (1.0 - (-8.0 * i as f32 / (n_rho - 1) as f32).exp()) / (1.0 - (-8.0f32).exp()))
            .collect();
        let mut profile = vec![0.0f32; n_rho * n_r];
        let mut profile_cdf = vec![0.0f32; n_rho * n_r];
        let mut rho_eff = vec![0.0f32; n_rho];
        for i in 0..n_rho {
            let rho = rho_samples[i] as f64;
            for j in 0..n_r {
                let r = radius_samples[j] as f64;
                let v = 2.0
                    * std::f64::consts::PI
                    * r
                    * (beam_diffusion_ss(rho, 1.0 - rho, g as f64, eta as f64, r)
                        + beam_diffusion_ms(rho, 1.0 - rho, g as f64, eta as f64, r));
                profile[i * n_r + j] = if v.is_finite() { v as f32 } else { 0.0 };
            }
            rho_eff[i] = integrate_catmull_rom(
                &radius_samples,
                &profile[i * n_r..(i + 1) * n_r],
                &mut profile_cdf[i * n_r..(i + 1) * n_r],
            );
        }
        BssrdfTable { rho_samples, radius_samples, profile, rho_eff, profile_cdf }
    }

    fn eval_profile(&self, rho_index: usize, radius_index: usize) -> f32 {
        self.profile[rho_index * self.radius_samples.len() + radius_index]
    }
}

/// pbrt-v3's `SubsurfaceFromDiffuse`: the scattering and absorption coefficients (in that
/// order) whose effective albedo is `rho_eff` for mean free path `mfp`, per channel.
pub fn subsurface_from_diffuse(t: &BssrdfTable, rho_eff: Rgb, mfp: Rgb) -> (Rgb, Rgb) {
    let (mut s, mut a) = (Rgb::ZERO, Rgb::ZERO);
    for c in 0..3 {
        let rho = invert_catmull_rom(&t.rho_samples, &t.rho_eff, rho_eff[c]);
        s[c] = rho / mfp[c];
        a[c] = (1.0 - rho) / mfp[c];
    }
    (s, a)
}

/// A BSSRDF's radial profile.
#[derive(Clone, Copy, Debug)]
pub enum Profile<'a> {
    /// `subsurface`/`kdsubsurface`: the beam-diffusion table scaled to `sigma_t`.
    Tabulated { table: &'a BssrdfTable, sigma_t: Rgb, rho: Rgb },
    /// `disney`: Burley's profile of albedo `r` and (already ×0.2) scatter distance `d`.
    Disney { r: Rgb, d: Rgb },
}

impl Profile<'_> {
    /// pbrt-v3's `TabulatedBSSRDF` coefficients from absorption and scattering.
    pub fn tabulated(table: &BssrdfTable, sigma_a: Rgb, sigma_s: Rgb) -> Profile<'_> {
        let sigma_t = sigma_a + sigma_s;
        let mut rho = Rgb::ZERO;
        for c in 0..3 {
            rho[c] = if sigma_t[c] != 0.0 { sigma_s[c] / sigma_t[c] } else { 0.0 };
        }
        Profile::Tabulated { table, sigma_t, rho }
    }

    /// `S_r(r)` per channel.
    pub fn sr(&self, r: f32) -> Rgb {
        match *self {
            Profile::Tabulated { table, sigma_t, rho } => {
                let mut out = Rgb::ZERO;
                for c in 0..3 {
                    let r_optical = r * sigma_t[c];
                    let Some(sr) = tabulated_profile(table, rho[c], r_optical).map(|(sr, _)| sr) else { continue };
                    let sr = if r_optical != 0.0 { sr / (2.0 * PI * r_optical) } else { sr };
                    out[c] = sr * sigma_t[c] * sigma_t[c];
                }
                out.max(Rgb::ZERO)
            }
            Profile::Disney { r: albedo, d } => {
                let r = r.max(1e-6);
                let e = |c: usize| ((-r / d[c]).exp() + (-r / (3.0 * d[c])).exp()) / (8.0 * PI * d[c] * r);
                let v = albedo * Rgb::new(e(0), e(1), e(2));
                if v.is_finite() {
                    v
                } else {
                    Rgb::ZERO
                }
            }
        }
    }

    /// A radius sampled from channel `ch`'s profile (`None`: the channel has no extinction).
    pub fn sample_sr(&self, ch: usize, u: f32) -> Option<f32> {
        match *self {
            Profile::Tabulated { table, sigma_t, rho } => {
                if sigma_t[ch] == 0.0 {
                    return None;
                }
                let s = sample_catmull_rom_2d(
                    &table.rho_samples,
                    &table.radius_samples,
                    &table.profile,
                    &table.profile_cdf,
                    rho[ch],
                    u,
                )?;
                Some(s.x / sigma_t[ch])
            }
            Profile::Disney { d, .. } => {
                let r = if u < 0.25 {
                    let u = (u * 4.0).min(crate::bxdf::ONE_MINUS_EPSILON);
                    d[ch] * (1.0 / (1.0 - u)).ln()
                } else {
                    let u = ((u - 0.25) / 0.75).min(crate::bxdf::ONE_MINUS_EPSILON);
                    3.0 * d[ch] * (1.0 / (1.0 - u)).ln()
                };
                Some(r)
            }
        }
    }

    /// Density (per unit area) of [`Self::sample_sr`] for channel `ch` at radius `r`.
    pub fn pdf_sr(&self, ch: usize, r: f32) -> f32 {
        match *self {
            Profile::Tabulated { table, sigma_t, rho } => {
                let r_optical = r * sigma_t[ch];
                let Some((sr, rho_eff)) = tabulated_profile(table, rho[ch], r_optical) else { return 0.0 };
                let sr = if r_optical != 0.0 { sr / (2.0 * PI * r_optical) } else { sr };
                let p = sr * sigma_t[ch] * sigma_t[ch] / rho_eff;
                if p.is_finite() {
                    p.max(0.0)
                } else {
                    0.0
                }
            }
            Profile::Disney { d, .. } => {
                let r = r.max(1e-6);
                let d = d[ch];
                let p = 0.25 * (-r / d).exp() / (2.0 * PI * d * r) + 0.75 * (-r / (3.0 * d)).exp() / (6.0 * PI * d * r);
                if p.is_finite() {
                    p
                } else {
                    0.0
                }
            }
        }
    }
}

/// The table's spline at (albedo `rho`, optical radius `r`) and the interpolated effective
/// albedo (`None` outside the table).
fn tabulated_profile(t: &BssrdfTable, rho: f32, r_optical: f32) -> Option<(f32, f32)> {
    let (ro, rw) = catmull_rom_weights(&t.rho_samples, rho)?;
    let (so, sw) = catmull_rom_weights(&t.radius_samples, r_optical)?;
    let (mut sr, mut rho_eff) = (0.0f32, 0.0f32);
    for (i, wi) in rw.iter().enumerate() {
        if *wi == 0.0 {
            continue;
        }
        let ri = (ro + i as isize) as usize;
        rho_eff += t.rho_eff[ri] * wi;
        for (j, wj) in sw.iter().enumerate() {
            if *wj != 0.0 {
                sr += wi * wj * t.eval_profile(ri, (so + j as isize) as usize);
            }
        }
    }
    Some((sr, rho_eff))
}

/// A separable BSSRDF at the point light enters (pbrt-v3's `SeparableBSSRDF`).
#[derive(Clone, Copy, Debug)]
pub struct SeparableBssrdf<'a> {
    pub p: Vec3,
    /// Shading frame at `p`: normal, tangent, bitangent.
    pub ns: Vec3,
    pub ss: Vec3,
    pub ts: Vec3,
    pub eta: f32,
    /// The material (index in `SceneDescription::materials`) whose surfaces the light may leave.
    pub material: usize,
    pub profile: Profile<'a>,
}

/// A probe segment from [`SeparableBssrdf::probe`]: intersect `from → to`, keep the hits on
/// the BSSRDF's material and pick one of them with `u`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    pub from: Vec3,
    pub to: Vec3,
    pub u: f32,
}

impl SeparableBssrdf<'_> {
    /// pbrt-v3's `Sample_Sp` up to the ray casting: the projection axis and colour channel
    /// from `u1`, the radius and angle from `u2`. `None` when the sampled radius is outside
    /// the profile's support (`r ≥ r_max`, the radius of 0.999 of the profile's mass).
    pub fn probe(&self, u1: f32, u2: Vec2) -> Option<Probe> {
        let (vx, vy, vz, mut u1) = if u1 < 0.5 {
            (self.ss, self.ts, self.ns, u1 * 2.0)
        } else if u1 < 0.75 {
            (self.ts, self.ns, self.ss, (u1 - 0.5) * 4.0)
        } else {
            (self.ns, self.ss, self.ts, (u1 - 0.75) * 4.0)
        };
        let ch = ((u1 * 3.0) as usize).min(2);
        u1 = u1 * 3.0 - ch as f32;
        let r = self.profile.sample_sr(ch, u2.x)?;
        if !(r >= 0.0) {
            return None;
        }
        let phi = 2.0 * PI * u2.y;
        let r_max = self.profile.sample_sr(ch, 0.999)?;
        if !(r < r_max) {
            return None;
        }
        let l = 2.0 * (r_max * r_max - r * r).sqrt();
        let from = self.p + r * (vx * phi.cos() + vy * phi.sin()) - l * vz * 0.5;
        let to = from + l * vz;
        (from.is_finite() && to.is_finite()).then_some(Probe { from, to, u: u1.clamp(0.0, 1.0) })
    }

    /// pbrt-v3's `Pdf_Sp`: the density (per unit area) of a probe hit at `pi` with geometric
    /// normal `ni`, summed over the three axes and channels.
    pub fn pdf_sp(&self, pi: Vec3, ni: Vec3) -> f32 {
        let d = self.p - pi;
        let dl = Vec3::new(self.ss.dot(d), self.ts.dot(d), self.ns.dot(d));
        let nl = Vec3::new(self.ss.dot(ni), self.ts.dot(ni), self.ns.dot(ni));
        let r_proj = [
            (dl.y * dl.y + dl.z * dl.z).sqrt(),
            (dl.z * dl.z + dl.x * dl.x).sqrt(),
            (dl.x * dl.x + dl.y * dl.y).sqrt(),
        ];
        let axis_prob = [0.25f32, 0.25, 0.5];
        let mut pdf = 0.0;
        for axis in 0..3 {
            for ch in 0..3 {
                pdf += self.profile.pdf_sr(ch, r_proj[axis]) * nl[axis].abs() * (1.0 / 3.0) * axis_prob[axis];
            }
        }
        pdf
    }

    /// `S_p(p_i) = S_r(|p_o − p_i|)`.
    pub fn sp(&self, pi: Vec3) -> Rgb {
        self.profile.sr(self.p.distance(pi))
    }
}

/// pbrt-v3's table of measured media (`GetMediumScatteringProperties`): `(σ_a, σ'_s)` in
/// mm⁻¹ from Jensen, Marschner, Levoy & Hanrahan, "A Practical Model for Subsurface Light
/// Transport" (SIGGRAPH 2001) and Narasimhan, Gupta, Donner, Ramamoorthi, Nayar & Jensen,
/// "Acquiring Scattering Properties of Participating Media by Dilution" (SIGGRAPH 2006).
pub fn measured_medium(name: &str) -> Option<(Rgb, Rgb)> {
    MEASURED.iter().find(|m| m.0 == name).map(|m| (Rgb::from_array(m.2), Rgb::from_array(m.1)))
}

/// The names [`measured_medium`] knows.
pub fn measured_medium_names() -> impl Iterator<Item = &'static str> {
    MEASURED.iter().map(|m| m.0)
}

/// (name, σ'_s, σ_a), mm⁻¹.
type Measured = (&'static str, [f32; 3], [f32; 3]);
#[rustfmt::skip]
const MEASURED: &[Measured] = &[
    ("Apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    ("Chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    ("Chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    ("Cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    ("Ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    ("Marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    ("Potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    ("Skimmilk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    ("Skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    ("Skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    ("Spectralon", [11.6, 20.4, 14.9], [0.00, 0.00, 0.00]),
    ("Wholemilk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
    ("Lowfat Milk", [0.89187, 1.5136, 2.532], [0.002875, 0.00575, 0.0115]),
    ("Reduced Milk", [2.4858, 3.1669, 4.5214], [0.0025556, 0.0051111, 0.012778]),
    ("Regular Milk", [4.5513, 5.8294, 7.136], [0.0015333, 0.0046, 0.019933]),
    ("Espresso", [0.72378, 0.84557, 1.0247], [4.7984, 6.5751, 8.8493]),
    ("Mint Mocha Coffee", [0.31602, 0.38538, 0.48131], [3.772, 5.8228, 7.82]),
    ("Lowfat Soy Milk", [0.30576, 0.34233, 0.61664], [0.0014375, 0.0071875, 0.035937]),
    ("Regular Soy Milk", [0.59223, 0.73866, 1.4693], [0.0019167, 0.0095833, 0.065167]),
    ("Lowfat Chocolate Milk", [0.64925, 0.83916, 1.1057], [0.0115, 0.0368, 0.1564]),
    ("Regular Chocolate Milk", [1.4585, 2.1289, 2.9527], [0.010063, 0.043125, 0.14375]),
    ("Coke", [8.9053e-05, 8.372e-05, 0.0], [0.10014, 0.16503, 0.2468]),
    ("Pepsi", [6.1697e-05, 4.2564e-05, 0.0], [0.091641, 0.14158, 0.20729]),
    ("Sprite", [6.0306e-06, 6.4139e-06, 6.5504e-06], [0.001886, 0.0018308, 0.0020025]),
    ("Gatorade", [0.0024574, 0.003007, 0.0037325], [0.024794, 0.019289, 0.008878]),
    ("Chardonnay", [1.7982e-05, 1.3758e-05, 1.2023e-05], [0.010782, 0.011855, 0.023997]),
    ("White Zinfandel", [1.7501e-05, 1.9069e-05, 1.288e-05], [0.012072, 0.016184, 0.019843]),
    ("Merlot", [2.1129e-05, 0.0, 0.0], [0.11632, 0.25191, 0.29434]),
    ("Budweiser Beer", [2.4356e-05, 2.4079e-05, 1.0564e-05], [0.011492, 0.024911, 0.057786]),
    ("Coors Light Beer", [5.0922e-05, 4.301e-05, 0.0], [0.006164, 0.013984, 0.034983]),
    ("Clorox", [0.0024035, 0.0031373, 0.003991], [0.0033542, 0.014892, 0.026297]),
    ("Apple Juice", [0.00013612, 0.00015836, 0.000227], [0.012957, 0.023741, 0.052184]),
    ("Cranberry Juice", [0.00010402, 0.00011646, 7.8139e-05], [0.039437, 0.094223, 0.12426]),
    ("Grape Juice", [5.382e-05, 0.0, 0.0], [0.10404, 0.23958, 0.29325]),
    ("Ruby Grapefruit Juice", [0.011002, 0.010927, 0.011036], [0.085867, 0.18314, 0.25262]),
    ("White Grapefruit Juice", [0.22826, 0.23998, 0.32748], [0.0138, 0.018831, 0.056781]),
    ("Shampoo", [0.0007176, 0.0008303, 0.0009016], [0.014107, 0.045693, 0.061717]),
    ("Strawberry Shampoo", [0.00015671, 0.00015947, 1.518e-05], [0.01449, 0.05796, 0.075823]),
    ("Head & Shoulders Shampoo", [0.023805, 0.028804, 0.034306], [0.084621, 0.15688, 0.20365]),
    ("Lemon Tea Powder", [0.040224, 0.045264, 0.051081], [2.4288, 4.5757, 7.2127]),
    ("Orange Powder", [0.00015617, 0.00017482, 0.0001762], [0.001449, 0.003441, 0.007863]),
    ("Pink Lemonade Powder", [0.00012103, 0.00013073, 0.00012528], [0.001165, 0.002366, 0.003195]),
    ("Cappuccino Powder", [1.8436, 2.5851, 2.1662], [35.844, 49.547, 61.084]),
    ("Salt Powder", [0.027333, 0.032451, 0.031979], [0.28415, 0.3257, 0.34148]),
    ("Sugar Powder", [0.00022272, 0.00025513, 0.000271], [0.012638, 0.031051, 0.050124]),
    ("Suisse Mocha Powder", [2.7979, 3.5452, 4.3365], [17.502, 27.004, 35.433]),
    ("Pacific Ocean Surface Water", [0.0001764, 0.00032095, 0.00019617], [0.031845, 0.031324, 0.030147]),
];

#[cfg(test)]
mod tests;
