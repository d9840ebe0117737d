//! `silhouette` (seed 000) end to end: closed forms (open hemisphere, spheres over a plane,
//! inside a closed box), pbrt-v3's references of the AO and environment scenes, and
//! determinism.

mod common;
use common::*;
use std::f64::consts::PI;

/// One pixel looking straight down at `(x, z)` on the plane y = 0 through a tiny window:
/// the pixel is the value at that point.
fn point_on_plane(x: f64, z: f64, world: &str, params: &[&str]) -> f64 {
    let text = format!(
        "LookAt {x} 5 {z}  {x} 0 {z}  0 0 1\nCamera \"orthographic\" \"float screenwindow\" [-1e-4 1e-4 -1e-4 1e-4]\n\
         Film \"image\" \"integer xresolution\" [1] \"integer yresolution\" [1]\nSampler \"halton\" \"integer pixelsamples\" [1]\n\
         WorldBegin\nMaterial \"matte\"\n{world}\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 0 -6 -6 0 6 6 0 6 6 0 -6]\nWorldEnd\n"
    );
    let r =
        render_text(&text, &Opts { integrator: Some("silhouette"), params, resolution: None, ..Default::default() });
    r.image.data[0] as f64
}

#[test]
fn open_plane_ao_is_pi() {
    for (x, z) in [(0.0, 0.0), (1.3, -2.2), (5.9, 5.9)] {
        let ao = point_on_plane(x, z, "", &["mode=ao", "resolution=16"]);
        assert!((ao - PI).abs() < 1e-5, "at ({x}, {z}): {ao}");
    }
}

/// The AO test's closed form (`tests/ao.rs`): at horizontal distance d from the foot of a
/// sphere of radius r centred at height h, the cosine-weighted unoccluded fraction is
/// 1 − r²h/(d²+h²)^{3/2}. Tolerance: the spheres' tessellation (relative error 1e-3 of the
/// radius, ~2e-3 here) plus the azimuth discretisation at 128 meridians.
#[test]
fn spheres_over_plane_closed_form() {
    let spheres = [([-1.0f64, 0.5, 0.0], 0.5f64), ([1.0, 0.8, 0.5], 0.4)];
    let world = "AttributeBegin\nTranslate -1 0.5 0\nShape \"sphere\" \"float radius\" [0.5]\nAttributeEnd\n\
                 AttributeBegin\nTranslate 1 0.8 0.5\nShape \"sphere\" \"float radius\" [0.4]\nAttributeEnd\n";
    let mut worst = 0.0f64;
    for p in [[-1.0f64, -1.0], [0.0, -0.2], [1.0, -0.5], [2.0, 0.5], [-1.0, 1.2], [1.6, 1.4]] {
        let expected: f64 = 1.0
            - spheres
                .iter()
                .map(|(c, r)| {
                    let d2 = (c[0] - p[0]).powi(2) + (c[2] - p[1]).powi(2);
                    r * r * c[1] / (d2 + c[1] * c[1]).powf(1.5)
                })
                .sum::<f64>();
        let got = point_on_plane(p[0], p[1], world, &["mode=ao"]) / PI;
        eprintln!("({}, {}): {got:.5} vs closed form {expected:.5}", p[0], p[1]);
        worst = worst.max((got - expected).abs());
    }
    assert!(worst < 2e-3, "worst difference {worst}");
}

/// A closed box (welded cube, consistently wound) around the camera and the shading points:
/// no edge is a contour from inside, the depth complexity is 1 everywhere, and only the
/// start ray can tell: every pixel is 0 (the paper's "shift the minimum to 0" would report
/// open sky). With one face removed the same points see light.
#[test]
fn inside_a_closed_box_is_black() {
    let cube = |faces: &str| {
        format!(
            "LookAt 0 0.5 0  0 -1 0.3  0 1 0\nCamera \"perspective\" \"float fov\" [60]\n\
             Film \"image\" \"integer xresolution\" [8] \"integer yresolution\" [8]\nSampler \"halton\" \"integer pixelsamples\" [1]\n\
             WorldBegin\nLightSource \"infinite\" \"rgb L\" [1 1 1]\nMaterial \"matte\" \"rgb Kd\" [0.5 0.5 0.5]\n\
             Shape \"trianglemesh\" \"point P\" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1]\n\
             \"integer indices\" [{faces}]\nWorldEnd\n"
        )
    };
    let all = "0 2 1 0 3 2  4 5 6 4 6 7  0 1 5 0 5 4  3 7 6 3 6 2  0 4 7 0 7 3  1 2 6 1 6 5";
    let open_top = "0 2 1 0 3 2  4 5 6 4 6 7  0 1 5 0 5 4  0 4 7 0 7 3  1 2 6 1 6 5";
    for mode in ["mode=ao", "mode=shade"] {
        let opts = Opts { integrator: Some("silhouette"), params: &[mode], resolution: None, ..Default::default() };
        let closed = render_text(&cube(all), &opts);
        assert!(closed.image.data.iter().all(|v| *v == 0.0), "{mode}: closed box not black");
        let open = render_text(&cube(open_top), &opts);
        assert!(open.image.data.iter().all(|v| *v > 0.0), "{mode}: open box has black pixels");
    }
}

/// pbrt-v3's `ambientocclusion` references (64×64, box-downsampled from 256×256 at 4096 spp):
/// the image mean within 0.5 % and every 8×8 region within 5σ of the camera-sample noise
/// (+0.5 %).
#[test]
fn ao_matches_pbrt_v3_references() {
    for name in ["spheres-on-plane", "blinds"] {
        let ours = render_path(
            &scene(&format!("suite/ao/{name}.pbrt")),
            &Opts { integrator: Some("silhouette"), params: &["mode=ao"], spp: Some(16), ..Default::default() },
        );
        let reference = reference(&format!("ao/{name}.ambientocclusion.exr"));
        let (mo, mr) = (mean(&ours.image), mean(&reference));
        eprintln!("{name}: mean {mo:.5} vs pbrt-v3 {mr:.5} ({:+.3} %)", (mo / mr - 1.0) * 100.0);
        assert!((mo / mr - 1.0).abs() < 0.005, "{name}: mean {mo} vs {mr}");
        assert_regions_match(name, &ours, &reference, 16.0 / (16.0 * 4096.0), 8);
    }
}

/// `shade` (the default: the AO scenes have a white sky) against pbrt-v3's `directlighting`
/// of the same scenes, which is 0.5 × cosine-weighted AO; and the studio scene, whose
/// Lambertian objects are shaded through the vector irradiance (its plastic one's glossy lobe
/// by SH projection).
#[test]
fn shade_matches_pbrt_v3_directlighting() {
    for name in ["ao/spheres-on-plane", "ao/blinds", "env/objects-studio", "env/objects-sky-sun"] {
        let ours = render_path(
            &scene(&format!("suite/{name}.pbrt")),
            &Opts { integrator: Some("silhouette"), spp: Some(16), ..Default::default() },
        );
        let reference = reference(&format!("{name}.exr"));
        let (mo, mr) = (mean(&ours.image), mean(&reference));
        eprintln!("{name}: mean {mo:.5} vs pbrt-v3 {mr:.5} ({:+.3} %)", (mo / mr - 1.0) * 100.0);
        assert!((mo / mr - 1.0).abs() < 0.01, "{name}: mean {mo} vs {mr}");
        assert_regions_match(name, &ours, &reference, 16.0 / (16.0 * 1024.0), 8);
    }
}

/// The scene turned as a whole (camera, objects and sky) about a non-axis direction renders
/// the same image. Sampling each radiance-table cell at fixed 3 × 3 points aliased the sky-sun
/// map's sun (12 texels, 60 % of the power), so each axis frame saw a different sun: relative
/// RMSE 24 % between the two renders and −10 % on the ground; and the Monte Carlo fallback's
/// uniform rays made a pixel 10× too bright wherever one hit the sun. With half-texel sampling
/// but the tables and meridians still about the world's axes: relative RMSE 1.8 %, means 0.5 %
/// apart (the sun's power sampled differently, the shadows' azimuth discretisation turned).
/// About the environment map's axes (`param::Axes`, issue 39) the turned scene is integrated
/// alike; measured now (32², 2 spp): relative RMSE 0.81 % (as for the scene scaled: pixels
/// whose clusters or fallbacks fall otherwise by rounding; `penumbra stability` max |z| 0.44),
/// means 0.03 % apart. The bounds leave 1.5× and 3× of that and fail for the world's axes.
#[test]
fn shade_is_unchanged_by_turning_the_scene() {
    let path = scene("suite/env/objects-sky-sun.pbrt");
    let base = penumbra_parser::parse_file(&path).unwrap().scene;
    let mut turned = base.clone();
    turned.transform_world(&penumbra_parser::Transform::rotate(37.0, [1.0, 2.0, 3.0]).unwrap());
    let o = Opts { integrator: Some("silhouette"), spp: Some(2), resolution: Some((32, 32)), ..Default::default() };
    let (a, b) = (render_desc(&base, &o), render_desc(&turned, &o));
    let rel = rmse(&a.image, &b.image) / mean(&a.image);
    eprintln!("turned: relative RMSE {rel:.4}, means {:.5} {:.5}", mean(&a.image), mean(&b.image));
    assert!(rel < 0.012, "relative RMSE {rel} between the scene and the scene turned");
    assert!((mean(&b.image) / mean(&a.image) - 1.0).abs() < 0.001, "means differ");
}

/// Same seed → bit-identical images with 1 or 2 threads and from assembled crops.
#[test]
fn deterministic_across_threads_and_crops() {
    let path = scene("suite/env/objects-studio.pbrt");
    let opts = |threads, crop| Opts {
        integrator: Some("silhouette"),
        params: &["resolution=48"],
        spp: Some(2),
        resolution: Some((40, 32)),
        threads,
        seed: 3,
        crop,
        sampler: None,
    };
    assert_deterministic(40, 32, |threads, crop| render_path(&path, &opts(threads, crop)));
}

/// Every stiff scene renders finite values (no NaN/Inf, none replaced by the driver) in both
/// modes (`tests/conformance.rs` checks the default mode, and scale invariance).
#[test]
fn stiff_scenes_are_finite_in_both_modes() {
    let dir = root().join("scenes/suite/stiff");
    let mut names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    for path in names.iter().filter(|p| p.extension().is_some_and(|e| e == "pbrt")) {
        for mode in ["mode=ao", "mode=shade"] {
            let r = render_path(
                path,
                &Opts {
                    integrator: Some("silhouette"),
                    params: &[mode, "resolution=32"],
                    spp: Some(1),
                    resolution: Some((24, 24)),
                    ..Default::default()
                },
            );
            assert!(r.image.data.iter().all(|v| v.is_finite()), "{path:?} {mode}: non-finite values");
            assert!(!r.warnings.iter().any(|w| w.contains("NaN")), "{path:?} {mode}: {:?}", r.warnings);
        }
    }
}

/// `prt`: relit by `penumbra relight` under the scene's own (constant white) sky, the transfer
/// gives `shade`'s image (albedo/π · ∫ V cos: the constant sky's SH projection is exact) to
/// float rounding; `sh.0` is `Y_0^0` times the AO value but for the shading normal (within
/// 1 % on the image mean: the spheres' interpolated normals).
#[test]
fn prt_transfer_relights_to_shade() {
    let dir = std::env::temp_dir().join(format!("penumbra-silhouette-prt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bin = env!("CARGO_BIN_EXE_penumbra");
    let scene_path = scene("suite/ao/spheres-on-plane.pbrt");
    let run = |args: &[&str]| {
        let out = std::process::Command::new(bin).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let (prt, relit, shade, ao) =
        (dir.join("prt.exr"), dir.join("relit.exr"), dir.join("shade.exr"), dir.join("ao.exr"));
    // Sample shading: `prt` integrates every camera sample, so `shade` must too to compare.
    let common = [
        "--resolution",
        "32x32",
        "--spp",
        "4",
        "-q",
        "-i",
        "silhouette",
        "--param",
        "resolution=64",
        "--param",
        "shading=sample",
    ];
    let s = scene_path.to_str().unwrap();
    for (mode, out) in [("mode=prt", &prt), ("mode=shade", &shade), ("mode=ao", &ao)] {
        let mut args = vec!["render", s];
        args.extend(common);
        args.extend(["--param", mode, "-o", out.to_str().unwrap()]);
        run(&args);
    }
    run(&["relight", prt.to_str().unwrap(), "--scene", s, "-o", relit.to_str().unwrap(), "-q"]);
    let read = |p: &std::path::Path| penumbra_core::image::read(p).unwrap();
    let (prt_img, relit, shade, ao) = (read(&prt), read(&relit), read(&shade), read(&ao));
    let nc = prt_img.channels.len();
    let sh0 = prt_img.channels.iter().position(|c| c == "sh.0").expect("sh.0");
    assert!(prt_img.channels.iter().any(|c| c == "sh.8") && prt_img.channels.iter().any(|c| c == "albedo.G"));
    let albedo = prt_img.channels.iter().position(|c| c == "albedo.G").unwrap();
    let y00 = 0.5 / PI.sqrt();
    let (mut sum_sh0, mut sum_ao, mut worst_relit, mut geometry) = (0.0f64, 0.0f64, 0.0f64, 0);
    for px in 0..(32 * 32) {
        sum_ao += ao.data[px * ao.channels.len()] as f64 * y00;
        sum_sh0 += prt_img.data[px * nc + sh0] as f64;
        // Pixels wholly on geometry (albedo 0.5 in every sample): `shade` also shows the sky.
        if prt_img.data[px * nc + albedo] != 0.5 {
            continue;
        }
        geometry += 1;
        for c in 0..3 {
            let (r, d) =
                (relit.data[px * relit.channels.len() + c] as f64, shade.data[px * shade.channels.len() + c] as f64);
            worst_relit = worst_relit.max((r - d).abs());
        }
    }
    let rel = sum_sh0 / sum_ao - 1.0;
    eprintln!("mean sh.0 / (AO·Y00) − 1 = {rel:e}, |relit − shade| ≤ {worst_relit:e} over {geometry} pixels");
    assert!(rel.abs() < 0.01, "sh.0 vs AO: {rel}");
    assert!(geometry > 500, "{geometry} geometry pixels");
    assert!(worst_relit < 1e-4, "relit vs shade: {worst_relit}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Glossy lobes by SH projection (`shade`): rough plastic and metal spheres and a glossy
/// ground (which the spheres' occlusion masks) under the studio map, against `directlighting`
/// at 256 spp.
/// Tolerances: the image mean within 0.75 % and every 8×8 region's mean within 1.5 % beyond
/// 5σ of the reference's noise — the SH truncation at the orders chosen from roughness
/// (measured: −0.12 % on the mean, 0.25 % on the worst region; `glossyorder=3` fails, −1.5 %
/// on the mean). The infinite light goes through the SH path at every glossy point (no
/// estimator fallback).
#[test]
fn glossy_lobes_match_directlighting() {
    let text = "LookAt 0 2.2 -4.5  0 0.5 0  0 1 0\nCamera \"perspective\" \"float fov\" [32]\n\
        Film \"image\" \"integer xresolution\" [32] \"integer yresolution\" [32]\nSampler \"halton\" \"integer pixelsamples\" [4]\n\
        WorldBegin\nAttributeBegin\nRotate -90 1 0 0\n\
        LightSource \"infinite\" \"string mapname\" [\"scenes/suite/textures/studio.exr\"] \"integer nsamples\" [4]\nAttributeEnd\n\
        AttributeBegin\nMaterial \"plastic\" \"rgb Kd\" [0.1 0.2 0.5] \"rgb Ks\" [0.4 0.4 0.4] \"float roughness\" [0.1]\n\
        Translate -0.7 0.5 0\nShape \"sphere\" \"float radius\" [0.5]\nAttributeEnd\n\
        AttributeBegin\nMaterial \"metal\" \"float roughness\" [0.25]\nTranslate 0.7 0.5 0.2\nShape \"sphere\" \"float radius\" [0.5]\nAttributeEnd\n\
        AttributeBegin\nMaterial \"plastic\" \"rgb Kd\" [0.3 0.3 0.3] \"rgb Ks\" [0.3 0.3 0.3] \"float roughness\" [0.3]\n\
        Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 0 -6 -6 0 6 6 0 6 6 0 -6]\nAttributeEnd\nWorldEnd\n";
    let ours = render_text(
        text,
        &Opts { integrator: Some("silhouette"), params: &["resolution=128"], resolution: None, ..Default::default() },
    );
    let reference = render_text(
        text,
        &Opts { integrator: Some("directlighting"), spp: Some(256), resolution: None, ..Default::default() },
    );
    let counter = |k: &str| ours.stats.counters.get(k).copied().unwrap_or(-1.0);
    assert!(counter("silhouette.glossy_points") > 1000.0, "{:?}", ours.stats.counters);
    assert_eq!(counter("silhouette.estimator_fallbacks"), 0.0);
    let (mo, mr) = (mean(&ours.image), mean(&reference.image));
    eprintln!("glossy: mean {mo:.5} vs directlighting {mr:.5} ({:+.3} %)", (mo / mr - 1.0) * 100.0);
    assert!((mo / mr - 1.0).abs() < 0.0075, "mean {mo} vs {mr}");
    let (w, b) = (32usize, 8usize);
    let mut worst = 0.0f64;
    for by in (0..w).step_by(b) {
        for bx in (0..w).step_by(b) {
            for c in 0..3 {
                let (mut so, mut sr, mut var) = (0.0f64, 0.0f64, 0.0f64);
                for y in by..by + b {
                    for x in bx..bx + b {
                        let i = (y * w + x) * 3 + c;
                        so += ours.image.data[i] as f64;
                        sr += reference.image.data[i] as f64;
                        var += reference.variance.data[i] as f64;
                    }
                }
                let n = (b * b) as f64;
                let (mo, mr, sigma) = (so / n, sr / n, var.sqrt() / n);
                let rel = ((mo - mr).abs() - 5.0 * sigma).max(0.0) / mr;
                eprintln!("region ({bx}, {by}) channel {c}: {mo:.5} vs {mr:.5} ± {sigma:.1e}");
                worst = worst.max(rel);
            }
        }
    }
    eprintln!("worst region beyond 5σ: {:.3} %", worst * 100.0);
    assert!(worst < 0.015, "a region differs by {:.2} % beyond the reference's noise", worst * 100.0);
}

/// `"shading" "pixel"` (the default) against `"sample"`: identical at 1 spp; at more samples
/// the same image up to the shading's variation inside a pixel, from fewer integrations (each
/// surface a pixel sees is integrated at ⌈√m⌉ of its m samples, spread over the film, the
/// others taking their nearest one's value, and at every sample where those differ by more than
/// 5–10 %), and **converging** to it: relative RMSE against sample shading at 16 → 64 spp
/// (48², measured): studio 0.32 → 0.11 %, sky-sun 0.55 → 0.21 %, blinds (ao) 0.38 → 0.15 %.
/// Bounds: 0.8 % at 16 spp, 0.35 % at 64, and at 64 at most half of 16's (measured 0.35–0.40).
/// Shading only the central sample (and the farthest, refining above 5 %) left a floor that
/// more samples did not lower — 0.54 → 0.60 %, 2.29 → 2.93 % (the sun's shadow edges), 0.46 →
/// 0.42 % — and fails all three (issue 37: a bias, not noise).
#[test]
fn pixel_shading_matches_sample_shading() {
    const SHADE: [[&str; 2]; 2] = [["mode=shade", "shading=pixel"], ["mode=shade", "shading=sample"]];
    const AO: [[&str; 2]; 2] = [["mode=ao", "shading=pixel"], ["mode=ao", "shading=sample"]];
    for (name, params) in [("env/objects-studio", &SHADE), ("env/objects-sky-sun", &SHADE), ("ao/blinds", &AO)] {
        let path = scene(&format!("suite/{name}.pbrt"));
        let o = |spp, shading: &'static str| Opts {
            integrator: Some("silhouette"),
            params: &params[usize::from(shading != "pixel")],
            spp: Some(spp),
            resolution: Some((48, 48)),
            ..Default::default()
        };
        let (p1, s1) = (render_path(&path, &o(1, "pixel")), render_path(&path, &o(1, "sample")));
        assert_eq!(p1.image.data, s1.image.data, "{name}: 1 spp must be identical");
        let mut errors = Vec::new();
        for (spp, bound) in [(16, 0.008), (64, 0.0035)] {
            let (p, s) = (render_path(&path, &o(spp, "pixel")), render_path(&path, &o(spp, "sample")));
            let e = rmse(&p.image, &s.image) / mean(&s.image);
            let points = |r: &Render| r.stats.counters["silhouette.points"];
            let ratio = points(&p) / points(&s);
            eprintln!("{name}: pixel vs sample shading, {spp} spp, relative RMSE {e:.5}, integrations {ratio:.3}");
            assert!(e < bound, "{name}, {spp} spp: relative RMSE {e} (bound {bound})");
            assert!(ratio < 0.5, "{name}, {spp} spp: {ratio} of sample shading's integrations");
            assert!(p.image.data.iter().all(|v| v.is_finite() && *v >= 0.0));
            errors.push(e);
        }
        assert!(errors[1] <= 0.5 * errors[0], "{name}: pixel shading does not converge: {errors:?}");
    }
}

/// A scene lit by an area light only (issue 37 item 4, issue 32's rule): the default mode is
/// `shade`, which takes lights other than infinite ones through `directlighting`'s estimator —
/// the same estimate, sample for sample — and says so; never ambient occlusion in place of the
/// scene's lighting (`-i silhouette` on `ltc/quad-cube` gave a mean of 2.2 where its light gives
/// 0.105). A scene without lights is rendered as `ao`, with a warning.
#[test]
fn default_mode_shades_the_scenes_lights_and_says_how() {
    let world = "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [4 4 4] \"bool twosided\" \"true\"\n\
        Shape \"trianglemesh\" \"integer indices\" [0 2 1 0 3 2] \"point P\" [-1 3 -1 1 3 -1 1 3 1 -1 3 1]\nAttributeEnd\n\
        Material \"plastic\" \"float roughness\" [0.2]\nShape \"sphere\" \"float radius\" [0.5]\nMaterial \"matte\"\n\
        Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 -0.5 -6 -6 -0.5 6 6 -0.5 6 6 -0.5 -6]\n";
    let text = format!(
        "LookAt 0 2 -4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\n\
         Film \"image\" \"integer xresolution\" [16] \"integer yresolution\" [16]\nSampler \"halton\" \"integer pixelsamples\" [4]\n\
         WorldBegin\n{world}WorldEnd\n"
    );
    let o = |integrator, params| Opts { integrator: Some(integrator), params, resolution: None, ..Default::default() };
    let ours = render_text(&text, &o("silhouette", &["shading=sample"]));
    let direct = render_text(&text, &o("directlighting", &[]));
    assert_same(&ours.image.data, &direct.image.data, "silhouette (default mode) vs directlighting");
    assert!(
        ours.warnings.iter().any(|w| w.contains("no \"infinite\" light") && w.contains("directlighting's estimator")),
        "no warning names the case: {:?}",
        ours.warnings
    );
    // `prt` cannot carry the area light (its transfer channels relight distant light only):
    // its image is ambient occlusion, so it says so, naming the mode and the lights.
    let prt = render_text(&text, &o("silhouette", &["mode=prt"]));
    assert!(
        prt.warnings.iter().any(|w| w.contains("\"prt\"") && w.contains("area") && w.contains("ambient occlusion")),
        "prt on an area-lit scene: no warning names the case: {:?}",
        prt.warnings
    );
    let pixel = render_text(&text, &o("silhouette", &[]));
    let rel = (mean(&pixel.image) / mean(&direct.image) - 1.0).abs();
    assert!(rel < 0.02, "pixel shading: mean {} vs directlighting {}", mean(&pixel.image), mean(&direct.image));
    // Without lights: ambient occlusion (π on an open plane), and a warning.
    let r = render_text(
        "LookAt 0 5 0  0 0 0  0 0 1\nCamera \"orthographic\" \"float screenwindow\" [-1e-4 1e-4 -1e-4 1e-4]\n\
         Film \"image\" \"integer xresolution\" [1] \"integer yresolution\" [1]\nSampler \"halton\" \"integer pixelsamples\" [1]\n\
         WorldBegin\nMaterial \"matte\"\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 0 -6 -6 0 6 6 0 6 6 0 -6]\nWorldEnd\n",
        &o("silhouette", &["resolution=16"]),
    );
    assert!((r.image.data[0] as f64 - PI).abs() < 1e-5, "{}", r.image.data[0]);
    assert!(r.warnings.iter().any(|w| w.contains("no lights") && w.contains("ambient occlusion")), "{:?}", r.warnings);
}
