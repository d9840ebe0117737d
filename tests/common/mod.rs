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
    }
}

pub fn mean(img: &Image) -> f64 {
    img.data.iter().map(|v| *v as f64).sum::<f64>() / img.data.len() as f64
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
