//! Issue 42: `ltc`'s cost per shading point is bounded. A light that cannot be taken whole (here
//! a tessellated sphere light sunk into the floor: the floor reaches into the ball, so its cap
//! minus occluders is not exact) would be integrated triangle by triangle, each triangle with its
//! own occluder search; over `LIGHT_TRIANGLE_BUDGET` facing triangles that light at that point is
//! shaded by `directlighting`'s estimator instead (the point's other lights stay analytic),
//! counted in the stats and reported once, naming the light.
//!
//! The checks are counters, not times: without the bound, `ltc_light_triangles` counts thousands
//! of triangles per point (6 300 of the sphere's 12 600 face a point on the wall), and no point is
//! counted over budget.

mod common;

use common::{render_path, root, Opts};
use penumbra_integrators::common::ltc_shading::LIGHT_TRIANGLE_BUDGET;

fn counter(r: &common::Render, name: &str) -> f64 {
    *r.stats.counters.get(name).unwrap_or_else(|| panic!("no counter {name}"))
}

#[test]
fn sunk_sphere_light_is_bounded_and_falls_back_to_directlighting() {
    let path = root().join("tests/data/ltc-budget/sunk-sphere.pbrt");
    let o = Opts { integrator: Some("ltc"), resolution: Some((32, 24)), threads: 2, ..Opts::default() };
    let r = render_path(&path, &o);
    let points = counter(&r, "ltc_points");
    let over = counter(&r, "ltc_over_budget_lights_sphere");
    let tris = counter(&r, "ltc_light_triangles");
    assert!(over > 0.0, "no (point, light) counted over budget (points {points})");
    // Every analytic point stays within the budget.
    assert!(
        tris <= LIGHT_TRIANGLE_BUDGET as f64 * points,
        "{tris} light triangles integrated one by one over {points} points"
    );
    // The floor's own points still take the cap whole (the floor cannot shadow a point on it).
    assert!(counter(&r, "ltc_whole_lights") > 0.0);
    let warned: Vec<_> =
        r.warnings.iter().filter(|w| w.contains("directlighting's estimator shaded those lights")).collect();
    assert_eq!(warned.len(), 1, "{:?}", r.warnings);
    assert!(warned[0].contains(&format!("{over} (shading point, light) pairs")), "{}", warned[0]);
    assert!(warned[0].contains("lights: \"sphere\" at "), "{}", warned[0]);
    assert!(warned[0].contains(&format!("sunk-sphere.pbrt:16:3 ({over} points)")), "{}", warned[0]);
    // Predicted at the render's start: the floor's box reaches into the sphere.
    assert!(r.warnings.iter().any(|w| w.contains("may take the slow path")), "{:?}", r.warnings);
    // The fallback is directlighting's estimator: the image agrees with directlighting's. Both at
    // 64 spp on 32×24; the tolerance is 4 standard errors of the two means' difference, from the
    // per-pixel variances both renders report.
    let dl = render_path(&path, &Opts { integrator: Some("directlighting"), spp: Some(64), ..o });
    let ours = render_path(&path, &Opts { spp: Some(64), ..o });
    let n = ours.image.data.len() as f64;
    let var_mean = |v: &common::Render| v.variance.data.iter().map(|x| *x as f64).sum::<f64>() / (n * n);
    let se = (var_mean(&dl) + var_mean(&ours)).sqrt();
    let (a, b) = (common::mean(&ours.image), common::mean(&dl.image));
    assert!((a - b).abs() <= 4.0 * se + 1e-9, "ltc mean {a} vs directlighting {b} (se {se})");
}

/// The cost bound is per (point, light): where the sunk sphere goes to `directlighting`'s
/// estimator, a quad light above is still taken whole (every point takes it whole: the pairs add
/// up), and the image agrees with `directlighting`'s (were the quad dropped or counted twice at
/// those points, the mean would move by far more than the noise).
#[test]
fn over_budget_light_leaves_the_other_lights_analytic() {
    let path = root().join("tests/data/ltc-budget/sunk-sphere-quad.pbrt");
    let o = Opts { integrator: Some("ltc"), resolution: Some((32, 24)), threads: 2, spp: Some(64), ..Opts::default() };
    let r = render_path(&path, &o);
    let points = counter(&r, "ltc_points");
    let over = counter(&r, "ltc_over_budget_lights_sphere");
    assert!(over > 0.0);
    let by_tris: f64 = ["ltc_by_triangles_shape", "ltc_by_triangles_loops", "ltc_by_triangles_occluder"]
        .iter()
        .map(|c| counter(&r, c))
        .sum();
    assert_eq!(counter(&r, "ltc_whole_lights") + by_tris + over, 2.0 * points);
    assert!(counter(&r, "ltc_whole_lights") >= points, "the quad light is taken whole everywhere");
    let dl = render_path(&path, &Opts { integrator: Some("directlighting"), ..o });
    let n = r.image.data.len() as f64;
    let var_mean = |v: &common::Render| v.variance.data.iter().map(|x| *x as f64).sum::<f64>() / (n * n);
    let se = (var_mean(&dl) + var_mean(&r)).sqrt();
    let (a, b) = (common::mean(&r.image), common::mean(&dl.image));
    assert!((a - b).abs() <= 4.0 * se + 1e-9, "ltc mean {a} vs directlighting {b} (se {se})");
}

/// The mean of rows `y0..y1` of `img` (all channels).
fn rows_mean(img: &penumbra_core::image::Image, y0: usize, y1: usize) -> f64 {
    let w = img.width as usize * 3;
    let v = &img.data[y0 * w..y1 * w];
    v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64
}

/// Veach's MIS plates (`scenes/mis-plates`, the scene of issue 42): every shading point takes
/// every sphere light whole (its cap, occluders clipped to the silhouette plane), none goes
/// triangle by triangle or over budget; the plates α 0.05 and 0.1 and the floor (the image's
/// lower half) agree with pbrt-v3 (`tests/data/mis-plates/reference-blocks8.pfm`, 128 spp at
/// 256×192, 8×8 block means) within 1 % — the goal; measured −0.0 % at 64×48 (the whole
/// 256×192 image: +0.33 %, see docs/integrators/ltc.md). The upper half is not compared at
/// 64×48: the lights seen directly (r 0.033 at L 902 covers a twentieth of a pixel) and their
/// highlights on the α 0.005 and 0.02 plates are sub-pixel, and 16 camera samples leave them
/// ±3–12 % noisy at this resolution (`directlighting` at 64 spp: ±0.6–1.8 %).
#[test]
fn mis_plates_lights_are_taken_whole_and_match_pbrt_v3() {
    let path = common::scene("mis-plates/mis-plates.pbrt");
    let o = Opts { integrator: Some("ltc"), resolution: Some((64, 48)), spp: Some(16), threads: 2, ..Opts::default() };
    let r = render_path(&path, &o);
    for c in [
        "ltc_by_triangles_shape",
        "ltc_by_triangles_loops",
        "ltc_by_triangles_occluder",
        "ltc_over_budget_lights_sphere",
    ] {
        assert_eq!(counter(&r, c), 0.0, "{c}");
    }
    assert_eq!(counter(&r, "ltc_whole_lights"), 4.0 * counter(&r, "ltc_points"));
    // Nothing predicted a slow path either (the backdrop's box holds the lights, its triangles
    // do not reach into them).
    assert!(!r.warnings.iter().any(|w| w.contains("slow path")), "{:?}", r.warnings);
    let reference =
        penumbra_core::image::read(root().join("tests/data/mis-plates/reference-blocks8.pfm")).expect("ref");
    assert_eq!((reference.width, reference.height), (32, 24));
    let (ours, theirs) = (rows_mean(&r.image, 24, 48), rows_mean(&reference, 12, 24));
    let rel = ours / theirs - 1.0;
    assert!(rel.abs() < 0.01, "lower half: ltc {ours} vs pbrt-v3 {theirs} ({:+.2} %)", rel * 100.0);
}

/// The difference of two renders' image means against 4 standard errors of it, from the
/// per-pixel variances both report.
fn assert_means_agree(what: &str, a: &common::Render, b: &common::Render) {
    let n = a.image.data.len() as f64;
    let var_mean = |v: &common::Render| v.variance.data.iter().map(|x| *x as f64).sum::<f64>() / (n * n);
    let se = (var_mean(a) + var_mean(b)).sqrt();
    let (ma, mb) = (common::mean(&a.image), common::mean(&b.image));
    assert!((ma - mb).abs() <= 4.0 * se + 1e-9, "{what}: mean {ma} vs directlighting {mb} (se {se})");
    eprintln!("{what}: mean {ma} vs directlighting {mb} ({:+.2} %, {:.2} se)", (ma / mb - 1.0) * 100.0, (ma - mb) / se);
}

/// `ratio`'s unshadowed `U` had no cost bound (it bounded occluder searches, and `U` has none):
/// a light of no simple shape was integrated triangle by triangle whatever its size. Here
/// (`corrugated.pbrt`: a two-sided sheet of 400 triangles, all facing every point) every point
/// leaves the sheet to ratio's stochastic estimate (its light and BRDF samples, MIS-weighted,
/// shadowed: `directlighting`'s estimator with N samples), added as is, outside the ratio;
/// counted and reported as `ltc`'s. Before: `ltc_light_triangles` 400 per point, nothing over
/// budget, no warning.
#[test]
fn ratio_bounds_its_unshadowed_light_triangles() {
    let path = root().join("tests/data/ltc-budget/corrugated.pbrt");
    let o =
        Opts { integrator: Some("ratio"), resolution: Some((32, 24)), threads: 2, spp: Some(64), ..Opts::default() };
    let r = render_path(&path, &o);
    let points = counter(&r, "ltc_points");
    let over = counter(&r, "ltc_over_budget_lights_triangles");
    assert!(points > 0.0 && over == points, "over budget {over} of {points} points");
    assert_eq!(counter(&r, "ltc_light_triangles"), 0.0);
    let warned: Vec<_> =
        r.warnings.iter().filter(|w| w.contains("directlighting's estimator shaded those lights")).collect();
    assert_eq!(warned.len(), 1, "{:?}", r.warnings);
    assert!(warned[0].starts_with("ratio: "), "{}", warned[0]);
    // Predicted at the render's start.
    assert!(r.warnings.iter().any(|w| w.contains("may take the slow path")), "{:?}", r.warnings);
    let dl = render_path(&path, &Opts { integrator: Some("directlighting"), ..o });
    assert_means_agree("ratio", &r, &dl);
}

/// More light groups than a 64-bit mask: `many-lights.pbrt` has 69 small quad lights and, as
/// the 70th group, corrugated.pbrt's 400-triangle sheet. Only the sheet goes to the estimator at
/// a point; the 69 quads stay analytic there (every (point, light) pair is either whole or over
/// budget). Before, groups from the 64th on had no bit in the mask and such a point went to the
/// estimator whole (`ltc_over_budget_points`), with nothing counted per light.
#[test]
fn more_than_64_lights_leave_only_the_over_budget_one_to_the_estimator() {
    let path = root().join("tests/data/ltc-budget/many-lights.pbrt");
    let o = Opts { integrator: Some("ltc"), resolution: Some((32, 24)), threads: 2, spp: Some(64), ..Opts::default() };
    let r = render_path(&path, &o);
    let points = counter(&r, "ltc_points");
    let over = counter(&r, "ltc_over_budget_lights_triangles");
    assert!(points > 0.0 && over == points, "over budget {over} of {points} points");
    assert_eq!(counter(&r, "ltc_whole_lights"), 69.0 * points);
    let warned: Vec<_> =
        r.warnings.iter().filter(|w| w.contains("directlighting's estimator shaded those lights")).collect();
    assert_eq!(warned.len(), 1, "{:?}", r.warnings);
    assert!(warned[0].contains("many-lights.pbrt:"), "{}", warned[0]);
    let dl = render_path(&path, &Opts { integrator: Some("directlighting"), ..o });
    assert_means_agree("ltc", &r, &dl);
    // ratio: the same split (its sample groups keep the shader's group numbers).
    let rr = render_path(&path, &Opts { integrator: Some("ratio"), spp: Some(16), ..o });
    let (points, over) = (counter(&rr, "ltc_points"), counter(&rr, "ltc_over_budget_lights_triangles"));
    assert!(points > 0.0 && over == points, "ratio: over budget {over} of {points} points");
    assert_eq!(counter(&rr, "ltc_whole_lights"), 69.0 * points);
}
