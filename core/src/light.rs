//! Lights with pbrt-v3's semantics. (Interface; the implementation follows.)
//!
//! Area lights over triangle meshes follow pbrt-v3's granularity: a
//! `trianglemesh`/`plymesh`/`loopsubdiv`/`heightfield` area light is one light
//! per triangle (pbrt-v3 makes one `Triangle` shape, hence one light, per
//! triangle); a quadric (sphere, disk, …) is one light over all the triangles
//! of its tessellation, sampled by area.

use crate::Rgb;
use glam::Vec3;

/// The receiving point of a light query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightContext {
    pub p: Vec3,
    pub p_error: Vec3,
    /// Geometric normal at `p` (zero if `p` is not on a surface).
    pub n: Vec3,
}

/// A sampled incident direction from a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightLiSample {
    /// Incident radiance (delta lights: intensity / distance², as pbrt-v3).
    pub li: Rgb,
    /// Unit direction from the receiving point towards the light.
    pub wi: Vec3,
    /// Solid-angle density (1 for delta lights).
    pub pdf: f32,
    /// The sampled point on the light, its error bound and normal (zero normal for
    /// point-like and infinitely distant lights), for the shadow ray.
    pub p_light: Vec3,
    pub p_light_error: Vec3,
    pub n_light: Vec3,
    pub delta: bool,
}

/// An emitting surface: which mesh and triangles, with what radiance.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    pub mesh: u32,
    pub tris: Vec<u32>,
    /// Emitted radiance `L × scale`.
    pub l: Rgb,
    pub two_sided: bool,
    pub area: f32,
}
