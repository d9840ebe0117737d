//! `penumbra`: render pbrt-v3 scenes with selectable integrators, compare them, gate image error in CI.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

mod diff;
mod info;
mod render;
mod sweep;

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Compare direct-illumination and visibility integrators on pbrt-v3 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (default: the embedded default scene).
    Render(render::RenderArgs),
    /// Parse a scene and print what it contains, with every warning.
    Info(info::InfoArgs),
    /// Compare two images with OpenImageIO idiff's metrics and exit codes.
    Diff(diff::DiffArgs),
    /// Error versus time: render with several integrators at growing budgets against a reference.
    Sweep(sweep::SweepArgs),
    /// Re-shade an image's SH transfer channels (sh.*, albedo.*) under new distant lighting.
    Relight(penumbra::relight::RelightArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Info(a)) => info::run(a),
        Some(Command::Diff(a)) => diff::run(a),
        Some(Command::Render(a)) => render::run(a),
        Some(Command::Sweep(a)) => sweep::run(a),
        Some(Command::Relight(a)) => penumbra::relight::run(a),
        None => render::run(render::RenderArgs::default()),
    }
}
