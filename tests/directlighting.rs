//! `directlighting` end to end: against the real pbrt-v3's renders of every suite
//! scene, against Lambert's closed form for a polygonal emitter, in a white
//! furnace, and on every
//! public scene shipped in `scenes/public/`.

mod common;
use common::*;
use std::f64::consts::PI;

/// Reference images: pbrt-v3 at `ref_spp` (1024 or 4096, see the folders' `timings.tsv`),
/// 256×256 box-downsampled 4×4, so each 64×64 reference pixel averages 16·ref_spp samples.
fn ref_spp(dir: &str, name: &str) -> f64 {
    let tsv = std::fs::read_to_string(root().join("tests/data/references").join(dir).join("timings.tsv")).unwrap();
    let line = tsv.lines().find(|l| l.contains(&format!("/{name}.pbrt"))).unwrap_or_else(|| panic!("{name} timing"));
    line.split('\t').nth(1).unwrap().parse().unwrap()
}

/// Renders `suite/<dir>/<name>.pbrt` with the scene's own sampler (Halton, as the references) at
/// 64×64 and compares with pbrt-v3: the image mean within 0.5 %, and per value the difference
/// against the noise of both images (our own per-pixel sample variance, which over-estimates the
/// error of a QMC render, plus the reference's, 16·ref_spp samples per pixel).
fn check(dir: &str, name: &str, spp: u32) {
    check_at(dir, name, spp, None);
}

/// `full`: compare at pbrt-v3's own 256×256 against the full-size references in `shared`.
fn check_at(dir: &str, name: &str, spp: u32, full: Option<&std::path::Path>) {
    let ours = render_path(
        &scene(&format!("suite/{dir}/{name}.pbrt")),
        &Opts {
            integrator: Some("directlighting"),
            spp: Some(spp),
            resolution: if full.is_some() { None } else { Some((64, 64)) },
            ..Default::default()
        },
    );
    let (reference, per_pixel) = match full {
        Some(shared) => {
            let img = penumbra_core::image::read(shared.join(format!("references/{dir}/{name}.exr"))).unwrap();
            (img.select_channels(&["R", "G", "B"]).unwrap(), 1.0)
        }
        None => (reference(&format!("{dir}/{name}.exr")), 16.0),
    };
    let ratio = spp as f64 / (per_pixel * ref_spp(dir, name));
    assert_matches_reference(&format!("{dir}/{name} at {spp} spp"), &ours, &reference, ratio, 0.005);
}

#[test]
fn ltc_scenes_match_pbrt_v3() {
    for (name, spp) in [
        ("quad-cube", 256),
        ("table-convex-parts", 256),
        ("torus-nonconvex", 256),
        ("cylinder-icosphere-ellipsoid", 128),
        ("two-lights-metal", 64),
    ] {
        check("ltc", name, spp);
    }
}

#[test]
fn env_scenes_match_pbrt_v3() {
    for name in ["objects-sky-sun", "objects-studio"] {
        check("env", name, 128);
    }
}

#[test]
fn stiff_scenes_match_pbrt_v3() {
    for name in STIFF_SCENES {
        // Light at grazing incidence: high per-sample variance; more samples for a 0.5 % image mean.
        check("stiff", name, if name == "grazing-light" { 1024 } else { 256 });
    }
}

#[test]
fn ao_scenes_match_pbrt_v3() {
    for name in ["spheres-on-plane", "blinds"] {
        check("ao", name, 128);
    }
}

/// Lambert's formula: irradiance at the origin (normal +z) from a polygon of radiance `l`,
/// E = (l/2) Σ_edges acos(v̂ᵢ·v̂ⱼ) (v̂ᵢ×v̂ⱼ)_z/|v̂ᵢ×v̂ⱼ| with the polygon wound clockwise as seen
/// from the origin (so the sum is positive).
fn lambert_irradiance(poly: &[[f64; 3]], p: [f64; 3], l: f64) -> f64 {
    let v: Vec<[f64; 3]> = poly
        .iter()
        .map(|q| {
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [d[0] / n, d[1] / n, d[2] / n]
        })
        .collect();
    let mut sum = 0.0;
    for i in 0..v.len() {
        let (a, b) = (v[i], v[(i + 1) % v.len()]);
        let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        let cn = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
        sum += dot.acos() * c[2] / cn;
    }
    0.5 * l * sum.abs()
}

/// A one-sided quad emitter (radiance 2, facing down) above a white-ish matte floor, seen by an
/// orthographic camera between them looking straight down: each pixel's radiance is
/// Kd/π · E(x) averaged over the pixel, E by Lambert's formula.
#[test]
fn polygonal_emitter_matches_lamberts_formula() {
    let (kd, l, h) = (0.7f64, 2.0f64, 1.0f64);
    // Quad centred in x (the image is mirrored in x by pbrt's LookAt convention; symmetric here)
    // but off-centre in y.
    let quad = [[-0.4, -0.1, h], [-0.4, 0.5, h], [0.4, 0.5, h], [0.4, -0.1, h]];
    let text = format!(
        "LookAt 0 0 0.5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n\
         Film \"image\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n\
         Sampler \"random\" \"integer pixelsamples\" [1024]\nPixelFilter \"box\"\nWorldBegin\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [{l} {l} {l}]\nMaterial \"matte\" \"rgb Kd\" [0 0 0]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [{}]\nAttributeEnd\n\
         Material \"matte\" \"rgb Kd\" [{kd} {kd} {kd}]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-3 -3 0 3 -3 0 3 3 0 -3 3 0]\nWorldEnd\n",
        quad.iter().flat_map(|q| q.iter().map(|c| c.to_string())).collect::<Vec<_>>().join(" ")
    );
    let r = render_text(&text, &Opts { integrator: Some("directlighting"), resolution: None, ..Default::default() });
    assert_eq!((r.image.width, r.image.height), (16, 16));
    let (mut z2, mut n, mut s_ours, mut s_exp) = (0.0, 0, 0.0, 0.0);
    for py in 0..16 {
        for px in 0..16 {
            // Pixel footprint on the floor: x ∈ [-1 + px/8, -1 + (px+1)/8] (mirrored: symmetric
            // scene), y from +1 at the top row down.
            let mut e = 0.0;
            let k = 8;
            for sy in 0..k {
                for sx in 0..k {
                    let x = -1.0 + (px as f64 + (sx as f64 + 0.5) / k as f64) / 8.0;
                    let y = 1.0 - (py as f64 + (sy as f64 + 0.5) / k as f64) / 8.0;
                    e += lambert_irradiance(&quad, [x, y, 0.0], l);
                }
            }
            let expected = kd / PI * e / (k * k) as f64;
            let i = (py * 16 + px) * 3;
            for c in 0..3 {
                let got = r.image.data[i + c] as f64;
                let var = r.variance.data[i + c] as f64 + 1e-10;
                z2 += (got - expected).powi(2) / var;
                n += 1;
                s_ours += got;
                s_exp += expected;
            }
        }
    }
    let rel = s_ours / s_exp - 1.0;
    eprintln!("Lambert: mean rel diff {:.4}%, mean z² {:.3}", rel * 100.0, z2 / n as f64);
    assert!(rel.abs() < 0.003, "mean differs from Lambert's formula by {:.3}%", rel * 100.0);
    assert!(z2 / (n as f64) < 1.5, "per-pixel differences exceed the noise: mean z² {}", z2 / n as f64);
}

/// White furnace: a uniform environment of radiance 1 and a matte floor with nothing above it:
/// every pixel is Kd (the floor reflects Kd of the hemisphere's irradiance π·1).
#[test]
fn white_furnace_renders_kd() {
    for strategy in ["all", "one"] {
        for kd in [0.25f32, 0.8] {
            let text = format!(
                "LookAt 0 0 1  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [30]\n\
                 Film \"image\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n\
                 Sampler \"halton\" \"integer pixelsamples\" [64]\nWorldBegin\n\
                 LightSource \"infinite\" \"rgb L\" [1 1 1] \"integer nsamples\" [2]\n\
                 Material \"matte\" \"rgb Kd\" [{kd} {kd} {kd}]\n\
                 Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-50 -50 0 50 -50 0 50 50 0 -50 50 0]\nWorldEnd\n"
            );
            let r = render_text(
                &text,
                &Opts {
                    integrator: Some("directlighting"),
                    params: &[&format!("strategy={strategy}")],
                    resolution: None,
                    ..Default::default()
                },
            );
            let m = mean(&r.image);
            let z2 = r
                .image
                .data
                .iter()
                .zip(&r.variance.data)
                .map(|(v, var)| (*v as f64 - kd as f64).powi(2) / (*var as f64 + 1e-12))
                .sum::<f64>()
                / r.image.data.len() as f64;
            eprintln!("furnace {strategy} Kd {kd}: mean {m:.6}, mean z² {z2:.3}");
            assert!((m / kd as f64 - 1.0).abs() < 2e-3, "{strategy}, Kd {kd}: mean {m}");
            assert!(z2 < 1.5, "{strategy}, Kd {kd}: pixels differ from Kd beyond their noise (mean z² {z2})");
        }
    }
}

/// Same seed → bit-identical images with 1 or 2 threads and from crops, with the Halton sampler's
/// per-light sample arrays (strategy "all") and with strategy "one" on the Sobol sampler.
#[test]
fn deterministic_across_threads_and_crops() {
    let path = scene("suite/ltc/two-lights-metal.pbrt");
    for (strategy, sampler) in [("all", None), ("one", Some("sobol"))] {
        let param = format!("strategy={strategy}");
        let params = [param.as_str()];
        assert_deterministic(40, 36, |threads, crop| {
            render_path(
                &path,
                &Opts {
                    integrator: Some("directlighting"),
                    params: &params,
                    spp: Some(4),
                    resolution: Some((40, 36)),
                    threads,
                    seed: 3,
                    crop,
                    sampler,
                },
            )
        });
    }
}

/// Every complete public scene shipped with the project renders (tiny, 1 spp) without error or
/// non-finite pixels, and its warnings are the kinds pbrt-v3 prints (unused parameters) or name
/// a documented unsupported feature.
#[test]
fn public_scenes_render() {
    let mut files = Vec::new();
    let mut stack = vec![root().join("scenes/public")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "pbrt") {
                files.push(p);
            }
        }
    }
    files.sort();
    assert!(files.len() > 40, "public scenes missing: {}", files.len());
    let allowed = [
        "unused by",
        "is not supported",
        "are not supported",
        "not supported; skipped",
        "animated transform",
        "reading this file as a world-block fragment",
        "is not implemented by penumbra",
        // A BSSRDF (subsurface) seen by an integrator other than path: docs/materials.md.
        "is rendered by \"path\" only",
    ];
    // Scenes that scenes/public/SOURCES.md lists as incomplete because they name a file their
    // repository does not hold: pbrt-v3 cannot create that camera either (its realistic camera
    // reports the unreadable lens file and no image is made), so penumbra's render is an error
    // that names the missing file at the line that asks for it, and writes nothing.
    let incomplete = [("cameras/realistic.pbrt", "fisheye.10mm.dat", "realistic.pbrt:5:7")];
    let dir = cli_dir("public-incomplete");
    for f in &files {
        if let Some((_, missing, at)) = incomplete.iter().find(|(name, ..)| f.ends_with(name)) {
            let out = dir.join("out.exr");
            let o = penumbra(
                &dir,
                &["render", &f.to_string_lossy(), "--spp", "1", "--resolution", "16x16", "-o", &out.to_string_lossy()],
            );
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(1), "{}: {err}", f.display());
            assert!(err.contains(missing) && err.contains(at), "{}: {err}", f.display());
            assert!(!out.exists(), "{}: an image was written", f.display());
            continue;
        }
        let parsed = match penumbra_parser::parse_file(f) {
            Ok(p) => p,
            Err(e) => panic!("{}: {e}", f.display()),
        };
        let r = render_desc(
            &parsed.scene,
            &Opts {
                integrator: Some("directlighting"),
                spp: Some(1),
                resolution: Some((16, 16)),
                ..Default::default()
            },
        );
        assert!(r.image.data.iter().all(|v| v.is_finite()), "{}: non-finite pixels", f.display());
        let all: Vec<String> = parsed.warnings.iter().map(|d| d.message.clone()).chain(r.warnings).collect();
        for w in &all {
            assert!(allowed.iter().any(|a| w.contains(a)), "{}: unexpected warning: {w}", f.display());
        }
    }
}

/// The full-size comparison the issue asks for: 256×256 at `PENUMBRA_FULL_SPP` (default 1024)
/// against `../shared/references/` (not in a fresh clone). Slow: run it by hand with
/// `cargo test --release --test directlighting -- --ignored --nocapture`.
#[test]
#[ignore]
fn full_size_suite_matches_pbrt_v3() {
    let shared = root().join("../shared");
    assert!(shared.join("references").is_dir(), "needs ../shared beside the repository");
    let spp = std::env::var("PENUMBRA_FULL_SPP").ok().and_then(|s| s.parse().ok()).unwrap_or(1024);
    for dir in ["ltc", "env", "stiff", "ao"] {
        let mut names: Vec<String> = std::fs::read_dir(root().join("scenes/suite").join(dir))
            .unwrap()
            .filter_map(|e| e.ok()?.path().file_stem()?.to_str().map(String::from))
            .collect();
        names.sort();
        for name in names {
            check_at(dir, &name, spp, Some(&shared));
        }
    }
}
