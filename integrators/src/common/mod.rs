//! Machinery several integrators share.

pub mod direct;
pub mod image_pass;
pub mod light_distribution;
pub mod other_lights;
pub mod pixel_shading;

pub mod params;

use params::{ParamSpec, Params};
use penumbra_core::geometry::Bounds2i;
use penumbra_core::sh::MAX_ORDER;
use penumbra_core::IVec2;
use penumbra_parser::Diagnostic;

/// pbrt-v3's `"integer maxdepth"` (default 5), at most `limit` (a recursive integrator's stack
/// bounds it; an iterative one only its run time).
pub const fn max_depth(limit: i32) -> ParamSpec {
    ParamSpec::int("maxdepth", 5, "specular (or path) bounces followed, as pbrt-v3's maxdepth").range(0, limit)
}

/// Reads [`max_depth`].
pub fn max_depth_param(params: &Params) -> Result<u32, Diagnostic> {
    params.count("maxdepth")
}

/// pbrt-v3's integrator parameter `"integer pixelbounds" [x0 x1 y0 y1]`.
pub const PIXEL_BOUNDS: ParamSpec = ParamSpec::ints(
    "pixelbounds",
    4,
    "the whole film",
    "x0 x1 y0 y1 (half-open): only these pixels are sampled, as pbrt-v3 (the image keeps its size)",
);

/// `"bool sh"`: also write SH transfer channels (order [`SH_ORDER`]) for `penumbra relight`.
pub const SH_TRANSFER: ParamSpec =
    ParamSpec::bool("sh", false, "also write SH transfer channels sh.* and albedo.* for penumbra relight");

/// The order of spherical-harmonic transfer channels (`"integer shorder"`).
pub const SH_ORDER: ParamSpec =
    ParamSpec::int("shorder", 3, "order of the sh.* transfer channels (n² coefficients)").range(1, MAX_ORDER as i32);

/// Reads [`PIXEL_BOUNDS`] (read by `directlighting`, `path`, `whitted` and `shexp`): the pixels
/// to sample. Not four values: a warning and every pixel, as pbrt-v3.
pub fn pixel_bounds_param(params: &Params) -> Result<Option<Bounds2i>, Diagnostic> {
    let (set, warnings) = (params.set(), params.warnings());
    let Some(pb) = params.ints("pixelbounds")? else { return Ok(None) };
    if pb.len() != 4 {
        warnings.warn(
            set.loc_of("pixelbounds").cloned(),
            format!("expected four values for \"pixelbounds\", got {}: ignored", pb.len()),
        );
        return Ok(None);
    }
    let b = Bounds2i::new(IVec2::new(pb[0], pb[2]), IVec2::new(pb[1], pb[3]));
    if b.is_empty() {
        warnings.warn(set.loc_of("pixelbounds").cloned(), "degenerate \"pixelbounds\": no pixel is sampled");
    }
    Ok(Some(b))
}
