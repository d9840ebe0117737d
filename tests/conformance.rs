//! Checks every registered integrator must pass, run for each entry of
//! `penumbra_integrators::REGISTRY`, so a new integrator gets them by being registered:
//! finite, non-negative values on every stiff scene; bit-identical images across thread counts
//! and when assembled from crops; the same image when the whole scene (camera included) is
//! scaled by 1e4 and 1e-4; rays counted as the driver's rule says (one per camera sample by
//! the driver, every other ray once, by whoever spawns it).

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

/// A matte floor filling the view and a two-triangle area light above it, out of view, facing
/// the floor: every camera ray hits the floor with one query, and every floor point sees the
/// light's emitting side, so each integrator's ray counts are closed forms of its parameters.
const RAY_COUNT_SCENE: &str = r#"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Sampler "halton" "integer pixelsamples" 4
Film "image" "integer xresolution" 8 "integer yresolution" 8
WorldBegin
Material "matte"
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point P" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4]
  Shape "trianglemesh" "integer indices" [0 2 1 0 3 2]
    "point P" [2.5 -0.5 2  3.5 -0.5 2  3.5 0.5 2  2.5 0.5 2]
AttributeEnd
WorldEnd
"#;

/// Rays and shadow rays per camera sample on [`RAY_COUNT_SCENE`], for every registered
/// integrator (a new one must add its line), with the parameters given.
fn expected_rays(name: &str) -> Option<(&'static [&'static str], u64, u64)> {
    // pbrt-v3 makes one light per triangle: 2 lights.
    Some(match name {
        // Per light: one light sample (a shadow ray) and one BSDF sample (a ray).
        "directlighting" => (&[], 1 + 2, 2),
        // One bounce: one light chosen per vertex (a shadow ray and a BSDF-sampled ray), then
        // the bounce ray; its vertex ends the path.
        "path" => (&["maxdepth=1"], 1 + 1 + 1, 1),
        // Every light one shadow ray; a matte floor reflects nothing specularly.
        "whitted" => (&[], 1, 2),
        // 16 AO rays, all visibility rays.
        "ambientocclusion" => (&["nsamples=16"], 1, 16),
        // The light is shaded analytically, shadows included: the camera ray only.
        "ltc" => (&[], 1, 0),
        // The analytic part is unshadowed; one stochastic sample, drawn from the light (a
        // shadow ray; BRDF-drawn samples, from the second on, cast one only when they meet it).
        "ratio" => (&["nsamples=1"], 1, 1),
        // `ao` (its default here would be `shade`, whose only light goes through
        // directlighting's estimator): the camera ray and one shadow ray through the longest
        // visible interval (measured: 256 and 256 of 256); sample shading, so that every camera
        // sample integrates.
        "silhouette" => (&["mode=ao", "shading=sample"], 1, 1),
        // No environment here: the area light goes through directlighting's estimator.
        "shexp" => (&[], 1 + 2, 2),
        // Its own driver: pass 1 traces one camera ray per camera sample (the margin is clipped
        // to the image, which this render fills) and `nsamples` cached occlusion rays;
        // `minweight` huge brute-forces every cell in pass 2: cells² × brutesamples occlusion
        // rays (4 + 2² × 3 = 16 shadow rays).
        "sheared-ao" => (&["nsamples=4", "cells=2", "brutesamples=3", "minweight=1e30"], 1, 16),
        _ => return None,
    })
}

#[test]
fn every_integrator_counts_each_ray_once() {
    for e in REGISTRY {
        let (params, rays, shadow) =
            expected_rays(e.name).unwrap_or_else(|| panic!("{}: add its ray counts to expected_rays", e.name));
        let o = Opts { integrator: Some(e.name), params, resolution: None, ..Default::default() };
        let r = render_text(RAY_COUNT_SCENE, &o);
        let c = r.stats.camera_samples;
        // (`ltc` raises the sample count to its coverage samples.)
        assert_eq!(c, 8 * 8 * r.stats.spp as u64, "{}: camera samples", e.name);
        eprintln!("{}: {} rays, {} shadow rays for {c} camera samples", e.name, r.stats.rays, r.stats.shadow_rays);
        assert_eq!((r.stats.rays, r.stats.shadow_rays), (rays * c, shadow * c), "{}: (rays, shadow rays)", e.name);
    }
}
