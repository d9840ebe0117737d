//! Linearly Transformed Cosines (Heitz, Dupuy, Hill & Neubelt 2016) fitted to
//! pbrt-v3's Trowbridge–Reitz (GGX) microfacet reflection as core evaluates it
//! ([`penumbra_core::microfacet::MicrofacetDistribution`], height-correlated Smith `G`,
//! no Fresnel): `f(ωo, ωi) cos θi = D(ωh) G(ωo, ωi) / (4 cos θo)`.
//!
//! # Frame and table
//!
//! Everything is in the local shading frame [`Frame::toward`]: `z` the normal,
//! `x` the tangent direction of `ωo` (so `ωo = (sin θo, 0, cos θo)`). An LTC is
//! the distribution `D(ω) = Do(ω̂o) |det M⁻¹| / |M⁻¹ω|³` with `ω̂o = M⁻¹ω / |M⁻¹ω|`
//! and `Do` the clamped cosine `max(0, z)/π`. For isotropic GGX, `M⁻¹` has the
//! form `[[m00, 0, m02], [0, 1, 0], [m20, 0, m22]]` (scale-free: the middle
//! entry is normalised to 1).
//!
//! The table ([`Ltc`]) holds, on a `N_θ × N_α` grid (rows: `v = √α / (1 + √α)` uniform in
//! `[v(α_min), v(α_max)]`, which keeps the fine steps of `√α` at low roughness and takes the
//! slowly changing lobes of α > 1 in few rows; columns: `√(1 − cos θo)` uniform in `[0, 1]`),
//! the LTC as Heitz et al.'s fitting code parameterises it — the angle `θz` from the normal of
//! the lobe's average direction `Z = (sin θz, 0, cos θz)` and the shape `m11, m22, m13` of
//! `M = [X Y Z] · [[m11, 0, m13], [0, m22, 0], [0, 0, 1]]` (`Y` normal to the plane of
//! incidence, `X = Y × Z`) — which interpolates between cells far better than the entries of
//! `M⁻¹` do (two narrow lobes in different directions do not blend into a lobe between them);
//! then the `magnitude` (directional albedo `∫ f cos dωi` with
//! Fresnel 1) and the `fresnel` ratio `∫ f cos (1 − ωo·ωh)⁵ dωi / magnitude`, so
//! that with Schlick's `F = F0 + (1 − F0)(1 − ωo·ωh)⁵`,
//! `∫ f F cos ≈ magnitude · (F0 + (1 − F0) · fresnel)` ([`LtcCoeffs::schlick_scale`]).
//! It is produced by `ltc-fit` (`cargo run --release -p penumbra-integrators --bin
//! ltc-fit -- --out integrators/data/ltc_ggx.bin`, see [`fit`]), which also writes the fit's
//! error per cell beside it (`integrators/data/ltc_ggx_fit.tsv`), and embedded with
//! `include_bytes!`.
//! The embedded table spans pbrt-v3's whole range: α from 0.001 (pbrt-v3's
//! `TrowbridgeReitzDistribution` clamps smaller values to it) to 3 (roughness 1 remaps to
//! 1.62; `remaproughness false` passes any value: beyond α_max, [`Ltc::eval`] returns the
//! α_max lobe, and the caller decides — [`quadrature`] stays exact with it as its warp, the
//! LTC alone does not).
//!
//! # Using it
//!
//! `∫_P f(ωo, ω) cos θ dω ≈ magnitude · ltc_integrate(&minv, &frame, loops)` for
//! a region `P` given as loops of world-space directions (see
//! [`crate::common::spherical_polygon`] for the loop conventions; the result is signed by
//! orientation, positive loops give positive values). That is the LTC's approximation of
//! the lobe; [`quadrature::integrate_residual`] adds what it misses, for the exact integral.

use std::sync::OnceLock;

use glam::{DMat3, DVec2, DVec3};

use crate::common::spherical_polygon;
use penumbra_core::geometry::Frame;

/// The embedded GGX table (see the module documentation for the format).
static LTC_GGX_BIN: &[u8] = include_bytes!("../../../data/ltc_ggx.bin");

/// One LTC: its inverse matrix (local frame) and the scalar terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LtcCoeffs {
    pub minv: DMat3,
    /// Directional albedo `∫ f cos dωi` (Fresnel 1).
    pub magnitude: f32,
    /// `∫ f cos (1 − ωo·ωh)⁵ dωi / magnitude`.
    pub fresnel: f32,
}

/// `M⁻¹` from four entries (middle entry 1).
pub fn minv_from_params(p: [f64; 4]) -> DMat3 {
    DMat3::from_cols(DVec3::new(p[0], 0.0, p[2]), DVec3::Y, DVec3::new(p[1], 0.0, p[3]))
}

/// `M = [X Y Z] · [[m11, 0, m13], [0, m22, 0], [0, 0, 1]]` for the average direction
/// `Z = (sin θz, 0, cos θz)` and `X = Y × Z` (a table cell's first four entries:
/// `[m11, m22, m13, θz]`).
pub fn m_from_shape([m11, m22, m13, theta_z]: [f64; 4]) -> DMat3 {
    let (s, c) = theta_z.sin_cos();
    let (x, z) = (DVec3::new(c, 0.0, -s), DVec3::new(s, 0.0, c));
    DMat3::from_cols(x * m11, DVec3::Y * m22, x * m13 + z)
}

/// The clamped-cosine density `max(0, z)/π` of a unit vector.
fn cos_density(w: DVec3) -> f64 {
    w.z.max(0.0) * std::f64::consts::FRAC_1_PI
}

/// Cosine-weighted hemisphere sample (Malley, concentric disk), f64.
pub fn cosine_sample(u: DVec2) -> DVec3 {
    let (a, b) = (2.0 * u.x - 1.0, 2.0 * u.y - 1.0);
    let (r, phi) = if a == 0.0 && b == 0.0 {
        (0.0, 0.0)
    } else if a.abs() > b.abs() {
        (a, std::f64::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (a / b))
    };
    let (x, y) = (r * phi.cos(), r * phi.sin());
    DVec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

/// The LTC density of `w` (any length) for the inverse matrix `minv`.
pub fn ltc_pdf(minv: &DMat3, w: DVec3) -> f64 {
    let l = w.length();
    if l == 0.0 || !l.is_finite() {
        return 0.0;
    }
    let wo = *minv * (w / l);
    let len = wo.length();
    if len == 0.0 || !len.is_finite() {
        return 0.0;
    }
    let v = cos_density(wo / len) * minv.determinant().abs() / (len * len * len);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

impl LtcCoeffs {
    /// The distribution's matrix `M` (the inverse of `minv`; identity if singular).
    pub fn m(&self) -> DMat3 {
        let d = self.minv.determinant();
        if d == 0.0 || !d.is_finite() {
            DMat3::IDENTITY
        } else {
            self.minv.inverse()
        }
    }

    /// Samples the LTC distribution (local frame): `normalize(M ωo)` with `ωo`
    /// cosine-distributed. Its density is [`pdf`](Self::pdf).
    pub fn sample(&self, u: DVec2) -> DVec3 {
        (self.m() * cosine_sample(u)).normalize_or_zero()
    }

    /// Density (solid angle, local frame) of [`sample`](Self::sample); integrates to 1.
    pub fn pdf(&self, w: DVec3) -> f64 {
        ltc_pdf(&self.minv, w)
    }

    /// Schlick-Fresnel weighted magnitude `magnitude · (F0 + (1 − F0) fresnel)`.
    pub fn schlick_scale(&self, f0: f32) -> f32 {
        self.magnitude * (f0 + (1.0 - f0) * self.fresnel)
    }
}

/// `∫_P D(ω) dω` of the LTC with inverse matrix `minv` over the region given by
/// `loops` of world-space directions (seen from the shading point): each loop
/// is taken to the local frame, transformed by `minv`, clipped to the horizon
/// and integrated with Lambert's edge formula. Signed by orientation (positive
/// loops positive); multiply by the magnitude for `∫ f cos`.
pub fn ltc_integrate(minv: &DMat3, frame: &Frame<DVec3>, loops: &[Vec<DVec3>]) -> f64 {
    ltc_integrate_vector(minv, frame, loops).z
}

/// The vector form factor, in the LTC's cosine space, of the region [`ltc_integrate`]
/// integrates: its `z` is that integral (bit for bit), and `M` times it points along the
/// region's LTC-weighted mean direction (Heitz et al.'s proxy for Fresnel and horizon
/// handling). Signed by orientation, as is the integral; nothing is allocated.
pub fn ltc_integrate_vector(minv: &DMat3, frame: &Frame<DVec3>, loops: &[Vec<DVec3>]) -> DVec3 {
    let mut sum = DVec3::ZERO;
    let flip = minv.determinant() < 0.0;
    for l in loops {
        let f = spherical_polygon::horizon_vector_form_factor(l.len(), |i| *minv * frame.to_local(l[i]));
        sum += if flip { -f } else { f };
    }
    sum
}

/// An LTC table.
#[derive(Clone, Debug, PartialEq)]
pub struct Ltc {
    pub n_theta: usize,
    pub n_alpha: usize,
    pub alpha_min: f32,
    pub alpha_max: f32,
    /// Row-major (alpha outer): `[m11, m22, m13, θz, magnitude, fresnel]` (see the module doc).
    pub cells: Vec<[f32; 6]>,
}

/// The table's row coordinate of `α`: `√α / (1 + √α)`.
pub fn alpha_axis(alpha: f64) -> f64 {
    let s = alpha.max(0.0).sqrt();
    s / (1.0 + s)
}

/// The inverse of [`alpha_axis`] (`v` in `[0, 1)`).
pub fn alpha_of_axis(v: f64) -> f64 {
    let s = v / (1.0 - v);
    s * s
}

/// Error reading an LTC table.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LtcError {
    #[error("LTC table: {0}")]
    Format(&'static str),
}

impl Ltc {
    /// `cos θo` of column `i`.
    pub fn column_cos_theta(&self, i: usize) -> f64 {
        let x = i as f64 / (self.n_theta.max(2) - 1) as f64;
        1.0 - x * x
    }

    /// `α` of row `j`.
    pub fn row_alpha(&self, j: usize) -> f64 {
        let (v0, v1) = (alpha_axis(self.alpha_min as f64), alpha_axis(self.alpha_max as f64));
        alpha_of_axis(v0 + (v1 - v0) * j as f64 / (self.n_alpha.max(2) - 1) as f64)
    }

    /// Parses the binary format: `b"LTC2"`, `u32` n_theta, `u32` n_alpha,
    /// `f32` alpha_min, `f32` alpha_max, then `n_alpha × n_theta × 6` `f32`, little-endian.
    pub fn from_bytes(b: &[u8]) -> Result<Ltc, LtcError> {
        const HEADER: usize = 20;
        if b.len() < HEADER || &b[0..4] != b"LTC2" {
            return Err(LtcError::Format("bad header"));
        }
        let u = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let f = |o: usize| f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let (n_theta, n_alpha) = (u(4) as usize, u(8) as usize);
        let (alpha_min, alpha_max) = (f(12), f(16));
        if !(2..=4096).contains(&n_theta) || !(2..=4096).contains(&n_alpha) {
            return Err(LtcError::Format("bad grid size"));
        }
        if !(alpha_min > 0.0 && alpha_min < alpha_max && alpha_max <= 1e4) {
            return Err(LtcError::Format("bad alpha range"));
        }
        let n = n_theta * n_alpha;
        if b.len() != HEADER + n * 24 {
            return Err(LtcError::Format("bad length"));
        }
        let cells: Vec<[f32; 6]> = (0..n).map(|c| std::array::from_fn(|k| f(HEADER + c * 24 + k * 4))).collect();
        if cells.iter().flatten().any(|v| !v.is_finite()) {
            return Err(LtcError::Format("non-finite entry"));
        }
        Ok(Ltc { n_theta, n_alpha, alpha_min, alpha_max, cells })
    }

    /// Serialises to [`from_bytes`](Self::from_bytes)'s format.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(20 + self.cells.len() * 24);
        out.extend_from_slice(b"LTC2");
        out.extend_from_slice(&(self.n_theta as u32).to_le_bytes());
        out.extend_from_slice(&(self.n_alpha as u32).to_le_bytes());
        out.extend_from_slice(&self.alpha_min.to_le_bytes());
        out.extend_from_slice(&self.alpha_max.to_le_bytes());
        for c in &self.cells {
            for v in c {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out
    }

    /// The embedded GGX table (`None` only if the embedded data is invalid,
    /// which a test rules out).
    pub fn ggx() -> Option<&'static Ltc> {
        static TABLE: OnceLock<Option<Ltc>> = OnceLock::new();
        TABLE.get_or_init(|| Ltc::from_bytes(LTC_GGX_BIN).ok()).as_ref()
    }

    /// Bilinearly interpolated coefficients of the embedded GGX table for
    /// `cos θo` and the (already remapped) Trowbridge–Reitz `alpha`; both are
    /// clamped to the table's range (`alpha ∈ [alpha_min, alpha_max]`, `cos θo ∈ [0, 1]`):
    /// beyond `alpha_max` (see [`Ltc::covers`]) the result is the last row's lobe, a warp for
    /// [`quadrature`] but not the lobe asked for.
    /// Falls back to the Lambertian identity if the table is unavailable.
    pub fn lookup(cos_theta_o: f32, alpha: f32) -> LtcCoeffs {
        match Ltc::ggx() {
            Some(t) => t.eval(cos_theta_o, alpha),
            None => LtcCoeffs { minv: DMat3::IDENTITY, magnitude: 1.0, fresnel: 0.0 },
        }
    }

    /// Whether the embedded table's rows reach `alpha` (the Lambertian fallback covers nothing).
    pub fn covers(alpha: f32) -> bool {
        Ltc::ggx().is_some_and(|t| alpha <= t.alpha_max)
    }

    /// Bilinear lookup in this table (see [`lookup`](Self::lookup)).
    pub fn eval(&self, cos_theta_o: f32, alpha: f32) -> LtcCoeffs {
        let c = if cos_theta_o.is_nan() { 1.0 } else { cos_theta_o.clamp(0.0, 1.0) as f64 };
        let a = if alpha.is_nan() { 1.0 } else { alpha.clamp(self.alpha_min, self.alpha_max) as f64 };
        let x = (1.0 - c).max(0.0).sqrt() * (self.n_theta - 1) as f64;
        let (v0, v1) = (alpha_axis(self.alpha_min as f64), alpha_axis(self.alpha_max as f64));
        let y = ((alpha_axis(a) - v0) / (v1 - v0)).clamp(0.0, 1.0) * (self.n_alpha - 1) as f64;
        let (i0, j0) = ((x.floor() as usize).min(self.n_theta - 2), (y.floor() as usize).min(self.n_alpha - 2));
        let (fx, fy) = (x - i0 as f64, y - j0 as f64);
        let cell = |i: usize, j: usize| &self.cells[j * self.n_theta + i];
        let mut v = [0.0f64; 6];
        for (k, vk) in v.iter_mut().enumerate() {
            let a00 = cell(i0, j0)[k] as f64;
            let a10 = cell(i0 + 1, j0)[k] as f64;
            let a01 = cell(i0, j0 + 1)[k] as f64;
            let a11 = cell(i0 + 1, j0 + 1)[k] as f64;
            *vk = (a00 * (1.0 - fx) + a10 * fx) * (1.0 - fy) + (a01 * (1.0 - fx) + a11 * fx) * fy;
        }
        let m = m_from_shape([v[0], v[1], v[2], v[3]]);
        let d = m.determinant();
        let minv = if d > 0.0 && d.is_finite() { m.inverse() * d.cbrt() } else { DMat3::IDENTITY };
        LtcCoeffs { minv, magnitude: v[4] as f32, fresnel: v[5] as f32 }
    }
}

pub mod fit;
pub mod quadrature;

#[cfg(test)]
mod tests;
