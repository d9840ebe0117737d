//! Prefix-sum tables of radiance-weighted direction moments along meridians (the paper's
//! "SAT over u-isolines"): for each pole axis and meridian, `S[j] = Σ_{j'<j} ∫_{cell j'}
//! L(ω) ω dv` with `L` sampled at sub-cell centres and `ω` integrated exactly, so a constant
//! environment is integrated exactly and `∫_{v_a}^{v_b} L ω dv` costs two interpolated
//! lookups. One set per axis; the `−axis` pole reads the `+axis` set from the other end.

use super::param::{moment, Meridians, PoleFrame};
use glam::DVec3;
use rayon::prelude::*;

/// Sub-cells per cell (in `v`, and sub-wedges in `φ`) at which the radiance is sampled.
const SUPER: usize = 3;

/// `L(ω)·ω` tables: 3 colours × 3 world axes per entry.
#[derive(Clone, Debug)]
pub struct MomentTable {
    n: usize,
    cells: usize,
    /// Per `[axis][meridian]`: the prefix sums at nodes `0..=cells` (colour*3 + xyz), then the
    /// cells' mean radiance (3 each).
    data: Vec<f64>,
}

impl MomentTable {
    fn stride(cells: usize) -> usize {
        (cells + 1) * 9 + cells * 3
    }

    /// Tables for `meridians` with `cells` cells in `v` per meridian, of the radiance `le`.
    pub fn build(m: &Meridians, cells: usize, le: impl Fn(DVec3) -> [f64; 3] + Sync) -> MomentTable {
        let cells = cells.max(1);
        let stride = Self::stride(cells);
        let mut data = vec![0.0; 3 * m.n * stride];
        data.par_chunks_mut(stride).enumerate().for_each(|(row, out)| {
            let (axis, i) = (row / m.n, row % m.n);
            let frame = PoleFrame::new(axis, 1.0);
            let dv = 2.0 / cells as f64;
            let (prefix, means) = out.split_at_mut((cells + 1) * 9);
            let mut acc = [0.0f64; 9];
            for j in 0..cells {
                let mut l = [0.0f64; 3];
                for a in 0..SUPER {
                    let phi = (i as f64 + (a as f64 + 0.5) / SUPER as f64) * m.dphi;
                    let (c, s) = (phi.cos(), phi.sin());
                    for b in 0..SUPER {
                        let v = -1.0 + dv * (j as f64 + (b as f64 + 0.5) / SUPER as f64);
                        let x = le(frame.direction(c, s, v));
                        for ch in 0..3 {
                            l[ch] += x[ch] / (SUPER * SUPER) as f64;
                        }
                    }
                }
                let v0 = -1.0 + dv * j as f64;
                let mom = moment(&frame, m, i, v0, v0 + dv);
                for ch in 0..3 {
                    means[j * 3 + ch] = l[ch];
                    for k in 0..3 {
                        acc[ch * 3 + k] += l[ch] * mom[k];
                    }
                }
                prefix[(j + 1) * 9..(j + 2) * 9].copy_from_slice(&acc);
            }
        });
        MomentTable { n: m.n, cells, data }
    }

    /// `∫_{−1}^{v} L ω dv` on meridian `i` of the `+axis` frame.
    fn at(&self, frame: &PoleFrame, m: &Meridians, i: usize, v: f64) -> [f64; 9] {
        let row = &self.data[(frame.axis * self.n + i) * Self::stride(self.cells)..];
        let x = ((v + 1.0) * 0.5 * self.cells as f64).clamp(0.0, self.cells as f64);
        let j = (x as usize).min(self.cells - 1);
        let v0 = -1.0 + 2.0 * j as f64 / self.cells as f64;
        let mom = moment(frame, m, i, v0, v.clamp(-1.0, 1.0));
        let mut out = [0.0; 9];
        out.copy_from_slice(&row[j * 9..j * 9 + 9]);
        let means = &row[(self.cells + 1) * 9 + j * 3..];
        for ch in 0..3 {
            for k in 0..3 {
                out[ch * 3 + k] += means[ch] * mom[k];
            }
        }
        out
    }

    /// Adds `∫_{lo}^{hi} L(ω) ω dv` on meridian `i` of `frame` to `out` (per colour, world
    /// xyz); times `Δφ` it is the wedge's share of `∫ L ω dω`. Exact for radiance constant
    /// over each cell.
    pub fn add(&self, frame: &PoleFrame, m: &Meridians, i: usize, lo: f64, hi: f64, out: &mut [DVec3; 3]) {
        let plus = PoleFrame::new(frame.axis, 1.0);
        let (a, b) = if frame.sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
        let (fa, fb) = (self.at(&plus, m, i, a), self.at(&plus, m, i, b));
        for (ch, o) in out.iter_mut().enumerate() {
            for k in 0..3 {
                o[k] += fb[ch * 3 + k] - fa[ch * 3 + k];
            }
        }
    }

    pub fn bytes(&self) -> usize {
        self.data.len() * 8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant environment is integrated exactly (the moments are analytic), from either
    /// pole, over any interval; a linear one to the accuracy of the sub-cell sampling.
    #[test]
    fn constant_environment_moments_are_exact() {
        let m = Meridians::new(16);
        let t = MomentTable::build(&m, 12, |_| [1.0, 2.0, 0.5]);
        for (axis, sign) in [(0, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)] {
            let f = PoleFrame::new(axis, sign);
            for (i, lo, hi) in [(0usize, -0.3, 0.77), (5, -1.0, 1.0), (11, 0.1234, 0.1235)] {
                let mut out = [DVec3::ZERO; 3];
                t.add(&f, &m, i, lo, hi, &mut out);
                let exact = moment(&f, &m, i, lo, hi);
                for (ch, s) in [1.0, 2.0, 0.5].iter().enumerate() {
                    let rel = (out[ch] - exact * *s).length() / (exact.length() * s).max(1e-300);
                    assert!(rel < 1e-9, "axis {axis} {sign} meridian {i}: {} vs {}", out[ch], exact * *s);
                }
            }
        }
    }
}
