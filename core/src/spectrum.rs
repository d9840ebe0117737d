//! RGB radiometry, as pbrt-v3's default (RGB) build.

/// Linear RGB (pbrt-v3's sRGB primaries), component-wise arithmetic.
pub type Rgb = glam::Vec3;

/// pbrt-v3's luminance weights (`RGBSpectrum::y`).
pub fn luminance(c: Rgb) -> f32 {
    0.212671 * c.x + 0.715160 * c.y + 0.072169 * c.z
}
