//! `penumbra relight` end to end: SH transfer channels written by `ambientocclusion "bool sh"`,
//! relit under the scene's environment, against `directlighting`'s render of the same scene
//! and against the closed form; and the AO image unchanged by writing them.

mod common;

use common::root;
use glam::{DMat3, DVec3};
use penumbra::cli_params::parse_param;
use penumbra::pipeline::{self, RenderOptions};
use penumbra::relight;
use penumbra_core::image::{self, Image};
use penumbra_core::scene::BuildOptions;
use penumbra_core::sh::{quadrature::gauss_legendre, ShOrder};
use penumbra_parser::DiagSink;
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::AtomicBool;

fn plane_scene() -> PathBuf {
    root().join("tests/data/relight/plane-sh2.pbrt")
}

/// The whole image (every channel) of a render of `path`.
fn render(
    path: &std::path::Path,
    integrator: &str,
    params: &[&str],
    spp: u32,
    seed: u64,
    resolution: Option<(u32, u32)>,
) -> Image {
    let parsed = penumbra_parser::parse_file(path).unwrap_or_else(|e| panic!("{e}"));
    let params: Vec<_> = params.iter().map(|p| parse_param(p).unwrap()).collect();
    let cancel = AtomicBool::new(false);
    let opts = RenderOptions {
        integrator: Some(integrator),
        params: &params,
        build: BuildOptions { spp: Some(spp), seed, crop: None, resolution },
        threads: 0,
        with_variance: false,
        cancel: &cancel,
        progress: None,
    };
    let warnings = DiagSink::new();
    pipeline::render(&parsed.scene, &opts, &warnings).unwrap_or_else(|e| panic!("{e}")).image
}

/// The map's function (make_env.py) in light space.
fn radiance(d: DVec3) -> [f64; 3] {
    let (x, y, z) = (d.x, d.y, d.z);
    [
        1.0 + 0.3 * x - 0.2 * y + 0.4 * z + 0.2 * (x * x - y * y) + 0.1 * x * z,
        0.8 - 0.1 * x + 0.3 * y - 0.2 * z + 0.15 * x * y,
        0.6 + 0.2 * z * z,
    ]
}

/// Kd/π ∫ L(M⁻¹ω) max(0, n·ω) dω by Gauss quadrature over the hemisphere about n (the
/// integrand is a polynomial there: exact), with M the light's Rotate 50 z · Rotate 30 x.
fn closed_form() -> [f64; 3] {
    let m = DMat3::from_rotation_z(50f64.to_radians()) * DMat3::from_rotation_x(30f64.to_radians());
    let n = DVec3::new(1.0, 2.0, 3.0).normalize();
    let t = n.cross(DVec3::Z).normalize();
    let b = n.cross(t);
    let (mu, w) = gauss_legendre(12);
    let mut e = [0.0; 3];
    let nphi = 24;
    for (x, wx) in mu.iter().zip(&w) {
        let c = 0.5 * (x + 1.0); // cos θ ∈ [0, 1]
        let s = (1.0 - c * c).sqrt();
        for k in 0..nphi {
            let phi = 2.0 * std::f64::consts::PI * k as f64 / nphi as f64;
            let d = n * c + t * (s * phi.cos()) + b * (s * phi.sin());
            let l = radiance(m.transpose() * d);
            for ch in 0..3 {
                e[ch] += 0.5 * wx * (2.0 * std::f64::consts::PI / nphi as f64) * c * l[ch];
            }
        }
    }
    let kd = [0.6, 0.5, 0.4];
    [0, 1, 2].map(|c| kd[c] / std::f64::consts::PI * e[c])
}

/// Mean and variance over pixels of channel `c` (every pixel has the same true value).
fn stats(img: &Image, c: usize) -> (f64, f64) {
    let nc = img.channels.len();
    let v: Vec<f64> = img.data.chunks_exact(nc).map(|p| p[c] as f64).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (mean, v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64)
}

/// The map on disk is the function make_env.py documents (at texel centres).
#[test]
fn environment_map_is_what_its_generator_says() {
    let img = image::read(root().join("tests/data/relight/sh2-env.pfm")).unwrap();
    assert_eq!((img.width, img.height), (128, 64));
    for (j, i) in [(0u32, 0u32), (10, 77), (31, 5), (63, 127)] {
        let theta = std::f64::consts::PI * (j as f64 + 0.5) / 64.0;
        let phi = 2.0 * std::f64::consts::PI * (i as f64 + 0.5) / 128.0;
        let want = radiance(DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
        let got = img.rgb(i, j).unwrap();
        for c in 0..3 {
            assert!((got[c] as f64 - want[c]).abs() < 1e-6, "texel ({i}, {j})");
        }
    }
}

/// The acceptance test: relight of the AO-with-SH render reproduces directlighting within
/// the noise of both, and both match the closed form.
#[test]
fn relight_of_ao_transfer_matches_directlighting_on_an_unoccluded_plane() {
    let scene = plane_scene();
    let ao = render(&scene, "ambientocclusion", &["sh=true", "nsamples=64"], 16, 1, None);
    let dl = render(&scene, "directlighting", &[], 64, 2, None);
    let warnings = DiagSink::new();
    let light = relight::scene_lighting(&scene, ShOrder::new(3).unwrap(), &warnings).unwrap();
    let relit = relight::relight(&ao, &light, 1.0).unwrap();
    let want = closed_form();
    let p = (relit.width * relit.height) as f64;
    for c in 0..3 {
        let ((mr, vr), (md, vd)) = (stats(&relit, c), stats(&dl, c));
        let sigma = (vr / p + vd / p).sqrt();
        println!(
            "channel {c}: closed form {:.5}, relight {mr:.5} ± {:.5} (pixel σ {:.4}), directlighting {md:.5} ± {:.5} (pixel σ {:.4})",
            want[c],
            (vr / p).sqrt(),
            vr.sqrt(),
            (vd / p).sqrt(),
            vd.sqrt()
        );
        assert!((mr - md).abs() < 4.0 * sigma, "channel {c}: relight {mr} vs directlighting {md} (σ {sigma})");
        // Bias allowance 1e-3 relative: the bilinear map is order 2 only up to O(h²).
        assert!((mr - want[c]).abs() < 4.0 * (vr / p).sqrt() + 1e-3 * want[c], "relight {mr} vs {}", want[c]);
        assert!((md - want[c]).abs() < 4.0 * (vd / p).sqrt() + 1e-3 * want[c], "directlighting {md} vs {}", want[c]);
        // Pixel by pixel the difference is the two noises, no more.
        let diff: f64 = relit
            .data
            .chunks_exact(3)
            .zip(dl.data.chunks_exact(dl.channels.len()))
            .map(|(a, b)| (a[c] as f64 - b[c] as f64).powi(2))
            .sum::<f64>()
            / p;
        assert!(diff < 1.3 * (vr + vd), "channel {c}: per-pixel mean square difference {diff} vs noise {}", vr + vd);
    }
    // Transfer band 0 is AO/√4π sample by sample (the same rays and weights).
    let (ir, i0) = (ao.channel_index("R").unwrap(), ao.channel_index("sh.0").unwrap());
    for px in ao.data.chunks_exact(ao.channels.len()) {
        assert!((px[i0] as f64 * penumbra_core::sh::SQRT_4PI - px[ir] as f64).abs() < 1e-5 * px[ir] as f64 + 1e-6);
    }
}

/// Writing SH channels leaves the AO image bit-identical.
#[test]
fn sh_channels_leave_the_ao_image_unchanged() {
    let scene = common::scene("suite/ao/spheres-on-plane.pbrt");
    let res = Some((48, 48));
    let plain = render(&scene, "ambientocclusion", &["nsamples=8"], 4, 3, res);
    let with = render(&scene, "ambientocclusion", &["nsamples=8", "sh=true", "shorder=4"], 4, 3, res);
    assert_eq!(plain.channels, ["R", "G", "B"]);
    assert_eq!(with.channels.len(), 3 + 16 + 3);
    let rgb = with.select_channels(&["R", "G", "B"]).unwrap();
    assert_eq!(rgb.data.len(), plain.data.len());
    assert!(rgb.data.iter().zip(&plain.data).all(|(a, b)| a.to_bits() == b.to_bits()), "AO changed");
    // Albedo 0.5 (matte) where the plane or a sphere is seen, 0 on the background, the
    // pixel-filtered mean of both on silhouettes.
    let ia = with.channel_index("albedo.G").unwrap();
    let albedos: Vec<f32> = with.data.chunks_exact(with.channels.len()).map(|p| p[ia]).collect();
    assert!(albedos.iter().all(|a| (0.0..=0.5 + 1e-6).contains(a)));
    assert!(albedos.iter().filter(|a| (**a - 0.5).abs() < 1e-6).count() > albedos.len() / 2);
}

#[test]
fn bad_sh_order_is_an_error() {
    let parsed = penumbra_parser::parse_file(&plane_scene()).unwrap();
    for bad in ["shorder=0", "shorder=40"] {
        let params = vec![parse_param("sh=true").unwrap(), parse_param(bad).unwrap()];
        let w = DiagSink::new();
        let r = pipeline::choose_integrator(&parsed.scene, Some("ambientocclusion"), &params, &w);
        let msg = r.err().map(|e| e.message).unwrap_or_default();
        assert!(msg.contains("shorder"), "{bad}: {msg}");
    }
}

/// The CLI refuses images without transfer channels and lighting without infinite lights,
/// and relights an image under `--env` (the map in pbrt-v3's default orientation).
#[test]
fn relight_cli() {
    let dir = std::env::temp_dir().join(format!("penumbra-relight-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plain = dir.join("plain.exr");
    image::write(&Image::from_rgb(2, 2, &[penumbra_core::Rgb::ONE; 4]).unwrap(), &plain).unwrap();
    let bin = env!("CARGO_BIN_EXE_penumbra");
    let run = |args: &[&std::ffi::OsStr]| Command::new(bin).arg("relight").args(args).output().unwrap();
    let env = root().join("tests/data/relight/sh2-env.pfm");
    let out = dir.join("out.exr");
    let r = run(&[plain.as_os_str(), "--env".as_ref(), env.as_os_str(), "-o".as_ref(), out.as_os_str()]);
    assert!(!r.status.success());
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("no SH transfer channels"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let r = run(&[plain.as_os_str(), "-o".as_ref(), out.as_os_str()]);
    assert!(!r.status.success(), "lighting is required");

    // A 4×4 transfer image: unoccluded transfer for normal +z, albedo 1.
    let o = ShOrder::new(3).unwrap();
    let mut t = vec![0.0; 9];
    penumbra_core::sh::zonal::rotate_zh(&penumbra_core::sh::zonal::clamped_cosine(o), DVec3::Z, &mut t).unwrap();
    let ch = penumbra_core::sh::transfer::TransferChannels::new(o, 0);
    let mut px: Vec<f32> = t.iter().map(|v| *v as f32).collect();
    px.extend([1.0, 1.0, 1.0]);
    let img = Image::from_data(4, 4, ch.names(), px.repeat(16)).unwrap();
    let input = dir.join("transfer.exr");
    image::write(&img, &input).unwrap();
    let r = run(&[
        input.as_os_str(),
        "--env".as_ref(),
        env.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--exposure".as_ref(),
        "1".as_ref(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let relit = image::read(&out).unwrap();
    // 2 × (1/π) ∫ L max(0, z) dω for the map's R = 1 + … + 0.4z + …: 2 (1 + 0.4·2/3 + 0.2·0) (the
    // x, y, xz, x² − y² terms integrate to 0 over the upper hemisphere).
    let want = 2.0 * (1.0 + 0.4 * 2.0 / 3.0);
    assert!((relit.data[0] as f64 - want).abs() < 2e-3 * want, "{} vs {want}", relit.data[0]);
    let scene_without = dir.join("nolight.pbrt");
    std::fs::write(&scene_without, "WorldBegin\nLightSource \"point\"\nWorldEnd\n").unwrap();
    let r = run(&[input.as_os_str(), "--scene".as_ref(), scene_without.as_os_str(), "-o".as_ref(), out.as_os_str()]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("no infinite light"));
    std::fs::remove_dir_all(&dir).ok();
}

/// Relight error against SH order (the README's table): `scenes/relight/spheres-on-plane-studio`
/// at 128², ambientocclusion sh=true at order 8 (2048 rays per pixel; lower orders are its first
/// n² channels, the same estimator truncated) relit under the scene's studio map, against
/// directlighting at 512 spp; RMSE over pixels that see only geometry (albedo 0.5: the
/// background, where directlighting shows the map, has no transfer). Noise of each side from
/// a second render with another seed. Slow: `cargo test --release --test relight -- --ignored`.
#[test]
#[ignore]
fn relight_error_versus_order() {
    let scene = root().join("scenes/relight/spheres-on-plane-studio.pbrt");
    let res = Some((128, 128));
    let ao = |seed| render(&scene, "ambientocclusion", &["sh=true", "shorder=8", "nsamples=128"], 16, seed, res);
    let dl = |seed| render(&scene, "directlighting", &[], 512, seed, res);
    let (ao1, ao2, dl1, dl2) = (ao(11), ao(12), dl(21), dl(22));
    let ia = ao1.channel_index("albedo.G").unwrap();
    let mask: Vec<bool> = ao1.data.chunks_exact(ao1.channels.len()).map(|p| (p[ia] - 0.5).abs() < 1e-6).collect();
    let count = mask.iter().filter(|m| **m).count() as f64;
    let rmse = |a: &Image, b: &Image| {
        let (na, nb) = (a.channels.len(), b.channels.len());
        let s: f64 = a
            .data
            .chunks_exact(na)
            .zip(b.data.chunks_exact(nb))
            .zip(&mask)
            .filter(|(_, m)| **m)
            .map(|((x, y), _)| (0..3).map(|c| (x[c] as f64 - y[c] as f64).powi(2)).sum::<f64>())
            .sum();
        (s / (3.0 * count)).sqrt()
    };
    let mean_dl = {
        let s: f64 = dl1
            .data
            .chunks_exact(dl1.channels.len())
            .zip(&mask)
            .filter(|(_, m)| **m)
            .map(|(p, _)| (p[0] + p[1] + p[2]) as f64)
            .sum();
        s / (3.0 * count)
    };
    let dl_noise = rmse(&dl1, &dl2) / 2f64.sqrt();
    println!("{count} geometry pixels, mean {mean_dl:.4}; directlighting noise (RMSE) {dl_noise:.2e}");
    println!("| SH order | RMSE vs directlighting | relative | relight noise |");
    let w = DiagSink::new();
    for n in 1..=8usize {
        let order = ShOrder::new(n).unwrap();
        let light = relight::scene_lighting(&scene, order, &w).unwrap();
        let mut names: Vec<String> = (0..n * n).map(|i| format!("sh.{i}")).collect();
        names.extend(["albedo.R", "albedo.G", "albedo.B"].map(String::from));
        let r = |img: &Image| relight::relight(&img.select_channels(&names).unwrap(), &light, 1.0).unwrap();
        let (r1, r2) = (r(&ao1), r(&ao2));
        let e = rmse(&r1, &dl1);
        println!("| {n} | {e:.2e} | {:.2}% | {:.2e} |", 100.0 * e / mean_dl, rmse(&r1, &r2) / 2f64.sqrt());
    }
}
