//! pbrt-v3's hair scattering model (`materials/hair.cpp`): Chiang, Bitterli, Tappan & Burley,
//! "A Practical and Controllable Hair and Fur Model for Production Path Tracing" (EGSR 2016),
//! with d'Eon et al.'s longitudinal scattering `M_p`, a trimmed-logistic azimuthal `N_p`, the
//! attenuations `A_p` of a dielectric cylinder with absorbing interior, cuticle scale tilt
//! `alpha`, and `p_max = 3` (the rest summed as an isotropic term).
//!
//! Frame: x runs along the fibre (pbrt-v3's `∂p/∂u`), so `sin θ = w.x`, and the azimuth is
//! `φ = atan2(w.z, w.y)` in the plane across it. `h ∈ [−1, 1]` is where the ray met the
//! fibre's width (pbrt-v3: `−1 + 2v` of the curve's parametric `v`).

use super::BxdfFlags;
use crate::spectrum::{Rgb, LUMINANCE_WEIGHTS};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Scattering orders modelled explicitly (pbrt-v3's `pMax`).
pub const P_MAX: usize = 3;
const SQRT_PI_OVER_8: f32 = 0.626_657_07;

#[inline]
fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

#[inline]
fn safe_asin(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).asin()
}

#[inline]
fn sqr(x: f32) -> f32 {
    x * x
}

/// The modified Bessel function I₀ by its power series (10 terms, as pbrt-v3).
fn i0(x: f32) -> f32 {
    let mut val = 0.0f32;
    let mut x2i = 1.0f32;
    let mut ifact: i64 = 1;
    let mut i4: i64 = 1;
    for i in 0..10 {
        if i > 1 {
            ifact *= i;
        }
        val += x2i / (i4 as f32 * sqr(ifact as f32));
        x2i *= x * x;
        i4 *= 4;
    }
    val
}

fn log_i0(x: f32) -> f32 {
    if x > 12.0 {
        x + 0.5 * (-(2.0 * PI).ln() + (1.0 / x).ln() + 1.0 / (8.0 * x))
    } else {
        i0(x).ln()
    }
}

/// Longitudinal scattering (d'Eon et al. 2011) with variance `v`.
fn mp(cos_i: f32, cos_o: f32, sin_i: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    let m = if v <= 0.1 {
        // (pbrt-v3 writes ln 2 as 0.6931.)
        (log_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        ((-b).exp() * i0(a)) / ((1.0 / v).sinh() * 2.0 * v)
    };
    if m.is_finite() {
        m
    } else {
        0.0
    }
}

fn logistic(x: f32, s: f32) -> f32 {
    let x = x.abs();
    (-x / s).exp() / (s * sqr(1.0 + (-x / s).exp()))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

fn trimmed_logistic(x: f32, s: f32, a: f32, b: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(b, s) - logistic_cdf(a, s))
}

fn sample_trimmed_logistic(u: f32, s: f32, a: f32, b: f32) -> f32 {
    let k = logistic_cdf(b, s) - logistic_cdf(a, s);
    let x = -s * (1.0 / (u * k + logistic_cdf(a, s)) - 1.0).ln();
    if x.is_nan() {
        0.0
    } else {
        x.clamp(a, b)
    }
}

/// The azimuth Δφ of the exit direction of scattering order `p`.
#[inline]
fn phi_p(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI
}

fn np(phi: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut dphi = phi - phi_p(p, gamma_o, gamma_t);
    if !dphi.is_finite() {
        return 0.0;
    }
    // Into [−π, π] (pbrt-v3 loops; a remainder is the same for finite angles).
    dphi = (dphi + PI).rem_euclid(2.0 * PI) - PI;
    trimmed_logistic(dphi, s, -PI, PI)
}

/// pbrt-v3's `DemuxFloat`: two 16-bit samples from the even and odd bits of one.
fn demux_float(f: f32) -> Vec2 {
    let v = ((f.clamp(0.0, super::ONE_MINUS_EPSILON) as f64) * 4_294_967_296.0) as u64 as u32;
    let compact = |mut x: u32| {
        x &= 0x5555_5555;
        x = (x ^ (x >> 1)) & 0x3333_3333;
        x = (x ^ (x >> 2)) & 0x0f0f_0f0f;
        x = (x ^ (x >> 4)) & 0x00ff_00ff;
        x = (x ^ (x >> 8)) & 0x0000_ffff;
        x
    };
    Vec2::new(compact(v) as f32 / 65536.0, compact(v >> 1) as f32 / 65536.0)
}

/// pbrt-v3's `HairBSDF`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairBxdf {
    h: f32,
    gamma_o: f32,
    eta: f32,
    sigma_a: Rgb,
    v: [f32; P_MAX + 1],
    s: f32,
    sin_2k_alpha: [f32; 3],
    cos_2k_alpha: [f32; 3],
    /// `mix`'s weight (pbrt-v3's `ScaledBxDF`); 1 otherwise.
    scale: Rgb,
}

/// pbrt-v3's `SigmaAFromConcentration`: absorption of eumelanin and pheomelanin concentrations.
pub fn sigma_a_from_concentration(ce: f32, cp: f32) -> Rgb {
    ce * Rgb::new(0.419, 0.697, 1.37) + cp * Rgb::new(0.187, 0.4, 1.05)
}

/// pbrt-v3's `SigmaAFromReflectance`: the absorption giving multiply-scattered colour `c` at
/// azimuthal roughness `beta_n` (Chiang et al.'s fit).
pub fn sigma_a_from_reflectance(c: Rgb, beta_n: f32) -> Rgb {
    let b = beta_n;
    let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5);
    let f = |c: f32| sqr(c.ln() / d);
    Rgb::new(f(c.x), f(c.y), f(c.z))
}

/// The terms of the model that depend on `wo` only.
struct Outgoing {
    sin_o: f32,
    cos_o: f32,
    phi_o: f32,
    gamma_t: f32,
    /// Attenuation of each order.
    ap: [Rgb; P_MAX + 1],
}

impl HairBxdf {
    /// `h` is clamped to [−1, 1] and the roughnesses to [0, 1] (pbrt-v3 asserts these ranges).
    pub fn new(h: f32, eta: f32, sigma_a: Rgb, beta_m: f32, beta_n: f32, alpha_degrees: f32) -> Self {
        let h = if h.is_nan() { 0.0 } else { h.clamp(-1.0, 1.0) };
        let beta_m = if beta_m.is_nan() { 0.3 } else { beta_m.clamp(0.0, 1.0) };
        let beta_n = if beta_n.is_nan() { 0.3 } else { beta_n.clamp(0.0, 1.0) };
        let mut v = [0.0f32; P_MAX + 1];
        v[0] = sqr(0.726 * beta_m + 0.812 * sqr(beta_m) + 3.7 * beta_m.powi(20));
        v[1] = 0.25 * v[0];
        v[2] = 4.0 * v[0];
        v[3] = v[2];
        let s = SQRT_PI_OVER_8 * (0.265 * beta_n + 1.194 * sqr(beta_n) + 5.372 * beta_n.powi(22));
        let mut sin_2k_alpha = [0.0f32; 3];
        let mut cos_2k_alpha = [0.0f32; 3];
        sin_2k_alpha[0] = alpha_degrees.to_radians().sin();
        cos_2k_alpha[0] = safe_sqrt(1.0 - sqr(sin_2k_alpha[0]));
        for i in 1..3 {
            sin_2k_alpha[i] = 2.0 * cos_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
            cos_2k_alpha[i] = sqr(cos_2k_alpha[i - 1]) - sqr(sin_2k_alpha[i - 1]);
        }
        HairBxdf {
            h,
            gamma_o: safe_asin(h),
            eta,
            sigma_a: sigma_a.max(Rgb::ZERO),
            v,
            s,
            sin_2k_alpha,
            cos_2k_alpha,
            scale: Rgb::ONE,
        }
    }

    pub fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::TRANSMISSION | BxdfFlags::GLOSSY
    }

    /// The lobe with its value multiplied by `s` (the sampling is unchanged).
    pub fn scaled(self, s: Rgb) -> Self {
        HairBxdf { scale: self.scale * s, ..self }
    }

    fn outgoing(&self, wo: Vec3) -> Outgoing {
        let sin_o = wo.x;
        let cos_o = safe_sqrt(1.0 - sqr(sin_o));
        let phi_o = wo.z.atan2(wo.y);
        let sin_t = sin_o / self.eta;
        let cos_t = safe_sqrt(1.0 - sqr(sin_t));
        let etap = (self.eta * self.eta - sqr(sin_o)).sqrt() / cos_o;
        let sin_gamma_t = self.h / etap;
        let cos_gamma_t = safe_sqrt(1.0 - sqr(sin_gamma_t));
        let gamma_t = safe_asin(sin_gamma_t);
        let t = (-self.sigma_a * (2.0 * cos_gamma_t / cos_t)).exp();
        Outgoing { sin_o, cos_o, phi_o, gamma_t, ap: self.attenuation(cos_o, t) }
    }

    /// pbrt-v3's `Ap`.
    fn attenuation(&self, cos_o: f32, t: Rgb) -> [Rgb; P_MAX + 1] {
        let cos_gamma_o = safe_sqrt(1.0 - self.h * self.h);
        let f = super::fr_dielectric(cos_o * cos_gamma_o, 1.0, self.eta);
        let mut ap = [Rgb::ZERO; P_MAX + 1];
        ap[0] = Rgb::splat(f);
        ap[1] = sqr(1.0 - f) * t;
        for p in 2..P_MAX {
            ap[p] = ap[p - 1] * t * f;
        }
        ap[P_MAX] = ap[P_MAX - 1] * f * t / (Rgb::ONE - t * f);
        ap
    }

    /// `(sin θ_o, cos θ_o)` turned by the cuticle tilt for order `p`, `cos` made non-negative.
    fn tilted(&self, p: usize, sin_o: f32, cos_o: f32) -> (f32, f32) {
        let (s, c) = match p {
            0 => (
                sin_o * self.cos_2k_alpha[1] - cos_o * self.sin_2k_alpha[1],
                cos_o * self.cos_2k_alpha[1] + sin_o * self.sin_2k_alpha[1],
            ),
            1 => (
                sin_o * self.cos_2k_alpha[0] + cos_o * self.sin_2k_alpha[0],
                cos_o * self.cos_2k_alpha[0] - sin_o * self.sin_2k_alpha[0],
            ),
            2 => (
                sin_o * self.cos_2k_alpha[2] + cos_o * self.sin_2k_alpha[2],
                cos_o * self.cos_2k_alpha[2] - sin_o * self.sin_2k_alpha[2],
            ),
            _ => (sin_o, cos_o),
        };
        (s, c.abs())
    }

    /// The probability of each order: its attenuation's luminance over the sum.
    fn ap_pdf(ap: &[Rgb; P_MAX + 1]) -> [f32; P_MAX + 1] {
        let y = ap.map(|a| a.dot(LUMINANCE_WEIGHTS));
        let sum: f32 = y.iter().sum();
        y.map(|yp| yp / sum)
    }

    pub fn f(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let o = self.outgoing(wo);
        let sin_i = wi.x;
        let cos_i = safe_sqrt(1.0 - sqr(sin_i));
        let phi = wi.z.atan2(wi.y) - o.phi_o;
        let mut sum = Rgb::ZERO;
        for p in 0..P_MAX {
            let (sp, cp) = self.tilted(p, o.sin_o, o.cos_o);
            sum += mp(cos_i, cp, sin_i, sp, self.v[p]) * o.ap[p] * np(phi, p, self.s, self.gamma_o, o.gamma_t);
        }
        sum += mp(cos_i, o.cos_o, sin_i, o.sin_o, self.v[P_MAX]) * o.ap[P_MAX] / (2.0 * PI);
        if wi.z.abs() > 0.0 {
            sum /= wi.z.abs();
        }
        sum * self.scale
    }

    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let o = self.outgoing(wo);
        let sin_i = wi.x;
        let cos_i = safe_sqrt(1.0 - sqr(sin_i));
        let phi = wi.z.atan2(wi.y) - o.phi_o;
        let ap_pdf = Self::ap_pdf(&o.ap);
        let mut pdf = 0.0;
        for (p, ap) in ap_pdf.iter().enumerate().take(P_MAX) {
            let (sp, cp) = self.tilted(p, o.sin_o, o.cos_o);
            pdf += mp(cos_i, cp, sin_i, sp, self.v[p]) * ap * np(phi, p, self.s, self.gamma_o, o.gamma_t);
        }
        pdf + mp(cos_i, o.cos_o, sin_i, o.sin_o, self.v[P_MAX]) * ap_pdf[P_MAX] / (2.0 * PI)
    }

    /// pbrt-v3's `Sample_f`: an order by the attenuations, θ_i by `M_p`, Δφ by `N_p` (four
    /// samples demultiplexed from the two of `u`).
    pub fn sample_wi(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let o = self.outgoing(wo);
        let (mut u0, u1) = (demux_float(u.x), demux_float(u.y));
        let ap_pdf = Self::ap_pdf(&o.ap);
        let mut p = 0;
        while p < P_MAX {
            if u0.x < ap_pdf[p] {
                break;
            }
            u0.x -= ap_pdf[p];
            p += 1;
        }
        let (sp, cp) = self.tilted(p, o.sin_o, o.cos_o);
        let v = self.v[p];
        let uu = u1.x.max(1e-5);
        let cos_theta = 1.0 + v * (uu + (1.0 - uu) * (-2.0 / v).exp()).ln();
        let sin_theta = safe_sqrt(1.0 - sqr(cos_theta));
        let cos_phi = (2.0 * PI * u1.y).cos();
        let sin_i = -cos_theta * sp + sin_theta * cos_phi * cp;
        let cos_i = safe_sqrt(1.0 - sqr(sin_i));
        let dphi = if p < P_MAX {
            phi_p(p, self.gamma_o, o.gamma_t) + sample_trimmed_logistic(u0.y, self.s, -PI, PI)
        } else {
            2.0 * PI * u0.y
        };
        let phi_i = o.phi_o + dphi;
        let wi = Vec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        wi.is_finite().then_some(wi)
    }
}
