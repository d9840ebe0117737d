//! Shards (`render --tile I/N`, `--spp-offset K`) and `penumbra merge`: for every registered
//! integrator, shards of a crop merged are the single render bit for bit; missing, duplicated
//! and foreign shards are refused by name; sample ranges add up to the single render at the
//! summed count where integrator and sampler allow it, and are refused where they do not.

mod common;
use common::*;
use penumbra::pipeline::{self, RenderOptions};
use penumbra::shard::{self, Shard, ShardRequest};
use penumbra_core::scene::{BuildOptions, Crop};
use penumbra_core::shard_rects::TileLayout;
use penumbra_integrators::REGISTRY;
use penumbra_parser::{DiagSink, SceneDescription};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::AtomicBool;

const RES: (u32, u32) = (40, 36);
/// Off the tile grid on every side: tiles of 16 clipped to 3..37 × 2..35 are uneven.
const CROP: Crop = Crop::Pixels([3, 37, 2, 35]);

fn desc(path: &Path) -> SceneDescription {
    penumbra_parser::parse_file(path).unwrap_or_else(|e| panic!("{e}")).scene
}

/// Runs `f` with the options every render of these tests shares.
fn with_opts<R>(integrator: &str, spp: u32, f: impl FnOnce(&RenderOptions, &DiagSink) -> R) -> R {
    with_params(integrator, &[], spp, f)
}

/// [`with_opts`] with command-line parameters `params` (`key=value`).
fn with_params<R>(integrator: &str, params: &[&str], spp: u32, f: impl FnOnce(&RenderOptions, &DiagSink) -> R) -> R {
    let cancel = AtomicBool::new(false);
    let warnings = DiagSink::new();
    let params: Vec<_> = params.iter().map(|p| penumbra::cli_params::parse_param(p).unwrap()).collect();
    let opts = RenderOptions {
        integrator: Some(integrator),
        params: &params,
        build: BuildOptions { spp: Some(spp), seed: 3, crop: Some(CROP), resolution: Some(RES) },
        threads: 2,
        with_variance: false,
        cancel: &cancel,
        progress: None,
    };
    f(&opts, &warnings)
}

fn single(d: &SceneDescription, integrator: &str, spp: u32) -> Vec<f32> {
    with_opts(integrator, spp, |o, w| pipeline::render(d, o, w).unwrap_or_else(|e| panic!("{e}")).image.data)
}

fn shard_of(d: &SceneDescription, integrator: &str, spp: u32, req: ShardRequest) -> Result<Shard, String> {
    with_opts(integrator, spp, |o, w| shard::render_shard(d, "test", o, req, w).map_err(|e| e.to_string()))
}

fn req(index: u32, count: u32, layout: TileLayout, spp_offset: Option<u32>) -> ShardRequest {
    ShardRequest { index, count, layout, spp_offset }
}

/// Merges shards after a trip through their file format.
fn merged(shards: Vec<Shard>) -> Result<Vec<f32>, String> {
    let named: Vec<(String, Shard)> = shards
        .into_iter()
        .enumerate()
        .map(|(i, s)| (format!("s{i}.shard"), Shard::from_bytes(&s.to_bytes()).unwrap()))
        .collect();
    shard::merge(&named).map(|m| m.film.to_image(false).data)
}

#[test]
fn every_integrator_merges_to_the_single_render_bit_for_bit() {
    let d = desc(&scene("suite/ltc/two-lights-metal.pbrt"));
    for e in REGISTRY {
        let one = single(&d, e.name, 2);
        for (n, layout) in [(1, TileLayout::Rows), (3, TileLayout::Rows), (7, TileLayout::Rows), (3, TileLayout::Grid)]
        {
            let shards: Vec<Shard> =
                (0..n).map(|i| shard_of(&d, e.name, 2, req(i, n, layout, None)).unwrap()).collect();
            assert_same(&merged(shards).unwrap(), &one, &format!("{}: {n} shards, {layout:?}", e.name));
        }
    }
}

/// Sample ranges 0..2, 2..3, 3..6 (and, combined with them, 3 tiles) merge to the 6-spp
/// render for the integrators that allow ranges; the others refuse `--spp-offset`.
#[test]
fn sample_ranges_add_up_to_the_single_render_where_allowed() {
    let d = desc(&scene("suite/ltc/two-lights-metal.pbrt")); // halton, box filter
    for e in REGISTRY {
        let first = shard_of(&d, e.name, 2, req(0, 1, TileLayout::Rows, Some(0)));
        let allowed = penumbra_integrators::find(e.name)
            .map(|f| (f.create)(&Default::default(), &DiagSink::new()).unwrap().merges_sample_ranges())
            .unwrap();
        if !allowed {
            let err = first.unwrap_err();
            assert!(err.contains("--spp-offset") && err.contains(e.name), "{}: {err}", e.name);
            continue;
        }
        let one = single(&d, e.name, 6);
        let mut shards = vec![first.unwrap()];
        shards.push(shard_of(&d, e.name, 1, req(0, 1, TileLayout::Rows, Some(2))).unwrap());
        shards.push(shard_of(&d, e.name, 3, req(0, 1, TileLayout::Rows, Some(3))).unwrap());
        assert_same(&merged(shards).unwrap(), &one, &format!("{}: ranges 0..2, 2..3, 3..6", e.name));
        if e.name == "directlighting" {
            let mut tiled = Vec::new();
            for i in 0..3 {
                for (k, n) in [(0, 2), (2, 4)] {
                    tiled.push(shard_of(&d, e.name, n, req(i, 3, TileLayout::Rows, Some(k))).unwrap());
                }
            }
            assert_same(&merged(tiled).unwrap(), &one, "directlighting: 3 tiles × ranges 0..2, 2..6");
        }
    }
}

/// The environment-lit paths (silhouette's SH tables, shexp's sphere sets and split lights)
/// keep sample ranges exact too (with sample shading: their pixel shading shares work between
/// a pixel's samples and refuses ranges).
#[test]
fn environment_lit_sample_ranges_add_up() {
    let d = desc(&scene("suite/env/objects-studio.pbrt")); // halton, box filter
    for (name, params) in [("silhouette", &["shading=sample"][..]), ("shexp", &["shading=sample"])] {
        let one = with_params(name, params, 3, |o, w| pipeline::render(&d, o, w).unwrap().image.data);
        let parts: Vec<Shard> = [(0, 1), (1, 2)]
            .iter()
            .map(|&(k, n)| {
                let req = req(0, 1, TileLayout::Rows, Some(k));
                with_params(name, params, n, |o, w| shard::render_shard(&d, "test", o, req, w)).unwrap()
            })
            .collect();
        assert_same(&merged(parts).unwrap(), &one, &format!("{name} on objects-studio: ranges 0..1, 1..3"));
    }
}

#[test]
fn samplers_whose_pattern_depends_on_the_count_refuse_sample_ranges() {
    let mut d = desc(&scene("suite/ltc/two-lights-metal.pbrt"));
    for (sampler, exact) in
        [("stratified", false), ("02sequence", false), ("maxmindist", false), ("random", true), ("sobol", true)]
    {
        d.sampler = penumbra_parser::Entity::default_of(sampler);
        let r = shard_of(&d, "ambientocclusion", 2, req(0, 1, TileLayout::Rows, Some(2)));
        match r {
            Ok(_) => assert!(exact, "{sampler} accepted --spp-offset"),
            Err(e) => assert!(!exact && e.contains(sampler) && e.contains("halton"), "{sampler}: {e}"),
        }
    }
    // Random and sobol ranges are exact too.
    for sampler in ["random", "sobol"] {
        d.sampler = penumbra_parser::Entity::default_of(sampler);
        let one = single(&d, "path", 8);
        let parts: Vec<Shard> =
            [0, 4].iter().map(|&k| shard_of(&d, "path", 4, req(0, 1, TileLayout::Rows, Some(k))).unwrap()).collect();
        assert_same(&merged(parts).unwrap(), &one, &format!("path, {sampler}: ranges 0..4, 4..8"));
    }
}

#[test]
fn missing_duplicated_and_foreign_shards_are_refused_by_name() {
    let d = desc(&scene("suite/ltc/two-lights-metal.pbrt"));
    let s: Vec<Shard> =
        (0..3).map(|i| shard_of(&d, "ambientocclusion", 1, req(i, 3, TileLayout::Rows, None)).unwrap()).collect();
    let named = |list: &[(&str, &Shard)]| -> Vec<(String, Shard)> {
        list.iter().map(|(n, s)| (n.to_string(), (*s).clone())).collect()
    };
    let err = |list: &[(&str, &Shard)]| shard::merge(&named(list)).err().expect("merge must fail");
    let e = err(&[("a.shard", &s[0]), ("c.shard", &s[2])]);
    assert!(e.contains("tile 1/3") && e.contains("missing"), "{e}");
    let e = err(&[("a.shard", &s[0]), ("b.shard", &s[1]), ("b2.shard", &s[1]), ("c.shard", &s[2])]);
    assert!(e.contains("b2.shard duplicates b.shard") || e.contains("b.shard duplicates b2.shard"), "{e}");
    let other_seed = with_opts("ambientocclusion", 1, |o, w| {
        let o = RenderOptions { build: BuildOptions { seed: 4, ..o.build }, ..*o };
        shard::render_shard(&d, "test", &o, req(1, 3, TileLayout::Rows, None), w).unwrap()
    });
    let e = err(&[("a.shard", &s[0]), ("x.shard", &other_seed), ("c.shard", &s[2])]);
    assert!(e.contains("x.shard is foreign") && e.contains("seed 4"), "{e}");
    let nsamples = [penumbra::cli_params::parse_param("nsamples=3").unwrap()];
    let other_params = with_opts("ambientocclusion", 1, |o, w| {
        let o = RenderOptions { params: &nsamples, build: BuildOptions { ..o.build }, ..*o };
        shard::render_shard(&d, "test", &o, req(1, 3, TileLayout::Rows, None), w).unwrap()
    });
    let e = err(&[("a.shard", &s[0]), ("p.shard", &other_params), ("c.shard", &s[2])]);
    assert!(e.contains("p.shard is foreign") && e.contains("nsamples=Int([3])"), "{e}");
    let other_scene = desc(&scene("suite/ltc/quad-cube.pbrt"));
    let foreign = shard_of(&other_scene, "ambientocclusion", 1, req(1, 3, TileLayout::Rows, None)).unwrap();
    let e = err(&[("a.shard", &s[0]), ("y.shard", &foreign), ("c.shard", &s[2])]);
    assert!(e.contains("y.shard is foreign") && e.contains("scene_hash"), "{e}");
    let mut bytes = s[0].to_bytes();
    bytes[100] ^= 1;
    assert!(Shard::from_bytes(&bytes).unwrap_err().contains("checksum"));
    assert!(Shard::from_bytes(&bytes[..bytes.len() - 9]).is_err());
}

/// The command line: `render --tile` shard files merge to the EXR `render` writes, byte for
/// byte, with the summed counters in `stats.json`; a missing shard is an error naming it.
#[test]
fn cli_shards_merge_to_the_same_file() {
    let exe = env!("CARGO_BIN_EXE_penumbra");
    let dir = std::env::temp_dir().join(format!("penumbra-shards-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let sc = scene("suite/ltc/two-lights-metal.pbrt");
    let base = ["render", sc.to_str().unwrap(), "-i", "directlighting", "--spp", "2", "--resolution", "40x36", "-q"];
    let run = |extra: &[&str]| {
        let out = Command::new(exe).args(base).args(extra).output().unwrap();
        assert!(out.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    run(&["-o", dir.join("single.exr").to_str().unwrap()]);
    let mut shards = Vec::new();
    for i in 0..3 {
        let p = dir.join(format!("s{i}.shard"));
        run(&["--tile", &format!("{i}/3"), "--tile-layout", "grid", "-o", p.to_str().unwrap()]);
        shards.push(p.to_str().unwrap().to_string());
    }
    let merge = |files: &[String]| {
        Command::new(exe)
            .arg("merge")
            .args(files)
            .args(["-o", dir.join("merged.exr").to_str().unwrap()])
            .output()
            .unwrap()
    };
    let out = merge(&shards);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(dir.join("single.exr")).unwrap(), std::fs::read(dir.join("merged.exr")).unwrap());
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("merged.stats.json")).unwrap()).unwrap();
    let single: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("single.stats.json")).unwrap()).unwrap();
    // (The box filter's sample bounds are the pixel bounds: no sample is taken twice.)
    assert_eq!(stats["camera_samples"], single["stats"]["camera_samples"]);
    assert_eq!(stats["rays"], single["stats"]["rays"]);
    assert_eq!(stats["merged_shards"], 3);
    let out = merge(&shards[..2]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("tile 2/3") && err.contains("missing"), "{err}");
    let bad = Command::new(exe).args(base).args(["--tile", "3/3"]).output().unwrap();
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("--tile expects I/N"));
    std::fs::remove_dir_all(&dir).ok();
}
