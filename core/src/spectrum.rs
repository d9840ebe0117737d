//! RGB radiometry, as pbrt-v3's default (RGB) build.
//!
//! pbrt-v3 compiled with `RGBSpectrum` stores every spectrum as linear RGB with
//! its sRGB primaries. Scene values given as `xyz`, `blackbody` or `spectrum`
//! are converted to RGB when the parameter is read; this module reproduces those
//! conversions:
//! - `rgb`: taken as is;
//! - `xyz`: multiplied by pbrt-v3's XYZ→RGB matrix;
//! - `spectrum` (λ, value) pairs: sorted by wavelength if needed, linearly
//!   interpolated at each CIE wavelength (1 nm, 360..=830 nm), summed against the
//!   CIE 1931 2° matching functions, scaled by `(830 - 360) / (CIE_Y_INTEGRAL * 471)`,
//!   then converted XYZ→RGB;
//! - `blackbody` (T, scale) pairs: Planck's law evaluated at the CIE wavelengths,
//!   normalised so that its maximum (at Wien's wavelength) is 1, converted as a
//!   sampled spectrum, times `scale`.

use crate::cie_data::{CIE_LAMBDA_START, CIE_SAMPLES, CIE_X, CIE_Y, CIE_Z};
use crate::metal_data::{COPPER_K, COPPER_LAMBDA, COPPER_N};
use glam::Vec3;
use penumbra_parser::SpectrumValue;
use std::sync::OnceLock;

/// Linear RGB (pbrt-v3's sRGB primaries), component-wise arithmetic.
pub type Rgb = glam::Vec3;

/// pbrt-v3's normalisation constant for the CIE y-bar integral.
pub const CIE_Y_INTEGRAL: f32 = 106.856_895;

/// pbrt-v3's luminance weights (`RGBSpectrum::y()`, the Y row of its RGB→XYZ matrix).
pub const LUMINANCE_WEIGHTS: Vec3 = Vec3::new(0.212_671, 0.715_16, 0.072_169);

/// Why a spectrum value could not be converted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpectrumError {
    #[error("{kind} spectrum has no values (expected a multiple of {arity})")]
    Empty { kind: &'static str, arity: usize },
    #[error("sampled spectrum has a non-finite wavelength or value")]
    NonFinite,
}

/// pbrt-v3's `XYZToRGB`.
pub fn xyz_to_rgb(xyz: Vec3) -> Rgb {
    Rgb::new(
        3.240_479 * xyz.x - 1.537_15 * xyz.y - 0.498_535 * xyz.z,
        -0.969_256 * xyz.x + 1.875_991 * xyz.y + 0.041_556 * xyz.z,
        0.055_648 * xyz.x - 0.204_043 * xyz.y + 1.057_311 * xyz.z,
    )
}

/// pbrt-v3's `RGBToXYZ`.
pub fn rgb_to_xyz(rgb: Rgb) -> Vec3 {
    Vec3::new(
        0.412_453 * rgb.x + 0.357_58 * rgb.y + 0.180_423 * rgb.z,
        0.212_671 * rgb.x + 0.715_16 * rgb.y + 0.072_169 * rgb.z,
        0.019_334 * rgb.x + 0.119_193 * rgb.y + 0.950_227 * rgb.z,
    )
}

/// Luminance (pbrt-v3's `Spectrum::y()` in the RGB build).
pub fn luminance(rgb: Rgb) -> f32 {
    LUMINANCE_WEIGHTS.dot(rgb)
}

/// Linear → sRGB transfer function (pbrt-v3's `GammaCorrect`), no clamping.
pub fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB → linear transfer function (pbrt-v3's `InverseGammaCorrect`), no clamping.
pub fn srgb_decode(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Wavelength (nm) of CIE table entry `i`.
#[inline]
pub fn cie_lambda(i: usize) -> f32 {
    CIE_LAMBDA_START + i as f32
}

/// Piecewise-linear interpolation of sorted samples at `l`, constant beyond the
/// ends (pbrt-v3's `InterpolateSpectrumSamples`). Returns 0 for no samples.
pub fn interpolate_samples(lambda: &[f32], vals: &[f32], l: f32) -> f32 {
    let n = lambda.len().min(vals.len());
    if n == 0 {
        return 0.0;
    }
    if l <= lambda[0] {
        return vals[0];
    }
    if l >= lambda[n - 1] {
        return vals[n - 1];
    }
    // Largest i with lambda[i] <= l, clamped to [0, n - 2].
    let i = lambda[..n].partition_point(|&x| x <= l).saturating_sub(1).min(n - 2);
    let (l0, l1) = (lambda[i], lambda[i + 1]);
    let t = (l - l0) / (l1 - l0);
    (1.0 - t) * vals[i] + t * vals[i + 1]
}

/// XYZ of a piecewise-linear spectrum given as (λ in nm, value) samples, as
/// pbrt-v3's `RGBSpectrum::FromSampled` computes it (before its XYZ→RGB step).
/// Unsorted samples are sorted by (λ, value) first, as pbrt-v3 does.
pub fn sampled_to_xyz(lambda: &[f32], vals: &[f32]) -> Result<Vec3, SpectrumError> {
    let n = lambda.len().min(vals.len());
    if n == 0 {
        return Err(SpectrumError::Empty { kind: "sampled", arity: 2 });
    }
    if lambda[..n].iter().chain(&vals[..n]).any(|v| !v.is_finite()) {
        return Err(SpectrumError::NonFinite);
    }
    let sorted = lambda[..n].windows(2).all(|w| w[0] <= w[1]);
    let (l, v): (Vec<f32>, Vec<f32>) = if sorted {
        (lambda[..n].to_vec(), vals[..n].to_vec())
    } else {
        let mut pairs: Vec<(f32, f32)> = lambda[..n].iter().copied().zip(vals[..n].iter().copied()).collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        pairs.into_iter().unzip()
    };
    let mut xyz = [0.0f64; 3];
    for i in 0..CIE_SAMPLES {
        let s = interpolate_samples(&l, &v, cie_lambda(i)) as f64;
        xyz[0] += s * CIE_X[i] as f64;
        xyz[1] += s * CIE_Y[i] as f64;
        xyz[2] += s * CIE_Z[i] as f64;
    }
    let scale = (CIE_SAMPLES as f64 - 1.0) / (CIE_Y_INTEGRAL as f64 * CIE_SAMPLES as f64);
    Ok(Vec3::new((xyz[0] * scale) as f32, (xyz[1] * scale) as f32, (xyz[2] * scale) as f32))
}

/// RGB of a sampled spectrum (pbrt-v3's `RGBSpectrum::FromSampled`).
pub fn sampled_to_rgb(lambda: &[f32], vals: &[f32]) -> Result<Rgb, SpectrumError> {
    sampled_to_xyz(lambda, vals).map(xyz_to_rgb)
}

/// [`sampled_to_rgb`] of interleaved `[λ0, v0, λ1, v1, …]` (a trailing odd value is ignored, as pbrt-v3).
pub fn interleaved_to_rgb(pairs: &[f32]) -> Result<Rgb, SpectrumError> {
    let n = pairs.len() / 2;
    let l: Vec<f32> = (0..n).map(|i| pairs[2 * i]).collect();
    let v: Vec<f32> = (0..n).map(|i| pairs[2 * i + 1]).collect();
    sampled_to_rgb(&l, &v)
}

/// Planck's law: emitted radiance of a blackbody at temperature `t` (K) at
/// wavelength `lambda_nm`, in W·sr⁻¹·m⁻³ (pbrt-v3's `Blackbody`; 0 for `t <= 0`).
pub fn blackbody(lambda_nm: f32, t: f32) -> f32 {
    if t.is_nan() || t <= 0.0 {
        return 0.0;
    }
    blackbody_f64(lambda_nm as f64, t as f64) as f32
}

fn blackbody_f64(lambda_nm: f64, t: f64) -> f64 {
    const C: f64 = 299_792_458.0;
    const H: f64 = 6.626_069_57e-34;
    const KB: f64 = 1.380_648_8e-23;
    let l = lambda_nm * 1e-9;
    let l5 = (l * l) * (l * l) * l;
    let le = (2.0 * H * C * C) / (l5 * ((H * C / (l * KB * t)).exp() - 1.0));
    if le.is_finite() {
        le
    } else {
        0.0
    }
}

/// Planck's law normalised by its maximum over wavelength (pbrt-v3's `BlackbodyNormalized`).
pub fn blackbody_normalized(lambda_nm: f32, t: f32) -> f32 {
    if t.is_nan() || t <= 0.0 || t.is_infinite() {
        return 0.0;
    }
    let t = t as f64;
    let lambda_max = 2.897_772_1e-3 / t * 1e9;
    let max_l = blackbody_f64(lambda_max, t);
    if max_l.is_nan() || max_l <= 0.0 {
        return 0.0;
    }
    (blackbody_f64(lambda_nm as f64, t) / max_l) as f32
}

/// RGB of `blackbody` `[t scale]`, as pbrt-v3's `ParamSet::AddBlackbodySpectrum`:
/// the normalised Planck spectrum sampled at the CIE wavelengths, converted with
/// [`sampled_to_rgb`], times `scale`. A non-positive temperature gives black.
pub fn blackbody_to_rgb(t: f32, scale: f32) -> Rgb {
    let lambda: Vec<f32> = (0..CIE_SAMPLES).map(cie_lambda).collect();
    let vals: Vec<f32> = lambda.iter().map(|&l| blackbody_normalized(l, t)).collect();
    sampled_to_rgb(&lambda, &vals).unwrap_or(Rgb::ZERO) * scale
}

/// All RGB values of a spectrum parameter (pbrt-v3 keeps every tuple; materials
/// then use the first). A `spectrum` parameter is a single spectrum.
pub fn spectrum_values_to_rgb(v: &SpectrumValue) -> Result<Vec<Rgb>, SpectrumError> {
    let out: Vec<Rgb> = match v {
        SpectrumValue::Rgb(x) => x.chunks_exact(3).map(|c| Rgb::new(c[0], c[1], c[2])).collect(),
        SpectrumValue::Xyz(x) => x.chunks_exact(3).map(|c| xyz_to_rgb(Vec3::new(c[0], c[1], c[2]))).collect(),
        SpectrumValue::Blackbody(x) => x.chunks_exact(2).map(|c| blackbody_to_rgb(c[0], c[1])).collect(),
        SpectrumValue::Sampled(x) => vec![interleaved_to_rgb(x)?],
    };
    if out.is_empty() {
        let (kind, arity) = match v {
            SpectrumValue::Rgb(_) => ("rgb", 3),
            SpectrumValue::Xyz(_) => ("xyz", 3),
            SpectrumValue::Blackbody(_) => ("blackbody", 2),
            SpectrumValue::Sampled(_) => ("sampled", 2),
        };
        return Err(SpectrumError::Empty { kind, arity });
    }
    Ok(out)
}

/// The (first) RGB value of a spectrum parameter.
pub fn spectrum_to_rgb(v: &SpectrumValue) -> Result<Rgb, SpectrumError> {
    spectrum_values_to_rgb(v).map(|all| all[0])
}

/// Copper's index of refraction as RGB: the default `eta` of pbrt-v3's `metal`
/// material, pbrt-v3's own copper table (`metal_data.rs`) converted as pbrt-v3's RGB build
/// converts it (`RGBSpectrum::FromSampled`, [`sampled_to_rgb`]).
pub fn copper_eta() -> Rgb {
    static V: OnceLock<Rgb> = OnceLock::new();
    *V.get_or_init(|| sampled_to_rgb(&COPPER_LAMBDA, &COPPER_N).unwrap_or(Rgb::new(0.2, 0.922, 1.1)))
}

/// Copper's extinction coefficient as RGB: the default `k` of pbrt-v3's `metal` material.
pub fn copper_k() -> Rgb {
    static V: OnceLock<Rgb> = OnceLock::new();
    *V.get_or_init(|| sampled_to_rgb(&COPPER_LAMBDA, &COPPER_K).unwrap_or(Rgb::new(3.905, 2.448, 2.138)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Rgb, b: Rgb, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn xyz_to_rgb_known_value_and_round_trip() {
        let rgb = xyz_to_rgb(Vec3::new(0.5, 0.4, 0.3));
        assert!(close(rgb, Rgb::new(0.855_819, 0.278_235_2, 0.263_400_1), 1e-6), "{rgb}");
        for c in [Rgb::new(0.2, 0.5, 0.9), Rgb::new(1.0, 0.0, 0.0), Rgb::new(3.0, 2.0, 0.1)] {
            let back = xyz_to_rgb(rgb_to_xyz(c));
            assert!(close(back, c, 2e-4 * c.max_element().max(1.0)), "{c} -> {back}");
        }
        // D65 white (Y = 1) maps to RGB ≈ (1, 1, 1): the matrices are sRGB/D65.
        let white = xyz_to_rgb(Vec3::new(0.950_47, 1.0, 1.088_83));
        assert!(close(white, Rgb::ONE, 2e-3), "{white}");
    }

    #[test]
    fn luminance_weights() {
        assert!((luminance(Rgb::ONE) - 1.0).abs() < 1e-6);
        assert_eq!(luminance(Rgb::new(0.0, 1.0, 0.0)), 0.715_16);
        assert!((luminance(Rgb::new(0.3, 0.6, 0.1)) - rgb_to_xyz(Rgb::new(0.3, 0.6, 0.1)).y).abs() < 1e-7);
    }

    #[test]
    fn srgb_round_trip_and_known_points() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.18) - 0.461_356).abs() < 1e-5);
        for i in 0..=1000 {
            let v = i as f32 / 1000.0;
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 2e-6, "{v}");
            assert!((srgb_encode(srgb_decode(v)) - v).abs() < 2e-6, "{v}");
        }
    }

    #[test]
    fn cie_table_matches_pbrt_normalisation() {
        // pbrt-v3's CIE_Y_integral is the sum of its 1 nm y-bar table; ours agrees.
        let sum: f64 = CIE_Y.iter().map(|&v| v as f64).sum();
        assert!((sum - CIE_Y_INTEGRAL as f64).abs() < 1e-3, "{sum}");
        assert_eq!(CIE_X[0], 0.000_129_9);
        assert_eq!(cie_lambda(CIE_SAMPLES - 1), 830.0);
    }

    #[test]
    fn constant_spectrum_gives_pbrt_v3_rgb() {
        // An equal-energy spectrum is not sRGB white: pbrt-v3 gives XYZ ≈ (0.99796,
        // 0.99788, 0.99821) (the 470/471 factor of its Riemann sum) and hence
        // RGB ≈ (1.2023, 0.9462, 0.9073). Reference from an independent numpy implementation.
        let xyz = sampled_to_xyz(&[300.0, 900.0], &[1.0, 1.0]).unwrap();
        assert!(close(xyz, Vec3::new(0.997_956_9, 0.997_877_1, 0.998_207), 2e-6), "{xyz}");
        assert!((xyz.y - 470.0 / 471.0).abs() < 1e-5);
        let rgb = sampled_to_rgb(&[500.0], &[1.0]).unwrap();
        assert!(close(rgb, Rgb::new(1.202_330_6, 0.946_214_1, 0.907_339_8), 2e-5), "{rgb}");
        // Linear in the values.
        let rgb3 = sampled_to_rgb(&[400.0, 700.0], &[3.0, 3.0]).unwrap();
        assert!(close(rgb3, 3.0 * rgb, 1e-5));
    }

    #[test]
    fn unsorted_samples_are_sorted_as_pbrt() {
        let a = sampled_to_rgb(&[400.0, 500.0, 600.0, 700.0], &[0.1, 0.9, 0.3, 0.5]).unwrap();
        let b = sampled_to_rgb(&[600.0, 400.0, 700.0, 500.0], &[0.3, 0.1, 0.5, 0.9]).unwrap();
        assert_eq!(a, b);
        let c = interleaved_to_rgb(&[700.0, 0.5, 500.0, 0.9, 400.0, 0.1, 600.0, 0.3, 42.0]).unwrap();
        assert_eq!(a, c);
        // A narrow band at 550 nm is green-dominated.
        let g = sampled_to_rgb(&[540.0, 545.0, 555.0, 560.0], &[0.0, 1.0, 1.0, 0.0]).unwrap();
        assert!(g.y > g.x && g.y > g.z, "{g}");
    }

    #[test]
    fn interpolation_matches_piecewise_linear() {
        let l = [400.0, 500.0, 500.0, 600.0];
        let v = [1.0, 3.0, 5.0, 7.0];
        assert_eq!(interpolate_samples(&l, &v, 300.0), 1.0);
        assert_eq!(interpolate_samples(&l, &v, 450.0), 2.0);
        assert_eq!(interpolate_samples(&l, &v, 550.0), 6.0);
        assert_eq!(interpolate_samples(&l, &v, 650.0), 7.0);
        assert_eq!(interpolate_samples(&[], &[], 650.0), 0.0);
    }

    #[test]
    fn blackbody_planck_and_normalisation() {
        // Planck radiance reference values (spectralcalc.com), as pbrt-v3's own test.
        for (l, t, expect) in [(483.0, 6000.0, 3.1849e13), (600.0, 6000.0, 2.86772e13), (500.0, 3700.0, 1.59845e12)] {
            let le = blackbody(l, t);
            assert!(((le - expect) / expect).abs() < 1e-3, "{l} {t} {le}");
        }
        for t in [2700.0f32, 4500.0, 6500.0] {
            let peak = 2.897_772e-3 / t * 1e9;
            assert!((blackbody_normalized(peak, t) - 1.0).abs() < 1e-6);
            assert!(blackbody_normalized(peak * 0.99, t) < 1.0 && blackbody_normalized(peak * 1.01, t) < 1.0);
        }
        assert_eq!(blackbody(500.0, 0.0), 0.0);
        assert_eq!(blackbody_to_rgb(-5.0, 1.0), Rgb::ZERO);
    }

    #[test]
    fn blackbody_6500_is_near_white_and_2700_is_warm() {
        let w = blackbody_to_rgb(6500.0, 1.0);
        assert!(close(w, Rgb::new(0.922_219_8, 0.869_495_2, 0.915_217_2), 1e-4), "{w}");
        assert!(w.max_element() / w.min_element() < 1.07, "{w}");
        let warm = blackbody_to_rgb(2700.0, 2.0);
        assert!(close(warm, 2.0 * Rgb::new(0.533_494_4, 0.221_570_6, 0.052_901_8), 2e-4), "{warm}");
        let v = spectrum_values_to_rgb(&SpectrumValue::Blackbody(vec![6500.0, 1.0, 2700.0, 2.0])).unwrap();
        assert_eq!(v, vec![w, warm]);
    }

    #[test]
    fn spectrum_value_dispatch_and_errors() {
        let rgb = spectrum_to_rgb(&SpectrumValue::Rgb(vec![0.1, 0.2, 0.3, 9.0])).unwrap();
        assert_eq!(rgb, Rgb::new(0.1, 0.2, 0.3));
        let xyz = spectrum_to_rgb(&SpectrumValue::Xyz(vec![0.5, 0.4, 0.3])).unwrap();
        assert_eq!(xyz, xyz_to_rgb(Vec3::new(0.5, 0.4, 0.3)));
        assert!(spectrum_to_rgb(&SpectrumValue::Rgb(vec![0.1, 0.2])).is_err());
        assert!(spectrum_to_rgb(&SpectrumValue::Sampled(vec![400.0])).is_err());
        assert!(spectrum_to_rgb(&SpectrumValue::Blackbody(vec![])).is_err());
        assert_eq!(spectrum_to_rgb(&SpectrumValue::Sampled(vec![f32::NAN, 1.0])), Err(SpectrumError::NonFinite));
    }

    #[test]
    fn copper_matches_pbrt_v3() {
        // pbrt-v3's default metal: its copper table through its RGBSpectrum::FromSampled, as
        // computed by an independent numpy implementation from pbrt-v3's own CIE tables and
        // constants (its CIE y-bar differs from ours by 6.3e-5 at one wavelength: < 1e-6 here).
        let eta = copper_eta();
        let k = copper_k();
        assert!(close(eta, Rgb::new(0.199_989_72, 0.922_085_79, 1.099_876_3), 2e-6), "{eta}");
        assert!(close(k, Rgb::new(3.904_638_2, 2.447_633_2, 2.137_651), 4e-6), "{k}");
    }

    /// The table's entries between its 0.1 eV grid points are 4-point Catmull-Rom midpoints of
    /// their neighbours (to the table's 6 decimals): how the table was made, see `metal_data.rs`.
    #[test]
    fn copper_table_midpoints_are_catmull_rom() {
        for v in [&COPPER_N, &COPPER_K] {
            // Entries 0 and 2 need grid points beyond the table's start.
            for i in (4..54).step_by(2) {
                let cr = (-v[i - 3] + 9.0 * v[i - 1] + 9.0 * v[i + 1] - v[i + 3]) / 16.0;
                assert!((cr - v[i]).abs() < 1e-6, "entry {i}: {} vs Catmull-Rom {cr}", v[i]);
            }
        }
        // 0.05 eV steps: E = 1239.84178 / λ runs 4.15, 4.10, …, 1.40 eV.
        for (i, l) in COPPER_LAMBDA.iter().enumerate() {
            let e = 1_239.841_8 / *l as f64;
            assert!((e - (4.15 - 0.05 * i as f64)).abs() < 1e-6, "{i}: {e} eV");
        }
    }
}
