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
//! [`exp_eigen`](super::eigen::exp_eigen) is the definition itself by a symmetric eigen-decomposition of `M_f` (the
//! reference for tests and tables, in [`super::eigen`]); [`log_star`](super::eigen::log_star) is `Q q′(Λ) Qᵀ (g − 1)` with
//! `M_g = Q Λ Qᵀ`, `q′(x) = ln x/(x − 1)` and eigenvalues clipped below at `ε_rel·λ_max`.

use super::tables::OptimalLinearTable;
use super::{check_len, product::TripleProduct, ShError, ShOrder, SQRT_4PI};

/// How [`ShExp`] evaluates `exp*(f̂)`.
#[derive(Clone, Debug, PartialEq)]
pub enum ExpMethod {
    ScalingSquaring { threshold: f64, max_degree: u32, tolerance: f64 },
    OptimalLinear(OptimalLinearTable),
    Hybrid { table: OptimalLinearTable, threshold: f64 },
}

impl Default for ExpMethod {
    /// Squarings past `‖f̂‖ = 4`, a Taylor base to `1e-10` (at most degree 40): within 1e-9
    /// of [`exp_eigen`](super::eigen::exp_eigen) wherever `‖f̂‖ ≤ 4` (test `scaling_and_squaring_matches_eigen_exp`).
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

#[cfg(test)]
mod tests;
