//! `sheared-ao` end to end: an unoccluded plane is π exactly; with every cell brute-forced it is
//! stratified Monte Carlo AO and matches pbrt-v3's references like `ambientocclusion`; at its
//! defaults its image mean is within a stated tolerance of the references and its error falls
//! with `nsamples`.

mod common;
use common::*;
use penumbra_core::scene::Crop;

/// A plane seen from above, filling the view, with nothing over it (16², 2 spp halton).
const PLANE: &str = "LookAt 0 3 0  0 0 0  0 0 1\nCamera \"perspective\" \"float fov\" [40]\n\
    Film \"image\" \"integer xresolution\" [16] \"integer yresolution\" [16]\nSampler \"halton\" \"integer pixelsamples\" [2]\n\
    WorldBegin\nMaterial \"matte\"\nShape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-6 0 -6 -6 0 6 6 0 6 6 0 -6]\nWorldEnd\n";

/// Every cell's visibility is 1.
#[test]
fn unoccluded_plane_is_pi_exactly() {
    let r = render_text(PLANE, &Opts { integrator: Some("sheared-ao"), resolution: None, ..Default::default() });
    let pi = std::f32::consts::PI;
    assert!(r.image.data.iter().all(|v| (*v - pi).abs() <= 2.0 * f32::EPSILON * pi), "not π everywhere");
}

/// Rays of a crop, in closed form: pass 1 traces the crop *and its margin* (`screenradius`
/// pixels each side, within the image): one camera ray (`rays`) and `nsamples` cached occlusion
/// rays (`shadow_rays`) per camera sample; pass 2, only over the crop, `cells² × brutesamples`
/// occlusion rays per camera sample when every cell is brute-forced (`minweight` huge).
#[test]
fn a_crop_counts_its_margin_rays_once() {
    let crop = Some(Crop::Pixels([8, 16, 4, 12]));
    let params = &["nsamples=4", "cells=2", "brutesamples=3", "minweight=1e30", "screenradius=6"];
    let o = Opts { integrator: Some("sheared-ao"), params, resolution: Some((32, 32)), crop, ..Default::default() };
    let r = render_text(PLANE, &o);
    // Crop 8×8 pixels, 2 spp; its margin region [2, 22) × [0, 18): 20 × 18 pixels.
    let (crop_samples, region_samples) = (8 * 8 * 2, 20 * 18 * 2);
    assert_eq!(r.stats.camera_samples, crop_samples);
    assert_eq!(r.stats.shadow_rays, region_samples * 4 + crop_samples * 4 * 3);
    assert_eq!(r.stats.rays, region_samples);
    assert_eq!(r.stats.counters["pass1_points"], region_samples as f64);
    assert_eq!(r.stats.counters["pass1_rays_per_point"], 4.0);
    assert_eq!(r.stats.counters["pass2_rays_per_point"], 12.0);
    assert_eq!(r.stats.counters["brute_cell_fraction"], 1.0);
}

fn ao_render(name: &str, integrator: &'static str, params: &[&str], spp: u32, sampler: Option<&'static str>) -> Render {
    render_path(
        &scene(&format!("suite/ao/{name}.pbrt")),
        &Opts { integrator: Some(integrator), params, spp: Some(spp), sampler, ..Default::default() },
    )
}

/// With `minweight` huge every cell is brute-forced with one ray stratified in it: 64-stratum
/// Monte Carlo AO. Each camera sample's estimate has variance at most π²p(1−p) (p the pixel's
/// unoccluded fraction; law of total variance, stratification only lowers it), so the z-test of
/// `ambientocclusion`'s against pbrt-v3's 4096-spp references applies with that bound.
#[test]
fn all_brute_force_is_stratified_monte_carlo_and_matches_pbrt_v3() {
    const SPP: u32 = 32;
    for name in ["spheres-on-plane", "blinds"] {
        let mut ours = ao_render(name, "sheared-ao", &["minweight=1e30", "nsamples=1"], SPP, Some("random"));
        let reference = reference(&format!("ao/{name}.ambientocclusion.exr"));
        let n = SPP as f64;
        for (v, r) in ours.variance.data.iter_mut().zip(&reference.data) {
            let p = (*r as f64 / std::f64::consts::PI).clamp(0.0, 1.0);
            *v = (std::f64::consts::PI.powi(2) * p * (1.0 - p) / n) as f32;
        }
        let a = agreement(&ours, &reference, n / (16.0 * 4096.0), 1e-4);
        eprintln!("{name}: {a:?}");
        assert!(a.rel_mean_diff.abs() < 0.005, "{name}: mean differs by {:.3}%", a.rel_mean_diff * 100.0);
        assert!(a.mean_z2 < 1.5, "{name}: differences exceed the noise (mean z² = {:.3})", a.mean_z2);
        assert!(a.outliers < 0.01, "{name}: {:.2}% of values beyond 5σ", a.outliers * 100.0);
    }
}

/// At the defaults (4 camera samples × 8 rays): the image mean within 0.4 % of pbrt-v3's
/// reference, and the RMSE below that of `ambientocclusion` with the same pass-1 rays.
#[test]
fn defaults_match_pbrt_v3_mean_and_beat_equal_ray_monte_carlo() {
    for name in ["spheres-on-plane", "blinds"] {
        let reference = reference(&format!("ao/{name}.ambientocclusion.exr"));
        let ours = ao_render(name, "sheared-ao", &[], 4, None);
        let mc = ao_render(name, "ambientocclusion", &["nsamples=8"], 4, None);
        let rel = mean(&ours.image) / mean(&reference) - 1.0;
        let (e_ours, e_mc) = (rmse(&ours.image, &reference), rmse(&mc.image, &reference));
        eprintln!(
            "{name}: mean {:+.3}% vs pbrt-v3; RMSE {e_ours:.4} (sheared-ao) vs {e_mc:.4} (ambientocclusion, same rays)",
            rel * 100.0
        );
        // Measured +0.033 % (spheres-on-plane) and −0.097 % (blinds); the issue asks for 1 %.
        assert!(rel.abs() < 0.004, "{name}: mean differs by {:.3}%", rel * 100.0);
        assert!(e_ours < e_mc, "{name}: RMSE {e_ours} not below equal-ray Monte Carlo's {e_mc}");
    }
}

/// More pass-1 rays, less noise: the seed-to-seed RMSE (√2 × the noise of one render) falls
/// with `nsamples` (the bias floor is `defaults_match_pbrt_v3_mean_and_beat_equal_ray_monte_carlo`'s).
#[test]
fn noise_falls_with_nsamples() {
    let path = scene("suite/ao/spheres-on-plane.pbrt");
    let noise = |p: &'static str| {
        let r = |seed| {
            render_path(
                &path,
                &Opts { integrator: Some("sheared-ao"), params: &[p], spp: Some(2), seed, ..Default::default() },
            )
        };
        rmse(&r(0).image, &r(1).image) / std::f64::consts::SQRT_2
    };
    let e: Vec<f64> = ["nsamples=1", "nsamples=4", "nsamples=16"].into_iter().map(noise).collect();
    eprintln!("noise with nsamples 1, 4, 16 (2 camera samples): {e:?}");
    // Measured 0.0246, 0.0178, 0.0126: the floor is the camera samples' own noise (2 per pixel,
    // a new seed moves them) and the brute-forced cells' single rays, which nsamples does not cut.
    assert!(e[1] < e[0] && e[2] < e[1] && e[2] < 0.7 * e[0], "noise {e:?}");
}

/// The mean of channel `name` over the image, and the channel's values.
fn channel(img: &penumbra_core::image::Image, name: &str) -> Vec<f64> {
    let c = img.channel_index(name).unwrap_or_else(|| panic!("no channel {name}"));
    img.data.chunks_exact(img.channels.len()).map(|p| p[c] as f64).collect()
}

/// `"bool sh"`: on an unoccluded plane of normal +y the transfer is the clamped cosine's,
/// `Â_l Y_lm(+y)`, in every pixel; `sh.0` is `Y_0 · AO` wherever something is seen.
#[test]
fn sh_of_an_unoccluded_plane_is_the_clamped_cosine() {
    let o = Opts { integrator: Some("sheared-ao"), params: &["sh=true"], resolution: None, ..Default::default() };
    let r = render_text(PLANE, &o);
    let order = penumbra_core::sh::ShOrder::new(3).unwrap();
    let y = penumbra_core::sh::basis::eval_vec(order, glam::DVec3::Y);
    let pi = std::f64::consts::PI;
    let a_hat = [pi, 2.0 * pi / 3.0, 2.0 * pi / 3.0, 2.0 * pi / 3.0, pi / 4.0, pi / 4.0, pi / 4.0, pi / 4.0, pi / 4.0];
    for i in 0..9 {
        let want = a_hat[i] * y[i];
        for v in channel(&r.channels, &format!("sh.{i}")) {
            assert!((v - want).abs() < 1e-5, "sh.{i}: {v} vs {want}");
        }
    }
    for v in channel(&r.channels, "albedo.G") {
        assert!((v - 0.5).abs() < 1e-6, "albedo {v}");
    }
}

/// `"bool sh"` against `ambientocclusion`'s SH channels (Monte Carlo over the same integrand):
/// per channel, the difference of image means relative to the mean of `sh.0`, and the RMSE.
#[test]
fn sh_matches_ambientocclusion() {
    for name in ["spheres-on-plane", "blinds"] {
        let path = scene(&format!("suite/ao/{name}.pbrt"));
        let res = Some((32, 32));
        let o = |integrator, params, spp| Opts {
            integrator: Some(integrator),
            params,
            spp: Some(spp),
            resolution: res,
            ..Default::default()
        };
        let mc = render_path(&path, &o("ambientocclusion", &["sh=true", "nsamples=256"], 16));
        let ours = render_path(&path, &o("sheared-ao", &["sh=true"], 4));
        let m0 = channel(&mc.channels, "sh.0").iter().sum::<f64>() / (32.0 * 32.0);
        let (r, s0) = (channel(&ours.channels, "R"), channel(&ours.channels, "sh.0"));
        for (a, s) in r.iter().zip(&s0) {
            assert!((s - a * 0.5 / std::f64::consts::PI.sqrt()).abs() < 1e-6 * a.max(1.0), "sh.0 {s} vs AO {a}");
        }
        for i in 0..9 {
            let (a, b) = (channel(&ours.channels, &format!("sh.{i}")), channel(&mc.channels, &format!("sh.{i}")));
            let n = a.len() as f64;
            let dm = (a.iter().sum::<f64>() - b.iter().sum::<f64>()) / n / m0;
            let e = (a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt() / m0;
            eprintln!("{name} sh.{i}: mean difference {:+.4} % of sh.0, RMSE {:.4} of sh.0", dm * 100.0, e);
            // Measured (32², 4 spp against 16 × 256 rays): at most 0.29 % and 0.041 on
            // spheres-on-plane, 2.27 % (sh.5) and 0.106 on blinds (sh.0: −0.02 %); ambientocclusion's
            // own noise in these means is about 0.07 %. Blinds' sh.5 is partly the cells'
            // piecewise-constant visibility against a Y varying across each cell: 1.28 % with
            // `cells` 16.
            let (max_dm, max_e) = if name == "blinds" { (0.03, 0.12) } else { (0.006, 0.05) };
            assert!(dm.abs() < max_dm && e < max_e, "{name} sh.{i}: mean difference {dm:.4}, RMSE {e:.4}");
        }
    }
}

/// A ground plane of `2 n²` small triangles whose vertex order turns from one triangle to the
/// next (so each has its own `dpdu`, the tangent of its shading frame), with a wall along x =
/// 0.6 that occludes one side of the hemisphere (32², 4 spp halton).
fn turned_triangles_by_a_wall(n: usize) -> String {
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            p.push(format!("{} 0 {}", -2.0 + 4.0 * i as f64 / n as f64, -2.0 + 4.0 * j as f64 / n as f64));
        }
    }
    let mut idx = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, c) = (j * (n + 1) + i, (j + 1) * (n + 1) + i);
            for mut t in [[a, c, c + 1], [a, c + 1, a + 1]] {
                t.rotate_left(idx.len() / 3 % 3);
                idx.extend(t);
            }
        }
    }
    let join = |v: Vec<String>| v.join(" ");
    format!(
        "LookAt 0 3 0  0 0 0  0 0 1\nCamera \"perspective\" \"float fov\" [40]\n\
         Film \"image\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n\
         Sampler \"halton\" \"integer pixelsamples\" [4]\nWorldBegin\nMaterial \"matte\"\n\
         Shape \"trianglemesh\" \"integer indices\" [{}] \"point P\" [{}]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [0.6 0 -3 0.6 0 3 0.6 1 3 0.6 1 -3]\n\
         WorldEnd\n",
        join(idx.iter().map(|i| i.to_string()).collect()),
        join(p)
    )
}

/// Pixel shading shares a receiver's filtered cells with the pixel's other camera samples: they
/// must mean the same directions there, whatever tangent each sample's triangle has. On a mesh
/// whose triangles' tangents turn by a third of a turn from one to the next (several per pixel)
/// the SH transfer with pixel shading matches the one with every sample its own receiver
/// (`shading=sample`, same pass-1 cache). Before the members took the receiver's frame, each
/// member rotated the receiver's cells by its own tangent: the wall's occlusion was smeared
/// around the normal, and its brute-forced cells landed in other cells than the receiver's:
/// channel means off by up to 14 % of `sh.0` (sh.4; sh.0, the AO, +1.2 %), and relit under the
/// studio map the killeroos were 0.5 % darker than with `shading=sample`
/// (docs/integrators/sheared-ao.md).
#[test]
fn pixel_shading_shares_cells_in_the_receivers_frame() {
    let text = turned_triangles_by_a_wall(96);
    let o = |shading| Opts {
        integrator: Some("sheared-ao"),
        params: if shading { &["sh=true", "shading=pixel"] } else { &["sh=true", "shading=sample"] },
        resolution: None,
        ..Default::default()
    };
    let (pixel, sample) = (render_text(&text, &o(true)), render_text(&text, &o(false)));
    let mean = |r: &Render, i: usize| {
        let v = channel(&r.channels, &format!("sh.{i}"));
        v.iter().sum::<f64>() / v.len() as f64
    };
    let m0 = mean(&sample, 0);
    let worst = (0..9).fold(0.0f64, |worst, i| {
        let (a, b) = (mean(&pixel, i), mean(&sample, i));
        eprintln!("sh.{i}: pixel {a:+.5} sample {b:+.5}, difference {:+.3} % of sh.0", 100.0 * (a - b) / m0);
        worst.max((a - b).abs() / m0)
    });
    // Measured: at most 0.042 % (sh.0; the receivers differ, so their filtered values do).
    assert!(worst < 0.005, "pixel shading's SH transfer differs from sample shading's by {worst:.4} of sh.0");
}

/// Issue 38: `"bool sh"` relit under a real map is within 2 % of `directlighting`'s mean at the
/// default `shorder` (5). `scenes/relight/spheres-on-plane-studio.pbrt` (all matte) at 64²:
/// `sheared-ao` at 4 spp relit, `directlighting` at 64 spp, means over the pixels that see a
/// surface. Measured here: order 5 −1.66 %, order 3 −3.33 % (so order 3 fails); at 128², 8 spp
/// (docs/integrators/sheared-ao.md) order 3 −2.9 %, 4 −3.2 %, 5 −1.3 %. The cause is the map's
/// truncation: an unoccluded plane under the same map is −3.5 % at order 3 with an exact
/// transfer.
#[test]
fn sh_relit_under_the_studio_map_matches_directlighting_mean() {
    let path = scene("relight/spheres-on-plane-studio.pbrt");
    let o = |integrator, params, spp| Opts {
        integrator: Some(integrator),
        params,
        spp: Some(spp),
        resolution: Some((64, 64)),
        ..Default::default()
    };
    let ours = render_path(&path, &o("sheared-ao", &["sh=true"], 4));
    let dl = render_path(&path, &o("directlighting", &[], 64));
    let order = penumbra_core::sh::ShOrder::new(5).unwrap();
    assert!(ours.channels.channel_index("sh.24").is_some(), "default shorder is not 5");
    let light = penumbra::relight::scene_lighting(&path, order, &penumbra_parser::DiagSink::new()).unwrap();
    let relit = penumbra::relight::relight(&ours.channels, &light, 1.0).unwrap();
    let (a, b) = (channel(&relit, "G"), channel(&dl.image, "G"));
    let seen: Vec<usize> = (0..a.len()).filter(|&i| a[i] > 0.0).collect();
    let mean = |v: &[f64]| seen.iter().map(|&i| v[i]).sum::<f64>() / seen.len() as f64;
    let rel = mean(&a) / mean(&b) - 1.0;
    eprintln!(
        "relit {:.5}, directlighting {:.5}: {:+.2} % over {} pixels",
        mean(&a),
        mean(&b),
        100.0 * rel,
        seen.len()
    );
    assert!(rel.abs() < 0.02, "relit mean {:+.2} % from directlighting's", 100.0 * rel);
}

/// Issue 38's check on mesh-heavy scenes of the held-out kind (`scenes/meshes/`: a staircase of
/// box steps by a wall; the 66.5k-triangle killeroos), at the scenes' 256², against pbrt-v3's
/// 4096-spp `ambientocclusion` (64² copies, so our render is box-downsampled 4×4). The issue asks
/// for the mean within 2 %. Measured at the defaults (4 spp): killeroos +0.74 %, staircase
/// +0.71 % (at 16 spp +0.37 % / +0.33 %: the filter's reprojection over the neighbourhood, which
/// narrows with more samples per pixel; at 64² the neighbourhood spans 4× the surface and the
/// killeroos are +2.0 %, so the test renders the scenes' own resolution). Bound: 1 %, the
/// measured figures plus the mean's noise (RMSE 0.043–0.049 over 65k pixels: < 0.01 %) and
/// room for a re-ordering of the filter's floating-point sums.
#[test]
fn mesh_scenes_match_pbrt_v3_mean_at_their_resolution() {
    for name in ["killeroos-sky", "staircase-sky"] {
        let ours = render_path(
            &scene(&format!("meshes/{name}.pbrt")),
            &Opts { integrator: Some("sheared-ao"), spp: Some(4), resolution: None, ..Default::default() },
        );
        assert_eq!(ours.image.width, 256, "{name}: the scene's resolution");
        let reference = reference(&format!("meshes/{name}.ao.exr"));
        let small = ours.image.box_downsample(4).expect("256² by 4");
        let rel = mean(&small) / mean(&reference) - 1.0;
        eprintln!(
            "{name}: sheared-ao mean {:+.3}% vs pbrt-v3, RMSE (64²) {:.4}",
            rel * 100.0,
            rmse(&small, &reference)
        );
        assert!(rel.abs() < 0.01, "{name}: mean differs by {:.3}%", rel * 100.0);
    }
}
