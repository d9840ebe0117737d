//! What one render of a variant is measured by: non-finite, negative and above-bound pixels,
//! and the per-pixel z-scores of its difference from the base render.

use penumbra_core::image::Image;
use penumbra_core::metrics;

/// The standard deviation added to every pixel's, relative to its base value: f32 rounding of
/// a moved scene, and pixels whose own samples all agree (zero sample variance, e.g. analytic
/// integrators inside a surface) would otherwise turn any rounding into an infinite z.
pub const RELATIVE_FLOOR: f64 = 1e-4;
/// And relative to the base image's mean (black pixels).
pub const MEAN_FLOOR: f64 = 1e-6;
/// A value is above a bound when it exceeds it by more than this relative margin (rounding).
pub const BOUND_MARGIN: f32 = 1e-4;
/// [`pooled`]: a pixel's variance is at least its neighbourhood's mean divided by this.
/// Measured (base variance pooled, 24², 4 spp; largest |z| of the Cornell box's every
/// integrator scaled and turned / the fixed-epsilon AO scaled and moved against
/// `ambientocclusion`'s): 1 → 3.6 / 13 and 46 vs 1.0; 4 → 6.9 / 26 and 70 vs 1.4;
/// 9 → 9.8 / 38 and 105 vs 1.4. 4 keeps the broken estimator 18× above the sound one while
/// every integrator stays below z = 8 on the Cornell box.
pub const POOL_WEIGHT: f32 = 4.0;

/// A render: R, G, B and the variance of each pixel's mean.
pub struct Channels {
    pub rgb: Image,
    pub var: Image,
}

impl Channels {
    /// From a render made with variance channels.
    pub fn of(img: &Image) -> Result<Channels, String> {
        let rgb = img.select_channels(&["R", "G", "B"]).map_err(|e| e.to_string())?;
        let mut var = img.select_channels(&["variance.R", "variance.G", "variance.B"]).map_err(|e| e.to_string())?;
        var.channels = rgb.channels.clone();
        Ok(Channels { rgb, var })
    }
}

/// What a variant must not exceed, per value.
pub enum Bound {
    Constant(f32),
    /// The bound render's R, G, B, and the relative tolerance its integrator states.
    Image(Image, f32),
}

/// The measures of one render against the base.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measures {
    /// Pixels with a NaN or infinite R, G or B.
    pub nonfinite: u64,
    /// Pixels with a negative R, G or B.
    pub negative: u64,
    /// Pixels with a value above the integrator's bound (`None`: it declares none).
    pub above_bound: Option<u64>,
    /// Largest |z| of the difference from the base (`None` for the base itself).
    pub max_z: Option<f64>,
    /// Fraction of pixels with some |z| > 3.
    pub frac_z3: Option<f64>,
    /// RMS difference from the base over the base's mean (finite values).
    pub rel_rmse: Option<f64>,
    /// The pixel shown on the contact sheet: the first non-finite one, else the largest |z|,
    /// else the first above the bound, else the first negative.
    pub worst: Option<(u32, u32)>,
}

/// Counts the pixels of `img` that are non-finite, negative or above `bound`; the first of
/// each kind (pixel index) comes back too.
fn counts(img: &Image, bound: Option<&Bound>) -> ([u64; 3], [Option<usize>; 3]) {
    let mut n = [0u64; 3];
    let mut first = [None; 3];
    for (i, px) in img.data.chunks_exact(3).enumerate() {
        let over = |j: usize, v: f32| match bound {
            Some(Bound::Constant(b)) => v > b + BOUND_MARGIN * b.abs(),
            Some(Bound::Image(b, tolerance)) => {
                let bv = b.data[i * 3 + j];
                v > bv + BOUND_MARGIN.max(*tolerance) * bv.abs().max(1e-6)
            }
            None => false,
        };
        let flags = [
            px.iter().any(|v| !v.is_finite()),
            px.iter().any(|&v| v < 0.0),
            px.iter().enumerate().any(|(j, &v)| v.is_finite() && over(j, v)),
        ];
        for k in 0..3 {
            if flags[k] {
                n[k] += 1;
                first[k].get_or_insert(i);
            }
        }
    }
    (n, first)
}

/// Each value of `var` raised to the mean of its channel over the pixel's 3 × 3
/// neighbourhood (clipped to the image) divided by [`POOL_WEIGHT`], where that is larger. A pixel's sample variance has only `spp − 1` degrees
/// of freedom: at a few samples per pixel the samples of a noisy estimator often agree (every
/// AO ray escaping, every path reaching the same light), and that pixel's zero variance made
/// the independent noise of a variant's differently oriented rays look like a z of hundreds
/// (measured on the Cornell box at 24², 4 spp: `ambientocclusion` rotated, largest |z| 985 with
/// 1 pixel of 576 above 3). The neighbours share the pixel's estimator and nearly its
/// integrand; a systematic change (the instabilities the command looks for) moves whole
/// regions, which pooling does not hide. Only the base render's variance is pooled (it is the
/// known-good estimate of the estimator's noise): a variant whose own samples agree because
/// it is broken (every ray of a fixed-epsilon AO caught by its own surface far from the
/// origin) keeps its zero variance and stands out against the base's.
pub fn pooled(var: &Image) -> Image {
    let (w, h, n) = (var.width as usize, var.height as usize, var.channels.len());
    let mut out = var.clone();
    for y in 0..h {
        for x in 0..w {
            for c in 0..n {
                let (mut sum, mut count) = (0.0f64, 0u32);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        sum += var.data[(yy * w + xx) * n + c] as f64;
                        count += 1;
                    }
                }
                // NaN stays NaN (and is reported as such by the z-scores).
                let own = var.data[(y * w + x) * n + c];
                let mean = (sum / count as f64) as f32;
                out.data[(y * w + x) * n + c] =
                    if own.is_nan() || mean.is_nan() { f32::NAN } else { own.max(mean / POOL_WEIGHT) };
            }
        }
    }
    out
}

/// Measures `variant` (its values divided by `factor`, the exact scale it must have) against
/// `base`; `None` for `base` measures the base itself. Returns the per-pixel largest |z| too
/// (empty for the base).
pub fn measure(
    variant: &Channels,
    factor: f64,
    base: Option<&Channels>,
    bound: Option<&Bound>,
) -> Result<(Measures, Vec<f32>), String> {
    let (n, first) = counts(&variant.rgb, bound);
    let w = variant.rgb.width;
    let at = |i: usize| (i as u32 % w, i as u32 / w);
    let mut m = Measures {
        nonfinite: n[0],
        negative: n[1],
        above_bound: bound.map(|_| n[2]),
        worst: first[0].or(first[2]).or(first[1]).map(at),
        ..Default::default()
    };
    let Some(base) = base else { return Ok((m, Vec::new())) };
    let (a, b) = (&variant.rgb, &base.rgb);
    if (a.width, a.height) != (b.width, b.height) {
        return Err(format!("the variant is {}x{}, the base {}x{}", a.width, a.height, b.width, b.height));
    }
    let k = factor as f32;
    let mut scaled = a.clone();
    scaled.data.iter_mut().for_each(|v| *v /= k);
    let mean = b.data.iter().filter(|v| v.is_finite()).map(|&v| v.abs() as f64).sum::<f64>() / b.data.len() as f64;
    let mut var = variant.var.clone();
    for (i, v) in var.data.iter_mut().enumerate() {
        let floor = RELATIVE_FLOOR * (b.data[i] as f64).abs() + MEAN_FLOOR * mean;
        *v = (*v as f64 / (factor * factor) + floor * floor) as f32;
    }
    let z = metrics::z_scores(&scaled, &var, b, Some(&pooled(&base.var))).map_err(|e| e.to_string())?;
    let zmap: Vec<f32> = z.z.chunks_exact(3).map(|p| p.iter().fold(0.0f64, |m, z| m.max(z.abs())) as f32).collect();
    m.max_z = Some(z.max_abs());
    m.frac_z3 = Some(z.fraction_pixels_above(3.0));
    let (mut se, mut count) = (0.0f64, 0usize);
    for (x, y) in scaled.data.iter().zip(&b.data) {
        if x.is_finite() && y.is_finite() {
            se += (*x as f64 - *y as f64).powi(2);
            count += 1;
        }
    }
    m.rel_rmse = Some(if count == 0 || mean == 0.0 { 0.0 } else { (se / count as f64).sqrt() / mean });
    if first[0].is_none() {
        let worst = zmap.iter().enumerate().filter(|z| !z.1.is_nan()).max_by(|x, y| x.1.total_cmp(y.1));
        if let Some((i, &zv)) = worst {
            if zv > 0.0 {
                m.worst = Some(at(i));
            }
        }
    }
    Ok((m, zmap))
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::image::channel_names;

    fn ch(values: &[f32], var: f32) -> Channels {
        let n = values.len() as u32;
        let data: Vec<f32> = values.iter().flat_map(|&v| [v; 3]).collect();
        let names = channel_names(&["R", "G", "B"]);
        Channels {
            rgb: Image::from_data(n, 1, names.clone(), data).unwrap(),
            var: Image::from_data(n, 1, names, vec![var; n as usize * 3]).unwrap(),
        }
    }

    #[test]
    fn counts_and_z_scores() {
        let base = ch(&[1.0, 2.0, 3.0, 4.0], 0.01);
        // Pixel 1 differs by 1 with a summed variance of 0.02 (+ the floor): |z| ≈ 7.07.
        let v = ch(&[1.0, 3.0, -1.0, f32::NAN], 0.01);
        let (m, zmap) = measure(&v, 1.0, Some(&base), Some(&Bound::Constant(2.5))).unwrap();
        assert_eq!((m.nonfinite, m.negative, m.above_bound), (1, 1, Some(1)));
        assert_eq!(m.worst, Some((3, 0)), "the non-finite pixel is shown first");
        assert!((zmap[1] - (1.0 / 0.02f32.sqrt())).abs() < 1e-2, "{zmap:?}");
        assert!(m.max_z.unwrap() > 28.0, "pixel 2 differs by 4: {m:?}");
        // An exactly scaled image measures as the base once divided.
        let big = ch(&[1e6, 2e6, 3e6, 4e6], 0.01 * 1e12);
        let (m, _) = measure(&big, 1e6, Some(&base), None).unwrap();
        assert!(m.max_z.unwrap() < 1e-6 && m.rel_rmse.unwrap() < 1e-7, "{m:?}");
        assert_eq!(m.above_bound, None);
    }

    /// A pixel's variance is raised to the mean of its 3 × 3 neighbourhood, per channel,
    /// clipped at the borders; a pixel whose samples agreed (variance 0) beside noisy ones no
    /// longer turns a noise-sized difference into a huge z.
    #[test]
    fn variance_is_pooled_over_the_neighbourhood() {
        let names = channel_names(&["R", "G", "B"]);
        // 4 × 3, variance only at (0, 0) (R: 24) and (3, 2) (B: 72).
        let mut data = vec![0.0f32; 4 * 3 * 3];
        data[0] = 24.0;
        data[(2 * 4 + 3) * 3 + 2] = 72.0;
        let p = pooled(&Image::from_data(4, 3, names.clone(), data).unwrap());
        let at = |x: usize, y: usize, c: usize| p.data[(y * 4 + x) * 3 + c];
        let w = POOL_WEIGHT;
        // The corner keeps its own (larger) value; its neighbours take their mean over w.
        assert_eq!(at(0, 0, 0), 24.0);
        assert_eq!((at(1, 0, 0), at(0, 1, 0)), (24.0 / 6.0 / w, 24.0 / 6.0 / w));
        assert_eq!(at(1, 1, 0), 24.0 / 9.0 / w);
        assert_eq!((at(2, 0, 0), at(0, 2, 0)), (0.0, 0.0));
        assert_eq!((at(3, 2, 2), at(2, 2, 2), at(2, 1, 2)), (72.0, 72.0 / 6.0 / w, 72.0 / 9.0 / w));
        assert_eq!((at(1, 1, 2), at(3, 0, 2), at(3, 2, 1)), (0.0, 0.0, 0.0));
        // In a measurement (1 × 3): base and variant agree everywhere but at pixel 0, whose
        // own variance is 0 while pixel 1's is 0.08 in the base: pooled 0.04 / w, so
        // |z| = 0.1 / sqrt(0.01) = 1 at w = 4 (about 1e3 with the floor alone). The variant's
        // own variance is not pooled.
        let mut base = ch(&[1.0, 1.0, 1.0], 0.0);
        let variant = ch(&[1.1, 1.0, 1.0], 0.0);
        base.var.data[3..6].iter_mut().for_each(|v| *v = 0.02 * w);
        let (m, _) = measure(&variant, 1.0, Some(&base), None).unwrap();
        assert!((m.max_z.unwrap() - 1.0).abs() < 1e-3, "{m:?}");
    }
}
