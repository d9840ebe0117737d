//! `penumbra`: render pbrt-v3 scenes with selectable integrators, compare them, gate image error in CI.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod cli;
mod convert;
mod diff;
mod info;
mod merge;
mod render;
mod stability;
mod sweep;

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Compare direct-illumination and visibility integrators on pbrt-v3 scenes",
    long_about = "Compare direct-illumination and visibility integrators on pbrt-v3 scenes.\n\n\
        With no subcommand, `penumbra` renders the embedded default scene to penumbra.exr \
        (the same as `penumbra render`).",
    after_help = "Exit status (every subcommand): 0 success; 1 error (a scene, input or output that \
        cannot be used); 64 command-line usage error (unknown option, missing or malformed argument); \
        130 interrupted (Ctrl-C). `diff` adds OpenImageIO idiff's 1 warning, 2 failure, 3 different \
        sizes or channel sets, 4 unreadable file or bad option value; \
        `stability` uses the same scheme: 0 stable, 1 a tolerance exceeded, 2 non-finite values, 4 an \
        unusable scene or option."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (default: the embedded default scene).
    #[command(after_help = penumbra_integrators::help_text())]
    Render(render::RenderArgs),
    /// Check a scene as `render` would (every warning and error, no rendering) and print what it contains.
    Info(info::InfoArgs),
    /// Compare two images with OpenImageIO idiff's metrics and exit codes.
    Diff(diff::DiffArgs),
    /// Merge the shard files of `render --tile I/N` / `--spp-offset K` into one image, bit-identical to the single render.
    Merge(merge::MergeArgs),
    /// Error versus time: render with several integrators at growing budgets against a reference.
    Sweep(sweep::SweepArgs),
    /// Numerical stability: render the scene scaled, rotated, moved far away, with lights and
    /// geometry edited, and report how each integrator's image changes where it must not.
    Stability(stability::StabilityArgs),
    /// Re-shade an image's SH transfer channels (sh.*, albedo.*) under new distant lighting.
    Relight(penumbra::relight::RelightArgs),
    /// Convert an image between EXR, PNG and PFM, with an exposure in stops (e.g. EXR to PNG to look at it).
    Convert(convert::ConvertArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            // Help and version requests are not errors; clap's own code for usage errors (2)
            // is `diff`'s FAIL, so usage errors get their own.
            return if e.use_stderr() { ExitCode::from(penumbra::exit::USAGE) } else { ExitCode::SUCCESS };
        }
    };
    match cli.command {
        Some(Command::Info(a)) => info::run(a),
        Some(Command::Diff(a)) => diff::run(a),
        Some(Command::Render(a)) => render::run(a),
        Some(Command::Sweep(a)) => sweep::run(a),
        Some(Command::Merge(a)) => merge::run(a),
        Some(Command::Stability(a)) => stability::run(a),
        Some(Command::Relight(a)) => penumbra::relight::run(a),
        Some(Command::Convert(a)) => convert::run(a),
        None => render::run(render::RenderArgs::default()),
    }
}
