//! `penumbra`: render pbrt-v3 scenes with selectable integrators, compare them, gate image error in CI.

use clap::{CommandFactory, Parser, Subcommand};
use penumbra::{cli, info, sweep};
use std::ffi::OsString;
use std::path::Path;
use std::process::ExitCode;

mod convert;
mod diff;
mod merge;
mod render;
mod stability;

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Compare direct-illumination and visibility integrators on pbrt-v3 scenes",
    long_about = "Compare direct-illumination and visibility integrators on pbrt-v3 scenes.\n\n\
        With no subcommand, `penumbra` renders the embedded default scene to penumbra.exr \
        (the same as `penumbra render`); `penumbra scene.pbrt [options]` renders that scene, \
        as `pbrt scene.pbrt` does (the same as `penumbra render scene.pbrt [options]`).",
    after_help = "Exit status (every subcommand): 0 success; 1 error (a scene, input or output that \
        cannot be used); 64 command-line usage error (unknown option, missing or malformed argument); \
        130 interrupted (Ctrl-C). `diff` adds OpenImageIO idiff's 1 warning, 2 failure, 3 different \
        sizes or channel sets, 4 unreadable file or bad option value; \
        `check` uses diff's 0 pass, 2 failure, 3 different sizes, 4 unusable file or option; \
        `stability` uses the same scheme: 0 stable, 1 a tolerance exceeded, 2 non-finite values, 4 an \
        unusable scene or option value. A value that cannot be parsed at all (e.g. `--resolution 128`, \
        `--crop 1,2,3`, `--tile 7/7`) is a usage error, 64, in every subcommand (`diff --crop` keeps idiff's 4)."
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
    /// Is a render's difference from a reference noise? A statistical image-regression gate
    /// (per-value Welch/z tests, block and whole-image means, family-wise alpha), and suites.
    Check(penumbra::check::CheckArgs),
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
    let cli = match Cli::try_parse_from(with_render_for_a_scene(std::env::args_os().collect())) {
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
        Some(Command::Check(a)) => penumbra::check::run(a),
        Some(Command::Render(a)) => render::run(a),
        Some(Command::Sweep(a)) => sweep::run(a),
        Some(Command::Merge(a)) => merge::run(a),
        Some(Command::Stability(a)) => stability::run(a),
        Some(Command::Relight(a)) => penumbra::relight::run(a),
        Some(Command::Convert(a)) => convert::run(a),
        None => render::run(render::RenderArgs::default()),
    }
}

/// The pbrt habit (issue 41): `penumbra scene.pbrt …` renders the scene. A first argument that
/// is not a subcommand or an option, and names an existing file or ends in `.pbrt`, gets
/// `render` put before it.
fn with_render_for_a_scene(mut args: Vec<OsString>) -> Vec<OsString> {
    if let Some(first) = args.get(1) {
        let text = first.to_string_lossy();
        let subcommand = text == "help" || Cli::command().get_subcommands().any(|c| c.get_name() == text);
        let scene = text.ends_with(".pbrt") || Path::new(first).is_file();
        if !subcommand && !text.starts_with('-') && scene {
            args.insert(1, OsString::from("render"));
        }
    }
    args
}
