//! Issue 42: `ltc`'s cost per shading point is bounded. A light that cannot be taken whole (here
//! a tessellated sphere light sunk into the floor: the floor reaches into the ball, so its cap
//! minus occluders is not exact) would be integrated triangle by triangle, each triangle with its
//! own occluder search; over `LIGHT_TRIANGLE_BUDGET` facing triangles the point is shaded by
//! `directlighting`'s estimator instead, counted in the stats and reported once.
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
    let over = counter(&r, "ltc_over_budget_points");
    let tris = counter(&r, "ltc_light_triangles");
    assert!(over > 0.0, "no point counted over budget (points {points})");
    // Every analytic point stays within the budget.
    assert!(
        tris <= LIGHT_TRIANGLE_BUDGET as f64 * points,
        "{tris} light triangles integrated one by one over {points} points"
    );
    // The floor's own points still take the cap whole (the floor cannot shadow a point on it).
    assert!(counter(&r, "ltc_whole_lights") > 0.0);
    let warned: Vec<_> = r.warnings.iter().filter(|w| w.contains("directlighting's estimator shaded them")).collect();
    assert_eq!(warned.len(), 1, "{:?}", r.warnings);
    assert!(warned[0].contains(&format!("{over} shading points")), "{}", warned[0]);
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
