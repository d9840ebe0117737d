//! Checks every registered integrator must pass, run for each entry of
//! `penumbra_integrators::REGISTRY`, so a new integrator gets them by being registered:
//! finite, non-negative values on every stiff scene; bit-identical images across thread counts
//! and when assembled from crops; the same image when the whole scene (camera included) is
//! scaled by 1e4 and 1e-4.

mod common;
use common::*;
use penumbra_integrators::REGISTRY;

fn opts(integrator: &'static str, spp: u32, res: (u32, u32)) -> Opts<'static> {
    Opts { integrator: Some(integrator), spp: Some(spp), resolution: Some(res), ..Default::default() }
}

#[test]
fn every_integrator_is_finite_on_the_stiff_scenes() {
    for e in REGISTRY {
        for name in STIFF_SCENES {
            let r = render_path(&scene(&format!("suite/stiff/{name}.pbrt")), &opts(e.name, 2, (24, 24)));
            let bad = r.image.data.iter().filter(|v| !v.is_finite() || **v < 0.0).count();
            assert_eq!(bad, 0, "{} on stiff/{name}: {bad} non-finite or negative values", e.name);
            assert!(r.image.data.iter().any(|v| *v > 0.0), "{} on stiff/{name}: a black image", e.name);
        }
    }
}

#[test]
fn every_integrator_is_bit_identical_across_threads_and_crops() {
    // Two lights, a glossy receiver and occluders: every integrator's paths are exercised.
    let path = scene("suite/ltc/two-lights-metal.pbrt");
    for e in REGISTRY {
        eprintln!("{}", e.name);
        assert_deterministic(40, 36, |threads, crop| {
            render_path(&path, &Opts { threads, crop, ..opts(e.name, 4, (40, 36)) })
        });
    }
}

/// `stiff/scaled-1e4` and `scaled-1e-4` are `ltc/quad-cube` with world and camera scaled. The
/// same sample sequences see the same scene up to f32 rounding: the relative RMSE is a rounding
/// figure, not noise: measured 9e-9 (ambientocclusion) to 5.1e-7 (path) at 32² and 4 spp.
#[test]
fn every_integrator_is_scale_invariant() {
    for e in REGISTRY {
        let o = opts(e.name, 4, (32, 32));
        let base = render_path(&scene("suite/ltc/quad-cube.pbrt"), &o);
        for name in ["scaled-1e4", "scaled-1e-4"] {
            let r = render_path(&scene(&format!("suite/stiff/{name}.pbrt")), &o);
            let rel = rmse(&r.image, &base.image) / mean(&base.image);
            eprintln!("{} {name}: relative RMSE against the unscaled image {rel:.2e}", e.name);
            assert!(rel < 1e-5, "{} {name}: relative RMSE {rel:.2e} against the unscaled image", e.name);
        }
    }
}
