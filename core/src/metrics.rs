//! Image error metrics, with OpenImageIO `idiff`'s definitions where it has one.
//!
//! # The idiff numbers ([`compare`])
//! Images A (the first, "test") and B (the second, "reference") must have the
//! same size and the same channel names (B's channels are matched to A's by
//! name; `idiff` matches them by position, which is the same thing for files
//! our readers return, as they order channels the way OpenImageIO does).
//! Every value pair `(a, b)` — all pixels, all channels, in row-major order,
//! channels innermost — is classified:
//!
//! - **both finite**: the error is `f = |a − b|`, computed in `f32` (as OIIO
//!   does) and accumulated in `f64`.
//!   - `mean_error = Σ f / N` and `rms_error = sqrt(Σ f² / N)`, where **N is the
//!     number of all values** (`width · height · channels`), non-finite pairs
//!     included, exactly as OIIO divides by `npels · nchannels`.
//!   - `max_error` is the largest `f`, and its location `(x, y, c)` is the
//!     **first** value (in scan order) that reaches it (OIIO updates only on a
//!     strictly larger error).
//!   - A pixel is counted in `nwarn` (`nfail`) if **any** of its channels has
//!     `f > warn` (`f > fail`): these are pixel counts, not value counts.
//!   - PSNR's peak: OIIO assumes a peak of 1.0 but raises it to the largest
//!     absolute value seen in either image (over finite pairs), so
//!     `psnr = 20 · log10(max(1, max|a|, max|b|) / rms_error)`; `+inf` when the
//!     images are identical.
//! - **matching non-finite** (both NaN, or the same infinity): skipped, as in
//!   OIIO (no error, but still counted in N).
//! - **mismatched non-finite** (NaN or ±Inf against anything else): OIIO sets
//!   `max_error = inf` at the first such value and does not add it to the sums;
//!   **we do the same for every such value**, so means stay finite (OIIO adds
//!   the second and later mismatches into its sums, making its mean/RMS NaN or
//!   Inf). Unlike OIIO, which forgets to count the first mismatch, every pixel
//!   with a mismatched non-finite value counts as over both thresholds, so a
//!   NaN always fails the comparison. NaN/Inf counts per image are reported
//!   separately (`nan_a`, `inf_a`, `nan_b`, `inf_b`, `nonfinite_mismatched`).
//!
//! Pass/warn/fail follows idiff ([`CompareResults::status`]): fail if
//! `nfail > failpercent/100 · npixels` or `max_error > hardfail`; else warn if
//! `nwarn > warnpercent/100 · npixels` or `max_error > hardwarn`; else pass.
//!
//! # Extra metrics (not in idiff)
//! Over finite pairs only, divided by their count:
//! - `mse` = mean (a − b)² (note: `rms_error²` differs when non-finite pairs exist),
//! - `relmse` = mean (a − b)² / (b² + ε), ε = [`RELMSE_EPSILON`] = 1e-2 (B is the
//!   reference),
//! - `smape` = mean 2|a − b| / (|a| + |b|), with 0 where both are 0 (range [0, 2]).

use thiserror::Error;

use crate::image::Image;

/// The ε in relative MSE's denominator `b² + ε`.
pub const RELMSE_EPSILON: f64 = 1e-2;

/// Why two images cannot be compared.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MetricsError {
    /// Different pixel dimensions.
    #[error("images have different sizes: {}×{} vs {}×{}", a.0, a.1, b.0, b.1)]
    SizeMismatch {
        /// A's width and height.
        a: (u32, u32),
        /// B's width and height.
        b: (u32, u32),
    },
    /// Different channel sets.
    #[error("images have different channels: [{}] vs [{}] (compare common ones with e.g. --channels R,G,B)", a.join(", "), b.join(", "))]
    ChannelMismatch {
        /// A's channels.
        a: Vec<String>,
        /// B's channels.
        b: Vec<String>,
    },
    /// Inconsistent image (data length does not match its size).
    #[error("inconsistent image: {0}")]
    Invalid(String),
}

/// Outcome of a comparison, with idiff's exit codes as discriminants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    /// Within thresholds (exit code 0).
    Pass = 0,
    /// Over the warning threshold (exit code 1).
    Warn = 1,
    /// Over the failure threshold (exit code 2).
    Fail = 2,
}

/// Thresholds, as idiff's options of the same names.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// Per-value warning threshold (`-warn`, default 1e-6).
    pub warn: f32,
    /// Per-value failure threshold (`-fail`, default 1e-6).
    pub fail: f32,
    /// Percentage of pixels allowed over `warn` (`-warnpercent`, default 0).
    pub warnpercent: f32,
    /// Percentage of pixels allowed over `fail` (`-failpercent`, default 0).
    pub failpercent: f32,
    /// Warn if the max error exceeds this (`-hardwarn`, default +inf).
    pub hardwarn: f32,
    /// Fail if the max error exceeds this (`-hardfail`, default +inf).
    pub hardfail: f32,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            warn: 1e-6,
            fail: 1e-6,
            warnpercent: 0.0,
            failpercent: 0.0,
            hardwarn: f32::INFINITY,
            hardfail: f32::INFINITY,
        }
    }
}

/// The result of [`compare`]. See the module documentation for definitions.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareResults {
    /// Width of the compared images.
    pub width: u32,
    /// Height of the compared images.
    pub height: u32,
    /// Channel names (A's order).
    pub channels: Vec<String>,
    /// Number of pixels.
    pub npixels: u64,
    /// Number of values (pixels × channels): the denominator of mean and RMS.
    pub nvalues: u64,
    /// idiff's mean error.
    pub mean_error: f64,
    /// idiff's RMS error.
    pub rms_error: f64,
    /// idiff's peak signal-to-noise ratio, dB.
    pub psnr: f64,
    /// The peak used by the PSNR: max(1, largest |value| over finite pairs).
    pub psnr_peak: f64,
    /// Largest absolute error (+inf if a non-finite value mismatches).
    pub max_error: f64,
    /// Pixel x of the max error (0 if there is no error).
    pub max_x: u32,
    /// Pixel y of the max error.
    pub max_y: u32,
    /// Channel index of the max error.
    pub max_c: usize,
    /// Pixels with some channel error over the warning threshold.
    pub nwarn: u64,
    /// Pixels with some channel error over the failure threshold.
    pub nfail: u64,
    /// NaN values in A.
    pub nan_a: u64,
    /// ±Inf values in A.
    pub inf_a: u64,
    /// NaN values in B.
    pub nan_b: u64,
    /// ±Inf values in B.
    pub inf_b: u64,
    /// Value pairs where both are NaN or both the same infinity (skipped).
    pub nonfinite_matched: u64,
    /// Value pairs where a NaN/Inf meets something else.
    pub nonfinite_mismatched: u64,
    /// Value pairs where both are finite.
    pub finite_values: u64,
    /// Mean squared error over finite pairs.
    pub mse: f64,
    /// Relative MSE over finite pairs: mean (a−b)²/(b²+ε).
    pub relmse: f64,
    /// Symmetric mean absolute percentage error over finite pairs, in [0, 2].
    pub smape: f64,
}

impl CompareResults {
    /// idiff's verdict for these thresholds.
    pub fn status(&self, t: &Thresholds) -> Status {
        let np = self.npixels as f64;
        if self.nfail as f64 > t.failpercent as f64 / 100.0 * np || self.max_error > t.hardfail as f64 {
            Status::Fail
        } else if self.nwarn as f64 > t.warnpercent as f64 / 100.0 * np || self.max_error > t.hardwarn as f64 {
            Status::Warn
        } else {
            Status::Pass
        }
    }

    /// Name of the channel of the max error.
    pub fn max_channel_name(&self) -> &str {
        self.channels.get(self.max_c).map(String::as_str).unwrap_or("?")
    }
}

fn check_consistent(img: &Image, which: &str) -> Result<(), MetricsError> {
    if img.npixels() == 0 {
        return Err(MetricsError::Invalid(format!("image {which} is empty")));
    }
    if img.channels.is_empty() || img.data.len() != img.npixels() * img.nchannels() {
        return Err(MetricsError::Invalid(format!("image {which} has {} values for its size", img.data.len())));
    }
    Ok(())
}

/// For each of A's channels, the index of the same-named channel in B.
fn channel_map(a: &Image, b: &Image) -> Result<Vec<usize>, MetricsError> {
    let mismatch = || MetricsError::ChannelMismatch { a: a.channels.clone(), b: b.channels.clone() };
    if a.nchannels() != b.nchannels() {
        return Err(mismatch());
    }
    a.channels.iter().map(|n| b.channel_index(n).ok_or_else(mismatch)).collect()
}

fn check_pair(a: &Image, b: &Image) -> Result<Vec<usize>, MetricsError> {
    check_consistent(a, "A")?;
    check_consistent(b, "B")?;
    if (a.width, a.height) != (b.width, b.height) {
        return Err(MetricsError::SizeMismatch { a: (a.width, a.height), b: (b.width, b.height) });
    }
    channel_map(a, b)
}

/// Compares A (test) against B (reference) with idiff's definitions (see the
/// module documentation) and the thresholds' `warn`/`fail` values.
pub fn compare(a: &Image, b: &Image, warn: f32, fail: f32) -> Result<CompareResults, MetricsError> {
    let map = check_pair(a, b)?;
    let n = a.nchannels();
    let mut r = CompareResults {
        width: a.width,
        height: a.height,
        channels: a.channels.clone(),
        npixels: a.npixels() as u64,
        nvalues: (a.npixels() * n) as u64,
        mean_error: 0.0,
        rms_error: 0.0,
        psnr: 0.0,
        psnr_peak: 1.0,
        max_error: 0.0,
        max_x: 0,
        max_y: 0,
        max_c: 0,
        nwarn: 0,
        nfail: 0,
        nan_a: 0,
        inf_a: 0,
        nan_b: 0,
        inf_b: 0,
        nonfinite_matched: 0,
        nonfinite_mismatched: 0,
        finite_values: 0,
        mse: 0.0,
        relmse: 0.0,
        smape: 0.0,
    };
    let (mut sum, mut sum2, mut rel, mut smape) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut peak = 1.0f32;
    let w = a.width.max(1) as usize;
    for (i, (pa, pb)) in a.data.chunks_exact(n).zip(b.data.chunks_exact(n)).enumerate() {
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        let (mut warned, mut failed) = (false, false);
        for (c, (&av, &bi)) in pa.iter().zip(&map).enumerate() {
            let bv = pb[bi];
            r.nan_a += av.is_nan() as u64;
            r.inf_a += av.is_infinite() as u64;
            r.nan_b += bv.is_nan() as u64;
            r.inf_b += bv.is_infinite() as u64;
            if !av.is_finite() || !bv.is_finite() {
                if (av.is_nan() && bv.is_nan()) || av == bv {
                    r.nonfinite_matched += 1;
                    continue;
                }
                r.nonfinite_mismatched += 1;
                if r.max_error.is_finite() {
                    r.max_error = f64::INFINITY;
                    (r.max_x, r.max_y, r.max_c) = (x, y, c);
                }
                warned = true;
                failed = true;
                continue;
            }
            r.finite_values += 1;
            peak = peak.max(av.abs()).max(bv.abs());
            let f = (av - bv).abs() as f64;
            sum += f;
            sum2 += f * f;
            let (ad, bd) = (av as f64, bv as f64);
            rel += (ad - bd) * (ad - bd) / (bd * bd + RELMSE_EPSILON);
            let denom = ad.abs() + bd.abs();
            if denom > 0.0 {
                smape += 2.0 * (ad - bd).abs() / denom;
            }
            if f > r.max_error {
                r.max_error = f;
                (r.max_x, r.max_y, r.max_c) = (x, y, c);
            }
            warned |= f > warn as f64;
            failed |= f > fail as f64;
        }
        r.nwarn += warned as u64;
        r.nfail += failed as u64;
    }
    let nv = r.nvalues.max(1) as f64;
    r.mean_error = sum / nv;
    r.rms_error = (sum2 / nv).sqrt();
    r.psnr_peak = peak as f64;
    r.psnr = 20.0 * (r.psnr_peak / r.rms_error).log10();
    let nf = r.finite_values.max(1) as f64;
    r.mse = sum2 / nf;
    r.relmse = rel / nf;
    r.smape = smape / nf;
    Ok(r)
}

/// Per-pixel error used by heat maps: the largest `|a − b|` over channels;
/// +inf where a non-finite value mismatches, 0 where non-finite values match.
pub fn error_map(a: &Image, b: &Image) -> Result<Vec<f32>, MetricsError> {
    let map = check_pair(a, b)?;
    let n = a.nchannels();
    Ok(a.data
        .chunks_exact(n)
        .zip(b.data.chunks_exact(n))
        .map(|(pa, pb)| {
            pa.iter().zip(&map).fold(0.0f32, |m, (&av, &bi)| {
                let bv = pb[bi];
                let e = if av.is_finite() && bv.is_finite() {
                    (av - bv).abs()
                } else if (av.is_nan() && bv.is_nan()) || av == bv {
                    0.0
                } else {
                    f32::INFINITY
                };
                m.max(e)
            })
        })
        .collect())
}

/// Per-value z-scores of an estimate A against a reference B.
#[derive(Debug, Clone, PartialEq)]
pub struct ZScores {
    /// Width of the images.
    pub width: u32,
    /// Height of the images.
    pub height: u32,
    /// Number of channels compared.
    pub nchannels: usize,
    /// `z = (a − b) / sqrt(var_a + var_b)`, per value (interleaved like
    /// [`Image::data`]). Where the variance sum is 0: 0 if `a == b`, else ±inf.
    /// NaN where any input is non-finite or a variance is negative.
    pub z: Vec<f64>,
}

impl ZScores {
    /// Fraction of values with `|z| > t` (a NaN z counts as over).
    pub fn fraction_values_above(&self, t: f64) -> f64 {
        if self.z.is_empty() {
            return 0.0;
        }
        self.z.iter().filter(|z| z.is_nan() || z.abs() > t).count() as f64 / self.z.len() as f64
    }

    /// Fraction of pixels with some channel's `|z| > t` (NaN counts as over).
    pub fn fraction_pixels_above(&self, t: f64) -> f64 {
        let n = self.nchannels.max(1);
        let np = self.z.len() / n;
        if np == 0 {
            return 0.0;
        }
        self.z.chunks_exact(n).filter(|p| p.iter().any(|z| z.is_nan() || z.abs() > t)).count() as f64 / np as f64
    }

    /// Mean of z over finite values (≈ 0 for an unbiased estimate).
    pub fn mean(&self) -> f64 {
        let (s, k) = self.z.iter().filter(|z| z.is_finite()).fold((0.0, 0usize), |(s, k), z| (s + z, k + 1));
        if k == 0 {
            0.0
        } else {
            s / k as f64
        }
    }

    /// Mean of z² over finite values (≈ 1 when the variances are right).
    pub fn mean_square(&self) -> f64 {
        let (s, k) = self.z.iter().filter(|z| z.is_finite()).fold((0.0, 0usize), |(s, k), z| (s + z * z, k + 1));
        if k == 0 {
            0.0
        } else {
            s / k as f64
        }
    }

    /// Largest |z| (NaN-free; +inf if any z is infinite).
    pub fn max_abs(&self) -> f64 {
        self.z.iter().filter(|z| !z.is_nan()).fold(0.0, |m, z| m.max(z.abs()))
    }
}

/// z-scores of the per-pixel estimate `a` (with `a_var`, the variance **of the
/// estimate**, i.e. of the pixel mean, not of single samples) against the
/// reference `b` (with `b_var`, or exact if `None`). All images must have the
/// same size; `a_var`, `b` and `b_var` are matched to `a`'s channels by name
/// (so pass e.g. `a.select_channels(["variance.R",…])` renamed, or build them
/// with matching names).
pub fn z_scores(a: &Image, a_var: &Image, b: &Image, b_var: Option<&Image>) -> Result<ZScores, MetricsError> {
    let mb = check_pair(a, b)?;
    let mva = check_pair(a, a_var)?;
    let mvb = match b_var {
        Some(v) => Some(check_pair(a, v)?),
        None => None,
    };
    let n = a.nchannels();
    let mut z = Vec::with_capacity(a.data.len());
    for i in 0..a.npixels() {
        for c in 0..n {
            let av = a.data[i * n + c] as f64;
            let bv = b.data[i * n + mb[c]] as f64;
            let va = a_var.data[i * n + mva[c]] as f64;
            let vb = match (b_var, &mvb) {
                (Some(v), Some(m)) => v.data[i * n + m[c]] as f64,
                _ => 0.0,
            };
            let var = va + vb;
            let d = av - bv;
            let zz = if !d.is_finite() || !var.is_finite() || va < 0.0 || vb < 0.0 {
                f64::NAN
            } else if var == 0.0 {
                if d == 0.0 {
                    0.0
                } else {
                    d.signum() * f64::INFINITY
                }
            } else {
                d / var.sqrt()
            };
            z.push(zz);
        }
    }
    Ok(ZScores { width: a.width, height: a.height, nchannels: n, z })
}

/// Whether this build can compute FLIP (the `flip` cargo feature).
pub const FLIP_AVAILABLE: bool = cfg!(feature = "flip");

/// Mean LDR-FLIP error (NVIDIA's metric, through the `nv-flip` crate) of test
/// image `a` against reference `b`, in [0, 1]. Both are converted to 8-bit
/// sRGB first (colour channels per [`Image::rgb_indices`], clamped, like
/// [`crate::image::encode_png`] with exposure 0), so for HDR images this is the
/// FLIP of the clamped display images. `pixels_per_degree` is the viewing
/// condition (FLIP's default is 67).
#[cfg(feature = "flip")]
pub fn flip_mean(a: &Image, b: &Image, pixels_per_degree: f32) -> Result<f64, MetricsError> {
    check_pair(a, b)?;
    let to8 = |img: &Image, which: &str| -> Result<Vec<u8>, MetricsError> {
        let rgb = img.to_rgb().ok_or_else(|| MetricsError::Invalid(format!("image {which} has no colour channels")))?;
        Ok(rgb
            .iter()
            .flat_map(|p| p.to_array())
            .map(|v| {
                let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
                (crate::spectrum::srgb_encode(v) * 255.0 + 0.5) as u8
            })
            .collect())
    };
    let (da, db) = (to8(a, "A")?, to8(b, "B")?);
    let test = nv_flip::FlipImageRgb8::with_data(a.width, a.height, &da);
    let reference = nv_flip::FlipImageRgb8::with_data(b.width, b.height, &db);
    let err = nv_flip::flip(reference, test, pixels_per_degree);
    Ok(nv_flip::FlipPool::from_image(&err).mean() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::channel_names;

    fn img2x2(data: [f32; 12]) -> Image {
        Image::from_data(2, 2, channel_names(&["R", "G", "B"]), data.to_vec()).unwrap()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn hand_computed_2x2() {
        let b = img2x2([0.0, 0.5, 1.0, 0.2, 0.2, 0.2, 2.0, 0.0, 0.0, 0.1, 0.1, 0.1]);
        let a = img2x2([0.0, 0.5, 1.0, 0.2, 0.2, 0.7, 2.0, 0.0, 0.0, 0.1, 0.1, 0.1]);
        // One value differs by 0.5 (pixel (1,0), channel B). Errors computed in f32.
        let r = compare(&a, &b, 0.1, 0.6).unwrap();
        let f = (0.7f32 - 0.2f32) as f64;
        assert!(close(r.mean_error, f / 12.0));
        assert!(close(r.rms_error, (f * f / 12.0).sqrt()));
        assert_eq!((r.max_x, r.max_y, r.max_c), (1, 0, 2));
        assert!(close(r.max_error, f));
        // Peak raised to the largest |value|, 2.0.
        assert_eq!(r.psnr_peak, 2.0);
        assert!(close(r.psnr, 20.0 * (2.0 / r.rms_error).log10()));
        assert_eq!((r.nwarn, r.nfail), (1, 0));
        assert_eq!(r.status(&Thresholds { warn: 0.1, fail: 0.6, ..Default::default() }), Status::Warn);
        let (a64, b64) = (0.7f32 as f64, 0.2f32 as f64);
        let rel = (a64 - b64).powi(2) / (b64 * b64 + 1e-2) / 12.0;
        assert!(close(r.relmse, rel), "{} vs {rel}", r.relmse);
        let sm = 2.0 * (a64 - b64) / (a64 + b64) / 12.0;
        assert!(close(r.smape, sm));
        assert!(close(r.mse, f * f / 12.0));
    }

    #[test]
    fn identical_images_pass_with_infinite_psnr() {
        let a = img2x2([0.3; 12]);
        let r = compare(&a, &a, 0.0, 0.0).unwrap();
        assert_eq!(r.mean_error, 0.0);
        assert_eq!(r.psnr, f64::INFINITY);
        assert_eq!(r.max_error, 0.0);
        assert_eq!(r.status(&Thresholds::default()), Status::Pass);
        assert_eq!(r.smape, 0.0);
    }

    #[test]
    fn bias_and_pixel_counts() {
        let b = img2x2([0.25; 12]);
        let mut av = [0.5f32; 12];
        av[0] = 0.25; // pixel (0,0) has one exact channel but two off ones
        let a = img2x2(av);
        let r = compare(&a, &b, 0.1, 0.2).unwrap();
        assert!(close(r.mean_error, 0.25 * 11.0 / 12.0));
        assert!(close(r.rms_error, (0.0625f64 * 11.0 / 12.0).sqrt()));
        // Pixels, not values.
        assert_eq!((r.nwarn, r.nfail, r.npixels), (4, 4, 4));
        // First occurrence of the max: (0,0) channel G.
        assert_eq!((r.max_x, r.max_y, r.max_c), (0, 0, 1));
        let t = Thresholds { warn: 0.1, fail: 0.2, failpercent: 99.0, warnpercent: 100.0, ..Default::default() };
        assert_eq!(r.status(&t), Status::Fail);
        let t = Thresholds { failpercent: 100.0, ..t };
        assert_eq!(r.status(&t), Status::Pass);
        let t = Thresholds { hardwarn: 0.2, ..t };
        assert_eq!(r.status(&t), Status::Warn);
        let t = Thresholds { hardfail: 0.2, ..t };
        assert_eq!(r.status(&t), Status::Fail);
    }

    #[test]
    fn negative_values_raise_peak_by_magnitude() {
        let b = img2x2([0.0; 12]);
        let mut av = [0.0f32; 12];
        av[5] = -3.0;
        let r = compare(&img2x2(av), &b, 1e-6, 1e-6).unwrap();
        assert_eq!(r.psnr_peak, 3.0);
    }

    #[test]
    fn nan_and_inf_are_counted_not_averaged() {
        let mut bv = [0.5f32; 12];
        bv[7] = f32::INFINITY;
        let mut av = [0.5f32; 12];
        av[1] = f32::NAN; // mismatch at (0,0) G
        av[4] = 0.75; // finite error at (1,0) G
        av[7] = f32::INFINITY; // matching Inf
        av[9] = f32::NAN; // second mismatch at (1,1) R
        let r = compare(&img2x2(av), &img2x2(bv), 0.1, 0.1).unwrap();
        assert_eq!((r.nan_a, r.inf_a, r.nan_b, r.inf_b), (2, 1, 0, 1));
        assert_eq!((r.nonfinite_matched, r.nonfinite_mismatched, r.finite_values), (1, 2, 9));
        assert!(close(r.mean_error, 0.25 / 12.0));
        assert!(r.rms_error.is_finite());
        assert_eq!(r.max_error, f64::INFINITY);
        assert_eq!((r.max_x, r.max_y, r.max_c), (0, 0, 1));
        // Pixels (0,0), (1,0) and (1,1) are over the thresholds.
        assert_eq!((r.nwarn, r.nfail), (3, 3));
        assert!(close(r.mse, 0.0625 / 9.0));
        let e = error_map(&img2x2(av), &img2x2(bv)).unwrap();
        assert_eq!(e, vec![f32::INFINITY, 0.25, 0.0, f32::INFINITY]);
    }

    #[test]
    fn channels_matched_by_name_and_mismatches_refused() {
        let a = img2x2([0.1, 0.2, 0.3, 0.1, 0.2, 0.3, 0.1, 0.2, 0.3, 0.1, 0.2, 0.3]);
        let b = a.select_channels(&["B", "G", "R"]).unwrap();
        assert_eq!(compare(&a, &b, 0.0, 0.0).unwrap().max_error, 0.0);
        let c = a.select_channels(&["R", "G"]).unwrap();
        assert!(matches!(compare(&a, &c, 0.0, 0.0), Err(MetricsError::ChannelMismatch { .. })));
        let d = a.crop(0, 1, 0, 2).unwrap();
        assert!(matches!(compare(&a, &d, 0.0, 0.0), Err(MetricsError::SizeMismatch { .. })));
        let empty = Image::from_data(0, 0, channel_names(&["R", "G", "B"]), vec![]).unwrap();
        assert!(matches!(compare(&empty, &empty, 0.0, 0.0), Err(MetricsError::Invalid(_))));
    }

    #[cfg(feature = "flip")]
    #[test]
    fn flip_is_zero_for_identical_and_grows_with_error() {
        let a = img2x2([0.2, 0.4, 0.6, 0.1, 0.1, 0.1, 0.9, 0.5, 0.2, 0.3, 0.3, 0.3]);
        assert_eq!(flip_mean(&a, &a, 67.0).unwrap(), 0.0);
        let small = Image { data: a.data.iter().map(|v| v * 1.1).collect(), ..a.clone() };
        let big = Image { data: a.data.iter().map(|v| 1.0 - v).collect(), ..a.clone() };
        let (fs, fb) = (flip_mean(&small, &a, 67.0).unwrap(), flip_mean(&big, &a, 67.0).unwrap());
        assert!(0.0 < fs && fs < fb && fb <= 1.0, "{fs} {fb}");
    }

    #[test]
    fn z_scores_closed_form() {
        let a = Image::from_data(2, 1, channel_names(&["Y"]), vec![1.0, 2.0]).unwrap();
        let va = Image::from_data(2, 1, channel_names(&["Y"]), vec![0.25, 0.0]).unwrap();
        let b = Image::from_data(2, 1, channel_names(&["Y"]), vec![0.0, 2.0]).unwrap();
        let vb = Image::from_data(2, 1, channel_names(&["Y"]), vec![0.75, 1.0]).unwrap();
        let z = z_scores(&a, &va, &b, Some(&vb)).unwrap();
        assert_eq!(z.z, vec![1.0, 0.0]);
        let z = z_scores(&a, &va, &b, None).unwrap();
        assert_eq!(z.z, vec![2.0, 0.0]);
        assert_eq!(z.fraction_values_above(1.5), 0.5);
        assert_eq!(z.fraction_pixels_above(3.0), 0.0);
        assert_eq!(z.max_abs(), 2.0);
        let zero = Image::from_data(2, 1, channel_names(&["Y"]), vec![0.0, 0.0]).unwrap();
        let z = z_scores(&a, &zero, &b, None).unwrap();
        assert_eq!(z.z, vec![f64::INFINITY, 0.0]);
    }

    #[test]
    fn z_scores_of_gaussian_noise_are_standard() {
        // Deterministic pseudo-random normal noise with known per-pixel sigma:
        // about 0.27% of |z| exceed 3, and mean z² is about 1.
        let (w, h) = (200u32, 100u32);
        let mut state = 0x9E3779B97F4A7C15u64;
        let mut uni = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let n = (w * h) as usize;
        let (mut av, mut vv) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for i in 0..n {
            let sigma = 0.1 + (i % 7) as f64 * 0.05;
            let g = (-2.0 * uni().ln()).sqrt() * (2.0 * std::f64::consts::PI * uni()).cos();
            av.push((1.0 + sigma * g) as f32);
            vv.push((sigma * sigma) as f32);
        }
        let a = Image::from_data(w, h, channel_names(&["Y"]), av).unwrap();
        let v = Image::from_data(w, h, channel_names(&["Y"]), vv).unwrap();
        let b = Image::from_data(w, h, channel_names(&["Y"]), vec![1.0; n]).unwrap();
        let z = z_scores(&a, &v, &b, None).unwrap();
        let f3 = z.fraction_pixels_above(3.0);
        assert!(f3 < 0.006, "{f3}");
        assert!((z.mean_square() - 1.0).abs() < 0.05, "{}", z.mean_square());
        assert!(z.mean().abs() < 0.05);
        // A biased estimate is detected.
        let biased = Image::from_data(w, h, channel_names(&["Y"]), a.data.iter().map(|x| x + 0.3).collect()).unwrap();
        assert!(z_scores(&biased, &v, &b, None).unwrap().fraction_pixels_above(3.0) > 0.05);
    }
}
