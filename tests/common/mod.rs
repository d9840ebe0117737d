//! Shared helpers for the end-to-end render tests.
#![allow(dead_code)]

use penumbra::cli_params::parse_param;
use penumbra::pipeline::{self, RenderOptions};
use penumbra_core::image::{self, Image};
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_parser::DiagSink;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// The suite's stiff scenes (`scenes/suite/stiff/NAME.pbrt`, references `stiff/NAME.exr`).
pub const STIFF_SCENES: [&str; 8] = [
    "coincident-geometry",
    "grazing-light",
    "intersecting-occluders",
    "light-touching-floor",
    "roughness-extremes",
    "scaled-1e-4",
    "scaled-1e4",
    "tiny-far-light",
];

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn scene(rel: &str) -> PathBuf {
    root().join("scenes").join(rel)
}

pub fn reference(rel: &str) -> Image {
    image::read(root().join("tests/data/references").join(rel)).expect("reference image")
}

pub struct Render {
    pub image: Image,
    pub variance: Image,
    pub warnings: Vec<String>,
    /// Camera samples per pixel taken.
    pub spp: u32,
    /// The render's counters (rays, shadow rays, camera samples, …).
    pub stats: penumbra_core::integrator::RenderStats,
    /// Every channel the render wrote (R, G, B, the integrator's extra channels, variance).
    pub channels: Image,
}

pub struct Opts<'a> {
    pub integrator: Option<&'a str>,
    pub params: &'a [&'a str],
    pub spp: Option<u32>,
    pub resolution: Option<(u32, u32)>,
    pub threads: usize,
    pub seed: u64,
    pub crop: Option<Crop>,
    /// Replace the scene's sampler type (e.g. "random" for honest per-pixel variance estimates).
    pub sampler: Option<&'a str>,
}

impl Default for Opts<'_> {
    fn default() -> Self {
        Opts {
            integrator: None,
            params: &[],
            spp: None,
            resolution: Some((64, 64)),
            threads: 0,
            seed: 0,
            crop: None,
            sampler: None,
        }
    }
}

pub fn render_path(path: &Path, o: &Opts) -> Render {
    let parsed = penumbra_parser::parse_file(path).unwrap_or_else(|e| panic!("{e}"));
    render_desc(&parsed.scene, o)
}

pub fn render_text(text: &str, o: &Opts) -> Render {
    let parsed = penumbra_parser::parse_str(text, "<test>", Some(&root())).unwrap_or_else(|e| panic!("{e}"));
    render_desc(&parsed.scene, o)
}

pub fn render_desc(desc: &penumbra_parser::SceneDescription, o: &Opts) -> Render {
    let mut desc = desc.clone();
    if let Some(s) = o.sampler {
        desc.sampler = penumbra_parser::Entity::default_of(s);
    }
    let desc = &desc;
    let warnings = DiagSink::new();
    let params: Vec<_> = o.params.iter().map(|p| parse_param(p).unwrap()).collect();
    let cancel = AtomicBool::new(false);
    let opts = RenderOptions {
        integrator: o.integrator,
        params: &params,
        build: BuildOptions { spp: o.spp, seed: o.seed, crop: o.crop, resolution: o.resolution },
        threads: o.threads,
        with_variance: true,
        cancel: &cancel,
        progress: None,
    };
    let r = pipeline::render(desc, &opts, &warnings).unwrap_or_else(|e| panic!("render failed: {e}"));
    let rgb = r.image.select_channels(&["R", "G", "B"]).unwrap();
    let mut var = r.image.select_channels(&["variance.R", "variance.G", "variance.B"]).unwrap();
    var.channels = rgb.channels.clone();
    Render {
        image: rgb,
        variance: var,
        warnings: warnings.take().iter().map(|d| d.message.clone()).collect(),
        spp: r.stats.spp,
        stats: r.stats,
        channels: r.image,
    }
}

pub fn mean(img: &Image) -> f64 {
    img.data.iter().map(|v| *v as f64).sum::<f64>() / img.data.len() as f64
}

/// The means of the image's 8×8-pixel blocks (over the colour channels), row by row.
pub fn block_means(img: &Image) -> Vec<f64> {
    let (w, h) = (img.width as usize, img.height as usize);
    let mut out = Vec::new();
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let mut s = 0.0;
            for y in by * 8..by * 8 + 8 {
                for x in bx * 8..bx * 8 + 8 {
                    s += (0..3).map(|c| img.data[(y * w + x) * 3 + c] as f64).sum::<f64>();
                }
            }
            out.push(s / (64.0 * 3.0));
        }
    }
    out
}

pub fn rmse(a: &Image, b: &Image) -> f64 {
    assert_eq!((a.width, a.height, a.data.len()), (b.width, b.height, b.data.len()));
    (a.data.iter().zip(&b.data).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum::<f64>() / a.data.len() as f64).sqrt()
}

/// Agreement of a render with a reference, allowing for the noise of both.
#[derive(Debug)]
pub struct Agreement {
    pub mean_ours: f64,
    pub mean_ref: f64,
    pub rel_mean_diff: f64,
    pub rmse: f64,
    /// Mean of z² over values (≈ 1 if the difference is noise; ≤ 1 for QMC, whose error is below its sample variance).
    pub mean_z2: f64,
    /// Fraction of values with |z| > 5.
    pub outliers: f64,
}

/// `ref_var_ratio`: the reference's per-pixel variance relative to ours (its sample count per
/// pixel over ours, inverted); `floor` is an absolute standard deviation added to both (for
/// pixels whose sample variance is zero, e.g. constant background, and float rounding).
pub fn agreement(ours: &Render, reference: &Image, ref_var_ratio: f64, floor: f64) -> Agreement {
    let a = &ours.image;
    assert_eq!((a.width, a.height), (reference.width, reference.height), "image sizes");
    let mean_ours = mean(a);
    let mean_ref = mean(reference);
    let mut z2 = 0.0;
    let mut out = 0usize;
    for i in 0..a.data.len() {
        let d = a.data[i] as f64 - reference.data[i] as f64;
        let v = ours.variance.data[i] as f64 * (1.0 + ref_var_ratio) + floor * floor;
        let z = d / v.sqrt();
        z2 += z * z;
        if !(z.abs() <= 5.0) {
            out += 1;
        }
    }
    Agreement {
        mean_ours,
        mean_ref,
        rel_mean_diff: (mean_ours - mean_ref) / mean_ref,
        rmse: rmse(a, reference),
        mean_z2: z2 / a.data.len() as f64,
        outliers: out as f64 / a.data.len() as f64,
    }
}

/// The `k` values with the largest |z| (index, ours, reference, our variance), for diagnostics.
pub fn worst(
    ours: &Render,
    reference: &Image,
    ref_var_ratio: f64,
    floor: f64,
    k: usize,
) -> Vec<(usize, f32, f32, f32)> {
    let mut v: Vec<(f64, usize)> = (0..ours.image.data.len())
        .map(|i| {
            let d = ours.image.data[i] as f64 - reference.data[i] as f64;
            let var = ours.variance.data[i] as f64 * (1.0 + ref_var_ratio) + floor * floor;
            ((d / var.sqrt()).abs(), i)
        })
        .collect();
    v.sort_by(|a, b| b.0.total_cmp(&a.0));
    v.iter().take(k).map(|&(_, i)| (i, ours.image.data[i], reference.data[i], ours.variance.data[i])).collect()
}

/// Checks that `render(threads, crop)` gives a bit-identical image with 1 and 2 threads, and
/// when assembled from four uneven crops not aligned to the 16-pixel tile grid (`w`×`h` image).
pub fn assert_deterministic(w: i32, h: i32, render: impl Fn(usize, Option<Crop>) -> Render) {
    let one = render(1, None);
    let two = render(2, None);
    assert_same(&one.image.data, &two.image.data, "1 vs 2 threads");
    let (sx, sy, sx2) = (w * 7 / 16, h / 3, w * 3 / 4);
    let mut assembled = vec![f32::NAN; one.image.data.len()];
    for (x0, x1, y0, y1) in [(0, sx, 0, sy), (sx, w, 0, sy), (0, sx2, sy, h), (sx2, w, sy, h)] {
        let piece = render(2, Some(Crop::Pixels([x0, x1, y0, y1])));
        assert_eq!((piece.image.width, piece.image.height), ((x1 - x0) as u32, (y1 - y0) as u32));
        for y in y0..y1 {
            for x in x0..x1 {
                for c in 0..3 {
                    assembled[((y * w + x) * 3 + c) as usize] =
                        piece.image.data[(((y - y0) * (x1 - x0) + (x - x0)) * 3 + c) as usize];
                }
            }
        }
    }
    assert_same(&assembled, &one.image.data, "crops assembled from pieces");
}

/// Bit-identical value arrays; on failure, how many differ and where (not the whole arrays).
pub fn assert_same(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let diff: Vec<usize> = (0..a.len()).filter(|&i| a[i].to_bits() != b[i].to_bits()).collect();
    assert!(
        diff.is_empty(),
        "{what}: {} of {} values differ; first at {} ({} vs {})",
        diff.len(),
        a.len(),
        diff[0],
        a[diff[0]],
        b[diff[0]]
    );
}

/// Asserts that a render matches a pbrt-v3 reference up to the noise of both: the image mean
/// within `mean_tol` (relative), mean z² < 1.5 and fewer than 0.5 % of values beyond 5σ, where
/// each value's variance is our per-pixel sample variance × (1 + `ref_var_ratio`, the
/// reference's variance relative to ours). A pixel whose samples all agree has a sample
/// variance of 0 even when a sliver of it (an emitter's edge) differs: a rare event at this
/// sample count that its neighbours' variance does show. So each value's variance is the
/// largest of its 3×3 neighbourhood (same channel), plus floors of 0.2 % of the image mean and
/// of the value itself (float accumulation). Prints the figures under `label`.
pub fn assert_matches_reference(label: &str, ours: &Render, reference: &Image, ref_var_ratio: f64, mean_tol: f64) {
    assert!(ours.image.data.iter().all(|v| v.is_finite()), "{label}: non-finite values");
    let (w, h) = (reference.width as usize, reference.height as usize);
    assert_eq!((ours.image.width as usize, ours.image.height as usize), (w, h), "{label}: image sizes");
    let local_var = |i: usize| {
        let (c, px) = (i % 3, i / 3);
        let (x, y) = ((px % w) as i64, (px / w) as i64);
        let mut v = 0.0f64;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                    v = v.max(ours.variance.data[(ny as usize * w + nx as usize) * 3 + c] as f64);
                }
            }
        }
        v
    };
    let floor_abs = 2e-3 * mean(reference);
    let mut z2 = 0.0;
    let mut outliers = 0;
    let mut worst = (0.0f64, 0usize);
    for (i, (o, r)) in ours.image.data.iter().zip(&reference.data).enumerate() {
        let var = local_var(i) * (1.0 + ref_var_ratio) + floor_abs.powi(2) + (2e-3 * *r as f64).powi(2);
        let z = (*o as f64 - *r as f64) / var.sqrt();
        z2 += z * z;
        if z.abs() > 5.0 {
            outliers += 1;
        }
        if z.abs() > worst.0 {
            worst = (z.abs(), i);
        }
    }
    let n = reference.data.len() as f64;
    let (m_ours, m_ref) = (mean(&ours.image), mean(reference));
    let rel = m_ours / m_ref - 1.0;
    let (mean_z2, outliers) = (z2 / n, outliers as f64 / n);
    let wi = worst.1;
    eprintln!(
        "{label}: mean {m_ours:.6} vs pbrt-v3 {m_ref:.6} ({:+.4}%), RMSE {:.3e}, mean z² {mean_z2:.3}, \
         beyond 5σ {:.3}%, worst z {:.1} at value {wi} ({} vs {})",
        rel * 100.0,
        rmse(&ours.image, reference),
        outliers * 100.0,
        worst.0,
        ours.image.data[wi],
        reference.data[wi]
    );
    assert!(rel.abs() < mean_tol, "{label}: image mean differs by {:.3}% from pbrt-v3", rel * 100.0);
    assert!(mean_z2 < 1.5, "{label}: differences exceed the noise (mean z² = {mean_z2:.3})");
    assert!(outliers < 0.005, "{label}: {:.2}% of values beyond 5σ", outliers * 100.0);
}

/// Asserts that the means of `block`×`block` pixel regions, per channel, agree with the
/// reference's within 5σ of both images' noise (our per-pixel variances summed: pixels are
/// independent; the reference's as `ref_var_ratio` of ours) beyond 0.5 % of the region's mean
/// (`penumbra_core::agreement::test_regions`). A bias confined to a dim region (a quarter of the
/// image 8 % too bright) hides in the image mean and in per-value z-scores, not in its regions'
/// means. Returns the largest |z|.
pub fn assert_regions_match(label: &str, ours: &Render, reference: &Image, ref_var_ratio: f64, block: usize) -> f64 {
    use penumbra_core::agreement::{blocks, test_regions, worst, NoisyImage, RefNoise, Tolerance};
    let (w, h) = (reference.width as usize, reference.height as usize);
    let test =
        NoisyImage { width: w, height: h, channels: 3, mean: &ours.image.data, variance: Some(&ours.variance.data) };
    let refi = NoisyImage { width: w, height: h, channels: 3, mean: &reference.data, variance: None };
    let tests = test_regions(
        &test,
        &refi,
        RefNoise::ScaledTest(ref_var_ratio),
        Tolerance { rel: 5e-3, abs: 0.0 },
        &blocks(w, h, 3, block),
    );
    let t = worst(&tests).expect("regions");
    let (z, r) = (t.z.abs(), t.region);
    eprintln!(
        "{label}: {block}x{block} regions, worst |z| {z:.2} at ({}, {}) channel {:?}: {:.5} vs pbrt-v3 {:.5}",
        r.x0, r.y0, r.channel, t.test, t.reference
    );
    assert!(
        z < 5.0,
        "{label}: region at ({}, {}) channel {:?}: {} vs pbrt-v3 {} (|z| = {z:.1})",
        r.x0,
        r.y0,
        r.channel,
        t.test,
        t.reference
    );
    z
}

/// A test that cannot run here (a tool or `../shared` is missing) skips loudly outside CI and
/// fails in CI (`.ci/run` sets `CI`), so a CI run can never pass by not testing.
pub fn skip_or_fail_in_ci(why: &str) {
    if std::env::var_os("CI").is_some() {
        panic!("{why}: required in CI (the CI environment variable is set)");
    }
    eprintln!("\n*** SKIPPED: {why} (this would fail in CI) ***\n");
    println!("SKIPPED: {why}");
}

/// A fresh temporary directory for one CLI test (`tag` names it; the process id keeps test
/// binaries apart).
pub fn cli_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-cli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the `penumbra` binary in `cwd`.
pub fn penumbra(cwd: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .current_dir(cwd)
        .args(args)
        .output()
        .expect("run penumbra")
}

pub fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
