//! Machinery several integrators share.

pub mod direct;
pub mod image_pass;
pub mod light_distribution;
pub mod ltc;
pub mod ltc_shading;
pub mod other_lights;
pub mod pixel_shading;
pub mod spherical_polygon;

pub mod params;

use params::{ParamSpec, Params};
use penumbra_core::geometry::Bounds2i;
use penumbra_core::interaction::SurfaceInteraction;
use penumbra_core::material::Material;
use penumbra_core::scene::Scene;
use penumbra_core::sh::MAX_ORDER;
use penumbra_core::texture::TextureEvalContext;
use penumbra_core::{IVec2, Rgb};
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

/// The diffuse reflectance at `si` (0 where the material has none, or none was built): the
/// `albedo.*` channels written beside SH transfer channels (`ambientocclusion`, `sheared-ao`,
/// `silhouette`).
pub fn diffuse_albedo(scene: &Scene, si: &SurfaceInteraction) -> Rgb {
    let Some((material, materials, textures)) = scene.material_of(si) else { return Rgb::ZERO };
    match material {
        Material::Matte { kd, .. } => textures.eval_spectrum(*kd, &TextureEvalContext::from_si(si)).max(Rgb::ZERO),
        // (substrate: its Kd, though its FresnelBlend is not Lambertian)
        Material::Substrate { kd, .. } => textures.eval_spectrum(*kd, &TextureEvalContext::from_si(si)).max(Rgb::ZERO),
        m => m.ltc_diffuse(si, materials, textures).unwrap_or(Rgb::ZERO),
    }
}

/// `integrator`'s refusal of a scene with an occluding alpha cut-out or curve, which its
/// `visibility` (built from the meshes' geometry) cannot represent: an error naming the shape
/// and what renders it instead.
pub fn refuse_cutouts(
    integrator: &str,
    visibility: &str,
    scene: &Scene,
) -> Result<(), penumbra_core::integrator::RenderError> {
    match scene.non_polygonal_occluder() {
        None => Ok(()),
        Some((o, why)) => Err(penumbra_core::integrator::RenderError::Failed(format!(
            "{}: shape \"{}\" {why}, which {integrator}'s {visibility} cannot represent: render the scene with \
             directlighting, path or ambientocclusion (whose ray queries honour cut-outs, intersect curves and \
             follow moving shapes), or \
             give the shape \"bool occluder\" false to leave it out of {integrator}'s visibility",
            o.loc, o.kind
        ))),
    }
}
