//! `penumbra sweep` end to end: a small directlighting sweep against a cached
//! `--reference-spp` reference, and the errors that must stop it before rendering.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn out_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-sweepcli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn sweep(args: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("sweep")
        .arg(root().join("scenes/suite/ltc/quad-cube.pbrt"))
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .expect("run penumbra")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

const ARGS: &[&str] =
    &["-i", "directlighting", "--reference-spp", "256", "--budgets", "1,4,16,64", "--resolution", "32x32"];

struct CsvRow {
    integrator: String,
    budget: u32,
    total_s: f64,
    rmse: f64,
}

fn parse_csv(csv: &str) -> Vec<CsvRow> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert_eq!(
        header,
        [
            "integrator",
            "budget",
            "build_s",
            "render_s",
            "total_s",
            "mae",
            "rmse",
            "psnr",
            "max_err",
            "relmse",
            "smape",
            "flip",
            "nan_count"
        ]
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), header.len(), "{l}");
            let num = |i: usize| f[i].parse::<f64>().unwrap_or_else(|_| panic!("column {} in {l}", header[i]));
            for i in [2, 3, 4, 5, 6, 7, 8, 9, 10] {
                assert!(num(i).is_finite() && num(i) >= 0.0, "{} in {l}", header[i]);
            }
            assert!(num(4) >= num(3), "total time below render time: {l}");
            assert_eq!(f[12], "0", "NaNs in {l}");
            CsvRow { integrator: f[0].to_string(), budget: f[1].parse().unwrap(), total_s: num(4), rmse: num(6) }
        })
        .collect()
}

#[test]
fn directlighting_sweep_with_cached_reference() {
    let out = out_dir("dl");
    let o = sweep(ARGS, &out);
    let (stdout, stderr) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{stdout}\n{stderr}");

    let rows = parse_csv(&std::fs::read_to_string(out.join("sweep.csv")).unwrap());
    assert_eq!(rows.len(), 4);
    assert!(rows.iter().all(|r| r.integrator == "directlighting"));
    assert_eq!(rows.iter().map(|r| r.budget).collect::<Vec<_>>(), [1, 4, 16, 64]);
    assert!(rows.iter().all(|r| r.total_s > 0.0));
    // Error falls with the budget: 64 spp well below 1 spp, and no step up by more than 10 %.
    assert!(rows[3].rmse < 0.5 * rows[0].rmse, "{} vs {}", rows[3].rmse, rows[0].rmse);
    for w in rows.windows(2) {
        assert!(w[1].rmse <= 1.1 * w[0].rmse, "rmse {} -> {}", w[0].rmse, w[1].rmse);
    }

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().map(|a| a.len()), Some(4));
    assert_eq!(json["complete"], true);
    assert_eq!(json["reference"]["spp"], 256);
    assert!(json["machine"]["threads"].as_u64().unwrap() >= 1);

    let png = std::fs::read(out.join("sweep.png")).unwrap();
    assert!(!png.is_empty());
    let img = penumbra_core::image::decode_png(&png, &out.join("sweep.png")).expect("valid PNG");
    assert!(img.width > 0 && img.height > 0);
    let svg = std::fs::read_to_string(out.join("sweep.svg")).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"), "{}", &svg[..svg.len().min(80)]);
    assert!(svg.contains("directlighting"));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("| directlighting |"), "{summary}");
    assert!(stdout.contains("| directlighting |"), "{stdout}");

    // The reference was rendered once and cached; a second run reuses it untouched.
    let cache: Vec<PathBuf> = std::fs::read_dir(out.join("cache")).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(cache.len(), 1, "{cache:?}");
    assert!(stderr.contains("rendering reference"), "{stderr}");
    let mtime = std::fs::metadata(&cache[0]).unwrap().modified().unwrap();
    let o2 = sweep(&ARGS.iter().map(|a| if *a == "1,4,16,64" { "1" } else { a }).collect::<Vec<_>>(), &out);
    let stderr2 = text(&o2.stderr);
    assert!(o2.status.success(), "{stderr2}");
    assert!(stderr2.contains("using cached reference"), "{stderr2}");
    assert_eq!(std::fs::metadata(&cache[0]).unwrap().modified().unwrap(), mtime);
    assert_eq!(parse_csv(&std::fs::read_to_string(out.join("sweep.csv")).unwrap()).len(), 1);
    let _ = std::fs::remove_dir_all(&out);
}

/// A `path` sweep against a `path` reference (`--reference-integrator`): error falls with the
/// budget towards the reference's own noise, where a directlighting reference would leave the
/// indirect light as a floor.
#[test]
fn path_sweep_against_a_path_reference() {
    let out = out_dir("path");
    let args = [
        "-i",
        "path",
        "--reference-spp",
        "512",
        "--reference-integrator",
        "path",
        "--budgets",
        "1,8,64",
        "--resolution",
        "24x24",
    ];
    let o = sweep(&args, &out);
    let (stdout, stderr) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stderr.contains("rendering reference: path at 512 spp"), "{stderr}");
    let rows = parse_csv(&std::fs::read_to_string(out.join("sweep.csv")).unwrap());
    assert_eq!(
        rows.iter().map(|r| (r.integrator.as_str(), r.budget)).collect::<Vec<_>>(),
        [("path", 1), ("path", 8), ("path", 64)]
    );
    assert!(rows[2].rmse < 0.4 * rows[0].rmse, "{} vs {}", rows[2].rmse, rows[0].rmse);
    assert!(stdout.contains("| path |"), "{stdout}");
    let bad = sweep(&["-i", "path", "--reference-spp", "4", "--reference-integrator", "nope"], &out);
    assert!(
        !bad.status.success() && text(&bad.stderr).contains("unknown reference integrator"),
        "{}",
        text(&bad.stderr)
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn errors_stop_before_rendering() {
    // Unknown integrator: rejected before anything is rendered or written.
    let out = out_dir("unknown");
    let o = sweep(&["-i", "directlighting,nosuch", "--reference-spp", "4", "--resolution", "8x8"], &out);
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(err.contains("unknown integrator \"nosuch\"") && err.contains("ambientocclusion"), "{err}");
    assert!(!out.exists());

    // Unreadable reference.
    let o = sweep(&["-i", "directlighting", "--reference", "/nonexistent/ref.exr"], &out);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("ref.exr"), "{}", text(&o.stderr));
    assert!(!out.exists());

    // A reference of another size: a clear error, no panic, no rows.
    let dir = out_dir("size");
    std::fs::create_dir_all(&dir).unwrap();
    let small = dir.join("ref.exr");
    let img = penumbra_core::image::Image::new(4, 4, penumbra_core::image::channel_names(&["R", "G", "B"])).unwrap();
    penumbra_core::image::write(&img, &small).unwrap();
    let o = sweep(&["-i", "directlighting", "--reference", small.to_str().unwrap(), "--resolution", "8x8"], &dir);
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert!(err.contains("the reference is 4x4 but the render is 8x8"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // Found before anything renders or is written: no empty tables, no summary.
    assert!(!err.contains("rendering"), "{err}");
    let written: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(written, vec![std::ffi::OsString::from("ref.exr")], "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--reference-spp` renders the first -i's natural reference: an AO sweep makes an AO reference.
#[test]
fn reference_integrator_defaults_to_the_first_integrators_natural_reference() {
    for (i, reference) in [("ambientocclusion", "ambientocclusion"), ("ltc,ambientocclusion", "directlighting")] {
        let out = out_dir(&format!("natural-{}", i.len()));
        let o = sweep(&["-i", i, "--reference-spp", "2", "--resolution", "8x8", "--budgets", "1"], &out);
        let err = text(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains(&format!("rendering reference: {reference} at 2 spp")), "-i {i}: {err}");
        let _ = std::fs::remove_dir_all(&out);
    }
}

/// `--plan`, every item run as its own process (in reverse order), then `--collect`: the
/// ordinary sweep's CSV rows, timing columns aside (ltc's coverage floor makes its budget-1
/// item a 16-spp render and its budget-4 and 16 items skips, as in the sweep).
#[test]
fn planned_items_collect_to_the_sweeps_rows() {
    let args = ["-i", "directlighting,ltc", "--reference-spp", "32", "--budgets", "1,4,16", "--resolution", "16x16"];
    let (plain, fanned) = (out_dir("plain"), out_dir("fanned"));
    let o = sweep(&args, &plain);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let with = |extra: &[&str]| {
        let mut a = args.to_vec();
        a.extend_from_slice(extra);
        sweep(&a, &fanned)
    };
    let o = with(&["--plan"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let n: usize = text(&o.stdout).trim().parse().unwrap();
    assert_eq!(n, 1 + 2 * 3, "the reference and 2 × 3 renders");
    let o = with(&["--collect"]);
    assert!(
        !o.status.success() && text(&o.stderr).contains("item 0 (the reference) has not run"),
        "{}",
        text(&o.stderr)
    );
    for k in (0..n).rev() {
        let o = with(&["--run-item", &k.to_string()]);
        assert!(o.status.success(), "item {k}: {}", text(&o.stderr));
    }
    let o = with(&["--collect"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let untimed = |dir: &Path| -> Vec<String> {
        let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
        parse_csv(&csv); // (checks the columns)
        csv.lines()
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                [&f[..2], &f[5..]].concat().join(",")
            })
            .collect()
    };
    let rows = untimed(&plain);
    // The header, directlighting's three budgets, ltc's one 16-spp render (4 and 16 are covered).
    assert_eq!(rows.len(), 1 + 3 + 1, "{rows:?}");
    assert_eq!(untimed(&fanned), rows);
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fanned.join("sweep.json")).unwrap()).unwrap();
    assert!(doc["items"][0]["machine"]["cores"].as_u64().unwrap() >= 1, "{}", doc["items"]);
    // Other arguments than the plan's are refused; so is --time-limit.
    let o = sweep(
        &[
            "-i",
            "directlighting",
            "--reference-spp",
            "32",
            "--budgets",
            "1",
            "--resolution",
            "16x16",
            "--run-item",
            "0",
        ],
        &fanned,
    );
    assert!(
        !o.status.success() && text(&o.stderr).contains("give the arguments --plan was given"),
        "{}",
        text(&o.stderr)
    );
    let o = with(&["--plan", "--time-limit", "5"]);
    assert!(!o.status.success() && text(&o.stderr).contains("--time-limit"), "{}", text(&o.stderr));
    let _ = std::fs::remove_dir_all(&plain);
    let _ = std::fs::remove_dir_all(&fanned);
}

/// The cached `--reference-spp` reference belongs to the scene as a whole: editing a file the
/// scene includes, or a PLY mesh it names, makes the next sweep render a new reference instead
/// of reusing the stale one (the cache key is the scene identity shards use too).
#[test]
fn editing_an_included_file_or_a_mesh_invalidates_the_cached_reference() {
    let dir = out_dir("identity");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("main.pbrt");
    std::fs::write(
        &scene,
        "LookAt 0 4 -6  0 0.5 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
         Sampler \"halton\" \"integer pixelsamples\" [ 4 ]\nWorldBegin\n\
         AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 8 8 8 ]\n  Shape \"trianglemesh\" \
         \"integer indices\" [ 0 1 2 0 2 3 ] \"point P\" [ -1 3 -1 1 3 -1 1 3 1 -1 3 1 ]\nAttributeEnd\n\
         Include \"objects.pbrt\"\nWorldEnd\n",
    )
    .unwrap();
    let objects = |kd: f32| {
        format!(
            "Material \"matte\" \"rgb Kd\" [ {kd} {kd} {kd} ]\nShape \"plymesh\" \"string filename\" \"floor.ply\"\n"
        )
    };
    let ply = |y: f32| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             element face 2\nproperty list uchar int vertex_indices\nend_header\n\
             -4 {y} -4\n4 {y} -4\n4 {y} 4\n-4 {y} 4\n3 0 2 1\n3 0 3 2\n"
        )
    };
    std::fs::write(dir.join("objects.pbrt"), objects(0.5)).unwrap();
    std::fs::write(dir.join("floor.ply"), ply(0.0)).unwrap();
    let out = dir.join("out");
    let run = || {
        let o = Command::new(env!("CARGO_BIN_EXE_penumbra"))
            .arg("sweep")
            .arg(&scene)
            .args(["-i", "directlighting", "--reference-spp", "4", "--budgets", "1", "--resolution", "8x8", "-o"])
            .arg(&out)
            .output()
            .expect("run penumbra");
        let stderr = text(&o.stderr);
        assert!(o.status.success(), "{}\n{stderr}", text(&o.stdout));
        let cached = std::fs::read_dir(out.join("cache")).unwrap().count();
        (stderr.contains("using cached reference"), cached)
    };
    assert_eq!(run(), (false, 1), "the first sweep renders its reference");
    assert_eq!(run(), (true, 1), "an unchanged scene reuses it");
    std::fs::write(dir.join("objects.pbrt"), objects(0.25)).unwrap();
    assert_eq!(run(), (false, 2), "an edited include renders a new one");
    std::fs::write(dir.join("floor.ply"), ply(-0.5)).unwrap();
    assert_eq!(run(), (false, 3), "an edited mesh renders a new one");
    assert_eq!(run(), (true, 3));
    let _ = std::fs::remove_dir_all(&dir);
}
