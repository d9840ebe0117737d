//! The SH triple-product tensor `Γ_ijk = ∫ Y_i Y_j Y_k dω`, sparse, the SH product
//! `(f∗g)_i = Σ_jk Γ_ijk f_j g_k` and the product matrix `(M_f)_ij = Σ_k Γ_ijk f_k`
//! (`f∗g = M_f g`, `M_1 = I`).
//!
//! Γ is computed once per order by Gauss quadrature exact for degree `3(n−1)` (so to
//! rounding), only for the triples the selection rules allow (`l`s satisfying the triangle
//! inequality with an even sum; one `|m|` the sum of the other two; an even number of negative
//! `m`s); entries below `1e-12` are exact zeros of the rules' survivors and are dropped.
//! Order 4 keeps 353 ordered triples, order 6 2907.

use super::{band_and_m, basis, check_len, quadrature::SphereQuadrature, ShError, ShOrder};
use std::sync::OnceLock;

/// Highest order for which Γ is built (`2n−1 = 27` bands of exact products in between).
pub const MAX_PRODUCT_ORDER: usize = 14;

/// One non-zero `Γ_ijk` of row `i`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    j: u16,
    k: u16,
    v: f64,
}

/// Γ for one order, stored by rows `i` (all ordered `(j, k)` per row).
#[derive(Clone, Debug, PartialEq)]
pub struct TripleProduct {
    order: ShOrder,
    row_start: Vec<u32>,
    entries: Vec<Entry>,
}

fn selection_rules(a: usize, b: usize, c: usize) -> bool {
    let ((la, ma), (lb, mb), (lc, mc)) = (band_and_m(a), band_and_m(b), band_and_m(c));
    if (la + lb + lc) % 2 == 1 || la > lb + lc || lb > la + lc || lc > la + lb {
        return false;
    }
    let (x, y, z) = (ma.abs(), mb.abs(), mc.abs());
    let negatives = (ma < 0) as u8 + (mb < 0) as u8 + (mc < 0) as u8;
    (x == y + z || y == x + z || z == x + y) && negatives.is_multiple_of(2)
}

impl TripleProduct {
    /// Γ at `order` (at most [`MAX_PRODUCT_ORDER`]).
    pub fn new(order: ShOrder) -> Result<TripleProduct, ShError> {
        let n = order.n();
        if n > MAX_PRODUCT_ORDER {
            return Err(ShError::Order { n, max: MAX_PRODUCT_ORDER });
        }
        let k = order.coeffs();
        let q = SphereQuadrature::exact_for_degree(3 * (n - 1));
        // Basis at every node, weighted once.
        let mut y = vec![0.0; q.len() * k];
        for (node, d) in q.dirs.iter().enumerate() {
            basis::eval_unit(order, *d, &mut y[node * k..(node + 1) * k]);
        }
        let mut unique = Vec::new();
        for a in 0..k {
            for b in a..k {
                for c in b..k {
                    if !selection_rules(a, b, c) {
                        continue;
                    }
                    let v: f64 = (0..q.len()).map(|t| q.weights[t] * y[t * k + a] * y[t * k + b] * y[t * k + c]).sum();
                    if v.abs() > 1e-12 {
                        unique.push((a, b, c, v));
                    }
                }
            }
        }
        let mut ordered = Vec::with_capacity(unique.len() * 6);
        for &(a, b, c, v) in &unique {
            let mut perms = [(a, b, c), (a, c, b), (b, a, c), (b, c, a), (c, a, b), (c, b, a)];
            perms.sort_unstable();
            let mut last = None;
            for p in perms {
                if last != Some(p) {
                    ordered.push((p.0, p.1, p.2, v));
                    last = Some(p);
                }
            }
        }
        ordered.sort_by_key(|x| (x.0, x.1, x.2));
        let mut row_start = vec![0u32; k + 1];
        for &(i, ..) in &ordered {
            row_start[i + 1] += 1;
        }
        for i in 0..k {
            row_start[i + 1] += row_start[i];
        }
        let entries = ordered.iter().map(|&(_, j, k, v)| Entry { j: j as u16, k: k as u16, v }).collect();
        Ok(TripleProduct { order, row_start, entries })
    }

    /// Γ at `order`, built on first use and shared for the life of the program.
    pub fn shared(order: ShOrder) -> Result<&'static TripleProduct, ShError> {
        static CACHE: [OnceLock<TripleProduct>; MAX_PRODUCT_ORDER] = [const { OnceLock::new() }; MAX_PRODUCT_ORDER];
        let n = order.n();
        if n > MAX_PRODUCT_ORDER {
            return Err(ShError::Order { n, max: MAX_PRODUCT_ORDER });
        }
        if let Some(t) = CACHE[n - 1].get() {
            return Ok(t);
        }
        let t = TripleProduct::new(order)?;
        Ok(CACHE[n - 1].get_or_init(|| t))
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    /// The number of non-zero ordered triples `(i, j, k)`.
    pub fn nonzeros(&self) -> usize {
        self.entries.len()
    }

    /// `Γ_ijk` (0 outside the order or where it vanishes).
    pub fn get(&self, i: usize, j: usize, k: usize) -> f64 {
        let n = self.order.coeffs();
        if i >= n {
            return 0.0;
        }
        let row = &self.entries[self.row_start[i] as usize..self.row_start[i + 1] as usize];
        row.binary_search_by(|e| (e.j as usize, e.k as usize).cmp(&(j, k))).map(|p| row[p].v).unwrap_or(0.0)
    }

    /// Every non-zero `(i, j, k, Γ_ijk)`, by `i` then `j` then `k`.
    pub fn iter(&self) -> impl Iterator<Item = (usize, usize, usize, f64)> + '_ {
        (0..self.order.coeffs()).flat_map(move |i| {
            self.entries[self.row_start[i] as usize..self.row_start[i + 1] as usize]
                .iter()
                .map(move |e| (i, e.j as usize, e.k as usize, e.v))
        })
    }

    /// `out = f∗g` (all at least `n²` long; `out` must not alias the inputs).
    pub fn product(&self, f: &[f64], g: &[f64], out: &mut [f64]) -> Result<(), ShError> {
        let n = self.order.coeffs();
        check_len("SH product input", f.len().min(g.len()), n)?;
        check_len("SH product output", out.len(), n)?;
        self.product_unchecked(f, g, out);
        Ok(())
    }

    /// [`product`](Self::product) with the lengths already checked by the caller.
    #[inline]
    pub(crate) fn product_unchecked(&self, f: &[f64], g: &[f64], out: &mut [f64]) {
        let n = self.order.coeffs();
        for (i, o) in out.iter_mut().enumerate().take(n) {
            let row = &self.entries[self.row_start[i] as usize..self.row_start[i + 1] as usize];
            *o = row.iter().map(|e| e.v * f[e.j as usize] * g[e.k as usize]).sum();
        }
    }

    /// The product matrix `M_f`, row-major `n² × n²` (symmetric).
    pub fn product_matrix(&self, f: &[f64]) -> Result<Vec<f64>, ShError> {
        let n = self.order.coeffs();
        check_len("SH product input", f.len(), n)?;
        let mut m = vec![0.0; n * n];
        for (i, j, k, v) in self.iter() {
            m[i * n + j] += v * f[k];
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::{quadrature::reconstruct, SQRT_4PI};

    fn o(n: usize) -> ShOrder {
        ShOrder::new(n).unwrap()
    }

    #[test]
    fn counts_symmetry_and_dc_row() {
        let counts: Vec<usize> = (1..=6).map(|n| TripleProduct::new(o(n)).unwrap().nonzeros()).collect();
        assert_eq!(&counts[2..], &[83, 353, 1158, 2907]);
        let g = TripleProduct::shared(o(5)).unwrap();
        let k = 25;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 1.0 / SQRT_4PI } else { 0.0 };
                assert!((g.get(0, i, j) - want).abs() < 1e-14);
                for l in 0..k {
                    let v = g.get(i, j, l);
                    assert_eq!(v, g.get(j, i, l));
                    assert_eq!(v, g.get(l, j, i));
                    assert_eq!(v, g.get(i, l, j));
                }
            }
        }
        assert!(TripleProduct::new(o(MAX_PRODUCT_ORDER + 1)).is_err());
    }

    /// Every dropped triple really is zero: a brute-force quadrature of all `n⁶` triples at
    /// order 3 agrees with `get` to rounding.
    #[test]
    fn sparse_tensor_equals_brute_force() {
        let g = TripleProduct::new(o(3)).unwrap();
        let q = SphereQuadrature::exact_for_degree(6);
        let mut y = [0.0; 9];
        let mut full = vec![0.0; 729];
        for (d, w) in q.dirs.iter().zip(&q.weights) {
            basis::eval(o(3), *d, &mut y);
            for i in 0..9 {
                for j in 0..9 {
                    for k in 0..9 {
                        full[i * 81 + j * 9 + k] += w * y[i] * y[j] * y[k];
                    }
                }
            }
        }
        for i in 0..9 {
            for j in 0..9 {
                for k in 0..9 {
                    assert!((g.get(i, j, k) - full[i * 81 + j * 9 + k]).abs() < 1e-13);
                }
            }
        }
    }

    #[test]
    fn product_identities() {
        let g = TripleProduct::new(o(4)).unwrap();
        let mut rng = crate::rng::Rng::new(2);
        let f: Vec<f64> = (0..16).map(|_| rng.uniform_f64() - 0.5).collect();
        let h: Vec<f64> = (0..16).map(|_| rng.uniform_f64() - 0.5).collect();
        let mut one = vec![0.0; 16];
        one[0] = SQRT_4PI;
        let mut out = vec![0.0; 16];
        g.product(&f, &one, &mut out).unwrap();
        for i in 0..16 {
            assert!((out[i] - f[i]).abs() < 1e-14, "f∗1 = f");
        }
        g.product(&f, &h, &mut out).unwrap();
        let dot: f64 = f.iter().zip(&h).map(|(a, b)| a * b).sum();
        assert!((out[0] - dot / SQRT_4PI).abs() < 1e-14, "(f∗g)₀ = f·g/√4π");
        // f∗g is the projection of f̃ g̃ (exact quadrature of degree 3·3 + … ≤ 9).
        let q = SphereQuadrature::exact_for_degree(9);
        let p = crate::sh::project(o(4), |d| reconstruct(&f, d) * reconstruct(&h, d), &q);
        for i in 0..16 {
            assert!((out[i] - p[i]).abs() < 1e-13);
        }
        let m = g.product_matrix(&f).unwrap();
        for i in 0..16 {
            let mg: f64 = (0..16).map(|j| m[i * 16 + j] * h[j]).sum();
            assert!((mg - out[i]).abs() < 1e-14, "M_f g = f∗g");
            for j in 0..16 {
                assert_eq!(m[i * 16 + j], m[j * 16 + i]);
            }
        }
        assert!(g.product(&f[..4], &h, &mut out).is_err());
    }
}
