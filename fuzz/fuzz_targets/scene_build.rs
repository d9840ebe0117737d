#![no_main]
//! `cargo +nightly fuzz run scene_build fuzz/corpus/scene_build`: a fuzzed scene and a fuzzed PLY file,
//! parsed and built as `render` builds them (every requirement on: BVH, lights, materials and
//! the textures they reference, BSSRDF tables, adjacency, dual edges), so that vertex indices, PLY bytes,
//! texture and light parameters — checked in the scene build, not the parser — are reached.
//!
//! Input: the scene text, then optionally a NUL byte and the bytes of `mesh.ply`, written to a
//! temporary directory that is the scene's base directory (`fuzz/seed-build.py` makes seeds
//! of this form from the suite scenes). Nothing else is written; the film is overridden to
//! 8×8 at 1 spp so that a fuzzed resolution cannot exhaust memory.

use libfuzzer_sys::fuzz_target;
use penumbra_core::scene::{BuildOptions, Requirements, Scene};
use penumbra_integrators::silhouette::dual::DualEdges;
use penumbra_parser::DiagSink;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The scene's triangle budget here (`PENUMBRA_MAX_TRIANGLES`, unless the run sets it): enough
/// for every seed (the largest, scenes/real/sphere-lights, makes 63 022 triangles), and
/// a bound on the time one input may take. An input over it is refused before its tessellation is
/// made, through the same charge the command line makes.
const FUZZ_MAX_TRIANGLES: &str = "131072";

/// This process's temporary directory.
fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        if std::env::var_os("PENUMBRA_MAX_TRIANGLES").is_none() {
            // Before any thread is started (this runs on the first input).
            std::env::set_var("PENUMBRA_MAX_TRIANGLES", FUZZ_MAX_TRIANGLES);
        }
        let d = std::env::temp_dir().join(format!("penumbra-fuzz-build-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("create the fuzz directory");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let (text, ply) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let d = dir();
    if std::fs::write(d.join("mesh.ply"), ply).is_err() {
        return;
    }
    let text = String::from_utf8_lossy(text);
    let Ok(parsed) = penumbra_parser::parse_str(&text, "fuzz.pbrt", Some(d)) else { return };
    let req = Requirements {
        accel: true,
        lights: true,
        materials: true,
        adjacency: true,
        min_pixel_samples: None,
        subsurface: true,
    };
    let opts = BuildOptions { spp: Some(1), seed: 0, crop: None, resolution: Some((8, 8)) };
    // With `silhouette`'s dual edges, built as its preparation builds them.
    if let Ok(scene) = Scene::build(&parsed.scene, req, &opts, &DiagSink::new()) {
        let occluders: Vec<bool> = scene.objects.iter().map(|o| o.occluder).collect();
        let _ = DualEdges::build(&scene.meshes, &occluders);
    }
});
