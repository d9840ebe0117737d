//! penumbra as a library: the pipeline the CLI's commands share (load a scene,
//! choose an integrator, build what it needs, render), so tests and `sweep`
//! call exactly what `penumbra render` runs.

pub mod cli_params;
pub mod output;
pub mod pipeline;
pub mod relight;
