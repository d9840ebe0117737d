//! RGB radiometry, as pbrt-v3's default (RGB) build.

/// Linear RGB (pbrt-v3's sRGB primaries), component-wise arithmetic.
pub type Rgb = glam::Vec3;
