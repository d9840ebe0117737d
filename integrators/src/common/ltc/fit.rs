//! Fitting LTCs to core's Trowbridge–Reitz reflection (used by the `ltc-fit`
//! tool and by the tests).
//!
//! Per cell `(α, θo)`, as Heitz et al.'s fitting code: the lobe's average direction `Z`
//! (its normalised first moment) and `X = Y × Z` (`Y` the normal to the plane of incidence)
//! frame `M = [X Y Z] · [[m11, 0, m13], [0, m22, 0], [0, 0, 1]]` (3 free parameters; any
//! scale of `M` gives the same distribution), so that even a lobe far narrower than its
//! offset from the normal starts where it is; the parameters are found by Nelder–Mead
//! minimising Heitz et al.'s
//! multiple-importance-sampled L3 error
//! `Σ |D_M(ω) − f̂(ω)|³ / (p_M(ω) + p_f(ω))` over a stratified set of samples of
//! both the LTC and the normalised BRDF·cos `f̂` (VNDF sampling). Rows go from
//! the one nearest `α = 1` up to `α_max`, then down to `α_min`; columns from normal to
//! grazing incidence, each cell starting from its neighbour's fit; the `θo = 0` column is
//! constrained to be isotropic (`m11 = m22`, `m13 = 0`, one parameter). The table stores
//! the shape and the average direction's angle (see [`super::m_from_shape`]).
//!
//! [`cell_error`] measures a table against the BRDF it approximates: the magnitude against a
//! finer quadrature and the lobe's shape as the L1 distance `∫ |D − f̂| dω` (twice the largest
//! error of the normalised integral over any region), at any `(α, θo)`, nodes or between them.

use glam::{DMat3, DVec2, DVec3, Vec2};

use super::{cosine_sample, ltc_pdf, Ltc};
use penumbra_core::microfacet::MicrofacetDistribution;

/// Fit settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    pub n_theta: usize,
    pub n_alpha: usize,
    pub alpha_min: f32,
    pub alpha_max: f32,
    /// Samples per axis of the stratified error estimate (`n²` of each kind).
    pub error_samples: usize,
    /// Samples per axis for the magnitude and Fresnel integrals.
    pub moment_samples: usize,
    /// Nelder–Mead iteration cap per cell.
    pub max_iter: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            n_theta: 64,
            n_alpha: 64,
            alpha_min: 1e-3,
            alpha_max: 3.0,
            error_samples: 24,
            moment_samples: 64,
            max_iter: 400,
        }
    }
}

/// Smallest `cos θo` fitted (the grazing column uses this instead of 0).
pub const MIN_COS_THETA: f64 = 5e-3;

/// `f(ωo, ωi) cos θi = D G / (4 cos θo)` for core's Trowbridge–Reitz lobe, Fresnel 1.
pub fn brdf_cos(dist: &MicrofacetDistribution, wo: DVec3, wi: DVec3) -> f64 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize_or_zero();
    if h == DVec3::ZERO {
        return 0.0;
    }
    let v = dist.d(h.as_vec3()) as f64 * dist.g(wo.as_vec3(), wi.as_vec3()) as f64 / (4.0 * wo.z);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Density of the VNDF-sampled reflection direction `wi`: `D G1(ωo) / (4 cos θo)`.
pub fn brdf_pdf(dist: &MicrofacetDistribution, wo: DVec3, wi: DVec3) -> f64 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize_or_zero();
    if h == DVec3::ZERO {
        return 0.0;
    }
    let v = dist.d(h.as_vec3()) as f64 * dist.g1(wo.as_vec3()) as f64 / (4.0 * wo.z);
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

fn reflect(wo: DVec3, h: DVec3) -> DVec3 {
    2.0 * wo.dot(h) * h - wo
}

/// Stratified VNDF samples `(wi, f·cos, pdf, ωo·ωh)` (`wi.z ≤ 0` ones get zero weight).
fn brdf_samples(dist: &MicrofacetDistribution, wo: DVec3, n: usize) -> Vec<(DVec3, f64, f64, f64)> {
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let Some(h) = dist.sample_wh(wo.as_vec3(), u) else { continue };
            let h = h.as_dvec3().normalize();
            let wi = reflect(wo, h);
            out.push((wi, brdf_cos(dist, wo, wi), brdf_pdf(dist, wo, wi), wo.dot(h)));
        }
    }
    out
}

/// The view direction of a cell.
pub fn view_dir(cos_theta: f64) -> DVec3 {
    let c = cos_theta.clamp(MIN_COS_THETA, 1.0);
    DVec3::new((1.0 - c * c).max(0.0).sqrt(), 0.0, c)
}

/// `(magnitude, fresnel)`: `∫ f cos` and `∫ f cos (1 − ωo·ωh)⁵ / magnitude`,
/// estimated with `n²` stratified VNDF samples (weights `G / G1`).
pub fn moments(alpha: f64, cos_theta: f64, n: usize) -> (f64, f64) {
    let (m, fr, _) = moments_and_direction(alpha, cos_theta, n);
    (m, fr)
}

/// [`moments`] and the lobe's average direction (`∫ f cos ω dω`, normalised; `+z` if zero).
pub fn moments_and_direction(alpha: f64, cos_theta: f64, n: usize) -> (f64, f64, DVec3) {
    let dist = MicrofacetDistribution::trowbridge_reitz(alpha as f32, alpha as f32);
    let wo = view_dir(cos_theta);
    let (mut m, mut fr, mut dir) = (0.0, 0.0, DVec3::ZERO);
    for (wi, f, p, oh) in brdf_samples(&dist, wo, n) {
        if p > 0.0 {
            let w = f / p;
            m += w;
            fr += w * (1.0 - oh).clamp(0.0, 1.0).powi(5);
            dir += wi * w;
        }
    }
    let total = (n * n) as f64;
    let (m, fr) = (m / total, fr / total);
    let dir = DVec3::new(dir.x, 0.0, dir.z).normalize_or_zero();
    (m, if m > 0.0 { fr / m } else { 0.0 }, if dir == DVec3::ZERO { DVec3::Z } else { dir })
}

/// `M` from the fit parameters `[a, b, d, e]`.
pub fn m_from_params(p: [f64; 4]) -> DMat3 {
    DMat3::from_cols(DVec3::new(p[0], 0.0, p[2]), DVec3::Y, DVec3::new(p[1], 0.0, p[3]))
}

/// The stored `M⁻¹` entries `[m00, m02, m20, m22]` (middle entry 1) for `M(p)`.
pub fn minv_params(p: [f64; 4]) -> [f64; 4] {
    let [a, b, d, e] = p;
    let det = a * e - b * d;
    [e / det, -b / det, -d / det, a / det]
}

/// The L3 fit error of a cell's problem.
struct Problem {
    dist: MicrofacetDistribution,
    wo: DVec3,
    magnitude: f64,
    /// `(wi, f̂, p_f)` of the BRDF samples.
    brdf: Vec<(DVec3, f64, f64)>,
    ltc_u: Vec<DVec2>,
}

impl Problem {
    fn new(alpha: f64, cos_theta: f64, magnitude: f64, n: usize) -> Self {
        let dist = MicrofacetDistribution::trowbridge_reitz(alpha as f32, alpha as f32);
        let wo = view_dir(cos_theta);
        let inv = if magnitude > 0.0 { 1.0 / magnitude } else { 0.0 };
        let brdf = brdf_samples(&dist, wo, n).into_iter().map(|(wi, f, p, _)| (wi, f * inv, p)).collect();
        let ltc_u = (0..n * n)
            .map(|k| DVec2::new(((k % n) as f64 + 0.5) / n as f64, ((k / n) as f64 + 0.5) / n as f64))
            .collect();
        Problem { dist, wo, magnitude, brdf, ltc_u }
    }

    fn error(&self, p: [f64; 4]) -> f64 {
        let m = m_from_params(p);
        let det = m.determinant();
        if !(det > 1e-12) || !det.is_finite() || p.iter().any(|v| !v.is_finite()) {
            return 1e30;
        }
        let minv = m.inverse();
        let inv_mag = 1.0 / self.magnitude;
        let mut err = 0.0;
        for u in &self.ltc_u {
            let w = (m * cosine_sample(*u)).normalize_or_zero();
            let pl = ltc_pdf(&minv, w);
            let f = brdf_cos(&self.dist, self.wo, w) * inv_mag;
            let pf = brdf_pdf(&self.dist, self.wo, w);
            let d = (pl - f).abs();
            if pl + pf > 0.0 {
                err += d * d * d / (pl + pf);
            }
        }
        for &(w, f, pf) in &self.brdf {
            let pl = ltc_pdf(&minv, w);
            let d = (pl - f).abs();
            if pl + pf > 0.0 {
                err += d * d * d / (pl + pf);
            }
        }
        err / (self.ltc_u.len() + self.brdf.len()).max(1) as f64
    }
}

/// Nelder–Mead minimisation of `f` over `R^n` (n ≤ 4) from `x0` with initial steps `step`.
pub fn nelder_mead<const N: usize>(
    f: impl Fn([f64; N]) -> f64,
    x0: [f64; N],
    step: [f64; N],
    max_iter: usize,
) -> ([f64; N], f64) {
    let mut simplex: Vec<([f64; N], f64)> = Vec::with_capacity(N + 1);
    simplex.push((x0, f(x0)));
    for i in 0..N {
        let mut x = x0;
        x[i] += step[i];
        simplex.push((x, f(x)));
    }
    let lerp = |a: &[f64; N], b: &[f64; N], t: f64| -> [f64; N] { std::array::from_fn(|k| a[k] + t * (b[k] - a[k])) };
    for _ in 0..max_iter {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (best, worst) = (simplex[0].1, simplex[N].1);
        if (worst - best).abs() <= 1e-9 * (best.abs() + 1e-12) {
            break;
        }
        let centroid: [f64; N] = std::array::from_fn(|k| simplex[..N].iter().map(|s| s.0[k]).sum::<f64>() / N as f64);
        let xr = lerp(&centroid, &simplex[N].0, -1.0);
        let fr = f(xr);
        if fr < simplex[0].1 {
            let xe = lerp(&centroid, &simplex[N].0, -2.0);
            let fe = f(xe);
            simplex[N] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[N - 1].1 {
            simplex[N] = (xr, fr);
        } else {
            let xc = if fr < simplex[N].1 { lerp(&centroid, &xr, 0.5) } else { lerp(&centroid, &simplex[N].0, 0.5) };
            let fc = f(xc);
            if fc < fr.min(simplex[N].1) {
                simplex[N] = (xc, fc);
            } else {
                let b = simplex[0].0;
                for s in simplex.iter_mut().skip(1) {
                    s.0 = lerp(&b, &s.0, 0.5);
                    s.1 = f(s.0);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    (simplex[0].0, simplex[0].1)
}

/// Per-cell result of [`fit_table`].
#[derive(Clone, Copy, Debug)]
pub struct CellFit {
    pub alpha: f64,
    pub cos_theta: f64,
    /// `M` parameters `[a, b, d, e]` (middle entry 1, see [`m_from_params`]).
    pub params: [f64; 4],
    /// The shape parameters `[m11, m22, m13]` in the frame of the average direction.
    pub shape: [f64; 3],
    /// The angle of the average direction from the normal (towards `−x`, away from `ωo`).
    pub theta_z: f64,
    pub error: f64,
}

/// `M = [X Y Z] · [[m11, 0, m13], [0, m22, 0], [0, 0, 1]]` for the average direction `z`
/// (in the xz-plane), as `[a, b, d, e]` with the middle entry scaled to 1.
pub fn params_from_shape(z: DVec3, shape: [f64; 3]) -> [f64; 4] {
    let [m11, m22, m13] = shape;
    let x = DVec3::Y.cross(z);
    let s = 1.0 / m22;
    [x.x * m11 * s, (x.x * m13 + z.x) * s, x.z * m11 * s, (x.z * m13 + z.z) * s]
}

/// Fits one cell starting from the shape `init` (`[m11, m22, m13]`).
pub fn fit_cell(alpha: f64, cos_theta: f64, init: [f64; 3], opts: &FitOptions) -> (CellFit, f64, f64) {
    let (mag, fres, z) = moments_and_direction(alpha, cos_theta, opts.moment_samples);
    let prob = Problem::new(alpha, cos_theta, mag, opts.error_samples);
    let err = |shape: [f64; 3]| {
        if !(shape[0] > 0.0 && shape[1] > 0.0) {
            return 1e30;
        }
        prob.error(params_from_shape(z, shape))
    };
    let step = |v: f64| 0.1 * v.abs().max(0.05 * alpha.min(1.0));
    let (shape, error) = if cos_theta >= 1.0 {
        let (x, e) = nelder_mead(|x: [f64; 1]| err([x[0], x[0], 0.0]), [init[0]], [step(init[0])], opts.max_iter);
        ([x[0], x[0], 0.0], e)
    } else {
        let steps = [step(init[0]), step(init[1]), 0.1 * init[0].abs().max(0.05 * alpha.min(1.0))];
        nelder_mead(err, init, steps, opts.max_iter)
    };
    let theta_z = z.x.atan2(z.z);
    (CellFit { alpha, cos_theta, params: params_from_shape(z, shape), shape, theta_z, error }, mag, fres)
}

/// Fits the whole table; `progress(row_done, rows)` is called after each row.
pub fn fit_table(opts: &FitOptions, mut progress: impl FnMut(usize, usize)) -> (Ltc, Vec<CellFit>) {
    let mut table = Ltc {
        n_theta: opts.n_theta,
        n_alpha: opts.n_alpha,
        alpha_min: opts.alpha_min,
        alpha_max: opts.alpha_max,
        cells: vec![[0.0; 6]; opts.n_theta * opts.n_alpha],
    };
    let mut fits = Vec::with_capacity(table.cells.len());
    // From the row nearest α = 1 (where the identity is a fair start) up, then down.
    let start = (0..opts.n_alpha)
        .min_by(|&a, &b| (table.row_alpha(a).ln().abs()).total_cmp(&table.row_alpha(b).ln().abs()))
        .unwrap_or(0);
    let order: Vec<usize> = (start..opts.n_alpha).chain((0..start).rev()).collect();
    let mut first_col: Vec<Option<[f64; 3]>> = vec![None; opts.n_alpha];
    for (done, &j) in order.iter().enumerate() {
        let alpha = table.row_alpha(j);
        let neighbour = if j >= start { j.checked_sub(1) } else { Some(j + 1) };
        // The neighbouring row's normal-incidence shape, scaled by the ratio of the alphas.
        let mut prev = neighbour
            .and_then(|k| first_col.get(k).copied().flatten().map(|s| s.map(|v| v * alpha / table.row_alpha(k))))
            .unwrap_or([alpha, alpha, 0.0]);
        for i in 0..opts.n_theta {
            let cos_theta = table.column_cos_theta(i);
            let (fit, mag, fres) = fit_cell(alpha, cos_theta, prev, opts);
            prev = fit.shape;
            if i == 0 {
                first_col[j] = Some(fit.shape);
            }
            let [m11, m22, m13] = fit.shape;
            table.cells[j * opts.n_theta + i] =
                [m11 as f32, m22 as f32, m13 as f32, fit.theta_z as f32, mag as f32, fres as f32];
            fits.push(fit);
        }
        progress(done + 1, opts.n_alpha);
    }
    (table, fits)
}

/// A table's error against the BRDF at one `(α, cos θo)`: see [`cell_error`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellError {
    /// `∫ f cos` by a 256² VNDF quadrature.
    pub magnitude: f64,
    /// The table's magnitude (interpolated) relative to it, minus 1.
    pub magnitude_error: f64,
    /// `∫ |D_LTC − f̂| dω` (0: the same lobe; 2: disjoint lobes).
    pub l1: f64,
}

/// The error of `table`'s (interpolated) LTC at `(alpha, cos_theta)` against core's
/// Trowbridge–Reitz reflection: the magnitude against `moments` at 256² samples and the lobe's
/// shape as `∫ |D_LTC − f̂| dω`, estimated from `n²` stratified samples of each distribution
/// combined by the balance heuristic (the VNDF density stands in for `f̂`'s).
pub fn cell_error(table: &Ltc, alpha: f64, cos_theta: f64, n: usize) -> CellError {
    let (magnitude, _) = moments(alpha, cos_theta, 256);
    let c = table.eval(view_dir(cos_theta).z as f32, alpha as f32);
    let dist = MicrofacetDistribution::trowbridge_reitz(alpha as f32, alpha as f32);
    let wo = view_dir(cos_theta);
    let inv_mag = if magnitude > 0.0 { 1.0 / magnitude } else { 0.0 };
    let m = c.m();
    // The VNDF sampler's density, also where the reflected direction is below the horizon
    // (its samples there carry the LTC's mass below the horizon, all of it error).
    let vndf = |w: DVec3| {
        let h = (wo + w).normalize_or_zero();
        let v = dist.d(h.as_vec3()) as f64 * dist.g1(wo.as_vec3()) as f64 / (4.0 * wo.z);
        if h == DVec3::ZERO || !v.is_finite() {
            0.0
        } else {
            v
        }
    };
    let term = |w: DVec3| {
        let pl = ltc_pdf(&c.minv, w);
        let pf = vndf(w);
        let f = brdf_cos(&dist, wo, w) * inv_mag;
        if pl + pf > 0.0 {
            (pl - f).abs() / (pl + pf)
        } else {
            0.0
        }
    };
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let u = DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            sum += term((m * cosine_sample(u)).normalize_or_zero());
        }
    }
    for (w, _, _, _) in brdf_samples(&dist, wo, n) {
        sum += term(w);
    }
    let l1 = sum / (n * n) as f64;
    CellError { magnitude, magnitude_error: c.magnitude as f64 / magnitude - 1.0, l1 }
}
