//! The gate's images, as 8-bit RGB PNG bytes the size of the checked image: the p-value map,
//! the failing-value mask and the signed-error map.

use super::gate::Outcome;
use penumbra_core::image::{self, Image, ImageError};
use std::path::Path;

/// Viridis at 9 evenly spaced stops (matplotlib's values), linear in between.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];
const MAGENTA: [u8; 3] = [255, 0, 255];

/// The viridis colour of `t` in [0, 1] (NaN: the low end); the reports' one colour map.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } * (VIRIDIS.len() - 1) as f64;
    let i = (t.floor() as usize).min(VIRIDIS.len() - 2);
    let f = t - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    std::array::from_fn(|k| (a[k] as f64 + (b[k] as f64 - a[k] as f64) * f).round() as u8)
}

/// Blue (−1) through white (0) to red (+1).
fn diverging(t: f64) -> [u8; 3] {
    if t.is_nan() {
        return MAGENTA;
    }
    let t = t.clamp(-1.0, 1.0);
    let fade = |c: f64| (255.0 * (1.0 - t.abs()) + c * t.abs()).round() as u8;
    if t >= 0.0 {
        [fade(178.0), fade(24.0), fade(43.0)]
    } else {
        [fade(33.0), fade(102.0), fade(172.0)]
    }
}

/// The maps' scales, for legends and reports.
pub const SIGNED_CLIP: f64 = 4.0;

/// −log10 of the smallest p of each pixel, on viridis from 0 (p = 1) to twice the value
/// family's threshold −log10(level): a rejected pixel is past the middle (green–yellow),
/// p = 0 (and non-finite values) saturate.
pub fn pvalue_rgb(o: &Outcome) -> Vec<u8> {
    let q_thr = -o.values.level.log10();
    let scale = 2.0 * q_thr.max(1.0);
    o.p.chunks_exact(3)
        .flat_map(|c| {
            let p = c.iter().copied().fold(1.0f64, f64::min);
            let q = if p > 0.0 { -p.log10() } else { f64::INFINITY };
            viridis(q / scale)
        })
        .collect()
}

/// White where a value of the pixel is rejected, dark red where the pixel lies in a rejected
/// block, black elsewhere.
pub fn mask_rgb(o: &Outcome) -> Vec<u8> {
    let mut rgb = vec![0u8; o.width * o.height * 3];
    for (t, &r) in o.block_tests.iter().zip(&o.block_rejected) {
        if r {
            let g = t.region;
            for y in g.y0..g.y1 {
                for x in g.x0..g.x1 {
                    rgb[(y * o.width + x) * 3] = 140;
                }
            }
        }
    }
    for (i, c) in o.rejected.chunks_exact(3).enumerate() {
        if c.iter().any(|&r| r) {
            rgb[i * 3..i * 3 + 3].copy_from_slice(&[255, 255, 255]);
        }
    }
    rgb
}

/// Each pixel's signed error in units of its noise (the mean of its channels' statistics),
/// clipped to ±[`SIGNED_CLIP`]: red where the test is brighter, blue darker,
/// magenta for non-finite values.
pub fn signed_rgb(o: &Outcome) -> Vec<u8> {
    o.t.chunks_exact(3)
        .flat_map(|c| {
            let z = c.iter().sum::<f64>() / 3.0;
            if z.is_nan() {
                MAGENTA
            } else {
                diverging(z / SIGNED_CLIP)
            }
        })
        .collect()
}

/// PNG bytes of an RGB8 buffer the outcome's size.
pub fn png(o: &Outcome, rgb: &[u8], path: &Path) -> Result<Vec<u8>, ImageError> {
    image::encode_png_rgb8(o.width as u32, o.height as u32, rgb, path)
}

/// PNG bytes of an image's R, G, B (sRGB, clamped, at `exposure` stops).
pub fn image_png(img: &Image, exposure: f32) -> Result<Vec<u8>, ImageError> {
    let rgb = img.select_channels(&["R", "G", "B"])?;
    image::encode_png(&rgb, exposure, Path::new("image.png"))
}

/// Writes `<dir>/<stem>.pvalue.png`, `.mask.png` and `.error.png`; returns their paths.
pub fn write_all(o: &Outcome, dir: &Path, stem: &str) -> Result<Vec<std::path::PathBuf>, String> {
    let mut out = Vec::new();
    for (kind, rgb) in [("pvalue", pvalue_rgb(o)), ("mask", mask_rgb(o)), ("error", signed_rgb(o))] {
        let path = dir.join(format!("{stem}.{kind}.png"));
        let bytes = png(o, &rgb, &path).map_err(|e| e.to_string())?;
        image::write_atomic(&path, |w| w.write_all(&bytes)).map_err(|e| e.to_string())?;
        out.push(path);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_scales() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(diverging(0.0), [255, 255, 255]);
        assert_eq!(diverging(1.0), [178, 24, 43]);
        assert_eq!(diverging(-1.0), [33, 102, 172]);
        assert_eq!(diverging(f64::NAN), MAGENTA);
    }
}
