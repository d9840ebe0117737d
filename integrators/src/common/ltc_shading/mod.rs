//! Analytic shading of polygonal area lights with Linearly Transformed Cosines and analytic
//! soft shadows (seed 004): what the `ltc` integrator renders with, and what `ratio` takes its
//! unshadowed term `U` from.
//!
//! At a shading point, each area light (one polygon where its mesh allows: a planar outline,
//! a convex mesh's silhouette; else triangle by triangle) is projected onto the sphere of
//! directions, the occluders between the point and the light are projected too, and the
//! visible part is integrated in closed form: the clamped cosine for the Lambertian lobe
//! (exact) and the GGX lobe's LTC ([`crate::common::ltc`]) times its Fresnel factor.
//!
//! Files, from the top: [`shader`] prepares the scene (objects, light shapes) and shades a
//! point light by light; [`occluders`] finds what hides a light piece (a cone query on the
//! object hierarchy, the paper's `GetBetween`); [`integrate`] integrates the visible part;
//! [`fresnel`] applies the glossy lobe's Fresnel factor; [`region`] holds the light loop,
//! the occluders' loops and the visible region; [`objects`] what is prepared per object;
//! [`settings`] what the shading is asked to do.

mod fresnel;
mod integrate;
mod objects;
mod occluders;
mod region;
mod settings;
mod shader;

pub use fresnel::{fresnel_at, FresnelMode};
pub use settings::{Glossy, Mode, ShaderSettings};
pub use shader::{AreaLighting, BudgetedLighting, LightGroup, LtcShader, OverBudget, LIGHT_TRIANGLE_BUDGET};
