//! `ratio` end to end: the undenoised ratio is exactly `U` where a point is fully lit and
//! exactly 0 where it is fully shadowed; figures against pbrt-v3 next to `ltc` and
//! `directlighting`; finite output on the stiff scenes.

mod common;
mod specular;
use common::*;

/// A quad light (y = 3, x, z ∈ [−0.5, 0.5], facing down) over a matte floor, half of which
/// (x < 0) is covered by a large opaque plate at y = 1.5: floor points with x < −0.5 see none of
/// the light, points with x > 0.5 all of it. The camera looks under the plate.
const HALF_SHADOWED: &str = r#"
LookAt 0 0.7 -5  0 0.2 1.5  0 1 0
Camera "perspective" "float fov" [ 60 ]
Film "image" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ] "string filename" [ "out.exr" ]
Sampler "halton" "integer pixelsamples" [ 4 ]
PixelFilter "box"
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 10 10 10 ]
  Material "matte" "rgb Kd" [ 0 0 0 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -0.5 3 -0.5  0.5 3 -0.5  0.5 3 0.5  -0.5 3 0.5 ]
      "normal N" [ 0 -1 0 0 -1 0 0 -1 0 0 -1 0 ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.2 0.2 0.2 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -30 1.5 -30  0 1.5 -30  0 1.5 30  -30 1.5 30 ]
AttributeEnd
AttributeBegin
  Material "plastic" "rgb Kd" [ 0.5 0.45 0.4 ] "rgb Ks" [ 0.3 0.3 0.3 ] "float roughness" [ 0.1 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
      "point P" [ -30 0 -30  -30 0 30  30 0 30  30 0 -30 ]
AttributeEnd
"#;

fn run<'a>(integrator: &'a str, params: &'a [&'a str], spp: u32) -> Render {
    render_text(HALF_SHADOWED, &Opts { integrator: Some(integrator), params, spp: Some(spp), ..Default::default() })
}

/// Where every sample of a pixel is fully lit (ltc's shadowed and unshadowed agree, to the
/// relative 1e-3 to which its glossy lobes' quadrature integrates each piece), the raw
/// ratio gives `U` (ltc unshadowed) to float rounding; where every sample is fully shadowed
/// (ltc's shadowed value is 0 while `U` is not), it gives exactly 0. The denoised ratio too, for
/// pixels whose whole kernel (maxradius 8, dilated by 1) lies in the same class.
#[test]
#[allow(clippy::needless_range_loop)]
fn fully_lit_is_u_and_fully_shadowed_is_zero() {
    let spp = 4;
    let shadowed = run("ltc", &["shading=sample"], spp);
    let u = run("ltc", &["shadows=false", "shading=sample"], spp);
    // Per-sample U, as the ltc images it is compared with (the ratio's property does not
    // depend on where U is evaluated).
    let raw = run("ratio", &["denoise=false", "shading=sample"], spp);
    let den = run("ratio", &["shading=sample"], spp);
    let (w, h) = (u.image.width as usize, u.image.height as usize);
    // Per pixel: 1 fully lit, 0 fully shadowed, -1 neither.
    let class: Vec<i32> = (0..w * h)
        .map(|p| {
            let (s, uu) = (&shadowed.image.data[p * 3..p * 3 + 3], &u.image.data[p * 3..p * 3 + 3]);
            if uu.iter().any(|v| *v <= 1e-4) {
                -1
            } else if s.iter().zip(uu).all(|(a, b)| (a - b).abs() <= 1e-3 * b) {
                1
            } else if s.iter().all(|a| *a == 0.0) {
                0
            } else {
                -1
            }
        })
        .collect();
    let uniform_around = |p: usize, r: i64| {
        let (x, y) = ((p % w) as i64, (p / w) as i64);
        (-r..=r).all(|dy| {
            (-r..=r).all(|dx| {
                let (nx, ny) = (x + dx, y + dy);
                nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 || class[ny as usize * w + nx as usize] == class[p]
            })
        })
    };
    let (mut lit, mut dark, mut deep) = (0, 0, 0);
    for p in 0..w * h {
        for c in 0..3 {
            let i = p * 3 + c;
            let (r, d, uu) = (raw.image.data[i], den.image.data[i], u.image.data[i]);
            match class[p] {
                1 => {
                    assert!((r - uu).abs() <= 1e-5 * uu, "pixel {p}: raw ratio {r} vs U {uu} (fully lit)");
                    lit += 1;
                }
                0 => {
                    assert_eq!(r, 0.0, "pixel {p}: raw ratio {r} where fully shadowed (U {uu})");
                    dark += 1;
                }
                _ => {}
            }
            if class[p] >= 0 && uniform_around(p, 9) {
                let want = if class[p] == 1 { uu } else { 0.0 };
                assert!((d - want).abs() <= 1e-5 * uu, "pixel {p}: denoised {d} vs {want}");
                deep += 1;
            }
        }
    }
    eprintln!("fully lit values {lit}, fully shadowed {dark}, deep inside either {deep}");
    assert!(lit > 600 && dark > 600 && deep > 150, "scene does not exercise both cases ({lit}, {dark}, {deep})");
    // The penumbra is really estimated: some values strictly between 0 and U.
    let between = (0..w * h * 3)
        .filter(|&i| raw.image.data[i] > 0.05 * u.image.data[i] && raw.image.data[i] < 0.95 * u.image.data[i])
        .count();
    assert!(between > 30, "no penumbra ({between} values)");
}

fn mae(a: &penumbra_core::image::Image, b: &penumbra_core::image::Image) -> f64 {
    a.data.iter().zip(&b.data).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / a.data.len() as f64
}

/// Against pbrt-v3 (64×64 downsampled references): MAE and RMSE of `ratio` (denoised and
/// raw), `ltc` and `directlighting` at the same spp. On quad-cube the denoised ratio's mean is
/// within 3 % of the reference and its RMSE below the raw ratio's.
#[test]
fn ltc_scenes_against_pbrt_v3() {
    for name in ["quad-cube", "two-lights-metal", "table-convex-parts"] {
        let reference = reference(&format!("ltc/{name}.exr"));
        let path = scene(&format!("suite/ltc/{name}.pbrt"));
        let mut figures = Vec::new();
        for (label, integrator, params) in [
            ("ratio", "ratio", &[][..]),
            ("ratio raw", "ratio", &["denoise=false"][..]),
            ("ltc", "ltc", &[][..]),
            ("directlighting", "directlighting", &[][..]),
        ] {
            let r =
                render_path(&path, &Opts { integrator: Some(integrator), params, spp: Some(4), ..Default::default() });
            assert!(r.image.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{name} {label}: bad values");
            let rel = mean(&r.image) / mean(&reference) - 1.0;
            let (e_abs, e_rms) = (mae(&r.image, &reference), rmse(&r.image, &reference));
            eprintln!("{name}: {label:>14} (4 spp): mean {:+.3}%  MAE {e_abs:.4e}  RMSE {e_rms:.4e}", rel * 100.0);
            figures.push((rel, r));
        }
        // At 64×64 and 4 spp the error against pbrt-v3 is dominated by anti-aliasing and the LTC
        // fit, which are the same for ratio and ltc (same sampler, same pixel positions): the
        // shadow noise shows against ltc's analytic shadows, and denoising must lower it.
        let (den, raw, ltc) = (&figures[0].1.image, &figures[1].1.image, &figures[2].1.image);
        let (e_den, e_raw) = (rmse(den, ltc), rmse(raw, ltc));
        eprintln!(
            "{name}: RMSE against ltc's analytic shadows: denoised {e_den:.4e} (MAE {:.4e}), raw {e_raw:.4e} (MAE {:.4e})",
            mae(den, ltc),
            mae(raw, ltc)
        );
        if name == "quad-cube" {
            assert!(e_den < 0.85 * e_raw, "{name}: denoising did not lower the shadow noise ({e_den} vs {e_raw})");
            assert!(figures[0].0.abs() < 0.03, "{name}: ratio mean off by {:.2}%", figures[0].0 * 100.0);
        }
    }
}

/// All channels of a `ratio` render (R, G, B, then the `ratio.*` extra channels).
fn ratio_channels(path: &std::path::Path, params: &[&str], spp: u32, res: (u32, u32)) -> penumbra_core::image::Image {
    let parsed = penumbra_parser::parse_file(path).unwrap();
    let warnings = penumbra_parser::DiagSink::new();
    let params: Vec<_> = params.iter().map(|p| penumbra::cli_params::parse_param(p).unwrap()).collect();
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let opts = penumbra::pipeline::RenderOptions {
        integrator: Some("ratio"),
        params: &params,
        build: penumbra_core::scene::BuildOptions { spp: Some(spp), seed: 0, crop: None, resolution: Some(res) },
        threads: 0,
        with_variance: false,
        cancel: &cancel,
        progress: None,
    };
    penumbra::pipeline::render(&parsed.scene, &opts, &warnings).unwrap().image
}

/// The stiff scenes render with finite, non-negative values, denoised or not, and the
/// denoised ratio never exceeds `U` (the unshadowed `ltc`). Pixels where `U > 0` but no
/// sample reached the light (`U_N = 0`: shadowing unknown) get exactly `U`.
#[test]
fn stiff_scenes_are_finite() {
    let mut unknown_total = 0;
    for name in STIFF_SCENES {
        let path = scene(&format!("suite/stiff/{name}.pbrt"));
        let o = |integrator, params| Opts {
            integrator: Some(integrator),
            params,
            spp: Some(2),
            resolution: Some((32, 32)),
            ..Default::default()
        };
        // U per camera sample and once per surface seen in a pixel: the ratio scales U by at
        // most 1 either way.
        let u_sample = render_path(&path, &o("ltc", &["shadows=false", "shading=sample"]));
        // (ltc without its coverage floor: the same camera samples as ratio's.)
        let u_pixel = render_path(&path, &o("ltc", &["shadows=false", "coveragesamples=1"]));
        for (params, u) in [
            (&[][..], &u_pixel),
            (&["denoise=false"][..], &u_pixel),
            (&["denoise=false", "shading=sample"][..], &u_sample),
        ] {
            let r = render_path(&path, &o("ratio", params));
            let bad = r.image.data.iter().filter(|v| !v.is_finite() || **v < 0.0).count();
            assert_eq!(bad, 0, "{name} {params:?}: {bad} non-finite or negative values");
            assert!(r.variance.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: bad variance");
            let brighter =
                r.image.data.iter().zip(&u.image.data).filter(|(s, u)| **s > **u * (1.0 + 1e-5) + 1e-7).count();
            assert_eq!(brighter, 0, "{name} {params:?}: {brighter} values brighter than unshadowed");
        }
        let all = ratio_channels(&path, &["denoise=false"], 2, (32, 32));
        assert!(all.data.iter().all(|v| v.is_finite()), "{name}: non-finite extra channels");
        let ch = |n: &str| all.channel_index(n).unwrap();
        let nc = all.channels.len();
        let mut unknown = 0;
        let mut u_max = 0.0f32;
        for px in all.data.chunks(nc) {
            for c in 0..3 {
                let (u, un) = (
                    px[ch(["ratio.U.R", "ratio.U.G", "ratio.U.B"][c])],
                    px[ch(["ratio.UN.R", "ratio.UN.G", "ratio.UN.B"][c])],
                );
                if u > 0.0 && un == 0.0 {
                    unknown += 1;
                    u_max = u_max.max(u);
                    assert!(px[c] >= u * (1.0 - 1e-5), "{name}: U_N = 0 but {} < U {u}", px[c]);
                }
            }
        }
        let u_mean = (0..all.data.len() / nc).map(|p| all.data[p * nc + ch("ratio.U.G")] as f64).sum::<f64>()
            / (all.data.len() / nc) as f64;
        eprintln!("{name}: {unknown} values with U > 0 and U_N = 0 (largest U {u_max:.3e}, mean U {u_mean:.3e})");
        unknown_total += unknown;
    }
    eprintln!("stiff scenes: {unknown_total} values with U > 0 and U_N = 0 in all");
    assert!(unknown_total > 0, "the stiff scenes no longer exercise the U_N = 0 guard");
}

/// Infinite lights only (through `directlighting`'s estimator, as `ltc` does): the image mean
/// is within 3 % of pbrt-v3's.
#[test]
fn env_scenes_against_pbrt_v3() {
    for name in ["objects-sky-sun", "objects-studio"] {
        let reference = reference(&format!("env/{name}.exr"));
        let r = render_path(
            &scene(&format!("suite/env/{name}.pbrt")),
            &Opts { integrator: Some("ratio"), spp: Some(8), ..Default::default() },
        );
        assert!(r.image.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{name}: bad values");
        let rel = mean(&r.image) / mean(&reference) - 1.0;
        eprintln!("{name}: ratio vs pbrt-v3 mean {:+.3}%, RMSE {:.4e}", rel * 100.0, rmse(&r.image, &reference));
        assert!(rel.abs() < 0.03, "{name}: mean off by {:.2}%", rel * 100.0);
    }
}

/// Point and distant lights take `ltc`'s path (one shadow ray, the real BSDF): with no area
/// light the image is `ltc`'s to float rounding.
#[test]
fn delta_lights_as_ltc() {
    let text = HALF_SHADOWED.replace(
        "AttributeBegin\n  AreaLightSource",
        "LightSource \"point\" \"point from\" [ 0.3 2.5 0.2 ] \"rgb I\" [ 5 5 5 ]\n\
         LightSource \"distant\" \"point from\" [ 1 3 -1 ] \"point to\" [ 0 0 0 ] \"rgb L\" [ 0.5 0.5 0.5 ]\n\
         AttributeBegin\n  Material \"matte\"\n  #",
    );
    assert_ne!(text, HALF_SHADOWED);
    let o = |i, params| Opts { integrator: Some(i), params, spp: Some(2), ..Default::default() };
    let (r, l) = (render_text(&text, &o("ratio", &[])), render_text(&text, &o("ltc", &["coveragesamples=1"])));
    assert!(mean(&l.image) > 1e-3, "the delta lights must light the scene");
    for (a, b) in r.image.data.iter().zip(&l.image.data) {
        assert!((a - b).abs() <= 1e-5 * b.abs() + 1e-7, "ratio {a} vs ltc {b}");
    }
}

/// Bit-identical with 1 and 2 threads and from render to render (the denoiser is a whole-image
/// pass: crops are not the full image's pixels near their borders), on a planar and a convex light.
#[test]
fn threads_and_runs_are_bit_identical() {
    for name in ["suite/stiff/coincident-geometry.pbrt", "suite/ltc/two-lights-metal.pbrt"] {
        let path = scene(name);
        let opts = |threads| Opts {
            integrator: Some("ratio"),
            spp: Some(2),
            resolution: Some((40, 36)),
            threads,
            ..Default::default()
        };
        let one = render_path(&path, &opts(1));
        assert_same(&one.image.data, &render_path(&path, &opts(2)).image.data, "1 vs 2 threads");
        assert_same(&one.image.data, &render_path(&path, &opts(2)).image.data, "two renders");
    }
}

/// Perfectly specular surfaces (a mirror, smooth glass) are followed as `directlighting` follows
/// them, up to `maxdepth`, and what they reach is shaded by `ratio`'s own method: on the public
/// mirror and glass dragons (infinite light) and on an area-lit scene with shadows seen in a
/// mirror and through a glass ball, the image mean and the mean over the specular objects'
/// pixels are within 2 % of `directlighting`'s, and no specular pixel is black. With
/// `maxdepth` 1 nothing is followed: the mirror and glass pixels are black (up to
/// their edges), as under `directlighting`.
#[test]
fn specular_chains_match_directlighting() {
    for s in [specular::dragon("mirror"), specular::dragon("glass"), specular::area_lit()] {
        specular::assert_matches_directlighting(&s, "ratio", &[], (64, 256, 32), 0.02);
    }
    let s = specular::area_lit();
    let spec = s.specular_pixels(32);
    let (one, five) = (s.render("ratio", &["maxdepth=1"], 16, 32), s.render("ratio", &[], 16, 32));
    let (m1, m5) = (specular::mean_over(&one, &spec), specular::mean_over(&five, &spec));
    eprintln!("area-lit ratio: specular pixels' mean {m1:.5} with maxdepth 1, {m5:.5} with 5");
    // (Not exactly 0: a pixel's edge samples may see past the objects.)
    assert!(m1 < 0.02 * m5, "maxdepth 1: the specular pixels' mean is {m1}, with maxdepth 5 {m5}");
}
