//! The ratio estimator's denoiser as an image-space pass: a cross-bilateral filter over typed
//! buffers ([`ImageBuffer`]) with per-pixel radii from the pixels' own noise, and the guarded
//! ratio of the denoised sums.

use crate::common::image_pass::ImageBuffer;
use penumbra_core::Vec3;

/// Weights of the cross-bilateral filter (all relative, see [`cross_bilateral`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterParams {
    /// Relative depth tolerance: weight `exp(−½ ((z_q − z_p) / (σ z_p))²)`.
    pub sigma_depth: f32,
    /// Normal weight `max(0, n_p·n_q)^e`.
    pub normal_exponent: f32,
    /// Plane-offset tolerance relative to depth: `exp(−½ ((d_q − d_p) / (σ z_p))²)`, `d = n·p`.
    pub sigma_plane: f32,
    /// Relative tolerance on the analytic `U` (luminance): `exp(−½ ((U_q − U_p) / (σ max(U_p, U_q)))²)`.
    pub sigma_u: f32,
    /// Edge stop on the raw ratio itself: `exp(−½ (|r_q − r_p| / (k √(σ_p² + σ_q²) + floor))²)`
    /// with `k` = `ratio_k` (0 disables it) and `floor` = `ratio_floor`: differences the
    /// pixels' own noise explains do not stop the filter, a contact shadow next to lit floor does.
    pub ratio_k: f32,
    pub ratio_floor: f32,
}

impl FilterParams {
    /// The defaults of `ratio`'s parameters.
    pub const DEFAULT: FilterParams = FilterParams {
        sigma_depth: 0.1,
        normal_exponent: 32.0,
        sigma_plane: 0.02,
        sigma_u: 0.5,
        ratio_k: 2.0,
        ratio_floor: 0.02,
    };
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams::DEFAULT
    }
}

/// The guide of one pixel. `depth ≤ 0` (or not finite) marks a pixel without geometry: it is
/// neither filtered nor used as a neighbour.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guide {
    pub depth: f32,
    pub normal: Vec3,
    pub plane: f32,
    pub u: f32,
    /// The raw ratio `S_N / U_N` (luminance) and the standard deviation of its estimate.
    pub ratio: f32,
    pub ratio_sigma: f32,
}

/// Cross-bilateral filter of `values` (`N` values per pixel) with per-pixel kernel radius
/// `radius` (0: the pixel is copied). The weight of neighbour `q` for pixel `p` is the product
/// of a spatial Gaussian (σ = R/2) and the guide terms of [`FilterParams`]; all channels share
/// the weights. Returns the filtered values and, per pixel, `Σw² / (Σw)²` (the variance
/// reduction of independent noise). Buffers of different sizes give the input back unchanged.
pub fn cross_bilateral<const N: usize>(
    guides: &ImageBuffer<Guide>,
    radius: &ImageBuffer<u32>,
    values: &ImageBuffer<[f32; N]>,
    params: &FilterParams,
) -> (ImageBuffer<[f32; N]>, ImageBuffer<f32>) {
    let (width, height) = (guides.width(), guides.height());
    if !guides.same_size(radius) || !guides.same_size(values) {
        return (values.clone(), values.map(|_| 1.0));
    }
    let filtered = ImageBuffer::from_rows_par(width, height, |y| {
        (0..width).map(|x| filter_pixel(guides, radius, values, params, (x, y))).collect()
    });
    (filtered.map(|p| p.0), filtered.map(|p| p.1))
}

fn valid(g: &Guide) -> bool {
    g.depth > 0.0 && g.depth.is_finite()
}

/// The guide terms' exponent for neighbour `gq` of `gp` (everything but the normal weight).
fn guide_exponent(gp: &Guide, gq: &Guide, params: &FilterParams) -> f32 {
    let dz = (gq.depth - gp.depth) / (params.sigma_depth * gp.depth);
    let dd = (gq.plane - gp.plane) / (params.sigma_plane * gp.depth);
    let umax = gp.u.max(gq.u);
    let du = if umax > 0.0 { (gq.u - gp.u) / (params.sigma_u * umax) } else { 0.0 };
    let dr = if params.ratio_k > 0.0 {
        let sr = params.ratio_k * (gp.ratio_sigma.powi(2) + gq.ratio_sigma.powi(2)).sqrt() + params.ratio_floor;
        (gq.ratio - gp.ratio) / sr
    } else {
        0.0
    };
    0.5 * (dz * dz + dd * dd + du * du + dr * dr)
}

/// One pixel of [`cross_bilateral`]: its filtered values and `Σw² / (Σw)²`.
fn filter_pixel<const N: usize>(
    guides: &ImageBuffer<Guide>,
    radius: &ImageBuffer<u32>,
    values: &ImageBuffer<[f32; N]>,
    params: &FilterParams,
    (x, y): (usize, usize),
) -> ([f32; N], f32) {
    let (width, height) = (guides.width(), guides.height());
    let i = y * width + x;
    let gp = &guides[i];
    let r = radius[i] as i64;
    if r == 0 || !valid(gp) {
        return (values[i], 1.0);
    }
    let unit = |v: Vec3| v.normalize_or_zero();
    let np = unit(gp.normal);
    let sig_s = (r as f32 * 0.5).max(0.5);
    let mut acc = [0.0f64; N];
    let (mut sw, mut sw2) = (0.0f64, 0.0f64);
    for qy in (y as i64 - r).max(0)..=(y as i64 + r).min(height as i64 - 1) {
        for qx in (x as i64 - r).max(0)..=(x as i64 + r).min(width as i64 - 1) {
            let j = qy as usize * width + qx as usize;
            let gq = &guides[j];
            if !valid(gq) {
                continue;
            }
            let (dx, dy) = ((qx - x as i64) as f32, (qy - y as i64) as f32);
            let mut e = (dx * dx + dy * dy) / (2.0 * sig_s * sig_s);
            e += guide_exponent(gp, gq, params);
            let c = np.dot(unit(gq.normal));
            let wn = if j == i {
                1.0
            } else if c > 0.0 {
                c.powf(params.normal_exponent)
            } else {
                0.0
            };
            let w = (-e).exp() * wn;
            if !(w > 0.0 && w.is_finite()) {
                continue;
            }
            let w = w as f64;
            sw += w;
            sw2 += w * w;
            for (c, a) in acc.iter_mut().enumerate() {
                *a += w * values[j][c] as f64;
            }
        }
    }
    if sw > 0.0 {
        (acc.map(|a| (a / sw) as f32), (sw2 / (sw * sw)) as f32)
    } else {
        (values[i], 1.0)
    }
}

/// Kernel radii from per-pixel noise: the smallest `R ≤ max_radius` with
/// `sigma / (2R + 1) ≤ target`, then the maximum over each pixel's 3×3 neighbourhood (a
/// pixel whose few samples happened to agree still gets its noisy neighbours' radius).
pub fn noise_radius(sigma: &ImageBuffer<f32>, target: f32, max_radius: u32) -> ImageBuffer<u32> {
    let (width, height) = (sigma.width(), sigma.height());
    let base = sigma.map(|&s| {
        if !(s > 0.0) || !(target > 0.0) {
            return 0;
        }
        let r = ((s / target - 1.0) * 0.5).ceil();
        if r.is_finite() {
            (r.max(0.0) as u32).min(max_radius)
        } else {
            max_radius
        }
    });
    let mut out = base.clone();
    for y in 0..height {
        for x in 0..width {
            let mut m = 0;
            for qy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for qx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    m = m.max(*base.at(qx, qy));
                }
            }
            out[y * width + x] = m;
        }
    }
    out
}

/// The shadow ratio `s / u` of one channel with the module's guard (see the module docs):
/// `d_s / d_u` (denoised) if `d_u` is positive and finite, else the raw ratio if `u > 0`,
/// else 1; clamped to `[0, 1]`.
pub fn guarded_ratio(d_s: f32, d_u: f32, s: f32, u: f32) -> f32 {
    let r = if d_u > 0.0 && d_u.is_finite() && d_s.is_finite() {
        d_s / d_u
    } else if u > 0.0 && u.is_finite() && s.is_finite() {
        s / u
    } else {
        1.0
    };
    if r.is_nan() {
        1.0
    } else {
        r.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::rng::Rng;

    /// [`cross_bilateral`] over flat slices (`N` interleaved values per pixel), radius `r` everywhere.
    fn run<const N: usize>(
        w: usize,
        h: usize,
        g: &[Guide],
        r: u32,
        vals: &[f32],
        p: &FilterParams,
    ) -> (Vec<f32>, Vec<f32>) {
        let guides = ImageBuffer::from_vec(w, h, g.to_vec()).unwrap();
        let values = ImageBuffer::from_fn(w, h, |i| std::array::from_fn::<f32, N, _>(|c| vals[i * N + c]));
        let (out, red) = cross_bilateral(&guides, &ImageBuffer::filled(w, h, r), &values, p);
        (out.pixels().iter().flatten().copied().collect(), red.pixels().to_vec())
    }

    fn radii(w: usize, h: usize, s: &[f32], target: f32, max_radius: u32) -> Vec<u32> {
        noise_radius(&ImageBuffer::from_vec(w, h, s.to_vec()).unwrap(), target, max_radius).pixels().to_vec()
    }

    fn plane_guides(w: usize, h: usize) -> Vec<Guide> {
        vec![Guide { depth: 5.0, normal: Vec3::Z, plane: 1.0, u: 1.0, ..Default::default() }; w * h]
    }

    #[test]
    fn constant_noisy_input_is_smoothed() {
        let (w, h) = (128, 128);
        let g = plane_guides(w, h);
        let mut rng = Rng::new(7);
        let vals: Vec<f32> = (0..w * h).map(|_| 0.5 + (rng.uniform_f32() - 0.5)).collect();
        let var = |v: &[f32]| {
            let m = v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64;
            v.iter().map(|x| (*x as f64 - m).powi(2)).sum::<f64>() / v.len() as f64
        };
        for r in [1u32, 2, 4] {
            let (out, red) = run::<1>(w, h, &g, r, &vals, &FilterParams::default());
            // Interior pixels only (the borders see fewer neighbours).
            let b = r as usize;
            let inner = |v: &[f32]| -> Vec<f32> {
                (b..h - b).flat_map(|y| (b..w - b).map(move |x| y * w + x)).map(|i| v[i]).collect()
            };
            let (vi, vo) = (var(&inner(&vals)), var(&inner(&out)));
            let factor = vi / vo;
            let predicted = 1.0 / red[h / 2 * w + w / 2] as f64;
            eprintln!("radius {r}: variance reduction ×{factor:.2} (Σw²/(Σw)² predicts ×{predicted:.2})");
            // Independent noise: the measured reduction follows Σw²/(Σw)² within sampling error.
            assert!(factor > 0.7 * predicted && factor < 1.3 * predicted, "radius {r}: ×{factor} vs ×{predicted}");
            assert!(factor > 2.0, "radius {r}: too little smoothing (×{factor})");
            let m = inner(&out).iter().map(|x| *x as f64).sum::<f64>() / ((w - 2 * b) * (h - 2 * b)) as f64;
            assert!((m - 0.5).abs() < 0.01, "mean moved to {m}");
        }
    }

    #[test]
    fn depth_step_edge_is_preserved() {
        let (w, h) = (32, 16);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if x >= w / 2 {
                    g[i].depth = 10.0;
                    g[i].plane = 6.0;
                    vals[i] = 1.0;
                }
            }
        }
        let (out, _) = run::<1>(w, h, &g, 6, &vals, &FilterParams::default());
        for (i, (o, v)) in out.iter().zip(&vals).enumerate() {
            assert!((o - v).abs() < 1e-4, "pixel {i}: {o} vs {v} across the depth edge");
        }
        // Without the depth/plane guides the edge would blur: check the test can fail.
        let flat = plane_guides(w, h);
        let (blur, _) = run::<1>(w, h, &flat, 6, &vals, &FilterParams::default());
        assert!(blur[w / 2 - 1] > 0.1 && blur[w / 2] < 0.9);
    }

    #[test]
    fn normal_edge_is_preserved_and_shared_weights() {
        let (w, h) = (16, 16);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h * 2];
        for y in 0..h {
            for x in w / 2..w {
                g[y * w + x].normal = Vec3::X;
                vals[(y * w + x) * 2] = 1.0;
                vals[(y * w + x) * 2 + 1] = 2.0;
            }
        }
        let (out, _) = run::<2>(w, h, &g, 4, &vals, &FilterParams::default());
        for i in 0..w * h {
            assert!((out[i * 2] - vals[i * 2]).abs() < 1e-4);
            // Same weights for every channel: the second channel stays twice the first.
            assert!((out[i * 2 + 1] - 2.0 * out[i * 2]).abs() < 1e-5);
        }
    }

    /// The raw-ratio edge stop keeps a step the pixels' noise cannot explain (a contact shadow
    /// on one plane) and smooths one it can.
    #[test]
    fn ratio_edge_stop_follows_noise() {
        let (w, h) = (16, 8);
        let mut g = plane_guides(w, h);
        let mut vals = vec![0.0f32; w * h];
        for y in 0..h {
            for x in w / 2..w {
                vals[y * w + x] = 1.0;
                g[y * w + x].ratio = 1.0;
            }
        }
        let p = FilterParams::default();
        let (sharp, _) = run::<1>(w, h, &g, 4, &vals, &p);
        assert!(sharp.iter().zip(&vals).all(|(a, b)| (a - b).abs() < 1e-4), "confident step blurred");
        g.iter_mut().for_each(|q| q.ratio_sigma = 1.0);
        let (soft, _) = run::<1>(w, h, &g, 4, &vals, &p);
        assert!(soft[w / 2 - 1] > 0.2 && soft[w / 2] < 0.8, "noisy step kept: {} {}", soft[w / 2 - 1], soft[w / 2]);
        let off = FilterParams { ratio_k: 0.0, ..p };
        g.iter_mut().for_each(|q| q.ratio_sigma = 0.0);
        let (blur, _) = run::<1>(w, h, &g, 4, &vals, &off);
        assert!(blur[w / 2 - 1] > 0.2, "ratio_k = 0 must disable the edge stop");
    }

    #[test]
    fn zero_un_never_gives_nan() {
        let (w, h) = (8, 8);
        let mut g = plane_guides(w, h);
        g[3].depth = 0.0;
        g[5].depth = f32::NAN;
        g[9].normal = Vec3::ZERO;
        g[10].u = 0.0;
        let vals = vec![0.0f32; w * h * 2];
        let (out, red) = run::<2>(w, h, &g, 3, &vals, &FilterParams::default());
        assert!(out.iter().chain(&red).all(|v| v.is_finite()));
        for i in 0..w * h {
            let r = guarded_ratio(out[2 * i], out[2 * i + 1], 0.0, 0.0);
            assert_eq!(r, 1.0, "unknown shadowing is taken as lit");
        }
        assert_eq!(guarded_ratio(0.0, 0.0, 0.0, 2.0), 0.0);
        assert_eq!(guarded_ratio(f32::NAN, 0.0, 1.0, 4.0), 0.25);
        assert_eq!(guarded_ratio(1.0, f32::INFINITY, f32::NAN, f32::NAN), 1.0);
        assert_eq!(guarded_ratio(3.0, 2.0, 0.0, 0.0), 1.0);
        assert_eq!(guarded_ratio(1.0, 4.0, 0.0, 0.0), 0.25);
    }

    #[test]
    fn noise_radius_follows_sigma() {
        let (w, h) = (5, 5);
        let mut s = vec![0.0f32; 25];
        s[12] = 0.1;
        // 0.1 / (2R + 1) ≤ 0.02 ⇒ R = 2; dilated over 3×3.
        let r = radii(w, h, &s, 0.02, 8);
        for y in 0..5 {
            for x in 0..5 {
                let inside = (1..=3).contains(&x) && (1..=3).contains(&y);
                assert_eq!(r[y * 5 + x], if inside { 2 } else { 0 }, "({x}, {y})");
            }
        }
        assert_eq!(radii(1, 1, &[f32::INFINITY], 0.02, 8), vec![8]);
        assert_eq!(radii(1, 1, &[f32::NAN], 0.02, 8), vec![0]);
        assert_eq!(radii(1, 1, &[10.0], 0.02, 3), vec![3]);
    }
}
