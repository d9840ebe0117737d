//! Spline and Fourier-series interpolation with pbrt-v3's definitions (`core/interpolation.cpp`):
//! Catmull–Rom splines over non-uniform nodes (finite-difference end derivatives), their
//! weights, integral, inversion and importance sampling (1D and along the second axis of a 2D
//! table interpolated in the first), and cosine series with their sampling. Used by the
//! measured `fourier` BSDF ([`crate::bxdf::fourier`]) and the tabulated BSSRDF
//! ([`crate::bssrdf`]).
//!
//! Every function is total: nodes must be sorted (the callers validate their tables), but
//! out-of-range arguments give 0 / `None` and the Newton–bisection loops are capped, so no
//! input makes them panic or spin.

use std::f64::consts::PI;

/// Newton–bisection steps at most (bisection alone halves the bracket below 1e-6 in 20).
const MAX_STEPS: usize = 64;

/// pbrt-v3's `FindInterval`: the largest `i` in `[0, size − 2]` with `pred(i)` true (0 if none),
/// for a predicate that is true then false along the indices.
pub fn find_interval(size: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut first, mut len) = (0usize, size);
    while len > 0 {
        let half = len >> 1;
        let middle = first + half;
        if pred(middle) {
            first = middle + 1;
            len -= half + 1;
        } else {
            len = half;
        }
    }
    first.saturating_sub(1).min(size.saturating_sub(2))
}

/// The end derivatives of the spline segment `i` (`[x_i, x_{i+1}]`) of `f`, scaled by its width.
#[inline]
fn segment_derivatives(x: &[f32], f: impl Fn(usize) -> f32, i: usize) -> (f32, f32) {
    let n = x.len();
    let (x0, x1) = (x[i], x[i + 1]);
    let (f0, f1) = (f(i), f(i + 1));
    let width = x1 - x0;
    let d0 = if i > 0 { width * (f1 - f(i - 1)) / (x1 - x[i - 1]) } else { f1 - f0 };
    let d1 = if i + 2 < n { width * (f(i + 2) - f0) / (x[i + 2] - x0) } else { f1 - f0 };
    (d0, d1)
}

/// pbrt-v3's `CatmullRom`: the spline through `(nodes, values)` at `x` (0 outside the nodes).
pub fn catmull_rom(nodes: &[f32], values: &[f32], x: f32) -> f32 {
    let n = nodes.len().min(values.len());
    if n < 2 || !(x >= nodes[0] && x <= nodes[n - 1]) {
        return 0.0;
    }
    let i = find_interval(n, |k| nodes[k] <= x);
    let (d0, d1) = segment_derivatives(&nodes[..n], |k| values[k], i);
    let (f0, f1) = (values[i], values[i + 1]);
    let t = (x - nodes[i]) / (nodes[i + 1] - nodes[i]);
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * f0 + (-2.0 * t3 + 3.0 * t2) * f1 + (t3 - 2.0 * t2 + t) * d0 + (t3 - t2) * d1
}

/// pbrt-v3's `CatmullRomWeights`: the spline at `x` as `Σ weights[k] · values[offset + k]`
/// (`offset` may be −1 with `weights[0] = 0`, and `offset + 3` may be past the end with
/// `weights[3] = 0`). `None` when `x` is outside the nodes (or not a number).
pub fn catmull_rom_weights(nodes: &[f32], x: f32) -> Option<(isize, [f32; 4])> {
    let n = nodes.len();
    if n < 2 || !(x >= nodes[0] && x <= nodes[n - 1]) {
        return None;
    }
    let idx = find_interval(n, |k| nodes[k] <= x);
    let (x0, x1) = (nodes[idx], nodes[idx + 1]);
    let t = (x - x0) / (x1 - x0);
    let (t2, t3) = (t * t, t * t * t);
    let mut w = [0.0f32; 4];
    w[1] = 2.0 * t3 - 3.0 * t2 + 1.0;
    w[2] = -2.0 * t3 + 3.0 * t2;
    if idx > 0 {
        let w0 = (t3 - 2.0 * t2 + t) * (x1 - x0) / (x1 - nodes[idx - 1]);
        w[0] = -w0;
        w[2] += w0;
    } else {
        let w0 = t3 - 2.0 * t2 + t;
        w[0] = 0.0;
        w[1] -= w0;
        w[2] += w0;
    }
    if idx + 2 < n {
        let w3 = (t3 - t2) * (x1 - x0) / (nodes[idx + 2] - x0);
        w[1] -= w3;
        w[3] = w3;
    } else {
        let w3 = t3 - t2;
        w[1] -= w3;
        w[2] += w3;
        w[3] = 0.0;
    }
    Some((idx as isize - 1, w))
}

/// pbrt-v3's `IntegrateCatmullRom`: the running integral of the spline through `(x, values)`
/// at every node (`cdf[0] = 0`); returns the total.
pub fn integrate_catmull_rom(x: &[f32], values: &[f32], cdf: &mut [f32]) -> f32 {
    let n = x.len().min(values.len()).min(cdf.len());
    if n == 0 {
        return 0.0;
    }
    let mut sum = 0.0f32;
    cdf[0] = 0.0;
    for i in 0..n.saturating_sub(1) {
        let (d0, d1) = segment_derivatives(&x[..n], |k| values[k], i);
        let width = x[i + 1] - x[i];
        sum += ((d0 - d1) * (1.0 / 12.0) + (values[i] + values[i + 1]) * 0.5) * width;
        cdf[i + 1] = sum;
    }
    sum
}

/// pbrt-v3's `InvertCatmullRom`: the `x` where the (increasing) spline through `(x, values)`
/// takes the value `u`, clamped to the end nodes.
pub fn invert_catmull_rom(x: &[f32], values: &[f32], u: f32) -> f32 {
    let n = x.len().min(values.len());
    if n < 2 {
        return x.first().copied().unwrap_or(0.0);
    }
    if !(u > values[0]) {
        return x[0];
    } else if !(u < values[n - 1]) {
        return x[n - 1];
    }
    let i = find_interval(n, |k| values[k] <= u);
    let (d0, d1) = segment_derivatives(&x[..n], |k| values[k], i);
    let (f0, f1) = (values[i], values[i + 1]);
    let (x0, width) = (x[i], x[i + 1] - x[i]);
    let (mut a, mut b, mut t) = (0.0f32, 1.0f32, 0.5f32);
    for _ in 0..MAX_STEPS {
        if !(t > a && t < b) {
            t = 0.5 * (a + b);
        }
        let (t2, t3) = (t * t, t * t * t);
        let big_f =
            (2.0 * t3 - 3.0 * t2 + 1.0) * f0 + (-2.0 * t3 + 3.0 * t2) * f1 + (t3 - 2.0 * t2 + t) * d0 + (t3 - t2) * d1;
        let f = (6.0 * t2 - 6.0 * t) * f0
            + (-6.0 * t2 + 6.0 * t) * f1
            + (3.0 * t2 - 4.0 * t + 1.0) * d0
            + (3.0 * t2 - 2.0 * t) * d1;
        if (big_f - u).abs() < 1e-6 || b - a < 1e-6 {
            break;
        }
        if big_f - u < 0.0 {
            a = t;
        } else {
            b = t;
        }
        t -= (big_f - u) / f;
    }
    x0 + t * width
}

/// Inverts the integral of one spline segment with values `f0, f1` and scaled derivatives
/// `d0, d1` at `u` (already divided by the width): `(t, f(t))`, Newton steps in a bisection
/// bracket as pbrt-v3's `SampleCatmullRom`/`SampleCatmullRom2D` do.
fn invert_segment(f0: f32, f1: f32, d0: f32, d1: f32, u: f32) -> (f32, f32) {
    let mut t = if f0 != f1 { (f0 - (f0 * f0 + 2.0 * u * (f1 - f0)).max(0.0).sqrt()) / (f0 - f1) } else { u / f0 };
    let (mut a, mut b) = (0.0f32, 1.0f32);
    let mut fhat = f0;
    for _ in 0..MAX_STEPS {
        if !(t >= a && t <= b) {
            t = 0.5 * (a + b);
        }
        let big_f = t
            * (f0
                + t * (0.5 * d0
                    + t * ((1.0 / 3.0) * (-2.0 * d0 - d1) + f1 - f0 + t * (0.25 * (d0 + d1) + 0.5 * (f0 - f1)))));
        fhat = f0 + t * (d0 + t * (-2.0 * d0 - d1 + 3.0 * (f1 - f0) + t * (d0 + d1 + 2.0 * (f0 - f1))));
        if (big_f - u).abs() < 1e-6 || b - a < 1e-6 {
            break;
        }
        if big_f - u < 0.0 {
            a = t;
        } else {
            b = t;
        }
        t -= (big_f - u) / fhat;
    }
    (t, fhat)
}

/// A sample of [`sample_catmull_rom_2d`]: the position, the spline's value there and the density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplineSample {
    pub x: f32,
    pub value: f32,
    pub pdf: f32,
}

/// pbrt-v3's `SampleCatmullRom2D`: samples the second coordinate of a 2D table (`values` and
/// its running integrals `cdf` along the second axis, both `nodes1.len() × nodes2.len()`,
/// row-major in the first axis) interpolated by the spline in the first coordinate at `alpha`.
/// `None` when `alpha` is outside `nodes1` or the tables are too short.
pub fn sample_catmull_rom_2d(
    nodes1: &[f32],
    nodes2: &[f32],
    values: &[f32],
    cdf: &[f32],
    alpha: f32,
    u: f32,
) -> Option<SplineSample> {
    let size2 = nodes2.len();
    if size2 < 2 || values.len() < nodes1.len() * size2 || cdf.len() < nodes1.len() * size2 {
        return None;
    }
    let (offset, weights) = catmull_rom_weights(nodes1, alpha)?;
    let interpolate = |array: &[f32], idx: usize| -> f32 {
        let mut v = 0.0;
        for (i, w) in weights.iter().enumerate() {
            if *w != 0.0 {
                v += array[(offset + i as isize) as usize * size2 + idx] * w;
            }
        }
        v
    };
    let maximum = interpolate(cdf, size2 - 1);
    let u = u * maximum;
    let idx = find_interval(size2, |i| interpolate(cdf, i) <= u);
    let (f0, f1) = (interpolate(values, idx), interpolate(values, idx + 1));
    let (x0, x1) = (nodes2[idx], nodes2[idx + 1]);
    let width = x1 - x0;
    let d0 = if idx > 0 { width * (f1 - interpolate(values, idx - 1)) / (x1 - nodes2[idx - 1]) } else { f1 - f0 };
    let d1 =
        if idx + 2 < size2 { width * (interpolate(values, idx + 2) - f0) / (nodes2[idx + 2] - x0) } else { f1 - f0 };
    let u = (u - interpolate(cdf, idx)) / width;
    let (t, fhat) = invert_segment(f0, f1, d0, d1, u);
    Some(SplineSample { x: x0 + width * t, value: fhat, pdf: fhat / maximum })
}

/// pbrt-v3's `Fourier`: `Σ_{k < m} a_k cos(k φ)` by the Chebyshev recurrence, in f64.
pub fn fourier(a: &[f32], cos_phi: f64) -> f32 {
    let mut value = 0.0f64;
    let (mut cos_prev, mut cos_cur) = (cos_phi, 1.0f64);
    for &ak in a {
        value += ak as f64 * cos_cur;
        let next = 2.0 * cos_phi * cos_cur - cos_prev;
        cos_prev = cos_cur;
        cos_cur = next;
    }
    value as f32
}

/// A sample of [`sample_fourier`]: the angle in `[0, 2π)`, the series' value there and the
/// density in φ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FourierSample {
    pub phi: f32,
    pub value: f32,
    pub pdf: f32,
}

/// pbrt-v3's `SampleFourier`: samples φ ∝ the even series `a` (positive, `a[0] > 0`) with
/// `u ∈ [0, 1)`: one half of the circle by `u`, then Newton–bisection on the integral.
pub fn sample_fourier(a: &[f32], u: f32) -> FourierSample {
    let flip = u >= 0.5;
    let u = if flip { 1.0 - 2.0 * (u as f64 - 0.5) } else { u as f64 * 2.0 };
    let a0 = a.first().copied().unwrap_or(0.0) as f64;
    let (mut lo, mut hi, mut phi) = (0.0f64, PI, 0.5 * PI);
    let mut f = a0;
    for _ in 0..MAX_STEPS {
        let cos_phi = phi.cos();
        let sin_phi = (1.0 - cos_phi * cos_phi).max(0.0).sqrt();
        let (mut cos_prev, mut cos_cur) = (cos_phi, 1.0f64);
        let (mut sin_prev, mut sin_cur) = (-sin_phi, 0.0f64);
        let mut big_f = a0 * phi;
        f = a0;
        for (k, &ak) in a.iter().enumerate().skip(1) {
            let sin_next = 2.0 * cos_phi * sin_cur - sin_prev;
            let cos_next = 2.0 * cos_phi * cos_cur - cos_prev;
            sin_prev = sin_cur;
            sin_cur = sin_next;
            cos_prev = cos_cur;
            cos_cur = cos_next;
            big_f += ak as f64 / k as f64 * sin_next;
            f += ak as f64 * cos_next;
        }
        big_f -= u * a0 * PI;
        if big_f > 0.0 {
            hi = phi;
        } else {
            lo = phi;
        }
        if big_f.abs() < 1e-6 || hi - lo < 1e-6 {
            break;
        }
        phi -= big_f / f;
        if !(phi > lo && phi < hi) {
            phi = 0.5 * (lo + hi);
        }
    }
    if flip {
        phi = 2.0 * PI - phi;
    }
    FourierSample { phi: phi as f32, value: f as f32, pdf: (f / (2.0 * PI * a0)) as f32 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_reproduce_the_spline_and_cubics() {
        let nodes = [-1.0f32, -0.7, -0.2, 0.0, 0.3, 0.55, 1.0];
        // The spline reproduces linear functions exactly (its finite differences are exact).
        let lin: Vec<f32> = nodes.iter().map(|x| 0.3 + 2.0 * x).collect();
        for k in 0..=200 {
            let x = -1.0 + 2.0 * k as f32 / 200.0;
            let (off, w) = catmull_rom_weights(&nodes, x).unwrap();
            let mut v = 0.0;
            for (i, wi) in w.iter().enumerate() {
                if *wi != 0.0 {
                    v += wi * lin[(off + i as isize) as usize];
                }
            }
            assert!((v - (0.3 + 2.0 * x)).abs() < 1e-5, "{x}: {v}");
            assert!((catmull_rom(&nodes, &lin, x) - v).abs() < 1e-5);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
        assert!(catmull_rom_weights(&nodes, 1.01).is_none());
        assert!(catmull_rom_weights(&nodes, f32::NAN).is_none());
        assert_eq!(catmull_rom(&nodes, &lin, -2.0), 0.0);
    }

    #[test]
    fn integral_and_inverse_of_a_linear_spline() {
        let x: Vec<f32> = (0..9).map(|i| (i as f32 / 8.0).powf(1.5)).collect();
        let f: Vec<f32> = x.iter().map(|x| 1.0 + x).collect();
        let mut cdf = vec![0.0; x.len()];
        let total = integrate_catmull_rom(&x, &f, &mut cdf);
        assert!((total - 1.5).abs() < 1e-5, "{total}");
        for (xi, c) in x.iter().zip(&cdf) {
            assert!((c - (xi + xi * xi / 2.0)).abs() < 1e-5);
        }
        for u in [1.1f32, 1.5, 1.9] {
            let xi = invert_catmull_rom(&x, &f, u);
            assert!((xi - (u - 1.0)).abs() < 1e-4, "{u}: {xi}");
        }
        assert_eq!(invert_catmull_rom(&x, &f, 0.0), 0.0);
        assert_eq!(invert_catmull_rom(&x, &f, 9.0), 1.0);
    }

    #[test]
    fn spline_2d_sampling_matches_its_density() {
        // Rows of f(x) = 1 + a x over x in [0, 1] for a = 0, 1, 2 (linear: the spline is exact).
        let n1 = [0.0f32, 1.0, 2.0];
        let n2: Vec<f32> = (0..11).map(|i| i as f32 / 10.0).collect();
        let mut values = vec![];
        let mut cdf = vec![0.0; 33];
        for (r, a) in n1.iter().enumerate() {
            let row: Vec<f32> = n2.iter().map(|x| 1.0 + a * x).collect();
            integrate_catmull_rom(&n2, &row, &mut cdf[r * 11..(r + 1) * 11]);
            values.extend(row);
        }
        let a = 1.5f32;
        let mut rng = crate::rng::Rng::new(3);
        let bins = 20;
        let mut hist = vec![0.0f64; bins];
        let n = 200_000;
        for _ in 0..n {
            let s = sample_catmull_rom_2d(&n1, &n2, &values, &cdf, a, rng.uniform_f32()).unwrap();
            let expect = (1.0 + a * s.x) / (1.0 + a / 2.0);
            assert!((s.pdf - expect).abs() < 1e-3, "{s:?} vs {expect}");
            hist[((s.x * bins as f32) as usize).min(bins - 1)] += 1.0;
        }
        let expected: Vec<f64> = (0..bins)
            .map(|i| {
                let (x0, x1) = (i as f64 / bins as f64, (i + 1) as f64 / bins as f64);
                let big = |x: f64| x + a as f64 * x * x / 2.0;
                n as f64 * (big(x1) - big(x0)) / (1.0 + a as f64 / 2.0)
            })
            .collect();
        let (chi2, dof, p) = crate::goodness_of_fit::chi2_test(&hist, &expected, 5.0);
        assert!(p > 1e-4, "chi2 {chi2} dof {dof} p {p}");
        assert!(sample_catmull_rom_2d(&n1, &n2, &values, &cdf, 2.5, 0.5).is_none());
    }

    #[test]
    fn fourier_series_and_its_sampling() {
        let a = [1.0f32, 0.6, 0.25, -0.1];
        for k in 0..50 {
            let phi = k as f64 * 0.13;
            let direct: f64 = a.iter().enumerate().map(|(k, ak)| *ak as f64 * (k as f64 * phi).cos()).sum();
            assert!((fourier(&a, phi.cos()) as f64 - direct).abs() < 1e-5);
        }
        let mut rng = crate::rng::Rng::new(9);
        let bins = 36;
        let mut hist = vec![0.0f64; bins];
        let n = 200_000;
        let tau = 2.0 * std::f64::consts::PI;
        for _ in 0..n {
            let s = sample_fourier(&a, rng.uniform_f32());
            assert!((0.0..tau as f32 + 1e-5).contains(&s.phi), "{s:?}");
            let f = fourier(&a, (s.phi as f64).cos());
            assert!((s.value - f).abs() < 1e-4 && (s.pdf - f / (tau as f32)).abs() < 1e-4, "{s:?}");
            hist[((s.phi as f64 / tau * bins as f64) as usize).min(bins - 1)] += 1.0;
        }
        let integral = |phi: f64| {
            a[0] as f64 * phi
                + a.iter()
                    .enumerate()
                    .skip(1)
                    .map(|(k, ak)| *ak as f64 * (k as f64 * phi).sin() / k as f64)
                    .sum::<f64>()
        };
        let expected: Vec<f64> = (0..bins)
            .map(|i| {
                let (p0, p1) = (i as f64 * tau / bins as f64, (i + 1) as f64 * tau / bins as f64);
                n as f64 * (integral(p1) - integral(p0)) / (a[0] as f64 * tau)
            })
            .collect();
        let (chi2, dof, p) = crate::goodness_of_fit::chi2_test(&hist, &expected, 5.0);
        assert!(p > 1e-4, "chi2 {chi2} dof {dof} p {p}");
    }

    #[test]
    fn degenerate_input_terminates() {
        let nan = [f32::NAN; 4];
        let _ = sample_fourier(&nan, 0.3);
        let _ = sample_fourier(&[], 0.3);
        let _ = invert_catmull_rom(&[0.0, 1.0], &[1.0, 0.0], 0.5);
        let x = [0.0f32, 1.0, 2.0];
        let _ = sample_catmull_rom_2d(&x, &x, &[f32::NAN; 9], &[f32::NAN; 9], 0.5, 0.5);
        let _ = sample_catmull_rom_2d(&x, &x, &[0.0; 9], &[0.0; 9], 0.5, 0.5);
    }
}
