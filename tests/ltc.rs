//! `ltc` end to end: exact where the method is exact (Lambertian receivers) against
//! `directlighting`, silhouette and per-triangle modes against each other, the
//! `shadows` and `occluder` switches, and finite output on the stiff scenes.

mod common;
mod specular;
use common::*;

/// The scene with every material made Lambertian (keeping `Kd` where given), so that LTC
/// shading is exact.
fn matte_variant(name: &str) -> String {
    let text = std::fs::read_to_string(scene(&format!("suite/ltc/{name}.pbrt"))).unwrap();
    let out = text
        .lines()
        .map(|l| {
            let t = l.trim_start();
            if t.starts_with("Material \"plastic\"") {
                let kd = t.find("\"rgb Kd\"").map(|i| {
                    let j = t[i..].find(']').unwrap() + i + 1;
                    t[i..j].to_string()
                });
                format!("Material \"matte\" {}", kd.unwrap_or_default())
            } else if t.starts_with("Material \"") && !t.starts_with("Material \"matte\"") {
                "Material \"matte\" \"rgb Kd\" [ 0.5 0.5 0.5 ]".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    // The variant must leave no other material behind (a material written another way, e.g. a
    // named one, would otherwise silently keep its glossy lobe).
    let non_matte = out
        .lines()
        .map(str::trim_start)
        .filter(|l| l.contains("Material") && !l.starts_with("Material \"matte\""))
        .collect::<Vec<_>>();
    assert!(non_matte.is_empty(), "{name}: the matte variant kept {non_matte:?}");
    out
}

fn opts<'a>(integrator: &'a str, params: &'a [&'a str], spp: u32) -> Opts<'a> {
    Opts { integrator: Some(integrator), params, spp: Some(spp), resolution: Some((48, 48)), ..Default::default() }
}

/// Mean relative difference and mean z² between two renders, each with its own variance.
fn compare(a: &Render, b: &Render) -> (f64, f64, f64) {
    let (ma, mb) = (mean(&a.image), mean(&b.image));
    let mut z2 = 0.0;
    for i in 0..a.image.data.len() {
        let d = a.image.data[i] as f64 - b.image.data[i] as f64;
        let v = a.variance.data[i] as f64 + b.variance.data[i] as f64 + (1e-3 * b.image.data[i] as f64).powi(2) + 1e-10;
        z2 += d * d / v;
    }
    (ma / mb - 1.0, z2 / a.image.data.len() as f64, rmse(&a.image, &b.image))
}

/// On Lambertian receivers LTC is exact: `ltc` (any mode) agrees with `directlighting` to within
/// the noise of both renders (ltc's own is only anti-aliasing).
#[test]
fn lambertian_scenes_match_directlighting() {
    for (name, dl_spp) in
        [("quad-cube", 256), ("torus-nonconvex", 256), ("table-convex-parts", 256), ("two-lights-metal", 128)]
    {
        let text = matte_variant(name);
        let dl = render_text(&text, &opts("directlighting", &[], dl_spp));
        let ltc = render_text(&text, &opts("ltc", &[], 32));
        assert!(ltc.image.data.iter().all(|v| v.is_finite()), "{name}: non-finite values");
        let (rel, z2, e) = compare(&ltc, &dl);
        eprintln!("{name} (matte): ltc vs directlighting: mean {:+.4}%, mean z² {z2:.3}, RMSE {e:.3e}", rel * 100.0);
        assert!(rel.abs() < 0.005, "{name}: mean differs by {:.3}%", rel * 100.0);
        assert!(z2 < 1.5, "{name}: differences beyond the noise (mean z² {z2})");
    }
}

/// Silhouette loops, per-triangle occluders (the paper's: light and occluders triangle by
/// triangle) and outlines of an object's triangles (for a closed mesh, of the faces turned away
/// from the point) describe the same visibility: identical images up to the polygon clipper's
/// snapping. The torus is closed but not convex: no silhouette mode there.
#[test]
fn silhouette_and_per_triangle_modes_agree() {
    for (name, modes) in [
        ("quad-cube", &["silhouette", "auto", "per-triangle"][..]),
        ("table-convex-parts", &["silhouette", "auto", "per-triangle"][..]),
        ("torus-nonconvex", &["auto", "per-triangle"][..]),
    ] {
        let text = matte_variant(name);
        let tri = render_text(&text, &opts("ltc", &["mode=per-triangle", "mergeoccluders=false"], 4));
        for mode in modes {
            let param = format!("mode={mode}");
            let r = render_text(&text, &opts("ltc", &[param.as_str()], 4));
            let e = rmse(&r.image, &tri.image) / mean(&tri.image);
            eprintln!("{name}: {mode} vs triangle by triangle: relative RMSE {e:.2e}");
            assert!(e < 1e-4, "{name}: {mode} differs from triangle by triangle (relative RMSE {e})");
        }
    }
}

/// `shadows false` is the unshadowed analytic term: never below the shadowed image, and equal
/// to it when the only possible occluder is marked `"bool occluder" false`.
#[test]
fn shadows_switch_and_occluder_flag() {
    let text = matte_variant("quad-cube");
    let lit = render_text(&text, &opts("ltc", &[], 4));
    let unshadowed = render_text(&text, &opts("ltc", &["shadows=false"], 4));
    let mut darker = 0;
    for (s, u) in lit.image.data.iter().zip(&unshadowed.image.data) {
        assert!(*s <= *u * (1.0 + 1e-5) + 1e-7, "shadowed {s} above unshadowed {u}");
        if *s < *u * 0.9 {
            darker += 1;
        }
    }
    assert!(darker > 100, "the cube must cast a shadow ({darker} values darker)");
    // The flag is a shape parameter (pbrt-v3 reports it unused and renders the scene).
    let no_cube =
        text.replacen("\"integer indices\" [ 0 2 3", "\"bool occluder\" \"false\" \"integer indices\" [ 0 2 3", 1);
    assert_ne!(no_cube, text);
    let r = render_text(&no_cube, &opts("ltc", &[], 4));
    let e = rmse(&r.image, &unshadowed.image) / mean(&unshadowed.image);
    assert!(e < 1e-4, "with the cube not an occluder the image must be unshadowed (relative RMSE {e})");
}

/// The stiff scenes (coincident geometry, grazing and tiny lights, intersecting occluders,
/// extreme roughness, 1e±4 scales) render with finite values and no pixel brighter than the
/// unshadowed analytic result.
#[test]
fn stiff_scenes_are_finite_and_never_brighter_than_unshadowed() {
    for name in STIFF_SCENES {
        let path = scene(&format!("suite/stiff/{name}.pbrt"));
        let o = |params| Opts {
            integrator: Some("ltc"),
            params,
            spp: Some(2),
            resolution: Some((32, 32)),
            ..Default::default()
        };
        let r = render_path(&path, &o(&[]));
        let u = render_path(&path, &o(&["shadows=false"]));
        let bad = r.image.data.iter().filter(|v| !v.is_finite() || **v < 0.0).count();
        assert_eq!(bad, 0, "{name}: {bad} non-finite or negative values");
        // The glossy lobes' quadrature is exact to a relative 1e-3 of each piece (shadowed and
        // unshadowed pieces are integrated separately: measured up to 3.1e-4 apart on
        // grazing-light's floor).
        let brighter = r.image.data.iter().zip(&u.image.data).filter(|(s, u)| **s > **u * (1.0 + 1e-3) + 1e-7).count();
        assert_eq!(brighter, 0, "{name}: {brighter} values brighter than unshadowed");
        // Against pbrt-v3 (its 1024-spp render, box-filtered to 64², whose image mean is the
        // full-resolution one's): the image mean within 1 % (issue 43's goal). Rendered at 64²
        // with 256 coverage samples (camera rays only; at 16 the anti-aliasing of grazing-light's
        // edges alone moves its mean by −0.65 %). Measured at 16 spp, coverage 256: ≤ 0.1 % on
        // every scene (roughness-extremes +0.08 %, was +3.5 % with the LTC's α ≤ 1 table clamped;
        // grazing-light −0.00 %).
        let reference = reference(&format!("stiff/{name}.exr"));
        let full = render_path(
            &path,
            &Opts {
                integrator: Some("ltc"),
                params: &["coveragesamples=256"],
                spp: Some(16),
                resolution: Some((64, 64)),
                ..Default::default()
            },
        );
        let rel = mean(&full.image) / mean(&reference) - 1.0;
        eprintln!("{name}: ltc vs pbrt-v3 mean {:+.2}%", rel * 100.0);
        assert!(rel.abs() < 0.01, "{name}: mean off by {:.2}%", rel * 100.0);
    }
}

/// `"shading" "pixel"` (the default: each surface seen in a pixel shaded at ⌈√m⌉ of its m
/// samples, the samples otherwise resolving visibility) against `"sample"` (every sample
/// shaded): identical at 1 spp (without the coverage floor); at more samples the same image up
/// to the variation of the shading inside a pixel, converging to it. Measured at 64², relative
/// RMSE at 16 → 64 spp: quad-cube 0.34 → 0.079 %, torus 0.66 → 0.155 %, two lights 0.28 →
/// 0.105 % (64's 0.23–0.37 of 16's). Bounds: 1 % at 16 spp, 0.22 % at 64, and 64's at most 0.45
/// of 16's. Shading each surface once at its central sample converged only partly (0.38 →
/// 0.18 %, 0.70 → 0.39 %, 0.37 → 0.25 %; ratios 0.47–0.67) and fails (issue 37). Pixel
/// shading takes at least `coveragesamples` (default 16) camera samples.
#[test]
fn pixel_shading_matches_sample_shading() {
    for name in ["quad-cube", "torus-nonconvex", "two-lights-metal"] {
        let path = scene(&format!("suite/ltc/{name}.pbrt"));
        let o = |spp, params: &'static [&'static str]| Opts {
            integrator: Some("ltc"),
            params,
            spp: Some(spp),
            resolution: Some((64, 64)),
            ..Default::default()
        };
        let p1 = render_path(&path, &o(1, &["shading=pixel", "coveragesamples=1"]));
        let s1 = render_path(&path, &o(1, &["shading=sample"]));
        assert_eq!((p1.spp, s1.spp), (1, 1));
        assert_eq!(p1.image.data, s1.image.data, "{name}: 1 spp must be identical");
        let (p, s) = (render_path(&path, &o(16, &["shading=pixel"])), render_path(&path, &o(16, &["shading=sample"])));
        // The floor: 1 spp asked, 16 taken, the 16-spp image.
        let floor = render_path(&path, &o(1, &[]));
        assert_eq!(floor.spp, 16, "{name}: the coverage floor");
        assert_eq!(floor.image.data, p.image.data, "{name}: 1 spp raised to 16 is the 16-spp image");
        let e = rmse(&p.image, &s.image) / mean(&s.image);
        eprintln!("{name}: pixel vs sample shading, 16 spp, relative RMSE {e:.5}");
        assert!(e < 0.01, "{name}: relative RMSE {e}");
        let bad = p.image.data.iter().filter(|v| !v.is_finite() || **v < 0.0).count();
        assert_eq!(bad, 0);
        let (p, s) = (render_path(&path, &o(64, &["shading=pixel"])), render_path(&path, &o(64, &["shading=sample"])));
        let e64 = rmse(&p.image, &s.image) / mean(&s.image);
        eprintln!("{name}: pixel vs sample shading, 64 spp, relative RMSE {e64:.5}");
        assert!(e64 < 0.0022, "{name}: relative RMSE {e64} at 64 spp");
        assert!(e64 <= 0.45 * e, "{name}: pixel shading does not converge: {e} at 16 spp, {e64} at 64");
    }
}

/// `stiff/scaled-1e4` and `scaled-1e-4` are `ltc/quad-cube` scaled: the same image.
#[test]
fn scaled_scenes_render_the_same() {
    let o = Opts { integrator: Some("ltc"), spp: Some(2), resolution: Some((48, 48)), ..Default::default() };
    let base = render_path(&scene("suite/ltc/quad-cube.pbrt"), &o);
    for name in ["scaled-1e4", "scaled-1e-4"] {
        let r = render_path(&scene(&format!("suite/stiff/{name}.pbrt")), &o);
        let e = rmse(&r.image, &base.image) / mean(&base.image);
        eprintln!("{name}: relative RMSE against the unscaled image {e:.2e}");
        assert!(e < 1e-3, "{name}: relative RMSE {e}");
    }
}

/// Coincident geometry (an occluder sharing the light's edge, coplanar faces, duplicated
/// vertices, zero-area triangles): no speckles. A speckle is a pixel whose error against pbrt-v3
/// is far above its neighbours' (LTC's glossy approximation error varies smoothly): on pixels
/// whose 3×3 neighbourhood is smooth in the reference, the error stays below 5× the median error
/// of the neighbourhood (plus 1 % of the value).
#[test]
fn coincident_geometry_has_no_speckles() {
    let r = render_path(
        &scene("suite/stiff/coincident-geometry.pbrt"),
        // Every sample shaded: the visibility computation runs at 16× more points than with the
        // default one shading per pixel, and a single-point shading of a whole 64² pixel is not
        // what this test is about (see `pixel_shading_matches_sample_shading`).
        &Opts { integrator: Some("ltc"), spp: Some(16), params: &["shading=sample"], ..Default::default() },
    );
    let reference = reference("stiff/coincident-geometry.exr");
    let (w, h) = (64usize, 64usize);
    let lum = |img: &[f32], x: usize, y: usize| (0..3).map(|c| img[(y * w + x) * 3 + c] as f64).sum::<f64>();
    let err = |x: usize, y: usize| (lum(&r.image.data, x, y) - lum(&reference.data, x, y)).abs();
    let (mut checked, mut worst) = (0, 0.0f64);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let c = lum(&reference.data, x, y);
            let nb: Vec<(usize, usize)> = (0..9).map(|k| (x + k % 3 - 1, y + k / 3 - 1)).collect();
            let smooth = nb.iter().all(|&(i, j)| (lum(&reference.data, i, j) - c).abs() <= 0.1 * c.abs() + 1e-3);
            if !smooth || c <= 1e-2 {
                continue;
            }
            let mut e: Vec<f64> = nb.iter().filter(|&&(i, j)| (i, j) != (x, y)).map(|&(i, j)| err(i, j)).collect();
            e.sort_by(f64::total_cmp);
            let median = e[e.len() / 2];
            let ratio = err(x, y) / (5.0 * median + 0.01 * c + 1e-4);
            worst = worst.max(ratio);
            checked += 1;
            assert!(ratio <= 1.0, "speckle at ({x}, {y}): error {} vs neighbours' median {median}", err(x, y));
        }
    }
    eprintln!("coincident-geometry: {checked} pixels checked, worst error / bound {worst:.3}");
    assert!(checked > 500, "too few smooth pixels ({checked})");
}

/// Glossy receivers (pbrt-v3 plastic, metal): with `"glossy" "exact"` (the default: the LTC
/// integral plus the residual of pbrt-v3's own lobe by quadrature) the image mean is pbrt-v3's
/// to its noise: measured −0.03 % (quad-cube), +0.14 % (torus-nonconvex), +0.02 %
/// (two-lights-metal) at 8 spp, 2026-12-04 — asserted within 0.5 % (the measurement plus the
/// references' and 8 spp's anti-aliasing noise). The LTC alone (`"glossy" "ltc"`, the paper's
/// approximation) with the material's exact Fresnel at the LTC-weighted mean direction
/// (`"average"`) measured −0.05 %, −0.14 %, +0.02 % (asserted within 0.5 % as well), and must
/// not be worse than Heitz et al.'s Schlick split, which misses pbrt-v3 plastic's dielectric
/// Fresnel (η 1.5 → 1): −6.4 %, −6.7 %, −0.10 %.
#[test]
fn glossy_scenes_are_close_to_pbrt_v3() {
    for name in ["quad-cube", "torus-nonconvex", "two-lights-metal"] {
        let reference = reference(&format!("ltc/{name}.exr"));
        let mut rels = Vec::new();
        for params in [&["glossy=exact"][..], &["glossy=ltc", "fresnel=average"], &["glossy=ltc", "fresnel=schlick"]] {
            let r = render_path(
                &scene(&format!("suite/ltc/{name}.pbrt")),
                &Opts { integrator: Some("ltc"), params, spp: Some(8), ..Default::default() },
            );
            let rel = mean(&r.image) / mean(&reference) - 1.0;
            eprintln!(
                "{name}: ltc ({}) vs pbrt-v3: mean {:+.3}%, RMSE {:.3e}",
                params.join(" "),
                rel * 100.0,
                rmse(&r.image, &reference)
            );
            rels.push(rel.abs());
        }
        assert!(rels[0] < 0.005, "{name}: ltc (exact lobes) mean off by {:.2}%", rels[0] * 100.0);
        assert!(rels[1] < 0.005, "{name}: ltc (LTC alone, average Fresnel) mean off by {:.2}%", rels[1] * 100.0);
        assert!(rels[1] <= rels[2] + 1e-3, "{name}: the average Fresnel should not be worse than Schlick's split");
    }
}

/// Bit-identical with 1 and 2 threads, from crops, and from render to render (each render
/// builds its own hash maps: a light outline or silhouette that started at a map's first key
/// changed the last bits between runs): a planar light (coincident geometry) and a convex one
/// (the truncated cone of two-lights-metal), with pixel and sample shading, shadowed and not.
#[test]
fn threads_crops_and_runs_are_bit_identical() {
    for name in ["suite/stiff/coincident-geometry.pbrt", "suite/ltc/two-lights-metal.pbrt"] {
        let path = scene(name);
        for params in [&[][..], &["shading=sample"][..], &["shadows=false"][..]] {
            let opts = |threads, crop| Opts {
                integrator: Some("ltc"),
                params,
                spp: Some(2),
                resolution: Some((40, 36)),
                threads,
                crop,
                ..Default::default()
            };
            assert_deterministic(40, 36, |threads, crop| render_path(&path, &opts(threads, crop)));
            let (a, b) = (render_path(&path, &opts(2, None)), render_path(&path, &opts(2, None)));
            assert_same(&a.image.data, &b.image.data, "two renders");
        }
    }
}

/// A closed box around the receiver (and the camera): a light outside it is hidden from every
/// point inside, whichever way the box is wound and in every mode (a convex occluder's
/// silhouette is empty from inside: its triangles decide); a light inside lights it as
/// `directlighting` does (matte: exact).
#[test]
fn closed_box_around_the_receiver() {
    let outward = "0 2 1 0 3 2 4 5 6 4 6 7 0 1 5 0 5 4 3 7 6 3 6 2 0 4 7 0 7 3 1 2 6 1 6 5";
    let inward: String = outward
        .split(' ')
        .collect::<Vec<_>>()
        .chunks(3)
        .map(|t| format!("{} {} {}", t[0], t[2], t[1]))
        .collect::<Vec<_>>()
        .join(" ");
    let scene = |indices: &str, light_y: f32| {
        format!(
            r#"LookAt 0 0.5 -0.8  0 0.2 0.5  0 1 0
Camera "perspective" "float fov" [ 60 ]
Film "image" "integer xresolution" [ 24 ] "integer yresolution" [ 24 ]
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 10 10 10 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point P" [ -0.3 {light_y} -0.3  0.3 {light_y} -0.3  0.3 {light_y} 0.3  -0.3 {light_y} 0.3 ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]
  Shape "trianglemesh" "point P" [ -1 0 -1  1 0 -1  1 2 -1  -1 2 -1  -1 0 1  1 0 1  1 2 1  -1 2 1 ]
    "integer indices" [ {indices} ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.8 0.8 0.8 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point P" [ -0.9 0.1 -0.9  -0.9 0.1 0.9  0.9 0.1 0.9  0.9 0.1 -0.9 ]
AttributeEnd
WorldEnd
"#
        )
    };
    let o =
        |i, params, spp| Opts { integrator: Some(i), params, spp: Some(spp), resolution: None, ..Default::default() };
    let modes: [&[&str]; 4] =
        [&[], &["mode=silhouette"], &["mode=per-triangle"], &["mode=per-triangle", "mergeoccluders=false"]];
    for (wind, indices) in [("outward", outward), ("inward", inward.as_str())] {
        let outside = scene(indices, 3.0);
        let inside = scene(indices, 1.8);
        let dl = render_text(&inside, &o("directlighting", &[], 256));
        assert!(mean(&dl.image) > 0.05, "the inner light must light the box");
        for params in modes {
            let dark = render_text(&outside, &o("ltc", params, 4));
            let max = dark.image.data.iter().fold(0.0f32, |m, v| m.max(*v));
            assert_eq!(max, 0.0, "{wind} {params:?}: light outside the box reaches inside ({max})");
            let lit = render_text(&inside, &o("ltc", params, 4));
            let rel = mean(&lit.image) / mean(&dl.image) - 1.0;
            eprintln!("{wind} {params:?}: light inside, ltc vs directlighting mean {:+.3}%", rel * 100.0);
            assert!(rel.abs() < 0.01, "{wind} {params:?}: mean off by {:.3}%", rel * 100.0);
        }
    }
}

/// Perfectly specular surfaces (a mirror, smooth glass) are followed as `directlighting` follows
/// them, up to `maxdepth`, and what they reach is shaded by `ltc`'s own method: on the public
/// mirror and glass dragons (infinite light) and on an area-lit scene with shadows seen in a
/// mirror and through a glass ball, the image mean and the mean over the specular objects'
/// pixels are within 2 % of `directlighting`'s, and no specular pixel is black. With
/// `maxdepth` 1 nothing is followed: the mirror and glass pixels are black (up to
/// their edges), as under `directlighting`.
#[test]
fn specular_chains_match_directlighting() {
    for s in [specular::dragon("mirror"), specular::dragon("glass"), specular::area_lit()] {
        specular::assert_matches_directlighting(&s, "ltc", &[], (64, 256, 32), 0.02);
    }
    let s = specular::area_lit();
    let spec = s.specular_pixels(32);
    let (one, five) = (s.render("ltc", &["maxdepth=1"], 16, 32), s.render("ltc", &[], 16, 32));
    let (m1, m5) = (specular::mean_over(&one, &spec), specular::mean_over(&five, &spec));
    eprintln!("area-lit ltc: specular pixels' mean {m1:.5} with maxdepth 1, {m5:.5} with 5");
    // (Not exactly 0: a pixel's edge samples may see past the objects.)
    assert!(m1 < 0.02 * m5, "maxdepth 1: the specular pixels' mean is {m1}, with maxdepth 5 {m5}");
}

/// The whole scene turned by 37° about (1, 2, 3) renders the same `ltc` image: the analytic
/// shading is noise-free, so only rounding may differ. Pixel shading's choices (which camera
/// sample shades a cluster, whether a cluster is near a light) depended on world-space axes —
/// relative RMSE 1.9e-3 (Cornell box) and 5.1e-3 (intersecting occluders) before, 3.6e-4 and
/// 2.6e-5 after (`penumbra stability SCENE -i ltc --variants rotate --resolution 32x32 --spp 4`).
#[test]
fn ltc_image_is_unchanged_by_rotating_the_scene() {
    for rel in ["public/wumpf-lightdam/scenes/cornell-box/scene.pbrt", "suite/stiff/intersecting-occluders.pbrt"] {
        let desc = penumbra_parser::parse_file(&scene(rel)).unwrap().scene;
        let mut turned = desc.clone();
        turned.transform_world(&penumbra_parser::Transform::rotate(37.0, [1.0, 2.0, 3.0]).unwrap());
        let o = Opts { integrator: Some("ltc"), spp: Some(4), resolution: Some((32, 32)), ..Default::default() };
        let (a, b) = (render_desc(&desc, &o), render_desc(&turned, &o));
        let rel_rmse = rmse(&a.image, &b.image) / mean(&a.image);
        assert!(rel_rmse < 1e-3, "{rel}: relative RMSE {rel_rmse:.2e} between the scene and the scene rotated");
    }
}
