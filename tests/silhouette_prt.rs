//! `silhouette` `mode=prt` relit under a real environment map (issue 37 item 5): the SH
//! transfer channels, relit by `penumbra relight`'s projection of the scene's infinite light,
//! against `mode=shade` of the same camera samples, on the pixels that see geometry.

mod common;

use common::{render_text, root, Opts};
use penumbra::relight;
use penumbra_core::image::Image;
use penumbra_core::sh::ShOrder;
use penumbra_parser::DiagSink;

/// The suite scene `env/NAME.pbrt` with its map path made absolute (it is parsed from the
/// repository root) and, with `matte_only`, its one plastic material (a glossy lobe, which
/// `prt`'s Lambertian transfer cannot carry) replaced by a matte of the same `Kd`.
fn scene_text(name: &str, matte_only: bool) -> String {
    let text = std::fs::read_to_string(root().join(format!("scenes/suite/env/{name}.pbrt"))).unwrap();
    let text = text.replace("\"../textures/", "\"scenes/suite/textures/");
    if matte_only {
        let plastic =
            "Material \"plastic\" \"rgb Kd\" [ 0.1 0.2 0.5 ] \"rgb Ks\" [ 0.3 0.3 0.3 ] \"float roughness\" [ 0.05 ]";
        assert!(text.contains(plastic), "{name}: the plastic material changed");
        text.replace(plastic, "Material \"matte\" \"rgb Kd\" [ 0.1 0.2 0.5 ]")
    } else {
        text
    }
}

/// Signed mean error and RMSE of `relit` against `shade`, both relative to `shade`'s mean, over
/// the pixels whose one camera sample saw geometry (albedo ≠ 0 in `prt`'s channels; every
/// material of these scenes has a diffuse albedo), and that pixel count.
fn compare(prt: &Image, relit: &Image, shade: &Image) -> (f64, f64, usize) {
    let albedo: Vec<usize> = ["albedo.R", "albedo.G", "albedo.B"]
        .iter()
        .map(|c| prt.channels.iter().position(|x| x == c).expect("albedo channel"))
        .collect();
    let nc = prt.channels.len();
    let (mut sum_d, mut sum_d2, mut sum_s, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    for px in 0..prt.npixels() {
        if albedo.iter().all(|&c| prt.data[px * nc + c] == 0.0) {
            continue;
        }
        n += 1;
        for c in 0..3 {
            let (r, s) = (relit.data[px * 3 + c] as f64, shade.data[px * 3 + c] as f64);
            sum_d += r - s;
            sum_d2 += (r - s) * (r - s);
            sum_s += s;
        }
    }
    let mean = sum_s / (3 * n) as f64;
    ((sum_d / (3 * n) as f64) / mean, (sum_d2 / (3 * n) as f64).sqrt() / mean, n)
}

/// `prt` at `order` relit, and `shade`, of the scene `name` (one camera sample per pixel, so a
/// pixel is one shading point in both, `resolution` meridians): (mean error, RMSE, pixels).
fn relit_vs_shade(name: &str, matte_only: bool, order: usize, res: u32, meridians: usize) -> (f64, f64, usize) {
    let text = scene_text(name, matte_only);
    let m = format!("resolution={meridians}");
    let o = format!("shorder={order}");
    let opts = |params| Opts {
        integrator: Some("silhouette"),
        params,
        spp: Some(1),
        resolution: Some((res, res)),
        ..Default::default()
    };
    let (prt_params, shade_params) = (["mode=prt", &o, &m, "shading=sample"], ["mode=shade", &m, "shading=sample"]);
    let prt = render_text(&text, &opts(&prt_params)).channels;
    let shade = render_text(&text, &opts(&shade_params)).image;
    let warnings = DiagSink::new();
    let path = root().join(format!("scenes/suite/env/{name}.pbrt"));
    let light = relight::scene_lighting(&path, ShOrder::new(order).unwrap(), &warnings).unwrap();
    let relit = relight::relight(&prt, &light, 1.0).unwrap();
    compare(&prt, &relit, &shade)
}

/// The measurement behind docs/integrators/silhouette.md's table (`cargo test --release --test
/// silhouette_prt -- --ignored --nocapture`): relit `prt` against `shade` against SH order.
#[test]
#[ignore]
fn prt_relit_error_against_order() {
    for name in ["objects-studio", "objects-sky-sun"] {
        for matte_only in [false, true] {
            for order in [1, 2, 3, 4, 5, 6, 8, 10, 12, 16] {
                let (mean, rmse, n) = relit_vs_shade(name, matte_only, order, 64, 128);
                eprintln!(
                    "{name} matte_only={matte_only} order {order}: mean {:+.3} %, RMSE {:.3} % ({n} px)",
                    100.0 * mean,
                    100.0 * rmse
                );
            }
        }
    }
}

/// `prt` at its default order (3) relit under the studio map against `shade`, on the scene
/// with its plastic made matte (`prt`'s transfer is Lambertian: a glossy lobe is not in it).
/// Measured at 64², 1 spp, 128 meridians (the ignored test above; docs/integrators/silhouette.md):
/// order 3 mean −1.24 %, RMSE 9.34 % of the mean; order 8 −0.33 %, 3.21 %. Bounds: the
/// measurements plus about a tenth (|mean| 1.5 %, RMSE 10.5 % and 3.6 %): the RMSE is SH
/// truncation of the map (it falls with the order, 1.19 % at order 16) and must keep
/// falling; a rotation, sign or projection error would not shrink with the order.
#[test]
fn prt_relit_under_studio_matches_shade_to_the_truncation_of_its_order() {
    let (mean3, rmse3, n) = relit_vs_shade("objects-studio", true, 3, 64, 128);
    let (mean8, rmse8, _) = relit_vs_shade("objects-studio", true, 8, 64, 128);
    eprintln!("order 3: mean {mean3:+.4}, RMSE {rmse3:.4}; order 8: mean {mean8:+.4}, RMSE {rmse8:.4} ({n} px)");
    assert!(n > 2000, "{n} geometry pixels");
    assert!(mean3.abs() < 0.015 && rmse3 < 0.105, "order 3: mean {mean3}, RMSE {rmse3}");
    assert!(mean8.abs() < 0.015 && rmse8 < 0.036, "order 8: mean {mean8}, RMSE {rmse8}");
}

/// `prt` on a scene with a glossy material says the relit image lacks its lobes (naming the
/// material), and says nothing when every material is matte.
#[test]
fn prt_warns_that_glossy_lobes_are_not_relit() {
    let warned = |matte_only| {
        let o = Opts {
            integrator: Some("silhouette"),
            params: &["mode=prt", "resolution=16"],
            spp: Some(1),
            resolution: Some((8, 8)),
            ..Default::default()
        };
        let r = render_text(&scene_text("objects-studio", matte_only), &o);
        r.warnings.iter().any(|w| w.contains("diffuse albedo only") && w.contains("plastic"))
    };
    assert!(warned(false), "no warning for the plastic sphere");
    assert!(!warned(true), "a warning without glossy materials");
}
