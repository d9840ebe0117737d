//! Is the difference between a noisy render and a reference noise? Statistical tests of image
//! agreement, with a stated false-alarm rate.
//!
//! # Inputs
//! An image is a mean per value (pixel × channel) and, when it is noisy, the **variance of that
//! mean**: what `render --variance` writes (`variance.R/G/B`: the sample variance of the
//! pixel's own samples divided by their count, [`crate::film::Film::to_image`]). A reference is
//! an image too; its noise is either given per value, or known to be a multiple of the test's
//! ([`RefNoise::ScaledTest`]): when the reference was rendered by the *same estimator* (a
//! pbrt-v3 `directlighting` reference of a penumbra `directlighting` render), its per-sample
//! variance is the test's, so its variance of the mean is the test's times `n_test / n_ref`
//! (samples per value). Under the hypothesis being tested — the two renderers compute the same
//! estimator — that is exact in expectation; where they differ, the test rejects anyway.
//!
//! # Tests
//! - [`z_test`]: the difference of two independent means with known variances (the usual case:
//!   per-value variances are estimated from many samples, and pooled regions from thousands);
//!   [`welch`]: Welch's t-test when each side's variance comes from few samples (its degrees of
//!   freedom by Welch–Satterthwaite), p-values from Student's t ([`student_t_two_sided_p`]).
//! - [`test_regions`]: the mean of a region (an 8×8 block of one channel, a whole channel) of
//!   the test against the reference's: Δ̄ = mean(test − ref) over the region's values, whose
//!   variance is Σ(var_test + var_ref)/n² (values independent). A bias confined to a dim region
//!   hides in the image mean and a 1 % global bias in per-pixel noise; blocks and whole-image
//!   means between them catch both.
//! - An allowed systematic difference ([`Tolerance`]: `abs + rel·|ref|`, for methods that are
//!   approximations by design, or noise-free integrators) is subtracted from |Δ̄| before it is
//!   compared with the noise: the region's [`RegionTest::z`] is the *excess* over the tolerance
//!   in units of σ (0 within it).
//!
//! # Multiple comparisons
//! Testing many regions of many images, some |z| are large by chance. [`sidak_alpha`] gives
//! the per-test level α₁ = 1 − (1 − α)^(1/m) that keeps the probability of *any* false alarm
//! among `m` independent tests at α (the family-wise rate; conservative for positively
//! correlated tests such as a block and the image mean containing it); [`critical_z`] its
//! two-sided threshold. [`holm`] is the step-down alternative on p-values (uniformly more
//! powerful, valid under any dependence).
//!
//! # Correlated values: QMC samplers and wide filters
//! The variance channels are the *independent-sample* estimate. Under a low-discrepancy sampler
//! (halton, sobol, …) the actual error of a pixel's mean is usually smaller than that, so the
//! tests are conservative (fewer false alarms than stated, less power); under the `random`
//! sampler they are calibrated. A pixel filter wider than a pixel makes neighbouring pixels
//! share samples: per-pixel variances then misstate each pixel's, but a region's mean is still
//! a mean of about the same samples with nearly equal weights, so region tests (blocks of 8×8
//! and up) stay right; per-value tests need a box filter.

use crate::goodness_of_fit::{ln_gamma, regularized_gamma_q};

/// Two-sided p-value of a standard normal statistic: P(|Z| ≥ |z|).
pub fn normal_two_sided_p(z: f64) -> f64 {
    if z.is_nan() {
        return f64::NAN;
    }
    // P(|Z| ≥ z) = P(Z² ≥ z²) = Q(1/2, z²/2) (Z² is chi-square with one degree of freedom).
    regularized_gamma_q(0.5, 0.5 * z * z)
}

/// The two-sided critical value: the z > 0 with P(|Z| ≥ z) = `alpha` (0 < alpha ≤ 1).
pub fn critical_z(alpha: f64) -> f64 {
    if !(alpha > 0.0) {
        return f64::INFINITY;
    }
    if alpha >= 1.0 {
        return 0.0;
    }
    // Bisection on the monotone p-value (which is accurate far into the tail): 200 halvings
    // of [0, 40] reach f64's resolution.
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if normal_two_sided_p(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Šidák's per-test level: the α₁ with 1 − (1 − α₁)^m = `family_alpha`, i.e. the level at
/// which `m` independent tests have probability `family_alpha` of any false alarm.
pub fn sidak_alpha(family_alpha: f64, m: usize) -> f64 {
    if m <= 1 {
        return family_alpha;
    }
    // 1 − (1 − α)^(1/m), without cancellation for small α.
    -((-family_alpha).ln_1p() / m as f64).exp_m1()
}

/// Holm's step-down procedure: which of the hypotheses with these p-values are rejected at
/// family-wise level `alpha` (the smallest p against α/m, the next against α/(m−1), …, stopping
/// at the first that is not rejected).
pub fn holm(p_values: &[f64], alpha: f64) -> Vec<bool> {
    let m = p_values.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p_values[a].total_cmp(&p_values[b]));
    let mut reject = vec![false; m];
    for (k, &i) in order.iter().enumerate() {
        if p_values[i] <= alpha / (m - k) as f64 {
            reject[i] = true;
        } else {
            break;
        }
    }
    reject
}

/// The regularized incomplete beta function I_x(a, b), a, b > 0, 0 ≤ x ≤ 1 (continued fraction,
/// modified Lentz, on the side where it converges fast).
pub fn regularized_beta(x: f64, a: f64, b: f64) -> f64 {
    if x.is_nan() || !(a > 0.0) || !(b > 0.0) {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (-x).ln_1p();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_cf(x, a, b) / a
    } else {
        1.0 - ln_front.exp() * beta_cf(1.0 - x, b, a) / b
    }
}

fn beta_cf(x: f64, a: f64, b: f64) -> f64 {
    let tiny = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..10_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        for aa in [m * (b - m) * x / ((qam + m2) * (a + m2)), -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))] {
            d = 1.0 + aa * d;
            if d.abs() < tiny {
                d = tiny;
            }
            c = 1.0 + aa / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            h *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// Two-sided p-value of Student's t with `df` degrees of freedom: P(|T| ≥ |t|)
/// = I_{df/(df+t²)}(df/2, 1/2). `df` = ∞ gives the normal's.
pub fn student_t_two_sided_p(t: f64, df: f64) -> f64 {
    if t.is_nan() || df.is_nan() || df <= 0.0 {
        return f64::NAN;
    }
    if df.is_infinite() {
        return normal_two_sided_p(t);
    }
    regularized_beta(df / (df + t * t), 0.5 * df, 0.5)
}

/// A test statistic and its two-sided p-value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Statistic {
    /// The difference of means in units of its standard error (signed: first minus second).
    pub t: f64,
    /// Degrees of freedom (∞ for a z-test).
    pub df: f64,
    pub p: f64,
}

/// The z-test of two independent means `m1`, `m2` with variances (of the means) `v1`, `v2`.
/// A zero total variance gives t = 0 when the means are equal, else ±∞.
pub fn z_test(m1: f64, v1: f64, m2: f64, v2: f64) -> Statistic {
    let t = ratio(m1 - m2, (v1 + v2).max(0.0).sqrt());
    Statistic { t, df: f64::INFINITY, p: normal_two_sided_p(t) }
}

/// Welch's t-test of two independent means: `m` the mean, `v` the variance *of the mean*
/// (sample variance / n), `n` the sample count of each side. Degrees of freedom by
/// Welch–Satterthwaite: (v1 + v2)² / (v1²/(n1 − 1) + v2²/(n2 − 1)).
pub fn welch(m1: f64, v1: f64, n1: f64, m2: f64, v2: f64, n2: f64) -> Statistic {
    let t = ratio(m1 - m2, (v1 + v2).max(0.0).sqrt());
    let den = v1 * v1 / (n1 - 1.0).max(f64::MIN_POSITIVE) + v2 * v2 / (n2 - 1.0).max(f64::MIN_POSITIVE);
    let df = if den > 0.0 { (v1 + v2).powi(2) / den } else { f64::INFINITY };
    Statistic { t, df, p: student_t_two_sided_p(t, df) }
}

fn ratio(d: f64, sigma: f64) -> f64 {
    if sigma > 0.0 {
        d / sigma
    } else if d == 0.0 {
        0.0
    } else {
        d.signum() * f64::INFINITY
    }
}

/// An image's values and, if it is noisy, the variance of each value's mean: `width × height`
/// pixels of `channels` interleaved values, rows top to bottom.
#[derive(Debug, Clone, Copy)]
pub struct NoisyImage<'a> {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub mean: &'a [f32],
    /// `None`: noise free (a converged or deterministic image).
    pub variance: Option<&'a [f32]>,
}

impl NoisyImage<'_> {
    fn var(&self, i: usize) -> f64 {
        self.variance.map_or(0.0, |v| v[i] as f64)
    }
}

/// The reference's noise, when it is not given per value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RefNoise {
    /// The reference's own `variance` (or none: converged).
    Own,
    /// Each value's variance is the test's times this (the same estimator at `n_test / n_ref`
    /// of the samples; the reference's own `variance` is ignored).
    ScaledTest(f64),
}

/// A systematic difference allowed before noise is considered: `abs + rel · |reference mean|`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tolerance {
    pub rel: f64,
    pub abs: f64,
}

/// A rectangle of pixels (half-open) and one channel, or all channels pooled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
    pub channel: Option<usize>,
}

/// The `block`×`block` regions tiling the image (smaller at the right and bottom edges), one per
/// channel.
pub fn blocks(width: usize, height: usize, channels: usize, block: usize) -> Vec<Region> {
    let block = block.max(1);
    let mut out = Vec::new();
    for y0 in (0..height).step_by(block) {
        for x0 in (0..width).step_by(block) {
            for c in 0..channels {
                let (x1, y1) = ((x0 + block).min(width), (y0 + block).min(height));
                out.push(Region { x0, y0, x1, y1, channel: Some(c) });
            }
        }
    }
    out
}

/// The whole image, one region per channel.
pub fn whole(width: usize, height: usize, channels: usize) -> Vec<Region> {
    (0..channels).map(|c| Region { x0: 0, y0: 0, x1: width, y1: height, channel: Some(c) }).collect()
}

/// One region's test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionTest {
    pub region: Region,
    /// The test's and the reference's mean over the region.
    pub test: f64,
    pub reference: f64,
    /// Standard deviation of `test − reference` from both images' noise.
    pub sigma: f64,
    /// The difference beyond the tolerance, in units of `sigma` (signed; 0 within the tolerance).
    pub z: f64,
}

impl RegionTest {
    /// (test − reference) / |reference| (∞ when the reference is 0 and the test is not).
    pub fn rel_error(&self) -> f64 {
        ratio(self.test - self.reference, self.reference.abs())
    }
}

/// Tests each region's mean of `test` against `reference`'s (same size and channels).
///
/// # Panics
/// If the images' sizes, channel counts or slice lengths differ.
pub fn test_regions(
    test: &NoisyImage,
    reference: &NoisyImage,
    noise: RefNoise,
    tolerance: Tolerance,
    regions: &[Region],
) -> Vec<RegionTest> {
    assert_eq!((test.width, test.height, test.channels), (reference.width, reference.height, reference.channels));
    let n_values = test.width * test.height * test.channels;
    assert_eq!((test.mean.len(), reference.mean.len()), (n_values, n_values), "image value counts");
    regions
        .iter()
        .map(|r| {
            let (mut st, mut sr, mut var, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
            for y in r.y0..r.y1.min(test.height) {
                for x in r.x0..r.x1.min(test.width) {
                    let channels = match r.channel {
                        Some(c) => c..c + 1,
                        None => 0..test.channels,
                    };
                    for c in channels {
                        let i = (y * test.width + x) * test.channels + c;
                        st += test.mean[i] as f64;
                        sr += reference.mean[i] as f64;
                        let vt = test.var(i);
                        var += vt
                            + match noise {
                                RefNoise::Own => reference.var(i),
                                RefNoise::ScaledTest(k) => k * vt,
                            };
                        n += 1;
                    }
                }
            }
            let nf = n.max(1) as f64;
            let (mt, mr) = (st / nf, sr / nf);
            let sigma = var.max(0.0).sqrt() / nf;
            let d = mt - mr;
            let excess = (d.abs() - tolerance.abs - tolerance.rel * mr.abs()).max(0.0);
            RegionTest { region: *r, test: mt, reference: mr, sigma, z: ratio(d.signum() * excess, sigma) }
        })
        .collect()
}

/// The first test with the largest |z| (NaN counts as largest), or `None` for none.
pub fn worst(tests: &[RegionTest]) -> Option<&RegionTest> {
    let key = |t: &RegionTest| if t.z.is_nan() { f64::INFINITY } else { t.z.abs() };
    tests.iter().fold(None, |best: Option<&RegionTest>, t| match best {
        Some(b) if key(t) <= key(b) => Some(b),
        _ => Some(t),
    })
}

#[cfg(test)]
mod tests;
