//! What a ray query finds: the local geometry at a hit ([`SurfaceInteraction`]) and the
//! scene object a mesh comes from ([`SceneObject`]). Lights, materials and textures
//! read these; the scene ([`crate::scene`]) produces them, so the arrows point one way:
//! `scene` → `light`/`material`/`texture` → `interaction` → `geometry`.

use crate::geometry::{offset_ray_origin, Frame, Ray};
use glam::{Vec2, Vec3};
use penumbra_parser::FileLoc;

/// One shape directive (or one shape of one object instance) in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// The shape type as written (`"sphere"`, `"trianglemesh"`…).
    pub kind: String,
    pub loc: FileLoc,
    /// Index into `SceneDescription::materials`; `None` means no surface (pbrt-v3's `Material "none"`).
    pub material: Option<usize>,
    /// Index into `SceneDescription::area_lights`.
    pub area_light: Option<usize>,
    /// Which `ObjectInstance` this came from, if any.
    pub instance: Option<usize>,
    /// `"bool occluder" false` on the shape: analytic visibility methods ignore it as an
    /// occluder (a penumbra extension; pbrt-v3 reports the parameter unused and renders).
    pub occluder: bool,
}

/// The local geometry at a ray hit, with pbrt-v3's conventions for normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    /// Conservative absolute error bound on `p`.
    pub p_error: Vec3,
    /// Geometric normal (pbrt-v3's `n`: flipped by `ReverseOrientation` xor handedness,
    /// and on the side of the shading normal when the mesh has normals).
    pub n: Vec3,
    pub uv: Vec2,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    /// Shading frame (z = shading normal).
    pub shading: Frame,
    /// Direction towards the ray origin.
    pub wo: Vec3,
    pub mesh: u32,
    pub tri: u32,
}

impl SurfaceInteraction {
    /// A ray leaving the surface in direction `d`, offset so it cannot re-hit this surface.
    pub fn spawn_ray(&self, d: Vec3) -> Ray {
        Ray::new(offset_ray_origin(self.p, self.p_error, self.n, d), d, f32::INFINITY)
    }
    /// A shadow ray from this surface to point `p` (stops just short of it).
    pub fn spawn_ray_to(&self, p: Vec3) -> Ray {
        let o = offset_ray_origin(self.p, self.p_error, self.n, p - self.p);
        Ray::new(o, p - o, 1.0 - SHADOW_EPSILON)
    }
    /// A shadow ray between this surface and another surface point, both ends offset.
    pub fn spawn_ray_to_surface(&self, p: Vec3, p_error: Vec3, n: Vec3) -> Ray {
        let o = offset_ray_origin(self.p, self.p_error, self.n, p - self.p);
        let t = offset_ray_origin(p, p_error, n, o - p);
        Ray::new(o, t - o, 1.0 - SHADOW_EPSILON)
    }
}

/// pbrt-v3's `ShadowEpsilon`.
pub const SHADOW_EPSILON: f32 = 0.0001;
