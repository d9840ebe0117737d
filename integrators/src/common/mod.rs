//! Machinery several integrators share.

pub mod direct;
pub mod image_pass;
pub mod light_distribution;
pub mod other_lights;
pub mod pixel_shading;

use penumbra_core::geometry::Bounds2i;
use penumbra_core::IVec2;
use penumbra_parser::{DiagSink, Diagnostic, ParamSet};

/// pbrt-v3's `"integer maxdepth"` (default 5), at most `limit` (a recursive integrator's stack
/// bounds it; an iterative one only its run time).
pub fn max_depth_param(params: &ParamSet, limit: u32) -> Result<u32, Diagnostic> {
    let max_depth = params.get_one_int("maxdepth", 5);
    match u32::try_from(max_depth) {
        Ok(d) if d <= limit => Ok(d),
        _ => Err(Diagnostic::error(
            params.loc_of("maxdepth").cloned(),
            format!("\"maxdepth\" must be in 0..={limit}, got {max_depth}"),
        )),
    }
}

/// pbrt-v3's integrator parameter `"integer pixelbounds" [x0 x1 y0 y1]` (read by
/// `directlighting`, `path` and `whitted`): the pixels to sample. Not four values: a warning
/// and every pixel, as pbrt-v3.
pub fn pixel_bounds_param(params: &ParamSet, warnings: &DiagSink) -> Option<Bounds2i> {
    let pb = params.get_ints("pixelbounds")?;
    if pb.len() != 4 {
        warnings.warn(
            params.loc_of("pixelbounds").cloned(),
            format!("expected four values for \"pixelbounds\", got {}: ignored", pb.len()),
        );
        return None;
    }
    let b = Bounds2i::new(IVec2::new(pb[0], pb[2]), IVec2::new(pb[1], pb[3]));
    if b.is_empty() {
        warnings.warn(params.loc_of("pixelbounds").cloned(), "degenerate \"pixelbounds\": no pixel is sampled");
    }
    Some(b)
}
