//! penumbra's framework: the renderable [`scene::Scene`], cameras, film,
//! samplers, filters, image I/O, metrics, and the integrator interface that
//! every integrator in `penumbra-integrators` plugs into.

pub mod accel;
pub mod agreement;
pub mod bssrdf;
pub mod bxdf;
pub mod camera;
#[rustfmt::skip]
#[allow(clippy::excessive_precision)]
pub mod cie_data;
pub mod film;
pub mod filter;
pub mod fnv;
pub mod geometry;
// Not test-only: `agreement` (used by `penumbra check`) needs its gamma functions.
pub mod goodness_of_fit;
pub mod image;
pub mod integrator;
pub mod interaction;
pub mod interpolation;
pub mod lens;
pub mod light;
pub mod material;
pub mod mesh;
pub mod motion;
#[rustfmt::skip]
#[allow(clippy::excessive_precision)]
pub mod metal_data;
pub mod metrics;
pub mod microfacet;
pub mod profiling;
pub mod rng;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod sh;
pub mod shapes;
pub mod shard_rects;
pub mod spectrum;
pub mod texture;

pub use glam::{IVec2, UVec2, Vec2, Vec3, Vec3A};
pub use penumbra_parser as parser;
pub use spectrum::Rgb;
