//! What the LTC shading is asked to do: how occluders are represented, whether there are
//! shadows at all, how the glossy lobe's Fresnel is applied, whether adjacent occluder
//! triangles are merged into outlines.

use super::fresnel::FresnelMode;

/// How occluders (and light meshes) are turned into spherical polygons (`ltc`'s `"string mode"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// One silhouette loop per closed mesh.
    Silhouette,
    /// Every light and every occluder as its triangles.
    PerTriangle,
    /// Silhouettes for objects proven closed and convex, triangles otherwise.
    Auto,
}

/// The settings of an [`LtcShader`](super::LtcShader).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderSettings {
    pub mode: Mode,
    /// Analytic visibility (false: the unshadowed term only).
    pub shadows: bool,
    pub fresnel: FresnelMode,
    /// Occluder triangles of one object that lie wholly in front of the light are subtracted
    /// as their outline (false: triangle by triangle; the same image).
    pub merge_occluders: bool,
}
