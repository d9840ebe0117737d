//! `silhouette` on real meshes (issue 37's check): two loop-subdivided killeroos, 66.5k
//! triangles, on a ground plane before a wall (`scenes/meshes/`), under a uniform white sky
//! (`mode=ao` against pbrt-v3's `ambientocclusion`) and under the studio map (`shade` against
//! pbrt-v3's `directlighting`), and a staircase under the sky. References: the real pbrt-v3 at
//! 256², 4096 spp (sky) and 1024 spp (studio), box-downsampled to 64²
//! (`tools/meshes_equal_error.py --references`).

mod common;
use common::*;

/// Renders `scenes/meshes/NAME.pbrt` with `silhouette` (64², 4 spp) and asserts its image mean
/// and its worst 8×8 block mean against pbrt-v3's within `mean_tol` and `block_tol` (relative).
fn check(name: &str, params: &[&str], reference_name: &str, mean_tol: f64, block_tol: f64) {
    let ours = render_path(
        &scene(&format!("meshes/{name}.pbrt")),
        &Opts { integrator: Some("silhouette"), params, spp: Some(4), ..Default::default() },
    );
    let reference = reference(&format!("meshes/{reference_name}.exr"));
    let rel = mean(&ours.image) / mean(&reference) - 1.0;
    let worst = block_means(&ours.image)
        .iter()
        .zip(block_means(&reference))
        .map(|(o, r)| (o / r - 1.0).abs())
        .fold(0.0f64, f64::max);
    eprintln!("{name}: image mean {:+.3} %, worst 8×8 block {:.3} %", rel * 100.0, worst * 100.0);
    assert!(rel.abs() < mean_tol, "{name}: image mean {rel:+.4}");
    assert!(worst < block_tol, "{name}: worst block {worst:.4}");
}

/// Issue 37 asks for 1 % (AO). Measured at 64², 4 spp: image mean +0.024 %, worst 8×8 block
/// 0.99 % (RMS over the 64 blocks 0.25 %); at 16 spp +0.020 % / 0.51 % (RMS 0.13 %): the blocks'
/// error is the anti-aliasing noise of 256 camera samples per block, halving with 4× the
/// samples, and the mean's noise is about 0.25 % / √64 = 0.03 %. Bounds: the measured figures
/// plus about five of those noise units (mean 0.2 %), and 1.5 × the worst block (1.5 %).
#[test]
fn killeroos_under_a_white_sky_match_pbrt_v3_ao() {
    check("killeroos-sky", &["mode=ao"], "killeroos-sky.ao", MEAN_TOL_SKY, BLOCK_TOL_SKY);
}

/// The staircase (12 box steps by a wall; sharp concave corners, every contour edge a crease)
/// under the same sky. Measured at 64², 4 spp: image mean +0.0065 %, worst 8×8 block 0.88 %
/// (16 spp: +0.019 % / 0.58 %); the killeroos' bounds hold it.
#[test]
fn staircase_under_a_white_sky_matches_pbrt_v3_ao() {
    check("staircase-sky", &["mode=ao"], "staircase-sky.ao", MEAN_TOL_SKY, BLOCK_TOL_SKY);
}

/// Issue 37 asks for 2 % (studio). Measured at 64², 4 spp: image mean +0.019 %, worst 8×8 block
/// 1.22 % (RMS 0.34 %); at 16 spp +0.027 % / 0.74 % (RMS 0.14 %), anti-aliasing noise as above
/// (`directlighting` at 256 spp: +0.016 % / 0.47 %). Bounds as for the sky: mean 0.2 %, blocks
/// 1.5 × the worst measured (1.8 %). With `resolution=8` (8 meridians) the render is +2.47 % /
/// 29.6 % off (the sky's −0.62 % / 9.9 %): both bounds catch a coarse azimuth.
#[test]
fn killeroos_under_the_studio_map_match_pbrt_v3() {
    check("killeroos-studio", &[], "killeroos-studio", MEAN_TOL_STUDIO, BLOCK_TOL_STUDIO);
}

const MEAN_TOL_SKY: f64 = 0.002;
const BLOCK_TOL_SKY: f64 = 0.015;
const MEAN_TOL_STUDIO: f64 = 0.002;
const BLOCK_TOL_STUDIO: f64 = 0.018;
