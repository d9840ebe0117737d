//! The SH exponential `exp*(f) = 1 + f + f∗f/2! + f∗f∗f/3! + …` (left-associated products,
//! i.e. `expm(M_f)·1`) and the SH logarithm (Ren et al. 2006, as restated in seed 003 §3.1.4).
//!
//! Every method isolates the DC term first: `f = (f₀/√4π) 1 + f̂` gives
//! `exp*(f) = e^{f₀/√4π} exp*(f̂)` exactly (`M_f = (f₀/√4π) I + M_f̂`), so `exp*(c·1)` is
//! `e^{c/√4π}·1` to the last bit. Then, for `f̂`:
//! - [`ExpMethod::ScalingSquaring`] (the default): `f̂/2^p` with `p` the smallest making
//!   `‖f̂‖/2^p ≤ threshold`, a Taylor polynomial in SH products (terms added until one is below
//!   `tolerance·√4π`, at most `max_degree`), then `p` squarings. Each squaring is an order-`n`
//!   product of a truncated vector, not `exp*` itself: it costs accuracy (measured at order 4,
//!   sums of 8 log-blockers up to 35°: irradiance/π off by 4.8e-4 with threshold 0.5 and a
//!   degree-4 base, against 6e-8 without squaring), so the default squares only past
//!   `‖f̂‖ = 4` and lets the base be as long as it needs (about 25 products at `‖f̂‖ = 4`);
//!   `tolerance 0` with a small `max_degree` is the classic fixed short base;
//! - [`ExpMethod::OptimalLinear`]: `a(‖f̂‖) 1 + b(‖f̂‖) f̂` with `a, b` tabulated from single
//!   cap blockers ([`OptimalLinearTable`]), no product at all;
//! - [`ExpMethod::Hybrid`]: optimal linear at `f̂/2^p`, then `p` squarings.
//!
//! [`exp_eigen`] is the definition itself by a symmetric eigen-decomposition of `M_f` (the
//! reference for tests and tables); [`log_star`] is `Q q′(Λ) Qᵀ (g − 1)` with
//! `M_g = Q Λ Qᵀ`, `q′(x) = ln x/(x − 1)` and eigenvalues clipped below at `ε_rel·λ_max`.

use super::tables::OptimalLinearTable;
use super::{check_len, index, product::TripleProduct, ShError, ShOrder, SQRT_4PI};
use nalgebra::DMatrix;

/// How [`ShExp`] evaluates `exp*(f̂)`.
#[derive(Clone, Debug, PartialEq)]
pub enum ExpMethod {
    ScalingSquaring { threshold: f64, max_degree: u32, tolerance: f64 },
    OptimalLinear(OptimalLinearTable),
    Hybrid { table: OptimalLinearTable, threshold: f64 },
}

impl Default for ExpMethod {
    /// Squarings past `‖f̂‖ = 4`, a Taylor base to `1e-10` (at most degree 40): within 1e-9
    /// of [`exp_eigen`] wherever `‖f̂‖ ≤ 4` (test `scaling_and_squaring_matches_eigen_exp`).
    fn default() -> Self {
        ExpMethod::ScalingSquaring { threshold: 4.0, max_degree: 40, tolerance: 1e-10 }
    }
}

/// Buffers for [`ShExp::exp`], so a shading point allocates nothing.
#[derive(Clone, Debug)]
pub struct ExpScratch {
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl ExpScratch {
    pub fn new(order: ShOrder) -> ExpScratch {
        let k = order.coeffs();
        ExpScratch { a: vec![0.0; k], b: vec![0.0; k], c: vec![0.0; k] }
    }
}

/// The SH exponential at one order with one method.
#[derive(Clone, Debug)]
pub struct ShExp {
    products: &'static TripleProduct,
    method: ExpMethod,
}

/// The number of squarings bringing `norm` to at most `threshold`.
fn squarings(norm: f64, threshold: f64) -> u32 {
    if norm <= threshold {
        0
    } else {
        (norm / threshold).log2().ceil().clamp(0.0, 1000.0) as u32
    }
}

impl ShExp {
    pub fn new(order: ShOrder, method: ExpMethod) -> Result<ShExp, ShError> {
        let products = TripleProduct::shared(order)?;
        let bad = |t: f64| !(t > 0.0) || !t.is_finite();
        match &method {
            ExpMethod::ScalingSquaring { threshold, max_degree, tolerance }
                if *max_degree == 0 || bad(*threshold) || !(*tolerance >= 0.0) =>
            {
                return Err(ShError::Invalid(format!(
                    "exp*: threshold {threshold}, max_degree {max_degree}, tolerance {tolerance} invalid"
                )));
            }
            ExpMethod::Hybrid { threshold, .. } if bad(*threshold) => {
                return Err(ShError::Invalid(format!("exp*: threshold {threshold} invalid")));
            }
            _ => {}
        }
        Ok(ShExp { products, method })
    }

    pub fn order(&self) -> ShOrder {
        self.products.order()
    }

    pub fn method(&self) -> &ExpMethod {
        &self.method
    }

    /// The squarings [`exp`](Self::exp) will do for `f` (0 for optimal linear).
    pub fn squarings_for(&self, f: &[f64]) -> u32 {
        let norm = f.iter().skip(1).take(self.order().coeffs() - 1).map(|v| v * v).sum::<f64>().sqrt();
        match &self.method {
            ExpMethod::ScalingSquaring { threshold, .. } | ExpMethod::Hybrid { threshold, .. } => {
                squarings(norm, *threshold)
            }
            ExpMethod::OptimalLinear(_) => 0,
        }
    }

    /// `out = exp*(f)`; `f` and `out` at least `n²` long; non-finite input is an error.
    pub fn exp(&self, f: &[f64], out: &mut [f64], s: &mut ExpScratch) -> Result<(), ShError> {
        let k = self.order().coeffs();
        check_len("exp* input", f.len(), k)?;
        check_len("exp* output", out.len(), k)?;
        check_len("exp* scratch", s.a.len().min(s.b.len()).min(s.c.len()), k)?;
        if f[..k].iter().any(|v| !v.is_finite()) {
            return Err(ShError::Invalid("exp*: non-finite coefficient".into()));
        }
        let dc = (f[0] / SQRT_4PI).exp();
        let norm = f[1..k].iter().map(|v| v * v).sum::<f64>().sqrt();
        let p = match &self.method {
            ExpMethod::ScalingSquaring { threshold, max_degree, tolerance } => {
                let p = squarings(norm, *threshold);
                self.taylor(f, 0.5f64.powi(p as i32), *max_degree, *tolerance * SQRT_4PI, out, s);
                p
            }
            ExpMethod::OptimalLinear(t) => {
                optimal_linear(t, f, norm, 1.0, out, k);
                0
            }
            ExpMethod::Hybrid { table, threshold } => {
                let p = squarings(norm, *threshold);
                optimal_linear(table, f, norm, 0.5f64.powi(p as i32), out, k);
                p
            }
        };
        for _ in 0..p {
            s.a[..k].copy_from_slice(&out[..k]);
            self.products.product_unchecked(&s.a, &s.a, out);
        }
        out[..k].iter_mut().for_each(|v| *v *= dc);
        Ok(())
    }

    /// [`exp`](Self::exp) into a new vector.
    pub fn exp_vec(&self, f: &[f64]) -> Result<Vec<f64>, ShError> {
        let mut out = vec![0.0; self.order().coeffs()];
        self.exp(f, &mut out, &mut ExpScratch::new(self.order()))?;
        Ok(out)
    }

    /// `out = Σ_j (h^{∗j})/j!` for `h = scale·f̂` (left-associated products), up to
    /// `max_degree` or until a term's norm is at most `stop`.
    fn taylor(&self, f: &[f64], scale: f64, max_degree: u32, stop: f64, out: &mut [f64], s: &mut ExpScratch) {
        let k = self.order().coeffs();
        let h = &mut s.b[..k];
        h[0] = 0.0;
        h[1..].iter_mut().zip(&f[1..k]).for_each(|(a, b)| *a = b * scale);
        out[..k].copy_from_slice(h);
        out[0] = SQRT_4PI;
        let term = &mut s.c[..k];
        term.copy_from_slice(h);
        for j in 2..=max_degree {
            s.a[..k].copy_from_slice(term);
            self.products.product_unchecked(h, &s.a, term);
            let inv = 1.0 / j as f64;
            let mut norm2 = 0.0;
            term.iter_mut().zip(out.iter_mut()).for_each(|(t, o)| {
                *t *= inv;
                *o += *t;
                norm2 += *t * *t;
            });
            if norm2 <= stop * stop {
                break;
            }
        }
    }
}

/// `out = a(‖h‖) 1 + b(‖h‖) h` for `h = scale·f̂`.
fn optimal_linear(t: &OptimalLinearTable, f: &[f64], norm: f64, scale: f64, out: &mut [f64], k: usize) {
    let (a, b) = t.lookup(norm * scale);
    out[0] = a * SQRT_4PI;
    out[1..k].iter_mut().zip(&f[1..k]).for_each(|(o, x)| *o = b * scale * x);
}

/// An eigen-decomposition `M = Q Λ Qᵀ` of a symmetric matrix.
struct Eigen {
    values: Vec<f64>,
    vectors: DMatrix<f64>,
}

/// The eigen-decomposition of the symmetric row-major `n × n` matrix `m`, by nalgebra's real
/// Schur decomposition (for a symmetric matrix `T` is diagonal). Not nalgebra's
/// `SymmetricEigen`: on product matrices, whose eigenvalues come in close clusters, it returns
/// decompositions with `|QΛQᵀ − M|` up to 0.2 (nalgebra issue #1109, swapped eigenvectors),
/// where the Schur route stays at 1e-14 (test `eigen_decomposition_reconstructs`).
fn symmetric_eigen(m: Vec<f64>, n: usize) -> Result<Eigen, ShError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(ShError::Invalid("SH eigen-decomposition: non-finite coefficient".into()));
    }
    let a = DMatrix::from_row_slice(n, n, &m);
    let a = (&a + a.transpose()) * 0.5;
    let scale = a.abs().max().max(f64::MIN_POSITIVE);
    let off_diagonal = |t: &DMatrix<f64>| {
        (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .fold(0.0f64, |w, (i, j)| w.max(t[(i, j)].abs()))
    };
    if off_diagonal(&a) == 0.0 {
        return Ok(Eigen { values: (0..n).map(|i| a[(i, i)]).collect(), vectors: DMatrix::identity(n, n) });
    }
    let fail = || ShError::Invalid("SH eigen-decomposition did not converge".into());
    let (q, t) = nalgebra::Schur::try_new(a, f64::EPSILON, 100_000).ok_or_else(fail)?.unpack();
    if !(off_diagonal(&t) <= 1e-9 * scale) {
        return Err(fail());
    }
    Ok(Eigen { values: (0..n).map(|i| t[(i, i)]).collect(), vectors: q })
}

/// `exp*(f) = expm(M_f)·1` by the eigen-decomposition `M_f = Q Λ Qᵀ` (the definition).
pub fn exp_eigen(products: &TripleProduct, f: &[f64]) -> Result<Vec<f64>, ShError> {
    let k = products.order().coeffs();
    let e = symmetric_eigen(products.product_matrix(f)?, k)?;
    let q = &e.vectors;
    // Q e^Λ Qᵀ (√4π, 0, …): column 0 of Qᵀ is row 0 of Q.
    Ok((0..k).map(|i| (0..k).map(|c| q[(i, c)] * e.values[c].exp() * q[(0, c)]).sum::<f64>() * SQRT_4PI).collect())
}

/// `q′(x) = ln x/(x − 1)`, continuous at 1.
fn log_ratio(x: f64) -> f64 {
    let d = x - 1.0;
    if d.abs() < 1e-9 {
        1.0 - 0.5 * d
    } else {
        d.ln_1p() / d
    }
}

/// `λ'ᵢ = q′(max(λᵢ, ε_rel·λ_max))`; an error when `M_g` has no positive eigenvalue.
fn clipped_log_ratios(eigenvalues: &[f64], lambda_max: f64, eps_rel: f64) -> Result<Vec<f64>, ShError> {
    if !(lambda_max > 0.0) || !(eps_rel > 0.0) || !(eps_rel < 1.0) {
        return Err(ShError::Invalid(format!(
            "log*: needs a positive eigenvalue and 0 < ε_rel < 1 (λ_max {lambda_max}, ε_rel {eps_rel})"
        )));
    }
    Ok(eigenvalues.iter().map(|&l| log_ratio(l.max(eps_rel * lambda_max))).collect())
}

/// `log*(g) = Q q′(Λ) Qᵀ (g − 1)`, eigenvalues of `M_g` clipped below at `eps_rel·λ_max`
/// (seed 003 leaves ε open; shexp-demo's `0.02` reproduces the digest's tables).
pub fn log_star(products: &TripleProduct, g: &[f64], eps_rel: f64) -> Result<Vec<f64>, ShError> {
    let k = products.order().coeffs();
    let e = symmetric_eigen(products.product_matrix(g)?, k)?;
    let lmax = e.values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let ratios = clipped_log_ratios(&e.values, lmax, eps_rel)?;
    let mut gm1 = g[..k].to_vec();
    gm1[0] -= SQRT_4PI;
    Ok(apply_function(&e.vectors, &ratios, &gm1))
}

/// `Q diag(d) Qᵀ v`.
fn apply_function(q: &DMatrix<f64>, d: &[f64], v: &[f64]) -> Vec<f64> {
    let k = v.len();
    let proj: Vec<f64> = (0..k).map(|c| d[c] * (0..k).map(|r| q[(r, c)] * v[r]).sum::<f64>()).collect();
    (0..k).map(|r| (0..k).map(|c| q[(r, c)] * proj[c]).sum()).collect()
}

/// The `m`-block of `M_g` for a zonal `g` (rows and columns `(l, m)`, `l = m … n−1`).
fn zonal_block(products: &TripleProduct, zh: &[f64], m: usize) -> Vec<f64> {
    let n = products.order().n();
    let size = n - m;
    let mut b = vec![0.0; size * size];
    for r in 0..size {
        for c in 0..size {
            let (i, j) = (index(m + r, m as i32), index(m + c, m as i32));
            b[r * size + c] = (0..n).map(|l| products.get(i, j, index(l, 0)) * zh[l]).sum();
        }
    }
    b
}

/// [`exp_eigen`] of a zonal vector (its `m = 0` block suffices: 1 lies in it), as ZH.
pub fn exp_eigen_zonal(products: &TripleProduct, zh: &[f64]) -> Result<Vec<f64>, ShError> {
    let n = products.order().n();
    check_len("exp* zonal input", zh.len(), n)?;
    let e = symmetric_eigen(zonal_block(products, zh, 0), n)?;
    let q = &e.vectors;
    Ok((0..n).map(|i| (0..n).map(|c| q[(i, c)] * e.values[c].exp() * q[(0, c)]).sum::<f64>() * SQRT_4PI).collect())
}

/// [`log_star`] of a zonal vector (`zh`, one coefficient per band, order = its length), as a
/// zonal vector. `M_g` of a zonal `g` is block-diagonal by `m` (the `±m` blocks equal), and
/// `g − 1` lies in the `m = 0` block, so `n` eigenproblems of size `n − m` replace one of size
/// `n²` — the log-blocker table is then cheap at any order.
pub fn log_star_zonal(products: &TripleProduct, zh: &[f64], eps_rel: f64) -> Result<Vec<f64>, ShError> {
    log_star_zonal_refined(products, zh, eps_rel, 0)
}

/// [`log_star_zonal`] followed by up to `iterations` Newton steps on `exp*(f) = g`
/// (`δ = M_g⁻¹ (g − exp*(f))`, the same clipped eigenvalues, each step kept only if it lowers
/// the residual). The thesis's formula inverts `exp*` only to first order in the truncation
/// (`exp*(log* B_20°)` misses `B` by 2.1e-6 at order 4); the steps take that to rounding
/// wherever no eigenvalue is clipped, and never make it worse.
pub fn log_star_zonal_refined(
    products: &TripleProduct,
    zh: &[f64],
    eps_rel: f64,
    iterations: usize,
) -> Result<Vec<f64>, ShError> {
    let n = products.order().n();
    check_len("log* zonal input", zh.len(), n)?;
    let mut lmax = f64::NEG_INFINITY;
    for m in 1..n {
        lmax = symmetric_eigen(zonal_block(products, zh, m), n - m)?.values.iter().copied().fold(lmax, f64::max);
    }
    let e0 = symmetric_eigen(zonal_block(products, zh, 0), n)?;
    lmax = e0.values.iter().copied().fold(lmax, f64::max);
    let ratios = clipped_log_ratios(&e0.values, lmax, eps_rel)?;
    let mut gm1 = zh[..n].to_vec();
    gm1[0] -= SQRT_4PI;
    let mut f = apply_function(&e0.vectors, &ratios, &gm1);
    let inverse: Vec<f64> = e0.values.iter().map(|&l| 1.0 / l.max(eps_rel * lmax)).collect();
    let residual = |f: &[f64]| -> Result<(Vec<f64>, f64), ShError> {
        let r: Vec<f64> = exp_eigen_zonal(products, f)?.iter().zip(zh).map(|(e, g)| g - e).collect();
        let norm = r.iter().map(|v| v * v).sum::<f64>();
        Ok((r, norm))
    };
    let (mut r, mut norm) = residual(&f)?;
    for _ in 0..iterations {
        let delta = apply_function(&e0.vectors, &inverse, &r);
        let next: Vec<f64> = f.iter().zip(&delta).map(|(a, b)| a + b).collect();
        let (r2, n2) = residual(&next)?;
        if !(n2 < norm) {
            break;
        }
        (f, r, norm) = (next, r2, n2);
    }
    Ok(f)
}

#[cfg(test)]
mod tests;
