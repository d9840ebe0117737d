//! penumbra's framework: the renderable [`scene::Scene`], cameras, film,
//! samplers, filters, image I/O, metrics, and the integrator interface that
//! every integrator in `penumbra-integrators` plugs into.

pub mod bxdf;
#[rustfmt::skip]
#[allow(clippy::excessive_precision)]
pub mod cie_data;
pub mod mesh;
#[rustfmt::skip]
#[allow(clippy::excessive_precision)]
pub mod metal_data;
pub mod microfacet;
pub mod sampler;
pub mod spectrum;

pub use glam::{IVec2, UVec2, Vec2, Vec3, Vec3A};
pub use penumbra_parser as parser;
pub use spectrum::Rgb;
