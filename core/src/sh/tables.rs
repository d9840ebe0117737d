//! Tables built with [`log_star`](super::eigen::log_star): the log-blocker table `G_θ` that
//! `shexp` sums per sphere (a zonal vector per cap angle), and the optimal-linear `(a, b)`
//! table of Ren et al.'s cheap exponential, fitted on the pairs `(Ĝ_θ, B_θ)`.

use super::eigen::{exp_eigen, log_star_zonal_refined};
use super::{product::TripleProduct, zonal, ShError, ShOrder, SQRT_4PI};
use std::f64::consts::FRAC_PI_2;

/// The blocker of a cap of half-angle `theta` about +z, `B_θ = 1 − cap_θ`, as ZH.
pub fn blocker(order: ShOrder, theta: f64) -> Vec<f64> {
    let mut b = zonal::cap(order, theta);
    b.iter_mut().for_each(|v| *v = -*v);
    b[0] += SQRT_4PI;
    b
}

/// Newton steps refining each table entry ([`log_star_zonal_refined`]).
pub const LOG_REFINEMENT_STEPS: usize = 4;

/// `G_θ = log*(B_θ)` (refined so that `exp*(G_θ) = B_θ` as far as clipping allows) for `θ_i = i/(N−1) · π/2`, zonal, interpolated linearly in θ.
#[derive(Clone, Debug, PartialEq)]
pub struct LogBlockerTable {
    order: ShOrder,
    eps_rel: f64,
    /// `entries × n`, row `i` is `G_{θ_i}`.
    zh: Vec<f64>,
    entries: usize,
}

impl LogBlockerTable {
    /// The default table of `shexp` (seed 003's digest §12): 1024 entries, `ε_rel = 0.02`.
    pub fn default_for(order: ShOrder) -> Result<LogBlockerTable, ShError> {
        LogBlockerTable::new(order, 1024, 0.02)
    }

    /// `entries ≥ 2` cap angles over [0, π/2], eigenvalues clipped at `eps_rel·λ_max`.
    pub fn new(order: ShOrder, entries: usize, eps_rel: f64) -> Result<LogBlockerTable, ShError> {
        if entries < 2 {
            return Err(ShError::Invalid(format!("log-blocker table: {entries} entries (need ≥ 2)")));
        }
        let products = TripleProduct::shared(order)?;
        let n = order.n();
        let mut zh = Vec::with_capacity(entries * n);
        for i in 0..entries {
            let theta = FRAC_PI_2 * i as f64 / (entries - 1) as f64;
            let g = if i == 0 {
                vec![0.0; n]
            } else {
                log_star_zonal_refined(products, &blocker(order, theta), eps_rel, LOG_REFINEMENT_STEPS)?
            };
            zh.extend_from_slice(&g);
        }
        Ok(LogBlockerTable { order, eps_rel, zh, entries })
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    pub fn eps_rel(&self) -> f64 {
        self.eps_rel
    }

    pub fn entries(&self) -> usize {
        self.entries
    }

    /// The cap angle of entry `i`.
    pub fn theta(&self, i: usize) -> f64 {
        FRAC_PI_2 * i as f64 / (self.entries - 1) as f64
    }

    /// Entry `i` (`G_{θ_i}`, n values).
    pub fn entry(&self, i: usize) -> &[f64] {
        let n = self.order.n();
        &self.zh[i * n..(i + 1) * n]
    }

    /// `G_θ` by linear interpolation (θ clamped to [0, π/2]) into `out[..n]`.
    pub fn lookup(&self, theta: f64, out: &mut [f64]) {
        let n = self.order.n();
        let x = if theta.is_nan() { 0.0 } else { (theta / FRAC_PI_2).clamp(0.0, 1.0) * (self.entries - 1) as f64 };
        let i = (x.floor() as usize).min(self.entries - 2);
        let t = x - i as f64;
        let (a, b) = (self.entry(i), self.entry(i + 1));
        for (l, o) in out.iter_mut().enumerate().take(n) {
            *o = a[l] + t * (b[l] - a[l]);
        }
    }
}

/// Ren et al.'s optimal-linear coefficients `a(‖f̂‖)`, `b(‖f̂‖)`: for each log-blocker `G_θ`,
/// `a = exp*(Ĝ)₀/√4π` and `b = exp*(Ĝ)·Ĝ/(Ĝ·Ĝ)` (exact `exp*`), keyed by `‖Ĝ‖` (entries
/// whose magnitude does not grow with θ are dropped so the key is monotone).
#[derive(Clone, Debug, PartialEq)]
pub struct OptimalLinearTable {
    magnitude: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
}

impl OptimalLinearTable {
    /// Fitted on the entries of `logs`.
    pub fn from_log_table(logs: &LogBlockerTable) -> Result<OptimalLinearTable, ShError> {
        let products = TripleProduct::shared(logs.order())?;
        let k = logs.order().coeffs();
        let (mut magnitude, mut a, mut b) = (vec![0.0], vec![1.0], vec![1.0]);
        let mut full = vec![0.0; k];
        for i in 1..logs.entries() {
            zonal::zh_to_sh(logs.entry(i), &mut full)?;
            full[0] = 0.0;
            let m2: f64 = full.iter().map(|v| v * v).sum();
            let mag = m2.sqrt();
            if !(mag > *magnitude.last().unwrap_or(&0.0)) {
                continue;
            }
            let e = exp_eigen(products, &full)?;
            magnitude.push(mag);
            a.push(e[0] / SQRT_4PI);
            b.push(e.iter().zip(&full).map(|(x, y)| x * y).sum::<f64>() / m2);
        }
        Ok(OptimalLinearTable { magnitude, a, b })
    }

    /// The largest magnitude fitted (lookups beyond it are clamped to it).
    pub fn max_magnitude(&self) -> f64 {
        *self.magnitude.last().unwrap_or(&0.0)
    }

    /// The fitted `(‖Ĝ‖, a, b)` nodes.
    pub fn nodes(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        (0..self.magnitude.len()).map(|i| (self.magnitude[i], self.a[i], self.b[i]))
    }

    /// `(a, b)` at magnitude `m`, linear between nodes, clamped at the ends.
    pub fn lookup(&self, m: f64) -> (f64, f64) {
        let n = self.magnitude.len();
        if n == 1 || !(m > 0.0) {
            return (self.a[0], self.b[0]);
        }
        if m >= self.magnitude[n - 1] {
            return (self.a[n - 1], self.b[n - 1]);
        }
        let i = self.magnitude.partition_point(|&x| x <= m).clamp(1, n - 1) - 1;
        let t = (m - self.magnitude[i]) / (self.magnitude[i + 1] - self.magnitude[i]);
        (self.a[i] + t * (self.a[i + 1] - self.a[i]), self.b[i] + t * (self.b[i + 1] - self.b[i]))
    }
}
