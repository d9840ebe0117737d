//! `penumbra merge`: shards (`render --tile I/N`, `render --spp-offset K`) into one image.

use crate::cli::{has_extension, write_outputs};
use penumbra::output::{self, MissingDir};
use penumbra::shard::{self, Shard};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct MergeArgs {
    /// Shard files of one image (every tile of `--tile I/N`, each with the same `--spp-offset`
    /// ranges), in any order.
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
    /// The merged image (.exr, .png or .pfm); `stats.json` is written beside it.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Also write per-pixel variance channels (EXR only).
    #[arg(long)]
    pub variance: bool,
    /// PNG output: multiply by 2^S before the sRGB encoding.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f32,
    /// No summary line.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

fn fail(msg: impl std::fmt::Display) -> ExitCode {
    eprintln!("error: {msg}");
    ExitCode::FAILURE
}

pub fn run(args: MergeArgs) -> ExitCode {
    if !["exr", "png", "pfm"].iter().any(|e| has_extension(&args.output, e)) {
        return fail(format!("{}: output must end in .exr, .png or .pfm", args.output.display()));
    }
    if let Err(e) = output::prepare(&args.output, MissingDir::Fail) {
        return fail(e);
    }
    let mut shards = Vec::with_capacity(args.shards.len());
    for p in &args.shards {
        match Shard::read(p) {
            Ok(s) => shards.push((p.display().to_string(), s)),
            Err(e) => return fail(e),
        }
    }
    let m = match shard::merge(&shards) {
        Ok(m) => m,
        Err(e) => return fail(format!("cannot merge: {e}")),
    };
    let id = &m.identity;
    let pb = m.film.pixel_bounds();
    let stats = serde_json::json!({
        "scene": shards[0].1.header.scene,
        "scene_hash": id.scene_hash,
        "integrator": id.integrator,
        "parameters": id.params,
        "image": args.output.display().to_string(),
        "resolution": id.full_resolution,
        "pixel_bounds": [pb.min.x, pb.max.x, pb.min.y, pb.max.y],
        "spp": m.spp,
        "seed": id.seed,
        "sampler": id.sampler,
        "exposure": args.exposure,
        "merged_shards": shards.len(),
        "tiles": id.tile_count,
        "tile_layout": id.tile_layout,
        "rays": m.stats.rays,
        "shadow_rays": m.stats.shadow_rays,
        "camera_samples": m.stats.camera_samples,
        "bad_samples": m.stats.bad_samples,
        "render_seconds": m.stats.render_seconds,
        "render_seconds_max": m.max_render_seconds,
        "build_seconds": m.stats.build_seconds,
        "parse_seconds": m.stats.parse_seconds,
        "shards": m.shards,
    });
    let image = match write_outputs(m.film.to_image(args.variance), &args.output, args.exposure, &stats) {
        Ok(i) => i,
        Err(e) => return fail(e),
    };
    if !args.quiet {
        eprintln!(
            "{}: {} shards of {} at {} spp, {}x{} px, render {:.3} s in all (longest shard {:.3} s)",
            args.output.display(),
            shards.len(),
            id.integrator,
            m.spp,
            image.width,
            image.height,
            m.stats.render_seconds,
            m.max_render_seconds
        );
    }
    ExitCode::SUCCESS
}
