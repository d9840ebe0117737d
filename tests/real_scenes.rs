//! Real pbrt-v3 scenes as pbrt-v3 renders them (issue 34): the scenes of `scenes/real/` against
//! the real pbrt-v3's renders of them (`tests/data/real-references/`, made by
//! `tools/render_real_references.py` with each scene's own sampler, sample count and
//! resolution — pbrt-v3's image depends on both through its ray differentials), so these
//! tests run on a fresh clone.
//!
//! - images: every PNG/TGA/EXR/PFM layout pbrt-v3's `ReadImage` reads (`image-formats`);
//! - orientation: `ReverseOrientation` and mirroring transforms on disk, sphere, cylinder and
//!   triangle-mesh area lights, with and without normals, one- and two-sided;
//! - ray differentials: an image-bumped sphere, a box of noise textures, a trilinear/EWA
//!   checkerboard at a grazing angle, mirror and glass spheres over a checkerboard, the
//!   orthographic and environment cameras, lookups at the pyramid's coarse levels (a 90×50
//!   image, every wrap mode, quadrics and a plane to the horizon at 4 spp) — each through `directlighting` and, where their
//!   expected images are the same, `whitted`, `path` (maxdepth 1) and `ltc`;
//! - sphere lights sampled by their cone, and quadric lights under scales that pbrt-v3 samples
//!   in object space.
//!
//! Tolerances: the image mean within 1 % (the check), values and 8×8 regions within
//! the noise of both images (ours estimated per pixel, the reference's taken equal to ours:
//! same sampler, same sample count; see `common::assert_matches_reference`).

mod common;
use common::*;
use penumbra_core::image::Image;

fn reference(name: &str) -> Image {
    penumbra_core::image::read(root().join(format!("tests/data/real-references/{name}.exr")))
        .unwrap()
        .select_channels(&["R", "G", "B"])
        .unwrap()
}

/// Renders `scenes/real/NAME.pbrt` as written (its sampler, sample count and resolution) with
/// `integrator` and its `params`, and compares it with pbrt-v3's `directlighting` reference.
fn check_with(name: &str, integrator: &str, params: &[&str]) -> Render {
    let ours = render_path(
        &scene(&format!("real/{name}.pbrt")),
        &Opts { integrator: Some(integrator), params, resolution: None, ..Default::default() },
    );
    let reference = reference(name);
    let label = format!("{name} ({integrator})");
    assert_matches_reference(&label, &ours, &reference, 1.0, 0.01);
    assert_regions_match(&label, &ours, &reference, 1.0, 8);
    ours
}

fn check(name: &str) -> Render {
    check_with(name, "directlighting", &[])
}

#[test]
fn images_of_every_layout_read_as_pbrt_v3_reads_them() {
    let r = check("image-formats");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

/// The decompression guard refuses a texture whose decoded size exceeds the cap, naming the
/// file, its size and the cap; the render fails cleanly and writes nothing.
#[test]
fn decompression_guard_names_the_file_and_the_cap() {
    let dir = cli_dir("real-guard");
    let out = dir.join("out.exr");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .current_dir(&dir)
        .env("PENUMBRA_MAX_IMAGE_BYTES", "2000")
        .args(["render", "-q", "--spp", "1"])
        .arg(scene("real/image-formats.pbrt"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("grey1.png") && err.contains("32×32×3") && err.contains("2000-byte limit"), "{err}");
    assert!(err.contains("PENUMBRA_MAX_IMAGE_BYTES"), "{err}");
    assert!(!out.exists());
}

#[test]
fn reverse_orientation_and_mirrors_on_quadric_lights() {
    for name in ["orientation-disk", "orientation-sphere", "orientation-cylinder"] {
        check(name);
    }
}

#[test]
fn reverse_orientation_and_mirrors_on_triangle_lights() {
    for name in ["orientation-triangles", "orientation-normals", "orientation-twosided"] {
        check(name);
    }
}

#[test]
fn ray_differentials_filter_textures_and_bump_maps() {
    for name in ["bump-image-sphere", "noise-box", "filter-plane"] {
        check(name);
    }
}

/// Reflection and refraction carry the differentials (pbrt-v3's `SpecularReflect`/`Transmit`):
/// `whitted` follows the same specular chains as `directlighting` (same expected image).
/// Lookups at large footprints reach the pyramid's coarse and top levels (40×40 pixels at
/// 4 spp): EWA and trilinear, repeat/clamp/black wraps, on a sphere, a cylinder, a disk and a
/// plane to the horizon, with a 90×50 image that pbrt-v3 resamples to 128×64 first. `whitted`
/// shades these matte surfaces as `directlighting` does (same expected image), and was the
/// integrator of the public scenes where a harness bug once showed a texture mismatch.
#[test]
fn texture_filtering_at_coarse_pyramid_levels() {
    // The same sampler draws the same camera samples as pbrt-v3 here, so the images agree far
    // below their noise: RMSE 0.79 % of the mean measured. Broken on purpose: box instead of
    // Lanczos resampling of the 90×50 image gives 2.29 % (only this bound sees it), a trilinear
    // filter twice as wide (pbrt-v3 before its commit aaa552a) 5.8 %, EWA's level chosen by the
    // major axis 8.9 %, the black wrap clamping 28 %.
    let ours = check("mip-coarse");
    let reference = reference("mip-coarse");
    let n = reference.data.len() as f64;
    let mse =
        ours.image.data.iter().zip(&reference.data).map(|(a, b)| (*a as f64 - *b as f64).powi(2)).sum::<f64>() / n;
    let rel = mse.sqrt() / (reference.data.iter().map(|v| *v as f64).sum::<f64>() / n);
    eprintln!("mip-coarse (directlighting): RMSE {:.2} % of the mean", 100.0 * rel);
    assert!(rel < 0.015, "mip-coarse: RMSE {:.2} % of the mean (measured 0.79 %)", 100.0 * rel);
    check_with("mip-coarse", "whitted", &[]);
}

#[test]
fn ray_differentials_through_specular_bounces() {
    check("specular-differentials");
    check_with("specular-differentials", "whitted", &[]);
}

#[test]
fn ray_differentials_of_orthographic_and_environment_cameras() {
    check("camera-orthographic");
    check("camera-environment");
}

/// Every integrator shades a camera ray's first surface with its differentials (the shared
/// `Scene::first_point`): `path` with one bounce and `whitted` see the same expected image as
/// `directlighting` in scenes without specular surfaces; `ltc` integrates the noise box's matte
/// walls under its area light exactly, so it must give `directlighting`'s image (its block
/// unbumped: `ltc` clamps the cosine at a bumped shading normal where pbrt-v3's BSDF takes its
/// absolute value, a separate matter). `ltc`'s image is nearly noise-free, so the noise is
/// `directlighting`'s.
#[test]
fn every_integrator_takes_the_camera_differentials() {
    check_with("filter-plane", "whitted", &[]);
    check_with("noise-box", "path", &["maxdepth=1"]);
    check_with("bump-image-sphere", "path", &["maxdepth=1"]);
    let text =
        std::fs::read_to_string(scene("real/noise-box.pbrt")).unwrap().replace(" \"texture bumpmap\" \"bump\"", "");
    let desc = penumbra_parser::parse_str(&text, "noise-box-unbumped", Some(&scene("real"))).unwrap().scene;
    let dl = render_desc(&desc, &Opts { resolution: None, spp: Some(64), ..Default::default() });
    let mut ltc =
        render_desc(&desc, &Opts { integrator: Some("ltc"), resolution: None, spp: Some(64), ..Default::default() });
    ltc.variance = dl.variance;
    assert_matches_reference("noise-box unbumped (ltc vs directlighting)", &ltc, &dl.image, 0.0, 0.01);
    assert_regions_match("noise-box unbumped (ltc vs directlighting)", &ltc, &dl.image, 0.0, 8);
}

#[test]
fn sphere_lights_sampled_by_their_cone() {
    check("sphere-lights");
}

/// pbrt-v3's scaled and partial quadric lights are reproduced by default, with a warning that
/// names the scale; `"string shapesampling" "physical"` gives the light the geometry emits: a
/// sphere of radius 2.5 scaled by 0.2 then renders as a sphere of radius 0.5.
#[test]
fn scaled_quadric_lights_as_pbrt_v3_and_physically() {
    let r = check("scaled-quadric-lights");
    for what in ["sphere scaled by 0.2000", "sphere scaled by 2.0000", "disk scaled by 0.5000", "partial sphere"] {
        assert!(r.warnings.iter().any(|w| w.contains(what) && w.contains("shapesampling")), "{what}: {:?}", r.warnings);
    }
    let scene_with = |light: &str| {
        format!(
            "LookAt 0 -6 4  0 0 0.5  0 0 1\nCamera \"perspective\" \"float fov\" [45]\n\
             Sampler \"halton\" \"integer pixelsamples\" [64]\n\
             Film \"image\" \"integer xresolution\" [32] \"integer yresolution\" [32]\nWorldBegin\n\
             AttributeBegin\nTranslate 0.5 0 1.5\n{light}\nAttributeEnd\n\
             Material \"matte\" \"rgb Kd\" [0.5 0.5 0.5]\n\
             Shape \"trianglemesh\" \"point P\" [-6 -6 0  6 -6 0  6 6 0  -6 6 0] \"integer indices\" [0 1 2 0 2 3]\n\
             Shape \"trianglemesh\" \"point P\" [-1 -1 0.8  1 -1 0.8  1 1 0.8  -1 1 0.8] \"integer indices\" [0 2 1 0 3 2]\n\
             WorldEnd\n"
        )
    };
    let o = Opts { resolution: None, sampler: Some("random"), ..Default::default() };
    let unscaled = render_text(
        &scene_with("AreaLightSource \"diffuse\" \"rgb L\" [4 4 4]\nShape \"sphere\" \"float radius\" [0.5]"),
        &o,
    );
    let physical = render_text(
        &scene_with(
            "Scale 0.2 0.2 0.2\nAreaLightSource \"diffuse\" \"rgb L\" [4 4 4] \"string shapesampling\" \"physical\"\n\
             Shape \"sphere\" \"float radius\" [2.5]",
        ),
        &o,
    );
    let pbrt = render_text(
        &scene_with(
            "Scale 0.2 0.2 0.2\nAreaLightSource \"diffuse\" \"rgb L\" [4 4 4]\nShape \"sphere\" \"float radius\" [2.5]",
        ),
        &o,
    );
    assert!(physical.warnings.is_empty(), "{:?}", physical.warnings);
    // Independent random-sampler renders: their means differ by noise alone (standard error
    // from the per-pixel variances).
    let se = |r: &Render| (r.variance.data.iter().map(|v| *v as f64).sum::<f64>()).sqrt() / r.image.data.len() as f64;
    let (mu, mp, mb) = (mean(&unscaled.image), mean(&physical.image), mean(&pbrt.image));
    let z = (mp - mu) / (se(&unscaled).powi(2) + se(&physical).powi(2)).sqrt();
    eprintln!("unscaled {mu:.5}, scaled physical {mp:.5} (z {z:.2}), scaled as pbrt-v3 {mb:.5}");
    assert!(z.abs() < 4.0, "physical scaled sphere {mp} vs unscaled {mu} (z = {z:.1})");
    assert!(mb > 2.0 * mu, "pbrt-v3's scaled sphere is several times brighter: {mb} vs {mu}");
}

/// Alpha cut-outs as pbrt-v3's `Triangle::Intersect`/`IntersectP` apply them, in closest-hit
/// and shadow queries alike: an image mask with (u, v) given, `shadowalpha` only, a procedural
/// mask on the default per-triangle (u, v) under a mirroring transform, a card cut out
/// entirely (it would shade most of the floor), fractional alpha (opaque) and a sphere
/// (pbrt-v3 reads no alpha there). `path` with one bounce sees the same expected image; `ltc`
/// cannot represent a cut-out in its analytic visibility, so it lights the scene with
/// directlighting's estimator (same expected image) and says so; `silhouette` and `shexp`
/// refuse the scene, naming the shape and its location, and write nothing.
#[test]
fn alpha_cutouts_in_closest_hit_and_shadow_queries() {
    let r = check("cutout-cards");
    assert!(r.warnings.iter().all(|w| w.contains("\"float alpha\" unused by shape \"sphere\"")), "{:?}", r.warnings);
    check_with("cutout-cards", "path", &["maxdepth=1"]);
    let ltc = check_with("cutout-cards", "ltc", &[]);
    assert!(
        ltc.warnings.iter().any(|w| w.contains("ltc: shape \"trianglemesh\" has an alpha cut-out")
            && w.contains("directlighting's estimator")),
        "{:?}",
        ltc.warnings
    );
    let dir = cli_dir("real-cutouts");
    let path = scene("real/cutout-cards.pbrt");
    outline_integrators_refuse(&dir, &path, "cutout-cards.pbrt:21:1", "cut-out");
}

/// `silhouette` and `shexp`, which build their visibility from the meshes' outlines, refuse the
/// scene at `path`: a failed render whose error is located `at` the shape, names `what` it is
/// and the `bool occluder` way out, and no image written.
fn outline_integrators_refuse(dir: &std::path::Path, path: &std::path::Path, at: &str, what: &str) {
    for integrator in ["silhouette", "shexp"] {
        let out = dir.join(format!("{integrator}.exr"));
        let o = penumbra(
            dir,
            &["render", "-q", "--spp", "1", "-i", integrator, path.to_str().unwrap(), "-o", out.to_str().unwrap()],
        );
        let err = stderr(&o);
        assert!(!o.status.success(), "{integrator}: {err}");
        assert!(err.contains(at) && err.contains(what) && err.contains("bool occluder"), "{integrator}: {err}");
        assert!(!out.exists(), "{integrator}");
    }
}

/// Camera motion blur (pbrt-v3's `AnimatedTransform` for `CameraToWorld`, the shutter over
/// `TransformTimes`): rotation and translation interpolated per camera ray. Without the motion
/// (the start keyframe only) the image is far from pbrt-v3's: several times the RMSE.
#[test]
fn camera_motion_blur_as_pbrt_v3() {
    let moving = check("camera-motion");
    assert!(moving.warnings.is_empty(), "{:?}", moving.warnings);
    let text = std::fs::read_to_string(scene("real/camera-motion.pbrt")).unwrap();
    let fixed = text.replace("ActiveTransform EndTime\nLookAt 1.2 -3.6 2.2  0.3 0 0.3  0.2 0 1\n", "");
    assert_ne!(fixed, text);
    let desc = penumbra_parser::parse_str(&fixed, "camera-fixed", Some(&scene("real"))).unwrap().scene;
    let still = render_desc(&desc, &Opts { resolution: None, ..Default::default() });
    let reference = reference("camera-motion");
    let (e_moving, e_still) = (rmse(&moving.image, &reference), rmse(&still.image, &reference));
    eprintln!("camera-motion RMSE vs pbrt-v3: moving {e_moving:.2e}, start keyframe only {e_still:.2e}");
    assert!(e_still > 4.0 * e_moving, "moving {e_moving} vs still {e_still}");
}

/// `text` with every `ActiveTransform EndTime … ActiveTransform All` block removed: the scene
/// at its start keyframes (what penumbra rendered before shapes moved).
fn without_motion(text: &str) -> String {
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        match line.trim() {
            "ActiveTransform EndTime" => skipping = true,
            "ActiveTransform All" if skipping => skipping = false,
            _ if !skipping => {
                out.push_str(line);
                out.push('\n');
            }
            _ => {}
        }
    }
    out
}

/// The RMSE against pbrt-v3 of `name` rendered at its start keyframes only, and the moving
/// render's: a shape left static must be far off.
fn assert_motion_matters(name: &str, moving: &Render, factor: f64) {
    let text = std::fs::read_to_string(scene(&format!("real/{name}.pbrt"))).unwrap();
    let fixed = without_motion(&text);
    assert_ne!(fixed, text);
    let desc = penumbra_parser::parse_str(&fixed, name, Some(&scene("real"))).unwrap().scene;
    let still = render_desc(&desc, &Opts { resolution: None, ..Default::default() });
    let reference = reference(name);
    let (e_moving, e_still) = (rmse(&moving.image, &reference), rmse(&still.image, &reference));
    eprintln!("{name} RMSE vs pbrt-v3: moving {e_moving:.2e}, start keyframes only {e_still:.2e}");
    assert!(e_still > factor * e_moving, "{name}: moving {e_moving} vs still {e_still}");
}

/// Shape motion blur (pbrt-v3's `TransformedPrimitive` of an animated shape): a killeroo that
/// slides and turns, a sphere that slides under the light (its shadow blurred: shadow rays
/// carry the camera ray's time), each intersected at the ray's time in its object space; the
/// sphere with an area light set is, as in pbrt-v3, not emissive, with pbrt-v3's warning.
/// Against pbrt-v3 with the strict tolerances of every scene here; the start keyframes alone
/// are several times as far. `path` (one bounce) gives the same expected image; `ltc` cannot
/// outline a moving occluder, so it lights everything with directlighting's estimator and says
/// so; `silhouette` and `shexp` refuse, naming the moving shape.
#[test]
fn shape_motion_blur_matches_pbrt_v3() {
    let r = check("shape-motion");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    let parsed = penumbra_parser::parse_file(&scene("real/shape-motion.pbrt")).unwrap();
    let messages: Vec<&str> = parsed.warnings.iter().map(|d| d.message.as_str()).collect();
    assert_eq!(messages, ["ignoring the current area light for an animated shape (as pbrt-v3)"]);
    assert_motion_matters("shape-motion", &r, 3.0);
    check_with("shape-motion", "path", &["maxdepth=1"]);
    let ltc = check_with("shape-motion", "ltc", &[]);
    assert!(
        ltc.warnings
            .iter()
            .any(|w| w.contains("ltc: shape \"sphere\" moves") && w.contains("directlighting's estimator")),
        "{:?}",
        ltc.warnings
    );
    let path = scene("real/shape-motion.pbrt");
    let text = std::fs::read_to_string(&path).unwrap();
    let line = text.lines().position(|l| l.contains("\"float radius\" [30]")).unwrap() + 1;
    outline_integrators_refuse(&cli_dir("real-motion"), &path, &format!("shape-motion.pbrt:{line}:"), "moves");
}

/// Object-instance motion blur (pbrt-v3's `TransformedPrimitive` over an animated instance's
/// hierarchy): one instance still, one sliding and turning, and inside the definition a box
/// with its own animated transform, composed with each instance's at the ray's time. Against
/// pbrt-v3 with the strict tolerances; the start keyframes alone are several times as far.
#[test]
fn instance_motion_blur_matches_pbrt_v3() {
    let r = check("instance-motion");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_motion_matters("instance-motion", &r, 3.0);
}

/// `nurbs` tessellated as pbrt-v3's `CreateNURBS` (30 × 30 evaluations over [u0, u1] ×
/// [v0, v1], normals from ∂p/∂u × ∂p/∂v, (u, v) the parameters): a bicubic patch with uneven
/// knots under a checkerboard in (u, v), a rational quarter cylinder ("Pw") cut by "u1", and an
/// emitting bilinear patch whose emitting side is that of ∂p/∂u × ∂p/∂v. A skipped NURBS
/// would leave the image black. Malformed knot vectors are errors at the parameter.
#[test]
fn nurbs_tessellated_as_pbrt_v3() {
    let r = check("nurbs");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    let dir = cli_dir("real-nurbs");
    let bad = dir.join("bad.pbrt");
    let text = std::fs::read_to_string(scene("real/nurbs.pbrt")).unwrap();
    let line = text.lines().position(|l| l.contains("[0 0 0 0 2 2 2 2]")).unwrap() + 1;
    std::fs::write(&bad, text.replace("[0 0 0 0 2 2 2 2]", "[0 0 0 2 2 2 2]")).unwrap();
    let o = penumbra(&dir, &["info", bad.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains(&format!("bad.pbrt:{line}:")) && err.contains("7 knots in \"uknots\", 4 control points + order 4"),
        "{err}"
    );
}

/// `curve` shapes intersected as pbrt-v3 intersects them (ray-aligned space, recursive
/// subdivision, the hit's width from the ray for ribbons): ribbons of every basis and degree
/// (`curve-ribbons`), ribbons seen and lit edge-on, where pbrt-v3 narrows them
/// (`curve-ribbon-edge`), flat curves facing each ray with splitdepth 0, 3 and 5
/// (`curve-flat`), and 360 cylinder curves with pbrt-v3's `hair` material (`curve-hair`),
/// each against pbrt-v3 with the strict tolerances of every scene here (mean within 1 %,
/// values and 8×8 regions within the noise). Measured figures: `docs/real-scenes.md`.
#[test]
fn curves_match_pbrt_v3() {
    for name in ["curve-ribbons", "curve-ribbon-edge", "curve-flat", "curve-hair"] {
        let r = check(name);
        assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
    }
}

/// Every integrator meets curves through the shared ray queries: `path` with one bounce sees
/// `directlighting`'s expected image; `ltc` cannot outline a curve in its analytic visibility,
/// so it lights the scene with directlighting's estimator (same expected image) and says so;
/// `silhouette` and `shexp` refuse, naming the curve and its location, and write nothing. An
/// area light on a curve (pbrt-v3 aborts: `Curve::Sample` is unimplemented) warns and emits
/// nothing; `Accelerator "embree"` with curves falls back to the BVH.
#[test]
fn curves_through_every_integrator() {
    check_with("curve-flat", "path", &["maxdepth=1"]);
    let ltc = check_with("curve-flat", "ltc", &[]);
    assert!(
        ltc.warnings
            .iter()
            .any(|w| w.contains("ltc: shape \"curve\" is a curve") && w.contains("directlighting's estimator")),
        "{:?}",
        ltc.warnings
    );
    let dir = cli_dir("real-curves-integrators");
    let path = scene("real/curve-flat.pbrt");
    let line =
        std::fs::read_to_string(&path).unwrap().lines().position(|l| l.starts_with("Shape \"curve\"")).unwrap() + 1;
    outline_integrators_refuse(&dir, &path, &format!("curve-flat.pbrt:{line}:1"), "is a curve");
    let text = std::fs::read_to_string(&path).unwrap();
    let lit = dir.join("lit.pbrt");
    let lit_text = text
        .replacen("Material \"matte\" \"rgb Kd\" [0.8 0.3 0.1]", "AreaLightSource \"diffuse\" \"rgb L\" [5 5 5]", 1)
        .replacen("WorldBegin", "Accelerator \"embree\"\nWorldBegin", 1);
    std::fs::write(&lit, lit_text).unwrap();
    let out = dir.join("lit.exr");
    let o = penumbra(&dir, &["render", "-q", "--spp", "1", lit.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("area light on a \"curve\"") && err.contains("does not emit"), "{err}");
    assert!(err.contains("Accelerator \"embree\"") && err.contains("\"bvh\""), "{err}");
}

/// Malformed curves are errors located at the parameter; an unknown type is pbrt-v3's
/// `cylinder` with a warning; normals on a non-ribbon are ignored with a warning; `splitdepth`
/// beyond 10 is clamped with a warning; `penumbra info` counts the curves.
#[test]
fn curve_parameters_as_pbrt_v3_reads_them() {
    let dir = cli_dir("real-curves");
    let text = std::fs::read_to_string(scene("real/curve-ribbons.pbrt")).unwrap();
    let line = text.lines().position(|l| l.contains("-1.3 0 0.05")).unwrap() + 1;
    let bad = dir.join("bad.pbrt");
    std::fs::write(&bad, text.replace("-1.3 0 0.05  ", "")).unwrap();
    let o = penumbra(&dir, &["info", bad.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains(&format!("bad.pbrt:{line}:")) && err.contains("6 control points"), "{err}");
    let odd = dir.join("odd.pbrt");
    let odd_text = text.replacen("\"string type\" \"ribbon\"", "\"string type\" \"tube\"", 1).replacen(
        "\"string type\" \"ribbon\"",
        "\"string type\" \"flat\" \"integer splitdepth\" [40]",
        1,
    );
    std::fs::write(&odd, odd_text).unwrap();
    let o = penumbra(&dir, &["info", odd.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains("unknown curve type \"tube\": using \"cylinder\""), "{out}");
    assert!(out.contains("only used with \"ribbon\" curves"), "{out}");
    assert!(out.contains("\"splitdepth\" 40 clamped to 10"), "{out}");
    assert!(out.contains("curve x3"), "{out}");
    assert!(out.contains("curve segments (from the text): 7"), "{out}");
}

/// pbrt-v3's hyperboloid is the implicit quadric fitted through `p2` and a point further along
/// `p1 → p2` (waist at z = 0), not the surface the segment sweeps: on `hyperboloids` (two
/// sheets, a one-sheet fit with other radii, a partial checkered one, and a waist-at-zero one)
/// the swept surface's image mean was −14.2 % from pbrt-v3's (RMSE 0.067); the fitted surface
/// with the segment's tangent in its normal, as pbrt-v3's ∂p/∂v, is +0.04 % (RMSE 6.6e-4). The
/// normal is also the one BSDFs decide reflection against: with the triangles' own normal
/// there, a one-sheet fit whose pbrt-v3 normal is 150° off the surface was +3.2 %.
#[test]
fn hyperboloids_as_pbrt_v3_fits_them() {
    let r = check("hyperboloids");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

/// pbrt-v3 shades its hyperboloid about ∂p/∂u × ∂p/∂v along the segment p1 → p2, up to 160°
/// off the surface, and offsets rays along that normal; a ray whose origin lands on the other
/// side of the surface from where it heads meets the surface at once and is blocked
/// (`SurfaceInteraction::ray_origin`). On `hyperboloid-inside` (all-shapes' first hyperboloid,
/// two bowls, close up under a constant sky; 48², 256 spp, pbrt-v3's `directlighting` reference)
/// penumbra let those rays through its tessellation: mean +2.30 %, 7 of 36 8×8 blocks beyond 5 %,
/// the worst +55.7 % (the lower bowl's inside). Deciding with the triangles' normals left rings
/// along the rows (worst +18.8 %); with the surface's smooth normal and a tenth of the usual
/// tessellation tolerance for hyperboloids: mean −0.20 %, worst block −5.34 %. That residual is
/// where pbrt-v3's choice rests on its floating-point error bounds (directions nearly tangent
/// to the surface, normals nearly in it), so the block bound is 8 %, not the noise.
#[test]
fn hyperboloid_rays_through_the_surface_are_blocked_as_in_pbrt_v3() {
    let ours = render_path(&scene("real/hyperboloid-inside.pbrt"), &Opts { resolution: None, ..Default::default() });
    let reference = reference("hyperboloid-inside");
    let (a, b) = (mean(&ours.image), mean(&reference));
    assert!((a / b - 1.0).abs() <= 0.01, "image mean {a} vs pbrt-v3's {b}");
    let worst = block_means(&ours.image)
        .iter()
        .zip(block_means(&reference))
        .map(|(o, t)| (o / t - 1.0).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "hyperboloid-inside (directlighting): mean {a:.6} vs pbrt-v3 {b:.6} ({:+.3} %), worst 8×8 block {:.2} %",
        100.0 * (a / b - 1.0),
        100.0 * worst
    );
    assert!(worst <= 0.08, "an 8×8 block {:.2} % off pbrt-v3", 100.0 * worst);
}

/// pbrt-v3's `realistic` camera with a lens file (`lenses/dgauss.50mm.dat`, a 50 mm double
/// Gauss almost wide open, focused at 5.5 m on a 35 mm film diagonal): rays traced through the
/// elements from the exit pupil's bounds, depth of field, vignetting and the cos⁴ × pupil-area
/// weight. `path` (one bounce) sees the weight through the same driver; `ratio` through its
/// weighted channels (`PixelEstimator::weight_channels`). Rendered as perspective (before),
/// the image was +78 % on the matrix's `camera-realistic` cell.
#[test]
fn realistic_camera_with_a_lens_file_as_pbrt_v3() {
    let r = check("realistic-dgauss");
    assert!(r.warnings.iter().all(|w| w.contains("simpleweighting")), "{:?}", r.warnings);
    check_with("realistic-dgauss", "path", &["maxdepth=1"]);
    check_with("realistic-dgauss", "ratio", &[]);
}

/// Subsurface in the regime of hackmad's `materials/subsurface.pbrt` (pbrt-v3's f11-15
/// figure), where a 64×32, 64-spp comparison had read −3.46 % on the mean and −40.4 % on an
/// 8×8 block: pbrt-v3's measured media by name at scale 1 (millimetre mean free paths in unit
/// spheres), rough interfaces without roughness remapping, an image-textured `kdsubsurface`
/// with mean free paths in metres, an importance-sampled environment map and a distant light,
/// through `path` at the scene's 1024 spp (sobol). That figure did not reproduce: pbrt-v3's own
/// 64-spp image of the hackmad scene differs from its 4096-spp one by up to 11 % in a block
/// (fireflies from the BSSRDF probes), penumbra's 64-spp images over six seeds by −0.27 % to
/// +0.37 % on the mean; penumbra at 1024 spp vs pbrt-v3 at 4096 spp there: mean +0.19 %
/// (95 % CI −0.11 %, +0.50 %), worst block −2.5 %, none significant (and +0.20 % vs pbrt-v3's
/// 800×400 render). Here, at 1024 spp on both: mean +0.04 % (95 % CI ±0.34 %), worst 8×8
/// block −2.1 %; with Apple's "scale" at 0.5 the mean moves −3.47 % and the test fails.
#[test]
fn measured_subsurface_media_as_pbrt_v3() {
    let r = check_with("subsurface-measured", "path", &[]);
    assert!(!r.warnings.iter().any(|w| w.contains("BSSRDF")), "{:?}", r.warnings);
}
