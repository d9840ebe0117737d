//! Run time of the `ltc` integrator against the number of light and occluder vertices.
//!
//! Scenes are built in memory as pbrt-v3 text: a polygonal disk light (a triangle fan of
//! `n_l` rim vertices plus its centre, facing down) above a matte ground plane, with a convex
//! polygonal prism (`n_o` vertices: two rings of `n_o / 2`) in between. Each scene is rendered
//! at a small resolution, 1 spp (no coverage floor), on one thread, with `ltc` in modes `silhouette` and
//! `per-triangle`; only `Integrator::render` is timed (median of up to 3 runs). Prints a table,
//! a least-squares fit `time = a + b·n` with R² per series, and the per-triangle/silhouette
//! time ratio.
//!
//! `cargo run --release -p penumbra-integrators --example ltc_scaling [-- RES [MAX_SECONDS]]`
//! (per-triangle runs stop once one takes more than MAX_SECONDS), or `-- --one N_L N_O MODE RES`
//! for a single render to profile, or `-- --poly` for the polygon micro-benchmark alone.

use penumbra_core::film::Film;
use penumbra_core::integrator::RenderContext;
use penumbra_core::scene::{BuildOptions, Scene};
use penumbra_parser::DiagSink;
use std::f64::consts::TAU;
use std::fmt::Write;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

const SIZES: [usize; 8] = [8, 16, 32, 64, 128, 256, 512, 1000];
const FIXED: usize = 64;

fn disk_light(n: usize) -> String {
    // Centre vertex 0, rim 1..=n; wound so that the emitting normal faces -y.
    let mut p = String::from("0 3 0 ");
    for i in 0..n {
        let a = TAU * i as f64 / n as f64;
        write!(p, "{:.6} 3 {:.6} ", a.cos(), a.sin()).unwrap();
    }
    let mut idx = String::new();
    for i in 0..n {
        write!(idx, "0 {} {} ", 1 + i, 1 + (i + 1) % n).unwrap();
    }
    format!(
        "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 10 10 10 ]\n  Material \"matte\" \"rgb Kd\" [ 0 0 0 ]\n  \
         Shape \"trianglemesh\" \"integer indices\" [ {idx}] \"point P\" [ {p}]\nAttributeEnd\n"
    )
}

/// A closed convex prism with `n / 2` sides (`n` vertices), radius 0.45, from y = 1 to y = 1.8.
fn prism(n: usize) -> String {
    let k = (n / 2).max(3);
    let mut p = String::new();
    for y in [1.0, 1.8] {
        for i in 0..k {
            let a = TAU * i as f64 / k as f64 + 0.1;
            write!(p, "{:.6} {y} {:.6} ", 0.45 * a.cos() + 0.15, 0.45 * a.sin()).unwrap();
        }
    }
    let mut idx = String::new();
    for i in 0..k {
        let j = (i + 1) % k;
        // Outward winding (counter-clockwise seen from outside).
        write!(idx, "{i} {} {j} {j} {} {} ", k + i, k + i, k + j).unwrap();
    }
    for i in 1..k - 1 {
        write!(idx, "0 {} {} ", i, i + 1).unwrap(); // bottom cap, facing -y
        write!(idx, "{k} {} {} ", k + i + 1, k + i).unwrap(); // top cap, facing +y
    }
    format!(
        "AttributeBegin\n  Material \"matte\" \"rgb Kd\" [ 0.6 0.2 0.1 ]\n  \
         Shape \"trianglemesh\" \"integer indices\" [ {idx}] \"point P\" [ {p}]\nAttributeEnd\n"
    )
}

fn scene_text(n_light: usize, n_occ: usize, mode: &str) -> String {
    format!(
        "LookAt 0 5 -3  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 50 ]\n\
         Film \"image\" \"integer xresolution\" [ 64 ] \"integer yresolution\" [ 64 ]\n\
         Sampler \"random\" \"integer pixelsamples\" [ 1 ]\nPixelFilter \"box\"\n\
         Integrator \"ltc\" \"string mode\" [ \"{mode}\" ] \"integer coveragesamples\" [ 1 ]\nWorldBegin\n{}{}\
         AttributeBegin\n  Material \"matte\" \"rgb Kd\" [ 0.5 0.5 0.5 ]\n  Shape \"trianglemesh\" \
         \"integer indices\" [ 0 1 2 0 2 3 ] \"point P\" [ -4 0 -4 -4 0 4 4 0 4 4 0 -4 ]\nAttributeEnd\nWorldEnd\n",
        disk_light(n_light),
        prism(n_occ)
    )
}

/// Seconds for one render (integrator only), and the image mean as a sanity value.
fn render_once(text: &str, res: u32) -> (f64, f64) {
    let parsed = penumbra_parser::parse_str(text, "<ltc_scaling>", None).expect("scene parses");
    let desc = &parsed.scene;
    let warnings = DiagSink::new();
    let entry = penumbra_integrators::find("ltc").expect("ltc is registered");
    let integrator = (entry.create)(&desc.integrator.params, &warnings).expect("ltc parameters");
    let build = BuildOptions { spp: Some(1), seed: 0, crop: None, resolution: Some((res, res)) };
    let scene = Scene::build(desc, integrator.requirements(), &build, &warnings).expect("scene builds");
    let mut film = Film::new(scene.film.clone(), scene.filter.radius(), integrator.extra_channels());
    let cancel = AtomicBool::new(false);
    let ctx = RenderContext { threads: 1, cancel: &cancel, progress: None, warnings: &warnings };
    let t0 = Instant::now();
    integrator.render(&scene, &ctx, &mut film).expect("render");
    let t = t0.elapsed().as_secs_f64();
    let img = film.to_image(false);
    let mean = img.data.iter().map(|v| *v as f64).sum::<f64>() / img.data.len().max(1) as f64;
    (t, mean)
}

fn timed(text: &str, res: u32) -> (f64, f64) {
    let (t, m) = render_once(text, res);
    if t > 3.0 {
        return (t, m); // slow enough that one run is stable
    }
    let mut ts = [t, render_once(text, res).0, render_once(text, res).0];
    ts.sort_by(f64::total_cmp);
    (ts[1], m)
}

/// Least-squares `y = a + b·x` and R².
fn fit(xs: &[f64], ys: &[f64]) -> (f64, f64, f64) {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let ss_res: f64 = xs.iter().zip(ys).map(|(x, y)| (y - a - b * x).powi(2)).sum();
    let ss_tot: f64 = ys.iter().map(|y| (y - my).powi(2)).sum();
    (a, b, 1.0 - ss_res / ss_tot)
}

/// Least-squares slope of log t against log n (the empirical exponent).
fn exponent(xs: &[f64], ys: &[f64]) -> f64 {
    let lx: Vec<f64> = xs.iter().map(|x| x.ln()).collect();
    let ly: Vec<f64> = ys.iter().map(|y| y.max(1e-9).ln()).collect();
    fit(&lx, &ly).1
}

/// The polygon-level cost behind one shading point: `spherical_polygon::difference` of a regular
/// `n`-gon light (seen from below, as one loop) minus a regular `n`-gon occluder loop straddling
/// its edge, then its form factor. Seconds per call (mean over enough repetitions).
fn polygon_difference_time(n: usize) -> f64 {
    use glam::DVec3;
    use penumbra_integrators::common::spherical_polygon;
    let ring = |r: f64, h: f64, dx: f64| -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let a = TAU * i as f64 / n as f64;
                DVec3::new(r * a.cos() + dx, r * a.sin(), h)
            })
            .collect()
    };
    let light = vec![ring(1.0, 3.0, 0.0)];
    let occ = vec![ring(0.45, 1.5, 0.3)];
    let reps = (200_000 / n).max(20);
    let t0 = Instant::now();
    let mut acc = 0.0;
    for _ in 0..reps {
        let d = spherical_polygon::difference(std::hint::black_box(&light), std::hint::black_box(&occ));
        acc += spherical_polygon::form_factor_loops(&d);
    }
    std::hint::black_box(acc);
    t0.elapsed().as_secs_f64() / reps as f64
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--one") {
        // `--one N_L N_O MODE RES`: one render, for profiling.
        let num = |i: usize, d: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
        let mode = args.get(4).map(String::as_str).unwrap_or("silhouette");
        let (t, m) = render_once(&scene_text(num(2, 1000), num(3, FIXED), mode), num(5, 16) as u32);
        println!("{t:.4} s, mean {m:.4}");
        return;
    }
    let res: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(32);
    let budget: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(f64::INFINITY);
    println!("spherical_polygon::difference of an n-gon light minus an n-gon occluder (one call, one thread)");
    let ts: Vec<f64> = SIZES.iter().map(|&n| polygon_difference_time(n)).collect();
    for (n, t) in SIZES.iter().zip(&ts) {
        println!("{n:>6} {:>10.2} µs", t * 1e6);
    }
    let xs: Vec<f64> = SIZES.iter().map(|&n| n as f64).collect();
    let (a, b, r2) = fit(&xs, &ts);
    println!(
        "  time = {:.2} µs + {:.3} µs·n, R² = {r2:.4}; log-log exponent {:.2}\n",
        a * 1e6,
        b * 1e6,
        exponent(&xs, &ts)
    );
    if args.get(1).map(String::as_str) == Some("--poly") {
        return;
    }
    println!("ltc scaling: {res}x{res} pixels, 1 spp, 1 thread; fixed count {FIXED}; median of 3 (1 run if > 3 s)");
    for (label, vary_light) in
        [("light vertices n_l (occluder n_o = 64)", true), ("occluder vertices n_o (light n_l = 64)", false)]
    {
        println!("\nvarying {label}");
        println!("{:>6} {:>14} {:>14} {:>8} {:>12}", "n", "silhouette s", "per-tri s", "ratio", "mean (s/pt)");
        let mut rows: Vec<(f64, f64, f64)> = Vec::new();
        for n in SIZES {
            let (nl, no) = if vary_light { (n, FIXED) } else { (FIXED, n) };
            let (ts, ms) = timed(&scene_text(nl, no, "silhouette"), res);
            let (tp, mp) = if rows.last().is_some_and(|r| r.2 > budget) {
                (f64::NAN, f64::NAN)
            } else {
                timed(&scene_text(nl, no, "per-triangle"), res)
            };
            println!("{n:>6} {ts:>14.4} {tp:>14.4} {:>8.2} {ms:>6.4}/{mp:.4}", tp / ts);
            rows.push((n as f64, ts, tp));
        }
        let xs: Vec<f64> = rows.iter().map(|r| r.0).collect();
        for (name, ys) in [
            ("silhouette", rows.iter().map(|r| r.1).collect::<Vec<_>>()),
            ("per-triangle", rows.iter().map(|r| r.2).collect()),
        ] {
            let (x, y): (Vec<f64>, Vec<f64>) =
                xs.iter().zip(&ys).filter(|(_, y)| y.is_finite()).map(|(x, y)| (*x, *y)).unzip();
            if x.len() < 3 {
                continue;
            }
            let (a, b, r2) = fit(&x, &y);
            println!(
                "  {name:>12}: time = {a:.4} s + {:.3} ms·n, R² = {r2:.4}; log-log exponent {:.2}",
                b * 1e3,
                exponent(&x, &y)
            );
        }
    }
}
