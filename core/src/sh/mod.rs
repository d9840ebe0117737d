//! Real spherical harmonics (SH): the basis, projection, zonal harmonics, rotation, products,
//! the SH exponential and logarithm, projection of environment lights, and the SH transfer
//! channels integrators write for `penumbra relight`.
//!
//! Shared by `shexp` (products, exp\*/log\*, the log-blocker table), `silhouette` (projection of
//! visibility-masked functions, PRT vectors) and `sheared-ao` (SH occlusion), so it lives here,
//! in f64 throughout: products and exponentials compound rounding, and a log table built in
//! f32 loses the small caps.
//!
//! # Conventions (used by everything in this module)
//! - **Order** `n` ([`ShOrder`]): bands `l = 0 … n−1`, `n²` coefficients; orders
//!   `1 ..= MAX_ORDER` are supported (products up to [`product::MAX_PRODUCT_ORDER`]).
//! - **Flat index** `i = l(l+1) + m`, `−l ≤ m ≤ l` ([`index`], [`band_and_m`]).
//! - **Basis** (real, orthonormal on the unit sphere, no Condon–Shortley phase — the usual
//!   graphics table): with `(x, y, z)` a unit direction, `z = cos θ`, `φ` from +x towards +y,
//!   `Y_l^0 = N_l^0 P_l(z)`, `Y_l^m = √2 N_l^m P_l^m(z) cos(mφ)` for `m > 0` and
//!   `Y_l^m = √2 N_l^|m| P_l^|m|(z) sin(|m|φ)` for `m < 0`, `N_l^m = √((2l+1)/4π · (l−m)!/(l+m)!)`.
//!   So `Y_0^0 = 0.282095`, `(Y_1^−1, Y_1^0, Y_1^1) = 0.488603 (y, z, x)`,
//!   `Y_2^−2 = 1.092548 xy`, `Y_2^0 = 0.315392 (3z² − 1)`, `Y_2^2 = 0.546274 (x² − y²)`.
//!   Evaluated by recurrence on `z` and on `(x + iy)^m` ([`basis::eval`]): no trigonometry.
//! - **Projection** `f_i = ∫ f(ω) Y_i(ω) dω`; reconstruction `f̃ = Σ f_i Y_i`;
//!   `∫ f̃ g̃ = f · g`. The constant function 1 has coefficients **1** `= (√4π, 0, …)`.
//! - **Rotation**: [`rotation::ShRotation::new`]`(R)` maps the coefficients of `f` to those of
//!   `f ∘ R⁻¹` (the function turned by `R`). World-space coefficients of an environment light
//!   are the rotation by its world-from-light transform of its light-space coefficients.
//! - **Zonal harmonics** (functions symmetric about +z) are stored as one coefficient per band,
//!   `g_l` = the coefficient of `Y_l^0`; turned to an axis `s` they become
//!   `g′_lm = √(4π/(2l+1)) g_l Y_lm(s)` ([`zonal::rotate_zh`]).
//!
//! # SH transfer channels
//! An integrator that can write per-pixel transfer vectors writes EXR channels `sh.0 … sh.K`
//! (`K = n² − 1`, flat index as above, **world-space** basis) and the surface's diffuse albedo
//! as `albedo.R`, `albedo.G`, `albedo.B`. For a Lambertian surface under distant light `L`
//! (SH coefficients `L_i`, per colour channel) the outgoing radiance is
//! `albedo/π · Σ_i transfer_i · L_i`, with `transfer_i = ∫ V(ω) max(0, n·ω) Y_i(ω) dω`
//! (V the visibility, n the normal the integrator shades with). [`transfer`] names, writes,
//! finds and shades these channels; `penumbra relight` consumes them.

pub mod basis;
pub mod eigen;
pub mod env;
pub mod exp;
pub mod product;
pub mod quadrature;
pub mod rotation;
pub mod tables;
pub mod transfer;
pub mod zonal;

pub use basis::{eval, eval_vec};
pub use eigen::{exp_eigen, log_star};
pub use env::{project_infinite_light, ShRgb};
pub use exp::{ExpMethod, ExpScratch, ShExp};
pub use product::TripleProduct;
pub use quadrature::{project, SphereQuadrature};
pub use rotation::ShRotation;
pub use tables::{LogBlockerTable, OptimalLinearTable};

/// Highest SH order supported by the basis, projection, zonal harmonics and rotation.
pub const MAX_ORDER: usize = 32;

/// `√(4π)`: the DC coefficient of the constant function 1, and `1/Y_0^0`.
pub const SQRT_4PI: f64 = 3.544_907_701_811_032;

/// An SH order `n` in `1 ..= MAX_ORDER` (bands `0 … n−1`, `n²` coefficients).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ShOrder(u8);

impl ShOrder {
    /// The order `n`, or an error outside `1 ..= MAX_ORDER`.
    pub fn new(n: usize) -> Result<ShOrder, ShError> {
        if (1..=MAX_ORDER).contains(&n) {
            Ok(ShOrder(n as u8))
        } else {
            Err(ShError::Order { n, max: MAX_ORDER })
        }
    }

    /// The order whose coefficient count is `count` (an error unless `count = n²` for a valid `n`).
    pub fn from_coeffs(count: usize) -> Result<ShOrder, ShError> {
        let n = (count as f64).sqrt().round() as usize;
        if n * n != count {
            return Err(ShError::NotSquare(count));
        }
        ShOrder::new(n)
    }

    /// The number of bands `n`.
    pub const fn n(self) -> usize {
        self.0 as usize
    }

    /// The number of coefficients `n²`.
    pub const fn coeffs(self) -> usize {
        (self.0 as usize) * (self.0 as usize)
    }
}

impl std::fmt::Display for ShOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// What the SH routines refuse.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShError {
    #[error("SH order {n} is not supported (1..={max})")]
    Order { n: usize, max: usize },
    #[error("{0} coefficients is not n² for an SH order n")]
    NotSquare(usize),
    #[error("{what}: expected {expected} values, got {got}")]
    Length { what: &'static str, expected: usize, got: usize },
    #[error("{0}")]
    Invalid(String),
}

/// Checks that a slice holds at least `expected` values.
pub(crate) fn check_len(what: &'static str, got: usize, expected: usize) -> Result<(), ShError> {
    if got < expected {
        Err(ShError::Length { what, expected, got })
    } else {
        Ok(())
    }
}

/// The flat index `l(l+1) + m` of `Y_l^m` (`|m| ≤ l`).
#[inline]
pub const fn index(l: usize, m: i32) -> usize {
    ((l * (l + 1)) as isize + m as isize) as usize
}

/// The band `l` and `m` of flat index `i`.
#[inline]
pub fn band_and_m(i: usize) -> (usize, i32) {
    let l = (i as f64).sqrt() as usize;
    // Guard the square root's rounding near perfect squares.
    let l = if (l + 1) * (l + 1) <= i {
        l + 1
    } else if l * l > i {
        l - 1
    } else {
        l
    };
    (l, i as i32 - (l * (l + 1)) as i32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_and_band_round_trip() {
        let mut i = 0;
        for l in 0..40 {
            for m in -(l as i32)..=l as i32 {
                assert_eq!(index(l, m), i);
                assert_eq!(band_and_m(i), (l, m));
                i += 1;
            }
        }
    }

    #[test]
    fn orders_are_validated() {
        assert!(ShOrder::new(0).is_err());
        assert!(ShOrder::new(MAX_ORDER + 1).is_err());
        assert_eq!(ShOrder::new(3).unwrap().coeffs(), 9);
        assert_eq!(ShOrder::from_coeffs(16).unwrap().n(), 4);
        assert_eq!(ShOrder::from_coeffs(15), Err(ShError::NotSquare(15)));
        assert!(ShOrder::from_coeffs(0).is_err());
        assert!((SQRT_4PI - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-15);
    }
}
