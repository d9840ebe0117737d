//! `ambientocclusion` end to end: against pbrt-v3's own AO renders, against the
//! closed form on a plane under spheres, against pbrt-v3's `directlighting` of the
//! same scenes, and for scale invariance and determinism.

mod common;
use common::*;

const SPP: u32 = 256;

/// Reference: pbrt-v3 AO at 4096 spp, 256×256 box-downsampled 4×4 → 16×4096 samples per 64×64 pixel.
/// Rendered with the independent `random` sampler: its per-pixel sample variance is an honest
/// estimate of the error (a QMC sampler's is not: 256 Halton points can all miss a sliver).
fn check_against_pbrt(name: &str) {
    let ours = render_path(
        &scene(&format!("suite/ao/{name}.pbrt")),
        &Opts {
            integrator: Some("ambientocclusion"),
            params: &["nsamples=1", "cossample=true"],
            spp: Some(SPP),
            sampler: Some("random"),
            ..Default::default()
        },
    );
    let reference = reference(&format!("ao/{name}.ambientocclusion.exr"));
    // Each cosine-sampled AO sample is π·Bernoulli(p), p the pixel's unoccluded fraction, so the
    // variance of a pixel mean is exactly π²p(1−p)/spp. (The sample variance of the render itself
    // is no estimate for rare occlusion: 256 samples often all miss a 0.5 % sliver.)
    let mut ours = ours;
    for (v, r) in ours.variance.data.iter_mut().zip(&reference.data) {
        let p = (*r as f64 / std::f64::consts::PI).clamp(0.0, 1.0);
        *v = (std::f64::consts::PI.powi(2) * p * (1.0 - p) / SPP as f64) as f32;
    }
    let a = agreement(&ours, &reference, SPP as f64 / (16.0 * 4096.0), 1e-4);
    eprintln!("{name}: {a:?}\nworst: {:?}", worst(&ours, &reference, SPP as f64 / (16.0 * 4096.0), 1e-4, 8));
    assert!(
        a.rel_mean_diff.abs() < 0.005,
        "{name}: image mean differs by {:.3}% from pbrt-v3",
        a.rel_mean_diff * 100.0
    );
    assert!(a.mean_z2 < 1.5, "{name}: differences exceed the noise (mean z² = {:.3})", a.mean_z2);
    assert!(a.outliers < 0.01, "{name}: {:.2}% of values beyond 5σ", a.outliers * 100.0);
}

#[test]
fn spheres_on_plane_matches_pbrt_v3() {
    check_against_pbrt("spheres-on-plane");
}

#[test]
fn blinds_matches_pbrt_v3() {
    check_against_pbrt("blinds");
}

/// pbrt-v3's `directlighting` render of the AO scenes (albedo 0.5, white sky of radiance 1)
/// equals 0.5 × the cosine-weighted unoccluded fraction = 0.5 × AO / π wherever geometry is seen.
#[test]
fn ao_agrees_with_pbrt_directlighting_of_the_same_scene() {
    for name in ["spheres-on-plane", "blinds"] {
        let ours = render_path(
            &scene(&format!("suite/ao/{name}.pbrt")),
            &Opts {
                integrator: Some("ambientocclusion"),
                params: &["nsamples=1"],
                spp: Some(SPP),
                ..Default::default()
            },
        );
        let dl = reference(&format!("ao/{name}.exr"));
        let (mut s_ours, mut s_ref, mut n) = (0.0, 0.0, 0);
        for i in 0..dl.data.len() {
            // Geometry pixels: the sky itself renders as 1 in the directlighting image.
            let seen = ours.image.data[i] > 0.0 && dl.data[i] < 0.55;
            if seen {
                s_ours += 0.5 * ours.image.data[i] as f64 / std::f64::consts::PI;
                s_ref += dl.data[i] as f64;
                n += 1;
            }
        }
        assert!(n > 1000, "{name}: too few geometry pixels ({n})");
        let rel = s_ours / s_ref - 1.0;
        eprintln!("{name}: 0.5·AO/π vs pbrt directlighting over {n} values: {:.4}%", rel * 100.0);
        assert!(rel.abs() < 0.01, "{name}: {rel}");
    }
}

/// On the plane of `spheres-on-plane.pbrt`, at horizontal distance d from the foot of a sphere of
/// radius r centred at height h, the cosine-weighted unoccluded fraction is
/// 1 − r²h / (d² + h²)^{3/2}; the two spheres' occlusions add where their cones do not overlap.
#[test]
fn closed_form_on_the_plane() {
    let spheres = [([-1.0f64, 0.5, 0.0], 0.5f64), ([1.0, 0.8, 0.5], 0.4)];
    let points =
        [[-1.0f64, 0.0, -1.0], [0.0, 0.0, -0.2], [1.0, 0.0, -0.5], [2.0, 0.0, 0.5], [-1.0, 0.0, 1.2], [1.6, 0.0, 1.4]];
    for p in points {
        // Solid-angle cones of both spheres must not overlap for the sum to be exact.
        let dirs: Vec<([f64; 3], f64)> = spheres
            .iter()
            .map(|(c, r)| {
                let v = [c[0] - p[0], c[1] - p[1], c[2] - p[2]];
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                ([v[0] / l, v[1] / l, v[2] / l], (r / l).asin())
            })
            .collect();
        let cos_between = dirs[0].0.iter().zip(&dirs[1].0).map(|(a, b)| a * b).sum::<f64>();
        assert!(cos_between.acos() > dirs[0].1 + dirs[1].1, "test point {p:?} has overlapping cones");
        let expected: f64 = 1.0
            - spheres
                .iter()
                .map(|(c, r)| {
                    let d2 = (c[0] - p[0]).powi(2) + (c[2] - p[2]).powi(2);
                    let h = c[1];
                    r * r * h / (d2 + h * h).powf(1.5)
                })
                .sum::<f64>();
        // An orthographic camera looking straight down at p through a tiny window: the pixel is π·AO(p).
        let text = format!(
            "LookAt {x} 5 {z}  {x} 0 {z}  0 0 1\nCamera \"orthographic\" \"float screenwindow\" [-1e-4 1e-4 -1e-4 1e-4]\n\
             Film \"image\" \"integer xresolution\" [1] \"integer yresolution\" [1]\nSampler \"halton\" \"integer pixelsamples\" [16384]\n\
             WorldBegin\nMaterial \"matte\"\nAttributeBegin\nTranslate -1 0.5 0\nShape \"sphere\" \"float radius\" [0.5]\nAttributeEnd\n\
             AttributeBegin\nTranslate 1 0.8 0.5\nShape \"sphere\" \"float radius\" [0.4]\nAttributeEnd\n\
             Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 0 -6 -6 0 6 6 0 6 6 0 -6]\nWorldEnd\n",
            x = p[0],
            z = p[2]
        );
        let r = render_text(
            &text,
            &Opts {
                integrator: Some("ambientocclusion"),
                params: &["nsamples=1"],
                resolution: None,
                ..Default::default()
            },
        );
        let got = r.image.data[0] as f64 / std::f64::consts::PI;
        // 16384 Halton samples of a Bernoulli-like estimate: σ ≤ 0.5/128; allow 4σ plus tessellation error.
        eprintln!("point {p:?}: AO fraction {got:.5}, closed form {expected:.5}");
        assert!((got - expected).abs() < 4.0 * 0.5 / 128.0 + 2e-3, "at {p:?}: got {got}, expected {expected}");
    }
}

/// `stiff/scaled-1e4` and `stiff/scaled-1e-4` are `ltc/quad-cube` with world and camera scaled:
/// the AO image must not change (same seed, same samples).
#[test]
fn scaled_scenes_render_the_same_ao() {
    let opts =
        Opts { integrator: Some("ambientocclusion"), params: &["nsamples=4"], spp: Some(64), ..Default::default() };
    let base = render_path(&scene("suite/ltc/quad-cube.pbrt"), &opts);
    for s in ["scaled-1e4", "scaled-1e-4"] {
        let scaled = render_path(&scene(&format!("suite/stiff/{s}.pbrt")), &opts);
        let a = agreement(&scaled, &base.image, 1.0, 1e-4);
        eprintln!("{s}: {a:?}");
        assert!(a.rel_mean_diff.abs() < 0.002, "{s}: mean differs by {:.3}%", a.rel_mean_diff * 100.0);
        assert!(a.outliers < 0.002, "{s}: {:.2}% of values beyond 5σ", a.outliers * 100.0);
    }
}

/// Same seed → bit-identical image with 1 or 2 threads, and crops assembled from pieces.
#[test]
fn deterministic_across_threads_and_crops() {
    let path = scene("suite/ao/blinds.pbrt");
    let opts = |threads, crop| Opts {
        integrator: Some("ambientocclusion"),
        params: &["nsamples=2"],
        spp: Some(8),
        resolution: Some((48, 40)),
        threads,
        seed: 7,
        crop,
        sampler: None,
    };
    assert_deterministic(48, 40, |threads, crop| render_path(&path, &opts(threads, crop)));
    let one = render_path(&path, &opts(1, None));
    let other_seed = render_path(&path, &Opts { seed: 8, ..opts(2, None) });
    assert_ne!(other_seed.image.data, one.image.data, "the seed must change the samples");
}
