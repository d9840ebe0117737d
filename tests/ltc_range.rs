//! `ltc` and `ratio` against pbrt-v3 over the whole roughness range pbrt-v3 can produce
//! (remapped roughness 0.001…1, raw α 0.001…3) for every material they shade analytically:
//! plastic, metal, substrate, uber, translucent (its reflection; its transmission goes through
//! `directlighting`'s estimator), mix, and an anisotropic metal (no LTC form: the estimator).
//!
//! The cells (`tests/data/ltc-range/cells.txt`) are `ltc/quad-cube`'s scene at 64×64
//! (`template.pbrt`) with the floor's material replaced; their references are pbrt-v3's
//! `directlighting` renders (1024–4096 spp, `timings.tsv`) reduced to the means of 8×8-pixel
//! blocks by `make_references.py`. Each cell is checked on its image mean and on every block
//! the reference does not leave black (the sky), at 16 spp for `ltc` with 256 coverage samples
//! (camera rays only: at 16 the anti-aliasing of the cube's and the floor's edges moves single
//! blocks by up to ±4 %, the same for `"shading" "sample"`; with 256 every block of every cell
//! is within 1 % but where the reference's own noise is larger, in the sharp highlights) and
//! 64 spp for `ratio` (at 16 its shadow ratio's noise is about ±3 % in the cube's darkest
//! shadow block).
//!
//! `plastic-a0.001` (raw α 0.001, below the range of 0.01…3; remapped roughness 0.001 is
//! α ≈ 0.05) is rendered and reported but not asserted: there pbrt-v3 evaluates the GGX `D` in
//! single precision, whose `Sin2Theta = 1 − cos²θ` cancels at `tan θ ≈ 0.001`, and penumbra's
//! `directlighting` (double-checked against it: +1.9 % at 256 spp) differs from pbrt-v3 as much
//! as `ltc` does (+1.4 %): a conformance matter of the material, not of the integrator.

mod common;
use common::*;
use penumbra_core::image::Image;
use std::path::PathBuf;

fn data_dir() -> PathBuf {
    root().join("tests/data/ltc-range")
}

/// `(name, floor material directives)` of every cell.
fn cells() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(data_dir().join("cells.txt")).expect("cells.txt");
    let mut out: Vec<(String, String)> = Vec::new();
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("## ") {
            out.push((name.trim().to_string(), String::new()));
        } else if !line.starts_with('#') {
            if let Some((_, body)) = out.last_mut() {
                body.push_str(line);
                body.push('\n');
            }
        }
    }
    out
}

fn scene_text(floor: &str) -> String {
    std::fs::read_to_string(data_dir().join("template.pbrt")).expect("template.pbrt").replace("@FLOOR@", floor)
}

/// The means of the 8×8-pixel blocks of a 64×64 image (RGB summed), row by row.
fn block_means(img: &Image) -> Vec<f64> {
    let (w, h) = (img.width as usize, img.height as usize);
    let (bw, bh) = (w / 8, h / 8);
    let mut out = vec![0.0; 64];
    for y in 0..h {
        for x in 0..w {
            let v: f64 = (0..3).map(|c| img.data[(y * w + x) * 3 + c] as f64).sum();
            out[(y / bh).min(7) * 8 + (x / bw).min(7)] += v / (bw * bh) as f64;
        }
    }
    out
}

/// A cell's errors against its reference: the image mean's relative error and the worst
/// block's (blocks the reference leaves black are skipped), with that block's index.
struct CellError {
    mean: f64,
    block: f64,
    at: usize,
}

fn cell_error(ours: &Image, reference: &Image) -> CellError {
    let (a, b) =
        (block_means(ours), reference.data.chunks(3).map(|p| p.iter().map(|v| *v as f64).sum()).collect::<Vec<f64>>());
    assert_eq!(b.len(), 64, "references are 8×8 images of block means");
    let mean = a.iter().sum::<f64>() / b.iter().sum::<f64>() - 1.0;
    let (mut block, mut at) = (0.0f64, 0);
    for k in 0..64 {
        if b[k] > 0.0 {
            let e = a[k] / b[k] - 1.0;
            if e.abs() > block.abs() {
                (block, at) = (e, k);
            }
        }
    }
    CellError { mean, block, at }
}

/// Renders every cell that has a reference with `integrator` at `spp` and checks the image mean
/// within `mean_tol` and every block within `block_tol` of pbrt-v3's; `keep` selects cells.
fn check_cells(integrator: &str, params: &[&str], spp: u32, keep: impl Fn(usize) -> bool, tol: (f64, f64)) {
    let mut failures = Vec::new();
    let mut checked = 0;
    for (i, (name, floor)) in cells().into_iter().enumerate() {
        if !keep(i) {
            continue;
        }
        let path = data_dir().join("refs").join(format!("{name}.pfm"));
        if !path.exists() {
            continue;
        }
        let reference = penumbra_core::image::read(&path).expect("reference");
        let spp = if integrator == "ratio" && RATIO_SPP_256.contains(&name.as_str()) { spp.max(256) } else { spp };
        let opts = Opts {
            integrator: Some(integrator),
            params,
            spp: Some(spp),
            resolution: Some((64, 64)),
            ..Default::default()
        };
        let r = render_text(&scene_text(&floor), &opts);
        assert!(r.image.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: bad values");
        let e = cell_error(&r.image, &reference);
        eprintln!(
            "{integrator} {name}: mean {:+.2}%, worst block {:+.2}% (block {} {})",
            e.mean * 100.0,
            e.block * 100.0,
            e.at / 8,
            e.at % 8
        );
        checked += 1;
        if NOT_ASSERTED.contains(&name.as_str()) {
            continue;
        }
        if e.mean.abs() > tol.0 || e.block.abs() > tol.1 {
            failures.push(format!("{name}: mean {:+.2}%, block {:+.2}%", e.mean * 100.0, e.block * 100.0));
        }
    }
    assert!(checked > 0, "no ltc-range reference found under {}", data_dir().display());
    assert!(failures.is_empty(), "{integrator}: cells off pbrt-v3: {failures:?}");
}

/// Cells outside the range whose reference `directlighting` does not match either (see
/// the module doc): reported, not asserted.
const NOT_ASSERTED: &[&str] = &["plastic-a0.001"];

/// Cells whose `ratio` run takes 256 camera samples instead of 64: `metal-r0.001` (α ≈ 0.05
/// copper) has a near-mirror reflection of the cube's shadow edge in block (3, 5), whose
/// anti-aliasing at 64 camera samples is off by a few per cent for every integrator (measured
/// on that block against pbrt-v3: `directlighting` 64 spp −3.29 %, 256 spp −0.21 %; `ltc` 64 spp
/// with one coverage sample per camera sample −3.72 %; `ratio` 64 spp −3.72 % whatever its seed,
/// `nsamples` 16 or `"shading" "sample"`, 256 spp −0.72 %, 1024 spp −0.04 %): camera sampling,
/// not `ratio`'s estimator (it was a known failure of issue 43 until measured so).
const RATIO_SPP_256: &[&str] = &["metal-r0.001"];

/// `ltc`'s parameters in the test: 256 coverage samples (see the module doc).
const LTC_PARAMS: &[&str] = &["coveragesamples=256"];

/// The targets (image mean within 1 %, every 8×8 block within 3 %), which every cell
/// meets with `ltc` at 16 spp; measured worst: see `docs/integrators/ltc-range.md`.
const TOL: (f64, f64) = (0.01, 0.03);

/// Half of the cells in the default run (the other half: `every_cell_ltc_and_ratio`, ignored
/// for time), each integrator taking the other half than the other.
#[test]
fn ltc_matches_pbrt_v3_across_roughness() {
    check_cells("ltc", LTC_PARAMS, 16, |i| i % 2 == 0, TOL);
}

#[test]
fn ratio_matches_pbrt_v3_across_roughness() {
    check_cells("ratio", &[], 64, |i| i % 2 == 1, TOL);
}

/// Every cell with both integrators (`cargo test --release --test ltc_range -- --ignored`).
#[test]
#[ignore]
fn every_cell_ltc_and_ratio() {
    check_cells("ltc", LTC_PARAMS, 16, |_| true, TOL);
    check_cells("ratio", &[], 64, |_| true, TOL);
}
