//! Machinery of the pbrt-v3 conformance matrix (`tests/conformance_matrix.rs` holds the
//! policy: which integrator runs where, its tolerance, the known failures): the cells
//! `tools/conformance.py` wrote, their pbrt-v3 references, the renders, the statistics
//! (`penumbra_core::agreement`) and the generated report.
#![allow(dead_code)]

use crate::common::root;
use penumbra::cli_params::parse_param;
use penumbra::pipeline::{self, RenderOptions};
use penumbra_core::agreement::{self, NoisyImage, RefNoise, Region, RegionTest, Tolerance};
use penumbra_core::image::{self, Image};
use penumbra_core::scene::BuildOptions;
use penumbra_parser::DiagSink;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Block size of the local tests (pixels).
pub const BLOCK: usize = 8;

pub fn dir() -> PathBuf {
    root().join("tests/conformance")
}

/// One cell of `tests/conformance/cells.tsv`.
#[derive(Debug, Clone)]
pub struct Cell {
    pub name: String,
    pub group: String,
    pub spp: u32,
    pub width: usize,
    pub height: usize,
    /// Reference kinds rendered for it: `direct`, `path`, `ao`.
    pub refs: Vec<String>,
    pub what: String,
}

impl Cell {
    /// `group/name`, what known-failure patterns match.
    pub fn key(&self) -> String {
        format!("{}/{}", self.group, self.name)
    }
    pub fn has_ref(&self, kind: &str) -> bool {
        self.refs.iter().any(|r| r == kind)
    }
}

pub fn cells() -> Vec<Cell> {
    let text = std::fs::read_to_string(dir().join("cells.tsv")).expect("tests/conformance/cells.tsv");
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            assert!(f.len() >= 7, "cells.tsv: {l}");
            Cell {
                name: f[0].into(),
                group: f[1].into(),
                spp: f[2].parse().expect("spp"),
                width: f[3].parse().expect("width"),
                height: f[4].parse().expect("height"),
                refs: f[5].split(',').map(String::from).collect(),
                what: f[6].into(),
            }
        })
        .collect()
}

/// A pbrt-v3 reference and the samples each of its pixels averages (`timings.tsv`).
pub struct Reference {
    pub image: Image,
    pub samples: f64,
}

/// Samples per pixel of every reference, by (cell, kind).
pub fn reference_samples() -> BTreeMap<(String, String), f64> {
    let text = std::fs::read_to_string(dir().join("timings.tsv")).unwrap_or_default();
    text.lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            Some(((f.first()?.to_string(), f.get(1)?.to_string()), f.get(2)?.parse().ok()?))
        })
        .collect()
}

/// The sample count pbrt-v3 rendered `cell`'s `kind` reference with (`pbrt_spp` in
/// timings.tsv: per pixel of its own, possibly doubled, resolution).
pub fn reference_pbrt_spp(cell: &Cell, kind: &str) -> Option<u32> {
    let text = std::fs::read_to_string(dir().join("timings.tsv")).ok()?;
    text.lines().skip(1).find_map(|l| {
        let f: Vec<&str> = l.split('\t').collect();
        (f.first() == Some(&cell.name.as_str()) && f.get(1) == Some(&kind)).then(|| f.get(4)?.parse().ok())?
    })
}

pub fn reference(cell: &Cell, kind: &str, samples: &BTreeMap<(String, String), f64>) -> Option<Reference> {
    let path = dir().join("ref").join(format!("{}.{kind}.pfm", cell.name));
    let img = image::read(&path).ok()?;
    let n = *samples.get(&(cell.name.clone(), kind.to_string()))?;
    Some(Reference { image: img.select_channels(&["R", "G", "B"]).ok()?, samples: n })
}

/// One render of a cell: RGB, the variance of each pixel's mean, the warnings.
pub struct Shot {
    pub rgb: Vec<f32>,
    pub var: Vec<f32>,
    pub warnings: Vec<String>,
    pub spp: u32,
    pub seconds: f64,
}

/// Seconds one render may take before it is cancelled and recorded as timed out (a failure
/// unless known): 5× the slowest run that finishes on a loaded 2-core machine (11 s), so that
/// one pathological case cannot hold the whole matrix up.
pub const BUDGET_SECONDS: f64 = 60.0;

/// Renders `cell` with `integrator` and `params` at `spp` and 1/`shrink` of its resolution (1
/// thread: cells run in parallel), its ray differentials scaled as for `footprint_spp` samples
/// per pixel at the cell's resolution (the reference's: pbrt-v3 filters textures over 1/√spp of
/// a pixel, so a render at another count or resolution filters them differently). `Err`
/// starting "timed out" after [`BUDGET_SECONDS`].
pub fn shoot(
    cell: &Cell,
    integrator: &str,
    params: &[&str],
    spp: u32,
    shrink: usize,
    footprint_spp: f64,
) -> Result<Shot, String> {
    let path = dir().join(format!("{}.pbrt", cell.name));
    let parsed = penumbra_parser::parse_file(&path).map_err(|e| format!("{e}"))?;
    let warnings = DiagSink::new();
    let params: Vec<_> = params.iter().map(|p| parse_param(p).expect("param")).collect();
    let cancel = AtomicBool::new(false);
    let opts = RenderOptions {
        integrator: Some(integrator),
        params: &params,
        build: BuildOptions {
            spp: Some(spp),
            seed: 0,
            crop: None,
            resolution: (shrink > 1).then(|| ((cell.width / shrink) as u32, (cell.height / shrink) as u32)),
        },
        threads: 1,
        with_variance: true,
        cancel: &cancel,
        progress: None,
    };
    let t0 = std::time::Instant::now();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let r = std::thread::scope(|s| {
        let cancel = &cancel;
        s.spawn(move || {
            if done_rx.recv_timeout(std::time::Duration::from_secs_f64(BUDGET_SECONDS)).is_err() {
                cancel.store(true, Ordering::Relaxed);
            }
        });
        let r = render(&parsed.scene, &opts, footprint_spp * (shrink * shrink) as f64, &warnings);
        let _ = done_tx.send(());
        r
    });
    let seconds = t0.elapsed().as_secs_f64();
    if cancel.load(Ordering::Relaxed) {
        return Err(format!("timed out after {seconds:.0} s"));
    }
    let (image, stats) = r.map_err(|e| format!("{e}"))?;
    let r = Rendered { image, stats };
    let rgb = r.image.select_channels(&["R", "G", "B"]).map_err(|e| format!("{e}"))?;
    let var = r.image.select_channels(&["variance.R", "variance.G", "variance.B"]).map_err(|e| format!("{e}"))?;
    assert_eq!(
        (rgb.width as usize * shrink, rgb.height as usize * shrink),
        (cell.width, cell.height),
        "{}: film size",
        cell.name
    );
    let mut msgs: Vec<String> = parsed.warnings.iter().map(|d| d.message.clone()).collect();
    msgs.extend(warnings.take().iter().map(|d| d.message.clone()));
    msgs.retain(|m| !m.contains("unused by"));
    msgs.sort();
    msgs.dedup();
    Ok(Shot { rgb: rgb.data, var: var.data, warnings: msgs, spp: r.stats.spp, seconds })
}

struct Rendered {
    image: Image,
    stats: penumbra_core::integrator::RenderStats,
}

/// `pipeline::render` with the camera's differentials scaled for `footprint_spp`.
fn render(
    desc: &penumbra_parser::SceneDescription,
    opts: &RenderOptions,
    footprint_spp: f64,
    warnings: &DiagSink,
) -> Result<(Image, penumbra_core::integrator::RenderStats), pipeline::PipelineError> {
    let (integrator, mut scene) = pipeline::prepare(desc, opts, warnings)?;
    scene.camera.footprint_spp = Some(footprint_spp.round() as u32);
    let (film, stats) = pipeline::render_film(integrator.as_ref(), &scene, scene.film.clone(), opts, warnings)?;
    Ok((film.to_image(opts.with_variance), stats))
}

/// What one (cell, integrator) run measured.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub cell: String,
    pub key: String,
    pub run: String,
    /// `Err`: the render was refused (its message).
    pub result: Result<Measure, String>,
    pub warnings: Vec<String>,
    pub seconds: f64,
}

#[derive(Debug, Clone)]
pub struct Measure {
    /// Relative error of the image mean, the channel with the largest |error| (signed).
    pub mean_err: f64,
    /// Largest |error| of an 8×8 block mean, relative to the larger of the block's and the
    /// channel's reference mean (so that dark blocks do not dominate).
    pub block_err: f64,
    /// The region tests: blocks, then whole channels.
    pub tests: Vec<RegionTest>,
}

/// Differences of a block mean below this fraction of its channel's image mean (at least 1e-3 of
/// the image's mean over all channels) are not tested:
/// such a block moves the image mean by less than 1/16 of it, and a dim block's relative error
/// means nothing (a single rare high-energy path in one reference pixel of a block at 1e-4 of
/// the image mean shifts it by several percent).
pub const BLOCK_FLOOR: f64 = 1e-3;

/// Compares a render with a reference of its size (blocks of `block` pixels): whole channels
/// against `mean_tol`, blocks against `block_tol` (relative) plus [`BLOCK_FLOOR`], each beyond its
/// tolerance in units of both images' noise (the reference's `variance`: each value's).
pub fn measure(shot: &Shot, refi: &NoisyImage, mean_tol: f64, block_tol: f64, block: usize) -> Measure {
    let (w, h) = (refi.width, refi.height);
    let test = NoisyImage { width: w, height: h, channels: 3, mean: &shot.rgb, variance: Some(&shot.var) };
    let refi = *refi;
    // The reference's mean over all channels: the scale of the floors below.
    let all = refi.mean.iter().map(|v| *v as f64).sum::<f64>() / refi.mean.len().max(1) as f64;
    // A channel pbrt-v3 renders black comes back as ~1e-9 from its film's RGB→XYZ→RGB round
    // trip: whole-channel differences below 1e-5 of the image's mean are rounding.
    let whole = agreement::whole(w, h, 3);
    let wt = agreement::test_regions(
        &test,
        &refi,
        RefNoise::Own,
        Tolerance { rel: mean_tol, abs: 1e-5 * all.abs() },
        &whole,
    );
    let scale = |c: usize| wt[c].reference.abs().max(1e-3 * all.abs());
    let mut tests = Vec::new();
    for b in agreement::blocks(w, h, 3, block) {
        let floor = BLOCK_FLOOR * scale(b.channel.unwrap_or(0));
        tests.extend(agreement::test_regions(
            &test,
            &refi,
            RefNoise::Own,
            Tolerance { rel: block_tol, abs: floor },
            &[b],
        ));
    }
    let mut mean_err = 0.0f64;
    for (c, t) in wt.iter().enumerate() {
        let e = rel(t.test - t.reference + scale(c), scale(c));
        if e.abs() > mean_err.abs() || e.is_nan() {
            mean_err = e;
        }
    }
    let mut block_err = 0.0f64;
    for t in &tests {
        let c = t.region.channel.unwrap_or(0);
        let s = t.reference.abs().max(scale(c));
        let e = rel(t.test - t.reference + s, s).abs();
        if !(e <= block_err) {
            block_err = e;
        }
    }
    tests.extend(wt);
    Measure { mean_err, block_err, tests }
}

fn rel(a: f64, b: f64) -> f64 {
    if b != 0.0 {
        (a - b) / b.abs()
    } else if a == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// The variance of each reference value: `var` (a penumbra render of the reference's own
/// estimator at `spp` samples per pixel) scaled to the reference's `samples`.
pub fn scaled_variance(var: &[f32], spp: u32, samples: f64) -> Vec<f32> {
    let k = spp as f64 / samples;
    var.iter().map(|v| (*v as f64 * k) as f32).collect()
}

/// `img` (`w`×`h`, 3 channels) box-downsampled by `k` (each output value the mean of k×k);
/// with `variance`, the variance of that mean (the sum of the k² variances over k⁴).
pub fn shrink(img: &[f32], w: usize, h: usize, k: usize, variance: bool) -> Vec<f32> {
    if k == 1 {
        return img.to_vec();
    }
    let (ow, oh) = (w / k, h / k);
    let div = if variance { (k * k * k * k) as f64 } else { (k * k) as f64 };
    let mut out = vec![0.0f32; ow * oh * 3];
    for y in 0..oh {
        for x in 0..ow {
            for c in 0..3 {
                let mut s = 0.0f64;
                for dy in 0..k {
                    for dx in 0..k {
                        s += img[((y * k + dy) * w + x * k + dx) * 3 + c] as f64;
                    }
                }
                out[(y * ow + x) * 3 + c] = (s / div) as f32;
            }
        }
    }
    out
}

/// Runs `jobs` on all cores, each job one closure; results in job order.
pub fn parallel<T: Send>(n: usize, job: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<T>>> = Mutex::new((0..n).map(|_| None).collect());
    let workers = std::thread::available_parallelism().map_or(2, |p| p.get()).min(n.max(1));
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= n {
                    break;
                }
                let r = job(i);
                out.lock().unwrap()[i] = Some(r);
            });
        }
    });
    out.into_inner().unwrap().into_iter().map(|r| r.expect("job finished")).collect()
}

/// A `*`-glob match (`*` any run of characters).
pub fn glob(pattern: &str, s: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == s,
        Some((head, tail)) => {
            if !s.starts_with(head) {
                return false;
            }
            let rest = &s[head.len()..];
            (0..=rest.len()).filter(|&i| rest.is_char_boundary(i)).any(|i| glob(tail, &rest[i..]))
        }
    }
}

/// Formats a relative error in percent with two decimals and its sign.
pub fn pct(e: f64) -> String {
    if e.is_finite() {
        format!("{:+.2} %", e * 100.0)
    } else {
        format!("{e}")
    }
}

pub fn region_name(r: &Region) -> String {
    let c = ["R", "G", "B"][r.channel.unwrap_or(0).min(2)];
    format!("({}..{}, {}..{}) {c}", r.x0, r.x1, r.y0, r.y1)
}
