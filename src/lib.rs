//! penumbra as a library: the pipeline the CLI's commands share (load a scene,
//! choose an integrator, build what it needs, render), so tests and `sweep`
//! call exactly what `penumbra render` runs.

pub mod check;
pub mod cli;
pub mod cli_params;
pub mod info;
pub mod output;
pub mod pipeline;
pub mod relight;
pub mod scene_identity;
pub mod shard;
pub mod sweep;

/// Exit statuses shared by every subcommand (`diff` adds idiff's 1–4 for its verdicts).
pub mod exit {
    /// Something could not be used: a scene, an input or an output.
    pub const ERROR: u8 = 1;
    /// Command-line usage error (sysexits' `EX_USAGE`): distinct from every `diff` verdict.
    pub const USAGE: u8 = 64;
    /// Interrupted by Ctrl-C (as a shell reports SIGINT: 128 + 2).
    pub const INTERRUPTED: u8 = 130;
}
