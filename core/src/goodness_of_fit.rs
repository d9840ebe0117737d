//! Goodness-of-fit statistics shared by the sampling tests of every module
//! (samplers, BSDFs, lights): Pearson's chi-square test with merging of
//! low-expectation cells, and the regularized incomplete gamma function that
//! turns a statistic into a p-value.

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7, 9 terms; ~15 significant digits).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const COEF: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x)Γ(1-x) = π / sin(πx).
        let s = (std::f64::consts::PI * x).sin().abs();
        return std::f64::consts::PI.ln() - s.ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = COEF[0];
    let t = x + G + 0.5;
    for (i, c) in COEF.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularized lower incomplete gamma function P(a, x) = γ(a, x) / Γ(a).
pub fn regularized_gamma_p(a: f64, x: f64) -> f64 {
    1.0 - regularized_gamma_q(a, x)
}

/// The regularized upper incomplete gamma function Q(a, x) = Γ(a, x) / Γ(a), for a > 0, x ≥ 0.
pub fn regularized_gamma_q(a: f64, x: f64) -> f64 {
    if x.is_nan() || a.is_nan() || a <= 0.0 {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    if x == f64::INFINITY {
        return 0.0;
    }
    let log_prefactor = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // Series for P: γ(a,x) = e^-x x^a Σ x^n / (a (a+1) … (a+n)).
        let mut term = 1.0 / a;
        let mut sum = term;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * log_prefactor.exp()).clamp(0.0, 1.0)
    } else {
        // Continued fraction for Q (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (log_prefactor.exp() * h).clamp(0.0, 1.0)
    }
}

/// P(X² ≥ `chi2`) for a chi-square distribution with `dof` degrees of freedom.
pub fn chi2_p_value(chi2: f64, dof: usize) -> f64 {
    if dof == 0 {
        return 1.0;
    }
    regularized_gamma_q(dof as f64 / 2.0, chi2 / 2.0)
}

/// Pearson's chi-square goodness-of-fit test of `observed` counts against `expected` counts.
///
/// Cells whose expectation is below `min_expected` (5 is customary) are pooled into one
/// cell (which, if still below `min_expected`, is added to the smallest regular cell) so that
/// the asymptotic chi-square distribution applies. Returns `(statistic, degrees of freedom,
/// p-value)`; a p-value below the chosen significance level rejects the hypothesis that the
/// observations follow `expected`. An observation in a cell of zero expectation gives an
/// infinite statistic and p = 0. The slices are compared up to the shorter length.
pub fn chi2_test(observed: &[f64], expected: &[f64], min_expected: f64) -> (f64, usize, f64) {
    let n = observed.len().min(expected.len());
    let mut cells: Vec<(f64, f64)> = Vec::with_capacity(n);
    let (mut pool_obs, mut pool_exp) = (0.0f64, 0.0f64);
    for i in 0..n {
        let (o, e) = (observed[i].max(0.0), expected[i].max(0.0));
        if e == 0.0 {
            if o > 0.0 {
                return (f64::INFINITY, n.saturating_sub(1), 0.0);
            }
            continue;
        }
        if e < min_expected {
            pool_obs += o;
            pool_exp += e;
        } else {
            cells.push((o, e));
        }
    }
    if pool_exp > 0.0 {
        if pool_exp >= min_expected || cells.is_empty() {
            cells.push((pool_obs, pool_exp));
        } else {
            let smallest = cells.iter_mut().min_by(|a, b| a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal));
            if let Some(c) = smallest {
                c.0 += pool_obs;
                c.1 += pool_exp;
            }
        }
    }
    let chi2: f64 = cells.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = cells.len().saturating_sub(1);
    (chi2, dof, chi2_p_value(chi2, dof))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn ln_gamma_matches_factorials() {
        let mut f = 1.0f64;
        for n in 1..20 {
            assert!((ln_gamma(n as f64) - f.ln()).abs() < 1e-10, "n={n}");
            f *= n as f64;
        }
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
    }

    #[test]
    fn p_values_match_known_quantiles() {
        // Upper 5% points of the chi-square distribution.
        for (dof, q) in
            [(1usize, 3.841458820694124), (2, 5.991464547107979), (10, 18.307038053275146), (100, 124.3421134)]
        {
            let p = chi2_p_value(q, dof);
            assert!((p - 0.05).abs() < 1e-6, "dof {dof}: {p}");
        }
        // dof 2 has the closed form e^{-x/2}.
        for x in [0.1, 1.0, 7.0, 30.0] {
            assert!((chi2_p_value(x, 2) - (-x / 2.0f64).exp()).abs() < 1e-12);
        }
        assert!((regularized_gamma_p(1.0, 2.0) - (1.0 - (-2.0f64).exp())).abs() < 1e-12);
    }

    #[test]
    fn chi2_accepts_uniform_and_rejects_skewed() {
        let mut rng = Rng::new(11);
        let cells = 50;
        let n = 100_000;
        let mut uniform = vec![0.0; cells];
        let mut skewed = vec![0.0; cells];
        for _ in 0..n {
            let u = rng.uniform_f64();
            uniform[(u * cells as f64) as usize] += 1.0;
            skewed[((u * u.sqrt()).powf(0.98) * cells as f64) as usize] += 1.0;
        }
        let expected = vec![n as f64 / cells as f64; cells];
        let (_, dof, p) = chi2_test(&uniform, &expected, 5.0);
        assert_eq!(dof, cells - 1);
        assert!(p > 1e-3, "uniform rejected: p={p}");
        let (_, _, p) = chi2_test(&skewed, &expected, 5.0);
        assert!(p < 1e-6);
    }

    #[test]
    fn chi2_merges_small_cells_and_flags_impossible_events() {
        let observed = [10.0, 10.0, 1.0, 0.0, 2.0];
        let expected = [10.0, 10.0, 1.0, 1.0, 1.0];
        let (chi2, dof, _) = chi2_test(&observed, &expected, 5.0);
        // The three small cells pool into (3, 3), which is added to a 10-cell: (13, 13).
        assert_eq!(dof, 1);
        assert!(chi2.abs() < 1e-12);
        let (chi2, _, p) = chi2_test(&[1.0, 5.0], &[0.0, 6.0], 5.0);
        assert!(chi2.is_infinite() && p == 0.0);
    }
}
