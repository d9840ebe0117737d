use super::*;
use crate::rng::Rng;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

#[test]
fn normal_tail_and_critical_values() {
    // Reference values: scipy.stats.norm.sf(z) * 2 and norm.isf(alpha / 2).
    for (z, p) in [
        (0.0, 1.0),
        (1.0, 0.317_310_507_862_914_1),
        (1.959_963_984_540_054, 0.05),
        (3.0, 0.002_699_796_063_260_186_7),
        (6.0, 1.973_175_290_075_7e-9),
        (10.0, 1.523_970_604_832_105e-23),
    ] {
        assert!(close(normal_two_sided_p(z), p, 1e-10), "p({z}) = {}", normal_two_sided_p(z));
        assert!(close(normal_two_sided_p(-z), p, 1e-10));
    }
    for (alpha, z) in [(0.05, 1.959_963_984_540_054), (1e-3, 3.290_526_731_491_926), (1e-8, 5.730_728_868_236_19)] {
        assert!(close(critical_z(alpha), z, 1e-10), "critical_z({alpha}) = {}", critical_z(alpha));
    }
    assert_eq!(critical_z(1.0), 0.0);
    assert_eq!(critical_z(0.0), f64::INFINITY);
}

#[test]
fn sidak_and_holm() {
    assert_eq!(sidak_alpha(0.05, 1), 0.05);
    for m in [2usize, 100, 100_000] {
        let a1 = sidak_alpha(0.01, m);
        // (1 − α₁)^m = 1 − α, and α₁ is a bit above Bonferroni's α/m.
        assert!(close(1.0 - (1.0 - a1).powi(m as i32), 0.01, 1e-9), "m = {m}");
        assert!(a1 > 0.01 / m as f64 && a1 < 1.01 * 0.01 / m as f64);
    }
    // Holm: sorted 0.005 ≤ .05/4, 0.01 ≤ .05/3, 0.03 > .05/2: stop.
    assert_eq!(holm(&[0.01, 0.04, 0.03, 0.005], 0.05), vec![true, false, false, true]);
    assert_eq!(holm(&[0.001, 0.002], 0.05), vec![true, true]);
    assert!(holm(&[], 0.05).is_empty());
}

#[test]
fn student_t_and_incomplete_beta() {
    // I_x(1, 1) = x, I_x(a, 1) = x^a, I_x(a, b) = 1 − I_{1−x}(b, a).
    for x in [0.0, 0.1, 0.5, 0.93, 1.0] {
        assert!((regularized_beta(x, 1.0, 1.0) - x).abs() < 1e-14);
        assert!((regularized_beta(x, 3.5, 1.0) - x.powf(3.5)).abs() < 1e-13);
        assert!((regularized_beta(x, 2.5, 0.7) + regularized_beta(1.0 - x, 0.7, 2.5) - 1.0).abs() < 1e-13);
    }
    // df = 1 is Cauchy: P(|T| ≥ t) = 1 − 2 atan(t)/π.
    for t in [0.3f64, 1.0, 12.0] {
        let p = 1.0 - 2.0 * t.atan() / std::f64::consts::PI;
        assert!(close(student_t_two_sided_p(t, 1.0), p, 1e-12), "{t}");
    }
    // Tables: t(0.975, 10) = 2.228138851986, t(0.995, 3) = 5.840909309733.
    assert!(close(student_t_two_sided_p(2.228_138_851_986, 10.0), 0.05, 1e-9));
    assert!(close(student_t_two_sided_p(5.840_909_309_733, 3.0), 0.01, 1e-9));
    // Large df approaches the normal.
    assert!(close(student_t_two_sided_p(3.0, 1e7), normal_two_sided_p(3.0), 1e-5));
    assert_eq!(student_t_two_sided_p(3.0, f64::INFINITY), normal_two_sided_p(3.0));
}

#[test]
fn welch_degrees_of_freedom_and_z_test() {
    // n = 10 each, sample variances 1 and 4: v = 0.1, 0.4; df = 0.25 / (0.01/9 + 0.16/9).
    let s = welch(1.0, 0.1, 10.0, 0.0, 0.4, 10.0);
    assert!(close(s.df, 0.25 * 9.0 / 0.17, 1e-12), "{}", s.df);
    assert!(close(s.t, 1.0 / 0.5f64.sqrt(), 1e-12));
    assert!(close(s.p, student_t_two_sided_p(s.t, s.df), 1e-15));
    let z = z_test(2.0, 0.5, 1.0, 0.5);
    assert_eq!((z.t, z.df), (1.0, f64::INFINITY));
    assert_eq!(z_test(1.0, 0.0, 1.0, 0.0).t, 0.0);
    assert_eq!(z_test(1.0, 0.0, 0.5, 0.0).t, f64::INFINITY);
}

/// A simulated render: every value the mean of `n` samples of an exponential distribution of
/// mean `mu[i]` (skewed, as radiance samples are), with its estimated variance of the mean.
fn simulated(rng: &mut Rng, mu: &[f64], n: usize, bias: f64) -> (Vec<f32>, Vec<f32>) {
    let mut mean = Vec::with_capacity(mu.len());
    let mut var = Vec::with_capacity(mu.len());
    for &m in mu {
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let x = -m * (1.0 - rng.uniform_f64()).ln();
            s += x;
            s2 += x * x;
        }
        let nf = n as f64;
        let mean_x = s / nf;
        mean.push((mean_x * (1.0 + bias)) as f32);
        var.push(((s2 / nf - mean_x * mean_x) * nf / (nf - 1.0) / nf) as f32);
    }
    (mean, var)
}

fn image_mu(w: usize, h: usize) -> Vec<f64> {
    // A smooth image with a dim and a bright side and unequal channels.
    (0..w * h * 3).map(|i| (0.05 + 0.5 * ((i / 3) % w) as f64 / w as f64) * [1.0, 0.7, 0.4][i % 3]).collect()
}

/// Runs `reps` replicate comparisons of a 16×16 RGB render (16 samples per value) against a
/// reference of 64 samples per value (its noise as a scaled copy of the test's), 8×8 blocks and
/// whole channels at family-wise α by Šidák; returns (fraction of replicates with any
/// rejection, fraction of single block tests beyond 1.96).
fn false_alarms(reps: usize, bias: f64) -> (f64, f64) {
    let (w, h) = (16, 16);
    let mu = image_mu(w, h);
    let mut regions = blocks(w, h, 3, 8);
    regions.extend(whole(w, h, 3));
    let z_crit = critical_z(sidak_alpha(0.05, regions.len()));
    let mut rng = Rng::new(7);
    let (mut any, mut single, mut singles) = (0usize, 0usize, 0usize);
    for _ in 0..reps {
        let (tm, tv) = simulated(&mut rng, &mu, 16, bias);
        let (rm, _) = simulated(&mut rng, &mu, 64, 0.0);
        let t = NoisyImage { width: w, height: h, channels: 3, mean: &tm, variance: Some(&tv) };
        let r = NoisyImage { width: w, height: h, channels: 3, mean: &rm, variance: None };
        let res = test_regions(&t, &r, RefNoise::ScaledTest(16.0 / 64.0), Tolerance::default(), &regions);
        any += res.iter().any(|x| x.z.abs() > z_crit) as usize;
        for x in res.iter().filter(|x| x.region.x1 - x.region.x0 == 8) {
            single += (x.z.abs() > 1.959_963_984_540_054) as usize;
            singles += 1;
        }
    }
    (any as f64 / reps as f64, single as f64 / singles as f64)
}

/// Calibration: with both images unbiased, the family-wise false-alarm rate is at most the
/// stated α = 0.05 (Šidák over 15 tests; a little below it, since the whole-image tests are
/// correlated with their blocks), and single block tests reject at their nominal 5 % (the
/// estimated variance of 1024 skewed samples makes z nearly normal). Measured: 0.0545 and
/// 0.0521 (seed 7).
#[test]
fn block_and_image_tests_hold_their_false_alarm_rate() {
    let reps = 2000;
    let (family, single) = false_alarms(reps, 0.0);
    // Binomial standard deviations: sqrt(.05 · .95 / 2000) = 0.0049 for the family rate;
    // for 24000 single tests 0.0014. Bounds at about 4 of them.
    eprintln!("family-wise false alarms {family:.4} (α 0.05), single block tests beyond 1.96: {single:.4}");
    assert!((0.02..=0.07).contains(&family), "family-wise rate {family}");
    assert!((single - 0.05).abs() < 0.006, "single-test rate {single}");
}

/// Power: the same setting with the test image too bright everywhere. A whole channel's mean
/// pools 4096 samples of relative standard deviation 1, so its σ is about 1.75 % of the mean
/// (the reference's noise included): a 6 % bias is about 3.4σ against the Šidák threshold of
/// 2.94 (most replicates reject), a 12 % bias about 7σ (every replicate does). Measured: 0.925
/// and 1.0 of 200.
#[test]
fn a_global_bias_is_detected() {
    let (p6, _) = false_alarms(200, 0.06);
    let (p12, _) = false_alarms(200, 0.12);
    eprintln!("rejection rate at +6 %: {p6:.3}, at +12 %: {p12:.3}");
    assert!(p6 > 0.6, "{p6}");
    assert_eq!(p12, 1.0);
}

#[test]
fn regions_pool_values_and_tolerance_is_subtracted() {
    // 4×2 pixels, 2 channels.
    let t: Vec<f32> = (0..16).map(|i| 1.0 + i as f32 * 0.0).collect();
    let r: Vec<f32> = vec![0.9; 16];
    let v: Vec<f32> = vec![0.01; 16];
    let ti = NoisyImage { width: 4, height: 2, channels: 2, mean: &t, variance: Some(&v) };
    let ri = NoisyImage { width: 4, height: 2, channels: 2, mean: &r, variance: Some(&v) };
    let regions = blocks(4, 2, 2, 2);
    assert_eq!(regions.len(), 2 * 2);
    assert_eq!(regions[1], Region { x0: 0, y0: 0, x1: 2, y1: 2, channel: Some(1) });
    let res = test_regions(&ti, &ri, RefNoise::Own, Tolerance::default(), &regions);
    // Each block: 4 values, Δ = 0.1, σ² = 4 · 0.02 / 16.
    let sigma = (4.0f64 * 0.02 / 16.0).sqrt();
    assert!(close(res[0].sigma, sigma, 1e-6) && close(res[0].z, 0.1 / sigma, 1e-5));
    assert!(close(res[0].rel_error(), 0.1 / 0.9, 1e-6));
    // Scaled reference noise: σ² = 4 · (0.01 + 0.5 · 0.01) / 16.
    let res = test_regions(&ti, &ri, RefNoise::ScaledTest(0.5), Tolerance::default(), &regions[..1]);
    assert!(close(res[0].sigma, (4.0f64 * 0.015 / 16.0).sqrt(), 1e-6));
    // A tolerance of 10 % of 0.9 (0.09) leaves an excess of 0.01; 20 % leaves none.
    let res = test_regions(&ti, &ri, RefNoise::Own, Tolerance { rel: 0.1, abs: 0.0 }, &regions[..1]);
    assert!(close(res[0].z, 0.01 / sigma, 1e-4), "{}", res[0].z);
    let res = test_regions(&ti, &ri, RefNoise::Own, Tolerance { rel: 0.2, abs: 0.0 }, &regions[..1]);
    assert_eq!(res[0].z, 0.0);
    // Noise-free images: any difference beyond the tolerance is infinitely significant.
    let ti = NoisyImage { variance: None, ..ti };
    let ri = NoisyImage { variance: None, ..ri };
    let res = test_regions(&ti, &ri, RefNoise::Own, Tolerance { rel: 0.0, abs: 0.05 }, &whole(4, 2, 2));
    assert!(res.iter().all(|x| x.z == f64::INFINITY));
    assert_eq!(worst(&res).map(|x| x.region.channel), Some(Some(0)));
    let res = test_regions(&ti, &ri, RefNoise::Own, Tolerance { rel: 0.0, abs: 0.2 }, &whole(4, 2, 2));
    assert!(res.iter().all(|x| x.z == 0.0));
}
