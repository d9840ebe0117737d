//! Prefix sums of radiance-weighted SH basis functions along meridians: for each pole axis,
//! meridian `i` and node `j`, `S[j] = Σ_{j'<j} ∫_{cell j'} L(ω) Y_k(ω) dv` (per colour and
//! coefficient `k < n²`), with `L` averaged over the meridian's azimuth wedge and `L·Y`
//! sampled at sub-cell centres. `∫_{v_a}^{v_b} L Y_k dv` is then two interpolated lookups
//! per coefficient, and times `Δφ`, summed over the visible intervals, it is the SH projection
//! of the visibility-masked environment `L·V·H` that `silhouette` shades glossy lobes with
//! (the paper's "one SAT at the maximum order", §5). The `−axis` pole reads the `+axis` set
//! from the other end, as [`super::table::MomentTable`] does. Stored in f32 (a 128-meridian table
//! at order 12 is 85 MB); accumulated in f64.

use super::param::{Axes, CellNodes, Meridians, PoleFrame};
use glam::DVec3;
use penumbra_core::sh::{basis, ShOrder, MAX_ORDER};
use rayon::prelude::*;

/// The fewest sub-cells per cell (in `v`, and sub-wedges in `φ`) at which the radiance is sampled.
const SUPER: usize = 3;

#[derive(Clone, Debug)]
pub struct ShTable {
    n: usize,
    cells: usize,
    order: ShOrder,
    /// Per `[axis][meridian]`: the prefix sums at nodes `0..=cells`, each `3 · n²` values
    /// (colour-major).
    data: Vec<f32>,
}

impl ShTable {
    fn row_len(&self) -> usize {
        (self.cells + 1) * 3 * self.order.coeffs()
    }

    /// Tables for `meridians` with `cells` cells in `v` per meridian, of radiance `le`, up to
    /// SH order `order`, the radiance sampled no more than `spacing` radians apart in each
    /// cell ([`CellNodes`]), about `axes`' poles.
    pub fn build(
        m: &Meridians,
        axes: &Axes,
        cells: usize,
        order: ShOrder,
        spacing: f64,
        le: impl Fn(DVec3) -> [f64; 3] + Sync,
    ) -> ShTable {
        let cells = cells.max(1);
        let k = order.coeffs();
        let stride = (cells + 1) * 3 * k;
        let mut data = vec![0.0f32; 3 * m.n * stride];
        data.par_chunks_mut(stride).enumerate().for_each(|(row, out)| {
            let (axis, i) = (row / m.n, row % m.n);
            let frame = axes.frame(axis, 1.0);
            let dv = 2.0 / cells as f64;
            let mut acc = vec![0.0f64; 3 * k];
            let mut y = [0.0f64; MAX_ORDER * MAX_ORDER];
            let mut nodes = CellNodes::default();
            for j in 0..cells {
                let v0 = -1.0 + dv * j as f64;
                nodes.sample(&frame, m, i, (v0, v0 + dv), spacing, SUPER, &le);
                let inv_phi = 1.0 / nodes.phi.len() as f64;
                for (&(v, w), row) in nodes.v.iter().zip(nodes.radiance.chunks(nodes.phi.len())) {
                    let mut l = [0.0f64; 3];
                    for x in row {
                        for ch in 0..3 {
                            l[ch] += x[ch] * inv_phi;
                        }
                    }
                    basis::eval(order, frame.direction(m.cos[i], m.sin[i], v), &mut y[..k]);
                    for ch in 0..3 {
                        let lw = l[ch] * w;
                        for (a, yk) in acc[ch * k..(ch + 1) * k].iter_mut().zip(&y[..k]) {
                            *a += lw * yk;
                        }
                    }
                }
                for (o, a) in out[(j + 1) * 3 * k..(j + 2) * 3 * k].iter_mut().zip(&acc) {
                    *o = *a as f32;
                }
            }
        });
        ShTable { n: m.n, cells, order, data }
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    /// Adds `∫_{lo}^{hi} L(ω) Y_k(ω) dv` on meridian `i` of `frame`, for `k < order²` (at most
    /// the table's order), to `out[c · order² + k]` (colour `c`). Linear in `v` within a cell.
    pub fn add(&self, frame: &PoleFrame, i: usize, lo: f64, hi: f64, order: ShOrder, out: &mut [f64]) {
        let (a, b) = if frame.sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
        let (kt, k) = (self.order.coeffs(), order.coeffs().min(self.order.coeffs()));
        let row = &self.data[(frame.axis * self.n + i) * self.row_len()..];
        let node = |v: f64| {
            let x = ((v + 1.0) * 0.5 * self.cells as f64).clamp(0.0, self.cells as f64);
            let j = (x as usize).min(self.cells - 1);
            (j, x - j as f64)
        };
        let ((ja, ta), (jb, tb)) = (node(a), node(b));
        for ch in 0..3 {
            let at = |j: usize, t: f64, c: usize| {
                let s0 = row[j * 3 * kt + ch * kt + c] as f64;
                let s1 = row[(j + 1) * 3 * kt + ch * kt + c] as f64;
                s0 + (s1 - s0) * t
            };
            for c in 0..k {
                out[ch * k + c] += at(jb, tb, c) - at(ja, ta, c);
            }
        }
    }

    pub fn bytes(&self) -> usize {
        self.data.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::sh::quadrature::SphereQuadrature;

    /// Summed over every meridian of either pole, the table projects the environment onto SH
    /// as a fine quadrature does (to the cell discretisation), and a constant environment to
    /// `(√4π L, 0, …)`: the DC term to f32 rounding, the others to the midpoint rule's error
    /// in `v` (48 samples per meridian, ~(2/48)²).
    #[test]
    fn whole_sphere_projection_matches_quadrature() {
        let order = ShOrder::new(4).unwrap();
        let k = order.coeffs();
        let le = |w: DVec3| [1.0 + 0.5 * w.x, 2.0 + w.z * w.y, (3.0 * w.z).exp()];
        let m = Meridians::new(64);
        let t = ShTable::build(&m, &Axes::WORLD, 64, order, 1.0, le);
        let q = SphereQuadrature::product(40, 80);
        let mut y = vec![0.0; k];
        let mut exact = vec![0.0; 3 * k];
        for (d, w) in q.dirs.iter().zip(&q.weights) {
            basis::eval(order, *d, &mut y);
            let l = le(*d);
            for ch in 0..3 {
                for c in 0..k {
                    exact[ch * k + c] += w * l[ch] * y[c];
                }
            }
        }
        for (axis, sign) in [(0, 1.0), (1, -1.0), (2, 1.0)] {
            let f = PoleFrame::new(axis, sign);
            let mut out = vec![0.0; 3 * k];
            for i in 0..m.n {
                let mut row = vec![0.0; 3 * k];
                t.add(&f, i, -1.0, 1.0, order, &mut row);
                out.iter_mut().zip(&row).for_each(|(o, r)| *o += r * m.dphi);
            }
            let scale = exact.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for (c, (o, e)) in out.iter().zip(&exact).enumerate() {
                assert!((o - e).abs() < 2e-3 * scale, "axis {axis} {sign} coefficient {c}: {o} vs {e}");
            }
        }
        let t = ShTable::build(&m, &Axes::WORLD, 16, order, 1.0, |_| [1.0, 1.0, 1.0]);
        let mut out = vec![0.0; 3 * k];
        for i in 0..m.n {
            t.add(&PoleFrame::new(2, -1.0), i, -1.0, 1.0, order, &mut out);
        }
        assert!((out[0] * m.dphi - penumbra_core::sh::SQRT_4PI).abs() < 1e-5, "{}", out[0] * m.dphi);
        assert!(out[1..k].iter().all(|v| (v * m.dphi).abs() < 2e-3), "{:?}", &out[1..k]);
    }
}
