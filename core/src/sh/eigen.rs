//! `exp*` and `log*` by the eigen-decomposition of the product matrix `M_f` (the definitions):
//! the reference the fast exponential of [`super::exp`] is tested against and the tables of
//! [`super::tables`] are built with.

use super::{check_len, index, product::TripleProduct, ShError, SQRT_4PI};
use nalgebra::DMatrix;

/// An eigen-decomposition `M = Q Λ Qᵀ` of a symmetric matrix.
pub(super) struct Eigen {
    pub(super) values: Vec<f64>,
    pub(super) vectors: DMatrix<f64>,
}

/// The eigen-decomposition of the symmetric row-major `n × n` matrix `m`, by nalgebra's real
/// Schur decomposition (for a symmetric matrix `T` is diagonal). Not nalgebra's
/// `SymmetricEigen`: on product matrices, whose eigenvalues come in close clusters, it returns
/// decompositions with `|QΛQᵀ − M|` up to 0.2 (nalgebra issue #1109, swapped eigenvectors),
/// where the Schur route stays at 1e-14 (test `eigen_decomposition_reconstructs`).
pub(super) fn symmetric_eigen(m: Vec<f64>, n: usize) -> Result<Eigen, ShError> {
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
