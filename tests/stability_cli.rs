//! `penumbra stability` end to end: every registered integrator is stable under scale and
//! rotation on a stiff scene (this is CI's stability run), and the deliberately unstable
//! hidden integrator (a fixed absolute ray epsilon) is flagged by the scale and translation
//! variants while the same estimator with pbrt's error-bounded offsets is not.

use penumbra_integrators::{ambientocclusion::FIXED_EPSILON_NAME, REGISTRY};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn out_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-stabilitycli-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn stability(scene: &str, args: &[&str], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .arg("stability")
        .arg(root().join(scene))
        .args(args)
        .arg("-o")
        .arg(out)
        .args(["--json", "-q"])
        .output()
        .expect("run penumbra")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The JSON on stdout, which must equal `stability.json`; with the outputs checked to exist.
fn report(o: &Output, out: &Path) -> Value {
    let v: Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}):\n{}\n{}", text(&o.stdout), text(&o.stderr)));
    let file: Value = serde_json::from_str(&std::fs::read_to_string(out.join("stability.json")).unwrap()).unwrap();
    assert_eq!(v, file, "--json prints stability.json");
    assert!(std::fs::read_to_string(out.join("summary.md")).unwrap().contains("| integrator | variant |"));
    let png = std::fs::read(out.join("contact.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    v
}

fn row<'a>(v: &'a Value, integrator: &str, variant: &str) -> &'a Value {
    v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["integrator"] == integrator && r["variant"] == variant)
        .unwrap_or_else(|| panic!("no row {integrator} {variant}"))
}

fn max_z(r: &Value) -> f64 {
    r["max_z"].as_f64().unwrap_or_else(|| panic!("max_z of {r}"))
}

/// Every registered integrator, the base and three variants of `stiff/grazing-light` (light
/// nearly coplanar with the floor) at 24², 4 spp: no non-finite or negative pixel, nothing
/// above a declared bound, and the scaled and rotated images within z = 8 of the base
/// (measured, with the base's variance pooled over 3 × 3 pixels: largest |z| 1.53, ratio
/// rotated; path rotated 0.92; every other row ≤ 1).
#[test]
fn every_integrator_is_stable_under_scale_and_rotation() {
    let out = out_dir("all");
    let names: Vec<&str> = REGISTRY.iter().map(|e| e.name).collect();
    let list = names.join(",");
    let args = ["-i", &list, "--variants", "scale,rotate", "--resolution", "24x24", "--spp", "4"];
    let o = stability("scenes/suite/stiff/grazing-light.pbrt", &args, &out);
    let v = report(&o, &out);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", text(&o.stdout), text(&o.stderr));
    assert_eq!(v["status"], "STABLE");
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), names.len() * 4);
    for r in rows {
        for key in ["nonfinite", "negative"] {
            assert_eq!(r[key], 0, "{r}");
        }
        assert!(r["above_bound"].is_null() || r["above_bound"] == 0, "{r}");
        assert!(r["seconds"].as_f64().unwrap() > 0.0, "{r}");
        if r["variant"] != "base" {
            let z = max_z(r);
            eprintln!("{} {}: max |z| {z:.2e}", r["integrator"], r["variant"]);
            assert!(z <= 8.0, "{r}");
        }
    }
    // The bounds are checked where declared: ltc (its unshadowed render) and ambientocclusion (π).
    for n in ["ltc", "ambientocclusion"] {
        assert_eq!(row(&v, n, "rotate")["above_bound"], 0);
    }
    assert!(row(&v, "directlighting", "rotate")["above_bound"].is_null());
    std::fs::remove_dir_all(&out).ok();
}

/// Scale alone on three more stiff scenes (coincident faces and zero-area triangles, occluders
/// piercing the floor, a light standing on it) at 16², 4 spp: every registered integrator
/// within z = 8 of the base at 1e-4 and 1e4 (measured: largest |z| 0.66, 8.5e-3 and 2.0e-2).
#[test]
fn every_integrator_is_scale_invariant_on_stiff_scenes() {
    let names: Vec<&str> = REGISTRY.iter().map(|e| e.name).collect();
    let list = names.join(",");
    for scene in ["coincident-geometry", "intersecting-occluders", "light-touching-floor"] {
        let out = out_dir(scene);
        let args = ["-i", &list, "--variants", "scale", "--resolution", "16x16", "--spp", "4"];
        let o = stability(&format!("scenes/suite/stiff/{scene}.pbrt"), &args, &out);
        let v = report(&o, &out);
        assert_eq!(o.status.code(), Some(0), "{scene}: {}\n{}", text(&o.stdout), text(&o.stderr));
        let rows = v["rows"].as_array().unwrap();
        assert_eq!(rows.len(), names.len() * 3);
        let worst = rows.iter().filter(|r| r["variant"] != "base").map(max_z).fold(0.0, f64::max);
        eprintln!("{scene}: largest |z| {worst:.2e}");
        assert!(worst <= 8.0, "{scene}: {worst}");
        std::fs::remove_dir_all(&out).ok();
    }
}

/// A fixed ray epsilon of 1e-3 steps over the contact occluders of a scene scaled by 1e-4 and
/// is below the rounding of hit points 1e4 extents from the origin: both are flagged (exit 1),
/// while ambientocclusion, the same estimator with pbrt's offsets, stays within the noise
/// (measured at 24², 16 AO samples: largest |z| 3.2e-6 vs 13.4 scaled, 1.0 vs 46 moved).
#[test]
fn a_fixed_ray_epsilon_is_flagged_by_scale_and_translation() {
    let out = out_dir("eps");
    let list = format!("ambientocclusion,{FIXED_EPSILON_NAME}");
    let args = [
        "-i",
        &list,
        "--variants",
        "scale-1e-4,translate",
        "--translations",
        "1e4",
        "--fail-on",
        "z=8,far=1e4",
        "--resolution",
        "24x24",
        "--param",
        "nsamples=16",
    ];
    let o = stability("scenes/suite/stiff/intersecting-occluders.pbrt", &args, &out);
    let v = report(&o, &out);
    assert_eq!(o.status.code(), Some(1), "{}\n{}", text(&o.stdout), text(&o.stderr));
    for variant in ["scale-1e-4", "translate-1e4"] {
        let good = row(&v, "ambientocclusion", variant);
        let bad = row(&v, FIXED_EPSILON_NAME, variant);
        eprintln!("{variant}: max |z| {} (pbrt offsets) vs {} (fixed epsilon)", max_z(good), max_z(bad));
        assert_eq!(good["fails"].as_array().unwrap().len(), 0, "{good}");
        assert!(bad["fails"].as_array().unwrap().iter().any(|f| f == "z"), "{bad}");
        assert!(max_z(bad) > 10.0 * max_z(good).max(1.0), "{bad}");
    }
    // The translation's distance is reported in world units: 1e4 scene extents.
    let extent = v["extent"].as_f64().unwrap();
    let d = row(&v, FIXED_EPSILON_NAME, "translate-1e4")["distance"].as_f64().unwrap();
    assert!((d / (1e4 * extent) - 1.0).abs() < 1e-9, "{d} vs {extent}");
    std::fs::remove_dir_all(&out).ok();
}

/// Bad option values are errors with diff's code 4, before anything renders.
#[test]
fn bad_options_exit_4() {
    let out = out_dir("bad");
    // An unknown integrator name is a usage error (64) in every subcommand, with the nearest
    // name suggested (tests/cli_new_user.rs).
    let o = stability("scenes/suite/stiff/grazing-light.pbrt", &["-i", "nope"], &out);
    assert_eq!(o.status.code(), Some(64), "{}", text(&o.stderr));
    for args in [
        &["-i", "ltc", "--fail-on", "zz=1"][..],
        &["-i", "ltc", "--variants", "spin"][..],
        &["-i", "ltc", "--scales", "0"][..],
    ] {
        let o = stability("scenes/suite/stiff/grazing-light.pbrt", args, &out);
        assert_eq!(o.status.code(), Some(4), "{args:?}: {}", text(&o.stderr));
        assert!(text(&o.stderr).starts_with("error: "), "{}", text(&o.stderr));
    }
    assert!(!out.join("stability.json").exists());
    std::fs::remove_dir_all(&out).ok();
}

/// Two public scenes (the Cornell box; yar's triangle light hanging 0.03 above a floor, facing
/// it) at 24², 4 spp, every registered integrator scaled by 1e±4 and turned: all within z = 8
/// of the base, nothing non-finite or negative. The triangle light caught `ltc` and `ratio`
/// lighting the light's own top face by itself (its points lie in the light's plane, on either
/// side by rounding: largest |z| 5.6e7, relative RMSE 2–6 between the variants); measured now:
/// largest |z| 3.6 (Cornell box) and 1.2 (triangle light).
#[test]
fn every_integrator_is_stable_on_public_scenes() {
    let names: Vec<&str> = REGISTRY.iter().map(|e| e.name).collect();
    let list = names.join(",");
    for scene in ["wumpf-lightdam/scenes/cornell-box/scene", "kennyalive-yar-test-scenes/triangle_light"] {
        let out = out_dir(scene.rsplit('/').next().unwrap());
        let args = ["-i", &list, "--variants", "scale,rotate", "--resolution", "24x24", "--spp", "4"];
        let o = stability(&format!("scenes/public/{scene}.pbrt"), &args, &out);
        let v = report(&o, &out);
        assert_eq!(o.status.code(), Some(0), "{scene}: {}\n{}", text(&o.stdout), text(&o.stderr));
        let rows = v["rows"].as_array().unwrap();
        assert_eq!(rows.len(), names.len() * 4);
        for r in rows {
            assert_eq!((r["nonfinite"].as_u64(), r["negative"].as_u64()), (Some(0), Some(0)), "{scene}: {r}");
        }
        let worst = rows.iter().filter(|r| r["variant"] != "base").map(max_z).fold(0.0, f64::max);
        eprintln!("{scene}: largest |z| {worst:.2e}");
        assert!(worst <= 8.0, "{scene}: {worst}");
        std::fs::remove_dir_all(&out).ok();
    }
}

/// Issue 39: pixel shading's hard 10 % switch (a cluster's shared value or each sample's own)
/// made `shexp` on `env/objects-sky-sun` (32², 4 spp) jump by 0.028 in one pixel scaled by 1e4
/// (max |z| 9.9) and turned (10.4); the blend over [5 %, 10 %] keeps every variant within the
/// gate (measured: shexp max |z| 2.75 turned, 0.028 scaled; ltc 7e-4). `silhouette`'s failure
/// turned, not from pixel shading, is the next test.
#[test]
fn pixel_shading_does_not_jump_on_the_sky_sun_scene() {
    let out = out_dir("sky-sun");
    let args = ["-i", "shexp,ltc", "--variants", "scale,rotate", "--resolution", "32x32", "--spp", "4"];
    let o = stability("scenes/suite/env/objects-sky-sun.pbrt", &args, &out);
    let v = report(&o, &out);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", text(&o.stdout), text(&o.stderr));
    assert_eq!(v["status"], "STABLE");
    for n in ["shexp", "ltc"] {
        for variant in ["scale-1e-4", "scale-1e4", "rotate"] {
            let z = max_z(row(&v, n, variant));
            eprintln!("{n} {variant}: max |z| {z:.2e}");
            assert!(z <= 8.0, "{n} {variant}: {z}");
        }
    }
    std::fs::remove_dir_all(&out).ok();
}

/// Issue 39: `silhouette` on `env/objects-sky-sun` turned 37° (32², 4 spp) failed the gate with
/// either shading (max |z| 50.3, 29.8 % of the pixels over 3; 45.9 with `"shading" "sample"`):
/// its radiance tables and meridians were about the world's axes, so the turned sun fell
/// elsewhere in the cells (0.5 % more light on the whole ground, up to 8 % at shadow edges).
/// About the environment map's axes the turned scene is integrated alike (measured: max |z|
/// 0.443, relative RMS 0.0041, as scaled by 1e4).
#[test]
fn silhouette_is_stable_turned_under_the_sky_sun() {
    let out = out_dir("sky-sun-silhouette");
    let args = ["-i", "silhouette", "--variants", "rotate", "--resolution", "32x32", "--spp", "4"];
    let o = stability("scenes/suite/env/objects-sky-sun.pbrt", &args, &out);
    let v = report(&o, &out);
    assert_eq!(o.status.code(), Some(0), "{}\n{}", text(&o.stdout), text(&o.stderr));
    let r = row(&v, "silhouette", "rotate");
    let z = max_z(r);
    eprintln!("silhouette rotate: max |z| {z:.2e}");
    assert!(z <= 8.0, "{r}");
    std::fs::remove_dir_all(&out).ok();
}
