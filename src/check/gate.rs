//! The gate itself: per-value, block and whole-image tests of a test image against a
//! reference, on images in memory (what `penumbra check`, its suites and the project's own
//! calibration test all call). The statistics are `penumbra_core::agreement`'s.
//!
//! # What is tested
//! Three families, each at a third of the family-wise level α (Bonferroni over the families,
//! so a false alarm anywhere has probability at most α):
//! 1. **values** (pixel × channel): Welch's t (both images noisy), a z-test (converged
//!    reference) or the pooled two-sample t (same estimator), corrected by Šidák or Holm over
//!    all values; the family fails when more than the allowed fraction of values is rejected.
//! 2. **blocks**: the mean of each `block × block` region of each channel (Šidák over blocks).
//! 3. **whole image**: the mean of each channel and of all channels together (Šidák over 4).
//!
//! An allowed systematic difference `abs + rel·|ref|` is subtracted from |Δ| before the
//! noise is considered; where both images are noise free that makes the test the plain
//! tolerance `|Δ| ≤ abs + rel·|ref|`.

use penumbra_core::agreement::{
    self, holm, normal_two_sided_p, sidak_alpha, student_t_two_sided_p, NoisyImage, RefNoise, Region, RegionTest,
    Tolerance,
};
use penumbra_core::image::Image;

/// How the reference's noise enters the test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefMode {
    /// Both images carry their own variance: Welch's t-test.
    Welch,
    /// The reference is converged: its noise is 0 (its variance channels, if any, are ignored).
    Converged,
    /// Both images come from the same estimator (e.g. pbrt-v3's `directlighting` reference of a
    /// penumbra `directlighting` render): one per-sample variance, pooled from the variance
    /// channels present, serves both (the classic pooled two-sample t-test).
    SameEstimator,
}

/// How the per-value p-values are corrected for their number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Correction {
    Sidak,
    Holm,
}

#[derive(Debug, Clone, Copy)]
pub struct GateOptions {
    /// Family-wise false-alarm probability of the whole gate.
    pub alpha: f64,
    pub correction: Correction,
    /// Fraction of values (0..1) allowed to be rejected before the value family fails.
    pub fail_fraction: f64,
    /// Side of the pooled blocks, in pixels.
    pub block: usize,
    pub tolerance: Tolerance,
    pub mode: RefMode,
}

impl Default for GateOptions {
    fn default() -> Self {
        GateOptions {
            alpha: 0.01,
            correction: Correction::Sidak,
            fail_fraction: 0.0025,
            block: 8,
            tolerance: Tolerance::default(),
            mode: RefMode::Welch,
        }
    }
}

/// One image as the gate reads it: R, G, B means, optionally their variances (of the mean, as
/// `render --variance` writes them) and the samples per pixel behind them.
#[derive(Debug, Clone)]
pub struct Side {
    pub width: usize,
    pub height: usize,
    /// R, G, B interleaved.
    pub mean: Vec<f32>,
    /// variance.R/G/B interleaved, if the image has them.
    pub variance: Option<Vec<f32>>,
    /// Samples per pixel (from the caller: `--test-spp` or the render's stats.json).
    pub spp: Option<f64>,
}

impl Side {
    /// The R, G, B channels of `img` and its `variance.R/G/B` when all three are present.
    pub fn from_image(img: &Image, spp: Option<f64>) -> Result<Side, String> {
        let idx = |names: [&str; 3]| -> Option<[usize; 3]> {
            Some([img.channel_index(names[0])?, img.channel_index(names[1])?, img.channel_index(names[2])?])
        };
        let rgb =
            idx(["R", "G", "B"]).ok_or_else(|| format!("no R, G, B channels (it has {})", img.channels.join(", ")))?;
        let var = idx(["variance.R", "variance.G", "variance.B"]);
        let n = img.nchannels();
        let pick = |ix: [usize; 3]| img.data.chunks_exact(n).flat_map(|p| ix.map(|i| p[i])).collect::<Vec<f32>>();
        Ok(Side {
            width: img.width as usize,
            height: img.height as usize,
            mean: pick(rgb),
            variance: var.map(pick),
            spp,
        })
    }
}

/// The test of one family of hypotheses.
#[derive(Debug, Clone, Default)]
pub struct Family {
    /// Hypotheses tested.
    pub count: usize,
    /// Rejected at the corrected level.
    pub rejected: usize,
    /// The per-test level (Šidák; for Holm the smallest, α/m).
    pub level: f64,
    /// The family's share of α.
    pub alpha: f64,
    /// Index and p-value of the smallest p.
    pub worst: Option<(usize, f64)>,
    pub failed: bool,
}

/// The bias of one channel (or all, pooled) over the whole image.
#[derive(Debug, Clone, Copy)]
pub struct Bias {
    /// "R", "G", "B" or "all".
    pub channel: &'static str,
    pub test_mean: f64,
    pub reference_mean: f64,
    /// (test − reference) / |reference|.
    pub rel: f64,
    /// Its 95 % confidence interval (from both images' noise).
    pub rel_lo: f64,
    pub rel_hi: f64,
    /// The whole-image z beyond the tolerance, and its p.
    pub z: f64,
    pub p: f64,
}

/// Everything the gate measured.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub width: usize,
    pub height: usize,
    pub mode: RefMode,
    /// Neither image has noise: the values are compared with the tolerance alone.
    pub noise_free: bool,
    /// Per value: the signed statistic (t or z beyond the tolerance) and its p.
    pub t: Vec<f64>,
    pub p: Vec<f64>,
    pub rejected: Vec<bool>,
    /// Non-finite values in the test or the reference (always rejected unless equal).
    pub nonfinite: usize,
    pub values: Family,
    pub blocks: Family,
    pub block_tests: Vec<RegionTest>,
    pub block_p: Vec<f64>,
    pub block_rejected: Vec<bool>,
    pub whole: Family,
    pub bias: Vec<Bias>,
    /// Pixels with any rejected channel.
    pub failing_pixels: usize,
    pub passed: bool,
    /// Why it failed, one line per failing family.
    pub reasons: Vec<String>,
}

/// Per-value variances of both sides as the mode defines them, and the degrees of freedom of
/// each value's statistic (∞ for a z-test).
struct Noise {
    var_t: Vec<f64>,
    var_r: Vec<f64>,
    df: Vec<f64>,
}

fn need_spp(side: &Side, which: &str) -> Result<f64, String> {
    match side.spp {
        Some(n) if n >= 1.0 => Ok(n),
        _ => Err(format!(
            "the {which}'s samples per pixel are unknown (needed for the degrees of freedom): give --{which}-spp N, or keep the render's .stats.json beside it"
        )),
    }
}

fn noise(test: &Side, reference: &Side, mode: RefMode) -> Result<Noise, String> {
    let n = test.mean.len();
    let get = |s: &Side, i: usize| s.variance.as_ref().map_or(0.0, |v| (v[i] as f64).max(0.0));
    let mut out = Noise { var_t: vec![0.0; n], var_r: vec![0.0; n], df: vec![f64::INFINITY; n] };
    match mode {
        RefMode::Converged => {
            // The test's variance, or the reference's per-sample variance scaled to the test's
            // samples where that is larger (Mitsuba's render tests use only the reference's): a
            // few samples' variance misses rare events (a 16-sample pixel whose samples all
            // missed a glossy highlight looks nearly noise free), the reference's many do not.
            let nt = test.variance.as_ref().map(|_| need_spp(test, "test")).transpose()?;
            let nr = if reference.variance.is_some() { reference.spp } else { None };
            for i in 0..n {
                out.var_t[i] = get(test, i);
                if let Some(nt) = nt {
                    out.df[i] = nt - 1.0;
                    if let Some(nr) = nr {
                        let borrowed = get(reference, i) * nr / nt;
                        if borrowed > out.var_t[i] {
                            out.var_t[i] = borrowed;
                            out.df[i] = nr - 1.0;
                        }
                    }
                }
            }
        }
        RefMode::Welch => {
            let nt = test.variance.as_ref().map(|_| need_spp(test, "test")).transpose()?;
            let nr = reference.variance.as_ref().map(|_| need_spp(reference, "reference")).transpose()?;
            for i in 0..n {
                let (mut vt, mut vr) = (get(test, i), get(reference, i));
                let mut df = f64::INFINITY;
                match (nt, nr) {
                    (Some(nt), Some(nr)) => {
                        // A side whose samples were all equal has no variance estimate: it
                        // borrows the other side's per-sample variance, and the statistic its
                        // degrees of freedom.
                        if vt == 0.0 && vr > 0.0 {
                            vt = vr * nr / nt;
                            df = nr - 1.0;
                        } else if vr == 0.0 && vt > 0.0 {
                            vr = vt * nt / nr;
                            df = nt - 1.0;
                        } else if vt > 0.0 {
                            df = agreement::welch(0.0, vt, nt, 0.0, vr, nr).df;
                        }
                    }
                    (Some(nt), None) => df = nt - 1.0,
                    (None, Some(nr)) => df = nr - 1.0,
                    (None, None) => {}
                }
                out.var_t[i] = vt;
                out.var_r[i] = vr;
                out.df[i] = df;
            }
        }
        RefMode::SameEstimator => {
            let nt = need_spp(test, "test")?;
            let nr = need_spp(reference, "reference")?;
            if test.variance.is_none() && reference.variance.is_none() {
                return Err("--same-estimator needs a variance channel in the test or the reference".into());
            }
            for i in 0..n {
                // Pooled per-sample variance: Σ (n − 1) s² / Σ (n − 1) over the sides that have one.
                let (mut ss, mut dof) = (0.0, 0.0);
                if test.variance.is_some() && nt > 1.0 {
                    ss += get(test, i) * nt * (nt - 1.0);
                    dof += nt - 1.0;
                }
                if reference.variance.is_some() && nr > 1.0 {
                    ss += get(reference, i) * nr * (nr - 1.0);
                    dof += nr - 1.0;
                }
                let s2 = if dof > 0.0 { ss / dof } else { 0.0 };
                out.var_t[i] = s2 / nt;
                out.var_r[i] = s2 / nr;
                out.df[i] = if dof > 0.0 { dof } else { f64::INFINITY };
            }
        }
    }
    Ok(out)
}

/// Runs the gate. Errors (as text) when the images differ in size or the mode needs what
/// they lack.
pub fn run(test: &Side, reference: &Side, o: &GateOptions) -> Result<Outcome, String> {
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(format!(
            "the images differ in size: test {}x{}, reference {}x{}",
            test.width, test.height, reference.width, reference.height
        ));
    }
    if !(o.alpha > 0.0 && o.alpha < 1.0) {
        return Err(format!("alpha must lie in (0, 1), got {}", o.alpha));
    }
    let nz = noise(test, reference, o.mode)?;
    let n = test.mean.len();
    let noise_free = nz.var_t.iter().chain(&nz.var_r).all(|&v| v == 0.0);
    let tol = o.tolerance;
    let mut t = vec![0.0; n];
    let mut p = vec![1.0; n];
    let mut nonfinite = 0;
    for i in 0..n {
        let (a, b) = (test.mean[i] as f64, reference.mean[i] as f64);
        if !a.is_finite() || !b.is_finite() {
            nonfinite += 1;
            let same = a == b || (a.is_nan() && b.is_nan());
            // Equal non-finite values are skipped (as `diff`); anything else is rejected.
            (t[i], p[i]) = if same && !a.is_nan() { (0.0, 1.0) } else { (f64::NAN, 0.0) };
            continue;
        }
        let d = a - b;
        let excess = d.signum() * (d.abs() - tol.abs - tol.rel * b.abs()).max(0.0);
        let s = agreement::z_test(excess, nz.var_t[i], 0.0, nz.var_r[i]);
        t[i] = s.t;
        p[i] = if nz.df[i].is_finite() { student_t_two_sided_p(s.t, nz.df[i].max(1.0)) } else { s.p };
    }
    let fam_alpha = o.alpha / 3.0;
    let (rejected, level) = match o.correction {
        Correction::Sidak => {
            let a1 = sidak_alpha(fam_alpha, n);
            (p.iter().map(|&p| p <= a1).collect::<Vec<_>>(), a1)
        }
        Correction::Holm => (holm(&p, fam_alpha), fam_alpha / n.max(1) as f64),
    };
    let n_rej = rejected.iter().filter(|&&r| r).count();
    let allowed = (o.fail_fraction * n as f64).floor() as usize;
    let values =
        Family { count: n, rejected: n_rej, level, alpha: fam_alpha, worst: worst_p(&p), failed: n_rej > allowed };
    let failing_pixels = rejected.chunks_exact(3).filter(|c| c.iter().any(|&r| r)).count();

    // Region tests: the per-value variances of the mode, both sides' noise as given.
    let var_t: Vec<f32> = nz.var_t.iter().map(|&v| v as f32).collect();
    let var_r: Vec<f32> = nz.var_r.iter().map(|&v| v as f32).collect();
    let ti =
        NoisyImage { width: test.width, height: test.height, channels: 3, mean: &test.mean, variance: Some(&var_t) };
    let ri = NoisyImage {
        width: reference.width,
        height: reference.height,
        channels: 3,
        mean: &reference.mean,
        variance: Some(&var_r),
    };
    let block_tests =
        agreement::test_regions(&ti, &ri, RefNoise::Own, tol, &agreement::blocks(test.width, test.height, 3, o.block));
    let (blocks, block_p, block_rejected) = region_family(&block_tests, fam_alpha);
    let mut whole_tests =
        agreement::test_regions(&ti, &ri, RefNoise::Own, tol, &agreement::whole(test.width, test.height, 3));
    whole_tests.push(pooled_channels(&whole_tests, tol));
    let (whole, whole_p, _) = region_family(&whole_tests, fam_alpha);
    let bias = whole_tests
        .iter()
        .zip(&whole_p)
        .zip(["R", "G", "B", "all"])
        .map(|((w, &p), channel)| {
            let r = w.reference.abs();
            let half = 1.959_963_984_540_054 * w.sigma;
            let rel = |d: f64| if r > 0.0 { d / r } else { f64::NAN };
            let d = w.test - w.reference;
            Bias {
                channel,
                test_mean: w.test,
                reference_mean: w.reference,
                rel: w.rel_error(),
                rel_lo: rel(d - half),
                rel_hi: rel(d + half),
                z: w.z,
                p,
            }
        })
        .collect();

    let mut reasons = Vec::new();
    if values.failed {
        reasons.push(format!(
            "{} of {} values ({:.3} %) differ beyond their noise (allowed {} = {:.3} %)",
            n_rej,
            n,
            100.0 * n_rej as f64 / n.max(1) as f64,
            allowed,
            100.0 * o.fail_fraction
        ));
    }
    if blocks.failed {
        reasons.push(format!("{} of {} {}x{} block means differ", blocks.rejected, blocks.count, o.block, o.block));
    }
    if whole.failed {
        let names: Vec<&str> = whole_tests
            .iter()
            .zip(["R", "G", "B", "all"])
            .zip(&whole_p)
            .filter(|(_, &p)| p <= whole.level)
            .map(|((_, c), _)| c)
            .collect();
        reasons.push(format!("the whole-image mean differs ({})", names.join(", ")));
    }
    Ok(Outcome {
        width: test.width,
        height: test.height,
        mode: o.mode,
        noise_free,
        t,
        p,
        rejected,
        nonfinite,
        passed: reasons.is_empty(),
        values,
        blocks,
        block_tests,
        block_p,
        block_rejected,
        whole,
        bias,
        failing_pixels,
        reasons,
    })
}

/// The mean over the three channels of the per-channel region tests. A pixel's channels come
/// from the same samples and are strongly correlated, so their variances do not simply add:
/// the standard deviation of the mean is bounded by the mean of the channels' (perfect
/// correlation, Cauchy–Schwarz), which is used — conservative for uncorrelated channels.
fn pooled_channels(channels: &[RegionTest], tol: Tolerance) -> RegionTest {
    let k = channels.len().max(1) as f64;
    let test = channels.iter().map(|t| t.test).sum::<f64>() / k;
    let reference = channels.iter().map(|t| t.reference).sum::<f64>() / k;
    let sigma = channels.iter().map(|t| t.sigma).sum::<f64>() / k;
    let d = test - reference;
    let excess = (d.abs() - tol.abs - tol.rel * reference.abs()).max(0.0);
    let z = if sigma > 0.0 {
        d.signum() * excess / sigma
    } else if excess == 0.0 {
        0.0
    } else {
        d.signum() * f64::INFINITY
    };
    let region = channels
        .first()
        .map_or(Region { x0: 0, y0: 0, x1: 0, y1: 0, channel: None }, |c| Region { channel: None, ..c.region });
    RegionTest { region, test, reference, sigma, z }
}

fn worst_p(p: &[f64]) -> Option<(usize, f64)> {
    p.iter().enumerate().fold(None, |best: Option<(usize, f64)>, (i, &v)| match best {
        Some((_, b)) if !(v < b) => best,
        _ => Some((i, v)),
    })
}

/// Šidák over the regions' z-tests: (family, p per region, rejected per region).
fn region_family(tests: &[RegionTest], alpha: f64) -> (Family, Vec<f64>, Vec<bool>) {
    let p: Vec<f64> = tests.iter().map(|t| if t.z.is_nan() { 0.0 } else { normal_two_sided_p(t.z) }).collect();
    let level = sidak_alpha(alpha, tests.len());
    let rejected: Vec<bool> = p.iter().map(|&p| p <= level).collect();
    let n_rej = rejected.iter().filter(|&&r| r).count();
    let family = Family { count: tests.len(), rejected: n_rej, level, alpha, worst: worst_p(&p), failed: n_rej > 0 };
    (family, p, rejected)
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::rng::Rng;

    /// A noisy `w × h` image of `spp` samples per pixel of value `mean(x, y)` + uniform noise of
    /// per-sample standard deviation `sd`, with its estimated variance of the mean.
    fn noisy(w: usize, h: usize, spp: usize, sd: f64, seed: u64, mean: impl Fn(usize, usize) -> f64) -> Side {
        let mut rng = Rng::new(seed);
        let (mut m, mut v) = (Vec::new(), Vec::new());
        let half = sd * 3f64.sqrt();
        for y in 0..h {
            for x in 0..w {
                for _ in 0..3 {
                    let (mut s, mut s2) = (0.0, 0.0);
                    for _ in 0..spp {
                        let u = mean(x, y) + half * (2.0 * rng.uniform_f32() as f64 - 1.0);
                        s += u;
                        s2 += u * u;
                    }
                    let n = spp as f64;
                    let mu = s / n;
                    m.push(mu as f32);
                    v.push(((s2 / n - mu * mu).max(0.0) * n / (n - 1.0) / n) as f32);
                }
            }
        }
        Side { width: w, height: h, mean: m, variance: Some(v), spp: Some(spp as f64) }
    }

    #[test]
    fn unbiased_pairs_pass_biased_and_defective_fail() {
        let flat = |_: usize, _: usize| 1.0;
        let o = GateOptions::default();
        for seed in 0..5 {
            let a = noisy(64, 64, 16, 0.3, 2 * seed + 1, flat);
            let b = noisy(64, 64, 16, 0.3, 2 * seed + 2, flat);
            let r = run(&a, &b, &o).unwrap();
            assert!(r.passed, "seed {seed}: {:?}", r.reasons);
            // 1 % everywhere: per-value invisible (σ ≈ 0.3·√2/4 ≈ 0.11 per value), plain in
            // each channel's mean (σ ≈ 0.3·√2/√(4096·16) ≈ 1.7e-3: z ≈ 6).
            let biased = Side { mean: a.mean.iter().map(|v| v * 1.01).collect(), ..a.clone() };
            let r = run(&biased, &b, &o).unwrap();
            assert!(!r.passed && r.whole.failed && !r.values.failed, "seed {seed}: {:?}", r.reasons);
            assert!(r.bias[3].rel_lo > 0.0 && r.bias[3].rel_hi < 0.02, "{:?}", r.bias[3]);
            // An 8×8 patch 20 % darker: invisible in the image mean (0.3 %), plain in its block.
            let defect = noisy(64, 64, 16, 0.3, 2 * seed + 1, |x, y| {
                if (8..16).contains(&x) && (8..16).contains(&y) {
                    0.8
                } else {
                    1.0
                }
            });
            let r = run(&defect, &b, &o).unwrap();
            assert!(!r.passed && r.blocks.failed, "seed {seed}: {:?}", r.reasons);
        }
    }

    #[test]
    fn zero_variance_values_borrow_the_other_side() {
        // Test: every sample 0 in one pixel (variance 0); reference 0.05 with per-sample
        // variance 0.05·0.95 at 1024 spp: the reference alone would give t ≈ −7.3.
        let mut a = noisy(8, 8, 16, 0.5, 1, |_, _| 1.0);
        let b = noisy(8, 8, 1024, 0.5, 2, |_, _| 1.0);
        let mut b2 = b.clone();
        for c in 0..3 {
            a.mean[c] = 0.0;
            a.variance.as_mut().unwrap()[c] = 0.0;
            b2.mean[c] = 0.05;
            b2.variance.as_mut().unwrap()[c] = (0.05 * 0.95 / 1024.0) as f32;
        }
        let r = run(&a, &b2, &GateOptions::default()).unwrap();
        assert!(r.t[0].abs() < 1.0, "t = {}", r.t[0]);
    }

    #[test]
    fn noise_free_images_use_the_tolerance() {
        let a = Side { width: 4, height: 4, mean: vec![1.0; 48], variance: None, spp: None };
        let mut b = a.clone();
        b.mean[5] = 1.015;
        let mut o = GateOptions { mode: RefMode::Converged, ..Default::default() };
        o.tolerance = Tolerance { rel: 0.02, abs: 0.0 };
        let r = run(&a, &b, &o).unwrap();
        assert!(r.noise_free && r.passed);
        o.tolerance = Tolerance { rel: 0.01, abs: 0.0 };
        o.fail_fraction = 0.0;
        let r = run(&a, &b, &o).unwrap();
        assert!(!r.passed && r.values.rejected == 1 && r.failing_pixels == 1, "{:?}", r.reasons);
    }

    #[test]
    fn nan_in_the_test_is_rejected() {
        let a = noisy(8, 8, 16, 0.5, 1, |_, _| 1.0);
        let mut t = a.clone();
        t.mean[7] = f32::NAN;
        let o = GateOptions { fail_fraction: 0.0, ..Default::default() };
        let r = run(&t, &a, &o).unwrap();
        assert!(!r.passed && r.nonfinite == 1 && r.rejected[7]);
    }
}
